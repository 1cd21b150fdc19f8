//! The simulated world of a scene: the ground truth behind the telerobot's default (simulated)
//! bridge, in three dimensions.
//!
//! The contact surface is the scene's plane (point `p0`, outward normal `n`, tangents `t1`, `t2`
//! from [`SurfaceFrame::from_normal`]). The tool is in contact while it is below the surface,
//! penetration `p = −(x − p0)·n > 0`:
//! - **normal axis**: the object's contact element against the table, Kelvin–Voigt and
//!   unilateral, `F·n = max(0, k2 p + b2 ṗ)` (thesis eq. 8);
//! - **tangential axes**: each a [`SlidingObjectSim`] — the object dragged through its contact
//!   element and sliding on the table with Karnopp friction (thesis set-up 1); for an anchored
//!   object (a wall) a Kelvin–Voigt element anchored where contact began (no preload: the
//!   regression then needs no per-episode constant).
//!
//! The robot tracks the commanded position exactly (the thesis's set-up 1 sends positions "directly
//! to the surface of an in-simulation object"). Every axis's measurement passes through the
//! scene's sensor-noise model; forces are on the tool.

use crate::scene::Scene;
use crate::{Measurement, Sensors, SimConfig, SimError, SlidingObjectSim};
use mmt::contact::SurfaceFrame;
use mmt::model::force_on_tool;
use mmt::vec3;
use node::RobotSample;
use rand::SeedableRng;
use rand_pcg::Pcg64;

/// One sample of the world, world frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WorldSample {
    /// What the robot's sensors read.
    pub measured: RobotSample,
    /// The truth.
    pub truth: RobotSample,
    /// The tool is below the surface.
    pub in_contact: bool,
    /// How far the object has slid along `t1`, `t2` since the start [m].
    pub object_offset_m: [f64; 2],
    /// Contact deflection `δ = x − L − x_m` and mass velocity of each tangential axis (truth).
    pub tangential_state: [(f64, f64); 2],
}

enum Tangential {
    Sliding(Box<SlidingObjectSim>),
    Anchored {
        k: f64,
        b: f64,
        rest_m: f64,
        last: [f64; 2],
        in_contact: bool,
        sensors: Sensors,
    },
}

/// One tangential axis's tick: what [`World::step`] gathers per axis.
struct AxisStep {
    measured: Measurement,
    truth: Measurement,
    /// The object's displacement along the axis \[m\].
    offset_m: f64,
    /// (contact deflection \[m\], object velocity \[m/s\]).
    state: (f64, f64),
}

impl Tangential {
    /// The axis moved to `x` \[m\] at `v` \[m/s\] in the surface frame for one tick.
    fn step(&mut self, x: f64, v: f64, in_contact: bool) -> AxisStep {
        match self {
            Tangential::Sliding(sim) => {
                let s = sim.step(x, v, in_contact);
                // F_op = k2 δ + b2 (ẋ − ẋ_m)  ⇒  δ.
                let o = sim.config().object;
                let delta = if in_contact && o.k_contact_n_per_m > 0.0 {
                    (force_on_tool(s.truth.force_n)
                        - o.b_contact_ns_per_m * (v - s.mass_velocity_m_per_s))
                        / o.k_contact_n_per_m
                } else {
                    0.0
                };
                AxisStep {
                    measured: s.measured,
                    truth: s.truth,
                    offset_m: s.mass_position_m,
                    state: (delta, s.mass_velocity_m_per_s),
                }
            }
            Tangential::Anchored {
                k,
                b,
                rest_m,
                last,
                in_contact: was,
                sensors,
            } => {
                if in_contact && !*was {
                    // Onset: the element is anchored where contact began (its damping force
                    // may jump, as a Kelvin–Voigt contact's does).
                    *rest_m = x;
                }
                *was = in_contact;
                *last = [x, v];
                let f = if in_contact {
                    force_on_tool(*k * (x - *rest_m) + *b * v)
                } else {
                    0.0
                };
                let truth = Measurement {
                    position_m: x,
                    velocity_m_per_s: v,
                    force_n: f,
                };
                AxisStep {
                    measured: sensors.measure(truth),
                    truth,
                    offset_m: 0.0,
                    state: (if in_contact { x - *rest_m } else { 0.0 }, 0.0),
                }
            }
        }
    }
}

/// Integration sub-steps per tick at a loop rate of `control_hz`: the default 10, or more below
/// 1 kHz, so that the integration runs at 10 kHz or faster at every rate a scene allows
/// (`SimConfig::substeps`; a 500 Hz scene used to pass validation and then fail here).
fn substeps(control_hz: f64) -> u32 {
    let needed = (1e4 / control_hz).ceil();
    let default = SimConfig::THESIS_EXP1.substeps;
    if needed > f64::from(default) && needed <= f64::from(u32::MAX) {
        needed as u32
    } else {
        default
    }
}

/// The simulated world.
pub struct World {
    origin: [f64; 3],
    frame: SurfaceFrame,
    k_n: f64,
    b_n: f64,
    tangential: [Tangential; 2],
    normal_sensors: Sensors,
}

