//! # transport — the QUIC plumbing the telerobot and operator daemons share
//!
//! What it is:
//! - [`identity`]: self-signed certificates and keys made with `rcgen`, as PEM files
//!   (`DIR/<name>.crt`, `DIR/<name>.key` with mode 0600), read back with errors naming the file;
//! - [`pin`]: **both sides pinned** — custom rustls verifiers that accept exactly the given peer
//!   certificates (exact DER) and still verify the TLS 1.3 handshake signatures (ring);
//! - [`tuning`]: quinn transport settings for 1 kHz datagrams over 400 ms links (fixed-window
//!   congestion controller, relaxed loss thresholds, small datagram send buffer, `initial_rtt`
//!   from a delay hint, keep-alive below the idle timeout);
//! - [`endpoint`]: the server and client configurations (TLS 1.3 only, ALPN, no resumption, no
//!   0-RTT), application close codes, and certificate refusals in words;
//! - [`framing`]: length-prefixed messages on the control stream, one stream per cloud frame;
//! - [`handoff`]: the **lock-free hand-off** between a real-time thread and the network task
//!   (bounded queues that drop the oldest, latest-value slots, a doorbell) — read its contract;
//! - [`stats`]: link counters as atomics, and the per-connection datagram bookkeeping over
//!   `protocol::session`;
//! - [`report`]: the report form of the link counters;
//! - [`status`]: the session status both daemons' loops read (connected, session number, since
//!   when), each daemon adding its own;
//! - [`address`]: the daemons' `--listen` / `--connect` addresses, parsed with examples in the
//!   error;
//! - [`network_runtime`]: the one-worker tokio runtime of a daemon's network task.
//!
//! The clock every stamp is read from is [`rt::monotonic_ns`].
//!
//! What it is not: no session logic of its own (sequence numbers, RTT, clock offset and the
//! handshake checks are `protocol`'s), no message types, no real-time loop, and no policy about
//! who may connect (the telerobot's `net` module decides; this crate only enforces the pins).
//! The daemons' network tasks (`telerobot::net`, `operator::net`) are built from these pieces.

pub mod address;
pub mod endpoint;
pub mod framing;
pub mod handoff;
pub mod identity;
pub mod pin;
pub mod report;
pub mod stats;
pub mod status;
pub mod tuning;

pub use endpoint::{ALPN, CloseCode, EndpointError, FRAMING_VERSION, SERVER_NAME};
pub use handoff::{Mailbox, Outbox, Received};
pub use identity::{Identity, IdentityError};
pub use pin::{OperatorPins, TelerobotPin};
pub use report::LinkReport;
pub use rt::Outages;
pub use stats::{DatagramLink, LinkSnapshot, LinkStats};
pub use status::{SessionCore, SessionRecorder};
pub use tuning::{Congestion, LinkTuning};

/// The network runtime of a daemon: tokio with one worker thread named `name` (the QUIC
/// endpoint's few thousand datagrams a second need no more; the cores are the loops').
pub fn network_runtime(name: &str) -> std::io::Result<tokio::runtime::Runtime> {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .thread_name(name)
        .enable_all()
        .build()
}
