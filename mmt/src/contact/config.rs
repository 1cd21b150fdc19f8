//! Proxy parameters (thesis appendix C) and their validation.

use serde::{Deserialize, Serialize};
use thiserror::Error;

use super::NormalEstimator;

/// Parameters of the three-sphere proxy (thesis appendix C, eq. 15–23).
///
/// # Choosing the radii
///
/// - `r2 − r1` must be **at least the magnitude of the point-cloud noise** (thesis, after Ryden &
///   Chizeck): points of a noisy surface then rest in the band between the spheres instead of
///   flickering between "entrenched" and "free".
/// - `r1` must be **small enough for the proxy to rest close to the cloud** without being
///   entrenched: the proxy rests about `(r1 + r2)/2` from the nearest point, and that is the
///   geometric offset the operator feels.
/// - `r3` must hold enough points for a stable normal (eq. 14) but stay small enough to follow
///   edges. The normal's error falls about as `noise / r3²`: with the default plane fit and
///   1 mm spacing, `r3 = 12 mm` keeps it under 2° for noise up to 0.5 mm (6 mm: ~7°). Each
///   moving step visits the ~`π r3²/spacing²` points of the ball, so it is also the cost knob.
/// - The point spacing must stay below `√2 · (r1 + r2)/2` ([`ProxyConfig::max_point_spacing_m`]),
///   or the proxy can slip between grid points (CHAI3D treats each point as a sphere of the
///   proxy radius for the same reason). Dropout doubles the local spacing: allow for it.
///
/// Where the plane fit bridges the cloud ([`ProxyConfig::bridge_holes`], the default), the
/// proxy rests `(r1 + r2)/2` from the fitted plane: the spacing and the noise then matter only
/// through the fit (`r2 − r1` must still hold the noise: it bounds the fit's residual), and
/// round holes up to about `1.9 r3` in radius are bridged. The rules above still hold where
/// the points are not a plane within the band (edges, corners, what stands out of a surface).
///
/// The defaults suit a depth camera at about 1 mm spacing with noise (standard deviation) up to
/// 0.5 mm — `r2 − r1` spans four standard deviations — and stay safe (no punch-through) up to
/// 1 mm: `r1 = 1 mm`, `r2 = 3 mm`, `r3 = 12 mm`, `γ = ζ = 0.5`, 1 kHz.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ProxyConfig {
    /// Inner radius `r1` [m]: a point closer than this entrenches the proxy (eq. 18–19).
    /// Default 1 mm.
    pub r1_m: f64,
    /// Contact radius `r2` [m]: a point within it (and none within `r1`) means contact
    /// (eq. 20–22). Default 3 mm.
    pub r2_m: f64,
    /// Normal radius `r3` [m]: points within it shape the normal (eq. 14–15). Default 12 mm.
    pub r3_m: f64,
    /// `γ` in (0, 1): fraction of `|u|` moved in contact when the HIP is within `r1` (eq. 20).
    /// Default 0.5.
    pub gamma: f64,
    /// `ζ` in (0, 1): fraction of `r1` moved in contact otherwise (eq. 21); below 1 so a
    /// contact step can never carry the proxy through the cloud. Default 0.5.
    pub zeta: f64,
    /// Rate the proxy is stepped at, `f_c` [Hz] (eq. 12–13). Default 1000.
    pub rate_hz: f64,
    /// How the normal is estimated from the Wendland-weighted points within `r3`.
    /// Default: the weighted plane fit (eq. 14 alone tilts on noisy clouds).
    pub normal_estimator: NormalEstimator,
    /// Where the points around the proxy are a plane that surrounds it, touch the fitted plane
    /// instead of the points ([`super::bridge`]): holes and noise in a camera's cloud then do
    /// not let the proxy through or make contact flicker. Acts with the plane-fit estimator
    /// only ([`ProxyConfig::bridges`]). Default `true`; `false` is the thesis's proxy, points
    /// only (appendix C), kept as the baseline the figures are measured against.
    #[serde(default = "bridge_by_default")]
    pub bridge_holes: bool,
}

fn bridge_by_default() -> bool {
    true
}

impl Default for ProxyConfig {
    fn default() -> Self {
        Self {
            r1_m: 0.001,
            r2_m: 0.003,
            r3_m: 0.012,
            gamma: 0.5,
            zeta: 0.5,
            rate_hz: 1000.0,
            normal_estimator: NormalEstimator::WeightedPlaneFit,
            bridge_holes: true,
        }
    }
}

