//! Findings of the fuzz campaign and its proptests (`fuzz/README.md`), each the input that
//! found it.
#![allow(clippy::unwrap_used)]

use sim::scene::{EXP1_TOML, Scene};
use sim::world::World;

/// Found by the `scene` seeds: `rates.control_hz` passes validation from 100 Hz, but the
/// sliding-object simulation integrated with a fixed 10 sub-steps per tick and refused any rate
/// below 1 kHz (sub-step > 0.1 ms), so a valid 500 Hz scene failed at world creation.
#[test]
fn a_valid_scene_below_1_khz_builds_its_world() {
    // (Far above 1 kHz the point-cloud budget refuses exp-1's cloud: a tick of 50 µs at 20 kHz.)
    for hz in ["100.0", "500.0", "999.0", "1000.0", "2000.0"] {
        let text = format!("{EXP1_TOML}\n[rates]\ncontrol_hz = {hz}\n");
        let scene = Scene::from_toml(&text, "rates.toml").unwrap();
        assert!(
            !scene.environment.anchored,
            "the sliding simulation is the one with sub-steps"
        );
        let mut world = World::new(&scene, [0.0, 0.0, 0.01], 1)
            .unwrap_or_else(|e| panic!("control_hz = {hz}: {e}"));
        for k in 0..50 {
            let s = world.step([0.0, 0.0, 0.01 - 0.0003 * f64::from(k)], [0.0, 0.0, -0.3]);
            assert!(s.truth.is_finite(), "control_hz = {hz}, tick {k}: {s:?}");
        }
    }
}

/// Found by `mutated_seeds_are_refused_or_usable` (the `scene` target's proptest): a `[cloud]`
/// key the source does not use was not checked at all, so `spacing_m = nan` in a ROS 2 scene
/// (or `stale_ms = nan` in a plane scene) was accepted, and the scene written back out no longer
/// equalled itself.
#[test]
fn a_nan_in_a_cloud_key_the_source_ignores_is_refused() {
    let ros2 = EXP1_TOML.replace("source = \"plane\"", "source = \"ros2\"");
    for (base, key, line) in [
        (ros2.as_str(), "cloud.spacing_m", "spacing_m = nan"),
        (ros2.as_str(), "cloud.dropout", "dropout = inf"),
        (EXP1_TOML, "cloud.stale_ms", "stale_ms = nan"),
        (EXP1_TOML, "cloud.voxel_m", "voxel_m = -inf"),
        (
            EXP1_TOML,
            "cloud.pose.translation_m",
            "pose = { translation_m = [0.0, nan, 0.0] }",
        ),
    ] {
        // The key in place of the seed's own line for it, if it has one.
        let name = line.split(' ').next().unwrap();
        let text = base
            .lines()
            .filter(|l| !l.starts_with(&format!("{name} =")))
            .collect::<Vec<_>>()
            .join("\n")
            .replace("[cloud]", &format!("[cloud]\n{line}"));
        let err = Scene::from_toml(&text, "nan.toml").unwrap_err().to_string();
        assert!(err.contains(key) && err.contains("finite"), "{line}: {err}");
    }
}

/// Found by `mutated_seeds_are_refused_or_usable` after the budget merge: a sliding object with
/// `stick_velocity_m_per_s = 0` passed validation (0 was allowed) and the world then refused it
/// ("stick_band_m_per_s = 0 invalid"). A sliding object needs a stick band; an anchored one
/// may have none.
#[test]
fn a_sliding_object_without_a_stick_band_is_refused_at_validation() {
    let text = EXP1_TOML.replace(
        "stick_velocity_m_per_s = 0.005",
        "stick_velocity_m_per_s = 0.0",
    );
    assert_ne!(text, EXP1_TOML);
    let e = Scene::from_toml(&text, "band.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("environment.stick_velocity_m_per_s"), "{e}");
}
