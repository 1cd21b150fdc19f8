//! The telerobot-side estimation pipeline for one group of axes that share a model (thesis §3.2,
//! D.2; `DESIGN.md` §5 and §11):
//!
//! ```text
//! x, v, F ─ tare ─▶ SVF regressors ─▶ RLS (paused out of contact and in the onset guard)
//!                                        │ every back-solve period
//!                                        ▼
//!                         back-solve + gates ─▶ confidence gate ─▶ confirmed parameter set
//! ```
//!
//! - **Tare**: the force sensor's offset is estimated out of contact (EWMA) and subtracted;
//!   a bias the regression cannot represent would otherwise become stiffness.
//! - **Axes sharing θ**: the tangential axes of an isotropic object are one model; both axes'
//!   regressions update the same RLS, with the forgetting per update set to `λ^(1/axes)` so the
//!   memory in time is that of one axis.
//! - **Pause and guard**: no update out of contact, nor during a guard after onset while the
//!   filters' switching transient passes (`DESIGN.md` §11.3, 0.1–0.4 s).
//! - **Covariance reset**: at the first contact the estimator starts from its prior; later it
//!   resets only when the detector says the error of the old parameters jumped (a new object), not
//!   on every re-contact with the same object (§11.3). [`ResetPolicy::EveryOnset`] gives the
//!   thesis's behaviour.
//! - **Friction shape**: the friction columns hold the friction an observer of the object
//!   computes ([`FrictionObserver`]: stick and slip), not the sign of the tool's velocity.
//! - **Confidence gate** (§11.4): a set is *confirmed* — and only then published — when, besides
//!   passing every gate, the back-solved parameters moved less than a set fraction over a window
//!   and the smoothed prediction error is small. Gate-passing early parameters can be 100–200 %
//!   wrong; rendering them cost 87 % error for 0.5 s in the prototype.

mod confidence;
mod first;
mod friction;
mod gaps;
mod slide_fit;
mod solve;
mod stats;
mod validate;

use confidence::Confidence;
pub use confidence::ConfidenceConfig;
pub use first::FirstFitConfig;
pub use friction::{FrictionObserver, ObservedObject};
pub use gaps::{GAP_MUTE_M, MAX_FILLED_PERIODS, MOTION_TOLERANCE_M, SETTLE_CUTOFF_PERIODS};
pub use slide_fit::SlideFitConfig;
pub use stats::{EstimatorStats, RejectionCounts};

use crate::filter::{FilterError, Regression, RegressorConfig, RegressorFilter};
use crate::model::gates::{GateConfig, GateRejection, Gated};
use crate::model::{Structure, col};
use crate::rls::{ColumnScales, Mode, Outcome, Rls, RlsConfig, RlsCounts, RlsError};
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// Most axes one estimator serves (the two tangential axes).
pub const MAX_AXES: usize = 2;

