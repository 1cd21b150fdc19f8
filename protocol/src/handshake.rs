//! The version handshake on the reliable control stream.
//!
//! ```text
//! operator                               telerobot
//!    Hello { version, name, want_clouds } ──▶  accept_hello / check_hello
//!    accept_welcome / check_welcome       ◀──  Welcome { version, scene } | Refused { reason }
//! ```
//!
//! A version mismatch is caught twice over: by the 2-byte prefix every message starts with (which
//! is fixed across versions, so [`DecodeError::Version`] names both versions even when the body
//! is unreadable) and by the `version` fields. Either way the refusal names both versions. An
//! operator of another version cannot read the telerobot's `Refused` body, but its decoder's
//! [`DecodeError::Version`] says the same thing, and [`accept_welcome`] turns it into
//! [`HandshakeError::VersionMismatch`].

use crate::codec::{DecodeError, PROTOCOL_VERSION};
use crate::operator_to_telerobot::{self as o2t, Hello};
use crate::telerobot_to_operator::{self as t2o, Refusal, SceneSummary, Welcome};

/// Why the operator could not open a session.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum HandshakeError {
    /// The two builds speak different protocol versions.
    #[error("protocol version mismatch: operator speaks {ours}, telerobot speaks {theirs}")]
    VersionMismatch {
        /// The operator's version.
        ours: u16,
        /// The telerobot's version.
        theirs: u16,
    },
    /// The telerobot refused the session.
    #[error("the telerobot refused the session: {0}")]
    Refused(Refusal),
    /// The first message was another kind.
    #[error("expected Welcome or Refused as the telerobot's first message, got {got}")]
    Unexpected {
        /// The kind received.
        got: &'static str,
    },
    /// The scene summary holds a value the operator cannot run with.
    #[error("invalid scene summary: {field} = {value}, expected {expected}")]
    InvalidScene {
        /// Field name.
        field: &'static str,
        /// The value received.
        value: f64,
        /// What it must be.
        expected: &'static str,
    },
    /// The first message could not be decoded.
    #[error("the telerobot's first message was not understood: {0}")]
    Decode(DecodeError),
}

/// Telerobot side: whether a `Hello` may open a session (versions match). Whether another
/// operator is already in control (`Refusal::Busy`) is the telerobot's own state and its check.
pub fn check_hello(hello: &Hello) -> Result<(), Refusal> {
    if hello.version == PROTOCOL_VERSION {
        Ok(())
    } else {
        Err(Refusal::VersionMismatch {
            ours: PROTOCOL_VERSION,
            theirs: hello.version,
        })
    }
}

/// Telerobot side: decodes the first control-stream message and checks it with
/// [`check_hello`]. On `Err`, send `Refused { reason }` and close.
pub fn accept_hello(bytes: &[u8]) -> Result<Hello, Refusal> {
    match o2t::decode(bytes) {
        Ok(o2t::Message::Hello(hello)) => check_hello(&hello).map(|()| hello),
        Ok(other) => Err(Refusal::Other(format!(
            "expected Hello as the first message, got {}",
            other.kind()
        ))),
        Err(DecodeError::Version { ours, theirs }) => {
            Err(Refusal::VersionMismatch { ours, theirs })
        }
        Err(e) => Err(Refusal::Other(format!("first message not understood: {e}"))),
    }
}

/// Operator side: whether a `Welcome` may open the session (versions match, rates positive).
pub fn check_welcome(welcome: &Welcome) -> Result<(), HandshakeError> {
    if welcome.version != PROTOCOL_VERSION {
        return Err(HandshakeError::VersionMismatch {
            ours: PROTOCOL_VERSION,
            theirs: welcome.version,
        });
    }
    check_scene(&welcome.scene)
}

/// Operator side: decodes the telerobot's first control-stream message and checks it with
/// [`check_welcome`].
pub fn accept_welcome(bytes: &[u8]) -> Result<Welcome, HandshakeError> {
    match t2o::decode(bytes) {
        Ok(t2o::Message::Welcome(welcome)) => check_welcome(&welcome).map(|()| welcome),
        Ok(t2o::Message::Refused(r)) => Err(HandshakeError::Refused(r.reason)),
        Ok(other) => Err(HandshakeError::Unexpected { got: other.kind() }),
        Err(DecodeError::Version { ours, theirs }) => {
            Err(HandshakeError::VersionMismatch { ours, theirs })
        }
        Err(e) => Err(HandshakeError::Decode(e)),
    }
}

fn check_scene(scene: &SceneSummary) -> Result<(), HandshakeError> {
    let positive = |field, value: f64| {
        if value > 0.0 {
            Ok(())
        } else {
            Err(HandshakeError::InvalidScene {
                field,
                value,
                expected: "a positive rate in Hz",
            })
        }
    };
    positive("control_rate_hz", scene.control_rate_hz)?;
    scene
        .cloud_rate_hz
        .map_or(Ok(()), |r| positive("cloud_rate_hz", r))?;
    // The contact detector's radii: positive and strictly increasing (r1 < r2 < r3).
    const RADII: [&str; 3] = ["proxy_radii_m[0]", "proxy_radii_m[1]", "proxy_radii_m[2]"];
    let mut below = 0.0;
    for (field, value) in RADII.into_iter().zip(scene.proxy_radii_m) {
        if !(value > below) {
            return Err(HandshakeError::InvalidScene {
                field,
                value,
                expected: "radii r1 < r2 < r3 in metres, each above 0 and the one before",
            });
        }
        below = value;
    }
    Ok(())
}
