//! Matrix exponential and exact first-order-hold discretisation, for the small (≤ 10×10) systems
//! of this crate: the state-variable filter and the simulator's linear part. Both are computed
//! **once, at construction**; nothing here runs per sample (it allocates).
//!
//! `expm` is the scaling-and-squaring algorithm with the degree-13 Padé approximant of
//! N. J. Higham, "The scaling and squaring method for the matrix exponential revisited",
//! SIAM J. Matrix Anal. Appl. 26(4):1179–1193, 2005 (Algorithm 2.3, degree 13 only: the lower
//! degrees there only save flops, which do not matter at construction). With `‖A/2^s‖₁ ≤ θ₁₃`
//! its backward error is below the unit round-off.

use nalgebra::DMatrix;
use thiserror::Error;

/// Why a matrix exponential could not be computed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ExpmError {
    /// The matrix holds NaN or ±inf.
    #[error("matrix exponential of a matrix with a non-finite entry")]
    NonFinite,
    /// The matrix is not square.
    #[error("matrix exponential of a non-square {rows}×{cols} matrix")]
    NotSquare {
        /// Rows.
        rows: usize,
        /// Columns.
        cols: usize,
    },
    /// The Padé denominator `V − U` was singular (cannot happen for a finite matrix after
    /// scaling; reported rather than unwrapped).
    #[error("matrix exponential: Padé denominator is singular")]
    Singular,
}

/// Padé(13) coefficients `b_0 … b_13` (Higham 2005, eq. 2.2 / Table 2.3 source).
const B13: [f64; 14] = [
    64_764_752_532_480_000.0,
    32_382_376_266_240_000.0,
    7_771_770_303_897_600.0,
    1_187_353_796_428_800.0,
    129_060_195_264_000.0,
    10_559_470_521_600.0,
    670_442_572_800.0,
    33_522_128_640.0,
    1_323_241_920.0,
    40_840_800.0,
    960_960.0,
    16_380.0,
    182.0,
    1.0,
];

/// `θ₁₃`: the largest `‖A‖₁` for which the degree-13 approximant is accurate to unit round-off
/// (Higham 2005, Table 2.3).
const THETA13: f64 = 5.371_920_351_148_152;

/// `e^A` for a square, finite matrix.
pub fn expm(a: &DMatrix<f64>) -> Result<DMatrix<f64>, ExpmError> {
    let (n, m) = a.shape();
    if n != m {
        return Err(ExpmError::NotSquare { rows: n, cols: m });
    }
    if a.iter().any(|v| !v.is_finite()) {
        return Err(ExpmError::NonFinite);
    }
    let norm1 = (0..n)
        .map(|j| a.column(j).iter().map(|v| v.abs()).sum::<f64>())
        .fold(0.0, f64::max);
    // s = max(0, ⌈log2(‖A‖₁/θ₁₃)⌉); scaling by 2^−s is exact in floating point.
    let s = if norm1 > THETA13 {
        (norm1 / THETA13).log2().ceil() as i32
    } else {
        0
    };
    let a = a * 2f64.powi(-s);
    let id = DMatrix::<f64>::identity(n, n);
    let a2 = &a * &a;
    let a4 = &a2 * &a2;
    let a6 = &a4 * &a2;
    let b = &B13;
    // U = A [A6 (b13 A6 + b11 A4 + b9 A2) + b7 A6 + b5 A4 + b3 A2 + b1 I]
    let u_inner = &a6 * (&a6 * b[13] + &a4 * b[11] + &a2 * b[9])
        + &a6 * b[7]
        + &a4 * b[5]
        + &a2 * b[3]
        + &id * b[1];
    let u = &a * u_inner;
    // V = A6 (b12 A6 + b10 A4 + b8 A2) + b6 A6 + b4 A4 + b2 A2 + b0 I
    let v = &a6 * (&a6 * b[12] + &a4 * b[10] + &a2 * b[8])
        + &a6 * b[6]
        + &a4 * b[4]
        + &a2 * b[2]
        + &id * b[0];
    // (V − U) R = V + U
    let mut r = (&v - &u)
        .lu()
        .solve(&(&v + &u))
        .ok_or(ExpmError::Singular)?;
    for _ in 0..s {
        r = &r * &r;
    }
    Ok(r)
}

