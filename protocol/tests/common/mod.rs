//! Messages shared by the integration tests: one fixed sample of every kind, the largest
//! datagrams, and proptest strategies for arbitrary (finite) messages.
#![allow(dead_code)] // each test binary uses a part

use proptest::prelude::*;
use protocol::Header;
use protocol::operator_to_telerobot::{self as o2t, Command, Hello, Ping};
use protocol::telerobot_to_operator::{
    self as t2o, AxisState, CloudFrame, Contact, ContactState, Measurement, ModelStructure,
    ModelTerms, ParameterSet, Parameters, Pong, Refusal, Refused, ScenePrior, SceneSummary,
    StateSync, SurfaceFrame, Welcome,
};

/// Lower-case hex of `bytes`, for golden literals.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A header with small, distinct values.
pub fn header() -> Header {
    Header {
        seq: 1,
        sample_time_ns: 2,
        send_time_ns: 3,
        echo_seq: 4,
        echo_hold_ns: 5,
    }
}

/// The largest header: every varint at its longest.
pub fn largest_header() -> Header {
    Header {
        seq: u64::MAX,
        sample_time_ns: i64::MIN,
        send_time_ns: i64::MIN,
        echo_seq: u64::MAX,
        echo_hold_ns: u32::MAX,
    }
}

/// One operator message of each kind, simple values.
pub fn operator_samples() -> Vec<o2t::Message> {
    vec![
        o2t::Message::Hello(Hello {
            version: 1,
            operator_name: "ab".into(),
            want_clouds: true,
        }),
        o2t::Message::Command(Command {
            header: header(),
            position_m: [0.5, -0.25, 1.0],
            velocity_m_per_s: [0.0, 2.0, -1.5],
        }),
        o2t::Message::Ping(Ping { id: 7, t1_ns: 1000 }),
        o2t::Message::Bye,
    ]
}

/// One telerobot message of each kind, simple values.
pub fn telerobot_samples() -> Vec<t2o::Message> {
    vec![
        t2o::Message::Welcome(Welcome {
            version: 1,
            scene: SceneSummary {
                name: "e1".into(),
                normal: ModelStructure::KelvinVoigt,
                tangential: ModelStructure::SlidingMass {
                    ground_spring: false,
                    friction: true,
                },
                control_rate_hz: 1000.0,
                cloud_rate_hz: Some(30.0),
                left_out: vec!["k1".into()],
                proxy_radii_m: [0.5, 1.0, 2.0],
                cloud_follows_object: true,
                prior: Some(ScenePrior {
                    normal_k_n_per_m: 2.0,
                    normal_b_ns_per_m: 0.5,
                    mass_kg: 1.0,
                    k_ground_n_per_m: 0.0,
                    b_ground_ns_per_m: 0.5,
                    k_contact_n_per_m: 2.0,
                    b_contact_ns_per_m: 0.5,
                    coulomb_n: 0.25,
                }),
            },
        }),
        t2o::Message::Refused(Refused {
            reason: Refusal::VersionMismatch { ours: 1, theirs: 2 },
        }),
        t2o::Message::Parameters(Parameters {
            header: header(),
            model_id: 3,
            normal: Some(ParameterSet {
                sample_time_ns: 10,
                residual: 0.5,
                terms: ModelTerms::KelvinVoigt {
                    k_n_per_m: 500.0,
                    b_ns_per_m: 60.0,
                },
            }),
            tangential: None,
        }),
        t2o::Message::Contact(Contact {
            header: header(),
            command_sample_time_ns: -1,
            state: ContactState::Contact,
            proxy_position_m: [0.0, 0.0, 0.5],
            normal: Some([0.0, 0.0, 1.0]),
            frame: None,
            surface_point_m: None,
            penetration_m: Some(0.25),
        }),
        t2o::Message::StateSync(StateSync {
            header: header(),
            command_sample_time_ns: 6,
            tangential: [
                AxisState {
                    deflection_m: 0.125,
                    mass_velocity_m_per_s: -0.5,
                },
                AxisState {
                    deflection_m: 0.0,
                    mass_velocity_m_per_s: 0.0,
                },
            ],
            in_contact: true,
            episode_onset_ns: Some(-2),
        }),
        t2o::Message::Measurement(Measurement {
            header: header(),
            command_sample_time_ns: 6,
            position_m: [1.0, 0.0, 0.0],
            velocity_m_per_s: [0.0, 0.0, 0.0],
            force_on_tool_n: [0.0, 0.0, -2.0],
            in_contact: false,
            estimator_stable: true,
            reconstruction: Some([4.0, 0.25]),
        }),
        t2o::Message::Cloud(CloudFrame {
            frame_id: 9,
            timestamp_ns: 8,
            sensor_position_m: [0.0, 0.0, 1.0],
            sensor_orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
            points: vec![[1.0, -1.0, 0.5]],
        }),
        t2o::Message::Pong(Pong {
            id: 7,
            t1_ns: 1000,
            t2_ns: -3,
            t3_ns: 4,
        }),
    ]
}

