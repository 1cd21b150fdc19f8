//! The `ros2` backend: a haptic device driven over ROS 2 (`ros2::haptic`, forcedimension_ros2's
//! topics by default), from pure Rust with no ROS installed.
//!
//! - **open**: joins the graph, starts the device's I/O thread (forces off) and waits for the
//!   first valid pose ([`RosOptions::first_pose_timeout`]); none is an error naming the topic,
//!   the domain and what arrived instead. The loop therefore starts from a real pose.
//! - **read**, once per tick: the newest checked sample (lock-free), the button as the clutch.
//!   When the newest valid pose *arrived* more than [`HapticConfig::stale_after`] ago (50 ms,
//!   the telerobot's stale-state rule; measured from its receipt by the I/O thread, so a pose
//!   that was already old when the loop first took it is stale at once), the read fails with
//!   [`DeviceError::StalePose`], which faults the device (zero force, forces off, logged once);
//!   the reading holds the last pose.
//! - **write**: hands the force to the I/O thread, which publishes it only once a pose has
//!   arrived, and as zero while the pose is stale or forces are off (`ros2::haptic`).
//! - **close** (the run's end): zero, then the I/O thread stops, so that the report built
//!   after it counts every command published, the closing zero included.
//!
//! Limits: the omega.7's ([`DeviceCapabilities::omega7`]), as `--device omega`: the defaults
//! are an Omega's driver's (which caps forces at 12 N itself). Frame: the pose's (`fd_base`,
//! the SDK's frame, as `--device omega`).
//!
//! The one clock read here is the monotonic clock ([`rt::monotonic_ns`], no system call, no
//! allocation) in `read`: a sample's receipt time is on it. The loop's `now` is not used for
//! staleness: its origin moves (the first read is at `now` = 0, before the loop's schedule
//! starts), and the time a sample was *taken* says nothing of how old it was.

use std::sync::Arc;
use std::time::Duration;

use mmt::vec3::Vec3;
use ros2::haptic::{DeviceSample, HapticConfig, RosHaptic};
use ros2::{Graph, GraphConfig};

use super::{Backend, BackendReport, DeviceCapabilities, DeviceError, DeviceReading};

/// ROS 2 device settings.
#[derive(Clone, Debug, PartialEq)]
pub struct RosOptions {
    /// Domain and discovery; `None`: `ROS_DOMAIN_ID` and `ROS_LOCALHOST_ONLY` at open.
    pub graph: Option<GraphConfig>,
    /// Topics, QoS, command layout, checks.
    pub device: HapticConfig,
    /// How long open waits for the first valid pose. Default 5 s: DDS discovery takes a few
    /// hundred milliseconds on one host, a second or two across a network.
    pub first_pose_timeout: Duration,
}

impl Default for RosOptions {
    fn default() -> Self {
        RosOptions {
            graph: None,
            device: HapticConfig::default(),
            first_pose_timeout: Duration::from_secs(5),
        }
    }
}

/// The device on a ROS 2 graph.
pub struct RosBackend {
    io: RosHaptic,
    capabilities: DeviceCapabilities,
    pose_topic: Arc<str>,
    /// [`HapticConfig::stale_after`].
    stale_after: Duration,
    /// The newest sample taken.
    latest: Option<DeviceSample>,
}

impl RosBackend {
    /// Joins the graph, starts the device and waits for its first valid pose.
    pub fn open(options: &RosOptions) -> Result<RosBackend, DeviceError> {
        let graph_config = match &options.graph {
            Some(g) => g.clone(),
            None => GraphConfig::from_env(None).map_err(ros2::haptic::HapticError::from)?,
        };
        let graph = Graph::join(&graph_config).map_err(ros2::haptic::HapticError::from)?;
        let io = RosHaptic::start(&graph, options.device.clone())?;
        tracing::info!(topics = %io.describe(), "ROS 2 device: waiting for its first pose");
        io.wait_for_pose(options.first_pose_timeout)?;
        let mut capabilities =
            DeviceCapabilities::omega7(format!("ROS 2 device, {}", io.describe()));
        capabilities.outputs_force = io.writes_force();
        Ok(RosBackend {
            pose_topic: Arc::from(io.pose_topic()),
            io,
            capabilities,
            stale_after: options.device.stale_after,
            latest: None,
        })
    }
}

impl Backend for RosBackend {
    fn capabilities(&self) -> &DeviceCapabilities {
        &self.capabilities
    }

    fn read(&mut self, _now: Duration) -> Result<DeviceReading, DeviceError> {
        if let Some(s) = self.io.take_sample() {
            self.latest = Some(s);
        }
        // Open waited for a pose: none is a pose that never arrived (infinitely old).
        let age = self.latest.map_or(Duration::MAX, |s| {
            let age_ns = rt::monotonic_ns().saturating_sub(s.received_ns);
            Duration::from_nanos(u64::try_from(age_ns).unwrap_or(0))
        });
        let Some(s) = self.latest.filter(|_| age <= self.stale_after) else {
            return Err(DeviceError::StalePose {
                topic: Arc::clone(&self.pose_topic),
                age,
                limit: self.stale_after,
            });
        };
        Ok(DeviceReading {
            position_m: s.position_m,
            velocity_m_per_s: s.velocity_m_per_s,
            clutch: self.io.button(),
        })
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        // Finite already (`ManagedDevice`); the I/O thread zeroes anything else regardless.
        self.io.command(force_n);
        Ok(())
    }

    fn set_force_enabled(&mut self, on: bool) -> Result<(), DeviceError> {
        self.io.set_forces(on);
        Ok(())
    }

    fn report(&self) -> Option<BackendReport> {
        Some(BackendReport::Ros2(Box::new(self.io.report())))
    }

    fn close(&mut self) {
        self.io.close();
    }
}
