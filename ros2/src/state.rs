//! Robot state from three topics: pose, twist and wrench → one [`StateSample`] per pose, timed
//! by its header stamp. Pure (no DDS, no clock): the I/O thread feeds it messages with their
//! [`Receipt`]s.
//!
//! # Conventions (the one place they are stated)
//!
//! - **Frames.** Positions, velocities and forces are in the robot's base frame: the pose's
//!   `header.frame_id` (e.g. `fr3_link0`). A twist is taken as the tool's linear velocity in that
//!   frame; a wrench either in that frame ([`WrenchFrame::Base`], the default: franka_ros2's
//!   `O_F_ext_hat_K`) or in the tool's frame ([`WrenchFrame::Tool`], rotated into the base frame
//!   by the same stamp's pose orientation).
//! - **Sign.** The wrench is **the force the environment exerts on the tool**
//!   ([`WrenchSign::OnTool`], the default; franka's external-force estimate is of this kind) —
//!   the sign of `node::RobotSample::force_on_tool_n` and of `mmt::model`'s regression
//!   (`y = −F_op`). A sensor that reports the force the tool exerts on the environment is
//!   declared [`WrenchSign::ByTool`] and negated here. Pressing down on a table (+z up) gives a
//!   force on the tool of +z.
//! - **Pairing.** A pose is completed by the wrench (and twist) of the same stamp: the sample is
//!   emitted as soon as every stream has reached the pose's stamp; a pose overtaken by the next
//!   one is emitted with the nearest samples within [`StateConfig::pair_tolerance_ns`], or
//!   refused as unpaired.
//! - **No twist.** Without a twist topic the velocity is the backward difference of consecutive
//!   accepted poses over their stamps (the first sample has velocity 0).
//!
//! # Refusals (each counted in [`StateCounts`])
//! - a stamp with `nanosec ≥ 1e9` (malformed);
//! - a stamp more than [`StateConfig::max_ahead_ns`] ahead of the receiver's ROS clock (from
//!   the future: another clock's);
//! - a stamp not newer than the newest *accepted* one of its stream (out of order, or a
//!   duplicate);
//! - a non-finite value anywhere in a pose, twist or wrench, or (for a tool-frame wrench, which
//!   needs it) a pose's orientation that is not a rotation (a zero quaternion);
//! - an impossible jump: a pose faster than [`StateConfig::max_speed_m_per_s`] from the last
//!   accepted pose.
//!
//! A refused message changes nothing but the counts: only an accepted message's stamp becomes
//! the one later messages of its stream must be newer than. (A refused pose that moved it would
//! make every good pose after it "out of order" until the driver's clock caught up: one garbage
//! message from a second publisher, a bag replay or a clock step would stop the states for the
//! rest of the session.) A pose is accepted on its stamp and its own values; the sample it makes
//! may still be refused as unpaired, which does not undo that.

use mmt::cloud::Pose;
use mmt::vec3::{self, Vec3};
use node::RobotSample;
use serde::Serialize;

use crate::msg::{PoseStamped, Time, TwistStamped, WrenchStamped};

/// Which frame the wrench is expressed in.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum WrenchFrame {
    /// The pose's frame (the base).
    #[default]
    Base,
    /// The tool's frame: rotated into the base frame by the pose's orientation.
    Tool,
}

/// What the wrench's force is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub enum WrenchSign {
    /// The force the environment exerts on the tool.
    #[default]
    OnTool,
    /// The force the tool exerts on the environment (negated here).
    ByTool,
}

/// How samples are assembled and checked.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StateConfig {
    /// A twist topic is expected (else the velocity is differentiated from the pose).
    pub twist: bool,
    /// The wrench's frame.
    pub wrench_frame: WrenchFrame,
    /// The wrench's sign.
    pub wrench_sign: WrenchSign,
    /// How far apart pose, twist and wrench stamps may be and still make one sample \[ns\].
    /// Default 2 ms: two ticks of a 1 kHz driver.
    pub pair_tolerance_ns: i64,
    /// Faster than this between two poses is an impossible jump \[m/s\]. Default 3 m/s:
    /// above any collaborative arm's Cartesian limit (Franka: 1.7 m/s).
    pub max_speed_m_per_s: f64,
    /// A message stamped more than this ahead of the receiver's ROS clock at receipt is refused
    /// \[ns\]. Default [`MAX_AHEAD_NS`].
    pub max_ahead_ns: i64,
}

