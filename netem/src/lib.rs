//! # netem — a seeded link model and the UDP shim that applies it
//!
//! What it is:
//! - [`model`]: a **pure link model** of one direction ([`Link`]): delay with ns resolution,
//!   jitter (uniform, normal, pareto, paretonormal, netem `.dist` tables) with optional
//!   correlation, Bernoulli and Gilbert–Elliott loss, duplication, reordering with gap, rate with
//!   per-packet overhead, a queue limit, and order-preserving jitter by default. It follows the
//!   semantics of Linux `sch_netem.c` (network notes §1.2, §2.3), is seeded (one PCG per
//!   direction) and reads no clock: time is an argument, so the same seed gives the same fates.
//! - [`channel`]: [`Channel`], the model carrying values in-process, for the experiment harness.
//! - [`shim`]: the **real-time UDP proxy** (std threads, no async runtime) that applies a link to
//!   each direction between a client and a server, with per-packet CSV log, counters, live
//!   reconfiguration and prompt shutdown. The `netem` binary is a thin command line around
//!   [`shim::run`]; the operator's `demo` starts it in-process with [`shim::start`].
//! - [`units`], [`queue`]: strict parsers for `400ms`/`10mbit`/`1%`, the `(due, seq)` queue. The
//!   clock, the precise wait and the latency histogram are [`rt`]'s.
//!
//! What it is not: not kernel netem (no root, no qdisc; it proxies one UDP flow), not a QUIC
//! endpoint, not a packet corrupter (netem's `corrupt` shows up as loss for QUIC), and not a
//! model of slots, ATM cells or netem's 4-state loss model.

pub mod channel;
pub mod model;
pub mod queue;
pub mod shim;
pub mod units;

pub use channel::Channel;
pub use model::{
    ConfigError, Delivery, DistTable, Distribution, DropReason, Fate, Link, LinkConfig,
    LinkCounters, Loss,
};
pub use shim::{Direction, ShimConfig, ShimHandle, ShimStats};
