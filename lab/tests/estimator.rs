//! The estimator on the simulated object: the exp-1 figures, re-contact, new objects, tare, a
//! bias drifting in contact, Kelvin–Voigt on two axes, invalid settings, confidence counts.

#![allow(clippy::unwrap_used)]

use lab::analysis::estimate::{EstimateConfig, estimate};
use mmt::estimator::*;
use mmt::model::{KelvinVoigt, Physical, Structure};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;
use sim::trajectory::Multisine;
use sim::{SensorNoise, SimConfig, SlidingObjectSim};

const EXP1: Structure = Structure::SlidingMass {
    ground_spring: false,
    friction: true,
};

fn exp1_config() -> EstimatorConfig {
    let mut c = EstimatorConfig::new(EXP1, 1);
    c.filter.svf.cutoff_hz = 5.0;
    c.forgetting = 0.9999;
    c
}

/// Issue 2 figures: reconstruction ≤ 2 % of RMS, stable within 2 s of contact, m, k2, b1, b2
/// within 5 %, on several noise seeds.
#[test]
fn exp1_object_with_franka_like_noise_meets_the_figures() {
    for seed in 1..=3 {
        let r = estimate(&EstimateConfig {
            seed,
            ..EstimateConfig::default()
        })
        .unwrap();
        let recon = r.reconstruction_error_pct.unwrap();
        let tts = r.time_to_stable_s.unwrap();
        let e = r.error_pct.unwrap();
        assert!(recon <= 2.0, "seed {seed}: reconstruction {recon} %");
        assert!(tts <= 2.0, "seed {seed}: time to stable {tts} s");
        assert_eq!(
            r.confidence,
            Some(mmt::model::backsolve::Confidence::Identified)
        );
        assert!(r.condition.unwrap() < 15.0);
        assert!(r.confirmed_updates > 0);
        assert_eq!(r.low_confidence_updates, 0);
        for (name, v) in [
            ("m", e.mass),
            ("k2", e.k_contact),
            ("b1", e.b_ground),
            ("b2", e.b_contact),
        ] {
            assert!(v.abs() <= 5.0, "seed {seed}: {name} off by {v} %");
        }
    }
}

