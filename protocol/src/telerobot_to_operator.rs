//! Messages the telerobot sends to the operator, and their encode/decode pair.
//!
//! | message | transport | rate |
//! |---|---|---|
//! | [`Welcome`] / [`Refused`] | reliable control stream, answer to `Hello` | once |
//! | [`Parameters`] | datagram | when the estimate changes, up to the loop rate |
//! | [`Contact`] | datagram | telerobot loop rate (1 kHz) |
//! | [`StateSync`] | datagram | telerobot loop rate or lower |
//! | [`Measurement`] | datagram | loop rate, for logs and reports |
//! | [`CloudFrame`] | a unidirectional stream per frame | camera rate |
//! | [`Pong`] | datagram | one per `Ping` |
//!
//! Vectors are in the telerobot's world frame unless a doc says otherwise; times are on the
//! telerobot's clock \[ns\] except `command_sample_time_ns`, which repeats the operator's
//! `Command.header.sample_time_ns` (operator clock) so the operator can line results up with its
//! own input history without knowing the clock offset.

use serde::{Deserialize, Serialize};

use crate::codec::{self, Direction};
use crate::finite::{self, CheckFinite, NonFinite};
use crate::header::Header;
pub use crate::model::{ModelStructure, ModelTerms, ParameterSet};
use crate::sequence::{Arrival, LatestSeq};

/// Everything the telerobot sends. The variant order is part of the wire format.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Message {
    /// The session is accepted; see [`crate::handshake`].
    Welcome(Welcome),
    /// The session is refused; the telerobot closes the connection after sending it.
    Refused(Refused),
    /// The current environment model.
    Parameters(Parameters),
    /// The telerobot's contact state for a command.
    Contact(Contact),
    /// The remote model's mass state, for drift correction of the local one.
    StateSync(StateSync),
    /// What the robot measured, for logs and reports.
    Measurement(Measurement),
    /// One point-cloud frame.
    Cloud(CloudFrame),
    /// Answer to a `Ping`.
    Pong(Pong),
}

/// Accepts a `Hello`: the protocol version and what the scene needs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Welcome {
    /// The protocol version the telerobot speaks.
    pub version: u16,
    /// What the operator must render and at which rates.
    pub scene: SceneSummary,
}

/// The part of the telerobot's scene the operator needs to set up its renderer.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneSummary {
    /// The scene's name (its file stem), for logs and reports.
    pub name: String,
    /// Model structure along the contact normal.
    pub normal: ModelStructure,
    /// Model structure along the two tangents (both share it).
    pub tangential: ModelStructure,
    /// Rate of the telerobot's control loop and of its datagrams \[Hz\] (thesis: 1000).
    pub control_rate_hz: f64,
    /// Rate of point-cloud frames \[Hz\]; `None` when the scene has no cloud or the operator did not
    /// ask for one.
    pub cloud_rate_hz: Option<f64>,
    /// Human-readable names of the model terms the scene leaves out (e.g. `ground spring k1`).
    pub left_out: Vec<String>,
    /// Radii `[r1, r2, r3]` of the telerobot's contact detector \[m\] (thesis appendix C). The
    /// operator's local detector uses the same, so both make and break contact at the same
    /// distance from the cloud.
    pub proxy_radii_m: [f64; 3],
    /// The scene's prior of its object, when it declares one (protocol 4).
    pub prior: Option<ScenePrior>,
    /// The cloud is the object's own surface and moves with it as it slides (a simulated or file
    /// cloud with `moving = true`; protocol 5). The operator then moves each frame by the slide
    /// its local model predicts since the frame was captured (issue 13 item 6). `false` for a
    /// cloud that holds anything else (a camera's whole view: the table does not slide).
    pub cloud_follows_object: bool,
}

