//! The sliding first fit's settings.

use serde::{Deserialize, Serialize};

use super::super::EstimatorError;

/// Settings of the sliding first fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SlideFitConfig {
    /// Whether a sliding group publishes a first fit before its RLS set. Default true.
    pub enabled: bool,
    /// Contact time before the first solve of every term \[s\]. Default 0.1.
    pub min_window_s: f64,
    /// Contact time before the first solve of the contact element alone \[s\]: `k2` and `b2`
    /// of the massless model, with `b1` and `Fc` held at the centre of the soft-object class,
    /// until [`Self::min_window_s`]; published as a reduced set. Default 0.02. In the first
    /// tens of milliseconds the object has barely moved, so the force is the contact
    /// element's and the mass's terms cannot be told apart yet; the generic prior's contact
    /// element was what the operator felt wrong (exp 1, seed 2: 114 % error from 50 to 100 ms
    /// of contact; its stiffness-to-damping ratio is 4 × the object's). A value
    /// ≥ `min_window_s` leaves this stage out.
    pub contact_fit_s: f64,
    /// Time between solve starts of the contact element \[s\]. Default 0.01.
    pub contact_period_s: f64,
    /// Half-width of the smoothing of the measured tool velocity that the fit simulates the
    /// model along \[s\] (a quadratic Savitzky–Golay fit, symmetric: the window is frozen when a
    /// solve starts). Default 0.02. 0 uses the velocity as measured.
    pub velocity_smoothing_s: f64,
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
            contact_fit_s: 0.02,
            contact_period_s: 0.01,
            velocity_smoothing_s: 0.02,
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
        let s = self.velocity_smoothing_s;
        if !(s.is_finite() && (0.0..=0.1).contains(&s)) {
            return Err(EstimatorError::Field {
                field: "slide_fit.velocity_smoothing_s",
                value: s,
                expected: "between 0 and 0.1 s",
            });
        }
        super::super::validate::positive(&[
            ("slide_fit.min_window_s", self.min_window_s),
            ("slide_fit.contact_fit_s", self.contact_fit_s),
            ("slide_fit.contact_period_s", self.contact_period_s),
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
