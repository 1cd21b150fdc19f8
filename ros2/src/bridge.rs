//! The ROS 2 robot bridge: `telerobot run --robot ros2`.
//!
//! ```text
//!  DDS ──pose/twist/wrench──▶ io thread: StateAssembler ─▶ StampClock ─▶ states (lock-free queue)
//!                                                                              │
//!  1 kHz loop: Ros2Bridge::step(now, target) ◀─────────────────────────────────┘
//!        │ target (latest-value slot) + wake
//!        ▼
//!  io thread ──target_pose──▶ DDS        ModelOutlet (loop) ──theta, in_contact──▶ io ──▶ DDS
//! ```
//!
//! The loop side ([`Ros2Bridge`], a `node::RobotBridge`) never blocks, allocates or logs: it
//! takes the states the I/O thread assembled, hands over the target, and wakes the I/O thread
//! (one `eventfd` write). Everything DDS — subscriptions, publishing, serialisation — is on the
//! `ros2-io` thread, woken by the middleware when a sample arrives and by the loop when a target
//! is ready.
//!
//! **Time.** Each state is timed by its header stamp, mapped onto the loop's clock
//! ([`crate::state::StampClock`]); the loop steps the node at that time, once per state, however
//! the states fall on its ticks ([`RobotBridge::step`] gives the oldest new one,
//! [`RobotBridge::next_reading`] the rest). The command a state was measured under is the last
//! target handed over before the state's time.
//!
//! **Safety.** Nothing is published before a state has arrived (the loop's command guard gives
//! no target, and this bridge would publish none without a state anyway). The commanded
//! orientation is the tool's orientation in the first state (the model is translational), so a
//! Cartesian controller is never asked to turn the tool. Stale states, limits: the command guard
//! (`node::guard`), applied by the loop around every bridge.

mod io;

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use node::{BridgeSample, Reading, RobotBridge, Target};
use protocol::telerobot_to_operator::Parameters;
use ros2_client::dds::rustdds::mio1::Waker;
use serde::Serialize;
use transport::Mailbox;

use crate::graph::{Graph, GraphError, Qos};
use crate::state::{StateConfig, StateCounts, StateSample};
use crate::topics::RobotTopics;

/// States queued between the I/O thread and the loop: 64 ms at 1 kHz.
const STATE_QUEUE: usize = 64;
/// Targets remembered to attribute states to the command they were measured under.
const TARGET_HISTORY: usize = 256;

/// Everything the bridge needs.
#[derive(Clone, Debug, PartialEq)]
pub struct BridgeConfig {
    /// The topics (defaults, remapped).
    pub topics: RobotTopics,
    /// State in: best-effort, keep-last-1 by default.
    pub state_qos: Qos,
    /// Commands out: best-effort, keep-last-1 by default.
    pub command_qos: Qos,
    /// Model and contact out: reliable, transient-local by default.
    pub settings_qos: Qos,
    /// How states are assembled and checked.
    pub state: StateConfig,
    /// `frame_id` of the commanded pose; `None`: the frame of the measured pose.
    pub command_frame: Option<String>,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        let topics = RobotTopics::default();
        BridgeConfig {
            state: StateConfig {
                twist: topics.robot_twist.is_some(),
                ..StateConfig::default()
            },
            topics,
            state_qos: Qos::STREAM,
            command_qos: Qos::STREAM,
            settings_qos: Qos::SETTINGS,
            command_frame: None,
        }
    }
}

/// A state as the loop receives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Timed {
    pub(crate) state: StateSample,
    /// The state's time on the loop's clock \[ns\].
    pub(crate) loop_ns: i64,
}

/// A target as the I/O thread publishes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct OutTarget {
    /// The tick it is for \[ns, loop clock\]: its header stamp (so that consecutive targets are
    /// exactly a tick apart in stamp time, whenever the I/O thread publishes them).
    pub(crate) tick_ns: i64,
    pub(crate) position_m: [f64; 3],
    pub(crate) velocity_m_per_s: [f64; 3],
    pub(crate) orientation_xyzw: [f64; 4],
}

