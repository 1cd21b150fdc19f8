//! Regressions of `--device ros2`, each named after the bug it pins: a pose stamped ahead that
//! stopped every pose after it, an unchecked frame, staleness counted from the wrong time, and
//! a final report that missed the last commands.

use super::*;
use ros2::haptic::ExpectedFrame;
use ros2::msg::Time;

/// [`moving`], with two poses stamped ahead of the driver once `go` is seen: a non-finite one
/// half a second ahead, then a valid one an hour ahead.
fn moving_with_poses_ahead(go: &Arc<AtomicBool>) -> Script {
    let (mut script, go, mut sent) = (moving(), Arc::clone(go), 0);
    Box::new(move |k, now| {
        let mut step = script(k, now);
        if go.load(Relaxed) && sent < 2 {
            let pose = step.pose.as_mut().unwrap();
            let stamp = pose.header.stamp.to_nanos().unwrap();
            let (ahead, x) = [(500 * MS, f64::NAN), (3_600_000 * MS, 0.01)][sent];
            pose.header.stamp = Time::from_nanos(stamp + ahead);
            pose.pose.position.x = x;
            sent += 1;
        }
        step
    })
}

/// Regression: one pose stamped ahead of the driver, refused or not, made every later pose
/// "out of order": the poses stopped and the device faulted for the rest of the run.
#[test]
fn one_pose_stamped_ahead_does_not_stop_the_poses_after_it() {
    let (graph, topics) = isolated();
    let go = Arc::new(AtomicBool::new(false));
    let d = double(&graph, &topics, moving_with_poses_ahead(&go));
    let mut config = config(&topics, DEADLINE);
    // Reliable and deep: both poses ahead arrive.
    config.state_qos = Qos::parse("reliable,keep-last-100", Qos::STREAM).unwrap();
    let mut device = open(&graph, config);
    go.store(true, Relaxed);
    let start = Instant::now();
    let mut refused_at = None;
    // The poses keep coming after both were refused: 500 more accepted.
    drive(device.as_mut(), start, [0.0; 3], |dev| {
        let g = report(dev).io.gate;
        if refused_at.is_none() && g.non_finite + g.from_future == 2 {
            refused_at = Some(g.accepted);
        }
        refused_at.is_some_and(|at| g.accepted > at + 500)
    });
    let g = report(device.as_ref()).io.gate;
    drop(d);
    assert_eq!(
        (g.non_finite, g.from_future, g.out_of_order),
        (1, 1, 0),
        "{g:?}"
    );
    assert_eq!(device.operating_state(), OperatingState::Disabled);
}

/// Regression: the pose's `frame_id` was recorded, never checked. Poses re-published in the
/// launch file's `world` (a half turn about z from `fd_base`) would have turned x and y forces
/// round: they are refused and counted, the device never opens on them, and the error says
/// which frame arrived; `--ros-pose-frame any` takes them.
#[test]
fn a_pose_in_another_frame_is_refused_and_never_reaches_the_device() {
    let (graph, topics) = isolated();
    let mut script = moving();
    let d = double(
        &graph,
        &topics,
        Box::new(move |k, now| {
            let mut step = script(k, now);
            if let Some(p) = step.pose.as_mut() {
                p.header.frame_id = "world".into();
            }
            step
        }),
    );
    let io = RosHaptic::start(&Graph::join(&graph).unwrap(), config(&topics, DEADLINE)).unwrap();
    testkit::wait_for(DEADLINE, || {
        Some(io.report().io.gate).filter(|g| g.wrong_frame > 0)
    })
    .unwrap();
    let e = io.wait_for_pose(Duration::ZERO).unwrap_err().to_string();
    assert!(
        e.contains("(the first: \"world\"; --ros-pose-frame)"),
        "{e}"
    );
    assert_eq!(io.take_sample(), None);
    assert!(io.describe().contains("(frame fd_base)"));
    drop(io);
    let any = HapticConfig {
        pose_frame: ExpectedFrame::Any,
        ..config(&topics, DEADLINE)
    };
    let device = open(&graph, any);
    let frame = testkit::wait_for(DEADLINE, || {
        Some(report(device.as_ref()).io.frame_id).filter(|f| !f.is_empty())
    });
    assert_eq!(frame.as_deref(), Some("world"));
    drop(d);
}

