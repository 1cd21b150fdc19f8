//! Recorded forms of what both sides record: parameters, contact states, state syncs, link
//! statistics, the surface frame. Flat, named fields (a plot path is `/telerobot/parameters
//! .tangential.mass_kg`); conversions to and from the wire types.

use protocol::telerobot_to_operator as wire;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// An orthonormal surface frame [unit vectors, world frame].
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct FrameRec {
    /// Surface normal, out of the object.
    pub normal: [f64; 3],
    /// First tangent.
    pub tangent1: [f64; 3],
    /// Second tangent.
    pub tangent2: [f64; 3],
}

impl From<wire::SurfaceFrame> for FrameRec {
    fn from(f: wire::SurfaceFrame) -> Self {
        FrameRec {
            normal: f.normal,
            tangent1: f.tangent1,
            tangent2: f.tangent2,
        }
    }
}

impl From<FrameRec> for wire::SurfaceFrame {
    fn from(f: FrameRec) -> Self {
        wire::SurfaceFrame {
            normal: f.normal,
            tangent1: f.tangent1,
            tangent2: f.tangent2,
        }
    }
}

/// One identified parameter set: the terms its structure has, the others absent.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ParameterSetRec {
    /// `kelvin-voigt` or `sliding-mass`.
    pub structure: StructureRec,
    /// Sample time of the newest data the set was estimated from [ns, telerobot clock].
    pub sample_time_ns: i64,
    /// Back-solve residual \[dimensionless\].
    pub residual: f64,
    /// Object mass `m` \[kg\] (sliding mass).
    pub mass_kg: Option<f64>,
    /// Ground spring `k1` \[N/m\] (sliding mass with a ground spring).
    pub k_ground_n_per_m: Option<f64>,
    /// Ground damper `b1` \[N·s/m\] (sliding mass).
    pub b_ground_ns_per_m: Option<f64>,
    /// Contact spring `k2` (sliding mass) or `k` (Kelvin–Voigt) \[N/m\].
    pub k_contact_n_per_m: f64,
    /// Contact damper `b2` (sliding mass) or `b` (Kelvin–Voigt) \[N·s/m\].
    pub b_contact_ns_per_m: f64,
    /// Coulomb friction `Fc` \[N\] (sliding mass with friction).
    pub coulomb_n: Option<f64>,
}

/// A parameter set's model structure.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum StructureRec {
    /// Kelvin–Voigt.
    KelvinVoigt,
    /// Sliding mass.
    SlidingMass,
}

impl From<&wire::ParameterSet> for ParameterSetRec {
    fn from(s: &wire::ParameterSet) -> Self {
        let base = |structure| ParameterSetRec {
            structure,
            sample_time_ns: s.sample_time_ns,
            residual: s.residual,
            mass_kg: None,
            k_ground_n_per_m: None,
            b_ground_ns_per_m: None,
            k_contact_n_per_m: 0.0,
            b_contact_ns_per_m: 0.0,
            coulomb_n: None,
        };
        match s.terms {
            wire::ModelTerms::KelvinVoigt {
                k_n_per_m,
                b_ns_per_m,
            } => ParameterSetRec {
                k_contact_n_per_m: k_n_per_m,
                b_contact_ns_per_m: b_ns_per_m,
                ..base(StructureRec::KelvinVoigt)
            },
            wire::ModelTerms::SlidingMass {
                mass_kg,
                k_ground_n_per_m,
                b_ground_ns_per_m,
                k_contact_n_per_m,
                b_contact_ns_per_m,
                coulomb_n,
            } => ParameterSetRec {
                mass_kg: Some(mass_kg),
                k_ground_n_per_m,
                b_ground_ns_per_m: Some(b_ground_ns_per_m),
                k_contact_n_per_m,
                b_contact_ns_per_m,
                coulomb_n,
                ..base(StructureRec::SlidingMass)
            },
        }
    }
}

impl ParameterSetRec {
    /// The wire form; `None` when a sliding-mass set lacks its mass or ground damper.
    pub fn to_wire(&self) -> Option<wire::ParameterSet> {
        let terms = match self.structure {
            StructureRec::KelvinVoigt => wire::ModelTerms::KelvinVoigt {
                k_n_per_m: self.k_contact_n_per_m,
                b_ns_per_m: self.b_contact_ns_per_m,
            },
            StructureRec::SlidingMass => wire::ModelTerms::SlidingMass {
                mass_kg: self.mass_kg?,
                k_ground_n_per_m: self.k_ground_n_per_m,
                b_ground_ns_per_m: self.b_ground_ns_per_m?,
                k_contact_n_per_m: self.k_contact_n_per_m,
                b_contact_ns_per_m: self.b_contact_ns_per_m,
                coulomb_n: self.coulomb_n,
            },
        };
        Some(wire::ParameterSet {
            sample_time_ns: self.sample_time_ns,
            residual: self.residual,
            terms,
        })
    }
}

/// A `Parameters` message: the current model.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ParametersRec {
    /// The operator session it belongs to (0 on the telerobot before the first operator).
    pub session: u64,
    /// When it was computed [ns, telerobot clock].
    pub sample_time_ns: i64,
    /// When the operator took it [ns, operator clock]; `None` on the telerobot.
    pub received_ns: Option<i64>,
    /// The estimator's object model number.
    pub model_id: u32,
    /// Normal-axis set.
    pub normal: Option<ParameterSetRec>,
    /// Tangential set.
    pub tangential: Option<ParameterSetRec>,
}

