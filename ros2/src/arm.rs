//! The test arm: a simulated robot on the ROS 2 graph, in a thread of its own, for tests and
//! figures where no robot (and no ROS) is installed.
//!
//! It plays a scene's simulated world (`sim::SimBridge`: the exp-1 object, Karnopp friction,
//! Franka-like sensor noise) at its own rate (1 kHz) as a driver with a Cartesian trajectory
//! interpolator would: the commanded poses from `target_pose` are played by their stamps, a
//! tick late, whenever DDS delivered them (the `path` module; past the newest pose the path goes
//! on along the commanded twist of its stamp, or else the poses' difference over their stamps);
//! each tick the tool goes to where that path is, and the arm publishes the measured pose, twist
//! and wrench with one header stamp (ROS time). Optionally a camera
//! thread publishes the scene's simulated depth camera as `sensor_msgs/PointCloud2`, in a camera
//! frame mounted above the table (what `realsense2_camera` would send).
//!
//! It is a test fixture, not a driver: no joint limits, no dynamics of its own.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::thread::JoinHandle;

use mmt::cloud::Pose;
use node::Target;
use ros2_client::{Publisher, Subscription};
use rt::{Periodic, PeriodicConfig, Shutdown};
use serde::Serialize;
use sim::SimBridge;
use sim::camera::Camera;
use sim::scene::Scene;
use sim::world::World;
use transport::Mailbox;

use crate::graph::{self, Graph, GraphError, Qos, TopicName};
use crate::msg::{
    Header, Point, PointCloud2, Pose as RosPose, PoseStamped, Quaternion, Time, Twist,
    TwistStamped, Vector3, Wrench, WrenchStamped,
};
use crate::pointcloud2::encode_xyz;
use crate::topics::RobotTopics;

mod path;

use path::{Point as PathPoint, TargetPath};
use sim::Follower;

/// The arm's settings.
#[derive(Clone, Debug)]
pub struct ArmConfig {
    /// The world it plays (its `[cloud]` must be a `plane` for the camera).
    pub scene: Scene,
    /// Seed of the sensor and camera noise.
    pub seed: u64,
    /// Where the tool starts \[m\].
    pub start_m: [f64; 3],
    /// Control and publishing rate \[Hz\]. Default 1000.
    pub rate_hz: f64,
    /// Topic names (the same defaults as the bridge).
    pub topics: RobotTopics,
    /// QoS of the state it publishes and of the targets it reads.
    pub qos: Qos,
    /// The base frame's name.
    pub frame_id: String,
    /// Publish the simulated camera.
    pub camera: Option<ArmCamera>,
    /// Busy-spin before each tick \[ns\].
    pub spin_ns: i64,
}

/// The arm's camera.
#[derive(Clone, Debug)]
pub struct ArmCamera {
    /// Where it publishes.
    pub topic: TopicName,
    /// Its frame's name.
    pub frame_id: String,
    /// base ← camera.
    pub pose: Pose,
}

impl ArmCamera {
    /// A camera 0.5 m above the base origin, looking straight down (its z axis is the base's
    /// −z, its x the base's x), 10 cm to the side: the mounting the tests use.
    pub fn overhead(topic: TopicName) -> ArmCamera {
        ArmCamera {
            topic,
            frame_id: "camera_depth_optical_frame".into(),
            pose: Pose::from_rotation_vector([std::f64::consts::PI, 0.0, 0.0], [0.1, 0.0, 0.5]),
        }
    }
}

/// What the arm did.
#[derive(Clone, Copy, Debug, Default, Serialize)]
pub struct ArmReport {
    /// Ticks run.
    pub ticks: u64,
    /// Targets received.
    pub targets: u64,
    /// States published (pose, twist and wrench each).
    pub states: u64,
    /// Camera frames published.
    pub frames: u64,
    /// Publications the middleware refused.
    pub publish_errors: u64,
    /// Breaks in the commanded path the tool returned across, and the periods it spent
    /// returning ([`sim::Follower`]).
    pub path_breaks: (u64, u64),
    /// Its loop's timing.
    pub timing: rt::TimingReport,
}

