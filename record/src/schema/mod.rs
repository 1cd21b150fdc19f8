//! What a recording holds: its kind and format version, its topics, and the message types of its
//! JSON channels (each with a JSON Schema, so Foxglove, Lichtblick and PlotJuggler plot any field
//! by name without a plug-in). The 3-D scene, point clouds, transforms and events use Foxglove's
//! own schemas (`foxglove.SceneUpdate`, `foxglove.PointCloud`, `foxglove.FrameTransform`,
//! `foxglove.Log`).
//!
//! These types are the recording's contract, kept apart from the wire (`protocol`) and the
//! nodes' internal types, which may change without changing a file's meaning: a change here bumps
//! [`FORMAT_VERSION`], and a reader refuses a file of another version, saying which it is.
//!
//! Times: every message carries its own sample times on the clock of the side that made it
//! (`*_ns`: the operator's or the telerobot's `rt::monotonic_ns`, or the simulated clock of an
//! in-process experiment). The MCAP log time of a message is the same instant mapped onto wall
//! time with the clock pair in the file's header ([`Header::clock_origin_ns`]).

mod common;
mod operator;
mod telerobot;

use std::sync::Arc;

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub use common::{
    ContactRec, ContactStateRec, FrameRec, LinkRec, ParameterSetRec, ParametersRec, StateSyncRec,
    StructureRec,
};
pub use operator::{MeasurementRec, OperatorTick, SafetyFlags};
pub use telerobot::{EstimatorRec, EstimatorSnapshot, TelerobotTick};

/// The recording format's version: a reader accepts only its own.
pub const FORMAT_VERSION: u32 = 1;

/// The MCAP metadata record that says what a file is.
pub const METADATA_NAME: &str = "mmt.recording";

/// The MCAP library string (the header's `library` field).
pub const LIBRARY: &str = concat!("mmt-record ", env!("CARGO_PKG_VERSION"));

/// Which run made the recording.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    /// `operator run`: the operator's side of a networked run.
    Operator,
    /// `telerobot run`: the telerobot's side.
    Telerobot,
    /// The networked demo: both sides, one process.
    Demo,
    /// `mmt experiment`: both nodes in-process on a simulated clock.
    Experiment,
}

impl Kind {
    /// Every kind.
    pub const ALL: [Kind; 4] = [
        Kind::Operator,
        Kind::Telerobot,
        Kind::Demo,
        Kind::Experiment,
    ];

    /// Its name in files and messages.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Operator => "operator",
            Kind::Telerobot => "telerobot",
            Kind::Demo => "demo",
            Kind::Experiment => "experiment",
        }
    }

    /// Parses [`Kind::name`].
    pub fn parse(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The recording has the operator's haptic-loop ticks.
    pub fn has_operator(self) -> bool {
        self != Kind::Telerobot
    }

    /// The recording has the telerobot's loop ticks.
    pub fn has_telerobot(self) -> bool {
        self != Kind::Operator
    }
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What the file says about itself (the `mmt.recording` metadata record, written first).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Header {
    /// [`FORMAT_VERSION`] of the writer.
    pub format_version: u32,
    /// The run's kind.
    pub kind: Kind,
    /// The writer's crate version.
    pub mmt_version: String,
    /// Wall time at the start \[ns since the Unix epoch\].
    pub created_unix_ns: u64,
    /// The producer clock's reading at `created_unix_ns` \[ns\]: a message stamped `t` on that
    /// clock is logged at `created_unix_ns + (t − clock_origin_ns)`.
    pub clock_origin_ns: i64,
}

/// Which side of the system a message comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Side {
    /// The operator app (or the operator node of an experiment).
    Operator,
    /// The telerobot daemon (or the telerobot node of an experiment).
    Telerobot,
}

