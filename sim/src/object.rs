//! The simulated environment: ground truth for the telerobot's default robot bridge on one
//! tangential axis (thesis set-up 1, §4.1 and §F.3.1; `DESIGN.md` §5).
//!
//! The sliding flexible object of [`mmt::model`]: a mass `m` tied to the world by `k1`, `b1`
//! and [Karnopp](friction) stick–slip friction, touched through a Kelvin–Voigt contact
//! `k2`, `b2`. The tool position is commanded at every 1 kHz sample; the simulator integrates at
//! `substeps` × that rate (≥ 10 kHz) and returns the sensors' reading of position, velocity and
//! force on the tool, plus the truth.
//!
//! # Integration
//!
//! - **Tool motion within a tick**: cubic Hermite through the commanded position and velocity at
//!   both ends (C¹, consistent with the commanded velocity, which the damper `b2` feels).
//! - **Linear part**: exact. Per sub-step `h_s` the state `z = [x_m, ẋ_m]` advances by the exact
//!   exponential of the 2×2 system with a first-order hold on the inputs `[x − L, ẋ]` (sampled
//!   from the Hermite curve at the sub-step ends) and a zero-order hold on the friction force
//!   ([`Foh`], computed once at construction for the in-contact and free systems):
//!   `z⁺ = Φ z + Γ_hold u + Γ_ramp Δu + c·f`. The only approximations are the linear
//!   interpolation of the tool between sub-step nodes (`O(h_s²)`) and friction held over a
//!   sub-step; the test `substeps_converge` bounds both against a 10× finer run (< 1e-4).
//! - **Friction**: [`Karnopp::force`] per sub-step, from the exact friction-free end velocity.
//! - **Contact make/break**: the flag of a sample applies from the start of its tick. At onset
//!   the contact rest length `L` is set so that the force starts at exactly 0
//!   (`k2 (x − L − x_m) + b2 (ẋ − ẋ_m) = 0`); out of contact the force is 0 and the mass evolves
//!   under `k1`, `b1` and friction only.
//!
//! No clock, no thread: [`SlidingObjectSim::step`] is called once per sample by the bridge.

use nalgebra::DMatrix;
use rand_pcg::Pcg64;
use thiserror::Error;

use crate::friction::{Karnopp, Phase};
use crate::noise::{Measurement, SensorNoise, Sensors};
use mmt::filter::expm::{ExpmError, Foh};
use mmt::model::{Physical, force_on_tool};

/// Configuration of the simulated object and its sensors.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SimConfig {
    /// The object. Its `coulomb_n` is the Karnopp dynamic level `F_d`, so the truth and the
    /// model's `g = k2 Fc/S` agree. `mass_kg` must be > 0.
    pub object: Physical,
    /// Karnopp static level `F_s` [N], ≥ `F_d`. Exp-1: 0.1 N (thesis §4.1).
    pub static_friction_n: f64,
    /// Karnopp stick band `v_d` [m/s], > 0. Exp-1: 0.005 m/s.
    pub stick_band_m_per_s: f64,
    /// Output sample period [s]. Default 1 ms (the telerobot's 1 kHz loop).
    pub sample_period_s: f64,
    /// Integration sub-steps per sample. Default 10 (10 kHz, the `DESIGN.md` §5 minimum):
    /// the result moves by < 1e-4 relative at 100 (test `substeps_converge`).
    pub substeps: u32,
    /// Sensor noise. Default [`SensorNoise::CLEAN`].
    pub noise: SensorNoise,
}

impl SimConfig {
    /// The thesis's experiment-1 scene (set-up 1): m = 1 kg, k1 = 0, b1 = 60, k2 = 500,
    /// b2 = 60, Karnopp 0.1 / 0.05 N, 0.005 m/s; clean sensors, 1 kHz, 10 sub-steps.
    pub const THESIS_EXP1: SimConfig = SimConfig {
        object: Physical::THESIS_EXP1,
        static_friction_n: 0.1,
        stick_band_m_per_s: 0.005,
        sample_period_s: 1e-3,
        substeps: 10,
        noise: SensorNoise::CLEAN,
    };

    /// The friction law.
    pub fn friction(&self) -> Karnopp {
        Karnopp {
            static_n: self.static_friction_n,
            dynamic_n: self.object.coulomb_n,
            band_m_per_s: self.stick_band_m_per_s,
        }
    }