/// Exact discretisation of `ż = A z + B u` over one period `h` for an input that is **linear
/// between samples** (first-order hold, "triangle hold"; Franklin, Powell & Workman, *Digital
/// Control of Dynamic Systems*, 3rd ed., §6.3.2):
///
/// ```text
/// z_{k+1} = Φ z_k + Γ_hold u_k + Γ_ramp (u_{k+1} − u_k)
/// Φ = e^{Ah},  Γ_hold = ∫₀ʰ e^{Aσ} dσ B,  Γ_ramp = (1/h) ∫₀ʰ e^{A(h−τ)} τ dτ B
/// ```
///
/// all three read off one exponential of the augmented matrix
/// `[[A h, B h, 0], [0, 0, I], [0, 0, 0]]` (it is `[[Φ, Γ_hold, Γ_ramp], [0, I, I], [0, 0, I]]`).
/// An input held constant over the step (`u_{k+1} = u_k`) gives the zero-order-hold result.
#[derive(Clone, Debug, PartialEq)]
pub struct Foh {
    /// `Φ = e^{Ah}` (n×n).
    pub phi: DMatrix<f64>,
    /// `Γ_hold` (n×m).
    pub gamma_hold: DMatrix<f64>,
    /// `Γ_ramp` (n×m).
    pub gamma_ramp: DMatrix<f64>,
}

