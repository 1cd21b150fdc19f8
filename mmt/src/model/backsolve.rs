//! Back-solve θ → φ: regression coefficients to physical parameters (numerics notes §2).
//!
//! θ has one more linear-part coefficient than φ has unknowns, so an estimate generally lies off
//! the model manifold, and every single closed form has a degenerate case (one of them exactly at
//! the thesis's test set). The algorithm (notes §2.3):
//!
//! 1. `b2 = a/e` (leading coefficients; exact).
//! 2. Candidate `k2` from every closed form: the (C)+(D) and (B)+(C) quadratics, the (B)+(D)
//!    cubic, their common root, and the real negative roots `r` of `N(s) = a s³ + b s² + c s + d`
//!    (`k2 = −r·b2`). Each polynomial was checked symbolically to have the true `k2` as a root.
//! 3. For each candidate, `1/S` by a 1-D weighted least-squares fit to (B), (C), (D); then
//!    `m = e S`, `k1 = S − k2`, `b1 = f S − b2`.
//! 4. Score every candidate on all equations, keep the best, polish it with Levenberg–Marquardt
//!    on log-parameters (positivity for free). `Fc` enters linearly and is solved in closed form.
//! 5. Report the relative residual and the conditioning of `∂ log θ/∂ log φ`; flag a mass that
//!    the identification band cannot see (`m → 0`) as not identifiable instead of inventing
//!    numbers, and `k1 ≫ k2` (notes §2.5: condition 171, errors amplified 60×) as low confidence.

use super::{KelvinVoigt, Physical, Structure, Theta, col};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Settings of the back-solve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BackSolveConfig {
    /// Highest angular frequency the identification data carries [rad/s]: the state-variable
    /// filter's cut-off. Default 2π·10 rad/s (the thesis's 10 Hz filter).
    pub band_rad_s: f64,
    /// Minimum sensitivity `|∂ log(F/X)/∂ log m|` at the band edge for the mass to count as
    /// identifiable. Default 1e-2: if doubling the mass changes the force by less than 1 % in the
    /// band, the data cannot tell the mass apart from zero.
    pub min_mass_visibility: f64,
    /// Condition number of the log-sensitivity `∂ log θ/∂ log φ` above which the estimate is
    /// reported as low confidence. Default 15: well-conditioned sets measure 3.6–7 (typical 4.0,
    /// thesis appendix-E set 7.0, exp-1 5.0); k1 = 5000 ≫ k2 = 300 measures 26 and turns 1 % noise
    /// on θ into 7 % median error on φ.
    pub max_condition: f64,
    /// Levenberg–Marquardt iteration cap. Default 40.
    pub max_iterations: usize,
}

impl Default for BackSolveConfig {
    fn default() -> Self {
        BackSolveConfig {
            band_rad_s: 2.0 * std::f64::consts::PI * 10.0,
            min_mass_visibility: 1e-2,
            max_condition: 15.0,
            max_iterations: 40,
        }
    }
}

/// The physical parameters recovered from θ.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Params {
    /// Free space: nothing to render.
    Free,
    /// Kelvin–Voigt contact.
    KelvinVoigt(KelvinVoigt),
    /// The sliding flexible object (terms the structure leaves out are exactly 0).
    SlidingMass(Physical),
}

/// How far the recovered parameters can be trusted.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Confidence {
    /// Well conditioned.
    Identified,
    /// The parameters exist but some are nearly unobservable (e.g. `k1 ≫ k2`): relative errors
    /// in θ are amplified up to `condition` times in φ.
    Low {
        /// Condition number of `∂ log θ/∂ log φ`.
        condition: f64,
    },
}

