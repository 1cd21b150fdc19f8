//! Device poses (and twists) → checked samples, one per accepted pose, timed by its header
//! stamp. Pure (no DDS, no clock): the I/O thread feeds it messages with their [`Receipt`]s.
//!
//! # Refusals (each counted in [`GateCounts`])
//! - a `frame_id` other than the expected one ([`ExpectedFrame`]);
//! - a stamp with `nanosec ≥ 1e9` (malformed);
//! - a stamp more than [`GateConfig::max_ahead_ns`] ahead of the receiver's ROS clock (from the
//!   future: another clock's);
//! - a stamp not newer than the newest *accepted* pose's (out of order, or a duplicate);
//! - a non-finite value anywhere in the pose;
//! - a position farther than [`GateConfig::max_radius_m`] from the frame's origin;
//! - an impossible jump: faster than [`GateConfig::max_speed_m_per_s`] from the last accepted
//!   pose.
//!
//! A refused pose changes nothing but the counts: only an accepted pose's stamp becomes the one
//! later poses must be newer than. (A refused pose that moved it would make every good pose
//! after it "out of order" until the driver's clock caught up: one garbage message from a
//! second publisher, a bag replay or a clock step would stop the poses for good.)
//!
//! # Velocity
//! With a twist topic, the linear velocity of the accepted twist nearest the pose's stamp
//! (within [`GateConfig::twist_tolerance_ns`]); without one (or with none that near, counted),
//! the difference of the positions over about [`GateConfig::velocity_window_ns`] of stamps: the
//! oldest accepted pose within the window, or the previous one when the driver is slower.

use mmt::vec3::{self, Vec3};
use serde::Serialize;

use super::HapticError;
use crate::msg::{PoseStamped, TwistStamped};
use crate::state::{Arrival, MAX_AHEAD_NS, Receipt, arrival, within_speed};

/// How poses are checked.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct GateConfig {
    /// Faster than this between two poses is an impossible jump \[m/s\]. Default 5 m/s: a hand
    /// does not cross the omega.7's 0.16 m workspace in 32 ms; a 5 mm step between two 1 ms
    /// samples is a glitch.
    pub max_speed_m_per_s: f64,
    /// Farther than this from the frame's origin is not a desk device's position \[m\].
    /// Default 1 m (the omega.7's workspace is a sphere of 0.075 m around `fd_base`'s origin).
    pub max_radius_m: f64,
    /// The window the velocity is differentiated over \[ns\]. Default 10 ms: a 0.01 mm position
    /// step reads as 1 mm/s instead of 10 mm/s from consecutive 1 ms samples, for 5 ms of lag.
    pub velocity_window_ns: i64,
    /// How far a twist's stamp may be from the pose's \[ns\]. Default 2 ms: two ticks at 1 kHz.
    pub twist_tolerance_ns: i64,
    /// A pose or twist stamped more than this ahead of the receiver's ROS clock at receipt is
    /// refused \[ns\]. Default [`MAX_AHEAD_NS`] (1 s; why, there), as for the robot's state.
    pub max_ahead_ns: i64,
}

impl Default for GateConfig {
    fn default() -> Self {
        GateConfig {
            max_speed_m_per_s: 5.0,
            max_radius_m: 1.0,
            velocity_window_ns: 10_000_000,
            twist_tolerance_ns: 2_000_000,
            max_ahead_ns: MAX_AHEAD_NS,
        }
    }
}

/// The frame poses must be in (their `header.frame_id`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub enum ExpectedFrame {
    /// Any frame (`--ros-pose-frame any`): the frame is not checked.
    Any,
    /// This frame only. Default `fd_base`, forcedimension_ros2's: the frame the forces are
    /// written in. A pose re-published in another frame (the launch file's `world` is a half
    /// turn about z from `fd_base`) would turn the forces the wrong way.
    Named(String),
}

impl Default for ExpectedFrame {
    fn default() -> Self {
        ExpectedFrame::Named("fd_base".to_owned())
    }
}

