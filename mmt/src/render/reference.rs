//! Exact solutions of the environment model, the oracles of the renderer's tests and of the
//! work–precision study.
//!
//! The tool moves as a sum of sines `x(t) = Σ Aᵢ sin(ωᵢ t + φᵢ)` from a given state. For the linear
//! model the solution is the particular (steady-state) sinusoids plus the free response,
//! `z(t) = z_p(t) + e^{At}(z₀ − z_p(0))`, evaluated in closed form (2×2 matrix exponential written
//! so that no exponent is positive: nothing overflows even for `m = 1e-6`). With Coulomb friction
//! the motion is piecewise linear with constant forcing ±Fc (slip) or `ẋ_m = 0` (stick); the mode
//! switches (velocity zero crossings, break-away) are located by bracketing on a fine grid and
//! bisection to machine precision.

use crate::model::Physical;
use num_complex::Complex64;

/// One sinusoid of the tool motion: `amplitude·sin(ω t + phase)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tone {
    /// Amplitude [m].
    pub amplitude_m: f64,
    /// Angular frequency [rad/s].
    pub omega_rad_s: f64,
    /// Phase [rad].
    pub phase_rad: f64,
}

/// A sum of tones.
#[derive(Clone, Debug, PartialEq)]
pub struct Multisine(pub Vec<Tone>);

impl Multisine {
    /// Tool position and velocity `[x, ẋ]` at `t`.
    pub fn input(&self, t: f64) -> [f64; 2] {
        self.0.iter().fold([0.0, 0.0], |acc, tone| {
            let arg = tone.omega_rad_s * t + tone.phase_rad;
            [
                acc[0] + tone.amplitude_m * arg.sin(),
                acc[1] + tone.amplitude_m * tone.omega_rad_s * arg.cos(),
            ]
        })
    }
}

/// The exact motion of the linear model (`Fc` ignored) with `m > 0`.
#[derive(Clone, Debug)]
pub struct LinearReference {
    p: Physical,
    input: Multisine,
    /// Particular-solution phasors per tone: `z_p = Im(Zᵢ e^{i(ωᵢt+φᵢ)})`.
    phasors: Vec<[Complex64; 2]>,
    /// Eigen-structure of `A = M⁻¹J` for the free response.
    expm: Expm2,
    z0: [f64; 2],
}

impl LinearReference {
    /// The motion starting at `t = 0` from mass state `z0 = [x_m, ẋ_m]`.
    pub fn new(p: &Physical, input: Multisine, z0: [f64; 2]) -> Self {
        let a = system_matrix(p);
        let phasors = input
            .0
            .iter()
            .map(|tone| {
                // (iω − A) Z = B U with U = A_i [1, iω] (x = Im(A e^{iωt})).
                let s = Complex64::new(0.0, tone.omega_rad_s);
                let u = [Complex64::new(tone.amplitude_m, 0.0), s * tone.amplitude_m];
                let bu = [
                    Complex64::new(0.0, 0.0),
                    (u[0] * p.k_contact_n_per_m + u[1] * p.b_contact_ns_per_m) / p.mass_kg,
                ];
                solve2_complex(
                    [
                        [s - a[0][0], Complex64::from(-a[0][1])],
                        [Complex64::from(-a[1][0]), s - a[1][1]],
                    ],
                    bu,
                )
            })
            .collect();
        LinearReference {
            p: *p,
            expm: Expm2::new(a),
            input,
            phasors,
            z0,
        }
    }

    fn particular(&self, t: f64) -> [f64; 2] {
        self.input
            .0
            .iter()
            .zip(&self.phasors)
            .fold([0.0, 0.0], |acc, (tone, z)| {
                let e = Complex64::from_polar(1.0, tone.omega_rad_s * t + tone.phase_rad);
                [acc[0] + (z[0] * e).im, acc[1] + (z[1] * e).im]
            })
    }

    /// The mass state at `t`.
    pub fn state(&self, t: f64) -> [f64; 2] {
        let zp0 = self.particular(0.0);
        let free = self
            .expm
            .apply(t, [self.z0[0] - zp0[0], self.z0[1] - zp0[1]]);
        let zp = self.particular(t);
        [zp[0] + free[0], zp[1] + free[1]]
    }

