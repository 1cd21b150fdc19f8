//! # telerobot — the telerobot daemon
//!
//! What it is:
//! - [`daemon`]: the daemon — [`Telerobot::start`] / [`Telerobot::stop`], and [`run`] around a
//!   shutdown signal (what `telerobot run` calls): the network runtime, the 1 kHz loop, the camera
//!   thread and a housekeeping thread;
//! - [`control`]: the real-time loop stepping the telerobot node (`node`) against the robot bridge,
//!   exactly as the in-process harness steps it (`lab::experiment`);
//! - [`robot`]: the robot, any `node::RobotBridge` behind the motion guard (`node::guard`) —
//!   the scene's simulated world (`sim::SimBridge`) or a ROS 2 robot (`ros2::Ros2Bridge`);
//! - [`camera`]: the simulated camera and its kd-tree, off the real-time thread;
//! - [`net`]: the QUIC server and its lock-free hand-off to the loop;
//! - [`cli`]: the command line of the `telerobot` binary.
//!
//! What it is not: no estimation logic of its own (that lives in the telerobot node), no wire
//! format (that is `protocol`), no QUIC plumbing shared with the operator (that is `transport`),
//! no loop timing of its own (that is `rt`).

pub mod camera;
pub mod cli;
pub mod control;
pub mod daemon;
pub mod net;
mod recording;
pub mod robot;
mod watch;

pub use daemon::{DaemonError, RunConfig, Summary, Telerobot, run};