impl ExpectedFrame {
    /// `any`, or a frame name (no whitespace).
    pub fn parse(text: &str) -> Result<ExpectedFrame, HapticError> {
        match text {
            "any" => Ok(ExpectedFrame::Any),
            _ if text.is_empty() || text.chars().any(char::is_whitespace) => {
                Err(HapticError::PoseFrame(text.to_owned()))
            }
            _ => Ok(ExpectedFrame::Named(text.to_owned())),
        }
    }

    /// Whether a pose in `frame_id` is accepted.
    pub fn accepts(&self, frame_id: &str) -> bool {
        match self {
            ExpectedFrame::Any => true,
            ExpectedFrame::Named(name) => name == frame_id,
        }
    }
}

impl std::fmt::Display for ExpectedFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ExpectedFrame::Any => f.write_str("any (NOT checked)"),
            ExpectedFrame::Named(name) => f.write_str(name),
        }
    }
}

/// One accepted device sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DeviceSample {
    /// The pose's header stamp \[ns, ROS time\].
    pub stamp_ns: i64,
    /// When the pose arrived \[ns, the receiver's monotonic clock\].
    pub received_ns: i64,
    /// Position \[m\], the pose's frame.
    pub position_m: Vec3,
    /// Velocity \[m/s\], the pose's frame.
    pub velocity_m_per_s: Vec3,
}

/// What the gate did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct GateCounts {
    /// Poses received.
    pub poses: u64,
    /// Poses accepted (samples made).
    pub accepted: u64,
    /// Poses in another frame than the expected one.
    pub wrong_frame: u64,
    /// Poses or twists whose stamp had `nanosec ≥ 1e9`.
    pub malformed_stamps: u64,
    /// Poses stamped more than [`GateConfig::max_ahead_ns`] ahead of the receiver's clock.
    pub from_future: u64,
    /// Poses older than the newest accepted pose.
    pub out_of_order: u64,
    /// Poses with the newest accepted pose's stamp.
    pub duplicates: u64,
    /// Poses with a non-finite value.
    pub non_finite: u64,
    /// Poses farther than the plausible radius.
    pub out_of_range: u64,
    /// Poses beyond the plausible speed from the last accepted one.
    pub impossible_jumps: u64,
    /// Twists received.
    pub twists: u64,
    /// Twists refused (malformed, future or not newer stamp, non-finite).
    pub twists_refused: u64,
    /// Accepted poses with no twist within the tolerance (velocity differentiated instead).
    pub without_twist: u64,
}

/// Accepted poses remembered for the velocity: 64 ms at 1 kHz.
const HISTORY: usize = 64;

/// The gate. See the module docs.
#[derive(Clone, Debug)]
pub struct PoseGate {
    config: GateConfig,
    frame: ExpectedFrame,
    /// The first refused frame, for the report.
    other_frame: Option<String>,
    twist: bool,
    newest_twist: Option<i64>,
    /// The last two accepted twists, newest first: (stamp, linear velocity).
    twists: [Option<(i64, Vec3)>; 2],
    /// Accepted poses, a ring: (stamp, position).
    history: [(i64, Vec3); HISTORY],
    len: usize,
    next: usize,
    counts: GateCounts,
}

impl PoseGate {
    /// A gate for `config`, poses in `frame`; `twist`: a twist topic gives the velocity.
    pub fn new(config: GateConfig, frame: ExpectedFrame, twist: bool) -> PoseGate {
        PoseGate {
            config,
            frame,
            other_frame: None,
            twist,
            newest_twist: None,
            twists: [None; 2],
            history: [(0, vec3::ZERO); HISTORY],
            len: 0,
            next: 0,
            counts: GateCounts::default(),
        }
    }