/// What the loop and the I/O thread share.
pub(crate) struct Shared {
    pub(crate) states: Mailbox<Timed>,
    pub(crate) targets: Mailbox<OutTarget>,
    pub(crate) theta: Mailbox<Parameters>,
    pub(crate) contact: Mailbox<bool>,
    pub(crate) waker: Waker,
    pub(crate) stop: AtomicBool,
    pub(crate) latency: rt::Histogram,
    pub(crate) io: Mutex<IoReport>,
    pub(crate) superseded: AtomicU64,
}

/// What the I/O thread counted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct IoReport {
    /// The assembler's counts.
    pub state: StateCounts,
    /// The first and last state stamps \[ns, ROS time\].
    pub stamp_span_ns: Option<(i64, i64)>,
    /// Longest gap between consecutive state stamps \[ms\] (the robot's stream, losses included).
    pub longest_stamp_gap_ms: f64,
    /// Longest gap between the receipts of consecutive states \[ms\] (what the loop saw).
    pub longest_receipt_gap_ms: f64,
    /// Messages that did not deserialise (malformed CDR).
    pub undecodable: u64,
    /// Targets published.
    pub targets_published: u64,
    /// Model parameter messages published.
    pub theta_published: u64,
    /// Contact messages published.
    pub contact_published: u64,
    /// Publications the middleware refused.
    pub publish_errors: u64,
}

/// The bridge's report.
#[derive(Clone, Debug, Serialize)]
pub struct BridgeReport {
    /// The DDS domain.
    pub domain_id: u16,
    /// The topics, for the record.
    pub topics: String,
    /// Where the velocity came from.
    pub velocity_from: &'static str,
    /// States per second, from their stamps \[Hz\].
    pub effective_rate_hz: f64,
    /// State stamp → receipt by the I/O thread \[µs\]: the one-way latency when the robot and
    /// this host share a clock (one host; otherwise offset by the clocks' difference).
    pub latency: rt::Summary,
    /// States dropped because the loop had not taken the 64 before them (should be 0: the loop
    /// takes every state, every tick).
    pub superseded: u64,
    /// The I/O thread's counts.
    #[serde(flatten)]
    pub io: IoReport,
}

/// The ROS 2 robot bridge (loop side). Dropping it stops the I/O thread.
pub struct Ros2Bridge {
    shared: Arc<Shared>,
    io: Option<JoinHandle<()>>,
    newest: Option<StateSample>,
    /// The first state's orientation: what every target commands.
    orientation: Option<[f64; 4]>,
    /// `(handed over at, command sample time)` of the last targets, oldest first.
    history: [(i64, i64); TARGET_HISTORY],
    history_len: usize,
    history_next: usize,
    domain_id: u16,
    topics: String,
    twist: bool,
}

impl Ros2Bridge {
    /// Subscribes and advertises on `graph` and starts the I/O thread.
    pub fn start(graph: &Graph, config: BridgeConfig) -> Result<Ros2Bridge, GraphError> {
        let (shared, handle) = io::spawn(graph, &config)?;
        Ok(Ros2Bridge {
            shared,
            io: Some(handle),
            newest: None,
            orientation: None,
            history: [(i64::MIN, 0); TARGET_HISTORY],
            history_len: 0,
            history_next: 0,
            domain_id: graph.config().domain_id,
            topics: config.topics.describe(),
            twist: config.state.twist,
        })
    }

    /// What publishes the model and the contact state.
    pub fn outlet(&self) -> ModelOutlet {
        ModelOutlet {
            shared: Arc::clone(&self.shared),
            last_contact: None,
        }
    }

    /// A handle on the counters (readable from any thread, while the bridge runs).
    pub fn monitor(&self) -> BridgeMonitor {
        BridgeMonitor {
            shared: Arc::clone(&self.shared),
            domain_id: self.domain_id,
            topics: self.topics.clone(),
            twist: self.twist,
        }
    }

    fn reading(&mut self, t: Timed) -> BridgeSample {
        self.newest = Some(t.state);
        if self.orientation.is_none() {
            self.orientation = Some(t.state.orientation_xyzw);
        }
        BridgeSample {
            measured: t.state.sample,
            tool_m: t.state.sample.position_m,
            object_slide_m: [0.0; 2],
            reading: Reading::Stamped {
                sample_time_ns: t.loop_ns,
                command_sample_time_ns: self.command_at(t.loop_ns),
            },
        }
    }

