//! Property tests of the codec (iroh-style): every message round-trips bit-exactly, and decoding
//! arbitrary, truncated, extended or corrupted bytes returns an error or a message, never a
//! panic.

mod common;

use std::fmt::Debug;

use common::{arb_operator_message, arb_telerobot_message};
use proptest::prelude::*;
use proptest::sample::Index;
use protocol::{DecodeError, operator_to_telerobot as o2t, telerobot_to_operator as t2o};

/// One direction's codec, so that each property is written once for both.
struct Codec<M> {
    encode: fn(&M) -> Vec<u8>,
    encode_into: fn(&M, &mut Vec<u8>),
    decode: fn(&[u8]) -> Result<M, DecodeError>,
}

const OPERATOR: Codec<o2t::Message> = Codec {
    encode: o2t::encode,
    encode_into: o2t::encode_into,
    decode: o2t::decode,
};

const TELEROBOT: Codec<t2o::Message> = Codec {
    encode: t2o::encode,
    encode_into: t2o::encode_into,
    decode: t2o::decode,
};

impl<M: PartialEq + Debug> Codec<M> {
    /// Decoding gives the message back, and re-encoding gives the same bytes (so every float
    /// keeps its bits, signed zeros and subnormals included); `encode_into` a dirty buffer gives
    /// the same bytes as `encode`.
    fn round_trips(&self, msg: &M, dirty: &[u8]) -> Result<(), TestCaseError> {
        let bytes = (self.encode)(msg);
        let back = (self.decode)(&bytes).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert_eq!(&back, msg);
        prop_assert_eq!(&(self.encode)(&back), &bytes);
        let mut buf = dirty.to_vec();
        (self.encode_into)(msg, &mut buf);
        prop_assert_eq!(&buf, &bytes);
        Ok(())
    }

    /// Every proper prefix is an error (the format is prefix-free), never a panic.
    fn rejects_truncation(&self, msg: &M, cut: &Index) -> Result<(), TestCaseError> {
        let bytes = (self.encode)(msg);
        let n = cut.index(bytes.len());
        prop_assert!((self.decode)(&bytes[..n]).is_err());
        Ok(())
    }

    /// A complete message followed by anything is rejected as trailing bytes.
    fn rejects_trailing_bytes(&self, msg: &M, extra: &[u8]) -> Result<(), TestCaseError> {
        let mut bytes = (self.encode)(msg);
        let message_len = bytes.len();
        bytes.extend_from_slice(extra);
        match (self.decode)(&bytes) {
            Err(DecodeError::TrailingBytes {
                message_len: m,
                trailing,
                ..
            }) => {
                prop_assert_eq!(m, message_len);
                prop_assert_eq!(trailing, extra.len());
            }
            other => prop_assert!(false, "expected TrailingBytes, got {:?}", other),
        }
        Ok(())
    }

    /// Overwritten bytes give an error or some message, never a panic.
    fn survives_corruption(&self, msg: &M, edits: &[(Index, u8)]) {
        let mut bytes = (self.encode)(msg);
        for (at, value) in edits {
            let i = at.index(bytes.len());
            bytes[i] = *value;
        }
        let _ = (self.decode)(&bytes);
    }
}

proptest! {
    #[test]
    fn operator_messages_round_trip(msg in arb_operator_message(), dirty in any::<Vec<u8>>()) {
        OPERATOR.round_trips(&msg, &dirty)?;
    }

    #[test]
    fn telerobot_messages_round_trip(msg in arb_telerobot_message(), dirty in any::<Vec<u8>>()) {
        TELEROBOT.round_trips(&msg, &dirty)?;
    }

    #[test]
    fn truncated_operator_messages_are_errors(msg in arb_operator_message(), cut in any::<Index>()) {
        OPERATOR.rejects_truncation(&msg, &cut)?;
    }

    #[test]
    fn truncated_telerobot_messages_are_errors(msg in arb_telerobot_message(), cut in any::<Index>()) {
        TELEROBOT.rejects_truncation(&msg, &cut)?;
    }

    #[test]
    fn operator_trailing_bytes_are_rejected(
        msg in arb_operator_message(),
        extra in proptest::collection::vec(any::<u8>(), 1..16),
    ) {
        OPERATOR.rejects_trailing_bytes(&msg, &extra)?;
    }

    #[test]
    fn telerobot_trailing_bytes_are_rejected(
        msg in arb_telerobot_message(),
        extra in proptest::collection::vec(any::<u8>(), 1..16),
    ) {
        TELEROBOT.rejects_trailing_bytes(&msg, &extra)?;
    }

    #[test]
    fn corrupted_operator_messages_never_panic(
        msg in arb_operator_message(),
        edits in proptest::collection::vec((any::<Index>(), any::<u8>()), 1..6),
    ) {
        OPERATOR.survives_corruption(&msg, &edits);
    }

    #[test]
    fn corrupted_telerobot_messages_never_panic(
        msg in arb_telerobot_message(),
        edits in proptest::collection::vec((any::<Index>(), any::<u8>()), 1..6),
    ) {
        TELEROBOT.survives_corruption(&msg, &edits);
    }

    /// Arbitrary bytes, raw and behind a valid version prefix (so that they reach the body
    /// decoder), never panic in either direction.
    #[test]
    fn arbitrary_bytes_never_panic(body in proptest::collection::vec(any::<u8>(), 0..512)) {
        let mut prefixed = protocol::PROTOCOL_VERSION.to_le_bytes().to_vec();
        prefixed.extend_from_slice(&body);
        for bytes in [&body, &prefixed] {
            let _ = o2t::decode(bytes);
            let _ = t2o::decode(bytes);
        }
    }
}
