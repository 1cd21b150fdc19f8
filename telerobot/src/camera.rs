//! The camera thread: the scene's cloud source — the simulated depth camera at its frame rate,
//! a PLY/PCD file ([`file`]) or a camera on a ROS 2 graph (`ros2::camera`) — off the real-time thread (`DESIGN.md` §2: nothing in the 1 kHz
//! loop allocates).
//!
//! ```text
//!  1 kHz loop ──CameraPose (latest value)──▶ camera thread: Camera::frame → CloudIndex::build
//!  1 kHz loop ◀──(frame id, Arc<CloudIndex>) (latest value)──┘      └──▶ send_cloud (operator)
//!  1 kHz loop ──Arc<CloudIndex> replaced──▶ camera thread: dropped there
//! ```
//!
//! The loop hands back every index it replaces, and this thread drops it, so the loop never drops
//! the last reference to one (freeing a kd-tree there would be a deallocation on the real-time
//! thread; keeping the last few alive here did not hold when the loop stalled for more frames
//! than were kept). With
//! `--record` or `--live` it hands each frame to the recorder too.
//!
//! Every frame is held to the real-time budget before it is indexed ([`FrameBudget`]): a frame
//! the proxy could not step on at the loop rate, or too large to index at the camera rate, is
//! voxel-downsampled, or refused when only a voxel the proxy slips through would fit (counted;
//! logged once). The simulated camera and cloud files are fitted at load already; this guards
//! a ROS 2 camera's frames, whose density is known only when they come.

use std::io;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::thread::JoinHandle;
use std::time::Duration;

use cloud_io::voxel::VoxelGrid;
use mmt::cloud::{CloudError, CloudFrame};
use mmt::contact::budget::CloudBudget;
use mmt::contact::{CloudIndex, ProxyConfig};
use node::cloud_to_wire;
use rt::Shutdown;
use sim::camera::Camera;
use sim::world::World;
use transport::Mailbox;

use crate::net::TelerobotLink;
use record::schema::CloudRec;
use record::{Message, RecordSink, Side};

pub mod file;
mod start;

pub use file::{CloudFileError, FileCloud, FileCloudInfo};
pub(crate) use start::start;

/// How often the camera thread looks for a due frame: 2 ms, so frames are at most 2 ms late.
const POLL: Duration = Duration::from_millis(2);
/// Indices the loop may hand back between two polls of the camera thread. The loop hands back
/// one for each index it takes, and the thread publishes at most one a poll, after draining
/// these: at most a couple wait at any time. A push into a full queue would drop, and free, on
/// the loop.
const RETIRED: usize = 8;

/// Where the tool and the object are, published by the loop every tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraPose {
    /// The loop's tick time [ns, `monotonic_ns`]: the frame's capture time.
    pub now_ns: i64,
    /// Tool position \[m\] (the camera window is centred on it).
    pub tool_m: [f64; 3],
    /// How far the object slid along the tangents \[m\] (the cloud moves with it).
    pub object_offset_m: [f64; 2],
}

/// The hand-off between the loop and the camera thread (both latest-value slots).
#[derive(Debug)]
pub struct CameraFeed {
    /// Loop → camera.
    pub pose: Mailbox<CameraPose>,
    /// Camera → loop: the newest frame's id and index.
    pub index: Mailbox<(u64, Arc<CloudIndex>)>,
    /// Loop → camera: the indices the loop replaced, to drop.
    pub retired: Mailbox<Arc<CloudIndex>>,
    frames: AtomicU64,
    rejected: AtomicU64,
    downsampled: AtomicU64,
    over_budget: AtomicU64,
}

impl Default for CameraFeed {
    fn default() -> Self {
        CameraFeed {
            pose: Mailbox::latest(),
            index: Mailbox::latest(),
            retired: Mailbox::new(RETIRED),
            frames: AtomicU64::new(0),
            rejected: AtomicU64::new(0),
            downsampled: AtomicU64::new(0),
            over_budget: AtomicU64::new(0),
        }
    }
}

impl CameraFeed {
    /// Frames indexed and sent, and frames the camera or the index refused.
    pub fn counts(&self) -> (u64, u64) {
        (self.frames.load(Relaxed), self.rejected.load(Relaxed))
    }