/// Settings of one estimator.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EstimatorConfig {
    /// The model structure identified.
    pub structure: Structure,
    /// Number of axes sharing the model (1 or 2).
    pub axes: usize,
    /// Regressor filter (SVF cut-off: a scene parameter; about 7 Hz for exp 1, §11.2).
    pub filter: RegressorConfig,
    /// Forgetting factor per tick λ. Default 0.999 (1 s memory).
    pub forgetting: f64,
    /// RLS column scales (from the scene's expected excitation).
    pub scales: ColumnScales,
    /// Initial/reset covariance of the scaled coefficients. Default 1e3.
    pub initial_covariance: f64,
    /// Guard after contact onset with no update [s]. Default 0.3.
    pub onset_guard_s: f64,
    /// After the guard, time the new-object detector stays muted [s]. Default 0.5: at a 5 Hz
    /// cut-off the filters' switching transient outlasts the guard (a false alarm 60 ms after a
    /// 0.3 s guard on re-contact with the same object, measured).
    pub detector_mute_s: f64,
    /// Back-solve period [s]. Default 0.01 (100 Hz): the renderer smooths over 20 ms anyway.
    pub back_solve_period_s: f64,
    /// Gate thresholds.
    pub gates: GateConfig,
    /// Confidence gate.
    pub confidence: ConfidenceConfig,
    /// When the covariance is reset.
    pub reset: ResetPolicy,
    /// Time constant of the out-of-contact force tare [s]. Default 0.5.
    pub tare_time_constant_s: f64,
    /// Identify a constant force per axis besides the structure's terms (the columns
    /// [`col::I`], [`col::J`]), restarted at every contact onset when the structure has a static
    /// stiffness (`d`): a spring-mounted object's force depends on where the contact began
    /// relative to where its ground spring rests, which no other column can represent. Default
    /// true.
    pub intercept: bool,
    /// Variance of the constants (scaled units, as [`Self::initial_covariance`]) when they
    /// restart at a contact onset. Default 1e3, the prior's: nothing known about them. A small
    /// value says the constant is nearly known at the onset — a sensor offset the tare has just
    /// removed — and lets it depart from there only as the data or the forgetting allow: a
    /// still hold, which cannot tell a stiffness from a constant, then leaves the stiffness
    /// where the motion put it (the normal axis with a drifting sensor,
    /// `sim::scene::Scene::telerobot_settings`).
    pub onset_intercept_covariance: f64,
    /// Back-solve and gate with the data's information ([`gate_informed`]) rather than with
    /// per-coefficient weights. Default true.
    pub informed: bool,
    /// Take the friction columns' shape from a model of the object run on the measured force
    /// ([`FrictionObserver`]) instead of the tool velocity's sign, which switches the friction a
    /// whole stick phase early at every reversal. The observer runs the latest set that passed
    /// the gates, from the model's first confirmed set on (or after `observer_wait_s` without
    /// one): the sets before it are rough, and starting on them cost exp 1 two points of error
    /// in its first 5 s (measured; 7.7 against 5.8 %). Default true; it acts on a structure with
    /// friction and no ground spring ([`Estimator`]'s `observes_friction`).
    pub friction_observer: bool,
    /// When the friction observer starts, the data taken with the tool's sign before it are
    /// forgotten by this factor at once ([`Rls::discount`]; 0.3 is what 12 s of the exp-1 scene's
    /// 10 s memory would forget). In (0, 1]; 1 keeps them. Default 0.3: over `mmt benchmark`
    /// seeds 1–3 (measured before `observer_wait_s` existed) it took the median error after stable from 4.1–6.6 % to 4.1–5.4 % and left
    /// exp 1 and exp 3 within 0.01 points; its cost is up to 0.45 s more median time to stable at
    /// 400 ms (the parameters move once more after the first confirmed set). 0.1 gained more
    /// error (4.1–4.3 % at seeds 1–2) and cost more time (seed 2: 3.0 → 3.8 s).
    pub observer_discount: f64,
    /// Learning time [s] after which the friction observer starts on the latest gated set even
    /// though no set has been confirmed: a high-friction object fitted with the tool's sign may
    /// never pass the confidence gate, and then never got the observer that would let it pass
    /// (seed 3's class object 07 of `mmt benchmark`: never rendered; rendered 4.0 s after
    /// contact with a 2 s wait). Default 1 s, which exp 1 never reaches (it confirms after about
    /// 0.8 s of learning): over `mmt benchmark` seeds 1–3 at 0 / 400 ms it left no object
    /// unrendered and, against 2 s, took the p90 time to the first render from 2.8–4.6 s to
    /// 2.1–4.0 s and the median error after stable from 4.1–5.4 % to 3.9–4.9 %.
    /// `f64::INFINITY` waits for a confirmed set.
    pub observer_wait_s: f64,
    /// Until a whole set has been confirmed, publish the structure's massless part when it
    /// passes [`gate_massless`] and its own confidence gate: the motion may not excite the mass
    /// (a slow probe, steps, a slow chirp) long after it has pinned down the springs, dampers
    /// and friction, and the operator would meanwhile feel only the prior (issue 12, excitation
    /// awareness). Such a set also starts the friction observer after `observer_wait_s`. It
    /// never replaces a whole set, not even after a reset. The sets are marked
    /// ([`Gated::is_reduced`]) and counted ([`EstimatorStats::reduced_confirmed`]). Default
    /// true; it acts on sliding-mass structures with informed back-solves.
    pub reduced_model: bool,
    /// Choose, at every back-solve, which structure inside `structure` the data support
    /// ([`crate::model::select`]: the Bayesian information criterion on the RLS's own fit, and
    /// whether the terms left out could be felt), and back-solve, gate and publish that one: a
    /// spring-mounted scene's ground spring, or its friction, is left out for an object that
    /// does not need it. Sliding-mass structures with informed back-solves only. The RLS keeps
    /// identifying the whole structure (narrowing it to the chosen columns, exactly, was
    /// measured and was worse: a light spring-mounted object's basin flipped), and the chosen
    /// structure is back-solved from it as the whole one is: per coefficient first (which
    /// ignores the left-out coefficients), then by the data's information (which holds them at
    /// 0). The choice is reported ([`EstimatorStats::selected`]). Default false: the scene's
    /// structure.
    pub select_structure: bool,
    /// A Kelvin–Voigt group's fast first fit, published before its RLS set ([`FirstFitConfig`]).
    #[serde(default)]
    pub first_fit: FirstFitConfig,
    /// A sliding group's fast first fit of its model's first contact, published before its RLS
    /// set ([`SlideFitConfig`]).
    #[serde(default)]
    pub slide_fit: SlideFitConfig,
}

