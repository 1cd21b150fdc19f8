//! The robot state a ROS 2 arm driver publishes (`PoseStamped`, `TwistStamped`,
//! `WrenchStamped`), fed to the state assembler as a peer could send it: any stamps (malformed,
//! repeated, out of order, far apart), any numbers (NaN, infinities, huge), and messages decoded
//! with `cdr-encoding` (what RustDDS uses) from mutated bytes. Never a panic, and every sample
//! the assembler hands the telerobot is finite, newer than the last and no faster than the
//! configured speed (issue 11: this decoding was not fuzzed); and whatever arrived, the messages
//! stamped after it (beyond what the receiver's clock allowed then) are never refused as out of
//! order: no message can stop the states.
#![allow(clippy::unwrap_used)]

use byteorder::LittleEndian;
use proptest::prelude::*;
use ros2::msg::{
    Header, Point, Pose, PoseStamped, Quaternion, Time, Twist, TwistStamped, Vector3, Wrench,
    WrenchStamped,
};
use ros2::state::{Receipt, StateAssembler, StateConfig, WrenchFrame, WrenchSign};

/// One message on one of the three topics.
#[derive(Clone, Debug)]
enum Msg {
    Pose(PoseStamped),
    Twist(TwistStamped),
    Wrench(WrenchStamped),
}

/// A number as a peer could send it: mostly ordinary, sometimes not finite or huge.
fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -2.0..2.0_f64,
        1 => prop::num::f64::ANY,
        1 => Just(f64::NAN),
    ]
}

fn vector() -> impl Strategy<Value = [f64; 3]> {
    [number(), number(), number()]
}

/// A stamp near the others (so that pairing happens), or anything at all.
fn stamp() -> impl Strategy<Value = Time> {
    prop_oneof![
        8 => (0u32..40).prop_map(|ms| Time { sec: 100, nanosec: ms * 1_000_000 }),
        1 => (any::<i32>(), any::<u32>()).prop_map(|(sec, nanosec)| Time { sec, nanosec }),
    ]
}

fn header(stamp: Time) -> Header {
    Header {
        stamp,
        frame_id: "fr3_link0".to_owned(),
    }
}

fn message() -> impl Strategy<Value = Msg> {
    let v3 = |v: [f64; 3]| Vector3 {
        x: v[0],
        y: v[1],
        z: v[2],
    };
    prop_oneof![
        (stamp(), vector(), [number(), number(), number(), number()]).prop_map(|(t, p, q)| {
            Msg::Pose(PoseStamped {
                header: header(t),
                pose: Pose {
                    position: Point {
                        x: p[0],
                        y: p[1],
                        z: p[2],
                    },
                    orientation: Quaternion {
                        x: q[0],
                        y: q[1],
                        z: q[2],
                        w: q[3],
                    },
                },
            })
        }),
        (stamp(), vector(), vector()).prop_map(move |(t, l, a)| {
            Msg::Twist(TwistStamped {
                header: header(t),
                twist: Twist {
                    linear: v3(l),
                    angular: v3(a),
                },
            })
        }),
        (stamp(), vector(), vector()).prop_map(move |(t, f, m)| {
            Msg::Wrench(WrenchStamped {
                header: header(t),
                wrench: Wrench {
                    force: v3(f),
                    torque: v3(m),
                },
            })
        }),
    ]
}

/// `msg` as CDR bytes with `flips` (index, xor) applied and cut to `keep` of its length, decoded
/// again as the same type: what a corrupted datagram could become (or nothing).
fn through_bytes(msg: Msg, flips: &[(usize, u8)], keep: f64) -> Option<Msg> {
    fn mangle<T>(value: &T, flips: &[(usize, u8)], keep: f64) -> Option<T>
    where
        T: serde::Serialize + serde::de::DeserializeOwned,
    {
        let mut bytes = cdr_encoding::to_vec::<_, LittleEndian>(value).ok()?;
        let n = bytes.len();
        for &(i, x) in flips {
            bytes[i % n] ^= x;
        }
        bytes.truncate(((n as f64) * keep).ceil() as usize);
        cdr_encoding::from_bytes::<T, LittleEndian>(&bytes)
            .ok()
            .map(|(v, _)| v)
    }
    match msg {
        Msg::Pose(m) => mangle(&m, flips, keep).map(Msg::Pose),
        Msg::Twist(m) => mangle(&m, flips, keep).map(Msg::Twist),
        Msg::Wrench(m) => mangle(&m, flips, keep).map(Msg::Wrench),
    }
}

/// The receipt of the `k`-th message: 1 ms apart, the ROS clock at 100 s (the stamps near the
/// others) plus `k` ms.
fn receipt(k: usize) -> Receipt {
    let k = k as i64;
    Receipt {
        monotonic_ns: k * 1_000_000,
        ros_ns: 100_000_000_000 + k * 1_000_000,
    }
}

