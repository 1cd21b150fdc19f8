//! One-step methods for the mass-matrix model `M ż = J z + G u(t) + e₂ f` (numerics notes §4),
//! `f ∈ −Fc·Sgn(ẋ_m)` the set-valued Coulomb friction force.
//!
//! The renderer uses [`Sdirk2`]; the others exist for the work–precision study and as test
//! oracles (trapezoid has the exact bilinear frequency map; exact FOH is exact for a linearly
//! interpolated input). Within a step the input is linearly interpolated between its values at
//! the start (`u0`) and the end (`u1`) of the step — what a renderer has when it only sees
//! samples.
//!
//! Friction: the implicit methods solve it implicitly by projection (Kikuuwe et al., IROS 2005;
//! numerics notes §8): compute the friction-free update, then stick if the friction force needed to
//! stop the mass is within `Fc`, else slip with `−Fc·sgn`. No velocity band, no chatter. The
//! explicit methods and exact FOH take `f = −Fc sgn(ẋ_m)` at the start of the step (that is what
//! they can do; it chatters, which the study shows).

use crate::model::MassMatrixForm;
use serde::{Deserialize, Serialize};

/// `γ = 1 − 1/√2`: the L-stable, stiffly accurate 2-stage SDIRK of Alexander (1977).
pub const SDIRK_GAMMA: f64 = 1.0 - std::f64::consts::FRAC_1_SQRT_2;

/// The methods compared in the work–precision study.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Explicit (forward) Euler. Order 1, not A-stable.
    ExplicitEuler,
    /// Classical Runge–Kutta 4. Not A-stable (|hλ| ≤ 2.8).
    Rk4,
    /// Trapezoid (Tustin). Order 2, A-stable, |R(∞)| = 1 (stiff modes ring).
    Trapezoid,
    /// Backward Euler. Order 1, L-stable, dissipative.
    BackwardEuler,
    /// 2-stage SDIRK, γ = 1 − 1/√2. Order 2, L-stable, stiffly accurate. The renderer's method.
    Sdirk2,
    /// Exact discretisation for a first-order-hold (linearly interpolated) input.
    ExactFoh,
}

impl Method {
    /// Every method, in report order.
    pub const ALL: [Method; 6] = [
        Method::ExplicitEuler,
        Method::Rk4,
        Method::Trapezoid,
        Method::BackwardEuler,
        Method::Sdirk2,
        Method::ExactFoh,
    ];

    /// Report name.
    pub fn name(self) -> &'static str {
        match self {
            Method::ExplicitEuler => "explicit-euler",
            Method::Rk4 => "rk4",
            Method::Trapezoid => "trapezoid",
            Method::BackwardEuler => "backward-euler",
            Method::Sdirk2 => "sdirk2",
            Method::ExactFoh => "exact-foh",
        }
    }

    /// A stepper for `sys` with step `h` [s].
    pub fn stepper(self, sys: &MassMatrixForm, h: f64) -> Box<dyn Stepper> {
        match self {
            Method::ExplicitEuler => Box::new(Explicit {
                sys: *sys,
                h,
                rk4: false,
            }),
            Method::Rk4 => Box::new(Explicit {
                sys: *sys,
                h,
                rk4: true,
            }),
            Method::Trapezoid => Box::new(Trapezoid { sys: *sys, h }),
            Method::BackwardEuler => Box::new(BackwardEuler { sys: *sys, h }),
            Method::Sdirk2 => Box::new(Sdirk2 { sys: *sys, h }),
            Method::ExactFoh => Box::new(ExactFoh::new(sys, h)),
        }
    }
}

/// One step of a method with fixed parameters and step length.
pub trait Stepper {
    /// Advances the state `z = [x_m, ẋ_m]` over one step, the input going linearly from `u0` to
    /// `u1` (`u = [x, ẋ]`).
    fn step(&mut self, z: [f64; 2], u0: [f64; 2], u1: [f64; 2]) -> [f64; 2];
}

/// The renderer's method: SDIRK2 with implicit friction in each stage (numerics notes §4.5):
///
/// ```text
/// (M − γhJ) K1 = J z_n + G u(t_n + γh) + e₂ f₁
/// (M − γhJ) K2 = J (z_n + h(1−γ)K1) + G u_{n+1} + e₂ f₂
/// z_{n+1} = z_n + h((1−γ)K1 + γK2)
/// ```
///
/// Legal at `m = 0` while `m + γh(b1+b2) + γ²h²(k1+k2) > 0`.
#[derive(Clone, Copy, Debug)]
pub struct Sdirk2 {
    /// The system.
    pub sys: MassMatrixForm,
    /// Step [s].
    pub h: f64,
}

