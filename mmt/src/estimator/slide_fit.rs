//! The first fit of a sliding object's tangents (issue 13 item 2): an output-error fit of the
//! sliding-mass model on the raw samples of the model's first contact, published within a few
//! hundredths of a second of it (its contact element) and a few tenths (every term), long
//! before the RLS's set (about 1 s on exp 1).
//!
//! A sliding object is not a law that holds sample by sample (its mass and friction carry a
//! state), and the RLS needs filtered derivatives whose onset transient it must wait out. But at
//! the first contact of a model the object's state is known: it is at rest. So the model can be
//! simulated from the window's first sample along the measured tool motion and its parameters
//! fitted to the measured force directly (Levenberg–Marquardt in the logs of `m, b1, k2, b2`
//! and `Fc`, forward-difference Jacobian, backward Euler, Coulomb friction with sticking). The
//! contact's force at that first sample is fitted too, per axis: the window opens on the
//! telerobot's contact flag, which is not the touch to the tick ([`model`]). The tool velocity
//! the model is simulated along is smoothed first ([`SlideFitConfig::velocity_smoothing_s`]):
//! its noise is an error in the simulation's input. The equations are the renderer's (which
//! integrates them by SDIRK2, not backward Euler: the fit's numerical damping differs slightly
//! on a stiff, light object).
//!
//! Two stages:
//! - from [`SlideFitConfig::contact_fit_s`] (20 ms) the contact element alone: `k2` and `b2` of
//!   the massless model, `b1` and `Fc` held at the soft-object class's centre. The object has
//!   barely moved yet, so the force is the contact element's. Its set is a reduced model
//!   ([`Gated::is_reduced`]): the operator replays the episode when every term's set follows;
//! - from [`SlideFitConfig::min_window_s`] (0.1 s) every term.
//!
//! It runs one Levenberg–Marquardt iteration per tick (each simulates the window once per
//! fitted parameter plus once more; see `cargo bench -p lab --bench estimator`), on a window
//! frozen when the solve starts; a solve starts every [`SlideFitConfig::contact_period_s`] in
//! the first stage and every [`SlideFitConfig::period_s`] in the second, until the window
//! reaches [`SlideFitConfig::max_window_s`] or the contact ends.
//! A converged set is published when it explains the force ([`SlideFitConfig::max_residual`]),
//! each parameter is pinned down by the data ([`SlideFitConfig::max_relative_error`], from the
//! Jacobian's covariance) and it passes the physical and deflection gates; afterwards again when
//! it has moved. Once a set of every term has published, the RLS's reduced (massless) set no
//! longer replaces it. It stops once the RLS confirms a set of the model.
//!
//! Left out: a structure with a ground spring (its rest position is not known at the onset),
//! and every later contact (the object may still be sliding when it begins; under
//! `ResetPolicy::EveryOnset` too, though each contact starts a model).

use nalgebra::{SMatrix, SVector};

mod config;
mod model;
use crate::model::backsolve::Params;
use crate::model::gates::{
    GateConfig, GateRejection, Gated, check_deflection, gate_fitted, gate_fitted_massless,
};
use crate::model::{Physical, Structure};
pub use config::SlideFitConfig;
use model::{Model, smooth_velocity};

/// Parameters fitted: `ln m, ln b1, ln k2, ln b2, ln Fc` (the last only with friction), then
/// each axis's contact force at the window's first sample \[N\] (a nuisance: see
/// [`Model::residuals`]).
const P: usize = 7;
/// Index of the first axis's onset force in the parameters.
const ONSET: usize = 5;
/// Indices of `ln k2` and `ln b2`: the contact element, all a solve of it fits.
const K2: usize = 2;
const B2: usize = 3;
type Vector = SVector<f64, P>;
type Matrix = SMatrix<f64, P, P>;

/// One axis's raw sample: tool position \[m\], velocity \[m/s\], tared force on the tool \[N\].
type Sample = [f64; 3];

/// A Levenberg–Marquardt solve in progress.
#[derive(Clone, Debug, PartialEq)]
struct Solve {
    theta: Vector,
    cost: f64,
    lambda: f64,
    iterations: u32,
    /// Samples per axis in the window.
    n: usize,
    /// The last accepted step gained less than [`CONVERGED_GAIN`] of the cost or moved less than
    /// [`CONVERGED_STEP`].
    converged: bool,
}

