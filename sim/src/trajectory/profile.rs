//! The named profiles: a tangential motion plus a pressing schedule, in surface coordinates.

use std::f64::consts::PI;

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

use super::{Multisine, SurfaceProfile};

/// Tangential content of a profile.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Tangential {
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
pub(super) struct Profile {
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
    pub(super) fn exp1(l: f64) -> Profile {
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
    pub(super) fn exp2(l: f64) -> Profile {
        Profile {
            name: "exp2",
            windows: vec![(0.5, l + 1.0)],
            ..Profile::exp1(l)
        }
    }

    /// A log chirp 0.1 → 3.6 Hz on t2 in one contact: one tone at a time (§11.9: poorly
    /// identifiable on purpose).
    pub(super) fn chirp(l: f64) -> Profile {
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
    pub(super) fn steps(l: f64) -> Profile {
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
    pub(super) fn probe(l: f64) -> Profile {
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

    /// Slow probing: the exp-1 contact schedule with slow tangential motion only (0.12 and
    /// 0.3 Hz on t2, 0.2 Hz on t1, 2.5 cm falling to 8 mm): what an operator feeling an object
    /// out does, and poor excitation on purpose — nothing above 0.5 Hz, so the contact element
    /// and the mass are barely visible.
    pub(super) fn slow(l: f64) -> Profile {
        Profile {
            name: "slow",
            tangential: Tangential::Multisine(
                Multisine {
                    tones: vec![(0.2, 0.008, 0.4)],
                },
                Multisine {
                    tones: vec![(0.12, 0.025, 0.0), (0.3, 0.01, 1.3)],
                },
            ),
            ..Profile::exp1(l)
        }
    }

    /// A human-like random motion, drawn from `seed`: on each tangent a sum of 14 tones
    /// log-spaced over 0.08–3 Hz (each frequency jittered by up to ±15 %, amplitude falling as
    /// f^−0.75 from about 2.5 cm on t2 and a third of that on t1, scaled by 0.6–1.4, random
    /// phases), pressed 3–5 mm in with 0.5–1 mm of variation, in contact episodes of 5–14 s
    /// separated by 0.4–1.5 s lifts (the first from 1 s). Same seed, same motion.
    pub(super) fn human(l: f64, seed: u64) -> Profile {
        let mut rng = Pcg64::seed_from_u64(seed ^ 0x68_75_6D_61_6E);
        let tones = |scale: f64, rng: &mut Pcg64| {
            let n = 14;
            let tones = (0..n)
                .map(|k| {
                    let r = k as f64 / (n - 1) as f64;
                    let f = 0.08 * (3.0f64 / 0.08).powf(r) * rng.random_range(0.87..1.15);
                    let a = scale * 0.025 * (f / 0.08).powf(-0.75) * rng.random_range(0.6..1.4);
                    (f, a, rng.random_range(0.0..2.0 * PI))
                })
                .collect();
            Multisine { tones }
        };
        let t1 = tones(1.0 / 3.0, &mut rng);
        let t2 = tones(1.0, &mut rng);
        let mut windows = Vec::new();
        let mut start = 1.0;
        while start < l {
            let end = start + rng.random_range(5.0..14.0);
            if end >= l - 2.0 {
                windows.push((start, l + 1.0));
                break;
            }
            windows.push((start, end));
            start = end + rng.random_range(0.4..1.5);
        }
        Profile {
            name: "human",
            length_s: l,
            tangential: Tangential::Multisine(t1, t2),
            windows,
            depth_m: (
                rng.random_range(0.003..0.005),
                rng.random_range(0.0005..0.001),
            ),
        }
    }

    /// Pressed 4 mm in, still.
    pub(super) fn hold(l: f64) -> Profile {
        Profile {
            name: "hold",
            tangential: Tangential::Still,
            depth_m: (0.004, 0.0),
            ..Profile::exp2(l)
        }
    }

    /// Contact factor in [0, 1] and its derivative: cosine ramps at the ends of each window.
    pub(super) fn contact(&self, t: f64) -> (f64, f64) {
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