/// Drives an estimator with the simulated exp-1 object; `contact(t)` says when the tool touches.
fn run(
    est: &mut Estimator,
    object: Physical,
    seconds: f64,
    contact: impl Fn(f64) -> bool,
    seed: u64,
) -> Vec<Update> {
    let config = SimConfig {
        object,
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    run_sim(est, config, seconds, contact, seed)
}

/// As [`run`], with the whole simulator configuration given.
fn run_sim(
    est: &mut Estimator,
    config: SimConfig,
    seconds: f64,
    contact: impl Fn(f64) -> bool,
    seed: u64,
) -> Vec<Update> {
    let ex = Multisine::exp1_tangential();
    let mut sim =
        SlidingObjectSim::new(config, ex.eval(0.0).0, 0.0, Pcg64::seed_from_u64(seed)).unwrap();
    let mut updates = Vec::new();
    for k in 0..(seconds * 1000.0) as usize {
        let t = k as f64 * 1e-3;
        let c = contact(t);
        let (x, v) = if c { ex.eval(t) } else { (ex.eval(t).0, 0.0) };
        let s = sim.step(x, v, c);
        let m = s.measured;
        updates.push(est.step(
            t,
            &[AxisSample {
                position_m: m.position_m,
                velocity_m_per_s: m.velocity_m_per_s,
                force_n: m.force_n,
            }],
            c,
        ));
    }
    updates
}

/// The cause of the high-friction objects' wrong models (issue 12): the friction columns took
/// their shape from the sign of the tool's velocity, which switches the friction at every
/// reversal while the object still sticks (until the contact spring has taken up `2·Fc`, here
/// 4 mm of tool travel). The regression then learnt a stiffer, lighter object. The friction
/// observer gives the columns the friction the object feels. Pure Coulomb friction (`Fs = Fc`),
/// so that the observer's law is the truth's and the figures are the estimator's alone. 60 s,
/// for the 10 s memory to forget the data taken before the observer started (measured: worst
/// parameter 3.2 % off with the observer, k2; 74 % with the tool's sign, b2).
/// The worst relative error [%] of m, b1, k2, b2 and Fc after `seconds` on a high-friction
/// object with pure Coulomb friction (`Fs = Fc`, so that the observer's law is the truth's and
/// the figures are the estimator's alone): class object 02 of `mmt benchmark --seed 1` with
/// Fc = 1 N.
fn high_friction_worst_pct(friction_observer: bool, observer_discount: f64, seconds: f64) -> f64 {
    let object = Physical {
        mass_kg: 0.63,
        k_ground_n_per_m: 0.0,
        b_ground_ns_per_m: 11.7,
        k_contact_n_per_m: 460.0,
        b_contact_ns_per_m: 53.0,
        coulomb_n: 1.0,
    };
    let config = SimConfig {
        object,
        static_friction_n: 1.0,
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    let mut est = Estimator::new(EstimatorConfig {
        friction_observer,
        observer_discount,
        ..exp1_config()
    })
    .unwrap();
    run_sim(&mut est, config, seconds, |t| t >= 0.5, 1);
    let p = est.latest().unwrap().sliding_mass().unwrap();
    let rel = |got: f64, want: f64| 100.0 * (got / want - 1.0);
    let errors = [
        ("m", rel(p.mass_kg, object.mass_kg)),
        ("b1", rel(p.b_ground_ns_per_m, object.b_ground_ns_per_m)),
        ("k2", rel(p.k_contact_n_per_m, object.k_contact_n_per_m)),
        ("b2", rel(p.b_contact_ns_per_m, object.b_contact_ns_per_m)),
        ("Fc", rel(p.coulomb_n, object.coulomb_n)),
    ];
    eprintln!(
        "observer {friction_observer}, discount {observer_discount}, {seconds} s: {errors:.1?}"
    );
    errors.into_iter().map(|(_, e)| e.abs()).fold(0.0, f64::max)
}

/// The cause of the high-friction objects' wrong models (issue 12): the friction columns took
/// their shape from the sign of the tool's velocity, which switches the friction at every
/// reversal while the object still sticks (until the contact spring has taken up `2·Fc`, here
/// 4 mm of tool travel). The regression then learnt a stiffer, lighter object. The friction
/// observer gives the columns the friction the object feels. 60 s, so that the data taken
/// before the observer started are forgotten whatever the discount.
#[test]
fn a_stick_phase_at_every_reversal_is_not_learnt_as_a_stiffer_lighter_object() {
    let with = high_friction_worst_pct(true, 1.0, 60.0);
    let without = high_friction_worst_pct(false, 1.0, 60.0);
    assert!(
        with <= 10.0,
        "with the observer: worst parameter {with:.1} % off"
    );
    assert!(
        without >= 30.0,
        "the tool's sign: worst parameter only {without:.1} % off"
    );
}

/// The data taken with the tool's sign before the observer started bias the estimate for as
/// long as the memory keeps them (10 s here); the discount at the observer's start forgets them
/// at once. Measured at 15 s: k2 71 % off with the discount against 113 % without (the rest
/// is the observer's own start from a rough set, which the memory forgets).
#[test]
fn data_taken_before_the_friction_observer_started_are_forgotten_when_it_starts() {
    let kept = high_friction_worst_pct(true, 1.0, 15.0);
    let discounted = high_friction_worst_pct(true, 0.3, 15.0);
    assert!(
        discounted < 0.8 * kept,
        "at 15 s: worst parameter {discounted:.1} % with the discount, {kept:.1} % without"
    );
}

#[test]
fn re_contact_with_the_same_object_keeps_the_model() {
    let mut est = Estimator::new(exp1_config()).unwrap();
    // Contact 0.5–8 s, free 8–9 s, contact again 9–14 s.
    let ups = run(
        &mut est,
        Physical::THESIS_EXP1,
        14.0,
        |t| (0.5..8.0).contains(&t) || t >= 9.0,
        3,
    );
    assert_eq!(est.model_id(), 1);
    assert!(ups.iter().all(|u| !u.new_object));
    assert!(est.is_confident());
    // With the thesis's policy every onset starts a new model.
    let mut thesis = Estimator::new(EstimatorConfig {
        reset: ResetPolicy::EveryOnset,
        ..exp1_config()
    })
    .unwrap();
    let ups = run(
        &mut thesis,
        Physical::THESIS_EXP1,
        14.0,
        |t| (0.5..8.0).contains(&t) || t >= 9.0,
        3,
    );
    assert_eq!(thesis.model_id(), 2);
    assert_eq!(ups.iter().filter(|u| u.new_object).count(), 1);
}

#[test]
fn a_different_object_is_detected_and_re_identified() {
    let mut est = Estimator::new(exp1_config()).unwrap();
    run(&mut est, Physical::THESIS_EXP1, 8.0, |t| t >= 0.5, 5);
    assert!(est.is_confident());
    let mut stiffer = Physical::THESIS_EXP1;
    stiffer.k_contact_n_per_m *= 2.0;
    stiffer.b_contact_ns_per_m *= 2.0;
    // A fresh simulator stands for the new object; the estimator carries on.
    let ups = run(&mut est, stiffer, 10.0, |t| t >= 0.5, 6);
    assert_eq!(
        ups.iter().filter(|u| u.new_object).count(),
        1,
        "exactly one new-object reset"
    );
    assert_eq!(est.model_id(), 2);
    let p = est.latest().unwrap().sliding_mass().unwrap();
    assert!((p.k_contact_n_per_m / 1000.0 - 1.0).abs() < 0.05, "{p:?}");
    assert!((p.b_contact_ns_per_m / 120.0 - 1.0).abs() < 0.05, "{p:?}");
}

#[test]
fn nothing_is_learned_out_of_contact() {
    let mut est = Estimator::new(exp1_config()).unwrap();
    run(&mut est, Physical::THESIS_EXP1, 4.0, |t| t >= 0.5, 7);
    let before = est.theta();
    let updates_before = est.rls_counts().updates;
    // 20 s out of contact: the tool still moves, the sensors still read.
    run(&mut est, Physical::THESIS_EXP1, 20.0, |_| false, 8);
    assert_eq!(est.theta(), before);
    assert_eq!(est.rls_counts().updates, updates_before);
    assert_eq!(est.phase(), Phase::Free);
}

#[test]
fn non_finite_samples_are_counted_and_change_nothing() {
    let mut est = Estimator::new(exp1_config()).unwrap();
    run(&mut est, Physical::THESIS_EXP1, 3.0, |t| t >= 0.5, 9);
    let theta = est.theta();
    let regressions = est.regressions().to_vec();
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let u = est.step(
            3.0,
            &[AxisSample {
                position_m: 0.0,
                velocity_m_per_s: bad,
                force_n: 1.0,
            }],
            true,
        );
        assert_eq!(u, Update::default());
    }
    assert_eq!(est.stats().rejected_samples, 3);
    assert_eq!(est.theta(), theta);
    assert_eq!(est.regressions(), &regressions[..]);
}

#[test]
fn force_bias_is_tared_out_of_contact() {
    let mut est = Estimator::new(exp1_config()).unwrap();
    run(&mut est, Physical::THESIS_EXP1, 3.0, |_| false, 10);
    let bias = SensorNoise::FRANKA_LIKE.force_bias_n;
    assert!(
        (est.tare_n()[0] - bias).abs() < 0.01,
        "{} vs {bias}",
        est.tare_n()[0]
    );
}

/// A Kelvin–Voigt wall on two axes sharing the model: k and b recovered, two parameters only.
#[test]
fn kelvin_voigt_on_two_axes() {
    let truth = KelvinVoigt {
        k_n_per_m: 3000.0,
        b_ns_per_m: 15.0,
    };
    let mut c = EstimatorConfig::new(Structure::KelvinVoigt, 2);
    c.scales = mmt::rls::ColumnScales::for_excitation(0.002, 6.0, 2.0 * std::f64::consts::PI * 2.0)
        .unwrap();
    let mut est = Estimator::new(c).unwrap();
    let mut rng = Pcg64::seed_from_u64(11);
    let noise = Normal::new(0.0, 0.02).unwrap();
    let mut last = None;
    for k in 0..6000 {
        let t = k as f64 * 1e-3;
        let touching = k >= 200;
        let axis = |w: f64, a: f64, p: f64| {
            let (x, v) = (a * (w * t + p).sin(), a * w * (w * t + p).cos());
            let f = if touching {
                -(truth.k_n_per_m * x + truth.b_ns_per_m * v)
            } else {
                0.0
            };
            (x, v, f)
        };
        let (x0, v0, f0) = axis(9.0, 0.002, 0.0);
        let (x1, v1, f1) = axis(23.0, 0.001, 1.0);
        let s = [
            AxisSample {
                position_m: x0,
                velocity_m_per_s: v0,
                force_n: f0 + noise.sample(&mut rng),
            },
            AxisSample {
                position_m: x1,
                velocity_m_per_s: v1,
                force_n: f1 + noise.sample(&mut rng),
            },
        ];
        let u = est.step(t, &s, touching);
        if let Some(g) = u.confirmed {
            last = Some(g);
        }
    }
    let kv = last.unwrap().kelvin_voigt().unwrap();
    assert!(
        (kv.k_n_per_m / truth.k_n_per_m - 1.0).abs() < 0.01,
        "{kv:?}"
    );
    assert!(
        (kv.b_ns_per_m / truth.b_ns_per_m - 1.0).abs() < 0.02,
        "{kv:?}"
    );
    assert_eq!(est.config().structure.columns().len(), 2);
}

#[test]
fn invalid_configuration_names_the_field() {
    let mut c = exp1_config();
    c.axes = 3;
    match Estimator::new(c) {
        Err(EstimatorError::Field { field: "axes", .. }) => {}
        other => panic!("{other:?}"),
    }
    for bad in [-1.0, f64::NAN] {
        let c = EstimatorConfig {
            observer_wait_s: bad,
            ..exp1_config()
        };
        assert!(
            matches!(
                Estimator::new(c),
                Err(EstimatorError::Field {
                    field: "observer_wait_s",
                    ..
                })
            ),
            "{bad}"
        );
    }
    for bad in [0.0, -0.3, 1.5, f64::NAN] {
        let c = EstimatorConfig {
            observer_discount: bad,
            ..exp1_config()
        };
        match Estimator::new(c) {
            Err(EstimatorError::Field {
                field: "observer_discount",
                ..
            }) => {}
            other => panic!("{bad}: {other:?}"),
        }
    }
    let mut c = exp1_config();
    c.confidence.window_s = -1.0;
    assert!(matches!(
        Estimator::new(c),
        Err(EstimatorError::Field {
            field: "confidence.window_s",
            ..
        })
    ));
}

/// A confirmed set whose back-solve reports low confidence is counted and keeps its flag. With
/// the condition threshold at 1 every exp-1 back-solve is `Low` (exp-1 measures about 5).
#[test]
fn low_confidence_confirmed_sets_are_counted() {
    let mut strict = exp1_config();
    strict.gates.back_solve.max_condition = 1.0;
    let mut est = Estimator::new(strict).unwrap();
    run(&mut est, Physical::THESIS_EXP1, 6.0, |t| t >= 0.5, 2);
    let s = est.stats();
    assert!(s.confirmed > 0, "{s:?}");
    assert_eq!(s.low_confidence_confirmed, s.confirmed);
    let latest = est.latest().unwrap();
    assert!(
        matches!(latest.confidence(), mmt::model::backsolve::Confidence::Low { condition } if condition == latest.condition() && condition > 1.0),
        "{:?}",
        latest.confidence()
    );
    let mut default = Estimator::new(exp1_config()).unwrap();
    run(&mut default, Physical::THESIS_EXP1, 6.0, |t| t >= 0.5, 2);
    assert!(default.stats().confirmed > 0);
    assert_eq!(default.stats().low_confidence_confirmed, 0);
}

/// With structure selection a set is published only once this model's choice has settled: the
/// whole structure's early sets for an object that does not need all of it can be far off
/// (a free object fitted with a ground spring: k1 3,900 N/m and k2 0.6 N/m, rendering 1.7 kN
/// against 2 N). Given a ground spring it does not have, the exp-1 object publishes none
/// before its first second of learning and never one with the ground spring, and the ground
/// spring is left out; without selection the same estimator publishes the ground spring.
#[test]
fn with_structure_selection_only_the_settled_choice_is_published() {
    let whole = Structure::SlidingMass {
        ground_spring: true,
        friction: true,
    };
    let sim = SimConfig {
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    let published = |select: bool| {
        let mut c = exp1_config();
        c.structure = whole;
        c.select_structure = select;
        let mut est = Estimator::new(c).unwrap();
        let updates = run_sim(&mut est, sim, 20.0, |t| t >= 0.5, 1);
        let sets: Vec<(f64, Structure)> = updates
            .iter()
            .enumerate()
            .filter_map(|(k, u)| u.confirmed.map(|g| (k as f64 * 1e-3, g.structure())))
            .collect();
        (sets, est.stats())
    };
    let has_k1 = |s: &Structure| s.columns().contains(mmt::model::col::D);
    let (sets, stats) = published(true);
    let first = sets.first().map(|s| s.0);
    eprintln!(
        "selection: {} sets, the first at {first:?} s, chose {:?} ({} changes)",
        sets.len(),
        stats.selected,
        stats.structure_changes
    );
    // Contact at 0.5 s, learning after the 0.3 s guard, the choice after 20 independent
    // samples: 2 s of learning on one axis filtered at 5 Hz (10 a second). Without the rule the
    // first set came at 1.94 s, with the ground spring.
    assert!(first.is_some_and(|t| t >= 2.8), "first set at {first:?} s");
    assert!(sets.iter().all(|(_, s)| !has_k1(s)));
    assert!(stats.selected.is_some_and(|s| !has_k1(&s)));
    let (sets, stats) = published(false);
    assert!(!sets.is_empty() && sets.iter().all(|(_, s)| has_k1(s)));
    assert_eq!(stats.selected, None);
}

/// The normal-axis estimator of the exp-1 scene read through the arm-wrench sensors, as
/// `Scene::telerobot_settings` builds it.
fn arm_wrench_normal_config() -> EstimatorConfig {
    let toml = sim::scene::EXP1_TOML.replace("preset = \"franka-like\"", "preset = \"arm-wrench\"");
    let scene = sim::scene::Scene::from_toml(&toml, "exp1, arm-wrench").unwrap();
    assert_eq!(scene.sensors.noise(), SensorNoise::ARM_WRENCH);
    scene.telerobot_settings().normal
}

/// The relative error [%] of the last confirmed stiffness of the exp-1 scene's Kelvin–Voigt
/// surface (500 N/m, 60 N·s/m), pressed along the normal of `trajectory` for 60 s and read
/// through the arm-wrench sensors with their force bias drifting at `drift_n_per_s`.
fn pressed_stiffness_error_pct(
    config: EstimatorConfig,
    drift_n_per_s: f64,
    trajectory: &str,
    seed: u64,
) -> f64 {
    use sim::trajectory::Trajectory;
    let (k, b) = (500.0, 60.0);
    let noise = SensorNoise {
        force_bias_drift_n_per_s: drift_n_per_s,
        ..SensorNoise::ARM_WRENCH
    };
    let mut sensors = sim::Sensors::new(noise, 1e-3, Pcg64::seed_from_u64(seed));
    let path = sim::trajectory::by_name(trajectory, 60.0, [0.0; 3], [0.0, 0.0, 1.0]).unwrap();
    let mut est = Estimator::new(config).unwrap();
    for i in 0..60_000 {
        let t = i as f64 * 1e-3;
        let s = path.sample(t);
        let (h, v) = (s.position_m[2], s.velocity_m_per_s[2]);
        let contact = h < 0.0;
        let f = if contact {
            (-k * h - b * v).max(0.0)
        } else {
            0.0
        };
        let m = sensors.measure(sim::Measurement {
            position_m: h,
            velocity_m_per_s: v,
            force_n: f,
        });
        let sample = AxisSample {
            position_m: m.position_m,
            velocity_m_per_s: m.velocity_m_per_s,
            force_n: m.force_n,
        };
        est.step(t, &[sample], contact);
    }
    let kv = est.latest().unwrap().kelvin_voigt().unwrap();
    let e = 100.0 * (kv.k_n_per_m / k - 1.0);
    eprintln!(
        "{trajectory}, {drift_n_per_s} N/s, seed {seed}, intercept {}: k {e:+.1} %",
        config.intercept
    );
    e
}

/// Issue 12 item 4: a bias that drifts during contact must not be learnt as stiffness. The tare
/// removes the force sensor's offset only out of contact; at the nearly constant depth of a
/// press, an offset that grows during the contact is a stiffer spring (`Δk ≈ Δoffset/depth`).
/// The drift here, 10 mN/s, is ten times the arm-wrench preset's assumed 1 mN/s and the most the
/// issue calls realistic: over one 60 s contact the offset grows by 0.6 N, 30 % of the 2 N the
/// surface pushes with. The estimator the scene builds for these sensors fits a constant
/// restarted at every onset with a small variance and gates k and b by the data's information.
/// Measured over seeds 1–3: k within −2.5…−2.8 % pressing along exp 2's schedule (−1.6…−1.9 %
/// without drift) and within +1.2…+4.0 % in a still hold (−1.0…+1.9 %). This test fails without
/// the constant (`intercept: false`, what the scene built before: k 23–26 % too stiff in both,
/// checked at the end) and with the constant restarted as loosely as the prior
/// (`onset_intercept_covariance: 1e3`: the hold's k +457 % at seed 1).
#[test]
fn a_bias_drifting_during_contact_is_not_learnt_as_stiffness() {
    let config = arm_wrench_normal_config();
    assert!(config.intercept);
    for trajectory in ["exp2", "hold"] {
        for seed in 1..=3 {
            let e = pressed_stiffness_error_pct(config, 0.01, trajectory, seed);
            assert!(
                e.abs() <= 8.0,
                "{trajectory}, seed {seed}: k off by {e:+.1} %"
            );
        }
    }
    let without = EstimatorConfig {
        intercept: false,
        ..config
    };
    let e = pressed_stiffness_error_pct(without, 0.01, "exp2", 1);
    assert!(e >= 15.0, "without the constant: k off by only {e:+.1} %");
}

/// The exp-1 estimator, the exp-1 tangential motion, and the exp-1 object read by an arm's
/// sensors (`seed`).
fn exp1_with_an_arm(seed: u64) -> (Estimator, Multisine, SlidingObjectSim) {
    let config = SimConfig {
        noise: SensorNoise::FRANKA_LIKE,
        ..SimConfig::THESIS_EXP1
    };
    let ex = Multisine::exp1_tangential();
    let sim =
        SlidingObjectSim::new(config, ex.eval(0.0).0, 0.0, Pcg64::seed_from_u64(seed)).unwrap();
    (Estimator::new(exp1_config()).unwrap(), ex, sim)
}

/// Steps `est` at `t` on one measured sample.
fn step_measured(est: &mut Estimator, t: f64, m: &sim::Measurement, in_contact: bool) -> Update {
    let sample = AxisSample {
        position_m: m.position_m,
        velocity_m_per_s: m.velocity_m_per_s,
        force_n: m.force_n,
    };
    est.step(t, &[sample], in_contact)
}

/// Every parameter of the exp-1 object within `pct` % of the truth.
fn assert_exp1_within(p: &Physical, pct: f64, seed: u64) {
    let truth = Physical::THESIS_EXP1;
    for (name, got, want) in [
        ("m", p.mass_kg, truth.mass_kg),
        ("k2", p.k_contact_n_per_m, truth.k_contact_n_per_m),
        ("b1", p.b_ground_ns_per_m, truth.b_ground_ns_per_m),
        ("b2", p.b_contact_ns_per_m, truth.b_contact_ns_per_m),
    ] {
        let off = (got / want - 1.0) * 100.0;
        assert!(off.abs() <= pct, "seed {seed}: {name} off by {off:.1} %");
    }
}

/// Issue 14: a ROS 2 arm's 1 kHz state stream loses about 1 % of its samples on best-effort,
/// keep-last-1 DDS (the test arm over loopback: 990.9 Hz effective, gaps to 11 ms). Each sample
/// arrives at its own time, but the filters advanced one fixed period per sample, so each lost
/// sample compressed time by a period; the new-object detector then reset the covariance five
/// times in 60 s (`demo/examples/ros2_figures.rs`, seed 1: stable at 2.3 s, then unstable for
/// 0.6–1.0 s at 17.5, 26.5, 32.3, 47.5 and 51.2 s). The filters now cover a gap with the
/// samples it lost, interpolated, and learn from the real ones only; a gap beyond
/// `MAX_FILLED_PERIODS` (here 0.3 s at 20 s) restarts them and waits out the onset guard.
#[test]
fn samples_lost_in_transport_are_not_a_new_object() {
    let lossy = |loss: f64, seed: u64| {
        let (mut est, ex, mut sim) = exp1_with_an_arm(seed);
        let mut transport = Pcg64::seed_from_u64(seed + 100);
        let (mut resets, mut lost) = (0, 0u64);
        let mut confident_at_end = Vec::new();
        for k in 0..60_000 {
            let t = k as f64 * 1e-3;
            let c = t >= 0.5;
            let (x, v) = if c { ex.eval(t) } else { (ex.eval(t).0, 0.0) };
            let m = sim.step(x, v, c).measured;
            let outage = (20.0..20.3).contains(&t);
            if outage || rand::Rng::random::<f64>(&mut transport) < loss {
                lost += 1;
                continue;
            }
            let u = step_measured(&mut est, t, &m, c);
            resets += usize::from(u.new_object);
            if t >= 50.0 {
                confident_at_end.push(est.is_confident());
            }
        }
        let p = est.latest().and_then(|g| g.sliding_mass()).unwrap();
        (
            resets,
            lost,
            confident_at_end.iter().all(|&c| c),
            p,
            est.stats(),
        )
    };
    for seed in [1, 2] {
        let (resets, lost, confident, p, stats) = lossy(0.01, seed);
        assert!(lost > 400, "{lost}");
        assert_eq!(
            resets, 0,
            "seed {seed}: {resets} new-object resets, {lost} lost"
        );
        assert!(confident, "seed {seed}");
        assert_exp1_within(&p, 5.0, seed);
        assert_eq!(stats.gap_restarts, 1, "{stats:?}");
        // Every lost sample but the outage's 300 (and any lost next to it, or last) filled.
        let filled = stats.filled_samples + 300;
        assert!(
            (lost - 3..=lost).contains(&filled),
            "{stats:?}, {lost} lost"
        );
    }
}

/// What the robot does at a stall of its commands, in
/// [`a_robot_stopped_while_its_states_were_lost_is_not_a_new_object`].
#[derive(Clone, Copy, PartialEq)]
enum Stall {
    /// Goes on smoothly; its states over the stall are lost.
    Smooth,
    /// Stops dead, then goes on from there; its states over the stop are lost.
    StopUnseen,
    /// Stops dead and goes on from there, every state seen.
    StopSeen,
    /// Stops dead, every state seen, then jumps back onto the path where it would have been.
    StopAndJump,
}

/// The robot stops dead for a few milliseconds (it ran out of targets) and its states over the
/// stop are lost: the same held-up link to a robot does both (`ros2_figures`' arm on a loaded
/// machine: every false reset of its 60 s runs), and the same arm then jumps to catch up. The
/// filters are stepped over a gap as if the motion had gone on straight (or across a jump as
/// if it were one), so the regressors carry a motion that never happened for a few filter time
/// constants afterwards: that transient is not a new object, and not to be learnt from. Before
/// the rule (gaps filled, jumps learnt through), seeds 1–3, stops unseen: 7, 1 and 4 resets,
/// mass +28–80 %, k2 +61–78 %, b2 −18–36 %, the prediction error 13–15 % of the force (0.4–0.5
/// % with the stops seen); stops and jumps, seeds 1–2: 5 and 7 resets, k2 +77–156 %.
#[test]
fn a_robot_stopped_while_its_states_were_lost_is_not_a_new_object() {
    // A stall of 4–11 ms every 0.5 s on average after 5 s; with a gap, its states and the next
    // two are lost.
    let run = |seed: u64, stall: Stall| {
        let (mut est, ex, mut sim) = exp1_with_an_arm(seed);
        let mut stalls = Pcg64::seed_from_u64(seed + 100);
        let stops = stall != Stall::Smooth;
        let gaps = matches!(stall, Stall::Smooth | Stall::StopUnseen);
        // The path's time: it stands still through a stop (and goes on from there, unless the
        // robot jumps back onto the path).
        let (mut path_t, mut stop_left, mut gap_left, mut held) = (0.0, 0u32, 0u32, 0.0);
        let (mut resets, mut error_sum, mut errors) = (0, 0.0, 0.0);
        for k in 0..40_000 {
            let t = k as f64 * 1e-3;
            let c = t >= 0.5;
            if t > 5.0 && gap_left == 0 && rand::Rng::random::<f64>(&mut stalls) < 1.0 / 500.0 {
                stop_left = rand::Rng::random_range(&mut stalls, 4..12);
                gap_left = stop_left + 2;
                held = ex.eval(path_t).0;
            }
            let stopped = stops && stop_left > 0;
            stop_left = stop_left.saturating_sub(1);
            if !stopped || stall == Stall::StopAndJump {
                path_t += 1e-3;
            }
            let (x, v) = match ex.eval(path_t) {
                _ if stopped => (held, 0.0),
                (x, v) => (x, if c { v } else { 0.0 }),
            };
            let m = sim.step(x, v, c).measured;
            let lost = gap_left > 0 && gaps;
            gap_left = gap_left.saturating_sub(1);
            if lost {
                continue;
            }
            let u = step_measured(&mut est, t, &m, c);
            resets += usize::from(u.new_object);
            if t > 30.0 {
                error_sum += est.relative_error().unwrap_or(1.0);
                errors += 1.0;
            }
        }
        let p = est.latest().and_then(|g| g.sliding_mass()).unwrap();
        (resets, error_sum / errors, p, est.stats())
    };
    for seed in [1, 2, 3] {
        let (seen, seen_error, _, seen_stats) = run(seed, Stall::StopSeen);
        assert_eq!((seen, seen_stats.motion_settles), (0, 0), "seed {seed}");
        for stall in [Stall::StopUnseen, Stall::StopAndJump] {
            let (resets, error, p, stats) = run(seed, stall);
            assert_eq!(resets, 0, "seed {seed}: {stats:?}");
            assert!(stats.motion_settles > 40, "seed {seed}: {stats:?}");
            // The RLS's prediction error (learnt samples only): 0.4–1.7 % here, 0.4–0.5 % with
            // the stops seen, 12–16 % before the rule.
            assert!(
                error < 0.03,
                "seed {seed}: {error} against {seen_error} seen"
            );
            assert_exp1_within(&p, 3.0, seed);
        }
        // The same gaps over a smooth motion: the fill holds, learning goes on (a gap at the
        // motion's peak acceleration may be waited out, its two velocities allowing a stop: 1–3
        // of about 70 gaps here).
        let (resets, error, _, stats) = run(seed, Stall::Smooth);
        assert_eq!(resets, 0, "seed {seed}: {stats:?}");
        assert!(stats.motion_settles <= 5, "seed {seed}: {stats:?}");
        assert!(stats.filled_samples > 400, "seed {seed}: {stats:?}");
        assert!(error < 0.01, "seed {seed}: {error}");
    }
}

/// The ROS 2 test arm (`sim::Follower`) goes on along its last target's velocity for 10 ms when
/// its targets stall, then stops at up to 10 m/s² and returns to the path when they come back;
/// on a loaded machine the same held-up link loses its states over the stall. The speed changes
/// inside such a gap while both ends' positions stay within what the two velocities allow, so
/// the motion check passed it; the filters were stepped over it in a straight line and the
/// force transient that followed reset the model: 3–8 times a minute here (seeds 1–3, a stall
/// of 11–42 ms a second; `ros2_figures` 60 s runs: 1–2 resets in three of five). Now a gap over
/// which the measured speed changed so much that a stop may hide in it is waited out, and one
/// over which it changed more than the fill follows mutes the detector (`mmt::estimator::
/// GAP_MUTE_M`). With every state seen, the same stops were never a problem.
#[test]
fn an_arm_that_stops_for_want_of_targets_while_its_states_are_lost_is_not_a_new_object() {
    let run = |seed: u64, lose: bool, stall_ms: (u32, u32)| {
        let (mut est, ex, mut sim) = exp1_with_an_arm(seed);
        let mut stalls = Pcg64::seed_from_u64(seed + 100);
        let mut arm = sim::Follower::default();
        let (mut stall_left, mut stalled_for, mut gap_left) = (0u32, 0u32, 0u32);
        let (mut held, mut resets) = ((0.0, 0.0), 0);
        for k in 0..60_000 {
            let t = k as f64 * 1e-3;
            let c = t >= 0.5;
            if t > 5.0 && stall_left == 0 && rand::Rng::random::<f64>(&mut stalls) < 1e-3 {
                stall_left = rand::Rng::random_range(&mut stalls, stall_ms.0..stall_ms.1);
                stalled_for = 0;
                held = ex.eval(t);
                gap_left = stall_left + 2;
            }
            // The arm's reference: the path, or along the last target for 10 ms, then held.
            let (x_r, v_r) = if stall_left > 0 {
                stall_left -= 1;
                stalled_for += 1;
                let h = f64::from(stalled_for.min(10)) * 1e-3;
                (
                    held.0 + held.1 * h,
                    if stalled_for < 10 { held.1 } else { 0.0 },
                )
            } else {
                let (x, v) = ex.eval(t);
                (x, if c { v } else { 0.0 })
            };
            let (x, v) = arm.step([x_r, 0.0, 0.0], [v_r, 0.0, 0.0], 1e-3);
            let m = sim.step(x[0], v[0], c).measured;
            let lost = lose && gap_left > 0;
            gap_left = gap_left.saturating_sub(1);
            if !lost {
                resets += usize::from(step_measured(&mut est, t, &m, c).new_object);
            }
        }
        let p = est.latest().and_then(|g| g.sliding_mass()).unwrap();
        assert!(arm.breaks().0 > 30, "seed {seed}: {:?}", arm.breaks());
        (resets, p, est.stats())
    };
    for seed in [1, 2, 3] {
        for stall in [(11, 20), (20, 42)] {
            let (resets, p, stats) = run(seed, false, stall);
            let quiet = (resets, stats.motion_settles, stats.gap_mutes);
            assert_eq!(quiet, (0, 0, 0), "seed {seed}: {stats:?}");
            assert_exp1_within(&p, 1.0, seed);
            let (resets, p, stats) = run(seed, true, stall);
            assert_eq!(resets, 0, "seed {seed} {stall:?}: {stats:?}");
            assert!(stats.motion_settles > 10, "seed {seed}: {stats:?}");
            assert!(stats.gap_mutes > 0, "seed {seed}: {stats:?}");
            // The mass is the least excited: −8 % at worst here (−37 % learnt through).
            let truth = Physical::THESIS_EXP1;
            let m = (p.mass_kg / truth.mass_kg - 1.0).abs();
            assert!(m <= 0.1, "seed {seed} {stall:?}: {p:?}");
            let p = Physical {
                mass_kg: truth.mass_kg,
                ..p
            };
            assert_exp1_within(&p, 3.0, seed);
        }
    }
}
