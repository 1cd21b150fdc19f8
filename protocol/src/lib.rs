//! Wire protocol between the operator app and the telerobot daemon (`DESIGN.md` §7).
//!
//! What it is:
//! - the messages, by direction: [`operator_to_telerobot`] and [`telerobot_to_operator`], each
//!   with its `Message` enum and its `encode_into` / `encode` / `decode`;
//! - the one encode/decode pair ([`codec`]): a fixed 2-byte version prefix, then bincode 2
//!   (pinned); strict decoding (version, trailing bytes, allocation limit, finite floats);
//! - the version handshake ([`handshake`]);
//! - the session logic, pure and stepped with `now_ns`: latest-wins sequence tracking with loss
//!   counts, echo bookkeeping and RTT ([`session`]), clock offset from Ping/Pong ([`clock`]), and
//!   the heartbeat check ([`session::Session::is_stale`]).
//!
//! What it is not: no sockets, no clocks, no threads, no QUIC (the `telerobot` and `operator`
//! crates own the transport and stream framing); it depends on no other crate of ours. The
//! operator and telerobot nodes in `mmt` build and consume these types.
//!
//! Transport, per `DESIGN.md` §7: `Hello` / `Welcome` / `Refused` / `Bye` on the reliable control
//! stream; `Command`, `Ping`, `Parameters`, `Contact`, `StateSync`, `Measurement` and `Pong` as
//! unreliable datagrams (each a complete, self-contained state with a [`Header`], at most
//! [`MAX_DATAGRAM_BYTES`] encoded); a `Cloud` alone on a stream per frame.
//!
//! Units are in every field's name and doc: SI, times in integer nanoseconds on the sender's
//! clock unless the doc names the other side's.

pub mod clock;
pub mod codec;
mod finite;
pub mod handshake;
mod header;
mod model;
pub mod operator_to_telerobot;
mod sequence;
pub mod session;
pub mod telerobot_to_operator;

pub use codec::{
    DecodeError, Direction, MAX_BODY_BYTES, MAX_CLOUD_POINTS, MAX_DATAGRAM_BYTES, PROTOCOL_VERSION,
    VERSION_PREFIX_BYTES,
};
pub use finite::NonFinite;
pub use header::{Header, NO_ECHO};
