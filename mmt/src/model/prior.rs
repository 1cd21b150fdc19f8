//! What the operator renders before the telerobot's first model of an object arrives (issue 13):
//! a passive spring–damper along the contact normal, and a passive sliding object (or a
//! spring–damper) along the tangents, so that contact is never rendered as free space.
//!
//! The default prior is generic. It is the centre of the plausible soft-object class
//! ([`SOFT_OBJECTS`], the class `mmt benchmark` draws from): the same for every scene, and never
//! fitted to a shipped scene. The renderers bound it like any model (the renderability gate,
//! Colgate's clip when the device's damping is known).

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::{KelvinVoigt, Physical};

/// The ranges of the plausible soft-object class.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SoftObjectRanges {
    /// Mass `m` [kg], log-uniform.
    pub mass_kg: (f64, f64),
    /// Contact stiffness `k2` [N/m], log-uniform.
    pub k_contact_n_per_m: (f64, f64),
    /// Dampings `b1`, `b2` [N·s/m], log-uniform each.
    pub damping_ns_per_m: (f64, f64),
    /// Static friction `Fs` [N], uniform.
    pub static_friction_n: (f64, f64),
    /// `Fc / Fs`.
    pub coulomb_ratio: f64,
    /// Ground spring `k1` [N/m] of the objects that have one, log-uniform.
    pub k_ground_n_per_m: (f64, f64),
}

/// The soft-object class (issue 12's): 0.2–5 kg, 200–3,000 N/m, 5–100 N·s/m, static friction
/// 0–1.5 N with `Fc = 0.7 Fs`, ground springs 50–500 N/m.
pub const SOFT_OBJECTS: SoftObjectRanges = SoftObjectRanges {
    mass_kg: (0.2, 5.0),
    k_contact_n_per_m: (200.0, 3000.0),
    damping_ns_per_m: (5.0, 100.0),
    static_friction_n: (0.0, 1.5),
    coulomb_ratio: 0.7,
    k_ground_n_per_m: (50.0, 500.0),
};

impl SoftObjectRanges {
    /// The class's centre: the geometric centre of each log-uniform range, the mean of the
    /// uniform one. The renderer's structure decides which terms it uses (a ground spring, a
    /// friction level, or neither).
    pub fn centre(&self) -> Physical {
        let log = |(lo, hi): (f64, f64)| (lo * hi).sqrt();
        let (f0, f1) = self.static_friction_n;
        Physical {
            mass_kg: log(self.mass_kg),
            k_ground_n_per_m: log(self.k_ground_n_per_m),
            b_ground_ns_per_m: log(self.damping_ns_per_m),
            k_contact_n_per_m: log(self.k_contact_n_per_m),
            b_contact_ns_per_m: log(self.damping_ns_per_m),
            coulomb_n: self.coulomb_ratio * 0.5 * (f0 + f1),
        }
    }
}

/// Where a prior came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PriorSource {
    /// The generic default ([`Prior::generic`]).
    Generic,
    /// Given by the user (`--prior K,B`).
    Given,
    /// The simulated scene's true contact parameters: the floor a perfect prior sets (never a
    /// reported figure's default).
    Truth,
    /// The scene's `[prior]` ([`Guess`]), weighed against the generic class.
    Scene,
}

impl PriorSource {
    /// How reports name it.
    pub fn label(self) -> &'static str {
        match self {
            PriorSource::Generic => "generic",
            PriorSource::Given => "given",
            PriorSource::Truth => "the scene's truth",
            PriorSource::Scene => "the scene's prior",
        }
    }
}

/// The models to render from the first tick of contact until the telerobot's first.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Prior {
    /// The spring–damper along the normal (its `k2`, `b2` when the normal is a wall).
    pub normal: KelvinVoigt,
    /// The object along the tangents: a sliding mass as the tangents' structure allows, or its
    /// contact `k2`, `b2` for a Kelvin–Voigt structure.
    pub tangential: Physical,
    /// Where it came from.
    pub source: PriorSource,
}

/// What a prior's terms must be ([`PriorError::expected`]).
pub const PASSIVE: &str =
    "a finite value above 0 (damping, mass, ground spring and friction: 0 or more)";

