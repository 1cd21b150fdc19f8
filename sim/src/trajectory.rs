//! Scripted tool trajectories: deterministic functions of time that drive the operator's device
//! in experiments and demos (`scripted:NAME`).
//!
//! The named profiles are written in surface coordinates — along the two tangents and the height
//! above the contact surface — and placed onto a scene's surface ([`by_name`]), so the same
//! profile presses into a horizontal table or a vertical wall. Placed at the default surface
//! (the plane z = 0 with normal +z, tangents +x, +y) they are plain world trajectories.

use mmt::contact::SurfaceFrame;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use thiserror::Error;

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
pub const NAMES: [&str; 6] = ["exp1", "exp2", "chirp", "steps", "probe", "hold"];

/// An unknown profile name.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("unknown trajectory {name:?}: expected one of exp1, exp2, chirp, steps, probe, hold")]
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
/// outward `normal`. A zero or non-finite normal falls back to +z.
pub fn by_name(
    name: &str,
    length_s: f64,
    origin_m: [f64; 3],
    normal: [f64; 3],
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

/// Tangential content of a profile.
#[derive(Clone, Debug, PartialEq)]
enum Tangential {
    /// Multisines on t1 and t2.
    Multisine(Multisine, Multisine),
    /// A logarithmic chirp on t2 from `f0` to `f1` [Hz] over the length, amplitude
    /// `a0·(f0/f)^0.5` [m].
    Chirp { f0: f64, f1: f64, a0: f64 },
    /// Smoothed steps of `step_m` on t2 every `period_s`.
    Steps { step_m: f64, period_s: f64 },
    /// Still.
    Still,
}

/// A profile: tangential motion plus a pressing schedule.
#[derive(Clone, Debug, PartialEq)]
struct Profile {
    name: &'static str,
    length_s: f64,
    tangential: Tangential,
    /// `(start, end)` of each contact episode [s].
    windows: Vec<(f64, f64)>,
    /// Mean pressing depth [m] and its slow variation amplitude [m].
    depth_m: (f64, f64),
}

/// Height above the surface between contact episodes [m].
const HOVER_M: f64 = 0.01;
/// Duration of the press-in and lift-off ramps [s].
const RAMP_S: f64 = 0.25;

impl Profile {
    /// The thesis's experiment-1 motion: tangential content up to the 3.6 Hz mode (nine tones on
    /// t2, five smaller ones on t1), pressed about 4 mm in, breaking and re-making contact twice
    /// (episodes `[1, 0.35L]`, `[0.38L, 0.68L]`, `[0.71L, L]`).
    fn exp1(l: f64) -> Profile {
        Profile {
            name: "exp1",
            length_s: l,
            tangential: Tangential::Multisine(
                Multisine::exp1_secondary(),
                Multisine::exp1_tangential(),
            ),
            windows: vec![(1.0, 0.35 * l), (0.38 * l, 0.68 * l), (0.71 * l, l + 1.0)],
            depth_m: (0.004, 0.0008),
        }
    }

    /// Experiment 2: the same excitation in one long contact (identification).
    fn exp2(l: f64) -> Profile {
        Profile {
            name: "exp2",
            windows: vec![(0.5, l + 1.0)],
            ..Profile::exp1(l)
        }
    }

    /// A log chirp 0.1 → 3.6 Hz on t2 in one contact: one tone at a time (§11.9: poorly
    /// identifiable on purpose).
    fn chirp(l: f64) -> Profile {
        Profile {
            name: "chirp",
            tangential: Tangential::Chirp {
                f0: 0.1,
                f1: 3.6,
                a0: 0.02,
            },
            ..Profile::exp2(l)
        }
    }

    /// 1 cm steps on t2 every 2 s in one contact.
    fn steps(l: f64) -> Profile {
        Profile {
            name: "steps",
            tangential: Tangential::Steps {
                step_m: 0.01,
                period_s: 2.0,
            },
            ..Profile::exp2(l)
        }
    }

    /// For stiff surfaces: the exp-1 schedule with a tenth of the tangential motion and 2 mm
    /// pressing.
    fn probe(l: f64) -> Profile {
        Profile {
            name: "probe",
            tangential: Tangential::Multisine(
                Multisine::exp1_secondary().scaled(0.1),
                Multisine::exp1_tangential().scaled(0.1),
            ),
            depth_m: (0.002, 0.0005),
            ..Profile::exp1(l)
        }
    }

    /// Pressed 4 mm in, still.
    fn hold(l: f64) -> Profile {
        Profile {
            name: "hold",
            tangential: Tangential::Still,
            depth_m: (0.004, 0.0),
            ..Profile::exp2(l)
        }
    }

    /// Contact factor in [0, 1] and its derivative: cosine ramps at the ends of each window.
    fn contact(&self, t: f64) -> (f64, f64) {
        let ramp = |tau: f64| -> (f64, f64) {
            if tau <= 0.0 {
                (0.0, 0.0)
            } else if tau >= RAMP_S {
                (1.0, 0.0)
            } else {
                let w = PI / RAMP_S;
                (0.5 - 0.5 * (w * tau).cos(), 0.5 * w * (w * tau).sin())
            }
        };
        for &(a, b) in &self.windows {
            if t >= a && t <= b {
                let (up, dup) = ramp(t - a);
                let (down, ddown) = ramp(b - t);
                return (up * down, dup * down - up * ddown);
            }
        }
        (0.0, 0.0)
    }
}

impl SurfaceProfile for Profile {
    fn name(&self) -> &'static str {
        self.name
    }

    fn length_s(&self) -> f64 {
        self.length_s
    }

    fn local(&self, t: f64) -> ([f64; 3], [f64; 3]) {
        let (t1, t2) = match &self.tangential {
            Tangential::Multisine(a, b) => (a.eval(t), b.eval(t)),
            Tangential::Chirp { f0, f1, a0 } => {
                ((0.0, 0.0), chirp(t, *f0, *f1, *a0, self.length_s))
            }
            Tangential::Steps { step_m, period_s } => ((0.0, 0.0), steps(t, *step_m, *period_s)),
            Tangential::Still => ((0.0, 0.0), (0.0, 0.0)),
        };
        // Pressed height −(d0 + Σ dᵢ sin(2π fᵢ t + φᵢ)): a hand is never steady; three tones
        // (0.23, 1.3, 3.1 Hz at d1, d1/2, d1/4) excite the normal axis's damping as well.
        let (d0, d1) = self.depth_m;
        let (pressed, pressed_rate) = [(0.23, 1.0, 0.0), (1.3, 0.5, 1.0), (3.1, 0.25, 2.0)]
            .iter()
            .fold((-d0, 0.0), |(p, v), &(f, a, phase)| {
                let w = 2.0 * PI * f;
                (
                    p - d1 * a * (w * t + phase).sin(),
                    v - d1 * a * w * (w * t + phase).cos(),
                )
            });
        let (c, dc) = self.contact(t);
        let h = HOVER_M + (pressed - HOVER_M) * c;
        let dh = (pressed - HOVER_M) * dc + c * pressed_rate;
        ([t1.0, t2.0, h], [t1.1, t2.1, dh])
    }
}

