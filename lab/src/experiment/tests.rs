//! The experiments at short durations with their figures asserted (accuracy, never timing).

use super::*;
use mmt::model::backsolve::Confidence;
use mmt::model::prior::{Guess, Prior, PriorSource};
use mmt::vec3;

fn run_with(
    kind: Kind,
    seconds: f64,
    adjust: impl FnOnce(&mut ExperimentConfig),
) -> (Series, ExperimentReport) {
    let mut config = ExperimentConfig::new(kind, Scene::exp1());
    config.seconds = seconds;
    adjust(&mut config);
    run(&config, &mut |_| {}).unwrap()
}

fn assert_bands(r: &ExperimentReport, max_pct: f64) {
    for b in &r.bands {
        let pct = b.rms_error_pct.expect("the band has rendered force");
        assert!(
            pct <= max_pct,
            "band {}–{} Hz: {pct:.2} %",
            b.lo_hz,
            b.hi_hz,
        );
    }
}

/// Issue 4: exp 1 — RMS error after stable ≤ 5 % of the measured RMS, each band ≤ 10 %.
#[test]
fn exp1_meets_its_figures() {
    let (_, r) = run_with(Kind::Exp1, 20.0, |_| {});
    let after = r.rms_error_pct_after_stable.unwrap();
    assert!(after <= 5.0, "after stable {after:.2} %");
    assert_bands(&r, 10.0);
    // The error against the measured force holds the sensor's noise and bias; against the
    // truth only the model's own error is left. Over seeds 1–5 it is 1.90–2.68 % (1.69–3.09 %
    // before the sliding fit's contact element, whose stage moved seed 1 from 2.04 to 2.58 %
    // and seed 4 from 3.09 to 2.68 %): the bound holds the seeds' spread.
    let vs_truth = r.rms_error_pct_after_stable_vs_true_force.unwrap();
    assert!(
        vs_truth < after && vs_truth <= 3.0,
        "against the truth {vs_truth:.2} %, measured {after:.2} %"
    );
    assert_eq!(
        r.contact_switch_latency_ms.switches, 5,
        "three episodes: five switches"
    );
}

/// Issue 4: exp 3 (400 ms each way) — the same accuracy, contact switched within 2 ms with
/// operator-side detection, a round trip with the remote state only (as in the thesis).
#[test]
fn exp3_meets_its_figures() {
    let (_, r) = run_with(Kind::Exp3, 20.0, |_| {});
    assert_eq!(r.delay_ms, 400.0);
    let after = r.rms_error_pct_after_stable.unwrap();
    assert!(after <= 5.0, "after stable {after:.2} %");
    assert_bands(&r, 10.0);
    let l = r.contact_switch_latency_ms;
    assert!(
        l.local.unwrap() <= 2.0 && l.local_max.unwrap() <= 3.0,
        "{l:?}"
    );
    let remote = l.remote_only.unwrap();
    assert!(
        (remote - 800.0).abs() <= 20.0,
        "remote-only {remote} ms, expected about the 800 ms round trip"
    );
    // Switching from the delayed remote state costs accuracy: the thesis's failure mode.
    assert!(r.rms_error_pct_remote_contact.unwrap() > 4.0 * after);
}

/// Issue 14: exp 3 on a depth camera's cloud — 40 % of the points dropped at random, or a
/// fifth of the face in hole patches 1.5–4.5 cm across — keeps its figures: error after stable ≤ 5 % (the thesis's proxy: 88 %
/// at 10 % dropout, every contact from 13 s on lost or inverted), contact switched locally
/// within milliseconds, no switch missed.
#[test]
fn exp3_holds_on_camera_clouds_with_dropout_and_hole_patches() {
    type Camera = fn(&mut Scene);
    let cameras: [(&str, Camera); 2] = [
        ("dropout 0.4", |s| s.cloud.dropout = 0.4),
        ("holes 0.2", |s| s.cloud.holes = 0.2),
    ];
    for (name, camera) in cameras {
        let mut scene = Scene::exp1();
        camera(&mut scene);
        let scene = Scene::from_toml(&toml::to_string(&scene).unwrap(), name).unwrap();
        for seed in [1, 2] {
            let (_, r) = run_with(Kind::Exp3, 20.0, |config| {
                config.scene = scene.clone();
                config.seed = seed;
            });
            let after = r.rms_error_pct_after_stable.unwrap();
            assert!(
                after <= 5.0,
                "{name}, seed {seed}: after stable {after:.2} %"
            );
            let l = r.contact_switch_latency_ms;
            assert_eq!((l.switches, l.local_missed), (5, 0), "{name}, seed {seed}");
            assert!(
                l.local.unwrap() <= 5.0 && l.local_max.unwrap() <= 10.0,
                "{name}, seed {seed}: {l:?}"
            );
        }
    }
}

