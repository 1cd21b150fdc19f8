//! The fast first fit of a Kelvin–Voigt group (issue 13 item 2): least squares of the force on
//! the raw samples since the contact began, `F = k x + b ẋ`, published within about 0.1 s of
//! contact, long before the regression filters' onset transient has passed and the RLS's own set
//! is confirmed (about 1 s).
//!
//! A Kelvin–Voigt law holds sample by sample, so it needs no filtered derivatives: the sums of
//! the normal equations grow by one sample per axis and tick (no allocation), and a 2 × 2 solve
//! every back-solve period gives `(k, b)`. A set is published when it is passive, explains the
//! force (its residual), is pinned down by the motion (each term's standard error, as a force,
//! small against the force), has held still since the previous solve, and passes the deflection
//! gate; afterwards only when it has moved. It stops for good once the RLS confirms a set of the
//! model, and restarts at each contact onset and new-object reset until then.
//!
//! It serves Kelvin–Voigt structures only: the tangents of a sliding object are not a spring
//! anchored where the contact began (a fit of `k, b` on exp 1's tangents over the first 0.1 and
//! 0.2 s gave k = −44 and −11 N/m, measured), and stay on the operator's prior until their own
//! model.

use super::EstimatorError;
use crate::model::gates::{GateConfig, GateRejection, Gated, check_deflection, gate_fit};
use crate::model::{KelvinVoigt, Structure};
use serde::{Deserialize, Serialize};

/// Settings of the first fit.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct FirstFitConfig {
    /// Whether a Kelvin–Voigt group publishes a first fit before its RLS set. Default true.
    pub enabled: bool,
    /// Contact time before the first solve [s]. Default 0.05: the approach into the surface (the
    /// rise of `x` under a nearly constant `ẋ`) is what separates `k` from `b`.
    pub min_window_s: f64,
    /// Largest RMS misfit of the force, relative to its RMS. Default 0.15.
    pub max_residual: f64,
    /// Largest standard error of each term's force (`σ_k·x_rms`, `σ_b·ẋ_rms`) relative to the
    /// RMS force. Default 0.05.
    pub max_term_error: f64,
    /// Largest change of `k` (and of `b`'s force) since the previous solve for a set to be
    /// first published, and the change after which a published set is published again. Default
    /// 0.1.
    pub max_change: f64,
}

impl Default for FirstFitConfig {
    fn default() -> Self {
        FirstFitConfig {
            enabled: true,
            min_window_s: 0.05,
            max_residual: 0.15,
            max_term_error: 0.05,
            max_change: 0.1,
        }
    }
}

impl FirstFitConfig {
    pub(super) fn validate(&self) -> Result<(), EstimatorError> {
        let checks = [
            ("first_fit.min_window_s", self.min_window_s, 0.0),
            (
                "first_fit.max_residual",
                self.max_residual,
                f64::MIN_POSITIVE,
            ),
            (
                "first_fit.max_term_error",
                self.max_term_error,
                f64::MIN_POSITIVE,
            ),
            ("first_fit.max_change", self.max_change, f64::MIN_POSITIVE),
        ];
        for (field, value, min) in checks {
            if !(value.is_finite() && value >= min) {
                return Err(EstimatorError::Field {
                    field,
                    value,
                    expected: "a finite number ≥ 0 (> 0 for the thresholds)",
                });
            }
        }
        Ok(())
    }
}

/// Why a solve published nothing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Withheld {
    /// Too few samples, or the motion has not separated `x` from `ẋ`.
    NotExcited,
    /// The set failed a gate.
    Gate(GateRejection),
    /// The set moved since the previous solve (or, once published, has not moved enough to be
    /// sent again).
    Moving,
}

/// The sums of the normal equations of `F = k x + b ẋ` since the fit (re)started.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sums {
    n: f64,
    xx: f64,
    xv: f64,
    vv: f64,
    xf: f64,
    vf: f64,
    ff: f64,
}

/// One solve: the set and the data's RMS force.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Solve {
    kv: KelvinVoigt,
    residual: f64,
    /// Standard error of each term's force, relative to the RMS force.
    term_error: [f64; 2],
    force_rms_n: f64,
    velocity_rms: f64,
}

/// The running fit of one group.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct FirstFit {
    sums: Sums,
    since_s: f64,
    next_solve_s: f64,
    previous: Option<KelvinVoigt>,
    published: Option<KelvinVoigt>,
}

impl FirstFit {
    /// Starts over at `now_s`: a contact onset, or a new object in contact.
    pub(super) fn restart(&mut self, now_s: f64) {
        *self = FirstFit {
            since_s: now_s,
            next_solve_s: now_s,
            ..FirstFit::default()
        };
    }