/// Why the arm could not start.
#[derive(Debug, thiserror::Error)]
pub enum ArmError {
    /// The graph.
    #[error(transparent)]
    Graph(#[from] GraphError),
    /// The simulated world.
    #[error("simulated world: {0}")]
    Sim(#[from] sim::SimError),
    /// The loop.
    #[error(transparent)]
    Loop(#[from] rt::PeriodicError),
    /// A thread.
    #[error("cannot start the arm's thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// A running test arm.
pub struct TestArm {
    stop: Shutdown,
    control: Option<JoinHandle<ArmReport>>,
    camera: Option<JoinHandle<()>>,
    frames: Arc<AtomicU64>,
}

struct Endpoints {
    target: Subscription<PoseStamped>,
    target_twist: Option<Subscription<TwistStamped>>,
    pose: Publisher<PoseStamped>,
    twist: Option<Publisher<TwistStamped>>,
    wrench: Publisher<WrenchStamped>,
}

impl TestArm {
    /// Joins `graph` and starts playing.
    pub fn start(graph: &Graph, config: ArmConfig) -> Result<TestArm, ArmError> {
        let mut node = graph.node("mmt_test_arm")?;
        let t = &config.topics;
        let endpoints = Endpoints {
            target: graph::subscribe(&mut node, &t.target_pose, config.qos)?,
            target_twist: match &t.target_twist {
                Some(name) => Some(graph::subscribe(&mut node, name, config.qos)?),
                None => None,
            },
            pose: graph::advertise(&mut node, &t.robot_pose, config.qos)?,
            twist: match &t.robot_twist {
                Some(name) => Some(graph::advertise(&mut node, name, config.qos)?),
                None => None,
            },
            wrench: graph::advertise(&mut node, &t.robot_wrench, config.qos)?,
        };
        let bridge = SimBridge::new(&config.scene, config.start_m, config.seed)?;
        let period_ns = (1e9 / config.rate_hz).round() as i64;
        let periodic = Periodic::new(
            PeriodicConfig {
                period_ns,
                spin_ns: config.spin_ns,
                ..PeriodicConfig::default()
            },
            rt::monotonic_ns() + 2_000_000,
        )?;
        let stop = Shutdown::new();
        let poses = Arc::new(Mailbox::latest());
        let frames = Arc::new(AtomicU64::new(0));
        let camera = match &config.camera {
            Some(cam) => {
                let mut cam_node = graph.node("mmt_test_camera")?;
                let publisher: Publisher<PointCloud2> =
                    graph::advertise(&mut cam_node, &cam.topic, Qos::STREAM)?;
                let cam = cam.clone();
                let world = World::new(&config.scene, config.start_m, config.seed)?;
                let camera = Camera::new(&config.scene, config.seed);
                let (poses, frames, stop) = (Arc::clone(&poses), Arc::clone(&frames), stop.clone());
                Some(
                    std::thread::Builder::new()
                        .name("arm-camera".into())
                        .spawn(move || {
                            let _node = cam_node;
                            run_camera(camera, &world, &cam, &publisher, &poses, &frames, &stop);
                        })?,
                )
            }
            None => None,
        };
        let arm = Arm {
            _node: node,
            endpoints,
            bridge,
            frame_id: config.frame_id.clone(),
            path: TargetPath::new(),
            follower: Follower::default(),
            period_ns,
            target_twist: None,
            last_index: None,
            wall_offset_ns: graph::wall_minus_monotonic_ns(),
            poses,
            report: ArmReport::default(),
        };
        let stop_loop = stop.clone();
        let control = std::thread::Builder::new()
            .name("test-arm".into())
            .spawn(move || arm.run(periodic, &stop_loop))?;
        Ok(TestArm {
            stop,
            control: Some(control),
            camera,
            frames,
        })
    }

    /// Stops the arm and returns what it did.
    pub fn stop(mut self) -> ArmReport {
        self.stop.trigger();
        let mut report = self
            .control
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        if let Some(c) = self.camera.take() {
            let _ = c.join();
        }
        report.frames = self.frames.load(Relaxed);
        report
    }
}

impl Drop for TestArm {
    fn drop(&mut self) {
        self.stop.trigger();
    }
}

/// The tool pose handed to the camera thread: (stamp \[ns\], position \[m\], the object's offset \[m\]).
type ToolPose = (i64, [f64; 3], [f64; 2]);

struct Arm {
    _node: ros2_client::Node,
    endpoints: Endpoints,
    bridge: SimBridge,
    frame_id: String,
    /// The commanded path, played by its stamps.
    path: TargetPath,
    /// Where the tool goes along it (back to it, across a break).
    follower: Follower,
    /// The arm's period \[ns\].
    period_ns: i64,
    /// The newest commanded twist: (stamp, velocity).
    target_twist: Option<(i64, [f64; 3])>,
    /// The last tick's index: the world steps once per period, skipped ticks included.
    last_index: Option<u64>,
    /// ROS time − loop clock \[ns\].
    wall_offset_ns: i64,
    poses: Arc<Mailbox<ToolPose>>,
    report: ArmReport,
}

impl Arm {
    fn run(mut self, mut periodic: Periodic, stop: &Shutdown) -> ArmReport {
        let timing = periodic.timing();
        loop {
            let tick = periodic.wait();
            if stop.is_triggered() {
                break;
            }
            // Skipped ticks (the thread was held up) still pass in the world: a real robot's
            // time does not stop; its states of those ticks are simply never published.
            let steps = self
                .last_index
                .map_or(1, |last| (tick.index - last).clamp(1, 100));
            self.last_index = Some(tick.index);
            self.tick(tick.deadline_ns, steps);
        }
        self.report.timing = timing.report();
        self.report.path_breaks = self.follower.breaks();
        self.report
    }

    fn tick(&mut self, now: i64, steps: u64) {
        self.take_targets();
        let here = node::RobotBridge::tool_m(&self.bridge).unwrap_or_default();
        // The tool's motion over each period since the last tick (more than one when this
        // thread was held up).
        let mut tool = (here, [0.0; 3]);
        for back in (0..steps as i64).rev() {
            let t = now - back * self.period_ns + self.wall_offset_ns;
            let (x, v) = self.path.at(t).unwrap_or((here, [0.0; 3]));
            tool = self.follower.step(x, v, self.period_ns as f64 * 1e-9);
        }
        let (position, velocity) = tool;
        // Held up for `steps` periods, the robot's own controller (which does not stall with
        // this thread) went to the target along the way ([`SimBridge::step_periods`]).
        let target = Target {
            position_m: position,
            velocity_m_per_s: velocity,
            command_sample_time_ns: 0,
            holding: false,
        };
        let s = self.bridge.step_periods(&target, steps);
        self.report.ticks += 1;
        // Stamped with the tick's time (what a driver's control loop stamps), not the moment of
        // publishing.
        let header = Header {
            stamp: Time::from_nanos(now + self.wall_offset_ns),
            frame_id: self.frame_id.clone(),
        };
        let m = s.measured;
        let ok_pose = self
            .endpoints
            .pose
            .publish(PoseStamped {
                header: header.clone(),
                pose: RosPose {
                    position: Point::from_array(m.position_m),
                    orientation: Quaternion::default(),
                },
            })
            .is_ok();
        let ok_twist = self.endpoints.twist.as_ref().is_none_or(|t| {
            t.publish(TwistStamped {
                header: header.clone(),
                twist: Twist {
                    linear: Vector3::from_array(m.velocity_m_per_s),
                    angular: Vector3::default(),
                },
            })
            .is_ok()
        });
        let ok_wrench = self
            .endpoints
            .wrench
            .publish(WrenchStamped {
                header,
                wrench: Wrench {
                    force: Vector3::from_array(m.force_on_tool_n),
                    torque: Vector3::default(),
                },
            })
            .is_ok();
        if ok_pose && ok_twist && ok_wrench {
            self.report.states += 1;
        } else {
            self.report.publish_errors += 1;
        }
        self.poses
            .push((now, s.truth.position_m, s.object_offset_m));
    }

    /// Takes the commanded twists and poses that arrived into the path.
    fn take_targets(&mut self) {
        if let Some(sub) = &self.endpoints.target_twist {
            while let Ok(Some((msg, _))) = sub.take() {
                if let Some(stamp) = msg.header.stamp.to_nanos() {
                    self.target_twist = Some((stamp, msg.twist.linear.to_array()));
                }
            }
        }
        while let Ok(Some((msg, _))) = self.endpoints.target.take() {
            let Some(stamp) = msg.header.stamp.to_nanos() else {
                continue;
            };
            let p = msg.pose.position.to_array();
            if !p.iter().all(|c| c.is_finite()) {
                continue;
            }
            let newest = self.path.newest().copied();
            let velocity = match self.target_twist {
                Some((t, v)) if t == stamp && v.iter().all(|c| c.is_finite()) => v,
                _ => match newest {
                    Some(n) if stamp > n.stamp_ns && stamp - n.stamp_ns < 50_000_000 => {
                        let dt = (stamp - n.stamp_ns) as f64 * 1e-9;
                        std::array::from_fn(|k| (p[k] - n.position_m[k]) / dt)
                    }
                    _ => [0.0; 3],
                },
            };
            let pushed = self.path.push(PathPoint {
                stamp_ns: stamp,
                position_m: p,
                velocity_m_per_s: velocity,
            });
            // Not counted: one not newer than the newest held (a duplicate, a reordered one).
            self.report.targets += u64::from(pushed);
        }
    }
}

fn run_camera(
    mut camera: Camera,
    world: &World,
    cam: &ArmCamera,
    publisher: &Publisher<PointCloud2>,
    poses: &Mailbox<ToolPose>,
    frames: &AtomicU64,
    stop: &Shutdown,
) {
    let to_camera = inverse(&cam.pose);
    let wall_offset_ns = graph::wall_minus_monotonic_ns();
    let mut last = None;
    let mut points = Vec::new();
    while !stop.wait_timeout(std::time::Duration::from_millis(2)) {
        if let Some(p) = poses.take() {
            last = Some(p);
        }
        let Some((now, tool, offset)) = last else {
            continue;
        };
        if let Ok(Some(frame)) = camera.frame(now, world, tool, &offset) {
            points.clear();
            points.extend(frame.points().iter().map(|p| {
                to_camera
                    .transform_point(p.map(f64::from))
                    .map(|c| c as f32)
            }));
            if publisher
                .publish(encode_xyz(&points, &cam.frame_id, now + wall_offset_ns))
                .is_ok()
            {
                frames.fetch_add(1, Relaxed);
            }
        }
    }
}

/// The inverse of a rigid pose.
pub fn inverse(p: &Pose) -> Pose {
    let r = p.rotation;
    let rt: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| r[j][i]));
    let t = p.translation_m;
    let ti: [f64; 3] = std::array::from_fn(|i| -(0..3).map(|j| rt[i][j] * t[j]).sum::<f64>());
    Pose {
        rotation: rt,
        translation_m: ti,
    }
}
