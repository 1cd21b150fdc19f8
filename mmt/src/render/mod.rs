//! The operator-side force renderer (numerics notes §4.5; `DESIGN.md` §6).
//!
//! One step per tick of SDIRK2 on the mass-matrix form ([`integrators::Sdirk2`]), wrapped in what
//! makes it safe to feed with estimated, changing parameters:
//! - it only accepts [`Gated`](crate::model::gates::Gated) parameter sets;
//! - parameters are smoothed towards each new set (first-order, τ = 20 ms by default: raw
//!   per-sample jumps pump energy even into exact integrators, notes §4.4); every intermediate set
//!   is a convex combination of physical sets, hence physical and passive;
//! - a renderability gate: a contact mode faster than the tick (`ω_n h > 1`) is either given a
//!   larger rendered mass (`ω_n h = 1`) or reduced to the massless model, and the renderer says
//!   which ([`Renderability`]);
//! - Colgate's bound `b_dev ≥ k T/2 + |b|` clips the rendered stiffness when the device's physical
//!   damping is known;
//! - a consistent state at contact onset (the force starts from 0), zero force in free space;
//! - the output is finite for every input: a non-finite state is reset, counted and outputs 0.

pub mod integrators;
mod kelvin_voigt;
pub mod reference;
mod sliding;
pub mod transfer;

pub use kelvin_voigt::{KelvinVoigtRenderer, ShearRenderer, ShearState};
pub use sliding::{SlidingMassRenderer, SlidingState};

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Settings shared by the renderers.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct RendererConfig {
    /// Haptic loop rate [Hz]. Default 1000.
    pub rate_hz: f64,
    /// Time constant of the parameter smoothing [s]. Default 0.02 (numerics notes §4.4: τ ≳ 20 ms
    /// keeps max|F| at the physical scale under parameter jumps). 0 applies a new set at once.
    pub smoothing_tau_s: f64,
    /// Largest `ω_n·h` rendered as is. Default 1 (the contact mode resolved by the tick);
    /// `f64::INFINITY` disables the renderability gate.
    pub max_omega_h: f64,
    /// What to do with an unresolved contact mode.
    pub unresolved: UnresolvedPolicy,
    /// Physical damping of the haptic device [N·s/m], when a device is in the loop. `None` (no
    /// device: analysis, scripted runs) disables the Colgate clip.
    pub device_damping_ns_per_m: Option<f64>,
    /// How long the hand-over from a prior to the first model lasts [s]: a linear blend (of the
    /// normal's parameters, of the tangents' force offset). Default 0.05: at the safety layer's
    /// default force-rate limit (1,000 N/s) a hand-over trips the limit only for a prior off by
    /// more than 50 N. Longer costs accuracy while the prior is wrong: exp 1, 60 s, seeds 1/2,
    /// error after stable 2.63/2.89 % at 0, 2.79/3.04 % at 0.05, 2.96/3.20 % at 0.1 and
    /// 3.85/4.03 % at 0.4 s. 0 hands over at once (then smoothed with `smoothing_tau_s` like any
    /// new set).
    #[serde(default = "default_handover_s")]
    pub handover_s: f64,
}

fn default_handover_s() -> f64 {
    0.05
}

impl Default for RendererConfig {
    fn default() -> Self {
        RendererConfig {
            rate_hz: 1000.0,
            smoothing_tau_s: 0.02,
            max_omega_h: 1.0,
            unresolved: UnresolvedPolicy::Auto,
            device_damping_ns_per_m: None,
            handover_s: default_handover_s(),
        }
    }
}

