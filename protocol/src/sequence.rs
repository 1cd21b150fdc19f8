//! Latest-wins acceptance of datagrams by sequence number, with loss and reordering counts.
//!
//! Datagrams may be lost, duplicated or reordered (RFC 9221; the netem shim does all three).
//! Every datagram is a complete state, so the receiver only ever wants the newest: it accepts a
//! datagram whose `seq` is above every one accepted so far and drops the rest. A 64-entry bitmap
//! behind the newest (the anti-replay window of IPsec/DTLS) tells a duplicate from a late,
//! reordered arrival, so that the counts can separate loss from reordering. No allocation.

/// How far behind the newest accepted `seq` a datagram can still be told duplicate or late.
pub const REORDER_WINDOW: u64 = 64;

/// How far ahead of the newest accepted `seq` a datagram may be and still be believed: 2²⁴
/// sequence numbers, 4.6 hours of datagrams at 1 kHz, far beyond any gap a live connection can
/// have (its idle timeout closes it first). A `seq` further ahead is a peer's bug; accepting it
/// would make every later honest datagram look stale until the connection is replaced.
pub const MAX_AHEAD: u64 = 1 << 24;

/// What to do with one received datagram.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Arrival {
    /// Newer than all accepted so far: use it. `skipped` sequence numbers between the previous
    /// newest and this one have not arrived (lost, or still on their way).
    Newer {
        /// Sequence numbers jumped over \[count\].
        skipped: u64,
    },
    /// Older than the newest accepted and not seen before: reordered, dropped.
    Late,
    /// Seen before: dropped.
    Duplicate,
    /// More than [`REORDER_WINDOW`] behind the newest (or `seq` 0, never sent): dropped without
    /// telling duplicate from late.
    TooOld,
    /// More than [`MAX_AHEAD`] ahead of the newest: not a sequence number the peer can have
    /// reached; dropped, and the newest is left as it was.
    Implausible,
}

impl Arrival {
    /// Whether the datagram is the newest of its direction and should be used.
    pub fn is_accepted(self) -> bool {
        matches!(self, Arrival::Newer { .. })
    }
}

/// Counts of one direction's datagrams, for the session's stats report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct SequenceStats {
    /// Datagrams observed.
    pub received: u64,
    /// Datagrams accepted as the newest.
    pub accepted: u64,
    /// Datagrams dropped: `late + duplicates + too old`.
    pub stale: u64,
    /// Dropped datagrams that had been seen before.
    pub duplicates: u64,
    /// Dropped datagrams that arrived after a newer one (reordered), within the window.
    pub late: u64,
    /// Dropped datagrams whose `seq` jumped more than [`MAX_AHEAD`] ahead.
    pub implausible: u64,
    /// Sequence numbers jumped over by accepted datagrams: lost for the loops, whether or not they
    /// turn up late afterwards.
    pub gaps: u64,
}

impl SequenceStats {
    /// Sequence numbers that never arrived (as far as the window can tell): `gaps − late`.
    pub fn lost(&self) -> u64 {
        self.gaps.saturating_sub(self.late)
    }
}

/// Accepts only datagrams newer than every one accepted before; see the module doc.
#[derive(Clone, Debug, Default)]
pub struct SequenceTracker {
    /// Newest accepted `seq`; 0 before the first.
    newest: u64,
    /// Bit `i` set: `newest − i` was received.
    window: u64,
    stats: SequenceStats,
}

impl SequenceTracker {
    /// A tracker that has seen nothing (the peer's first `seq` is 1).
    pub fn new() -> SequenceTracker {
        SequenceTracker::default()
    }

    /// Classifies a received `seq` and counts it.
    pub fn observe(&mut self, seq: u64) -> Arrival {
        self.stats.received += 1;
        let arrival = if seq > self.newest.saturating_add(MAX_AHEAD) {
            Arrival::Implausible
        } else if seq > self.newest {
            let ahead = seq - self.newest;
            self.window = self.window.checked_shl(saturate_u32(ahead)).unwrap_or(0) | 1;
            self.newest = seq;
            Arrival::Newer { skipped: ahead - 1 }
        } else {
            let behind = self.newest - seq;
            if seq == 0 || behind >= REORDER_WINDOW {
                Arrival::TooOld
            } else if self.window & (1 << behind) != 0 {
                Arrival::Duplicate
            } else {
                self.window |= 1 << behind;
                Arrival::Late
            }
        };
        match arrival {
            Arrival::Newer { skipped } => {
                self.stats.accepted += 1;
                self.stats.gaps += skipped;
            }
            Arrival::Late => self.stats.late += 1,
            Arrival::Duplicate => self.stats.duplicates += 1,
            Arrival::Implausible => self.stats.implausible += 1,
            Arrival::TooOld => {}
        }
        if !arrival.is_accepted() {
            self.stats.stale += 1;
        }
        arrival
    }

