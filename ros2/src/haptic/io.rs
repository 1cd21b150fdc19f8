//! The device's I/O thread: every DDS call of the haptic device happens here, and the rules
//! that keep a force off the hand (module docs of [`super`]).

use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use mmt::vec3::{self, Vec3};
use ros2_client::dds::rustdds::mio1::{Events, Poll, Token, Waker};
use ros2_client::{Node, Publisher, Subscription};
use transport::Mailbox;

use super::{CommandLen, HapticConfig, HapticError, IoReport, Shared, command_message};
use crate::graph::{self, Graph, io_error, register, ros_now_ns};
use crate::haptic::gate::{DeviceSample, PoseGate};
use crate::msg::{Bool, Float64MultiArray, PoseStamped, TwistStamped};
use crate::state::Receipt;

const POSE: Token = Token(1);
const TWIST: Token = Token(2);
const BUTTON: Token = Token(3);
const WAKE: Token = Token(9);

/// Longest sleep: the watchdog and the stale rule are checked at least this often.
const PASS: Duration = Duration::from_millis(5);
/// How often the counters are shared.
const SHARE: i64 = 20_000_000;
/// How long the thread keeps its writer after the last zero, for the reliable protocol to
/// deliver it.
const LINGER: Duration = Duration::from_millis(100);

struct Io {
    _node: Node,
    poll: Poll,
    pose: Subscription<PoseStamped>,
    pose_topic: String,
    twist: Option<Subscription<TwistStamped>>,
    button: Option<Subscription<Bool>>,
    command: Option<Publisher<Float64MultiArray>>,
    command_len: CommandLen,
    shared: Arc<Shared>,
    gate: PoseGate,
    report: IoReport,
    stale_after_ns: i64,
    watchdog_ns: i64,
    /// Receipt of the newest accepted pose \[ns, monotonic\].
    last_pose_ns: Option<i64>,
    /// When the loop last handed over a force \[ns, monotonic\].
    last_command_ns: i64,
    /// The last force published was not zero.
    holding_force: bool,
    /// The pose is stale while a force is commanded (one log per episode).
    stale: bool,
}

/// Creates the endpoints and starts the thread.
pub(super) fn spawn(
    graph: &Graph,
    config: &HapticConfig,
) -> Result<(Arc<Shared>, JoinHandle<()>), HapticError> {
    let t = &config.topics;
    let qos = config.state_qos;
    let mut node = graph.node("mmt_operator_device")?;
    let mut pose = graph::subscribe::<PoseStamped>(&mut node, &t.pose, qos)?;
    let mut twist = match &t.twist {
        Some(name) => Some(graph::subscribe::<TwistStamped>(&mut node, name, qos)?),
        None => None,
    };
    let mut button = match &t.button {
        Some(name) => Some(graph::subscribe::<Bool>(&mut node, name, qos)?),
        None => None,
    };
    let command = match &t.command {
        Some(name) => Some(graph::advertise::<Float64MultiArray>(
            &mut node,
            name,
            config.command_qos,
        )?),
        None => None,
    };
    let poll = Poll::new().map_err(io_error("poll"))?;
    register(&poll, Some(&mut pose), POSE, "pose subscription")?;
    register(&poll, twist.as_mut(), TWIST, "twist subscription")?;
    register(&poll, button.as_mut(), BUTTON, "button subscription")?;
    let waker = Waker::new(poll.registry(), WAKE).map_err(io_error("waker"))?;
    let shared = Arc::new(Shared {
        samples: Mailbox::latest(),
        forces: Mailbox::latest(),
        forces_on: AtomicBool::new(false),
        button: AtomicBool::new(false),
        posed: AtomicBool::new(false),
        waker,
        stop: AtomicBool::new(false),
        latency: rt::Histogram::new(),
        io: Mutex::new(IoReport::default()),
    });
    let io = Io {
        _node: node,
        poll,
        pose,
        pose_topic: t.pose.to_string(),
        twist,
        button,
        command,
        command_len: config.command_len,
        shared: Arc::clone(&shared),
        gate: PoseGate::new(config.gate, config.pose_frame.clone(), t.twist.is_some()),
        report: IoReport::default(),
        stale_after_ns: duration_ns(config.stale_after),
        watchdog_ns: duration_ns(config.command_watchdog),
        last_pose_ns: None,
        last_command_ns: 0,
        holding_force: false,
        stale: false,
    };
    let handle = std::thread::Builder::new()
        .name("ros2-device-io".to_owned())
        .spawn(move || io.run())
        .map_err(io_error("the ros2-device-io thread"))?;
    Ok((shared, handle))
}

fn duration_ns(d: Duration) -> i64 {
    i64::try_from(d.as_nanos()).unwrap_or(i64::MAX)
}

impl Io {
    fn run(mut self) {
        let mut events = Events::with_capacity(16);
        let mut last_share = rt::monotonic_ns();
        while !self.shared.stop.load(Relaxed) {
            // Interrupted or failed polls only cost a spurious pass.
            let _ = self.poll.poll(&mut events, Some(PASS));
            self.drain();
            let now = rt::monotonic_ns();
            if let Some(force) = self.shared.forces.take() {
                self.last_command_ns = now;
                self.on_command(force, now);
            }
            self.guard(now);
            if now - last_share > SHARE {
                last_share = now;
                self.share_report();
            }
        }
        if self.report.commands.published > 0 {
            self.publish([0.0; 3]);
            std::thread::sleep(LINGER);
        }
        self.share_report();
    }