    /// Force on the tool at `t`.
    pub fn force(&self, t: f64) -> f64 {
        let z = self.state(t);
        let u = self.input.input(t);
        self.p.mass_matrix_form().force_on_tool(z, u)
    }
}

/// The exact motion with Coulomb friction (`Fs = Fd = Fc`), `m > 0`, starting at rest at `x_m = 0`
/// with `t = 0`, precomputed on `[0, horizon]`.
#[derive(Clone, Debug)]
pub struct FrictionReference {
    p: Physical,
    input: Multisine,
    a: [[f64; 2]; 2],
    expm: Expm2,
    linear: LinearReference,
    /// Mode segments `(t_start, mode, z_start)`: mode −1/+1 slipping with that velocity sign,
    /// 0 stuck.
    segments: Vec<(f64, i8, [f64; 2])>,
}

impl FrictionReference {
    /// Builds the event-located solution on `[0, horizon_s]`.
    pub fn new(p: &Physical, input: Multisine, horizon_s: f64) -> Self {
        let a = system_matrix(p);
        let mut r = FrictionReference {
            p: *p,
            a,
            expm: Expm2::new(a),
            linear: LinearReference::new(p, input.clone(), [0.0, 0.0]),
            input,
            segments: Vec::new(),
        };
        r.solve(horizon_s);
        r
    }

    /// Net non-friction force on the mass when it is at `z`.
    fn applied(&self, t: f64, z: [f64; 2]) -> f64 {
        let u = self.input.input(t);
        let p = &self.p;
        p.k_contact_n_per_m * (u[0] - z[0]) + p.b_contact_ns_per_m * (u[1] - z[1])
            - p.k_ground_n_per_m * z[0]
            - p.b_ground_ns_per_m * z[1]
    }

    /// State at `t` in a segment starting at `(t0, mode, z0)`.
    fn eval(&self, t0: f64, mode: i8, z0: [f64; 2], t: f64) -> [f64; 2] {
        if mode == 0 {
            return [z0[0], 0.0];
        }
        // Constant friction force −mode·Fc adds the equilibrium offset z_c = −A⁻¹ b_c.
        let bc = [0.0, -(mode as f64) * self.p.coulomb_n / self.p.mass_kg];
        let det = self.a[0][0] * self.a[1][1] - self.a[0][1] * self.a[1][0];
        let zc = if det != 0.0 {
            [
                -(self.a[1][1] * bc[0] - self.a[0][1] * bc[1]) / det,
                -(self.a[0][0] * bc[1] - self.a[1][0] * bc[0]) / det,
            ]
        } else {
            [0.0, 0.0]
        };
        let zp0 = self.linear.particular(t0);
        let zp = self.linear.particular(t);
        let dz = [z0[0] - zp0[0] - zc[0], z0[1] - zp0[1] - zc[1]];
        let free = self.expm.apply(t - t0, dz);
        [zp[0] + zc[0] + free[0], zp[1] + zc[1] + free[1]]
    }

    fn solve(&mut self, horizon: f64) {
        let fc = self.p.coulomb_n;
        let (mut t0, mut z0) = (0.0, [0.0, 0.0]);
        let mut mode = self.next_mode(0.0, z0);
        // Bracketing grid: far finer than any phase of the problems studied (≥ 1 ms).
        let grid = 2e-5;
        while t0 < horizon && self.segments.len() < 1_000_000 {
            self.segments.push((t0, mode, z0));
            // Stuck: ends when |F_a| exceeds Fc. Slipping: ends when the velocity crosses 0.
            let crossed = |s: &Self, t: f64| -> bool {
                let z = s.eval(t0, mode, z0, t);
                if mode == 0 {
                    s.applied(t, z).abs() > fc
                } else {
                    z[1] * f64::from(mode) < 0.0
                }
            };
            let mut lo = t0;
            let end = loop {
                let hi = (lo + grid).min(horizon);
                if crossed(self, hi) {
                    break Some(bisect(lo, hi, |t| crossed(self, t)));
                }
                if hi >= horizon {
                    break None;
                }
                lo = hi;
            };
            let Some(te) = end else { break };
            let mut ze = self.eval(t0, mode, z0, te);
            if mode != 0 {
                ze[1] = 0.0;
            }
            mode = self.next_mode(te, ze);
            (t0, z0) = (te, ze);
        }
    }

