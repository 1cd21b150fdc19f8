//! The one encode/decode pair: the only code in the project that touches the codec.
//!
//! # Wire format
//!
//! ```text
//! [ version: u16 little-endian ][ body: bincode 2, config::standard() ]
//! ```
//!
//! The 2-byte prefix is fixed forever, whatever the version, so that any two builds can tell each
//! other which version they speak. The body is the direction's `Message` enum through serde with
//! bincode 2.0.1 (pinned with `=`): variable-length little-endian integers (zig-zag for signed
//! ones), floats as their 4 or 8 IEEE bytes, enum variants as their index, options as a 0/1 byte,
//! sequences and strings length-prefixed. The variant order and field order of every message type
//! are therefore part of the format: append new variants and bump [`PROTOCOL_VERSION`] for any
//! change; the golden-byte tests (`tests/golden.rs`) fail on an accidental one.
//!
//! Decoding is strict: the version must match, the body must be exactly one message (no trailing
//! bytes), a corrupt length prefix cannot make it allocate more than [`MAX_BODY_BYTES`], and every
//! float must be finite.

use std::fmt;

use bincode::config::{Configuration, Limit, LittleEndian, Varint};
use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::finite::{CheckFinite, NonFinite};

/// The protocol version this build speaks; the first two bytes (little-endian) of every message.
pub const PROTOCOL_VERSION: u16 = 5;

/// Length of the version prefix \[bytes\].
pub const VERSION_PREFIX_BYTES: usize = 2;

/// Upper bound on what decoding one message may allocate or read \[bytes\]: 64 MiB.
///
/// Bincode counts every decoded value and every announced container against it *before*
/// allocating, so a garbage length prefix fails with [`DecodeError::TooLarge`] instead of
/// allocating gigabytes. Sized for the largest point cloud we send (see [`MAX_CLOUD_POINTS`]).
pub const MAX_BODY_BYTES: usize = 64 * 1024 * 1024;

/// The largest point cloud a [`crate::telerobot_to_operator::CloudFrame`] may carry and still
/// decode within [`MAX_BODY_BYTES`]: 4 Mi points of 12 bytes (48 MiB), with room to spare for the
/// rest of the frame. Senders downsample larger clouds.
pub const MAX_CLOUD_POINTS: usize = 4 * 1024 * 1024;

/// Upper bound on an encoded datagram message \[bytes\], tested for the largest values of every
/// field. QUIC guarantees 1162 bytes of datagram payload at the handshake (network notes §3.1);
/// the margin is left for future fields.
pub const MAX_DATAGRAM_BYTES: usize = 1100;

/// Which way a message travels; named in decode errors.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// [`crate::operator_to_telerobot`].
    OperatorToTelerobot,
    /// [`crate::telerobot_to_operator`].
    TelerobotToOperator,
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Direction::OperatorToTelerobot => "operator-to-telerobot",
            Direction::TelerobotToOperator => "telerobot-to-operator",
        })
    }
}

/// Why bytes from the peer were not accepted as a message.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DecodeError {
    /// Fewer bytes than the version prefix.
    #[error(
        "message of {len} bytes is too short: expected at least the {VERSION_PREFIX_BYTES}-byte protocol version"
    )]
    TooShort {
        /// Length received \[bytes\].
        len: usize,
    },
    /// The peer speaks another protocol version; nothing after the prefix was read.
    #[error("protocol version mismatch: this side speaks {ours}, the peer sent {theirs}")]
    Version {
        /// [`PROTOCOL_VERSION`].
        ours: u16,
        /// The version in the message's prefix.
        theirs: u16,
    },
    /// The message ended before its body was complete.
    #[error("truncated {direction} message: expected at least {needed} more bytes")]
    Truncated {
        /// Which message type was expected.
        direction: Direction,
        /// How many more bytes the decoder wanted, at least.
        needed: usize,
    },
    /// A length prefix announced more than [`MAX_BODY_BYTES`].
    #[error(
        "{direction} message would exceed the {limit}-byte decode limit (corrupt length prefix, or a cloud over {MAX_CLOUD_POINTS} points)"
    )]
    TooLarge {
        /// Which message type was expected.
        direction: Direction,
        /// [`MAX_BODY_BYTES`].
        limit: usize,
    },
    /// The body is not a valid message of this direction (unknown variant, invalid bool or UTF-8, …).
    #[error("malformed {direction} message: {detail}")]
    Malformed {
        /// Which message type was expected.
        direction: Direction,
        /// The codec's description of what was wrong.
        detail: String,
    },
    /// A complete message was followed by more bytes.
    #[error(
        "{trailing} trailing bytes after a complete {direction} message of {message_len} bytes: expected the datagram to end there"
    )]
    TrailingBytes {
        /// Which message type was decoded.
        direction: Direction,
        /// Length of the message, prefix included \[bytes\].
        message_len: usize,
        /// Bytes left over \[bytes\].
        trailing: usize,
    },
    /// A float field held NaN or ±∞.
    #[error("{direction} message rejected: {source}")]
    NonFinite {
        /// Which message type was decoded.
        direction: Direction,
        /// The field and its value.
        source: NonFinite,
    },
}

