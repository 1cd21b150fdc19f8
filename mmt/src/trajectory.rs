//! Scripted tool trajectories: deterministic functions of time that drive the operator's device
//! in experiments and demos (`scripted:NAME`). The thesis's experiment-1 profile, chirps and steps
//! are added by the experiments work (issue 4); this module fixes the interface.

use serde::{Deserialize, Serialize};

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

    /// Position [m] and velocity [m/s] at `t_s`.
    pub fn eval(&self, t_s: f64) -> (f64, f64) {
        self.tones.iter().fold((0.0, 0.0), |(x, v), &(f, a, p)| {
            let w = 2.0 * std::f64::consts::PI * f;
            let arg = w * t_s + p;
            (x + a * arg.sin(), v + a * w * arg.cos())
        })
    }
}