    /// The mode of a mass at rest at `z` at time `t`: stuck while the applied force is within
    /// `Fc`, otherwise slipping the way it pushes.
    fn next_mode(&self, t: f64, z: [f64; 2]) -> i8 {
        let fa = self.applied(t, [z[0], 0.0]);
        if fa.abs() <= self.p.coulomb_n {
            0
        } else if fa > 0.0 {
            1
        } else {
            -1
        }
    }

    /// The mass state at `t`.
    pub fn state(&self, t: f64) -> [f64; 2] {
        let idx = self
            .segments
            .partition_point(|s| s.0 <= t)
            .saturating_sub(1);
        match self.segments.get(idx) {
            Some(&(t0, mode, z0)) => self.eval(t0, mode, z0, t),
            None => [0.0, 0.0],
        }
    }

    /// Force on the tool at `t`.
    pub fn force(&self, t: f64) -> f64 {
        let z = self.state(t);
        let u = self.input.input(t);
        self.p.mass_matrix_form().force_on_tool(z, u)
    }

    /// Number of mode segments (stick/slip phases) found.
    pub fn segment_count(&self) -> usize {
        self.segments.len()
    }
}

/// The first point of `(lo, hi]` where `crossed` holds, to machine precision (`crossed(hi)` holds).
fn bisect(mut lo: f64, mut hi: f64, crossed: impl Fn(f64) -> bool) -> f64 {
    loop {
        let mid = 0.5 * (lo + hi);
        if mid <= lo || mid >= hi {
            return hi;
        }
        if crossed(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
}

/// `A = M⁻¹J` for `m > 0`.
fn system_matrix(p: &Physical) -> [[f64; 2]; 2] {
    let m = p.mass_kg;
    [
        [0.0, 1.0],
        [
            -p.stiffness_sum() / m,
            -(p.b_ground_ns_per_m + p.b_contact_ns_per_m) / m,
        ],
    ]
}

/// Closed-form `e^{At}` of a 2×2 matrix through its eigenvalues `μ ± ν`.
#[derive(Clone, Copy, Debug)]
struct Expm2 {
    a: [[f64; 2]; 2],
    mu: f64,
    nu: Complex64,
}

impl Expm2 {
    fn new(a: [[f64; 2]; 2]) -> Self {
        let mu = 0.5 * (a[0][0] + a[1][1]);
        let det = a[0][0] * a[1][1] - a[0][1] * a[1][0];
        let nu = Complex64::new(mu * mu - det, 0.0).sqrt();
        Expm2 { a, mu, nu }
    }

    /// `e^{At} v`, as `½[e^{λ₊t}(I + N/ν) + e^{λ₋t}(I − N/ν)] v`, `N = A − μI`, `λ± = μ ± ν`.
    fn apply(&self, t: f64, v: [f64; 2]) -> [f64; 2] {
        let n = [
            [self.a[0][0] - self.mu, self.a[0][1]],
            [self.a[1][0], self.a[1][1] - self.mu],
        ];
        let nv = [
            n[0][0] * v[0] + n[0][1] * v[1],
            n[1][0] * v[0] + n[1][1] * v[1],
        ];
        if self.nu.norm() < 1e-9 * self.mu.abs().max(1.0) {
            // Repeated eigenvalue: e^{μt}(I + N t).
            let e = (self.mu * t).exp();
            return [e * (v[0] + t * nv[0]), e * (v[1] + t * nv[1])];
        }
        let ep = (Complex64::from(self.mu) + self.nu) * t;
        let em = (Complex64::from(self.mu) - self.nu) * t;
        let (ep, em) = (ep.exp(), em.exp());
        let mut out = [0.0; 2];
        for i in 0..2 {
            let w = Complex64::from(nv[i]) / self.nu;
            out[i] = (0.5 * (ep * (v[i] + w) + em * (v[i] - w))).re;
        }
        out
    }
}

fn solve2_complex(m: [[Complex64; 2]; 2], b: [Complex64; 2]) -> [Complex64; 2] {
    let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    [
        (m[1][1] * b[0] - m[0][1] * b[1]) / det,
        (m[0][0] * b[1] - m[1][0] * b[0]) / det,
    ]
}
