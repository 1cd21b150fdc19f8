//! The least-squares problem of the back-solve in log-parameters, and its Levenberg–Marquardt
//! solver.

use super::super::{Physical, Theta, col};

use super::information::Information;

/// Number of linear-part unknowns: m, b1, k2, b2 and (with a ground spring) k1.
pub(super) const MAX_P: usize = 5;

/// Most residuals: one per coefficient.
const MAX_R: usize = col::COUNT;

/// How the misfit `θ̂ − θ(φ)` is measured.
#[derive(Clone, Copy, Debug)]
pub(super) enum Metric<'a> {
    /// Per-coefficient weights on the linear part (`a`–`f`); friction (`Fc`) is fitted after it
    /// from `g` and `h` alone.
    Diagonal,
    /// The data's information ([`Information`]): every coefficient the structure has, friction
    /// included (`Fc` solved in closed form at each step), weighted by how much the data
    /// constrain it — in newtons² of prediction error.
    Information(&'a Information),
}

/// The weighted least-squares problem in log-parameters `q = log [m, b1, k2, b2, (k1)]`.
pub(super) struct Problem<'a> {
    theta: [f64; col::COUNT],
    weight: [f64; col::COUNT],
    metric: Metric<'a>,
    /// Linear-part columns in the diagonal fit.
    rows: [usize; 6],
    n_rows: usize,
    pub(super) p: usize,
    /// The first free entry of `q`: 1 for a massless problem, whose mass is held at 0.
    first: usize,
    ground_spring: bool,
    friction: bool,
    band_rad_s: f64,
}

