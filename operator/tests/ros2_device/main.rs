//! `--device ros2` against a Rust stand-in for forcedimension_ros2 (`ros2::fd_double`), over
//! real DDS on loopback: two participants in this process, each test on its own topic names.
//! The double publishes poses at 1 kHz and records every force command that reaches its
//! `fd_controller/commands` subscription, with the driver's QoS.
//!
//! No test asserts a speed: waits are generous deadlines on what must happen.

#![allow(clippy::unwrap_used)]

mod regressions;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering::Relaxed};
use std::time::{Duration, Instant};

use operator::device::ros::RosOptions;
use operator::device::{
    BackendReport, DeviceSpec, HapticDevice, ManagedConfig, OpenOptions, OperatingState,
    open_device,
};
use ros2::fd_double::{FdDouble, Received, Script, Step, fd_pose};
use ros2::haptic::{CommandLen, HapticConfig, HapticReport, HapticTopics, RosHaptic};
use ros2::{Graph, GraphConfig, Qos};

const MS: i64 = 1_000_000;
/// Every wait's deadline: far beyond what a loaded machine needs.
const DEADLINE: Duration = Duration::from_secs(30);

static NEXT: AtomicU32 = AtomicU32::new(0);

/// A domain for this process (20–89: the ros2 crate's tests use 100–199, the demo's 150–229)
/// and topic names of this test's own (`/t<pid>_<n>/fd/…`), so that tests running at once
/// never hear each other.
fn isolated() -> (GraphConfig, HapticTopics) {
    let n = NEXT.fetch_add(1, Relaxed);
    let pid = std::process::id();
    let mut topics = HapticTopics::default();
    for (key, name) in [
        ("pose", "fd/ee_pose"),
        ("button", "fd/button_state"),
        ("command", "fd/fd_controller/commands"),
    ] {
        topics.remap(&format!("{key}=/t{pid}_{n}/{name}")).unwrap();
    }
    let graph = GraphConfig {
        domain_id: 20 + (pid % 70) as u16,
        localhost_only: true,
    };
    (graph, topics)
}

/// A device config over `topics`; `stale_after` long unless a test is about it (a loaded
/// machine may hold a thread up for tens of milliseconds).
fn config(topics: &HapticTopics, stale_after: Duration) -> HapticConfig {
    HapticConfig {
        topics: topics.clone(),
        stale_after,
        ..HapticConfig::default()
    }
}

fn double(graph: &GraphConfig, topics: &HapticTopics, script: Script) -> FdDouble {
    FdDouble::start(&Graph::join(graph).unwrap(), topics, 1000.0, script).unwrap()
}

/// Opens `--device ros2` with no enable ramp and a lenient servo watchdog (the test's thread
/// is the loop).
fn open(graph: &GraphConfig, device: HapticConfig) -> Box<dyn HapticDevice> {
    let options = OpenOptions {
        managed: ManagedConfig {
            enable_ramp: Duration::ZERO,
            servo_watchdog: Duration::from_secs(10),
        },
        ros: RosOptions {
            graph: Some(graph.clone()),
            device,
            first_pose_timeout: DEADLINE,
        },
        ..OpenOptions::default()
    };
    open_device(&DeviceSpec::Ros2, &options).unwrap()
}

/// A script that moves along x at 5 cm/s, from 1 cm to 11 cm and back every 4 s, stamped 1 ms
/// apart from its first tick, the button pressed every other half second.
fn moving() -> Script {
    let mut t0 = None;
    Box::new(move |k, now| {
        let t0 = *t0.get_or_insert(now - k as i64 * MS);
        let up = (k % 4000) as f64;
        let x = 0.01 + 0.05e-3 * if up <= 2000.0 { up } else { 4000.0 - up };
        Step {
            pose: Some(fd_pose(t0 + k as i64 * MS, [x, 0.0, 0.0])),
            button: Some((k / 500) % 2 == 1),
        }
    })
}

/// [`moving`] until `stop` is set, then nothing at all (the driver died).
fn moving_until(stop: &Arc<AtomicBool>) -> Script {
    let (mut script, stop) = (moving(), Arc::clone(stop));
    Box::new(move |k, now| {
        if stop.load(Relaxed) {
            Step::default()
        } else {
            script(k, now)
        }
    })
}

/// The device's report.
fn report(device: &dyn HapticDevice) -> HapticReport {
    match device.backend_report() {
        Some(BackendReport::Ros2(r)) => *r,
        None => panic!("no ROS 2 report"),
    }
}

