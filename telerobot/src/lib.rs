//! # telerobot — the telerobot daemon
//!
//! What it is: the QUIC server and its hand-off to the real-time loop ([`net`]), and the
//! command line of the `telerobot` binary ([`cli`]). Later: robot bridges and the real-time loop
//! stepping `mmt`'s telerobot node.
//!
//! What it is not: no estimation logic of its own (that lives in `mmt`'s telerobot node), no wire
//! format (that is `protocol`), no QUIC plumbing shared with the operator (that is `transport`).

pub mod cli;
pub mod net;
