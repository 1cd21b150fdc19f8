//! [`SafetyStats`]: what the safety layer did, counted (never logged per tick), serialisable into
//! run reports; and [`Trip`], the edge detector that makes each rule log once per episode.

use serde::Serialize;

/// How often one rule acted.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TripCount {
    /// Episodes: times the rule went from inactive to active.
    pub episodes: u64,
    /// Ticks on which it was active.
    pub ticks: u64,
    /// Whether it is active now (not serialised).
    #[serde(skip)]
    pub active: bool,
}

/// What [`TripCount::record`] saw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edge {
    /// Became active this tick.
    Rose,
    /// Stopped being active this tick.
    Fell,
    /// No change.
    Steady,
}

impl TripCount {
    /// Records one tick; returns the edge so the caller can log on state change only.
    pub fn record(&mut self, active: bool) -> Edge {
        if active {
            self.ticks += 1;
        }
        let edge = match (self.active, active) {
            (false, true) => {
                self.episodes += 1;
                Edge::Rose
            }
            (true, false) => Edge::Fell,
            _ => Edge::Steady,
        };
        self.active = active;
        edge
    }
}

/// Counters of every safety rule. One per layer; read with
/// [`super::SafetyLayer::stats`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct SafetyStats {
    /// Ticks processed.
    pub ticks: u64,
    /// Renderer force had a NaN or infinite component (replaced by zero).
    pub non_finite_force: TripCount,
    /// Measured position had a NaN or infinite component (commanded position held).
    pub non_finite_position: TripCount,
    /// Measured velocity had a NaN or infinite component (zero velocity commanded).
    pub non_finite_velocity: TripCount,
    /// Force magnitude limited to the device maximum.
    pub saturated: TripCount,
    /// Force change limited by the rate limit.
    pub rate_limited: TripCount,
    /// Device outside its workspace (spring pushing back).
    pub workspace: TripCount,
    /// Loop overran its deadline by more than allowed (watchdog).
    pub loop_overrun: TripCount,
    /// A model rendered from parameters older than allowed (watchdog; renderer force faded).
    pub stale_params: TripCount,
    /// Watchdog gain on the renderer's force below 1 (fading out, held at zero, or fading back
    /// in).
    pub watchdog_fading: TripCount,
    /// Clutch engaged.
    pub clutch: TripCount,
    /// Position-scale changes refused (non-positive or non-finite).
    pub scale_rejections: u64,
    /// Passivity observer and controller.
    pub passivity: super::PassivityStats,
}