/// Issue 4: exp 2 — reconstruction error ≤ 2 %, time to stable ≤ 2 s.
#[test]
fn exp2_meets_its_figures() {
    let (_, r) = run_with(Kind::Exp2, 15.0, |_| {});
    let recon = r.reconstruction_error_pct.unwrap();
    assert!(recon <= 2.0, "reconstruction {recon:.2} %");
    let tts = r.time_to_stable_s.unwrap();
    assert!(tts <= 2.0, "time to stable {tts:.2} s");
    // The final sets are well conditioned, and none of the confirmed ones was low-confidence.
    assert!(!r.parameters.is_empty());
    for p in &r.parameters {
        assert_eq!(p.confidence, Confidence::Identified, "{}", p.axes);
        assert!(p.confirmed_updates.unwrap() > 0, "{}", p.axes);
        assert_eq!(p.low_confidence_updates, Some(0), "{}", p.axes);
    }
}

/// A low-confidence set (k1 ≫ k2: condition ≈ 26) is reported as such in the JSON and the table,
/// next to the unchanged keys.
#[test]
fn low_confidence_parameters_are_reported() {
    use mmt::model::gates::{GateConfig, gate};
    use mmt::model::{Physical, Structure};
    let heavy_ground = Physical::new(0.5, 5000.0, 5.0, 300.0, 10.0, 0.3);
    let structure = Structure::SlidingMass {
        ground_spring: true,
        friction: true,
    };
    let g = gate(
        structure,
        &heavy_ground.theta().unwrap(),
        None,
        &GateConfig::default(),
    )
    .unwrap();
    let report = parameter_report(&Scene::exp1(), [None, Some(&g)]);
    assert_eq!(report.len(), 1);
    let Confidence::Low { condition } = report[0].confidence else {
        panic!("{:?}", report[0].confidence)
    };
    assert!(condition > 15.0 && condition == report[0].condition);
    let json = serde_json::to_value(&report[0]).unwrap();
    assert_eq!(json["axes"], "tangential");
    assert!(json["values"].is_array());
    assert_eq!(json["confidence"]["kind"], "low");
    assert!(json.get("low_confidence_updates").is_none());
    // The in-process run fills in the counts and the table says it.
    let (_, mut r) = run_with(Kind::Exp1, 3.0, |_| {});
    let mut low = report[0].clone();
    low.low_confidence_updates = Some(4);
    low.confirmed_updates = Some(9);
    r.parameters = vec![low];
    let table = metrics::table(&r);
    assert!(
        table.contains("back-solve confidence, tangential: LOW")
            && table.contains("4 of 9 confirmed sets low-confidence"),
        "{table}"
    );
}

/// The wall identifies and renders two parameters per axis, streams no moving cloud, and its
/// report says what it left out.
#[test]
fn the_wall_uses_two_parameters_per_axis() {
    let mut config = ExperimentConfig::new(Kind::Exp1, Scene::wall());
    config.seconds = 15.0;
    config.trajectory = "probe".into();
    let (_, r) = run(&config, &mut |_| {}).unwrap();
    assert_eq!(r.parameters.len(), 2, "{:?}", r.parameters);
    for p in &r.parameters {
        let names: Vec<&str> = p.values.iter().map(|v| v.0.as_str()).collect();
        assert_eq!(names, ["k", "b"], "{} axes", p.axes);
        // The stiffness is well excited; the damping of a 2 mm press much less.
        let (k, b) = (&p.values[0], &p.values[1]);
        assert!(
            (k.2 / k.1 - 1.0).abs() < 0.1,
            "{} k: {} vs {}",
            p.axes,
            k.2,
            k.1
        );
        assert!(
            b.2 > 0.5 * b.1 && b.2 < 2.0 * b.1,
            "{} b: {} vs {}",
            p.axes,
            b.2,
            b.1
        );
    }
    assert_eq!(r.operator_stats.clouds, 1, "a static cloud is sent once");
    assert_eq!(r.operator_stats.moved_clouds, 0, "nor moved by a slide");
    for term in [
        "tangential: mass",
        "tangential: coulomb friction",
        "moving cloud (the cloud is sent once)",
    ] {
        assert!(
            r.left_out.iter().any(|l| l == term),
            "{term} not in {:?}",
            r.left_out
        );
    }
    assert!(r.rms_error_pct_after_stable.unwrap() <= 10.0);
}