/// Regression: staleness was counted from when the loop *took* a sample, so the first read
/// (`first_node`'s `update(0)`) accepted a waiting pose however old. It is counted from the
/// pose's receipt: a pose already old when the loop starts is stale at once.
#[test]
fn a_pose_already_old_when_the_loop_starts_is_stale_at_once() {
    let (graph, topics) = isolated();
    let (stop, stopped) = (
        Arc::new(AtomicBool::new(false)),
        Arc::new(AtomicBool::new(false)),
    );
    let last_stamp = Arc::new(std::sync::atomic::AtomicI64::new(0));
    let (mut script, seen, last) = (moving(), Arc::clone(&stopped), Arc::clone(&last_stamp));
    let halt = Arc::clone(&stop);
    let d = double(
        &graph,
        &topics,
        Box::new(move |k, now| {
            if halt.load(Relaxed) {
                // The double's ticks are sequential: every earlier pose is published by now.
                seen.store(true, Relaxed);
                return Step::default();
            }
            let step = script(k, now);
            let stamp = step.pose.as_ref().and_then(|p| p.header.stamp.to_nanos());
            last.store(stamp.unwrap(), Relaxed);
            step
        }),
    );
    let stale_after = Duration::from_millis(100);
    let mut config = config(&topics, stale_after);
    // Reliable: the double's last pose is received.
    config.state_qos = Qos::parse("reliable,keep-last-100", Qos::STREAM).unwrap();
    let mut device = open(&graph, config);
    stop.store(true, Relaxed);
    // The double's last pose has been received (and it publishes no more).
    testkit::wait_for(DEADLINE, || {
        let newest = report(device.as_ref())
            .io
            .stamp_span_ns
            .map(|(_, last)| last);
        (stopped.load(Relaxed) && newest == Some(last_stamp.load(Relaxed))).then_some(())
    })
    .unwrap();
    // Older than the limit by construction: no speed is assumed.
    std::thread::sleep(stale_after * 3);
    let e = device.update(Duration::ZERO).unwrap_err().to_string();
    assert!(
        e.contains(&format!("no valid pose on {} for", topics.pose)),
        "{e}"
    );
    assert_eq!(device.operating_state(), OperatingState::Faulted);
    drop(d);
}

/// A device config whose every command published reaches the double once the endpoints match
/// (reliable and deep), with no watchdog zero (the test's thread is the loop, and may be held
/// up).
fn every_command(topics: &HapticTopics) -> HapticConfig {
    let mut config = config(topics, DEADLINE);
    config.command_qos = Qos::parse("reliable,keep-last-1000", config.command_qos).unwrap();
    config.command_watchdog = DEADLINE;
    config
}

/// The commands in `r` whose x force is `fx`.
fn count(r: &[Received], fx: f64) -> u64 {
    r.iter().filter(|c| c.message.data[0] == fx).count() as u64
}

/// Regression: the run's report was built before the device was dropped, with counts shared
/// every 20 ms: the closing zero and the last forces were missing. Closing the device first,
/// the report counts every force the driver received.
#[test]
fn the_final_report_counts_every_command_the_closing_zero_included() {
    let (graph, topics) = isolated();
    let d = double(&graph, &topics, moving());
    let mut device = open(&graph, every_command(&topics));
    let start = Instant::now();
    // Zeros until the endpoints have matched (those before are lost: counted, not received);
    // then every force is received.
    drive(device.as_mut(), start, [1.0, 0.0, 0.0], |_| {
        !d.received().is_empty()
    });
    device.enable(start.elapsed()).unwrap();
    drive(device.as_mut(), start, [1.0, 0.0, 0.0], |_| {
        count(&d.received(), 1.0) > 100
    });
    device.close(start.elapsed()).unwrap();
    let c = report(device.as_ref()).io.commands;
    let forces = c.published - c.zero;
    let received = wait_received(&d, |r| {
        r.last().is_some_and(|c| c.message.data[0] == 0.0) && count(r, 1.0) >= forces
    });
    assert_eq!(count(&received, 1.0), forces, "{c:?}");
    drop(device);
    assert_eq!(d.stop().len(), received.len(), "nothing after the close");
}

/// The same at the device's own interface, where nothing is lost before the endpoints match:
/// every zero the driver received is in the report once the device is closed, the disabling
/// zero and the closing one included.
#[test]
fn a_closed_devices_report_counts_the_closing_zero() {
    let (graph, topics) = isolated();
    let d = double(&graph, &topics, moving());
    let config = every_command(&topics);
    let mut io = RosHaptic::start(&Graph::join(&graph).unwrap(), config).unwrap();
    io.wait_for_pose(DEADLINE).unwrap();
    io.set_forces(true);
    // Forces only until the endpoints have matched: no zero is published before.
    wait_received(&d, |r| {
        io.command([1.0, 0.0, 0.0]);
        std::thread::sleep(Duration::from_millis(1));
        !r.is_empty()
    });
    io.set_forces(false);
    io.close();
    let c = io.report().io.commands;
    let received = wait_received(&d, |r| count(r, 0.0) >= c.zero);
    assert!(c.zero >= 1, "{c:?}");
    assert_eq!(received.last().unwrap().message.data, [0.0; 3]);
    drop(io);
    assert_eq!(count(&d.stop(), 0.0), c.zero, "{c:?}");
}