impl Stepper for Sdirk2 {
    fn step(&mut self, z: [f64; 2], u0: [f64; 2], u1: [f64; 2]) -> [f64; 2] {
        let (sys, h, g) = (&self.sys, self.h, SDIRK_GAMMA);
        let l = stage_matrix(sys, g * h);
        let ug = lerp(u0, u1, g);
        let (k1, _) = project(
            &l,
            add(mul_j(sys, z), mul_g(sys, ug)),
            1.0,
            z[1],
            g * h,
            sys.coulomb_n,
        );
        let base = [z[0] + h * (1.0 - g) * k1[0], z[1] + h * (1.0 - g) * k1[1]];
        let (k2, stuck) = project(
            &l,
            add(mul_j(sys, base), mul_g(sys, u1)),
            1.0,
            base[1],
            g * h,
            sys.coulomb_n,
        );
        // Stiffly accurate: z_{n+1} is the second stage value, exactly at rest when stuck.
        let v = if stuck { 0.0 } else { base[1] + h * g * k2[1] };
        [base[0] + h * g * k2[0], v]
    }
}

struct Trapezoid {
    sys: MassMatrixForm,
    h: f64,
}

impl Stepper for Trapezoid {
    /// `(M − h/2 J) z' = (M + h/2 J) z + h/2 G (u0 + u1) + h e₂ f`.
    fn step(&mut self, z: [f64; 2], u0: [f64; 2], u1: [f64; 2]) -> [f64; 2] {
        let (sys, h) = (&self.sys, self.h);
        let l = stage_matrix(sys, 0.5 * h);
        let jz = mul_j(sys, z);
        let gu = mul_g(sys, [0.5 * (u0[0] + u1[0]), 0.5 * (u0[1] + u1[1])]);
        let rhs = [
            z[0] + 0.5 * h * jz[0] + h * gu[0],
            sys.mass_kg * z[1] + 0.5 * h * jz[1] + h * gu[1],
        ];
        project(&l, rhs, h, 0.0, 1.0, sys.coulomb_n).0
    }
}

struct BackwardEuler {
    sys: MassMatrixForm,
    h: f64,
}

impl Stepper for BackwardEuler {
    /// `(M − hJ) z' = M z + h G u1 + h e₂ f`.
    fn step(&mut self, z: [f64; 2], _u0: [f64; 2], u1: [f64; 2]) -> [f64; 2] {
        let (sys, h) = (&self.sys, self.h);
        let l = stage_matrix(sys, h);
        let gu = mul_g(sys, u1);
        let rhs = [z[0] + h * gu[0], sys.mass_kg * z[1] + h * gu[1]];
        project(&l, rhs, h, 0.0, 1.0, sys.coulomb_n).0
    }
}

struct Explicit {
    sys: MassMatrixForm,
    h: f64,
    rk4: bool,
}

impl Explicit {
    /// `ż = M⁻¹(J z + G u − e₂ Fc sgn(ẋ_m))`, friction frozen at the start of the step.
    fn f(&self, z: [f64; 2], u: [f64; 2], friction: f64) -> [f64; 2] {
        let r = add(mul_j(&self.sys, z), mul_g(&self.sys, u));
        [r[0], (r[1] + friction) / self.sys.mass_kg]
    }
}

impl Stepper for Explicit {
    fn step(&mut self, z: [f64; 2], u0: [f64; 2], u1: [f64; 2]) -> [f64; 2] {
        let h = self.h;
        let fr = -self.sys.coulomb_n * sign(z[1]);
        if !self.rk4 {
            let d = self.f(z, u0, fr);
            return [z[0] + h * d[0], z[1] + h * d[1]];
        }
        let um = lerp(u0, u1, 0.5);
        let k1 = self.f(z, u0, fr);
        let k2 = self.f(axpy(z, 0.5 * h, k1), um, fr);
        let k3 = self.f(axpy(z, 0.5 * h, k2), um, fr);
        let k4 = self.f(axpy(z, h, k3), u1, fr);
        [
            z[0] + h / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0]),
            z[1] + h / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1]),
        ]
    }
}

/// `z' = Φ z + Γ0 u0 + Γ1 (u1 − u0) + Γf f`, from `exp` of the augmented matrix (Van Loan):
/// `d/dt [z, u, u̇, f] = [[A, B, 0, b_f], [0, 0, I, 0], [0, 0, 0, 0], [0, 0, 0, 0]]` over `h`, with
/// `u̇ = (u1 − u0)/h`. Needs `m > 0` (`A = M⁻¹J`).
struct ExactFoh {
    phi: [[f64; 2]; 2],
    gamma0: [[f64; 2]; 2],
    gamma1: [[f64; 2]; 2],
    gamma_f: [f64; 2],
    coulomb_n: f64,
}

