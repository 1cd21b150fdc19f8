//! [`LoopTiming`]: the timing statistics of a periodic loop, recorded lock-free from the loop
//! thread and read from any other.
//!
//! Three [`Histogram`]s (0.1 % buckets, exact maximum):
//! - **period**: time between the starts of consecutive ticks;
//! - **lateness**: how long after its deadline a tick started;
//! - **work**: from a tick's start to the loop's next wait (what the tick cost).
//!
//! An **overrun** is a tick that started more than half a period after its deadline: the loop
//! missed its slot (catch-up ticks after a stall are overruns too). **Skipped** ticks were given
//! up after a stall longer than the catch-up budget.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering::Relaxed};

use serde::{Deserialize, Serialize};

use crate::histogram::{Histogram, Summary};

/// The statistics of one loop.
#[derive(Debug)]
pub struct LoopTiming {
    nominal_period_ns: i64,
    spin_ns: i64,
    period: Histogram,
    lateness: Histogram,
    work: Histogram,
    ticks: AtomicU64,
    overruns: AtomicU64,
    skipped: AtomicU64,
    idle: AtomicU64,
    last_start_ns: AtomicI64,
}

/// A summary of [`LoopTiming`], for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TimingReport {
    /// Nominal period \[µs\].
    pub nominal_period_us: f64,
    /// Spin window \[µs\].
    pub spin_us: f64,
    /// Ticks run.
    pub ticks: u64,
    /// Time between consecutive tick starts.
    pub period: Summary,
    /// Start time after the deadline.
    pub lateness: Summary,
    /// Work per tick.
    pub work: Summary,
    /// Ticks that started more than half a period late.
    pub overruns: u64,
    /// Ticks given up after stalls longer than the catch-up budget.
    pub skipped_ticks: u64,
    /// Ticks run idle (no spin, left out of period, lateness and overruns): the telerobot's
    /// loop while no operator is connected.
    #[serde(default)]
    pub idle_ticks: u64,
}

impl LoopTiming {
    /// Empty statistics for a loop of `nominal_period_ns` spinning `spin_ns` (allocated here).
    pub fn new(nominal_period_ns: i64, spin_ns: i64) -> LoopTiming {
        LoopTiming {
            nominal_period_ns,
            spin_ns,
            period: Histogram::new(),
            lateness: Histogram::new(),
            work: Histogram::new(),
            ticks: AtomicU64::new(0),
            overruns: AtomicU64::new(0),
            skipped: AtomicU64::new(0),
            idle: AtomicU64::new(0),
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

    /// An idle tick started at `started_ns` (counted, not timed: nobody waits on it).
    /// Lock-free.
    pub fn record_idle_start(&self, started_ns: i64) {
        self.ticks.fetch_add(1, Relaxed);
        self.idle.fetch_add(1, Relaxed);
        self.last_start_ns.store(started_ns, Relaxed);
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
            period: self.period.summary(),
            lateness: self.lateness.summary(),
            work: self.work.summary(),
            overruns: self.overruns.load(Relaxed),
            skipped_ticks: self.skipped.load(Relaxed),
            idle_ticks: self.idle.load(Relaxed),
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
        // 2 µs is in the histogram's exact range.
        assert_eq!(r.lateness.p50_us, 2.0, "{r:?}");
        assert!((r.lateness.max_us - 700.0).abs() < 1e-9);
        // Periods of 1000 µs (and 1698 / 302 µs around the late tick): within a bucket (0.1 %).
        assert!((r.period.p50_us / 1000.0 - 1.0).abs() < 1e-3, "{r:?}");
        assert!((r.period.max_us - 1698.0).abs() < 1e-9, "{r:?}");
        // Work 20.000–20.099 µs: the 99th value's bucket, capped by the exact maximum.
        assert!(
            r.work.p99_us <= 20.099 && r.work.p99_us >= 20.098 * (1.0 - 1e-3),
            "{r:?}"
        );
    }

    #[test]
    fn long_stalls_count_in_the_maximum() {
        let t = LoopTiming::new(1_000_000, 0);
        t.record_work(50_000_000);
        let r = t.report();
        assert_eq!(r.work.max_us, 50_000.0);
        assert_eq!(r.work.p50_us, 50_000.0);
    }
}
