//! Lock-free hand-off between a real-time thread and the network task (`DESIGN.md` §2, STYLE
//! principle 3: latest values, not locks).
//!
//! # The contract
//!
//! What a real-time thread (the 1 kHz loops) may call, every tick:
//! - [`Mailbox::push`] / [`Outbox::push`]: a bounded lock-free queue (`crossbeam_queue::ArrayQueue`);
//!   when full the **oldest** entry is dropped and counted, so a lagging network costs the oldest
//!   message, never a blocked loop;
//! - [`Mailbox::take`]: the newest (or next) value, if one came since the last take;
//! - [`Outbox::push`] also rings the [`Bell`]: the first ring since the network task last woke
//!   writes one byte to a non-blocking Unix datagram socket (one `send` system call, no
//!   user-space lock, so no priority inversion against a preempted tokio thread); further rings
//!   before the network task wakes are a single atomic swap;
//! - the atomic counters and snapshots of [`crate::stats`].
//!
//! None of these blocks, takes a lock or allocates, provided the values pushed carry no heap data
//! (the `protocol` datagram messages do not) and values taken are not dropped with heap data on
//! the real-time thread (point-cloud frames are taken by a helper thread, not the 1 kHz tick).
//!
//! What runs on the network side: [`BellListener::wait`] (async), `pop`, `publish`.

use std::io;
use std::os::unix::net::UnixDatagram as StdUnixDatagram;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crossbeam_queue::ArrayQueue;

/// A value that came from the network, stamped on receipt.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Received<T> {
    /// The message.
    pub message: T,
    /// When the network task received it [ns, [`rt::monotonic_ns`]].
    pub received_ns: i64,
    /// The connection it came on (increases by one per accepted session; see the daemons'
    /// status). Sequence numbers and clocks restart with a new session.
    pub session: u64,
}

/// A bounded multi-producer multi-consumer queue that drops its oldest entry when full. With
/// capacity 1 ([`Mailbox::latest`]) it is a latest-value slot.
#[derive(Debug)]
pub struct Mailbox<T> {
    queue: ArrayQueue<T>,
    overwritten: AtomicU64,
}

impl<T> Mailbox<T> {
    /// A queue of `capacity` entries (at least 1), allocated here, once.
    pub fn new(capacity: usize) -> Mailbox<T> {
        Mailbox {
            queue: ArrayQueue::new(capacity.max(1)),
            overwritten: AtomicU64::new(0),
        }
    }

    /// A latest-value slot: each push replaces the value not yet taken.
    pub fn latest() -> Mailbox<T> {
        Mailbox::new(1)
    }

    /// Adds `value`; if the queue is full the oldest entry is dropped (here, on the caller's
    /// thread) and counted. Returns whether nothing was dropped. Lock-free, no allocation.
    pub fn push(&self, value: T) -> bool {
        match self.queue.force_push(value) {
            None => true,
            Some(_oldest) => {
                self.overwritten.fetch_add(1, Ordering::Relaxed);
                false
            }
        }
    }

    /// The oldest entry (for a latest-value slot: the value), if any. Lock-free, no allocation.
    pub fn take(&self) -> Option<T> {
        self.queue.pop()
    }

    /// Entries dropped by a push into a full queue, since creation. For a latest-value slot this
    /// counts values that were superseded before anyone took them.
    pub fn overwritten(&self) -> u64 {
        self.overwritten.load(Ordering::Relaxed)
    }

    /// Entries waiting.
    pub fn len(&self) -> usize {
        self.queue.len()
    }

    /// Whether nothing is waiting.
    pub fn is_empty(&self) -> bool {
        self.queue.is_empty()
    }

    /// Drops everything waiting (e.g. stale messages at the start of a new session); returns how
    /// many.
    pub fn clear(&self) -> usize {
        std::iter::from_fn(|| self.queue.pop()).count()
    }
}

/// A [`Mailbox`] from real-time threads to the network task, with the [`Bell`] that wakes it.
#[derive(Debug)]
pub struct Outbox<T> {
    mailbox: Mailbox<T>,
    bell: Bell,
}

impl<T> Outbox<T> {
    /// An outbox of `capacity` entries and the listener the network task waits on.
    pub fn new(capacity: usize) -> io::Result<(Outbox<T>, BellListener)> {
        let (bell, listener) = doorbell()?;
        Ok((
            Outbox {
                mailbox: Mailbox::new(capacity),
                bell,
            },
            listener,
        ))
    }