/// How far ahead of the receiver's ROS clock a header stamp may be \[ns\]: 1 s. Hosts kept by
/// NTP agree within milliseconds and a message is in transit for less, so a stamp a second ahead
/// is another clock's (a stepped or unsynchronised host, a second publisher, a replay); accepted,
/// it would refuse every correct message of its stream as out of order until the driver's clock
/// caught up. (A driver host whose clock runs more than 1 s ahead of this one has all its
/// messages refused, counted as `from_future`: synchronise the clocks.)
pub const MAX_AHEAD_NS: i64 = 1_000_000_000;

impl Default for StateConfig {
    fn default() -> Self {
        StateConfig {
            twist: true,
            wrench_frame: WrenchFrame::Base,
            wrench_sign: WrenchSign::OnTool,
            pair_tolerance_ns: 2_000_000,
            max_speed_m_per_s: 3.0,
            max_ahead_ns: MAX_AHEAD_NS,
        }
    }
}

/// One assembled robot state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StateSample {
    /// The pose's header stamp \[ns, ROS time\].
    pub stamp_ns: i64,
    /// When the pose arrived \[ns, the receiver's monotonic clock\].
    pub received_ns: i64,
    /// Position, velocity and force on the tool, base frame.
    pub sample: RobotSample,
    /// The tool's orientation (x, y, z, w).
    pub orientation_xyzw: [f64; 4],
}

/// What the assembler did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct StateCounts {
    /// Poses received.
    pub poses: u64,
    /// Twists received.
    pub twists: u64,
    /// Wrenches received.
    pub wrenches: u64,
    /// Samples emitted.
    pub samples: u64,
    /// Messages whose stamp had `nanosec ≥ 1e9`.
    pub malformed_stamps: u64,
    /// Poses (or twists, wrenches) stamped more than [`StateConfig::max_ahead_ns`] ahead of the
    /// receiver's ROS clock.
    pub from_future: u64,
    /// Poses (or twists, wrenches) older than the newest accepted one of their stream.
    pub out_of_order: u64,
    /// Poses (or twists, wrenches) with the same stamp as the newest accepted one of their
    /// stream.
    pub duplicates: u64,
    /// Poses, twists or wrenches with a non-finite value, or poses with a zero quaternion (for a
    /// tool-frame wrench).
    pub non_finite: u64,
    /// Poses beyond the plausible speed from the last accepted pose.
    pub impossible_jumps: u64,
    /// Poses with no wrench (or twist) within the pairing tolerance.
    pub unpaired: u64,
    /// Samples whose wrench or twist was of another stamp than the pose's (the nearest within
    /// the tolerance).
    #[serde(default)]
    pub inexact: u64,
}

/// When a message arrived, on both of the receiver's clocks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Receipt {
    /// The monotonic clock \[ns\]: what staleness is measured on.
    pub monotonic_ns: i64,
    /// The ROS clock (system time) \[ns\]: what header stamps are compared with.
    pub ros_ns: i64,
}

/// One stream's last two accepted samples (stamp, value).
#[derive(Clone, Copy, Debug, Default)]
struct Recent {
    latest: Option<(i64, Vec3)>,
    previous: Option<(i64, Vec3)>,
}

impl Recent {
    /// The newest accepted stamp.
    fn newest(&self) -> Option<i64> {
        self.latest.map(|(t, _)| t)
    }

    /// Stores an accepted sample.
    fn push(&mut self, stamp: i64, v: Vec3) {
        self.previous = self.latest;
        self.latest = Some((stamp, v));
    }