/// Same seed, same report, bit for bit; another seed, another report.
#[test]
fn same_seed_same_report_bits() {
    let json = |seed: u64| {
        let (_, r) = run_with(Kind::Exp1, 6.0, |c| c.seed = seed);
        serde_json::to_string(&r).unwrap()
    };
    assert_eq!(json(7), json(7));
    assert_ne!(json(7), json(8));
}

/// Lost, duplicated and reordered datagrams (5 % each, both ways, 50 ms delay) change nothing
/// unsafe: every force finite and within the physical range, and the model still renders well,
/// whatever the seed (an early reordered command once held the playout lag down for good).
#[test]
fn lost_duplicated_and_reordered_messages_change_nothing_unsafe() {
    for seed in 1..=3 {
        let (series, r) = run_with(Kind::Exp1, 15.0, |c| {
            c.delay_ms = 50.0;
            c.loss = 0.05;
            c.duplicate = 0.05;
            c.reorder = 0.05;
            c.seed = seed;
        });
        let max_measured = series
            .measured
            .iter()
            .flatten()
            .map(|f| vec3::norm(*f))
            .fold(0.0, f64::max);
        for f in series.rendered.iter().chain(&series.rendered_remote) {
            assert!(vec3::is_finite(*f));
            assert!(
                vec3::norm(*f) <= 2.0 * max_measured,
                "seed {seed}: {f:?} against at most {max_measured} N measured"
            );
        }
        let after = r
            .rms_error_pct_after_stable
            .expect("parameters pass the gates");
        assert!(after <= 5.0, "seed {seed}: after stable {after:.2} %");
        let t = &r.telerobot_stats;
        assert!(
            t.stale_commands > 0,
            "duplicated commands are dropped, not executed twice"
        );
        assert!(
            t.stale_commands + t.skipped_commands <= t.commands / 10,
            "seed {seed}: {} stale and {} skipped of {} commands",
            t.stale_commands,
            t.skipped_commands,
            t.commands
        );
    }
}

/// Jitter that keeps packet order bunches the commands: the playout plays them in order
/// instead of skipping to the newest (which cost 11 % error at 5 ms jitter).
#[test]
fn jittered_commands_are_played_in_order() {
    let (_, r) = run_with(Kind::Exp1, 15.0, |c| {
        c.delay_ms = 50.0;
        c.jitter_ms = 5.0;
    });
    let after = r
        .rms_error_pct_after_stable
        .expect("parameters pass the gates");
    assert!(after <= 5.0, "after stable {after:.2} %");
    assert_bands(&r, 10.0);
    let t = &r.telerobot_stats;
    assert!(
        t.skipped_commands <= t.commands / 10,
        "{} of {} commands skipped",
        t.skipped_commands,
        t.commands
    );
}

#[test]
fn bad_settings_name_the_field() {
    let mut config = ExperimentConfig::new(Kind::Exp1, Scene::exp1());
    config.seconds = 0.0;
    let e = run(&config, &mut |_| {}).unwrap_err();
    assert!(e.to_string().contains("seconds = 0"), "{e}");
    assert!(
        Kind::parse("exp4")
            .unwrap_err()
            .to_string()
            .contains("exp4")
    );
    let mut config = ExperimentConfig::new(Kind::Exp1, Scene::exp1());
    config.trajectory = "nope".into();
    assert!(run(&config, &mut |_| {}).is_err());
}

/// A run too short for the parameters to pass the gates renders nothing: its error figures are
/// absent (`null`), not 0 %.
#[test]
fn a_run_without_rendering_reports_no_error_figures() {
    let (series, r) = run_with(Kind::Exp1, 1.0, |_| {});
    assert!(series.rendering.iter().all(|r| !r));
    assert_eq!(r.rms_error_pct_after_stable, None);
    assert!(
        r.bands.iter().all(|b| b.rms_error_pct.is_none()),
        "{:?}",
        r.bands
    );
    let json = serde_json::to_value(&r).unwrap();
    assert!(json["bands"][0]["rms_error_pct"].is_null());
}

