//! The operator node's counters.

use serde::{Deserialize, Serialize};

/// Counters for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OperatorStats {
    /// Ticks stepped.
    pub ticks: u64,
    /// Parameter sets accepted (after the local gates).
    pub parameter_sets: u64,
    /// Parameter sets the local gates rejected.
    pub parameter_rejections: u64,
    /// Models started (first model, then each new model id, and the whole set after a reduced
    /// one).
    pub models: u64,
    /// Episode replays at model start, and the ticks they replayed.
    pub model_replays: u64,
    /// State syncs applied, and the ticks they replayed.
    pub syncs: u64,
    /// Ticks replayed by syncs and model starts.
    pub replayed_ticks: u64,
    /// State syncs ignored (not in contact, too old, or rate-limited).
    pub syncs_skipped: u64,
    /// Clouds received and indexed.
    pub clouds: u64,
    /// Clouds that could not be indexed.
    pub rejected_clouds: u64,
    /// Contact onsets.
    pub contact_onsets: u64,
    /// Ticks with a non-finite device reading (force 0).
    pub rejected_inputs: u64,
    /// Views of a received cloud moved by the object's predicted slide (a new one each time the
    /// move changes by 0.1 mm).
    #[serde(default)]
    pub moved_clouds: u64,
    /// The largest of those moves \[m\].
    #[serde(default)]
    pub largest_cloud_move_m: f64,
    /// Moves of a frame captured before the slide's history (16 s): the whole history's slide
    /// was used.
    #[serde(default)]
    pub cloud_moves_beyond_history: u64,
}