    /// A pose arrived: the sample it makes, or `None` (refused, counted).
    pub fn on_pose(&mut self, msg: &PoseStamped, at: Receipt) -> Option<DeviceSample> {
        self.counts.poses += 1;
        if !self.frame.accepts(&msg.header.frame_id) {
            self.counts.wrong_frame += 1;
            if self.other_frame.is_none() {
                self.other_frame = Some(msg.header.frame_id.clone());
            }
            return None;
        }
        let stamp = self.stamp(msg, at.ros_ns)?;
        let position = msg.pose.position.to_array();
        let o = msg.pose.orientation;
        let c = &mut self.counts;
        if !(vec3::is_finite(position) && [o.x, o.y, o.z, o.w].iter().all(|v| v.is_finite())) {
            c.non_finite += 1;
            return None;
        }
        if !(vec3::norm(position) <= self.config.max_radius_m) {
            c.out_of_range += 1;
            return None;
        }
        if !within_speed(self.last(), stamp, position, self.config.max_speed_m_per_s) {
            self.counts.impossible_jumps += 1;
            return None;
        }
        let velocity = self.velocity(stamp, position);
        self.history[self.next] = (stamp, position);
        self.next = (self.next + 1) % HISTORY;
        self.len = (self.len + 1).min(HISTORY);
        self.counts.accepted += 1;
        Some(DeviceSample {
            stamp_ns: stamp,
            received_ns: at.monotonic_ns,
            position_m: position,
            velocity_m_per_s: velocity,
        })
    }

    /// A twist arrived when the receiver's ROS clock read `ros_now_ns`.
    pub fn on_twist(&mut self, msg: &TwistStamped, ros_now_ns: i64) {
        self.counts.twists += 1;
        let Some(stamp) = msg.header.stamp.to_nanos() else {
            self.counts.malformed_stamps += 1;
            self.counts.twists_refused += 1;
            return;
        };
        let v = msg.twist.linear.to_array();
        let max_ahead = self.config.max_ahead_ns;
        if arrival(self.newest_twist, stamp, ros_now_ns, max_ahead) != Arrival::Newer
            || !vec3::is_finite(v)
        {
            self.counts.twists_refused += 1;
            return;
        }
        self.newest_twist = Some(stamp);
        self.twists = [Some((stamp, v)), self.twists[0]];
    }

    /// What it did.
    pub fn counts(&self) -> GateCounts {
        self.counts
    }

    /// The first frame a pose was refused for, if any.
    pub fn other_frame(&self) -> Option<&str> {
        self.other_frame.as_deref()
    }

    /// The pose's stamp if it is well-formed, not from the future and newer than the newest
    /// accepted pose's. (It becomes the newest only once the pose is accepted.)
    fn stamp(&mut self, msg: &PoseStamped, ros_now_ns: i64) -> Option<i64> {
        let Some(stamp) = msg.header.stamp.to_nanos() else {
            self.counts.malformed_stamps += 1;
            return None;
        };
        // The newest accepted pose is the history's newest: a stamp counts once its pose does.
        match arrival(
            self.last().map(|(t, _)| t),
            stamp,
            ros_now_ns,
            self.config.max_ahead_ns,
        ) {
            Arrival::FromFuture => self.counts.from_future += 1,
            Arrival::Duplicate => self.counts.duplicates += 1,
            Arrival::OutOfOrder => self.counts.out_of_order += 1,
            Arrival::Newer => return Some(stamp),
        }
        None
    }

    /// The `k`-th newest accepted pose (0: the newest).
    fn recent(&self, k: usize) -> Option<(i64, Vec3)> {
        (k < self.len).then(|| self.history[(self.next + HISTORY - 1 - k) % HISTORY])
    }

    fn last(&self) -> Option<(i64, Vec3)> {
        self.recent(0)
    }

    fn velocity(&mut self, stamp: i64, position: Vec3) -> Vec3 {
        if self.twist {
            let tolerance = self.config.twist_tolerance_ns;
            let nearest = self
                .twists
                .into_iter()
                .flatten()
                .min_by_key(|(t, _)| (t - stamp).abs())
                .filter(|(t, _)| (t - stamp).abs() <= tolerance);
            match nearest {
                Some((_, v)) => return v,
                None => self.counts.without_twist += 1,
            }
        }
        // The oldest pose within the window; the newest one if even that is older.
        let window_start = stamp - self.config.velocity_window_ns;
        let mut base = self.recent(0);
        for k in 1..self.len {
            match self.recent(k) {
                Some(r) if r.0 >= window_start => base = Some(r),
                _ => break,
            }
        }
        match base {
            Some((t, at)) => vec3::scale(vec3::sub(position, at), 1e9 / (stamp - t) as f64),
            None => vec3::ZERO,
        }
    }
}
