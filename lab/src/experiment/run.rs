//! The tick loop of the harness: the two nodes, their sessions, the links, the world.
//!
//! Everything the daemons do to a datagram happens here too, through the same code: the nodes
//! emit unstamped datagrams, one `protocol::session::Session` per endpoint stamps them and takes
//! in the peer's headers, the operator applies the same [`Admission`] rule as its network task,
//! camera frames go out as `node::cloud_to_wire` makes them, and the simulated robot is the
//! daemon's own bridge ([`SimBridge`]).

use std::collections::VecDeque;
use std::sync::Arc;

use metrics::{NodeInfo, RunInfo, Series, analyse, parameter_report};
use mmt::contact::CloudIndex;
use netem::{Channel, LinkConfig};
use node::MotionGuard;
use node::operator::{OperatorConfig, OperatorNode};
use node::telerobot::{CommandSample, TelerobotNode};
use node::{OperatorSettings, Target, cloud_to_wire};
use protocol::session::Session;
use protocol::telerobot_to_operator::Admission;
use protocol::{operator_to_telerobot as up, telerobot_to_operator as down};
use sim::SimBridge;
use sim::camera::Camera;
use sim::trajectory::{Placed, Trajectory, by_name_seeded};

use super::recorded::{HarnessTick, Recorded};
use super::{ExperimentConfig, ExperimentError, ExperimentReport};
use record::RecordSink;
use record::schema::CloudRec;

