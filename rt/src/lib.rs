//! # rt — time: the clock, the precise wait, real-time threads, loop schedules and histograms
//!
//! What it is (`DESIGN.md` §2, network notes §0.2 and §3.5):
//! - [`clock`]: the one clock of the system, [`monotonic_ns`] (`CLOCK_MONOTONIC` as `i64`
//!   nanoseconds, what every message is stamped with), and the precise wait on it
//!   ([`sleep_until_ns`]: sleep until `deadline − spin`, then spin);
//! - [`thread`]: real-time threads — timer slack, `SCHED_FIFO` priority, [`spawn`];
//! - [`Periodic`]: the schedule of a 1 kHz loop on its own OS thread — **absolute deadlines**
//!   (`start + k·period`, so lateness never accumulates), a short busy-spin (configurable, at
//!   most [`MAX_SPIN_NS`]: the demo and the tests share two cores between two spinning loops and
//!   the netem scheduler). Never tokio timers: they are millisecond-coarse (measured 1.4 ms late
//!   at the median).
//! - [`LoopTiming`]: what the loop's timing was — period, lateness and work-time histograms,
//!   overruns and skipped ticks — readable from any thread while the loop runs ([`TimingReport`]);
//! - [`Histogram`] and [`Summary`]: the one lock-free latency histogram and the one summary form
//!   (count, mean, p50/p90/p99, max in µs) every report prints;
//! - [`Shutdown`]: one stop signal for the real-time thread (an atomic it polls each tick), the
//!   helper threads (a blocking wait) and the network tasks (an async wait), fired by the caller or
//!   by Ctrl-C / SIGTERM ([`Shutdown::on_signals`]).
//!
//! - [`out`]: a run's output directory, checked before the run ([`OutDir::prepare`]), its
//!   files written atomically, its streams flushed as the run goes;
//! - [`exit::message`]: the one line a binary prints when it stops on an error (each cause once).
//!
//! What it is not: no knowledge of nodes, devices, links or the network. The netem shim, the
//! QUIC transport and both daemons take their time from here.

pub mod clock;
pub mod exit;
mod histogram;
pub mod out;
pub mod outage;
mod periodic;
mod shutdown;
pub mod thread;
mod timing;

pub use clock::{monotonic_ns, sleep_until_ns};
pub use histogram::{Histogram, Summary};
pub use out::{OutDir, OutError};
pub use outage::Outages;
pub use periodic::{MAX_SPIN_NS, Periodic, PeriodicConfig, PeriodicError, Tick};
pub use shutdown::Shutdown;
pub use thread::spawn;
pub use timing::{LoopTiming, TimingReport};
