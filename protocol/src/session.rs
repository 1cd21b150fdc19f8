//! Per-connection datagram bookkeeping, without I/O: every call takes `now_ns`.
//!
//! One [`Session`] per endpoint and connection. For each datagram sent it hands out the
//! [`Header`] (`seq`, times, echo of the peer's newest `seq`); for each datagram received it
//! decides latest-wins acceptance ([`SequenceTracker`]), remembers what to echo, and measures the
//! round-trip time from the peer's echo of our own sequence numbers ([`RttEstimator`], network
//! notes §5.3); [`Session::is_stale`] is the heartbeat check. Clock offset is in [`crate::clock`].
//!
//! `now_ns` is the caller's clock (monotonic nanoseconds in the nodes). Nothing here allocates
//! after [`Session::new`]: the 1 kHz loops call it every tick.

use crate::header::{Header, NO_ECHO};
pub use crate::sequence::{
    Arrival, LatestSeq, MAX_AHEAD, REORDER_WINDOW, SequenceStats, SequenceTracker,
};

/// Sent datagrams remembered for RTT: the echo of a `seq` older than this many datagrams gives no
/// sample. 4096 covers 4 s at 1 kHz, well above the 800 ms round trip of the 400 ms experiments.
pub const SENT_LOG_LEN: usize = 4096;

/// One endpoint's view of a connection's datagrams.
#[derive(Clone, Debug)]
pub struct Session {
    /// `seq` of the next datagram sent.
    next_seq: u64,
    incoming: SequenceTracker,
    echo: Echo,
    rtt: RttEstimator,
    /// When the newest accepted datagram arrived [ns, our clock].
    last_accepted_ns: Option<i64>,
}

impl Default for Session {
    fn default() -> Self {
        Session::new()
    }
}

impl Session {
    /// A session that has sent and received nothing (allocates the RTT send log once).
    pub fn new() -> Session {
        Session {
            next_seq: 1,
            incoming: SequenceTracker::new(),
            echo: Echo::default(),
            rtt: RttEstimator::new(),
            last_accepted_ns: None,
        }
    }

    /// The header of the next datagram to send, sent at `now_ns` (our clock) with content sampled
    /// at `sample_time_ns`. Takes the next `seq`, fills the echo fields and records `now_ns` as
    /// the datagram's `t1` for the RTT. Call it just before encoding and sending.
    pub fn next_header(&mut self, sample_time_ns: i64, now_ns: i64) -> Header {
        let seq = self.next_seq;
        self.next_seq += 1;
        let (echo_seq, echo_hold_ns) = self.echo.fields(now_ns);
        self.rtt.on_sent(seq, now_ns);
        Header {
            seq,
            sample_time_ns,
            send_time_ns: now_ns,
            echo_seq,
            echo_hold_ns,
        }
    }

    /// Stamps `header` for a datagram sent at `now_ns`: sequence number, send time and echo, as
    /// [`Session::next_header`] gives them; the content's `sample_time_ns` is kept. The one place
    /// headers are filled, by the daemons' network tasks and the in-process harness alike.
    pub fn stamp(&mut self, header: &mut Header, now_ns: i64) {
        *header = self.next_header(header.sample_time_ns, now_ns);
    }

    /// Takes in the header of a datagram received at `now_ns` (our clock). Use the datagram only
    /// if the answer [`Arrival::is_accepted`] (but see [`LatestSeq`] for per-kind use).
    pub fn on_receive(&mut self, header: &Header, now_ns: i64) -> Arrival {
        let arrival = self.incoming.observe(header.seq);
        if arrival.is_accepted() {
            self.echo.on_accepted(header.seq, now_ns);
            self.last_accepted_ns = Some(now_ns);
        }
        self.rtt
            .on_echo(header.echo_seq, header.echo_hold_ns, now_ns);
        arrival
    }

    /// Heartbeat check: true if no datagram was accepted within `max_age_ns` before `now_ns`,
    /// or none ever was. The loops then hold still (operator: zero force; telerobot: hold
    /// position) until fresh data arrives.
    pub fn is_stale(&self, now_ns: i64, max_age_ns: i64) -> bool {
        self.last_accepted_ns
            .is_none_or(|t| now_ns.saturating_sub(t) > max_age_ns)
    }