/// Runs an experiment; `progress(fraction)` is called about a hundred times. Returns the time
/// series and the report (everything but wall-clock time, which the caller measures).
pub fn run(
    config: &ExperimentConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<(Series, ExperimentReport), ExperimentError> {
    run_recorded(config, progress, None, None)
}

/// [`run`], handing everything to `record` too (`mmt experiment --record`/`--live`), and
/// stopping with [`ExperimentError::Interrupted`] once `stop` is triggered (Ctrl-C).
pub fn run_recorded(
    config: &ExperimentConfig,
    progress: &mut dyn FnMut(f64),
    record: Option<RecordSink>,
    stop: Option<&rt::Shutdown>,
) -> Result<(Series, ExperimentReport), ExperimentError> {
    config.validate()?;
    let mut harness = Harness::new(config)?;
    if let Some(sink) = record {
        let frame = *harness.bridge.world().frame();
        harness.record = Some(Recorded::start(
            sink,
            config,
            harness.period_ns,
            [frame.tangent2, frame.normal],
            harness.robot_m,
        ));
    }
    let ticks = (config.seconds * 1e9 / harness.period_ns as f64).round() as usize;
    let mut series = Series::with_capacity(
        ticks,
        harness.bridge.world().frame().tangent2,
        harness.bridge.world().frame().normal,
        harness.period_ns,
    );
    let report_every = (ticks / 100).max(1);
    for k in 0..ticks {
        harness.tick(k as i64 * harness.period_ns, &mut series)?;
        if k % report_every == 0 {
            progress(k as f64 / ticks as f64);
            if stop.is_some_and(rt::Shutdown::is_triggered) {
                return Err(ExperimentError::Interrupted {
                    at_s: k as f64 * harness.period_ns as f64 * 1e-9,
                    of_s: config.seconds,
                });
            }
        }
    }
    progress(1.0);
    Ok(harness.finish(config, series))
}

/// One direction's links: datagrams (lossy as configured) and clouds (a reliable stream per
/// frame: delayed and jittered, never lost).
struct Links {
    uplink: Channel<Vec<u8>>,
    downlink: Channel<Vec<u8>>,
    cloudlink: Channel<Vec<u8>>,
}

impl Links {
    fn new(config: &ExperimentConfig) -> Result<Links, ExperimentError> {
        let link = |seed_offset: u64, datagrams: bool| {
            let ms = 1_000_000.0;
            let mut c = LinkConfig::delay((config.delay_ms * ms).round() as u64);
            c.jitter_ns = (config.jitter_ms * ms).round() as u64;
            if datagrams {
                if config.loss > 0.0 {
                    c.loss = netem::Loss::Random {
                        probability: config.loss,
                    };
                }
                c.duplicate_probability = config.duplicate;
                if config.reorder > 0.0 {
                    c.reorder_probability = config.reorder;
                    c.reorder_gap = 5;
                }
            }
            Channel::<Vec<u8>>::new(c, config.seed.wrapping_add(seed_offset))
                .map_err(|e| ExperimentError::Link(e.to_string()))
        };
        Ok(Links {
            uplink: link(101, true)?,
            downlink: link(202, true)?,
            cloudlink: link(303, false)?,
        })
    }
}

/// The operator side: its node, the shadow node (contact from the telerobot's state only, as
/// the thesis did, measured in the same run), its session and admission rule.
struct OperatorSide {
    node: OperatorNode,
    shadow: OperatorNode,
    session: Session,
    admission: Admission,
}

/// The telerobot side: its node, its session, the camera and the frames in flight.
struct TelerobotSide {
    node: TelerobotNode,
    session: Session,
    camera: Camera,
    frame_id: u64,
    /// Frames sent and not yet received: their kd-trees, which the operator shares instead of
    /// building the same ones again (the bytes still go through the wire format).
    in_flight: VecDeque<(u64, Arc<CloudIndex>)>,
}

struct Harness {
    period_ns: i64,
    trajectory: Placed,
    bridge: SimBridge,
    /// The motion guard the daemon's bridge goes through (`node::guard`), the same limits.
    guard: MotionGuard,
    robot_m: [f64; 3],
    operator: OperatorSide,
    telerobot: TelerobotSide,
    links: Links,
    buf: Vec<u8>,
    record: Option<Recorded>,
    ticks: u64,
}

impl Harness {
    fn new(config: &ExperimentConfig) -> Result<Harness, ExperimentError> {
        let scene = &config.scene;
        let mut settings = scene.telerobot_settings();
        let mut operator_settings = OperatorSettings::from_welcome(&scene.summary())
            .map_err(|e| ExperimentError::Settings(e.to_string()))?;
        if config.thesis_proxy {
            settings.proxy.bridge_holes = false;
            operator_settings.proxy.bridge_holes = false;
        }
        settings.normal.first_fit.enabled &= config.first_fit;
        settings.tangential.first_fit.enabled &= config.first_fit;
        settings.normal.slide_fit.enabled &= config.first_fit;
        settings.tangential.slide_fit.enabled &= config.first_fit;
        let trajectory = by_name_seeded(
            &config.trajectory,
            config.seconds,
            scene.surface.point_m,
            scene.surface.normal,
            config.seed,
        )?;
        let start = trajectory.sample(0.0).position_m;
        let shadow_config = OperatorConfig {
            local_contact: false,
            ..config.operator
        };
        Ok(Harness {
            period_ns: settings.period_ns,
            trajectory,
            bridge: SimBridge::new(scene, start, config.seed)?,
            guard: MotionGuard::new(settings.limits),
            robot_m: start,
            operator: OperatorSide {
                node: OperatorNode::new(operator_settings, config.operator, start)?,
                shadow: OperatorNode::new(operator_settings, shadow_config, start)?,
                session: Session::new(),
                admission: Admission::default(),
            },
            telerobot: TelerobotSide {
                node: TelerobotNode::new(settings, start)?,
                session: Session::new(),
                camera: Camera::new(scene, config.seed),
                frame_id: 0,
                in_flight: VecDeque::new(),
            },
            links: Links::new(config)?,
            buf: Vec::with_capacity(1500),
            record: None,
            ticks: 0,
        })
    }

    /// One tick at `now`:
    /// 1. messages the downlink releases now go to the operator node (and the shadow);
    /// 2. the scripted device moves; the operator node renders the force and emits a command,
    ///    which is stamped and encoded onto the uplink;
    /// 3. commands the uplink releases now reach the telerobot node; the simulated robot
    ///    executes the current target; a camera frame is taken at the scene's rate;
    /// 4. the telerobot node's datagrams are stamped and encoded onto the downlink.
    fn tick(&mut self, now: i64, series: &mut Series) -> Result<(), ExperimentError> {
        self.deliver_downlink(now);
        let device = self.trajectory.sample(now as f64 * 1e-9);
        let op = &mut self.operator;
        let mut out = op
            .node
            .step(now, device.position_m, device.velocity_m_per_s);
        let remote = op
            .shadow
            .step(now, device.position_m, device.velocity_m_per_s);
        op.session.stamp(&mut out.command.header, now);
        up::encode_into(&up::Message::Command(out.command), &mut self.buf);
        self.links
            .uplink
            .send(now as u64, self.buf.clone(), self.buf.len());
        series.push_operator(device.position_m, &out, &remote);
        self.deliver_uplink(now);
        let target = self.telerobot.node.target(now, self.robot_m);
        let target = self.guard.limit(&target, self.robot_m);
        let sample = self.bridge.step_world(&target);
        self.robot_m = sample.truth.position_m;
        let cloud_captured_ns = self.take_frame(now, &sample.object_offset_m)?;
        self.send_telerobot(now, &target, &sample);
        let tr = &self.telerobot.node;
        let operator_state = self.operator.node.tangential_state();
        series.push_true_force(target.command_sample_time_ns, sample.truth.force_on_tool_n);
        series.push_telerobot(
            target.command_sample_time_ns,
            sample.measured.force_on_tool_n,
            sample.in_contact,
            tr.is_stable(),
            tr.reconstruction(),
            sample.tangential_state,
            operator_state,
        );
        if let Some(r) = &mut self.record {
            r.tick(&HarnessTick {
                index: self.ticks,
                now,
                device: &device,
                out: &out,
                remote: &remote,
                proxy_m: self.operator.node.proxy_m(),
                operator_state,
                target: &target,
                sample: &sample,
                cloud_captured_ns,
                telerobot: tr,
            });
        }
        self.ticks += 1;
        Ok(())
    }

    /// Downlink arrivals (clouds first) to the operator and the shadow node.
    fn deliver_downlink(&mut self, now: i64) {
        let links = &mut self.links;
        while let Some(bytes) = links
            .cloudlink
            .recv_due(now as u64)
            .or_else(|| links.downlink.recv_due(now as u64))
        {
            let Ok(message) = down::decode(&bytes) else {
                continue;
            };
            let op = &mut self.operator;
            if let Some(h) = message.header() {
                let arrival = op.session.on_receive(h, now);
                if !op.admission.admit(&message, arrival) {
                    continue;
                }
            }
            match &message {
                down::Message::Cloud(c)
                    if self
                        .telerobot
                        .in_flight
                        .front()
                        .is_some_and(|(id, _)| *id == c.frame_id) =>
                {
                    if let Some((_, index)) = self.telerobot.in_flight.pop_front() {
                        op.node.set_cloud(index);
                    }
                }
                _ => {
                    op.node.on_message(&message, now);
                    op.shadow.on_message(&message, now);
                }
            }
        }
    }

    /// Uplink arrivals to the telerobot node.
    fn deliver_uplink(&mut self, now: i64) {
        let tr = &mut self.telerobot;
        while let Some(bytes) = self.links.uplink.recv_due(now as u64) {
            if let Ok(up::Message::Command(c)) = up::decode(&bytes) {
                tr.session.on_receive(&c.header, now);
                tr.node.on_command(CommandSample {
                    sample_time_ns: c.header.sample_time_ns,
                    position_m: c.position_m,
                    velocity_m_per_s: c.velocity_m_per_s,
                    received_ns: now,
                });
            }
        }
    }

    /// A camera frame, if one is due: indexed, installed in the telerobot node, sent. Returns
    /// the capture time of a frame installed.
    fn take_frame(
        &mut self,
        now: i64,
        object_offset_m: &[f64; 2],
    ) -> Result<Option<i64>, ExperimentError> {
        let tr = &mut self.telerobot;
        let frame = tr
            .camera
            .frame(now, self.bridge.world(), self.robot_m, object_offset_m)
            .map_err(|e| ExperimentError::Cloud(e.to_string()))?;
        let Some(frame) = frame else { return Ok(None) };
        let captured = frame.timestamp_ns();
        match CloudIndex::build(&frame) {
            Ok(index) => {
                tr.frame_id += 1;
                let index = Arc::new(index);
                tr.node.set_cloud(Arc::clone(&index), tr.frame_id);
                let wire = cloud_to_wire(tr.frame_id, frame);
                if let Some(r) = &mut self.record {
                    r.cloud(
                        now,
                        CloudRec {
                            frame_id: wire.frame_id,
                            timestamp_ns: wire.timestamp_ns,
                            points: Arc::new(wire.points.clone()),
                        },
                    );
                }
                let message = down::Message::Cloud(wire);
                down::encode_into(&message, &mut self.buf);
                self.links
                    .cloudlink
                    .send(now as u64, self.buf.clone(), self.buf.len());
                tr.in_flight.push_back((tr.frame_id, index));
                // Frames in flight wait here (12 at 30 Hz over 400 ms); keep the queue bounded.
                while tr.in_flight.len() > 64 {
                    tr.in_flight.pop_front();
                }
                Ok(Some(captured))
            }
            Err(_) => {
                tr.node.count_rejected_cloud();
                Ok(None)
            }
        }
    }

    /// Steps the telerobot node with the robot's sample; its datagrams go onto the downlink.
    fn send_telerobot(&mut self, now: i64, target: &Target, sample: &sim::world::WorldSample) {
        let tr = &mut self.telerobot;
        let datagrams = tr
            .node
            .step(now, target.command_sample_time_ns, &sample.measured);
        for d in datagrams {
            let mut d = *d;
            tr.session.stamp(d.header_mut(), now);
            down::encode_datagram_into(&d, &mut self.buf);
            self.links
                .downlink
                .send(now as u64, self.buf.clone(), self.buf.len());
        }
    }

    /// The report of the run.
    fn finish(self, config: &ExperimentConfig, series: Series) -> (Series, ExperimentReport) {
        let info = RunInfo {
            experiment: config.kind.name().to_string(),
            scene: config.scene.name.clone(),
            left_out: config.scene.left_out(),
            trajectory: config.trajectory.clone(),
            seed: config.seed,
            delay_ms: config.delay_ms,
        };
        let telerobot = &self.telerobot.node;
        let latest = |e: Option<&mmt::estimator::Estimator>| e.and_then(|e| e.latest()).copied();
        let (normal, tangential) = (
            latest(telerobot.normal_estimator()),
            latest(telerobot.tangential_estimator()),
        );
        let mut parameters =
            parameter_report(&config.scene, [normal.as_ref(), tangential.as_ref()]);
        for p in &mut parameters {
            let estimator = match p.axes.as_str() {
                "normal" => telerobot.normal_estimator(),
                _ => telerobot.tangential_estimator(),
            };
            if let Some(s) = estimator.map(|e| e.stats()) {
                p.low_confidence_updates = Some(s.low_confidence_confirmed);
                p.confirmed_updates = Some(s.confirmed);
            }
        }
        let estimators = [
            ("normal", telerobot.normal_estimator()),
            ("tangential", telerobot.tangential_estimator()),
        ]
        .into_iter()
        .filter_map(|(axes, e)| {
            e.map(|e| metrics::EstimatorReport {
                axes: axes.to_owned(),
                stats: e.stats(),
            })
        })
        .collect();
        let nodes = NodeInfo {
            estimators,
            parameters,
            operator: self.operator.node.stats(),
            shadow: self.operator.shadow.stats(),
            telerobot: telerobot.stats(),
            prior: self.operator.node.prior(),
        };
        if let Some(r) = self.record {
            r.finish(self.ticks as i64 * self.period_ns, self.ticks, &nodes);
        }
        let report = analyse(&info, &series, nodes);
        (series, report)
    }
}