/// A prior that is not a passive spring–damper, or a guess that cannot be weighed.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[error("prior {field} = {value} is invalid: expected {expected}")]
pub struct PriorError {
    /// The field (`normal.k_n_per_m`, `tangential.mass_kg`, `spread`, …).
    pub field: &'static str,
    /// Its value.
    pub value: f64,
    /// What it must be.
    pub expected: &'static str,
}

impl Prior {
    /// The generic prior: the centre of [`SOFT_OBJECTS`] ([`SoftObjectRanges::centre`]), along
    /// the normal 775 N/m and 22.4 N·s/m. Off by at most ×3.9 in stiffness over the class.
    pub fn generic() -> Prior {
        let centre = SOFT_OBJECTS.centre();
        Prior {
            normal: KelvinVoigt {
                k_n_per_m: centre.k_contact_n_per_m,
                b_ns_per_m: centre.b_contact_ns_per_m,
            },
            tangential: centre,
            source: PriorSource::Generic,
        }
    }

    /// A prior given as the normal's `k`, `b` (the tangents keep the generic object), checked.
    pub fn given(k_n_per_m: f64, b_ns_per_m: f64) -> Result<Prior, PriorError> {
        let prior = Prior {
            normal: KelvinVoigt {
                k_n_per_m,
                b_ns_per_m,
            },
            source: PriorSource::Given,
            ..Prior::generic()
        };
        prior.validate()?;
        Ok(prior)
    }

    /// Checks that the prior is passive: stiffnesses above 0 where a contact needs them, every
    /// other term 0 or more, all finite.
    pub fn validate(&self) -> Result<(), PriorError> {
        let t = &self.tangential;
        let positive = [
            ("normal.k_n_per_m", self.normal.k_n_per_m),
            ("tangential.k_contact_n_per_m", t.k_contact_n_per_m),
        ];
        let non_negative = [
            ("normal.b_ns_per_m", self.normal.b_ns_per_m),
            ("tangential.mass_kg", t.mass_kg),
            ("tangential.k_ground_n_per_m", t.k_ground_n_per_m),
            ("tangential.b_ground_ns_per_m", t.b_ground_ns_per_m),
            ("tangential.b_contact_ns_per_m", t.b_contact_ns_per_m),
            ("tangential.coulomb_n", t.coulomb_n),
        ];
        let bad = positive
            .into_iter()
            .find(|(_, v)| !(v.is_finite() && *v > 0.0))
            .or_else(|| {
                non_negative
                    .into_iter()
                    .find(|(_, v)| !(v.is_finite() && *v >= 0.0))
            });
        match bad {
            Some((field, value)) => Err(PriorError {
                field,
                value,
                expected: PASSIVE,
            }),
            None => Ok(()),
        }
    }
}

/// The largest [`Guess::spread`]: beyond ×11 either way a guess says nothing the class does not.
pub const MAX_SPREAD: f64 = 10.0;

/// An informed guess of the object (a scene's `[prior]`, e.g. from vision: issue 13's hook): the
/// terms it knows, named as the scene's `[environment]`, and how sure it is. The terms it leaves
/// out are the generic prior's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Guess {
    /// Mass `m` \[kg\].
    pub mass_kg: Option<f64>,
    /// Ground spring `k1` \[N/m\].
    pub k_ground_n_per_m: Option<f64>,
    /// Ground damper `b1` \[N·s/m\].
    pub b_ground_ns_per_m: Option<f64>,
    /// Contact spring `k2` \[N/m\] (also the normal's `k`).
    pub k_contact_n_per_m: Option<f64>,
    /// Contact damper `b2` \[N·s/m\] (also the normal's `b`).
    pub b_contact_ns_per_m: Option<f64>,
    /// Coulomb friction level `Fc` \[N\].
    pub coulomb_friction_n: Option<f64>,
    /// How sure the guess is, required: its one-sigma spread relative to each term, as a factor
    /// `1 + spread` either way for the terms weighed in logarithms (0.3: ×1.3 or ÷1.3) and
    /// `±spread` for the friction level; 0: exactly these. 0 to [`MAX_SPREAD`].
    pub spread: f64,
}