    /// When the newest accepted datagram arrived [ns, our clock].
    pub fn last_accepted_ns(&self) -> Option<i64> {
        self.last_accepted_ns
    }

    /// Counts of the peer's datagrams.
    pub fn stats(&self) -> &SequenceStats {
        self.incoming.stats()
    }

    /// Round-trip time estimates.
    pub fn rtt(&self) -> &RttEstimator {
        &self.rtt
    }
}

/// What to echo to the peer: its newest accepted `seq` and when it arrived.
#[derive(Clone, Copy, Debug, Default)]
struct Echo {
    /// `(seq, arrival time [ns, our clock])`.
    newest: Option<(u64, i64)>,
}

impl Echo {
    fn on_accepted(&mut self, seq: u64, now_ns: i64) {
        self.newest = Some((seq, now_ns));
    }

    /// `(echo_seq, echo_hold_ns)` for a datagram sent at `now_ns`; the hold saturates at
    /// `u32::MAX` and is 0 if the clock went backwards.
    fn fields(&self, now_ns: i64) -> (u64, u32) {
        match self.newest {
            None => (NO_ECHO, 0),
            Some((seq, at)) => {
                let hold = now_ns.saturating_sub(at).max(0);
                (seq, u32::try_from(hold).unwrap_or(u32::MAX))
            }
        }
    }
}

/// Round-trip time from echoed sequence numbers, without synchronised clocks (network notes
/// §5.3): `RTT = t4 − t1 − echo_hold`, where `t1` is when we sent `echo_seq` and `t4` when the
/// datagram echoing it arrived, both on our clock, and `echo_hold` is how long the peer held it,
/// a duration on its clock.
///
/// `t1` is kept per sent `seq` in a ring of [`SENT_LOG_LEN`] entries allocated once. Only the
/// first echo of each `seq` gives a sample (later ones echo the same datagram with a longer hold
/// and add nothing); echoes of datagrams no longer in the ring, a saturated hold, or a negative
/// result give none. Smoothing follows RFC 6298 (`srtt ← 7/8·srtt + 1/8·r`,
/// `rttvar ← 3/4·rttvar + 1/4·|srtt − r|`).
#[derive(Clone, Debug)]
pub struct RttEstimator {
    /// `(seq, t1)` at index `seq % SENT_LOG_LEN`; seq 0 marks an empty slot.
    sent: Box<[(u64, i64)]>,
    /// Newest `echo_seq` that gave a sample (or was tried).
    newest_echo: u64,
    latest_ns: Option<i64>,
    min_ns: Option<i64>,
    smoothed_ns: Option<i64>,
    variation_ns: i64,
    samples: u64,
}

impl Default for RttEstimator {
    fn default() -> Self {
        RttEstimator::new()
    }
}

impl RttEstimator {
    /// An estimator with an empty send log.
    pub fn new() -> RttEstimator {
        RttEstimator {
            sent: vec![(0, 0); SENT_LOG_LEN].into_boxed_slice(),
            newest_echo: NO_ECHO,
            latest_ns: None,
            min_ns: None,
            smoothed_ns: None,
            variation_ns: 0,
            samples: 0,
        }
    }

    /// Records that datagram `seq` was sent at `t1_ns` (our clock).
    pub fn on_sent(&mut self, seq: u64, t1_ns: i64) {
        self.sent[slot(seq)] = (seq, t1_ns);
    }

    /// Takes the echo fields of a datagram that arrived at `t4_ns` (our clock); returns the new
    /// RTT sample \[ns\], if it gave one.
    pub fn on_echo(&mut self, echo_seq: u64, echo_hold_ns: u32, t4_ns: i64) -> Option<i64> {
        if echo_seq <= self.newest_echo {
            return None;
        }
        self.newest_echo = echo_seq;
        let (seq, t1_ns) = self.sent[slot(echo_seq)];
        if seq != echo_seq || echo_hold_ns == u32::MAX {
            return None;
        }
        let rtt = t4_ns
            .checked_sub(t1_ns)?
            .checked_sub(i64::from(echo_hold_ns))?;
        if rtt < 0 {
            return None;
        }
        self.add_sample(rtt);
        Some(rtt)
    }

