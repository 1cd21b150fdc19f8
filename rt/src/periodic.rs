//! [`Periodic`]: the schedule of a fixed-rate loop on absolute deadlines.
//!
//! Tick `k` is due at `start + k·period`. The loop sleeps until `deadline − spin`, then spins (see
//! [`sleep_until_ns`](crate::clock::sleep_until_ns)). A tick that starts late is still tick `k` with its nominal time: the nodes
//! step with a fixed `dt`, so their time must advance by exactly one period per tick. After a
//! stall the missed ticks run back to back (catch-up) up to [`PeriodicConfig::max_catch_up`];
//! beyond that the schedule jumps to now and the ticks in between are counted as skipped (the
//! caller sees the gap in [`Tick::index`]).

use std::sync::Arc;

use crate::clock::{monotonic_ns, sleep_until_ns};
use crate::timing::LoopTiming;

/// Largest spin window allowed \[ns\]: 200 µs, 20 % of a 1 ms period (`DESIGN.md` §2: two spinning
/// loops and the netem scheduler share a 2-core machine in the demo and the tests).
pub const MAX_SPIN_NS: i64 = 200_000;

/// Settings of a periodic loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PeriodicConfig {
    /// Period \[ns\], 100 µs to 1 s. Default 1 ms (1 kHz).
    pub period_ns: i64,
    /// Busy-spin before each deadline \[ns\], 0 to [`MAX_SPIN_NS`]. Default 100 µs: absorbs the
    /// kernel timer's 25–75 µs wake-up lateness (network notes §0.2) at 10 % of one core.
    pub spin_ns: i64,
    /// Missed ticks run back to back after a stall, at most this many; a longer stall moves the
    /// schedule on and skips the rest. Default 50 (50 ms at 1 kHz: what the watchdogs tolerate).
    pub max_catch_up: u32,
}

impl Default for PeriodicConfig {
    fn default() -> Self {
        PeriodicConfig {
            period_ns: 1_000_000,
            spin_ns: 100_000,
            max_catch_up: 50,
        }
    }
}

/// A loop setting out of range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PeriodicError {
    /// The period.
    #[error("loop period {0} ns is out of range: expected 100 µs to 1 s")]
    Period(i64),
    /// The spin window.
    #[error("spin window {0} µs is out of range: expected 0 to 200 µs")]
    Spin(f64),
}

impl PeriodicConfig {
    /// Checks the ranges above.
    pub fn validate(&self) -> Result<(), PeriodicError> {
        if !(100_000..=1_000_000_000).contains(&self.period_ns) {
            return Err(PeriodicError::Period(self.period_ns));
        }
        if !(0..=MAX_SPIN_NS).contains(&self.spin_ns) || self.spin_ns >= self.period_ns {
            return Err(PeriodicError::Spin(self.spin_ns as f64 / 1e3));
        }
        Ok(())
    }
}

/// One tick of the loop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tick {
    /// Tick number since the start (increases by one per tick, by more after skipped ticks).
    pub index: u64,
    /// The tick's nominal time, `start + index·period` [ns, `monotonic_ns`]: the `now` the loop
    /// steps its node with.
    pub deadline_ns: i64,
    /// When the tick actually started [ns, `monotonic_ns`].
    pub started_ns: i64,
}

/// The schedule. Owned by the loop thread; its [`LoopTiming`] is shared.
#[derive(Debug)]
pub struct Periodic {
    config: PeriodicConfig,
    start_ns: i64,
    next_index: u64,
    current_start_ns: Option<i64>,
    timing: Arc<LoopTiming>,
    idle: bool,
}

impl Periodic {
    /// A schedule whose tick 0 is due at `start_ns` (`monotonic_ns` time). Allocates its timing
    /// histograms here, once.
    pub fn new(config: PeriodicConfig, start_ns: i64) -> Result<Periodic, PeriodicError> {
        config.validate()?;
        Ok(Periodic {
            config,
            start_ns,
            next_index: 0,
            current_start_ns: None,
            timing: Arc::new(LoopTiming::new(config.period_ns, config.spin_ns)),
            idle: false,
        })
    }

    /// When tick 0 was due.
    pub fn start_ns(&self) -> i64 {
        self.start_ns
    }

    /// The settings.
    pub fn config(&self) -> &PeriodicConfig {
        &self.config
    }

    /// The timing statistics (shared: readable while the loop runs).
    pub fn timing(&self) -> Arc<LoopTiming> {
        Arc::clone(&self.timing)
    }

