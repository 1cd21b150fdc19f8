//! The tick loop of the harness.

use super::{ExperimentConfig, ExperimentError, ExperimentReport};
use metrics::{NodeInfo, RunInfo, Series, analyse, parameter_report};
use netem::{Channel, LinkConfig};
use node::NodeSettings;
use node::operator::{OperatorConfig, OperatorNode};
use node::telerobot::{CommandSample, TelerobotNode};
use protocol::{operator_to_telerobot as up, telerobot_to_operator as down};
use sim::camera::Camera;
use sim::trajectory::{Trajectory, by_name};
use sim::world::World;

/// Runs an experiment; `progress(fraction)` is called about a hundred times. Returns the time
/// series and the report (everything but wall-clock time, which the caller measures).
pub fn run(
    config: &ExperimentConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<(Series, ExperimentReport), ExperimentError> {
    config.validate()?;
    let scene = &config.scene;
    let settings = NodeSettings::from_scene(scene);
    let period = settings.period_ns;
    let trajectory = by_name(
        &config.trajectory,
        config.seconds,
        scene.surface.point_m,
        scene.surface.normal,
    )?;
    let start = trajectory.sample(0.0).position_m;
    let mut world = World::new(scene, start, config.seed)?;
    let mut telerobot = TelerobotNode::new(settings.clone(), start)?;
    let mut operator = OperatorNode::new(settings.clone(), config.operator, start)?;
    let shadow_config = OperatorConfig {
        local_contact: false,
        ..config.operator
    };
    let mut shadow = OperatorNode::new(settings.clone(), shadow_config, start)?;
    // Datagrams (commands, parameters, contact, state sync) may be lost, duplicated and
    // reordered; clouds travel as the networked system sends them, one reliable stream per
    // frame: delayed (and jittered), never lost. A static scene sends its one cloud once.
    let link = |seed_offset: u64, datagrams: bool| {
        let ms = 1_000_000.0;
        let mut c = LinkConfig::delay((config.delay_ms * ms).round() as u64);
        c.jitter_ns = (config.jitter_ms * ms).round() as u64;
        if !datagrams {
            return Channel::<Vec<u8>>::new(c, config.seed.wrapping_add(seed_offset))
                .map_err(|e| ExperimentError::Link(e.to_string()));
        }
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
        Channel::<Vec<u8>>::new(c, config.seed.wrapping_add(seed_offset))
            .map_err(|e| ExperimentError::Link(e.to_string()))
    };
    let mut uplink = link(101, true)?;
    let mut downlink = link(202, true)?;
    let mut cloudlink = link(303, false)?;
    let mut camera = Camera::new(&config.scene, config.seed);
    let ticks = (config.seconds * 1e9 / period as f64).round() as usize;
    let mut series =
        Series::with_capacity(ticks, world.frame().tangent2, world.frame().normal, period);
    let mut buf = Vec::with_capacity(1500);
    let mut shared_clouds = std::collections::VecDeque::new();
    let mut robot = start;
    let mut report_every = (ticks / 100).max(1);
    for k in 0..ticks {
        let now = k as i64 * period;
        // 1. Downlink arrivals.
        while let Some(bytes) = cloudlink
            .recv_due(now as u64)
            .or_else(|| downlink.recv_due(now as u64))
        {
            if let Ok(message) = down::decode(&bytes) {
                if let Some(h) = message.header() {
                    operator.session().on_receive(h, now);
                }
                match &message {
                    // The decoded frame is bit-identical to the one the telerobot indexed: share
                    // its kd-tree instead of building the same one again (the bytes still went
                    // through the wire format).
                    down::Message::Cloud(c)
                        if shared_clouds
                            .front()
                            .is_some_and(|(id, _)| *id == c.frame_id) =>
                    {
                        if let Some((_, index)) = shared_clouds.pop_front() {
                            operator.set_cloud(index);
                        }
                    }
                    _ => {
                        operator.on_message(&message, now);
                        shadow.on_message(&message, now);
                    }
                }
            }
        }
        // 2. The operator.
        let device = trajectory.sample(now as f64 * 1e-9);
        let out = operator.step(now, device.position_m, device.velocity_m_per_s);
        let remote = shadow.step(now, device.position_m, device.velocity_m_per_s);
        buf.clear();
        up::encode_into(&up::Message::Command(out.command), &mut buf);
        uplink.send(now as u64, buf.clone(), buf.len());
        series.push_operator(device.position_m, &out, &remote);
        // 3. Uplink arrivals, the robot, the camera.
        while let Some(bytes) = uplink.recv_due(now as u64) {
            if let Ok(up::Message::Command(c)) = up::decode(&bytes) {
                telerobot.session().on_receive(&c.header, now);
                telerobot.on_command(CommandSample {
                    sample_time_ns: c.header.sample_time_ns,
                    position_m: c.position_m,
                    velocity_m_per_s: c.velocity_m_per_s,
                    received_ns: now,
                });
            }
        }
        let target = telerobot.target(now, robot);
        let sample = world.step(target.position_m, target.velocity_m_per_s);
        robot = sample.truth.position_m;
        let frame = camera
            .frame(now, &world, robot, &sample.object_offset_m)
            .map_err(|e| ExperimentError::Cloud(e.to_string()))?;
        let took_frame = frame.is_some();
        let messages = telerobot.step(now, target.command_sample_time_ns, &sample.measured, frame);
        for m in messages {
            buf.clear();
            down::encode_into(m, &mut buf);
            let link = match m {
                down::Message::Cloud(_) => &mut cloudlink,
                _ => &mut downlink,
            };
            link.send(now as u64, buf.clone(), buf.len());
        }
        if took_frame && let Some(shared) = telerobot.latest_cloud() {
            shared_clouds.push_back(shared);
            // Frames in flight wait here (12 at 30 Hz over 400 ms); keep the queue bounded.
            while shared_clouds.len() > 64 {
                shared_clouds.pop_front();
            }
        }
        series.push_true_force(target.command_sample_time_ns, sample.truth.force_n);
        series.push_telerobot(
            target.command_sample_time_ns,
            sample.measured.force_n,
            sample.in_contact,
            telerobot.is_stable(),
            telerobot.reconstruction(),
            sample.tangential_state,
            operator.tangential_state(),
        );
        if k % report_every == 0 {
            progress(k as f64 / ticks as f64);
            report_every = report_every.max(1);
        }
    }
    progress(1.0);
    let info = RunInfo {
        experiment: config.kind.name().to_string(),
        scene: config.scene.name.clone(),
        left_out: config.scene.left_out(),
        trajectory: config.trajectory.clone(),
        seed: config.seed,
        delay_ms: config.delay_ms,
    };
    let latest = |e: Option<&mmt::estimator::Estimator>| e.and_then(|e| e.latest()).copied();
    let (normal, tangential) = (
        latest(telerobot.normal_estimator()),
        latest(telerobot.tangential_estimator()),
    );
    let mut parameters = parameter_report(&config.scene, [normal.as_ref(), tangential.as_ref()]);
    for p in &mut parameters {
        let estimator = match p.axes {
            "normal" => telerobot.normal_estimator(),
            _ => telerobot.tangential_estimator(),
        };
        if let Some(s) = estimator.map(|e| e.stats()) {
            p.low_confidence_updates = Some(s.low_confidence_confirmed);
            p.confirmed_updates = Some(s.confirmed);
        }
    }
    let nodes = NodeInfo {
        parameters,
        operator: operator.stats(),
        shadow: shadow.stats(),
        telerobot: telerobot.stats(),
    };
    let report = analyse(&info, &series, nodes);
    Ok((series, report))
}
