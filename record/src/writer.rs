//! The recorder: one thread (`recorder`) that writes every message it is handed to an MCAP file
//! and offers it to the live view, and draws the 3-D scene at display rate.
//!
//! ```text
//!  1 kHz loop ──Mailbox (lock-free, no allocation)──▶ helper thread ──RecordSink──▶ recorder
//!                                                     (the loop's own hand-off)       ├─▶ MCAP file
//!                                                                                     └─▶ live view
//! ```
//!
//! Producers hand over batches of [`Timed`] messages through a bounded queue ([`RecordSink`]);
//! a full queue drops the batch and counts its messages (never waits). The file is chunked
//! (1 MiB of messages per chunk, or every [`FLUSH_EVERY`] at least) and each chunk compressed
//! with zstd, so a file cut short by a kill holds every chunk but the last; [`Recorder::finish`]
//! (and dropping the [`Recorder`]) writes the summary and closes it.
//!
//! The file is finalised atomically: until it is finished it is written as
//! [`partial_path`]`(FILE)` (`FILE.partial`, created and checked by [`Recorder::start`], before
//! the run starts), then synced and renamed to `FILE`. `FILE` is therefore always either absent,
//! an older recording, or a complete one; a run that is killed leaves `FILE.partial`, readable
//! up to its last complete chunk.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use foxglove::Encode as _;
use serde::Serialize;

use crate::encode::{self, ChannelSchema, topic_schema};
use crate::file::McapOut;
pub use crate::file::partial_path;
use crate::live::{LiveError, LiveReport, LiveServer};
use crate::scene::SceneState;
use crate::schema::{self, FORMAT_VERSION, Kind, Message, Timed, topic};

/// Batches queued for the recorder before producers' batches are dropped.
pub const QUEUE: usize = 1024;
/// Longest time between two finished chunks: what a kill can lose at most.
pub const FLUSH_EVERY: Duration = Duration::from_secs(1);
/// Uncompressed bytes per chunk.
pub const CHUNK_BYTES: u64 = 1 << 20;
/// Shortest interval between two messages of a 1 kHz topic sent to the live view \[ns\]: plots
/// at 100 Hz.
pub const LIVE_PLOT_INTERVAL_NS: i64 = 10_000_000;

/// What to record, and where.
#[derive(Clone, Debug, PartialEq)]
pub struct RecorderConfig {
    /// The MCAP file to write, if any (written as [`partial_path`] and renamed over it when
    /// finished).
    pub mcap: Option<PathBuf>,
    /// Where the live view listens, if anywhere.
    pub live: Option<SocketAddr>,
    /// What runs.
    pub kind: Kind,
    /// The producers' clock now \[ns\] (`rt::monotonic_ns()`, or 0 for a simulated clock that
    /// starts now): maps message times onto wall time.
    pub clock_origin_ns: i64,
}

/// Why the recorder could not start or finish.
#[derive(Debug, thiserror::Error)]
pub enum RecordError {
    /// The file could not be created or written.
    #[error("recording {path}: {error}")]
    File {
        /// The file.
        path: String,
        /// What went wrong.
        error: String,
    },
    /// The live view could not start.
    #[error(transparent)]
    Live(#[from] LiveError),
    /// The recorder thread could not start, or died.
    #[error("recorder thread: {0}")]
    Thread(String),
}

/// What the recorder did.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RecorderReport {
    /// The file written, if any.
    pub path: Option<PathBuf>,
    /// Its size \[bytes\].
    pub bytes: u64,
    /// Messages written (the scene's included).
    pub messages: u64,
    /// Messages dropped: the recorder's queue was full or the recorder had stopped.
    pub dropped: u64,
    /// Messages that could not be encoded.
    pub unencodable: u64,
    /// How long the recorder ran, start to finish \[s\] (wall time).
    pub seconds: f64,
    /// The live view, if there was one.
    pub live: Option<LiveReport>,
}

impl RecorderReport {
    /// The file's size over the time the recorder ran \[bytes/s\].
    pub fn bytes_per_second(&self) -> f64 {
        if self.seconds > 0.0 {
            self.bytes as f64 / self.seconds
        } else {
            0.0
        }
    }
}

enum Command {
    Batch(Vec<Timed>),
    Finish,
}

/// What producers hold: hands batches to the recorder without waiting.
#[derive(Clone)]
pub struct RecordSink {
    tx: SyncSender<Command>,
    dropped: Arc<AtomicU64>,
    paused: Arc<AtomicBool>,
    clouds: bool,
}

