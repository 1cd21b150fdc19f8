//! What the data say about θ: the information matrix of the regression coefficients, as the RLS
//! holds it, for measuring how far a physical parameter set is from the estimate *in the
//! data's own terms*.
//!
//! The RLS minimises the forgotten sum of squared prediction errors `J(θ) = Σₖ λᵏ (yₖ − ψₖᵀθ)²`.
//! Its covariance `P` (per unit noise variance) is the inverse of that sum's curvature, so for
//! any other coefficient vector `θ = θ̂ + δ`
//!
//! ```text
//! J(θ̂ + δ) − J(θ̂) = δᵀ P⁻¹ δ            (exact for the quadratic J; prior terms aside)
//! ```
//!
//! is how much worse `θ` predicts the very data the estimate came from, in N². Directions the
//! motion did not excite cost nothing; directions it did cost a lot. Measured against the
//! forgotten output energy `Σₖ λᵏ yₖ²` it is scale-free: a heavy, a light and a stiff object
//! are judged alike (issue 12: scale-aware gates). With the factor `P = U D Uᵀ` (`U` unit upper
//! triangular, Bierman's form), `δᵀ P⁻¹ δ = |D^{−½} U⁻¹ δ|²`: one back substitution.

use super::super::{Columns, col};
use nalgebra::{SMatrix, SVector};

const N: usize = col::COUNT;

/// The information of the structure's coefficients (the constant columns marginalised out).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Information {
    /// The coefficient ([`col`]) of each factor row, in the factor's order.
    cols: [usize; N],
    n: usize,
    /// Scale `s` of each row's coefficient: the factor is of `θ ⊙ s`.
    scale: [f64; N],
    /// Unit upper-triangular `U` (entries above the diagonal used).
    u: [[f64; N]; N],
    /// The diagonal `D` (> 0).
    d: [f64; N],
    /// `Σₖ λᵏ yₖ²` [N²], the output energy the information was gathered with.
    output_energy: f64,
    /// The noise variance of the regression output [N²]: the a-priori error power.
    noise_variance: f64,
    /// Consecutive samples whose errors are correlated (1: white).
    correlation_samples: f64,
}

impl Information {
    /// The information of coefficients `cols` (factor order) with scales `scale`, from the
    /// factor `U D Uᵀ` of their covariance per unit noise variance; `None` when a diagonal
    /// entry is not positive or a number is not finite.
    pub fn new(
        cols: &[usize],
        scale: &[f64],
        u: impl Fn(usize, usize) -> f64,
        d: &[f64],
        output_energy: f64,
        noise_variance: f64,
    ) -> Option<Information> {
        let n = cols.len();
        if n > N || scale.len() != n || d.len() != n || cols.iter().any(|&c| c >= N) {
            return None;
        }
        let mut info = Information {
            cols: [0; N],
            n,
            scale: [0.0; N],
            u: [[0.0; N]; N],
            d: [0.0; N],
            output_energy,
            noise_variance,
            correlation_samples: 1.0,
        };
        for k in 0..n {
            info.cols[k] = cols[k];
            info.scale[k] = scale[k];
            info.d[k] = d[k];
            for j in k + 1..n {
                info.u[k][j] = u(k, j);
            }
        }
        let finite = info.d[..n].iter().all(|v| v.is_finite() && *v > 0.0)
            && info.scale[..n].iter().all(|v| v.is_finite() && *v > 0.0)
            && info.u.iter().flatten().all(|v| v.is_finite())
            && output_energy.is_finite()
            && output_energy > 0.0
            && noise_variance.is_finite()
            && noise_variance >= 0.0;
        finite.then_some(info)
    }

    /// Whether coefficient `c` is in the information.
    pub fn contains(&self, c: usize) -> bool {
        self.cols[..self.n].contains(&c)
    }

    /// `r = D^{−½} U⁻¹ (δ ⊙ s)` into `out`, so that `|r|² = δᵀ P⁻¹ δ` [N²]; returns its length.
    /// Entries of `delta` outside the information are ignored.
    pub fn whiten(&self, delta: &[f64; N], out: &mut [f64; N]) -> usize {
        let n = self.n;
        let mut z = [0.0; N];
        for j in (0..n).rev() {
            let tail: f64 = (j + 1..n).map(|l| self.u[j][l] * z[l]).sum();
            z[j] = delta[self.cols[j]] * self.scale[j] - tail;
        }
        for j in 0..n {
            out[j] = z[j] / self.d[j].sqrt();
        }
        n
    }

    /// The variance of coefficient `c`'s estimate given the data [its unit²]: `P`'s diagonal
    /// entry `Σ_{l≥j} U_jl² D_l`, unscaled, times [`Self::noise_variance`]; `None` when `c` is
    /// not in the information.
    pub fn variance(&self, c: usize) -> Option<f64> {
        let j = self.cols[..self.n].iter().position(|&x| x == c)?;
        Some(self.noise_variance() * self.covariance(j, j) / (self.scale[j] * self.scale[j]))
    }

    /// `(U D Uᵀ)_ab = Σ_{j ≥ max(a, b)} u_aj d_j u_bj` (factor rows `a`, `b`; scaled, per unit
    /// noise variance).
    fn covariance(&self, a: usize, b: usize) -> f64 {
        let unit = |r: usize, j: usize| if r == j { 1.0 } else { self.u[r][j] };
        (a.max(b)..self.n)
            .map(|j| unit(a, j) * self.d[j] * unit(b, j))
            .sum()
    }

    /// `δᵀ P⁻¹ δ` [N²]: how much worse `θ̂ + δ` predicts the data.
    pub fn distance2(&self, delta: &[f64; N]) -> f64 {
        let mut r = [0.0; N];
        let n = self.whiten(delta, &mut r);
        r[..n].iter().map(|v| v * v).sum()
    }