/// Runs the device as the haptic loop would, about once a millisecond, commanding `force`,
/// until `done` says so (or the deadline: a failure).
fn drive(
    device: &mut dyn HapticDevice,
    start: Instant,
    force: [f64; 3],
    mut done: impl FnMut(&dyn HapticDevice) -> bool,
) {
    while !done(device) {
        assert!(start.elapsed() < DEADLINE, "not done within {DEADLINE:?}");
        let now = start.elapsed();
        let _ = device.update(now);
        let _ = device.servo_cf(now, force);
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Waits until the double has received a command that satisfies `f`.
fn wait_received(d: &FdDouble, f: impl Fn(&[Received]) -> bool) -> Vec<Received> {
    testkit::wait_for(DEADLINE, || Some(d.received()).filter(|r| f(r)))
        .unwrap_or_else(|| panic!("the double never received what was expected"))
}

#[test]
fn the_device_reads_the_pose_and_writes_the_force_in_fd_controllers_layout() {
    let (graph, topics) = isolated();
    let d = double(&graph, &topics, moving());
    let mut device = open(&graph, config(&topics, DEADLINE));
    assert!(device.spec().outputs_force);
    assert!(device.spec().name.contains("/fd/fd_controller/commands"));
    let start = Instant::now();
    // Disabled: zero is written.
    drive(device.as_mut(), start, [1.5, -2.0, 0.25], |_| {
        d.received().len() > 20
    });
    device.enable(start.elapsed()).unwrap();
    let (mut clutched, mut readings) = (false, Vec::new());
    drive(device.as_mut(), start, [1.5, -2.0, 0.25], |dev| {
        clutched |= dev.clutch();
        readings.push((dev.measured_cp(), dev.measured_cv()));
        readings.len() > 500 && clutched && !dev.clutch()
    });
    let received = wait_received(&d, |r| r.last().is_some_and(|c| c.message.data[0] != 0.0));
    device.disable(start.elapsed()).unwrap();
    let r = report(device.as_ref());
    drop(device);
    let after = d.stop();

    // The pose: positions on the double's line, the velocity its 5 cm/s (differentiated over
    // 10 ms of exact 1 ms stamps).
    assert!(
        readings
            .iter()
            .all(|(p, _)| p[0] >= 0.01 && p[0] < 0.12 && p[1] == 0.0)
    );
    // (All but the ticks within 10 ms of a turn, and the first few.)
    let on_line = readings[20..]
        .iter()
        .filter(|(_, v)| (v[0].abs() - 0.05).abs() < 1e-6)
        .count();
    assert!(
        on_line * 10 > (readings.len() - 20) * 9,
        "{on_line} of {}",
        readings.len()
    );
    assert_eq!(r.velocity_from, "the pose, differentiated over 10 ms");
    assert_eq!(r.io.frame_id, "fd_base");
    assert!(r.io.buttons > 0);
    // The command: exactly what fd_controller takes, zero while disabled, the force once
    // enabled, zero again when disabled and when the device closes.
    for c in &received {
        assert!(c.message.layout.dim.is_empty() && c.message.layout.data_offset == 0);
        let data = c.message.data.as_slice();
        assert!(data == [0.0; 3] || data == [1.5, -2.0, 0.25], "{data:?}");
    }
    assert_eq!(received[0].message.data, [0.0; 3]);
    assert_eq!(after.last().unwrap().message.data, [0.0; 3]);
    let g = r.io.gate;
    assert_eq!(g.accepted, g.poses, "{r:#?}");
    assert_eq!(r.io.commands.before_pose + r.io.commands.stale_zeroed, 0);
}

#[test]
fn opening_with_no_driver_names_the_topic_and_the_domain() {
    let (graph, topics) = isolated();
    let options = OpenOptions {
        ros: RosOptions {
            graph: Some(graph.clone()),
            device: config(&topics, DEADLINE),
            first_pose_timeout: Duration::from_millis(300),
        },
        ..OpenOptions::default()
    };
    let e = open_device(&DeviceSpec::Ros2, &options)
        .err()
        .unwrap()
        .to_string();
    assert!(
        e.contains(&format!("no valid pose on {}", topics.pose))
            && e.contains(&format!("ROS domain {}", graph.domain_id))
            && e.contains("no message arrived")
            && e.contains("--topic pose=/name"),
        "{e}"
    );
}

#[test]
fn no_force_is_published_before_a_pose_has_arrived() {
    let (graph, topics) = isolated();
    let go = Arc::new(AtomicBool::new(false));
    let mut script = moving();
    let started = Arc::clone(&go);
    let d = double(
        &graph,
        &topics,
        Box::new(move |k, now| {
            if started.load(Relaxed) {
                script(k, now)
            } else {
                Step::default()
            }
        }),
    );
    let io = RosHaptic::start(&Graph::join(&graph).unwrap(), config(&topics, DEADLINE)).unwrap();
    io.set_forces(true);
    // The loop commands a force for a second with no pose on the graph: nothing goes out.
    for _ in 0..1000 {
        io.command([1.0, 0.0, 0.0]);
        std::thread::sleep(Duration::from_millis(1));
    }
    let before = testkit::wait_for(DEADLINE, || {
        Some(io.report().io.commands).filter(|c| c.before_pose > 0)
    })
    .unwrap();
    assert_eq!(before.published, 0, "{before:?}");
    go.store(true, Relaxed);
    let received = testkit::wait_for(DEADLINE, || {
        io.command([1.0, 0.0, 0.0]);
        Some(d.received()).filter(|r| !r.is_empty())
    })
    .unwrap();
    // Every command the double took came after its first pose.
    let first_pose = d.first_pose_tick().unwrap();
    assert!(received.iter().all(|c| c.tick > first_pose), "{first_pose}");
    assert_eq!(received[0].message.data, [1.0, 0.0, 0.0]);
}

#[test]
fn a_stale_pose_or_a_silent_loop_zeroes_the_force_on_the_io_thread() {
    let (graph, topics) = isolated();
    let stop = Arc::new(AtomicBool::new(false));
    let d = double(&graph, &topics, moving_until(&stop));
    let mut device = config(&topics, Duration::from_millis(50));
    device.command_len = CommandLen::new(7).unwrap();
    let io = RosHaptic::start(&Graph::join(&graph).unwrap(), device).unwrap();
    io.wait_for_pose(DEADLINE).unwrap();
    io.set_forces(true);
    let command = || {
        io.command([2.0, 0.0, 0.0]);
        std::thread::sleep(Duration::from_millis(1));
    };
    wait_received(&d, |r| {
        command();
        r.iter().any(|c| c.message.data[0] == 2.0)
    });
    // The driver stops; the loop keeps commanding 2 N: the I/O thread sends zero.
    stop.store(true, Relaxed);
    let received = wait_received(&d, |r| {
        command();
        r.last().is_some_and(|c| c.message.data[0] == 0.0)
    });
    for c in &received {
        let data = c.message.data.as_slice();
        assert!(
            data == [2.0, 0., 0., 0., 0., 0., 0.] || data == [0.0; 7],
            "{data:?}"
        );
    }
    let c = testkit::wait_for(DEADLINE, || {
        Some(io.report().io.commands).filter(|c| c.stale_zeroed > 0)
    })
    .unwrap();
    // One episode, or more if the machine held the double up for 50 ms before it stopped.
    assert!(c.stale_episodes >= 1, "{c:?}");
    drop(io);

    // A loop that stops commanding after a force: the watchdog sends zero.
    let (graph, topics) = isolated();
    let d = double(&graph, &topics, moving());
    let io = RosHaptic::start(&Graph::join(&graph).unwrap(), config(&topics, DEADLINE)).unwrap();
    io.wait_for_pose(DEADLINE).unwrap();
    io.set_forces(true);
    wait_received(&d, |r| {
        io.command([1.0, 0.0, 0.0]);
        std::thread::sleep(Duration::from_millis(1));
        r.iter().any(|c| c.message.data[0] == 1.0)
    });
    wait_received(&d, |r| r.last().is_some_and(|c| c.message.data[0] == 0.0));
    let c = testkit::wait_for(DEADLINE, || {
        Some(io.report().io.commands).filter(|c| c.watchdog_zeroed > 0)
    })
    .unwrap();
    assert_eq!(c.stale_zeroed, 0, "{c:?}");
}

#[test]
fn a_stale_pose_faults_the_device_and_says_so() {
    let (graph, topics) = isolated();
    let stop = Arc::new(AtomicBool::new(false));
    let d = double(&graph, &topics, moving_until(&stop));
    let mut device = open(&graph, config(&topics, Duration::from_millis(50)));
    let start = Instant::now();
    device.enable(start.elapsed()).unwrap();
    // (A machine that holds the double up for 50 ms faults the device early: as good.)
    drive(device.as_mut(), start, [1.0, 0.0, 0.0], |dev| {
        dev.operating_state() == OperatingState::Faulted
            || d.received().iter().any(|c| c.message.data[0] == 1.0)
    });
    stop.store(true, Relaxed);
    drive(device.as_mut(), start, [1.0, 0.0, 0.0], |dev| {
        dev.operating_state() == OperatingState::Faulted
    });
    let cause = device.fault().unwrap().cause.to_string();
    assert!(
        cause.contains(&format!("no valid pose on {} for", topics.pose))
            && cause.contains("forces off"),
        "{cause}"
    );
    // Faulted: zero from here on, whatever the loop asks.
    let n = d.received().len();
    drive(device.as_mut(), start, [1.0, 0.0, 0.0], |_| {
        d.received().len() > n + 100
    });
    let received = d.received();
    assert_eq!(received.last().unwrap().message.data, [0.0; 3]);
    assert_eq!(device.fault_count(), 1);
}

/// The double's garbage, one of each kind, among good poses 1 ms apart: from the tick `go` is
/// seen, one every 100 ticks; `done` is set 1000 ticks after `go`.
fn garbage(go: &Arc<AtomicBool>, done: &Arc<AtomicBool>) -> Script {
    let (go, done) = (Arc::clone(go), Arc::clone(done));
    let (mut t0, mut k_go) = (None, None);
    Box::new(move |k, now| {
        let t0 = *t0.get_or_insert(now - k as i64 * MS);
        let k = k as i64;
        if go.load(Relaxed) && k_go.is_none() {
            k_go = Some(k);
        }
        let rel = k_go.map_or(-1, |g| k - g);
        done.store(rel >= 1000, Relaxed);
        let x = 0.01 + 0.05e-6 * (k % 1000) as f64;
        let pose = match rel {
            200 => fd_pose(t0 + k * MS, [f64::NAN, 0.0, 0.0]),
            300 => fd_pose(t0 + k * MS, [x + 0.2, 0.0, 0.0]),
            400 => fd_pose(t0 + (k - 5) * MS, [x, 0.0, 0.0]),
            500 => fd_pose(t0 + (k - 1) * MS, [x, 0.0, 0.0]),
            600 => {
                let mut p = fd_pose(t0 + k * MS, [x, 0.0, 0.0]);
                p.header.stamp.nanosec = 1_500_000_000;
                p
            }
            700 => fd_pose(t0 + k * MS, [x, 2.0, 0.0]),
            _ => fd_pose(t0 + k * MS, [x, 0.0, 0.0]),
        };
        Step {
            pose: Some(pose),
            button: None,
        }
    })
}

#[test]
fn garbage_poses_are_refused_counted_and_never_reach_the_device() {
    let (graph, topics) = isolated();
    let (go, done) = (
        Arc::new(AtomicBool::new(false)),
        Arc::new(AtomicBool::new(false)),
    );
    let d = double(&graph, &topics, garbage(&go, &done));
    let mut config = config(&topics, DEADLINE);
    // Reliable and deep: every pose arrives, so each refusal is counted exactly once.
    config.state_qos = Qos::parse("reliable,keep-last-100", Qos::STREAM).unwrap();
    let mut device = open(&graph, config);
    go.store(true, Relaxed);
    let start = Instant::now();
    let mut positions = Vec::new();
    drive(device.as_mut(), start, [0.0; 3], |dev| {
        positions.push(dev.measured_cp());
        let g = report(dev).io.gate;
        done.load(Relaxed) && g.out_of_range > 0 && g.poses > g.accepted + 5
    });
    let r = report(device.as_ref());
    drop(d);
    let g = r.io.gate;
    assert_eq!(
        (
            g.non_finite,
            g.impossible_jumps,
            g.out_of_order,
            g.duplicates
        ),
        (1, 1, 1, 1),
        "{r:#?}"
    );
    assert_eq!((g.malformed_stamps, g.out_of_range), (1, 1), "{r:#?}");
    assert_eq!(g.accepted, g.poses - 6, "{r:#?}");
    // The device saw only the good line: finite, on x, never the jump.
    for p in &positions {
        assert!(
            p.iter().all(|v| v.is_finite()) && p[1] == 0.0 && p[0] < 0.011,
            "{p:?}"
        );
    }
    assert_eq!(device.operating_state(), OperatingState::Disabled);
}

/// A bad value is one line on stderr naming it, and a failure exit: no backtrace.
#[test]
fn a_bad_ros2_flag_is_one_line_on_stderr_and_a_failure_exit() {
    for (extra, says) in [
        (
            ["--topic", "command=fd_controller/commands"],
            "topic command = \"fd_controller/commands\" is not a valid ROS 2 name",
        ),
        (
            ["--ros-command-len", "9"],
            "--ros-command-len 9: expected 3 to 7",
        ),
        (["--qos", "command=keep-last-0"], "QoS \"keep-last-0\""),
        (
            ["--ros-pose-frame", ""],
            "--ros-pose-frame \"\": expected the poses' frame_id",
        ),
    ] {
        let output = std::process::Command::new(env!("CARGO_BIN_EXE_operator"))
            .args(["run", "--device", "ros2"])
            .args(extra)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.starts_with("operator: ") && stderr.contains(says),
            "{stderr}"
        );
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
    }
}