    /// Frames over the real-time budget: downsampled to fit, and refused (also counted in
    /// [`CameraFeed::counts`]' refused).
    pub fn budget_counts(&self) -> (u64, u64) {
        (
            self.downsampled.load(Relaxed),
            self.over_budget.load(Relaxed),
        )
    }
}

/// The real-time budget a frame is held to before it is indexed: the scene's proxy (radii, loop
/// rate) and the camera's frame rate (`mmt::contact::budget`).
pub struct FrameBudget {
    proxy: ProxyConfig,
    budget: CloudBudget,
    frame_rate_hz: Option<f64>,
    grid: VoxelGrid,
    warned: bool,
}

impl FrameBudget {
    /// The budget of `scene`'s frames.
    pub fn of_scene(scene: &sim::scene::Scene) -> FrameBudget {
        FrameBudget {
            proxy: scene.proxy.config(scene.rates.control_hz),
            budget: scene.cloud.budget,
            frame_rate_hz: Some(scene.cloud.rate_hz),
            grid: VoxelGrid::new(),
            warned: false,
        }
    }

    /// The frame, downsampled if it is over the budget; `None` (counted in `feed`) if it cannot
    /// be brought in. The first frame that is not as it came is logged.
    fn hold(&mut self, frame: CloudFrame, feed: &CameraFeed) -> Option<CloudFrame> {
        let (timestamp_ns, pose) = (frame.timestamp_ns(), *frame.sensor_pose());
        let mut points = frame.into_points();
        let fit = cloud_io::budget::fit_to_budget(
            &mut points,
            &self.proxy,
            &self.budget,
            self.frame_rate_hz,
            &mut self.grid,
        );
        match fit {
            Ok(None) => {}
            Ok(Some(fit)) => {
                feed.downsampled.fetch_add(1, Relaxed);
                if !std::mem::replace(&mut self.warned, true) {
                    tracing::warn!("camera frame: {fit} (logged once; counted in the report)");
                }
            }
            Err(e) => {
                feed.over_budget.fetch_add(1, Relaxed);
                if !std::mem::replace(&mut self.warned, true) {
                    tracing::warn!(
                        "camera frame refused: {e} (logged once; counted in the report)"
                    );
                }
                return None;
            }
        }
        CloudFrame::new(points, timestamp_ns, pose).ok()
    }
}

/// Where the camera thread's frames come from.
pub enum Source {
    /// The scene's simulated camera (seeded) and a copy of the scene's world it reads the
    /// surface frame from (never stepped).
    Simulated(Box<Camera>, Box<World>),
    /// A PLY or PCD file, loaded at start.
    File(Box<FileCloud>),
    /// A camera's PointCloud2 topic on a ROS 2 graph.
    Ros2(Box<ros2::CameraSource>),
}

impl Source {
    fn frame(&mut self, p: &CameraPose) -> Result<Option<mmt::cloud::CloudFrame>, CloudError> {
        match self {
            Source::Simulated(camera, geometry) => {
                camera.frame(p.now_ns, geometry, p.tool_m, &p.object_offset_m)
            }
            Source::File(file) => file.frame(p.now_ns, &p.object_offset_m),
            Source::Ros2(camera) => Ok(camera.poll(rt::monotonic_ns())),
        }
    }
}

/// Starts the camera thread on `source`. It stops when `shutdown` is triggered.
pub fn spawn(
    source: Source,
    budget: FrameBudget,
    feed: Arc<CameraFeed>,
    link: TelerobotLink,
    record: Option<RecordSink>,
    shutdown: Shutdown,
) -> io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name("camera".to_owned())
        .spawn(move || run(source, budget, &feed, &link, record.as_ref(), &shutdown))
}

