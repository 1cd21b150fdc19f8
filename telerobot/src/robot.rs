//! Which robot the daemon drives (`--robot sim|ros2`), and building its bridge.
//!
//! - `sim` (default): the scene's simulated world (`sim::SimBridge`).
//! - `ros2`: a robot on a ROS 2 graph (`ros2::Ros2Bridge`): its pose, twist and wrench in, the
//!   commanded pose out, the model and contact state published.
//!
//! Either way the daemon puts the same motion guard (`node::Guarded`) around it.

use node::{RobotBridge, TelerobotSettings};
use ros2::{BridgeConfig, BridgeMonitor, Graph, GraphConfig, ModelOutlet, Ros2Bridge};
use sim::scene::Scene;

use crate::daemon::DaemonError;

/// The robot, as configured.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum RobotConfig {
    /// The scene's simulated world.
    #[default]
    Sim,
    /// A robot on a ROS 2 graph.
    Ros2 {
        /// Domain and discovery.
        graph: GraphConfig,
        /// Topics, QoS, conventions.
        bridge: Box<BridgeConfig>,
    },
}

/// A bridge built, with what the daemon keeps of it.
pub(crate) struct Built {
    pub(crate) bridge: Box<dyn RobotBridge>,
    pub(crate) outlet: Option<ModelOutlet>,
    pub(crate) monitor: Option<BridgeMonitor>,
    /// The ROS 2 participant, shared with a ROS 2 camera.
    pub(crate) graph: Option<Graph>,
    /// For the start log.
    pub(crate) description: String,
}

/// Builds the bridge of `robot` for `scene`, the tool (simulated) starting at `start_m`.
pub(crate) fn build(
    robot: &RobotConfig,
    scene: &Scene,
    settings: &TelerobotSettings,
    start_m: [f64; 3],
    seed: u64,
    graph: Option<Graph>,
) -> Result<Built, DaemonError> {
    match robot {
        RobotConfig::Sim => Ok(Built {
            bridge: Box::new(sim::SimBridge::new(scene, start_m, seed)?),
            outlet: None,
            monitor: None,
            graph,
            description: "simulated bridge".into(),
        }),
        RobotConfig::Ros2 {
            graph: graph_config,
            bridge,
        } => {
            let graph = match graph {
                Some(g) => g,
                None => Graph::join(graph_config)?,
            };
            let ros = Ros2Bridge::start(&graph, (**bridge).clone())?;
            let rate = 1e9 / settings.period_ns as f64;
            let description = format!(
                "ROS 2 bridge, domain {}{}: {}; QoS state {}, commands {}, model {}; the \
                 estimator's filters are discretised at {rate} Hz ({} Hz cut-off): states should \
                 arrive at that rate, at least {} Hz; nothing is commanded before the first state",
                graph.config().domain_id,
                if graph.config().localhost_only {
                    " (localhost only)"
                } else {
                    ""
                },
                bridge.topics.describe(),
                bridge.state_qos,
                bridge.command_qos,
                bridge.settings_qos,
                settings.tangential.filter.svf.cutoff_hz,
                MIN_STATE_RATE_HZ,
            );
            Ok(Built {
                outlet: Some(ros.outlet()),
                monitor: Some(ros.monitor()),
                bridge: Box::new(ros),
                graph: Some(graph),
                description,
            })
        }
    }
}

/// The slowest state stream the shipped estimator settings work with \[Hz\] (measured: see the
/// README's ROS 2 section).
pub const MIN_STATE_RATE_HZ: f64 = 500.0;

