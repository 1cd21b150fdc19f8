//! The operator's haptic device on a ROS 2 graph (`operator run --device ros2`): the device's
//! pose (and twist, if its driver publishes one) in, the force command out, with every DDS call
//! on an I/O thread of its own.
//!
//! ```text
//!  DDS ──pose/twist/button──▶ io thread: PoseGate ─▶ newest sample (latest-value slot) ─▶ loop
//!  loop: force (latest-value slot) + wake ─▶ io thread: pose fresh? forces on? ─▶ command ─▶ DDS
//! ```
//!
//! The loop side ([`RosHaptic`]) never blocks, locks, allocates or logs: it takes the newest
//! checked sample and hands over the newest force.
//!
//! # The defaults: forcedimension_ros2
//!
//! The ICube driver for Force Dimension devices (github.com/ICube-Robotics/forcedimension_ros2,
//! main at 5b6b976, 2025-07-21) is a `ros2_control` system; its launch file
//! `fd_bringup/launch/fd.launch.py` starts the controller manager in the namespace `fd`
//! (hard-coded, not a launch argument) with the controllers of
//! `fd_description/config/fd_controllers.yaml`:
//! - `fd_ee_broadcaster` (`fd_controllers/ee_pose_broadcaster/src/ee_pose_broadcaster.cpp`)
//!   publishes `ee_pose` → **`/fd/ee_pose`**, `geometry_msgs/PoseStamped`, `frame_id`
//!   `fd_base`, stamped with the node's clock at publication, every update (1 kHz,
//!   `update_rate`), and `button_state` → **`/fd/button_state`**, `std_msgs/Bool` (button 0,
//!   `dhdGetButton(0)` in `fd_hardware/src/fd_effort_hi.cpp`), both with `SystemDefaultsQoS`
//!   (reliable, volatile, keep-last-10). No twist is published: the velocity is differentiated
//!   here.
//! - `fd_controller`, an `effort_controllers/JointGroupEffortController`, takes
//!   `~/commands` → **`/fd/fd_controller/commands`**, `std_msgs/Float64MultiArray`, one entry
//!   per joint of its `joints` list, subscribed with `SystemDefaultsQoS` (ros2_controllers,
//!   `forward_command_controller/src/forward_controllers_base.cpp`). A message of another length
//!   is dropped; the last command is held until the next one, **with no timeout**.
//! - Units and frame: `fd_hardware/src/fd_effort_hi.cpp` reads `dhdGetPosition` \[m\] and
//!   writes the commands with `dhdSetForceAndTorqueAndGripperForce` \[N, N·m\] in the SDK's own
//!   frame, which `fd_base` is while `fd_ee_broadcaster`'s `transform_translation` and
//!   `transform_rotation` stay zero (the defaults): the frame `--device omega` reads and writes
//!   too. The driver caps forces at 12 N (`dhdSetMaxForce`); any NaN command entry makes it
//!   write zero force.
//!
//! # Conventions (the one place they are stated)
//!
//! - **Frame and units**: positions \[m\], velocities \[m/s\] and forces \[N\] in the pose's
//!   frame, which must be [`HapticConfig::pose_frame`] (`fd_base`: the frame the driver writes
//!   forces in); the orientation is not used (the model is translational).
//! - **Command layout** ([`command_message`]): `layout` empty (no dimensions, `data_offset` 0),
//!   `data = [fx, fy, fz]`, then zeros up to [`CommandLen`] — the controller's joints in order:
//!   `fd_x, fd_y, fd_z` (3, the default), `+ fd_clutch` (4, gripper force 0), `+ fd_roll,
//!   fd_pitch, fd_yaw` (6, torques 0), all of them (7).
//! - **Button**: `true` = pressed = the clutch held (the tool holds while the hand moves), as
//!   the handle button of `--device omega`.
//!
//! # Safety (the I/O thread, whatever the loop hands over)
//!
//! - Nothing is published before a valid pose has arrived (the loop's commands are dropped and
//!   counted).
//! - A pose older than [`HapticConfig::stale_after`] (50 ms, the telerobot's stale-state rule):
//!   zero force is published instead of the loop's; episodes and ticks counted, logged once per
//!   episode. (The operator's device faults on it as well.)
//! - The loop's commands stopping for [`HapticConfig::command_watchdog`] (20 ms, the Omega
//!   SDK watchdog `--device omega` sets, which the driver does not) after a non-zero force:
//!   zero is published, counted and logged — the controller would hold the force forever.
//! - Forces switched off, and the I/O thread stopping ([`RosHaptic::close`], or the drop: a
//!   last zero, then 100 ms for the reliable writer to deliver it): zero.
//! - Poses are checked by [`gate::PoseGate`] (frame, stamp, finiteness, range, speed), every
//!   refusal counted in [`HapticReport`].