    fn reached(&self, stamp: i64) -> bool {
        self.latest.is_some_and(|(t, _)| t >= stamp)
    }

    /// The sample nearest `stamp`, if within `tolerance`, and its stamp.
    fn nearest(&self, stamp: i64, tolerance: i64) -> Option<(i64, Vec3)> {
        [self.latest, self.previous]
            .into_iter()
            .flatten()
            .min_by_key(|(t, _)| (t - stamp).abs())
            .filter(|(t, _)| (t - stamp).abs() <= tolerance)
    }
}

#[derive(Clone, Copy, Debug)]
struct PendingPose {
    stamp: i64,
    received_ns: i64,
    position: Vec3,
    orientation: [f64; 4],
    /// The orientation's rotation, when a tool-frame wrench needs it (checked on arrival).
    rotation: Option<Pose>,
}

/// The assembler. See the module docs.
#[derive(Clone, Debug)]
pub struct StateAssembler {
    config: StateConfig,
    pending: Option<PendingPose>,
    /// The newest accepted pose (stamp, position): what later poses must be newer than and
    /// within speed of.
    last_pose: Option<(i64, Vec3)>,
    twist: Recent,
    wrench: Recent,
    /// The last emitted sample (stamp, position): the velocity without a twist topic.
    last: Option<(i64, Vec3)>,
    out: Vec<StateSample>,
    counts: StateCounts,
}

/// Where a header stamp falls against the receiver's clock and the newest accepted stamp of its
/// stream (the robot's state, a haptic device's pose): only a newer stamp, not from the future,
/// is a new sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Arrival {
    /// Newer than the newest (or the first).
    Newer,
    /// More than the allowed margin ahead of the receiver's ROS clock.
    FromFuture,
    /// The same stamp again.
    Duplicate,
    /// Older than the newest.
    OutOfOrder,
}

/// Where `stamp` falls against `newest` and the receiver's ROS clock `ros_now_ns`, a stamp more
/// than `max_ahead_ns` ahead of which is from the future.
pub(crate) fn arrival(
    newest: Option<i64>,
    stamp: i64,
    ros_now_ns: i64,
    max_ahead_ns: i64,
) -> Arrival {
    if stamp.saturating_sub(ros_now_ns) > max_ahead_ns {
        return Arrival::FromFuture;
    }
    match newest {
        Some(t) if stamp == t => Arrival::Duplicate,
        Some(t) if stamp < t => Arrival::OutOfOrder,
        _ => Arrival::Newer,
    }
}

/// Whether moving from `last` (stamp \[ns\], position \[m\]) to `position` at `stamp` stays at or
/// below `max_speed_m_per_s` (always, with no `last`; never, for a non-finite speed).
pub(crate) fn within_speed(
    last: Option<(i64, Vec3)>,
    stamp: i64,
    position: Vec3,
    max_speed_m_per_s: f64,
) -> bool {
    last.is_none_or(|(t, at)| {
        let dt = (stamp - t) as f64 * 1e-9;
        vec3::norm(vec3::sub(position, at)) / dt <= max_speed_m_per_s
    })
}

/// The rotation of a quaternion (x, y, z, w); `None` if it is not one (zero or non-finite).
fn rotation([x, y, z, w]: [f64; 4]) -> Option<Pose> {
    Pose::from_quaternion([w, x, y, z], [0.0; 3])
}

