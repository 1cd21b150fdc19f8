//! The Kelvin–Voigt renderer: the normal axis against a surface (thesis eq. 8), or any axis of a
//! rigid-ish wall. Stateless apart from parameter smoothing and the hand-over from a prior.

use super::{Adjustments, ConfigError, RendererConfig, RendererStats, smooth};
use crate::model::KelvinVoigt;
use crate::model::gates::Gated;

/// Renders `F = k·p + b·ṗ` along the surface normal for penetration depth `p > 0`, unilateral (a
/// surface pushes, it never pulls). Force on the tool, newtons, along the outward normal.
#[derive(Clone, Debug)]
pub struct KelvinVoigtRenderer {
    config: RendererConfig,
    alpha: f64,
    target: Option<KelvinVoigt>,
    current: Option<KelvinVoigt>,
    /// Rendered until the first target arrives, then blended out over `handover_ticks`.
    prior: Option<KelvinVoigt>,
    /// Ticks of the hand-over from the prior to the first target done so far (`None`: no
    /// hand-over under way).
    handover: Option<u32>,
    handover_ticks: u32,
    adjustments: Adjustments,
    stats: RendererStats,
}

impl KelvinVoigtRenderer {
    /// A renderer with no parameters yet (it renders 0, or its prior, until the first gated set
    /// arrives).
    pub fn new(config: RendererConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(KelvinVoigtRenderer {
            alpha: config.smoothing_alpha(),
            handover_ticks: config.handover_ticks(),
            config,
            target: None,
            current: None,
            prior: None,
            handover: None,
            adjustments: Adjustments::default(),
            stats: RendererStats::default(),
        })
    }

    /// Renders `prior` until the first parameter set arrives, then blends from it to that set
    /// linearly over the configured hand-over time (every blend is a convex combination of two
    /// passive sets, hence passive). The prior passes the same gates as any set (the caller gates
    /// it, [`crate::model::gates::gate_physical`]). `false` (ignored) if not Kelvin–Voigt or
    /// once a set has arrived.
    pub fn set_prior(&mut self, prior: &Gated) -> bool {
        match prior.kelvin_voigt() {
            Some(kv) if self.target.is_none() => {
                self.prior = Some(kv);
                true
            }
            _ => false,
        }
    }

    /// Sets the parameters to smooth towards; `false` (ignored) if not Kelvin–Voigt.
    pub fn set_target(&mut self, params: &Gated) -> bool {
        match params.kelvin_voigt() {
            Some(kv) => {
                if self.target.is_none() && self.prior.is_some() {
                    self.handover = Some(0);
                }
                self.target = Some(kv);
                self.stats.parameter_updates += 1;
                true
            }
            None => false,
        }
    }

    /// The parameters being smoothed towards.
    pub fn target(&self) -> Option<KelvinVoigt> {
        self.target
    }

    /// One tick: penetration depth [m] (positive inside the surface), its rate [m/s], and whether
    /// the tool is in contact. Returns the force on the tool along the outward normal [N], ≥ 0.
    pub fn step(
        &mut self,
        penetration_m: f64,
        penetration_rate_m_per_s: f64,
        in_contact: bool,
    ) -> f64 {
        self.stats.ticks += 1;
        if !(penetration_m.is_finite() && penetration_rate_m_per_s.is_finite()) {
            self.stats.rejected_inputs += 1;
            return 0.0;
        }
        let Some((k, b)) = self.advance_parameters() else {
            return 0.0;
        };
        if !in_contact || penetration_m <= 0.0 {
            return 0.0;
        }
        let f = (k * penetration_m + b * penetration_rate_m_per_s).max(0.0);
        if f.is_finite() {
            f
        } else {
            self.stats.state_resets += 1;
            0.0
        }
    }

    /// What the last tick changed (Colgate clip).
    pub fn adjustments(&self) -> Adjustments {
        self.adjustments
    }

    /// Counters.
    pub fn stats(&self) -> RendererStats {
        self.stats
    }
}

/// A Kelvin–Voigt element anchored where contact began, bilateral: the tangential axes of an
/// object that does not move (a wall holding the tool in its compliant surface). The anchor is
/// the position at onset, the simulator's convention (the damping force `b ẋ` may jump there,
/// as a Kelvin–Voigt contact's does; a preload to cancel it would leave a per-episode constant
/// the telerobot's regression cannot represent).
#[derive(Clone, Debug)]
pub struct ShearRenderer {
    inner: KelvinVoigtRenderer,
    anchor_m: f64,
    in_contact: bool,
}