/// Every operator datagram at its largest.
pub fn largest_operator_datagrams() -> Vec<o2t::Message> {
    vec![
        o2t::Message::Command(Command {
            header: largest_header(),
            position_m: [f64::MAX; 3],
            velocity_m_per_s: [f64::MAX; 3],
        }),
        o2t::Message::Ping(Ping {
            id: u64::MAX,
            t1_ns: i64::MIN,
        }),
    ]
}

/// Every telerobot datagram at its largest: all options present, varints longest.
pub fn largest_telerobot_datagrams() -> Vec<t2o::Message> {
    let set = ParameterSet {
        sample_time_ns: i64::MIN,
        residual: f64::MAX,
        terms: ModelTerms::SlidingMass {
            mass_kg: f64::MAX,
            k_ground_n_per_m: Some(f64::MAX),
            b_ground_ns_per_m: f64::MAX,
            k_contact_n_per_m: f64::MAX,
            b_contact_ns_per_m: f64::MAX,
            coulomb_n: Some(f64::MAX),
        },
    };
    let v = [f64::MAX; 3];
    vec![
        t2o::Message::Parameters(Parameters {
            header: largest_header(),
            model_id: u32::MAX,
            normal: Some(set),
            tangential: Some(set),
        }),
        t2o::Message::Contact(Contact {
            header: largest_header(),
            command_sample_time_ns: i64::MIN,
            state: ContactState::Entrenched,
            proxy_position_m: v,
            normal: Some(v),
            frame: Some(SurfaceFrame {
                normal: v,
                tangent1: v,
                tangent2: v,
            }),
            surface_point_m: Some(v),
            penetration_m: Some(f64::MAX),
        }),
        t2o::Message::StateSync(StateSync {
            header: largest_header(),
            command_sample_time_ns: i64::MIN,
            tangential: [AxisState {
                deflection_m: f64::MAX,
                mass_velocity_m_per_s: f64::MAX,
            }; 2],
            in_contact: true,
            episode_onset_ns: Some(i64::MIN),
        }),
        t2o::Message::Measurement(Measurement {
            header: largest_header(),
            command_sample_time_ns: i64::MIN,
            position_m: v,
            velocity_m_per_s: v,
            force_on_tool_n: v,
            in_contact: true,
            estimator_stable: true,
            reconstruction: Some([f64::MAX; 2]),
        }),
        t2o::Message::Pong(Pong {
            id: u64::MAX,
            t1_ns: i64::MIN,
            t2_ns: i64::MIN,
            t3_ns: i64::MIN,
        }),
    ]
}

// ---- proptest strategies: arbitrary messages with finite floats --------------------------------

/// Any finite f64, both signs, subnormals and zeros included.
pub fn finite() -> impl Strategy<Value = f64> + Clone {
    use proptest::num::f64::{NEGATIVE, NORMAL, POSITIVE, SUBNORMAL, ZERO};
    POSITIVE | NEGATIVE | NORMAL | SUBNORMAL | ZERO
}

fn vec3() -> impl Strategy<Value = [f64; 3]> + Clone {
    [finite(), finite(), finite()]
}

fn point() -> impl Strategy<Value = [f32; 3]> {
    use proptest::num::f32::{NEGATIVE, NORMAL, POSITIVE, SUBNORMAL, ZERO};
    let f = POSITIVE | NEGATIVE | NORMAL | SUBNORMAL | ZERO;
    [f, f, f]
}