impl ExactFoh {
    fn new(sys: &MassMatrixForm, h: f64) -> Self {
        let m = sys.mass_kg;
        let mut aug = nalgebra::DMatrix::<f64>::zeros(7, 7);
        aug[(0, 1)] = 1.0;
        aug[(1, 0)] = sys.j[1][0] / m;
        aug[(1, 1)] = sys.j[1][1] / m;
        aug[(1, 2)] = sys.g[1][0] / m;
        aug[(1, 3)] = sys.g[1][1] / m;
        aug[(1, 6)] = 1.0 / m;
        aug[(2, 4)] = 1.0;
        aug[(3, 5)] = 1.0;
        let e = (aug * h).exp();
        let at = |r: usize, c: usize| e[(r, c)];
        ExactFoh {
            phi: [[at(0, 0), at(0, 1)], [at(1, 0), at(1, 1)]],
            gamma0: [[at(0, 2), at(0, 3)], [at(1, 2), at(1, 3)]],
            // The u̇ block integrates to Γ1·u̇; scale by 1/h once so the step takes (u1 − u0).
            gamma1: [[at(0, 4) / h, at(0, 5) / h], [at(1, 4) / h, at(1, 5) / h]],
            gamma_f: [at(0, 6), at(1, 6)],
            coulomb_n: sys.coulomb_n,
        }
    }
}

impl Stepper for ExactFoh {
    fn step(&mut self, z: [f64; 2], u0: [f64; 2], u1: [f64; 2]) -> [f64; 2] {
        let f = -self.coulomb_n * sign(z[1]);
        let du = [u1[0] - u0[0], u1[1] - u0[1]];
        let mut out = [0.0; 2];
        for (r, o) in out.iter_mut().enumerate() {
            *o = self.phi[r][0] * z[0]
                + self.phi[r][1] * z[1]
                + self.gamma0[r][0] * u0[0]
                + self.gamma0[r][1] * u0[1]
                + self.gamma1[r][0] * du[0]
                + self.gamma1[r][1] * du[1]
                + self.gamma_f[r] * f;
        }
        out
    }
}

/// `M − c J` for `M = diag(1, m)`.
#[inline]
pub(crate) fn stage_matrix(sys: &MassMatrixForm, c: f64) -> [[f64; 2]; 2] {
    [
        [1.0 - c * sys.j[0][0], -c * sys.j[0][1]],
        [-c * sys.j[1][0], sys.mass_kg - c * sys.j[1][1]],
    ]
}

/// Solves `L K = r + fgain·e₂·f` for `K`, with the friction force `f ∈ −Fc·Sgn(v)` acting on the
/// velocity `v = base_v + alpha·K[1]` (implicit Coulomb projection). Returns `K` and whether the
/// mass sticks (then `K[1] = −base_v/alpha`, so `v = 0`). Non-finite when `L` is singular;
/// callers check.
#[inline]
pub(crate) fn project(
    l: &[[f64; 2]; 2],
    r: [f64; 2],
    fgain: f64,
    base_v: f64,
    alpha: f64,
    fc: f64,
) -> ([f64; 2], bool) {
    let det = l[0][0] * l[1][1] - l[0][1] * l[1][0];
    let inv = 1.0 / det;
    let k_free = [
        inv * (l[1][1] * r[0] - l[0][1] * r[1]),
        inv * (l[0][0] * r[1] - l[1][0] * r[0]),
    ];
    if fc <= 0.0 {
        return (k_free, false);
    }
    // Response of K to a unit friction force: fgain·L⁻¹e₂.
    let resp = [-inv * l[0][1] * fgain, inv * l[0][0] * fgain];
    let v_free = base_v + alpha * k_free[1];
    let c = alpha * resp[1];
    if c > 0.0 && v_free.abs() <= c * fc {
        // Stick: the friction force that stops the mass.
        let f = -v_free / c;
        return ([k_free[0] + resp[0] * f, -base_v / alpha], true);
    }
    let f = -fc * sign(v_free);
    ([k_free[0] + resp[0] * f, k_free[1] + resp[1] * f], false)
}

#[inline]
fn mul_j(sys: &MassMatrixForm, z: [f64; 2]) -> [f64; 2] {
    [
        sys.j[0][0] * z[0] + sys.j[0][1] * z[1],
        sys.j[1][0] * z[0] + sys.j[1][1] * z[1],
    ]
}

#[inline]
fn mul_g(sys: &MassMatrixForm, u: [f64; 2]) -> [f64; 2] {
    [
        sys.g[0][0] * u[0] + sys.g[0][1] * u[1],
        sys.g[1][0] * u[0] + sys.g[1][1] * u[1],
    ]
}

#[inline]
fn add(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] + b[0], a[1] + b[1]]
}

#[inline]
fn axpy(z: [f64; 2], a: f64, d: [f64; 2]) -> [f64; 2] {
    [z[0] + a * d[0], z[1] + a * d[1]]
}

#[inline]
pub(crate) fn lerp(u0: [f64; 2], u1: [f64; 2], t: f64) -> [f64; 2] {
    [u0[0] + t * (u1[0] - u0[0]), u0[1] + t * (u1[1] - u0[1])]
}

/// `sgn` with `sgn(0) = 0`.
#[inline]
pub(crate) fn sign(v: f64) -> f64 {
    if v > 0.0 {
        1.0
    } else if v < 0.0 {
        -1.0
    } else {
        0.0
    }
}
