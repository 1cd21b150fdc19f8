//! The per-packet CSV log: the ground truth of the delay each packet was given.
//!
//! Records travel over a bounded channel to a writer thread with a buffered file, so neither the
//! receive threads nor the scheduler ever touch the file. When the channel is full a record is
//! counted as lost rather than making the scheduler wait.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::sync::atomic::Ordering::Relaxed;
use std::sync::mpsc::{Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use super::{Direction, Shared};

/// Header of the CSV log.
pub const CSV_HEADER: &str = "dir,packet,seq,len,arrival_ns,due_ns,release_ns,fate";

/// Records the channel holds before records are dropped (≈ 16 s of a 1 kHz stream each way).
pub(super) const LOG_CHANNEL_CAPACITY: usize = 1 << 15;

/// What happened to one packet copy, as written in the log's `fate` column.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LogFate {
    /// Sent after its delay.
    Forwarded,
    /// The extra copy of a duplicated packet, sent.
    Duplicate,
    /// Sent at once by the reorder option.
    Reordered,
    /// Dropped by the loss model.
    Lost,
    /// Dropped because the queue was full.
    Limit,
    /// The send call failed.
    SendError,
    /// A down-direction packet with no client to send it to.
    NoClient,
}

impl LogFate {
    fn as_str(self) -> &'static str {
        match self {
            Self::Forwarded => "forwarded",
            Self::Duplicate => "duplicate",
            Self::Reordered => "reordered",
            Self::Lost => "lost",
            Self::Limit => "limit",
            Self::SendError => "send_error",
            Self::NoClient => "no_client",
        }
    }
}

/// One row of the log. Times in ns of [`rt::monotonic_ns`].
#[derive(Clone, Copy, Debug)]
pub(super) struct LogRecord {
    pub(super) dir: Direction,
    /// Arrival index in this direction, from 0.
    pub(super) packet: u64,
    /// The scheduler's sequence number (unique per copy); `None` for a dropped packet.
    pub(super) seq: Option<u64>,
    pub(super) len: usize,
    pub(super) arrival_ns: u64,
    pub(super) due_ns: Option<u64>,
    pub(super) release_ns: Option<u64>,
    pub(super) fate: LogFate,
}

/// The sending side, shared by the worker threads. Never blocks.
#[derive(Clone, Debug)]
pub(super) struct LogSink {
    tx: Option<SyncSender<LogRecord>>,
    shared: Arc<Shared>,
}

impl LogSink {
    pub(super) fn new(tx: Option<SyncSender<LogRecord>>, shared: Arc<Shared>) -> Self {
        Self { tx, shared }
    }

    pub(super) fn record(&self, record: LogRecord) {
        let Some(tx) = &self.tx else { return };
        match tx.try_send(record) {
            Ok(()) | Err(TrySendError::Disconnected(_)) => {}
            Err(TrySendError::Full(_)) => {
                self.shared.log_records_dropped.fetch_add(1, Relaxed);
            }
        }
    }
}

/// Creates the file and writes the header (so a bad path fails at start-up).
pub(super) fn create(path: &Path) -> std::io::Result<BufWriter<File>> {
    let mut out = BufWriter::with_capacity(1 << 16, File::create(path)?);
    writeln!(out, "{CSV_HEADER}")?;
    Ok(out)
}

/// The writer thread: drains records until every sender is gone, flushing when idle for 200 ms,
/// at least every second while busy, and at the end. A write error is kept for the stats and
/// stops the writing.
pub(super) fn write_all(
    mut out: BufWriter<File>,
    rx: Receiver<LogRecord>,
    error: &Mutex<Option<String>>,
) {
    let mut last_flush = Instant::now();
    let mut result = Ok(());
    while result.is_ok() {
        result = match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(record) => write_record(&mut out, &record).and_then(|()| {
                if last_flush.elapsed() < Duration::from_secs(1) {
                    return Ok(());
                }
                last_flush = Instant::now();
                out.flush()
            }),
            Err(RecvTimeoutError::Timeout) => {
                last_flush = Instant::now();
                out.flush()
            }
            Err(RecvTimeoutError::Disconnected) => break,
        };
    }
    let result = result.and_then(|()| out.flush());
    if let Err(e) = result {
        *error.lock().unwrap_or_else(PoisonError::into_inner) = Some(e.to_string());
    }
}

fn write_record(out: &mut impl Write, r: &LogRecord) -> std::io::Result<()> {
    let opt = |v: Option<u64>| v.map(|v| v.to_string()).unwrap_or_default();
    writeln!(
        out,
        "{},{},{},{},{},{},{},{}",
        r.dir,
        r.packet,
        opt(r.seq),
        r.len,
        r.arrival_ns,
        opt(r.due_ns),
        opt(r.release_ns),
        r.fate.as_str()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_leave_missing_times_empty() {
        let mut out = Vec::new();
        let record = LogRecord {
            dir: Direction::Down,
            packet: 3,
            seq: None,
            len: 64,
            arrival_ns: 10,
            due_ns: None,
            release_ns: None,
            fate: LogFate::Lost,
        };
        write_record(&mut out, &record).unwrap();
        assert_eq!(String::from_utf8(out).unwrap(), "down,3,,64,10,,,lost\n");
    }
}