impl EstimatorConfig {
    /// Defaults for a structure and number of axes.
    pub fn new(structure: Structure, axes: usize) -> Self {
        EstimatorConfig {
            structure,
            axes,
            filter: RegressorConfig::default(),
            forgetting: 0.999,
            scales: ColumnScales::exp1(),
            initial_covariance: 1e3,
            onset_guard_s: 0.3,
            detector_mute_s: 0.5,
            back_solve_period_s: 0.01,
            gates: GateConfig::default(),
            confidence: ConfidenceConfig::default(),
            reset: ResetPolicy::NewObject,
            tare_time_constant_s: 0.5,
            intercept: true,
            onset_intercept_covariance: 1e3,
            informed: true,
            friction_observer: true,
            observer_discount: 0.3,
            observer_wait_s: 1.0,
            reduced_model: true,
            select_structure: false,
            first_fit: FirstFitConfig::default(),
            slide_fit: SlideFitConfig::default(),
        }
    }
}

/// When to reset the covariance.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ResetPolicy {
    /// Only when the detector reports a new object (`DESIGN.md` §11.3).
    NewObject,
    /// At every contact onset (the thesis).
    EveryOnset,
}

/// One axis's measurement, in the model's frame: position [m], velocity [m/s], force on the
/// tool [N].
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AxisSample {
    /// Position [m].
    pub position_m: f64,
    /// Velocity [m/s].
    pub velocity_m_per_s: f64,
    /// Force on the tool [N].
    pub force_n: f64,
}

/// What the estimator is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Phase {
    /// Out of contact: paused.
    Free,
    /// In the guard after onset.
    Guard,
    /// Learning.
    Learning,
}

/// The outcome of one tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Update {
    /// A newly confirmed parameter set, to publish.
    pub confirmed: Option<Gated>,
    /// The gate that rejected this tick's back-solve, if one ran and failed.
    pub rejection: Option<GateRejection>,
    /// The detector reported a new object this tick (the covariance was reset).
    pub new_object: bool,
}

