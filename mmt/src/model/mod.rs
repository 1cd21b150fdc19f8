//! The environment model (thesis §3.2, fig. 3; `DESIGN.md` §4).
//!
//! A mass `m` at `x_m` is tied to the world by a spring `k1`, a damper `b1` and Coulomb friction
//! `Fc`, and to the interaction point `x` by a Kelvin–Voigt contact (`k2`, `b2`):
//!
//! ```text
//! F_op = k2 (x − x_m) + b2 (ẋ − ẋ_m)            force the tool pushes with
//! m ẍ_m = F_op − k1 x_m − b1 ẋ_m − Fc sgn(ẋ_m)
//! ```
//!
//! # Sign convention (the one place it is fixed)
//!
//! Every force in this crate — measured by the simulator, regressed by the estimator, rendered by
//! the renderer, displayed by a device — is the **reaction force on the tool**, `F = −F_op`
//! ([`force_on_tool`]). With that convention the regression of thesis eq. 7,
//! `y = ψᵀθ`, `ψ = [−x‴, −x″, −x′, −x, −F″, −F′, −sgn ẋ, −d/dt sgn ẋ]`, has every entry of
//! `θ = [a, b, c, d, e, f, g, h]` positive for a physical object (numerics notes §1.2). The eighth
//! column (`h = b2·Fc/S`) is the friction derivative term the thesis dropped (`DESIGN.md` §11.1).

pub mod backsolve;
pub mod gates;
pub mod prior;
pub mod select;

use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// Converts the force the tool pushes on the environment with (`F_op`) into the force the
/// environment exerts on the tool — the quantity every other module uses.
#[inline]
pub fn force_on_tool(force_by_tool_n: f64) -> f64 {
    -force_by_tool_n
}

/// Physical parameters of the sliding flexible object (thesis fig. 3). SI units throughout.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Physical {
    /// Object mass `m` [kg]. Exp-1 scene: 1 kg. May be 0 (a massless, first-order object).
    pub mass_kg: f64,
    /// Ground spring `k1` [N/m] tying the object to the world. Exp-1: 0 (free to slide).
    pub k_ground_n_per_m: f64,
    /// Ground damper `b1` [N·s/m] (viscous friction with the table). Exp-1: 60.
    pub b_ground_ns_per_m: f64,
    /// Contact spring `k2` [N/m] between tool and object. Exp-1: 500.
    pub k_contact_n_per_m: f64,
    /// Contact damper `b2` [N·s/m]. Exp-1: 60.
    pub b_contact_ns_per_m: f64,
    /// Coulomb (dynamic) friction level `Fc` [N] between object and table. Exp-1: 0.05.
    pub coulomb_n: f64,
}

impl Physical {
    /// The thesis's experiment-1 object (set-up 1): 1 kg, k1 = 0, b1 = 60, k2 = 500, b2 = 60,
    /// dynamic friction 0.05 N.
    pub const THESIS_EXP1: Physical = Physical {
        mass_kg: 1.0,
        k_ground_n_per_m: 0.0,
        b_ground_ns_per_m: 60.0,
        k_contact_n_per_m: 500.0,
        b_contact_ns_per_m: 60.0,
        coulomb_n: 0.05,
    };

    /// The numerics notes' "typical" object (§2.4, §6.2): 0.5 kg, k1 = 200, b1 = 5, k2 = 2000,
    /// b2 = 10, dynamic friction 0.3 N.
    pub const TYPICAL: Physical = Physical {
        mass_kg: 0.5,
        k_ground_n_per_m: 200.0,
        b_ground_ns_per_m: 5.0,
        k_contact_n_per_m: 2000.0,
        b_contact_ns_per_m: 10.0,
        coulomb_n: 0.3,
    };

    /// A set from `(m, k1, b1, k2, b2, Fc)` in that order [kg, N/m, N·s/m, N/m, N·s/m, N].
    pub const fn new(
        mass_kg: f64,
        k_ground: f64,
        b_ground: f64,
        k_contact: f64,
        b_contact: f64,
        coulomb: f64,
    ) -> Physical {
        Physical {
            mass_kg,
            k_ground_n_per_m: k_ground,
            b_ground_ns_per_m: b_ground,
            k_contact_n_per_m: k_contact,
            b_contact_ns_per_m: b_contact,
            coulomb_n: coulomb,
        }
    }

