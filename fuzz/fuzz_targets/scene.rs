//! Parses arbitrary text as a scene (`sim::Scene::from_toml`: TOML, then field-by-field
//! validation). Never a panic; and a scene that passes validation is one every consumer accepts:
//! its motion limits validate, the telerobot node builds from its settings, the operator accepts
//! its `Welcome` and derives the same settings the telerobot uses, the simulated world builds and
//! gives finite samples for a press into the surface, and it survives a write to TOML and a
//! re-parse unchanged (the unit normal up to rounding).
#![no_main]

use libfuzzer_sys::fuzz_target;
use node::OperatorSettings;
use node::telerobot::TelerobotNode;
use protocol::PROTOCOL_VERSION;
use protocol::handshake::check_welcome;
use protocol::telerobot_to_operator::Welcome;
use sim::scene::Scene;
use sim::world::World;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(scene) = Scene::from_toml(text, "fuzz.toml") else {
        return;
    };

    let settings = scene.telerobot_settings();
    if let Err(e) = settings.limits.validate() {
        panic!("accepted scene, refused limits: {e}");
    }
    let view = settings.operator_view();
    let point = scene.surface.point_m;
    if let Err(e) = TelerobotNode::new(settings, point) {
        panic!("accepted scene, refused node: {e}");
    }
    let summary = scene.summary();
    let welcome = Welcome {
        version: PROTOCOL_VERSION,
        scene: summary.clone(),
    };
    assert_eq!(check_welcome(&welcome), Ok(()));
    match OperatorSettings::from_welcome(&summary) {
        Ok(remote) => assert_eq!(remote, view),
        Err(e) => panic!("accepted scene, refused welcome: {e}"),
    }

    world_steps(&scene);

    let written = match toml::to_string(&scene) {
        Ok(t) => t,
        Err(e) => panic!("accepted scene does not serialise: {e}"),
    };
    let mut again = match Scene::from_toml(&written, "again.toml") {
        Ok(s) => s,
        Err(e) => panic!("written scene refused: {e}\n{written}"),
    };
    let (n0, n1) = (scene.surface.normal, again.surface.normal);
    assert!(
        (0..3).all(|i| (n0[i] - n1[i]).abs() <= 4.0 * f64::EPSILON),
        "{n0:?} vs {n1:?}"
    );
    again.surface.normal = n0;
    assert_eq!(again, scene);
});

/// Builds the simulated world and presses 1 mm into the surface for a few ticks.
fn world_steps(scene: &Scene) {
    let n = scene.surface.normal;
    let p = scene.surface.point_m;
    let at = |d: f64| [p[0] + d * n[0], p[1] + d * n[1], p[2] + d * n[2]];
    let mut world = match World::new(scene, at(0.01), 7) {
        Ok(w) => w,
        Err(e) => panic!("accepted scene, refused world: {e}"),
    };
    for k in 0..20 {
        let d = 0.01 - 0.0006 * f64::from(k);
        let s = world.step(at(d), [-0.6 * n[0], -0.6 * n[1], -0.6 * n[2]]);
        assert!(
            s.truth.is_finite() && s.measured.is_finite(),
            "tick {k}: {s:?}"
        );
    }
}
