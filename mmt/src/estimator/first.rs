//! The fast first fit of a Kelvin–Voigt group (issue 13 item 2): least squares on the raw
//! samples since the contact began of the force on the tool, `−(k x + b ẋ)`, published within
//! about 0.1 s of contact, long before the regression filters' onset transient has passed and
//! the RLS's own set is confirmed (about 1 s).
//!
//! A Kelvin–Voigt law holds sample by sample, so it needs no filtered derivatives: the sums of
//! the normal equations grow by one sample per axis and tick (no allocation), and a 2 × 2 solve
//! every back-solve period gives `(k, b)`. A set is published when it is passive, explains the
//! force (its residual), is pinned down by the motion (each term's standard error, as a force,
//! small against the force), has held still since the previous solve, and passes the deflection
//! gate; afterwards only when it has moved. It stops once the RLS confirms a set of the model,
//! and restarts at each contact onset and new-object reset until then. On a re-contact with a
//! confirmed model it checks the object instead of publishing: a first still set far from the
//! confirmed one is a different object at the same place (issue 13 item 4), which starts a new
//! model rendered from that set at once.
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
    /// Contact time before the first solve [s]. Default 0.03: the approach into the surface (the
    /// rise of `x` under a nearly constant `ẋ`) is what separates `k` from `b`, and the gates
    /// (each term's error, the set's stillness) hold a set back until it has. At 0.05 the
    /// operator waited for the normal's set 25 ms longer than for the tangents' first set
    /// (rendering starts once every group has a model): exp 1, seeds 1–5, error from first
    /// contact 4.77–5.06 % at 0.05, 4.40–4.68 % at 0.03, 4.37–4.61 % at 0.02. The cost: a
    /// force lagging the position by 1 ms biases the shorter window's set more (`k` 7.7 % off
    /// at 0.03 against under 5 % at 0.05, in `first::tests`).
    pub min_window_s: f64,
    /// Largest RMS misfit of the force, relative to its RMS. Default 0.15.
    pub max_residual: f64,
    /// Largest standard error of each term's force (`σ_k·x_rms`, `σ_b·ẋ_rms`) relative to the
    /// RMS force. Default 0.05.
    pub max_term_error: f64,
    /// Largest change since the previous solve for a set to be first published, and the change
    /// after which a published set is published again (`k` by a factor of `1 +` this either
    /// way, `b` as a force relative to the RMS force). Default 0.1.
    pub max_change: f64,
    /// On a re-contact with a model that has a confirmed set, the fit checks the object instead
    /// of publishing: its first still set differing from the confirmed one by more than this
    /// (`k` by a factor beyond `1 +` this either way, `b` as a force relative to the RMS force)
    /// is a different object at the same place. The model is then
    /// reset and the fit published at once (issue 13 item 4): a 3 × stiffer contact was
    /// otherwise rendered with the old model, adapting by forgetting, for 1.9 s (measured).
    /// Default 0.3.
    pub new_object_change: f64,
}

impl Default for FirstFitConfig {
    fn default() -> Self {
        FirstFitConfig {
            enabled: true,
            min_window_s: 0.03,
            max_residual: 0.15,
            max_term_error: 0.05,
            max_change: 0.1,
            new_object_change: 0.3,
        }
    }
}

impl FirstFitConfig {
    pub(super) fn validate(&self) -> Result<(), EstimatorError> {
        let w = self.min_window_s;
        if !(w.is_finite() && w >= 0.0) {
            return Err(EstimatorError::Field {
                field: "first_fit.min_window_s",
                value: w,
                expected: "≥ 0 s",
            });
        }
        super::validate::positive(&[
            ("first_fit.max_residual", self.max_residual),
            ("first_fit.max_term_error", self.max_term_error),
            ("first_fit.max_change", self.max_change),
            ("first_fit.new_object_change", self.new_object_change),
        ])
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

/// What a re-contact's (or a reset's) fit does instead of publishing at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Check {
    /// A re-contact with a confirmed model: a differing fit starts a new model.
    Object,
    /// The RLS's detector has just started a new model in contact: a differing fit is published
    /// (the object did change), an agreeing one leaves the last confirmed set rendered.
    AfterReset,
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

impl Sums {
    /// `ẋ_rms / F_rms`: a damping difference as a force relative to the RMS force.
    fn damping_scale(&self) -> f64 {
        (self.vv / self.ff).sqrt()
    }
}

/// One solve: the set and the data's RMS force.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Solve {
    kv: KelvinVoigt,
    residual: f64,
    /// Standard error of each term's force, relative to the RMS force.
    term_error: [f64; 2],
    force_rms_n: f64,
}

/// The running fit of one group.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(super) struct FirstFit {
    sums: Sums,
    since_s: f64,
    next_solve_s: f64,
    previous: Option<KelvinVoigt>,
    published: Option<KelvinVoigt>,
    /// This episode checks the object against a confirmed set rather than publishing.
    check: Option<Check>,
    /// The check has decided (the same object, or a new one declared).
    decided: bool,
}