    /// `S = k1 + k2`, the static stiffness sum that normalises θ.
    pub fn stiffness_sum(&self) -> f64 {
        self.k_ground_n_per_m + self.k_contact_n_per_m
    }

    /// Every field finite.
    pub fn is_finite(&self) -> bool {
        self.fields().iter().all(|v| v.is_finite())
    }

    /// The forward map φ → θ (thesis eq. 30, plus `h = b2·Fc/S`). Returns `None` when `S = 0`,
    /// where θ is undefined.
    pub fn theta(&self) -> Option<Theta> {
        let s = self.stiffness_sum();
        if s == 0.0 || !s.is_finite() {
            return None;
        }
        let [m, k1, b1, k2, b2, fc] = self.fields();
        Some(Theta([
            m * b2 / s,
            (m * k2 + b1 * b2) / s,
            (k1 * b2 + k2 * b1) / s,
            k1 * k2 / s,
            m / s,
            (b1 + b2) / s,
            k2 * fc / s,
            b2 * fc / s,
            0.0,
            0.0,
        ]))
    }

    /// Exact frequency response of the force on the tool per unit tool displacement,
    /// `F(iω)/X(iω) = −Z1 Z2 / (Z1 + Z2)`, `Z1 = m s² + b1 s + k1`, `Z2 = b2 s + k2`
    /// (friction left out: it is not linear).
    pub fn force_per_displacement(&self, omega_rad_s: f64) -> Complex64 {
        let s = Complex64::new(0.0, omega_rad_s);
        let [m, k1, b1, k2, b2, _] = self.fields();
        let z1 = s * s * m + s * b1 + k1;
        let z2 = s * b2 + k2;
        -(z1 * z2) / (z1 + z2)
    }

    /// The mass-matrix state-space form `M ż = J z + G u` (legal at `m = 0`).
    pub fn mass_matrix_form(&self) -> MassMatrixForm {
        MassMatrixForm::from_physical(self)
    }

    /// Natural frequency of the contact mode, `ω_n = √((k1+k2)/m)` [rad/s]; infinite at `m = 0`.
    pub fn natural_frequency_rad_s(&self) -> f64 {
        (self.stiffness_sum() / self.mass_kg).sqrt()
    }

    /// `[m, k1, b1, k2, b2, Fc]`.
    fn fields(&self) -> [f64; 6] {
        [
            self.mass_kg,
            self.k_ground_n_per_m,
            self.b_ground_ns_per_m,
            self.k_contact_n_per_m,
            self.b_contact_ns_per_m,
            self.coulomb_n,
        ]
    }
}

/// A Kelvin–Voigt contact (thesis eq. 8): `F_op = k x + b ẋ`, i.e. θ has only `d = k`, `c = b`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct KelvinVoigt {
    /// Stiffness `k` [N/m].
    pub k_n_per_m: f64,
    /// Damping `b` [N·s/m].
    pub b_ns_per_m: f64,
}

/// Index of each regression coefficient in [`Theta`] and of each column in a regressor.
pub mod col {
    /// `a = m b2/S`, column `−x‴`.
    pub const A: usize = 0;
    /// `b = (m k2 + b1 b2)/S`, column `−x″`.
    pub const B: usize = 1;
    /// `c = (k1 b2 + k2 b1)/S`, column `−x′`.
    pub const C: usize = 2;
    /// `d = k1 k2/S`, column `−x`.
    pub const D: usize = 3;
    /// `e = m/S`, column `−F″`.
    pub const E: usize = 4;
    /// `f = (b1 + b2)/S`, column `−F′`.
    pub const F: usize = 5;
    /// `g = k2 Fc/S`, column `−sgn ẋ`.
    pub const G: usize = 6;
    /// `h = b2 Fc/S`, column `−d/dt sgn ẋ` (`DESIGN.md` §11.1).
    pub const H: usize = 7;
    /// `i`, column `1` on the first axis (`0` on the second): a constant force in the
    /// regression [N], not a physical parameter. A spring-mounted object's force depends on the
    /// tool's position relative to where the ground spring rests and where the contact began,
    /// `y = … − d·(x − x₀)`, so `i = d·x₀` changes with every contact episode and differs
    /// between axes; a force-sensor offset that was not tared adds to it. No structure has it;
    /// an estimator adds it ([`Columns::with`]) and the back-solve ignores it.
    pub const I: usize = 8;
    /// `j`: the constant of the second axis of a group sharing θ (column `1` on it, `0` on
    /// the first).
    pub const J: usize = 9;
    /// Number of coefficients.
    pub const COUNT: usize = 10;
    /// Names, for reports.
    pub const NAMES: [&str; COUNT] = ["a", "b", "c", "d", "e", "f", "g", "h", "i", "j"];

