//! [`LoopTiming`]: the timing statistics of a periodic loop, recorded lock-free from the loop
//! thread and read from any other.
//!
//! Three histograms with 1 µs bins up to 10 ms (values beyond go to an overflow count; the
//! maximum is kept exactly):
//! - **period**: time between the starts of consecutive ticks;
//! - **lateness**: how long after its deadline a tick started;
//! - **work**: from a tick's start to the loop's next wait (what the tick cost).
//!
//! An **overrun** is a tick that started more than half a period after its deadline: the loop
//! missed its slot (catch-up ticks after a stall are overruns too). **Skipped** ticks were given
//! up after a stall longer than the catch-up budget.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering::Relaxed};

use serde::Serialize;

/// Bin width \[ns\].
const BIN_NS: i64 = 1_000;
/// Bins: 0 to 10 ms.
const BINS: usize = 10_000;

/// The statistics of one loop.
#[derive(Debug)]
pub struct LoopTiming {
    nominal_period_ns: i64,
    spin_ns: i64,
    period: Linear,
    lateness: Linear,
    work: Linear,
    ticks: AtomicU64,
    overruns: AtomicU64,
    skipped: AtomicU64,
    last_start_ns: AtomicI64,
}

/// Three quantiles of a distribution \[µs\].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Quantiles {
    /// Median \[µs\] (1 µs resolution).
    pub p50_us: f64,
    /// 99th percentile \[µs\] (1 µs resolution).
    pub p99_us: f64,
    /// Largest value \[µs\], exact.
    pub max_us: f64,
}

/// A summary of [`LoopTiming`], for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct TimingReport {
    /// Nominal period \[µs\].
    pub nominal_period_us: f64,
    /// Spin window \[µs\].
    pub spin_us: f64,
    /// Ticks run.
    pub ticks: u64,
    /// Time between consecutive tick starts.
    pub period: Quantiles,
    /// Start time after the deadline.
    pub lateness: Quantiles,
    /// Work per tick.
    pub work: Quantiles,
    /// Ticks that started more than half a period late.
    pub overruns: u64,
    /// Ticks given up after stalls longer than the catch-up budget.
    pub skipped_ticks: u64,
}

impl LoopTiming {
    /// Empty statistics for a loop of `nominal_period_ns` spinning `spin_ns` (allocated here).
    pub fn new(nominal_period_ns: i64, spin_ns: i64) -> LoopTiming {
        LoopTiming {
            nominal_period_ns,
            spin_ns,
            period: Linear::new(),
            lateness: Linear::new(),
            work: Linear::new(),
            ticks: AtomicU64::new(0),
            overruns: AtomicU64::new(0),
            skipped: AtomicU64::new(0),
            last_start_ns: AtomicI64::new(i64::MIN),
        }
    }

    /// A tick started at `started_ns`, `lateness_ns` after its deadline. Lock-free.
    pub fn record_start(&self, started_ns: i64, lateness_ns: i64) {
        self.ticks.fetch_add(1, Relaxed);
        let last = self.last_start_ns.swap(started_ns, Relaxed);
        if last != i64::MIN {
            self.period.record(started_ns - last);
        }
        self.lateness.record(lateness_ns);
        if lateness_ns > self.nominal_period_ns / 2 {
            self.overruns.fetch_add(1, Relaxed);
        }
    }

    /// A tick's work took `work_ns`. Lock-free.
    pub fn record_work(&self, work_ns: i64) {
        self.work.record(work_ns);
    }

    /// `n` ticks were skipped. Lock-free.
    pub fn record_skipped(&self, n: u64) {
        self.skipped.fetch_add(n, Relaxed);
    }

    /// The summary so far (allocates nothing either; reads every bin: not per tick).
    pub fn report(&self) -> TimingReport {
        TimingReport {
            nominal_period_us: self.nominal_period_ns as f64 / 1e3,
            spin_us: self.spin_ns as f64 / 1e3,
            ticks: self.ticks.load(Relaxed),
            period: self.period.quantiles(),
            lateness: self.lateness.quantiles(),
            work: self.work.quantiles(),
            overruns: self.overruns.load(Relaxed),
            skipped_ticks: self.skipped.load(Relaxed),
        }
    }
}

/// Counts in 1 µs bins, an overflow count and the exact maximum.
#[derive(Debug)]
struct Linear {
    bins: Box<[AtomicU64]>,
    overflow: AtomicU64,
    count: AtomicU64,
    max_ns: AtomicI64,
}

impl Linear {
    fn new() -> Linear {
        Linear {
            bins: (0..BINS).map(|_| AtomicU64::new(0)).collect(),
            overflow: AtomicU64::new(0),
            count: AtomicU64::new(0),
            max_ns: AtomicI64::new(0),
        }
    }

    /// Records `value_ns` (negative values count as 0).
    fn record(&self, value_ns: i64) {
        let v = value_ns.max(0);
        match usize::try_from(v / BIN_NS)
            .ok()
            .and_then(|i| self.bins.get(i))
        {
            Some(bin) => bin.fetch_add(1, Relaxed),
            None => self.overflow.fetch_add(1, Relaxed),
        };
        self.count.fetch_add(1, Relaxed);
        self.max_ns.fetch_max(v, Relaxed);
    }

    fn quantiles(&self) -> Quantiles {
        let count = self.count.load(Relaxed);
        let max_us = self.max_ns.load(Relaxed) as f64 / 1e3;
        let quantile = |q: f64| -> f64 {
            if count == 0 {
                return 0.0;
            }
            let rank = ((q * count as f64).ceil() as u64).clamp(1, count);
            let mut seen = 0;
            for (i, bin) in self.bins.iter().enumerate() {
                seen += bin.load(Relaxed);
                if seen >= rank {
                    // The bin's centre, never above the exact maximum.
                    return ((i as f64 + 0.5) * BIN_NS as f64 / 1e3).min(max_us);
                }
            }
            max_us
        };
        Quantiles {
            p50_us: quantile(0.5),
            p99_us: quantile(0.99),
            max_us,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_and_overruns_follow_the_recorded_values() {
        let t = LoopTiming::new(1_000_000, 100_000);
        let mut start = 0;
        for k in 0..100 {
            // 99 ticks on time, one 700 µs late (an overrun).
            let late = if k == 50 { 700_000 } else { 2_000 };
            start += 1_000_000;
            t.record_start(start + late, late);
            t.record_work(20_000 + k);
        }
        let r = t.report();
        assert_eq!(r.ticks, 100);
        assert_eq!(r.overruns, 1);
        assert!((r.lateness.p50_us - 2.5).abs() < 1e-9, "{r:?}");
        assert!((r.lateness.max_us - 700.0).abs() < 1e-9);
        assert!((r.period.p50_us - 1000.5).abs() < 1e-9, "{r:?}");
        assert!((r.period.max_us - 1698.0).abs() < 1e-9, "{r:?}");
        // The 20 µs bin's centre, capped by the exact maximum (20.099 µs).
        assert!((r.work.p99_us - 20.099).abs() < 1e-9, "{r:?}");
    }

    #[test]
    fn values_beyond_the_bins_count_in_the_maximum() {
        let t = LoopTiming::new(1_000_000, 0);
        t.record_work(50_000_000);
        let r = t.report();
        assert_eq!(r.work.max_us, 50_000.0);
        assert_eq!(r.work.p50_us, 50_000.0);
    }
}