/// A scene's prior of its object (issue 13: an informed guess, e.g. from vision): what the
/// operator renders from the first tick of contact until the telerobot's first model, unless
/// its user chose another. Already weighed against the generic soft-object class by the
/// telerobot (`mmt::model::prior::Guess::prior`); the operator checks it is passive.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ScenePrior {
    /// Along the normal: stiffness `k` \[N/m\].
    pub normal_k_n_per_m: f64,
    /// Along the normal: damping `b` \[N·s/m\].
    pub normal_b_ns_per_m: f64,
    /// Along the tangents: mass `m` \[kg\].
    pub mass_kg: f64,
    /// Ground spring `k1` \[N/m\].
    pub k_ground_n_per_m: f64,
    /// Ground damper `b1` \[N·s/m\].
    pub b_ground_ns_per_m: f64,
    /// Contact spring `k2` \[N/m\].
    pub k_contact_n_per_m: f64,
    /// Contact damper `b2` \[N·s/m\].
    pub b_contact_ns_per_m: f64,
    /// Coulomb friction level `Fc` \[N\].
    pub coulomb_n: f64,
}

/// Refuses a `Hello`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Refused {
    /// Why.
    pub reason: Refusal,
}

/// Why the telerobot refused a session. Its `Display` is the sentence to show the operator.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
pub enum Refusal {
    /// The two builds speak different protocol versions.
    #[error("protocol version mismatch: telerobot speaks {ours}, operator speaks {theirs}")]
    VersionMismatch {
        /// The telerobot's version.
        ours: u16,
        /// The operator's version.
        theirs: u16,
    },
    /// Another operator is in control (one controlling operator at a time).
    #[error("telerobot is busy: {controlling_operator} is in control")]
    Busy {
        /// The `operator_name` of the operator in control.
        controlling_operator: String,
    },
    /// Anything else, said in words.
    #[error("refused: {0}")]
    Other(String),
}

/// The current environment model (a datagram).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Parameters {
    /// `sample_time_ns` is the newest data either set was estimated from.
    pub header: Header,
    /// Increments when the estimator starts a new object model (covariance reset on a new
    /// object, `DESIGN.md` §11.3); the operator then restarts its model state (§11.5).
    pub model_id: u32,
    /// Normal-axis set; `None` until one passes the gates (render nothing new meanwhile).
    pub normal: Option<ParameterSet>,
    /// Tangential set (both tangents); `None` until one passes the gates.
    pub tangential: Option<ParameterSet>,
}

/// The proxy contact detector's state (thesis appendix C).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ContactState {
    /// The tool is away from the surface.
    Free,
    /// The tool touches the surface.
    Contact,
    /// The tool has pushed through the proxy's outer sphere into the cloud.
    Entrenched,
}

/// An orthonormal frame at the contact: normal out of the surface and two tangents
/// [unit vectors, world frame].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfaceFrame {
    /// Surface normal, pointing out of the object \[unit\].
    pub normal: [f64; 3],
    /// First tangent \[unit\].
    pub tangent1: [f64; 3],
    /// Second tangent, `normal × tangent1` \[unit\].
    pub tangent2: [f64; 3],
}

/// The telerobot's contact state for one operator command (a datagram).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    /// `sample_time_ns` is when the contact state was computed.
    pub header: Header,
    /// Sample time of the operator command the state was computed for [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// Free, contact or entrenched.
    pub state: ContactState,
    /// Position of the proxy (the tool's constrained stand-in) \[m\].
    pub proxy_position_m: [f64; 3],
    /// Contact normal \[unit\]; `None` when free.
    pub normal: Option<[f64; 3]>,
    /// Surface frame the parameters are identified in; `None` when free.
    pub frame: Option<SurfaceFrame>,
    /// Closest surface point, the rest position of the normal axis \[m\]; `None` when free.
    pub surface_point_m: Option<[f64; 3]>,
    /// Depth of the tool below the surface along the normal \[m\]; `None` when free.
    pub penetration_m: Option<f64>,
}

/// State of one tangential axis of the sliding-mass model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisState {
    /// Contact deflection `δ = x − L − x_m` along the tangent: how far the contact element is
    /// stretched, the state the force depends on (`F_op = k2 δ + b2 δ̇`) \[m\]. (The field was
    /// misnamed `mass_position_m`; the telerobot always sent the deflection, and the encoding is
    /// the same.)
    pub deflection_m: f64,
    /// Mass velocity `ẋ_m` along the tangent \[m/s\].
    pub mass_velocity_m_per_s: f64,
}