/// The result of a successful back-solve.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BackSolved {
    /// The recovered parameters.
    pub params: Params,
    /// Misfit of the linear-part coefficients relative to the size of their polynomial in the
    /// identification band: for each coefficient of `N(s) = a s³ + b s² + c s + d` and
    /// `D(s) = e s² + f s + 1`, `|θ̂ᵢ − hᵢ(φ)| ωᵏ / Σⱼ |θ̂ⱼ| ωʲ` maximised over
    /// `ω ∈ {band/10, band/3, band}`, then RMS over the coefficients. It equals the relative error
    /// of a coefficient that dominates its polynomial somewhere in the band, and ignores
    /// coefficients that never matter there (e.g. `d` when `k1 ≈ 0`). 0 on the model manifold.
    pub residual: f64,
    /// Condition number of `∂ log θ/∂ log φ` at the solution (1 for Kelvin–Voigt).
    pub condition: f64,
    /// Whether the numbers can be trusted.
    pub confidence: Confidence,
}

/// Why θ could not be turned into physical parameters.
#[derive(Clone, Copy, Debug, PartialEq, Error, Serialize, Deserialize)]
pub enum BackSolveError {
    /// A coefficient is NaN or infinite.
    #[error("coefficient {name} is not finite ({value})")]
    NonFinite {
        /// Coefficient name (`a`..`h`).
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A coefficient that must be positive is not.
    #[error("coefficient {name} = {value} must be positive")]
    NotPositive {
        /// Coefficient name.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The mass is invisible in the identification band (`m → 0`): `b2 = a/e` is 0/0 and the
    /// model is symmetric under (k1, b1) ↔ (k2, b2), so no unique answer exists.
    #[error(
        "mass not identifiable: |∂ log(F/X)/∂ log m| = {visibility:.3e} in the identification band (need ≥ {required:.1e})"
    )]
    MassNotIdentifiable {
        /// `|∂ log(F/X)/∂ log m|` at the band edge.
        visibility: f64,
        /// The configured minimum.
        required: f64,
    },
    /// No closed form gave a positive candidate.
    #[error("no positive candidate for the contact stiffness k2")]
    NoCandidate,
}

/// Recovers the physical parameters of `structure` from θ. `weights`, if given, are per
/// coefficient inverse standard deviations (e.g. from the RLS covariance); otherwise relative
/// weights `1/|θ̂ᵢ|` are used.
pub fn back_solve(
    structure: Structure,
    theta: &Theta,
    weights: Option<&[f64; col::COUNT]>,
    config: &BackSolveConfig,
) -> Result<BackSolved, BackSolveError> {
    let cols = structure.columns();
    for i in cols.indices() {
        let v = theta.0[i];
        if !v.is_finite() {
            return Err(BackSolveError::NonFinite {
                name: col::NAMES[i],
                value: v,
            });
        }
    }
    match structure {
        Structure::Free => Ok(BackSolved {
            params: Params::Free,
            residual: 0.0,
            condition: 1.0,
            confidence: Confidence::Identified,
        }),
        Structure::KelvinVoigt => Ok(BackSolved {
            params: Params::KelvinVoigt(KelvinVoigt {
                k_n_per_m: theta.0[col::D],
                b_ns_per_m: theta.0[col::C],
            }),
            residual: 0.0,
            condition: 1.0,
            confidence: Confidence::Identified,
        }),
        Structure::SlidingMass {
            ground_spring,
            friction,
        } => sliding_mass(theta, ground_spring, friction, weights, config),
    }
}

