//! `mmt estimate --from FILE.mcap`: the estimator run offline on a recorded telerobot
//! measurement stream. The recording's ticks are played back through the replay robot bridge
//! ([`record::ReplayBridge`]) into a fresh telerobot node built from the recorded scene, exactly
//! as the daemon's loop steps it (`now`, the command's sample time, the bridge's sample), with
//! each camera frame installed at the tick the live node installed it. With the scene's own
//! settings the replay repeats the live run's estimates bit for bit (within its first operator
//! session: a later session's node started from a position the recording does not hold
//! exactly); with other settings (`--cutoff-hz`, `--forgetting`) it is how a lab re-runs the
//! estimator on data from its own arm.

use std::collections::HashMap;
use std::path::Path;

use metrics::{ParameterReport, parameter_report};
use node::telerobot::TelerobotNode;
use node::{RobotBridge, Target};
use protocol::telerobot_to_operator::{Datagram, Parameters};
use record::schema::{ParametersRec, topic};
use record::{Kind, ReplayBridge, Side};
use serde::Serialize;
use sim::scene::Scene;
use thiserror::Error;

/// Settings of an offline run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EstimateFromConfig {
    /// State-variable filter cut-off \[Hz\]; `None`: the recorded scene's.
    pub cutoff_hz: Option<f64>,
    /// Forgetting factor per tick; `None`: the recorded scene's.
    pub forgetting: Option<f64>,
}

/// What the offline run gave.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct EstimateFromReport {
    /// The file.
    pub file: String,
    /// What it is.
    pub recording: String,
    /// The scene the node was built from.
    pub scene: String,
    /// Ticks replayed, and their length \[s\].
    pub ticks: u64,
    /// Length of the replayed stream \[s\].
    pub seconds: f64,
    /// Filter cut-off and forgetting factor used.
    pub cutoff_hz: f64,
    /// Forgetting factor used.
    pub forgetting: f64,
    /// Contact episodes the replayed node saw.
    pub contact_onsets: u64,
    /// From the first contact until the estimators are confident and stay so \[s\].
    pub time_to_stable_s: Option<f64>,
    /// A-priori reconstruction error of the tangential estimator while confident \[%\].
    pub reconstruction_error_pct: Option<f64>,
    /// Parameter sets the replay published (confirmed sets, and repeats).
    pub parameter_messages: u64,
    /// The replay's final parameters against the scene's truth (a simulated scene's; a real
    /// robot's recording has none to compare with, and its rows are still the estimates).
    pub parameters: Vec<ParameterReport>,
    /// The replay's last parameters message, as it would have been sent.
    pub final_parameters: Option<ParametersRec>,
    /// The recording's own last parameters message.
    pub recorded_parameters: Option<ParametersRec>,
    /// The replay published exactly the parameter sets the live node did (same count, same
    /// values, same sample times).
    pub same_as_recorded: bool,
    /// Camera frames installed, and frames the recording did not hold.
    pub clouds: (u64, u64),
}