    /// Takes a sample `rtt ≥ 0`. The weighted sums are formed in `i128` and are convex
    /// combinations of `i64` values, so they fit back.
    fn add_sample(&mut self, rtt: i64) {
        self.samples += 1;
        self.latest_ns = Some(rtt);
        self.min_ns = Some(self.min_ns.map_or(rtt, |m| m.min(rtt)));
        let (srtt, var) = match self.smoothed_ns {
            None => (i128::from(rtt), i128::from(rtt) / 2),
            Some(s) => {
                let (s, var, r) = (
                    i128::from(s),
                    i128::from(self.variation_ns),
                    i128::from(rtt),
                );
                ((7 * s + r) / 8, (3 * var + (s - r).abs()) / 4)
            }
        };
        self.smoothed_ns = Some(narrow(srtt));
        self.variation_ns = narrow(var);
    }

    /// The newest sample \[ns\].
    pub fn latest_ns(&self) -> Option<i64> {
        self.latest_ns
    }

    /// The smallest sample so far \[ns\]: the path's RTT without queueing.
    pub fn min_ns(&self) -> Option<i64> {
        self.min_ns
    }

    /// Smoothed RTT (RFC 6298 `srtt`) \[ns\].
    pub fn smoothed_ns(&self) -> Option<i64> {
        self.smoothed_ns
    }

    /// RTT variation (RFC 6298 `rttvar`) \[ns\]; 0 before the first sample.
    pub fn variation_ns(&self) -> i64 {
        self.variation_ns
    }

    /// Number of samples taken.
    pub fn samples(&self) -> u64 {
        self.samples
    }
}

fn narrow(v: i128) -> i64 {
    i64::try_from(v).unwrap_or(if v < 0 { i64::MIN } else { i64::MAX })
}