    /// Checks every field; the error names the field, the value and the allowed range.
    pub fn validate(&self) -> Result<(), SimError> {
        if let Some((field, value, _, expected)) = self
            .checks()
            .into_iter()
            .find(|(_, v, ok, _)| !(v.is_finite() && *ok))
        {
            return Err(SimError::Field {
                field,
                value,
                expected,
            });
        }
        if let Some((field, value, expected)) = self.noise.invalid_field() {
            return Err(SimError::Field {
                field,
                value,
                expected,
            });
        }
        Ok(())
    }

    /// Each field with its value, whether it is in range (besides being finite), and the range.
    fn checks(&self) -> [(&'static str, f64, bool, &'static str); 10] {
        let o = &self.object;
        let h = self.sample_period_s;
        let h_sub = h / f64::from(self.substeps.max(1));
        [
            (
                "object.mass_kg",
                o.mass_kg,
                o.mass_kg > 0.0,
                "finite and > 0",
            ),
            (
                "object.k_ground_n_per_m",
                o.k_ground_n_per_m,
                o.k_ground_n_per_m >= 0.0,
                "finite and ≥ 0",
            ),
            (
                "object.b_ground_ns_per_m",
                o.b_ground_ns_per_m,
                o.b_ground_ns_per_m >= 0.0,
                "finite and ≥ 0",
            ),
            (
                "object.k_contact_n_per_m",
                o.k_contact_n_per_m,
                o.k_contact_n_per_m >= 0.0,
                "finite and ≥ 0",
            ),
            (
                "object.b_contact_ns_per_m",
                o.b_contact_ns_per_m,
                o.b_contact_ns_per_m >= 0.0,
                "finite and ≥ 0",
            ),
            (
                "object.coulomb_n",
                o.coulomb_n,
                o.coulomb_n >= 0.0,
                "finite and ≥ 0",
            ),
            (
                "static_friction_n",
                self.static_friction_n,
                self.static_friction_n >= o.coulomb_n,
                "finite and ≥ object.coulomb_n",
            ),
            (
                "stick_band_m_per_s",
                self.stick_band_m_per_s,
                self.stick_band_m_per_s > 0.0,
                "finite and > 0",
            ),
            ("sample_period_s", h, h > 0.0, "finite and > 0"),
            (
                "substeps",
                f64::from(self.substeps),
                self.substeps >= 1 && h_sub <= 1e-4 * (1.0 + 1e-12),
                "≥ 1 and sample_period_s/substeps ≤ 1e-4 s (≥ 10 kHz)",
            ),
        ]
    }
}

/// An invalid simulator configuration.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SimError {
    /// A field out of range.
    #[error("sim config: {field} = {value} invalid, expected {expected}")]
    Field {
        /// Field name.
        field: &'static str,
        /// The value given.
        value: f64,
        /// The allowed range.
        expected: &'static str,
    },
    /// The discretisation failed (cannot happen for a valid configuration).
    #[error("sim discretisation failed: {0}")]
    Discretisation(#[from] ExpmError),
}

/// One output sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSample {
    /// What the sensors read.
    pub measured: Measurement,
    /// The true tool position, velocity and force on the tool.
    pub truth: Measurement,
    /// Object position `x_m` [m] (0 where `k1` is relaxed).
    pub mass_position_m: f64,
    /// Object velocity [m/s].
    pub mass_velocity_m_per_s: f64,
    /// Friction force on the object over the last sub-step [N].
    pub friction_n: f64,
    /// Friction branch of the last sub-step.
    pub phase: Phase,
    /// Whether the tool touched the object during this tick.
    pub in_contact: bool,
    /// Energy stored in the object: `½ m ẋ_m² + ½ k1 x_m² + ½ k2 δ²` (δ the contact spring's
    /// stretch, in contact only) [J].
    pub stored_energy_j: f64,
}

/// Friction event counters, for chatter checks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrictionStats {
    /// Entries into the stick branch.
    pub stick_episodes: u64,
    /// Sign changes of the (non-zero) object velocity, sub-step by sub-step.
    pub sign_changes: u64,
    /// Most sign changes counted within one stick episode: from entering the stick branch until
    /// the object slides at `|v| ≥ v_d` again (a reversal through a stick counts 1; chatter
    /// counts many).
    pub max_sign_changes_per_episode: u32,
}

