use super::*;
use crate::msg::{Header, Point, Pose as RosPose, Quaternion, Twist, Vector3, Wrench};

const MS: i64 = 1_000_000;
/// The receiver's ROS clock in the tests that are not about it: 1 s, after every stamp here.
const NOW: i64 = 1_000 * MS;

/// A receipt at `monotonic_ns`, the ROS clock at [`NOW`].
fn rx(monotonic_ns: i64) -> Receipt {
    Receipt {
        monotonic_ns,
        ros_ns: NOW,
    }
}

fn header(stamp: i64) -> Header {
    Header {
        stamp: Time::from_nanos(stamp),
        frame_id: "fr3_link0".into(),
    }
}

fn pose(stamp: i64, p: Vec3) -> PoseStamped {
    PoseStamped {
        header: header(stamp),
        pose: RosPose {
            position: Point::from_array(p),
            orientation: Quaternion::default(),
        },
    }
}

fn twist(stamp: i64, v: Vec3) -> TwistStamped {
    TwistStamped {
        header: header(stamp),
        twist: Twist {
            linear: Vector3::from_array(v),
            angular: Vector3::default(),
        },
    }
}

fn wrench(stamp: i64, f: Vec3) -> WrenchStamped {
    WrenchStamped {
        header: header(stamp),
        wrench: Wrench {
            force: Vector3::from_array(f),
            torque: Vector3::default(),
        },
    }
}

fn all(a: &mut StateAssembler) -> Vec<StateSample> {
    std::iter::from_fn(|| a.take()).collect()
}

#[test]
fn one_sample_per_stamp_once_every_stream_has_it_in_any_arrival_order() {
    let mut a = StateAssembler::new(StateConfig::default());
    // Stamp 1: pose, twist, wrench.
    a.on_pose(&pose(MS, [0.1, 0.0, 0.01]), rx(5));
    a.on_twist(&twist(MS, [0.01, 0.0, 0.0]), NOW);
    assert!(a.take().is_none(), "waits for the wrench");
    a.on_wrench(&wrench(MS, [0.0, 0.0, 1.5]), NOW);
    let s = all(&mut a);
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].stamp_ns, MS);
    assert_eq!(s[0].received_ns, 5);
    assert_eq!(s[0].sample.position_m, [0.1, 0.0, 0.01]);
    assert_eq!(s[0].sample.velocity_m_per_s, [0.01, 0.0, 0.0]);
    assert_eq!(s[0].sample.force_on_tool_n, [0.0, 0.0, 1.5]);
    // Stamp 2: wrench first, then twist, then pose.
    a.on_wrench(&wrench(2 * MS, [0.0, 0.0, 1.6]), NOW);
    a.on_twist(&twist(2 * MS, [0.02, 0.0, 0.0]), NOW);
    a.on_pose(&pose(2 * MS, [0.10001, 0.0, 0.01]), rx(6));
    let s = all(&mut a);
    assert_eq!(s.len(), 1);
    assert_eq!(s[0].sample.force_on_tool_n, [0.0, 0.0, 1.6]);
    assert_eq!(a.counts().samples, 2);
    assert_eq!(a.counts().inexact, 0);
}

#[test]
fn a_pose_overtaken_is_paired_with_the_nearest_or_refused() {
    let mut a = StateAssembler::new(StateConfig {
        twist: false,
        ..StateConfig::default()
    });
    // A driver whose wrench stamps lag its pose stamps by 0.3 ms.
    for k in 1..=5 {
        a.on_pose(&pose(k * MS, [0.0; 3]), rx(0));
        a.on_wrench(&wrench(k * MS - 300_000, [0.0, 0.0, k as f64]), NOW);
    }
    let s = all(&mut a);
    // Each pose is emitted when the next arrives, with its nearest wrench.
    assert_eq!(s.len(), 4);
    for (i, s) in s.iter().enumerate() {
        assert_eq!(s.sample.force_on_tool_n[2], (i + 1) as f64);
    }
    assert_eq!(a.counts().inexact, 4, "each with a wrench 0.3 ms off");
    // A wrench stream that stopped: poses are refused as unpaired, not paired with old forces.
    for k in 10..=14 {
        a.on_pose(&pose(k * MS, [0.0; 3]), rx(0));
    }
    let s = all(&mut a);
    assert_eq!(
        s.len(),
        1,
        "pose 5, overtaken by pose 10, still had its wrench"
    );
    assert_eq!(s[0].sample.force_on_tool_n[2], 5.0);
    assert_eq!(a.counts().unpaired, 4, "poses 10 to 13");
}

