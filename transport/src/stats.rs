//! Link statistics shared with the real-time side as atomics, and [`DatagramLink`], the network
//! task's per-connection datagram bookkeeping that fills them.
//!
//! Counters are cumulative over the daemon's life (across sessions); RTT and clock values belong
//! to the current session and are cleared ([`LinkStats::clear_session`]) when it ends.

use std::sync::Arc;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering::Relaxed};

use bytes::Bytes;
use protocol::Header;
use protocol::session::{Arrival, Session};

/// Marks an absent value in an `AtomicI64`.
const NONE: i64 = i64::MIN;

/// How many recent RTT samples the median is taken over.
pub const RTT_WINDOW: usize = 512;

/// The counters of one daemon's link, updated by the network task, read by anyone (relaxed
/// atomics: each value is exact, a snapshot is not one instant).
#[derive(Debug)]
pub struct LinkStats {
    sent: AtomicU64,
    send_oversized: AtomicU64,
    send_failed: AtomicU64,
    garbage: AtomicU64,
    received: AtomicU64,
    accepted: AtomicU64,
    late: AtomicU64,
    duplicates: AtomicU64,
    lost: AtomicU64,
    rtt_latest_ns: AtomicI64,
    rtt_smoothed_ns: AtomicI64,
    rtt_min_ns: AtomicI64,
    rtt_p50_ns: AtomicI64,
    clock_offset_ns: AtomicI64,
    clock_delay_ns: AtomicI64,
    /// Counts of earlier sessions (order of `sequence_counters`), so the peer's sequence counts
    /// stay cumulative.
    base: [AtomicU64; 5],
    /// quinn's own counts ([`QUINN_COUNTS`] order), cumulative over sessions.
    quinn: [AtomicU64; 3],
    /// ... of earlier sessions.
    quinn_base: [AtomicU64; 3],
    /// quinn's congestion window of the current connection \[bytes\] (`u64::MAX`: none yet).
    quinn_cwnd_bytes: AtomicU64,
    /// Longest time between two accepted datagrams of one session \[ns\] (0: none yet).
    max_gap_ns: AtomicI64,
}

/// What [`LinkStats::quinn`] counts, from `quinn::Connection::stats()`: datagram frames
/// transmitted, congestion events, packets declared lost.
pub const QUINN_COUNTS: [&str; 3] = [
    "datagram frames transmitted",
    "congestion events",
    "lost packets",
];

/// Sends between two reads of quinn's connection statistics (about 1 s at 1 kHz).
const QUINN_EVERY: u64 = 1024;

impl Default for LinkStats {
    fn default() -> Self {
        LinkStats {
            sent: AtomicU64::new(0),
            send_oversized: AtomicU64::new(0),
            send_failed: AtomicU64::new(0),
            garbage: AtomicU64::new(0),
            received: AtomicU64::new(0),
            accepted: AtomicU64::new(0),
            late: AtomicU64::new(0),
            duplicates: AtomicU64::new(0),
            lost: AtomicU64::new(0),
            rtt_latest_ns: AtomicI64::new(NONE),
            rtt_smoothed_ns: AtomicI64::new(NONE),
            rtt_min_ns: AtomicI64::new(NONE),
            rtt_p50_ns: AtomicI64::new(NONE),
            clock_offset_ns: AtomicI64::new(NONE),
            clock_delay_ns: AtomicI64::new(NONE),
            base: Default::default(),
            quinn: Default::default(),
            quinn_base: Default::default(),
            quinn_cwnd_bytes: AtomicU64::new(u64::MAX),
            max_gap_ns: AtomicI64::new(0),
        }
    }
}