pub mod gate;
mod io;

use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use mmt::vec3::Vec3;
use ros2_client::dds::rustdds::mio1::Waker;
use serde::Serialize;
use transport::Mailbox;

use crate::graph::{Graph, GraphError, Qos, TopicName};
use crate::msg::{Float64MultiArray, MultiArrayLayout};
use crate::topics::{split_rule, unknown_key};

pub use crate::state::Receipt;
pub use gate::{DeviceSample, ExpectedFrame, GateConfig, GateCounts, PoseGate};

/// The device's topics.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HapticTopics {
    /// The device's pose (`geometry_msgs/PoseStamped`).
    pub pose: TopicName,
    /// Its twist (`geometry_msgs/TwistStamped`); `None`: velocity differentiated from the pose.
    pub twist: Option<TopicName>,
    /// The clutch button (`std_msgs/Bool`); `None`: no clutch.
    pub button: Option<TopicName>,
    /// The force command (`std_msgs/Float64MultiArray`); `None`: no force is written (the
    /// device is position input only).
    pub command: Option<TopicName>,
}

impl Default for HapticTopics {
    /// forcedimension_ros2's names (see the module docs).
    fn default() -> Self {
        let t = |what, name| TopicName::parse(what, name).unwrap_or_else(|e| panic!("{e}"));
        HapticTopics {
            pose: t("pose", "/fd/ee_pose"),
            twist: None,
            button: Some(t("button", "/fd/button_state")),
            command: Some(t("command", "/fd/fd_controller/commands")),
        }
    }
}

/// The keys [`HapticTopics::remap`] knows.
pub const HAPTIC_KEYS: &str = "pose, twist, button, command";

impl HapticTopics {
    /// Applies one `KEY=/name` remapping; `twist`, `button` and `command` take `none`.
    pub fn remap(&mut self, rule: &str) -> Result<(), GraphError> {
        let (key, name) = split_rule(rule, HAPTIC_KEYS)?;
        let slot = match key {
            "pose" => {
                self.pose = TopicName::parse(key, name)?;
                return Ok(());
            }
            "twist" => &mut self.twist,
            "button" => &mut self.button,
            "command" => &mut self.command,
            _ => return Err(unknown_key(key, HAPTIC_KEYS)),
        };
        *slot = match name {
            "none" => None,
            _ => Some(TopicName::parse(key, name)?),
        };
        Ok(())
    }

    /// Every topic, `key = name`, and the poses' frame, for the start message.
    pub fn describe(&self, command_len: CommandLen, frame: &ExpectedFrame) -> String {
        let or = |t: &Option<TopicName>, none: &str| {
            t.as_ref().map_or(none.to_owned(), ToString::to_string)
        };
        format!(
            "pose = {} (frame {frame}), twist = {}, button = {}, command = {}",
            self.pose,
            or(
                &self.twist,
                "none (velocity differentiated from the pose over 10 ms)"
            ),
            or(&self.button, "none (no clutch)"),
            self.command
                .as_ref()
                .map_or("none (NO force is written)".to_owned(), |t| format!(
                    "{t} ({})",
                    command_len.layout()
                )),
        )
    }
}

/// Entries of the force command: the joints of the driver's force controller, 3 to 7
/// (forcedimension_ros2's `fd_controller` lists `fd_x, fd_y, fd_z`, then optionally the
/// orientation joints and the clutch; see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CommandLen(usize);