#[test]
fn out_of_order_duplicates_and_malformed_stamps_are_dropped_and_counted() {
    let mut a = StateAssembler::new(StateConfig::default());
    for k in [1, 2, 2, 1, 3] {
        a.on_pose(&pose(k * MS, [0.0; 3]), rx(0));
        a.on_twist(&twist(k * MS, [0.0; 3]), NOW);
        a.on_wrench(&wrench(k * MS, [0.0; 3]), NOW);
    }
    let stamps: Vec<i64> = all(&mut a).iter().map(|s| s.stamp_ns).collect();
    assert_eq!(stamps, [MS, 2 * MS, 3 * MS]);
    let c = a.counts();
    assert_eq!((c.duplicates, c.out_of_order), (3, 3), "{c:?}");
    let mut bad = pose(4 * MS, [0.0; 3]);
    bad.header.stamp.nanosec = 1_000_000_000;
    a.on_pose(&bad, rx(0));
    assert_eq!(a.counts().malformed_stamps, 1);
}

#[test]
fn non_finite_values_and_impossible_jumps_are_refused() {
    // Exact pairing: a pose whose twist or wrench is refused is left unpaired.
    let mut a = StateAssembler::new(StateConfig {
        pair_tolerance_ns: 0,
        ..StateConfig::default()
    });
    let step = |a: &mut StateAssembler, k: i64, p: Vec3, v: Vec3, f: Vec3| {
        a.on_pose(&pose(k * MS, p), rx(0));
        a.on_twist(&twist(k * MS, v), NOW);
        a.on_wrench(&wrench(k * MS, f), NOW);
        all(a).len()
    };
    assert_eq!(step(&mut a, 1, [0.0; 3], [0.0; 3], [0.0; 3]), 1);
    assert_eq!(step(&mut a, 2, [f64::NAN, 0.0, 0.0], [0.0; 3], [0.0; 3]), 0);
    assert_eq!(
        step(&mut a, 3, [0.0; 3], [0.0, f64::INFINITY, 0.0], [0.0; 3]),
        0
    );
    assert_eq!(step(&mut a, 4, [0.0; 3], [0.0; 3], [0.0, 0.0, f64::NAN]), 0);
    // 2 mm in 1 ms from the last accepted pose (at 4 ms): 2 m/s, plausible.
    assert_eq!(step(&mut a, 5, [0.002, 0.0, 0.0], [0.0; 3], [0.0; 3]), 1);
    // 1 cm more in 1 ms: 10 m/s, impossible.
    assert_eq!(step(&mut a, 6, [0.012, 0.0, 0.0], [0.0; 3], [0.0; 3]), 0);
    // The next pose is judged against the last accepted one: back where it was, fine.
    assert_eq!(step(&mut a, 7, [0.0021, 0.0, 0.0], [0.0; 3], [0.0; 3]), 1);
    let c = a.counts();
    assert_eq!((c.non_finite, c.impossible_jumps), (3, 1), "{c:?}");
    assert_eq!((c.unpaired, c.samples), (2, 3), "poses 3 and 4: {c:?}");
}