/// Issue 13: before, a new object rendered nothing for 1.1 s after first contact (exp 1, the
/// time the first model takes). The generic prior renders from the first tick of local contact.
/// Without the first fits (which now come within about 30 ms) the RLS's model is that late.
#[test]
fn the_prior_is_felt_from_the_first_tick_of_local_contact() {
    let (series, with) = run_with(Kind::Exp1, 4.0, |c| c.first_fit = false);
    let (series_without, without) = run_with(Kind::Exp1, 4.0, |c| {
        c.first_fit = false;
        c.operator.prior = None;
    });
    assert_eq!(with.prior, Some(Prior::generic()));
    assert_eq!(with.first_force_after_local_contact_ms, Some(0.0));
    let late = without.first_force_after_local_contact_ms.unwrap();
    assert!(late >= 500.0, "without a prior: {late} ms");
    // Contact is never rendered as free space: every tick in local contact pushes.
    let onset = series.contact_local.iter().position(|c| *c).unwrap();
    let first_model = series.rendering.iter().position(|r| *r).unwrap();
    assert!(first_model > onset + 500, "{onset} {first_model}");
    let free = (onset..first_model)
        .filter(|&i| series.contact_local[i] && vec3::norm2(series.rendered[i]) == 0.0)
        .count();
    assert_eq!(free, 0, "ticks in contact rendered as free space");
    let (w, wo) = (with.rms_error_pct.unwrap(), without.rms_error_pct.unwrap());
    assert!(
        w < 0.8 * wo,
        "from first contact: {w:.2} % with, {wo:.2} % without"
    );
    // The hand-over to the first model has no jump: within the safety layer's default force-rate
    // limit (1,000 N/s, 1 N a tick). Without a prior the model starts with a step.
    let step = |s: &Series| {
        let at = s.rendering.iter().position(|r| *r).unwrap();
        (at - 5..at + 100)
            .map(|i| vec3::norm(vec3::sub(s.rendered[i], s.rendered[i - 1])))
            .fold(0.0, f64::max)
    };
    let (smooth, jump) = (step(&series), step(&series_without));
    assert!(smooth <= 1.0, "hand-over step {smooth:.2} N");
    assert!(jump > 1.0, "without a prior: {jump:.2} N");
}

/// Issue 13: a prior far from the truth (×0.2 and ×5 in stiffness) costs accuracy for a bounded
/// time only, and never stability: the force stays on the scale of the measured one, and from
/// 1 s after the first model on, the error is what it is with no prior at all.
#[test]
fn a_prior_far_from_the_truth_costs_accuracy_for_a_bounded_time_only() {
    for kind in [Kind::Exp1, Kind::Exp3] {
        let (_, none) = run_with(kind, 20.0, |c| c.operator.prior = None);
        for scale in [0.2, 5.0] {
            let (series, r) = run_with(kind, 20.0, |c| {
                let env = c.scene.environment;
                let mut prior =
                    Prior::given(scale * env.k_contact_n_per_m, env.b_contact_ns_per_m).unwrap();
                prior.tangential = env.physical();
                prior.tangential.k_contact_n_per_m *= scale;
                c.operator.prior = Some(prior);
            });
            let largest = |v: &[[f64; 3]]| v.iter().map(|f| vec3::norm(*f)).fold(0.0, f64::max);
            let measured: Vec<[f64; 3]> = series.measured.iter().flatten().copied().collect();
            let (rendered, measured) = (largest(&series.rendered), largest(&measured));
            assert!(
                rendered.is_finite() && rendered <= 3.0 * measured,
                "{kind:?} ×{scale}: largest force {rendered:.1} N, measured {measured:.1} N"
            );
            let start = r.render_start_s.unwrap() + first_contact_s(&series) + 1.0;
            let windows = r.error_over_time.iter().zip(&none.error_over_time);
            for (w, n) in windows.filter(|(w, _)| w.t_s >= start) {
                let (e, e_none) = (
                    w.rms_error_pct.unwrap_or(0.0),
                    n.rms_error_pct.unwrap_or(0.0),
                );
                assert!(
                    (e - e_none).abs() <= 0.5,
                    "{kind:?} ×{scale}: {e:.2} % at {} s, {e_none:.2} % with no prior",
                    w.t_s
                );
            }
            // The "after stable" window begins at the first whole model: on exp 1's object that
            // is now the sliding first fit, about 0.25 s into the first contact, so it holds the
            // prior's hand-over (exp 1, ×0.2: 5.3 % against 3.1 % with no prior; the windows
            // from a second after the first model on are the same, above).
            let (after, after_none) = (
                r.rms_error_pct_after_stable.unwrap(),
                none.rms_error_pct_after_stable.unwrap(),
            );
            assert!(
                after <= after_none + 2.5,
                "{kind:?} ×{scale}: after stable {after:.2} %, {after_none:.2} % with no prior"
            );
        }
    }
}

