//! The sliding-mass model simulated along a window of the tool's motion, and the smoothing of
//! the tool velocity it is simulated along.

use super::{ONSET, Sample, Vector};
use crate::model::Physical;

/// The model simulated along a window, and its misfit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Model {
    pub(super) p: Physical,
    /// Each axis's contact force (on the object) at the window's first sample \[N\].
    onset_n: [f64; 2],
    dt: f64,
}

impl Model {
    /// The model of `theta`; `massless` leaves the mass out (`m = 0`, whatever `theta` holds).
    pub(super) fn new(theta: &Vector, friction: bool, massless: bool, dt: f64) -> Model {
        let e = |i: usize| theta[i].exp();
        Model {
            p: Physical {
                mass_kg: if massless { 0.0 } else { e(0) },
                k_ground_n_per_m: 0.0,
                b_ground_ns_per_m: e(1),
                k_contact_n_per_m: e(2),
                b_contact_ns_per_m: e(3),
                coulomb_n: if friction { e(4) } else { 0.0 },
            },
            onset_n: [theta[ONSET], theta[ONSET + 1]],
            dt,
        }
    }

    /// The force on the tool along axis `a`'s samples, from an object at rest at the first,
    /// its contact loaded by that axis's onset force; each residual (measured − model) goes to
    /// `out`.
    ///
    /// The onset force is fitted, not taken as 0: the window opens on the telerobot's contact
    /// flag, which a point cloud's noise sets a few ticks before or after the touch (2 ms
    /// early on exp 1's 0.5 mm cloud), and a simulator or an arm reports the first contact
    /// sample a tick after the touch. On exp 1 with clean sensors (seeds 1–2), fitting it cut
    /// the misfit of the first 0.1 s window to a half and to a third.
    pub(super) fn residuals(
        &self,
        a: usize,
        axis: impl Iterator<Item = Sample>,
        out: &mut impl FnMut(f64),
    ) {
        let Physical {
            mass_kg: m,
            b_ground_ns_per_m: b1,
            k_contact_n_per_m: k2,
            b_contact_ns_per_m: b2,
            coulomb_n: fc,
            ..
        } = self.p;
        let dt = self.dt;
        // Backward Euler's constants: a division per sample was a third of a simulation's cost.
        let m_dt = m / dt;
        let inv = 1.0 / (m_dt + b1 + b2 + k2 * dt);
        let (mut xm, mut vm) = (0.0_f64, 0.0_f64);
        let mut rest = None;
        for [x, v, f] in axis {
            let l = *rest.get_or_insert(x + (b2 * v - self.onset_n[a]) / k2);
            let drive = k2 * (x - l - xm) + b2 * v;
            let stuck = vm == 0.0 && drive.abs() <= fc;
            if !stuck {
                let dir = if vm != 0.0 {
                    vm.signum()
                } else {
                    drive.signum()
                };
                let fr = fc * dir;
                // Backward Euler of m v̇ = k2 (x − L − xm) + b2 (ẋ − v) − b1 v − Fc sgn v.
                let next = (m_dt * vm + drive - fr) * inv;
                vm = if next * dir < 0.0 { 0.0 } else { next };
                xm += vm * dt;
            }
            let model = -(k2 * (x - l - xm) + b2 * (v - vm));
            out(f - model);
        }
    }
}

/// `raw` into `out` with each velocity replaced by a quadratic Savitzky–Golay smoothing over
/// `half` samples either side (fewer near the ends, symmetric; the first and last are kept).
/// `out` may hold this smoothing of a prefix of `raw` (the window of the last solve, with the
/// same `half`): the samples more than `half` before its end keep their windows and are not
/// computed again, so a growing window costs its new samples only.
///
/// The fit simulates the model along the measured tool motion, so the velocity's noise is an
/// error in its input, which a least-squares fit pays for by lowering `b2` (the noise's share
/// of the force) and moving `m` and `k2` to make up. On exp 1 with the Franka-like 1 mm/s:
/// `m` 4.1 for 1 kg, `k2` 300 for 500 N/m, `b2` 39 for 60. The window is frozen when a solve
/// starts, so the smoothing can look ahead: over ±20 ms it cuts white noise to 0.23 of it,
/// keeps a quadratic exactly, and is 0.06 % off at 5 Hz, 0.9 % at 10 Hz, 12 % at 20 Hz.
pub(super) fn smooth_velocity(raw: &[Sample], half: usize, out: &mut Vec<Sample>) {
    let n = raw.len();
    let from = out.len().min(n).saturating_sub(half);
    out.truncate(from);
    for i in from..n {
        let h = half.min(i).min(n - 1 - i);
        let hf = h as f64;
        let a = 3.0 * (3.0 * hf * hf + 3.0 * hf - 1.0);
        let denominator = (2.0 * hf - 1.0) * (2.0 * hf + 1.0) * (2.0 * hf + 3.0);
        let v: f64 = (i - h..=i + h)
            .map(|j| {
                let k = j as f64 - i as f64;
                (a - 15.0 * k * k) / denominator * raw[j][1]
            })
            .sum();
        out.push([raw[i][0], v, raw[i][2]]);
    }
}
