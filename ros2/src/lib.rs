//! # ros2 — the telerobot and the operator on a ROS 2 graph, from pure Rust
//!
//! What it is: everything this system needs to meet robots, cameras and haptic devices that
//! speak ROS 2, with no ROS installed — `ros2-client` on RustDDS, interoperating with ROS 2's
//! DDS middlewares (`rmw_fastrtps_cpp`, `rmw_cyclonedds_cpp`; ROS names on DDS: `rt/…` topics,
//! `pkg::msg::dds_::Type_` types, XCDR1):
//! - [`msg`]: the standard messages with ROS 2's type names and CDR layout;
//! - [`pointcloud2`]: `sensor_msgs/PointCloud2` of any field layout → points in the base frame,
//!   voxel grid and point budget;
//! - [`graph`]: the domain (`ROS_DOMAIN_ID`, `--ros-domain`), topic names, QoS;
//! - [`state`]: pose + twist + wrench → one robot state per header stamp, checked and counted
//!   (the frame and sign conventions are stated there);
//! - [`topics`]: the bridge's topics, their defaults and remapping, `/mmt/theta`'s labels;
//! - [`bridge`]: [`Ros2Bridge`], the robot bridge (`telerobot run --robot ros2`), with its
//!   DDS I/O on a thread of its own;
//! - [`camera`]: a camera's PointCloud2 topic → the contact detector's cloud frames;
//! - [`arm`]: the test arm, a simulated robot on the graph (tests, figures, `mmt-test-arm`);
//! - [`haptic`]: the operator's haptic device on the graph (`operator run --device ros2`,
//!   forcedimension_ros2's topics by default), with its DDS I/O on a thread of its own;
//! - [`fd_double`]: a stand-in for forcedimension_ros2 on the graph (tests);
//!
//! What it is not: no estimation, contact or wire protocol of its own (`mmt`, `node`,
//! `protocol`, none of which depends on this crate or on DDS).

pub mod arm;
pub mod bridge;
pub mod camera;
pub mod fd_double;
pub mod graph;
pub mod haptic;
pub mod msg;
pub mod pointcloud2;
pub mod state;
pub mod topics;

pub use bridge::{BridgeConfig, BridgeMonitor, BridgeReport, ModelOutlet, Ros2Bridge};
pub use camera::{CameraConfig, CameraReport, CameraSource};
pub use graph::{Graph, GraphConfig, GraphError, Qos, TopicName};
