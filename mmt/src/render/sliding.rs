//! The sliding-mass renderer: one tangential axis of the flexible object (thesis fig. 3).

use super::integrators::{Sdirk2, Stepper, stage_matrix};
use super::{
    Adjustments, ConfigError, Renderability, RendererConfig, RendererStats, UnresolvedPolicy,
    smooth,
};
use crate::model::Physical;
use crate::model::gates::Gated;
use serde::{Deserialize, Serialize};

/// The renderer's dynamic state, enough to rewind and replay (state sync).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SlidingState {
    /// Mass position `ξ_m` [m] in the renderer's coordinate (0 = ground spring at rest).
    pub mass_position_m: f64,
    /// Mass velocity `ẋ_m` [m/s].
    pub mass_velocity_m_per_s: f64,
    /// Tool position minus `anchor` is the tool coordinate `ξ`; the anchor is set at contact onset
    /// so that the contact force starts from 0 [m].
    pub anchor_m: f64,
    /// Whether the last tick was in contact.
    pub in_contact: bool,
    /// Input `[ξ, ẋ]` of the last tick (start of the next step's interpolation).
    pub last_input: [f64; 2],
    /// Smoothed parameters being rendered (before renderability/Colgate adjustments).
    pub current: Option<Physical>,
    /// The contact's onset, while in contact: `[x, ẋ − ẋ_m, ξ_m]` then (tool position [m], tool
    /// velocity relative to the mass [m/s], mass position [m]). The anchor is placed from it
    /// with the parameters rendered now, so an onset rendered with an early estimate does not
    /// leave a ground spring preloaded by that estimate's `b2/k2` for the whole contact.
    pub onset: Option<[f64; 3]>,
}

/// Renders the force of a sliding flexible object on one axis. Force on the tool, newtons.
#[derive(Clone, Debug)]
pub struct SlidingMassRenderer {
    config: RendererConfig,
    alpha: f64,
    target: Option<Physical>,
    state: SlidingState,
    adjustments: Adjustments,
    stats: RendererStats,
}

impl SlidingMassRenderer {
    /// A renderer with no parameters yet (it renders 0 until the first gated set arrives).
    pub fn new(config: RendererConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(SlidingMassRenderer {
            alpha: config.smoothing_alpha(),
            config,
            target: None,
            state: SlidingState::default(),
            adjustments: Adjustments::default(),
            stats: RendererStats::default(),
        })
    }

    /// Sets the parameters to smooth towards. Returns `false` (and ignores the set) when it is not
    /// a sliding mass.
    pub fn set_target(&mut self, params: &Gated) -> bool {
        match params.sliding_mass() {
            Some(p) => {
                self.target = Some(p);
                self.stats.parameter_updates += 1;
                true
            }
            None => false,
        }
    }

    /// The parameters being smoothed towards.
    pub fn target(&self) -> Option<Physical> {
        self.target
    }

    /// Renders one tick: tool position `x` [m] and velocity `v` [m/s] on this axis, and whether
    /// the tool is in contact. Returns the force on the tool [N]; 0 out of contact, before any
    /// parameters, and whenever an input is not finite.
    pub fn step(&mut self, x: f64, v: f64, in_contact: bool) -> f64 {
        self.stats.ticks += 1;
        if !(x.is_finite() && v.is_finite()) {
            self.stats.rejected_inputs += 1;
            return 0.0;
        }
        let Some(target) = self.target else {
            // No model yet: keep the contact bookkeeping so a later replay from this state starts
            // consistent (spring unloaded at onset, object at rest).
            let s = &mut self.state;
            if in_contact && !s.in_contact {
                s.anchor_m = x - s.mass_position_m;
                s.onset = Some([x, v - s.mass_velocity_m_per_s, s.mass_position_m]);
            }
            if !in_contact {
                s.onset = None;
            }
            s.in_contact = in_contact;
            s.last_input = [x - s.anchor_m, v];
            return 0.0;
        };
        let current = match self.state.current {
            None => target,
            Some(c) => blend(&c, &target, self.alpha),
        };
        self.state.current = Some(current);
        let rendered = self.adjust(&current);
        let h = self.config.step_s();
        let s = &mut self.state;
        place_anchor(s, x, v, in_contact, &rendered);
        let u1 = [x - s.anchor_m, v];
        let mut sys = rendered;
        if !in_contact {
            // Free space: the object slides on by itself; the tool feels nothing.
            sys.k_contact_n_per_m = 0.0;
            sys.b_contact_ns_per_m = 0.0;
        }
        let mm = sys.mass_matrix_form();
        let z0 = [s.mass_position_m, s.mass_velocity_m_per_s];
        let det = {
            let l = stage_matrix(&mm, super::integrators::SDIRK_GAMMA * h);
            l[0][0] * l[1][1] - l[0][1] * l[1][0]
        };
        let z1 = if det > 0.0 {
            Sdirk2 { sys: mm, h }.step(z0, s.last_input, u1)
        } else if in_contact {
            [f64::NAN; 2]
        } else {
            z0 // a massless, undamped object out of contact has no dynamics
        };
        s.last_input = u1;
        let force = if in_contact {
            mm.force_on_tool(z1, u1)
        } else {
            0.0
        };
        if z1.iter().all(|v| v.is_finite()) && force.is_finite() {
            s.mass_position_m = z1[0];
            s.mass_velocity_m_per_s = z1[1];
            force
        } else {
            // Unloaded, at rest relative to the tool: the force restarts from 0.
            self.stats.state_resets += 1;
            s.mass_position_m = u1[0];
            s.mass_velocity_m_per_s = v;
            0.0
        }
    }