fn sliding_mass(
    theta: &Theta,
    ground_spring: bool,
    friction: bool,
    weights: Option<&[f64; col::COUNT]>,
    config: &BackSolveConfig,
) -> Result<BackSolved, BackSolveError> {
    let t = &theta.0;
    let not_identifiable = |visibility| BackSolveError::MassNotIdentifiable {
        visibility,
        required: config.min_mass_visibility,
    };
    if t[col::A] == 0.0 && t[col::E] == 0.0 {
        return Err(not_identifiable(0.0));
    }
    for i in [col::A, col::E, col::F] {
        if t[i] <= 0.0 {
            return Err(BackSolveError::NotPositive {
                name: col::NAMES[i],
                value: t[i],
            });
        }
    }
    let problem = Problem::new(theta, ground_spring, friction, weights, config.band_rad_s);
    let best = candidates(t, ground_spring)
        .filter_map(|k2| problem.start_from_k2(k2))
        .map(|q| (problem.cost(&q), q))
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .ok_or(BackSolveError::NoCandidate)?
        .1;
    let q = problem.levenberg_marquardt(best, config.max_iterations);
    let physical = problem.physical(&q);
    let visibility = mass_visibility(&physical, config.band_rad_s);
    if !(visibility >= config.min_mass_visibility) {
        return Err(not_identifiable(visibility));
    }
    let condition = problem.condition(&q);
    let confidence = if condition > config.max_condition {
        Confidence::Low { condition }
    } else {
        Confidence::Identified
    };
    Ok(BackSolved {
        params: Params::SlidingMass(physical),
        residual: problem.relative_residual(&physical),
        condition,
        confidence,
    })
}

/// `|∂ log(F/X)/∂ log m| = |m (iω)² Z2 / (Z1 (Z1 + Z2))|`, the largest over the band.
fn mass_visibility(p: &Physical, band_rad_s: f64) -> f64 {
    [0.25, 0.5, 1.0]
        .iter()
        .map(|frac| {
            let s = num_complex::Complex64::new(0.0, frac * band_rad_s);
            let z1 = s * s * p.mass_kg + s * p.b_ground_ns_per_m + p.k_ground_n_per_m;
            let z2 = s * p.b_contact_ns_per_m + p.k_contact_n_per_m;
            (s * s * p.mass_kg * z2 / (z1 * (z1 + z2))).norm()
        })
        .fold(0.0, f64::max)
}

/// Candidate contact stiffnesses from every closed form (notes §2.2). Non-positive and non-finite
/// values are filtered out later.
fn candidates(t: &[f64; col::COUNT], ground_spring: bool) -> impl Iterator<Item = f64> {
    let (a, b, c, d, e, f) = (
        t[col::A],
        t[col::B],
        t[col::C],
        t[col::D],
        t[col::E],
        t[col::F],
    );
    let b2 = a / e;
    let mut out = [f64::NAN; 12];
    if ground_spring {
        let beta = b - f * b2;
        let gamma = c - b2;
        let mut n = 0;
        let mut push = |v: f64, out: &mut [f64; 12]| {
            if n < out.len() {
                out[n] = v;
                n += 1;
            }
        };
        // (C)+(D): f u² − (b2 + c) u + 2 b2 d = 0
        for r in quadratic_roots(f, -(b2 + c), 2.0 * b2 * d)
            .into_iter()
            .flatten()
        {
            push(r, &mut out);
        }
        // (B)+(C): 2e u² − (b2 f + 2β) u + b2 γ = 0
        for r in quadratic_roots(2.0 * e, -(b2 * f + 2.0 * beta), b2 * gamma)
            .into_iter()
            .flatten()
        {
            push(r, &mut out);
        }
        // (B)+(D): e u³ − β u² − b2² u + b2² d = 0
        for r in cubic_roots(e, -beta, -b2 * b2, b2 * b2 * d)
            .into_iter()
            .flatten()
        {
            push(r, &mut out);
        }
        // Common root of the two quadratics (0/0 when b1² = b2² + 4 k1 m).
        push(
            b2 * (f * c - f * b2 - 4.0 * e * d) / (2.0 * f * b - f * f * b2 - 2.0 * e * (b2 + c)),
            &mut out,
        );
        // Z2 = b2 s + k2 divides N(s): its real negative roots r give k2 = −r·b2.
        for r in cubic_roots(a, b, c, d).into_iter().flatten() {
            push(-r * b2, &mut out);
        }
    } else {
        // k1 = 0: c = b1 and f = (b1 + b2)/k2, so k2 = (c + b2)/f; (B) gives e u² − b u + c b2 = 0.
        out[0] = (c + b2) / f;
        let [r0, r1] = quadratic_roots(e, -b, c * b2);
        out[1] = r0.unwrap_or(f64::NAN);
        out[2] = r1.unwrap_or(f64::NAN);
    }
    out.into_iter().filter(|v| v.is_finite() && *v > 0.0)
}

