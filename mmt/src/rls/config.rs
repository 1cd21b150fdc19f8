//! Configuration of the estimator: column scales, forgetting, covariance bound, and validation.

use thiserror::Error;

use super::CusumConfig;
use crate::model::{Columns, Structure, col};

const N: usize = col::COUNT;

/// Fixed regressor column scales `s` (one per [`col`] index, unit of that column), powers of two.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ColumnScales(pub [f64; N]);

impl ColumnScales {
    /// No scaling.
    pub const UNIT: ColumnScales = ColumnScales([1.0; N]);

    /// Scales of the regressor under a sinusoid of amplitude `position_m` [m] at `omega_rad_s`
    /// [rad/s] giving a force amplitude `force_n` [N]: `[Xω³, Xω², Xω, X, Fω², Fω, 1, ω, 1, 1]`, each
    /// rounded to the nearest power of two (the constant columns: 1). Non-positive or
    /// non-finite inputs give `None`.
    pub fn for_excitation(position_m: f64, force_n: f64, omega_rad_s: f64) -> Option<ColumnScales> {
        let (x, f, w) = (position_m, force_n, omega_rad_s);
        if ![x, f, w].iter().all(|v| v.is_finite() && *v > 0.0) {
            return None;
        }
        let raw = [
            x * w * w * w,
            x * w * w,
            x * w,
            x,
            f * w * w,
            f * w,
            1.0,
            w,
            1.0,
            1.0,
        ];
        Some(ColumnScales(
            raw.map(|v| 2f64.powi(v.log2().round() as i32)),
        ))
    }

    /// The exp-1 scene: 3 cm, 3 N, 1 Hz (feasibility notes: 3.0 N RMS in contact).
    pub fn exp1() -> ColumnScales {
        let w = 2.0 * std::f64::consts::PI;
        ColumnScales::for_excitation(0.03, 3.0, w).unwrap_or(ColumnScales::UNIT)
    }
}

/// Configuration of the estimator.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RlsConfig {
    /// The identified coefficients. Default: the exp-1 structure (sliding mass, no ground spring,
    /// friction: 7 columns).
    pub columns: Columns,
    /// Forgetting factor `λ` ∈ (0, 1]. Default 0.999: a memory of `1/(1 − λ)` = 1000 updates
    /// (1 s at 1 kHz), inside the 0.995–0.9995 range of numerics notes §6.3.
    pub forgetting: f64,
    /// Initial and reset covariance `p0` of each scaled coefficient [1: `P_s` is the covariance
    /// of `θ_s` per unit output-noise variance, since `ψ_s` is dimensionless]. Default 1e3: a
    /// prior standard deviation of ≈ 32 N per newton of noise, against `θ_s` of O(1–10) N with
    /// the exp-1 scales, so the prior is weak.
    pub initial_covariance: f64,
    /// Bound `p̄` on the mean variance `tr P_s / n` (scaled units). Default 1e3 (= `p0`): never
    /// less certain than just after a reset. Must be ≥ `p0`.
    pub max_mean_variance: f64,
    /// Column scales. Default [`ColumnScales::exp1`].
    pub scales: ColumnScales,
    /// Time constant of the relative prediction-error EWMA [updates]. Default 250 (the 250 ms
    /// of the confidence gate, `DESIGN.md` §11.4).
    pub error_time_constant_samples: f64,
    /// The new-object detector.
    pub cusum: CusumConfig,
}

impl Default for RlsConfig {
    fn default() -> Self {
        RlsConfig {
            columns: Structure::SlidingMass {
                ground_spring: false,
                friction: true,
            }
            .columns(),
            forgetting: 0.999,
            initial_covariance: 1e3,
            max_mean_variance: 1e3,
            scales: ColumnScales::exp1(),
            error_time_constant_samples: 250.0,
            cusum: CusumConfig::default(),
        }
    }
}

/// An invalid estimator configuration: the field, the value and what was expected.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RlsError {
    /// A numeric field out of range.
    #[error("rls config: {field} = {value} invalid, expected {expected}")]
    Field {
        /// Field name.
        field: &'static str,
        /// The value given.
        value: f64,
        /// The allowed range.
        expected: &'static str,
    },
    /// No column to identify.
    #[error("rls config: columns is empty (free space has nothing to estimate)")]
    NoColumns,
}

pub(super) fn check_p0(p0: f64, bound: f64) -> Result<(), RlsError> {
    if p0.is_finite() && p0 > 0.0 && p0 <= bound {
        Ok(())
    } else {
        Err(RlsError::Field {
            field: "initial_covariance",
            value: p0,
            expected: "finite, > 0 and ≤ max_mean_variance",
        })
    }
}

pub(super) fn validate(c: &RlsConfig) -> Result<(), RlsError> {
    if c.columns.is_empty() {
        return Err(RlsError::NoColumns);
    }
    let field = |field, value: f64, ok: bool, expected| {
        if value.is_finite() && ok {
            Ok(())
        } else {
            Err(RlsError::Field {
                field,
                value,
                expected,
            })
        }
    };
    field(
        "forgetting",
        c.forgetting,
        c.forgetting > 0.0 && c.forgetting <= 1.0,
        "in (0, 1]",
    )?;
    let m = c.max_mean_variance;
    field("max_mean_variance", m, m > 0.0, "finite and > 0")?;
    check_p0(c.initial_covariance, m)?;
    let t = c.error_time_constant_samples;
    field("error_time_constant_samples", t, t >= 1.0, "finite and ≥ 1")?;
    for i in c.columns.indices() {
        let s = c.scales.0[i];
        field(
            "scales",
            s,
            s > 0.0,
            "finite and > 0 for every active column",
        )?;
    }
    if let Some((name, value, expected)) = c.cusum.invalid_field() {
        field(name, value, false, expected)?;
    }
    Ok(())
}
