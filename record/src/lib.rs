//! # record — recordings of runs, the live view, and reading recordings back
//!
//! What it is:
//! - [`Recorder`]: `--record FILE.mcap` and `--live ADDR` of `operator run`, `telerobot run`, the
//!   demo and `mmt experiment`. One thread writes every channel the reports use, each with its
//!   own timestamps, to a chunked, zstd-compressed MCAP file with well-known schemas (JSON with a
//!   JSON Schema for ours; Foxglove's `SceneUpdate`, `PointCloud`, `FrameTransform` and `Log`),
//!   so Foxglove, Lichtblick, PlotJuggler and the `mcap` CLI open it without a plug-in; the same
//!   thread feeds the live view, decimated for display. Producers hand it batches through a
//!   bounded queue ([`RecordSink`]) from their helper threads: the 1 kHz loops only push their
//!   tick records into the lock-free mailboxes they already had, never touching this crate.
//! - [`live`]: the Foxglove WebSocket server of the live view; a slow or vanished viewer drops
//!   messages (counted), never slows anything.
//! - [`read`]: a recording read back, checked (format version, kind), up to the last complete
//!   chunk of a file cut short.
//! - [`replay`]: the replay robot bridge and the recorded device trajectory.
//! - [`schema`]: the recording's topics and message types: its contract.
//!
//! What it is not: no analysis (the reports are `metrics`' and `lab`'s), no loop of its own,
//! nothing the loops call. `mmt`, `node` and `protocol` do not depend on it.

pub mod cli;
mod encode;
mod file;
mod lenient;
pub mod live;
pub mod read;
pub mod replay;
mod scene;
pub mod schema;
mod stream;
mod writer;

pub use encode::{ChannelSchema, topic_schema};
pub use live::{LiveReport, LiveServer};
pub use read::{ReadError, Recording, read, read_bytes};
pub use replay::ReplayBridge;
pub use scene::SCENE_RATE_HZ;
pub use schema::{Kind, Message, Side, Timed};
pub use writer::{
    CHUNK_BYTES, FLUSH_EVERY, LIVE_PLOT_INTERVAL_NS, QUEUE, RecordError, RecordSink, Recorder,
    RecorderConfig, RecorderReport, partial_path,
};
