//! The class of objects the benchmark draws from, and its named corner cases.
//!
//! The class (issue 12; the thesis's own real object weighed 459 g, and objects sliding on a
//! table have friction coefficients of 0.2–0.6):
//!
//! | term | range | drawn |
//! |---|---|---|
//! | mass m | 0.2–5 kg | log-uniform |
//! | contact spring k2 | 200–3,000 N/m | log-uniform |
//! | ground damper b1, contact damper b2 | 5–100 N·s/m each | log-uniform |
//! | static friction Fs | 0–1.5 N | uniform; Coulomb friction Fc = 0.7·Fs |
//! | ground spring k1 | 50–500 N/m in 30 % of the objects, else 0 | log-uniform |
//!
//! The Karnopp stick band is the exp-1 scene's 5 mm/s. A spring-mounted object's scene says so
//! (`ground_spring = true`); every scene models friction. Everything else (surface, cloud,
//! proxy, filter cut-off, forgetting) is the exp-1 scene's, so what changes between objects is
//! the object alone. The same seed draws the same objects.

use mmt::model::prior::{SOFT_OBJECTS, SoftObjectRanges};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde::{Deserialize, Serialize};
use sim::scene::{Scene, SensorPreset, Sensors};

/// Standard gravity [m/s²], for friction coefficients.
pub const GRAVITY_M_PER_S2: f64 = 9.81;

/// One object of the benchmark, with the structure its scene declares.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Object {
    /// `class-07`, or a corner case's name.
    pub name: String,
    /// m [kg].
    pub mass_kg: f64,
    /// k1 [N/m].
    pub k_ground_n_per_m: f64,
    /// b1 [N·s/m].
    pub b_ground_ns_per_m: f64,
    /// k2 [N/m].
    pub k_contact_n_per_m: f64,
    /// b2 [N·s/m].
    pub b_contact_ns_per_m: f64,
    /// Karnopp static friction Fs [N].
    pub static_friction_n: f64,
    /// Karnopp dynamic (Coulomb) friction Fd [N].
    pub coulomb_friction_n: f64,
    /// The scene declares the ground spring (`model.ground_spring`).
    pub ground_spring: bool,
}

impl Object {
    /// An object from `[m, k1, b1, k2, b2]` (SI) and its static friction `fs` [N], with the
    /// class's Coulomb level `0.7·fs` and the ground spring declared when `k1 > 0`.
    pub fn from_terms(name: &str, [m, k1, b1, k2, b2]: [f64; 5], fs: f64) -> Object {
        Object {
            name: name.to_string(),
            mass_kg: m,
            k_ground_n_per_m: k1,
            b_ground_ns_per_m: b1,
            k_contact_n_per_m: k2,
            b_contact_ns_per_m: b2,
            static_friction_n: fs,
            coulomb_friction_n: round4(0.7 * fs),
            ground_spring: k1 > 0.0,
        }
    }

    /// The object's contact mode `√((k1 + k2)/m)/2π` [Hz].
    pub fn mode_hz(&self) -> f64 {
        ((self.k_ground_n_per_m + self.k_contact_n_per_m) / self.mass_kg).sqrt()
            / (2.0 * std::f64::consts::PI)
    }

    /// Static friction as a fraction of the object's weight (a friction coefficient).
    pub fn friction_coefficient(&self) -> f64 {
        self.static_friction_n / (self.mass_kg * GRAVITY_M_PER_S2)
    }

    /// The exp-1 scene with this object, its declared structure and the sensor preset.
    pub fn scene(&self, preset: SensorPreset) -> Scene {
        let mut scene = Scene::exp1();
        scene.name = self.name.clone();
        scene.description = format!("benchmark object {}", self.name);
        let e = &mut scene.environment;
        e.mass_kg = self.mass_kg;
        e.k_ground_n_per_m = self.k_ground_n_per_m;
        e.b_ground_ns_per_m = self.b_ground_ns_per_m;
        e.k_contact_n_per_m = self.k_contact_n_per_m;
        e.b_contact_ns_per_m = self.b_contact_ns_per_m;
        e.static_friction_n = self.static_friction_n;
        e.coulomb_friction_n = self.coulomb_friction_n;
        scene.model.ground_spring = self.ground_spring;
        scene.model.friction = true;
        scene.sensors = Sensors::preset(preset);
        scene
    }
}

/// The class (see the module docs): the soft-object ranges, and how many objects are
/// spring-mounted.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ObjectClass {
    /// The ranges of each term.
    #[serde(flatten)]
    pub ranges: SoftObjectRanges,
    /// Fraction of the objects tied to the world by a ground spring (`k1` from
    /// `ranges.k_ground_n_per_m`).
    pub spring_fraction: f64,
}

impl Default for ObjectClass {
    /// Issue 12's class: the soft-object ranges the operator's generic prior is the centre of
    /// ([`SOFT_OBJECTS`]), 30 % of the objects on a ground spring.
    fn default() -> Self {
        ObjectClass {
            ranges: SOFT_OBJECTS,
            spring_fraction: 0.3,
        }
    }
}