/// Number of linear-part unknowns: m, b1, k2, b2 and (with a ground spring) k1.
const MAX_P: usize = 5;

/// The weighted least-squares problem in log-parameters `q = log [m, b1, k2, b2, (k1)]`.
struct Problem {
    theta: [f64; col::COUNT],
    weight: [f64; col::COUNT],
    /// Linear-part columns in the fit.
    rows: [usize; 6],
    n_rows: usize,
    p: usize,
    ground_spring: bool,
    friction: bool,
    band_rad_s: f64,
}

impl Problem {
    fn new(
        theta: &Theta,
        ground_spring: bool,
        friction: bool,
        weights: Option<&[f64; col::COUNT]>,
        band_rad_s: f64,
    ) -> Self {
        let t = theta.0;
        let mut weight = [0.0; col::COUNT];
        for i in 0..col::COUNT {
            // Relative weights; a coefficient below 1e-6 of its polynomial at the band edge is
            // floored there, so an exact zero (k1 = 0 in a full model) gets a large, finite weight.
            let floor = 1e-6 * band_scale(&t, i, band_rad_s);
            weight[i] = match weights {
                Some(w) if w[i].is_finite() && w[i] > 0.0 => w[i],
                _ => 1.0 / t[i].abs().max(floor).max(f64::MIN_POSITIVE),
            };
        }
        let (rows, n_rows) = if ground_spring {
            ([col::A, col::B, col::C, col::D, col::E, col::F], 6)
        } else {
            ([col::A, col::B, col::C, col::E, col::F, 0], 5)
        };
        Problem {
            theta: t,
            weight,
            rows,
            n_rows,
            p: if ground_spring { 5 } else { 4 },
            ground_spring,
            friction,
            band_rad_s,
        }
    }

    /// Completes a candidate `k2` into a full start point (notes §2.2: `1/S` by LS over (B), (C),
    /// (D)), or `None` if it is not physical.
    fn start_from_k2(&self, u: f64) -> Option<[f64; MAX_P]> {
        let t = &self.theta;
        let (b, c, d, e, f) = (t[col::B], t[col::C], t[col::D], t[col::E], t[col::F]);
        let b2 = t[col::A] / e;
        let s = if self.ground_spring {
            // α_i = β_i·w with weights 1/|θ_i|.
            let eqs = [
                (e * u - (b - f * b2), b2 * b2, self.weight[col::B]),
                (f * u - (c - b2), 2.0 * b2 * u, self.weight[col::C]),
                (u - d, u * u, self.weight[col::D]),
            ];
            let (num, den) = eqs.iter().fold((0.0, 0.0), |(n, dn), (al, be, w)| {
                (n + w * w * al * be, dn + w * w * be * be)
            });
            let w = num / den;
            if !(w.is_finite() && w > 0.0) {
                return None;
            }
            (1.0 / w).max(u)
        } else {
            u
        };
        let floor = |v: f64, scale: f64| v.max(1e-9 * scale);
        let m = floor(e * s, e * s.abs().max(1.0));
        let b1 = floor(f * s - b2, b2);
        let k1 = floor(s - u, u);
        let q = [m.ln(), b1.ln(), u.ln(), b2.ln(), k1.ln()];
        q.iter().all(|v| v.is_finite()).then_some(q)
    }

