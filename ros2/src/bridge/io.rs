//! The bridge's I/O thread: every DDS call of the robot bridge happens here.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use ros2_client::dds::rustdds::mio1::{Events, Poll, Token, Waker};
use ros2_client::{Node, Publisher, Subscription};
use transport::Mailbox;

use super::{BridgeConfig, IoReport, STATE_QUEUE, Shared, Timed};
use crate::graph::{self, Graph, GraphError, io_error, register, ros_now_ns};
use crate::msg::{
    Bool, Float64MultiArray, Header, Point, Pose, PoseStamped, Quaternion, Time, Twist,
    TwistStamped, Vector3, WrenchStamped,
};
use crate::state::{Receipt, StampClock, StateAssembler};
use crate::topics::theta_message;

const POSE: Token = Token(1);
const TWIST: Token = Token(2);
const WRENCH: Token = Token(3);
const WAKE: Token = Token(9);

/// How long the thread sleeps with nothing to do (it also publishes its counters then).
const IDLE: Duration = Duration::from_millis(20);

struct Io {
    _node: Node,
    poll: Poll,
    pose: Subscription<PoseStamped>,
    twist: Option<Subscription<TwistStamped>>,
    wrench: Subscription<WrenchStamped>,
    target: Publisher<PoseStamped>,
    target_twist: Option<Publisher<TwistStamped>>,
    theta: Publisher<Float64MultiArray>,
    contact: Publisher<Bool>,
    shared: Arc<Shared>,
    assembler: StateAssembler,
    clock: StampClock,
    report: IoReport,
    last_stamp: Option<i64>,
    last_receipt: Option<i64>,
    frame_id: String,
    command_frame: Option<String>,
    /// ROS time − loop clock \[ns\], measured once at start.
    wall_offset_ns: i64,
}

/// Creates the endpoints and starts the thread.
pub(super) fn spawn(
    graph: &Graph,
    config: &BridgeConfig,
) -> Result<(Arc<Shared>, JoinHandle<()>), GraphError> {
    let t = &config.topics;
    let mut node = graph.node("mmt_telerobot")?;
    let mut pose = graph::subscribe::<PoseStamped>(&mut node, &t.robot_pose, config.state_qos)?;
    let mut twist = match (&t.robot_twist, config.state.twist) {
        (Some(name), true) => Some(graph::subscribe::<TwistStamped>(
            &mut node,
            name,
            config.state_qos,
        )?),
        _ => None,
    };
    let mut wrench =
        graph::subscribe::<WrenchStamped>(&mut node, &t.robot_wrench, config.state_qos)?;
    let target = graph::advertise::<PoseStamped>(&mut node, &t.target_pose, config.command_qos)?;
    let target_twist = match &t.target_twist {
        Some(name) => Some(graph::advertise::<TwistStamped>(
            &mut node,
            name,
            config.command_qos,
        )?),
        None => None,
    };
    let theta = graph::advertise::<Float64MultiArray>(&mut node, &t.theta, config.settings_qos)?;
    let contact = graph::advertise::<Bool>(&mut node, &t.in_contact, config.settings_qos)?;
    let poll = Poll::new().map_err(io_error("poll"))?;
    register(&poll, Some(&mut pose), POSE, "pose subscription")?;
    register(&poll, twist.as_mut(), TWIST, "twist subscription")?;
    register(&poll, Some(&mut wrench), WRENCH, "wrench subscription")?;
    let waker = Waker::new(poll.registry(), WAKE).map_err(io_error("waker"))?;
    let shared = Arc::new(Shared {
        states: Mailbox::new(STATE_QUEUE),
        targets: Mailbox::latest(),
        theta: Mailbox::latest(),
        contact: Mailbox::latest(),
        waker,
        stop: AtomicBool::new(false),
        latency: rt::Histogram::new(),
        io: Mutex::new(IoReport::default()),
        superseded: AtomicU64::new(0),
    });
    let io = Io {
        _node: node,
        poll,
        pose,
        twist,
        wrench,
        target,
        target_twist,
        theta,
        contact,
        shared: Arc::clone(&shared),
        assembler: StateAssembler::new(config.state),
        clock: StampClock::default(),
        report: IoReport::default(),
        last_stamp: None,
        last_receipt: None,
        frame_id: String::new(),
        command_frame: config.command_frame.clone(),
        wall_offset_ns: graph::wall_minus_monotonic_ns(),
    };
    let handle = std::thread::Builder::new()
        .name("ros2-io".to_owned())
        .spawn(move || io.run())
        .map_err(io_error("the ros2-io thread"))?;
    Ok((shared, handle))
}