/// Issue 13 item 5: a scene's `[prior]` is what the operator renders from the first tick of
/// contact (unless told otherwise), exactly as the same prior given directly; the report names
/// it and gives the error of each stage.
#[test]
fn a_scene_prior_is_rendered_from_the_first_tick_and_reported_with_each_stage() {
    let truth = |c: &ExperimentConfig| {
        let env = c.scene.environment;
        Guess {
            mass_kg: Some(env.mass_kg),
            k_ground_n_per_m: Some(env.k_ground_n_per_m),
            b_ground_ns_per_m: Some(env.b_ground_ns_per_m),
            k_contact_n_per_m: Some(env.k_contact_n_per_m),
            b_contact_ns_per_m: Some(env.b_contact_ns_per_m),
            coulomb_friction_n: Some(env.coulomb_friction_n),
            spread: 0.0,
        }
    };
    // Without the first fits, so that the prior's stage lasts until the RLS's model (1.1 s).
    let (s_scene, scene) = run_with(Kind::Exp1, 4.0, |c| {
        c.first_fit = false;
        c.scene.prior = Some(truth(c));
    });
    let (s_given, given) = run_with(Kind::Exp1, 4.0, |c| {
        c.first_fit = false;
        let mut prior = truth(c).prior().unwrap();
        prior.source = PriorSource::Truth;
        c.operator.prior = Some(prior);
    });
    let (_, generic) = run_with(Kind::Exp1, 4.0, |c| {
        c.first_fit = false;
        c.scene.prior = Some(truth(c));
        c.operator.prefer_scene_prior = false;
    });
    assert_eq!(scene.prior.map(|p| p.source), Some(PriorSource::Scene));
    assert_eq!(generic.prior, Some(Prior::generic()));
    assert_eq!(
        s_scene.rendered, s_given.rendered,
        "the same prior renders the same"
    );
    assert_eq!(scene.first_force_after_local_contact_ms, Some(0.0));
    // The stages: the prior's error is the truth's (small) against the generic's, then models.
    let (p, g) = (scene.stage_errors, generic.stage_errors);
    let (e_scene, e_generic) = (p.prior_pct.unwrap(), g.prior_pct.unwrap());
    assert!(
        e_scene < 0.5 * e_generic,
        "prior stage: {e_scene:.1} % against {e_generic:.1} %"
    );
    assert!(p.seconds[0] > 0.3 && p.whole_pct.is_some(), "{p:?}");
    assert_eq!(p, given.stage_errors);
    let table = metrics::table(&scene);
    assert!(table.contains("the scene's prior"), "{table}");
    assert!(
        table.contains("error in contact: prior / reduced / whole model"),
        "{table}"
    );
}

fn first_contact_s(series: &Series) -> f64 {
    let i = series.contact_true.iter().position(|c| *c == Some(true));
    i.unwrap() as f64 * series.dt_s()
}

/// Issue 13 item 2: a Kelvin–Voigt group's first fit. The wall (Kelvin–Voigt on every axis)
/// renders models from about 0.06 s after first contact instead of about 1.4 s, and its error from
/// first contact falls well below the same run's without the first fit; exp 1 gets one for its
/// normal only (its tangents are a sliding object), and the report says so.
#[test]
fn a_kelvin_voigt_contact_renders_its_first_fit_within_a_tenth_of_a_second() {
    let wall = |first: bool| {
        let mut config = ExperimentConfig::new(Kind::Exp1, Scene::wall());
        config.seconds = 20.0;
        config.first_fit = first;
        run(&config, &mut |_| {}).unwrap().1
    };
    let (with, without) = (wall(true), wall(false));
    let start = with.render_start_s.unwrap();
    assert!(start <= 0.1, "rendering from {start} s");
    let late = without.render_start_s;
    assert!(late.is_none_or(|s| s > 0.5), "without: {late:?}");
    let (e_with, e_without) = (with.rms_error_pct.unwrap(), without.rms_error_pct.unwrap());
    assert!(
        e_with < 0.5 * e_without && e_with < 3.0,
        "from first contact: {e_with:.2} % against {e_without:.2} % without"
    );
    for e in &with.estimators {
        assert!(e.stats.first_fit_after_s.is_some_and(|s| s <= 0.1), "{e:?}");
    }
    let (_, exp1) = run_with(Kind::Exp1, 3.0, |_| {});
    let first = |axes: &str| {
        let e = exp1.estimators.iter().find(|e| e.axes == axes).unwrap();
        e.stats.first_fit_after_s
    };
    assert!(first("normal").is_some_and(|s| s <= 0.1), "{exp1:?}");
    // Its tangents are a sliding object: their first fit is the simulated one's
    // (`estimator::slide_fit`), within the first contact.
    assert!(first("tangential").is_some_and(|s| s <= 0.44), "{exp1:?}");
    let table = metrics::table(&exp1);
    assert!(table.contains("first fit after contact"), "{table}");
}