/// Why a proxy cannot be made or placed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ProxyError {
    /// A parameter is not a positive finite number.
    #[error("{field} = {value}, expected a finite number > 0")]
    NotPositive {
        /// The parameter.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// The radii are not strictly increasing.
    #[error("r1_m = {r1}, r2_m = {r2}, r3_m = {r3}: expected r1 < r2 < r3")]
    RadiiOrder {
        /// `r1` [m].
        r1: f64,
        /// `r2` [m].
        r2: f64,
        /// `r3` [m].
        r3: f64,
    },
    /// `γ` or `ζ` is outside (0, 1).
    #[error("{field} = {value}, expected 0 < {field} < 1")]
    FactorOutOfRange {
        /// `gamma` or `zeta`.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// The proxy was placed at a non-finite position.
    #[error("proxy position {value:?} [m], expected finite coordinates")]
    NonFinitePosition {
        /// The position given.
        value: [f64; 3],
    },
}

impl ProxyConfig {
    /// Checks every field; the error names the field, its value and the allowed range.
    pub fn validate(&self) -> Result<(), ProxyError> {
        for (field, value) in [
            ("r1_m", self.r1_m),
            ("r2_m", self.r2_m),
            ("r3_m", self.r3_m),
            ("rate_hz", self.rate_hz),
        ] {
            if !(value > 0.0 && value.is_finite()) {
                return Err(ProxyError::NotPositive { field, value });
            }
        }
        if !(self.r1_m < self.r2_m && self.r2_m < self.r3_m) {
            return Err(ProxyError::RadiiOrder {
                r1: self.r1_m,
                r2: self.r2_m,
                r3: self.r3_m,
            });
        }
        for (field, value) in [("gamma", self.gamma), ("zeta", self.zeta)] {
            if !(value > 0.0 && value < 1.0) {
                return Err(ProxyError::FactorOutOfRange { field, value });
            }
        }
        Ok(())
    }

    /// `(r1 + r2)/2` [m]: how far from a point the proxy stops (eq. 16, 18).
    pub fn rest_distance_m(&self) -> f64 {
        0.5 * (self.r1_m + self.r2_m)
    }

    /// Eq. 23: the most steps a proxy in contact takes to free itself when the HIP is pulled
    /// straight out, `ceil((r2 − r1)/(ζ r1))` (the "sticking" the operator feels).
    pub fn sticking_steps(&self) -> u32 {
        ((self.r2_m - self.r1_m) / (self.zeta * self.r1_m)).ceil() as u32
    }

    /// Whether the proxy bridges holes with the fitted plane: [`ProxyConfig::bridge_holes`]
    /// with the plane-fit estimator (eq. 14 alone fits no plane to bridge with).
    pub fn bridges(&self) -> bool {
        self.bridge_holes && self.normal_estimator == NormalEstimator::WeightedPlaneFit
    }

    /// Largest grid spacing [m] the proxy cannot slip through: a square grid's widest gap has
    /// its centre `spacing/√2` from the nearest points, which must exceed `(r1 + r2)/2`.
    pub fn max_point_spacing_m(&self) -> f64 {
        std::f64::consts::SQRT_2 * self.rest_distance_m()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_and_gives_the_thesis_sticking_bound() {
        let c = ProxyConfig::default();
        c.validate().unwrap();
        assert_eq!(c.rest_distance_m(), 0.002);
        // (3 − 1) mm / (0.5 · 1 mm) = 4 steps.
        assert_eq!(c.sticking_steps(), 4);
    }

    #[test]
    fn invalid_configs_name_field_value_and_range() {
        let base = ProxyConfig::default();
        let cases = [
            (
                ProxyConfig { r1_m: 0.0, ..base },
                "r1_m = 0, expected a finite number > 0",
            ),
            (
                ProxyConfig {
                    rate_hz: f64::NAN,
                    ..base
                },
                "rate_hz = NaN",
            ),
            (
                ProxyConfig {
                    r2_m: 0.0005,
                    ..base
                },
                "expected r1 < r2 < r3",
            ),
            (
                ProxyConfig {
                    r3_m: 0.003,
                    ..base
                },
                "expected r1 < r2 < r3",
            ),
            (
                ProxyConfig { gamma: 1.0, ..base },
                "gamma = 1, expected 0 < gamma < 1",
            ),
            (
                ProxyConfig { zeta: -0.1, ..base },
                "zeta = -0.1, expected 0 < zeta < 1",
            ),
        ];
        for (config, expected) in cases {
            let msg = config.validate().unwrap_err().to_string();
            assert!(msg.contains(expected), "{msg}");
        }
    }
}
