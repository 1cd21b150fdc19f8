//! Filtering and differentiation for the estimator (numerics notes §7, `DESIGN.md` §5).
//!
//! The regression `y = ψᵀθ` of [`crate::model`] survives filtering only if **every** column and
//! the output pass through the **same** linear filter: then `H·y = (H·ψ)ᵀθ`, because the filter
//! commutes with the linear model. [`RegressorFilter`] therefore runs one state-variable filter
//! ([`svf`]) on the position, the force and the smoothed velocity sign, and reads every
//! derivative off the filter's states. Filtering each derivative separately (the thesis's
//! "backward Euler + low-pass", §D.2) stacks a different delay on each column and biases the fit
//! by hundreds of percent; the test `pipeline::inconsistent_cascade_fails` keeps that mistake
//! out.
//!
//! What it is not: no clock, no allocation per sample; construction (the matrix exponential)
//! allocates once.

pub mod expm;
pub mod svf;

#[cfg(test)]
mod pipeline;

use thiserror::Error;

use crate::model::col;
pub use svf::{Discretisation, Svf, SvfConfig, SvfState, butterworth_polynomial};

/// Lowest filter order: `x‴` must still roll off (`s³/Λ(s)`).
pub const MIN_ORDER: usize = 4;
/// Highest filter order (fixed-size state storage).
pub const MAX_ORDER: usize = 8;

/// A filter configuration that cannot be built.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FilterError {
    /// Order out of range.
    #[error("filter order {order} out of range: allowed 4..=8 (x‴ needs order ≥ 4 to roll off)")]
    Order {
        /// The order given.
        order: usize,
    },
    /// Cut-off not finite, not positive or too close to the sample rate.
    #[error(
        "filter cut-off {cutoff_hz} Hz out of range: allowed (0, {max_hz}] Hz (a tenth of the sample rate)"
    )]
    Cutoff {
        /// The cut-off given [Hz].
        cutoff_hz: f64,
        /// The largest allowed [Hz].
        max_hz: f64,
    },
    /// Sample period not finite or not positive.
    #[error("filter sample period {period_s} s invalid: must be finite and > 0")]
    SamplePeriod {
        /// The period given [s].
        period_s: f64,
    },
    /// Smooth-sign velocity scale not finite or not positive.
    #[error("sign velocity scale {v_m_per_s} m/s invalid: must be finite and > 0")]
    SignVelocity {
        /// The scale given [m/s].
        v_m_per_s: f64,
    },
    /// The discretisation failed (cannot happen for a valid configuration).
    #[error("filter discretisation failed: {0}")]
    Expm(#[from] expm::ExpmError),
}

/// Configuration of the regressor filter.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RegressorConfig {
    /// The one state-variable filter applied to x, F and σ.
    pub svf: SvfConfig,
    /// Velocity scale `v_s` [m/s] of the smooth sign `σ = tanh(ẋ/v_s)` that stands in for
    /// `sgn ẋ_m` in the friction columns (numerics notes §1.2: a hard sign makes the regression
    /// biased at every reversal and turns velocity noise at rest into ±1 noise). Default
    /// 0.005 m/s: the Karnopp stick band of the exp-1 scene, and five times the assumed 1 mm/s
    /// velocity noise, so noise at rest moves σ by about 0.2, not by 2.
    pub sign_velocity_m_per_s: f64,
}

impl Default for RegressorConfig {
    fn default() -> Self {
        RegressorConfig {
            svf: SvfConfig::default(),
            sign_velocity_m_per_s: 0.005,
        }
    }
}

/// One sample of the filtered regression: `y ≈ ψᵀθ` (see [`crate::model`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Regression {
    /// `ψ = [−x‴, −x″, −x′, −x, −F″, −F′, −σ, −σ′, 0, 0]`, all filtered by the same `1/Λ(s)`
    /// (indices [`col`]). Units: m/s³, m/s², m/s, m, N/s², N/s, 1, 1/s. The constant columns
    /// `i`, `j` are set by whoever knows the axis ([`Regression::with_constant`]).
    pub psi: [f64; col::COUNT],
    /// `y = F_f`: the filtered force on the tool [N].
    pub y: f64,
}