impl Guess {
    /// Checks every term ([`PASSIVE`]: the contact spring above 0, the rest 0 or more, all
    /// finite) and the spread; the error names the field as the scene writes it.
    pub fn validate(&self) -> Result<(), PriorError> {
        let terms = [
            ("mass_kg", self.mass_kg, false),
            ("k_ground_n_per_m", self.k_ground_n_per_m, false),
            ("b_ground_ns_per_m", self.b_ground_ns_per_m, false),
            ("k_contact_n_per_m", self.k_contact_n_per_m, true),
            ("b_contact_ns_per_m", self.b_contact_ns_per_m, false),
            ("coulomb_friction_n", self.coulomb_friction_n, false),
        ];
        for (field, value, positive) in terms {
            let Some(value) = value else { continue };
            let ok = value.is_finite() && if positive { value > 0.0 } else { value >= 0.0 };
            if !ok {
                return Err(PriorError {
                    field,
                    value,
                    expected: PASSIVE,
                });
            }
        }
        if !(self.spread.is_finite() && (0.0..=MAX_SPREAD).contains(&self.spread)) {
            return Err(PriorError {
                field: "spread",
                value: self.spread,
                expected: "a relative spread from 0 (exact) to 10",
            });
        }
        Ok(())
    }

    /// The prior to render: each given term weighed against the generic class by the two
    /// spreads (the product of the two densities, as a Bayesian update of the class by the
    /// guess), each left-out term the class's centre ([`Prior::generic`]). The log-uniform
    /// terms are weighed in logarithms (the guess's spread `ln(1 + spread)`, the class range's
    /// `ln(hi/lo)/√12`), the uniform friction level linearly (`spread·Fc` against `(hi−lo)/√12`).
    /// A spread of 0 gives the guess exactly; a term guessed 0 stays 0.
    pub fn prior(&self) -> Result<Prior, PriorError> {
        self.validate()?;
        let c = SOFT_OBJECTS;
        let centre = c.centre();
        let spread_of = |(lo, hi): (f64, f64)| (hi / lo).ln() / 12f64.sqrt();
        let s_guess = (1.0 + self.spread).ln();
        let log = |guess: Option<f64>, range: (f64, f64), centre: f64| match guess {
            None => centre,
            Some(0.0) => 0.0,
            Some(g) => match weight(s_guess, spread_of(range)) {
                1.0 => g,
                w => (w * g.ln() + (1.0 - w) * centre.ln()).exp(),
            },
        };
        let coulomb = match self.coulomb_friction_n {
            None => centre.coulomb_n,
            Some(g) => {
                let (lo, hi) = c.static_friction_n;
                let class = c.coulomb_ratio * (hi - lo) / 12f64.sqrt();
                let w = weight(self.spread * g, class);
                w * g + (1.0 - w) * centre.coulomb_n
            }
        };
        let damping = c.damping_ns_per_m;
        let tangential = Physical {
            mass_kg: log(self.mass_kg, c.mass_kg, centre.mass_kg),
            k_ground_n_per_m: log(
                self.k_ground_n_per_m,
                c.k_ground_n_per_m,
                centre.k_ground_n_per_m,
            ),
            b_ground_ns_per_m: log(self.b_ground_ns_per_m, damping, centre.b_ground_ns_per_m),
            k_contact_n_per_m: log(
                self.k_contact_n_per_m,
                c.k_contact_n_per_m,
                centre.k_contact_n_per_m,
            ),
            b_contact_ns_per_m: log(self.b_contact_ns_per_m, damping, centre.b_contact_ns_per_m),
            coulomb_n: coulomb,
        };
        let prior = Prior {
            normal: KelvinVoigt {
                k_n_per_m: tangential.k_contact_n_per_m,
                b_ns_per_m: tangential.b_contact_ns_per_m,
            },
            tangential,
            source: PriorSource::Scene,
        };
        prior.validate()?;
        Ok(prior)
    }
}

/// The guess's weight against the class, from their spreads (the precisions' share): 1 for an
/// exact guess.
fn weight(s_guess: f64, s_class: f64) -> f64 {
    if s_guess == 0.0 {
        1.0
    } else {
        s_class * s_class / (s_class * s_class + s_guess * s_guess)
    }
}

/// What a `--prior` value may be: `scene`, `generic`, `none`, or `K,B` (the normal's stiffness
/// in N/m and damping in N·s/m; the tangents keep the generic object).
pub const PRIOR_VALUES: &str = "scene (the scene's [prior] if it declares one, else generic), \
     generic, none, or K,B (the normal's stiffness in N/m and damping in N·s/m, e.g. 500,20)";

/// A `--prior` choice: what to render before the first model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Choice {
    /// The prior (`None`: free space).
    pub prior: Option<Prior>,
    /// Render the scene's own prior instead, when it declares one (`scene`).
    pub prefer_scene: bool,
}