/// Writes `PROTOCOL_VERSION` and the body of `msg` into `buf`, replacing its contents and keeping
/// its capacity (so a reused buffer does not allocate once it has grown to the largest message).
///
/// Floats are not checked here: a non-finite one is refused by the peer's decoder. Senders that
/// compute floats check them first (`Message::check_finite`).
pub(crate) fn encode_into<M: Serialize>(msg: &M, buf: &mut Vec<u8>) {
    buf.clear();
    buf.extend_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    let written = bincode::serde::encode_into_std_write(msg, buf, config());
    // Every message type is plain data (structs, enums, options, arrays, strings, vectors with a
    // known length) and writing to a `Vec` cannot fail, so bincode has no error to report; the
    // proptests encode every variant with arbitrary values.
    written.expect("encoding a protocol message into a Vec cannot fail");
}

/// Decodes exactly one message of `direction` from `bytes`; see the module doc for what is
/// rejected.
pub(crate) fn decode<M>(bytes: &[u8], direction: Direction) -> Result<M, DecodeError>
where
    M: DeserializeOwned + CheckFinite,
{
    let Some((prefix, body)) = bytes.split_first_chunk::<VERSION_PREFIX_BYTES>() else {
        return Err(DecodeError::TooShort { len: bytes.len() });
    };
    let theirs = u16::from_le_bytes(*prefix);
    if theirs != PROTOCOL_VERSION {
        return Err(DecodeError::Version {
            ours: PROTOCOL_VERSION,
            theirs,
        });
    }
    let (msg, used) = bincode::serde::decode_from_slice::<M, _>(body, config())
        .map_err(|e| body_error(e, direction))?;
    if used != body.len() {
        return Err(DecodeError::TrailingBytes {
            direction,
            message_len: VERSION_PREFIX_BYTES + used,
            trailing: body.len() - used,
        });
    }
    msg.check_finite()
        .map_err(|source| DecodeError::NonFinite { direction, source })?;
    Ok(msg)
}

/// Defines a direction module's public `encode_into`, `encode` and `decode` for its `Message`
/// over [`encode_into`] and [`decode`].
macro_rules! direction_codec {
    ($direction:expr) => {
        /// Encodes `msg` into `buf`: cleared first, capacity kept, so a reused buffer does not
        /// allocate once it has grown to the largest message. Floats are not checked here (the
        /// peer's decoder refuses non-finite ones): check them with [`Message::check_finite`]
        /// where they are computed.
        pub fn encode_into(msg: &Message, buf: &mut Vec<u8>) {
            $crate::codec::encode_into(msg, buf);
        }

        /// Encodes `msg` into a new buffer.
        pub fn encode(msg: &Message) -> Vec<u8> {
            let mut buf = Vec::new();
            encode_into(msg, &mut buf);
            buf
        }

        /// Decodes exactly one message; see [`crate::codec`] for what is rejected.
        pub fn decode(bytes: &[u8]) -> Result<Message, $crate::codec::DecodeError> {
            $crate::codec::decode(bytes, $direction)
        }
    };
}
pub(crate) use direction_codec;

/// The codec configuration: bincode's standard one with the allocation limit.
fn config() -> Configuration<LittleEndian, Varint, Limit<MAX_BODY_BYTES>> {
    bincode::config::standard().with_limit::<MAX_BODY_BYTES>()
}

/// Maps the codec's error onto ours, so that bincode's types stay out of the public API.
fn body_error(e: bincode::error::DecodeError, direction: Direction) -> DecodeError {
    use bincode::error::DecodeError as B;
    match e {
        B::UnexpectedEnd { additional } => DecodeError::Truncated {
            direction,
            needed: additional,
        },
        B::LimitExceeded => DecodeError::TooLarge {
            direction,
            limit: MAX_BODY_BYTES,
        },
        other => DecodeError::Malformed {
            direction,
            detail: other.to_string(),
        },
    }
}
