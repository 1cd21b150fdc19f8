use byteorder::LittleEndian;
use cdr_encoding::to_vec;

use super::*;
use crate::fd_double::fd_pose;
use crate::msg::{Header, Time, Twist, TwistStamped, Vector3};

const MS: i64 = 1_000_000;

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
    let text = t.describe(CommandLen::FORCES);
    assert!(
        text.contains("command = none (NO force is written)"),
        "{text}"
    );
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
    let mut g = PoseGate::new(GateConfig::default(), false);
    let t0 = 1_700_000_000 * 1_000 * MS;
    let at = |k: i64| t0 + k * MS;
    assert!(g.on_pose(&fd_pose(at(0), [0.01, 0.0, 0.0]), 1).is_some());
    let mut nan = fd_pose(at(1), [f64::NAN, 0.0, 0.0]);
    assert!(g.on_pose(&nan, 2).is_none());
    nan.pose.position.x = 0.01;
    nan.pose.orientation.w = f64::INFINITY;
    assert!(g.on_pose(&fd_pose(at(2), [0.01, 0.0, 0.0]), 3).is_some());
    assert!(
        g.on_pose(&fd_pose(at(3), [0.2, 0.0, 0.0]), 4).is_none(),
        "jump"
    );
    assert!(
        g.on_pose(&fd_pose(at(1), [0.01, 0.0, 0.0]), 5).is_none(),
        "old"
    );
    assert!(
        g.on_pose(&fd_pose(at(3), [0.01, 0.0, 0.0]), 6).is_none(),
        "dup"
    );
    let mut malformed = fd_pose(at(4), [0.01, 0.0, 0.0]);
    malformed.header.stamp.nanosec = 1_500_000_000;
    assert!(g.on_pose(&malformed, 7).is_none());
    assert!(
        g.on_pose(&fd_pose(at(5), [3.0, 0.0, 0.0]), 8).is_none(),
        "far"
    );
    nan.header.stamp = Time::from_nanos(at(6));
    assert!(g.on_pose(&nan, 9).is_none(), "a non-finite orientation");
    // The next good pose is checked against the last accepted one (at 2 ms), not the refused.
    let s = g.on_pose(&fd_pose(at(7), [0.0105, 0.0, 0.0]), 10).unwrap();
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
    let mut g = PoseGate::new(GateConfig::default(), false);
    // 5 cm/s along x with ±5 µm of alternating noise, 1 ms apart.
    let mut last = None;
    for k in 0..40i64 {
        let noise = if k % 2 == 0 { 5e-6 } else { -5e-6 };
        let x = 0.05 * k as f64 * 1e-3 + noise;
        last = g.on_pose(&fd_pose(k * MS + MS, [x, 0.0, 0.0]), k);
    }
    let v = last.unwrap().velocity_m_per_s;
    // Over 10 ms the noise is 1 mm/s at most; over 1 ms it would be 10 mm/s.
    assert!((v[0] - 0.05).abs() <= 0.0011, "{v:?}");
    assert_eq!(v[1], 0.0);
    // The first sample has nothing to differentiate: zero.
    let mut g = PoseGate::new(GateConfig::default(), false);
    let first = g.on_pose(&fd_pose(MS, [0.01, 0.0, 0.0]), 0).unwrap();
    assert_eq!(first.velocity_m_per_s, [0.0; 3]);
    // A slow driver (20 ms apart): the previous pose.
    let s = g.on_pose(&fd_pose(21 * MS, [0.011, 0.0, 0.0]), 0).unwrap();
    assert!((s.velocity_m_per_s[0] - 0.05).abs() < 1e-12);
}

#[test]
fn a_twist_near_the_pose_gives_the_velocity_else_the_pose_is_differentiated() {
    let mut g = PoseGate::new(GateConfig::default(), true);
    g.on_twist(&twist(MS, [0.3, 0.0, 0.0]));
    g.on_twist(&twist(2 * MS, [f64::NAN, 0.0, 0.0]));
    g.on_twist(&twist(MS, [0.4, 0.0, 0.0]));
    let s = g.on_pose(&fd_pose(2 * MS, [0.01, 0.0, 0.0]), 0).unwrap();
    assert_eq!(s.velocity_m_per_s, [0.3, 0.0, 0.0]);
    // No twist within 2 ms of 10 ms: differentiated (0.01 → 0.0108 over 8 ms).
    let s = g.on_pose(&fd_pose(10 * MS, [0.0108, 0.0, 0.0]), 0).unwrap();
    assert!((s.velocity_m_per_s[0] - 0.1).abs() < 1e-9, "{s:?}");
    let c = g.counts();
    assert_eq!((c.twists, c.twists_refused, c.without_twist), (3, 2, 1));
}
