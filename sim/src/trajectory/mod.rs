//! Scripted tool trajectories: deterministic functions of time that drive the operator's device
//! in experiments and demos (`scripted:NAME`).
//!
//! The named profiles are written in surface coordinates — along the two tangents and the height
//! above the contact surface — and placed onto a scene's surface ([`by_name`]), so the same
//! profile presses into a horizontal table or a vertical wall. Placed at the default surface
//! (the plane z = 0 with normal +z, tangents +x, +y) they are plain world trajectories.

use mmt::contact::SurfaceFrame;
use serde::{Deserialize, Serialize};
use thiserror::Error;

mod profile;
use profile::Profile;

/// Position and velocity of the tool at one instant, in world coordinates [m], [m/s].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TrajectorySample {
    /// Position [m].
    pub position_m: [f64; 3],
    /// Velocity [m/s] (the exact derivative of `position_m`).
    pub velocity_m_per_s: [f64; 3],
}

/// A deterministic tool trajectory. Pure: the same `t_s` always gives the same sample.
pub trait Trajectory: Send + Sync {
    /// Short name, as used in `scripted:NAME`.
    fn name(&self) -> &str;
    /// Sample at time `t_s` [s] from the start of the run. Defined for every finite `t_s`
    /// (before 0 it holds the start, after the end it holds the end).
    fn sample(&self, t_s: f64) -> TrajectorySample;
    /// Natural length of the script [s], if it has one.
    fn duration_s(&self) -> Option<f64>;
}

/// Holds one position forever.
#[derive(Clone, Debug)]
pub struct Hold {
    /// The position held [m].
    pub position_m: [f64; 3],
}

impl Trajectory for Hold {
    fn name(&self) -> &str {
        "hold"
    }
    fn sample(&self, _t_s: f64) -> TrajectorySample {
        TrajectorySample {
            position_m: self.position_m,
            velocity_m_per_s: [0.0; 3],
        }
    }
    fn duration_s(&self) -> Option<f64> {
        None
    }
}

/// A sum of sines on one axis, around an offset: `offset + Σ Aᵢ sin(2π fᵢ t + φᵢ)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Multisine {
    /// `(frequency [Hz], amplitude [m], phase [rad])` of each tone.
    pub tones: Vec<(f64, f64, f64)>,
}

impl Multisine {
    /// The tangential excitation of the thesis's experiment 1, made identifiable (`DESIGN.md`
    /// §11.9: several tones at once above 0.5 Hz): nine tones from 0.1 to 3.6 Hz (the object's
    /// highest mode), amplitudes falling log-linearly from 3 cm to 2 mm, Schroeder phases for a
    /// low crest factor. Peak ±7.5 cm or so; in contact the force is about 3 N RMS (feasibility
    /// notes).
    pub fn exp1_tangential() -> Multisine {
        let freqs = [0.1, 0.2, 0.35, 0.6, 0.9, 1.4, 2.0, 2.8, 3.6];
        let n = freqs.len() as f64;
        let (a0, a1) = (0.03f64, 0.002f64);
        let tones = freqs
            .iter()
            .enumerate()
            .map(|(k, &f)| {
                let frac = k as f64 / (n - 1.0);
                let amp = (a0.ln() + frac * (a1.ln() - a0.ln())).exp();
                let phase = -std::f64::consts::PI * (k as f64) * (k as f64 + 1.0) / n;
                (f, amp, phase)
            })
            .collect();
        Multisine { tones }
    }

    /// The second tangential axis of experiment 1: five smaller tones (8 mm falling to 1 mm,
    /// 0.15–3.3 Hz), so both tangents are excited.
    pub fn exp1_secondary() -> Multisine {
        let freqs = [0.15, 0.5, 1.1, 2.3, 3.3];
        let amps = [0.008, 0.005, 0.003, 0.0015, 0.001];
        let tones = freqs
            .iter()
            .zip(amps)
            .enumerate()
            .map(|(k, (&f, a))| (f, a, 1.0 + 0.9 * k as f64))
            .collect();
        Multisine { tones }
    }

    /// Every amplitude times `factor`.
    pub fn scaled(mut self, factor: f64) -> Multisine {
        for t in &mut self.tones {
            t.1 *= factor;
        }
        self
    }