impl RendererConfig {
    /// Checks every field, naming the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let check = |field: &'static str, value: f64, ok: bool, expected: &'static str| {
            if ok {
                Ok(())
            } else {
                Err(ConfigError {
                    field,
                    value,
                    expected,
                })
            }
        };
        check(
            "rate_hz",
            self.rate_hz,
            self.rate_hz.is_finite() && self.rate_hz > 0.0,
            "a positive rate",
        )?;
        check(
            "smoothing_tau_s",
            self.smoothing_tau_s,
            self.smoothing_tau_s.is_finite() && self.smoothing_tau_s >= 0.0,
            "0 or a positive time constant",
        )?;
        check(
            "max_omega_h",
            self.max_omega_h,
            self.max_omega_h > 0.0,
            "a positive bound (∞ disables the gate)",
        )?;
        check(
            "handover_s",
            self.handover_s,
            self.handover_s.is_finite() && (0.0..=10.0).contains(&self.handover_s),
            "0 to 10 s",
        )?;
        if let Some(b) = self.device_damping_ns_per_m {
            check(
                "device_damping_ns_per_m",
                b,
                b.is_finite() && b >= 0.0,
                "a non-negative damping",
            )?;
        }
        Ok(())
    }

    /// Tick length [s].
    pub fn step_s(&self) -> f64 {
        1.0 / self.rate_hz
    }

    /// The hand-over from a prior to the first model [ticks] (`handover_s` at `rate_hz`).
    pub fn handover_ticks(&self) -> u32 {
        (self.handover_s * self.rate_hz).round() as u32
    }

    /// Smoothing factor per tick, `1 − exp(−h/τ)`.
    fn smoothing_alpha(&self) -> f64 {
        if self.smoothing_tau_s > 0.0 {
            1.0 - (-self.step_s() / self.smoothing_tau_s).exp()
        } else {
            1.0
        }
    }

    /// Colgate & Schenkel: `b_dev ≥ k T/2 + |b|`. Returns the (possibly clipped) `(k, b)`.
    fn colgate(&self, k: f64, b: f64) -> (f64, f64) {
        match self.device_damping_ns_per_m {
            None => (k, b),
            Some(b_dev) => {
                let b = b.min(b_dev);
                let k_max = 2.0 * (b_dev - b) / self.step_s();
                (k.min(k_max), b)
            }
        }
    }
}

/// An invalid renderer setting.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[error("renderer setting {field} = {value} is invalid: expected {expected}")]
pub struct ConfigError {
    /// The field.
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What was expected.
    pub expected: &'static str,
}

/// What to do when the contact mode is faster than the tick (`ω_n h > max_omega_h`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum UnresolvedPolicy {
    /// Raise the mass when that changes it by at most 10×; otherwise the mass is dynamically
    /// invisible at the haptic rate and the massless model is exact to first order: reduce.
    Auto,
    /// Always raise the rendered mass to `m = (k1+k2) (h/max_omega_h)²`.
    RaiseMass,
    /// Always render the massless (first-order) model.
    ReducedModel,
}

/// How the renderer is rendering the current parameters.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Renderability {
    /// As estimated.
    Resolved,
    /// The mass was raised so the contact mode is resolved.
    RaisedMass {
        /// Estimated mass [kg].
        from_kg: f64,
        /// Rendered mass [kg].
        to_kg: f64,
    },
    /// Rendered without the mass.
    Reduced {
        /// Estimated mass [kg].
        mass_kg: f64,
    },
}

/// What the renderer changed in the parameters it was given, this tick.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Adjustments {
    /// Renderability decision.
    pub renderability: Renderability,
    /// `(estimated, rendered)` contact stiffness when Colgate's bound clipped it [N/m].
    pub stiffness_clipped: Option<(f64, f64)>,
}

impl Default for Adjustments {
    fn default() -> Self {
        Adjustments {
            renderability: Renderability::Resolved,
            stiffness_clipped: None,
        }
    }
}

/// Counters a renderer keeps (for reports; nothing is logged per tick).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RendererStats {
    /// Ticks stepped.
    pub ticks: u64,
    /// Ticks whose input was not finite (output 0, state untouched).
    pub rejected_inputs: u64,
    /// Times the state became non-finite and was reset.
    pub state_resets: u64,
    /// Ticks rendered with a raised mass or the reduced model.
    pub unresolved_ticks: u64,
    /// Ticks with the stiffness clipped by Colgate's bound.
    pub clipped_ticks: u64,
    /// Parameter sets accepted.
    pub parameter_updates: u64,
    /// Ticks stepped with the prior as the only model (before the first set).
    #[serde(default)]
    pub prior_ticks: u64,
}

/// First-order smoothing of one parameter towards its target.
#[inline]
fn smooth(current: f64, target: f64, alpha: f64) -> f64 {
    current + alpha * (target - current)
}

#[cfg(test)]
mod tests;