/// The exact sub-step map of one linear configuration (in contact or free).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Linear {
    phi: [[f64; 2]; 2],
    /// Columns: `x − L`, `ẋ`, friction.
    hold: [[f64; 3]; 2],
    ramp: [[f64; 3]; 2],
}

impl Linear {
    fn new(o: &Physical, contact: bool, h_sub: f64) -> Result<Linear, ExpmError> {
        let (k2, b2) = if contact {
            (o.k_contact_n_per_m, o.b_contact_ns_per_m)
        } else {
            (0.0, 0.0)
        };
        let m = o.mass_kg;
        let a = DMatrix::from_row_slice(
            2,
            2,
            &[
                0.0,
                1.0,
                -(o.k_ground_n_per_m + k2) / m,
                -(o.b_ground_ns_per_m + b2) / m,
            ],
        );
        let b = DMatrix::from_row_slice(2, 3, &[0.0, 0.0, 0.0, k2 / m, b2 / m, 1.0 / m]);
        let d = Foh::new(&a, &b, h_sub)?;
        Ok(Linear {
            phi: std::array::from_fn(|i| std::array::from_fn(|j| d.phi[(i, j)])),
            hold: std::array::from_fn(|i| std::array::from_fn(|j| d.gamma_hold[(i, j)])),
            ramp: std::array::from_fn(|i| std::array::from_fn(|j| d.gamma_ramp[(i, j)])),
        })
    }

    /// End state without friction for tool inputs `u0 → u1` (`[x − L, ẋ]`).
    fn free_response(&self, z: [f64; 2], u0: [f64; 2], u1: [f64; 2]) -> [f64; 2] {
        std::array::from_fn(|i| {
            self.phi[i][0] * z[0]
                + self.phi[i][1] * z[1]
                + (0..2)
                    .map(|j| self.hold[i][j] * u0[j] + self.ramp[i][j] * (u1[j] - u0[j]))
                    .sum::<f64>()
        })
    }

    /// End-state change per newton of friction held over the sub-step.
    fn friction_response(&self) -> [f64; 2] {
        [self.hold[0][2], self.hold[1][2]]
    }
}

/// The simulated sliding flexible object with its sensors.
#[derive(Clone, Debug)]
pub struct SlidingObjectSim {
    config: SimConfig,
    friction: Karnopp,
    contact: Linear,
    free: Linear,
    /// `[x_m, ẋ_m]`.
    z: [f64; 2],
    /// Tool position and velocity at the last sample.
    tool: [f64; 2],
    /// Contact rest offset `L` [m].
    rest_offset_m: f64,
    in_contact: bool,
    sensors: Sensors,
    stats: FrictionStats,
    last_sign: f64,
    /// Sign changes in the current stick episode, `None` outside one.
    episode_changes: Option<u32>,
    phase: Phase,
}

impl SlidingObjectSim {
    /// An object at rest at `x_m = 0`, the tool at `tool_position_m` moving at
    /// `tool_velocity_m_per_s`, not in contact; sensor noise drawn from `rng`.
    pub fn new(
        config: SimConfig,
        tool_position_m: f64,
        tool_velocity_m_per_s: f64,
        rng: Pcg64,
    ) -> Result<SlidingObjectSim, SimError> {
        config.validate()?;
        let h_sub = config.sample_period_s / f64::from(config.substeps);
        Ok(SlidingObjectSim {
            friction: config.friction(),
            contact: Linear::new(&config.object, true, h_sub)?,
            free: Linear::new(&config.object, false, h_sub)?,
            z: [0.0; 2],
            tool: [tool_position_m, tool_velocity_m_per_s],
            rest_offset_m: 0.0,
            in_contact: false,
            sensors: Sensors::new(config.noise, config.sample_period_s, rng),
            stats: FrictionStats::default(),
            last_sign: 0.0,
            episode_changes: None,
            phase: Phase::Stick,
            config,
        })
    }