impl std::fmt::Debug for RecordSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordSink")
            .field("dropped", &self.dropped())
            .finish()
    }
}

impl RecordSink {
    /// Hands over a batch; `false` (and counted) when the queue is full or the recorder stopped.
    pub fn send(&self, batch: Vec<Timed>) -> bool {
        if batch.is_empty() || self.skips(&batch) {
            return true;
        }
        let n = batch.len() as u64;
        match self.tx.try_send(Command::Batch(batch)) {
            Ok(()) => true,
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(n, Relaxed);
                false
            }
        }
    }

    /// Hands over a batch, waiting for room: for producers on a simulated clock (an in-process
    /// experiment), which would rather wait than lose data. `false` (and counted) when the
    /// recorder stopped.
    pub fn send_waiting(&self, batch: Vec<Timed>) -> bool {
        if batch.is_empty() || self.skips(&batch) {
            return true;
        }
        let n = batch.len() as u64;
        let sent = self.tx.send(Command::Batch(batch)).is_ok();
        if !sent {
            self.dropped.fetch_add(n, Relaxed);
        }
        sent
    }

    /// While paused, everything is skipped but `/run` and `/run/end` (a report needs them).
    fn skips(&self, batch: &[Timed]) -> bool {
        self.is_paused()
            && !batch
                .iter()
                .all(|t| matches!(t.message, Message::Run(_) | Message::RunEnd(_)))
    }

    /// Hands over one message.
    pub fn send_one(&self, t_ns: i64, message: Message) -> bool {
        self.send(vec![Timed { t_ns, message }])
    }

    /// Messages dropped so far.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Relaxed)
    }

    /// The recorder is paused ([`Recorder::pause`]): producers skip building what they would
    /// send.
    pub fn is_paused(&self) -> bool {
        self.paused.load(Relaxed)
    }

    /// Pauses (or resumes) recording, as [`Recorder::pause`] does, from wherever the sink is.
    pub fn set_paused(&self, paused: bool) {
        self.paused.store(paused, Relaxed);
    }

    /// Whether this producer records point-cloud frames.
    pub fn wants_clouds(&self) -> bool {
        self.clouds && !self.is_paused()
    }

    /// The same sink for a producer that leaves its point clouds out (the demo's operator side:
    /// its frames are the telerobot's, recorded once, by the telerobot).
    pub fn without_clouds(&self) -> RecordSink {
        RecordSink {
            clouds: false,
            ..self.clone()
        }
    }
}

/// The running recorder; finishing it (or dropping it) closes the file.
pub struct Recorder {
    sink: RecordSink,
    thread: Option<JoinHandle<Result<RecorderReport, RecordError>>>,
    live_addr: Option<SocketAddr>,
}

impl Recorder {
    /// Creates the file (with its header) and the live view, and starts the recorder thread.
    pub fn start(config: RecorderConfig) -> Result<Recorder, RecordError> {
        let unix_now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX));
        let header = schema::Header {
            format_version: FORMAT_VERSION,
            kind: config.kind,
            mmt_version: env!("CARGO_PKG_VERSION").to_owned(),
            created_unix_ns: unix_now,
            clock_origin_ns: config.clock_origin_ns,
        };
        // The live view first: a port that cannot be bound must not leave a file behind.
        let live = config.live.map(LiveServer::start).transpose()?;
        let out = config
            .mcap
            .as_deref()
            .map(|path| McapOut::create(path, &header))
            .transpose()?;
        let live_addr = live.as_ref().map(LiveServer::local_addr);
        let (tx, rx) = std::sync::mpsc::sync_channel(QUEUE);
        let sink = RecordSink {
            tx,
            dropped: Arc::new(AtomicU64::new(0)),
            paused: Arc::new(AtomicBool::new(false)),
            clouds: true,
        };
        let mut writer = Writer {
            out,
            live: live.map(|server| Live {
                server,
                channels: HashMap::new(),
            }),
            schemas: HashMap::new(),
            scene: SceneState::default(),
            header,
            buf: Vec::with_capacity(4096),
            started: Instant::now(),
            report: RecorderReport {
                path: config.mcap,
                ..RecorderReport::default()
            },
            failed: None,
        };
        let dropped = Arc::clone(&sink.dropped);
        let thread = std::thread::Builder::new()
            .name("recorder".to_owned())
            .spawn(move || {
                writer.run(&rx);
                writer.finish(dropped.load(Relaxed))
            })
            .map_err(|e| RecordError::Thread(e.to_string()))?;
        Ok(Recorder {
            sink,
            thread: Some(thread),
            live_addr,
        })
    }

    /// A handle for producers.
    pub fn sink(&self) -> RecordSink {
        self.sink.clone()
    }

    /// Where the live view listens (its port chosen by the OS when asked for port 0).
    pub fn live_addr(&self) -> Option<SocketAddr> {
        self.live_addr
    }

    /// Pauses (or resumes) recording: while paused, producers hand nothing over (but a run's
    /// `/run` and `/run/end`) and the file and the live view get nothing else. For measuring what recording costs the loops, in one run.
    pub fn pause(&self, paused: bool) {
        self.sink.paused.store(paused, Relaxed);
    }

    /// Writes what was handed over, the summary, and closes the file.
    pub fn finish(mut self) -> Result<RecorderReport, RecordError> {
        self.stop()
    }

    fn stop(&mut self) -> Result<RecorderReport, RecordError> {
        let Some(thread) = self.thread.take() else {
            return Err(RecordError::Thread("already finished".to_owned()));
        };
        // Blocks until the recorder takes it: everything queued before is written first.
        let _ = self.sink.tx.send(Command::Finish);
        thread
            .join()
            .map_err(|_| RecordError::Thread("the recorder thread panicked".to_owned()))?
    }
}

