//! What both daemons' real-time loops read of their session: whether one is open, its number
//! and when it began ([`SessionCore`]). Atomics only, so every read is lock-free (a 1 kHz loop
//! may read them every tick); only the network task, through the [`SessionRecorder`] it keeps,
//! changes them. Each daemon wraps the recorder in its own `SessionStatus`, which reads as a
//! [`SessionCore`] (`Deref`) and adds what is its own (the telerobot: the controlling
//! operator's name, refusal and cloud counters; the operator: the `Welcome`, connection
//! attempts, why the last session ended).

use std::sync::atomic::{AtomicBool, AtomicI64, AtomicU64, Ordering::Relaxed};

/// A daemon's session as its loop sees it (read-only: see [`SessionRecorder`]).
#[derive(Debug, Default)]
pub struct SessionCore {
    connected: AtomicBool,
    session: AtomicU64,
    since_ns: AtomicI64,
}

impl SessionCore {
    /// Whether a session is open. Lock-free.
    pub fn connected(&self) -> bool {
        self.connected.load(Relaxed)
    }

    /// Number of the current (or last) session: one more per session opened, 0 before the first;
    /// a change means a new session (sequence numbers and the clock offset restarted).
    /// Lock-free.
    pub fn session(&self) -> u64 {
        self.session.load(Relaxed)
    }

    /// When the current (or last) session began [ns, [`rt::monotonic_ns`]]; 0 before the first.
    /// Lock-free.
    pub fn since_ns(&self) -> i64 {
        self.since_ns.load(Relaxed)
    }
}

/// The network task's hold on a [`SessionCore`]: the only way to change it.
#[derive(Debug, Default)]
pub struct SessionRecorder {
    core: SessionCore,
}

impl SessionRecorder {
    /// What the loop reads.
    pub fn core(&self) -> &SessionCore {
        &self.core
    }

    /// A session opened at `now_ns` ([`rt::monotonic_ns`]); returns its number. Call it after
    /// storing whatever else the daemon keeps of the session, so that a loop that sees
    /// `connected` sees the rest.
    pub fn begin(&self, now_ns: i64) -> u64 {
        let core = &self.core;
        core.since_ns.store(now_ns, Relaxed);
        let session = core.session.fetch_add(1, Relaxed) + 1;
        core.connected.store(true, Relaxed);
        session
    }

    /// The session ended.
    pub fn end(&self) {
        self.core.connected.store(false, Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sessions_are_numbered_from_one_and_keep_their_start() {
        let recorder = SessionRecorder::default();
        let core = recorder.core();
        let read = || (core.connected(), core.session(), core.since_ns());
        assert_eq!(read(), (false, 0, 0));
        assert_eq!(recorder.begin(1_000), 1);
        assert_eq!(read(), (true, 1, 1_000));
        recorder.end();
        assert_eq!(read(), (false, 1, 1_000));
        assert_eq!(recorder.begin(5_000), 2);
        assert_eq!(read(), (true, 2, 5_000));
    }
}