fn run(
    mut source: Source,
    mut budget: FrameBudget,
    feed: &CameraFeed,
    link: &TelerobotLink,
    record: Option<&RecordSink>,
    shutdown: &Shutdown,
) {
    let mut frame_id = 0u64;
    let mut pose = None;
    while !shutdown.wait_timeout(POLL) {
        while feed.retired.take().is_some() {}
        if let Some(p) = feed.pose.take() {
            pose = Some(p);
        }
        let Some(p) = pose.or_else(|| {
            // A real camera does not wait for the robot's first state.
            matches!(source, Source::Ros2(_)).then(CameraPose::default)
        }) else {
            continue;
        };
        let frame = match source.frame(&p) {
            Ok(Some(frame)) => budget.hold(frame, feed).ok_or(()),
            Ok(None) => continue,
            Err(_) => Err(()),
        };
        match frame {
            Ok(frame) => match CloudIndex::build(&frame) {
                Ok(index) => {
                    frame_id += 1;
                    feed.index.push((frame_id, Arc::new(index)));
                    let wire = cloud_to_wire(frame_id, frame);
                    if let Some(sink) = record.filter(|s| s.wants_clouds()) {
                        let cloud = CloudRec {
                            frame_id,
                            timestamp_ns: wire.timestamp_ns,
                            points: Arc::new(wire.points.clone()),
                        };
                        sink.send_one(p.now_ns, Message::Cloud(Side::Telerobot, cloud));
                    }
                    link.send_cloud(Box::new(wire));
                    feed.frames.fetch_add(1, Relaxed);
                }
                Err(_) => {
                    feed.rejected.fetch_add(1, Relaxed);
                }
            },
            Err(()) => {
                feed.rejected.fetch_add(1, Relaxed);
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use mmt::cloud::Pose;

    /// Issue 11: the camera holds frames to the scene's `[cloud.budget]`, not to the 2-core
    /// defaults: a 90,000-point frame at 30 Hz is downsampled by default and kept whole on a
    /// robot PC whose scene says it indexes four times faster on a whole core.
    #[test]
    fn the_camera_holds_frames_to_the_scenes_budget() {
        let grid: Vec<[f32; 3]> = (0..300 * 300)
            .map(|k| [(k % 300) as f32 * 0.001, (k / 300) as f32 * 0.001, 0.0])
            .collect();
        let mut scene = sim::scene::Scene::exp1();
        let feed = CameraFeed::default();
        let frame = CloudFrame::new(grid.clone(), 1, Pose::IDENTITY).unwrap();
        let kept = FrameBudget::of_scene(&scene).hold(frame, &feed).unwrap();
        assert!(
            kept.points().len() < grid.len(),
            "the default budget downsamples"
        );
        scene.cloud.budget.index_share = 1.0;
        scene.cloud.budget.build_ns_per_point = 40.0;
        let feed = CameraFeed::default();
        let frame = CloudFrame::new(grid.clone(), 2, Pose::IDENTITY).unwrap();
        let kept = FrameBudget::of_scene(&scene).hold(frame, &feed).unwrap();
        assert_eq!(kept.points().len(), grid.len());
        assert_eq!(feed.budget_counts(), (0, 0));
    }

    /// Issue 11, finding 5 on the camera thread: a ROS 2 camera's million-point frame (which
    /// only its own `max_points` held) is downsampled before it is indexed, and counted.
    #[test]
    fn a_frame_over_the_budget_is_downsampled_before_it_is_indexed() {
        let scene = sim::scene::Scene::exp1();
        let mut budget = FrameBudget::of_scene(&scene);
        let feed = CameraFeed::default();
        let small: Vec<[f32; 3]> = (0..56 * 56)
            .map(|k| [(k % 56) as f32 * 0.0045, (k / 56) as f32 * 0.0045, 0.0])
            .collect();
        let frame = CloudFrame::new(small.clone(), 7, Pose::IDENTITY).unwrap();
        let kept = budget.hold(frame, &feed).unwrap();
        assert_eq!((kept.points(), kept.timestamp_ns()), (&small[..], 7));
        assert_eq!(feed.budget_counts(), (0, 0));
        let dense: Vec<[f32; 3]> = (0..1_001 * 1_001)
            .map(|k| {
                [
                    (k % 1_001) as f32 * 0.00025,
                    (k / 1_001) as f32 * 0.00025,
                    0.0,
                ]
            })
            .collect();
        let frame = CloudFrame::new(dense, 8, Pose::IDENTITY).unwrap();
        let kept = budget.hold(frame, &feed).unwrap();
        assert_eq!(feed.budget_counts(), (1, 0));
        assert_eq!(kept.timestamp_ns(), 8);
        let limit = CloudBudget::default().max_points(Some(scene.cloud.rate_hz));
        assert!(kept.points().len() <= limit, "{}", kept.points().len());
    }
}
