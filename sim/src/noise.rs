//! Seeded sensor models for the simulated telerobot: what the estimator sees instead of the
//! truth. Every sample draws exactly three standard normals (position, velocity, force) in that
//! order, whatever the levels, so runs with different levels stay aligned and a seed fixes the
//! bits.
//!
//! Each axis reads `F + b(x, t) + σ_F n`, with the force bias
//! `b = force_bias_n + force_bias_gradient_n_per_m·(x − x₀) + force_bias_drift_n_per_s·t`
//! (`x₀` the axis position at the first sample, `t` the time since it): a constant offset, a
//! part that varies with the pose (an arm's model-based wrench estimate is off by a different
//! amount in every configuration, franka_ros #404) and a slow drift in time (a strain-gauge
//! sensor warming up).

use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64;

/// Sensor noise levels, per 1 kHz sample. All white and Gaussian, independent per channel.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SensorNoise {
    /// Position quantisation step `q` [m] (encoder resolution seen at the tool); 0 = none. The
    /// reading is `q·round((x + n_x)/q)`.
    pub position_resolution_m: f64,
    /// Position noise standard deviation [m].
    pub position_sd_m: f64,
    /// Velocity noise standard deviation [m/s].
    pub velocity_sd_m_per_s: f64,
    /// Force noise standard deviation [N].
    pub force_sd_n: f64,
    /// Constant force offset [N], added in and out of contact (a bridge tares it out of contact).
    pub force_bias_n: f64,
    /// Change of the force offset with the axis position [N/m] (pose-dependent bias); 0 = none.
    /// Inside one contact it looks exactly like a spring, so the estimator must learn it out of
    /// contact.
    pub force_bias_gradient_n_per_m: f64,
    /// Change of the force offset with time [N/s] (thermal drift); 0 = none.
    pub force_bias_drift_n_per_s: f64,
}

impl SensorNoise {
    /// Perfect sensors.
    pub const CLEAN: SensorNoise = SensorNoise {
        position_resolution_m: 0.0,
        position_sd_m: 0.0,
        velocity_sd_m_per_s: 0.0,
        force_sd_n: 0.0,
        force_bias_n: 0.0,
        force_bias_gradient_n_per_m: 0.0,
        force_bias_drift_n_per_s: 0.0,
    };

    /// A Franka-Panda-like arm measuring at its flange, with the levels of the feasibility
    /// prototype (`feasibility-notes.md`) so that figures compare:
    /// - position: 2 µm noise (prototype), read through a 1 µm quantiser (an assumed Cartesian
    ///   resolution of the joint encoders; it is dithered by the noise);
    /// - velocity: 1 mm/s (prototype's assumption: `J·q̇` from differentiated encoders);
    /// - force: 0.02 N white (prototype) plus a 0.05 N offset (assumed; about `F_d`, so an
    ///   untared offset is visible in the friction columns).
    ///
    /// A real Panda's model-based external-wrench estimate (`O_F_ext_hat_K`) is noisier and
    /// drifts; these are not datasheet figures. Replace them from a recording when one exists.
    pub const FRANKA_LIKE: SensorNoise = SensorNoise {
        position_resolution_m: 1e-6,
        position_sd_m: 2e-6,
        velocity_sd_m_per_s: 1e-3,
        force_sd_n: 0.02,
        force_bias_n: 0.05,
        force_bias_gradient_n_per_m: 0.0,
        force_bias_drift_n_per_s: 0.0,
    };

    /// An arm's model-based estimate of the external wrench (a Panda's `O_F_ext_hat_K`), as its
    /// users describe it: well away from zero without contact and varying with the pose
    /// (franka_ros #404; its maintainers advise the filtered external torques instead). **These
    /// levels are assumptions until a recording replaces them**: 0.2 N white force noise (ten
    /// times the Franka-like preset), a 1 N offset on every axis that changes by 5 N/m with
    /// the position (0.5 N over 10 cm of motion) and drifts by 1 mN/s; position and velocity as
    /// [`Self::FRANKA_LIKE`].
    pub const ARM_WRENCH: SensorNoise = SensorNoise {
        position_resolution_m: 1e-6,
        position_sd_m: 2e-6,
        velocity_sd_m_per_s: 1e-3,
        force_sd_n: 0.2,
        force_bias_n: 1.0,
        force_bias_gradient_n_per_m: 5.0,
        force_bias_drift_n_per_s: 1e-3,
    };

    /// A six-axis strain-gauge force/torque sensor at the wrist (ATI Mini40/Nano25 class) on the
    /// same arm. **Assumed levels**, from the class's published resolution (about 1/100 N) and
    /// not from a recording: 0.01 N white noise, a 0.3 N offset (the tool's weight and the
    /// sensor's zero, tared out of contact), a thermal drift of 0.5 mN/s and no pose dependence
    /// (translation only: the tool's weight does not turn); position and velocity as
    /// [`Self::FRANKA_LIKE`].
    pub const WRIST_FT: SensorNoise = SensorNoise {
        position_resolution_m: 1e-6,
        position_sd_m: 2e-6,
        velocity_sd_m_per_s: 1e-3,
        force_sd_n: 0.01,
        force_bias_n: 0.3,
        force_bias_gradient_n_per_m: 0.0,
        force_bias_drift_n_per_s: 5e-4,
    };