/// The remote model's state at a command's sample time, for the operator's rewind-and-replay
/// drift correction (`DESIGN.md` §6, §11.6) (a datagram).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct StateSync {
    /// `sample_time_ns` is when the state was computed.
    pub header: Header,
    /// Sample time of the operator command the state belongs to [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// Mass state along `tangent1` and `tangent2` of the current surface frame.
    pub tangential: [AxisState; 2],
    /// Whether the telerobot was in contact at that time.
    pub in_contact: bool,
    /// Sample time of the command at which the current contact episode began [ns, operator
    /// clock]; `None` out of contact.
    pub episode_onset_ns: Option<i64>,
}

/// What the robot measured at one tick, for logs and reports (a datagram).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// `sample_time_ns` is the sensor time.
    pub header: Header,
    /// Sample time of the operator command being executed [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// Measured tool position \[m\].
    pub position_m: [f64; 3],
    /// Measured tool velocity \[m/s\].
    pub velocity_m_per_s: [f64; 3],
    /// Force the environment exerts on the tool (`F = −F_op`, the sign convention of
    /// `mmt::model`) \[N\].
    pub force_on_tool_n: [f64; 3],
    /// Whether the robot was in contact.
    pub in_contact: bool,
    /// Whether the telerobot's estimators all pass every gate, the confidence gate included
    /// (`DESIGN.md` §11.4): the report's "time to stable parameters".
    pub estimator_stable: bool,
    /// This tick's terms of the tangential estimator's a-priori reconstruction error, while it
    /// is learning and confident: `[Σ y², Σ (y − ψᵀθ̂)²]` over the tick's axes, `θ̂` from before
    /// the update; `None` otherwise. Summed over a run, `100·√(Σe/Σy)` is the reconstruction
    /// error \[%\] (thesis: about 5 %).
    pub reconstruction: Option<[f64; 2]>,
}

/// One point-cloud frame, sent alone on its own stream.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CloudFrame {
    /// Frame number, increasing; a receiver drops a frame older than the one it has.
    pub frame_id: u64,
    /// When the sensor captured the frame [ns, telerobot clock].
    pub timestamp_ns: i64,
    /// Sensor position \[m\].
    pub sensor_position_m: [f64; 3],
    /// Sensor orientation, unit quaternion `[x, y, z, w]`.
    pub sensor_orientation_xyzw: [f64; 4],
    /// Points in the world frame \[m\], single precision (≈ 0.1 µm at 1 m); at most
    /// [`crate::MAX_CLOUD_POINTS`].
    pub points: Vec<[f32; 3]>,
}

/// Answer to a `Ping` (network notes §5.2).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Pong {
    /// The ping's `id`.
    pub id: u64,
    /// The ping's `t1_ns` [ns, operator clock].
    pub t1_ns: i64,
    /// When the telerobot received the ping [ns, telerobot clock].
    pub t2_ns: i64,
    /// When the telerobot sent this answer [ns, telerobot clock].
    pub t3_ns: i64,
}

/// The datagrams the telerobot node emits: the [`Message`] kinds that hold no heap data, so the
/// real-time loop can queue one without allocating. Encoded exactly as the matching [`Message`]
/// variant ([`encode_datagram_into`]), so the receiver decodes a [`Message`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Datagram {
    /// The current environment model.
    Parameters(Parameters),
    /// The contact state for a command.
    Contact(Contact),
    /// The remote model's mass state.
    StateSync(StateSync),
    /// What the robot measured.
    Measurement(Measurement),
}

impl Datagram {
    /// The header (its `sample_time_ns` set by the node; the rest stamped by the session).
    pub fn header(&self) -> &Header {
        match self {
            Datagram::Parameters(m) => &m.header,
            Datagram::Contact(m) => &m.header,
            Datagram::StateSync(m) => &m.header,
            Datagram::Measurement(m) => &m.header,
        }
    }

