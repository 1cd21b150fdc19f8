//! Messages the operator sends to the telerobot, and their encode/decode pair.
//!
//! | message | transport | rate |
//! |---|---|---|
//! | [`Hello`] | reliable control stream, first message | once per session |
//! | [`Command`] | datagram | haptic loop rate (1 kHz) |
//! | [`Ping`] | datagram | e.g. 10 Hz, answered by a `Pong` |
//! | `Bye` | reliable control stream, last message | once |
//!
//! Positions and velocities are in the telerobot's world frame [m, m/s] (the operator node maps
//! device coordinates into it); times are on the operator's clock \[ns\].

use serde::{Deserialize, Serialize};

use crate::codec::{self, Direction};
use crate::finite::{self, CheckFinite, NonFinite};
use crate::header::Header;

/// Everything the operator sends. The variant order is part of the wire format.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// Opens the session; see [`crate::handshake`].
    Hello(Hello),
    /// The device's position and velocity, every haptic tick.
    Command(Command),
    /// Clock-offset probe; see [`crate::clock`].
    Ping(Ping),
    /// The operator closes the session; the telerobot holds the robot still.
    Bye,
}

/// First message on the reliable control stream.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Hello {
    /// The protocol version the operator speaks ([`crate::PROTOCOL_VERSION`] of its build).
    pub version: u16,
    /// Who is operating, for the telerobot's log and for a `Busy` refusal seen by others.
    pub operator_name: String,
    /// Whether the operator wants point clouds (local contact detection needs them).
    pub want_clouds: bool,
}

/// The operator's command: where the tool should be. A complete state, so a lost datagram costs
/// one period.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Command {
    /// `sample_time_ns` is when the device was read; the telerobot echoes it back in the
    /// `command_sample_time_ns` of what it computed from this command.
    pub header: Header,
    /// Commanded tool position, world frame \[m\].
    pub position_m: [f64; 3],
    /// Commanded tool velocity, world frame \[m/s\].
    pub velocity_m_per_s: [f64; 3],
}

/// NTP-style probe (network notes §5.2): the telerobot answers with a `Pong` carrying `t1` back
/// with its own receive and send times.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Ping {
    /// Probe number, increasing; the `Pong` repeats it.
    pub id: u64,
    /// When the operator sent the probe [ns, operator's clock].
    pub t1_ns: i64,
}

impl Message {
    /// The variant's name, for logs and errors.
    pub fn kind(&self) -> &'static str {
        match self {
            Message::Hello(_) => "Hello",
            Message::Command(_) => "Command",
            Message::Ping(_) => "Ping",
            Message::Bye => "Bye",
        }
    }

    /// The datagram header, for the messages that are datagrams.
    pub fn header(&self) -> Option<&Header> {
        match self {
            Message::Command(c) => Some(&c.header),
            Message::Hello(_) | Message::Ping(_) | Message::Bye => None,
        }
    }

    /// The first NaN or ±∞ in the message, with its field; what the peer's decoder would refuse.
    pub fn check_finite(&self) -> Result<(), NonFinite> {
        CheckFinite::check_finite(self)
    }
}

impl CheckFinite for Message {
    fn check_finite(&self) -> Result<(), NonFinite> {
        match self {
            Message::Command(c) => finite::vector("position_m", &c.position_m)
                .and_then(|()| finite::vector("velocity_m_per_s", &c.velocity_m_per_s))
                .map_err(|e| e.within("Command")),
            Message::Hello(_) | Message::Ping(_) | Message::Bye => Ok(()),
        }
    }
}

codec::direction_codec!(Direction::OperatorToTelerobot);