impl<'a> Problem<'a> {
    pub(super) fn new(
        theta: &Theta,
        ground_spring: bool,
        friction: bool,
        weights: Option<&[f64; col::COUNT]>,
        information: Option<&'a Information>,
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
            metric: information.map_or(Metric::Diagonal, Metric::Information),
            rows,
            n_rows,
            p: if ground_spring { 5 } else { 4 },
            first: 0,
            ground_spring,
            friction,
            band_rad_s,
        }
    }

    /// The problem of the massless model (`m = 0`, a first-order object): the mass is held at 0
    /// and left out of the fitted coefficients (`a`, `e`). Informed only: the data's information
    /// says how much worse than θ̂ the massless set predicts them, the mass's excitation included.
    pub(super) fn massless(
        theta: &Theta,
        ground_spring: bool,
        friction: bool,
        information: &'a Information,
        band_rad_s: f64,
    ) -> Self {
        let mut problem = Problem::new(
            theta,
            ground_spring,
            friction,
            None,
            Some(information),
            band_rad_s,
        );
        problem.first = 1;
        (problem.rows, problem.n_rows) = if ground_spring {
            ([col::B, col::C, col::D, col::F, 0, 0], 4)
        } else {
            ([col::B, col::C, col::F, 0, 0, 0], 3)
        };
        problem
    }

    /// Start points of the massless problem, from magnitudes only: in the directions the motion
    /// did not excite θ̂ can have any sign, and the informed fit pulls the start to the data. `b1`
    /// from `|c|` (`c = b1` without a ground spring), ratios `b2/b1` of 0.1–10, `k2` from `|f|`
    /// (`f = (b1 + b2)/S`) and a sweep of 10²–10⁴ N/m; with a ground spring, ratios `k1/k2` of
    /// 0.1–10.
    pub(super) fn massless_starts(&self) -> impl Iterator<Item = [f64; MAX_P]> + use<> {
        let t = &self.theta;
        let b1 = t[col::C].abs().max(1e-3);
        let f = t[col::F].abs();
        let mut out = [[f64::NAN; MAX_P]; 24];
        let mut n = 0;
        for ratio in [0.1, 1.0, 10.0] {
            let b2 = ratio * b1;
            for k2 in [(b1 + b2) / f, 1e2, 1e3, 1e4] {
                for rho in if self.ground_spring {
                    &[0.1, 1.0][..]
                } else {
                    &[0.0][..]
                } {
                    if n < out.len() {
                        out[n] = [0.0, b1.ln(), k2.ln(), b2.ln(), (rho * k2).ln()];
                        n += 1;
                    }
                }
            }
        }
        let free = if self.ground_spring { 5 } else { 4 };
        out.into_iter()
            .filter(move |q| q[1..free].iter().all(|v| v.is_finite()))
    }

    /// Completes a candidate `k2` into a full start point (notes §2.2: `1/S` by LS over (B), (C),
    /// (D)), or `None` if it is not physical.
    pub(super) fn start_from_k2(&self, u: f64) -> Option<[f64; MAX_P]> {
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

    /// The physical set of `q`, with `Fc` fitted to it.
    pub(super) fn physical(&self, q: &[f64; MAX_P]) -> Physical {
        let mut p = self.linear(q);
        if self.friction {
            p.coulomb_n = match self.metric {
                Metric::Diagonal => self.coulomb(&p),
                Metric::Information(info) => self.informed(info, &p, &mut [0.0; MAX_R]).1,
            };
        }
        p
    }

    /// The set of `q` without friction.
    fn linear(&self, q: &[f64; MAX_P]) -> Physical {
        Physical {
            mass_kg: if self.first > 0 { 0.0 } else { q[0].exp() },
            b_ground_ns_per_m: q[1].exp(),
            k_contact_n_per_m: q[2].exp(),
            b_contact_ns_per_m: q[3].exp(),
            k_ground_n_per_m: if self.ground_spring { q[4].exp() } else { 0.0 },
            coulomb_n: 0.0,
        }
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

    /// The whitened residual of the frictionless set `p` with the best `Fc ≥ 0`:
    /// `r(Fc) = r₀ + Fc·v` is linear in `Fc`, so `Fc = max(0, −r₀·v/|v|²)`. Returns the
    /// residual count and `Fc`.
    fn informed(&self, info: &Information, p: &Physical, out: &mut [f64; MAX_R]) -> (usize, f64) {
        let h = p
            .theta()
            .map(|t| t.0)
            .unwrap_or([f64::INFINITY; col::COUNT]);
        let mut delta = [0.0; col::COUNT];
        for i in 0..col::COUNT {
            if i != col::I && i != col::J {
                delta[i] = self.theta[i] - h[i];
            }
        }
        let n = info.whiten(&delta, out);
        if !(self.friction && info.contains(col::G)) {
            return (n, 0.0);
        }
        let s = p.stiffness_sum();
        let mut unit = [0.0; col::COUNT];
        unit[col::G] = -p.k_contact_n_per_m / s;
        unit[col::H] = -p.b_contact_ns_per_m / s;
        let mut v = [0.0; MAX_R];
        info.whiten(&unit, &mut v);
        let vv: f64 = v[..n].iter().map(|x| x * x).sum();
        let rv: f64 = (0..n).map(|k| out[k] * v[k]).sum();
        let fc = if vv > 0.0 { (-rv / vv).max(0.0) } else { 0.0 };
        for k in 0..n {
            out[k] += fc * v[k];
        }
        (n, if fc.is_finite() { fc } else { 0.0 })
    }

    fn residuals(&self, q: &[f64; MAX_P], out: &mut [f64; MAX_R]) -> usize {
        let p = self.linear(q);
        if let Metric::Information(info) = self.metric {
            return self.informed(info, &p, out).0;
        }
        let h = p
            .theta()
            .map(|t| t.0)
            .unwrap_or([f64::INFINITY; col::COUNT]);
        for (k, &i) in self.rows[..self.n_rows].iter().enumerate() {
            out[k] = self.weight[i] * (self.theta[i] - h[i]);
        }
        self.n_rows
    }

    pub(super) fn cost(&self, q: &[f64; MAX_P]) -> f64 {
        let mut r = [0.0; MAX_R];
        let n = self.residuals(q, &mut r);
        let c: f64 = r[..n].iter().map(|v| v * v).sum();
        if c.is_finite() { c } else { f64::INFINITY }
    }

    /// Levenberg–Marquardt with a central-difference Jacobian in log space (the residual is a
    /// handful of flops, so differences cost nothing and cannot get the algebra wrong).
    pub(super) fn levenberg_marquardt(
        &self,
        mut q: [f64; MAX_P],
        iterations: usize,
    ) -> [f64; MAX_P] {
        let p = self.p;
        let mut cost = self.cost(&q);
        let mut mu = 1e-3;
        let mut r = [0.0; MAX_R];
        for _ in 0..iterations {
            let (jac, _) = self.jacobian(&q);
            let n = self.residuals(&q, &mut r);
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
            self.hold_fixed(&mut jtj, &mut jtr);
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

    /// A held entry of `q` (a massless problem's mass) gets a unit diagonal and no gradient in
    /// the normal equations: its step is 0 and the others' are those of the free problem.
    fn hold_fixed(&self, jtj: &mut [[f64; MAX_P]; MAX_P], jtr: &mut [f64; MAX_P]) {
        for (i, g) in jtr.iter_mut().enumerate().take(self.first) {
            hold(jtj, i);
            *g = 0.0;
        }
    }

    /// Of a massless problem, the entries of `q` the fit drove to nothing: a damper below 10⁻⁶ of
    /// the other damper, a spring below 10⁻⁶ of the other spring. The data cannot see them (their
    /// log's Jacobian column vanishes with them), and what they contribute is nothing either way,
    /// so their spread is not asked for: the reduced model leaves them out. A term driven to
    /// infinity instead is not left out (it would matter beyond the data).
    fn vanished(&self, q: &[f64; MAX_P]) -> [bool; MAX_P] {
        let mut out = [false; MAX_P];
        if self.first == 0 {
            return out;
        }
        let tiny = 1e-6f64.ln();
        // q = log [m, b1, k2, b2, k1]
        out[1] = q[1] - q[3] < tiny;
        out[3] = q[3] - q[1] < tiny;
        if self.ground_spring {
            out[4] = q[4] - q[2] < tiny;
        }
        out
    }

    /// `p` with the terms [`Self::vanished`] at `q` set to exactly 0, as they are rendered and
    /// observed (a damper of 10⁻¹¹ N·s/m divides the contact observer's force by nothing).
    pub(super) fn without_vanished(&self, q: &[f64; MAX_P], mut p: Physical) -> Physical {
        let v = self.vanished(q);
        if v[1] {
            p.b_ground_ns_per_m = 0.0;
        }
        if v[3] {
            p.b_contact_ns_per_m = 0.0;
        }
        if v[4] {
            p.k_ground_n_per_m = 0.0;
        }
        p
    }

    /// `∂r/∂q` by central differences, and the residual count.
    fn jacobian(&self, q: &[f64; MAX_P]) -> ([[f64; MAX_P]; MAX_R], usize) {
        let mut jac = [[0.0; MAX_P]; MAX_R];
        let step = 1e-6;
        let (mut rp, mut rm) = ([0.0; MAX_R], [0.0; MAX_R]);
        let mut n = 0;
        for j in self.first..self.p {
            let (mut qp, mut qm) = (*q, *q);
            qp[j] += step;
            qm[j] -= step;
            n = self.residuals(&qp, &mut rp);
            self.residuals(&qm, &mut rm);
            for k in 0..n {
                jac[k][j] = (rp[k] - rm[k]) / (2.0 * step);
            }
        }
        (jac, n)
    }

    /// The standard deviation of each log-parameter `q` at the solution, from the data's
    /// information (`σ² (JᵀJ)⁻¹` with `J` the whitened residual's Jacobian, `Fc` profiled out,
    /// `σ²` the output's noise variance); `None` for the diagonal metric or a singular `JᵀJ`.
    pub(super) fn spread(&self, q: &[f64; MAX_P]) -> Option<[f64; MAX_P]> {
        let Metric::Information(info) = self.metric else {
            return None;
        };
        let (jac, n) = self.jacobian(q);
        let p = self.p;
        let mut jtj = [[0.0; MAX_P]; MAX_P];
        for i in 0..p {
            for j in 0..p {
                jtj[i][j] = (0..n).map(|k| jac[k][i] * jac[k][j]).sum();
            }
        }
        self.hold_fixed(&mut jtj, &mut [0.0; MAX_P]);
        let vanished = self.vanished(q);
        for (i, _) in vanished.iter().enumerate().filter(|(_, v)| **v) {
            hold(&mut jtj, i);
        }
        let mut out = [0.0; MAX_P];
        for (i, o) in out.iter_mut().enumerate().take(p).skip(self.first) {
            if vanished[i] {
                continue;
            }
            let mut e = [0.0; MAX_P];
            e[i] = 1.0;
            let col = cholesky_solve(&jtj, &e, p)?;
            *o = (info.noise_variance() * col[i]).sqrt();
        }
        out.iter().all(|v| v.is_finite()).then_some(out)
    }

    /// Condition number of `∂ log θ/∂ log φ` (rows: fitted coefficients; columns: parameters).
    /// Fixed-size matrices (the shapes a problem has: 5 × 4, 6 × 5,
    /// and 3 × 3, 4 × 4 massless), so that the telerobot's
    /// real-time loop, which back-solves, allocates nothing.
    pub(super) fn condition(&self, q: &[f64; MAX_P]) -> f64 {
        let base = self.model_theta(q);
        let step = 1e-6;
        let mut m = [[0.0; MAX_P]; 6];
        for j in self.first..self.p {
            let (mut qp, mut qm) = (*q, *q);
            qp[j] += step;
            qm[j] -= step;
            let (tp, tm) = (self.model_theta(&qp), self.model_theta(&qm));
            for (k, &i) in self.rows[..self.n_rows].iter().enumerate() {
                m[k][j - self.first] = (tp[i].ln() - tm[i].ln()) / (2.0 * step);
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
        let (max, min) = match (self.n_rows, self.p - self.first) {
            (3, 3) => extremes(
                nalgebra::SMatrix::<f64, 3, 3>::from_fn(|k, j| m[k][j])
                    .singular_values()
                    .as_slice(),
            ),
            (4, 4) => extremes(
                nalgebra::SMatrix::<f64, 4, 4>::from_fn(|k, j| m[k][j])
                    .singular_values()
                    .as_slice(),
            ),
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

    pub(super) fn relative_residual(&self, q: &[f64; MAX_P], p: &Physical) -> f64 {
        if let Metric::Information(info) = self.metric {
            return (self.cost(q) / info.output_energy()).sqrt();
        }
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
const ORDER: [i32; col::COUNT] = [3, 2, 1, 0, 2, 1, 0, 1, 0, 0];

/// `Σⱼ |θⱼ| ωʲ` over the polynomial that coefficient `i` belongs to (`D` includes its constant 1).
pub(super) fn band_poly(t: &[f64; col::COUNT], i: usize, w: f64) -> f64 {
    let members: &[usize] = match i {
        col::A | col::B | col::C | col::D => &[col::A, col::B, col::C, col::D],
        col::E | col::F => &[col::E, col::F],
        col::G | col::H => &[col::G, col::H],
        _ => &[col::I, col::J],
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
pub(super) fn band_scale(t: &[f64; col::COUNT], i: usize, w: f64) -> f64 {
    band_poly(t, i, w) / w.powi(ORDER[i])
}

/// Row and column `i` of `JᵀJ` zeroed and a unit diagonal: parameter `i` held where it is.
fn hold(jtj: &mut [[f64; MAX_P]; MAX_P], i: usize) {
    for row in jtj.iter_mut() {
        row[i] = 0.0;
    }
    jtj[i] = [0.0; MAX_P];
    jtj[i][i] = 1.0;
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