impl ObjectClass {
    /// `n` objects drawn from `seed`, named `class-00`, `class-01`, …. Every object's terms
    /// come from one stream in a fixed order, so the same seed gives the same objects.
    pub fn sample(&self, n: usize, seed: u64) -> Vec<Object> {
        let mut rng = Pcg64::seed_from_u64(seed ^ 0x6F_62_6A_65_63_74);
        let log_uniform = |rng: &mut Pcg64, (lo, hi): (f64, f64)| -> f64 {
            (lo.ln() + rng.random::<f64>() * (hi.ln() - lo.ln())).exp()
        };
        let r = &self.ranges;
        (0..n)
            .map(|i| {
                let mass_kg = log_uniform(&mut rng, r.mass_kg);
                let k_contact = log_uniform(&mut rng, r.k_contact_n_per_m);
                let b_ground = log_uniform(&mut rng, r.damping_ns_per_m);
                let b_contact = log_uniform(&mut rng, r.damping_ns_per_m);
                let (f0, f1) = r.static_friction_n;
                let fs = f0 + rng.random::<f64>() * (f1 - f0);
                let spring = rng.random::<f64>() < self.spring_fraction;
                let k_ground = log_uniform(&mut rng, r.k_ground_n_per_m);
                Object {
                    name: format!("class-{i:02}"),
                    mass_kg: round4(mass_kg),
                    k_ground_n_per_m: if spring { round4(k_ground) } else { 0.0 },
                    b_ground_ns_per_m: round4(b_ground),
                    k_contact_n_per_m: round4(k_contact),
                    b_contact_ns_per_m: round4(b_contact),
                    static_friction_n: round4(fs),
                    coulomb_friction_n: round4(r.coulomb_ratio * round4(fs)),
                    ground_spring: spring,
                }
            })
            .collect()
    }
}

/// Four significant digits: readable names in reports, exact values in scenes.
fn round4(v: f64) -> f64 {
    if v == 0.0 || !v.is_finite() {
        return v;
    }
    let scale = 10f64.powi(3 - v.abs().log10().floor() as i32);
    (v * scale).round() / scale
}

/// The named corner cases:
/// - `spring-mounted`: k1 = 500 N/m as stiff as its contact, lightly damped;
/// - `high-friction`: μ = 0.5 of the weight of a 0.5 kg object (Fs 2.45 N, Fc 1.72 N);
/// - `stiff-light`: 0.12 kg on 3,000 N/m, the contact mode at 25 Hz;
/// - `heavy-soft`: 5 kg on 200 N/m, the mode at 1 Hz, much friction;
/// - `renderability`: 8 g on 5,000 N/m, ω_n·h = 0.79 at 1 kHz (the renderer's gate is 1),
///   at the stiffness and damping limits of an omega.7 (5,000 N/m, 30 N·s/m);
/// - `exp1`: the thesis's object, for reference.
pub fn corner_cases() -> Vec<Object> {
    let object = |name: &str, m, k1, b1, k2, b2, fs: f64, spring| Object {
        ground_spring: spring,
        ..Object::from_terms(name, [m, k1, b1, k2, b2], fs)
    };
    let mu = |m: f64, mu: f64| round4(mu * m * GRAVITY_M_PER_S2);
    vec![
        object("spring-mounted", 1.0, 500.0, 10.0, 500.0, 10.0, 0.3, true),
        object(
            "high-friction",
            0.5,
            0.0,
            20.0,
            800.0,
            20.0,
            mu(0.5, 0.5),
            false,
        ),
        object("stiff-light", 0.12, 0.0, 5.0, 3000.0, 5.0, 0.2, false),
        object("heavy-soft", 5.0, 0.0, 80.0, 200.0, 40.0, 1.5, false),
        object("renderability", 0.008, 0.0, 5.0, 5000.0, 30.0, 0.05, false),
        Object {
            coulomb_friction_n: 0.05,
            ..object("exp1", 1.0, 0.0, 60.0, 500.0, 60.0, 0.1, false)
        },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_class_is_seeded_within_its_ranges_and_makes_valid_scenes() {
        let class = ObjectClass::default();
        let a = class.sample(200, 7);
        assert_eq!(a, class.sample(200, 7));
        assert_ne!(a, class.sample(200, 8));
        let springs = a.iter().filter(|o| o.ground_spring).count();
        assert!(
            (40..=80).contains(&springs),
            "{springs} of 200 spring-mounted"
        );
        for o in &a {
            assert!((0.2..=5.0).contains(&o.mass_kg), "{o:?}");
            assert!((200.0..=3000.0).contains(&o.k_contact_n_per_m), "{o:?}");
            assert!((5.0..=100.0).contains(&o.b_ground_ns_per_m), "{o:?}");
            assert!((0.0..=1.5).contains(&o.static_friction_n), "{o:?}");
            assert!(o.coulomb_friction_n <= o.static_friction_n);
            assert_eq!(o.ground_spring, o.k_ground_n_per_m > 0.0);
            let scene = o.scene(SensorPreset::FrankaLike);
            assert!(Scene::from_toml(&toml_of(&scene), "class").is_ok(), "{o:?}");
        }
        for o in corner_cases() {
            let scene = o.scene(SensorPreset::ArmWrench);
            assert!(Scene::from_toml(&toml_of(&scene), &o.name).is_ok(), "{o:?}");
        }
        let stiff = &corner_cases()[2];
        assert!((stiff.mode_hz() - 25.2).abs() < 0.1, "{}", stiff.mode_hz());
        assert!((corner_cases()[1].friction_coefficient() - 0.5).abs() < 1e-3);
    }

    fn toml_of(scene: &Scene) -> String {
        toml::to_string(scene).expect("a scene serialises")
    }
}
