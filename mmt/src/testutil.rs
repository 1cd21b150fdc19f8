//! Shared test helpers: exact excitation data, phasor fits and reference least squares.

#![allow(clippy::unwrap_used)] // test helpers: a failed solve is a failed test

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

use crate::cloud::{CloudFrame, Pose};
use crate::contact::CloudIndex;
use crate::model::{Columns, Physical, col};

/// A plane of points at z = 0, 1 mm apart over ±`half_mm` in x and y, captured at `t_ns`,
/// indexed.
pub fn plane_index(half_mm: i16, t_ns: i64) -> std::sync::Arc<CloudIndex> {
    let points = (-half_mm..=half_mm)
        .flat_map(|i| {
            (-half_mm..=half_mm).map(move |j| [f32::from(i) * 1e-3, f32::from(j) * 1e-3, 0.0])
        })
        .collect();
    let frame = CloudFrame::new(points, t_ns, Pose::IDENTITY).unwrap();
    std::sync::Arc::new(CloudIndex::build(&frame).unwrap())
}

/// The numerics notes' "typical" object (§2.4, §6.2), without friction.
pub fn typical() -> Physical {
    Physical {
        coulomb_n: 0.0,
        ..Physical::TYPICAL
    }
}

/// The exp-1 object without friction.
pub fn exp1_frictionless() -> Physical {
    Physical {
        coulomb_n: 0.0,
        ..Physical::THESIS_EXP1
    }
}

/// Max over `i` of `|a_i − b_i| / |b_i|` (absolute where `b_i = 0`).
pub fn max_abs_rel(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let d = (x - y).abs();
            if *y == 0.0 { d } else { d / y.abs() }
        })
        .fold(0.0, f64::max)
}

/// Phasor `P` of a sampled steady-state sinusoid `s_i = Re(P e^{iω t_i})`, `t_i = (k0 + i) h`,
/// by projection onto cos/sin (exact least squares when the samples cover whole periods).
pub fn fit_phasor(samples: &[f64], w: f64, h: f64, k0: usize) -> Complex64 {
    let (mut a, mut b) = (0.0, 0.0);
    for (i, s) in samples.iter().enumerate() {
        let t = (k0 + i) as f64 * h;
        a += s * (w * t).cos();
        b += s * (w * t).sin();
    }
    let n = samples.len() as f64;
    Complex64::new(2.0 * a / n, -2.0 * b / n)
}

/// Worst relative error over a set of complex (phasor) comparisons.
#[derive(Debug, Default)]
pub struct PhasorCheck {
    /// Largest `|got − want| / |want|` so far.
    pub worst: f64,
}

impl PhasorCheck {
    /// Records `|got − want| / |want|` and asserts it is below `tol`.
    pub fn check(&mut self, got: Complex64, want: Complex64, tol: f64, what: &str) {
        let rel = (got - want).norm() / want.norm();
        self.worst = self.worst.max(rel);
        assert!(rel < tol, "{what}: relative error {rel:e}");
    }
}

/// A sum of sines `x(t) = Σ A_k sin(ω_k t + φ_k)` and the object's exact steady-state force on
/// the tool (linear part only: no friction).
#[derive(Clone, Debug)]
pub struct Multisine {
    /// `(ω [rad/s], amplitude [m], phase [rad])` per tone.
    pub tones: Vec<(f64, f64, f64)>,
}

impl Multisine {
    /// `n` log-spaced tones from `f_lo` to `f_hi` [Hz], amplitude falling log-linearly from
    /// `a_lo` to `a_hi` [m], Schroeder phases (low crest factor).
    pub fn log_spaced(n: usize, f_lo: f64, f_hi: f64, a_lo: f64, a_hi: f64) -> Multisine {
        let tones = (0..n)
            .map(|k| {
                let r = k as f64 / (n - 1) as f64;
                let f = f_lo * (f_hi / f_lo).powf(r);
                let a = a_lo * (a_hi / a_lo).powf(r);
                let phase = -std::f64::consts::PI * (k * k.saturating_sub(1)) as f64 / n as f64;
                (2.0 * std::f64::consts::PI * f, a, phase)
            })
            .collect();
        Multisine { tones }
    }

    /// The experiment-1-like excitation of the feasibility study: 9 tones 0.1–3.6 Hz, 3 cm
    /// falling to 2 mm.
    pub fn exp1() -> Multisine {
        Multisine::log_spaced(9, 0.1, 3.6, 0.03, 0.002)
    }

    /// Position and velocity at `t` [s].
    pub fn position_velocity(&self, t: f64) -> (f64, f64) {
        self.tones.iter().fold((0.0, 0.0), |(x, v), &(w, a, p)| {
            (x + a * (w * t + p).sin(), v + a * w * (w * t + p).cos())
        })
    }

    /// Exact steady-state force on the tool of `object` at `t` (sign convention of
    /// [`crate::model`]).
    pub fn force(&self, object: &Physical, t: f64) -> f64 {
        self.tones
            .iter()
            .map(|&(w, a, p)| {
                let h = object.force_per_displacement(w);
                // x = Im(a e^{i(ωt+φ)}) → F = Im(H a e^{i(ωt+φ)})
                (h * Complex64::from_polar(a, w * t + p)).im
            })
            .sum()
    }
}

/// Least squares over the active columns, minimising `‖Ψθ − y‖² + θᵀ P0⁻¹ θ` with the prior
/// `P0 = diag(p0 / s_i²)` (that is `p0·I` in the scaled coordinates `θ_s = s·θ`); `p0 = ∞` is
/// the plain problem. Solved by QR of the column-scaled, prior-augmented matrix.
pub fn batch_ls(
    rows: &[[f64; col::COUNT]],
    y: &[f64],
    columns: Columns,
    scales: &[f64; col::COUNT],
    p0: f64,
) -> [f64; col::COUNT] {
    let idx: Vec<usize> = columns.indices().collect();
    let n = idx.len();
    let extra = if p0.is_finite() { n } else { 0 };
    let mut a = DMatrix::<f64>::zeros(rows.len() + extra, n);
    let mut b = DVector::<f64>::zeros(rows.len() + extra);
    for (r, (row, yr)) in rows.iter().zip(y).enumerate() {
        for (c, &i) in idx.iter().enumerate() {
            a[(r, c)] = row[i] / scales[i];
        }
        b[r] = *yr;
    }
    for c in 0..extra {
        a[(rows.len() + c, c)] = 1.0 / p0.sqrt();
    }
    let qr = a.qr();
    let rhs = qr.q().transpose() * b;
    let sol = qr.r().solve_upper_triangular(&rhs).unwrap();
    let mut theta = [0.0; col::COUNT];
    for (c, &i) in idx.iter().enumerate() {
        theta[i] = sol[c] / scales[i];
    }
    theta
}