impl CommandLen {
    /// `[fx, fy, fz]`: forcedimension_ros2's default `fd_controller`.
    pub const FORCES: CommandLen = CommandLen(3);

    /// `n` entries, 3 to 7.
    pub fn new(n: usize) -> Result<CommandLen, HapticError> {
        if (3..=7).contains(&n) {
            Ok(CommandLen(n))
        } else {
            Err(HapticError::CommandLen(n))
        }
    }

    /// The number of entries.
    pub fn get(self) -> usize {
        self.0
    }

    /// The layout in words, e.g. `[fx, fy, fz, 0, 0, 0, 0] N`.
    pub fn layout(self) -> String {
        let mut s = "std_msgs/Float64MultiArray [fx, fy, fz".to_owned();
        for _ in 3..self.0 {
            s.push_str(", 0");
        }
        s.push_str("] N, fd_base");
        s
    }
}

/// The force command for `force_n` \[N\]: see the module docs for the layout.
pub fn command_message(force_n: Vec3, len: CommandLen) -> Float64MultiArray {
    let mut data = vec![0.0; len.get()];
    data[..3].copy_from_slice(&force_n);
    Float64MultiArray {
        layout: MultiArrayLayout::default(),
        data,
    }
}

/// Everything the device needs.
#[derive(Clone, Debug, PartialEq)]
pub struct HapticConfig {
    /// The topics (defaults, remapped).
    pub topics: HapticTopics,
    /// Pose, twist and button in: best-effort, keep-last-1 by default (the newest or nothing;
    /// it matches the driver's reliable writers).
    pub state_qos: Qos,
    /// The command out: reliable, volatile, keep-last-1 by default. Reliable because the
    /// controller subscribes reliably (`SystemDefaultsQoS`), and DDS matches no best-effort
    /// writer to a reliable reader.
    pub command_qos: Qos,
    /// Entries of the command.
    pub command_len: CommandLen,
    /// How poses are checked.
    pub gate: GateConfig,
    /// The frame poses must be in (`fd_base` by default; see [`ExpectedFrame`]).
    pub pose_frame: ExpectedFrame,
    /// With no valid pose for this long, zero force is published. Default 50 ms: the
    /// telerobot's stale-state rule (`node::guard`).
    pub stale_after: Duration,
    /// With no force from the loop for this long after a non-zero one, zero is published.
    /// Default 20 ms: the hardware watchdog `--device omega` sets (`OmegaConfig::watchdog`).
    pub command_watchdog: Duration,
}

impl Default for HapticConfig {
    fn default() -> Self {
        HapticConfig {
            topics: HapticTopics::default(),
            state_qos: Qos::STREAM,
            command_qos: Qos {
                reliable: true,
                transient_local: false,
                depth: 1,
            },
            command_len: CommandLen::FORCES,
            gate: GateConfig::default(),
            pose_frame: ExpectedFrame::default(),
            stale_after: Duration::from_millis(50),
            command_watchdog: Duration::from_millis(20),
        }
    }
}

/// Why the device cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum HapticError {
    /// The graph, a name or a QoS.
    #[error(transparent)]
    Graph(#[from] GraphError),
    /// A command length the driver's controllers do not have.
    #[error(
        "--ros-command-len {0}: expected 3 to 7, the number of joints of the force controller \
         (forcedimension_ros2's fd_controller: 3 = fd_x, fd_y, fd_z; 4 with fd_clutch; 6 with \
         fd_roll, fd_pitch, fd_yaw; 7 with both)"
    )]
    CommandLen(usize),
    /// A pose frame that cannot be a `frame_id`.
    #[error(
        "--ros-pose-frame {0:?}: expected the poses' frame_id (forcedimension_ros2's: fd_base), \
         or `any` to accept every frame"
    )]
    PoseFrame(String),
    /// No valid pose within the wait.
    #[error(
        "no valid pose on {topic} (geometry_msgs/msg/PoseStamped, ROS domain {domain}) within \
         {waited:?}: {seen}. Is the driver running (ros2 launch fd_bringup fd.launch.py), on \
         this domain (--ros-domain, ROS_DOMAIN_ID), and is the topic right (ros2 topic list; \
         --topic pose=/name)?"
    )]
    NoPose {
        /// The pose topic.
        topic: String,
        /// The domain.
        domain: u16,
        /// How long it waited.
        waited: Duration,
        /// What arrived instead.
        seen: String,
    },
}

