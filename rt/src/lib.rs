//! # rt — the real-time loop both daemons run
//!
//! What it is (`DESIGN.md` §2, network notes §0.2 and §3.5):
//! - [`Periodic`]: the schedule of a 1 kHz loop on its own OS thread — **absolute deadlines**
//!   (`start + k·period`, so lateness never accumulates), a `sleep` until `deadline − spin`, then a
//!   short busy-spin (configurable, at most [`MAX_SPIN_NS`]: the demo and the tests share two cores
//!   between two spinning loops and the netem scheduler). Never tokio timers: they are
//!   millisecond-coarse (measured 1.4 ms late at the median).
//! - [`LoopTiming`]: what the loop's timing was — period, lateness and work-time histograms
//!   (lock-free, allocated once), overruns and skipped ticks — readable from any thread while the
//!   loop runs, summarised as a [`TimingReport`].
//! - [`Shutdown`]: one stop signal for the real-time thread (an atomic it polls each tick), the
//!   helper threads (a blocking wait) and the network tasks (an async wait), fired by the caller or
//!   by Ctrl-C / SIGTERM ([`Shutdown::on_signals`]).
//! - [`LatencyReport`], [`LinkReport`]: the report forms of latency histograms and link counters.
//! - [`network_runtime`]: the one-worker tokio runtime of a daemon's network task.
//! - [`spawn`]: starts a named loop thread with a 1 ns timer slack and, if asked, `SCHED_FIFO`.
//!
//! What it is not: no knowledge of nodes, devices or the network. The clock is
//! `transport::clock::monotonic_ns`, the one both daemons stamp messages with.

mod periodic;
mod report;
mod shutdown;
mod timing;

pub use periodic::{MAX_SPIN_NS, Periodic, PeriodicConfig, PeriodicError, Tick, sleep_until_ns};
pub use report::{LatencyReport, LinkReport};
pub use shutdown::Shutdown;
pub use timing::{LoopTiming, Quantiles, TimingReport};

use std::io;
use std::thread::JoinHandle;

/// The network runtime of a daemon: tokio with one worker thread named `name` (the QUIC
/// endpoint's few thousand datagrams a second need no more; the cores are the loops').
pub fn network_runtime(name: &str) -> io::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name(name)
        .enable_all()
        .build()
}

/// Starts `body` on a new OS thread named `name`, with its timer slack at 1 ns (the default 50 µs
/// lets the kernel wake a sleeper that much late) and, with `priority = Some(p)`, under
/// `SCHED_FIFO` at `p` (needs `CAP_SYS_NICE`; refused → a warning, the loop runs anyway).
pub fn spawn<F, T>(name: &str, priority: Option<u8>, body: F) -> io::Result<JoinHandle<T>>
where
    F: FnOnce() -> T + Send + 'static,
    T: Send + 'static,
{
    let thread_name = name.to_owned();
    std::thread::Builder::new()
        .name(thread_name.clone())
        .spawn(move || {
            netem::clock::set_timer_slack_ns(1);
            if let Some(p) = priority
                && let Err(e) = netem::clock::set_realtime_priority(p)
            {
                tracing::warn!(thread = %thread_name, priority = p,
                    "SCHED_FIFO refused ({e}); running at normal priority");
            }
            body()
        })
}