const MAX_ITERATIONS: u32 = 40;
/// An accepted step that lowers the cost by less than this fraction ends the solve, converged.
const CONVERGED_GAIN: f64 = 1e-6;
/// An accepted step that moves no parameter by more than this (in the log: a relative change)
/// ends the solve, converged.
const CONVERGED_STEP: f64 = 1e-6;
const FD_STEP: f64 = 1e-4;

/// The running fit of one group's first contact.
#[derive(Clone, Debug, Default)]
pub(super) struct SlideFit {
    /// The first contact's samples, per axis (`[axis][tick]`); capacity reserved up front.
    samples: [Vec<Sample>; 2],
    /// The window of the solve in progress: the samples with the tool's velocity smoothed
    /// ([`smooth_velocity`], extended at each solve's start).
    window: [Vec<Sample>; 2],
    axes: usize,
    /// Collecting this contact (the model's first, of a sliding structure without `k1`).
    active: bool,
    friction: bool,
    /// The solve in progress (or the last) fits the contact element alone.
    partial: bool,
    since_s: f64,
    next_start_s: f64,
    solve: Option<Solve>,
    /// The Jacobian of the solve's last iteration, `[sample][parameter]`.
    jacobian: Vec<[f64; P]>,
    residual: Vec<f64>,
    /// Where the last solve converged (its start for the next).
    last: Option<Vector>,
    published: Option<Physical>,
}

/// What a tick of the fit produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Outcome {
    /// Nothing yet.
    Working,
    /// A converged set passed every gate.
    Publish(Gated),
    /// A converged set failed a gate.
    Rejected(GateRejection),
    /// The solve ended without converging (its iterations, its damping, or a cost that is not
    /// finite): nothing is gated.
    NotConverged,
}

impl SlideFit {
    /// A fit for `axes` axes sampled every `dt` \[s\], its memory reserved for `config`'s window.
    pub(super) fn new(config: &SlideFitConfig, axes: usize, dt: f64) -> SlideFit {
        let cap = window_samples(config, dt);
        SlideFit {
            samples: [Vec::with_capacity(cap), Vec::with_capacity(cap)],
            window: [Vec::with_capacity(cap), Vec::with_capacity(cap)],
            axes: axes.min(2),
            jacobian: Vec::with_capacity(2 * cap),
            residual: Vec::with_capacity(2 * cap),
            ..SlideFit::default()
        }
    }

    /// A contact begins at `now_s`. `first`: it is the model's first, the object at rest, and
    /// the structure one this fit serves (`friction` when it has Coulomb friction).
    pub(super) fn restart(&mut self, now_s: f64, first: bool, friction: bool) {
        for s in self.samples.iter_mut().chain(&mut self.window) {
            s.clear();
        }
        self.active = first;
        self.friction = friction;
        self.partial = false;
        self.since_s = now_s;
        self.next_start_s = now_s;
        self.solve = None;
        self.last = None;
        self.published = None;
        self.residual.clear();
        self.jacobian.clear();
    }

    /// Ends this contact's fit (its end, a gap, a confirmed RLS set, a new object).
    pub(super) fn stop(&mut self) {
        self.active = false;
        self.solve = None;
    }

    /// One tick in contact at `now_s`: each axis's `[x, ẋ, tared F]` joins the window while it
    /// is not full; a due solve starts, or the one in progress makes one iteration.
    pub(super) fn step(
        &mut self,
        now_s: f64,
        axes: &[Sample],
        config: &SlideFitConfig,
        gates: &GateConfig,
        dt: f64,
    ) -> Outcome {
        if !self.active || axes.len() < self.axes {
            return Outcome::Working;
        }
        let n = self.samples[0].len();
        if n < window_samples(config, dt) {
            for (window, s) in self.samples.iter_mut().zip(axes).take(self.axes) {
                window.push(*s);
            }
        }
        let Some(solve) = self.solve.take() else {
            self.start(now_s, config, dt);
            return Outcome::Working;
        };
        match self.iterate(solve, dt) {
            Ok(solve) => {
                self.solve = Some(solve);
                Outcome::Working
            }
            Err(done) => self.finish(&done, config, gates, dt),
        }
    }

