//! The telerobot node's counters.

use serde::{Deserialize, Serialize};

/// Counters for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TelerobotStats {
    /// Ticks stepped.
    pub ticks: u64,
    /// Ticks spent holding still for lack of fresh commands.
    pub holding_ticks: u64,
    /// Ticks the playout's path was at rest for want of commands (extrapolated as far as it
    /// goes); the estimators' new-object detectors are muted through them and the filters'
    /// transient after.
    #[serde(default)]
    pub stopped_ticks: u64,
    /// Breaks of the playout's path (a snap onto a late command, a stop at the end of the
    /// extrapolation) absorbed into an offset that decays smoothly ([`crate::continuity`]).
    #[serde(default)]
    pub path_breaks: u64,
    /// Of them, too large to blend (beyond 5 mm or 0.5 m/s): passed on for the motion guard.
    #[serde(default)]
    pub unblended_breaks: u64,
    /// Ticks the robot was told the path plus such an offset.
    #[serde(default)]
    pub blended_ticks: u64,
    /// Commands accepted.
    pub commands: u64,
    /// Commands dropped: duplicates, older than the one executing, or not finite.
    pub stale_commands: u64,
    /// Commands refused for an implausible playout time: their lag (arrival − sample time)
    /// differs from the session's first command's by more than the limit
    /// ([`crate::MotionLimits::max_clock_jump_ns`]).
    pub implausible_commands: u64,
    /// Commands passed over because a newer one's turn had come (backlog after a stall).
    pub skipped_commands: u64,
    /// Samples with a non-finite value (dropped).
    pub rejected_samples: u64,
    /// Camera frames that could not be indexed ([`super::TelerobotNode::count_rejected_cloud`]).
    pub rejected_clouds: u64,
    /// Contact episodes.
    pub contact_onsets: u64,
    /// Ticks the robot followed the operator's path (fresh commands, the path not stopped).
    #[serde(default)]
    pub played_ticks: u64,
    /// Over them, the sum of the playout lag `L` as played: how long after its sample time the
    /// robot was told a point of the path (the link's delay, plus what the playout added for
    /// its jitter) \[µs\]. The sample times are on the operator's clock: across two hosts the
    /// lag includes the clocks' offset (negative when the operator's clock is ahead).
    #[serde(default)]
    pub played_lag_us_sum: i64,
}

impl TelerobotStats {
    /// The mean playout lag over the ticks the robot followed the path \[ms\]: the delay from
    /// the operator's device to the robot, as the robot executed it (on one host; across two,
    /// plus the clocks' offset).
    pub fn mean_played_lag_ms(&self) -> Option<f64> {
        (self.played_ticks > 0)
            .then(|| self.played_lag_us_sum as f64 / self.played_ticks as f64 * 1e-3)
    }
}
