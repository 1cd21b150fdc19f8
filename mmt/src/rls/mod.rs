//! The estimator core: recursive least squares for `y = ψᵀθ` ([`crate::model`]) in Bierman's
//! U-D factorised form, on column-scaled regressors, with exponential forgetting, a bounded
//! covariance, a prediction-error signal and a new-object detector (numerics notes §6,
//! `DESIGN.md` §5 and §11.3).
//!
//! # Why U-D
//!
//! The textbook update (thesis eqs. 4–5) loses positive definiteness within seconds even in f64
//! at λ = 0.999 (numerics notes §6.2). Bierman's U-D form (G. J. Bierman, *Factorization Methods
//! for Discrete Sequential Estimation*, 1977, §V.3) keeps `P = U D Uᵀ` with `U` unit upper
//! triangular and `D > 0` *by construction*, costs about what the textbook form costs, needs no
//! square root, and forgetting is a division of `D`. Square-root information (QR) RLS is equally
//! robust, but it holds `P⁻¹`, so the covariance bound, the excitation of each direction and
//! the covariance the back-solve weights with need a triangular inversion per use; with U-D they
//! are read off directly.
//!
//! # Column scaling
//!
//! Raw regressor columns span 1e-2 … 1e4 (condition of `Σψψᵀ` 1e12; 1e3 after scaling). The
//! estimator works on `ψ_s = ψ ⊘ s`, `θ_s = θ ⊙ s`, so `ψ_sᵀθ_s = ψᵀθ`: an exact change of
//! variables that does not change the least-squares solution. The U-D recursion itself is
//! equivariant under diagonal scaling: with power-of-two scales and the prior carried over it
//! gives the same bits while the covariance bound is inactive (test
//! `power_of_two_scaling_changes_no_bits`). What the scaling makes meaningful are the isotropic
//! prior `P0 = p0·I` and the covariance bound, which compare directions of `θ_s`. The scales are
//! therefore **fixed** from the configuration ([`ColumnScales::for_excitation`]) and rounded to
//! powers of two: a running RMS would move the meaning of `p0` and of the bound with the user's
//! motion and make runs depend on history, and only the order of magnitude matters.
//!
//! # Per update (`φ` = scaled active regressor, `n` = active columns)
//!
//! ```text
//! e    = y − φᵀθ̂                                   a-priori error
//! λ_k  = clamp(tr P / (n p̄), λ, 1);   D ← D/λ_k      forgetting, never past tr P = n p̄
//! f = Uᵀφ,  g = D f,  α₀ = 1                        Bierman's observational update:
//! α_j = α_{j−1} + f_j g_j,  d_j ← d_j α_{j−1}/α_j
//! u_ij ← u_ij − b_i f_j/α_{j−1},  b_i ← b_i + u_ij g_j   (i < j, old u_ij),  b_j = g_j
//! θ̂   ← θ̂ + b e/α_n                                  (gain K = b/α_n = P φ/(1 + φᵀPφ))
//! ```
//!
//! The bound is the constant/bounded-trace idea (G. C. Goodwin & K. S. Sin, *Adaptive Filtering,
//! Prediction and Control*, 1984, §3.7) in its simplest form: forgetting is slowed so that
//! `tr P ≤ n p̄` (EFRA's upper bound, Salgado, Goodwin & Middleton 1988), which is what stops the
//! covariance winding up during a static hold (numerics notes §6.2: 3.5e5 without a bound).

mod config;
pub mod cusum;
#[cfg(test)]
mod tests;

use nalgebra::SMatrix;

use crate::model::backsolve::Information;
use crate::model::{Columns, Theta, col};
pub use config::{ColumnScales, RlsConfig, RlsError};
use config::{check_p0, validate};
pub use cusum::{Cusum, CusumConfig};

const N: usize = col::COUNT;

/// Whether a sample is learned from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// In contact and past the onset guard: update.
    Learn,
    /// Out of contact or in the guard: nothing changes — no update, no forgetting.
    Pause,
}