    fn physical(&self, q: &[f64; MAX_P]) -> Physical {
        let mut p = Physical {
            mass_kg: q[0].exp(),
            b_ground_ns_per_m: q[1].exp(),
            k_contact_n_per_m: q[2].exp(),
            b_contact_ns_per_m: q[3].exp(),
            k_ground_n_per_m: if self.ground_spring { q[4].exp() } else { 0.0 },
            coulomb_n: 0.0,
        };
        if self.friction {
            p.coulomb_n = self.coulomb(&p);
        }
        p
    }

    /// `Fc` by weighted LS from `g = k2 Fc/S`, `h = b2 Fc/S`, clamped at 0.
    fn coulomb(&self, p: &Physical) -> f64 {
        let s = p.stiffness_sum();
        let (wg, wh) = (self.weight[col::G], self.weight[col::H]);
        let (xg, xh) = (p.k_contact_n_per_m / s, p.b_contact_ns_per_m / s);
        let num = wg * wg * xg * self.theta[col::G] + wh * wh * xh * self.theta[col::H];
        let den = wg * wg * xg * xg + wh * wh * xh * xh;
        (num / den).max(0.0)
    }

    fn residuals(&self, q: &[f64; MAX_P], out: &mut [f64; 6]) {
        let mut p = self.physical(q);
        p.coulomb_n = 0.0;
        let h = p
            .theta()
            .map(|t| t.0)
            .unwrap_or([f64::INFINITY; col::COUNT]);
        for (k, &i) in self.rows[..self.n_rows].iter().enumerate() {
            out[k] = self.weight[i] * (self.theta[i] - h[i]);
        }
    }

    fn cost(&self, q: &[f64; MAX_P]) -> f64 {
        let mut r = [0.0; 6];
        self.residuals(q, &mut r);
        let c: f64 = r[..self.n_rows].iter().map(|v| v * v).sum();
        if c.is_finite() { c } else { f64::INFINITY }
    }

    /// Levenberg–Marquardt with a central-difference Jacobian in log space (the residual is a
    /// handful of flops, so differences cost nothing and cannot get the algebra wrong).
    fn levenberg_marquardt(&self, mut q: [f64; MAX_P], iterations: usize) -> [f64; MAX_P] {
        let (n, p) = (self.n_rows, self.p);
        let mut cost = self.cost(&q);
        let mut mu = 1e-3;
        let mut r = [0.0; 6];
        for _ in 0..iterations {
            let jac = self.jacobian(&q);
            self.residuals(&q, &mut r);
            // Normal equations (JᵀJ + μ diag JᵀJ) δ = −Jᵀr.
            let mut jtj = [[0.0; MAX_P]; MAX_P];
            let mut jtr = [0.0; MAX_P];
            for i in 0..p {
                for k in 0..n {
                    jtr[i] += jac[k][i] * r[k];
                }
                for j in 0..p {
                    jtj[i][j] = (0..n).map(|k| jac[k][i] * jac[k][j]).sum();
                }
            }
            let mut improved = false;
            for _ in 0..12 {
                let mut lhs = jtj;
                for (i, row) in lhs.iter_mut().enumerate().take(p) {
                    row[i] += mu * row[i].max(1e-12);
                }
                let Some(step) = cholesky_solve(&lhs, &jtr, p) else {
                    mu *= 10.0;
                    continue;
                };
                let mut trial = q;
                for i in 0..p {
                    trial[i] -= step[i].clamp(-2.0, 2.0);
                }
                let trial_cost = self.cost(&trial);
                if trial_cost < cost {
                    let gain = cost - trial_cost;
                    q = trial;
                    cost = trial_cost;
                    mu = (mu * 0.3).max(1e-12);
                    improved = gain > 1e-15 * (1.0 + cost);
                    break;
                }
                mu *= 10.0;
            }
            if !improved {
                break;
            }
        }
        q
    }

