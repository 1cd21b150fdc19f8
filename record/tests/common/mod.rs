//! Messages to record in the tests: deterministic, every field set, floats that exercise the
//! JSON round trip (subnormals, long mantissas, negative zero).
#![allow(dead_code)]

use std::sync::Arc;

use record::schema::{
    CloudRec, ContactRec, ContactStateRec, EstimatorRec, EventRec, FrameRec, Level, MeasurementRec,
    OperatorTick, ParameterSetRec, ParametersRec, RunEnd, RunStart, SafetyFlags, StructureRec,
    TelerobotTick,
};
use record::{Message, Side, Timed};

/// A float with a long mantissa, different per `k` and `i`.
pub fn f(k: u64, i: u64) -> f64 {
    let x = (k as f64 * 0.001 + i as f64 * 0.1).sin() / 3.0;
    if k.is_multiple_of(97) { 5e-324 } else { x }
}

pub fn v3(k: u64, i: u64) -> [f64; 3] {
    [f(k, i), f(k, i + 1), -f(k, i + 2)]
}

pub fn run_start(side: Side) -> RunStart {
    RunStart {
        side,
        experiment: "exp3".into(),
        start_ns: 1_000_000_000,
        period_ns: 1_000_000,
        scene_name: "exp1".into(),
        left_out: vec!["ground spring k1".into()],
        proxy_radii_m: [0.004, 0.006, 0.03],
        device: Some("scripted:exp1".into()),
        seed: Some(7),
        set_delay_ms: Some(400.0),
        scene: Some(sim::scene::Scene::exp1()),
        config: Some(serde_json::json!({"seconds": 60.0})),
        axes: Some([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
        tool_start_m: Some([0.0, 0.0, 0.01]),
    }
}

pub fn operator_tick(k: u64) -> OperatorTick {
    OperatorTick {
        session: 1,
        index: k,
        sample_time_ns: 1_000_000_000 + k as i64 * 1_000_000,
        started_ns: 1_000_000_000 + k as i64 * 1_000_000 + 3_217,
        device_position_m: v3(k, 0),
        device_velocity_m_per_s: v3(k, 3),
        command_position_m: v3(k, 6),
        command_velocity_m_per_s: v3(k, 9),
        force_rendered_n: v3(k, 12),
        force_device_n: v3(k, 15),
        in_contact: k.is_multiple_of(3),
        rendering: k > 10,
        reduced: k > 10 && k < 20,
        proxy_m: (!k.is_multiple_of(5)).then(|| v3(k, 18)),
        safety: SafetyFlags {
            bits: (k % 7) as u32,
        },
        device_faults: k / 1000,
        remote_force_n: Some([-0.0, f(k, 21), 1e300]),
        remote_in_contact: Some(k.is_multiple_of(2)),
        tangential_state: [Some([f(k, 22), f(k, 23)]), None],
    }
}

pub fn telerobot_tick(k: u64) -> TelerobotTick {
    TelerobotTick {
        session: 1,
        index: k,
        t_ns: 5_000_000_000 + k as i64 * 1_000_000,
        target_position_m: v3(k, 30),
        target_velocity_m_per_s: v3(k, 33),
        command_sample_time_ns: 1_000_000_000 + k as i64 * 1_000_000 - 400_000_000,
        holding: k < 5,
        position_m: v3(k, 36),
        velocity_m_per_s: v3(k, 39),
        force_on_tool_n: v3(k, 42),
        tool_m: v3(k, 45),
        object_slide_m: [f(k, 48), f(k, 49)],
        cloud_captured_ns: k.is_multiple_of(33).then_some(k as i64 * 1_000_000),
        in_contact: !k.is_multiple_of(4),
        estimator_stable: k > 100,
        reconstruction: k.is_multiple_of(2).then(|| [f(k, 50), f(k, 51)]),
        estimator_normal: None,
        estimator_tangential: Some(EstimatorRec {
            phase: "learning".into(),
            confident: k > 100,
            model_id: 1,
            relative_error: Some(f(k, 52)),
            confirmed: k.is_multiple_of(10),
            rejected_by: (k % 10 == 5).then(|| "not passive: d > 0".into()),
            confidence: k.is_multiple_of(10).then(|| "identified".into()),
            condition: Some(3.5),
            residual: Some(f(k, 53)),
            new_object: false,
        }),
        true_force_n: Some(v3(k, 54)),
        true_in_contact: Some(true),
        true_state: Some([[f(k, 57), f(k, 58)], [f(k, 59), f(k, 60)]]),
    }
}

pub fn measurement(k: u64) -> MeasurementRec {
    MeasurementRec {
        session: 1,
        received_ns: 1_400_000_000 + k as i64 * 1_000_000,
        offset_ns: (k > 3).then_some(123_456),
        latency_ms: Some(400.123),
        seq: k + 1,
        sample_time_ns: 5_000_000_000 + k as i64 * 1_000_000,
        send_time_ns: 5_000_000_000 + k as i64 * 1_000_000 + 700,
        command_sample_time_ns: 1_000_000_000 + k as i64 * 1_000_000,
        position_m: v3(k, 61),
        velocity_m_per_s: v3(k, 64),
        force_on_tool_n: v3(k, 67),
        in_contact: k % 2 == 1,
        estimator_stable: k > 50,
        reconstruction: Some([f(k, 70), f(k, 71)]),
    }
}

pub fn parameters(k: u64) -> ParametersRec {
    ParametersRec {
        session: 1,
        sample_time_ns: k as i64,
        received_ns: Some(k as i64 + 1),
        model_id: 2,
        normal: Some(ParameterSetRec {
            structure: StructureRec::KelvinVoigt,
            sample_time_ns: k as i64,
            residual: f(k, 72),
            mass_kg: None,
            k_ground_n_per_m: None,
            b_ground_ns_per_m: None,
            k_contact_n_per_m: 1000.0 + f(k, 73),
            b_contact_ns_per_m: 30.0,
            coulomb_n: None,
        }),
        tangential: Some(ParameterSetRec {
            structure: StructureRec::SlidingMass,
            sample_time_ns: k as i64,
            residual: 0.01,
            mass_kg: Some(1.0 + f(k, 74)),
            k_ground_n_per_m: None,
            b_ground_ns_per_m: Some(60.0),
            k_contact_n_per_m: 500.0,
            b_contact_ns_per_m: 60.0,
            coulomb_n: Some(0.05),
        }),
    }
}

pub fn contact(k: u64) -> ContactRec {
    ContactRec {
        session: 1,
        sample_time_ns: k as i64,
        received_ns: None,
        command_sample_time_ns: k as i64 - 7,
        state: ContactStateRec::Contact,
        in_contact: 1,
        proxy_position_m: v3(k, 75),
        frame: Some(FrameRec {
            normal: [0.0, 0.0, 1.0],
            tangent1: [1.0, 0.0, 0.0],
            tangent2: [0.0, 1.0, 0.0],
        }),
        surface_point_m: Some(v3(k, 78)),
        penetration_m: Some(f(k, 81)),
    }
}

pub fn cloud(k: u64) -> CloudRec {
    CloudRec {
        frame_id: k,
        timestamp_ns: k as i64 * 33_000_000,
        points: Arc::new(
            (0..500)
                .map(|i| [i as f32 * 0.001, -(k as f32) * 1e-3, f(k, i) as f32])
                .collect(),
        ),
    }
}

/// `ticks` ticks of everything both sides record, in the order a run hands them over.
pub fn batches(ticks: u64) -> Vec<Vec<Timed>> {
    let mut out = vec![vec![
        Timed {
            t_ns: 0,
            message: Message::Run(Box::new(run_start(Side::Operator))),
        },
        Timed {
            t_ns: 0,
            message: Message::Run(Box::new(run_start(Side::Telerobot))),
        },
    ]];
    for chunk in (0..ticks).collect::<Vec<_>>().chunks(20) {
        let mut batch = Vec::new();
        for &k in chunk {
            let t = k as i64 * 1_000_000;
            let mut push = |message| batch.push(Timed { t_ns: t, message });
            push(Message::OperatorTick(Box::new(operator_tick(k))));
            push(Message::Measurement(Box::new(measurement(k))));
            push(Message::TelerobotTick(Box::new(telerobot_tick(k))));
            push(Message::Contact(Side::Telerobot, Box::new(contact(k))));
            if k.is_multiple_of(100) {
                push(Message::Parameters(
                    Side::Telerobot,
                    Box::new(parameters(k)),
                ));
                push(Message::Link(Side::Operator, Box::default()));
                push(Message::Event(EventRec {
                    level: Level::Warning,
                    source: "safety",
                    text: format!("tick {k}"),
                }));
            }
            if k.is_multiple_of(33) {
                push(Message::Cloud(Side::Telerobot, cloud(k)));
            }
        }
        out.push(batch);
    }
    out.push(vec![Timed {
        t_ns: ticks as i64 * 1_000_000,
        message: Message::RunEnd(Box::new(RunEnd {
            side: Side::Operator,
            ticks,
            nodes: Some(metrics::NodeInfo::default()),
            frame: None,
            final_offset_ns: Some(-5),
            counters: Some(serde_json::json!({"sessions": 1})),
            recorder_dropped: 0,
        })),
    }]);
    out
}
