//! The telerobot's estimate of the object's state on each tangential axis (contact deflection
//! and mass velocity), sent to the operator as state sync (`DESIGN.md` §11.6).

/// Estimates the contact deflection `δ` and the mass velocity of one tangential axis from the
/// measured force (feasibility notes, variant (b)): the Kelvin–Voigt contact law
/// `F_op = k2 δ + b2 δ̇` is a stable first-order filter for `δ` driven by the force, exact
/// whatever the friction; then `ẋ_m = ẋ − δ̇`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Observer {
    pub(crate) deflection_m: f64,
    pub(crate) mass_velocity_m_per_s: f64,
    /// The state follows the force (false after a reset: out of contact, no usable set).
    running: bool,
}

impl Observer {
    pub(crate) fn step(
        &mut self,
        p: &mmt::model::Physical,
        velocity: f64,
        force_on_tool: f64,
        in_contact: bool,
        onset: bool,
        dt: f64,
    ) {
        let (k, b) = (p.k_contact_n_per_m, p.b_contact_ns_per_m);
        let valid = k > 0.0 && k.is_finite() && b >= 0.0 && b.is_finite();
        if !in_contact || !valid {
            *self = Observer::default();
            return;
        }
        let f_op = -force_on_tool;
        if b == 0.0 {
            // A pure spring contact (the estimator's reduced model can have one): the deflection
            // is the force over the stiffness at once — the filter's b → 0 limit, in which the
            // mass velocity is the tool's.
            self.deflection_m = f_op / k;
            self.mass_velocity_m_per_s = velocity;
            self.running = true;
            return;
        }
        if onset {
            // The contact starts unloaded with the object at rest (the renderer's convention).
            self.deflection_m = -b * velocity / k;
        } else if !self.running {
            // Started mid-contact (the first set arrived, or the set became usable): from the
            // deflection the force holds, not from 0 — from 0 the first ticks read the whole
            // force as damper force, a mass velocity of F/b2, and the first state sync carried
            // it (1.06 m/s on the seed-1 class object 27 at 400 ms; −0.03 m/s from here).
            self.deflection_m = f_op / k;
        }
        self.running = true;
        // δ' = (F_op − k δ)/b, exact for F held over the tick.
        let decay = (-k * dt / b).exp();
        self.deflection_m = self.deflection_m * decay + (1.0 - decay) * f_op / k;
        self.mass_velocity_m_per_s = velocity - (f_op - k * self.deflection_m) / b;
    }
}