/// Issue 13 item 6: at 2 s one way the camera window of exp 3 (centred on the tool a round trip
/// ago) no longer covers the tool, and contact inverted at its edge: 75 % error after stable.
/// Moved by the slide the operator's model predicts since each frame's capture, the window
/// follows the object the tool drags, and the error after stable is back within 5 %.
#[test]
fn the_cloud_moved_by_the_predicted_slide_holds_exp3_at_two_seconds() {
    let exp3 = |slide: bool| {
        run_with(Kind::Exp3, 30.0, |c| {
            c.delay_ms = 2000.0;
            c.operator.move_cloud_with_slide = slide;
        })
        .1
    };
    let (with, without) = (exp3(true), exp3(false));
    let (e_with, e_without) = (
        with.rms_error_pct_after_stable.unwrap(),
        without.rms_error_pct_after_stable.unwrap(),
    );
    assert!(
        e_with <= 5.0,
        "after stable {e_with:.2} % (without: {e_without:.2} %)"
    );
    assert!(e_without > 50.0, "without the slide {e_without:.2} %");
    let s = with.operator_stats;
    assert!(s.moved_clouds > 0 && s.largest_cloud_move_m > 0.05, "{s:?}");
    assert_eq!(s.cloud_moves_beyond_history, 0);
    assert_eq!(without.operator_stats.moved_clouds, 0);
    let l = with.contact_switch_latency_ms;
    assert_eq!((l.switches, l.local_missed), (5, 0), "{l:?}");
}

/// Issue 13 item 2 for a sliding object: the telerobot fits the whole sliding-mass model to its
/// first contact by simulation (`mmt::estimator::SlideFitConfig`), so its tangents render a
/// model within a few tenths of a second of first contact instead of the prior for about a
/// second (its contact element alone within a few hundredths); on exp 1's object and on a
/// heavier, softer one with realistic friction (1.2 N of Coulomb friction on 3 kg) that no
/// default was tuned on.
#[test]
fn a_sliding_objects_first_contact_renders_its_fit_within_a_few_tenths_of_a_second() {
    let mut heavy = Scene::exp1();
    let e = &mut heavy.environment;
    (e.mass_kg, e.k_contact_n_per_m, e.b_contact_ns_per_m) = (3.0, 300.0, 25.0);
    (
        e.b_ground_ns_per_m,
        e.static_friction_n,
        e.coulomb_friction_n,
    ) = (20.0, 1.7, 1.2);
    for scene in [Scene::exp1(), heavy] {
        let exp1 = |first: bool| {
            let mut config = ExperimentConfig::new(Kind::Exp1, scene.clone());
            config.seconds = 10.0;
            config.first_fit = first;
            run(&config, &mut |_| {}).unwrap().1
        };
        let (with, without) = (exp1(true), exp1(false));
        let tangential = with.estimators.iter().find(|e| e.axes == "tangential");
        let stats = tangential.map(|e| e.stats).unwrap();
        // The contact element's reduced set within 50 ms, every term's within 0.3 s.
        let (first, whole) = (stats.first_fit_after_s, stats.whole_fit_after_s);
        assert!(
            first.is_some_and(|s| s <= 0.05) && stats.contact_fits > 0,
            "{}: {stats:?}",
            scene.name
        );
        assert!(whole.is_some_and(|s| s <= 0.3), "{}: {stats:?}", scene.name);
        let prior_s = |r: &ExperimentReport| r.stage_errors.seconds[0];
        assert!(
            prior_s(&with) <= 0.3 && prior_s(&without) > 0.9,
            "{}: the prior rendered {} s, {} s without",
            scene.name,
            prior_s(&with),
            prior_s(&without)
        );
        let (e_with, e_without) = (with.rms_error_pct.unwrap(), without.rms_error_pct.unwrap());
        assert!(
            e_with < 0.85 * e_without,
            "{}: from first contact {e_with:.2} % against {e_without:.2} % without",
            scene.name
        );
    }
}
