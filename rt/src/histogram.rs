//! The one latency histogram of the system and its summary.
//!
//! [`Histogram`]: log-linear buckets of nanosecond values, recorded lock-free (two relaxed atomic
//! adds and an atomic max), so a real-time loop or the shim's scheduler records every value and
//! any thread reads a [`Summary`] at any time. Values below 2048 ns are exact; above, each power
//! of two is split into 1024 buckets, so a quantile is within 1/1024 (0.1 %) of the truth (1 µs
//! at a 1 ms period). The maximum is exact.
//!
//! [`Summary`]: count, mean, p50, p90, p99 and max in microseconds, the form every report
//! prints; also computed exactly from a set of samples ([`Summary::of_samples`]).

use std::fmt;
use std::sync::atomic::{AtomicI64, AtomicU64, Ordering::Relaxed};

use serde::{Deserialize, Serialize};

/// Buckets per power of two (above the exact range).
const SUB_BUCKETS: u64 = 1024;
/// log2 of [`SUB_BUCKETS`].
const SUB_BITS: u32 = 10;
/// Buckets in all: exact below `2·SUB_BUCKETS`, then `SUB_BUCKETS` per power of two up to 2^63.
const BUCKETS: usize = ((63 - SUB_BITS as u64) * SUB_BUCKETS + 2 * SUB_BUCKETS) as usize;

/// Counts of nanosecond values in log-linear buckets. Allocated once ([`Histogram::new`]);
/// recording never allocates.
#[derive(Debug)]
pub struct Histogram {
    buckets: Box<[AtomicU64]>,
    count: AtomicU64,
    sum_ns: AtomicU64,
    max_ns: AtomicI64,
}

/// A distribution in microseconds: what every report prints. All zero when empty.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Values.
    pub count: u64,
    /// Mean \[µs\].
    pub mean_us: f64,
    /// Median \[µs\].
    pub p50_us: f64,
    /// 90th percentile \[µs\].
    pub p90_us: f64,
    /// 99th percentile \[µs\].
    pub p99_us: f64,
    /// Largest value \[µs\], exact.
    pub max_us: f64,
}

impl Default for Histogram {
    fn default() -> Self {
        Self::new()
    }
}

impl Histogram {
    /// An empty histogram (about 450 KB of counters).
    pub fn new() -> Self {
        Self {
            buckets: (0..BUCKETS).map(|_| AtomicU64::new(0)).collect(),
            count: AtomicU64::new(0),
            sum_ns: AtomicU64::new(0),
            max_ns: AtomicI64::new(0),
        }
    }

    /// Records one value \[ns\]; negative values count as 0. Lock-free, allocation-free.
    pub fn record(&self, value_ns: i64) {
        let v = value_ns.max(0);
        let u = v.unsigned_abs();
        if let Some(bucket) = self.buckets.get(index(u)) {
            bucket.fetch_add(1, Relaxed);
        }
        self.count.fetch_add(1, Relaxed);
        self.sum_ns.fetch_add(u, Relaxed);
        self.max_ns.fetch_max(v, Relaxed);
    }

    /// Values recorded.
    pub fn count(&self) -> u64 {
        self.count.load(Relaxed)
    }

    /// The summary of this histogram (reads every bucket: not per tick).
    pub fn summary(&self) -> Summary {
        Self::summary_of(&[self])
    }

    /// The summary of several histograms taken together.
    pub fn summary_of(histograms: &[&Histogram]) -> Summary {
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
            return Summary::default();
        }
        let max_ns = histograms
            .iter()
            .map(|h| h.max_ns.load(Relaxed))
            .max()
            .unwrap_or(0)
            .unsigned_abs();
        let sum: u64 = histograms.iter().map(|h| h.sum_ns.load(Relaxed)).sum();
        // A quantile in the maximum's bucket is the maximum (exact for a lone value); others are
        // their bucket's middle.
        let top = index(max_ns);
        let quantile = |q: f64| {
            let rank = ((q * count as f64).ceil() as u64).clamp(1, count);
            let mut seen = 0;
            for (i, &c) in counts.iter().enumerate() {
                seen += c;
                if seen >= rank {
                    return us(if i == top { max_ns } else { representative(i) });
                }
            }
            us(max_ns)
        };
        Summary {
            count,
            mean_us: sum as f64 / count as f64 / 1e3,
            p50_us: quantile(0.50),
            p90_us: quantile(0.90),
            p99_us: quantile(0.99),
            max_us: us(max_ns),
        }
    }
}