/// The topics of a recording.
pub mod topic {
    /// [`super::RunStart`]: what ran, once per side (JSON).
    pub const RUN: &str = "/run";
    /// [`super::RunEnd`]: what only the end knows, once per side; the last one counts (JSON).
    pub const RUN_END: &str = "/run/end";
    /// [`super::OperatorTick`]: every haptic-loop tick (JSON, 1 kHz).
    pub const OPERATOR_TICK: &str = "/operator/tick";
    /// [`super::MeasurementRec`]: every telerobot measurement the operator received (JSON).
    pub const OPERATOR_MEASUREMENT: &str = "/operator/measurement";
    /// [`super::ParametersRec`]: parameters the haptic loop took (JSON).
    pub const OPERATOR_PARAMETERS: &str = "/operator/parameters";
    /// [`super::ContactRec`]: the telerobot's contact states the haptic loop took (JSON).
    pub const OPERATOR_CONTACT: &str = "/operator/contact";
    /// [`super::StateSyncRec`]: state syncs the haptic loop took (JSON).
    pub const OPERATOR_STATE_SYNC: &str = "/operator/state_sync";
    /// [`super::LinkRec`]: the operator's link statistics, 10 Hz (JSON).
    pub const OPERATOR_LINK: &str = "/operator/link";
    /// Point-cloud frames the operator received (`foxglove.PointCloud`).
    pub const OPERATOR_CLOUD: &str = "/operator/cloud";
    /// [`super::TelerobotTick`]: every telerobot-loop tick (JSON, 1 kHz).
    pub const TELEROBOT_TICK: &str = "/telerobot/tick";
    /// [`super::ParametersRec`]: parameters the telerobot sent (JSON).
    pub const TELEROBOT_PARAMETERS: &str = "/telerobot/parameters";
    /// [`super::ContactRec`]: the telerobot's contact state, every tick (JSON).
    pub const TELEROBOT_CONTACT: &str = "/telerobot/contact";
    /// [`super::StateSyncRec`]: state syncs the telerobot sent (JSON).
    pub const TELEROBOT_STATE_SYNC: &str = "/telerobot/state_sync";
    /// [`super::LinkRec`]: the telerobot's link statistics, 10 Hz (JSON).
    pub const TELEROBOT_LINK: &str = "/telerobot/link";
    /// Camera frames the telerobot took (`foxglove.PointCloud`).
    pub const TELEROBOT_CLOUD: &str = "/telerobot/cloud";
    /// The 3-D scene at display rate (`foxglove.SceneUpdate`).
    pub const SCENE: &str = "/scene";
    /// The surface frame (`foxglove.FrameTransform`, `world` → `surface`).
    pub const TF: &str = "/tf";
    /// Safety, device, session and recording events (`foxglove.Log`).
    pub const EVENTS: &str = "/events";
}

/// What ran: written when a side's loop starts.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RunStart {
    /// The side.
    pub side: Side,
    /// Report name: `networked`, `demo`, `exp1`, … (`telerobot` for the daemon).
    pub experiment: String,
    /// Tick 0's time \[ns, the side's clock\].
    pub start_ns: i64,
    /// Tick period \[ns\].
    pub period_ns: i64,
    /// Scene name.
    pub scene_name: String,
    /// Terms the scene's model leaves out.
    pub left_out: Vec<String>,
    /// Radii `[r1, r2, r3]` of the contact detector \[m\] (the proxy sphere is drawn with r1).
    pub proxy_radii_m: [f64; 3],
    /// The device (`scripted:exp1`, …) or trajectory of the operator side.
    pub device: Option<String>,
    /// Seed of the simulated telerobot, if known.
    pub seed: Option<u64>,
    /// The set one-way delay, if known \[ms\].
    pub set_delay_ms: Option<f64>,
    /// The scene (`sim::scene::Scene` as JSON), where this side knows it: the telerobot, the demo
    /// and experiments.
    #[schemars(with = "serde_json::Value")]
    pub scene: Option<sim::scene::Scene>,
    /// An experiment's settings (`lab::experiment::ExperimentConfig` as JSON).
    pub config: Option<serde_json::Value>,
    /// The series' axes, `[tangent2, normal]` (experiments: the scene's; networked runs take
    /// the last surface frame, from [`RunEnd`]).
    pub axes: Option<[[f64; 3]; 2]>,
    /// Where the telerobot's tool started \[m\] (its node's first proxy position).
    pub tool_start_m: Option<[f64; 3]>,
}

/// What only the end of a run knows (counters, final estimates), so that a report computed again
/// from the recording is complete.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct RunEnd {
    /// The side.
    pub side: Side,
    /// Ticks run.
    pub ticks: u64,
    /// The nodes' counters and the final parameters against a known truth.
    #[schemars(with = "serde_json::Value")]
    pub nodes: Option<metrics::NodeInfo>,
    /// The newest surface frame the operator received (the report's axes).
    pub frame: Option<FrameRec>,
    /// The operator's clock offset at the end (telerobot − operator) \[ns\].
    pub final_offset_ns: Option<i64>,
    /// The rest of the run's report: the counters only the end knows (loop timing, link,
    /// safety, device, …), as the run wrote them.
    pub counters: Option<serde_json::Value>,
    /// Messages the recorder had dropped by then (a full queue): a report computed from the
    /// recording may then differ from the run's.
    pub recorder_dropped: u64,
}

/// An event for the log (`foxglove.Log`).
#[derive(Clone, Debug, PartialEq)]
pub struct EventRec {
    /// Level.
    pub level: Level,
    /// Who: `safety`, `device`, `session`, `recorder`, ….
    pub source: &'static str,
    /// What happened.
    pub text: String,
}