    /// The newest accepted `seq`; 0 before the first.
    pub fn newest(&self) -> u64 {
        self.newest
    }

    /// The counts so far.
    pub fn stats(&self) -> &SequenceStats {
        &self.stats
    }
}

/// Latest-wins per message kind: the newest `seq` admitted so far.
///
/// All datagram kinds of a direction share one sequence, so a `Contact` reordered behind a newer
/// `Parameters` is [`Arrival::Late`] for the direction yet still the newest `Contact`. A node that
/// interleaves kinds and wants to keep such a one admits it with one `LatestSeq` per kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct LatestSeq(u64);

impl LatestSeq {
    /// True (and remembered) if `seq` is newer than every one admitted before.
    pub fn admit(&mut self, seq: u64) -> bool {
        let newer = seq > self.0;
        if newer {
            self.0 = seq;
        }
        newer
    }
}

fn saturate_u32(v: u64) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn observe_all(seqs: &[u64]) -> (Vec<Arrival>, SequenceStats) {
        let mut t = SequenceTracker::new();
        let arrivals = seqs.iter().map(|&s| t.observe(s)).collect();
        (arrivals, *t.stats())
    }

    #[test]
    fn in_order_datagrams_are_all_accepted() {
        let (arrivals, stats) = observe_all(&[1, 2, 3, 4]);
        assert!(arrivals.iter().all(|a| *a == Arrival::Newer { skipped: 0 }));
        assert_eq!(stats.accepted, 4);
        assert_eq!(stats.gaps, 0);
        assert_eq!(stats.stale, 0);
    }

    #[test]
    fn a_gap_is_counted_and_a_stale_datagram_dropped() {
        // 3 and 4 are overtaken by 5; 4 arrives late, 3 never; 5 comes twice.
        let (arrivals, stats) = observe_all(&[1, 2, 5, 4, 5]);
        assert_eq!(arrivals[2], Arrival::Newer { skipped: 2 });
        assert_eq!(arrivals[3], Arrival::Late);
        assert_eq!(arrivals[4], Arrival::Duplicate);
        assert_eq!(
            stats,
            SequenceStats {
                received: 5,
                accepted: 3,
                stale: 2,
                duplicates: 1,
                late: 1,
                implausible: 0,
                gaps: 2,
            }
        );
        assert_eq!(stats.lost(), 1);
    }

    #[test]
    fn a_late_datagram_is_not_accepted_twice() {
        let (arrivals, stats) = observe_all(&[3, 2, 2, 1]);
        assert_eq!(
            arrivals,
            [
                Arrival::Newer { skipped: 2 },
                Arrival::Late,
                Arrival::Duplicate,
                Arrival::Late
            ]
        );
        assert_eq!(stats.lost(), 0);
    }

    #[test]
    fn far_behind_or_zero_is_too_old() {
        let (arrivals, stats) = observe_all(&[100, 100 - REORDER_WINDOW, 0, 101 - REORDER_WINDOW]);
        assert_eq!(arrivals[1], Arrival::TooOld);
        assert_eq!(arrivals[2], Arrival::TooOld);
        assert_eq!(arrivals[3], Arrival::Late);
        assert_eq!(stats.stale, 3);
    }

    #[test]
    fn an_implausible_jump_is_dropped_and_honest_datagrams_go_on() {
        // A peer's bug sends u64::MAX, then a seq just beyond the bound; the honest sequence
        // continues and is still accepted.
        let (arrivals, stats) = observe_all(&[1, u64::MAX, 2 + MAX_AHEAD, 2, 1 + MAX_AHEAD, 3]);
        assert_eq!(arrivals[1], Arrival::Implausible);
        assert_eq!(arrivals[2], Arrival::Implausible);
        assert_eq!(arrivals[3], Arrival::Newer { skipped: 0 });
        // Exactly MAX_AHEAD ahead of 2 is still believed (a long outage), and then 3 is late.
        assert_eq!(
            arrivals[4],
            Arrival::Newer {
                skipped: MAX_AHEAD - 2
            }
        );
        assert_eq!(arrivals[5], Arrival::TooOld);
        assert_eq!(stats.implausible, 2);
        assert_eq!(stats.accepted, 3);
        assert_eq!(stats.stale, 3);
        // From nothing, the first datagram may be at most MAX_AHEAD.
        let (arrivals, _) = observe_all(&[MAX_AHEAD + 1, MAX_AHEAD]);
        assert_eq!(
            arrivals,
            [
                Arrival::Implausible,
                Arrival::Newer {
                    skipped: MAX_AHEAD - 1
                }
            ]
        );
    }

    #[test]
    fn latest_seq_admits_per_kind() {
        let mut contact = LatestSeq::default();
        assert!(contact.admit(7));
        assert!(!contact.admit(7));
        assert!(!contact.admit(6));
        assert!(contact.admit(9));
    }
}
