//! [`Outages`]: times without data from a peer, counted over a whole run.

use serde::{Deserialize, Serialize};

/// Times without data from the peer, over the whole run — every session, and the time between
/// them — so that a reconnect does not hide an outage (a per-session gap restarts at 0).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Outages {
    /// Gaps longer than [`Outages::MIN_NS`].
    pub count: u64,
    /// The longest \[ms\].
    pub longest_ms: f64,
    /// Their total \[ms\].
    pub total_ms: f64,
}

impl Outages {
    /// The shortest gap counted as an outage \[ns\]: 100 ms, twice the telerobot's command
    /// timeout (a gap this long makes the robot hold still), far above 1 kHz jitter.
    pub const MIN_NS: i64 = 100_000_000;

    /// Counts a time of `gap_ns` without data, if it is an outage; returns whether it was.
    pub fn record(&mut self, gap_ns: i64) -> bool {
        if gap_ns < Self::MIN_NS {
            return false;
        }
        let ms = gap_ns as f64 * 1e-6;
        self.count += 1;
        self.longest_ms = self.longest_ms.max(ms);
        self.total_ms += ms;
        true
    }

    /// The outages of a run from the times data arrived (sorted), the run ending at `end_ns`
    /// (a run that ends in an outage counts it). Returns the outages and their `(from, to)`
    /// spans \[ns\].
    pub fn from_arrivals(arrivals_ns: &[i64], end_ns: i64) -> (Outages, Vec<(i64, i64)>) {
        let mut o = Outages::default();
        let mut spans = Vec::new();
        let ends = arrivals_ns.iter().copied().skip(1).chain([end_ns]);
        for (from, to) in arrivals_ns.iter().copied().zip(ends) {
            if o.record(to - from) {
                spans.push((from, to));
            }
        }
        (o, spans)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outages_count_across_sessions_and_at_the_end() {
        const MS: i64 = 1_000_000;
        // Data every ms, a 5.5 s hole (the telerobot restarted: a new session after it), data
        // again, and the run ends 300 ms after the last datagram.
        let mut t: Vec<i64> = (0..1000).map(|k| k * MS).collect();
        t.extend((0..1000).map(|k| 6_499 * MS + k * MS));
        let end = *t.last().unwrap() + 300 * MS;
        let (o, spans) = Outages::from_arrivals(&t, end);
        assert_eq!(o.count, 2);
        assert_eq!(o.longest_ms, 5_500.0);
        assert_eq!(o.total_ms, 5_800.0);
        assert_eq!(spans[0], (999 * MS, 6_499 * MS));
        // 99 ms is not an outage; nothing at all is no outage either.
        assert_eq!(Outages::from_arrivals(&[0, 99 * MS], 99 * MS).0.count, 0);
        assert_eq!(Outages::from_arrivals(&[], 0).0, Outages::default());
    }
}
