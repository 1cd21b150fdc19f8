//! Issue 12: objects other than exp 1's, through the whole pipeline (the two nodes, the link
//! model, the simulated world), as `mmt benchmark` runs them.

#![allow(clippy::unwrap_used)]

use lab::benchmark::{
    BenchmarkConfig, Case, CaseFigures, Object, StructureMode, corner_cases, run_case,
};

/// One case as `mmt benchmark` runs it: franka-like sensors, the estimator given `structure`.
fn run_object(
    object: &Object,
    motion: &str,
    delay_ms: f64,
    seed: u64,
    seconds: f64,
    structure: StructureMode,
) -> CaseFigures {
    let config = BenchmarkConfig {
        seconds,
        structure,
        ..BenchmarkConfig::default()
    };
    let case = Case {
        object: 0,
        motion: motion.to_string(),
        delay_ms,
        preset: "franka-like".to_string(),
        seed,
    };
    run_case(&config, object, &case).unwrap()
}

/// A named corner case with its own structure.
fn run(name: &str, motion: &str, delay_ms: f64, seed: u64, seconds: f64) -> CaseFigures {
    let object = corner_cases().into_iter().find(|o| o.name == name).unwrap();
    run_object(
        &object,
        motion,
        delay_ms,
        seed,
        seconds,
        StructureMode::Object,
    )
}

/// The spring-mounted object (k1 = 500 N/m) was never rendered: each contact episode begins
/// at a different place relative to the ground spring's rest, which bent θ until no gate
/// passed. With a constant column restarted at every onset it is rendered within 2 s of
/// contact, its error from the first contact (60 s) within 10 % and k1 within 20 %.
#[test]
fn spring_mounted_object_is_rendered_with_an_intercept_per_contact() {
    for seed in [1, 2] {
        let f = run("spring-mounted", "exp1", 0.0, seed, 60.0);
        let render = f.time_to_first_render_s.unwrap();
        let first = f.error_from_first_contact_pct.unwrap();
        let k1 = f
            .parameters
            .iter()
            .find(|p| p.0 == "tangential" && p.1 == "k1")
            .map(|p| p.4)
            .unwrap();
        eprintln!(
            "seed {seed}: render {render:.2} s, from first contact {first:.1} %, k1 {k1:+.0} %"
        );
        assert!(render <= 2.0, "seed {seed}: first render at {render} s");
        assert!(
            first <= 10.0,
            "seed {seed}: error from first contact {first} %"
        );
        assert!(k1.abs() <= 20.0, "seed {seed}: k1 error {k1} %");
    }
}

/// Seed 3's class object 07 (0.75 kg, k2 260 N/m, Fs 1.36 N) was never rendered: the tool's
/// sign could not fit it well enough for the confidence gate, and the friction observer, which
/// would, started only at the first confirmed set. It now also starts after
/// `observer_wait_s` (1 s) of learning without one; measured: first render 3.6 s after contact.
#[test]
fn an_object_the_tool_sign_cannot_confirm_is_rendered_after_the_observer_wait() {
    let object = Object {
        name: "class-07".to_string(),
        mass_kg: 0.7548,
        k_ground_n_per_m: 0.0,
        b_ground_ns_per_m: 13.41,
        k_contact_n_per_m: 260.4,
        b_contact_ns_per_m: 6.457,
        static_friction_n: 1.355,
        coulomb_friction_n: 0.9485,
        ground_spring: false,
    };
    let f = run_object(&object, "exp1", 0.0, 3008, 20.0, StructureMode::Object);
    let render = f.time_to_first_render_s;
    eprintln!("first render {render:?} s after contact");
    assert!(render.is_some_and(|t| t <= 6.0), "first render {render:?}");
}

/// A slow probe never excites the mass: the seed-1 class objects 00 (spring-mounted), 02 and 11
/// (μ ≈ 0.13–0.2) were never rendered with it — every whole set failed a gate (θ̂ not passive,
/// the mass not identified) — and the operator felt the prior only (20 s: 37–40 % error from
/// the first contact on 00 and 11). The massless part of the structure is identified long
/// before the mass and is rendered until the whole set passes: measured 1.7–4.3 s to the first
/// render, 14–18 % error from the first contact.
#[test]
fn a_slow_probe_that_never_excites_the_mass_renders_the_massless_part() {
    let object = Object::from_terms;
    let objects = [
        (
            object("class-00", [1.142, 350.5, 5.402, 687.9, 50.6], 1.271),
            1001,
        ),
        (
            object("class-02", [0.6276, 0.0, 11.73, 459.8, 53.05], 1.27),
            1003,
        ),
        (
            object("class-11", [0.7646, 0.0, 48.73, 356.7, 12.39], 0.9803),
            1012,
        ),
    ];
    for (object, seed) in objects {
        let f = run_object(&object, "slow", 0.0, seed, 20.0, StructureMode::Object);
        let (render, first) = (f.time_to_first_render_s, f.error_from_first_contact_pct);
        eprintln!(
            "{}: first render {render:?} s, from first contact {first:?} %, {} reduced sets",
            object.name, f.reduced
        );
        assert!(
            render.is_some_and(|t| t <= 6.0),
            "{}: first render {render:?}",
            object.name
        );
        assert!(f.reduced > 0, "{}", object.name);
        assert!(
            first.is_some_and(|e| e <= 22.0),
            "{}: {first:?} %",
            object.name
        );
    }
}