impl Foh {
    /// Discretises `(A, B)` (n×n, n×m) over `h` seconds.
    pub fn new(a: &DMatrix<f64>, b: &DMatrix<f64>, h: f64) -> Result<Foh, ExpmError> {
        let n = a.nrows();
        let m = b.ncols();
        if a.ncols() != n || b.nrows() != n {
            return Err(ExpmError::NotSquare {
                rows: b.nrows(),
                cols: a.ncols(),
            });
        }
        let dim = n + 2 * m;
        let mut aug = DMatrix::<f64>::zeros(dim, dim);
        aug.view_mut((0, 0), (n, n)).copy_from(&(a * h));
        aug.view_mut((0, n), (n, m)).copy_from(&(b * h));
        aug.view_mut((n, n + m), (m, m))
            .copy_from(&DMatrix::<f64>::identity(m, m));
        let e = expm(&aug)?;
        Ok(Foh {
            phi: e.view((0, 0), (n, n)).into_owned(),
            gamma_hold: e.view((0, n), (n, m)).into_owned(),
            gamma_ramp: e.view((0, n + m), (n, m)).into_owned(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn max_rel(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
        (a - b).amax() / b.amax()
    }

    #[test]
    fn zero_and_diagonal() {
        let z = DMatrix::<f64>::zeros(5, 5);
        assert_eq!(expm(&z).unwrap(), DMatrix::identity(5, 5));
        let d = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![-30.0, -1.0, 0.5, 3.0]));
        let e = expm(&d).unwrap();
        for (i, v) in [-30.0f64, -1.0, 0.5, 3.0].iter().enumerate() {
            assert!((e[(i, i)] - v.exp()).abs() <= 4e-15 * v.exp().max(1.0));
        }
    }

    /// exp([[0, w], [−w, 0]]) is a rotation; large `w` exercises scaling and squaring.
    #[test]
    fn rotation_closed_form() {
        for w in [0.1, 1.0, 5.0, 40.0, 300.0] {
            let a = DMatrix::from_row_slice(2, 2, &[0.0, w, -w, 0.0]);
            let e = expm(&a).unwrap();
            let want = DMatrix::from_row_slice(2, 2, &[w.cos(), w.sin(), -w.sin(), w.cos()]);
            // Rounding grows with the number of squarings, ~ w·ε.
            assert!((&e - &want).amax() < 1e-15 * w.max(1.0) * 8.0, "w = {w}");
        }
    }

    /// A Jordan block `λI + N` (N nilpotent, 4×4): e^{λ}(I + N + N²/2 + N³/6).
    #[test]
    fn jordan_block_closed_form() {
        let lam: f64 = -2.5;
        let mut n = DMatrix::<f64>::zeros(4, 4);
        for i in 0..3 {
            n[(i, i + 1)] = 3.0;
        }
        let a = &n + DMatrix::<f64>::identity(4, 4) * lam;
        let n2 = &n * &n;
        let n3 = &n2 * &n;
        let want = (DMatrix::<f64>::identity(4, 4) + &n + n2 / 2.0 + n3 / 6.0) * lam.exp();
        assert!(max_rel(&expm(&a).unwrap(), &want) < 1e-14);
    }

    /// The damped oscillator `[[0, 1], [−ω², −2ζω]]` (ζ < 1) in closed form.
    #[test]
    fn damped_oscillator_closed_form() {
        let (w, zeta, t): (f64, f64, f64) = (120.0, 0.05, 0.37);
        let a = DMatrix::from_row_slice(2, 2, &[0.0, 1.0, -w * w, -2.0 * zeta * w]) * t;
        let sigma = zeta * w;
        let wd = w * (1.0 - zeta * zeta).sqrt();
        let (c, s, ex) = ((wd * t).cos(), (wd * t).sin(), (-sigma * t).exp());
        let want = DMatrix::from_row_slice(
            2,
            2,
            &[
                ex * (c + sigma / wd * s),
                ex * s / wd,
                -ex * w * w / wd * s,
                ex * (c - sigma / wd * s),
            ],
        );
        let e = expm(&a).unwrap();
        for i in 0..2 {
            for j in 0..2 {
                let scale = want.row(i).amax();
                // ωt = 44 rad: both sides carry ~ωt·ε of rounding.
                assert!(
                    (e[(i, j)] - want[(i, j)]).abs() < 2e-11 * scale,
                    "({i},{j})"
                );
            }
        }
    }

    /// Scalar FOH in closed form: Φ = e^{ah}, Γ_hold = (e^{ah} − 1)/a · b,
    /// Γ_ramp = (e^{ah} − 1 − ah)/(a² h) · b.
    #[test]
    fn scalar_foh_closed_form() {
        let (a, b, h): (f64, f64, f64) = (-37.0, 2.0, 1e-3);
        let d = Foh::new(
            &DMatrix::from_element(1, 1, a),
            &DMatrix::from_element(1, 1, b),
            h,
        )
        .unwrap();
        let e = (a * h).exp();
        let hold = (a * h).exp_m1() / a * b;
        let ramp = ((a * h).exp_m1() - a * h) / (a * a * h) * b;
        assert!((d.phi[(0, 0)] - e).abs() < 1e-15);
        assert!((d.gamma_hold[(0, 0)] - hold).abs() < 1e-15 * hold.abs());
        assert!((d.gamma_ramp[(0, 0)] - ramp).abs() < 1e-11 * ramp.abs());
    }

    /// Against nalgebra's own Padé implementation on a dense 8×8 matrix.
    #[test]
    fn agrees_with_nalgebra_on_dense_8x8() {
        let a = DMatrix::from_fn(8, 8, |i, j| ((i * 7 + j * 3) % 11) as f64 / 3.0 - 1.5);
        let ours = expm(&a).unwrap();
        let theirs = a.clone().exp();
        assert!(max_rel(&ours, &theirs) < 1e-13);
    }

    #[test]
    fn rejects_bad_input() {
        let mut a = DMatrix::<f64>::zeros(2, 2);
        a[(0, 1)] = f64::NAN;
        assert_eq!(expm(&a), Err(ExpmError::NonFinite));
        assert!(matches!(
            expm(&DMatrix::<f64>::zeros(2, 3)),
            Err(ExpmError::NotSquare { .. })
        ));
    }
}