impl Summary {
    /// The exact summary of `samples` \[ns\] (sorts them). Quantiles are the nearest-rank
    /// samples.
    pub fn of_samples(samples: &mut [i64]) -> Summary {
        samples.sort_unstable();
        let n = samples.len();
        if n == 0 {
            return Summary::default();
        }
        let at = |q: f64| {
            let rank = ((q * n as f64).ceil() as usize).clamp(1, n) - 1;
            samples[rank] as f64 / 1e3
        };
        let sum: f64 = samples.iter().map(|&v| v as f64).sum();
        Summary {
            count: n as u64,
            mean_us: sum / n as f64 / 1e3,
            p50_us: at(0.5),
            p90_us: at(0.9),
            p99_us: at(0.99),
            max_us: samples[n - 1] as f64 / 1e3,
        }
    }

    /// The same distribution shifted by `offset_us` (e.g. less a set delay), count unchanged.
    pub fn shifted(&self, offset_us: f64) -> Summary {
        if self.count == 0 {
            return *self;
        }
        Summary {
            count: self.count,
            mean_us: self.mean_us + offset_us,
            p50_us: self.p50_us + offset_us,
            p90_us: self.p90_us + offset_us,
            p99_us: self.p99_us + offset_us,
            max_us: self.max_us + offset_us,
        }
    }
}

fn us(ns: u64) -> f64 {
    ns as f64 / 1e3
}

/// Bucket of a value: exact below `2·SUB_BUCKETS`, then `SUB_BUCKETS` per power of two.
fn index(value: u64) -> usize {
    let shift = (63 - u64::from(value.max(1).leading_zeros())).saturating_sub(u64::from(SUB_BITS));
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

impl fmt::Display for Summary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "n={} p50={:.1}µs p90={:.1}µs p99={:.1}µs max={:.1}µs",
            self.count, self.p50_us, self.p90_us, self.p99_us, self.max_us
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_are_contiguous_and_tight() {
        assert_eq!(index(0), 0);
        assert_eq!(index(2047), 2047);
        assert_eq!(index(2048), 2048);
        assert_eq!(index(4095), 3071);
        assert_eq!(index(4096), 3072);
        assert_eq!(index(u64::MAX), BUCKETS - 1);
        for v in [
            0u64,
            5,
            2047,
            2048,
            10_000,
            123_456,
            9_999_999,
            1 << 40,
            u64::MAX,
        ] {
            let r = representative(index(v));
            assert!(
                (r as f64 - v as f64).abs() <= v as f64 / 1024.0 + 0.5,
                "{v} → {r}"
            );
        }
        for i in 1..BUCKETS {
            assert!(representative(i) > representative(i - 1), "bucket {i}");
        }
    }

    #[test]
    fn quantiles_of_a_known_set() {
        let h = Histogram::new();
        for v in 1..=100i64 {
            h.record(v * 1_000);
        }
        let s = h.summary();
        assert_eq!(s.count, 100);
        assert_eq!(s.max_us, 100.0);
        for (got, want) in [(s.p50_us, 50.0), (s.p90_us, 90.0), (s.p99_us, 99.0)] {
            assert!((got / want - 1.0).abs() < 1.0 / 1024.0, "{got} vs {want}");
        }
        assert!((s.mean_us - 50.5).abs() < 1e-9);
        assert_eq!(Histogram::new().summary(), Summary::default());
    }

    #[test]
    fn negative_values_count_as_zero_and_the_maximum_is_exact() {
        let h = Histogram::new();
        h.record(-5);
        h.record(1_234_567);
        let s = h.summary();
        assert_eq!(s.count, 2);
        assert_eq!(s.p50_us, 0.0);
        assert_eq!(s.max_us, 1_234.567);
        assert_eq!(s.p99_us, 1_234.567, "in the maximum's bucket: the maximum");
    }

    #[test]
    fn several_histograms_summarise_together() {
        let (a, b) = (Histogram::new(), Histogram::new());
        a.record(1_000);
        b.record(3_000);
        let s = Histogram::summary_of(&[&a, &b]);
        assert_eq!((s.count, s.p50_us, s.max_us), (2, 1.0, 3.0));
        assert_eq!(s.mean_us, 2.0);
    }

    #[test]
    fn samples_give_exact_nearest_rank_quantiles() {
        let mut v: Vec<i64> = (1..=100).rev().map(|k| k * 1_000).collect();
        let s = Summary::of_samples(&mut v);
        assert_eq!(
            (s.count, s.p50_us, s.p90_us, s.p99_us, s.max_us),
            (100, 50.0, 90.0, 99.0, 100.0)
        );
        assert_eq!(Summary::of_samples(&mut []), Summary::default());
        let shifted = s.shifted(-10.0);
        assert_eq!((shifted.p50_us, shifted.max_us), (40.0, 90.0));
        assert_eq!(Summary::default().shifted(5.0), Summary::default());
    }
}