/// `a0 (f0/f)^½ sin(φ(t))` with `f(t) = f0 (f1/f0)^(t/L)`; returns position and velocity.
fn chirp(t: f64, f0: f64, f1: f64, a0: f64, l: f64) -> (f64, f64) {
    let k = (f1 / f0).ln() / l;
    let f = f0 * (k * t).exp();
    let phase = 2.0 * PI * f0 * ((k * t).exp() - 1.0) / k;
    let a = a0 * (f0 / f).sqrt();
    let da = -0.5 * k * a;
    (
        a * phase.sin(),
        da * phase.sin() + a * 2.0 * PI * f * phase.cos(),
    )
}

/// Alternating ±`step/2` levels every `period`, each change a 0.1 s cosine ramp.
fn steps(t: f64, step: f64, period: f64) -> (f64, f64) {
    let n = (t / period).floor();
    let level = |k: f64| {
        if (k as i64).rem_euclid(2) == 0 {
            -0.5 * step
        } else {
            0.5 * step
        }
    };
    let tau = t - n * period;
    let ramp = 0.1;
    if tau >= ramp || n < 1.0 {
        return (level(n), 0.0);
    }
    let (from, to) = (level(n - 1.0), level(n));
    let w = PI / ramp;
    let s = 0.5 - 0.5 * (w * tau).cos();
    (
        from + (to - from) * s,
        (to - from) * 0.5 * w * (w * tau).sin(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Velocity is the exact derivative of position (central differences), for every profile.
    #[test]
    fn velocity_is_the_derivative_of_position() {
        for name in NAMES {
            let tr = by_name(name, 20.0, [0.1, -0.2, 0.3], [1.0, 1.0, 0.5]).unwrap();
            for k in 1..4000 {
                let t = k as f64 * 0.005;
                let h = 1e-6;
                let (a, b) = (tr.sample(t - h), tr.sample(t + h));
                let v = tr.sample(t).velocity_m_per_s;
                for (i, vi) in v.iter().enumerate() {
                    let fd = (b.position_m[i] - a.position_m[i]) / (2.0 * h);
                    assert!(
                        (fd - vi).abs() < 1e-5 * (1.0 + vi.abs()),
                        "{name} t={t} axis {i}: {fd} vs {vi}",
                    );
                }
            }
        }
    }

    /// exp1 breaks and re-makes contact at least twice, and presses about 4 mm.
    #[test]
    fn exp1_breaks_and_remakes_contact_twice() {
        let tr = by_name("exp1", 60.0, [0.0; 3], [0.0, 0.0, 1.0]).unwrap();
        let mut onsets = 0;
        let mut was = false;
        let mut deepest = 0.0f64;
        for k in 0..60_000 {
            let z = tr.sample(k as f64 * 1e-3).position_m[2];
            let touching = z < 0.0;
            onsets += usize::from(touching && !was);
            was = touching;
            deepest = deepest.min(z);
        }
        assert_eq!(onsets, 3);
        assert!((-0.0056..-0.0050).contains(&deepest), "{deepest}");
    }

    /// Placed on a tilted surface, the height is measured along its normal.
    #[test]
    fn placement_follows_the_surface() {
        let n = [-1.0, 0.0, 0.0];
        let tr = by_name("hold", 10.0, [0.05, 0.0, 0.0], n).unwrap();
        let p = tr.sample(5.0).position_m;
        assert!((p[0] - 0.054).abs() < 1e-12, "{p:?}"); // 4 mm into a wall facing −x
        assert!(by_name("nope", 10.0, [0.0; 3], n).is_err());
    }

    #[test]
    fn profiles_are_deterministic() {
        let a = by_name("exp1", 30.0, [0.0; 3], [0.0, 0.0, 1.0]).unwrap();
        let b = by_name("exp1", 30.0, [0.0; 3], [0.0, 0.0, 1.0]).unwrap();
        for k in 0..1000 {
            assert_eq!(a.sample(k as f64 * 0.0123), b.sample(k as f64 * 0.0123));
        }
    }
}
