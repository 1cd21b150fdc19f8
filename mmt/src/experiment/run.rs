//! The tick loop of the harness.

use super::metrics::{NodeInfo, RunInfo, Series, analyse, parameter_report};
use super::{ExperimentConfig, ExperimentError, ExperimentReport};
use crate::cloud::{CloudFrame, Pose};
use crate::model::col;
use crate::node::NodeSettings;
use crate::node::operator::{OperatorConfig, OperatorNode};
use crate::node::telerobot::{CommandSample, TelerobotNode};
use crate::scene::CloudKind;
use crate::sim::world::World;
use crate::trajectory::{Trajectory, by_name};
use crate::vec3;
use netem::{Channel, LinkConfig};
use protocol::{operator_to_telerobot as up, telerobot_to_operator as down};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

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
    let link = |seed_offset: u64| {
        let ms = 1_000_000.0;
        let mut c = LinkConfig::delay((config.delay_ms * ms).round() as u64);
        c.jitter_ns = (config.jitter_ms * ms).round() as u64;
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
    let mut uplink = link(101)?;
    let mut downlink = link(202)?;
    let mut camera = Camera::new(config);
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
        while let Some(bytes) = downlink.recv_due(now as u64) {
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
        let frame = camera.frame(now, &world, robot, &sample.object_offset_m)?;
        let prior = telerobot.tangential_estimator().map(|e| e.theta());
        let took_frame = frame.is_some();
        let messages = telerobot.step(now, target.command_sample_time_ns, &sample.measured, frame);
        for m in messages {
            buf.clear();
            down::encode_into(m, &mut buf);
            downlink.send(now as u64, buf.clone(), buf.len());
        }
        if took_frame && let Some(shared) = telerobot.latest_cloud() {
            shared_clouds.push_back(shared);
            // Frames lost on the link would leave their index here: keep the queue short.
            while shared_clouds.len() > 64 {
                shared_clouds.pop_front();
            }
        }
        let reconstruction = match (prior, telerobot.tangential_estimator()) {
            (Some(theta), Some(est))
                if est.phase() == crate::estimator::Phase::Learning && est.is_confident() =>
            {
                Some(
                    est.regressions()
                        .iter()
                        .map(|r| {
                            (
                                r.y,
                                (0..col::COUNT).map(|i| theta.0[i] * r.psi[i]).sum::<f64>(),
                            )
                        })
                        .fold((0.0, 0.0), |(a, b), (y, p)| {
                            (a + y * y, b + (y - p) * (y - p))
                        }),
                )
            }
            _ => None,
        };
        series.push_telerobot(
            target.command_sample_time_ns,
            sample.truth.force_n,
            sample.in_contact,
            telerobot.is_stable(),
            reconstruction,
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
        scene: &config.scene,
        trajectory: config.trajectory.clone(),
        seed: config.seed,
        delay_ms: config.delay_ms,
    };
    let latest = |e: Option<&crate::estimator::Estimator>| e.and_then(|e| e.latest()).copied();
    let (normal, tangential) = (
        latest(telerobot.normal_estimator()),
        latest(telerobot.tangential_estimator()),
    );
    let nodes = NodeInfo {
        parameters: parameter_report(&config.scene, [normal.as_ref(), tangential.as_ref()]),
        operator: operator.stats(),
        shadow: shadow.stats(),
        telerobot: telerobot.stats(),
    };
    let report = analyse(&info, &series, nodes);
    Ok((series, report))
}

/// The simulated depth camera: the object's (large) contact face seen in a window of the scene's
/// `cloud.size_m` centred on the tool, sampled on a grid fixed to the object — the points move
/// with the object as it slides — with the scene's noise and dropout.
struct Camera {
    enabled: bool,
    moving: bool,
    period_ns: i64,
    next_ns: i64,
    rng: Pcg64,
    noise: Option<Normal<f64>>,
    dropout: f64,
    spacing_m: f64,
    window_m: [f64; 2],
    origin: [f64; 3],
}

impl Camera {
    fn new(config: &ExperimentConfig) -> Self {
        let c = &config.scene.cloud;
        Camera {
            enabled: c.source == CloudKind::Plane,
            moving: c.moving,
            period_ns: (1e9 / c.rate_hz).round() as i64,
            next_ns: 0,
            rng: Pcg64::seed_from_u64(config.seed.wrapping_add(303)),
            noise: (c.noise_m > 0.0)
                .then(|| Normal::new(0.0, c.noise_m).ok())
                .flatten(),
            dropout: c.dropout,
            spacing_m: c.spacing_m,
            window_m: c.size_m,
            origin: config.scene.surface.point_m,
        }
    }

    /// A frame if one is due: the face around the tool at `tool_m`, the object slid by
    /// `offset` along the tangents.
    fn frame(
        &mut self,
        now_ns: i64,
        world: &World,
        tool_m: [f64; 3],
        offset: &[f64; 2],
    ) -> Result<Option<CloudFrame>, ExperimentError> {
        if !self.enabled || now_ns < self.next_ns || (!self.moving && self.next_ns > 0) {
            return Ok(None);
        }
        self.next_ns = now_ns + self.period_ns;
        let f = world.frame();
        let rel = vec3::sub(tool_m, self.origin);
        let centre = [vec3::dot(rel, f.tangent1), vec3::dot(rel, f.tangent2)];
        let s = self.spacing_m;
        // Grid indices of the object's face inside the window (the grid moves with the object).
        let range = |axis: usize| {
            let lo = ((centre[axis] - 0.5 * self.window_m[axis] - offset[axis]) / s).ceil() as i64;
            let hi = ((centre[axis] + 0.5 * self.window_m[axis] - offset[axis]) / s).floor() as i64;
            lo..=hi
        };
        let mut points = Vec::new();
        for i in range(0) {
            for j in range(1) {
                if self.dropout > 0.0 && self.rng.random::<f64>() < self.dropout {
                    continue;
                }
                let (u, v) = (offset[0] + i as f64 * s, offset[1] + j as f64 * s);
                let mut p = vec3::add(
                    self.origin,
                    vec3::add(vec3::scale(f.tangent1, u), vec3::scale(f.tangent2, v)),
                );
                if let Some(noise) = &self.noise {
                    for c in &mut p {
                        *c += noise.sample(&mut self.rng);
                    }
                }
                points.push(p.map(|c| c as f32));
            }
        }
        CloudFrame::new(points, now_ns, Pose::default())
            .map(Some)
            .map_err(|e| ExperimentError::Cloud(e.to_string()))
    }
}