/// The part of a [`ShearRenderer`] needed to rewind it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShearState {
    /// Anchor [m].
    pub anchor_m: f64,
    /// Whether the last tick was in contact.
    pub in_contact: bool,
}

impl ShearRenderer {
    /// A renderer with no parameters yet.
    pub fn new(config: RendererConfig) -> Result<Self, ConfigError> {
        Ok(ShearRenderer {
            inner: KelvinVoigtRenderer::new(config)?,
            anchor_m: 0.0,
            in_contact: false,
        })
    }

    /// Sets the parameters to smooth towards; `false` (ignored) if not Kelvin–Voigt.
    pub fn set_target(&mut self, params: &Gated) -> bool {
        self.inner.set_target(params)
    }

    /// Whether a parameter set was given.
    pub fn has_target(&self) -> bool {
        self.inner.target.is_some()
    }

    /// One tick: position [m] and velocity [m/s] along the axis. Returns the force on the tool
    /// along the axis [N].
    pub fn step(&mut self, x: f64, v: f64, in_contact: bool) -> f64 {
        if !(x.is_finite() && v.is_finite()) {
            return self.inner.step(f64::NAN, 0.0, false);
        }
        if in_contact && !self.in_contact {
            self.anchor_m = x;
        }
        self.in_contact = in_contact;
        // The inner renderer is unilateral along its axis; run it on the magnitude and restore
        // the sign: F = −(k δ + b ẋ).
        let d = x - self.anchor_m;
        let along = self.inner.step_bilateral(d, v, in_contact);
        -along
    }

    /// The rewind state.
    pub fn snapshot(&self) -> ShearState {
        ShearState {
            anchor_m: self.anchor_m,
            in_contact: self.in_contact,
        }
    }

    /// Restores a state from [`Self::snapshot`].
    pub fn restore(&mut self, s: ShearState) {
        self.anchor_m = s.anchor_m;
        self.in_contact = s.in_contact;
    }

    /// Counters.
    pub fn stats(&self) -> RendererStats {
        self.inner.stats()
    }
}

impl KelvinVoigtRenderer {
    /// One tick of parameter smoothing towards the target (blended from the prior while handing
    /// over), then Colgate's clip (counted and reported): the `(k, b)` to render; the prior's
    /// before any parameters, `None` with no prior either.
    fn advance_parameters(&mut self) -> Option<(f64, f64)> {
        let Some(target) = self.target else {
            let prior = self.prior?;
            self.stats.prior_ticks += 1;
            return Some(self.clip(prior));
        };
        let current = match self.current {
            None => target,
            Some(c) => KelvinVoigt {
                k_n_per_m: smooth(c.k_n_per_m, target.k_n_per_m, self.alpha),
                b_ns_per_m: smooth(c.b_ns_per_m, target.b_ns_per_m, self.alpha),
            },
        };
        self.current = Some(current);
        let rendered = match (self.handover, self.prior) {
            (Some(done), Some(prior)) if done < self.handover_ticks => {
                self.handover = Some(done + 1);
                let w = f64::from(done + 1) / f64::from(self.handover_ticks);
                KelvinVoigt {
                    k_n_per_m: prior.k_n_per_m + w * (current.k_n_per_m - prior.k_n_per_m),
                    b_ns_per_m: prior.b_ns_per_m + w * (current.b_ns_per_m - prior.b_ns_per_m),
                }
            }
            _ => {
                self.handover = None;
                current
            }
        };
        Some(self.clip(rendered))
    }

    /// Colgate's clip of `p`, counted and reported.
    fn clip(&mut self, p: KelvinVoigt) -> (f64, f64) {
        let (k, b) = self.config.colgate(p.k_n_per_m, p.b_ns_per_m);
        self.adjustments.stiffness_clipped = (k < p.k_n_per_m).then_some((p.k_n_per_m, k));
        if self.adjustments.stiffness_clipped.is_some() {
            self.stats.clipped_ticks += 1;
        }
        (k, b)
    }

    /// `k d + b ḋ` (either sign) with smoothing and Colgate's clip, 0 out of contact.
    fn step_bilateral(&mut self, d: f64, rate: f64, in_contact: bool) -> f64 {
        self.stats.ticks += 1;
        let Some((k, b)) = self.advance_parameters() else {
            return 0.0;
        };
        if !in_contact {
            return 0.0;
        }
        let f = k * d + b * rate;
        if f.is_finite() { f } else { 0.0 }
    }
}
