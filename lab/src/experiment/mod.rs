//! The in-process experiment harness: the thesis's experiments 1–3 with the two nodes of the
//! shipped system, connected by the `netem` link model carrying the encoded wire bytes, on one
//! simulated clock — deterministic and faster than real time.
//!
//! Per 1 ms tick:
//! 1. messages the downlink releases now are decoded and handed to the operator node (and to a
//!    *shadow* operator node that decides contact from the telerobot's state only, as the thesis
//!    did, so both are measured in the same run);
//! 2. the scripted device moves; the operator node renders the force and emits a command, which is
//!    encoded onto the uplink;
//! 3. commands the uplink releases now reach the telerobot node; the simulated world executes the
//!    current target; a camera frame is taken at the scene's rate;
//! 4. the telerobot node's messages are encoded onto the downlink.
//!
//! Measured and rendered force are aligned by the command sample time: the force the telerobot
//! measured while executing the command the operator sent at `t` is compared with the force the
//! operator rendered at `t` — "rendered shifted back by the delay", exactly.

mod recorded;
mod run;

pub use metrics::{
    Band, ContactLatency, ExperimentReport, NodeInfo, ParameterReport, RunInfo, Series, analyse,
    parameter_report,
};
pub use run::{run, run_recorded};

use node::operator::OperatorConfig;
use serde::{Deserialize, Serialize};
use sim::scene::Scene;
use thiserror::Error;

/// Which experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// Experiment 1: the full system, simulated scene, make/break contact, no delay.
    Exp1,
    /// Experiment 2: the estimator on a noisy, Franka-like sensor model, one long contact.
    Exp2,
    /// Experiment 3: experiment 1 with a 400 ms one-way delay.
    Exp3,
}

impl Kind {
    /// Parses `exp1`, `exp2`, `exp3`.
    pub fn parse(name: &str) -> Result<Kind, ExperimentError> {
        match name {
            "exp1" => Ok(Kind::Exp1),
            "exp2" => Ok(Kind::Exp2),
            "exp3" => Ok(Kind::Exp3),
            _ => Err(ExperimentError::Name(name.to_string())),
        }
    }

    /// Report name.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Exp1 => "exp1",
            Kind::Exp2 => "exp2",
            Kind::Exp3 => "exp3",
        }
    }

    /// Default one-way delay [ms].
    pub fn default_delay_ms(self) -> f64 {
        match self {
            Kind::Exp3 => 400.0,
            _ => 0.0,
        }
    }

    /// Default scripted trajectory.
    pub fn default_trajectory(self) -> &'static str {
        match self {
            Kind::Exp2 => "exp2",
            _ => "exp1",
        }
    }
}

/// Settings of a run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExperimentConfig {
    /// The experiment.
    pub kind: Kind,
    /// The scene.
    pub scene: Scene,
    /// One-way delay each way [ms].
    pub delay_ms: f64,
    /// Jitter (uniform half-width, order kept) each way [ms].
    pub jitter_ms: f64,
    /// Random loss each way, fraction.
    pub loss: f64,
    /// Duplicated datagrams each way, fraction.
    pub duplicate: f64,
    /// Datagrams sent ahead of their turn each way (netem reorder, gap 5), fraction; needs a
    /// delay.
    pub reorder: f64,
    /// Simulated time [s].
    pub seconds: f64,
    /// Seed of the sensor noise, the cloud noise and the link.
    pub seed: u64,
    /// Scripted trajectory name ([`sim::trajectory::NAMES`]).
    pub trajectory: String,
    /// The operator node's settings.
    pub operator: OperatorConfig,
    /// Both nodes detect contact with the thesis's proxy, points only, without the plane that
    /// bridges a camera's holes (`mmt::contact::bridge`): the baseline of issue 14's figures.
    #[serde(default)]
    pub thesis_proxy: bool,
    /// The telerobot publishes its first fits before the RLS sets: a Kelvin–Voigt group's
    /// (`mmt::estimator::FirstFitConfig`) and a sliding object's first contact's
    /// (`mmt::estimator::SlideFitConfig`), issue 13 item 2. Default true; false is the baseline.
    #[serde(default = "yes")]
    pub first_fit: bool,
}

fn yes() -> bool {
    true
}

impl ExperimentConfig {
    /// The defaults of `kind` on `scene`: 60 s, seed 1.
    pub fn new(kind: Kind, scene: Scene) -> Self {
        ExperimentConfig {
            kind,
            scene,
            delay_ms: kind.default_delay_ms(),
            jitter_ms: 0.0,
            loss: 0.0,
            duplicate: 0.0,
            reorder: 0.0,
            seconds: 60.0,
            seed: 1,
            trajectory: kind.default_trajectory().to_string(),
            operator: OperatorConfig::default(),
            thesis_proxy: false,
            first_fit: true,
        }
    }

    /// Every setting against its range: the field, the value and what is allowed.
    pub fn validate(&self) -> Result<(), ExperimentError> {
        let field = |field: &'static str, value: f64, ok: bool, expected: &'static str| {
            if ok {
                Ok(())
            } else {
                Err(ExperimentError::Field {
                    field,
                    value,
                    expected,
                })
            }
        };
        field(
            "seconds",
            self.seconds,
            self.seconds.is_finite() && self.seconds >= 1.0 && self.seconds <= 3600.0,
            "in [1, 3600] s",
        )?;
        field(
            "delay_ms",
            self.delay_ms,
            self.delay_ms.is_finite() && (0.0..=5000.0).contains(&self.delay_ms),
            "in [0, 5000] ms",
        )?;
        field(
            "jitter_ms",
            self.jitter_ms,
            self.jitter_ms.is_finite() && (0.0..=100.0).contains(&self.jitter_ms),
            "in [0, 100] ms",
        )?;
        field(
            "loss",
            self.loss,
            (0.0..0.5).contains(&self.loss),
            "a fraction in [0, 0.5)",
        )?;
        field(
            "duplicate",
            self.duplicate,
            (0.0..0.5).contains(&self.duplicate),
            "a fraction in [0, 0.5)",
        )?;
        field(
            "reorder",
            self.reorder,
            (0.0..0.5).contains(&self.reorder),
            "a fraction in [0, 0.5)",
        )
    }
}

/// Why an experiment could not run.
#[derive(Debug, Error)]
pub enum ExperimentError {
    /// An unknown experiment name.
    #[error("unknown experiment {0:?}: expected exp1, exp2 or exp3")]
    Name(String),
    /// A setting out of range.
    #[error("{field} = {value} is out of range: expected {expected}")]
    Field {
        /// Setting.
        field: &'static str,
        /// Value.
        value: f64,
        /// Expectation.
        expected: &'static str,
    },
    /// The trajectory.
    #[error(transparent)]
    Trajectory(#[from] sim::trajectory::UnknownTrajectory),
    /// A node.
    #[error(transparent)]
    Node(#[from] node::telerobot::NodeError),
    /// The simulated world.
    #[error(transparent)]
    Sim(#[from] sim::SimError),
    /// The link model.
    #[error("link: {0}")]
    Link(String),
    /// The cloud source.
    #[error("cloud: {0}")]
    Cloud(String),
    /// The operator's settings from the scene's `Welcome`.
    #[error("operator settings: {0}")]
    Settings(String),
    /// Stopped by Ctrl-C or SIGTERM before the end.
    #[error("interrupted at {at_s:.1} s of {of_s:.1} s simulated")]
    Interrupted {
        /// Simulated time reached \[s\].
        at_s: f64,
        /// Simulated time asked for \[s\].
        of_s: f64,
    },
}

#[cfg(test)]
mod tests;