/// Regression: a pose refused for its values (non-finite, no rotation for a tool-frame wrench,
/// an impossible jump) still became the newest pose; one stamped ahead of the stream (a second
/// publisher, a replay, a clock step) made every good pose after it out of order, and the states
/// stopped for the rest of the session.
#[test]
fn a_refused_pose_stamped_ahead_does_not_stop_the_poses_after_it() {
    let mut a = StateAssembler::new(StateConfig {
        wrench_frame: WrenchFrame::Tool,
        ..StateConfig::default()
    });
    let good = |a: &mut StateAssembler, k: i64| {
        a.on_pose(&pose(k * MS, [0.1, 0.0, 0.0]), rx(k));
        a.on_twist(&twist(k * MS, [0.0; 3]), NOW);
        a.on_wrench(&wrench(k * MS, [0.0; 3]), NOW);
        all(a).len()
    };
    assert_eq!(good(&mut a, 1), 1);
    // Half a second ahead of the stream (within a second of the clock), each refused.
    a.on_pose(&pose(500 * MS, [f64::NAN, 0.0, 0.0]), rx(2));
    let mut no_rotation = pose(550 * MS, [0.1, 0.0, 0.0]);
    no_rotation.pose.orientation.w = 0.0;
    a.on_pose(&no_rotation, rx(3));
    a.on_pose(&pose(600 * MS, [5.0, 0.0, 0.0]), rx(4)); // 8 m/s from the last pose
    for k in 2..=4 {
        assert_eq!(good(&mut a, k), 1, "{:?}", a.counts());
    }
    let c = a.counts();
    assert_eq!((c.non_finite, c.impossible_jumps), (2, 1), "{c:?}");
    assert_eq!((c.out_of_order, c.samples), (0, 4), "{c:?}");
}

/// Regression (the same bug in the other streams): a twist or wrench refused for its values
/// still became the newest of its stream; one stamped ahead left every pose after it unpaired.
#[test]
fn a_refused_twist_or_wrench_stamped_ahead_does_not_stop_the_states_after_it() {
    let mut a = StateAssembler::new(StateConfig::default());
    a.on_twist(&twist(500 * MS, [f64::NAN, 0.0, 0.0]), NOW);
    a.on_wrench(&wrench(500 * MS, [0.0, f64::INFINITY, 0.0]), NOW);
    for k in 1..=3 {
        a.on_pose(&pose(k * MS, [0.0; 3]), rx(k));
        a.on_twist(&twist(k * MS, [0.0; 3]), NOW);
        a.on_wrench(&wrench(k * MS, [0.0; 3]), NOW);
    }
    let c = a.counts();
    assert_eq!(all(&mut a).len(), 3, "{c:?}");
    assert_eq!(
        (c.non_finite, c.out_of_order, c.unpaired),
        (2, 0, 0),
        "{c:?}"
    );
}

/// Regression: a pose (twist, wrench) stamped far ahead of the receiver's clock, valid in every
/// other way, was accepted and made every correct one after it out of order until the driver's
/// clock caught up.
#[test]
fn a_pose_stamped_far_ahead_of_the_clock_is_refused_and_counted() {
    let mut a = StateAssembler::new(StateConfig::default());
    // The driver's clock and this host's agree: each message is received 0.2 ms after its stamp.
    let step = |a: &mut StateAssembler, k: i64, stamp: i64| {
        let at = Receipt {
            monotonic_ns: k,
            ros_ns: k * MS + 200_000,
        };
        a.on_pose(&pose(stamp, [0.0; 3]), at);
        a.on_twist(&twist(stamp, [0.0; 3]), at.ros_ns);
        a.on_wrench(&wrench(stamp, [0.0; 3]), at.ros_ns);
        all(a).len()
    };
    assert_eq!(step(&mut a, 1, MS), 1);
    let hour = 3_600_000 * MS;
    assert_eq!(step(&mut a, 2, hour), 0);
    for k in 3..=5 {
        assert_eq!(step(&mut a, k, k * MS), 1, "{:?}", a.counts());
    }
    let c = a.counts();
    assert_eq!((c.from_future, c.out_of_order), (3, 0), "{c:?}");
    assert_eq!(c.samples, 4, "{c:?}");
    // Up to the bound is accepted (a clock ahead by less than a second).
    let mut a = StateAssembler::new(StateConfig::default());
    let edge = NOW + StateConfig::default().max_ahead_ns;
    a.on_pose(&pose(edge, [0.0; 3]), rx(0));
    a.on_pose(&pose(edge + 1, [0.0; 3]), rx(0));
    a.on_twist(&twist(edge, [0.0; 3]), NOW);
    a.on_wrench(&wrench(edge, [0.0; 3]), NOW);
    assert_eq!(all(&mut a).len(), 1);
    assert_eq!(a.counts().from_future, 1);
}