    /// The header, to stamp.
    pub fn header_mut(&mut self) -> &mut Header {
        match self {
            Datagram::Parameters(m) => &mut m.header,
            Datagram::Contact(m) => &mut m.header,
            Datagram::StateSync(m) => &mut m.header,
            Datagram::Measurement(m) => &mut m.header,
        }
    }
}

impl From<Datagram> for Message {
    fn from(d: Datagram) -> Message {
        match d {
            Datagram::Parameters(m) => Message::Parameters(m),
            Datagram::Contact(m) => Message::Contact(m),
            Datagram::StateSync(m) => Message::StateSync(m),
            Datagram::Measurement(m) => Message::Measurement(m),
        }
    }
}

/// Serialised as the [`Message`] variant of the same name and index (the wire format's).
impl Serialize for Datagram {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self {
            Datagram::Parameters(m) => s.serialize_newtype_variant("Message", 2, "Parameters", m),
            Datagram::Contact(m) => s.serialize_newtype_variant("Message", 3, "Contact", m),
            Datagram::StateSync(m) => s.serialize_newtype_variant("Message", 4, "StateSync", m),
            Datagram::Measurement(m) => s.serialize_newtype_variant("Message", 5, "Measurement", m),
        }
    }
}

/// Encodes a datagram into `buf` (cleared first): the same bytes as [`encode_into`] of the
/// matching [`Message`], without building one.
pub fn encode_datagram_into(datagram: &Datagram, buf: &mut Vec<u8>) {
    codec::encode_into(datagram, buf);
}

/// The operator's rule for which of the telerobot's datagrams it uses, applied by its network
/// task and by the in-process harness alike: a datagram the session saw for the first time
/// ([`Arrival::Newer`] or [`Arrival::Late`]: duplicates, implausible and too old ones never are),
/// and, for the latest-value kinds (`Parameters`, `Contact`, `StateSync`), only if it is the
/// newest of its kind — a `Contact` reordered behind a newer `Parameters` is late for the
/// direction yet still the newest `Contact`. Messages without a header (clouds, `Pong`, the
/// handshake) are not the session's business and are always admitted here.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Admission {
    latest: [LatestSeq; 3],
}

impl Admission {
    /// Whether to use `message`, whose header the session judged `arrival`.
    pub fn admit(&mut self, message: &Message, arrival: Arrival) -> bool {
        let first_time = matches!(arrival, Arrival::Newer { .. } | Arrival::Late);
        let kind = match message {
            Message::Parameters(_) => 0,
            Message::Contact(_) => 1,
            Message::StateSync(_) => 2,
            Message::Measurement(_) => return first_time,
            Message::Welcome(_) | Message::Refused(_) | Message::Cloud(_) | Message::Pong(_) => {
                return true;
            }
        };
        let seq = message.header().map_or(0, |h| h.seq);
        first_time && self.latest[kind].admit(seq)
    }
}

impl Message {
    /// The variant's name, for logs and errors.
    pub fn kind(&self) -> &'static str {
        match self {
            Message::Welcome(_) => "Welcome",
            Message::Refused(_) => "Refused",
            Message::Parameters(_) => "Parameters",
            Message::Contact(_) => "Contact",
            Message::StateSync(_) => "StateSync",
            Message::Measurement(_) => "Measurement",
            Message::Cloud(_) => "Cloud",
            Message::Pong(_) => "Pong",
        }
    }

    /// The datagram header, for the messages that are datagrams.
    pub fn header(&self) -> Option<&Header> {
        match self {
            Message::Parameters(m) => Some(&m.header),
            Message::Contact(m) => Some(&m.header),
            Message::StateSync(m) => Some(&m.header),
            Message::Measurement(m) => Some(&m.header),
            Message::Welcome(_) | Message::Refused(_) | Message::Cloud(_) | Message::Pong(_) => {
                None
            }
        }
    }

    /// The first NaN or ±∞ in the message, with its field; what the peer's decoder would refuse.
    pub fn check_finite(&self) -> Result<(), NonFinite> {
        CheckFinite::check_finite(self)
    }
}

