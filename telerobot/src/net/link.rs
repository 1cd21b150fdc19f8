//! The telerobot's side of the hand-off ([`transport::handoff`]): what the real-time loop and
//! the cloud source see of the network, and the network task's half.

use std::io;
use std::ops::Deref;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};

use protocol::operator_to_telerobot::Command;
use protocol::telerobot_to_operator::{CloudFrame, Datagram};
use transport::handoff::BellListener;
use transport::{LinkSnapshot, LinkStats, Mailbox, Outbox, Received, SessionCore, SessionRecorder};

/// Default outbox capacity \[messages\]: 64 ≈ 16 ms of four datagram kinds at 1 kHz; a network
/// task that lags more than that loses the oldest.
pub const DEFAULT_OUTBOX_CAPACITY: usize = 64;

/// Commands queued for the loop \[commands\]: 64 ms at 1 kHz. The loop drains the queue every tick
/// and hands **every** command to the node's playout buffer (which orders reordered datagrams and
/// drops stale ones), so a queue, not a latest-value slot; a loop stalled longer loses the oldest.
pub const COMMAND_QUEUE_CAPACITY: usize = 64;

/// Who is in control, for the loop and the report. Reads as a [`SessionCore`] (`connected()`,
/// `session()`, `since_ns()`, lock-free); the rest is the telerobot's own. Atomics except the
/// name.
#[derive(Debug, Default)]
pub struct SessionStatus {
    recorder: SessionRecorder,
    operator: Mutex<Option<String>>,
    refused_busy: AtomicU64,
    refused_other: AtomicU64,
    clouds_sent: AtomicU64,
    clouds_superseded: AtomicU64,
    clouds_failed: AtomicU64,
}

impl Deref for SessionStatus {
    type Target = SessionCore;

    fn deref(&self) -> &SessionCore {
        self.recorder.core()
    }
}

impl SessionStatus {
    /// The controlling operator's name. **Takes a lock: not for the real-time loop.**
    pub fn operator(&self) -> Option<String> {
        self.operator
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .clone()
    }

    /// Operators refused because another was in control.
    pub fn refused_busy(&self) -> u64 {
        self.refused_busy.load(Relaxed)
    }

    /// Operators refused for their version or a bad first message.
    pub fn refused_other(&self) -> u64 {
        self.refused_other.load(Relaxed)
    }

    /// Cloud frames sent through, superseded by a newer frame (stream reset), and failed.
    pub fn clouds(&self) -> (u64, u64, u64) {
        (
            self.clouds_sent.load(Relaxed),
            self.clouds_superseded.load(Relaxed),
            self.clouds_failed.load(Relaxed),
        )
    }

    pub(crate) fn begin(&self, operator: &str, now_ns: i64) -> u64 {
        *self.operator.lock().unwrap_or_else(PoisonError::into_inner) = Some(operator.to_owned());
        self.recorder.begin(now_ns)
    }

    pub(crate) fn end(&self) {
        self.recorder.end();
        *self.operator.lock().unwrap_or_else(PoisonError::into_inner) = None;
    }

    pub(crate) fn count_refusal(&self, busy: bool) {
        let counter = if busy {
            &self.refused_busy
        } else {
            &self.refused_other
        };
        counter.fetch_add(1, Relaxed);
    }

    pub(crate) fn count_cloud(&self, outcome: CloudOutcome) {
        match outcome {
            CloudOutcome::Sent => &self.clouds_sent,
            CloudOutcome::Superseded => &self.clouds_superseded,
            CloudOutcome::Failed => &self.clouds_failed,
        }
        .fetch_add(1, Relaxed);
    }
}

/// What became of a cloud frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CloudOutcome {
    Sent,
    Superseded,
    Failed,
}

/// State shared by [`TelerobotLink`] and the network task.
#[derive(Debug)]
pub(crate) struct Shared {
    pub(crate) outbox: Outbox<Datagram>,
    pub(crate) clouds: Outbox<Box<CloudFrame>>,
    pub(crate) commands: Mailbox<Received<Command>>,
    pub(crate) stats: Arc<LinkStats>,
    pub(crate) status: SessionStatus,
}

/// The real-time loop's handle on the network (cheap to clone; share it with the cloud source).
///
/// # What the 1 kHz loop may call
///
/// [`send`](Self::send), [`next_command`](Self::next_command), [`stats`](Self::stats),
/// [`status`](Self::status)`().connected()/session()/since_ns()`: none of them blocks, locks or
/// allocates (see [`transport::handoff`]). [`send_cloud`](Self::send_cloud) and
/// `status().operator()` are for other threads.
#[derive(Clone, Debug)]
pub struct TelerobotLink {
    shared: Arc<Shared>,
}

/// The network task's half, given to [`super::serve`].
#[derive(Debug)]
pub struct NetIo {
    pub(crate) shared: Arc<Shared>,
    pub(crate) datagram_bell: BellListener,
    pub(crate) cloud_bell: BellListener,
}

/// Creates the hand-off: the loop's [`TelerobotLink`] and the network task's [`NetIo`], with an
/// outbox of `outbox_capacity` datagrams (e.g. [`DEFAULT_OUTBOX_CAPACITY`]).
pub fn link(outbox_capacity: usize) -> io::Result<(TelerobotLink, NetIo)> {
    let (outbox, datagram_bell) = Outbox::new(outbox_capacity)?;
    let (clouds, cloud_bell) = Outbox::new(1)?;
    let shared = Arc::new(Shared {
        outbox,
        clouds,
        commands: Mailbox::new(COMMAND_QUEUE_CAPACITY),
        stats: LinkStats::new(),
        status: SessionStatus::default(),
    });
    Ok((
        TelerobotLink {
            shared: Arc::clone(&shared),
        },
        NetIo {
            shared,
            datagram_bell,
            cloud_bell,
        },
    ))
}

impl TelerobotLink {
    /// Queues a datagram for the operator. Returns `false` if the oldest queued one was dropped
    /// to make room (the network task lags). While no operator is connected the queue simply
    /// overwrites itself; it is cleared when a session starts. RT-safe.
    pub fn send(&self, datagram: Datagram) -> bool {
        self.shared.outbox.push(datagram)
    }

    /// The oldest command not yet taken (in arrival order), stamped with its receipt time;
    /// `None` when the queue is empty. Take them all every tick. RT-safe.
    pub fn next_command(&self) -> Option<Received<Command>> {
        self.shared.commands.take()
    }

    /// Commands dropped from a full command queue (the loop did not drain it), since start.
    pub fn commands_overwritten(&self) -> u64 {
        self.shared.commands.overwritten()
    }

    /// Offers a point-cloud frame; a frame not yet sent is replaced (latest wins), and one still
    /// being sent is reset when the next starts. Drops the replaced frame on this thread: **not
    /// for the real-time loop.**
    pub fn send_cloud(&self, frame: Box<CloudFrame>) {
        self.shared.clouds.push(frame);
    }

    /// Link counters and RTT. Lock-free.
    pub fn stats(&self) -> LinkSnapshot {
        self.shared.stats.snapshot()
    }

    /// Datagrams dropped from a full outbox, since start.
    pub fn outbox_overwritten(&self) -> u64 {
        self.shared.outbox.mailbox().overwritten()
    }

    /// Who is in control.
    pub fn status(&self) -> &SessionStatus {
        &self.shared.status
    }
}