/// What [`Rls::update`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
#[must_use]
pub enum Outcome {
    /// Learned from the sample.
    Updated {
        /// A-priori error `y − ψᵀθ̂` [N] of the parameters before the sample.
        prior_error_n: f64,
        /// The detector saw the error of the old parameters jump: probably a new object. The
        /// caller decides whether to [`reset`](Rls::reset) the covariance.
        new_object: bool,
    },
    /// Paused: state untouched.
    Paused,
    /// A non-finite regressor entry or output: counted, state untouched.
    RejectedNonFinite,
    /// The factor left the positive-definite set (or overflowed): θ̂ kept from before the
    /// sample, covariance reset to `p0`, detector restarted, counted.
    CovarianceReset,
}

/// Event counters (reported, never logged per sample).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RlsCounts {
    /// Learned samples.
    pub updates: u64,
    /// Paused samples.
    pub paused: u64,
    /// Samples rejected for a non-finite entry.
    pub rejected_non_finite: u64,
    /// Covariance resets because the factor was not positive definite.
    pub not_positive_definite: u64,
    /// Explicit [`Rls::reset`] calls.
    pub resets: u64,
    /// New-object alarms.
    pub new_object_alarms: u64,
}

/// Bierman U-D recursive least squares over the active columns (fixed-size, no allocation).
#[derive(Clone, Debug, PartialEq)]
pub struct Rls {
    config: RlsConfig,
    n: usize,
    /// `idx[k]`: the [`col`] index of active column `k`.
    idx: [usize; N],
    /// `1/s` of active column `k`.
    inv_scale: [f64; N],
    /// `θ̂_s`, scaled, compact.
    theta_s: [f64; N],
    /// Unit upper triangular `U` (entries `i < j` used).
    u: [[f64; N]; N],
    /// `D`, the diagonal.
    d: [f64; N],
    /// EWMA of `e²` and of `y²`, and the last a-priori error.
    err2: f64,
    out2: f64,
    /// `Σₖ λᵏ yₖ²` with the forgetting the covariance had [N²].
    out_energy: f64,
    last_error: f64,
    cusum: Cusum,
    counts: RlsCounts,
}

impl Rls {
    /// An estimator with `θ̂ = 0` and `P = p0·I` (scaled).
    pub fn new(config: RlsConfig) -> Result<Rls, RlsError> {
        validate(&config)?;
        let mut idx = [0; N];
        let mut inv_scale = [0.0; N];
        let mut n = 0;
        // The constant columns first: then their covariance can be reset on its own
        // ([`Rls::reset_intercepts`]).
        let constants = [col::I, col::J];
        let first = constants
            .into_iter()
            .filter(|&i| config.columns.contains(i));
        let rest = config.columns.without(col::I).without(col::J).indices();
        for i in first.chain(rest) {
            idx[n] = i;
            inv_scale[n] = 1.0 / config.scales.0[i];
            n += 1;
        }
        let mut rls = Rls {
            config,
            n,
            idx,
            inv_scale,
            theta_s: [0.0; N],
            u: [[0.0; N]; N],
            d: [0.0; N],
            err2: 0.0,
            out2: 0.0,
            out_energy: 0.0,
            last_error: 0.0,
            cusum: Cusum::new(config.cusum),
            counts: RlsCounts::default(),
        };
        rls.reset_covariance(config.initial_covariance);
        Ok(rls)
    }

