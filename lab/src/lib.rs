//! # lab — experiments, analysis, reports and plots, and the `mmt` binary
//!
//! What it is:
//! - [`experiment`]: the in-process harness — the thesis's experiments 1–3 with the two shipped
//!   nodes connected by the seeded `netem` link model carrying the encoded wire bytes, on one
//!   simulated clock (deterministic, faster than real time);
//! - [`analysis`]: the analysis commands' computations (estimator figures, stress, work–precision);
//! - [`benchmark`]: the object-class benchmark — the experiment over a seeded class of objects
//!   and named corner cases, several motions, delays and sensor presets, with percentiles;
//! - [`report`] and [`plot`]: the files of a run (`report.json`, `series.csv`, force, error and
//!   spectrum plots as SVG and PNG; the font lives here); [`recorded`]: the same report computed
//!   again from a run's recording (`mmt report FILE.mcap`);
//! - [`cli`]: the `mmt` binary's commands (`experiment`, `benchmark`, `report`, `transfer`,
//!   `estimate`, `stress`, `work-precision`, `contact-bench`).
//!
//! What it is not: no numerics of its own (they are `mmt`'s), no node logic (`node`'s), no
//! figures of its own (`metrics` computes them, for the networked operator too). Neither daemon
//! depends on this crate.

pub mod analysis;
pub mod benchmark;
pub mod cli;
pub mod experiment;
pub mod plot;
pub mod recorded;
pub mod report;