/// An invalid estimator configuration.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum EstimatorError {
    /// The filter settings.
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// The RLS settings.
    #[error(transparent)]
    Rls(#[from] RlsError),
    /// Another field.
    #[error("estimator config: {field} = {value} invalid, expected {expected}")]
    Field {
        /// Field name.
        field: &'static str,
        /// The value.
        value: f64,
        /// What was expected.
        expected: &'static str,
    },
}

/// The pipeline for one group of axes.
#[derive(Clone, Debug)]
pub struct Estimator {
    config: EstimatorConfig,
    filters: [RegressorFilter; MAX_AXES],
    regressions: [Regression; MAX_AXES],
    rls: Rls,
    tare: [f64; MAX_AXES],
    tare_alpha: f64,
    tared: bool,
    phase: Phase,
    contact_since_s: f64,
    next_back_solve_s: f64,
    ever_contact: bool,
    confidence: Confidence,
    /// Boxed (allocated once, at construction): the ring is 28 kB, and estimators travel by value
    /// inside the nodes.
    reduced_confidence: Box<Confidence>,
    latest: Option<Gated>,
    observers: [FrictionObserver; MAX_AXES],
    observed: Option<ObservedObject>,
    confirmed_this_model: bool,
    observer_started: bool,
    learned_s: f64,
    /// The last sample, for covering a gap and checking the motion across it.
    last_sample: Option<gaps::LastSample>,
    /// Until when [s] learning waits after samples that contradict a motion
    /// ([`SETTLE_CUTOFF_PERIODS`]).
    settle_until_s: f64,
    model_id: u32,
    /// The structure back-solved and published: `config.structure`, or the one selection chose
    /// inside it.
    structure: Structure,
    /// A structure selection chose that is not in use yet, and for how many back-solves in a row.
    pending: Option<(Structure, u32)>,
    /// This model's structure selection has left no change pending once (publication may
    /// start).
    settled: bool,
    stats: EstimatorStats,
    first: first::FirstFit,
    slide: slide_fit::SlideFit,
    /// Contacts of this model so far (the sliding first fit serves only the first).
    model_episodes: u32,
    /// The sliding first fit published a whole set of this model (the reduced set then no
    /// longer replaces it).
    whole_published: bool,
}

impl Estimator {
    /// Validates the configuration and builds the pipeline at rest.
    pub fn new(config: EstimatorConfig) -> Result<Self, EstimatorError> {
        config.validate()?;
        let filter = RegressorFilter::new(config.filter)?;
        let mut columns = config.structure.columns();
        if config.intercept {
            for axis in 0..config.axes {
                columns = columns.with(col::intercept(axis));
            }
        }
        let rls = Rls::new(RlsConfig {
            columns,
            forgetting: config.forgetting.powf(1.0 / config.axes as f64),
            initial_covariance: config.initial_covariance,
            max_mean_variance: config.initial_covariance,
            scales: config.scales,
            ..RlsConfig::default()
        })?;
        let dt = config.filter.svf.sample_period_s;
        Ok(Estimator {
            filters: [filter.clone(), filter],
            regressions: [Regression::default(); MAX_AXES],
            rls,
            tare: [0.0; MAX_AXES],
            tare_alpha: 1.0 - (-dt / config.tare_time_constant_s).exp(),
            tared: false,
            phase: Phase::Free,
            contact_since_s: 0.0,
            next_back_solve_s: 0.0,
            ever_contact: false,
            confidence: Confidence::new(config.confidence, config.back_solve_period_s),
            reduced_confidence: Box::new(Confidence::new(
                config.confidence,
                config.back_solve_period_s,
            )),
            latest: None,
            observers: [FrictionObserver::default(); MAX_AXES],
            observed: None,
            confirmed_this_model: false,
            observer_started: false,
            learned_s: 0.0,
            last_sample: None,
            settle_until_s: f64::NEG_INFINITY,
            model_id: 0,
            structure: config.structure,
            pending: None,
            settled: false,
            stats: EstimatorStats::default(),
            first: first::FirstFit::default(),
            slide: slide_fit::SlideFit::new(&config.slide_fit, config.axes, dt),
            model_episodes: 0,
            whole_published: false,
            config,
        })
    }

