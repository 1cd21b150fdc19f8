//! The operator's side of the hand-off ([`transport::handoff`]): what the haptic loop sees of the
//! network, and the network task's half.

use std::io;
use std::ops::Deref;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};

use protocol::operator_to_telerobot::Command;
use protocol::telerobot_to_operator::{
    CloudFrame, Contact, Measurement, Parameters, StateSync, Welcome,
};
use transport::handoff::BellListener;
use transport::{LinkSnapshot, LinkStats, Mailbox, Outbox, Received, SessionCore, SessionRecorder};

/// Default outbox capacity \[commands\]: 16 ms at 1 kHz; a network task that lags more loses
/// the oldest command (the newest is what matters).
pub const DEFAULT_OUTBOX_CAPACITY: usize = 16;

/// Default measurement queue \[measurements\]: 4096, ≈ 4 s at 1 kHz, for a report thread that
/// drains in batches.
pub const DEFAULT_MEASUREMENT_CAPACITY: usize = 4096;

/// The session as the loop and the report see it. Reads as a [`SessionCore`] (`connected()`,
/// `session()`, `since_ns()`, lock-free); the rest is the operator's own. Atomics except the
/// texts.
#[derive(Debug, Default)]
pub struct SessionStatus {
    recorder: SessionRecorder,
    attempts: AtomicU64,
    welcome: Mutex<Option<Welcome>>,
    last_disconnect: Mutex<Option<String>>,
}

impl Deref for SessionStatus {
    type Target = SessionCore;

    fn deref(&self) -> &SessionCore {
        self.recorder.core()
    }
}

impl SessionStatus {
    /// Connection attempts since start (successful or not). Lock-free.
    pub fn attempts(&self) -> u64 {
        self.attempts.load(Relaxed)
    }

    /// The telerobot's `Welcome` of the current session (its scene summary). **Takes a lock: not
    /// for the real-time loop**; read it once per session.
    pub fn welcome(&self) -> Option<Welcome> {
        lock(&self.welcome).clone()
    }

    /// Why the last session or attempt ended. **Takes a lock: not for the real-time loop.**
    pub fn last_disconnect(&self) -> Option<String> {
        lock(&self.last_disconnect).clone()
    }

    pub(crate) fn attempt(&self) {
        self.attempts.fetch_add(1, Relaxed);
    }

    pub(crate) fn begin(&self, welcome: Welcome, now_ns: i64) -> u64 {
        *lock(&self.welcome) = Some(welcome);
        self.recorder.begin(now_ns)
    }

    pub(crate) fn end(&self, reason: &str) {
        self.recorder.end();
        *lock(&self.last_disconnect) = Some(reason.to_owned());
    }
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// State shared by [`OperatorLink`] and the network task.
#[derive(Debug)]
pub(crate) struct Shared {
    pub(crate) outbox: Outbox<Command>,
    pub(crate) parameters: Mailbox<Received<Parameters>>,
    pub(crate) contact: Mailbox<Received<Contact>>,
    pub(crate) state_sync: Mailbox<Received<StateSync>>,
    pub(crate) measurements: Mailbox<Received<Measurement>>,
    pub(crate) cloud: Mailbox<Received<Box<CloudFrame>>>,
    pub(crate) stats: Arc<LinkStats>,
    pub(crate) status: SessionStatus,
}

/// The haptic loop's handle on the network (cheap to clone).
///
/// # What the 1 kHz loop may call
///
/// [`send_command`](Self::send_command), [`parameters`](Self::parameters),
/// [`contact`](Self::contact), [`state_sync`](Self::state_sync),
/// [`measurement`](Self::measurement), [`stats`](Self::stats),
/// `status().connected()/session()`: none blocks, locks or allocates
/// ([`transport::handoff`]). [`cloud`](Self::cloud) hands over a heap frame (take it on the
/// contact-detection thread), and `status().welcome()/last_disconnect()` lock.
#[derive(Clone, Debug)]
pub struct OperatorLink {
    shared: Arc<Shared>,
}

/// The network task's half, given to [`super::connect_and_run`].
#[derive(Debug)]
pub struct NetIo {
    pub(crate) shared: Arc<Shared>,
    pub(crate) bell: BellListener,
}

/// Creates the hand-off with queues of the given capacities (e.g. [`DEFAULT_OUTBOX_CAPACITY`],
/// [`DEFAULT_MEASUREMENT_CAPACITY`]).
pub fn link(
    outbox_capacity: usize,
    measurement_capacity: usize,
) -> io::Result<(OperatorLink, NetIo)> {
    let (outbox, bell) = Outbox::new(outbox_capacity)?;
    let shared = Arc::new(Shared {
        outbox,
        parameters: Mailbox::latest(),
        contact: Mailbox::latest(),
        state_sync: Mailbox::latest(),
        measurements: Mailbox::new(measurement_capacity),
        cloud: Mailbox::latest(),
        stats: LinkStats::new(),
        status: SessionStatus::default(),
    });
    Ok((
        OperatorLink {
            shared: Arc::clone(&shared),
        },
        NetIo { shared, bell },
    ))
}

impl OperatorLink {
    /// Queues a command. Fill the content and `header.sample_time_ns` (the device read time,
    /// on `rt::monotonic_ns`); the network task stamps the rest of the header.
    /// Returns `false` if the oldest queued command was dropped. RT-safe.
    pub fn send_command(&self, command: Command) -> bool {
        self.shared.outbox.push(command)
    }

    /// The newest `Parameters` since the last call. RT-safe.
    pub fn parameters(&self) -> Option<Received<Parameters>> {
        self.shared.parameters.take()
    }

    /// The newest `Contact` since the last call. RT-safe.
    pub fn contact(&self) -> Option<Received<Contact>> {
        self.shared.contact.take()
    }

    /// The newest `StateSync` since the last call. RT-safe.
    pub fn state_sync(&self) -> Option<Received<StateSync>> {
        self.shared.state_sync.take()
    }

    /// The oldest queued `Measurement` (they are queued, not collapsed, for the report).
    /// RT-safe; [`measurements_overwritten`](Self::measurements_overwritten) counts the ones
    /// lost to a full queue.
    pub fn measurement(&self) -> Option<Received<Measurement>> {
        self.shared.measurements.take()
    }

    /// Measurements dropped because nobody drained the queue in time.
    pub fn measurements_overwritten(&self) -> u64 {
        self.shared.measurements.overwritten()
    }

    /// The newest point-cloud frame since the last call. **Not for the 1 kHz loop** (the caller
    /// owns a heap frame).
    pub fn cloud(&self) -> Option<Received<Box<CloudFrame>>> {
        self.shared.cloud.take()
    }

    /// Link counters, RTT and clock offset. Lock-free.
    pub fn stats(&self) -> LinkSnapshot {
        self.shared.stats.snapshot()
    }

    /// Commands dropped from a full outbox, since start.
    pub fn outbox_overwritten(&self) -> u64 {
        self.shared.outbox.mailbox().overwritten()
    }

    /// The session.
    pub fn status(&self) -> &SessionStatus {
        &self.shared.status
    }
}