    /// The constant column of axis `axis` (0 or 1) of a group sharing θ.
    pub const fn intercept(axis: usize) -> usize {
        if axis == 0 { I } else { J }
    }
}

/// Regression coefficients `θ = [a, b, c, d, e, f, g, h, i, j]` (see [`col`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Theta(pub [f64; col::COUNT]);

impl Theta {
    /// Model output `y = ψᵀθ` for a regressor built with the sign convention of this module.
    pub fn predict(&self, psi: &[f64; col::COUNT]) -> f64 {
        self.0.iter().zip(psi).map(|(t, p)| t * p).sum()
    }

    /// Every entry finite.
    pub fn is_finite(&self) -> bool {
        self.0.iter().all(|v| v.is_finite())
    }
}

/// Which coefficients a model structure identifies and renders: a bit per [`col`] index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Columns(u16);

impl Columns {
    /// No coefficient (free space).
    pub const NONE: Columns = Columns(0);

    /// Builds a set from column indices.
    pub const fn of(indices: &[usize]) -> Columns {
        let mut bits = 0u16;
        let mut i = 0;
        while i < indices.len() {
            bits |= 1 << indices[i];
            i += 1;
        }
        Columns(bits)
    }

    /// These columns and column `i`.
    pub const fn with(self, i: usize) -> Columns {
        if i < col::COUNT {
            Columns(self.0 | 1 << i)
        } else {
            self
        }
    }

    /// These columns without column `i`.
    pub const fn without(self, i: usize) -> Columns {
        if i < col::COUNT {
            Columns(self.0 & !(1 << i))
        } else {
            self
        }
    }

    /// Whether column `i` is identified.
    pub const fn contains(self, i: usize) -> bool {
        i < col::COUNT && self.0 & (1 << i) != 0
    }

    /// Number of identified columns.
    pub const fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    /// True for free space.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The identified column indices in increasing order.
    pub fn indices(self) -> impl Iterator<Item = usize> {
        (0..col::COUNT).filter(move |&i| self.contains(i))
    }
}

/// The model structure of one axis (or one group of axes sharing parameters), chosen by the scene.
/// Only the terms a structure has are identified, sent and rendered.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Structure {
    /// No contact: `F = 0` (thesis eq. 9). Nothing is identified.
    Free,
    /// Kelvin–Voigt contact `F_op = k x + b ẋ` (thesis eq. 8): the `c` (= b) and `d` (= k)
    /// columns only. The normal axis against a table, or any rigid-ish surface.
    KelvinVoigt,
    /// The sliding flexible object of thesis fig. 3.
    SlidingMass {
        /// Whether the ground spring `k1` is part of the model. Keep it out when the scene says the
        /// object is free to slide (`DESIGN.md` §11.7): `d = 0` then and is not estimated.
        ground_spring: bool,
        /// Whether Coulomb friction is part of the model (columns `g` and `h`).
        friction: bool,
    },
}

impl Structure {
    /// The coefficients this structure identifies.
    pub const fn columns(self) -> Columns {
        use col::*;
        match self {
            Structure::Free => Columns::NONE,
            Structure::KelvinVoigt => Columns::of(&[C, D]),
            Structure::SlidingMass {
                ground_spring,
                friction,
            } => {
                let base = Columns::of(&[A, B, C, E, F]).0;
                let d = if ground_spring { 1 << D } else { 0 };
                let gh = if friction { (1 << G) | (1 << H) } else { 0 };
                Columns(base | d | gh)
            }
        }
    }

    /// The structure in words, for reports: `sliding mass, ground spring, friction`.
    pub fn describe(self) -> String {
        match self {
            Structure::Free => "free".into(),
            Structure::KelvinVoigt => "kelvin-voigt".into(),
            Structure::SlidingMass {
                ground_spring,
                friction,
            } => format!(
                "sliding mass{}{}",
                if ground_spring { ", ground spring" } else { "" },
                if friction { ", friction" } else { "" }
            ),
        }
    }