    /// One tick at time `now_s` [s]: the measurement of each axis (`config.axes` of them) and
    /// whether the tool is in contact (from the contact detector).
    pub fn step(&mut self, now_s: f64, samples: &[AxisSample], in_contact: bool) -> Update {
        let mut update = Update::default();
        let n = self.config.axes.min(samples.len());
        let finite = samples[..n].iter().all(|s| {
            s.position_m.is_finite() && s.velocity_m_per_s.is_finite() && s.force_n.is_finite()
        });
        if !finite || n < self.config.axes {
            self.stats.rejected_samples += 1;
            return update;
        }
        let missed = self.missed_periods(now_s);
        self.track_phase(now_s, in_contact, &mut update);
        self.check_gap(now_s, &samples[..n], missed);
        let dt = self.config.filter.svf.sample_period_s;
        let mut inputs = [(0.0, 0.0); MAX_AXES];
        for (i, s) in samples[..n].iter().enumerate() {
            if self.phase == Phase::Free {
                if self.tared {
                    self.tare[i] += self.tare_alpha * (s.force_n - self.tare[i]);
                } else {
                    self.tare[i] = s.force_n;
                }
            }
            let f = s.force_n - self.tare[i];
            inputs[i] = (s.position_m, f);
            self.filter_axis(i, s, f, missed);
        }
        if self.phase == Phase::Free {
            self.tared = true;
        }
        if missed <= MAX_FILLED_PERIODS {
            self.stats.filled_samples += u64::from(missed);
        }
        self.remember(now_s, inputs, &samples[..n]);
        let mode = if self.phase == Phase::Learning && now_s >= self.settle_until_s {
            self.learned_s += dt * f64::from(missed.min(MAX_FILLED_PERIODS) + 1);
            Mode::Learn
        } else {
            Mode::Pause
        };
        let mut detected = false;
        for i in 0..n {
            let r = self.regressions[i];

            if let Outcome::Updated {
                new_object: true, ..
            } = self.rls.update(&r.psi, r.y, mode)
            {
                detected |= self.config.reset == ResetPolicy::NewObject;
            }
        }
        if detected {
            // Mostly the detector's false alarms (`solve.rs`): the first fit checks the object
            // against the last confirmed set before it replaces it.
            let check = self.latest.is_some().then_some(first::Check::AfterReset);
            self.start_new_model();
            self.first.restart(now_s, check);
            // The object may be moving now: the model's next contact is not one from rest.
            self.slide.stop();
            self.model_episodes = 1;
            self.stats.new_objects += 1;
            update.new_object = true;
        }
        if self.phase == Phase::Learning && now_s >= self.next_back_solve_s {
            self.next_back_solve_s = now_s + self.config.back_solve_period_s;
            self.back_solve(&mut update);
        }
        self.fit_first(now_s, &samples[..n], &mut update);
        self.fit_slide(now_s, &samples[..n], missed, &mut update);
        update
    }

    fn track_phase(&mut self, now_s: f64, in_contact: bool, update: &mut Update) {
        if !in_contact {
            self.phase = Phase::Free;
            return;
        }
        if self.phase == Phase::Free {
            self.contact_since_s = now_s;
            self.phase = Phase::Guard;
            if !self.ever_contact {
                self.ever_contact = true;
                self.model_id = 1;
            } else if self.config.reset == ResetPolicy::EveryOnset {
                self.start_new_model();
                self.stats.onset_resets += 1;
                update.new_object = true;
            }
            let check = self.confirmed_this_model.then_some(first::Check::Object);
            self.first.restart(now_s, check);
            let (serves, friction) = self.slide_fit_serves();
            self.slide.restart(now_s, serves, friction);
            self.model_episodes = self.model_episodes.saturating_add(1);
            self.restart_intercepts();
        }
        if self.phase == Phase::Guard && now_s - self.contact_since_s >= self.config.onset_guard_s {
            self.phase = Phase::Learning;
            self.next_back_solve_s = now_s;
            // The filters still hold some of the free-motion inputs, which the contact model cannot
            // explain: keep that tail from looking like a new object.
            self.mute_new_object_detector();
        }
    }

