//! `mmt experiment --record`/`--live`: what the harness hands the recorder — both nodes' ticks
//! (with the simulator's truth), the telerobot's datagrams, the camera frames, the run's start
//! and end — on the simulated clock (`t = 0` at tick 0). The harness is not a real-time loop: a
//! full recorder queue makes it wait rather than lose data.

use metrics::NodeInfo;
use node::operator::OperatorOutput;
use node::telerobot::TelerobotNode;
use node::{BridgeSample, Target};
use protocol::telerobot_to_operator::Datagram;
use record::schema::{
    CloudRec, ContactRec, EstimatorSnapshot, OperatorTick, ParametersRec, RunEnd, RunStart,
    StateSyncRec, TelerobotTick,
};
use record::{Message, RecordSink, Side, Timed};
use sim::trajectory::TrajectorySample;
use sim::world::WorldSample;

use super::ExperimentConfig;

/// Ticks per batch handed to the recorder.
const BATCH_TICKS: usize = 100;

/// The harness's recording state.
pub(super) struct Recorded {
    sink: RecordSink,
    batch: Vec<Timed>,
    ticks: usize,
}

/// One tick of both nodes, as the harness ran it.
pub(super) struct HarnessTick<'a> {
    pub(super) index: u64,
    pub(super) now: i64,
    pub(super) device: &'a TrajectorySample,
    pub(super) out: &'a OperatorOutput,
    pub(super) remote: &'a OperatorOutput,
    pub(super) proxy_m: Option<[f64; 3]>,
    pub(super) operator_state: [Option<(f64, f64)>; 2],
    pub(super) target: &'a Target,
    pub(super) sample: &'a WorldSample,
    pub(super) cloud_captured_ns: Option<i64>,
    pub(super) telerobot: &'a TelerobotNode,
}

impl Recorded {
    /// Starts the recording of `config`'s run: `/run` for both sides.
    pub(super) fn start(
        sink: RecordSink,
        config: &ExperimentConfig,
        period_ns: i64,
        axes: [[f64; 3]; 2],
        tool_start_m: [f64; 3],
    ) -> Recorded {
        let scene = &config.scene;
        let summary = scene.summary();
        let run = |side| RunStart {
            side,
            experiment: config.kind.name().to_owned(),
            start_ns: 0,
            period_ns,
            scene_name: scene.name.clone(),
            left_out: scene.left_out(),
            proxy_radii_m: summary.proxy_radii_m,
            device: Some(config.trajectory.clone()),
            seed: Some(config.seed),
            set_delay_ms: Some(config.delay_ms),
            scene: Some(scene.clone()),
            config: serde_json::to_value(config).ok(),
            axes: Some(axes),
            tool_start_m: Some(tool_start_m),
        };
        let mut r = Recorded {
            sink,
            batch: Vec::with_capacity(BATCH_TICKS * 6),
            ticks: 0,
        };
        for side in [Side::Operator, Side::Telerobot] {
            r.push(0, Message::Run(Box::new(run(side))));
        }
        r
    }

    fn push(&mut self, t_ns: i64, message: Message) {
        self.batch.push(Timed { t_ns, message });
    }

    /// A camera frame the telerobot took (and installed).
    pub(super) fn cloud(&mut self, now: i64, cloud: CloudRec) {
        self.push(now, Message::Cloud(Side::Telerobot, cloud));
    }

    /// One tick of both nodes.
    pub(super) fn tick(&mut self, t: &HarnessTick<'_>) {
        let at = t.now;
        let operator = operator_tick(t);
        self.push(at, Message::OperatorTick(Box::new(operator)));
        let tr = t.telerobot;
        let datagrams = tr.datagrams();
        let measurement = datagrams.iter().find_map(|d| match d {
            Datagram::Measurement(m) => Some(m),
            _ => None,
        });
        let [normal, tangential] = tr.updates();
        let estimators = [
            normal.zip(tr.normal_estimator()),
            tangential.zip(tr.tangential_estimator()),
        ]
        .map(|e| e.map(|(u, est)| EstimatorSnapshot::of(est, u)));
        let s = t.sample;
        let bridge = BridgeSample {
            measured: s.measured,
            tool_m: s.truth.position_m,
            object_slide_m: s.object_offset_m,
            reading: node::Reading::ThisTick,
        };
        let mut tick = TelerobotTick::new(
            0,
            t.index,
            at,
            t.target,
            &bridge,
            t.cloud_captured_ns,
            measurement,
            &estimators,
        );
        // What the series takes, exactly: the node's own stability and reconstruction terms,
        // and the simulator's truth.
        tick.estimator_stable = tr.is_stable();
        tick.reconstruction = tr.reconstruction().map(|(a, b)| [a, b]);
        tick.true_force_n = Some(s.truth.force_on_tool_n);
        tick.true_in_contact = Some(s.in_contact);
        tick.true_state = Some(s.tangential_state.map(|(a, b)| [a, b]));
        self.push(at, Message::TelerobotTick(Box::new(tick)));
        for d in datagrams {
            let message = match d {
                Datagram::Contact(c) => {
                    Message::Contact(Side::Telerobot, Box::new(ContactRec::new(0, c, None)))
                }
                Datagram::Parameters(p) => {
                    Message::Parameters(Side::Telerobot, Box::new(ParametersRec::new(0, p, None)))
                }
                Datagram::StateSync(s) => {
                    Message::StateSync(Side::Telerobot, Box::new(StateSyncRec::new(0, s, None)))
                }
                Datagram::Measurement(_) => continue,
            };
            self.push(at, message);
        }
        self.ticks += 1;
        if self.ticks.is_multiple_of(BATCH_TICKS) {
            self.flush();
        }
    }

    fn flush(&mut self) {
        let batch = std::mem::replace(&mut self.batch, Vec::with_capacity(BATCH_TICKS * 6));
        self.sink.send_waiting(batch);
    }

    /// The run's end: what the nodes knew (`/run/end`).
    pub(super) fn finish(mut self, now: i64, ticks: u64, nodes: &NodeInfo) {
        let end = RunEnd {
            side: Side::Operator,
            ticks,
            nodes: Some(nodes.clone()),
            frame: None,
            final_offset_ns: None,
            counters: None,
            recorder_dropped: self.sink.dropped(),
        };
        self.push(now, Message::RunEnd(Box::new(end)));
        self.flush();
    }
}

/// The operator node's tick as the recording holds it.
fn operator_tick(t: &HarnessTick<'_>) -> OperatorTick {
    let at = t.now;
    OperatorTick {
        session: 0,
        index: t.index,
        sample_time_ns: at,
        started_ns: at,
        device_position_m: t.device.position_m,
        device_velocity_m_per_s: t.device.velocity_m_per_s,
        command_position_m: t.device.position_m,
        command_velocity_m_per_s: t.device.velocity_m_per_s,
        force_rendered_n: t.out.force_n,
        force_device_n: t.out.force_n,
        in_contact: t.out.in_contact,
        rendering: t.out.rendering,
        reduced: t.out.reduced,
        proxy_m: t.proxy_m,
        remote_force_n: Some(t.remote.force_n),
        remote_in_contact: Some(t.remote.in_contact),
        tangential_state: t.operator_state.map(|s| s.map(|(a, b)| [a, b])),
        ..OperatorTick::default()
    }
}