    /// Human-readable names of the physical terms this structure leaves out.
    pub fn left_out(self) -> Vec<&'static str> {
        const ALL: [&str; 6] = [
            "mass",
            "ground spring k1",
            "ground damper b1",
            "contact spring k2",
            "contact damper b2",
            "coulomb friction",
        ];
        let kept: &[&str] = match self {
            Structure::Free => &[],
            Structure::KelvinVoigt => &["contact spring k2", "contact damper b2"],
            Structure::SlidingMass {
                ground_spring,
                friction,
            } => match (ground_spring, friction) {
                (true, true) => &ALL,
                (false, true) => &[
                    "mass",
                    "ground damper b1",
                    "contact spring k2",
                    "contact damper b2",
                    "coulomb friction",
                ],
                (true, false) => &[
                    "mass",
                    "ground spring k1",
                    "ground damper b1",
                    "contact spring k2",
                    "contact damper b2",
                ],
                (false, false) => &[
                    "mass",
                    "ground damper b1",
                    "contact spring k2",
                    "contact damper b2",
                ],
            },
        };
        ALL.iter().copied().filter(|n| !kept.contains(n)).collect()
    }
}

/// `M ż = J z + G u`, `z = [x_m, ẋ_m]`, `u = [x, ẋ]`, `M = diag(1, m)`; the force on the tool is
/// `F = −(k2 (x − x_m) + b2 (ẋ − ẋ_m))` (numerics notes §1.3). Friction enters the second row as
/// `−Fc sgn(ẋ_m)` and is handled by the integrators' projection step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MassMatrixForm {
    /// `m` [kg], the (2,2) entry of `M`.
    pub mass_kg: f64,
    /// `J = [[0, 1], [−(k1+k2), −(b1+b2)]]`.
    pub j: [[f64; 2]; 2],
    /// `G = [[0, 0], [k2, b2]]`.
    pub g: [[f64; 2]; 2],
    /// `k2` [N/m], for the output equation.
    pub k_contact_n_per_m: f64,
    /// `b2` [N·s/m], for the output equation.
    pub b_contact_ns_per_m: f64,
    /// `Fc` [N].
    pub coulomb_n: f64,
}

impl MassMatrixForm {
    fn from_physical(p: &Physical) -> Self {
        MassMatrixForm {
            mass_kg: p.mass_kg,
            j: [
                [0.0, 1.0],
                [
                    -p.stiffness_sum(),
                    -(p.b_ground_ns_per_m + p.b_contact_ns_per_m),
                ],
            ],
            g: [[0.0, 0.0], [p.k_contact_n_per_m, p.b_contact_ns_per_m]],
            k_contact_n_per_m: p.k_contact_n_per_m,
            b_contact_ns_per_m: p.b_contact_ns_per_m,
            coulomb_n: p.coulomb_n,
        }
    }

    /// Force on the tool for mass state `z` and tool state `u`.
    #[inline]
    pub fn force_on_tool(&self, z: [f64; 2], u: [f64; 2]) -> f64 {
        force_on_tool(
            self.k_contact_n_per_m * (u[0] - z[0]) + self.b_contact_ns_per_m * (u[1] - z[1]),
        )
    }

