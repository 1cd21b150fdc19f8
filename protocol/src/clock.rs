//! Clock offset between operator and telerobot from an NTP-style four-timestamp exchange over the
//! connection itself (network notes §5.2), without I/O.
//!
//! ```text
//! operator  t1 ──Ping{id, t1}──▶ t2  telerobot
//!           t4 ◀──Pong{id, t1, t2, t3}── t3
//!
//! offset θ = ((t2 − t1) + (t3 − t4)) / 2     (peer clock − our clock)
//! delay  δ = (t4 − t1) − (t3 − t2)           (round trip without the peer's hold)
//! ```
//!
//! θ is exact when the two one-way delays are equal; otherwise it is off by half their difference,
//! `(d_forward − d_return)/2`, which is also the bound on its error since δ = d_forward +
//! d_return. Queueing makes a sample's paths unequal, so the estimator keeps the sample with the
//! smallest δ over the last [`OFFSET_WINDOW`] exchanges (the least-queued one). Pitfall: a netem
//! shim with asymmetric delay or one-way jitter biases θ by the asymmetry/2 — estimate with the
//! shim in pass-through mode, or rely on a shared clock and use this as a cross-check. Oscillator
//! drift (10–50 ppm) makes old samples wrong: keep pinging (e.g. 10 Hz) so the window moves on.

use crate::operator_to_telerobot::Ping;
use crate::telerobot_to_operator::Pong;

/// Exchanges the minimum-delay sample is chosen from.
pub const OFFSET_WINDOW: usize = 16;

/// The outcome of one Ping/Pong exchange.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct OffsetSample {
    /// θ: the peer's clock minus ours \[ns\]; `peer_time ≈ our_time + offset_ns`. Rounded toward
    /// zero to the nanosecond.
    pub offset_ns: i64,
    /// δ: round-trip delay without the peer's processing time \[ns\], ≥ 0.
    pub delay_ns: i64,
    /// When the answer arrived [ns, our clock].
    pub t4_ns: i64,
}

impl OffsetSample {
    /// θ and δ from the four timestamps (`t1`, `t4` on our clock, `t2`, `t3` on the peer's).
    /// `None` if the timestamps are inconsistent (`t3 < t2`, `t4 < t1`, `δ < 0`) or the result
    /// does not fit in `i64`: a peer cannot make this panic or produce nonsense.
    pub fn from_timestamps(t1_ns: i64, t2_ns: i64, t3_ns: i64, t4_ns: i64) -> Option<OffsetSample> {
        let [t1, t2, t3, t4] = [t1_ns, t2_ns, t3_ns, t4_ns].map(i128::from);
        if t3 < t2 || t4 < t1 {
            return None;
        }
        let offset = ((t2 - t1) + (t3 - t4)) / 2;
        let delay = (t4 - t1) - (t3 - t2);
        if delay < 0 {
            return None;
        }
        Some(OffsetSample {
            offset_ns: i64::try_from(offset).ok()?,
            delay_ns: i64::try_from(delay).ok()?,
            t4_ns,
        })
    }
}

/// Telerobot side: the answer to `ping`, received at `t2_ns` and answered at `t3_ns` (telerobot
/// clock).
pub fn answer_ping(ping: &Ping, t2_ns: i64, t3_ns: i64) -> Pong {
    Pong {
        id: ping.id,
        t1_ns: ping.t1_ns,
        t2_ns,
        t3_ns,
    }
}

/// Operator side: sends pings and keeps the minimum-delay offset sample of the last
/// [`OFFSET_WINDOW`] answers. No allocation.
#[derive(Clone, Debug)]
pub struct ClockOffsetEstimator {
    /// `id` of the next ping.
    next_id: u64,
    /// Newest `id` answered; older answers are ignored.
    newest_answered: u64,
    /// The last samples, oldest overwritten first.
    window: [Option<OffsetSample>; OFFSET_WINDOW],
    /// Where the next sample goes.
    next_slot: usize,
}

impl Default for ClockOffsetEstimator {
    fn default() -> Self {
        ClockOffsetEstimator::new()
    }
}

impl ClockOffsetEstimator {
    /// An estimator with no samples.
    pub fn new() -> ClockOffsetEstimator {
        ClockOffsetEstimator {
            next_id: 1,
            newest_answered: 0,
            window: [None; OFFSET_WINDOW],
            next_slot: 0,
        }
    }

    /// The next ping, sent at `now_ns` (our clock).
    pub fn ping(&mut self, now_ns: i64) -> Ping {
        let id = self.next_id;
        self.next_id += 1;
        Ping { id, t1_ns: now_ns }
    }

