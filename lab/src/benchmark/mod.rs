//! `mmt benchmark`: the whole pipeline over a class of objects instead of one (issue 12).
//!
//! Objects are drawn from a documented, seeded class ([`class`]) and joined by named corner
//! cases; each is run through the in-process experiment ([`crate::experiment::run`]: the two
//! shipped nodes, the link model, the simulated world) with several motions (`exp1`, `chirp`,
//! `steps`, `slow` probing, a `human`-like random motion), one-way delays and sensor presets.
//! Every case gives the figures of [`CaseFigures`]; the report groups them by motion, delay
//! and preset and gives their percentiles ([`Summary`]).
//!
//! Cases run on `jobs` worker threads (one case per thread at a time); each case is the
//! single-threaded, deterministic experiment, so the report does not depend on `jobs`.

pub mod class;
mod figures;

pub use class::{Object, ObjectClass, corner_cases};
pub use figures::{CaseFigures, Percentiles, Summary};

use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use serde::Serialize;
use sim::scene::SensorPreset;

use crate::experiment::{ExperimentConfig, ExperimentError, Kind, run as run_experiment};

/// The motions of a full benchmark.
pub const MOTIONS: [&str; 5] = ["exp1", "chirp", "steps", "slow", "human"];

/// Settings of a benchmark.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BenchmarkConfig {
    /// The class the objects are drawn from.
    pub class: ObjectClass,
    /// Objects drawn from the class. Default 30.
    pub objects: usize,
    /// Add the named corner cases. Default true.
    pub corner_cases: bool,
    /// Seed of the class draw; each case's noise and random motion are seeded from it and the
    /// object's index.
    pub seed: u64,
    /// Trajectories ([`MOTIONS`] by default).
    pub motions: Vec<String>,
    /// One-way delays [ms]. Default 0 and 400.
    pub delays_ms: Vec<f64>,
    /// Sensor presets. Default franka-like.
    pub presets: Vec<SensorPreset>,
    /// Simulated time per case [s]. Default 60.
    pub seconds: f64,
    /// Worker threads. Default 1.
    pub jobs: usize,
    /// Which tangential structure the scenes give the estimator. Default: the object's own.
    pub structure: StructureMode,
}

/// Which tangential structure a benchmark's scenes give the estimator.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, clap::ValueEnum)]
#[serde(rename_all = "kebab-case")]
pub enum StructureMode {
    /// The object's own: a ground spring exactly when it has one, and friction.
    #[default]
    Object,
    /// The largest (ground spring and friction) for every object: a scene that does not say.
    Whole,
    /// The largest, and the estimator chooses from the data which of it the object needs
    /// (`EstimatorConfig::select_structure`).
    Select,
}

impl Default for BenchmarkConfig {
    fn default() -> Self {
        BenchmarkConfig {
            class: ObjectClass::default(),
            objects: 30,
            corner_cases: true,
            seed: 1,
            motions: MOTIONS.iter().map(|m| m.to_string()).collect(),
            delays_ms: vec![0.0, 400.0],
            presets: vec![SensorPreset::FrankaLike],
            seconds: 60.0,
            jobs: 1,
            structure: StructureMode::Object,
        }
    }
}

/// One run: an object, a motion, a delay, a preset.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Case {
    /// Index into [`BenchmarkReport::objects`].
    pub object: usize,
    /// Trajectory.
    pub motion: String,
    /// One-way delay [ms].
    pub delay_ms: f64,
    /// Sensor preset.
    pub preset: String,
    /// Seed of the run (noise, link, random motion).
    pub seed: u64,
}

/// A case and its figures.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CaseResult {
    /// The case.
    #[serde(flatten)]
    pub case: Case,
    /// Its figures.
    pub figures: CaseFigures,
}

/// The report of a benchmark.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BenchmarkReport {
    /// The settings.
    pub config: BenchmarkConfig,
    /// The objects: the class draw, then the corner cases.
    pub objects: Vec<Object>,
    /// Objects drawn from the class (the first `class_objects` of `objects`).
    pub class_objects: usize,
    /// Every case.
    pub cases: Vec<CaseResult>,
    /// Per motion, delay, preset and object group (class, corner cases).
    pub summaries: Vec<Summary>,
}

