//! The ROS 2 robot bridge against the test arm, over real DDS on loopback (two participants in
//! this process, discovering each other through RustDDS's localhost announcements).

mod common;

use std::time::{Duration, Instant};

use node::{Reading, RobotBridge, Target};
use ros2::arm::{ArmConfig, TestArm};
use ros2::bridge::BridgeConfig;
use ros2::state::StateConfig;
use ros2::{Graph, Qos, Ros2Bridge};
use sim::scene::Scene;

fn arm_config(topics: &ros2::topics::RobotTopics) -> ArmConfig {
    ArmConfig {
        scene: Scene::exp1(),
        seed: 1,
        start_m: [0.0, 0.0, 0.01],
        rate_hz: 1000.0,
        topics: topics.clone(),
        qos: Qos::STREAM,
        frame_id: "base".into(),
        camera: None,
        spin_ns: 0,
    }
}

/// Steps the bridge at 1 kHz for `seconds`, commanding `path(t)` once it has a state; returns
/// every reading.
fn drive(
    bridge: &mut Ros2Bridge,
    seconds: f64,
    path: impl Fn(f64) -> [f64; 3],
) -> Vec<node::BridgeSample> {
    let start = Instant::now();
    let mut out = Vec::new();
    let mut k = 0i64;
    while start.elapsed().as_secs_f64() < seconds {
        let now = rt::monotonic_ns();
        let t = start.elapsed().as_secs_f64();
        let target = bridge.tool_m().map(|_| Target {
            position_m: path(t),
            velocity_m_per_s: [0.0; 3],
            command_sample_time_ns: k,
            holding: false,
        });
        let s = bridge.step(now, target.as_ref());
        if matches!(s.reading, Reading::Stamped { .. }) {
            out.push(s);
        }
        while let Some(s) = bridge.next_reading() {
            out.push(s);
        }
        k += 1;
        std::thread::sleep(Duration::from_micros(900));
    }
    out
}

#[test]
fn the_bridge_reads_the_arm_at_its_rate_and_the_arm_follows_the_targets() {
    let (graph, topics, _) = common::isolated();
    let arm_graph = Graph::join(graph.config()).unwrap();
    let arm = TestArm::start(&arm_graph, arm_config(&topics)).unwrap();
    let mut bridge = Ros2Bridge::start(
        &graph,
        BridgeConfig {
            topics: topics.clone(),
            ..BridgeConfig::default()
        },
    )
    .unwrap();
    let monitor = bridge.monitor();
    // Nothing is commanded before a state: `drive` gives no target until `tool_m` is known.
    let readings = drive(&mut bridge, 4.0, |t| {
        [0.02 * (t * 2.0).sin(), 0.0, 0.01 + 0.005 * (t * 3.0).sin()]
    });
    let arm = arm.stop();
    let report = monitor.report();
    assert!(
        readings.len() > 2000,
        "{} readings; {report:#?}; {arm:?}",
        readings.len()
    );
    assert!(arm.targets > 1000, "{arm:?}");
    // Every state once, in stamp order, each at its own time on the loop's clock.
    let times: Vec<i64> = readings
        .iter()
        .map(|s| match s.reading {
            Reading::Stamped { sample_time_ns, .. } => sample_time_ns,
            _ => unreachable!(),
        })
        .collect();
    assert!(times.windows(2).all(|w| w[1] > w[0]));
    // The rate is the states used per second of stamps: never above the arm's 1 kHz, and well
    // above zero even when this machine's scheduler drops some (the figure itself is measured
    // by `ros2_figures`, not timed here).
    assert!(
        report.effective_rate_hz > 300.0 && report.effective_rate_hz < 1100.0,
        "{report:#?}"
    );
    assert_eq!(report.io.state.out_of_order + report.io.state.duplicates, 0);
    assert!(report.latency.count > 2000 && report.latency.p50_us < 5_000.0);
    // The arm follows: the last measured position is within a few mm of the last target.
    let last = readings.last().unwrap();
    assert!(
        (last.measured.position_m[0] - 0.02 * (4.0f64 * 2.0).sin()).abs() < 0.005,
        "{last:?}"
    );
    // Commands are attributed: later states carry later command sample times.
    let commands: Vec<i64> = readings
        .iter()
        .map(|s| match s.reading {
            Reading::Stamped {
                command_sample_time_ns,
                ..
            } => command_sample_time_ns,
            _ => unreachable!(),
        })
        .collect();
    assert!(commands.windows(2).all(|w| w[1] >= w[0]));
    assert!(*commands.last().unwrap() > 1000);
}

#[test]
fn without_a_twist_topic_the_velocity_is_differentiated() {
    let (graph, mut topics, _) = common::isolated();
    topics.remap("robot_twist=none").unwrap();
    let arm_graph = Graph::join(graph.config()).unwrap();
    let arm = TestArm::start(&arm_graph, arm_config(&topics)).unwrap();
    let mut bridge = Ros2Bridge::start(
        &graph,
        BridgeConfig {
            topics: topics.clone(),
            state: StateConfig {
                twist: false,
                ..StateConfig::default()
            },
            ..BridgeConfig::default()
        },
    )
    .unwrap();
    let readings = drive(&mut bridge, 3.0, |t| [0.05 * t, 0.0, 0.02]);
    arm.stop();
    let report = bridge.monitor().report();
    assert_eq!(report.velocity_from, "the pose, differentiated");
    assert!(readings.len() > 1000, "{report:#?}");
    // Each velocity is the pose's backward difference over its own stamps, so over the tail the
    // velocities weighted by their intervals add up to the distance travelled (exact but for the
    // stamp clock's offset, which moves only at its 1 s buckets), and the arm moved at about the
    // commanded 5 cm/s (faster while it catches up after this loop was held up).
    let tail = &readings[readings.len() - 500..];
    let time = |s: &node::BridgeSample| match s.reading {
        Reading::Stamped { sample_time_ns, .. } => sample_time_ns as f64 * 1e-9,
        _ => unreachable!(),
    };
    let (mut travelled, mut integrated) = (0.0, 0.0);
    for w in tail.windows(2) {
        travelled += w[1].measured.position_m[0] - w[0].measured.position_m[0];
        integrated += w[1].measured.velocity_m_per_s[0] * (time(&w[1]) - time(&w[0]));
    }
    let span = time(&tail[tail.len() - 1]) - time(&tail[0]);
    assert!(
        (integrated - travelled).abs() < 0.02 * travelled.abs(),
        "∫v dt {integrated} m against {travelled} m travelled"
    );
    let mean = travelled / span;
    assert!((0.03..0.09).contains(&mean), "mean velocity {mean}");
}