/// Steps hold the object still between moves, by stiction above `Fc` that neither model has: the
/// whole structure's prediction error then stays near 100 % of the output, and the reduced set,
/// judged by it, was withheld for the whole run (seed-1 class object 20, 20 s: never rendered,
/// 31 % from the first contact). Judged by its own fit and stillness it renders after 2.0 s
/// (19 % from the first contact).
#[test]
fn steps_that_hold_the_object_by_stiction_still_render_the_massless_part() {
    let object = Object::from_terms("class-20", [1.337, 0.0, 46.12, 511.9, 12.36], 1.321);
    let f = run_object(&object, "steps", 0.0, 1021, 20.0, StructureMode::Object);
    let (render, first) = (f.time_to_first_render_s, f.error_from_first_contact_pct);
    eprintln!(
        "first render {render:?} s, from first contact {first:?} %, {} reduced sets",
        f.reduced
    );
    assert!(render.is_some_and(|t| t <= 4.0), "first render {render:?}");
    assert!(f.reduced > 0);
    assert!(first.is_some_and(|e| e <= 25.0), "{first:?} %");
}

/// A scene that gives every object the largest structure (ground spring and friction) — one
/// that does not say what the object needs — left free objects without a confirmed whole set
/// for most of a run: seed-1 class objects 13 and 23 were stable only after 57–59 s of 60.
/// Choosing the structure from the data (`--structure select`) leaves their ground spring out
/// and keeps it for the spring-mounted object: measured stable after 1.8–1.9 s, error after
/// stable 2.6–4.6 %, and the spring-mounted object rendered 0.8 s after contact, 3.8 % from
/// the first contact.
#[test]
fn a_scene_that_does_not_say_gets_the_structure_each_object_needs() {
    let run = |object: &Object, seed: u64, structure: StructureMode| {
        run_object(object, "exp1", 0.0, seed, 60.0, structure)
    };
    let free = [
        (
            Object::from_terms("class-13", [0.8897, 0.0, 8.534, 818.8, 11.86], 0.7539),
            1014,
        ),
        (
            Object::from_terms("class-23", [2.491, 0.0, 7.732, 1898.0, 37.9], 0.603),
            1024,
        ),
    ];
    for (object, seed) in &free {
        let whole = run(object, *seed, StructureMode::Whole);
        let chosen = run(object, *seed, StructureMode::Select);
        let (w, c) = (whole.time_to_stable_s, chosen.time_to_stable_s);
        eprintln!(
            "{}: stable after {w:?} s with the whole structure, {c:?} s choosing {:?} \
             (after stable {:?} %)",
            object.name, chosen.selected, chosen.error_after_stable_pct
        );
        assert!(w.is_none_or(|t| t > 30.0), "{}: whole {w:?}", object.name);
        assert!(c.is_some_and(|t| t <= 4.0), "{}: chosen {c:?}", object.name);
        assert_eq!(
            chosen.ground_spring_chosen_right,
            Some(true),
            "{}",
            object.name
        );
        assert!(
            chosen.error_after_stable_pct.is_some_and(|e| e <= 6.0),
            "{}: {:?}",
            object.name,
            chosen.error_after_stable_pct
        );
    }
    let spring = corner_cases()
        .into_iter()
        .find(|o| o.name == "spring-mounted")
        .unwrap();
    let f = run(&spring, 1, StructureMode::Select);
    eprintln!(
        "spring-mounted: chose {:?}, render {:?} s, from first contact {:?} %",
        f.selected, f.time_to_first_render_s, f.error_from_first_contact_pct
    );
    assert_eq!(f.ground_spring_chosen_right, Some(true));
    assert!(f.time_to_first_render_s.is_some_and(|t| t <= 2.0));
    assert!(f.error_from_first_contact_pct.is_some_and(|e| e <= 10.0));
}

/// A scene that gives a free object a ground spring it does not have let a degenerate set pass
/// every gate: seed 2's class object 24 (0.52 kg, k2 203 N/m) was fitted with k1 3,916 N/m,
/// k2 0.58 N/m and m 9.6 kg, and the operator rendered up to 38 kN against 2 N (1.3 million %
/// error from the first contact). The contact spring would deflect 3.4 m under the force
/// measured; such a set is now refused, and the operator keeps its prior until a plausible
/// set comes (measured: at most 18.5 N rendered, 337 % from the first contact, most of it the
/// prior's for the first 20 s).
#[test]
fn a_set_whose_contact_spring_is_too_soft_for_the_force_is_not_rendered() {
    use lab::benchmark::{Object, StructureMode};
    let object = Object::from_terms("class-24", [0.5238, 0.0, 8.333, 203.0, 9.239], 0.4357);
    let f = run_object(&object, "exp1", 0.0, 2025, 60.0, StructureMode::Whole);
    let first = f.error_from_first_contact_pct;
    eprintln!("from first contact {first:?} %, {:?}", f.rejections);
    assert!(first.is_some_and(|e| e < 500.0), "{first:?} %");
    assert!(f.rejections.too_soft > 0);
}
