//! Time-domain passivity at the device port (`DESIGN.md` §11.10): an observer of the energy the
//! rendered environment has taken from the hand, and a controller that adds just enough damping
//! when that energy would go negative (Hannaford & Ryu, "Time-domain passivity control of haptic
//! interfaces", IEEE T-RA 18(1), 2002).
//!
//! Why it is needed although every parameter set the renderer accepts is passive: the rendered
//! environment is passive in continuous time with fixed parameters, and the device port is not
//! that. The model changes under the hand (new estimates while compressed, a surface that moves
//! with the delayed cloud, contact switches), the force is held for a tick (Colgate's bound:
//! b2 = 60 N·s/m at 1 kHz asks for more device damping than ordinary devices have), and the
//! safety rules themselves (rate limit) lag. The observer measures what actually happened.
//!
//! **Observer.** The force written at tick `n−1` is held until tick `n` (zero-order hold), so the
//! work the device did on the hand over that interval is exactly `F(n−1)·(x(n) − x(n−1))`,
//! whatever the path: the environment's energy is
//! `E(n) = E(n−1) − F(n−1)·(x(n) − x(n−1))`, positive when it absorbed energy. A passive port
//! keeps `E ≥ 0`. The reserve is capped at [`PassivityConfig::energy_cap_j`]: energy dissipated
//! long ago must not license an active burst later (a plain observer would let a long contact's
//! damping pay for seconds of activity).
//!
//! **Controller.** Before writing `F(n)` it predicts the next interval with the last
//! displacement, `E(n+1) ≈ E(n) − F(n)·Δx(n)`. If that is negative it adds the damping
//! `F' = F − α·Δx/T` that brings the prediction to zero, `α = T (F·Δx − E)/|Δx|²`, capped at the
//! device's damping limit (beyond it the damper itself would be active; the cap's ticks are
//! counted). Damping opposes the motion, so it never adds energy; a later saturation scales the
//! force down, which keeps `F·Δx ≤ E` because `E ≥ 0` there.

use serde::Serialize;

use super::stats::{Edge, TripCount};
use mmt::vec3::{self, Vec3};

/// A displacement per tick beyond this is a sensor glitch or a re-homing, not motion [m]: the
/// energy of that interval is not counted (10 m/s at 1 kHz).
const MAX_STEP_M: f64 = 0.01;

/// Settings of the passivity layer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PassivityConfig {
    /// Add damping when the observed energy would go negative; `false` observes only. Default
    /// true.
    pub control: bool,
    /// Largest damping the controller adds [N·s/m], ≥ 0; `None` takes the device's
    /// `max_damping_n_s_per_m`. 0 observes only.
    pub max_damping_n_s_per_m: Option<f64>,
    /// Largest energy reserve the observer keeps [J], > 0. Default 0.25 J: above what a 12 N
    /// device can store in the thesis's 500 N/m contact spring (½F²/k = 0.14 J), so that a
    /// passive environment giving back what it stored is never touched.
    pub energy_cap_j: f64,
}

impl Default for PassivityConfig {
    fn default() -> Self {
        PassivityConfig {
            control: true,
            max_damping_n_s_per_m: None,
            energy_cap_j: 0.25,
        }
    }
}

/// What the observer saw and the controller did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct PassivityStats {
    /// Energy the environment holds now [J] (≥ 0 for a passive port; capped).
    pub energy_j: f64,
    /// Lowest energy observed [J]: how far the port was active before the controller caught it
    /// (observe-only: how active the rendered environment was).
    pub min_energy_j: f64,
    /// Energy the controller's damping took out (predicted, per tick) [J].
    pub dissipated_j: f64,
    /// Ticks the controller added damping.
    pub controlling: TripCount,
    /// Ticks its damping was capped at the device's limit (passivity not restored that tick).
    pub capped: TripCount,
    /// Intervals left out of the energy: position not finite, or a jump beyond 1 cm per tick.
    pub glitches: u64,
}

/// The observer and controller. Runs in the 1 kHz loop: no allocation.
#[derive(Clone, Debug)]
pub(crate) struct Passivity {
    control: bool,
    max_damping: f64,
    cap_j: f64,
    energy_j: f64,
    last_cp: Option<Vec3>,
    /// `x(n) − x(n−1)` of this tick (zero when unknown).
    delta: Vec3,
    stats: PassivityStats,
}

impl Passivity {
    /// A layer adding at most `max_damping` [N·s/m]; the config was validated.
    pub(crate) fn new(config: &PassivityConfig, max_damping: f64) -> Self {
        Passivity {
            control: config.control && max_damping > 0.0,
            max_damping,
            cap_j: config.energy_cap_j,
            energy_j: 0.0,
            last_cp: None,
            delta: vec3::ZERO,
            stats: PassivityStats::default(),
        }
    }

    pub(crate) fn stats(&self) -> &PassivityStats {
        &self.stats
    }

    /// The observer, once per tick: the device is at `cp` [m] and `applied` [N] was written on
    /// the previous tick.
    pub(crate) fn observe(&mut self, cp: Vec3, applied: Vec3) {
        self.delta = vec3::ZERO;
        if !vec3::is_finite(cp) {
            self.last_cp = None;
            self.stats.glitches += 1;
            return;
        }
        if let Some(last) = self.last_cp {
            let delta = vec3::sub(cp, last);
            if vec3::norm(delta) <= MAX_STEP_M {
                self.energy_j = (self.energy_j - vec3::dot(applied, delta)).min(self.cap_j);
                self.delta = delta;
            } else {
                self.stats.glitches += 1;
            }
        }
        self.last_cp = Some(cp);
        self.stats.energy_j = self.energy_j;
        self.stats.min_energy_j = self.stats.min_energy_j.min(self.energy_j);
    }

    /// The controller: `force` [N] about to be written, `dt_s` the tick [s]. Returns the force
    /// with the damping it needs (`force` itself when it needs none or only observes), and the
    /// edges of its two counters (controlling, capped) for the log.
    pub(crate) fn control(&mut self, force: Vec3, dt_s: f64) -> (Vec3, Edge, Edge) {
        let d2 = vec3::dot(self.delta, self.delta);
        let excess = vec3::dot(force, self.delta) - self.energy_j;
        let (out, controlling, capped) =
            if !self.control || !(excess > 0.0) || !(d2 > 0.0) || !(dt_s > 0.0) {
                (force, false, false)
            } else {
                let wanted = dt_s * excess / d2;
                let capped = !(wanted <= self.max_damping);
                let c = wanted.min(self.max_damping) / dt_s;
                let out = vec3::sub(force, vec3::scale(self.delta, c));
                if vec3::is_finite(out) {
                    self.stats.dissipated_j += c * d2;
                    (out, true, capped)
                } else {
                    (force, false, false)
                }
            };
        (
            out,
            self.stats.controlling.record(controlling),
            self.stats.capped.record(capped),
        )
    }
}