    /// The rendered parameters after the renderability gate and Colgate's bound.
    fn adjust(&mut self, p: &Physical) -> Physical {
        let mut r = *p;
        let h = self.config.step_s();
        let (k2, b2) = self
            .config
            .colgate(r.k_contact_n_per_m, r.b_contact_ns_per_m);
        self.adjustments.stiffness_clipped =
            (k2 < r.k_contact_n_per_m).then_some((r.k_contact_n_per_m, k2));
        r.k_contact_n_per_m = k2;
        r.b_contact_ns_per_m = b2;
        let s = r.stiffness_sum();
        let omega_h = h * (s / r.mass_kg).sqrt();
        self.adjustments.renderability = if r.mass_kg > 0.0 && omega_h > self.config.max_omega_h {
            let raised = s * (h / self.config.max_omega_h).powi(2);
            let reduce = match self.config.unresolved {
                UnresolvedPolicy::Auto => raised > 10.0 * r.mass_kg,
                UnresolvedPolicy::RaiseMass => false,
                UnresolvedPolicy::ReducedModel => true,
            };
            let from_kg = r.mass_kg;
            if reduce {
                r.mass_kg = 0.0;
                Renderability::Reduced { mass_kg: from_kg }
            } else {
                r.mass_kg = raised;
                Renderability::RaisedMass {
                    from_kg,
                    to_kg: raised,
                }
            }
        } else {
            Renderability::Resolved
        };
        if self.adjustments.renderability != Renderability::Resolved {
            self.stats.unresolved_ticks += 1;
        }
        if self.adjustments.stiffness_clipped.is_some() {
            self.stats.clipped_ticks += 1;
        }
        r
    }

    /// What the last tick changed in the parameters (renderability, Colgate clip).
    pub fn adjustments(&self) -> Adjustments {
        self.adjustments
    }

    /// Counters.
    pub fn stats(&self) -> RendererStats {
        self.stats
    }

    /// The state, for rewinding.
    pub fn snapshot(&self) -> SlidingState {
        self.state
    }

    /// Restores a state taken with [`Self::snapshot`].
    pub fn restore(&mut self, state: SlidingState) {
        self.state = state;
    }

    /// Contact deflection `δ = ξ − ξ_m` [m] at the last tick (0 out of contact).
    pub fn deflection_m(&self) -> f64 {
        if self.state.in_contact {
            self.state.last_input[0] - self.state.mass_position_m
        } else {
            0.0
        }
    }

    /// Blends an externally estimated contact deflection and mass velocity into the state
    /// (state sync, `DESIGN.md` §11.6): `gain` = 1 replaces, 0 ignores. Non-finite values and gains
    /// outside [0, 1] are ignored.
    pub fn sync(&mut self, deflection_m: f64, mass_velocity_m_per_s: f64, gain: f64) {
        if !(deflection_m.is_finite()
            && mass_velocity_m_per_s.is_finite()
            && (0.0..=1.0).contains(&gain))
        {
            return;
        }
        let s = &mut self.state;
        let target_xm = s.last_input[0] - deflection_m;
        s.mass_position_m = smooth(s.mass_position_m, target_xm, gain);
        s.mass_velocity_m_per_s = smooth(s.mass_velocity_m_per_s, mass_velocity_m_per_s, gain);
    }
}

/// The contact bookkeeping of a rendered tick: at the onset the anchor from the onset state;
/// in contact the onset's anchor with the parameters rendered now (the parameters moved; the
/// last input moves with it, so the step interpolates no jump); out of contact no onset.
/// Largest move of the anchor per tick while in contact [m] (5 mm/s at 1 kHz).
pub(crate) const MAX_ANCHOR_STEP_M: f64 = 5e-6;

fn place_anchor(s: &mut SlidingState, x: f64, v: f64, in_contact: bool, rendered: &Physical) {
    if in_contact && !s.in_contact {
        s.onset = Some([x, v - s.mass_velocity_m_per_s, s.mass_position_m]);
        s.anchor_m = anchor(s.onset, rendered).unwrap_or(x - s.mass_position_m);
        s.last_input = [x - s.anchor_m, v];
    } else if in_contact && let Some(a) = anchor(s.onset, rendered) {
        let step = (a - s.anchor_m).clamp(-MAX_ANCHOR_STEP_M, MAX_ANCHOR_STEP_M);
        s.last_input[0] -= step;
        s.anchor_m += step;
    }
    if !in_contact {
        s.onset = None;
    }
    s.in_contact = in_contact;
}

/// Contact onset: the anchor that makes the contact force start from exactly 0,
/// `k2 (ξ − ξ_m) + b2 (v − v_m) = 0`, the mass where free motion left it; `None` without an
/// onset.
fn anchor(onset: Option<[f64; 3]>, p: &Physical) -> Option<f64> {
    let [x, dv, xm] = onset?;
    let preload = if p.k_contact_n_per_m > 0.0 {
        -p.b_contact_ns_per_m * dv / p.k_contact_n_per_m
    } else {
        0.0
    };
    let a = x - xm - preload;
    a.is_finite().then_some(a)
}

fn blend(c: &Physical, t: &Physical, alpha: f64) -> Physical {
    Physical {
        mass_kg: smooth(c.mass_kg, t.mass_kg, alpha),
        k_ground_n_per_m: smooth(c.k_ground_n_per_m, t.k_ground_n_per_m, alpha),
        b_ground_ns_per_m: smooth(c.b_ground_ns_per_m, t.b_ground_ns_per_m, alpha),
        k_contact_n_per_m: smooth(c.k_contact_n_per_m, t.k_contact_n_per_m, alpha),
        b_contact_ns_per_m: smooth(c.b_contact_ns_per_m, t.b_contact_ns_per_m, alpha),
        coulomb_n: smooth(c.coulomb_n, t.coulomb_n, alpha),
    }
}