    /// Queues `value` for sending and wakes the network task. Returns whether nothing was
    /// dropped to make room. Never blocks; no lock, no allocation.
    pub fn push(&self, value: T) -> bool {
        let kept = self.mailbox.push(value);
        self.bell.ring();
        kept
    }

    /// The queue itself (the network side pops from it).
    pub fn mailbox(&self) -> &Mailbox<T> {
        &self.mailbox
    }
}

/// The real-time side of a doorbell: wakes a task waiting in [`BellListener::wait`].
#[derive(Debug)]
pub struct Bell {
    socket: StdUnixDatagram,
    /// A ring is pending (sent, not yet heard): further rings need no system call.
    pending: Arc<AtomicBool>,
}

/// The network side of a doorbell.
#[derive(Debug)]
pub struct BellListener {
    socket: Listening,
    pending: Arc<AtomicBool>,
}

#[derive(Debug)]
enum Listening {
    /// Not yet registered with the tokio reactor (done on the first wait, inside the runtime).
    Std(StdUnixDatagram),
    Tokio(tokio::net::UnixDatagram),
    /// Registration failed once; kept to report the error again.
    Failed,
}

/// A connected pair of non-blocking Unix datagram sockets.
pub fn doorbell() -> io::Result<(Bell, BellListener)> {
    let (ring, listen) = StdUnixDatagram::pair()?;
    ring.set_nonblocking(true)?;
    listen.set_nonblocking(true)?;
    let pending = Arc::new(AtomicBool::new(false));
    Ok((
        Bell {
            socket: ring,
            pending: Arc::clone(&pending),
        },
        BellListener {
            socket: Listening::Std(listen),
            pending,
        },
    ))
}

impl Bell {
    /// Wakes the listener. The first ring after the listener woke sends one byte; if that send
    /// fails (it cannot block: the socket is non-blocking and at most one byte is pending) the
    /// next ring tries again.
    pub fn ring(&self) {
        if !self.pending.swap(true, Ordering::AcqRel) && self.socket.send(&[1]).is_err() {
            self.pending.store(false, Ordering::Release);
        }
    }
}

impl BellListener {
    /// Waits for a ring (returns at once if one is pending), then re-arms the bell: values pushed
    /// before the ring are visible to the caller's pops after this returns. Cancel-safe.
    pub async fn wait(&mut self) -> io::Result<()> {
        self.socket = match std::mem::replace(&mut self.socket, Listening::Failed) {
            Listening::Std(std) => Listening::Tokio(tokio::net::UnixDatagram::from_std(std)?),
            registered => registered,
        };
        let Listening::Tokio(socket) = &self.socket else {
            return Err(io::Error::other(
                "the doorbell socket could not be registered",
            ));
        };
        let mut buf = [0u8; 16];
        socket.recv(&mut buf).await?;
        // Drain anything else (several rings can land while a previous wake is handled).
        while socket.try_recv(&mut buf).is_ok() {}
        self.pending.swap(false, Ordering::AcqRel);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_mailbox_drops_the_oldest() {
        let m = Mailbox::new(2);
        assert!(m.push(1));
        assert!(m.push(2));
        assert!(!m.push(3));
        assert_eq!((m.take(), m.take(), m.take()), (Some(2), Some(3), None));
        assert_eq!(m.overwritten(), 1);
        let latest = Mailbox::latest();
        latest.push('a');
        latest.push('b');
        assert_eq!(latest.take(), Some('b'));
        assert_eq!(latest.take(), None);
        m.push(4);
        assert_eq!(m.clear(), 1);
        assert!(m.is_empty());
    }

    #[tokio::test]
    async fn the_bell_wakes_the_listener_once_per_batch() {
        let (outbox, mut listener) = Outbox::new(8).unwrap();
        for i in 0..5 {
            outbox.push(i);
        }
        listener.wait().await.unwrap();
        assert_eq!(outbox.mailbox().len(), 5);
        // Re-armed: a push after the wake rings again.
        outbox.mailbox().clear();
        let o = Arc::new(outbox);
        let pusher = Arc::clone(&o);
        std::thread::spawn(move || pusher.push(9)).join().unwrap();
        listener.wait().await.unwrap();
        assert_eq!(o.mailbox().take(), Some(9));
    }
}
