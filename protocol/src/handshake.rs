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
        .map_or(Ok(()), |r| positive("cloud_rate_hz", r))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::telerobot_to_operator::{ModelStructure, Refused};

    fn hello(version: u16) -> Hello {
        Hello {
            version,
            operator_name: "alice".into(),
            want_clouds: true,
        }
    }

    fn welcome(version: u16) -> Welcome {
        Welcome {
            version,
            scene: SceneSummary {
                name: "exp1".into(),
                normal: ModelStructure::KelvinVoigt,
                tangential: ModelStructure::SlidingMass {
                    ground_spring: false,
                    friction: true,
                },
                control_rate_hz: 1000.0,
                cloud_rate_hz: Some(30.0),
                left_out: vec!["ground spring k1".into()],
            },
        }
    }

    /// Bytes as a build speaking `version` would send them: the body is the same in this test.
    fn with_prefix(version: u16, mut bytes: Vec<u8>) -> Vec<u8> {
        bytes[..2].copy_from_slice(&version.to_le_bytes());
        bytes
    }

    #[test]
    fn matching_versions_open_the_session() {
        assert_eq!(check_hello(&hello(PROTOCOL_VERSION)), Ok(()));
        let bytes = o2t::encode(&o2t::Message::Hello(hello(PROTOCOL_VERSION)));
        assert_eq!(accept_hello(&bytes), Ok(hello(PROTOCOL_VERSION)));
        let bytes = t2o::encode(&t2o::Message::Welcome(welcome(PROTOCOL_VERSION)));
        assert_eq!(accept_welcome(&bytes), Ok(welcome(PROTOCOL_VERSION)));
    }

    #[test]
    fn a_mismatched_hello_is_refused_naming_both_versions() {
        let refusal = check_hello(&hello(2)).unwrap_err();
        assert_eq!(
            refusal.to_string(),
            "protocol version mismatch: telerobot speaks 1, operator speaks 2"
        );
        // A version-2 build also puts 2 in the prefix: refused before the body is read.
        let bytes = with_prefix(2, o2t::encode(&o2t::Message::Hello(hello(2))));
        assert_eq!(accept_hello(&bytes), Err(refusal));
    }

    #[test]
    fn the_operator_names_both_versions_too() {
        let e = check_welcome(&welcome(3)).unwrap_err();
        assert_eq!(
            e.to_string(),
            "protocol version mismatch: operator speaks 1, telerobot speaks 3"
        );
        let refused = t2o::Message::Refused(Refused {
            reason: Refusal::VersionMismatch { ours: 3, theirs: 1 },
        });
        let bytes = with_prefix(3, t2o::encode(&refused));
        assert_eq!(accept_welcome(&bytes), Err(e));
    }

    #[test]
    fn refusals_and_wrong_first_messages_are_reported() {
        let busy = Refusal::Busy {
            controlling_operator: "bob".into(),
        };
        let bytes = t2o::encode(&t2o::Message::Refused(Refused {
            reason: busy.clone(),
        }));
        let e = accept_welcome(&bytes).unwrap_err();
        assert_eq!(e, HandshakeError::Refused(busy));
        assert_eq!(
            e.to_string(),
            "the telerobot refused the session: telerobot is busy: bob is in control"
        );
        let bytes = o2t::encode(&o2t::Message::Bye);
        assert_eq!(
            accept_hello(&bytes).unwrap_err().to_string(),
            "refused: expected Hello as the first message, got Bye"
        );
        assert!(matches!(
            accept_hello(&[1]),
            Err(Refusal::Other(s)) if s.contains("too short")
        ));
    }

    #[test]
    fn a_scene_without_a_positive_rate_is_rejected() {
        let mut w = welcome(PROTOCOL_VERSION);
        w.scene.cloud_rate_hz = Some(0.0);
        assert_eq!(
            check_welcome(&w).unwrap_err().to_string(),
            "invalid scene summary: cloud_rate_hz = 0, expected a positive rate in Hz"
        );
    }
}