impl StateAssembler {
    /// An assembler for `config`.
    pub fn new(config: StateConfig) -> StateAssembler {
        StateAssembler {
            config,
            pending: None,
            last_pose: None,
            twist: Recent::default(),
            wrench: Recent::default(),
            last: None,
            out: Vec::with_capacity(4),
            counts: StateCounts::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &StateConfig {
        &self.config
    }

    /// A pose arrived `at`.
    pub fn on_pose(&mut self, msg: &PoseStamped, at: Receipt) {
        self.counts.poses += 1;
        let newest = self.last_pose.map(|(t, _)| t);
        let Some(stamp) = self.check_stamp(msg.header.stamp, newest, at.ros_ns) else {
            return;
        };
        let Some(pose) = self.check_pose(msg, stamp, at.monotonic_ns) else {
            return;
        };
        // Accepted: only now does its stamp bound the poses after it.
        self.last_pose = Some((stamp, pose.position));
        if let Some(old) = self.pending.replace(pose) {
            self.emit(old); // overtaken: the nearest wrench and twist, or unpaired
        }
        self.try_complete();
    }

    /// A twist arrived when the receiver's ROS clock read `ros_now_ns`.
    pub fn on_twist(&mut self, msg: &TwistStamped, ros_now_ns: i64) {
        self.counts.twists += 1;
        let v = msg.twist.linear.to_array();
        if let Some(stamp) = self.check_vector(msg.header.stamp, self.twist.newest(), v, ros_now_ns)
        {
            self.twist.push(stamp, v);
            self.try_complete();
        }
    }

    /// A wrench arrived when the receiver's ROS clock read `ros_now_ns`.
    pub fn on_wrench(&mut self, msg: &WrenchStamped, ros_now_ns: i64) {
        self.counts.wrenches += 1;
        let f = msg.wrench.force.to_array();
        if let Some(stamp) =
            self.check_vector(msg.header.stamp, self.wrench.newest(), f, ros_now_ns)
        {
            self.wrench.push(stamp, f);
            self.try_complete();
        }
    }

    /// The next assembled sample, oldest first.
    pub fn take(&mut self) -> Option<StateSample> {
        if self.out.is_empty() {
            None
        } else {
            Some(self.out.remove(0))
        }
    }

    /// What it did.
    pub fn counts(&self) -> StateCounts {
        self.counts
    }

    /// The stamp `t` if it is well-formed, not from the future and newer than `newest` (the
    /// newest accepted of its stream); else counted.
    fn check_stamp(&mut self, t: Time, newest: Option<i64>, ros_now_ns: i64) -> Option<i64> {
        let c = &mut self.counts;
        let Some(stamp) = t.to_nanos() else {
            c.malformed_stamps += 1;
            return None;
        };
        match arrival(newest, stamp, ros_now_ns, self.config.max_ahead_ns) {
            Arrival::Newer => return Some(stamp),
            Arrival::FromFuture => c.from_future += 1,
            Arrival::Duplicate => c.duplicates += 1,
            Arrival::OutOfOrder => c.out_of_order += 1,
        }
        None
    }

    /// A twist's or wrench's stamp if it and the vector `v` pass; else counted.
    fn check_vector(
        &mut self,
        t: Time,
        newest: Option<i64>,
        v: Vec3,
        ros_now_ns: i64,
    ) -> Option<i64> {
        let stamp = self.check_stamp(t, newest, ros_now_ns)?;
        if !vec3::is_finite(v) {
            self.counts.non_finite += 1;
            return None;
        }
        Some(stamp)
    }

    /// The pose at `stamp` if its own values pass: finite, a rotation when a tool-frame wrench
    /// needs one, within speed of the last accepted pose; else counted.
    fn check_pose(
        &mut self,
        msg: &PoseStamped,
        stamp: i64,
        received_ns: i64,
    ) -> Option<PendingPose> {
        let position = msg.pose.position.to_array();
        let o = msg.pose.orientation;
        let orientation = [o.x, o.y, o.z, o.w];
        let finite = vec3::is_finite(position) && orientation.iter().all(|c| c.is_finite());
        // The orientation matters only to rotate a tool-frame wrench.
        let rotation = match self.config.wrench_frame {
            WrenchFrame::Tool if finite => rotation(orientation),
            _ => None,
        };
        let rotation_needed = self.config.wrench_frame == WrenchFrame::Tool;
        if !finite || (rotation_needed && rotation.is_none()) {
            self.counts.non_finite += 1;
            return None;
        }
        let max_speed = self.config.max_speed_m_per_s;
        if !within_speed(self.last_pose, stamp, position, max_speed) {
            self.counts.impossible_jumps += 1;
            return None;
        }
        Some(PendingPose {
            stamp,
            received_ns,
            position,
            orientation,
            rotation,
        })
    }

    fn try_complete(&mut self) {
        let Some(p) = self.pending else { return };
        let ready =
            self.wrench.reached(p.stamp) && (!self.config.twist || self.twist.reached(p.stamp));
        if ready {
            self.pending = None;
            self.emit(p);
        }
    }

    /// The pending pose `p` with the nearest wrench (and twist), or unpaired. Every value was
    /// checked on arrival.
    fn emit(&mut self, p: PendingPose) {
        let tol = self.config.pair_tolerance_ns;
        let force = self.wrench.nearest(p.stamp, tol);
        let twist = if self.config.twist {
            self.twist.nearest(p.stamp, tol).map(Some)
        } else {
            Some(None) // differentiated below
        };
        let (Some((force_at, force)), Some(twist)) = (force, twist) else {
            self.counts.unpaired += 1;
            return;
        };
        if force_at != p.stamp || twist.is_some_and(|(t, _)| t != p.stamp) {
            self.counts.inexact += 1;
        }
        let twist = twist.map(|(_, v)| v);
        let force = match self.config.wrench_frame {
            WrenchFrame::Base => force,
            WrenchFrame::Tool => p.rotation.map_or(force, |r| r.rotate(force)),
        };
        let force = match self.config.wrench_sign {
            WrenchSign::OnTool => force,
            WrenchSign::ByTool => vec3::scale(force, -1.0),
        };
        let velocity = match (twist, self.last) {
            (Some(v), _) => v,
            (None, Some((t, at))) => {
                vec3::scale(vec3::sub(p.position, at), 1e9 / (p.stamp - t) as f64)
            }
            (None, None) => [0.0; 3],
        };
        self.last = Some((p.stamp, p.position));
        self.counts.samples += 1;
        self.out.push(StateSample {
            stamp_ns: p.stamp,
            received_ns: p.received_ns,
            sample: RobotSample {
                position_m: p.position,
                velocity_m_per_s: velocity,
                force_on_tool_n: force,
            },
            orientation_xyzw: p.orientation,
        });
    }
}

/// Maps header stamps (the robot's clock) onto the receiver's monotonic clock: `stamp + offset`,
/// the offset being the smallest `received − stamp` seen over the last 1–2 s (the fastest
/// delivery, so a mapped time is never after its receipt; the window follows a slow drift of
/// either clock). On one host the offset is the clocks' difference plus the fastest latency; on
/// two it also absorbs their offset, so no clock synchronisation is needed for timing.
#[derive(Clone, Copy, Debug, Default)]
pub struct StampClock {
    current: Option<i64>,
    previous: Option<i64>,
    bucket_start_ns: i64,
    last_mapped: Option<i64>,
}

/// The offset window's bucket length \[ns\].
const BUCKET_NS: i64 = 1_000_000_000;

impl StampClock {
    /// Maps `stamp_ns`, received at `received_ns`. Mapped times strictly increase.
    pub fn map(&mut self, stamp_ns: i64, received_ns: i64) -> i64 {
        let offset = received_ns - stamp_ns;
        if self.current.is_none() || received_ns - self.bucket_start_ns > BUCKET_NS {
            self.previous = self.current;
            self.current = Some(offset);
            self.bucket_start_ns = received_ns;
        } else {
            self.current = self.current.map(|c| c.min(offset));
        }
        let best = match (self.current, self.previous) {
            (Some(c), Some(p)) => c.min(p),
            (Some(c), None) => c,
            (None, _) => offset,
        };
        let mapped = stamp_ns.saturating_add(best);
        let mapped = match self.last_mapped {
            Some(last) if mapped <= last => last + 1,
            _ => mapped,
        };
        self.last_mapped = Some(mapped);
        mapped
    }
}

#[cfg(test)]
mod tests;