impl Drop for Recorder {
    /// A recorder dropped without [`Recorder::finish`] (an early return, an error, a panic
    /// unwinding) still closes its file.
    fn drop(&mut self) {
        if self.thread.is_some()
            && let Err(e) = self.stop()
        {
            tracing::error!("{e}");
        }
    }
}

/// The live view and its channels (topic → channel id, and when it last got a message of a
/// decimated topic).
struct Live {
    server: LiveServer,
    channels: HashMap<&'static str, LiveChannel>,
}

/// A live channel: its id, and when it last sent a message, in the producers' time (the
/// decimation of the 1 kHz topics) and in wall time (the cap on every topic but the logs).
struct LiveChannel {
    id: u32,
    last_t_ns: Option<i64>,
    last_sent: Option<Instant>,
}

/// The most a live topic is sent in wall time, whatever the producers' clock does (an
/// experiment runs tens of times faster than real time): scenes, transforms and clouds at
/// display rate, the rest at twice the plots' rate.
fn live_min_gap(topic_name: &str) -> Option<Duration> {
    match topic_name {
        topic::SCENE | topic::TF | topic::OPERATOR_CLOUD | topic::TELEROBOT_CLOUD => {
            Some(Duration::from_secs_f64(1.0 / LIVE_MAX_SCENE_HZ))
        }
        topic::EVENTS | topic::RUN | topic::RUN_END => None,
        _ => Some(Duration::from_nanos(LIVE_PLOT_INTERVAL_NS as u64 / 2)),
    }
}

/// The live view's display rate cap \[Hz\].
pub const LIVE_MAX_SCENE_HZ: f64 = 60.0;

impl Live {
    fn offer(
        &mut self,
        topic: &'static str,
        schema: &ChannelSchema,
        t_ns: i64,
        log_time: u64,
        data: &[u8],
    ) {
        let server = &self.server;
        let entry = self.channels.entry(topic).or_insert_with(|| LiveChannel {
            id: server.channel(topic, schema),
            last_t_ns: None,
            last_sent: None,
        });
        if decimated(topic) {
            if entry
                .last_t_ns
                .is_some_and(|last| t_ns - last < LIVE_PLOT_INTERVAL_NS)
            {
                return;
            }
            entry.last_t_ns = Some(t_ns);
        }
        if let Some(gap) = live_min_gap(topic) {
            let now = Instant::now();
            if entry.last_sent.is_some_and(|last| now - last < gap) {
                return;
            }
            entry.last_sent = Some(now);
        }
        server.offer(entry.id, log_time, data);
    }
}

/// The 1 kHz topics, which the live view gets at 100 Hz.
fn decimated(topic_name: &str) -> bool {
    matches!(
        topic_name,
        topic::OPERATOR_TICK
            | topic::OPERATOR_MEASUREMENT
            | topic::OPERATOR_CONTACT
            | topic::TELEROBOT_TICK
            | topic::TELEROBOT_CONTACT
    )
}

struct Writer {
    out: Option<McapOut>,
    live: Option<Live>,
    /// Each topic's schema, made once.
    schemas: HashMap<&'static str, ChannelSchema>,
    scene: SceneState,
    header: schema::Header,
    buf: Vec<u8>,
    started: Instant,
    report: RecorderReport,
    failed: Option<RecordError>,
}

