//! The telerobot daemon: the network runtime, the 1 kHz loop, the camera thread and the
//! housekeeping thread, started together ([`Telerobot::start`]) and stopped together
//! ([`Telerobot::stop`]); [`run`] is both around a shutdown signal (what `telerobot run` calls).
//!
//! Threads:
//! - `telerobot-net`: a one-worker tokio runtime serving QUIC ([`crate::net::serve`]);
//! - `telerobot-loop`: the real-time loop ([`crate::control`]), absolute deadlines plus a short
//!   spin ([`rt::Periodic`]);
//! - `camera`: the simulated camera and its kd-tree ([`crate::camera`]);
//! - `housekeeping`: everything the loop must not do — builds a spare node for the next session
//!   (at the robot's current position), drops retired ones, keeps the latest loop snapshot for
//!   [`Telerobot::snapshot`], logs each session's end with its figures, and with `--record` or
//!   `--live` hands the loop's tick records, the link statistics and the session events to the
//!   recorder (the camera thread hands it the frames).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use metrics::{ParameterReport, parameter_report};
use mmt::estimator::EstimatorStats;
use node::telerobot::TelerobotNode;
use node::{GuardStats, MotionLimits, TelerobotSettings};
use protocol::telerobot_to_operator::SceneSummary;
use rt::monotonic_ns;
use rt::{Periodic, PeriodicConfig, Shutdown, TimingReport};
use rustls_pki_types::CertificateDer;
use serde::Serialize;
use sim::scene::Scene;
use transport::{Identity, LinkReport, LinkTuning, Mailbox};

use crate::camera::{self, CameraFeed};
use crate::control::{ControlLoop, LoopEnd, LoopSnapshot, Spares, TICK_QUEUE};
use crate::net::{self, NetConfig, TelerobotLink};
use crate::recording::{self, Forward};
use crate::robot::{self, RobotConfig};
use crate::watch::{CommandGaps, GuardLog};
use record::RecordSink;

mod network;
use network::Network;

/// How often the housekeeping thread wakes.
const HOUSEKEEPING: Duration = Duration::from_millis(20);
/// Command latencies queued for the housekeeping thread: 8 s at 1 kHz.
const LATENCY_QUEUE: usize = 8192;

/// Everything `telerobot run` needs, validated.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// Where to listen.
    pub listen: SocketAddr,
    /// The telerobot's certificate and key.
    pub identity: Identity,
    /// Trusted operator certificates, with the file each came from.
    pub trusted_operators: Vec<(PathBuf, CertificateDer<'static>)>,
    /// quinn settings.
    pub tuning: LinkTuning,
    /// The scene the simulated bridge runs (validated when it was parsed).
    pub scene: Scene,
    /// Seed of the simulated sensors' and camera's noise.
    pub seed: u64,
    /// Where the tool starts [m]: 1 cm above the scene's surface point by default.
    pub start_m: [f64; 3],
    /// The loop's schedule (period from the scene's control rate, spin window).
    pub periodic: PeriodicConfig,
    /// `SCHED_FIFO` priority of the loop thread, if wanted (needs `CAP_SYS_NICE`).
    pub realtime_priority: Option<u8>,
    /// The recorder (`--record`, `--live`), if the daemon records: every tick, camera frame,
    /// link statistics and session event goes to it off the loop, and the run's start and end.
    pub record: Option<RecordSink>,
    /// Which robot: the simulated world or a ROS 2 robot.
    pub robot: RobotConfig,
    /// The motion limits every bridge sits behind (`node::guard`): the scene's `[limits]`
    /// (`Scene::motion_limits`), the command line's flags over them. The node's settings take
    /// them too (its playout-time check).
    pub limits: MotionLimits,
}

impl RunConfig {
    /// The `Welcome`'s scene summary ([`Scene::summary`]).
    pub fn scene_summary(&self) -> SceneSummary {
        self.scene.summary()
    }

    /// The server's configuration.
    pub fn net_config(&self) -> NetConfig {
        let mut config = NetConfig::new(
            self.listen,
            self.identity.clone(),
            self.trusted_operators
                .iter()
                .map(|(_, c)| c.clone())
                .collect(),
            self.scene_summary(),
        );
        config.tuning = self.tuning.clone();
        config.trusted_labels = self
            .trusted_operators
            .iter()
            .map(|(p, _)| p.display().to_string())
            .collect();
        config
    }

