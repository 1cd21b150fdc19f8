//! The ROS 2 bridge's figures (issue 14), end to end: the telerobot daemon with `--robot ros2`
//! against the test arm (the simulated exp-1 world on the ROS 2 graph, its own threads, real DDS
//! on loopback), and the operator with the scripted exp-1 device, against the same run with the
//! simulated bridge:
//!
//! - error after stable and time to stable, both bridges (the ROS 2 one within 1 point);
//! - the longest gap in the 1 kHz state stream (stamps, and receipts by the telerobot);
//! - DDS one-way latency, state sample → telerobot (p50, p99; one host, one clock);
//! - the bridge's counters (stamped ahead, out of order, duplicates, refusals, unpaired) and the
//!   command guard's.
//!
//! ```sh
//! cargo run --release -p demo --example ros2_figures [-- SECONDS [SEED [plane]]]
//! ```
//! Each run takes SECONDS (default 60) of wall time plus a few seconds of start-up. The ROS 2
//! run's cloud comes from the arm's camera over PointCloud2 (`[cloud] source = "ros2"`);
//! `plane` keeps the telerobot's simulated camera instead. With `ROS2_FIGURES_RECORD=FILE.mcap`
//! in the environment the ROS 2 run is recorded (its resets are on `/telerobot/tick`).

#![allow(clippy::unwrap_used)]

use demo::DemoConfig;
use demo::run::run as run_demo;
use ros2::arm::{ArmCamera, ArmConfig, TestArm};
use ros2::topics::RobotTopics;
use ros2::{BridgeConfig, Graph, GraphConfig, Qos};
use rt::Shutdown;
use sim::scene::{CloudKind, CloudPose, Scene};
use telerobot::robot::RobotConfig;