    /// Adds one axis's sample (position [m], velocity [m/s], tared force on the tool [N]). The
    /// law is the regression's (`DESIGN.md` §4): the force on the tool is `−(k x + b ẋ)`.
    pub(super) fn push(&mut self, x: f64, v: f64, force_on_tool_n: f64) {
        let f = -force_on_tool_n;
        let s = &mut self.sums;
        s.n += 1.0;
        s.xx += x * x;
        s.xv += x * v;
        s.vv += v * v;
        s.xf += x * f;
        s.vf += v * f;
        s.ff += f * f;
    }

    /// Whether a solve is due at `now_s`; schedules the next one `period_s` later.
    pub(super) fn due(&mut self, now_s: f64, config: &FirstFitConfig, period_s: f64) -> bool {
        if now_s - self.since_s < config.min_window_s || now_s < self.next_solve_s {
            return false;
        }
        self.next_solve_s = now_s + period_s;
        true
    }

    /// Solves and gates: the set to publish, or why there is none.
    pub(super) fn solve(
        &mut self,
        config: &FirstFitConfig,
        gates: &GateConfig,
    ) -> Result<Gated, Withheld> {
        let solve = self.least_squares().ok_or(Withheld::NotExcited)?;
        let previous = self.previous.replace(solve.kv);
        let gated = self.gate(&solve, config, gates).map_err(Withheld::Gate)?;
        let moved = |from: KelvinVoigt| {
            let dk = (solve.kv.k_n_per_m - from.k_n_per_m).abs() / solve.kv.k_n_per_m;
            let db = (solve.kv.b_ns_per_m - from.b_ns_per_m).abs() * solve.velocity_rms
                / solve.force_rms_n;
            dk.max(db) > config.max_change
        };
        let publish = match (self.published, previous) {
            (None, Some(p)) => !moved(p),
            (None, None) => false,
            (Some(p), _) => moved(p),
        };
        if !publish {
            return Err(Withheld::Moving);
        }
        self.published = Some(solve.kv);
        Ok(gated)
    }

    fn gate(
        &self,
        solve: &Solve,
        config: &FirstFitConfig,
        gates: &GateConfig,
    ) -> Result<Gated, GateRejection> {
        if !(solve.residual <= config.max_residual) {
            return Err(GateRejection::Residual {
                residual: solve.residual,
                max: config.max_residual,
            });
        }
        let worst = solve.term_error[0].max(solve.term_error[1]);
        if !(worst <= config.max_term_error) {
            let name = if solve.term_error[0] >= solve.term_error[1] {
                "k"
            } else {
                "b"
            };
            return Err(GateRejection::NotIdentified {
                parameter: name,
                spread: worst,
                max: config.max_term_error,
            });
        }
        let gated = gate_fit(Structure::KelvinVoigt, solve.kv, solve.residual)?;
        check_deflection(gated, solve.force_rms_n, gates)
    }

    /// `(k, b)` by least squares with its residual and the terms' standard errors; `None` with
    /// fewer than three samples, no force, or `x` and `ẋ` not yet told apart.
    fn least_squares(&self) -> Option<Solve> {
        let s = &self.sums;
        if s.n < 3.0 || !(s.ff > 0.0) {
            return None;
        }
        let det = s.xx * s.vv - s.xv * s.xv;
        // Correlation² of x and ẋ below 0.999: otherwise the split between k and b is noise.
        if !(det > 1e-3 * s.xx * s.vv) {
            return None;
        }
        let (k, b) = (
            (s.vv * s.xf - s.xv * s.vf) / det,
            (s.xx * s.vf - s.xv * s.xf) / det,
        );
        // Non-negative damping: where the free fit's is negative, the fit with b = 0 (a force that
        // lags the position by τ reads as b = −k·τ: −2 N·s/m on a 2,000 N/m wall at 1 ms,
        // measured on the wall scene's sensors, whose own b is 5 N·s/m).
        let (k, b, ssr, terms) = if b >= 0.0 {
            let ssr = (s.ff - k * s.xf - b * s.vf).max(0.0);
            let sigma2 = ssr / (s.n - 2.0);
            (k, b, ssr, [sigma2 * s.vv / det, sigma2 * s.xx / det])
        } else {
            let k = s.xf / s.xx;
            let ssr = (s.ff - k * s.xf).max(0.0);
            (k, 0.0, ssr, [ssr / (s.n - 1.0) / s.xx, 0.0])
        };
        let (x_rms, v_rms, f_rms) = (
            (s.xx / s.n).sqrt(),
            (s.vv / s.n).sqrt(),
            (s.ff / s.n).sqrt(),
        );
        let term = |variance: f64, rms: f64| variance.sqrt() * rms / f_rms;
        let solve = Solve {
            kv: KelvinVoigt {
                k_n_per_m: k,
                b_ns_per_m: b,
            },
            residual: (ssr / s.ff).sqrt(),
            term_error: [term(terms[0], x_rms), term(terms[1], v_rms)],
            force_rms_n: f_rms,
            velocity_rms: v_rms,
        };
        (k.is_finite() && b.is_finite()).then_some(solve)
    }
}