/// A copy of [`LinkStats`]. Counts since the daemon started; RTT and clock of the current
/// session (`None` before the first sample or between sessions).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkSnapshot {
    /// Datagrams handed to quinn.
    pub sent: u64,
    /// Datagrams not sent because they exceeded the connection's maximum datagram size.
    pub send_oversized: u64,
    /// Datagrams quinn refused (connection lost, datagrams disabled by the peer).
    pub send_failed: u64,
    /// Datagrams received that did not decode, decoded to a message that is not a datagram of
    /// this direction, or carried a sequence number implausibly far ahead
    /// ([`protocol::session::MAX_AHEAD`]): counted and ignored.
    pub garbage: u64,
    /// Well-formed datagrams with a header received (`protocol::session` counts).
    pub received: u64,
    /// ... of which the newest of their direction when they arrived.
    pub accepted: u64,
    /// ... of which reordered behind a newer one (dropped as stale for the direction).
    pub late: u64,
    /// ... of which seen before.
    pub duplicates: u64,
    /// Sequence numbers never received (`gaps − late`, per session, summed).
    pub lost: u64,
    /// Newest RTT sample from header echoes \[ns\].
    pub rtt_latest_ns: Option<i64>,
    /// Smoothed RTT (RFC 6298) \[ns\].
    pub rtt_smoothed_ns: Option<i64>,
    /// Smallest RTT sample of the session \[ns\].
    pub rtt_min_ns: Option<i64>,
    /// Median of the last [`RTT_WINDOW`] samples \[ns\] (updated by the operator's ping tick).
    pub rtt_p50_ns: Option<i64>,
    /// Clock offset θ, peer clock minus ours \[ns\] (operator only: from Ping/Pong).
    pub clock_offset_ns: Option<i64>,
    /// Round-trip delay δ of the sample θ came from \[ns\].
    pub clock_delay_ns: Option<i64>,
    /// Datagram frames quinn put on the wire. `sent − quinn_datagrams_transmitted` were dropped
    /// inside quinn (its send buffer) or still waiting there when last read: the check that
    /// quinn itself never holds datagrams back (no congestion-window or pacing queue).
    pub quinn_datagrams_transmitted: u64,
    /// Congestion events quinn's controller saw.
    pub quinn_congestion_events: u64,
    /// Packets quinn declared lost.
    pub quinn_lost_packets: u64,
    /// quinn's congestion window on the current connection \[bytes\].
    pub quinn_cwnd_bytes: Option<u64>,
    /// Longest time between two accepted datagrams within a session \[ns\]: the largest stall
    /// of the stream the loops are fed (0 before two arrived).
    pub max_gap_ns: i64,
}

fn get(a: &AtomicI64) -> Option<i64> {
    Some(a.load(Relaxed)).filter(|&v| v != NONE)
}

fn set(a: &AtomicI64, v: Option<i64>) {
    a.store(v.unwrap_or(NONE), Relaxed);
}

impl LinkStats {
    /// All counts zero, no RTT.
    pub fn new() -> Arc<LinkStats> {
        Arc::new(LinkStats::default())
    }

    /// A copy of every value. Lock-free.
    pub fn snapshot(&self) -> LinkSnapshot {
        let load = |a: &AtomicU64| a.load(Relaxed);
        LinkSnapshot {
            sent: load(&self.sent),
            send_oversized: load(&self.send_oversized),
            send_failed: load(&self.send_failed),
            garbage: load(&self.garbage),
            received: load(&self.received),
            accepted: load(&self.accepted),
            late: load(&self.late),
            duplicates: load(&self.duplicates),
            lost: load(&self.lost),
            rtt_latest_ns: get(&self.rtt_latest_ns),
            rtt_smoothed_ns: get(&self.rtt_smoothed_ns),
            rtt_min_ns: get(&self.rtt_min_ns),
            rtt_p50_ns: get(&self.rtt_p50_ns),
            clock_offset_ns: get(&self.clock_offset_ns),
            clock_delay_ns: get(&self.clock_delay_ns),
            quinn_datagrams_transmitted: load(&self.quinn[0]),
            quinn_congestion_events: load(&self.quinn[1]),
            quinn_lost_packets: load(&self.quinn[2]),
            quinn_cwnd_bytes: Some(load(&self.quinn_cwnd_bytes)).filter(|&c| c != u64::MAX),
            max_gap_ns: self.max_gap_ns.load(Relaxed),
        }
    }

    /// Counts one datagram that was not a valid datagram of this direction.
    pub fn count_garbage(&self) {
        self.garbage.fetch_add(1, Relaxed);
    }

    /// Publishes the clock offset estimate (θ, δ) \[ns\].
    pub fn set_clock(&self, offset_ns: Option<i64>, delay_ns: Option<i64>) {
        set(&self.clock_offset_ns, offset_ns);
        set(&self.clock_delay_ns, delay_ns);
    }