fn main() {
    let mut args = std::env::args().skip(1);
    let seconds: f64 = args
        .next()
        .map_or(60.0, |s| s.parse().expect("SECONDS must be a number"));
    let seed: u64 = args
        .next()
        .map_or(1, |s| s.parse().expect("SEED must be an integer"));
    // `plane`: the telerobot keeps its simulated camera (the arm's clouds unused), to tell the
    // bridge's share of a difference from the camera path's.
    let ros2_camera = args.next().as_deref() != Some("plane");
    let base = DemoConfig {
        delay_ms: 0.0,
        seconds,
        via_shim: false,
        seed,
        ..DemoConfig::default()
    };

    println!("exp 1, {seconds} s, seed {seed}, no delay, the operator connected directly");
    let sim = run_demo(&base, Shutdown::new()).unwrap();

    // The ROS 2 run: a namespace of its own on the domain the environment gives (or 0).
    let ns = format!("/mmt_fig{}", std::process::id());
    let mut topics = RobotTopics::default();
    for (key, name) in [
        ("robot_pose", "robot/pose"),
        ("robot_twist", "robot/twist"),
        ("robot_wrench", "robot/wrench"),
        ("target_pose", "robot/target_pose"),
        ("theta", "theta"),
        ("in_contact", "in_contact"),
        ("camera_points", "camera/points"),
    ] {
        topics.remap(&format!("{key}={ns}/{name}")).unwrap();
    }
    let mut graph = GraphConfig::from_env(None).unwrap();
    graph.localhost_only = true;
    // The telerobot's cloud comes from the arm's camera over PointCloud2, posed by the scene.
    let camera = ArmCamera::overhead(topics.camera_points.clone());
    let mut ros_scene = Scene::exp1();
    if ros2_camera {
        ros_scene.cloud.source = CloudKind::Ros2;
    }
    ros_scene.cloud.topic = Some(topics.camera_points.to_string());
    ros_scene.cloud.pose = CloudPose {
        translation_m: camera.pose.translation_m,
        quaternion_xyzw: camera.pose.quaternion_xyzw(),
    };
    let scene = Scene::exp1();
    let arm = TestArm::start(
        &Graph::join(&graph).unwrap(),
        ArmConfig {
            scene: scene.clone(),
            seed,
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
    let recorder = std::env::var_os("ROS2_FIGURES_RECORD").and_then(|path| {
        record::cli::RecordArgs {
            record: Some(path.into()),
            live: None,
        }
        .start(record::Kind::Demo, rt::monotonic_ns())
        .unwrap()
    });
    let ros = run_demo(
        &DemoConfig {
            record: recorder.as_ref().map(record::Recorder::sink),
            robot: RobotConfig::Ros2 {
                graph: graph.clone(),
                bridge: Box::new(BridgeConfig {
                    topics,
                    ..BridgeConfig::default()
                }),
            },
            scene: ros_scene,
            ..base.clone()
        },
        Shutdown::new(),
    )
    .unwrap();
    let arm = arm.stop();
    if let Some(r) = recorder {
        r.finish().unwrap();
    }

    let row = |name: &str, o: &demo::Outcome| {
        let e = &o.report.run.experiment;
        let t = &o.report.telerobot;
        println!(
            "{name:<10} {:>20} {:>16} {:>18} {:>14}",
            e.rms_error_pct_after_stable
                .map_or("—".into(), |v| format!("{v:.2} %")),
            e.time_to_stable_s
                .map_or("never".into(), |v| format!("{v:.2} s")),
            format!("{}", t.last.fresh_samples),
            format!(
                "{:.0}/{:.0}",
                t.timing.period.p99_us, t.timing.period.max_us
            ),
        );
    };
    println!(
        "\n{:<10} {:>20} {:>16} {:>18} {:>14}",
        "bridge", "error after stable", "time to stable", "samples estimated", "loop p99/max µs"
    );
    row("sim", &sim);
    row("ros2", &ros);
    let (a, b) = (
        sim.report.run.experiment.rms_error_pct_after_stable,
        ros.report.run.experiment.rms_error_pct_after_stable,
    );
    if let (Some(a), Some(b)) = (a, b) {
        println!("difference: {:+.2} points", b - a);
    }
    let t = &ros.report.telerobot;
    let r = t.robot.as_ref().unwrap();
    println!(
        "\nstate stream: {:.1} Hz effective; longest gap {:.2} ms between stamps, {:.2} ms between \
         receipts",
        r.effective_rate_hz, r.io.longest_stamp_gap_ms, r.io.longest_receipt_gap_ms
    );
    println!(
        "DDS one-way latency, state sample → telerobot: p50 {:.0} µs, p99 {:.0} µs, max {:.0} µs \
         ({} samples)",
        r.latency.p50_us, r.latency.p99_us, r.latency.max_us, r.latency.count
    );
    let s = &r.io.state;
    println!(
        "bridge: {} states from {} poses / {} twists / {} wrenches; stamped ahead of the clock \
         {}, out of order {}, duplicates {}, non-finite {}, impossible jumps {}, unpaired {}, \
         paired with another stamp {}, undecodable {}, dropped {}",
        s.samples,
        s.poses,
        s.twists,
        s.wrenches,
        s.from_future,
        s.out_of_order,
        s.duplicates,
        s.non_finite,
        s.impossible_jumps,
        s.unpaired,
        s.inexact,
        r.io.undecodable,
        r.superseded
    );
    println!(
        "published: {} targets, {} theta, {} in_contact",
        r.io.targets_published, r.io.theta_published, r.io.contact_published
    );
    if let Some(c) = &t.ros2_camera {
        println!(
            "camera (PointCloud2): {} messages, {} frames, {} superseded, {} refused, {} \
             undecodable, {} stale, oldest {:.1} ms; telerobot indexed {} / rejected {}",
            c.messages,
            c.frames,
            c.superseded,
            c.refused,
            c.undecodable,
            c.stale,
            c.max_age_ms,
            t.camera_frames.0,
            t.camera_frames.1
        );
    }
    let (normal, tangential) = t.last.estimators;
    for (name, stats) in [("normal", normal), ("tangential", tangential)] {
        let Some(e) = stats else { continue };
        println!(
            "estimator ({name}): {} new-object resets; gaps: {} samples filled, {} restarted; {} \
             samples contradicting the motion (learning settled), {} gaps hiding a change of \
             speed (detector muted)",
            e.new_objects, e.filled_samples, e.gap_restarts, e.motion_settles, e.gap_mutes
        );
    }
    let g = &t.last.guard;
    println!(
        "motion guard: {} ticks without a state; stale {} / workspace {} / step {} / speed {} \
         ticks; {} faults",
        g.no_state_ticks,
        g.stale_state.ticks,
        g.workspace.ticks,
        g.step.ticks,
        g.speed.ticks,
        g.faults
    );
    println!(
        "test arm: {} ticks, {} targets, {} states, {} camera frames; {} breaks in its path, {} \
         ticks returning to it; loop p99 {:.0} µs, max {:.0} µs",
        arm.ticks,
        arm.targets,
        arm.states,
        arm.frames,
        arm.path_breaks.0,
        arm.path_breaks.1,
        arm.timing.period.p99_us,
        arm.timing.period.max_us
    );
}
