//! The version handshake, end to end through the codec.

mod common;

use protocol::PROTOCOL_VERSION;
use protocol::handshake::{
    HandshakeError, accept_hello, accept_welcome, check_hello, check_welcome,
};
use protocol::operator_to_telerobot::{self as o2t, Hello};
use protocol::telerobot_to_operator::{self as t2o, Refusal, Refused, Welcome};

/// The sample `Hello` of `common`, speaking `version`.
fn hello(version: u16) -> Hello {
    match &common::operator_samples()[0] {
        o2t::Message::Hello(h) => Hello {
            version,
            ..h.clone()
        },
        other => panic!("sample 0 is a {}", other.kind()),
    }
}

/// The sample `Welcome` of `common`, speaking `version`.
fn welcome(version: u16) -> Welcome {
    match &common::telerobot_samples()[0] {
        t2o::Message::Welcome(w) => Welcome {
            version,
            ..w.clone()
        },
        other => panic!("sample 0 is a {}", other.kind()),
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
    let newer = PROTOCOL_VERSION + 1;
    let refusal = check_hello(&hello(newer)).unwrap_err();
    assert_eq!(
        refusal.to_string(),
        format!(
            "protocol version mismatch: telerobot speaks {PROTOCOL_VERSION}, operator speaks {newer}"
        )
    );
    // A newer build also puts its version in the prefix: refused before the body is read.
    let bytes = with_prefix(newer, o2t::encode(&o2t::Message::Hello(hello(newer))));
    assert_eq!(accept_hello(&bytes), Err(refusal));
}

#[test]
fn the_operator_names_both_versions_too() {
    let newer = PROTOCOL_VERSION + 2;
    let e = check_welcome(&welcome(newer)).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "protocol version mismatch: operator speaks {PROTOCOL_VERSION}, telerobot speaks {newer}"
        )
    );
    let refused = t2o::Message::Refused(Refused {
        reason: Refusal::VersionMismatch {
            ours: newer,
            theirs: PROTOCOL_VERSION,
        },
    });
    let bytes = with_prefix(newer, t2o::encode(&refused));
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

#[test]
fn proxy_radii_out_of_order_or_not_positive_are_rejected() {
    for (radii, field, value) in [
        ([0.0, 0.006, 0.03], "proxy_radii_m[0]", "0"),
        ([0.004, 0.004, 0.03], "proxy_radii_m[1]", "0.004"),
        ([0.004, 0.006, 0.005], "proxy_radii_m[2]", "0.005"),
        ([-0.004, 0.006, 0.03], "proxy_radii_m[0]", "-0.004"),
    ] {
        let mut w = welcome(PROTOCOL_VERSION);
        w.scene.proxy_radii_m = radii;
        assert_eq!(
            check_welcome(&w).unwrap_err().to_string(),
            format!(
                "invalid scene summary: {field} = {value}, expected radii r1 < r2 < r3 in metres, \
                 each above 0 and the one before"
            )
        );
    }
    let mut w = welcome(PROTOCOL_VERSION);
    w.scene.proxy_radii_m = [0.001, 0.003, 0.012];
    assert_eq!(check_welcome(&w), Ok(()));
}

/// The `decode` fuzz target's handshake checks, on arbitrary and on corrupted first messages:
/// the handshake never panics and agrees with the decoders (what it accepts is the decoded
/// message, of this version, and passes the checks).
mod agreement {
    use super::*;
    use proptest::prelude::*;
    use proptest::sample::Index;

    fn agrees(bytes: &[u8]) -> Result<(), TestCaseError> {
        if let Ok(h) = accept_hello(bytes) {
            prop_assert_eq!(h.version, PROTOCOL_VERSION);
            prop_assert_eq!(o2t::decode(bytes), Ok(o2t::Message::Hello(h)));
        }
        if let Ok(w) = accept_welcome(bytes) {
            prop_assert_eq!(check_welcome(&w), Ok(()));
            prop_assert_eq!(t2o::decode(bytes), Ok(t2o::Message::Welcome(w)));
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn arbitrary_first_messages(body in proptest::collection::vec(any::<u8>(), 0..256)) {
            let mut prefixed = PROTOCOL_VERSION.to_le_bytes().to_vec();
            prefixed.extend_from_slice(&body);
            agrees(&body)?;
            agrees(&prefixed)?;
        }

        #[test]
        fn corrupted_hello_and_welcome(
            edits in proptest::collection::vec((any::<Index>(), any::<u8>()), 1..5),
        ) {
            let hello = o2t::encode(&o2t::Message::Hello(hello(PROTOCOL_VERSION)));
            let welcome = t2o::encode(&t2o::Message::Welcome(welcome(PROTOCOL_VERSION)));
            for mut bytes in [hello, welcome] {
                for (at, value) in &edits {
                    let i = at.index(bytes.len());
                    bytes[i] = *value;
                }
                agrees(&bytes)?;
            }
        }
    }
}