pub fn arb_header() -> impl Strategy<Value = Header> {
    (
        any::<u64>(),
        any::<i64>(),
        any::<i64>(),
        any::<u64>(),
        any::<u32>(),
    )
        .prop_map(
            |(seq, sample_time_ns, send_time_ns, echo_seq, echo_hold_ns)| Header {
                seq,
                sample_time_ns,
                send_time_ns,
                echo_seq,
                echo_hold_ns,
            },
        )
}

fn arb_structure() -> impl Strategy<Value = ModelStructure> {
    prop_oneof![
        Just(ModelStructure::Free),
        Just(ModelStructure::KelvinVoigt),
        (any::<bool>(), any::<bool>()).prop_map(|(ground_spring, friction)| {
            ModelStructure::SlidingMass {
                ground_spring,
                friction,
            }
        }),
    ]
}

fn arb_set() -> impl Strategy<Value = ParameterSet> {
    let kv = (finite(), finite()).prop_map(|(k_n_per_m, b_ns_per_m)| ModelTerms::KelvinVoigt {
        k_n_per_m,
        b_ns_per_m,
    });
    let sm = (
        finite(),
        proptest::option::of(finite()),
        finite(),
        finite(),
        finite(),
        proptest::option::of(finite()),
    )
        .prop_map(|(m, k1, b1, k2, b2, fc)| ModelTerms::SlidingMass {
            mass_kg: m,
            k_ground_n_per_m: k1,
            b_ground_ns_per_m: b1,
            k_contact_n_per_m: k2,
            b_contact_ns_per_m: b2,
            coulomb_n: fc,
        });
    (any::<i64>(), finite(), prop_oneof![kv, sm]).prop_map(|(sample_time_ns, residual, terms)| {
        ParameterSet {
            sample_time_ns,
            residual,
            terms,
        }
    })
}

pub fn arb_operator_message() -> impl Strategy<Value = o2t::Message> {
    prop_oneof![
        (any::<u16>(), ".{0,40}", any::<bool>()).prop_map(
            |(version, operator_name, want_clouds)| {
                o2t::Message::Hello(Hello {
                    version,
                    operator_name,
                    want_clouds,
                })
            }
        ),
        (arb_header(), vec3(), vec3()).prop_map(|(header, position_m, velocity_m_per_s)| {
            o2t::Message::Command(Command {
                header,
                position_m,
                velocity_m_per_s,
            })
        }),
        (any::<u64>(), any::<i64>()).prop_map(|(id, t1_ns)| o2t::Message::Ping(Ping { id, t1_ns })),
        Just(o2t::Message::Bye),
    ]
}

fn arb_handshake() -> impl Strategy<Value = t2o::Message> {
    let scene = (
        ".{0,20}",
        arb_structure(),
        arb_structure(),
        finite(),
        proptest::option::of(finite()),
        proptest::collection::vec(".{0,10}", 0..4),
        [finite(), finite(), finite()],
        proptest::option::of(proptest::array::uniform8(finite())),
        any::<bool>(),
    )
        .prop_map(
            |(
                name,
                normal,
                tangential,
                control_rate_hz,
                cloud_rate_hz,
                left_out,
                proxy_radii_m,
                prior,
                cloud_follows_object,
            )| {
                SceneSummary {
                    name,
                    normal,
                    tangential,
                    control_rate_hz,
                    cloud_rate_hz,
                    left_out,
                    proxy_radii_m,
                    cloud_follows_object,
                    prior: prior.map(|[a, b, c, d, e, f, g, h]| ScenePrior {
                        normal_k_n_per_m: a,
                        normal_b_ns_per_m: b,
                        mass_kg: c,
                        k_ground_n_per_m: d,
                        b_ground_ns_per_m: e,
                        k_contact_n_per_m: f,
                        b_contact_ns_per_m: g,
                        coulomb_n: h,
                    }),
                }
            },
        );
    let refusal = prop_oneof![
        (any::<u16>(), any::<u16>())
            .prop_map(|(ours, theirs)| Refusal::VersionMismatch { ours, theirs }),
        ".{0,20}".prop_map(|controlling_operator| Refusal::Busy {
            controlling_operator
        }),
        ".{0,20}".prop_map(Refusal::Other),
    ];
    prop_oneof![
        (any::<u16>(), scene)
            .prop_map(|(version, scene)| t2o::Message::Welcome(Welcome { version, scene })),
        refusal.prop_map(|reason| t2o::Message::Refused(Refused { reason })),
    ]
}

