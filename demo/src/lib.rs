//! # demo — the whole system in one process
//!
//! What it is: the README's first command. Throw-away certificates, the telerobot daemon on the
//! built-in exp-1 scene, the netem shim delaying each direction, and the operator app with the
//! scripted exp-1 device, all over real loopback QUIC/UDP in one process ([`run`]); then the
//! report ([`report`]: the operator's figures plus the telerobot's and the shim's), its series
//! and its plots.
//!
//! ```text
//!  operator app ──QUIC/UDP──▶ netem shim (delay each way) ──▶ telerobot daemon
//!  127.0.0.1:*                127.0.0.1:*                      127.0.0.1:*
//! ```
//!
//! What it is not: no code path of its own. It starts the daemons exactly as `telerobot run` and
//! `operator run` do; it sits above both so that neither daemon depends on the other.

pub mod cli;
pub mod report;
pub mod run;
pub mod soak;

pub use report::{DemoReport, ShimReport};
pub use run::{DemoConfig, DemoError, Outcome};
