//! # operator — the operator side of the teleoperation system
//!
//! What it is:
//! - [`app`]: the operator app — [`app::run`], what `operator run` calls: the QUIC client, the
//!   1 kHz haptic loop ([`haptic`]) stepping the operator node (`node`) exactly as the in-process
//!   harness does, its helper thread ([`helper`]), and the report ([`report`]): `mmt
//!   experiment`'s figures plus `measured_delay_ms`, loop timing and link statistics;
//! - [`demo`]: the whole system in one process over loopback (the README's first command);
//! - [`device`]: haptic devices behind one trait with simulated twins; [`safety`]: the one safety
//!   layer between renderer and device;
//! - [`net`]: the QUIC client with its lock-free hand-off to the haptic loop (the node's
//!   settings come from the telerobot's `Welcome`, `node::OperatorSettings::from_welcome`);
//! - [`cli`]: the command-line entry points of the `operator` binary.
//!
//! What it is not: no rendering or estimation logic of its own (that is `mmt`), no wire format
//! (that is `protocol`). Nothing here reads a clock inside the device and safety layers: `now` is
//! passed in, so every rule is tested without one.

pub mod app;
pub mod cli;
pub mod demo;
pub mod device;
pub mod haptic;
pub mod helper;
pub mod net;
pub mod report;
pub mod safety;
