//! Framing of `protocol` messages on QUIC streams.
//!
//! ```text
//! control stream (bidirectional, opened by the operator):
//!     [ len: u32 little-endian ][ len bytes: one encoded message ] ...   len ≤ MAX_CONTROL_FRAME_BYTES
//! cloud stream (unidirectional, one per frame, opened by the telerobot):
//!     [ the encoded `Cloud` message ][ FIN ]                            ≤ MAX_CLOUD_STREAM_BYTES
//! ```
//!
//! A cloud stream needs no length prefix: the stream's end is the frame's end, and a frame that
//! went stale before it was sent through is reset by the sender (`reset` with
//! [`STALE_CLOUD_CODE`]), which the receiver sees as an error and drops.

use quinn::{
    ReadError, ReadExactError, ReadToEndError, RecvStream, SendStream, VarInt, WriteError,
};

/// Largest control-stream frame \[B\]: the largest control message is a `Welcome` with its scene
/// summary (names of left-out terms), a few hundred bytes; 64 KiB bounds what a broken peer can
/// make us buffer.
pub const MAX_CONTROL_FRAME_BYTES: u32 = 64 * 1024;

/// Largest cloud stream \[B\]: one encoded message of at most [`protocol::MAX_BODY_BYTES`] after
/// the version prefix.
pub const MAX_CLOUD_STREAM_BYTES: usize = protocol::MAX_BODY_BYTES + protocol::VERSION_PREFIX_BYTES;

/// Stream reset code of a cloud frame superseded by a newer one before it was sent through.
pub const STALE_CLOUD_CODE: VarInt = VarInt::from_u32(1);

/// Why a frame could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The peer finished the stream cleanly before the next frame began.
    #[error("the peer closed the stream")]
    Finished,
    /// The stream ended inside a frame.
    #[error("the stream ended inside a frame: {got} of {expected} bytes")]
    Truncated {
        /// Bytes of the frame received.
        got: usize,
        /// Bytes the frame should have had (4 for the length prefix).
        expected: usize,
    },
    /// A frame longer than the limit was announced or sent.
    #[error("frame of {len} bytes exceeds the {max}-byte limit")]
    TooLong {
        /// Its length \[B\] (at least, for a cloud stream cut off at the limit).
        len: usize,
        /// The limit \[B\].
        max: usize,
    },
    /// Reading failed (connection lost, stream reset by the peer).
    #[error("reading the stream: {0}")]
    Read(#[from] ReadError),
    /// Writing failed (connection lost, stream stopped by the peer).
    #[error("writing the stream: {0}")]
    Write(#[from] WriteError),
}

/// Writes one frame: the length prefix and `message` (an encoded protocol message).
pub async fn write_frame(send: &mut SendStream, message: &[u8]) -> Result<(), FrameError> {
    let len = u32::try_from(message.len())
        .ok()
        .filter(|&l| l <= MAX_CONTROL_FRAME_BYTES)
        .ok_or(FrameError::TooLong {
            len: message.len(),
            max: MAX_CONTROL_FRAME_BYTES as usize,
        })?;
    let mut frame = Vec::with_capacity(4 + message.len());
    frame.extend_from_slice(&len.to_le_bytes());
    frame.extend_from_slice(message);
    send.write_all(&frame).await?;
    Ok(())
}

/// Reads one frame into `buf` (cleared first), refusing one over [`MAX_CONTROL_FRAME_BYTES`]
/// before reading its body.
pub async fn read_frame(recv: &mut RecvStream, buf: &mut Vec<u8>) -> Result<(), FrameError> {
    let mut prefix = [0u8; 4];
    match recv.read_exact(&mut prefix).await {
        Ok(()) => {}
        Err(ReadExactError::FinishedEarly(0)) => return Err(FrameError::Finished),
        Err(ReadExactError::FinishedEarly(got)) => {
            return Err(FrameError::Truncated { got, expected: 4 });
        }
        Err(ReadExactError::ReadError(e)) => return Err(e.into()),
    }
    let len = u32::from_le_bytes(prefix);
    if len > MAX_CONTROL_FRAME_BYTES {
        return Err(FrameError::TooLong {
            len: len as usize,
            max: MAX_CONTROL_FRAME_BYTES as usize,
        });
    }
    buf.clear();
    buf.resize(len as usize, 0);
    recv.read_exact(buf).await.map_err(|e| match e {
        ReadExactError::FinishedEarly(got) => FrameError::Truncated {
            got,
            expected: len as usize,
        },
        ReadExactError::ReadError(e) => FrameError::Read(e),
    })
}

/// Sends one cloud frame (an encoded `Cloud` message) on its own stream and finishes it. The
/// stream gets a lower priority than the control stream and datagrams (quinn sends datagrams
/// before any stream data anyway).
pub async fn write_cloud(send: &mut SendStream, message: &[u8]) -> Result<(), FrameError> {
    if message.len() > MAX_CLOUD_STREAM_BYTES {
        return Err(FrameError::TooLong {
            len: message.len(),
            max: MAX_CLOUD_STREAM_BYTES,
        });
    }
    // Only fails on a stream already closed, which write_all then reports.
    let _ = send.set_priority(-1);
    send.write_all(message).await?;
    // Only fails if the stream was already finished or reset; nothing is lost either way.
    let _ = send.finish();
    Ok(())
}

/// Reads a whole cloud stream (at most [`MAX_CLOUD_STREAM_BYTES`]).
pub async fn read_cloud(recv: &mut RecvStream) -> Result<Vec<u8>, FrameError> {
    recv.read_to_end(MAX_CLOUD_STREAM_BYTES)
        .await
        .map_err(|e| match e {
            ReadToEndError::TooLong => FrameError::TooLong {
                len: MAX_CLOUD_STREAM_BYTES + 1,
                max: MAX_CLOUD_STREAM_BYTES,
            },
            ReadToEndError::Read(e) => FrameError::Read(e),
        })
}