/// An event's level (`foxglove.Log.Level`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// Information.
    Info,
    /// A warning: a rule acting, a fault.
    Warning,
    /// An error.
    Error,
}

/// A point-cloud frame.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudRec {
    /// Frame number.
    pub frame_id: u64,
    /// Capture time \[ns, the telerobot's clock\].
    pub timestamp_ns: i64,
    /// Points in the world frame \[m\].
    pub points: Arc<Vec<[f32; 3]>>,
}

/// One recorded message.
#[derive(Clone, Debug, PartialEq)]
pub enum Message {
    /// `/run`.
    Run(Box<RunStart>),
    /// `/run/end`.
    RunEnd(Box<RunEnd>),
    /// `/operator/tick`.
    OperatorTick(Box<OperatorTick>),
    /// `/operator/measurement`.
    Measurement(Box<MeasurementRec>),
    /// `/{side}/parameters`.
    Parameters(Side, Box<ParametersRec>),
    /// `/{side}/contact`.
    Contact(Side, Box<ContactRec>),
    /// `/{side}/state_sync`.
    StateSync(Side, Box<StateSyncRec>),
    /// `/telerobot/tick`.
    TelerobotTick(Box<TelerobotTick>),
    /// `/{side}/link`.
    Link(Side, Box<LinkRec>),
    /// `/{side}/cloud`.
    Cloud(Side, CloudRec),
    /// `/events`.
    Event(EventRec),
}

impl Message {
    /// The topic it is recorded on.
    pub fn topic(&self) -> &'static str {
        use Side::{Operator as O, Telerobot as T};
        match self {
            Message::Run(_) => topic::RUN,
            Message::RunEnd(_) => topic::RUN_END,
            Message::OperatorTick(_) => topic::OPERATOR_TICK,
            Message::Measurement(_) => topic::OPERATOR_MEASUREMENT,
            Message::Parameters(O, _) => topic::OPERATOR_PARAMETERS,
            Message::Parameters(T, _) => topic::TELEROBOT_PARAMETERS,
            Message::Contact(O, _) => topic::OPERATOR_CONTACT,
            Message::Contact(T, _) => topic::TELEROBOT_CONTACT,
            Message::StateSync(O, _) => topic::OPERATOR_STATE_SYNC,
            Message::StateSync(T, _) => topic::TELEROBOT_STATE_SYNC,
            Message::TelerobotTick(_) => topic::TELEROBOT_TICK,
            Message::Link(O, _) => topic::OPERATOR_LINK,
            Message::Link(T, _) => topic::TELEROBOT_LINK,
            Message::Cloud(O, _) => topic::OPERATOR_CLOUD,
            Message::Cloud(T, _) => topic::TELEROBOT_CLOUD,
            Message::Event(_) => topic::EVENTS,
        }
    }
}

/// A message and when it happened \[ns, the producer's clock\].
#[derive(Clone, Debug, PartialEq)]
pub struct Timed {
    /// When.
    pub t_ns: i64,
    /// What.
    pub message: Message,
}

/// The JSON Schema of a recorded type, as Foxglove reads it.
pub(crate) fn json_schema<T: JsonSchema>() -> Vec<u8> {
    serde_json::to_vec(&schemars::schema_for!(T)).unwrap_or_else(|_| b"{}".to_vec())
}

/// The schema name and JSON Schema of a JSON topic's type.
pub(crate) fn json_topic_schema(topic: &str) -> Option<(&'static str, Vec<u8>)> {
    Some(match topic {
        topic::RUN => ("mmt.RunStart", json_schema::<RunStart>()),
        topic::RUN_END => ("mmt.RunEnd", json_schema::<RunEnd>()),
        topic::OPERATOR_TICK => ("mmt.OperatorTick", json_schema::<OperatorTick>()),
        topic::OPERATOR_MEASUREMENT => ("mmt.Measurement", json_schema::<MeasurementRec>()),
        topic::OPERATOR_PARAMETERS | topic::TELEROBOT_PARAMETERS => {
            ("mmt.Parameters", json_schema::<ParametersRec>())
        }
        topic::OPERATOR_CONTACT | topic::TELEROBOT_CONTACT => {
            ("mmt.Contact", json_schema::<ContactRec>())
        }
        topic::OPERATOR_STATE_SYNC | topic::TELEROBOT_STATE_SYNC => {
            ("mmt.StateSync", json_schema::<StateSyncRec>())
        }
        topic::TELEROBOT_TICK => ("mmt.TelerobotTick", json_schema::<TelerobotTick>()),
        topic::OPERATOR_LINK | topic::TELEROBOT_LINK => ("mmt.Link", json_schema::<LinkRec>()),
        _ => return None,
    })
}