impl super::Estimator {
    /// One tick of the first fit, after the RLS's: the samples join the fit while a
    /// Kelvin–Voigt group is in contact and its model has no confirmed set; a due solve that
    /// passes is this tick's update (unless the RLS confirmed one this tick).
    pub(super) fn fit_first(
        &mut self,
        now_s: f64,
        samples: &[super::AxisSample],
        update: &mut super::Update,
    ) {
        let config = self.config.first_fit;
        if !config.enabled
            || self.structure != Structure::KelvinVoigt
            || self.phase == super::Phase::Free
            || self.confirmed_this_model
        {
            return;
        }
        for (s, tare) in samples.iter().zip(self.tare) {
            self.first
                .push(s.position_m, s.velocity_m_per_s, s.force_n - tare);
        }
        let period = self.config.back_solve_period_s;
        if update.confirmed.is_some() || !self.first.due(now_s, &config, period) {
            return;
        }
        match self.first.solve(&config, &self.config.gates) {
            Ok(g) => {
                self.stats.first_fits += 1;
                let after = now_s - self.contact_since_s;
                self.stats.first_fit_after_s.get_or_insert(after);
                update.confirmed = Some(g);
            }
            Err(Withheld::Gate(_)) => self.stats.first_fit_rejections += 1,
            Err(Withheld::NotExcited | Withheld::Moving) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{AxisSample, Estimator, EstimatorConfig, EstimatorError};
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use rand_pcg::Pcg64;

    const H: f64 = 1e-3;
    const K: f64 = 800.0;
    const B: f64 = 12.0;

    /// A press into the surface from 0.1 s: an approach to 4 mm depth (a first-order rise,
    /// 30 ms) with a 2 Hz wobble of 0.5 mm; the position is the signed distance (negative inside).
    fn press(t: f64) -> (f64, f64) {
        if t < 0.1 {
            return (0.001, -0.05);
        }
        let (s, w) = (t - 0.1, 2.0 * std::f64::consts::PI * 2.0);
        let x = -0.004 * (1.0 - (-s / 0.03).exp()) - 0.0005 * (w * s).sin();
        let v = -0.004 / 0.03 * (-s / 0.03).exp() - 0.0005 * w * (w * s).cos();
        (x, v)
    }

    /// Runs `seconds` of a press whose force on the tool is `−(k x + b ẋ)` plus `noise_n` of
    /// white noise: every update, with its time.
    fn run(config: EstimatorConfig, k: f64, b: f64, noise_n: f64, seconds: f64) -> Estimator {
        let mut est = Estimator::new(config).unwrap();
        let mut rng = Pcg64::seed_from_u64(3);
        let noise = Normal::new(0.0, noise_n.max(1e-300)).unwrap();
        for i in 0..(seconds / H).round() as usize {
            let t = i as f64 * H;
            let (x, v) = press(t);
            let in_contact = x < 0.0;
            let f = if in_contact { -(k * x + b * v) } else { 0.0 };
            let f = f + if noise_n > 0.0 {
                noise.sample(&mut rng)
            } else {
                0.0
            };
            let s = AxisSample {
                position_m: x,
                velocity_m_per_s: v,
                force_n: f,
            };
            let u = est.step(t, &[s], in_contact);
            if let Some(g) = u.confirmed {
                let kv = g.kelvin_voigt().unwrap();
                FIRST.with(|v| v.borrow_mut().push((t, kv, est.stats())));
            }
        }
        est
    }

    thread_local! {
        static FIRST: std::cell::RefCell<Vec<(f64, KelvinVoigt, super::super::EstimatorStats)>> =
            const { std::cell::RefCell::new(Vec::new()) };
    }

    fn published() -> Vec<(f64, KelvinVoigt, super::super::EstimatorStats)> {
        FIRST.with(|v| std::mem::take(&mut *v.borrow_mut()))
    }

    fn kelvin_voigt() -> EstimatorConfig {
        EstimatorConfig::new(Structure::KelvinVoigt, 1)
    }

    /// Against the exact answer: noise-free data give `k` and `b` to rounding within 0.1 s of
    /// contact; the set is published once (later solves agree), and never after the RLS's own
    /// set is confirmed.
    #[test]
    fn a_pressed_kelvin_voigt_contact_is_published_exactly_within_a_tenth_of_a_second() {
        let est = run(kelvin_voigt(), K, B, 0.0, 3.0);
        let sets = published();
        let (t, kv, stats) = sets[0];
        assert!(t - 0.1 <= 0.1, "first set at {t} s");
        assert_eq!(stats.first_fits, 1);
        assert!((kv.k_n_per_m / K - 1.0).abs() < 1e-9, "{kv:?}");
        assert!((kv.b_ns_per_m / B - 1.0).abs() < 1e-9, "{kv:?}");
        let s = est.stats();
        assert!(s.confirmed > 0, "the RLS confirms later: {s:?}");
        assert_eq!(s.first_fits, 1, "{s:?}");
        // Contact from the first tick inside (0.101 s).
        let after = s.first_fit_after_s.unwrap();
        assert!(
            (after - (t - 0.101)).abs() < 1e-9,
            "{after} after onset, set at {t} s"
        );
        assert!(sets[1..].iter().all(|(_, _, s)| s.first_fits == 1));
    }

    /// With force noise the set waits until the motion pins both terms down, and is then within
    /// a few percent of the truth.
    #[test]
    fn a_noisy_force_publishes_a_set_close_to_the_truth() {
        run(kelvin_voigt(), K, B, 0.05, 1.0);
        let (t, kv, _) = published()[0];
        assert!(t - 0.1 <= 0.15, "first set at {t} s");
        assert!((kv.k_n_per_m / K - 1.0).abs() < 0.03, "{kv:?}");
        assert!((kv.b_ns_per_m / B - 1.0).abs() < 0.15, "{kv:?}");
    }

    /// No set from data that cannot give one: an active law (a pull, `k < 0`), a still hold
    /// (no `ẋ` to tell `b` from `k`), pure noise, or a sliding object's structure.
    #[test]
    fn an_active_law_a_still_hold_noise_or_a_sliding_object_publish_no_first_fit() {
        let pull = run(kelvin_voigt(), -K, B, 0.0, 0.3);
        assert_eq!(pull.stats().first_fits, 0);
        assert!(pull.stats().first_fit_rejections > 0);
        let noise = run(kelvin_voigt(), 0.0, 0.0, 0.5, 0.3);
        assert_eq!(noise.stats().first_fits, 0);
        let sliding = Structure::SlidingMass {
            ground_spring: false,
            friction: true,
        };
        let slide = run(EstimatorConfig::new(sliding, 1), K, B, 0.0, 0.3);
        assert_eq!(slide.stats().first_fits, 0);
        published();
        let mut fit = FirstFit::default();
        fit.restart(0.0);
        for _ in 0..100 {
            fit.push(-0.004, 0.0, 3.2);
        }
        let config = FirstFitConfig::default();
        let solved = fit.solve(&config, &GateConfig::default());
        assert_eq!(solved, Err(Withheld::NotExcited));
        let mut off = kelvin_voigt();
        off.first_fit.enabled = false;
        assert_eq!(run(off, K, B, 0.0, 0.3).stats().first_fits, 0);
    }

    /// A stiff, barely damped contact whose force lags the position by 1 ms (a sensor's delay):
    /// the free fit's damping is `b − k·τ` < 0; the set published holds b at 0 and keeps k.
    #[test]
    fn a_lagging_force_on_a_stiff_contact_gives_no_damping_not_negative_damping() {
        let (k, b, lag) = (2_000.0, 0.5, 1e-3);
        let mut fit = FirstFit::default();
        fit.restart(0.0);
        let mut t = 0.1;
        while t < 0.2 {
            let (x, v) = press(t);
            let (xl, vl) = press(t - lag);
            fit.push(x, v, -(k * xl + b * vl));
            t += H;
        }
        let free = fit.sums;
        let det = free.xx * free.vv - free.xv * free.xv;
        assert!(
            (free.xx * free.vf - free.xv * free.xf) / det < 0.0,
            "the free fit's b"
        );
        let config = FirstFitConfig::default();
        let gates = GateConfig::default();
        // The first solve only primes the check of stillness.
        assert_eq!(fit.solve(&config, &gates), Err(Withheld::Moving));
        let kv = fit.solve(&config, &gates).unwrap().kelvin_voigt().unwrap();
        assert_eq!(kv.b_ns_per_m, 0.0);
        assert!((kv.k_n_per_m / k - 1.0).abs() < 0.02, "{kv:?}");
    }

    #[test]
    fn a_bad_threshold_is_named() {
        let mut c = kelvin_voigt();
        c.first_fit.max_residual = f64::NAN;
        match Estimator::new(c) {
            Err(EstimatorError::Field { field, .. }) => assert_eq!(field, "first_fit.max_residual"),
            other => panic!("{other:?}"),
        }
        c.first_fit.max_residual = 0.15;
        c.first_fit.min_window_s = -1.0;
        assert!(Estimator::new(c).is_err());
    }
}