impl FirstFit {
    /// Starts over at `now_s`: a contact onset, or a new object in contact; `check` when there
    /// is a confirmed set to check the object against.
    pub(super) fn restart(&mut self, now_s: f64, check: Option<Check>) {
        *self = FirstFit {
            since_s: now_s,
            next_solve_s: now_s,
            check,
            ..FirstFit::default()
        };
    }

    /// Whether `a` and `b` differ by more than `limit`: the stiffnesses by a factor beyond
    /// `1 + limit` either way, or the dampings, as a force, by more than `limit` of the RMS force.
    fn differs(&self, a: KelvinVoigt, b: KelvinVoigt, limit: f64) -> bool {
        let dk = (a.k_n_per_m / b.k_n_per_m).ln().abs();
        let db = (a.b_ns_per_m - b.b_ns_per_m).abs() * self.sums.damping_scale();
        dk > limit.ln_1p() || db > limit
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
        let moved = |from: KelvinVoigt| self.differs(solve.kv, from, config.max_change);
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
        };
        (k.is_finite() && b.is_finite()).then_some(solve)
    }
}

impl super::Estimator {
    /// One tick of the first fit, after the RLS's: the samples join the fit while a
    /// Kelvin–Voigt group is in contact and its model has no confirmed set (or, on a re-contact,
    /// until the check has decided); a due solve that passes is this tick's update (unless the
    /// RLS confirmed one this tick), or the check's answer.
    pub(super) fn fit_first(
        &mut self,
        now_s: f64,
        samples: &[super::AxisSample],
        update: &mut super::Update,
    ) {
        let config = self.config.first_fit;
        let check = self.first.check;
        if !config.enabled
            || self.structure != Structure::KelvinVoigt
            || self.phase == super::Phase::Free
            || (check.is_none() && self.confirmed_this_model)
            || self.first.decided
        {
            return;
        }
        if check.is_some() && update.confirmed.is_some() {
            // The RLS confirmed a set on this contact's data: it has answered the check.
            self.first.decided = true;
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
            Ok(g) if let Some(check) = check => self.check_object(now_s, g, check, update),
            Ok(g) => self.publish_first(now_s, g, update),
            Err(Withheld::Gate(_)) => self.stats.first_fit_rejections += 1,
            Err(Withheld::NotExcited | Withheld::Moving) => {}
        }
    }

    /// A re-contact's first still set against the model's confirmed one: the same object ends
    /// the check; a different one starts a new model with this set.
    fn check_object(
        &mut self,
        now_s: f64,
        fitted: Gated,
        check: Check,
        update: &mut super::Update,
    ) {
        self.first.decided = true;
        let confirmed = self.latest.as_ref().and_then(Gated::kelvin_voigt);
        let (Some(fit), Some(old)) = (fitted.kelvin_voigt(), confirmed) else {
            return;
        };
        if !self
            .first
            .differs(fit, old, self.config.first_fit.new_object_change)
        {
            return;
        }
        if check == Check::Object {
            self.start_new_model();
            self.stats.new_objects += 1;
            self.stats.first_fit_new_objects += 1;
            update.new_object = true;
        }
        // The fit goes on publishing for the new model until its RLS set.
        self.first.check = None;
        self.first.decided = false;
        self.publish_first(now_s, fitted, update);
    }

    fn publish_first(&mut self, now_s: f64, g: Gated, update: &mut super::Update) {
        self.stats.first_fits += 1;
        let after = now_s - self.contact_since_s;
        self.stats.first_fit_after_s.get_or_insert(after);
        update.confirmed = Some(g);
    }
}

#[cfg(test)]
mod tests;