/// Three well-formed states stamped after anything the receiver's clock allowed while the first
/// `n` messages arrived, each received at its stamp (the driver's clock and this host's agree).
fn good_states(config: &StateConfig, n: usize) -> Vec<(Msg, Receipt)> {
    let horizon = receipt(n).ros_ns + config.max_ahead_ns;
    (1..=3)
        .flat_map(|j| {
            let stamp = horizon + j * 1_000_000;
            let at = Receipt {
                monotonic_ns: receipt(n).monotonic_ns + j * 1_000_000,
                ros_ns: stamp,
            };
            let header = header(Time::from_nanos(stamp));
            let pose = PoseStamped {
                header: header.clone(),
                pose: Pose::default(),
            };
            let twist = TwistStamped {
                header: header.clone(),
                twist: Twist::default(),
            };
            let wrench = WrenchStamped {
                header,
                wrench: Wrench::default(),
            };
            [Msg::Pose(pose), Msg::Twist(twist), Msg::Wrench(wrench)].map(|m| (m, at))
        })
        .collect()
}

/// Feeds `messages` to an assembler of `config` and checks every sample it hands out, then that
/// well-formed states stamped after them are not refused for their stamps.
fn check(config: StateConfig, messages: &[Msg]) -> Result<(), TestCaseError> {
    let mut a = StateAssembler::new(config);
    let mut last: Option<(i64, [f64; 3])> = None;
    let mut emitted = 0_u64;
    let stamp_refusals = |a: &StateAssembler| {
        let c = a.counts();
        (
            c.malformed_stamps,
            c.from_future,
            c.out_of_order,
            c.duplicates,
        )
    };
    let peer = messages
        .iter()
        .cloned()
        .enumerate()
        .map(|(k, m)| (m, receipt(k)));
    let good = good_states(&config, messages.len());
    let mut refused_before_good = None;
    for (k, (m, at)) in peer.chain(good).enumerate() {
        if k == messages.len() {
            refused_before_good = Some(stamp_refusals(&a));
        }
        match &m {
            Msg::Pose(p) => a.on_pose(p, at),
            Msg::Twist(t) => a.on_twist(t, at.ros_ns),
            Msg::Wrench(w) => a.on_wrench(w, at.ros_ns),
        }
        while let Some(s) = a.take() {
            emitted += 1;
            let r = &s.sample;
            let values = r
                .position_m
                .iter()
                .chain(&r.velocity_m_per_s)
                .chain(&r.force_on_tool_n);
            prop_assert!(values.clone().all(|v| v.is_finite()), "{s:?}");
            if let Some((t, at)) = last {
                prop_assert!(s.stamp_ns > t, "stamp {} after {t}", s.stamp_ns);
                let d = mmt::vec3::norm(mmt::vec3::sub(r.position_m, at));
                let speed = d / ((s.stamp_ns - t) as f64 * 1e-9);
                prop_assert!(speed <= config.max_speed_m_per_s, "{speed} m/s");
            }
            last = Some((s.stamp_ns, r.position_m));
        }
    }
    prop_assert_eq!(
        refused_before_good,
        Some(stamp_refusals(&a)),
        "good states refused for their stamps: {:?}",
        a.counts()
    );
    let c = a.counts();
    prop_assert!(
        emitted <= c.poses,
        "{emitted} samples from {} poses",
        c.poses
    );
    Ok(())
}

fn configs() -> [StateConfig; 3] {
    [
        StateConfig::default(),
        StateConfig {
            twist: false,
            wrench_frame: WrenchFrame::Tool,
            ..StateConfig::default()
        },
        StateConfig {
            wrench_sign: WrenchSign::ByTool,
            max_speed_m_per_s: 0.5,
            ..StateConfig::default()
        },
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Any messages, in any order: never a panic, only finite, ordered, possible samples.
    #[test]
    fn any_robot_state_gives_only_sound_samples(
        messages in proptest::collection::vec(message(), 0..80),
    ) {
        for config in configs() {
            check(config, &messages)?;
        }
    }

    /// The same through corrupted CDR bytes: whatever still decodes is handled as above.
    #[test]
    fn corrupted_cdr_gives_only_sound_samples(
        messages in proptest::collection::vec(
            (message(), proptest::collection::vec((any::<usize>(), any::<u8>()), 0..4), 0.0..=1.0_f64),
            0..60,
        ),
    ) {
        let decoded: Vec<Msg> = messages
            .into_iter()
            .filter_map(|(m, flips, keep)| through_bytes(m, &flips, keep))
            .collect();
        for config in configs() {
            check(config, &decoded)?;
        }
    }
}