/// The commands the I/O thread published, and what it refused to publish.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CommandCounts {
    /// Commands published.
    pub published: u64,
    /// Of them, zero force.
    pub zero: u64,
    /// The loop's commands dropped because no valid pose had arrived yet.
    pub before_pose: u64,
    /// The loop's non-zero commands replaced by zero: the pose was stale.
    pub stale_zeroed: u64,
    /// Times the pose went stale while a force was commanded.
    pub stale_episodes: u64,
    /// Zeros published because the loop's commands stopped after a non-zero force.
    pub watchdog_zeroed: u64,
    /// Publications the middleware refused.
    pub publish_errors: u64,
}

/// What the I/O thread counted.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct IoReport {
    /// The pose checks.
    pub gate: GateCounts,
    /// The pose's `frame_id` (the first accepted pose's).
    pub frame_id: String,
    /// The first frame a pose was refused for (`wrong_frame`), if any.
    pub other_frame: Option<String>,
    /// The first and last accepted stamps \[ns, ROS time\].
    pub stamp_span_ns: Option<(i64, i64)>,
    /// Longest gap between consecutive accepted stamps \[ms\].
    pub longest_stamp_gap_ms: f64,
    /// Messages that did not deserialise (malformed CDR).
    pub undecodable: u64,
    /// Button messages received.
    pub buttons: u64,
    /// The force commands.
    pub commands: CommandCounts,
}

/// The device's report.
#[derive(Clone, Debug, Serialize)]
pub struct HapticReport {
    /// The DDS domain.
    pub domain_id: u16,
    /// The topics, for the record.
    pub topics: String,
    /// Where the velocity came from.
    pub velocity_from: &'static str,
    /// Whether forces are written at all (`command` not `none`).
    pub writes_force: bool,
    /// Accepted poses per second, from their stamps \[Hz\].
    pub effective_rate_hz: f64,
    /// Pose stamp → receipt by the I/O thread \[µs\] (the one-way latency when the driver and
    /// this host share a clock).
    pub latency: rt::Summary,
    /// Accepted samples the loop did not take before a newer one (normal when the driver
    /// publishes faster than the loop runs; not a refusal).
    pub samples_not_taken: u64,
    /// The I/O thread's counts.
    #[serde(flatten)]
    pub io: IoReport,
}

/// What the loop and the I/O thread share.
pub(crate) struct Shared {
    pub(crate) samples: Mailbox<DeviceSample>,
    pub(crate) forces: Mailbox<Vec3>,
    pub(crate) forces_on: AtomicBool,
    pub(crate) button: AtomicBool,
    /// A valid pose has arrived.
    pub(crate) posed: AtomicBool,
    pub(crate) waker: Waker,
    pub(crate) stop: AtomicBool,
    pub(crate) latency: rt::Histogram,
    pub(crate) io: Mutex<IoReport>,
}

/// The device on the graph (loop side). Closing or dropping it publishes zero force and stops
/// the I/O thread.
pub struct RosHaptic {
    shared: Arc<Shared>,
    io: Option<JoinHandle<()>>,
    domain_id: u16,
    pose_topic: String,
    topics: String,
    twist: bool,
    writes_force: bool,
}

impl RosHaptic {
    /// Subscribes and advertises on `graph` and starts the I/O thread. Forces start off.
    pub fn start(graph: &Graph, config: HapticConfig) -> Result<RosHaptic, HapticError> {
        let (shared, handle) = io::spawn(graph, &config)?;
        Ok(RosHaptic {
            shared,
            io: Some(handle),
            domain_id: graph.config().domain_id,
            pose_topic: config.topics.pose.to_string(),
            topics: config
                .topics
                .describe(config.command_len, &config.pose_frame),
            twist: config.topics.twist.is_some(),
            writes_force: config.topics.command.is_some(),
        })
    }