/// Parses a `--prior` value ([`PRIOR_VALUES`]). The error says what was wrong, for the caller to
/// prefix with the flag and the value.
pub fn parse(value: &str) -> Result<Choice, String> {
    let prior = match value {
        "scene" => {
            return Ok(Choice {
                prior: Some(Prior::generic()),
                prefer_scene: true,
            });
        }
        "generic" => Some(Prior::generic()),
        "none" => None,
        given => {
            let parsed = given
                .split_once(',')
                .and_then(|(k, b)| Some((k.trim().parse().ok()?, b.trim().parse().ok()?)));
            let (k, b) = parsed.ok_or_else(|| format!("expected {PRIOR_VALUES}"))?;
            Some(Prior::given(k, b).map_err(|e| e.to_string())?)
        }
    };
    Ok(Choice {
        prior,
        prefer_scene: false,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generic_prior_is_the_log_centre_of_the_class() {
        let p = Prior::generic();
        assert!((p.normal.k_n_per_m - 774.596_669).abs() < 1e-5, "{p:?}");
        assert!((p.normal.b_ns_per_m - 22.360_679_8).abs() < 1e-6, "{p:?}");
        let t = p.tangential;
        assert!((t.mass_kg - 1.0).abs() < 1e-12, "{t:?}");
        assert!((t.k_ground_n_per_m - 158.113_883).abs() < 1e-5, "{t:?}");
        assert_eq!(
            (
                t.k_contact_n_per_m,
                t.b_contact_ns_per_m,
                t.b_ground_ns_per_m
            ),
            (p.normal.k_n_per_m, p.normal.b_ns_per_m, p.normal.b_ns_per_m)
        );
        assert!((t.coulomb_n - 0.525).abs() < 1e-12, "{t:?}");
        assert_eq!(p.source, PriorSource::Generic);
        p.validate().unwrap();
        // The worst case over the class: its ends, ×3.87 either way.
        let (lo, hi) = SOFT_OBJECTS.k_contact_n_per_m;
        assert!((p.normal.k_n_per_m / lo - hi / p.normal.k_n_per_m).abs() < 1e-9);
    }

    #[test]
    fn a_prior_value_is_parsed_or_refused_with_what_was_expected() {
        let only = |prior| {
            Ok(Choice {
                prior,
                prefer_scene: false,
            })
        };
        assert_eq!(parse("generic"), only(Some(Prior::generic())));
        assert_eq!(parse("none"), only(None));
        assert_eq!(
            parse("scene"),
            Ok(Choice {
                prior: Some(Prior::generic()),
                prefer_scene: true
            })
        );
        let given = parse("800, 20").unwrap().prior.unwrap();
        assert_eq!(
            (
                given.normal.k_n_per_m,
                given.normal.b_ns_per_m,
                given.source
            ),
            (800.0, 20.0, PriorSource::Given)
        );
        assert_eq!(given.tangential, Prior::generic().tangential);
        for bad in ["stiff", "800", "800,x", ""] {
            assert_eq!(
                parse(bad),
                Err(format!("expected {PRIOR_VALUES}")),
                "{bad:?}"
            );
        }
        assert!(
            parse("-1,20")
                .unwrap_err()
                .contains("normal.k_n_per_m = -1")
        );
    }

    #[test]
    fn a_given_prior_must_be_a_passive_spring_damper() {
        assert!(Prior::given(500.0, 0.0).is_ok());
        for (k, b, field) in [
            (0.0, 10.0, "normal.k_n_per_m"),
            (-5.0, 10.0, "normal.k_n_per_m"),
            (f64::NAN, 10.0, "normal.k_n_per_m"),
            (f64::INFINITY, 10.0, "normal.k_n_per_m"),
            (500.0, -1.0, "normal.b_ns_per_m"),
            (500.0, f64::NAN, "normal.b_ns_per_m"),
        ] {
            let e = Prior::given(k, b).unwrap_err();
            assert_eq!(e.field, field, "{k} {b}");
        }
        assert_eq!(
            Prior::given(-5.0, 1.0).unwrap_err().to_string(),
            "prior normal.k_n_per_m = -5 is invalid: expected a finite value above 0 (damping, \
             mass, ground spring and friction: 0 or more)"
        );
        let mut p = Prior::generic();
        p.tangential.mass_kg = -1.0;
        assert_eq!(p.validate().unwrap_err().field, "tangential.mass_kg");
        p.tangential.mass_kg = 0.0; // a massless object is a model the renderer has
        p.validate().unwrap();
        p.tangential.k_contact_n_per_m = 0.0;
        assert_eq!(
            p.validate().unwrap_err().field,
            "tangential.k_contact_n_per_m"
        );
    }

    fn guess(spread: f64) -> Guess {
        Guess {
            mass_kg: Some(0.8),
            k_ground_n_per_m: Some(0.0),
            k_contact_n_per_m: Some(600.0),
            b_contact_ns_per_m: Some(15.0),
            coulomb_friction_n: Some(1.2),
            spread,
            ..Guess::default()
        }
    }

    #[test]
    fn an_exact_guess_is_rendered_as_given_and_its_gaps_are_the_generic_priors() {
        let p = guess(0.0).prior().unwrap();
        let generic = Prior::generic();
        assert_eq!(p.source, PriorSource::Scene);
        assert_eq!((p.normal.k_n_per_m, p.normal.b_ns_per_m), (600.0, 15.0));
        let t = p.tangential;
        assert_eq!(
            (t.mass_kg, t.k_ground_n_per_m, t.k_contact_n_per_m),
            (0.8, 0.0, 600.0)
        );
        assert_eq!((t.b_contact_ns_per_m, t.coulomb_n), (15.0, 1.2));
        assert_eq!(t.b_ground_ns_per_m, generic.tangential.b_ground_ns_per_m);
        let empty = Guess::default().prior().unwrap();
        assert_eq!(
            (empty.normal, empty.tangential),
            (generic.normal, generic.tangential)
        );
    }

    /// A guess as uncertain as the class itself meets it halfway: the geometric mean for the
    /// log-uniform terms, the mean for the friction level.
    #[test]
    fn a_guess_as_spread_as_the_class_meets_it_halfway() {
        let centre = SOFT_OBJECTS.centre();
        let (lo, hi) = SOFT_OBJECTS.k_contact_n_per_m;
        let spread = ((hi / lo).ln() / 12f64.sqrt()).exp() - 1.0;
        let p = guess(spread).prior().unwrap();
        let k = (600.0 * centre.k_contact_n_per_m).sqrt();
        assert!((p.normal.k_n_per_m - k).abs() < 1e-9 * k, "{p:?} {k}");
        assert_eq!(p.tangential.k_ground_n_per_m, 0.0, "a guessed 0 stays 0");
        // Fc = 1.2 with a one-sigma spread equal to the class's: spread·1.2 = 1.05/√12.
        let spread = 1.05 / 12f64.sqrt() / 1.2;
        let fc = guess(spread).prior().unwrap().tangential.coulomb_n;
        let mean = 0.5 * (1.2 + centre.coulomb_n);
        assert!((fc - mean).abs() < 1e-12, "{fc} {mean}");
        // A vaguer guess lies nearer the class's centre, never beyond either.
        let mut last = 600.0;
        for spread in [0.1, 0.5, 1.0, 3.0, 10.0] {
            let k = guess(spread).prior().unwrap().normal.k_n_per_m;
            assert!(k > last && k < centre.k_contact_n_per_m, "{spread}: {k}");
            last = k;
        }
    }

    #[test]
    fn a_guess_that_cannot_be_weighed_names_its_field() {
        let bad = |f: &dyn Fn(&mut Guess)| {
            let mut g = guess(0.3);
            f(&mut g);
            g.prior().unwrap_err()
        };
        assert_eq!(
            bad(&|g| g.k_contact_n_per_m = Some(0.0)).field,
            "k_contact_n_per_m"
        );
        assert_eq!(bad(&|g| g.mass_kg = Some(f64::NAN)).field, "mass_kg");
        assert_eq!(
            bad(&|g| g.coulomb_friction_n = Some(-0.1)).field,
            "coulomb_friction_n"
        );
        for spread in [-0.1, 10.5, f64::NAN, f64::INFINITY] {
            let e = bad(&|g| g.spread = spread);
            assert_eq!(e.field, "spread", "{spread}");
        }
        assert_eq!(
            bad(&|g| g.spread = -0.1).to_string(),
            "prior spread = -0.1 is invalid: expected a relative spread from 0 (exact) to 10"
        );
    }
}