    /// Feeds one sample: the full regressor `psi` (inactive columns ignored) and output `y` [N].
    pub fn update(&mut self, psi: &[f64; N], y: f64, mode: Mode) -> Outcome {
        if mode == Mode::Pause {
            self.counts.paused += 1;
            return Outcome::Paused;
        }
        let n = self.n;
        let mut phi = [0.0; N];
        for k in 0..n {
            phi[k] = psi[self.idx[k]] * self.inv_scale[k];
        }
        if !y.is_finite() || !phi.iter().all(|v| v.is_finite()) {
            self.counts.rejected_non_finite += 1;
            return Outcome::RejectedNonFinite;
        }
        let e = y - dot(&phi, &self.theta_s);
        // Forgetting, slowed so that tr P never exceeds n·p̄.
        let bound = n as f64 * self.config.max_mean_variance;
        let lambda = (self.trace() / bound).clamp(self.config.forgetting, 1.0);
        // Bierman's update (module docs), in place; on failure θ̂ is restored and P reset.
        let (u, d) = (&mut self.u, &mut self.d);
        let mut f = [0.0; N];
        for j in 0..n {
            f[j] = phi[j] + (0..j).map(|i| u[i][j] * phi[i]).sum::<f64>();
        }
        let mut g = [0.0; N];
        let mut b = [0.0; N];
        let mut alpha = 1.0;
        for j in 0..n {
            d[j] /= lambda;
            g[j] = d[j] * f[j];
            let beta = alpha;
            alpha += f[j] * g[j];
            d[j] *= beta / alpha;
            let p = -f[j] / beta;
            for i in 0..j {
                let uij = u[i][j];
                u[i][j] = uij + b[i] * p;
                b[i] += uij * g[j];
            }
            b[j] = g[j];
        }
        let gain = e / alpha;
        let before = self.theta_s;
        for (t, bk) in self.theta_s.iter_mut().zip(&b) {
            *t += bk * gain;
        }
        let positive_definite = alpha.is_finite()
            && self.d[..n].iter().all(|&v| v > 0.0 && v.is_finite())
            && b[..n].iter().all(|v| v.is_finite())
            && self.theta_s[..n].iter().all(|v| v.is_finite());
        if !positive_definite {
            self.theta_s = before;
            self.reset_covariance(self.config.initial_covariance);
            self.counts.not_positive_definite += 1;
            return Outcome::CovarianceReset;
        }
        self.counts.updates += 1;
        // The information was forgotten by λ this update (D ← D/λ): the energy it was gathered
        // with is forgotten alike.
        self.out_energy = lambda * self.out_energy + y * y;
        let w = 1.0 / self.config.error_time_constant_samples;
        self.err2 += w * (e * e - self.err2);
        self.out2 += w * (y * y - self.out2);
        self.last_error = e;
        let new_object = self.cusum.update(e, y);
        if new_object {
            self.counts.new_object_alarms += 1;
        }
        Outcome::Updated {
            prior_error_n: e,
            new_object,
        }
    }

    /// Resets the covariance to `p0·I` (scaled units) — on a new object — keeping θ̂ as the
    /// prior, and restarts the detector's hold-off.
    pub fn reset(&mut self, p0: f64) -> Result<(), RlsError> {
        check_p0(p0, self.config.max_mean_variance)?;
        self.reset_covariance(p0);
        self.counts.resets += 1;
        Ok(())
    }

    /// Restarts the constant columns `i`, `j` (a new contact episode moves them: see
    /// [`col::I`]): their estimates become `values` [N] (a non-finite value keeps the old one)
    /// and their variances `p0` (scaled units), independent of the other coefficients, whose
    /// estimates and covariance are kept. Exact in U-D form: with the constants first,
    /// `P = Σⱼ dⱼ uⱼ uⱼᵀ` with `U` unit upper triangular, and setting the constants' rows of `U`
    /// to unit rows drops exactly their cross-covariances, leaving the rest of `P` unchanged. No
    /// effect without constant columns or when `p0` is not positive and finite.
    pub fn reset_intercepts(&mut self, values: [f64; 2], p0: f64) {
        if !(p0.is_finite() && p0 > 0.0) {
            return;
        }
        let k = self.idx[..self.n]
            .iter()
            .take_while(|&&i| i == col::I || i == col::J)
            .count();
        for r in 0..k {
            let axis = usize::from(self.idx[r] == col::J);
            if values[axis].is_finite() {
                self.theta_s[r] = values[axis] / self.inv_scale[r];
            }
            for j in r + 1..self.n {
                self.u[r][j] = 0.0;
            }
            self.d[r] = p0;
        }
    }

    /// Forgets the data so far by `rho` at once (`D ← D/ρ`, and the output energy alike), as
    /// `ln ρ / ln λ` updates of forgetting would, keeping θ̂: for data taken under a regressor
    /// since corrected. Never past `tr P = n·p̄`, the bound the forgetting keeps. No effect unless
    /// `0 < ρ < 1`.
    pub fn discount(&mut self, rho: f64) {
        if !(rho > 0.0 && rho < 1.0) {
            return;
        }
        let bound = self.n as f64 * self.config.max_mean_variance;
        let rho = rho.max(self.trace() / bound).min(1.0);
        for d in &mut self.d[..self.n] {
            *d /= rho;
        }
        self.out_energy *= rho;
    }