    /// The peer's sequence counts, in the order of `base`.
    fn sequence_counters(&self) -> [&AtomicU64; 5] {
        [
            &self.received,
            &self.accepted,
            &self.late,
            &self.duplicates,
            &self.lost,
        ]
    }

    /// Forgets the session's RTT and clock values (the counts stay).
    pub fn clear_session(&self) {
        for a in [
            &self.rtt_latest_ns,
            &self.rtt_smoothed_ns,
            &self.rtt_min_ns,
            &self.rtt_p50_ns,
            &self.clock_offset_ns,
            &self.clock_delay_ns,
        ] {
            set(a, None);
        }
    }
}

/// Why a datagram was not sent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SendOutcome {
    /// Handed to quinn.
    Sent,
    /// Larger than the connection's current maximum datagram size.
    Oversized,
    /// quinn refused it (connection lost, datagrams unsupported).
    Failed,
}

/// The network task's datagram bookkeeping for one connection: the `protocol` [`Session`]
/// (sequence numbers, echoes, RTT), a reused encode buffer, and the counters it publishes.
#[derive(Debug)]
pub struct DatagramLink {
    session: Session,
    buf: Vec<u8>,
    stats: Arc<LinkStats>,
    /// Sequence counts of this session already added to `stats`.
    published: [u64; 5],
    rtt_samples: u64,
    rtt_window: Vec<i64>,
    /// The connection datagrams are sent on (from the first send), for quinn's statistics.
    connection: Option<quinn::Connection>,
    sends: u64,
}

impl DatagramLink {
    /// Fresh bookkeeping for a new connection (sequence numbers restart at 1).
    pub fn new(stats: Arc<LinkStats>) -> DatagramLink {
        stats.clear_session();
        let published = std::array::from_fn(|i| stats.base[i].load(Relaxed));
        DatagramLink {
            session: Session::new(),
            buf: Vec::with_capacity(protocol::MAX_DATAGRAM_BYTES),
            stats,
            published,
            rtt_samples: 0,
            rtt_window: Vec::with_capacity(RTT_WINDOW),
            connection: None,
            sends: 0,
        }
    }

    /// Publishes quinn's statistics of the connection (also done every [`QUINN_EVERY`] sends and
    /// when the link is dropped).
    pub fn publish_quinn(&self) {
        let Some(connection) = &self.connection else {
            return;
        };
        let s = connection.stats();
        let values = [
            s.frame_tx.datagram,
            s.path.congestion_events,
            s.path.lost_packets,
        ];
        for ((target, base), value) in self
            .stats
            .quinn
            .iter()
            .zip(&self.stats.quinn_base)
            .zip(values)
        {
            target.store(base.load(Relaxed) + value, Relaxed);
        }
        self.stats.quinn_cwnd_bytes.store(s.path.cwnd, Relaxed);
    }

    /// Fills `header` for a datagram sent now: sequence number, send time and echo from the
    /// session; `header.sample_time_ns` (set by the real-time side) is kept.
    pub fn stamp(&mut self, header: &mut Header, now_ns: i64) {
        *header = self.session.next_header(header.sample_time_ns, now_ns);
    }

    /// Encodes with `encode` (into a reused buffer) and sends it as one datagram; counts the
    /// outcome.
    pub fn send(
        &mut self,
        connection: &quinn::Connection,
        encode: impl FnOnce(&mut Vec<u8>),
    ) -> SendOutcome {
        encode(&mut self.buf);
        if self.connection.is_none() {
            self.connection = Some(connection.clone());
        }
        self.sends += 1;
        if self.sends.is_multiple_of(QUINN_EVERY) {
            self.publish_quinn();
        }
        let outcome = if connection
            .max_datagram_size()
            .is_none_or(|max| self.buf.len() > max)
        {
            SendOutcome::Oversized
        } else if connection
            .send_datagram(Bytes::copy_from_slice(&self.buf))
            .is_ok()
        {
            SendOutcome::Sent
        } else {
            SendOutcome::Failed
        };
        let counter = match outcome {
            SendOutcome::Sent => &self.stats.sent,
            SendOutcome::Oversized => &self.stats.send_oversized,
            SendOutcome::Failed => &self.stats.send_failed,
        };
        counter.fetch_add(1, Relaxed);
        outcome
    }

