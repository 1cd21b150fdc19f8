//! The software watchdog: gains in [0, 1] that **fade** (never step) the output force to zero when
//! the haptic loop overruns its deadline or the model parameters are stale, and fade back in once
//! the rule's condition has been healthy for a hold time. A rule stays tripped (fading out) until
//! then, so with the defaults (fade-out 50 ms < hold 100 ms) any trip reaches zero before
//! recovering.
//!
//! The two rules fade different forces:
//! - **loop overrun** → every force, the workspace spring included: when the loop has lost its
//!   timing, no force computed from its positions is trusted (the issue's "zero force when the
//!   loop misses its deadline"); the device's own watchdog is the next line;
//! - **stale parameters** → the renderer's force only, and only while a model is rendered
//!   ([`Model::Rendering`]). Before the first parameters there is no model and no renderer force,
//!   so nothing is stale; and an old model never switches off a safety force such as the
//!   workspace spring.
//!
//! Loop overrun is measured from the `now` of consecutive ticks: a gap longer than the nominal
//! period plus the allowed overrun trips it. This works whatever the loop does with missed
//! deadlines (catch up or skip). The time step used for fades and the rate limit is the gap
//! clamped to `nominal_period + max_overrun`, so a stall does not turn into a step.

use std::time::Duration;

/// Watchdog settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchdogConfig {
    /// Nominal loop period. Default 1 ms (1 kHz); the app replaces it by the session's tick period
    /// (the telerobot's control rate, 100 Hz to 10 kHz) once the `Welcome` says what it is
    /// ([`super::SafetyLayer::set_loop_period`]).
    pub nominal_period: Duration,
    /// Lateness allowed beyond the nominal period before the watchdog trips. Default 2 ms: the
    /// loop sleeps to absolute deadlines, so a 3 ms gap means it lost the CPU.
    pub max_overrun: Duration,
    /// Largest age of the model parameters being rendered (time since the last parameter update
    /// arrived); applies only while a model is rendered. Default 500 ms: the telerobot resends
    /// its parameters every 100 ms, so this is several lost messages; the local model stays valid
    /// for a while (MMT), the fade covers the rest.
    pub max_params_age: Duration,
    /// Time to fade from full force to zero once tripped, > 0. Default 50 ms.
    pub fade_out: Duration,
    /// Time to fade back from zero to full force, > 0. Default 200 ms (as the enable ramp).
    pub fade_in: Duration,
    /// How long a rule's condition must be healthy before it fades back in, ≥ `fade_out`.
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

/// What the renderer renders from, for the parameter-age rule.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// No model yet (or none any more): the renderer's force is zero, nothing can be stale. The
    /// telerobot sends parameters only once it has estimated a contact, so every session starts
    /// here.
    None,
    /// A model whose parameters were last updated `params_age` ago.
    Rendering {
        /// Time since the last parameter update arrived.
        params_age: Duration,
    },
}

/// What the watchdog decided this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WatchdogTick {
    /// Time step for fades and rate limits [s] (gap clamped; nominal period on the first tick).
    pub dt_s: f64,
    /// The loop overran this tick.
    pub overrun: bool,
    /// A model is rendered from parameters older than allowed.
    pub stale: bool,
    /// Gain of the loop-timing rule, in [0, 1]: applies to **every** force (renderer and
    /// workspace spring).
    pub timing_gain: f64,
    /// Gain of the parameter-age rule, in [0, 1]: applies to the **renderer's** force only.
    pub model_gain: f64,
}

impl WatchdogTick {
    /// The gain on the renderer's force: both rules.
    #[must_use]
    pub fn renderer_gain(&self) -> f64 {
        self.timing_gain * self.model_gain
    }
}

/// One rule's fade: tripped until its condition has been healthy for the hold time.
#[derive(Clone, Copy, Debug)]
struct Fade {
    gain: f64,
    last_bad: Option<Duration>,
}

impl Fade {
    const FULL: Self = Self {
        gain: 1.0,
        last_bad: None,
    };

    fn step(&mut self, c: &WatchdogConfig, now: Duration, bad: bool, dt_s: f64) -> f64 {
        if bad {
            self.last_bad = Some(now);
        }
        // Tripped until the condition has been healthy for the hold time: a single bad tick fades
        // the force all the way out (with fade_out < recovery_hold) before it returns.
        let tripped = self
            .last_bad
            .is_some_and(|t| now.saturating_sub(t) < c.recovery_hold);
        self.gain = if tripped {
            (self.gain - dt_s / c.fade_out.as_secs_f64()).max(0.0)
        } else {
            (self.gain + dt_s / c.fade_in.as_secs_f64()).min(1.0)
        };
        self.gain
    }
}

/// The watchdog state: one fade per rule.
#[derive(Clone, Copy, Debug)]
pub struct SoftWatchdog {
    config: WatchdogConfig,
    last_now: Option<Duration>,
    timing: Fade,
    model: Fade,
}

impl SoftWatchdog {
    /// Starts at full gain: start-up is covered by the device's enable ramp.
    #[must_use]
    pub fn new(config: WatchdogConfig) -> Self {
        Self {
            config,
            last_now: None,
            timing: Fade::FULL,
            model: Fade::FULL,
        }
    }

    /// Changes the nominal loop period (the session's tick period), keeping the fades.
    pub(crate) fn set_nominal_period(&mut self, period: Duration) {
        self.config.nominal_period = period;
    }

    /// The settings in use.
    #[must_use]
    pub fn config(&self) -> &WatchdogConfig {
        &self.config
    }

    /// One tick at `now` with what the renderer renders from.
    pub fn step(&mut self, now: Duration, model: Model) -> WatchdogTick {
        let c = self.config;
        let limit = c.nominal_period + c.max_overrun;
        let (gap, overrun) = match self.last_now {
            Some(prev) => {
                let gap = now.saturating_sub(prev);
                (gap.min(limit), gap > limit)
            }
            None => (c.nominal_period, false),
        };
        self.last_now = Some(now);
        let stale = match model {
            Model::None => false,
            Model::Rendering { params_age } => params_age > c.max_params_age,
        };
        let dt_s = gap.as_secs_f64();
        WatchdogTick {
            dt_s,
            overrun,
            stale,
            timing_gain: self.timing.step(&c, now, overrun, dt_s),
            model_gain: self.model.step(&c, now, stale, dt_s),
        }
    }

    /// Current gain on the renderer's force, in [0, 1].
    #[must_use]
    pub fn gain(&self) -> f64 {
        self.timing.gain * self.model.gain
    }

    /// Current gain on the safety forces (workspace spring), in [0, 1].
    #[must_use]
    pub fn timing_gain(&self) -> f64 {
        self.timing.gain
    }
}
