//! `--robot ros2` end to end: the telerobot daemon drives the test arm (the simulated exp-1
//! world on the ROS 2 graph, its own threads, real DDS on loopback) and takes its cloud from the
//! arm's camera over PointCloud2; the operator connects over QUIC and renders. The bridge must
//! estimate from the arm's states, publish the model and contact state, and the run must track
//! the measured force.

#![allow(clippy::unwrap_used)]

use demo::DemoConfig;
use ros2::arm::{ArmCamera, ArmConfig, TestArm};
use ros2::topics::RobotTopics;
use ros2::{BridgeConfig, Graph, GraphConfig, Qos};
use rt::Shutdown;
use sim::scene::{CloudKind, CloudPose, Scene};
use telerobot::robot::RobotConfig;

#[test]
fn the_daemon_drives_the_test_arm_over_ros2_and_the_operator_renders() {
    let pid = std::process::id();
    let ns = format!("/demo_t{pid}");
    let mut topics = RobotTopics::default();
    for (key, name) in [
        ("robot_pose", "robot/pose"),
        ("robot_twist", "robot/twist"),
        ("robot_wrench", "robot/wrench"),
        ("target_pose", "robot/target_pose"),
        ("target_twist", "robot/target_twist"),
        ("theta", "theta"),
        ("in_contact", "in_contact"),
        ("camera_points", "camera/points"),
    ] {
        topics.remap(&format!("{key}={ns}/{name}")).unwrap();
    }
    let graph = GraphConfig {
        domain_id: 150 + (pid % 80) as u16,
        localhost_only: true,
    };
    let camera = ArmCamera::overhead(topics.camera_points.clone());
    let mut scene = Scene::exp1();
    scene.cloud.source = CloudKind::Ros2;
    scene.cloud.topic = Some(topics.camera_points.to_string());
    scene.cloud.pose = CloudPose {
        translation_m: camera.pose.translation_m,
        quaternion_xyzw: camera.pose.quaternion_xyzw(),
    };
    let arm = TestArm::start(
        &Graph::join(&graph).unwrap(),
        ArmConfig {
            scene: Scene::exp1(),
            seed: 1,
            start_m: telerobot::RunConfig::default_start(&scene),
            rate_hz: 1000.0,
            topics: topics.clone(),
            qos: Qos::STREAM,
            frame_id: "base".into(),
            camera: Some(camera),
            spin_ns: 50_000,
        },
    )
    .unwrap();
    let outcome = demo::run::run(
        &DemoConfig {
            delay_ms: 0.0,
            seconds: 10.0,
            via_shim: false,
            scene,
            robot: RobotConfig::Ros2 {
                graph,
                bridge: Box::new(BridgeConfig {
                    topics,
                    ..BridgeConfig::default()
                }),
            },
            ..DemoConfig::default()
        },
        Shutdown::new(),
    )
    .unwrap();
    let arm = arm.stop();
    let t = &outcome.report.telerobot;
    let r = t.robot.as_ref().unwrap();
    let summary = format!("{r:#?}\n{:#?}\n{arm:?}", t.last.guard);
    // The arm's states reached the bridge and the node stepped on them. Best-effort keep-last-1
    // drops states when a loop stalls, so this counts what arrived against what the arm sent
    // rather than timing the machine (the rate is a benchmark figure: `ros2_figures`).
    let sent = arm.states as f64;
    assert!(r.io.state.samples as f64 > 0.3 * sent, "{summary}");
    assert!(t.last.fresh_samples as f64 > 0.3 * sent, "{summary}");
    assert!(r.effective_rate_hz > 0.0, "{summary}");
    assert_eq!(r.io.undecodable, 0, "{summary}");
    // The arm followed the commands; the model and contact state went out on their topics.
    assert!(arm.targets as f64 > 0.3 * sent, "{summary}");
    assert!(
        r.io.theta_published > 0 && r.io.contact_published > 0,
        "{summary}"
    );
    // Nothing was commanded before the first state. A stall of this machine over 50 ms (CI's
    // two cores run the arm, DDS, the daemon and the operator) makes the state stale: the bridge
    // holds the robot for it and goes on, so such holds are a small part of the run.
    assert!(t.last.guard.no_state_ticks > 0, "{summary}");
    assert!(t.last.guard.stale_state.ticks < 500, "{summary}");
    // The cloud came over PointCloud2 and was indexed.
    let c = t.ros2_camera.unwrap();
    assert!(c.frames > 100 && c.refused == 0, "{c:?}");
    assert!(t.camera_frames.0 > 100, "{:?}", t.camera_frames);
    // The operator rendered from the estimated model: a usable error after stable (the exp-1
    // target is 5 %; this loaded, 10 s run gets a margin: when this machine stalls the
    // telerobot's loop for over 10 ms the test arm runs out of targets and stops dead, and the
    // estimator takes the transient for a new object. 21.7 % was measured in one of three runs
    // at a 698 Hz state rate; a model that was not rendered, or a wrong one, is far above 30 %).
    let e = &outcome.report.run.experiment;
    let error = e
        .rms_error_pct_after_stable
        .unwrap_or_else(|| panic!("no whole model within 10 s\n{summary}"));
    eprintln!(
        "error after stable {error} %, rate {} Hz",
        r.effective_rate_hz
    );
    assert!(error < 30.0, "error after stable {error} %\n{summary}");
}