    /// Mutes the new-object detector for the next `samples` updates (see [`Cusum::mute`]).
    pub fn mute_detector(&mut self, samples: u32) {
        self.cusum.mute(samples);
    }

    /// The information the data gave about the coefficients other than the constants
    /// ([`Information`]: the constants marginalised out, which with them first in the factor is
    /// its lower-right block), with the forgotten output energy and the a-priori error power;
    /// `None` before any update.
    pub fn information(&self) -> Option<Information> {
        let k = self.idx[..self.n]
            .iter()
            .take_while(|&&i| i == col::I || i == col::J)
            .count();
        let n = self.n - k;
        let mut scale = [0.0; N];
        for (s, inv) in scale.iter_mut().zip(&self.inv_scale[k..self.n]) {
            *s = 1.0 / inv;
        }
        Information::new(
            &self.idx[k..self.n],
            &scale[..n],
            |i, j| self.u[k + i][k + j],
            &self.d[k..self.n],
            self.out_energy,
            self.err2,
        )
    }

    /// θ̂ in physical units, every [`col`] entry (zero for inactive columns).
    pub fn theta(&self) -> Theta {
        let mut t = [0.0; N];
        for k in 0..self.n {
            t[self.idx[k]] = self.theta_s[k] * self.inv_scale[k];
        }
        Theta(t)
    }

    /// The parameter covariance `P_θ = S⁻¹ U D Uᵀ S⁻¹` in physical units (8×8, zero rows and
    /// columns for inactive coefficients), for weighting the back-solve. Unit: that of
    /// `P0 = p0·I` scaled back, i.e. relative to a unit output-noise variance.
    pub fn covariance(&self) -> SMatrix<f64, N, N> {
        let mut p = SMatrix::<f64, N, N>::zeros();
        for a in 0..self.n {
            for c in a..self.n {
                // (U D Uᵀ)_{ac} = Σ_{j ≥ c} u_aj d_j u_cj, with u_jj = 1.
                let v: f64 = (c..self.n)
                    .map(|j| self.unit_u(a, j) * self.d[j] * self.unit_u(c, j))
                    .sum::<f64>()
                    * self.inv_scale[a]
                    * self.inv_scale[c];
                p[(self.idx[a], self.idx[c])] = v;
                p[(self.idx[c], self.idx[a])] = v;
            }
        }
        p
    }

    /// `tr P_s`, scaled units.
    pub fn trace(&self) -> f64 {
        (0..self.n)
            .map(|j| self.d[j] * (1.0 + (0..j).map(|i| self.u[i][j] * self.u[i][j]).sum::<f64>()))
            .sum()
    }

    /// Smallest entry of `D` (> 0 whenever the factor is positive definite).
    pub fn min_d(&self) -> f64 {
        self.d[..self.n]
            .iter()
            .copied()
            .fold(f64::INFINITY, f64::min)
    }

    /// The last a-priori error `y − ψᵀθ̂` [N].
    pub fn prior_error(&self) -> f64 {
        self.last_error
    }

    /// EWMA RMS of the output learnt from, `√E[y²]` [N] (0 before any update).
    pub fn output_rms(&self) -> f64 {
        self.out2.sqrt()
    }

    /// EWMA relative size of the a-priori error, `√(E[e²]/E[y²])`; `None` before any update.
    pub fn relative_error(&self) -> Option<f64> {
        (self.out2 > 0.0).then(|| (self.err2 / self.out2).sqrt())
    }

    /// The detector (its statistic, for reports).
    pub fn detector(&self) -> &Cusum {
        &self.cusum
    }

    /// Event counters.
    pub fn counts(&self) -> RlsCounts {
        self.counts
    }

    /// The active columns.
    pub fn columns(&self) -> Columns {
        self.config.columns
    }

    fn unit_u(&self, i: usize, j: usize) -> f64 {
        if i == j { 1.0 } else { self.u[i][j] }
    }

    fn reset_covariance(&mut self, p0: f64) {
        self.out_energy = 0.0;
        self.u = [[0.0; N]; N];
        self.d = [0.0; N];
        self.d[..self.n].fill(p0);
        self.cusum.restart();
    }
}

fn dot(a: &[f64; N], b: &[f64; N]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}