#[test]
fn without_a_twist_the_velocity_is_the_pose_difference() {
    let mut a = StateAssembler::new(StateConfig {
        twist: false,
        ..StateConfig::default()
    });
    for k in 0..5 {
        let t = k * 2 * MS; // a 500 Hz driver
        a.on_pose(&pose(t, [0.001 * k as f64, 0.0, 0.0]), rx(0));
        a.on_wrench(&wrench(t, [0.0; 3]), NOW);
    }
    let s = all(&mut a);
    assert_eq!(s.len(), 5);
    assert_eq!(s[0].sample.velocity_m_per_s, [0.0; 3]);
    for s in &s[1..] {
        assert!((s.sample.velocity_m_per_s[0] - 0.5).abs() < 1e-9, "{s:?}");
    }
}

/// The sign convention: pressing down (−z) into a table whose surface pushes back up (+z).
#[test]
fn the_wrench_is_the_force_on_the_tool_rotated_and_signed_as_declared() {
    let press = |config: StateConfig, orientation: Quaternion, f: Vec3| {
        let mut a = StateAssembler::new(config);
        let mut p = pose(MS, [0.0, 0.0, -0.004]);
        p.pose.orientation = orientation;
        a.on_pose(&p, rx(0));
        a.on_twist(&twist(MS, [0.0; 3]), NOW);
        a.on_wrench(&wrench(MS, f), NOW);
        a.take().unwrap().sample.force_on_tool_n
    };
    let base = StateConfig::default();
    assert_eq!(
        press(base, Quaternion::default(), [0.0, 0.0, 2.0]),
        [0.0, 0.0, 2.0]
    );
    let by_tool = StateConfig {
        wrench_sign: WrenchSign::ByTool,
        ..base
    };
    assert_eq!(
        press(by_tool, Quaternion::default(), [0.0, 0.0, -2.0]),
        [0.0, 0.0, 2.0]
    );
    // A tool pointing down (rotated π about x): its +z is the base's −z.
    let down = Quaternion {
        x: 1.0,
        y: 0.0,
        z: 0.0,
        w: 0.0,
    };
    let tool = StateConfig {
        wrench_frame: WrenchFrame::Tool,
        ..base
    };
    let f = press(tool, down, [0.0, 0.0, -2.0]);
    assert!(vec3::norm(vec3::sub(f, [0.0, 0.0, 2.0])) < 1e-12, "{f:?}");
    // A tool-frame wrench needs an orientation: a zero quaternion is refused.
    let mut a = StateAssembler::new(tool);
    let mut p = pose(MS, [0.0; 3]);
    p.pose.orientation = Quaternion {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        w: 0.0,
    };
    a.on_pose(&p, rx(0));
    a.on_twist(&twist(MS, [0.0; 3]), NOW);
    a.on_wrench(&wrench(MS, [0.0; 3]), NOW);
    assert!(a.take().is_none());
    assert_eq!(a.counts().non_finite, 1);
}

#[test]
fn the_stamp_clock_maps_onto_the_fastest_delivery_and_increases() {
    let mut c = StampClock::default();
    let offset = 1_000_000_000_000; // the two clocks differ by 1000 s
    // Latencies 300, 100, 500 µs: the offset settles on the 100 µs one.
    assert_eq!(c.map(0, offset + 300_000), offset + 300_000);
    assert_eq!(c.map(MS, offset + MS + 100_000), offset + MS + 100_000);
    assert_eq!(
        c.map(2 * MS, offset + 2 * MS + 500_000),
        offset + 2 * MS + 100_000
    );
    // A later, faster delivery lowers the offset, but never makes time go back.
    let m = c.map(3 * MS, offset + 3 * MS - 900_000 + 1_000_000 - 995_000);
    assert!(m > offset + 2 * MS + 100_000);
    // Mapped times never lie after their receipt.
    let mut c = StampClock::default();
    let mut last = i64::MIN;
    for k in 0..5000i64 {
        let lat = 50_000 + (k * 7919 % 400) * 1000;
        let received = offset + k * MS + lat;
        let m = c.map(k * MS, received);
        assert!(m <= received && m > last);
        last = m;
    }
}
