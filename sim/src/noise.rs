//! Seeded sensor models for the simulated telerobot: what the estimator sees instead of the
//! truth. Every sample draws exactly three standard normals (position, velocity, force) in that
//! order, whatever the levels, so runs with different levels stay aligned and a seed fixes the
//! bits.

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
}

impl SensorNoise {
    /// Perfect sensors.
    pub const CLEAN: SensorNoise = SensorNoise {
        position_resolution_m: 0.0,
        position_sd_m: 0.0,
        velocity_sd_m_per_s: 0.0,
        force_sd_n: 0.0,
        force_bias_n: 0.0,
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
            (!self.force_bias_n.is_finite()).then_some((
                "noise.force_bias_n",
                self.force_bias_n,
                "finite",
            ))
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

/// The seeded noise source.
#[derive(Clone, Debug)]
pub struct Sensors {
    noise: SensorNoise,
    rng: Pcg64,
}

impl Sensors {
    /// Sensors with `noise` levels drawing from `rng`.
    pub fn new(noise: SensorNoise, rng: Pcg64) -> Sensors {
        Sensors { noise, rng }
    }

    /// What the sensors read for the true values.
    pub fn measure(&mut self, truth: Measurement) -> Measurement {
        let n = &self.noise;
        let mut draw = || -> f64 { StandardNormal.sample(&mut self.rng) };
        let (nx, nv, nf) = (draw(), draw(), draw());
        let x = truth.position_m + n.position_sd_m * nx;
        let q = n.position_resolution_m;
        Measurement {
            position_m: if q > 0.0 { q * (x / q).round() } else { x },
            velocity_m_per_s: truth.velocity_m_per_s + n.velocity_sd_m_per_s * nv,
            force_n: truth.force_n + n.force_bias_n + n.force_sd_n * nf,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn levels_and_quantisation() {
        let mut s = Sensors::new(SensorNoise::FRANKA_LIKE, Pcg64::seed_from_u64(3));
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
            Sensors::new(SensorNoise::CLEAN, Pcg64::seed_from_u64(3)).measure(Measurement {
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
}
