//! # operator — the operator side of the teleoperation system
//!
//! What it is:
//! - [`app`]: the operator app — [`app::run`], what `operator run` calls: the QUIC client, the
//!   1 kHz haptic loop ([`haptic`]) stepping the operator node (`node`) exactly as the in-process
//!   harness does, its helper thread ([`helper`]), and the report ([`report`]): `mmt
//!   experiment`'s figures plus `measured_delay_ms`, loop timing and link statistics;
//! - [`device`]: haptic devices behind one trait with simulated twins; [`safety`]: the one safety
//!   layer between renderer and device;
//! - [`net`]: the QUIC client with its lock-free hand-off to the haptic loop (the node's
//!   settings come from the telerobot's `Welcome`, `node::OperatorSettings::from_welcome`);
//! - [`cli`]: the command-line entry points of the `operator` binary.
//!
//! What it is not: no rendering or estimation logic of its own (that is `mmt` and `node`), no
//! wire format (that is `protocol`), no telerobot (the two daemons are peers; the `demo` crate
//! runs both in one process) and no plots (`lab` draws them from the files this app writes). Nothing here reads a clock inside the device and safety layers: `now` is
//! passed in, so every rule is tested without one.

pub mod app;
pub mod cli;
pub mod device;
pub mod haptic;
pub mod helper;
pub mod net;
pub mod report;
pub mod safety;