    /// `∂r/∂q` by central differences.
    fn jacobian(&self, q: &[f64; MAX_P]) -> [[f64; MAX_P]; 6] {
        let mut jac = [[0.0; MAX_P]; 6];
        let step = 1e-6;
        let (mut rp, mut rm) = ([0.0; 6], [0.0; 6]);
        for j in 0..self.p {
            let (mut qp, mut qm) = (*q, *q);
            qp[j] += step;
            qm[j] -= step;
            self.residuals(&qp, &mut rp);
            self.residuals(&qm, &mut rm);
            for k in 0..self.n_rows {
                jac[k][j] = (rp[k] - rm[k]) / (2.0 * step);
            }
        }
        jac
    }

    /// Condition number of `∂ log θ/∂ log φ` (rows: fitted coefficients; columns: parameters).
    /// Fixed-size matrices (the two shapes a problem has: 5 × 4, 6 × 5), so that the telerobot's
    /// real-time loop, which back-solves, allocates nothing.
    fn condition(&self, q: &[f64; MAX_P]) -> f64 {
        let base = self.model_theta(q);
        let step = 1e-6;
        let mut m = [[0.0; MAX_P]; 6];
        for j in 0..self.p {
            let (mut qp, mut qm) = (*q, *q);
            qp[j] += step;
            qm[j] -= step;
            let (tp, tm) = (self.model_theta(&qp), self.model_theta(&qm));
            for (k, &i) in self.rows[..self.n_rows].iter().enumerate() {
                m[k][j] = (tp[i].ln() - tm[i].ln()) / (2.0 * step);
            }
        }
        if !base.iter().all(|v| v.is_finite()) {
            return f64::INFINITY;
        }
        let extremes = |sv: &[f64]| {
            sv.iter().fold((0.0f64, f64::INFINITY), |(mx, mn), &s| {
                (mx.max(s), mn.min(s))
            })
        };
        let (max, min) = match (self.n_rows, self.p) {
            (5, 4) => extremes(
                nalgebra::SMatrix::<f64, 5, 4>::from_fn(|k, j| m[k][j])
                    .singular_values()
                    .as_slice(),
            ),
            _ => extremes(
                nalgebra::SMatrix::<f64, 6, 5>::from_fn(|k, j| m[k][j])
                    .singular_values()
                    .as_slice(),
            ),
        };
        if min > 0.0 { max / min } else { f64::INFINITY }
    }

    fn model_theta(&self, q: &[f64; MAX_P]) -> [f64; col::COUNT] {
        self.physical(q)
            .theta()
            .map(|t| t.0)
            .unwrap_or([f64::NAN; col::COUNT])
    }

    fn relative_residual(&self, p: &Physical) -> f64 {
        let Some(h) = p.theta() else {
            return f64::INFINITY;
        };
        let rows = &self.rows[..self.n_rows];
        let sum: f64 = rows
            .iter()
            .map(|&i| {
                [0.1, 1.0 / 3.0, 1.0]
                    .iter()
                    .map(|frac| {
                        let w = frac * self.band_rad_s;
                        (self.theta[i] - h.0[i]).abs() * w.powi(ORDER[i])
                            / band_poly(&self.theta, i, w)
                    })
                    .fold(0.0, f64::max)
                    .powi(2)
            })
            .sum();
        (sum / rows.len() as f64).sqrt()
    }
}

/// Power of `s` each coefficient multiplies in its polynomial (`N`, `D` or the friction term).
const ORDER: [i32; col::COUNT] = [3, 2, 1, 0, 2, 1, 0, 1];

/// `Σⱼ |θⱼ| ωʲ` over the polynomial that coefficient `i` belongs to (`D` includes its constant 1).
fn band_poly(t: &[f64; col::COUNT], i: usize, w: f64) -> f64 {
    let members: &[usize] = match i {
        col::A | col::B | col::C | col::D => &[col::A, col::B, col::C, col::D],
        col::E | col::F => &[col::E, col::F],
        _ => &[col::G, col::H],
    };
    let constant = if matches!(i, col::E | col::F) {
        1.0
    } else {
        0.0
    };
    members
        .iter()
        .map(|&j| t[j].abs() * w.powi(ORDER[j]))
        .sum::<f64>()
        + constant
}

