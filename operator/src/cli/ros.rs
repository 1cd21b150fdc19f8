//! `operator run`'s ROS 2 device options (`--device ros2`): the flags of the telerobot's
//! `--robot ros2` — `--ros-domain`, `--topic KEY=/name`, `--qos KIND=SPEC` — over the device's
//! topics, parsed by the same code (`ros2::graph`, `ros2::topics`).

use clap::Args;
use ros2::GraphConfig;
use ros2::haptic::{CommandLen, ExpectedFrame, HapticConfig, HapticError};

use crate::device::DeviceSpec;
use crate::device::ros::RosOptions;

/// The ROS 2 device's options.
#[derive(Clone, Debug, Default, Args)]
pub struct RosArgs {
    /// ROS 2 domain id of the device's driver (0-232; --device ros2); default ROS_DOMAIN_ID,
    /// else 0.
    #[arg(long, value_name = "N")]
    pub ros_domain: Option<u16>,
    /// Remap a device topic, KEY=/name (--device ros2). Keys and forcedimension_ros2's
    /// defaults: pose (/fd/ee_pose), twist (none: velocity from the pose), button
    /// (/fd/button_state, the clutch), command (/fd/fd_controller/commands); twist, button and
    /// command take `none` (command=none: NO force is written). Repeatable.
    #[arg(long = "topic", value_name = "KEY=/NAME")]
    pub topics: Vec<String>,
    /// QoS of the device's topics, KIND=SPEC (--device ros2): KIND state (pose, twist, button;
    /// default best-effort,volatile,keep-last-1) or command (default
    /// reliable,volatile,keep-last-1). Repeatable.
    #[arg(long = "qos", value_name = "KIND=SPEC")]
    pub qos: Vec<String>,
    /// Entries of the force command, 3 to 7 (--device ros2): the joints of the driver's force
    /// controller, [fx, fy, fz] then zeros (default 3: forcedimension_ros2's fd_controller).
    #[arg(long, value_name = "N")]
    pub ros_command_len: Option<usize>,
    /// The frame_id the device's poses must have (--device ros2; default fd_base,
    /// forcedimension_ros2's, the frame forces are written in): a pose in another frame is
    /// refused and counted. `any` accepts every frame, unchecked.
    #[arg(long, value_name = "NAME")]
    pub ros_pose_frame: Option<String>,
}

/// A ROS 2 device option that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum RosArgsError {
    /// A ROS 2 option with another device.
    #[error("{flag} applies to --device ros2 only")]
    NotRos2 {
        /// The flag.
        flag: &'static str,
    },
    /// A domain, topic, QoS, command length or pose frame.
    #[error(transparent)]
    Device(#[from] HapticError),
}

impl From<ros2::GraphError> for RosArgsError {
    fn from(e: ros2::GraphError) -> Self {
        RosArgsError::Device(e.into())
    }
}

impl RosArgs {
    /// The ROS 2 device's settings for `device`, validated (the defaults for another device,
    /// which must not be given these flags).
    pub fn options(&self, device: &DeviceSpec) -> Result<RosOptions, RosArgsError> {
        if *device != DeviceSpec::Ros2 {
            let used = [
                ("--ros-domain", self.ros_domain.is_some()),
                ("--topic", !self.topics.is_empty()),
                ("--qos", !self.qos.is_empty()),
                ("--ros-command-len", self.ros_command_len.is_some()),
                ("--ros-pose-frame", self.ros_pose_frame.is_some()),
            ];
            if let Some((flag, _)) = used.iter().find(|(_, used)| *used) {
                return Err(RosArgsError::NotRos2 { flag });
            }
            return Ok(RosOptions::default());
        }
        let graph = GraphConfig::from_env(self.ros_domain)?;
        let mut config = HapticConfig::default();
        for rule in &self.topics {
            config.topics.remap(rule)?;
        }
        ros2::topics::apply_qos_rules(
            &self.qos,
            &mut [
                ("state", &mut config.state_qos),
                ("command", &mut config.command_qos),
            ],
        )?;
        if let Some(n) = self.ros_command_len {
            config.command_len = CommandLen::new(n)?;
        }
        if let Some(frame) = &self.ros_pose_frame {
            config.pose_frame = ExpectedFrame::parse(frame)?;
        }
        Ok(RosOptions {
            graph: Some(graph),
            device: config,
            ..RosOptions::default()
        })
    }
}
