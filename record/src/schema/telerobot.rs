//! Recorded form of the telerobot side: one [`TelerobotTick`] per loop tick — the robot's
//! measurement stream (what a replay bridge plays back), the target, the estimators' gate
//! verdicts, and in an experiment the simulator's truth.

use mmt::estimator::{Estimator, Phase, Update};
use mmt::model::backsolve::Confidence;
use node::{BridgeSample, RobotSample, Target};
use protocol::telerobot_to_operator::Measurement;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// One telerobot-loop tick.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct TelerobotTick {
    /// The operator session whose commands run (0 before the first).
    pub session: u64,
    /// Tick number.
    pub index: u64,
    /// The tick's nominal time [ns, telerobot clock].
    pub t_ns: i64,
    /// Where the robot was told to go \[m\].
    pub target_position_m: [f64; 3],
    /// Target velocity \[m/s\].
    pub target_velocity_m_per_s: [f64; 3],
    /// The command being executed [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// The robot holds still (no fresh command).
    pub holding: bool,
    /// Measured tool position \[m\].
    pub position_m: [f64; 3],
    /// Measured tool velocity \[m/s\].
    pub velocity_m_per_s: [f64; 3],
    /// Measured force the environment exerts on the tool \[N\].
    pub force_on_tool_n: [f64; 3],
    /// The tool as the bridge knows it \[m\] (a simulator's truth; a robot's kinematics).
    pub tool_m: [f64; 3],
    /// How far the touched object slid along the surface's tangents \[m\] (simulated bridge).
    pub object_slide_m: [f64; 2],
    /// Capture time of the camera frame installed this tick, if one was [ns, telerobot clock]
    /// (its points are on `/telerobot/cloud` with this timestamp).
    pub cloud_captured_ns: Option<i64>,
    /// The node's tracked contact.
    pub in_contact: bool,
    /// Its estimators all pass every gate.
    pub estimator_stable: bool,
    /// `[Σ y², Σ (y − ψᵀθ̂)²]` of the tick while learning and confident.
    pub reconstruction: Option<[f64; 2]>,
    /// The normal-axis estimator, if the scene has one.
    pub estimator_normal: Option<EstimatorRec>,
    /// The tangential estimator, if the scene has one.
    pub estimator_tangential: Option<EstimatorRec>,
    /// Experiments: the true force on the tool \[N\].
    pub true_force_n: Option<[f64; 3]>,
    /// Experiments: the true contact.
    pub true_in_contact: Option<bool>,
    /// Experiments: the true contact deflection and mass velocity per tangent.
    pub true_state: Option<[[f64; 2]; 2]>,
}

impl TelerobotTick {
    /// A tick of the node: where it sent the robot, what the bridge gave, the measurement
    /// datagram it made (none for a refused sample), its estimators.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        session: u64,
        index: u64,
        t_ns: i64,
        target: &Target,
        sample: &BridgeSample,
        cloud_captured_ns: Option<i64>,
        measurement: Option<&Measurement>,
        estimators: &[Option<EstimatorSnapshot>; 2],
    ) -> Self {
        let m = &sample.measured;
        TelerobotTick {
            session,
            index,
            t_ns,
            target_position_m: target.position_m,
            target_velocity_m_per_s: target.velocity_m_per_s,
            command_sample_time_ns: target.command_sample_time_ns,
            holding: target.holding,
            position_m: m.position_m,
            velocity_m_per_s: m.velocity_m_per_s,
            force_on_tool_n: m.force_on_tool_n,
            tool_m: sample.tool_m,
            object_slide_m: sample.object_slide_m,
            cloud_captured_ns,
            in_contact: measurement.is_some_and(|m| m.in_contact),
            estimator_stable: measurement.is_some_and(|m| m.estimator_stable),
            reconstruction: measurement.and_then(|m| m.reconstruction),
            estimator_normal: estimators[0].as_ref().map(EstimatorRec::from),
            estimator_tangential: estimators[1].as_ref().map(EstimatorRec::from),
            true_force_n: None,
            true_in_contact: None,
            true_state: None,
        }
    }

    /// The measurement the robot gave this tick.
    pub fn sample(&self) -> RobotSample {
        RobotSample {
            position_m: self.position_m,
            velocity_m_per_s: self.velocity_m_per_s,
            force_on_tool_n: self.force_on_tool_n,
        }
    }
}

/// One estimator at one tick: its phase, and the gates' verdict when a back-solve ran.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct EstimatorRec {
    /// `free`, `guard` or `learning`.
    pub phase: String,
    /// Its latest set passes every gate, the confidence gate included.
    pub confident: bool,
    /// The object model number.
    pub model_id: u32,
    /// Smoothed relative prediction error, while learning.
    pub relative_error: Option<f64>,
    /// A set was confirmed this tick.
    pub confirmed: bool,
    /// The gate that rejected this tick's back-solve, in words.
    pub rejected_by: Option<String>,
    /// The back-solve's confidence in the set confirmed this tick: `identified` or `low`.
    pub confidence: Option<String>,
    /// Condition number of the set confirmed this tick.
    pub condition: Option<f64>,
    /// Back-solve residual of the set confirmed this tick.
    pub residual: Option<f64>,
    /// The detector reported a new object this tick (covariance reset).
    pub new_object: bool,
}

/// An estimator at one tick, as plain values: what a loop hands on (no allocation), made into
/// an [`EstimatorRec`] off the loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EstimatorSnapshot {
    /// Its phase.
    pub phase: Phase,
    /// Confident.
    pub confident: bool,
    /// Object model number.
    pub model_id: u32,
    /// Smoothed relative prediction error.
    pub relative_error: Option<f64>,
    /// The tick's outcome.
    pub update: Update,
}

impl EstimatorSnapshot {
    /// The estimator after a tick whose outcome was `update`.
    pub fn of(est: &Estimator, update: Update) -> Self {
        EstimatorSnapshot {
            phase: est.phase(),
            confident: est.is_confident(),
            model_id: est.model_id(),
            relative_error: est.relative_error(),
            update,
        }
    }
}

impl From<&EstimatorSnapshot> for EstimatorRec {
    fn from(s: &EstimatorSnapshot) -> Self {
        let phase = match s.phase {
            Phase::Free => "free",
            Phase::Guard => "guard",
            Phase::Learning => "learning",
        };
        let update = &s.update;
        let confirmed = update.confirmed.as_ref();
        EstimatorRec {
            phase: phase.to_owned(),
            confident: s.confident,
            model_id: s.model_id,
            relative_error: s.relative_error,
            confirmed: confirmed.is_some(),
            rejected_by: update.rejection.map(|r| r.to_string()),
            confidence: confirmed.map(|g| {
                match g.confidence() {
                    Confidence::Identified => "identified",
                    Confidence::Low { .. } => "low",
                }
                .to_owned()
            }),
            condition: confirmed.map(|g| g.condition()),
            residual: confirmed.map(|g| g.residual()),
            new_object: update.new_object,
        }
    }
}