/// The size coefficient `i` would need to contribute as much as its whole polynomial at `w`.
fn band_scale(t: &[f64; col::COUNT], i: usize, w: f64) -> f64 {
    band_poly(t, i, w) / w.powi(ORDER[i])
}

/// Solves `A x = b` for the leading `p×p` block of a symmetric positive-definite `A`.
fn cholesky_solve(a: &[[f64; MAX_P]; MAX_P], b: &[f64; MAX_P], p: usize) -> Option<[f64; MAX_P]> {
    let mut l = [[0.0; MAX_P]; MAX_P];
    for i in 0..p {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                let d = a[i][i] - s;
                if !(d > 0.0 && d.is_finite()) {
                    return None;
                }
                l[i][i] = d.sqrt();
            } else {
                l[i][j] = (a[i][j] - s) / l[j][j];
            }
        }
    }
    let mut y = [0.0; MAX_P];
    for i in 0..p {
        y[i] = (b[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0; MAX_P];
    for i in (0..p).rev() {
        x[i] = (y[i] - (i + 1..p).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Real roots of `a x² + b x + c` (numerically stable form), or of the linear equation if `a = 0`.
pub(crate) fn quadratic_roots(a: f64, b: f64, c: f64) -> [Option<f64>; 2] {
    if a == 0.0 {
        return [(b != 0.0).then(|| -c / b), None];
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 || !disc.is_finite() {
        return [None, None];
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    let r1 = q / a;
    let r2 = if q != 0.0 { c / q } else { r1 };
    [Some(r1), Some(r2)]
}

/// Real roots of `a x³ + b x² + c x + d` (trigonometric/Cardano form, each root polished by two
/// Newton steps). Falls back to the quadratic when `a = 0`.
pub(crate) fn cubic_roots(a: f64, b: f64, c: f64, d: f64) -> [Option<f64>; 3] {
    if a == 0.0 || !a.is_finite() {
        let [r0, r1] = quadratic_roots(b, c, d);
        return [r0, r1, None];
    }
    let (p2, p1, p0) = (b / a, c / a, d / a);
    // Depressed cubic t³ + P t + Q with x = t − p2/3.
    let shift = p2 / 3.0;
    let pp = p1 - p2 * p2 / 3.0;
    let qq = 2.0 * p2 * p2 * p2 / 27.0 - p2 * p1 / 3.0 + p0;
    let disc = (qq / 2.0).powi(2) + (pp / 3.0).powi(3);
    let mut roots = [None; 3];
    if disc > 0.0 {
        let sq = disc.sqrt();
        let t = (-qq / 2.0 + sq).cbrt() + (-qq / 2.0 - sq).cbrt();
        roots[0] = Some(t - shift);
    } else if pp == 0.0 {
        roots[0] = Some(-shift);
    } else {
        let r = (-pp / 3.0).sqrt();
        let phi = (-qq / (2.0 * r * r * r)).clamp(-1.0, 1.0).acos();
        for (k, root) in roots.iter_mut().enumerate() {
            let t = 2.0 * r * ((phi + 2.0 * std::f64::consts::PI * k as f64) / 3.0).cos();
            *root = Some(t - shift);
        }
    }
    let poly = |x: f64| ((x + p2) * x + p1) * x + p0;
    let dpoly = |x: f64| (3.0 * x + 2.0 * p2) * x + p1;
    for root in roots.iter_mut().flatten() {
        for _ in 0..2 {
            let dp = dpoly(*root);
            if dp != 0.0 {
                let next = *root - poly(*root) / dp;
                if next.is_finite() {
                    *root = next;
                }
            }
        }
    }
    roots.map(|r| r.filter(|v| v.is_finite()))
}

#[cfg(test)]
mod tests;
