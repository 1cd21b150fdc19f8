//! The sliding first fit's settings.

use serde::{Deserialize, Serialize};

use super::super::EstimatorError;

/// Settings of the sliding first fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SlideFitConfig {
    /// Whether a sliding group publishes a first fit before its RLS set. Default true.
    pub enabled: bool,
    /// Contact time before the first solve \[s\]. Default 0.1.
    pub min_window_s: f64,
    /// Longest window fitted \[s\]: the memory held and the cost of an iteration. Default 0.4.
    pub max_window_s: f64,
    /// Time between solve starts \[s\]. Default 0.05.
    pub period_s: f64,
    /// Largest RMS misfit of the force, relative to its RMS. Default 0.15.
    pub max_residual: f64,
    /// Largest relative standard error of `m, b1, k2, b2`, and of `Fc` as a force relative to
    /// the RMS force. Default 0.3.
    pub max_relative_error: f64,
    /// A published set is published again once a parameter has moved by a factor of `1 +`
    /// this either way. Default 0.1.
    pub republish_change: f64,
}

impl Default for SlideFitConfig {
    fn default() -> Self {
        SlideFitConfig {
            enabled: true,
            min_window_s: 0.1,
            max_window_s: 0.4,
            period_s: 0.05,
            max_residual: 0.15,
            max_relative_error: 0.3,
            republish_change: 0.1,
        }
    }
}

impl SlideFitConfig {
    pub(in crate::estimator) fn validate(&self) -> Result<(), EstimatorError> {
        super::super::validate::positive(&[
            ("slide_fit.min_window_s", self.min_window_s),
            ("slide_fit.max_window_s", self.max_window_s),
            ("slide_fit.period_s", self.period_s),
            ("slide_fit.max_residual", self.max_residual),
            ("slide_fit.max_relative_error", self.max_relative_error),
            ("slide_fit.republish_change", self.republish_change),
        ])?;
        if self.max_window_s < self.min_window_s || self.max_window_s > 2.0 {
            return Err(EstimatorError::Field {
                field: "slide_fit.max_window_s",
                value: self.max_window_s,
                expected: "between slide_fit.min_window_s and 2 s",
            });
        }
        Ok(())
    }
}