fn slot(seq: u64) -> usize {
    // SENT_LOG_LEN is a power of two well inside usize, so the remainder fits.
    (seq % SENT_LOG_LEN as u64) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// Sends one datagram from `from` to `to`, leaving at `t_send` and arriving at `t_arrive`.
    fn deliver(from: &mut Session, to: &mut Session, t_send: i64, t_arrive: i64) -> Arrival {
        let h = from.next_header(t_send, t_send);
        to.on_receive(&h, t_arrive)
    }

    #[test]
    fn rtt_is_exact_on_a_scripted_exchange() {
        // Operator and telerobot clocks differ by 5 s; each way takes 40 ms; the telerobot holds
        // the operator's datagram 3 ms before its next send.
        let offset = 5_000 * MS;
        let (mut op, mut tr) = (Session::new(), Session::new());
        assert!(deliver(&mut op, &mut tr, 100 * MS, 140 * MS + offset).is_accepted());
        let h = tr.next_header(0, 143 * MS + offset);
        assert_eq!((h.echo_seq, h.echo_hold_ns), (1, 3 * MS as u32));
        assert!(op.on_receive(&h, 183 * MS).is_accepted());
        assert_eq!(op.rtt().latest_ns(), Some(80 * MS));
        assert_eq!(op.rtt().smoothed_ns(), Some(80 * MS));
        assert_eq!(op.rtt().variation_ns(), 40 * MS);
        // A second datagram echoing the same seq gives no new sample.
        let h = tr.next_header(0, 150 * MS + offset);
        op.on_receive(&h, 190 * MS);
        assert_eq!(op.rtt().samples(), 1);
    }

    #[test]
    fn rtt_smooths_and_keeps_the_minimum() {
        let mut rtt = RttEstimator::new();
        for (seq, t1, t4, hold) in [(1, 0, 100, 0), (2, 10, 90, 0), (3, 20, 160, 20)] {
            rtt.on_sent(seq, t1);
            rtt.on_echo(seq, hold, t4);
        }
        // Samples 100, 80, 120: srtt 100 → 97 → 99; rttvar 50 → 42 → 37.
        assert_eq!(rtt.min_ns(), Some(80));
        assert_eq!(rtt.latest_ns(), Some(120));
        assert_eq!(rtt.smoothed_ns(), Some(99));
        assert_eq!(rtt.variation_ns(), 37);
    }

    #[test]
    fn echoes_without_a_usable_t1_give_no_sample() {
        let mut rtt = RttEstimator::new();
        assert_eq!(rtt.on_echo(NO_ECHO, 0, 10), None);
        assert_eq!(rtt.on_echo(5, 0, 10), None, "never sent");
        rtt.on_sent(6, 0);
        rtt.on_sent(6 + SENT_LOG_LEN as u64, 1);
        assert_eq!(rtt.on_echo(6, 0, 10), None, "overwritten in the ring");
        rtt.on_sent(7000, 0);
        assert_eq!(
            rtt.on_echo(7000, u32::MAX, i64::MAX),
            None,
            "saturated hold"
        );
        rtt.on_sent(7001, 100);
        assert_eq!(rtt.on_echo(7001, 50, 120), None, "negative");
        rtt.on_sent(7002, i64::MIN);
        assert_eq!(rtt.on_echo(7002, 0, i64::MAX), None, "overflow");
        assert_eq!(rtt.samples(), 0);
    }

    #[test]
    fn hold_saturates_and_never_goes_negative() {
        let mut echo = Echo::default();
        assert_eq!(echo.fields(0), (NO_ECHO, 0));
        echo.on_accepted(9, 1_000);
        assert_eq!(echo.fields(1_500), (9, 500));
        assert_eq!(echo.fields(500), (9, 0));
        assert_eq!(echo.fields(i64::MAX), (9, u32::MAX));
    }

    #[test]
    fn stale_datagrams_are_dropped_and_do_not_refresh_the_echo() {
        let (mut a, mut b) = (Session::new(), Session::new());
        let h1 = a.next_header(0, 0);
        let h2 = a.next_header(1, 1);
        assert!(b.on_receive(&h2, 10).is_accepted());
        assert_eq!(b.on_receive(&h1, 11), Arrival::Late);
        assert_eq!(b.on_receive(&h2, 12), Arrival::Duplicate);
        let reply = b.next_header(0, 20);
        assert_eq!((reply.echo_seq, reply.echo_hold_ns), (2, 10));
        assert_eq!(b.stats().stale, 2);
        assert_eq!(b.last_accepted_ns(), Some(10));
    }

    #[test]
    fn staleness_follows_the_newest_accepted_datagram() {
        let (mut a, mut b) = (Session::new(), Session::new());
        assert!(b.is_stale(0, 100 * MS), "nothing received yet");
        deliver(&mut a, &mut b, 0, 10 * MS);
        assert!(!b.is_stale(110 * MS, 100 * MS));
        assert!(b.is_stale(110 * MS + 1, 100 * MS));
        assert!(
            !b.is_stale(i64::MIN, 100 * MS),
            "clock going backwards is not staleness"
        );
    }

    #[test]
    fn stamping_keeps_the_sample_time_and_fills_the_rest() {
        let (mut a, mut b) = (Session::new(), Session::new());
        let mut h = Header::unstamped(7 * MS);
        assert_eq!((h.seq, h.send_time_ns), (0, 0));
        a.stamp(&mut h, 9 * MS);
        assert_eq!(
            (h.seq, h.sample_time_ns, h.send_time_ns),
            (1, 7 * MS, 9 * MS)
        );
        assert!(b.on_receive(&h, 10 * MS).is_accepted());
        let mut reply = Header::unstamped(0);
        b.stamp(&mut reply, 12 * MS);
        assert_eq!((reply.echo_seq, reply.echo_hold_ns), (1, 2 * MS as u32));
    }

    #[test]
    fn sequence_numbers_start_at_one_and_the_gap_is_counted() {
        let (mut a, mut b) = (Session::new(), Session::new());
        assert_eq!(a.next_header(0, 0).seq, 1);
        let _lost = a.next_header(0, 1);
        assert_eq!(deliver(&mut a, &mut b, 2, 3), Arrival::Newer { skipped: 2 });
        assert_eq!(b.stats().gaps, 2);
    }
}