    /// Starts a solve when one is due and the window has grown since the last.
    fn start(&mut self, now_s: f64, config: &SlideFitConfig, dt: f64) {
        let n = self.samples[0].len();
        let elapsed = now_s - self.since_s + 0.5 * dt;
        let partial = elapsed < config.min_window_s;
        let first = if partial {
            config.contact_fit_s
        } else {
            config.min_window_s
        };
        let due = elapsed >= first && now_s >= self.next_start_s && self.last_n() < n;
        if !due {
            return;
        }
        self.partial = partial;
        self.next_start_s = now_s
            + if partial {
                config.contact_period_s
            } else {
                config.period_s
            };
        let half = (config.velocity_smoothing_s / dt).round() as usize;
        for (raw, window) in self.samples.iter().zip(&mut self.window).take(self.axes) {
            smooth_velocity(&raw[..n], half, window);
        }
        let theta = self.last.unwrap_or_else(start_point);
        let cost = self.cost(&theta, n, dt);
        self.solve = Some(Solve {
            theta,
            cost,
            lambda: 1e-2,
            iterations: 0,
            n,
            converged: false,
        });
    }

    /// Samples per axis the last finished solve used (0 before one).
    fn last_n(&self) -> usize {
        self.residual.len() / self.axes.max(1)
    }

    fn model(&self, theta: &Vector, dt: f64) -> Model {
        Model::new(theta, self.friction, self.partial, dt)
    }

    /// The physical terms fitted: `m, b1, k2, b2`, and `Fc` with friction.
    fn fitted(&self) -> usize {
        if self.friction { ONSET } else { ONSET - 1 }
    }

    /// Whether parameter `j` is fitted: a physical term (only `k2` and `b2` in a solve of the
    /// contact element), or an axis's onset force.
    fn is_fitted(&self, j: usize) -> bool {
        let physical = if self.partial {
            j == K2 || j == B2
        } else {
            j < self.fitted()
        };
        physical || (ONSET..ONSET + self.axes).contains(&j)
    }

    /// The sum of squared residuals over the first `n` samples of each axis (∞ when not finite).
    fn cost(&self, theta: &Vector, n: usize, dt: f64) -> f64 {
        let model = self.model(theta, dt);
        let mut ssr = 0.0;
        for (a, window) in self.window.iter().take(self.axes).enumerate() {
            model.residuals(a, window[..n].iter().copied(), &mut |r| ssr += r * r);
        }
        if ssr.is_finite() { ssr } else { f64::INFINITY }
    }

    /// The residuals and the forward-difference Jacobian at `theta` into the buffers.
    fn linearise(&mut self, theta: &Vector, n: usize, dt: f64) {
        self.residual.clear();
        self.jacobian.clear();
        let model = self.model(theta, dt);
        for (a, window) in self.window.iter().take(self.axes).enumerate() {
            let residual = &mut self.residual;
            model.residuals(a, window[..n].iter().copied(), &mut |r| residual.push(r));
        }
        self.jacobian.resize(self.residual.len(), [0.0; P]);
        for j in 0..P {
            if !self.is_fitted(j) {
                continue;
            }
            let mut moved = *theta;
            moved[j] += FD_STEP;
            let model = self.model(&moved, dt);
            for (a, window) in self.window.iter().take(self.axes).enumerate() {
                // An axis's onset force moves only that axis's residuals.
                if j >= ONSET && j != ONSET + a {
                    continue;
                }
                let (jacobian, base) = (&mut self.jacobian, &self.residual);
                let mut i = a * n;
                model.residuals(a, window[..n].iter().copied(), &mut |r| {
                    jacobian[i][j] = (r - base[i]) / FD_STEP;
                    i += 1;
                });
            }
        }
    }

    /// `JᵀJ` and `Jᵀr` of the buffers; the parameters not fitted get an identity row.
    fn normal_equations(&self) -> (Matrix, Vector) {
        // The upper triangle, row by row, without temporaries (a 7 × 7 outer product per sample
        // made this most of an iteration's cost).
        let (mut upper, mut g) = ([[0.0; P]; P], Vector::zeros());
        for (row, r) in self.jacobian.iter().zip(&self.residual) {
            for (i, &ri) in row.iter().enumerate() {
                if ri == 0.0 {
                    continue;
                }
                g[i] += ri * r;
                for (u, &rj) in upper[i][i..].iter_mut().zip(&row[i..]) {
                    *u += ri * rj;
                }
            }
        }
        let mut a = Matrix::from_fn(|i, j| upper[i.min(j)][i.max(j)]);
        for j in (0..P).filter(|&j| !self.is_fitted(j)) {
            a[(j, j)] = 1.0;
            g[j] = 0.0;
        }
        (a, g)
    }