    /// Takes in the header of a well-formed datagram received at `now_ns`; publishes the
    /// sequence counts and RTT. Use the datagram only as the answer allows (see
    /// [`protocol::session::LatestSeq`] for per-kind use).
    pub fn on_header(&mut self, header: &Header, now_ns: i64) -> Arrival {
        let previous = self.session.last_accepted_ns();
        let arrival = self.session.on_receive(header, now_ns);
        if arrival == Arrival::Implausible {
            self.stats.count_garbage();
        }
        if let (true, Some(previous)) = (arrival.is_accepted(), previous) {
            let gap = now_ns.saturating_sub(previous);
            self.stats.max_gap_ns.fetch_max(gap, Relaxed);
        }
        let s = *self.session.stats();
        let values = [s.received, s.accepted, s.late, s.duplicates, s.lost()];
        let targets = self.stats.sequence_counters();
        for ((value, target), base) in values.iter().zip(targets).zip(&self.published) {
            target.store(base + value, Relaxed);
        }
        let rtt = self.session.rtt();
        if rtt.samples() != self.rtt_samples {
            self.rtt_samples = rtt.samples();
            set(&self.stats.rtt_latest_ns, rtt.latest_ns());
            set(&self.stats.rtt_smoothed_ns, rtt.smoothed_ns());
            set(&self.stats.rtt_min_ns, rtt.min_ns());
            if let Some(sample) = rtt.latest_ns() {
                if self.rtt_window.len() < RTT_WINDOW {
                    self.rtt_window.push(sample);
                } else {
                    // A ring: overwrite the oldest.
                    self.rtt_window[(self.rtt_samples % RTT_WINDOW as u64) as usize] = sample;
                }
            }
        }
        arrival
    }

    /// Publishes the median of the recent RTT samples (sorts a copy: call it at a low rate).
    pub fn publish_rtt_median(&self) {
        let mut sorted = self.rtt_window.clone();
        sorted.sort_unstable();
        set(
            &self.stats.rtt_p50_ns,
            sorted.get(sorted.len() / 2).copied(),
        );
    }

    /// The session's bookkeeping.
    pub fn session(&self) -> &Session {
        &self.session
    }

    /// The shared counters.
    pub fn stats(&self) -> &LinkStats {
        &self.stats
    }
}

impl Drop for DatagramLink {
    /// Folds this session's sequence counts into the base of the next.
    fn drop(&mut self) {
        for (base, target) in self.stats.base.iter().zip(self.stats.sequence_counters()) {
            base.store(target.load(Relaxed), Relaxed);
        }
        self.publish_quinn();
        for (base, target) in self.stats.quinn_base.iter().zip(&self.stats.quinn) {
            base.store(target.load(Relaxed), Relaxed);
        }
        self.stats.quinn_cwnd_bytes.store(u64::MAX, Relaxed);
        self.stats.clear_session();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use protocol::session::MAX_AHEAD;

    fn header(seq: u64) -> Header {
        Header {
            seq,
            sample_time_ns: 0,
            send_time_ns: 0,
            echo_seq: protocol::NO_ECHO,
            echo_hold_ns: 0,
        }
    }

    #[test]
    fn an_implausible_sequence_number_is_garbage_and_the_link_goes_on() {
        let stats = LinkStats::new();
        let mut link = DatagramLink::new(Arc::clone(&stats));
        assert!(link.on_header(&header(1), 10).is_accepted());
        assert_eq!(link.on_header(&header(u64::MAX), 20), Arrival::Implausible);
        assert_eq!(
            link.on_header(&header(2 + MAX_AHEAD), 30),
            Arrival::Implausible
        );
        assert!(link.on_header(&header(2), 40).is_accepted());
        let s = stats.snapshot();
        assert_eq!((s.garbage, s.received, s.accepted), (2, 4, 2));
        assert_eq!(s.max_gap_ns, 30, "between the two accepted ones");
    }

    #[test]
    fn sequence_counts_stay_cumulative_across_sessions() {
        let stats = LinkStats::new();
        for _ in 0..2 {
            let mut link = DatagramLink::new(Arc::clone(&stats));
            for seq in [1, 2, 4, 3, 4] {
                link.on_header(&header(seq), 0);
            }
        }
        let s = stats.snapshot();
        assert_eq!(
            (s.received, s.accepted, s.late, s.duplicates, s.lost),
            (10, 6, 2, 2, 0)
        );
    }
}
