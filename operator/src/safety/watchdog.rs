//! The software watchdog: a gain in [0, 1] on the output force that **fades** (never steps) to zero
//! when the haptic loop overruns its deadline or the model parameters are stale, and fades back in
//! once both have been healthy for a hold time. It stays tripped (fading out) until then, so with
//! the defaults (fade-out 50 ms < hold 100 ms) any trip reaches zero force before recovering.
//!
//! Loop overrun is measured from the `now` of consecutive ticks: a gap longer than the nominal
//! period plus the allowed overrun trips it. This works whatever the loop does with missed
//! deadlines (catch up or skip). The time step used for fades and the rate limit is the gap
//! clamped to `nominal_period + max_overrun`, so a stall does not turn into a step.

use std::time::Duration;

/// Watchdog settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchdogConfig {
    /// Nominal loop period. Default 1 ms (1 kHz).
    pub nominal_period: Duration,
    /// Lateness allowed beyond the nominal period before the watchdog trips. Default 2 ms: the
    /// loop sleeps to absolute deadlines, so a 3 ms gap means it lost the CPU.
    pub max_overrun: Duration,
    /// Largest age of the model parameters being rendered (time since the last parameter update
    /// arrived). Default 500 ms: at a few-hundred-hertz update rate this is many lost messages;
    /// the local model stays valid for a while (MMT), the fade covers the rest.
    pub max_params_age: Duration,
    /// Time to fade from full force to zero once tripped, > 0. Default 50 ms.
    pub fade_out: Duration,
    /// Time to fade back from zero to full force, > 0. Default 200 ms (as the enable ramp).
    pub fade_in: Duration,
    /// How long both conditions must be healthy before fading back in, ≥ `fade_out`.
    /// Default 100 ms.
    pub recovery_hold: Duration,
}

impl Default for WatchdogConfig {
    fn default() -> Self {
        Self {
            nominal_period: Duration::from_millis(1),
            max_overrun: Duration::from_millis(2),
            max_params_age: Duration::from_millis(500),
            fade_out: Duration::from_millis(50),
            fade_in: Duration::from_millis(200),
            recovery_hold: Duration::from_millis(100),
        }
    }
}

/// What the watchdog decided this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchdogTick {
    /// Time step for fades and rate limits [s] (gap clamped; nominal period on the first tick).
    pub dt_s: f64,
    /// The loop overran this tick.
    pub overrun: bool,
    /// The parameters are stale (or absent).
    pub stale: bool,
    /// Gain to apply to the force, in [0, 1].
    pub gain: f64,
}

/// The watchdog state.
#[derive(Clone, Copy, Debug)]
pub struct SoftWatchdog {
    config: WatchdogConfig,
    gain: f64,
    last_now: Option<Duration>,
    last_bad: Option<Duration>,
}

impl SoftWatchdog {
    /// Starts at full gain: start-up is covered by the device's enable ramp.
    #[must_use]
    pub fn new(config: WatchdogConfig) -> Self {
        Self {
            config,
            gain: 1.0,
            last_now: None,
            last_bad: None,
        }
    }

    /// One tick at `now` with the current parameter age (`None`: no parameters yet).
    pub fn step(&mut self, now: Duration, params_age: Option<Duration>) -> WatchdogTick {
        let c = &self.config;
        let limit = c.nominal_period + c.max_overrun;
        let (gap, overrun) = match self.last_now {
            Some(prev) => {
                let gap = now.saturating_sub(prev);
                (gap.min(limit), gap > limit)
            }
            None => (c.nominal_period, false),
        };
        self.last_now = Some(now);
        let stale = params_age.is_none_or(|age| age > c.max_params_age);
        let dt_s = gap.as_secs_f64();
        if overrun || stale {
            self.last_bad = Some(now);
        }
        // Tripped until both conditions have been healthy for the hold time: a single overrun
        // fades the force all the way out (with fade_out < recovery_hold) before it returns.
        let tripped = self
            .last_bad
            .is_some_and(|bad| now.saturating_sub(bad) < c.recovery_hold);
        if tripped {
            self.gain = (self.gain - dt_s / c.fade_out.as_secs_f64()).max(0.0);
        } else {
            self.gain = (self.gain + dt_s / c.fade_in.as_secs_f64()).min(1.0);
        }
        WatchdogTick {
            dt_s,
            overrun,
            stale,
            gain: self.gain,
        }
    }

    /// Current gain in [0, 1].
    #[must_use]
    pub fn gain(&self) -> f64 {
        self.gain
    }
}