    /// Waits (blocking; not for the loop) until a valid pose has arrived, at most `timeout`.
    pub fn wait_for_pose(&self, timeout: Duration) -> Result<(), HapticError> {
        let start = Instant::now();
        while !self.shared.posed.load(Relaxed) {
            if start.elapsed() > timeout {
                let seen = seen(&self.report().io);
                return Err(HapticError::NoPose {
                    topic: self.pose_topic.clone(),
                    domain: self.domain_id,
                    waited: timeout,
                    seen,
                });
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        Ok(())
    }

    /// The newest checked sample not taken yet (lock-free).
    pub fn take_sample(&self) -> Option<DeviceSample> {
        self.shared.samples.take()
    }

    /// The button, as last received (`false` before any, or without a button topic).
    pub fn button(&self) -> bool {
        self.shared.button.load(Relaxed)
    }

    /// Hands over the force to write \[N\] (lock-free; the I/O thread publishes the newest, a
    /// non-finite one as zero).
    pub fn command(&self, force_n: Vec3) {
        self.shared.forces.push(force_n);
        let _ = self.shared.waker.wake();
    }

    /// Switches forces on or off; off publishes zero at once.
    pub fn set_forces(&self, on: bool) {
        self.shared.forces_on.store(on, Relaxed);
        if !on {
            self.command([0.0; 3]);
        }
    }

    /// The pose topic.
    pub fn pose_topic(&self) -> &str {
        &self.pose_topic
    }

    /// Whether forces are written at all.
    pub fn writes_force(&self) -> bool {
        self.writes_force
    }

    /// Every topic, for the start message.
    pub fn describe(&self) -> String {
        format!("domain {}: {}", self.domain_id, self.topics)
    }

    /// Publishes zero and stops the I/O thread (blocking, about 100 ms: not for the loop):
    /// from here the counts are final, [`RosHaptic::report`] gives every command published, the
    /// closing zero included, and nothing more is published (a pose already taken in may still
    /// be read until it is stale). Dropping closes it too.
    pub fn close(&mut self) {
        self.shared.forces_on.store(false, Relaxed);
        self.shared.stop.store(true, Relaxed);
        let _ = self.shared.waker.wake();
        if let Some(h) = self.io.take() {
            let _ = h.join();
        }
    }

    /// The report: as of at most 20 ms ago while the device runs, final once it is closed
    /// (locks: not for the loop).
    pub fn report(&self) -> HapticReport {
        let io = self
            .shared
            .io
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone();
        let effective_rate_hz = match io.stamp_span_ns {
            Some((first, last)) if last > first => {
                io.gate.accepted.saturating_sub(1) as f64 / ((last - first) as f64 * 1e-9)
            }
            _ => 0.0,
        };
        HapticReport {
            domain_id: self.domain_id,
            topics: self.topics.clone(),
            velocity_from: if self.twist {
                "the twist topic (the pose, differentiated, without a twist within 2 ms)"
            } else {
                "the pose, differentiated over 10 ms"
            },
            writes_force: self.writes_force,
            effective_rate_hz,
            latency: self.shared.latency.summary(),
            samples_not_taken: self.shared.samples.overwritten(),
            io,
        }
    }
}

impl Drop for RosHaptic {
    fn drop(&mut self) {
        self.close();
    }
}

/// What arrived on the pose topic, for [`HapticError::NoPose`].
fn seen(io: &IoReport) -> String {
    let g = &io.gate;
    if g.poses == 0 && io.undecodable == 0 {
        return "no message arrived".to_owned();
    }
    let frame = match &io.other_frame {
        Some(f) => format!(" (the first: {f:?}; --ros-pose-frame)"),
        None => String::new(),
    };
    format!(
        "{} poses arrived, none valid (in another frame {}{frame}, malformed stamps {}, stamped \
         ahead of this host's clock {}, out of order {}, duplicates {}, non-finite {}, \
         out of range {}, impossible jumps {}); {} messages did not decode",
        g.poses,
        g.wrong_frame,
        g.malformed_stamps,
        g.from_future,
        g.out_of_order,
        g.duplicates,
        g.non_finite,
        g.out_of_range,
        g.impossible_jumps,
        io.undecodable
    )
}

#[cfg(test)]
mod tests;