    /// Takes everything that arrived (readiness is edge-triggered: drain every subscription).
    fn drain(&mut self) {
        loop {
            let mut any = false;
            let undecodable = &mut self.report.undecodable;
            if let Some(msg) = graph::take(Some(&self.pose), &mut any, undecodable) {
                self.on_pose(&msg);
            }
            let undecodable = &mut self.report.undecodable;
            if let Some(msg) = graph::take(self.twist.as_ref(), &mut any, undecodable) {
                self.gate.on_twist(&msg, ros_now_ns());
            }
            let undecodable = &mut self.report.undecodable;
            if let Some(msg) = graph::take(self.button.as_ref(), &mut any, undecodable) {
                self.report.buttons += 1;
                self.shared.button.store(msg.data, Relaxed);
            }
            if !any {
                break;
            }
        }
    }

    fn on_pose(&mut self, msg: &PoseStamped) {
        let received = rt::monotonic_ns();
        let at = Receipt {
            monotonic_ns: received,
            ros_ns: ros_now_ns(),
        };
        let Some(sample) = self.gate.on_pose(msg, at) else {
            return;
        };
        if self.report.frame_id.is_empty() {
            self.report.frame_id.clone_from(&msg.header.frame_id);
            tracing::info!(topic = %self.pose_topic, frame = %msg.header.frame_id,
                "first valid device pose");
        }
        self.record(&sample, at.ros_ns);
        self.last_pose_ns = Some(received);
        self.shared.samples.push(sample);
        self.shared.posed.store(true, Relaxed);
    }

    /// Notes an accepted sample, received when the ROS clock read `ros_ns`.
    fn record(&mut self, s: &DeviceSample, ros_ns: i64) {
        self.shared.latency.record((ros_ns - s.stamp_ns).max(0));
        self.report.stamp_span_ns = Some(match self.report.stamp_span_ns {
            Some((first, last)) => {
                let gap = (s.stamp_ns - last) as f64 * 1e-6;
                self.report.longest_stamp_gap_ms = self.report.longest_stamp_gap_ms.max(gap);
                (first, s.stamp_ns)
            }
            None => (s.stamp_ns, s.stamp_ns),
        });
    }

    fn pose_is_stale(&self, now: i64) -> bool {
        self.last_pose_ns
            .is_none_or(|t| now - t > self.stale_after_ns)
    }

    /// A force from the loop: published if a pose has arrived, as zero if the pose is stale or
    /// forces are off.
    fn on_command(&mut self, force: Vec3, now: i64) {
        if self.last_pose_ns.is_none() {
            self.report.commands.before_pose += 1;
            return;
        }
        let stale = self.pose_is_stale(now);
        let c = &mut self.report.commands;
        let mut force = force;
        // Not counted: the operator's device never hands one over (its safety layer counts
        // non-finite forces and zeroes them first); this is the last line for other callers.
        if !vec3::is_finite(force) || !self.shared.forces_on.load(Relaxed) {
            force = vec3::ZERO;
        }
        if force != vec3::ZERO && stale {
            c.stale_zeroed += 1;
            if !self.stale {
                self.stale = true;
                c.stale_episodes += 1;
                tracing::warn!(topic = %self.pose_topic,
                    stale_after_ms = self.stale_after_ns as f64 * 1e-6,
                    "no valid device pose: zero force published until poses come again");
            }
            force = vec3::ZERO;
        } else if !stale && self.stale {
            self.stale = false;
            tracing::info!(topic = %self.pose_topic, "device poses again");
        }
        self.publish(force);
    }

    /// Between commands: zero when the loop stopped handing over forces, or the pose went
    /// stale, after a non-zero force.
    fn guard(&mut self, now: i64) {
        if !self.holding_force {
            return;
        }
        if now - self.last_command_ns > self.watchdog_ns {
            self.report.commands.watchdog_zeroed += 1;
            tracing::warn!(
                watchdog_ms = self.watchdog_ns as f64 * 1e-6,
                "no force from the haptic loop: zero force published"
            );
            self.publish([0.0; 3]);
        } else if self.pose_is_stale(now) {
            // The loop's next command will count the episode; the force goes now.
            self.publish([0.0; 3]);
        }
    }

    fn publish(&mut self, force: Vec3) {
        let Some(publisher) = &self.command else {
            return;
        };
        let ok = publisher
            .publish(command_message(force, self.command_len))
            .is_ok();
        let c = &mut self.report.commands;
        if ok {
            c.published += 1;
            if force == vec3::ZERO {
                c.zero += 1;
            }
            self.holding_force = force != vec3::ZERO;
        } else {
            c.publish_errors += 1;
        }
    }

    fn share_report(&mut self) {
        self.report.gate = self.gate.counts();
        if self.report.other_frame.is_none() {
            self.report.other_frame = self.gate.other_frame().map(str::to_owned);
        }
        self.shared
            .io
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone_from(&self.report);
    }
}
