//! # mmt — the model-mediated teleoperation core
//!
//! What it is: the environment model and its sign convention ([`model`]), point clouds
//! ([`cloud`]: frames, synthetic sources, PLY/PCD files, voxel grid), the proxy contact detector
//! ([`contact`]), the back-solve and gates, the state-variable filters and the RLS estimator, the
//! renderer, the simulated environment (ground truth), and — in later modules — scenes,
//! trajectories, metrics and the two nodes (telerobot, operator) with the in-process
//! experiment harness.
//!
//! What it is not: no I/O. It reads no clock, opens no socket, spawns no thread and touches no
//! device; time and randomness are arguments, so a run with the same inputs gives the same bits.
//! (One exception, kept apart: [`cloud::format::load_path`] reads a point-cloud file.)
//! The thin `mmt` binary (`src/main.rs`) does the printing, file writing and timing.

pub mod analysis;
pub mod cloud;
pub mod contact;
pub mod estimator;
pub mod experiment;
pub mod filter;
pub mod model;
pub mod node;
pub mod render;
pub mod report;
pub mod rls;
pub mod scene;
pub mod sim;
pub mod trajectory;
mod vec3;

#[cfg(test)]
mod testutil;
