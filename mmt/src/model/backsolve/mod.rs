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

mod information;
mod problem;
mod roots;

pub use information::Information;
pub(crate) use roots::{cubic_roots, quadratic_roots};

use super::{KelvinVoigt, Physical, Structure, Theta, col};
use problem::Problem;
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
    /// How well the data pin each parameter down, when the back-solve was given the data's
    /// [`Information`].
    pub spread: Option<Spread>,
}

/// The standard deviation of each parameter's logarithm (≈ its relative standard error) given
/// the data so far: how well the motion excited it (issue 12, excitation awareness). A parameter
/// the motion never excited has a large spread; one the structure leaves out has 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Spread {
    /// m.
    pub mass: f64,
    /// k1 (0 when the structure has none).
    pub k_ground: f64,
    /// b1.
    pub b_ground: f64,
    /// k2 (a Kelvin–Voigt's k).
    pub k_contact: f64,
    /// b2 (a Kelvin–Voigt's b).
    pub b_contact: f64,
}

impl Spread {
    /// The largest spread and its parameter's name.
    pub fn worst(&self) -> (&'static str, f64) {
        [
            ("m", self.mass),
            ("k1", self.k_ground),
            ("b1", self.b_ground),
            ("k2", self.k_contact),
            ("b2", self.b_contact),
        ]
        .into_iter()
        .fold(("m", 0.0), |a, b| if b.1 > a.1 { b } else { a })
    }
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
    solve(structure, theta, weights, None, config)
}

/// Recovers the physical parameters of `structure` from θ, measuring the misfit by the data's
/// own information ([`Information`]): the set returned predicts the data the estimate came from
/// as closely as a physical set can, its [`BackSolved::residual`] is the RMS prediction error
/// it adds relative to the RMS output, and its [`BackSolved::spread`] says how well each
/// parameter is pinned down. Directions the motion did not excite neither pull the solution
/// nor count against it, whatever the object's scales.
pub fn back_solve_informed(
    structure: Structure,
    theta: &Theta,
    information: &Information,
    config: &BackSolveConfig,
) -> Result<BackSolved, BackSolveError> {
    solve(structure, theta, None, Some(information), config)
}

/// Recovers the massless set (`m = 0`: a first-order object) of a sliding-mass `structure` that
/// predicts the data closest to θ̂, by the data's own [`Information`] as in
/// [`back_solve_informed`]: the reduced model to render while the motion has not excited the
/// mass (issue 12, excitation awareness). Its residual counts what leaving the mass out costs
/// on the data. `None` for another structure.
pub fn back_solve_massless(
    structure: Structure,
    theta: &Theta,
    information: &Information,
    config: &BackSolveConfig,
) -> Option<Result<BackSolved, BackSolveError>> {
    let Structure::SlidingMass {
        ground_spring,
        friction,
    } = structure
    else {
        return None;
    };
    if let Err(e) = check_finite(structure, theta) {
        return Some(Err(e));
    }
    let problem = Problem::massless(
        theta,
        ground_spring,
        friction,
        information,
        config.band_rad_s,
    );
    let best = problem
        .massless_starts()
        .map(|q| (problem.cost(&q), q))
        .min_by(|x, y| x.0.total_cmp(&y.0));
    let Some((_, start)) = best else {
        return Some(Err(BackSolveError::NoCandidate));
    };
    let q = problem.levenberg_marquardt(start, config.max_iterations);
    let fitted = problem.physical(&q);
    let physical = problem.without_vanished(&q, fitted);
    let spread = problem.spread(&q).map(|s| spread_of(&s, ground_spring));
    let condition = problem.condition(&q);
    Some(Ok(BackSolved {
        params: Params::SlidingMass(physical),
        residual: problem.relative_residual(&q, &fitted),
        condition,
        confidence: confidence_of(condition, config),
        spread,
    }))
}

fn solve(
    structure: Structure,
    theta: &Theta,
    weights: Option<&[f64; col::COUNT]>,
    information: Option<&Information>,
    config: &BackSolveConfig,
) -> Result<BackSolved, BackSolveError> {
    check_finite(structure, theta)?;
    match structure {
        Structure::Free => Ok(BackSolved {
            params: Params::Free,
            residual: 0.0,
            condition: 1.0,
            confidence: Confidence::Identified,
            spread: None,
        }),
        Structure::KelvinVoigt => {
            let kv = KelvinVoigt {
                k_n_per_m: theta.0[col::D],
                b_ns_per_m: theta.0[col::C],
            };
            Ok(BackSolved {
                params: Params::KelvinVoigt(kv),
                residual: 0.0,
                condition: 1.0,
                confidence: Confidence::Identified,
                spread: information.map(|i| kelvin_voigt_spread(&kv, i)),
            })
        }
        Structure::SlidingMass {
            ground_spring,
            friction,
        } => sliding_mass(
            theta,
            (ground_spring, friction),
            weights,
            information,
            config,
        ),
    }
}