    /// Position [m] and velocity [m/s] at `t_s`.
    pub fn eval(&self, t_s: f64) -> (f64, f64) {
        self.tones.iter().fold((0.0, 0.0), |(x, v), &(f, a, p)| {
            let w = 2.0 * std::f64::consts::PI * f;
            let arg = w * t_s + p;
            (x + a * arg.sin(), v + a * w * arg.cos())
        })
    }
}

/// A trajectory in surface coordinates: `[along t1, along t2, height above the surface]` [m].
pub trait SurfaceProfile: Send + Sync {
    /// Name.
    fn name(&self) -> &'static str;
    /// Position and velocity in surface coordinates at `t_s`.
    fn local(&self, t_s: f64) -> ([f64; 3], [f64; 3]);
    /// The nominal length [s].
    fn length_s(&self) -> f64;
}

/// The profiles [`by_name`] knows.
pub const NAMES: [&str; 8] = [
    "exp1", "exp2", "chirp", "steps", "probe", "slow", "human", "hold",
];

/// An unknown profile name.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error(
    "unknown trajectory {name:?}: expected one of exp1, exp2, chirp, steps, probe, slow, human, hold"
)]
pub struct UnknownTrajectory {
    /// The name asked for.
    pub name: String,
}

/// A profile placed on a surface (point, outward normal) as a world trajectory.
pub struct Placed {
    profile: Box<dyn SurfaceProfile>,
    origin: [f64; 3],
    axes: [[f64; 3]; 3],
}

impl Trajectory for Placed {
    fn name(&self) -> &str {
        self.profile.name()
    }
    fn sample(&self, t_s: f64) -> TrajectorySample {
        let t = if t_s.is_finite() { t_s.max(0.0) } else { 0.0 };
        let (p, v) = self.profile.local(t);
        let map = |c: [f64; 3], offset: [f64; 3]| {
            std::array::from_fn(|k| offset[k] + (0..3).map(|i| self.axes[i][k] * c[i]).sum::<f64>())
        };
        TrajectorySample {
            position_m: map(p, self.origin),
            velocity_m_per_s: map(v, [0.0; 3]),
        }
    }
    fn duration_s(&self) -> Option<f64> {
        Some(self.profile.length_s())
    }
}

/// The named profile of nominal length `length_s`, placed on the surface through `origin_m` with
/// outward `normal`. A zero or non-finite normal falls back to +z. The random profile (`human`)
/// is drawn from seed 1; [`by_name_seeded`] chooses the seed.
pub fn by_name(
    name: &str,
    length_s: f64,
    origin_m: [f64; 3],
    normal: [f64; 3],
) -> Result<Placed, UnknownTrajectory> {
    by_name_seeded(name, length_s, origin_m, normal, 1)
}

/// [`by_name`] with the seed of the random profile (`human`); the other profiles ignore it.
pub fn by_name_seeded(
    name: &str,
    length_s: f64,
    origin_m: [f64; 3],
    normal: [f64; 3],
    seed: u64,
) -> Result<Placed, UnknownTrajectory> {
    let length_s = if length_s.is_finite() && length_s > 2.0 {
        length_s
    } else {
        60.0
    };
    let profile: Box<dyn SurfaceProfile> = match name {
        "exp1" => Box::new(Profile::exp1(length_s)),
        "exp2" => Box::new(Profile::exp2(length_s)),
        "chirp" => Box::new(Profile::chirp(length_s)),
        "steps" => Box::new(Profile::steps(length_s)),
        "probe" => Box::new(Profile::probe(length_s)),
        "slow" => Box::new(Profile::slow(length_s)),
        "human" => Box::new(Profile::human(length_s, seed)),
        "hold" => Box::new(Profile::hold(length_s)),
        _ => {
            return Err(UnknownTrajectory {
                name: name.to_string(),
            });
        }
    };
    let frame = SurfaceFrame::from_normal(normal)
        .or_else(|| SurfaceFrame::from_normal([0.0, 0.0, 1.0]))
        .map(|f| [f.tangent1, f.tangent2, f.normal])
        .unwrap_or([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
    Ok(Placed {
        profile,
        origin: origin_m,
        axes: frame,
    })
}

#[cfg(test)]
mod tests;