    /// One Levenberg–Marquardt iteration: `Ok` to go on, `Err` when the solve is done.
    fn iterate(&mut self, mut s: Solve, dt: f64) -> Result<Solve, Solve> {
        if !s.cost.is_finite() || s.iterations >= MAX_ITERATIONS || s.lambda > 1e8 {
            return Err(s);
        }
        s.iterations += 1;
        self.linearise(&s.theta, s.n, dt);
        let (a, g) = self.normal_equations();
        let mut damped = a;
        for j in 0..P {
            damped[(j, j)] += s.lambda * a[(j, j)].max(1e-12);
        }
        let Some(step) = damped.cholesky().map(|c| c.solve(&(-g))) else {
            s.lambda *= 4.0;
            return Ok(s);
        };
        // At most a factor e² per physical term and iteration: a long step into a region where
        // the simulation sticks throughout has no gradient to come back by.
        let mut step = step;
        for d in step.iter_mut().take(ONSET) {
            *d = d.clamp(-2.0, 2.0);
        }
        let theta = s.theta + step;
        let cost = self.cost(&theta, s.n, dt);
        if cost < s.cost {
            let gain = (s.cost - cost) / s.cost;
            s.theta = theta;
            s.cost = cost;
            s.lambda = (s.lambda / 3.0).max(1e-9);
            // Converged: the cost no longer falls, or the parameters no longer move (an exact
            // fit's cost falls geometrically to 0 and its relative gain never becomes small).
            if gain < CONVERGED_GAIN || step.amax() < CONVERGED_STEP {
                s.converged = true;
                return Err(s);
            }
        } else {
            s.lambda *= 4.0;
        }
        Ok(s)
    }

    /// Gates a finished solve: the set to publish, nothing (it has not moved since the last
    /// published), or the gate that failed.
    fn finish(
        &mut self,
        s: &Solve,
        config: &SlideFitConfig,
        gates: &GateConfig,
        dt: f64,
    ) -> Outcome {
        if !s.converged {
            self.last = None;
            return Outcome::NotConverged;
        }
        // The buffers hold the last iteration's linearisation, one converged step before `theta`:
        // its covariance serves (no second pass this tick).
        match self.gate(s, config, gates, dt) {
            Ok((gated, p)) => {
                self.last = Some(s.theta);
                let moved = self.published.is_none_or(|old| {
                    differs(&old, &p, config.republish_change.ln_1p(), self.fitted())
                });
                if moved {
                    Outcome::Publish(gated)
                } else {
                    Outcome::Working
                }
            }
            Err(e) => {
                self.last = None;
                Outcome::Rejected(e)
            }
        }
    }

    /// Records `p` as sent to the operator (a set offered by [`Self::step`] may be held back when
    /// the RLS published one that tick: it is then offered again by the next solve).
    pub(super) fn mark_published(&mut self, p: Physical) {
        self.published = Some(p);
    }

    fn gate(
        &self,
        s: &Solve,
        config: &SlideFitConfig,
        gates: &GateConfig,
        dt: f64,
    ) -> Result<(Gated, Physical), GateRejection> {
        let ff: f64 = self
            .window
            .iter()
            .take(self.axes)
            .flat_map(|w| w[..s.n].iter())
            .map(|x| x[2] * x[2])
            .sum();
        let residual = (s.cost / ff).sqrt();
        if !(residual <= config.max_residual) {
            return Err(GateRejection::Residual {
                residual,
                max: config.max_residual,
            });
        }
        let count = (self.axes * s.n) as f64;
        let f_rms = (ff / count).sqrt();
        let (a, _) = self.normal_equations();
        let fitted = (0..P).filter(|&j| self.is_fitted(j)).count();
        let sigma2 = s.cost / (count - fitted as f64).max(1.0);
        let model = self.model(&s.theta, dt);
        let spread = |j: usize, cov: &Matrix| {
            let se = (sigma2 * cov[(j, j)]).max(0.0).sqrt();
            if j == 4 {
                se * model.p.coulomb_n / f_rms
            } else {
                se
            }
        };
        let cov = a.try_inverse().ok_or(GateRejection::NotIdentified {
            parameter: "m",
            spread: f64::INFINITY,
            max: config.max_relative_error,
        })?;
        for (j, name) in ["m", "b1", "k2", "b2", "Fc"]
            .into_iter()
            .enumerate()
            .filter(|&(j, _)| self.is_fitted(j))
        {
            let spread = spread(j, &cov);
            if !(spread <= config.max_relative_error) {
                return Err(GateRejection::NotIdentified {
                    parameter: name,
                    spread,
                    max: config.max_relative_error,
                });
            }
        }
        let structure = Structure::SlidingMass {
            ground_spring: false,
            friction: self.friction,
        };
        let params = Params::SlidingMass(model.p);
        let gated = if self.partial {
            gate_fitted_massless(structure, &params, residual)?
        } else {
            gate_fitted(structure, &params, residual)?
        };
        Ok((check_deflection(gated, f_rms, gates)?, model.p))
    }
}

