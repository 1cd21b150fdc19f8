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

/// Logging for the demo's binaries: stderr, warnings only by default (their stdout is the
/// report) and the safety layer's per-episode events (counted in the report) not at all;
/// `RUST_LOG` overrides. Colour only on a terminal: a log file or a pipe gets plain text.
pub fn init_logging() {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
                tracing_subscriber::EnvFilter::new("warn,operator::safety=error")
            }),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
}