fn arb_contact() -> impl Strategy<Value = t2o::Message> {
    let state = prop_oneof![
        Just(ContactState::Free),
        Just(ContactState::Contact),
        Just(ContactState::Entrenched),
    ];
    let frame = (vec3(), vec3(), vec3()).prop_map(|(normal, tangent1, tangent2)| SurfaceFrame {
        normal,
        tangent1,
        tangent2,
    });
    (
        (arb_header(), any::<i64>(), state, vec3()),
        (
            proptest::option::of(vec3()),
            proptest::option::of(frame),
            proptest::option::of(vec3()),
            proptest::option::of(finite()),
        ),
    )
        .prop_map(
            |(
                (header, command_sample_time_ns, state, proxy_position_m),
                (normal, frame, surface_point_m, penetration_m),
            )| {
                t2o::Message::Contact(Contact {
                    header,
                    command_sample_time_ns,
                    state,
                    proxy_position_m,
                    normal,
                    frame,
                    surface_point_m,
                    penetration_m,
                })
            },
        )
}

fn arb_state_sync() -> impl Strategy<Value = t2o::Message> {
    let axis = (finite(), finite()).prop_map(|(deflection_m, mass_velocity_m_per_s)| AxisState {
        deflection_m,
        mass_velocity_m_per_s,
    });
    (
        arb_header(),
        any::<i64>(),
        [axis.clone(), axis],
        any::<bool>(),
        proptest::option::of(any::<i64>()),
    )
        .prop_map(
            |(header, command_sample_time_ns, tangential, in_contact, episode_onset_ns)| {
                t2o::Message::StateSync(StateSync {
                    header,
                    command_sample_time_ns,
                    tangential,
                    in_contact,
                    episode_onset_ns,
                })
            },
        )
}

fn arb_datagram() -> impl Strategy<Value = t2o::Message> {
    let parameters = (
        arb_header(),
        any::<u32>(),
        proptest::option::of(arb_set()),
        proptest::option::of(arb_set()),
    )
        .prop_map(|(header, model_id, normal, tangential)| {
            t2o::Message::Parameters(Parameters {
                header,
                model_id,
                normal,
                tangential,
            })
        });
    let measurement = (
        arb_header(),
        any::<i64>(),
        vec3(),
        vec3(),
        vec3(),
        any::<bool>(),
        any::<bool>(),
        proptest::option::of((finite(), finite())),
    )
        .prop_map(
            |(header, command_sample_time_ns, p, v, f, in_contact, estimator_stable, r)| {
                t2o::Message::Measurement(Measurement {
                    header,
                    command_sample_time_ns,
                    position_m: p,
                    velocity_m_per_s: v,
                    force_on_tool_n: f,
                    in_contact,
                    estimator_stable,
                    reconstruction: r.map(|(y, e)| [y, e]),
                })
            },
        );
    let pong = (any::<u64>(), any::<i64>(), any::<i64>(), any::<i64>()).prop_map(
        |(id, t1_ns, t2_ns, t3_ns)| {
            t2o::Message::Pong(Pong {
                id,
                t1_ns,
                t2_ns,
                t3_ns,
            })
        },
    );
    prop_oneof![
        parameters,
        arb_contact(),
        arb_state_sync(),
        measurement,
        pong
    ]
}

pub fn arb_telerobot_message() -> impl Strategy<Value = t2o::Message> {
    let cloud = (
        any::<u64>(),
        any::<i64>(),
        vec3(),
        [finite(), finite(), finite(), finite()],
        proptest::collection::vec(point(), 0..20),
    )
        .prop_map(
            |(frame_id, timestamp_ns, sensor_position_m, sensor_orientation_xyzw, points)| {
                t2o::Message::Cloud(CloudFrame {
                    frame_id,
                    timestamp_ns,
                    sensor_position_m,
                    sensor_orientation_xyzw,
                    points,
                })
            },
        );
    prop_oneof![arb_handshake(), arb_datagram(), cloud]
}