    /// Quasi-static consistent state for a tool at rest at `x`: the mass where the springs balance
    /// and at rest (`x_m = k2 x / (k1 + k2)`), or at `x` when `k1 + k2 = 0`.
    pub fn rest_state(&self, x: f64) -> [f64; 2] {
        let s = -self.j[1][0];
        let xm = if s > 0.0 {
            self.k_contact_n_per_m * x / s
        } else {
            x
        };
        [xm, 0.0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn typical() -> Physical {
        Physical::TYPICAL
    }

    /// θ is the coefficient vector of `F(Z1+Z2)/S = −(Z1 Z2 X + Z2 Fc σ)/S` — check the forward
    /// map against the polynomial products directly, at several complex `s`.
    #[test]
    fn forward_map_matches_polynomial_identity() {
        let p = typical();
        let t = p.theta().unwrap().0;
        let s_sum = p.stiffness_sum();
        for s in [
            Complex64::new(0.3, 1.7),
            Complex64::new(-2.0, 40.0),
            Complex64::new(5.0, -0.2),
        ] {
            let z1 = s * s * p.mass_kg + s * p.b_ground_ns_per_m + p.k_ground_n_per_m;
            let z2 = s * p.b_contact_ns_per_m + p.k_contact_n_per_m;
            let num = s * s * s * t[col::A] + s * s * t[col::B] + s * t[col::C] + t[col::D];
            let den = s * s * t[col::E] + s * t[col::F] + 1.0;
            assert!(((z1 * z2) / s_sum - num).norm() < 1e-9 * num.norm());
            assert!(((z1 + z2) / s_sum - den).norm() < 1e-12 * den.norm());
            let fr = (z2 * p.coulomb_n) / s_sum - (s * t[col::H] + t[col::G]);
            assert!(fr.norm() < 1e-12);
        }
    }

    /// The sign convention: for a time-domain trajectory of the exact model, `F_tool = ψᵀθ` with
    /// positive θ. Checked on an analytic sinusoidal steady state (no filtering needed: the
    /// derivatives of a sinusoid are exact).
    #[test]
    fn sign_convention_reaction_force_gives_positive_theta() {
        let mut p = typical();
        p.coulomb_n = 0.0;
        let theta = p.theta().unwrap();
        assert!(theta.0[..6].iter().all(|&v| v > 0.0));
        let omega: f64 = 7.0;
        let h = p.force_per_displacement(omega); // F_tool / X
        for k in 0..50 {
            let t = k as f64 * 0.013;
            let e = Complex64::from_polar(1.0, omega * t);
            let iw = Complex64::new(0.0, omega);
            // x(t) = Re(e), F(t) = Re(h e); derivatives multiply by iω.
            let x = |n: i32| (iw.powi(n) * e).re;
            let f = |n: i32| (iw.powi(n) * h * e).re;
            let psi = [-x(3), -x(2), -x(1), -x(0), -f(2), -f(1), 0.0, 0.0, 0.0, 0.0];
            let y = f(0);
            assert!((theta.predict(&psi) - y).abs() < 1e-9 * (1.0 + y.abs()));
            // And F_op (the force the tool pushes with) does not satisfy it.
            let psi_op = [-x(3), -x(2), -x(1), -x(0), f(2), f(1), 0.0, 0.0, 0.0, 0.0];
            assert!((theta.predict(&psi_op) + y).abs() > 1e-3);
        }
    }

    #[test]
    fn transfer_function_limits() {
        let p = typical();
        // DC: series springs, force opposes displacement.
        let dc = p.force_per_displacement(0.0);
        let series = p.k_ground_n_per_m * p.k_contact_n_per_m / p.stiffness_sum();
        assert!((dc.re + series).abs() < 1e-9 && dc.im.abs() < 1e-12);
        // High frequency: the mass blocks, the operator feels the contact element.
        let w = 1e6;
        let hf = p.force_per_displacement(w);
        let z2 = Complex64::new(p.k_contact_n_per_m, w * p.b_contact_ns_per_m);
        assert!((hf + z2).norm() / z2.norm() < 1e-3);
    }

    #[test]
    fn columns_per_structure() {
        assert_eq!(Structure::Free.columns().len(), 0);
        assert_eq!(Structure::KelvinVoigt.columns().len(), 2);
        let full = Structure::SlidingMass {
            ground_spring: true,
            friction: true,
        };
        assert_eq!(full.columns().len(), 8);
        let exp1 = Structure::SlidingMass {
            ground_spring: false,
            friction: true,
        };
        assert_eq!(exp1.columns().len(), 7);
        assert!(!exp1.columns().contains(col::D));
        assert_eq!(exp1.left_out(), vec!["ground spring k1"]);
        assert_eq!(
            Structure::KelvinVoigt.left_out(),
            vec![
                "mass",
                "ground spring k1",
                "ground damper b1",
                "coulomb friction"
            ]
        );
    }

    #[test]
    fn mass_matrix_form_output_and_rest_state() {
        let p = typical();
        let mm = p.mass_matrix_form();
        let z = mm.rest_state(0.01);
        // At the quasi-static rest state the force equals the series spring force.
        let f = mm.force_on_tool(z, [0.01, 0.0]);
        let series = p.k_ground_n_per_m * p.k_contact_n_per_m / p.stiffness_sum();
        assert!((f + series * 0.01).abs() < 1e-12);
    }
}
