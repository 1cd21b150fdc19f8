//! A scene whose cloud comes from a file: the exp-1 object's top face, written as a PCD file and
//! named by a scene TOML, drives the telerobot's contact detector and is streamed to the operator
//! exactly as the simulated camera's plane is, and contact holds on it.

#![allow(clippy::unwrap_used)]

use demo::DemoConfig;
use rt::Shutdown;
use sim::scene::{CloudKind, Scene};

#[test]
fn exp1_with_its_surface_from_a_pcd_file_estimates_as_with_the_camera() {
    let dir = std::env::temp_dir().join(format!("mmt-demo-cloud-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("clouds")).unwrap();
    // The top face z = 0, 40 cm square at 4 mm (under the proxy's spacing bound), with 0.5 mm of
    // deterministic ripple as a camera's noise would put.
    let n = 101;
    let points: Vec<[f32; 3]> = (0..n * n)
        .map(|i| {
            let (u, v) = ((i % n) as f32, (i / n) as f32);
            let ripple = 0.0005 * ((u * 0.7).sin() * (v * 1.3).cos());
            [u * 0.004 - 0.2, v * 0.004 - 0.2, ripple]
        })
        .collect();
    std::fs::write(
        dir.join("clouds/top.pcd"),
        cloud_io::encode_pcd(&points, cloud_io::PcdEncoding::Binary),
    )
    .unwrap();
    let exp1 = include_str!("../../scenes/exp1.toml");
    let start = exp1.find("[cloud]").unwrap();
    let end = start + exp1[start..].find("\n[").unwrap() + 1;
    let text = format!(
        "{}[cloud]\nsource = \"file\"\npath = \"clouds/top.pcd\"\nrate_hz = 30.0\nmoving = true\n{}",
        &exp1[..start],
        &exp1[end..]
    );
    let scene_file = dir.join("scene.toml");
    std::fs::write(&scene_file, &text).unwrap();

    // As `telerobot run --scene` reads it: parsed, the path resolved next to the scene file.
    let mut scene = Scene::from_toml(&text, "scene.toml").unwrap();
    assert_eq!(scene.cloud.source, CloudKind::File);
    let rel = scene.cloud.path.take().unwrap();
    scene.cloud.path = Some(
        telerobot::camera::file::resolve(&rel, Some(&scene_file))
            .display()
            .to_string(),
    );

    let outcome = demo::run::run(
        &DemoConfig {
            delay_ms: 0.0,
            seconds: 10.0,
            via_shim: false,
            scene,
            ..DemoConfig::default()
        },
        Shutdown::new(),
    )
    .unwrap();
    let (frames, rejected) = outcome.report.telerobot.camera_frames;
    // 30 Hz for ~10 s, every frame accepted.
    assert!(frames > 200 && rejected == 0, "{frames} {rejected}");
    let e = &outcome.report.run.experiment;
    // Contact held on the file's surface and the model rendered: a cloud the proxy fell through,
    // or none, gives ~100 %. (The simulated camera's 10 s runs give 3–7 % on this loaded machine,
    // single runs of either source up to 12 %: accuracy is compared in the figures, not here.)
    let error = e.rms_error_pct_after_stable;
    assert!(error.is_some_and(|v| v < 25.0), "{e:?}");
    // The operator rendered the file's cloud: contact onsets on both sides.
    assert!(e.operator_stats.clouds > 200 && e.operator_stats.rejected_clouds == 0);
    assert!(e.telerobot_stats.contact_onsets > 0 && e.operator_stats.contact_onsets > 0);
    std::fs::remove_dir_all(&dir).unwrap();
}
