//! The Kelvin–Voigt renderer: the normal axis against a surface (thesis eq. 8), or any axis of a
//! rigid-ish wall. Stateless apart from parameter smoothing.

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
    adjustments: Adjustments,
    stats: RendererStats,
}

impl KelvinVoigtRenderer {
    /// A renderer with no parameters yet (it renders 0 until the first gated set arrives).
    pub fn new(config: RendererConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(KelvinVoigtRenderer {
            alpha: config.smoothing_alpha(),
            config,
            target: None,
            current: None,
            adjustments: Adjustments::default(),
            stats: RendererStats::default(),
        })
    }

    /// Sets the parameters to smooth towards; `false` (ignored) if not Kelvin–Voigt.
    pub fn set_target(&mut self, params: &Gated) -> bool {
        match params.kelvin_voigt() {
            Some(kv) => {
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
        let Some(target) = self.target else {
            return 0.0;
        };
        let current = match self.current {
            None => target,
            Some(c) => KelvinVoigt {
                k_n_per_m: smooth(c.k_n_per_m, target.k_n_per_m, self.alpha),
                b_ns_per_m: smooth(c.b_ns_per_m, target.b_ns_per_m, self.alpha),
            },
        };
        self.current = Some(current);
        let (k, b) = self.config.colgate(current.k_n_per_m, current.b_ns_per_m);
        self.adjustments.stiffness_clipped =
            (k < current.k_n_per_m).then_some((current.k_n_per_m, k));
        if self.adjustments.stiffness_clipped.is_some() {
            self.stats.clipped_ticks += 1;
        }
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