impl World {
    /// The world of `scene` with the tool starting at rest at `tool_m`; noise streams seeded
    /// from `seed` (one per axis).
    pub fn new(scene: &Scene, tool_m: [f64; 3], seed: u64) -> Result<World, SimError> {
        let frame = SurfaceFrame::from_normal(scene.surface.normal).ok_or(SimError::Field {
            field: "surface.normal",
            value: f64::NAN,
            expected: "a non-zero normal",
        })?;
        let origin = scene.surface.point_m;
        let env = scene.environment;
        let noise = scene.sensors.noise();
        let period = 1.0 / scene.rates.control_hz;
        let local = to_local(&frame, origin, tool_m);
        let rng =
            |k: u64| Pcg64::seed_from_u64(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(k));
        let axis = |i: usize| -> Result<Tangential, SimError> {
            if env.anchored {
                return Ok(Tangential::Anchored {
                    k: env.k_contact_n_per_m,
                    b: env.b_contact_ns_per_m,
                    rest_m: 0.0,
                    last: [local[i], 0.0],
                    in_contact: false,
                    sensors: Sensors::new(noise, period, rng(i as u64 + 1)),
                });
            }
            let config = SimConfig {
                object: env.physical(),
                static_friction_n: env.static_friction_n,
                stick_band_m_per_s: env.stick_velocity_m_per_s,
                sample_period_s: 1.0 / scene.rates.control_hz,
                substeps: substeps(scene.rates.control_hz),
                noise,
            };
            Ok(Tangential::Sliding(Box::new(SlidingObjectSim::new(
                config,
                local[i],
                0.0,
                rng(i as u64 + 1),
            )?)))
        };
        Ok(World {
            origin,
            frame,
            k_n: env.k_contact_n_per_m,
            b_n: env.b_contact_ns_per_m,
            tangential: [axis(0)?, axis(1)?],
            normal_sensors: Sensors::new(noise, period, rng(0)),
        })
    }

    /// Moves the tool to `position_m` with `velocity_m_per_s` over one tick.
    pub fn step(&mut self, position_m: [f64; 3], velocity_m_per_s: [f64; 3]) -> WorldSample {
        let x = to_local(&self.frame, self.origin, position_m);
        let v = [
            vec3::dot(velocity_m_per_s, self.frame.tangent1),
            vec3::dot(velocity_m_per_s, self.frame.tangent2),
            vec3::dot(velocity_m_per_s, self.frame.normal),
        ];
        let penetration = -x[2];
        let in_contact = penetration > 0.0;
        let f_n = if in_contact {
            (self.k_n * penetration - self.b_n * v[2]).max(0.0)
        } else {
            0.0
        };
        let mut measured_local = [Measurement::default(); 3];
        let mut truth_local = [Measurement::default(); 3];
        let mut out = WorldSample {
            in_contact,
            ..WorldSample::default()
        };
        for (i, axis) in self.tangential.iter_mut().enumerate() {
            let AxisStep {
                measured: m,
                truth: t,
                offset_m: offset,
                state,
            } = axis.step(x[i], v[i], in_contact);
            measured_local[i] = m;
            truth_local[i] = t;
            out.object_offset_m[i] = offset;
            out.tangential_state[i] = state;
        }
        let truth_n = Measurement {
            position_m: x[2],
            velocity_m_per_s: v[2],
            force_n: f_n,
        };
        truth_local[2] = truth_n;
        measured_local[2] = self.normal_sensors.measure(truth_n);
        out.measured = self.to_world(&measured_local);
        out.truth = self.to_world(&truth_local);
        out
    }

    /// The surface frame (normal and tangents).
    pub fn frame(&self) -> &SurfaceFrame {
        &self.frame
    }

    /// The surface point `p0`.
    pub fn origin(&self) -> [f64; 3] {
        self.origin
    }

    fn to_world(&self, local: &[Measurement; 3]) -> RobotSample {
        let axes = [self.frame.tangent1, self.frame.tangent2, self.frame.normal];
        let combine = |get: &dyn Fn(&Measurement) -> f64, offset: [f64; 3]| {
            (0..3).fold(offset, |acc, i| {
                vec3::add(acc, vec3::scale(axes[i], get(&local[i])))
            })
        };
        RobotSample {
            position_m: combine(&|m| m.position_m, self.origin),
            velocity_m_per_s: combine(&|m| m.velocity_m_per_s, [0.0; 3]),
            force_on_tool_n: combine(&|m| m.force_n, [0.0; 3]),
        }
    }
}

/// Position in the surface frame: `[(x − p0)·t1, (x − p0)·t2, (x − p0)·n]`.
pub fn to_local(frame: &SurfaceFrame, origin: [f64; 3], x: [f64; 3]) -> [f64; 3] {
    let d = vec3::sub(x, origin);
    [
        vec3::dot(d, frame.tangent1),
        vec3::dot(d, frame.tangent2),
        vec3::dot(d, frame.normal),
    ]
}