impl Writer {
    fn run(&mut self, rx: &Receiver<Command>) {
        loop {
            match rx.recv_timeout(FLUSH_EVERY) {
                Ok(Command::Batch(batch)) => {
                    for timed in &batch {
                        self.write(timed);
                    }
                }
                Ok(Command::Finish) | Err(RecvTimeoutError::Disconnected) => return,
                Err(RecvTimeoutError::Timeout) => {
                    if let Some(out) = &mut self.out
                        && let Err(e) = out.writer.flush()
                    {
                        self.fail(&e);
                    }
                }
            }
        }
    }

    /// The wall time of `t_ns` on the producers' clock \[ns since the Unix epoch\].
    fn log_time(&self, t_ns: i64) -> u64 {
        let offset = t_ns.saturating_sub(self.header.clock_origin_ns);
        self.header.created_unix_ns.saturating_add_signed(offset)
    }

    fn write(&mut self, timed: &Timed) {
        let topic_name = timed.message.topic();
        let log_time = self.log_time(timed.t_ns);
        if encode::encode(&timed.message, log_time, &mut self.buf).is_err() {
            self.report.unencodable += 1;
            return;
        }
        let buf = std::mem::take(&mut self.buf);
        self.emit(topic_name, timed.t_ns, log_time, &buf);
        self.buf = buf;
        if self.scene.update(timed.t_ns, &timed.message) {
            self.emit_scene(timed.t_ns, log_time);
        }
    }

    fn emit_scene(&mut self, t_ns: i64, log_time: u64) {
        let mut buf = Vec::new();
        if self.scene.scene(log_time).encode(&mut buf).is_ok() {
            self.emit(topic::SCENE, t_ns, log_time, &buf);
        }
        if let Some(tf) = self.scene.transform(log_time) {
            buf.clear();
            if tf.encode(&mut buf).is_ok() {
                self.emit(topic::TF, t_ns, log_time, &buf);
            }
        }
    }

    /// Writes one encoded message to the file and offers it to the live view.
    fn emit(&mut self, topic_name: &'static str, t_ns: i64, log_time: u64, data: &[u8]) {
        let schema = match self.schemas.get(topic_name) {
            Some(s) => s,
            None => match topic_schema(topic_name) {
                Some(s) => self.schemas.entry(topic_name).or_insert(s),
                None => {
                    self.report.unencodable += 1;
                    return;
                }
            },
        };
        self.report.messages += 1;
        let mut failed = None;
        if let Some(out) = &mut self.out
            && self.failed.is_none()
            && let Err(e) = out.write(topic_name, schema, log_time, data)
        {
            failed = Some(e);
        }
        if let Some(live) = &mut self.live {
            live.offer(topic_name, schema, t_ns, log_time, data);
        }
        if let Some(e) = failed {
            self.fail(&e);
        }
    }

    fn fail(&mut self, e: &dyn std::fmt::Display) {
        if self.failed.is_none() {
            let path = self
                .report
                .path
                .as_ref()
                .map_or_else(String::new, |p| p.display().to_string());
            tracing::error!("recording {path}: {e}; the recording stops here");
            self.failed = Some(RecordError::File {
                path,
                error: e.to_string(),
            });
        }
    }

    fn finish(mut self, dropped: u64) -> Result<RecorderReport, RecordError> {
        self.report.dropped = dropped;
        self.report.seconds = self.started.elapsed().as_secs_f64();
        self.report.live = self.live.take().map(|l| l.server.stop());
        if let Some(out) = self.out.take() {
            let McapOut {
                mut writer, path, ..
            } = out;
            if self.failed.is_none()
                && let Err(e) = writer.finish()
            {
                self.fail(&e);
            }
            let mut file = writer.into_inner();
            if let Err(e) = std::io::Write::flush(&mut file) {
                self.fail(&e);
            }
            let partial = partial_path(&path);
            if self.failed.is_none() {
                // Synced, then renamed: `path` is a complete recording or not there at all.
                let done = file
                    .get_ref()
                    .sync_all()
                    .and_then(|()| std::fs::rename(&partial, &path));
                if let Err(e) = done {
                    self.fail(&format!("finishing {}: {e}", partial.display()));
                }
            }
            drop(file);
            let written = if self.failed.is_none() {
                &path
            } else {
                &partial
            };
            self.report.bytes = std::fs::metadata(written).map_or(0, |m| m.len());
        }
        match self.failed {
            Some(e) => Err(e),
            None => Ok(self.report),
        }
    }
}
