//! A lock-free latency histogram and its summary (count, p50, p90, p99, max).
//!
//! Log-linear buckets: values below 128 ns are exact; above, each power of two is split into 64
//! buckets, so a quantile is within 1/64 (1.6 %) of the truth. Recording is two relaxed atomic
//! adds and an atomic max, so the scheduler thread records every packet without a lock and any
//! thread can read a summary at any time.

use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

const SUB_BUCKETS: u64 = 64;
/// Index of the last bucket: shift 57, mantissa 127.
const BUCKETS: usize = 57 * 64 + 128;

/// Counts of nanosecond values in log-linear buckets.
#[derive(Debug)]
pub struct Histogram {
    buckets: Box<[AtomicU64]>,
    count: AtomicU64,
    sum: AtomicU64,
    max: AtomicU64,
}

/// Quantiles of a [`Histogram`] [ns]. All zero when nothing was recorded.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LatencySummary {
    /// Values recorded.
    pub count: u64,
    /// Mean [ns].
    pub mean_ns: f64,
    /// Median [ns].
    pub p50_ns: u64,
    /// 90th percentile [ns].
    pub p90_ns: u64,
    /// 99th percentile [ns].
    pub p99_ns: u64,
    /// Largest value [ns], exact.
    pub max_ns: u64,
}

impl Default for Histogram {
    fn default() -> Self {
        Self::new()
    }
}

impl Histogram {
    /// An empty histogram.
    pub fn new() -> Self {
        Self {
            buckets: (0..BUCKETS).map(|_| AtomicU64::new(0)).collect(),
            count: AtomicU64::new(0),
            sum: AtomicU64::new(0),
            max: AtomicU64::new(0),
        }
    }

    /// Records one value [ns].
    pub fn record(&self, value_ns: u64) {
        if let Some(bucket) = self.buckets.get(index(value_ns)) {
            bucket.fetch_add(1, Relaxed);
        }
        self.count.fetch_add(1, Relaxed);
        self.sum.fetch_add(value_ns, Relaxed);
        self.max.fetch_max(value_ns, Relaxed);
    }

    /// The summary of this histogram.
    pub fn summary(&self) -> LatencySummary {
        Self::summary_of(&[self])
    }

    /// The summary of several histograms taken together.
    pub fn summary_of(histograms: &[&Histogram]) -> LatencySummary {
        let counts: Vec<u64> = (0..BUCKETS)
            .map(|i| {
                histograms
                    .iter()
                    .filter_map(|h| h.buckets.get(i))
                    .map(|b| b.load(Relaxed))
                    .sum()
            })
            .collect();
        let count: u64 = counts.iter().sum();
        if count == 0 {
            return LatencySummary::default();
        }
        let max_ns = histograms
            .iter()
            .map(|h| h.max.load(Relaxed))
            .max()
            .unwrap_or(0);
        let sum: u64 = histograms.iter().map(|h| h.sum.load(Relaxed)).sum();
        let quantile = |q: f64| {
            let rank = ((q * count as f64).ceil() as u64).clamp(1, count);
            let mut seen = 0;
            for (i, &c) in counts.iter().enumerate() {
                seen += c;
                if seen >= rank {
                    return representative(i).min(max_ns);
                }
            }
            max_ns
        };
        LatencySummary {
            count,
            mean_ns: sum as f64 / count as f64,
            p50_ns: quantile(0.50),
            p90_ns: quantile(0.90),
            p99_ns: quantile(0.99),
            max_ns,
        }
    }
}

/// Bucket of a value: exact below 128, then 64 buckets per power of two.
fn index(value: u64) -> usize {
    let shift = (63 - u64::from(value.max(1).leading_zeros())).saturating_sub(6);
    (SUB_BUCKETS * shift + (value >> shift)) as usize
}

/// The middle of bucket `i`.
fn representative(i: usize) -> u64 {
    let i = i as u64;
    if i < 2 * SUB_BUCKETS {
        return i;
    }
    let shift = i / SUB_BUCKETS - 1;
    let mantissa = i - SUB_BUCKETS * shift;
    (mantissa << shift) + (1u64 << shift) / 2
}

impl fmt::Display for LatencySummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let us = |ns: u64| ns as f64 / 1_000.0;
        write!(
            f,
            "n={} p50={:.1}µs p90={:.1}µs p99={:.1}µs max={:.1}µs",
            self.count,
            us(self.p50_ns),
            us(self.p90_ns),
            us(self.p99_ns),
            us(self.max_ns)
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_are_contiguous_and_tight() {
        assert_eq!(index(0), 0);
        assert_eq!(index(127), 127);
        assert_eq!(index(128), 128);
        assert_eq!(index(255), 191);
        assert_eq!(index(256), 192);
        assert_eq!(index(u64::MAX), BUCKETS - 1);
        for v in [0u64, 5, 127, 128, 1_000, 123_456, 9_999_999, 1 << 40] {
            let r = representative(index(v));
            assert!(
                (r as f64 - v as f64).abs() <= v as f64 / 64.0 + 0.5,
                "{v} → {r}"
            );
        }
    }

    #[test]
    fn quantiles_of_a_known_set() {
        let h = Histogram::new();
        for v in 1..=100u64 {
            h.record(v * 1_000);
        }
        let s = h.summary();
        assert_eq!(s.count, 100);
        assert_eq!(s.max_ns, 100_000);
        for (got, want) in [
            (s.p50_ns, 50_000.0),
            (s.p90_ns, 90_000.0),
            (s.p99_ns, 99_000.0),
        ] {
            assert!(
                (got as f64 / want - 1.0).abs() < 1.0 / 64.0,
                "{got} vs {want}"
            );
        }
        assert!((s.mean_ns - 50_500.0).abs() < 1e-9);
        assert_eq!(Histogram::new().summary(), LatencySummary::default());
    }
}
