//! The confidence gate (`DESIGN.md` §11.4): the back-solved parameters moved less than a set
//! fraction over a window, and the smoothed prediction error is small.

use super::EstimatorError;
use crate::model::backsolve::Params;
use crate::model::gates::Gated;
use serde::{Deserialize, Serialize};

/// Thresholds of the confidence gate.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConfidenceConfig {
    /// Window over which the parameters must hold still [s]. Default 0.25.
    pub window_s: f64,
    /// Largest relative spread `(max − min)/max` of each key parameter in the window. Default
    /// 0.10. Key parameters: m, k2, b1, b2 (sliding mass); k, b (Kelvin–Voigt).
    pub max_relative_change: f64,
    /// Largest smoothed relative prediction error of the RLS. Default 0.10.
    pub max_prediction_error: f64,
    /// Once confident, the spread and error may grow to this multiple of the entry thresholds
    /// before a set is withheld; confidence is lost only when every back-solve of a whole window
    /// fails (a gate or these looser thresholds). Default 3: the filters' switching transient
    /// after a re-contact must not revoke a model that has not changed.
    pub exit_factor: f64,
}

impl Default for ConfidenceConfig {
    fn default() -> Self {
        ConfidenceConfig {
            window_s: 0.25,
            max_relative_change: 0.10,
            max_prediction_error: 0.10,
            exit_factor: 3.0,
        }
    }
}

impl ConfidenceConfig {
    pub(super) fn validate(&self) -> Result<(), EstimatorError> {
        let checks = [
            ("confidence.window_s", self.window_s),
            ("confidence.max_relative_change", self.max_relative_change),
            ("confidence.max_prediction_error", self.max_prediction_error),
            ("confidence.exit_factor", self.exit_factor),
        ];
        for (field, value) in checks {
            if !(value.is_finite() && value > 0.0) {
                return Err(EstimatorError::Field {
                    field,
                    value,
                    expected: "a positive number",
                });
            }
        }
        Ok(())
    }
}

/// Longest window kept (entries at the back-solve rate).
const CAPACITY: usize = 256;

/// Ring of recent gate-passing back-solves.
#[derive(Clone, Debug)]
pub(super) struct Confidence {
    config: ConfidenceConfig,
    /// `(time, key parameters)`.
    ring: [(f64, [f64; 4]); CAPACITY],
    len: usize,
    head: usize,
    needed: usize,
    confident: bool,
    /// Consecutive back-solves that failed while confident.
    fail_streak: usize,
}

impl Confidence {
    pub(super) fn new(config: ConfidenceConfig, period_s: f64) -> Self {
        let needed = ((config.window_s / period_s).ceil() as usize + 1).clamp(2, CAPACITY);
        Confidence {
            config,
            ring: [(0.0, [0.0; 4]); CAPACITY],
            len: 0,
            head: 0,
            needed,
            confident: false,
            fail_streak: 0,
        }
    }

    /// Forgets everything (a new object).
    pub(super) fn clear(&mut self) {
        self.len = 0;
        self.confident = false;
        self.fail_streak = 0;
    }

    /// A back-solve failed a gate. Before confidence this restarts the window; once confident it
    /// counts towards losing it.
    pub(super) fn reject(&mut self) {
        if self.confident {
            self.fail(true);
        } else {
            self.len = 0;
        }
    }

    fn fail(&mut self, count: bool) {
        if count {
            self.fail_streak += 1;
        }
        if self.fail_streak >= self.needed {
            self.clear();
        }
    }

    pub(super) fn is_confident(&self) -> bool {
        self.confident
    }

    /// Adds a gate-passing set; returns whether it may be published (the gate passes).
    pub(super) fn push(&mut self, now_s: f64, g: &Gated, relative_error: Option<f64>) -> bool {
        let key = match g.params() {
            Params::SlidingMass(p) => [
                p.mass_kg,
                p.k_contact_n_per_m,
                p.b_ground_ns_per_m,
                p.b_contact_ns_per_m,
            ],
            Params::KelvinVoigt(kv) => [kv.k_n_per_m, kv.b_ns_per_m, 1.0, 1.0],
            Params::Free => [1.0; 4],
        };
        self.ring[self.head] = (now_s, key);
        self.head = (self.head + 1) % CAPACITY;
        self.len = (self.len + 1).min(CAPACITY);
        let c = &self.config;
        let within = |factor: f64| {
            self.len >= self.needed
                && self.still(c.max_relative_change * factor)
                && relative_error.is_some_and(|e| e <= c.max_prediction_error * factor)
        };
        if self.confident {
            if within(c.exit_factor) {
                self.fail_streak = 0;
                return true;
            }
            self.fail(true);
            return false;
        }
        self.confident = within(1.0);
        self.confident
    }

    fn still(&self, max_change: f64) -> bool {
        let window = self.needed;
        let mut lo = [f64::INFINITY; 4];
        let mut hi = [f64::NEG_INFINITY; 4];
        for k in 0..window {
            let idx = (self.head + CAPACITY - 1 - k) % CAPACITY;
            for (j, v) in self.ring[idx].1.iter().enumerate() {
                lo[j] = lo[j].min(*v);
                hi[j] = hi[j].max(*v);
            }
        }
        // Relative to the largest value; a parameter that stays exactly 0 is still.
        (0..4).all(|j| hi[j] - lo[j] <= max_change * hi[j].abs())
    }
}
