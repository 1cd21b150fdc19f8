//! Starting the camera thread on the scene's `[cloud]` source: the simulated camera, a PLY/PCD
//! file (read here, so that a bad one is refused at start) or a camera on a ROS 2 graph
//! (subscribed here).

use std::sync::Arc;
use std::thread::JoinHandle;

use rt::Shutdown;
use sim::camera::Camera;
use sim::scene::CloudKind;
use sim::world::World;

use super::{CameraFeed, FileCloud, Source};
use crate::daemon::{DaemonError, RunConfig};
use crate::net::TelerobotLink;
use crate::robot::RobotConfig;

/// The camera thread, when the scene has a cloud (simulated, from a file or from a ROS 2
/// camera on `graph` or the environment's domain): it sends the frames into `feed` and on `link`.
/// With a ROS 2 camera, its counters.
pub(crate) fn start(
    config: &RunConfig,
    graph: Option<&ros2::Graph>,
    feed: &Arc<CameraFeed>,
    link: &TelerobotLink,
    stop: &Shutdown,
) -> Result<CameraStarted, DaemonError> {
    let (source, counters) = camera_source(config, graph)?;
    let Some(source) = source else {
        return Ok((None, None));
    };
    let camera = super::spawn(
        source,
        super::FrameBudget::of_scene(&config.scene),
        Arc::clone(feed),
        link.clone(),
        config.record.clone(),
        stop.clone(),
    )
    .map_err(|source| DaemonError::Io {
        what: "the camera thread",
        source,
    })?;
    Ok((Some(camera), counters))
}

/// The camera thread, if any, and a ROS 2 camera's counters.
type CameraStarted = (
    Option<JoinHandle<()>>,
    Option<Arc<ros2::camera::CameraCounters>>,
);

/// The camera thread's source for the scene's `[cloud]`; `None`: no cloud. A cloud file is read
/// and a camera topic subscribed here, so that a bad one is refused at start. A ROS 2 camera
/// joins the robot's graph if there is one, else the domain of `ROS_DOMAIN_ID`.
fn camera_source(
    config: &RunConfig,
    graph: Option<&ros2::Graph>,
) -> Result<(Option<Source>, Option<Arc<ros2::camera::CameraCounters>>), DaemonError> {
    let scene = &config.scene;
    let geometry = World::new(scene, config.start_m, config.seed)?;
    let source = match scene.cloud.source {
        CloudKind::None => None,
        CloudKind::Plane => Some(Source::Simulated(
            Box::new(Camera::new(scene, config.seed)),
            Box::new(geometry),
        )),
        CloudKind::File => {
            let file = FileCloud::load(scene, &geometry)?;
            let i = file.info();
            tracing::info!(file = %i.path.display(), read = i.read,
                skipped_non_finite = i.skipped_non_finite, kept = i.kept, voxel_m = ?i.voxel_m,
                budget_acted = i.budget_acted, moving = scene.cloud.moving, "cloud from a file");
            if let Some(fit) = &i.real_time {
                tracing::warn!(file = %i.path.display(), "cloud file {}: {fit}", i.path.display());
            }
            Some(Source::File(Box::new(file)))
        }
        CloudKind::Ros2 => {
            let camera = ros2_camera(config, graph)?;
            let counters = camera.counters();
            return Ok((Some(Source::Ros2(Box::new(camera))), Some(counters)));
        }
    };
    Ok((source, None))
}

/// The scene's ROS 2 camera: its topic (the scene's, else the robot's `camera_points`, else
/// `/mmt/camera/points`), pose, voxel grid and budget.
fn ros2_camera(
    config: &RunConfig,
    graph: Option<&ros2::Graph>,
) -> Result<ros2::CameraSource, DaemonError> {
    let c = &config.scene.cloud;
    let topic = match (&c.topic, &config.robot) {
        (Some(t), _) => ros2::TopicName::parse("cloud.topic", t)?,
        (None, RobotConfig::Ros2 { bridge, .. }) => bridge.topics.camera_points.clone(),
        (None, RobotConfig::Sim) => ros2::topics::RobotTopics::default().camera_points,
    };
    let graph = match graph {
        Some(g) => g.clone(),
        None => ros2::Graph::join(&ros2::GraphConfig::from_env(None)?)?,
    };
    let camera = ros2::CameraSource::start(
        &graph,
        ros2::CameraConfig {
            topic: topic.clone(),
            qos: ros2::Qos::STREAM,
            pipeline: ros2::pointcloud2::PipelineConfig {
                // Validated with the scene.
                camera_to_base: c.pose.pose().unwrap_or_default(),
                voxel_m: c.voxel_m,
                max_points: c.max_points,
            },
            stale_ns: (c.stale_ms * 1e6).round() as i64,
        },
    )?;
    tracing::info!(%topic, domain = graph.config().domain_id, voxel_m = ?c.voxel_m,
        max_points = c.max_points, stale_ms = c.stale_ms,
        "cloud from a ROS 2 camera (sensor_msgs/PointCloud2, best-effort)");
    Ok(camera)
}
