//! A stand-in for forcedimension_ros2 on the graph, for tests where no ROS (and no device) is
//! installed: a thread that publishes a scripted device pose and button at its rate (1 kHz),
//! as the driver's `fd_ee_broadcaster` does, and records every message that reaches its
//! command subscription, as the driver's `fd_controller` would receive it. Both endpoints use
//! the driver's QoS (`SystemDefaultsQoS`: reliable, volatile, keep-last-10), so a device that
//! talks to the double matches the driver's endpoints too.
//!
//! Each tick it first takes the commands that arrived, then publishes what the script says: a
//! command taken on a tick no later than the first pose's was sent before any pose existed.
//!
//! It is a test fixture, not a driver: no device, no dynamics; the script decides every pose
//! (garbage included).

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;

use ros2_client::{Publisher, Subscription};
use rt::{Periodic, PeriodicConfig, Shutdown};

use crate::graph::{self, Graph, GraphError, Qos};
use crate::haptic::HapticTopics;
use crate::msg::{Bool, Float64MultiArray, Header, Point, Pose, PoseStamped, Time};

/// What the double publishes on one tick.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Step {
    /// The pose, if any.
    pub pose: Option<PoseStamped>,
    /// The button, if any.
    pub button: Option<bool>,
}

/// The script: tick number and ROS time now \[ns\] → what to publish.
pub type Script = Box<dyn FnMut(u64, i64) -> Step + Send>;

/// A pose in `fd_base` at `position_m`, stamped `stamp_ns` (ROS time), identity orientation:
/// what `fd_ee_broadcaster` publishes for an Omega.3.
pub fn fd_pose(stamp_ns: i64, position_m: [f64; 3]) -> PoseStamped {
    PoseStamped {
        header: Header {
            stamp: Time::from_nanos(stamp_ns),
            frame_id: "fd_base".into(),
        },
        pose: Pose {
            position: Point::from_array(position_m),
            ..Pose::default()
        },
    }
}

/// A command as it arrived.
#[derive(Clone, Debug, PartialEq)]
pub struct Received {
    /// The double's tick when it was taken.
    pub tick: u64,
    /// The message.
    pub message: Float64MultiArray,
}

/// A running double.
pub struct FdDouble {
    stop: Shutdown,
    handle: Option<JoinHandle<()>>,
    received: Arc<Mutex<Vec<Received>>>,
    first_pose_tick: Arc<AtomicU64>,
    poses: Arc<AtomicU64>,
}

struct Endpoints {
    pose: Publisher<PoseStamped>,
    button: Option<Publisher<Bool>>,
    command: Option<Subscription<Float64MultiArray>>,
}

impl FdDouble {
    /// Joins `graph` with `topics` (the device's names) and plays `script` at `rate_hz`.
    pub fn start(
        graph: &Graph,
        topics: &HapticTopics,
        rate_hz: f64,
        script: Script,
    ) -> Result<FdDouble, GraphError> {
        let qos = Qos::SYSTEM_DEFAULT;
        let mut node = graph.node("fd_double")?;
        let endpoints = Endpoints {
            pose: graph::advertise(&mut node, &topics.pose, qos)?,
            button: match &topics.button {
                Some(t) => Some(graph::advertise(&mut node, t, qos)?),
                None => None,
            },
            command: match &topics.command {
                Some(t) => Some(graph::subscribe(&mut node, t, qos)?),
                None => None,
            },
        };
        let periodic = Periodic::new(
            PeriodicConfig {
                period_ns: (1e9 / rate_hz).round() as i64,
                spin_ns: 0,
                ..PeriodicConfig::default()
            },
            rt::monotonic_ns() + 1_000_000,
        )
        .map_err(|e| GraphError::Dds {
            what: "the double's loop".into(),
            reason: e.to_string(),
        })?;
        let mut double = FdDouble {
            stop: Shutdown::new(),
            handle: None,
            received: Arc::new(Mutex::new(Vec::new())),
            first_pose_tick: Arc::new(AtomicU64::new(u64::MAX)),
            poses: Arc::new(AtomicU64::new(0)),
        };
        let run = Run {
            _node: node,
            endpoints,
            script,
            received: Arc::clone(&double.received),
            first_pose_tick: Arc::clone(&double.first_pose_tick),
            poses: Arc::clone(&double.poses),
        };
        let stop = double.stop.clone();
        let handle = std::thread::Builder::new()
            .name("fd-double".into())
            .spawn(move || run.run(periodic, &stop))
            .map_err(|e| GraphError::Dds {
                what: "the double's thread".into(),
                reason: e.to_string(),
            })?;
        double.handle = Some(handle);
        Ok(double)
    }

    /// Every command received so far, oldest first.
    pub fn received(&self) -> Vec<Received> {
        self.received
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// The tick of the first pose published, if any.
    pub fn first_pose_tick(&self) -> Option<u64> {
        Some(self.first_pose_tick.load(Relaxed)).filter(|t| *t != u64::MAX)
    }

    /// Poses published so far.
    pub fn poses(&self) -> u64 {
        self.poses.load(Relaxed)
    }

    /// Stops the double; returns every command it received.
    pub fn stop(mut self) -> Vec<Received> {
        self.stop.trigger();
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
        self.received()
    }
}

impl Drop for FdDouble {
    fn drop(&mut self) {
        self.stop.trigger();
    }
}

struct Run {
    _node: ros2_client::Node,
    endpoints: Endpoints,
    script: Script,
    received: Arc<Mutex<Vec<Received>>>,
    first_pose_tick: Arc<AtomicU64>,
    poses: Arc<AtomicU64>,
}

impl Run {
    fn run(mut self, mut periodic: Periodic, stop: &Shutdown) {
        loop {
            let tick = periodic.wait();
            if stop.is_triggered() {
                break;
            }
            self.take_commands(tick.index);
            let step = (self.script)(tick.index, graph::ros_now_ns());
            if let Some(pose) = step.pose
                && self.endpoints.pose.publish(pose).is_ok()
            {
                // Only the first tick's index is kept (the later stores fail).
                let _ =
                    self.first_pose_tick
                        .compare_exchange(u64::MAX, tick.index, Relaxed, Relaxed);
                self.poses.fetch_add(1, Relaxed);
            }
            if let (Some(b), Some(p)) = (step.button, &self.endpoints.button) {
                let _ = p.publish(Bool { data: b });
            }
        }
    }

    fn take_commands(&mut self, tick: u64) {
        let Some(sub) = &self.endpoints.command else {
            return;
        };
        let mut received = self.received.lock().unwrap_or_else(PoisonError::into_inner);
        while let Ok(Some((message, _))) = sub.take() {
            received.push(Received { tick, message });
        }
    }
}