impl Regression {
    /// The regression with the constant column of `axis` (0 or 1, [`col::intercept`]) set to 1
    /// and the other's to 0.
    pub fn with_constant(mut self, axis: usize) -> Regression {
        self.psi[col::I] = 0.0;
        self.psi[col::J] = 0.0;
        self.psi[col::intercept(axis)] = 1.0;
        self
    }
}

/// Channel indices in the filter's state array.
const X: usize = 0;
const F: usize = 1;
const SIGMA: usize = 2;

/// The same state-variable filter run on the position, the force on the tool and the smoothed
/// velocity sign, assembling the regressor of thesis eq. 7 plus the friction-derivative column
/// (`DESIGN.md` §11.1: `σ′` is the first derivative state of the σ channel).
#[derive(Clone, Debug, PartialEq)]
pub struct RegressorFilter {
    disc: Discretisation,
    states: [SvfState; 3],
    sign_velocity_m_per_s: f64,
}

impl RegressorFilter {
    /// Builds the filter at rest at zero. Allocates once (the discretisation).
    pub fn new(config: RegressorConfig) -> Result<RegressorFilter, FilterError> {
        let v = config.sign_velocity_m_per_s;
        if !(v.is_finite() && v > 0.0) {
            return Err(FilterError::SignVelocity { v_m_per_s: v });
        }
        Ok(RegressorFilter {
            disc: Discretisation::new(config.svf)?,
            states: [SvfState::default(); 3],
            sign_velocity_m_per_s: v,
        })
    }

    /// `σ = tanh(ẋ/v_s)`, the smooth sign of the measured velocity.
    #[inline]
    pub fn smooth_sign(&self, velocity_m_per_s: f64) -> f64 {
        (velocity_m_per_s / self.sign_velocity_m_per_s).tanh()
    }

    /// Feeds one sample — measured position `x` [m], velocity `v` [m/s] and force on the tool
    /// `f` [N] — and returns the filtered regression at this tick.
    #[inline]
    pub fn step(&mut self, x_m: f64, v_m_per_s: f64, f_n: f64) -> Regression {
        self.step_with_shape(x_m, f_n, self.smooth_sign(v_m_per_s))
    }

    /// As [`step`](Self::step), with the friction shape `σ` given (the friction force over its
    /// level, e.g. from a model of the object) instead of the tool velocity's smooth sign.
    #[inline]
    pub fn step_with_shape(&mut self, x_m: f64, f_n: f64, sigma: f64) -> Regression {
        self.disc.advance(&mut self.states, [x_m, f_n, sigma]);
        self.regression()
    }

    /// The regression at the current state (what the last [`step`](Self::step) returned).
    pub fn regression(&self) -> Regression {
        let d = |c: usize, k: usize| self.disc.derivative(&self.states[c], k);
        Regression {
            psi: [
                -d(X, 3),
                -d(X, 2),
                -d(X, 1),
                -d(X, 0),
                -d(F, 2),
                -d(F, 1),
                -d(SIGMA, 0),
                -d(SIGMA, 1),
                0.0,
                0.0,
            ],
            y: d(F, 0),
        }
    }

    /// Puts every channel in the steady state of constant inputs (e.g. at start-up, so the
    /// filter does not ring from zero to the first sample).
    pub fn reset_steady(&mut self, x_m: f64, v_m_per_s: f64, f_n: f64) {
        let sigma = self.smooth_sign(v_m_per_s);
        self.states = [
            SvfState::steady(x_m),
            SvfState::steady(f_n),
            SvfState::steady(sigma),
        ];
    }

    /// The shared discretisation.
    pub fn discretisation(&self) -> &Discretisation {
        &self.disc
    }
}