impl Io {
    fn run(mut self) {
        let mut events = Events::with_capacity(16);
        let mut last_report = rt::monotonic_ns();
        while !self.shared.stop.load(Relaxed) {
            // Interrupted or failed polls only cost a spurious pass.
            let _ = self.poll.poll(&mut events, Some(IDLE));
            self.drain();
            self.publish();
            let now = rt::monotonic_ns();
            if now - last_report > IDLE.as_nanos() as i64 {
                last_report = now;
                self.share_report();
            }
        }
        self.share_report();
    }

    /// Takes everything that arrived (readiness is edge-triggered: drain every subscription).
    fn drain(&mut self) {
        loop {
            let mut any = false;
            let undecodable = &mut self.report.undecodable;
            if let Some(msg) = graph::take(Some(&self.pose), &mut any, undecodable) {
                if self.frame_id.is_empty() {
                    self.frame_id.clone_from(&msg.header.frame_id);
                }
                let at = Receipt {
                    monotonic_ns: rt::monotonic_ns(),
                    ros_ns: ros_now_ns(),
                };
                self.assembler.on_pose(&msg, at);
            }
            let undecodable = &mut self.report.undecodable;
            if let Some(msg) = graph::take(self.twist.as_ref(), &mut any, undecodable) {
                self.assembler.on_twist(&msg, ros_now_ns());
            }
            let undecodable = &mut self.report.undecodable;
            if let Some(msg) = graph::take(Some(&self.wrench), &mut any, undecodable) {
                self.assembler.on_wrench(&msg, ros_now_ns());
            }
            self.forward_states();
            if !any {
                break;
            }
        }
    }

    /// Assembled states → the loop, each mapped onto the loop's clock.
    fn forward_states(&mut self) {
        while let Some(state) = self.assembler.take() {
            let wall = ros_now_ns();
            self.shared.latency.record((wall - state.stamp_ns).max(0));
            let loop_ns = self.clock.map(state.stamp_ns, state.received_ns);
            if let Some(last) = self.last_stamp {
                let gap = (state.stamp_ns - last) as f64 * 1e-6;
                self.report.longest_stamp_gap_ms = self.report.longest_stamp_gap_ms.max(gap);
            }
            if let Some(last) = self.last_receipt {
                let gap = (state.received_ns - last) as f64 * 1e-6;
                self.report.longest_receipt_gap_ms = self.report.longest_receipt_gap_ms.max(gap);
            }
            self.last_stamp = Some(state.stamp_ns);
            self.last_receipt = Some(state.received_ns);
            self.report.stamp_span_ns = Some(match self.report.stamp_span_ns {
                Some((first, _)) => (first, state.stamp_ns),
                None => (state.stamp_ns, state.stamp_ns),
            });
            if !self.shared.states.push(Timed { state, loop_ns }) {
                self.shared.superseded.fetch_add(1, Relaxed);
            }
        }
    }

    fn publish(&mut self) {
        if let Some(t) = self.shared.targets.take() {
            let [x, y, z, w] = t.orientation_xyzw;
            let header = Header {
                stamp: Time::from_nanos(t.tick_ns + self.wall_offset_ns),
                frame_id: self
                    .command_frame
                    .clone()
                    .unwrap_or_else(|| self.frame_id.clone()),
            };
            // The twist first: a subscriber that pairs them by stamp has it when the pose comes.
            let twist_ok = self.target_twist.as_ref().is_none_or(|p| {
                p.publish(TwistStamped {
                    header: header.clone(),
                    twist: Twist {
                        linear: Vector3::from_array(t.velocity_m_per_s),
                        angular: Vector3::default(),
                    },
                })
                .is_ok()
            });
            let msg = PoseStamped {
                header,
                pose: Pose {
                    position: Point::from_array(t.position_m),
                    orientation: Quaternion { x, y, z, w },
                },
            };
            let ok = self.target.publish(msg).is_ok() && twist_ok;
            self.count(|r| &mut r.targets_published, ok);
        }
        if let Some(p) = self.shared.theta.take() {
            let ok = self.theta.publish(theta_message(&p)).is_ok();
            self.count(|r| &mut r.theta_published, ok);
        }
        if let Some(c) = self.shared.contact.take() {
            let ok = self.contact.publish(Bool { data: c }).is_ok();
            self.count(|r| &mut r.contact_published, ok);
        }
    }

    fn count(&mut self, field: impl Fn(&mut IoReport) -> &mut u64, ok: bool) {
        if ok {
            *field(&mut self.report) += 1;
        } else {
            self.report.publish_errors += 1;
        }
    }

    fn share_report(&mut self) {
        self.report.state = self.assembler.counts();
        *self
            .shared
            .io
            .lock()
            .unwrap_or_else(PoisonError::into_inner) = self.report;
    }
}