    /// `√(δᵀ P⁻¹ δ / Σ λᵏ yₖ²)`: the RMS prediction error `θ̂ + δ` adds, relative to the RMS
    /// output [1].
    pub fn relative(&self, delta: &[f64; N]) -> f64 {
        (self.distance2(delta) / self.output_energy).sqrt()
    }

    /// `θ̂_Oᵀ P_OO⁻¹ θ̂_O` [N²]: how much worse the data the estimate came from are predicted when
    /// the coefficients `omitted` are held at 0 and the others refitted — least squares on the
    /// same forgotten data, so it is the constrained fit's extra squared error, exactly (the
    /// prior's small pull aside). `P_OO` is the omitted coefficients' block of the covariance
    /// (the others, and the constant columns, marginalised out). Columns not in the information
    /// cost nothing. `None` when a number is not finite or the block is not positive definite.
    pub fn omission_cost(&self, theta: &[f64; N], omitted: Columns) -> Option<f64> {
        let mut rows = [0; N];
        let mut m = 0;
        for k in (0..self.n).filter(|&k| omitted.contains(self.cols[k])) {
            rows[m] = k;
            m += 1;
        }
        let rows = &rows[..m];
        // Identity outside the omitted block, zero right-hand side: one fixed-size factor.
        let mut p = SMatrix::<f64, N, N>::identity();
        let mut v = SVector::<f64, N>::zeros();
        for (i, &a) in rows.iter().enumerate() {
            v[i] = theta[self.cols[a]] * self.scale[a];
            for (l, &b) in rows.iter().enumerate() {
                p[(i, l)] = self.covariance(a, b);
            }
        }
        if !(p.iter().all(|x| x.is_finite()) && v.iter().all(|x| x.is_finite())) {
            return None;
        }
        let cost = v.dot(&p.cholesky()?.solve(&v));
        cost.is_finite().then_some(cost.max(0.0))
    }

    /// `Σₖ λᵏ yₖ²` [N²].
    pub fn output_energy(&self) -> f64 {
        self.output_energy
    }

    /// The variance of the output's noise per independent sample [N²]: the error power times
    /// the samples it stays correlated over ([`Self::with_correlation`]), so that a spread
    /// computed from `P`, which counts every sample as independent, is not too small by the
    /// square root of that count.
    pub fn noise_variance(&self) -> f64 {
        self.noise_variance * self.correlation_samples
    }

    /// The output's errors stay correlated over `samples` consecutive samples (≥ 1): a regression
    /// filtered at `f_c` and sampled at `f_s` has about `f_s/(2 f_c)`.
    pub fn with_correlation(mut self, samples: f64) -> Information {
        if samples.is_finite() && samples >= 1.0 {
            self.correlation_samples = samples;
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A three-coefficient factor `U D Uᵀ` with its scales.
    const COLS: [usize; 3] = [col::A, col::C, col::F];
    const SCALE: [f64; 3] = [2.0, 0.5, 4.0];
    const U: [[f64; 3]; 3] = [[1.0, 0.3, -0.7], [0.0, 1.0, 0.2], [0.0, 0.0, 1.0]];
    const D: [f64; 3] = [0.5, 2.0, 0.1];

    fn info(output_energy: f64, noise_variance: f64) -> Information {
        Information::new(
            &COLS,
            &SCALE,
            |i, j| U[i][j],
            &D,
            output_energy,
            noise_variance,
        )
        .unwrap()
    }

    /// `U D Uᵀ` (scaled), densely.
    fn dense_p() -> nalgebra::Matrix3<f64> {
        nalgebra::Matrix3::from_fn(|i, j| (0..3).map(|k| U[i][k] * D[k] * U[j][k]).sum())
    }

    /// `|D^{−½} U⁻¹ δ|²` equals `δᵀ (U D Uᵀ)⁻¹ δ` computed densely.
    #[test]
    fn whitening_is_the_inverse_covariance_norm() {
        let info = info(10.0, 0.0);
        let p = dense_p();
        let mut delta = [0.0; N];
        delta[col::A] = 0.3;
        delta[col::C] = -1.1;
        delta[col::F] = 0.05;
        delta[col::B] = 99.0; // not in the information: ignored
        let ds = nalgebra::Vector3::new(0.3 * 2.0, -1.1 * 0.5, 0.05 * 4.0);
        let want = (ds.transpose() * p.try_inverse().unwrap() * ds)[0];
        let got = info.distance2(&delta);
        assert!(
            (got - want).abs() < 1e-12 * want.abs().max(1.0),
            "{got} vs {want}"
        );
        assert!((info.relative(&delta) - (want / 10.0).sqrt()).abs() < 1e-12);
        assert!(
            Information::new(&COLS, &SCALE, |i, j| U[i][j], &[0.5, 0.0, 1.0], 1.0, 0.0).is_none()
        );
    }

    /// A coefficient's variance is `P`'s diagonal entry, unscaled, times the noise variance
    /// (and the samples it stays correlated over).
    #[test]
    fn variance_is_the_unscaled_covariance_diagonal() {
        let info = info(10.0, 0.3).with_correlation(4.0);
        let p = dense_p();
        for (k, &c) in COLS.iter().enumerate() {
            let want = 0.3 * 4.0 * p[(k, k)] / (SCALE[k] * SCALE[k]);
            let got = info.variance(c).unwrap();
            assert!((got - want).abs() < 1e-12 * want, "{c}: {got} vs {want}");
        }
        assert_eq!(info.variance(col::B), None);
    }
}