fn sliding_mass(
    theta: &Theta,
    (ground_spring, friction): (bool, bool),
    weights: Option<&[f64; col::COUNT]>,
    information: Option<&Information>,
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
    let problem = Problem::new(
        theta,
        ground_spring,
        friction,
        weights,
        information,
        config.band_rad_s,
    );
    let best = candidates(t, ground_spring)
        .filter_map(|k2| problem.start_from_k2(k2))
        .map(|q| (problem.cost(&q), q))
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .ok_or(BackSolveError::NoCandidate)?
        .1;
    let q = problem.levenberg_marquardt(best, config.max_iterations);
    let physical = problem.physical(&q);
    // With the data's information the spread says how well the mass is known; without, the
    // band decides whether it can be seen at all.
    let spread = problem.spread(&q).map(|s| spread_of(&s, ground_spring));
    let visibility = mass_visibility(&physical, config.band_rad_s);
    if information.is_none() && !(visibility >= config.min_mass_visibility) {
        return Err(not_identifiable(visibility));
    }
    let condition = problem.condition(&q);
    Ok(BackSolved {
        params: Params::SlidingMass(physical),
        residual: problem.relative_residual(&q, &physical),
        condition,
        confidence: confidence_of(condition, config),
        spread,
    })
}

/// A Kelvin–Voigt set's spread: its coefficients are its parameters, so `k`'s spread is its
/// standard deviation given the data over its value ([`Spread::k_contact`]; infinite when `k`
/// is not positive). `b`'s is its standard deviation over the larger of `b` and `k/ω` at 1 Hz
/// ([`Spread::b_contact`]): the damping that matters beside the spring at the motion's scale,
/// so that a pure spring surface (`b = 0`, which a scene may declare) can pass. Judging `b`
/// keeps a still hold, where `k` and a constant force are one direction of the data, from
/// confirming a wandering `k` (measured: +12.6 % at 10 mN/s of drift without it).
fn kelvin_voigt_spread(kv: &KelvinVoigt, information: &Information) -> Spread {
    const OMEGA_RAD_S: f64 = 2.0 * std::f64::consts::PI;
    let relative = |c: usize, scale: f64| match information.variance(c) {
        Some(v) if scale > 0.0 => v.sqrt() / scale,
        _ => f64::INFINITY,
    };
    let b_scale = if kv.k_n_per_m > 0.0 {
        kv.b_ns_per_m.max(kv.k_n_per_m / OMEGA_RAD_S)
    } else {
        kv.b_ns_per_m
    };
    Spread {
        k_contact: relative(col::D, kv.k_n_per_m),
        b_contact: relative(col::C, b_scale),
        ..Spread::default()
    }
}

/// Every coefficient the structure has is finite.
fn check_finite(structure: Structure, theta: &Theta) -> Result<(), BackSolveError> {
    match structure
        .columns()
        .indices()
        .find(|&i| !theta.0[i].is_finite())
    {
        Some(i) => Err(BackSolveError::NonFinite {
            name: col::NAMES[i],
            value: theta.0[i],
        }),
        None => Ok(()),
    }
}

/// The spread of each parameter from the log-parameters' standard deviations `s` (the
/// problem's order `m, b1, k2, b2, k1`; a massless problem's mass has 0).
fn spread_of(s: &[f64; problem::MAX_P], ground_spring: bool) -> Spread {
    Spread {
        mass: s[0],
        b_ground: s[1],
        k_contact: s[2],
        b_contact: s[3],
        k_ground: if ground_spring { s[4] } else { 0.0 },
    }
}

/// Low confidence beyond [`BackSolveConfig::max_condition`].
fn confidence_of(condition: f64, config: &BackSolveConfig) -> Confidence {
    if condition > config.max_condition {
        Confidence::Low { condition }
    } else {
        Confidence::Identified
    }
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

#[cfg(test)]
mod tests;
