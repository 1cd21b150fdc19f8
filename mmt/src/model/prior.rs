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
    /// Given by the user or the scene (an informed guess, e.g. from vision).
    Given,
    /// The simulated scene's true contact parameters: the floor a perfect prior sets (never a
    /// reported figure's default).
    Truth,
}

impl PriorSource {
    /// How reports name it.
    pub fn label(self) -> &'static str {
        match self {
            PriorSource::Generic => "generic",
            PriorSource::Given => "given",
            PriorSource::Truth => "the scene's truth",
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

/// A prior that is not a passive spring–damper.
#[derive(Clone, Copy, Debug, PartialEq, Error)]
#[error(
    "prior {field} = {value} is invalid: expected a finite value above 0 (damping, mass, \
         ground spring and friction: 0 or more)"
)]
pub struct PriorError {
    /// The field (`normal.k_n_per_m`, `tangential.mass_kg`, …).
    pub field: &'static str,
    /// Its value.
    pub value: f64,
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
            Some((field, value)) => Err(PriorError { field, value }),
            None => Ok(()),
        }
    }
}

/// What a `--prior` value may be: `generic`, `none`, or `K,B` (the normal's stiffness in N/m and
/// damping in N·s/m; the tangents keep the generic object).
pub const PRIOR_VALUES: &str =
    "generic, none, or K,B (the normal's stiffness in N/m and damping in N·s/m, e.g. 500,20)";

/// Parses a `--prior` value ([`PRIOR_VALUES`]); `None` for `none`. The error says what was
/// wrong, for the caller to prefix with the flag and the value.
pub fn parse(value: &str) -> Result<Option<Prior>, String> {
    match value {
        "generic" => Ok(Some(Prior::generic())),
        "none" => Ok(None),
        given => {
            let parsed = given
                .split_once(',')
                .and_then(|(k, b)| Some((k.trim().parse().ok()?, b.trim().parse().ok()?)));
            let (k, b) = parsed.ok_or_else(|| format!("expected {PRIOR_VALUES}"))?;
            Prior::given(k, b).map(Some).map_err(|e| e.to_string())
        }
    }
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
        assert_eq!(parse("generic"), Ok(Some(Prior::generic())));
        assert_eq!(parse("none"), Ok(None));
        let given = parse("800, 20").unwrap().unwrap();
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
}
