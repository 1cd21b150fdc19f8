//! Checks of an estimator's configuration: the first invalid field, named.

use super::{EstimatorConfig, EstimatorError, MAX_AXES};

impl EstimatorConfig {
    /// The first invalid field, named: the scalars here, then the confidence gate's and the
    /// first fit's.
    pub(super) fn validate(&self) -> Result<(), EstimatorError> {
        let field = |field, value: f64, ok: bool, expected| {
            if ok {
                Ok(())
            } else {
                Err(EstimatorError::Field {
                    field,
                    value,
                    expected,
                })
            }
        };
        field(
            "axes",
            self.axes as f64,
            (1..=MAX_AXES).contains(&self.axes),
            "1 or 2",
        )?;
        let g = self.onset_guard_s;
        field("onset_guard_s", g, g.is_finite() && g >= 0.0, "≥ 0 s")?;
        let p = self.back_solve_period_s;
        field("back_solve_period_s", p, p.is_finite() && p > 0.0, "> 0 s")?;
        let d = self.detector_mute_s;
        field("detector_mute_s", d, d.is_finite() && d >= 0.0, "≥ 0 s")?;
        let r = self.observer_discount;
        field("observer_discount", r, r > 0.0 && r <= 1.0, "in (0, 1]")?;
        let w = self.observer_wait_s;
        field(
            "observer_wait_s",
            w,
            w >= 0.0,
            "≥ 0 s (∞ waits for a confirmed set)",
        )?;
        let v = self.onset_intercept_covariance;
        field(
            "onset_intercept_covariance",
            v,
            v.is_finite() && v > 0.0,
            "> 0",
        )?;
        let m = self.gates.max_contact_deflection_m;
        field(
            "gates.max_contact_deflection_m",
            m,
            m.is_finite() && m > 0.0,
            "a finite length > 0 m",
        )?;
        let t = self.tare_time_constant_s;
        field("tare_time_constant_s", t, t.is_finite() && t > 0.0, "> 0 s")?;
        self.confidence.validate()?;
        self.first_fit.validate()?;
        self.slide_fit.validate()
    }
}

/// The first of `checks` (field, value) that is not a finite positive number, named.
pub(super) fn positive(checks: &[(&'static str, f64)]) -> Result<(), EstimatorError> {
    match checks.iter().find(|(_, v)| !(v.is_finite() && *v > 0.0)) {
        Some(&(field, value)) => Err(EstimatorError::Field {
            field,
            value,
            expected: "a positive number",
        }),
        None => Ok(()),
    }
}