/// Why the offline run could not be made.
#[derive(Debug, Error)]
pub enum EstimateFromError {
    /// The file was refused.
    #[error(transparent)]
    Read(#[from] record::ReadError),
    /// Something missing or invalid.
    #[error("{0}")]
    Invalid(String),
    /// The node could not be built.
    #[error(transparent)]
    Node(#[from] node::telerobot::NodeError),
}

/// The topics the offline run reads.
const TOPICS: [&str; 6] = [
    topic::RUN,
    topic::TELEROBOT_TICK,
    topic::TELEROBOT_CLOUD,
    topic::OPERATOR_CLOUD,
    topic::TELEROBOT_PARAMETERS,
    topic::RUN_END,
];

/// Reads `path` and runs the estimator on its telerobot stream.
pub fn estimate_from(
    path: &Path,
    config: &EstimateFromConfig,
) -> Result<EstimateFromReport, EstimateFromError> {
    let rec = record::read(path, &TOPICS)?;
    rec.require(
        &[Kind::Telerobot, Kind::Demo, Kind::Experiment],
        "mmt estimate --from needs the telerobot's measurement stream: a telerobot, demo or \
         experiment recording",
    )?;
    let invalid = |what: String| EstimateFromError::Invalid(format!("{}: {what}", path.display()));
    let run = rec
        .run(Side::Telerobot)
        .ok_or_else(|| invalid("no /run of the telerobot side".into()))?;
    let mut scene = run
        .scene
        .clone()
        .ok_or_else(|| invalid("the telerobot's /run does not say which scene ran".into()))?;
    apply(&mut scene, config).map_err(invalid)?;
    // A file's scene is checked as a scene file is, before a node is built from it.
    let scene = scene
        .validated("the recording's /run")
        .map_err(|e| invalid(e.to_string()))?;
    let settings = scene.telerobot_settings();
    let start = run
        .tool_start_m
        .or(rec.telerobot_ticks.first().map(|t| t.tool_m))
        .unwrap_or([0.0; 3]);
    let (node, replay) = replay(&rec, &settings, start)?;
    let recorded: Vec<ParametersRec> = rec
        .parameters
        .iter()
        .filter(|(side, _)| *side == Side::Telerobot)
        .map(|(_, p)| *p)
        .collect();
    let latest = |e: Option<&mmt::estimator::Estimator>| e.and_then(|e| e.latest()).copied();
    let parameters = parameter_report(
        &scene,
        [
            latest(node.normal_estimator()).as_ref(),
            latest(node.tangential_estimator()).as_ref(),
        ],
    );
    let period_s = settings.period_ns as f64 * 1e-9;
    Ok(EstimateFromReport {
        file: path.display().to_string(),
        recording: rec.describe(),
        scene: scene.name.clone(),
        ticks: replay.ticks,
        seconds: replay.ticks as f64 * period_s,
        cutoff_hz: scene.model.filter_cutoff_hz,
        forgetting: scene.model.forgetting,
        contact_onsets: replay.onsets,
        time_to_stable_s: replay.time_to_stable(period_s),
        reconstruction_error_pct: (replay.reconstruction.0 > 0.0)
            .then(|| 100.0 * (replay.reconstruction.1 / replay.reconstruction.0).sqrt()),
        parameter_messages: replay.published.len() as u64,
        parameters,
        final_parameters: replay.published.last().copied(),
        recorded_parameters: recorded.last().copied(),
        same_as_recorded: !recorded.is_empty() && replay.published == recorded,
        clouds: replay.clouds,
    })
}

/// Plays the recording's telerobot ticks through a fresh node (a fresh one per session, as the
/// daemon swaps them), installing each recorded camera frame at the tick it was installed.
fn replay(
    rec: &record::Recording,
    settings: &node::TelerobotSettings,
    start: [f64; 3],
) -> Result<(TelerobotNode, Replay), EstimateFromError> {
    // Frames by capture time: the telerobot's, else as the operator received them.
    let mut clouds: HashMap<i64, _> = HashMap::new();
    for side in [Side::Operator, Side::Telerobot] {
        for (_, cloud) in rec.clouds.iter().filter(|(s, _)| *s == side) {
            clouds.insert(cloud.timestamp_ns, cloud);
        }
    }
    let mut bridge = ReplayBridge::new(rec.telerobot_ticks.clone());
    let mut node = TelerobotNode::new(settings.clone(), start)?;
    let mut replay = Replay::default();
    let mut session = rec.telerobot_ticks.first().map_or(0, |t| t.session);
    let hold = Target {
        position_m: start,
        velocity_m_per_s: [0.0; 3],
        command_sample_time_ns: 0,
        holding: true,
    };
    while let Some(tick) = bridge.peek().cloned() {
        if tick.session != session {
            // The daemon swaps in a fresh node for a new operator (built where the robot held).
            if session != 0 {
                let tool = bridge.tool_m().unwrap_or([0.0; 3]);
                node = TelerobotNode::new(settings.clone(), tool)?;
            }
            session = tick.session;
        }
        if let Some(t) = tick.cloud_captured_ns {
            match clouds.get(&t).and_then(|c| index(c)) {
                Some(i) => {
                    replay.clouds.0 += 1;
                    node.set_cloud(i, replay.clouds.0);
                }
                None => replay.clouds.1 += 1,
            }
        }
        let sample = bridge.step(tick.t_ns, Some(&hold));
        node.step(tick.t_ns, tick.command_sample_time_ns, &sample.measured);
        replay.tick(&node, tick.session);
    }
    Ok((node, replay))
}

/// The overrides, checked.
fn apply(scene: &mut Scene, config: &EstimateFromConfig) -> Result<(), String> {
    if let Some(c) = config.cutoff_hz {
        let nyquist = scene.rates.control_hz / 2.0;
        if !(c.is_finite() && c > 0.0 && c < nyquist / 5.0) {
            return Err(format!(
                "--cutoff-hz {c}: expected a cut-off in (0, {}) Hz (a tenth of the {} Hz loop rate)",
                nyquist / 5.0,
                scene.rates.control_hz
            ));
        }
        scene.model.filter_cutoff_hz = c;
    }
    if let Some(f) = config.forgetting {
        if !(f.is_finite() && f > 0.99 && f <= 1.0) {
            return Err(format!(
                "--forgetting {f}: expected a factor per tick in (0.99, 1] (1: no forgetting)"
            ));
        }
        scene.model.forgetting = f;
    }
    Ok(())
}

fn index(c: &record::schema::CloudRec) -> Option<std::sync::Arc<mmt::contact::CloudIndex>> {
    let frame =
        mmt::cloud::CloudFrame::new(c.points.to_vec(), c.timestamp_ns, Default::default()).ok()?;
    mmt::contact::CloudIndex::build(&frame)
        .ok()
        .map(std::sync::Arc::new)
}

/// What the replay saw, tick by tick.
#[derive(Default)]
struct Replay {
    ticks: u64,
    onsets: u64,
    first_contact: Option<u64>,
    /// The last tick at which the estimators were not confident.
    last_unstable: Option<u64>,
    reconstruction: (f64, f64),
    published: Vec<ParametersRec>,
    clouds: (u64, u64),
}

impl Replay {
    fn tick(&mut self, node: &TelerobotNode, session: u64) {
        let k = self.ticks;
        self.ticks += 1;
        for d in node.datagrams() {
            match d {
                Datagram::Measurement(m) => {
                    if m.in_contact && self.first_contact.is_none() {
                        self.first_contact = Some(k);
                    }
                    if !m.estimator_stable {
                        self.last_unstable = Some(k);
                    }
                    if let Some([y2, e2]) = m.reconstruction {
                        self.reconstruction.0 += y2;
                        self.reconstruction.1 += e2;
                    }
                }
                Datagram::Parameters(p) => self.published.push(rec(session, p)),
                _ => {}
            }
        }
        self.onsets = node.stats().contact_onsets;
    }

    fn time_to_stable(&self, period_s: f64) -> Option<f64> {
        let first = self.first_contact?;
        let stable_from = self.last_unstable.map_or(0, |k| k + 1);
        (stable_from < self.ticks).then(|| stable_from.saturating_sub(first) as f64 * period_s)
    }
}

fn rec(session: u64, p: &Parameters) -> ParametersRec {
    ParametersRec::new(session, p, None)
}