    /// The tool's default start: 1 cm above the surface point, along the normal.
    pub fn default_start(scene: &Scene) -> [f64; 3] {
        let s = &scene.surface;
        std::array::from_fn(|i| s.point_m[i] + 0.01 * s.normal[i])
    }
}

/// Why the daemon could not start.
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    /// The loop settings.
    #[error(transparent)]
    Loop(#[from] rt::PeriodicError),
    /// The node could not be built from the scene.
    #[error("telerobot node: {0}")]
    Node(#[from] node::telerobot::NodeError),
    /// The simulated world could not be built from the scene.
    #[error("simulated world: {0}")]
    Sim(#[from] sim::SimError),
    /// The ROS 2 graph or an endpoint on it.
    #[error(transparent)]
    Ros2(#[from] ros2::GraphError),
    /// The scene's cloud file.
    #[error(transparent)]
    CloudFile(#[from] camera::CloudFileError),
    /// `[cloud] source = "ros2"` is not wired into the daemon yet.
    #[error(
        "[cloud] source = \"ros2\": not supported by the telerobot daemon yet (use \"file\" or \"plane\")"
    )]
    Ros2Cloud,
    /// The command limits.
    #[error(transparent)]
    Limits(#[from] node::guard::LimitsError),
    /// The server could not start.
    #[error(transparent)]
    Net(#[from] net::NetError),
    /// A runtime, a socket pair or a thread could not be created.
    #[error("{what}: {source}")]
    Io {
        /// What was being created.
        what: &'static str,
        /// The operating system's reason.
        source: std::io::Error,
    },
}

fn io(what: &'static str) -> impl FnOnce(std::io::Error) -> DaemonError {
    move |source| DaemonError::Io { what, source }
}

/// What the daemon did, for its log and for the demo's report.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    /// Scene name.
    pub scene: String,
    /// Loop timing.
    pub timing: TimingReport,
    /// Operator sessions accepted.
    pub sessions: u64,
    /// Operators refused (busy, version or bad first message).
    pub refusals: u64,
    /// The last session's node: its counters and whether its estimators were confident.
    pub last: SnapshotReport,
    /// Command receipt − sample time [µs]: the uplink's one-way latency when both daemons share
    /// one clock (one host); offset by the clock difference otherwise.
    pub command_latency: rt::Summary,
    /// Camera frames indexed and sent, and refused.
    pub camera_frames: (u64, u64),
    /// Cloud frames handed whole to QUIC, superseded by a newer frame before they were (the
    /// link or the operator could not take them yet: latest wins), and failed.
    pub clouds: (u64, u64, u64),
    /// Camera frames over the real-time budget: downsampled to fit, and refused (counted in
    /// `camera_frames` too).
    pub camera_over_budget: (u64, u64),
    /// Commands lost to a full command queue.
    pub commands_overwritten: u64,
    /// Datagrams lost to a full outbox.
    pub outbox_overwritten: u64,
    /// Link counters.
    pub link: LinkReport,
    /// Times without commands (100 ms or more) between the first command and the last, across
    /// sessions (a reconnect does not restart them; the time between two operators counts).
    pub outages: transport::Outages,
    /// The last confirmed parameters against the scene's truth (the simulated bridge's).
    pub parameters: Vec<ParameterReport>,
    /// The ROS 2 bridge's report (`--robot ros2`).
    pub robot: Option<ros2::BridgeReport>,
    /// The ROS 2 camera's counters (`[cloud] source = "ros2"`).
    pub ros2_camera: Option<ros2::CameraReport>,
}

/// [`LoopSnapshot`] for reports.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SnapshotReport {
    /// Ticks run.
    pub tick: u64,
    /// Session served.
    pub session: u64,
    /// Node counters.
    pub node: node::telerobot::TelerobotStats,
    /// Estimators confident.
    pub stable: bool,
    /// Nodes built on the loop thread (no spare ready).
    pub inline_node_builds: u64,
    /// The motion guard's counters over every session.
    pub guard: GuardStats,
    /// New robot samples the node stepped on.
    pub fresh_samples: u64,
    /// The estimators' counters (normal, tangential).
    pub estimators: (Option<EstimatorStats>, Option<EstimatorStats>),
}

/// A running telerobot daemon.
pub struct Telerobot {
    network: Network,
    stop: Shutdown,
    control: Option<JoinHandle<LoopEnd>>,
    camera: Option<JoinHandle<()>>,
    housekeeping: Option<JoinHandle<(rt::Histogram, transport::Outages)>>,
    shared: Arc<Housekeeping>,
    link: TelerobotLink,
    feed: Arc<CameraFeed>,
    timing: Arc<rt::LoopTiming>,
    scene: Scene,
    /// The recorder, while the daemon records (the run's end goes to it).
    record: Option<RecordSink>,
    robot: Option<ros2::BridgeMonitor>,
    ros2_camera: Option<Arc<ros2::camera::CameraCounters>>,
}

/// The node's settings (with the run's motion limits, checked), a fresh node at the start
/// position and the loop's schedule at the scene's rate.
fn node_and_schedule(
    config: &RunConfig,
) -> Result<(TelerobotSettings, Box<TelerobotNode>, PeriodicConfig), DaemonError> {
    let mut settings = config.scene.telerobot_settings();
    settings.limits = config.limits;
    let node = Box::new(TelerobotNode::new(settings.clone(), config.start_m)?);
    config.limits.validate()?;
    let periodic_config = PeriodicConfig {
        period_ns: settings.period_ns,
        ..config.periodic
    };
    periodic_config.validate()?;
    Ok((settings, node, periodic_config))
}

/// What the housekeeping thread shares.
struct Housekeeping {
    snapshot: Mutex<LoopSnapshot>,
}

impl Housekeeping {
    /// Before the loop's first snapshot: the tool where it starts.
    fn new(tool_m: [f64; 3]) -> Housekeeping {
        Housekeeping {
            snapshot: Mutex::new(LoopSnapshot {
                tool_m,
                ..LoopSnapshot::default()
            }),
        }
    }
}

/// The start log: where the daemon listens, what it drives and the command limits.
fn log_start(config: &RunConfig, addr: SocketAddr, periodic: &PeriodicConfig, robot: &str) {
    let l = &config.limits;
    tracing::info!(%addr, scene = %config.scene.name, seed = config.seed,
        period_us = periodic.period_ns / 1000, spin_us = periodic.spin_ns / 1000,
        "telerobot running ({robot})");
    if let Some(fit) = config.scene.cloud_budget() {
        tracing::warn!(scene = %config.scene.name, "{fit}");
    }
    tracing::info!(workspace_min_m = ?l.workspace_min_m, workspace_max_m = ?l.workspace_max_m,
        max_step_m = l.max_step_m, max_speed_m_per_s = l.max_speed_m_per_s,
        max_clock_jump_s = l.max_clock_jump_ns as f64 * 1e-9,
        state_timeout_ms = MotionLimits::STATE_TIMEOUT_NS as f64 * 1e-6,
        "motion limits (every limit that acts is counted and logged once per episode)");
}

impl Telerobot {
    /// Binds the server and starts every thread. Returns once the server listens.
    pub fn start(config: RunConfig) -> Result<Telerobot, DaemonError> {
        let start = config.start_m;
        let (settings, node, periodic_config) = node_and_schedule(&config)?;
        let built = robot::build(
            &config.robot,
            &config.scene,
            &settings,
            start,
            config.seed,
            None,
        )?;
        let bridge = node::Guarded::new(built.bridge, settings.limits);
        let (link, net_io) =
            net::link(net::DEFAULT_OUTBOX_CAPACITY).map_err(io("the loop's hand-off"))?;
        let network = Network::start(&config, net_io)?;
        let stop = Shutdown::new();
        let feed = Arc::new(CameraFeed::default());
        let (camera, camera_counters) =
            camera::start(&config, built.graph.as_ref(), &feed, &link, &stop)?;
        let spares = Arc::new(Spares::default());
        let snapshots = Arc::new(Mailbox::latest());
        let command_latency = Arc::new(Mailbox::new(LATENCY_QUEUE));
        let records = recording::tick_mailbox(config.record.as_ref(), TICK_QUEUE);
        // Tick 0 a little ahead, so that the first deadline is not already late.
        let periodic = Periodic::new(periodic_config, monotonic_ns() + 2_000_000)?;
        let timing = periodic.timing();
        recording::record_start(&config, periodic.start_ns(), settings.period_ns);
        let control = ControlLoop {
            node,
            settings: settings.clone(),
            bridge,
            outlet: built.outlet,
            link: link.clone(),
            camera: Arc::clone(&feed),
            spares: Arc::clone(&spares),
            snapshots: Arc::clone(&snapshots),
            command_latency: Arc::clone(&command_latency),
            records: records.clone(),
            shutdown: stop.clone(),
        };
        let control = rt::spawn("telerobot-loop", config.realtime_priority, move || {
            control.run(periodic)
        })
        .map_err(io("the loop thread"))?;
        let shared = Arc::new(Housekeeping::new(start));
        let keeper = Keeper {
            settings,
            spares,
            snapshots,
            shared: Arc::clone(&shared),
            link: link.clone(),
            timing: Arc::clone(&timing),
            command_latency,
            latencies: rt::Histogram::new(),
            record: config.record.clone().zip(records).map(Forward::new),
            outages: CommandGaps::default(),
        };
        let housekeeping = keeper.spawn(&stop)?;
        log_start(&config, network.addr, &periodic_config, &built.description);
        Ok(Telerobot {
            network,
            stop,
            control: Some(control),
            camera,
            housekeeping: Some(housekeeping),
            shared,
            link,
            feed,
            timing,
            scene: config.scene,
            record: config.record,
            robot: built.monitor,
            ros2_camera: camera_counters,
        })
    }

    /// The address the server listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.network.addr
    }

    /// The loop as of its last snapshot (at most ~30 ms old).
    pub fn snapshot(&self) -> LoopSnapshot {
        *self
            .shared
            .snapshot
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
    }

    /// The control loop's timing so far (idle ticks counted apart).
    pub fn timing(&self) -> rt::TimingReport {
        self.timing.report()
    }

    /// The network side: link counters, session status.
    pub fn link(&self) -> &TelerobotLink {
        &self.link
    }

    /// Operator certificates the TLS handshake refused since start.
    pub fn untrusted_refusals(&self) -> u64 {
        self.network.pins.rejections()
    }

    /// Stops everything (operators are told the telerobot shuts down) and returns the summary.
    pub fn stop(mut self) -> Summary {
        self.stop.trigger();
        let end = self.control.take().and_then(|h| h.join().ok());
        if let Some(camera) = self.camera.take() {
            let _ = camera.join();
        }
        let (latencies, outages) = self
            .housekeeping
            .take()
            .and_then(|h| h.join().ok())
            .unwrap_or_default();
        self.network.net_stop.trigger();
        let server = &mut self.network.server;
        let _ = self
            .network
            .runtime
            .block_on(async { tokio::time::timeout(Duration::from_secs(3), server).await });
        let last = end.as_ref().map_or_else(|| self.snapshot(), |e| e.last);
        let parameters = end.as_ref().map_or_else(Vec::new, |e| {
            let latest =
                |est: Option<&mmt::estimator::Estimator>| est.and_then(|e| e.latest()).copied();
            let (n, t) = (
                latest(e.node.normal_estimator()),
                latest(e.node.tangential_estimator()),
            );
            parameter_report(&self.scene, [n.as_ref(), t.as_ref()])
        });
        let status = self.link.status();
        let summary = Summary {
            scene: self.scene.name.clone(),
            timing: self.timing.report(),
            sessions: status.session(),
            refusals: status.refused_busy() + status.refused_other(),
            last: SnapshotReport {
                tick: last.tick,
                session: last.session,
                node: last.node,
                stable: last.stable,
                inline_node_builds: last.inline_node_builds,
                guard: last.guard,
                fresh_samples: last.fresh_samples,
                estimators: last.estimators,
            },
            command_latency: latencies.summary(),
            camera_frames: self.feed.counts(),
            clouds: status.clouds(),
            camera_over_budget: self.feed.budget_counts(),
            commands_overwritten: self.link.commands_overwritten(),
            outbox_overwritten: self.link.outbox_overwritten(),
            link: self.link.stats().into(),
            outages,
            parameters,
            robot: self.robot.as_ref().map(|m| m.report()),
            ros2_camera: self.ros2_camera.as_ref().map(|c| c.report()),
        };
        if let Some(sink) = &self.record {
            let ticks = end.as_ref().map_or(last.tick, |e| e.last.tick + 1);
            recording::record_end(sink, ticks, &summary);
        }
        let t = &summary.timing;
        tracing::info!(
            ticks = t.ticks,
            period_p50_us = t.period.p50_us,
            period_p99_us = t.period.p99_us,
            period_max_us = t.period.max_us,
            overruns = t.overruns,
            skipped = t.skipped_ticks,
            sessions = summary.sessions,
            "telerobot stopped"
        );
        summary
    }
}

impl Drop for Telerobot {
    /// A daemon dropped without [`Telerobot::stop`] still stops its threads (without waiting).
    fn drop(&mut self) {
        self.stop.trigger();
        self.network.net_stop.trigger();
    }
}

/// Runs the daemon until `shutdown` is triggered (Ctrl-C in `telerobot run`).
pub fn run(config: RunConfig, shutdown: Shutdown) -> Result<Summary, DaemonError> {
    let telerobot = Telerobot::start(config)?;
    while !shutdown.wait_timeout(Duration::from_secs(3600)) {}
    Ok(telerobot.stop())
}

/// The housekeeping thread's state.
struct Keeper {
    settings: TelerobotSettings,
    spares: Arc<Spares>,
    snapshots: Arc<Mailbox<LoopSnapshot>>,
    shared: Arc<Housekeeping>,
    link: TelerobotLink,
    timing: Arc<rt::LoopTiming>,
    command_latency: Arc<Mailbox<i64>>,
    /// Command latencies \[ns\] for the summary: a histogram (0.1 % quantiles, fixed size),
    /// so that a daemon left running keeps flat memory (a list grew by 29 MB an hour).
    latencies: rt::Histogram,
    record: Option<Forward>,
    outages: CommandGaps,
}

impl Keeper {
    /// Starts the housekeeping thread.
    fn spawn(
        self,
        stop: &Shutdown,
    ) -> Result<JoinHandle<(rt::Histogram, transport::Outages)>, DaemonError> {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("housekeeping".to_owned())
            .spawn(move || self.run(&stop))
            .map_err(io("the housekeeping thread"))
    }

    /// Runs until `stop`; returns the command latencies \[ns\] and the outages.
    fn run(mut self, stop: &Shutdown) -> (rt::Histogram, transport::Outages) {
        let mut last = LoopSnapshot::default();
        let mut connected = false;
        let mut guard_log = GuardLog::default();
        while !stop.wait_timeout(HOUSEKEEPING) {
            while self.spares.retired.take().is_some() {}
            self.drain_latencies();
            if let Some(s) = self.snapshots.take() {
                *self
                    .shared
                    .snapshot
                    .lock()
                    .unwrap_or_else(PoisonError::into_inner) = s;
                last = s;
                let events = guard_log.update(&last);
                if let Some(f) = &mut self.record {
                    f.events(last.now_ns, events);
                }
                self.outages.update(&last);
            }
            let now_connected = self.link.status().connected();
            if connected && !now_connected {
                self.log_session_end(&last);
            }
            connected = now_connected;
            self.keep_spare(&last);
            if let Some(f) = &mut self.record {
                f.round(&self.link);
            }
        }
        self.drain_latencies();
        if let Some(f) = &mut self.record {
            f.round(&self.link);
        }
        (self.latencies, self.outages.outages)
    }

    fn drain_latencies(&mut self) {
        while let Some(lag) = self.command_latency.take() {
            self.latencies.record(lag);
        }
    }

    /// Keeps a spare node ready for the next session. Where it is built does not matter: the
    /// loop gives it the last node's proxy and cloud ([`TelerobotNode::take_over_geometry`]).
    fn keep_spare(&mut self, last: &LoopSnapshot) {
        if !self.spares.spare.is_empty() {
            return;
        }
        match TelerobotNode::new(self.settings.clone(), last.tool_m) {
            Ok(node) => {
                self.spares.spare.push(Box::new(node));
            }
            Err(e) => tracing::error!("cannot build a spare telerobot node: {e}"),
        }
    }

    fn log_session_end(&self, last: &LoopSnapshot) {
        let t = self.timing.report();
        let n = &last.node;
        tracing::info!(
            session = last.session,
            ticks = n.ticks,
            holding_ticks = n.holding_ticks,
            commands = n.commands,
            stale_commands = n.stale_commands,
            contact_onsets = n.contact_onsets,
            estimators_confident = last.stable,
            loop_period_p99_us = t.period.p99_us,
            loop_overruns = t.overruns,
            "session ended; the robot holds still until the next operator"
        );
    }
}