/// The robot's command-line options (flattened into `telerobot run`).
#[derive(Clone, Debug, Default, clap::Args)]
pub struct RobotArgs {
    /// The robot: `sim` (the scene's simulated world) or `ros2` (a robot on a ROS 2 graph).
    #[arg(long, value_name = "KIND", default_value = "sim", value_parser = ["sim", "ros2"])]
    pub robot: String,
    /// ROS 2 domain id (0-232); default ROS_DOMAIN_ID, else 0.
    #[arg(long, value_name = "N")]
    pub ros_domain: Option<u16>,
    /// Remap a topic, KEY=/name (keys: robot_pose, robot_twist, robot_wrench, target_pose,
    /// target_twist, theta, in_contact, camera_points; robot_twist=none: the driver gives no
    /// twist; target_twist=none: publish no commanded twist). Repeatable.
    #[arg(long = "topic", value_name = "KEY=/NAME")]
    pub topics: Vec<String>,
    /// QoS of one kind of topic, KIND=SPEC with KIND state, command or settings and SPEC e.g.
    /// reliable,transient-local,keep-last-1. Repeatable.
    #[arg(long = "qos", value_name = "KIND=SPEC")]
    pub qos: Vec<String>,
    /// Frame of the wrench: base (the pose's frame) or tool (rotated by the pose).
    #[arg(long, value_name = "FRAME", default_value = "base", value_parser = ["base", "tool"])]
    pub wrench_frame: String,
    /// Sign of the wrench: on-tool (the force the environment exerts on the tool) or by-tool
    /// (the force the tool exerts, negated).
    #[arg(long, value_name = "SIGN", default_value = "on-tool", value_parser = ["on-tool", "by-tool"])]
    pub wrench_sign: String,
    /// frame_id of the commanded pose (default: the measured pose's frame).
    #[arg(long, value_name = "FRAME")]
    pub command_frame: Option<String>,
    /// Workspace box in the base frame, MINX,MINY,MINZ,MAXX,MAXY,MAXZ [m] (default: the scene's
    /// [limits], else the surface point ± 0.25 m).
    #[arg(long, value_name = "BOX", allow_hyphen_values = true)]
    pub workspace: Option<String>,
    /// Largest move between consecutive commands, per tick [m] (default: the scene's, else
    /// 0.001).
    #[arg(long, value_name = "M", allow_hyphen_values = true)]
    pub max_step_m: Option<f64>,
    /// Largest commanded speed [m/s] (default: the scene's, else 1.0).
    #[arg(long, value_name = "M_PER_S", allow_hyphen_values = true)]
    pub max_speed: Option<f64>,
}

/// A robot option that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum RobotArgsError {
    /// A ROS 2 option with `--robot sim`.
    #[error("{flag} applies to --robot ros2 only")]
    NotRos2 {
        /// The flag.
        flag: &'static str,
    },
    /// A ROS 2 setting.
    #[error(transparent)]
    Graph(#[from] ros2::GraphError),
    /// `--workspace` is not six numbers.
    #[error("--workspace {0:?}: expected six numbers MINX,MINY,MINZ,MAXX,MAXY,MAXZ in metres")]
    Workspace(String),
    /// A limit out of range.
    #[error(transparent)]
    Limits(#[from] node::guard::LimitsError),
}

impl RobotArgs {
    /// The robot, validated.
    pub fn robot_config(&self) -> Result<RobotConfig, RobotArgsError> {
        if self.robot == "sim" {
            let used = [
                ("--ros-domain", self.ros_domain.is_some()),
                ("--topic", !self.topics.is_empty()),
                ("--qos", !self.qos.is_empty()),
                ("--wrench-frame", self.wrench_frame != "base"),
                ("--wrench-sign", self.wrench_sign != "on-tool"),
                ("--command-frame", self.command_frame.is_some()),
            ];
            if let Some((flag, _)) = used.iter().find(|(_, used)| *used) {
                return Err(RobotArgsError::NotRos2 { flag });
            }
            return Ok(RobotConfig::Sim);
        }
        let graph = GraphConfig::from_env(self.ros_domain)?;
        let mut bridge = BridgeConfig::default();
        for rule in &self.topics {
            bridge.topics.remap(rule)?;
        }
        ros2::topics::apply_qos_rules(
            &self.qos,
            &mut [
                ("state", &mut bridge.state_qos),
                ("command", &mut bridge.command_qos),
                ("settings", &mut bridge.settings_qos),
            ],
        )?;
        bridge.state.twist = bridge.topics.robot_twist.is_some();
        bridge.state.wrench_frame = match self.wrench_frame.as_str() {
            "tool" => ros2::state::WrenchFrame::Tool,
            _ => ros2::state::WrenchFrame::Base,
        };
        bridge.state.wrench_sign = match self.wrench_sign.as_str() {
            "by-tool" => ros2::state::WrenchSign::ByTool,
            _ => ros2::state::WrenchSign::OnTool,
        };
        bridge.command_frame.clone_from(&self.command_frame);
        Ok(RobotConfig::Ros2 {
            graph,
            bridge: Box::new(bridge),
        })
    }

    /// The scene's command limits with the flags over them, validated.
    pub fn limits(&self, scene: &Scene) -> Result<node::MotionLimits, RobotArgsError> {
        let mut l = scene.motion_limits();
        if let Some(text) = &self.workspace {
            let v: Vec<f64> = text
                .split(',')
                .map(|p| p.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| RobotArgsError::Workspace(text.clone()))?;
            let [a, b, c, d, e, f] = v[..] else {
                return Err(RobotArgsError::Workspace(text.clone()));
            };
            l.workspace_min_m = [a, b, c];
            l.workspace_max_m = [d, e, f];
        }
        if let Some(v) = self.max_step_m {
            l.max_step_m = v;
        }
        if let Some(v) = self.max_speed {
            l.max_speed_m_per_s = v;
        }
        l.validate()?;
        Ok(l)
    }
}