    /// Takes a pong that arrived at `t4_ns` (our clock). Returns its sample, or `None` if the
    /// pong answers no ping we sent, is older than one already taken (reordered or duplicated),
    /// or has inconsistent timestamps.
    pub fn on_pong(&mut self, pong: &Pong, t4_ns: i64) -> Option<OffsetSample> {
        if pong.id <= self.newest_answered || pong.id >= self.next_id {
            return None;
        }
        let sample = OffsetSample::from_timestamps(pong.t1_ns, pong.t2_ns, pong.t3_ns, t4_ns)?;
        self.newest_answered = pong.id;
        self.window[self.next_slot] = Some(sample);
        self.next_slot = (self.next_slot + 1) % OFFSET_WINDOW;
        Some(sample)
    }

    /// The minimum-delay sample of the window (the newest among equals).
    pub fn best(&self) -> Option<OffsetSample> {
        self.window
            .iter()
            .flatten()
            .min_by_key(|s| (s.delay_ns, std::cmp::Reverse(s.t4_ns)))
            .copied()
    }

    /// The current offset estimate θ \[ns\]: peer clock minus ours.
    pub fn offset_ns(&self) -> Option<i64> {
        self.best().map(|s| s.offset_ns)
    }

    /// Maps a time on the peer's clock onto ours \[ns\], if there is an estimate.
    pub fn peer_to_local_ns(&self, peer_time_ns: i64) -> Option<i64> {
        self.offset_ns().map(|o| peer_time_ns.saturating_sub(o))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// One scripted exchange: the telerobot clock reads `offset` more than the operator's; the
    /// ping takes `forward`, the telerobot holds it `hold`, the pong takes `back`.
    fn exchange(
        est: &mut ClockOffsetEstimator,
        t1: i64,
        offset: i64,
        forward: i64,
        hold: i64,
        back: i64,
    ) -> Option<OffsetSample> {
        let ping = est.ping(t1);
        let t2 = t1 + forward + offset;
        let pong = answer_ping(&ping, t2, t2 + hold);
        est.on_pong(&pong, t1 + forward + hold + back)
    }

    #[test]
    fn offset_is_exact_on_a_symmetric_exchange() {
        let mut est = ClockOffsetEstimator::new();
        let s = exchange(
            &mut est,
            1_000 * MS,
            -7_321_123_457,
            40 * MS,
            3 * MS,
            40 * MS,
        );
        assert_eq!(
            s,
            Some(OffsetSample {
                offset_ns: -7_321_123_457,
                delay_ns: 80 * MS,
                t4_ns: 1_083 * MS
            })
        );
        assert_eq!(est.offset_ns(), Some(-7_321_123_457));
        assert_eq!(
            est.peer_to_local_ns(2_000 * MS - 7_321_123_457),
            Some(2_000 * MS)
        );
    }

    #[test]
    fn asymmetry_biases_the_offset_by_half_of_it() {
        let mut est = ClockOffsetEstimator::new();
        let (offset, forward, back) = (5 * MS, 400 * MS, 10 * MS);
        let s = exchange(&mut est, 0, offset, forward, MS, back).unwrap();
        assert_eq!(s.offset_ns - offset, (forward - back) / 2);
        assert_eq!(s.delay_ns, forward + back);
    }

    #[test]
    fn the_minimum_delay_sample_of_the_window_wins() {
        let mut est = ClockOffsetEstimator::new();
        let offset = 1_000;
        // A queued exchange (biased), then a clean one, then another queued one.
        exchange(&mut est, 0, offset, 30 * MS, 0, 10 * MS);
        exchange(&mut est, 100 * MS, offset, 10 * MS, 0, 10 * MS);
        exchange(&mut est, 200 * MS, offset, 10 * MS, 0, 50 * MS);
        assert_eq!(est.offset_ns(), Some(offset));
        // After a full window of queued exchanges the clean one has left the window.
        for i in 0..OFFSET_WINDOW as i64 {
            exchange(&mut est, (300 + 100 * i) * MS, offset, 20 * MS, 0, 10 * MS);
        }
        assert_eq!(est.offset_ns(), Some(offset + 5 * MS));
    }

    #[test]
    fn stray_reordered_and_inconsistent_pongs_are_ignored() {
        let mut est = ClockOffsetEstimator::new();
        let p1 = est.ping(0);
        let p2 = est.ping(10);
        let stray = Pong {
            id: 99,
            ..answer_ping(&p1, 5, 5)
        };
        assert_eq!(est.on_pong(&stray, 20), None, "never sent");
        assert!(est.on_pong(&answer_ping(&p2, 15, 15), 20).is_some());
        assert_eq!(est.on_pong(&answer_ping(&p1, 5, 5), 21), None, "older");
        let p3 = est.ping(30);
        assert_eq!(est.on_pong(&answer_ping(&p3, 40, 39), 50), None, "t3 < t2");
        assert_eq!(est.on_pong(&answer_ping(&p3, 40, 40), 29), None, "t4 < t1");
        assert_eq!(
            est.on_pong(&answer_ping(&p3, 0, 100), 50),
            None,
            "negative delay"
        );
        let extreme = answer_ping(&p3, i64::MIN, i64::MAX);
        assert_eq!(est.on_pong(&extreme, i64::MAX), None);
    }
}