    /// The command sample time of the last target handed over at or before `t`.
    fn command_at(&self, t: i64) -> i64 {
        (1..=self.history_len)
            .map(|k| self.history[(self.history_next + TARGET_HISTORY - k) % TARGET_HISTORY])
            .find(|(at, _)| *at <= t)
            .map_or(0, |(_, c)| c)
    }
}

impl RobotBridge for Ros2Bridge {
    fn tool_m(&self) -> Option<[f64; 3]> {
        self.newest.map(|s| s.sample.position_m)
    }

    fn step(&mut self, now_ns: i64, target: Option<&Target>) -> BridgeSample {
        if let (Some(t), Some(orientation)) = (target, self.orientation) {
            self.shared.targets.push(OutTarget {
                tick_ns: now_ns,
                position_m: t.position_m,
                velocity_m_per_s: t.velocity_m_per_s,
                orientation_xyzw: orientation,
            });
            let _ = self.shared.waker.wake();
            self.history[self.history_next] = (now_ns, t.command_sample_time_ns);
            self.history_next = (self.history_next + 1) % TARGET_HISTORY;
            self.history_len = (self.history_len + 1).min(TARGET_HISTORY);
        }
        match self.shared.states.take() {
            Some(t) => self.reading(t),
            None => BridgeSample {
                measured: self.newest.map(|s| s.sample).unwrap_or_default(),
                tool_m: self.newest.map_or([0.0; 3], |s| s.sample.position_m),
                object_slide_m: [0.0; 2],
                reading: if self.newest.is_some() {
                    Reading::Repeated
                } else {
                    Reading::Nothing
                },
            },
        }
    }

    /// The next state of this tick beyond the one `step` returned, oldest first: the loop steps
    /// the node once per state.
    fn next_reading(&mut self) -> Option<BridgeSample> {
        let t = self.shared.states.take()?;
        Some(self.reading(t))
    }
}

impl Drop for Ros2Bridge {
    fn drop(&mut self) {
        self.shared.stop.store(true, Relaxed);
        let _ = self.shared.waker.wake();
        if let Some(h) = self.io.take() {
            let _ = h.join();
        }
    }
}

/// Publishes the telerobot's model and contact state (`/mmt/theta`, `/mmt/in_contact`) from the
/// loop's datagrams: lock-free hand-over, published by the I/O thread. The contact state goes
/// out when it changes and with every parameter message (every 100 ms).
pub struct ModelOutlet {
    shared: Arc<Shared>,
    last_contact: Option<bool>,
}

impl ModelOutlet {
    /// New parameters (the node's `Parameters` datagram).
    pub fn parameters(&mut self, p: &Parameters) {
        self.shared.theta.push(*p);
        if let Some(c) = self.last_contact {
            self.shared.contact.push(c);
        }
        let _ = self.shared.waker.wake();
    }

    /// The contact state of this tick.
    pub fn contact(&mut self, in_contact: bool) {
        if self.last_contact != Some(in_contact) {
            self.last_contact = Some(in_contact);
            self.shared.contact.push(in_contact);
            let _ = self.shared.waker.wake();
        }
    }
}

/// Reads the bridge's counters from any thread.
#[derive(Clone)]
pub struct BridgeMonitor {
    shared: Arc<Shared>,
    domain_id: u16,
    topics: String,
    twist: bool,
}

impl BridgeMonitor {
    /// The report as of now.
    pub fn report(&self) -> BridgeReport {
        let io = *self
            .shared
            .io
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let effective_rate_hz = match io.stamp_span_ns {
            Some((first, last)) if last > first => {
                (io.state.samples.saturating_sub(1)) as f64 / ((last - first) as f64 * 1e-9)
            }
            _ => 0.0,
        };
        BridgeReport {
            domain_id: self.domain_id,
            topics: self.topics.clone(),
            velocity_from: if self.twist {
                "the twist topic"
            } else {
                "the pose, differentiated"
            },
            effective_rate_hz,
            latency: self.shared.latency.summary(),
            superseded: self.shared.superseded.load(Relaxed),
            io,
        }
    }
}