    /// A new episode: with a static stiffness `d` in the structure, the constant of each axis
    /// becomes `d·x` at the onset (the object at rest where its ground spring balances the
    /// unloaded contact), uncertain by [`EstimatorConfig::onset_intercept_covariance`]; without,
    /// the constant is a force offset that persists and is kept.
    fn restart_intercepts(&mut self) {
        if !(self.config.intercept && self.config.structure.columns().contains(col::D)) {
            return;
        }
        let d = self.rls.theta().0[col::D];
        // ψ_D = −x_f: the filtered position at the onset.
        let at = |i: usize| -d * self.regressions[i].psi[col::D];
        self.rls
            .reset_intercepts([at(0), at(1)], self.config.onset_intercept_covariance);
    }

    fn start_new_model(&mut self) {
        // `reset` only fails for an invalid p0, which `new` already validated.
        let _ = self.rls.reset(self.config.initial_covariance);
        self.model_episodes = 0;
        self.whole_published = false;

        self.confidence.clear();
        self.reduced_confidence.clear();
        self.observed = None;
        self.observers = [FrictionObserver::default(); MAX_AXES];
        self.confirmed_this_model = false;
        self.observer_started = false;
        self.learned_s = 0.0;
        self.model_id += 1;
        self.structure = self.config.structure;
        self.pending = None;
        self.settled = false;
    }

    /// The motion is not the operator's (the robot was stopped for want of commands): the
    /// new-object detector stays muted for [`EstimatorConfig::detector_mute_s`] from now, as
    /// after a contact onset, so the force transient that follows is not taken for a new object.
    pub fn mute_new_object_detector(&mut self) {
        let updates = self.config.detector_mute_s / self.config.filter.svf.sample_period_s
            * self.config.axes as f64;
        self.rls.mute_detector(updates.round() as u32);
    }

    /// The last confirmed set.
    pub fn latest(&self) -> Option<&Gated> {
        self.latest.as_ref()
    }

    /// Number of object models started (0 before the first contact).
    pub fn model_id(&self) -> u32 {
        self.model_id
    }

    /// Whether the current model's parameters pass every gate, the confidence gate included, as of
    /// the last back-solve.
    pub fn is_confident(&self) -> bool {
        self.confidence.is_confident()
    }

    /// What the estimator is doing.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The last filtered regression of each axis (for reconstruction reports).
    pub fn regressions(&self) -> &[Regression] {
        &self.regressions[..self.config.axes]
    }

    /// The current RLS estimate θ̂.
    pub fn theta(&self) -> crate::model::Theta {
        self.rls.theta()
    }

    /// What the data so far say about θ ([`crate::model::backsolve::Information`]).
    pub fn information(&self) -> Option<crate::model::backsolve::Information> {
        self.rls.information()
    }

    /// Smoothed relative a-priori prediction error of the RLS.
    pub fn relative_error(&self) -> Option<f64> {
        self.rls.relative_error()
    }

    /// The force offset removed from each axis [N].
    pub fn tare_n(&self) -> &[f64] {
        &self.tare[..self.config.axes]
    }

    /// Counters.
    pub fn stats(&self) -> EstimatorStats {
        self.stats
    }

    /// RLS counters.
    pub fn rls_counts(&self) -> RlsCounts {
        self.rls.counts()
    }

    /// The structure back-solved and published: the configured one, or the one selection
    /// chose inside it ([`EstimatorConfig::select_structure`]).
    pub fn structure(&self) -> Structure {
        self.structure
    }

    /// The configuration.
    pub fn config(&self) -> &EstimatorConfig {
        &self.config
    }
}
