use byteorder::LittleEndian;
use cdr_encoding::to_vec;

use super::*;
use crate::fd_double::fd_pose;
use crate::msg::{Header, Time, Twist, TwistStamped, Vector3};

const MS: i64 = 1_000_000;
/// The receiver's ROS clock in the tests that are not about it: 2033, after every stamp here.
const LATER: i64 = 2_000_000_000 * 1_000 * MS;

/// A receipt at `monotonic_ns`, the ROS clock at [`LATER`].
fn rx(monotonic_ns: i64) -> Receipt {
    Receipt {
        monotonic_ns,
        ros_ns: LATER,
    }
}

/// A stamp of 2023 \[ns\].
const T0: i64 = 1_700_000_000 * 1_000 * MS;

/// A receipt at `k` ms after [`T0`] on the ROS clock (`k` ns on the monotonic one).
fn clock(k: i64) -> Receipt {
    Receipt {
        monotonic_ns: k,
        ros_ns: T0 + k * MS,
    }
}

fn gate(twist: bool) -> PoseGate {
    PoseGate::new(GateConfig::default(), ExpectedFrame::default(), twist)
}

#[test]
fn the_defaults_are_forcedimension_ros2s_and_remap_one_by_one() {
    let t = HapticTopics::default();
    assert_eq!(t.pose.as_str(), "/fd/ee_pose");
    assert_eq!(t.button.as_ref().unwrap().as_str(), "/fd/button_state");
    assert_eq!(
        t.command.as_ref().unwrap().as_str(),
        "/fd/fd_controller/commands"
    );
    assert!(t.twist.is_none());
    let mut t = HapticTopics::default();
    t.remap("pose=/left/fd/ee_pose").unwrap();
    t.remap(" twist = /left/fd/ee_twist ").unwrap();
    t.remap("button=none").unwrap();
    t.remap("command=none").unwrap();
    assert_eq!(t.pose.as_str(), "/left/fd/ee_pose");
    assert_eq!(t.twist.as_ref().unwrap().as_str(), "/left/fd/ee_twist");
    assert!(t.button.is_none() && t.command.is_none());
    let text = t.describe(CommandLen::FORCES, &ExpectedFrame::default());
    assert!(
        text.contains("pose = /left/fd/ee_pose (frame fd_base)")
            && text.contains("command = none (NO force is written)"),
        "{text}"
    );
    let text = t.describe(CommandLen::FORCES, &ExpectedFrame::Any);
    assert!(text.contains("(frame any (NOT checked))"), "{text}");
    for (rule, says) in [
        (
            "wrench=/x",
            "unknown key; expected one of pose, twist, button, command",
        ),
        ("pose=none", "topic pose = \"none\""),
        ("command=fd/commands", "topic command = \"fd/commands\""),
        ("pose", "KEY=/topic/name"),
    ] {
        let e = HapticTopics::default().remap(rule).unwrap_err().to_string();
        assert!(e.contains(says), "{rule}: {e}");
    }
}

#[test]
fn the_command_is_the_forces_then_zeros_with_an_empty_layout() {
    let m = command_message([1.5, -2.0, 0.25], CommandLen::FORCES);
    assert!(m.layout.dim.is_empty() && m.layout.data_offset == 0);
    assert_eq!(m.data, [1.5, -2.0, 0.25]);
    let m = command_message([1.5, -2.0, 0.25], CommandLen::new(7).unwrap());
    assert_eq!(m.data, [1.5, -2.0, 0.25, 0.0, 0.0, 0.0, 0.0]);
    assert_eq!(
        CommandLen::new(4).unwrap().layout(),
        "std_msgs/Float64MultiArray [fx, fy, fz, 0] N, fd_base"
    );
    for bad in [0, 2, 8] {
        let e = CommandLen::new(bad).unwrap_err().to_string();
        assert!(
            e.contains(&format!("--ros-command-len {bad}: expected 3 to 7")),
            "{e}"
        );
    }
}

/// What `ros2 topic pub /fd/fd_controller/commands std_msgs/msg/Float64MultiArray "data: [0.5,
/// 0.0, 0.0]"` sends (forcedimension_ros2's README), byte for byte.
#[test]
fn the_command_bytes_are_a_plain_float64_multi_array() {
    let bytes =
        to_vec::<_, LittleEndian>(&command_message([0.5, 0.0, 0.0], CommandLen::FORCES)).unwrap();
    let mut expected = vec![
        0, 0, 0, 0, // layout.dim: no dimension
        0, 0, 0, 0, // layout.data_offset
        3, 0, 0, 0, // data: 3 entries, then the doubles (offset 12 → padded to 16)
        0, 0, 0, 0,
    ];
    for v in [0.5f64, 0.0, 0.0] {
        expected.extend_from_slice(&v.to_le_bytes());
    }
    assert_eq!(bytes, expected);
}

fn twist(stamp: i64, v: [f64; 3]) -> TwistStamped {
    TwistStamped {
        header: Header {
            stamp: Time::from_nanos(stamp),
            frame_id: "fd_base".into(),
        },
        twist: Twist {
            linear: Vector3::from_array(v),
            angular: Vector3::default(),
        },
    }
}