impl CheckFinite for Message {
    fn check_finite(&self) -> Result<(), NonFinite> {
        let (name, result) = match self {
            Message::Welcome(m) => ("Welcome.scene", check_scene(&m.scene)),
            Message::Parameters(m) => ("Parameters", check_parameters(m)),
            Message::Contact(m) => ("Contact", check_contact(m)),
            Message::StateSync(m) => ("StateSync", check_state_sync(m)),
            Message::Measurement(m) => ("Measurement", check_measurement(m)),
            Message::Cloud(m) => ("Cloud", check_cloud(m)),
            Message::Refused(_) | Message::Pong(_) => return Ok(()),
        };
        result.map_err(|e| e.within(name))
    }
}

fn check_scene(s: &SceneSummary) -> Result<(), NonFinite> {
    finite::scalar("control_rate_hz", s.control_rate_hz)?;
    finite::opt_scalar("cloud_rate_hz", s.cloud_rate_hz)?;
    finite::vector("proxy_radii_m", &s.proxy_radii_m)?;
    let Some(p) = &s.prior else { return Ok(()) };
    let terms = [
        ("prior.normal_k_n_per_m", p.normal_k_n_per_m),
        ("prior.normal_b_ns_per_m", p.normal_b_ns_per_m),
        ("prior.mass_kg", p.mass_kg),
        ("prior.k_ground_n_per_m", p.k_ground_n_per_m),
        ("prior.b_ground_ns_per_m", p.b_ground_ns_per_m),
        ("prior.k_contact_n_per_m", p.k_contact_n_per_m),
        ("prior.b_contact_ns_per_m", p.b_contact_ns_per_m),
        ("prior.coulomb_n", p.coulomb_n),
    ];
    terms
        .into_iter()
        .try_for_each(|(name, v)| finite::scalar(name, v))
}

fn check_parameters(p: &Parameters) -> Result<(), NonFinite> {
    let check = |name: &str, set: &Option<ParameterSet>| {
        set.as_ref()
            .map_or(Ok(()), |s| s.check_finite().map_err(|e| e.within(name)))
    };
    check("normal", &p.normal)?;
    check("tangential", &p.tangential)
}

fn check_contact(c: &Contact) -> Result<(), NonFinite> {
    finite::vector("proxy_position_m", &c.proxy_position_m)?;
    finite::opt_vector("normal", &c.normal)?;
    if let Some(f) = &c.frame {
        finite::vector("frame.normal", &f.normal)?;
        finite::vector("frame.tangent1", &f.tangent1)?;
        finite::vector("frame.tangent2", &f.tangent2)?;
    }
    finite::opt_vector("surface_point_m", &c.surface_point_m)?;
    finite::opt_scalar("penetration_m", c.penetration_m)
}

fn check_state_sync(s: &StateSync) -> Result<(), NonFinite> {
    for (axis, name) in s.tangential.iter().zip(["tangential[0]", "tangential[1]"]) {
        finite::scalar("deflection_m", axis.deflection_m)
            .and_then(|()| finite::scalar("mass_velocity_m_per_s", axis.mass_velocity_m_per_s))
            .map_err(|e| e.within(name))?;
    }
    Ok(())
}

fn check_measurement(m: &Measurement) -> Result<(), NonFinite> {
    finite::vector("position_m", &m.position_m)?;
    finite::vector("velocity_m_per_s", &m.velocity_m_per_s)?;
    finite::vector("force_on_tool_n", &m.force_on_tool_n)?;
    m.reconstruction
        .map_or(Ok(()), |r| finite::vector("reconstruction", &r))
}

fn check_cloud(c: &CloudFrame) -> Result<(), NonFinite> {
    finite::vector("sensor_position_m", &c.sensor_position_m)?;
    finite::vector("sensor_orientation_xyzw", &c.sensor_orientation_xyzw)?;
    finite::points("points", &c.points)
}

codec::direction_codec!(Direction::TelerobotToOperator);