impl ParametersRec {
    /// From the wire message.
    pub fn new(session: u64, p: &wire::Parameters, received_ns: Option<i64>) -> Self {
        ParametersRec {
            session,
            sample_time_ns: p.header.sample_time_ns,
            received_ns,
            model_id: p.model_id,
            normal: p.normal.as_ref().map(ParameterSetRec::from),
            tangential: p.tangential.as_ref().map(ParameterSetRec::from),
        }
    }

    /// The wire message (header: the sample time only).
    pub fn to_wire(&self) -> wire::Parameters {
        wire::Parameters {
            header: protocol::Header::unstamped(self.sample_time_ns),
            model_id: self.model_id,
            normal: self.normal.and_then(|s| s.to_wire()),
            tangential: self.tangential.and_then(|s| s.to_wire()),
        }
    }
}

/// The telerobot's contact state for one command.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct ContactRec {
    /// The operator session.
    pub session: u64,
    /// When it was computed [ns, telerobot clock].
    pub sample_time_ns: i64,
    /// When the operator took it [ns, operator clock]; `None` on the telerobot.
    pub received_ns: Option<i64>,
    /// The command it was computed for [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// `free`, `contact` or `entrenched`.
    pub state: ContactStateRec,
    /// 1 in contact (either state), 0 free: for plots.
    pub in_contact: u8,
    /// The proxy's position \[m\].
    pub proxy_position_m: [f64; 3],
    /// The surface frame; `None` when free.
    pub frame: Option<FrameRec>,
    /// The closest surface point \[m\]; `None` when free.
    pub surface_point_m: Option<[f64; 3]>,
    /// Depth below the surface \[m\]; `None` when free.
    pub penetration_m: Option<f64>,
}

/// The proxy's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum ContactStateRec {
    /// Away from the surface.
    Free,
    /// Touching.
    Contact,
    /// Pushed through the outer sphere.
    Entrenched,
}

impl ContactRec {
    /// From the wire message.
    pub fn new(session: u64, c: &wire::Contact, received_ns: Option<i64>) -> Self {
        let state = match c.state {
            wire::ContactState::Free => ContactStateRec::Free,
            wire::ContactState::Contact => ContactStateRec::Contact,
            wire::ContactState::Entrenched => ContactStateRec::Entrenched,
        };
        ContactRec {
            session,
            sample_time_ns: c.header.sample_time_ns,
            received_ns,
            command_sample_time_ns: c.command_sample_time_ns,
            state,
            in_contact: u8::from(state != ContactStateRec::Free),
            proxy_position_m: c.proxy_position_m,
            frame: c.frame.map(FrameRec::from),
            surface_point_m: c.surface_point_m,
            penetration_m: c.penetration_m,
        }
    }
}

/// The remote model's state for drift correction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct StateSyncRec {
    /// The operator session.
    pub session: u64,
    /// When it was computed [ns, telerobot clock].
    pub sample_time_ns: i64,
    /// When the operator took it [ns, operator clock]; `None` on the telerobot.
    pub received_ns: Option<i64>,
    /// The command it belongs to [ns, operator clock].
    pub command_sample_time_ns: i64,
    /// `[contact deflection m, mass velocity m/s]` along tangent1 and tangent2.
    pub tangential: [[f64; 2]; 2],
    /// In contact then.
    pub in_contact: bool,
    /// The episode's onset [ns, operator clock].
    pub episode_onset_ns: Option<i64>,
}

impl StateSyncRec {
    /// From the wire message.
    pub fn new(session: u64, s: &wire::StateSync, received_ns: Option<i64>) -> Self {
        StateSyncRec {
            session,
            sample_time_ns: s.header.sample_time_ns,
            received_ns,
            command_sample_time_ns: s.command_sample_time_ns,
            tangential: s
                .tangential
                .map(|a| [a.deflection_m, a.mass_velocity_m_per_s]),
            in_contact: s.in_contact,
            episode_onset_ns: s.episode_onset_ns,
        }
    }
}

/// A side's link statistics at one time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct LinkRec {
    /// A session is open.
    pub connected: bool,
    /// The session number.
    pub session: u64,
    /// Smoothed round-trip time \[ms\].
    pub rtt_ms: Option<f64>,
    /// Smallest RTT sample \[ms\].
    pub rtt_min_ms: Option<f64>,
    /// Half the smoothed RTT: the link delay one way, if symmetric \[ms\].
    pub one_way_ms: Option<f64>,
    /// Clock offset, peer minus ours \[ms\] (operator side).
    pub clock_offset_ms: Option<f64>,
    /// Datagrams sent.
    pub sent: u64,
    /// Datagrams received.
    pub received: u64,
    /// ... reordered behind a newer one.
    pub late: u64,
    /// Sequence numbers never received.
    pub lost: u64,
    /// Datagrams seen twice.
    pub duplicates: u64,
    /// Datagrams that were not messages of the direction.
    pub garbage: u64,
    /// Longest gap between accepted datagrams \[ms\].
    pub max_gap_ms: f64,
}

impl LinkRec {
    /// A side's link statistics now.
    pub fn new(connected: bool, session: u64, s: &transport::LinkSnapshot) -> Self {
        let ms = |v: Option<i64>| v.map(|ns| ns as f64 / 1e6);
        LinkRec {
            connected,
            session,
            rtt_ms: ms(s.rtt_smoothed_ns),
            rtt_min_ms: ms(s.rtt_min_ns),
            one_way_ms: ms(s.rtt_smoothed_ns.map(|r| r / 2)),
            clock_offset_ms: ms(s.clock_offset_ns),
            sent: s.sent,
            received: s.received,
            late: s.late,
            lost: s.lost,
            duplicates: s.duplicates,
            garbage: s.garbage,
            max_gap_ms: s.max_gap_ns as f64 / 1e6,
        }
    }
}