#[test]
fn the_gate_refuses_and_counts_each_kind_of_garbage() {
    let mut g = gate(false);
    let at = |k: i64| T0 + k * MS;
    assert!(
        g.on_pose(&fd_pose(at(0), [0.01, 0.0, 0.0]), rx(1))
            .is_some()
    );
    let mut nan = fd_pose(at(1), [f64::NAN, 0.0, 0.0]);
    assert!(g.on_pose(&nan, rx(2)).is_none());
    nan.pose.position.x = 0.01;
    nan.pose.orientation.w = f64::INFINITY;
    assert!(
        g.on_pose(&fd_pose(at(2), [0.01, 0.0, 0.0]), rx(3))
            .is_some()
    );
    assert!(
        g.on_pose(&fd_pose(at(3), [0.2, 0.0, 0.0]), rx(4)).is_none(),
        "jump"
    );
    assert!(
        g.on_pose(&fd_pose(at(1), [0.01, 0.0, 0.0]), rx(5))
            .is_none(),
        "old"
    );
    assert!(
        g.on_pose(&fd_pose(at(2), [0.01, 0.0, 0.0]), rx(6))
            .is_none(),
        "dup"
    );
    let mut malformed = fd_pose(at(4), [0.01, 0.0, 0.0]);
    malformed.header.stamp.nanosec = 1_500_000_000;
    assert!(g.on_pose(&malformed, rx(7)).is_none());
    assert!(
        g.on_pose(&fd_pose(at(5), [3.0, 0.0, 0.0]), rx(8)).is_none(),
        "far"
    );
    nan.header.stamp = Time::from_nanos(at(6));
    assert!(g.on_pose(&nan, rx(9)).is_none(), "a non-finite orientation");
    // The next good pose is checked against the last accepted one (at 2 ms), not the refused.
    let s = g
        .on_pose(&fd_pose(at(7), [0.0105, 0.0, 0.0]), rx(10))
        .unwrap();
    assert_eq!((s.stamp_ns, s.received_ns), (at(7), 10));
    assert_eq!(
        g.counts(),
        GateCounts {
            poses: 10,
            accepted: 3,
            malformed_stamps: 1,
            out_of_order: 1,
            duplicates: 1,
            non_finite: 2,
            out_of_range: 1,
            impossible_jumps: 1,
            ..GateCounts::default()
        }
    );
}

#[test]
fn without_a_twist_the_velocity_is_differentiated_over_the_window() {
    let mut g = gate(false);
    // 5 cm/s along x with ±5 µm of alternating noise, 1 ms apart.
    let mut last = None;
    for k in 0..40i64 {
        let noise = if k % 2 == 0 { 5e-6 } else { -5e-6 };
        let x = 0.05 * k as f64 * 1e-3 + noise;
        last = g.on_pose(&fd_pose(k * MS + MS, [x, 0.0, 0.0]), rx(k));
    }
    let v = last.unwrap().velocity_m_per_s;
    // Over 10 ms the noise is 1 mm/s at most; over 1 ms it would be 10 mm/s.
    assert!((v[0] - 0.05).abs() <= 0.0011, "{v:?}");
    assert_eq!(v[1], 0.0);
    // The first sample has nothing to differentiate: zero.
    let mut g = gate(false);
    let first = g.on_pose(&fd_pose(MS, [0.01, 0.0, 0.0]), rx(0)).unwrap();
    assert_eq!(first.velocity_m_per_s, [0.0; 3]);
    // A slow driver (20 ms apart): the previous pose.
    let s = g
        .on_pose(&fd_pose(21 * MS, [0.011, 0.0, 0.0]), rx(0))
        .unwrap();
    assert!((s.velocity_m_per_s[0] - 0.05).abs() < 1e-12);
}

#[test]
fn a_twist_near_the_pose_gives_the_velocity_else_the_pose_is_differentiated() {
    let mut g = gate(true);
    g.on_twist(&twist(MS, [0.3, 0.0, 0.0]), LATER);
    g.on_twist(&twist(2 * MS, [f64::NAN, 0.0, 0.0]), LATER);
    g.on_twist(&twist(MS, [0.4, 0.0, 0.0]), LATER);
    let s = g
        .on_pose(&fd_pose(2 * MS, [0.01, 0.0, 0.0]), rx(0))
        .unwrap();
    assert_eq!(s.velocity_m_per_s, [0.3, 0.0, 0.0]);
    // No twist within 2 ms of 10 ms: differentiated (0.01 → 0.0108 over 8 ms).
    let s = g
        .on_pose(&fd_pose(10 * MS, [0.0108, 0.0, 0.0]), rx(0))
        .unwrap();
    assert!((s.velocity_m_per_s[0] - 0.1).abs() < 1e-9, "{s:?}");
    let c = g.counts();
    assert_eq!((c.twists, c.twists_refused, c.without_twist), (3, 2, 1));
}

