//! `mmt transfer`: the renderer's frequency response against the exact `|F/X|` (thesis
//! appendix E, where Gazebo's engines were off by up to ~80 % and Raisim by up to ~4 %).
//!
//! For each ω the renderer is driven in contact by a sampled sinusoid `x = X sin(ωt)` (with its
//! exact velocity samples), run until the slowest mode has decayed to e⁻²⁵, and the steady-state
//! force amplitude is fitted by least squares (`c₀ + c cos ωt + s sin ωt`) over whole periods.

use crate::model::Physical;
use crate::model::Structure;
use crate::model::backsolve::Params;
use crate::model::gates::{GateRejection, gate_physical};
use crate::render::{RendererConfig, SlidingMassRenderer};
use serde::Serialize;
use thiserror::Error;

/// One row of the report.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TransferRow {
    /// Angular frequency [rad/s].
    pub omega: f64,
    /// Exact `|F/X|` [N/m].
    pub expected: f64,
    /// Rendered steady-state amplitude per unit displacement [N/m].
    pub rendered: f64,
    /// `|rendered − expected| / expected`.
    pub rel_error: f64,
}

/// The report: `{"rows":[…]}`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TransferReport {
    /// One row per ω, in the order asked.
    pub rows: Vec<TransferRow>,
}

/// Why the transfer could not be measured.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum TransferError {
    /// The parameter set fails the gates, so the renderer would not render it.
    #[error("the parameter set is rejected by the gates: {0}")]
    Rejected(GateRejection),
    /// An ω is not a positive finite number.
    #[error("omega = {0} is invalid: expected a positive frequency in rad/s")]
    Omega(f64),
    /// The renderer rate is not positive and finite.
    #[error("rate = {0} Hz is invalid: expected a positive rate")]
    Rate(f64),
}

/// Displacement amplitude used [m]. The model is linear, so the value only sets the scale.
pub const AMPLITUDE_M: f64 = 1e-3;

/// Measures the renderer's response to each ω for the given parameters (friction ignored: it is
/// not linear).
pub fn transfer(
    p: &Physical,
    rate_hz: f64,
    omegas: &[f64],
) -> Result<TransferReport, TransferError> {
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(TransferError::Rate(rate_hz));
    }
    let mut p = *p;
    p.coulomb_n = 0.0;
    let structure = Structure::SlidingMass {
        ground_spring: p.k_ground_n_per_m > 0.0,
        friction: false,
    };
    let gated =
        gate_physical(structure, &Params::SlidingMass(p)).map_err(TransferError::Rejected)?;
    let config = RendererConfig {
        rate_hz,
        ..RendererConfig::default()
    };
    let rows = omegas
        .iter()
        .map(|&omega| {
            if !(omega.is_finite() && omega > 0.0) {
                return Err(TransferError::Omega(omega));
            }
            let mut r =
                SlidingMassRenderer::new(config).map_err(|_| TransferError::Rate(rate_hz))?;
            r.set_target(&gated);
            let rendered =
                steady_state_amplitude(&mut r, omega, rate_hz, settle_time_s(&p)) / AMPLITUDE_M;
            let expected = p.force_per_displacement(omega).norm();
            Ok(TransferRow {
                omega,
                expected,
                rendered,
                rel_error: (rendered - expected).abs() / expected,
            })
        })
        .collect::<Result<_, _>>()?;
    Ok(TransferReport { rows })
}

/// Time for the slowest mode to decay to e⁻²⁵ (≈ 1e-11), capped at 300 s.
pub fn settle_time_s(p: &Physical) -> f64 {
    let b = p.b_ground_ns_per_m + p.b_contact_ns_per_m;
    let s = p.stiffness_sum();
    let m = p.mass_kg;
    // Slowest decay rate of m λ² + b λ + s: for m = 0, s/b.
    let sigma = if m > 0.0 {
        let disc = b * b - 4.0 * m * s;
        if disc > 0.0 {
            (b - disc.sqrt()) / (2.0 * m)
        } else {
            b / (2.0 * m)
        }
    } else if b > 0.0 {
        s / b
    } else {
        0.0
    };
    if sigma > 0.0 {
        (25.0 / sigma).min(300.0)
    } else {
        300.0
    }
}

/// Drives `renderer` in contact with `x = X sin(ωt)` sampled at `rate_hz` for `settle_s`, then fits
/// the force amplitude over whole periods (at least 1 s, at least 4 periods).
pub fn steady_state_amplitude(
    renderer: &mut SlidingMassRenderer,
    omega: f64,
    rate_hz: f64,
    settle_s: f64,
) -> f64 {
    let h = 1.0 / rate_hz;
    let period = 2.0 * std::f64::consts::PI / omega;
    let fit_s = (4.0 * period).max(1.0);
    let fit_s = (fit_s / period).ceil() * period;
    let n_settle = (settle_s / h).ceil() as u64;
    let n_fit = (fit_s / h).round() as u64;
    let mut normal = [[0.0f64; 3]; 3];
    let mut rhs = [0.0f64; 3];
    for k in 0..n_settle + n_fit {
        let t = k as f64 * h;
        let (s, c) = (omega * t).sin_cos();
        let f = renderer.step(AMPLITUDE_M * s, AMPLITUDE_M * omega * c, true);
        if k >= n_settle {
            let basis = [1.0, c, s];
            for i in 0..3 {
                rhs[i] += basis[i] * f;
                for j in 0..3 {
                    normal[i][j] += basis[i] * basis[j];
                }
            }
        }
    }
    let coef = solve3(normal, rhs);
    coef[1].hypot(coef[2])
}

/// Solves the 3×3 normal equations (LU with partial pivoting); NaN when singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> [f64; 3] {
    let m = nalgebra::Matrix3::from_fn(|i, j| a[i][j]);
    m.lu()
        .solve(&nalgebra::Vector3::from(b))
        .map(|x| [x[0], x[1], x[2]])
        .unwrap_or([f64::NAN; 3])
}