    /// Name, value and expectation of the first invalid field, if any.
    pub fn invalid_field(&self) -> Option<(&'static str, f64, &'static str)> {
        [
            ("noise.position_resolution_m", self.position_resolution_m),
            ("noise.position_sd_m", self.position_sd_m),
            ("noise.velocity_sd_m_per_s", self.velocity_sd_m_per_s),
            ("noise.force_sd_n", self.force_sd_n),
        ]
        .into_iter()
        .find(|(_, v)| !(v.is_finite() && *v >= 0.0))
        .map(|(name, v)| (name, v, "finite and ≥ 0"))
        .or_else(|| {
            [
                ("noise.force_bias_n", self.force_bias_n),
                (
                    "noise.force_bias_gradient_n_per_m",
                    self.force_bias_gradient_n_per_m,
                ),
                (
                    "noise.force_bias_drift_n_per_s",
                    self.force_bias_drift_n_per_s,
                ),
            ]
            .into_iter()
            .find(|(_, v)| !v.is_finite())
            .map(|(name, v)| (name, v, "finite"))
        })
    }
}

/// Position [m], velocity [m/s] and force on the tool [N] at one sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Measurement {
    /// Tool position [m].
    pub position_m: f64,
    /// Tool velocity [m/s].
    pub velocity_m_per_s: f64,
    /// Force on the tool [N] (sign convention of [`mmt::model`]).
    pub force_n: f64,
}

/// The seeded noise source of one axis.
#[derive(Clone, Debug)]
pub struct Sensors {
    noise: SensorNoise,
    rng: Pcg64,
    period_s: f64,
    /// Samples read so far.
    samples: u64,
    /// Axis position at the first sample [m].
    origin_m: Option<f64>,
}

impl Sensors {
    /// Sensors with `noise` levels drawing from `rng`, read every `period_s` [s].
    pub fn new(noise: SensorNoise, period_s: f64, rng: Pcg64) -> Sensors {
        Sensors {
            noise,
            rng,
            period_s,
            samples: 0,
            origin_m: None,
        }
    }

    /// The force offset at axis position `x_m` now [N].
    pub fn bias_n(&self, x_m: f64) -> f64 {
        let n = &self.noise;
        let dx = x_m - self.origin_m.unwrap_or(x_m);
        n.force_bias_n
            + n.force_bias_gradient_n_per_m * dx
            + n.force_bias_drift_n_per_s * self.samples as f64 * self.period_s
    }

    /// What the sensors read for the true values.
    pub fn measure(&mut self, truth: Measurement) -> Measurement {
        self.origin_m.get_or_insert(truth.position_m);
        let bias = self.bias_n(truth.position_m);
        self.samples += 1;
        let n = &self.noise;
        let mut draw = || -> f64 { StandardNormal.sample(&mut self.rng) };
        let (nx, nv, nf) = (draw(), draw(), draw());
        let x = truth.position_m + n.position_sd_m * nx;
        let q = n.position_resolution_m;
        Measurement {
            position_m: if q > 0.0 { q * (x / q).round() } else { x },
            velocity_m_per_s: truth.velocity_m_per_s + n.velocity_sd_m_per_s * nv,
            force_n: truth.force_n + bias + n.force_sd_n * nf,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn levels_and_quantisation() {
        let mut s = Sensors::new(SensorNoise::FRANKA_LIKE, 1e-3, Pcg64::seed_from_u64(3));
        let n = 20_000;
        let (mut sf, mut sf2, mut sv2) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let m = s.measure(Measurement {
                position_m: 0.0123456789,
                velocity_m_per_s: 0.0,
                force_n: 1.0,
            });
            let steps = m.position_m / 1e-6;
            assert!((steps - steps.round()).abs() < 1e-6, "{}", m.position_m);
            sf += m.force_n - 1.0;
            sf2 += (m.force_n - 1.0 - 0.05).powi(2);
            sv2 += m.velocity_m_per_s.powi(2);
        }
        let nf = n as f64;
        assert!((sf / nf - 0.05).abs() < 1e-3, "bias {}", sf / nf);
        assert!(((sf2 / nf).sqrt() / 0.02 - 1.0).abs() < 0.03);
        assert!(((sv2 / nf).sqrt() / 1e-3 - 1.0).abs() < 0.03);
        let clean =
            Sensors::new(SensorNoise::CLEAN, 1e-3, Pcg64::seed_from_u64(3)).measure(Measurement {
                position_m: 0.1,
                velocity_m_per_s: 0.2,
                force_n: 0.3,
            });
        assert_eq!(
            (clean.position_m, clean.velocity_m_per_s, clean.force_n),
            (0.1, 0.2, 0.3)
        );
        let bad = SensorNoise {
            force_sd_n: -1.0,
            ..SensorNoise::CLEAN
        };
        assert_eq!(bad.invalid_field().map(|f| f.0), Some("noise.force_sd_n"));
    }

    /// The arm preset's offset moves with the position and with time, as documented.
    #[test]
    fn bias_drifts_with_position_and_time() {
        let mut s = Sensors::new(SensorNoise::ARM_WRENCH, 1e-3, Pcg64::seed_from_u64(1));
        let at = |x: f64| Measurement {
            position_m: x,
            velocity_m_per_s: 0.0,
            force_n: 0.0,
        };
        let _ = s.measure(at(0.3));
        assert!((s.bias_n(0.3) - 1.0 - 1e-6).abs() < 1e-12);
        assert!((s.bias_n(0.4) - s.bias_n(0.3) - 0.5).abs() < 1e-12);
        for _ in 0..999 {
            let _ = s.measure(at(0.3));
        }
        assert!((s.bias_n(0.3) - 1.001).abs() < 1e-12, "{}", s.bias_n(0.3));
        let bad = SensorNoise {
            force_bias_gradient_n_per_m: f64::NAN,
            ..SensorNoise::CLEAN
        };
        assert_eq!(
            bad.invalid_field().map(|f| f.0),
            Some("noise.force_bias_gradient_n_per_m")
        );
    }
}