/// The objects of a benchmark: the class draw, then the corner cases.
pub fn objects(config: &BenchmarkConfig) -> Vec<Object> {
    let mut objects = config.class.sample(config.objects, config.seed);
    if config.corner_cases {
        objects.extend(corner_cases());
    }
    objects
}

/// Every case, in a fixed order (preset, delay, motion, object).
pub fn cases(config: &BenchmarkConfig, objects: usize) -> Vec<Case> {
    let mut out = Vec::new();
    for preset in &config.presets {
        for &delay_ms in &config.delays_ms {
            for motion in &config.motions {
                for object in 0..objects {
                    out.push(Case {
                        object,
                        motion: motion.clone(),
                        delay_ms,
                        preset: preset.name().to_string(),
                        seed: config
                            .seed
                            .wrapping_mul(1000)
                            .wrapping_add(object as u64 + 1),
                    });
                }
            }
        }
    }
    out
}

/// Runs one case.
pub fn run_case(
    config: &BenchmarkConfig,
    object: &Object,
    case: &Case,
) -> Result<CaseFigures, ExperimentError> {
    let preset = SensorPreset::parse(&case.preset).unwrap_or_default();
    let kind = if case.delay_ms > 0.0 {
        Kind::Exp3
    } else {
        Kind::Exp1
    };
    let mut scene = object.scene(preset);
    if config.structure != StructureMode::Object {
        scene.model.ground_spring = true;
        scene.model.friction = true;
        scene.model.select_structure = config.structure == StructureMode::Select;
    }
    let mut e = ExperimentConfig::new(kind, scene);
    e.delay_ms = case.delay_ms;
    e.seconds = config.seconds;
    e.seed = case.seed;
    e.trajectory = case.motion.clone();
    let (_, report) = run_experiment(&e, &mut |_| {})?;
    let mut figures = CaseFigures::from_report(&report);
    figures.ground_spring_chosen_right = figures
        .selected
        .map(|s| s.columns().contains(mmt::model::col::D) == object.ground_spring);
    Ok(figures)
}

/// Runs every case on `config.jobs` threads; `progress(done, total)` after each case.
pub fn run(
    config: &BenchmarkConfig,
    progress: &(dyn Fn(usize, usize) + Sync),
) -> Result<BenchmarkReport, ExperimentError> {
    let objects = objects(config);
    let cases = cases(config, objects.len());
    let next = AtomicUsize::new(0);
    let done = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<CaseFigures, ExperimentError>>>> =
        Mutex::new((0..cases.len()).map(|_| None).collect());
    std::thread::scope(|scope| {
        for _ in 0..config.jobs.max(1) {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(case) = cases.get(i) else { break };
                    let r = run_case(config, &objects[case.object], case);
                    if let Ok(mut v) = results.lock() {
                        v[i] = Some(r);
                    }
                    progress(done.fetch_add(1, Ordering::Relaxed) + 1, cases.len());
                }
            });
        }
    });
    let results = results.into_inner().unwrap_or_default();
    let mut out = Vec::with_capacity(cases.len());
    for (case, r) in cases.into_iter().zip(results) {
        let figures = r.ok_or_else(|| ExperimentError::Link("a worker stopped".into()))??;
        out.push(CaseResult { case, figures });
    }
    let summaries = summaries(config, &out, config.objects);
    Ok(BenchmarkReport {
        config: config.clone(),
        objects,
        class_objects: config.objects,
        cases: out,
        summaries,
    })
}

/// The summaries of every (preset, delay, motion) over the class, and over the corner cases.
fn summaries(config: &BenchmarkConfig, cases: &[CaseResult], class: usize) -> Vec<Summary> {
    let mut out = Vec::new();
    for preset in &config.presets {
        for &delay in &config.delays_ms {
            for motion in &config.motions {
                for (group, range) in [("class", 0..class), ("corner", class..usize::MAX)] {
                    let figures: Vec<&CaseFigures> = cases
                        .iter()
                        .filter(|c| {
                            c.case.preset == preset.name()
                                && c.case.delay_ms == delay
                                && &c.case.motion == motion
                                && range.contains(&c.case.object)
                        })
                        .map(|c| &c.figures)
                        .collect();
                    if !figures.is_empty() {
                        out.push(Summary::of(motion, delay, preset.name(), group, &figures));
                    }
                }
            }
        }
    }
    out
}