    /// Ends the current tick (its work time is recorded) and waits for the next one. No
    /// allocation, no lock, no log.
    pub fn wait(&mut self) -> Tick {
        let now = monotonic_ns();
        if let Some(start) = self.current_start_ns {
            self.timing.record_work(now - start);
        }
        let period = self.config.period_ns;
        let mut deadline = self.deadline(self.next_index);
        let behind = now - deadline;
        if behind > i64::from(self.config.max_catch_up) * period {
            // Too far behind to catch up: move the schedule to now.
            let index = u64::try_from((now - self.start_ns) / period).unwrap_or(self.next_index);
            let index = index.max(self.next_index);
            self.timing.record_skipped(index - self.next_index);
            self.next_index = index;
            deadline = self.deadline(index);
        }
        let started = if self.idle {
            let started = sleep_until_ns(deadline, 0);
            self.timing.record_idle_start(started);
            started
        } else {
            let started = sleep_until_ns(deadline, self.config.spin_ns);
            self.timing.record_start(started, started - deadline);
            started
        };
        self.current_start_ns = Some(started).filter(|_| !self.idle);
        let tick = Tick {
            index: self.next_index,
            deadline_ns: deadline,
            started_ns: started,
        };
        self.next_index += 1;
        tick
    }

    /// Idle or not, from the next tick on. An idle tick keeps the schedule but does not spin
    /// before its deadline (the spin window is most of an idle loop's CPU: 10 % of a core at
    /// 100 µs per 1 ms), and its timing is counted apart ([`TimingReport::idle_ticks`]): while
    /// nobody is served its lateness is nobody's. The next tick after idling spins again.
    ///
    /// [`TimingReport::idle_ticks`]: crate::TimingReport::idle_ticks
    pub fn set_idle(&mut self, idle: bool) {
        self.idle = idle;
    }

    fn deadline(&self, index: u64) -> i64 {
        let k = i64::try_from(index).unwrap_or(i64::MAX);
        self.start_ns
            .saturating_add(k.saturating_mul(self.config.period_ns))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_on_absolute_deadlines_and_never_early() {
        let config = PeriodicConfig {
            period_ns: 1_000_000,
            spin_ns: 50_000,
            max_catch_up: 50,
        };
        let start = monotonic_ns() + 1_000_000;
        let mut p = Periodic::new(config, start).unwrap();
        for k in 0..20u64 {
            let t = p.wait();
            assert_eq!(t.index, k);
            assert_eq!(t.deadline_ns, start + k as i64 * 1_000_000);
            assert!(t.started_ns >= t.deadline_ns);
        }
        let r = p.timing().report();
        assert_eq!(r.ticks, 20);
        assert_eq!(r.skipped_ticks, 0);
    }

    #[test]
    fn a_short_stall_is_caught_up_and_a_long_one_skipped() {
        let config = PeriodicConfig {
            period_ns: 1_000_000,
            spin_ns: 0,
            max_catch_up: 5,
        };
        let start = monotonic_ns();
        let mut p = Periodic::new(config, start).unwrap();
        assert_eq!(p.wait().index, 0);
        std::thread::sleep(std::time::Duration::from_millis(3));
        // Late but within the catch-up budget: the next indices follow on.
        assert_eq!(p.wait().index, 1);
        std::thread::sleep(std::time::Duration::from_millis(30));
        let t = p.wait();
        assert!(t.index >= 30, "{t:?}");
        assert!(p.timing().report().skipped_ticks >= 25);
    }

    #[test]
    fn idle_ticks_keep_the_schedule_and_are_counted_apart() {
        let config = PeriodicConfig {
            period_ns: 1_000_000,
            spin_ns: 100_000,
            max_catch_up: 50,
        };
        let start = monotonic_ns() + 1_000_000;
        let mut p = Periodic::new(config, start).unwrap();
        p.set_idle(true);
        for k in 0..10u64 {
            let t = p.wait();
            assert_eq!(t.deadline_ns, start + k as i64 * 1_000_000);
            assert!(t.started_ns >= t.deadline_ns);
        }
        p.set_idle(false);
        for k in 10..15u64 {
            assert_eq!(p.wait().index, k);
        }
        let r = p.timing().report();
        assert_eq!((r.ticks, r.idle_ticks), (15, 10));
        // Only the served ticks are timed: 5 lateness samples, 5 periods (the first from the
        // last idle start).
        assert_eq!(r.lateness.count, 5);
        assert_eq!(r.period.count, 5);
        assert_eq!(
            r.work.count, 4,
            "the work of a tick served after an idle one"
        );
    }

    #[test]
    fn settings_out_of_range_are_refused() {
        let bad_spin = PeriodicConfig {
            spin_ns: 250_000,
            ..PeriodicConfig::default()
        };
        assert!(bad_spin.validate().unwrap_err().to_string().contains("250"));
        let bad_period = PeriodicConfig {
            period_ns: 10,
            ..PeriodicConfig::default()
        };
        assert!(bad_period.validate().is_err());
        assert!(PeriodicConfig::default().validate().is_ok());
    }
}