    /// Advances one sample: the tool moves to `tool_position_m` / `tool_velocity_m_per_s` over
    /// the tick, touching the object if `in_contact`.
    pub fn step(
        &mut self,
        tool_position_m: f64,
        tool_velocity_m_per_s: f64,
        in_contact: bool,
    ) -> SimSample {
        let o = self.config.object;
        let [x0, v0] = self.tool;
        let (x1, v1) = (tool_position_m, tool_velocity_m_per_s);
        if in_contact && !self.in_contact {
            let slip = x0 - self.z[0];
            self.rest_offset_m = if o.k_contact_n_per_m > 0.0 {
                slip + o.b_contact_ns_per_m * (v0 - self.z[1]) / o.k_contact_n_per_m
            } else {
                slip
            };
        }
        self.in_contact = in_contact;
        let lin = if in_contact { self.contact } else { self.free };
        let c = lin.friction_response();
        let h = self.config.sample_period_s;
        let n = self.config.substeps;
        let tool_at = |tau: f64| hermite(x0, v0, x1, v1, h, tau);
        let mut u0 = tool_at(0.0);
        let mut friction_n = 0.0;
        for j in 1..=n {
            let u1 = tool_at(f64::from(j) / f64::from(n));
            let shift = |u: [f64; 2]| [u[0] - self.rest_offset_m, u[1]];
            let free = lin.free_response(self.z, shift(u0), shift(u1));
            let (f, phase) = self.friction.force(self.z[1], free[1], c[1]);
            self.z = [
                free[0] + c[0] * f,
                if phase == Phase::Stick {
                    0.0
                } else {
                    free[1] + c[1] * f
                },
            ];
            self.count(phase);
            friction_n = f;
            u0 = u1;
        }
        self.tool = [x1, v1];
        let (delta, force_n) = if in_contact {
            let delta = x1 - self.rest_offset_m - self.z[0];
            let f_op = o.k_contact_n_per_m * delta + o.b_contact_ns_per_m * (v1 - self.z[1]);
            (delta, force_on_tool(f_op))
        } else {
            (0.0, 0.0)
        };
        let truth = Measurement {
            position_m: x1,
            velocity_m_per_s: v1,
            force_n,
        };
        SimSample {
            measured: self.sensors.measure(truth),
            truth,
            mass_position_m: self.z[0],
            mass_velocity_m_per_s: self.z[1],
            friction_n,
            phase: self.phase,
            in_contact,
            stored_energy_j: 0.5
                * (o.mass_kg * self.z[1] * self.z[1]
                    + o.k_ground_n_per_m * self.z[0] * self.z[0]
                    + o.k_contact_n_per_m * delta * delta),
        }
    }

    /// Friction event counters since construction.
    pub fn friction_stats(&self) -> FrictionStats {
        self.stats
    }

    /// The configuration.
    pub fn config(&self) -> &SimConfig {
        &self.config
    }

    fn count(&mut self, phase: Phase) {
        let stats = &mut self.stats;
        if phase == Phase::Stick && self.phase != Phase::Stick {
            stats.stick_episodes += 1;
            self.episode_changes = Some(0);
        }
        self.phase = phase;
        let v = self.z[1];
        if v.abs() >= self.friction.band_m_per_s {
            self.episode_changes = None;
        }
        if v != 0.0 {
            let s = v.signum();
            if self.last_sign != 0.0 && s != self.last_sign {
                stats.sign_changes += 1;
                if let Some(c) = self.episode_changes.as_mut() {
                    *c += 1;
                    stats.max_sign_changes_per_episode = stats.max_sign_changes_per_episode.max(*c);
                }
            }
            self.last_sign = s;
        }
    }
}

/// Cubic Hermite interpolation of the tool over one tick of length `h`, at `tau` ∈ [0, 1]:
/// `[x(τ), ẋ(τ)]`, matching position and velocity at both ends.
fn hermite(x0: f64, v0: f64, x1: f64, v1: f64, h: f64, tau: f64) -> [f64; 2] {
    let (t2, t3) = (tau * tau, tau * tau * tau);
    let x = (2.0 * t3 - 3.0 * t2 + 1.0) * x0
        + (t3 - 2.0 * t2 + tau) * h * v0
        + (-2.0 * t3 + 3.0 * t2) * x1
        + (t3 - t2) * h * v1;
    let v = (6.0 * t2 - 6.0 * tau) * (x0 - x1) / h
        + (3.0 * t2 - 4.0 * tau + 1.0) * v0
        + (3.0 * t2 - 2.0 * tau) * v1;
    [x, v]
}

#[cfg(test)]
mod tests;