impl super::Estimator {
    /// One tick of the sliding first fit, after the RLS's: the samples join the fit while the
    /// model's first contact lasts and the model has no confirmed set; a set that passes is this
    /// tick's update (unless the RLS confirmed one this tick).
    pub(super) fn fit_slide(
        &mut self,
        now_s: f64,
        samples: &[super::AxisSample],
        missed: u32,
        update: &mut super::Update,
    ) {
        if self.phase == super::Phase::Free || self.confirmed_this_model || missed > 0 {
            // A gap breaks the simulation's even time steps: the window ends there.
            self.slide.stop();
            return;
        }
        let mut axes = [[0.0; 3]; 2];
        for ((a, s), tare) in axes.iter_mut().zip(samples).zip(self.tare) {
            *a = [s.position_m, s.velocity_m_per_s, s.force_n - tare];
        }
        let n = samples.len().min(2);
        let dt = self.config.filter.svf.sample_period_s;
        let config = self.config.slide_fit;
        match self
            .slide
            .step(now_s, &axes[..n], &config, &self.config.gates, dt)
        {
            Outcome::Publish(g) if update.confirmed.is_none() => {
                if let Some(p) = g.sliding_mass() {
                    self.slide.mark_published(p);
                }
                // A reduced set leaves the RLS's own reduced sets free to replace it.
                self.whole_published |= !g.is_reduced();
                self.stats.first_fits += 1;
                let after = now_s - self.contact_since_s;
                self.stats.first_fit_after_s.get_or_insert(after);
                if g.is_reduced() {
                    self.stats.contact_fits += 1;
                } else {
                    self.stats.whole_fit_after_s.get_or_insert(after);
                }
                update.confirmed = Some(g);
            }
            Outcome::Rejected(_) | Outcome::NotConverged => self.stats.first_fit_rejections += 1,
            Outcome::Publish(_) | Outcome::Working => {}
        }
    }

    /// Whether a contact beginning now is one the sliding fit serves: the model's first, of a
    /// sliding structure without a ground spring; and whether that structure has friction.
    pub(super) fn slide_fit_serves(&self) -> (bool, bool) {
        match self.structure {
            Structure::SlidingMass {
                ground_spring: false,
                friction,
            } => {
                // Under `EveryOnset` each contact starts a model, but only the session's first
                // finds the object at rest.
                let at_rest =
                    self.config.reset != super::ResetPolicy::EveryOnset || self.model_id <= 1;
                (
                    self.config.slide_fit.enabled && self.model_episodes == 0 && at_rest,
                    friction,
                )
            }
            _ => (false, false),
        }
    }
}

/// Samples per axis in the longest window.
fn window_samples(config: &SlideFitConfig, dt: f64) -> usize {
    ((config.max_window_s / dt).round() as usize).clamp(1, 20_000)
}

/// Where a solve without a previous one starts: the centre of the soft-object class
/// (`mmt::model::prior::SOFT_OBJECTS`), the same for every scene.
fn start_point() -> Vector {
    let c = crate::model::prior::SOFT_OBJECTS.centre();
    Vector::from([
        c.mass_kg.ln(),
        c.b_ground_ns_per_m.ln(),
        c.k_contact_n_per_m.ln(),
        c.b_contact_ns_per_m.ln(),
        c.coulomb_n.max(0.01).ln(),
        0.0,
        0.0,
    ])
}

/// Whether any of the first `fitted` terms (`m, b1, k2, b2, Fc`) of `a` and `b` differs by
/// more than `ln_limit` in the log.
fn differs(a: &Physical, b: &Physical, ln_limit: f64, fitted: usize) -> bool {
    let terms = |p: &Physical| {
        [
            p.mass_kg,
            p.b_ground_ns_per_m,
            p.k_contact_n_per_m,
            p.b_contact_ns_per_m,
            p.coulomb_n,
        ]
    };
    terms(a)
        .iter()
        .zip(terms(b))
        .take(fitted)
        .any(|(x, y)| (x / y).ln().abs() > ln_limit)
}

#[cfg(test)]
mod tests;
