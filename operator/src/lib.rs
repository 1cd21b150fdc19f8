//! # operator — the operator side of the teleoperation system
//!
//! What it is: haptic devices behind one trait with simulated twins ([`device`]), the one safety
//! layer between renderer and device ([`safety`]), and the command-line entry points of the
//! `operator` binary ([`cli`]), and the QUIC client with its hand-off to the haptic loop ([`net`]).
//! Later: the haptic loop stepping `mmt`'s operator node and `demo`.
//!
//! What it is not: no rendering or estimation logic of its own (that is `mmt`), no wire format
//! (that is `protocol`). Nothing here reads a clock inside the device and safety layers: `now` is
//! passed in, so every rule is tested without one.

pub mod cli;
pub mod device;
pub mod net;
pub mod safety;
pub mod vec3;