/// Regression: the gate made a pose's stamp the newest before checking its values, so one
/// refused pose stamped ahead of the driver (a second publisher, a replay, a clock step) made
/// every good pose after it "out of order": the pose went stale and the device faulted for the
/// rest of the run.
#[test]
fn a_refused_pose_stamped_ahead_does_not_refuse_the_good_poses_after_it() {
    let mut g = gate(false);
    assert!(
        g.on_pose(&fd_pose(T0, [0.01, 0.0, 0.0]), clock(0))
            .is_some()
    );
    // Ahead of the driver (within the 1 s allowed), each refused for its value.
    let ahead = T0 + 500 * MS;
    assert!(
        g.on_pose(&fd_pose(ahead, [f64::NAN, 0.0, 0.0]), clock(1))
            .is_none()
    );
    assert!(
        g.on_pose(&fd_pose(ahead + MS, [3.0, 0.0, 0.0]), clock(1))
            .is_none()
    );
    assert!(
        g.on_pose(&fd_pose(T0 + 10 * MS, [0.2, 0.0, 0.0]), clock(1))
            .is_none()
    );
    for k in 1..=3 {
        let s = g.on_pose(&fd_pose(T0 + k * MS, [0.01, 0.0, 0.0]), clock(k));
        assert_eq!(s.map(|s| s.stamp_ns), Some(T0 + k * MS), "{:?}", g.counts());
    }
    let c = g.counts();
    assert_eq!(
        (c.non_finite, c.out_of_range, c.impossible_jumps),
        (1, 1, 1)
    );
    assert_eq!((c.out_of_order, c.accepted), (0, 4));
}

/// Regression (the same bug): a pose stamped far ahead of the receiver's clock, valid in every
/// other way, was accepted and refused every correct pose until the driver's clock caught up.
#[test]
fn a_pose_stamped_over_a_second_ahead_of_the_clock_is_refused_and_counted() {
    let mut g = gate(true);
    assert!(
        g.on_pose(&fd_pose(T0, [0.01, 0.0, 0.0]), clock(0))
            .is_some()
    );
    let hour = 3_600_000 * MS;
    assert!(
        g.on_pose(&fd_pose(T0 + hour, [0.01, 0.0, 0.0]), clock(1))
            .is_none()
    );
    g.on_twist(&twist(T0 + hour, [0.3, 0.0, 0.0]), T0 + MS);
    g.on_twist(&twist(T0 + 2 * MS, [0.2, 0.0, 0.0]), T0 + 2 * MS);
    let s = g.on_pose(&fd_pose(T0 + 2 * MS, [0.01, 0.0, 0.0]), clock(2));
    assert_eq!(s.map(|s| s.velocity_m_per_s), Some([0.2, 0.0, 0.0]));
    let c = g.counts();
    assert_eq!((c.from_future, c.twists_refused), (1, 1), "{c:?}");
    assert_eq!((c.out_of_order, c.accepted), (0, 2), "{c:?}");
    // Up to the bound is accepted (a clock ahead by less than a second).
    let mut g = gate(false);
    let edge = T0 + GateConfig::default().max_ahead_ns;
    assert!(
        g.on_pose(&fd_pose(edge, [0.01, 0.0, 0.0]), clock(0))
            .is_some()
    );
    assert!(
        g.on_pose(&fd_pose(edge + 2, [0.01, 0.0, 0.0]), clock(0))
            .is_none()
    );
    assert_eq!(g.counts().from_future, 1);
}

/// Regression: the pose's frame was recorded, never checked: a pose re-published in the launch
/// file's `world` (a half turn about z from `fd_base`) would have turned x and y forces round.
#[test]
fn a_pose_in_another_frame_is_refused_and_counted_unless_any_frame_is_accepted() {
    let mut g = gate(false);
    let mut world = fd_pose(MS, [0.01, 0.0, 0.0]);
    world.header.frame_id = "world".into();
    assert!(g.on_pose(&world, rx(0)).is_none());
    world.header.frame_id = "base".into();
    world.header.stamp = Time::from_nanos(2 * MS);
    assert!(g.on_pose(&world, rx(0)).is_none());
    assert!(g.on_pose(&fd_pose(MS, [0.01, 0.0, 0.0]), rx(0)).is_some());
    assert_eq!((g.counts().wrong_frame, g.counts().accepted), (2, 1));
    assert_eq!(g.other_frame(), Some("world"));
    let io = IoReport {
        gate: g.counts(),
        other_frame: g.other_frame().map(str::to_owned),
        ..IoReport::default()
    };
    let text = seen(&io);
    assert!(
        text.contains("in another frame 2 (the first: \"world\"; --ros-pose-frame)"),
        "{text}"
    );
    let mut any = PoseGate::new(GateConfig::default(), ExpectedFrame::Any, false);
    assert!(any.on_pose(&world, rx(0)).is_some());
    // The flag's values.
    assert_eq!(ExpectedFrame::parse("any").unwrap(), ExpectedFrame::Any);
    assert_eq!(
        ExpectedFrame::parse("fd_base").unwrap(),
        ExpectedFrame::default()
    );
    for bad in ["", "fd base"] {
        let e = ExpectedFrame::parse(bad).unwrap_err().to_string();
        assert!(e.contains(&format!("--ros-pose-frame {bad:?}")), "{e}");
    }
}
