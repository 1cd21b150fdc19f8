//! `operator run`: the operator app — the network runtime, the haptic loop and its helper thread
//! — until the run's length or the shutdown signal, then the report ([`crate::report`]).
//!
//! Threads:
//! - `operator-net`: a one-worker tokio runtime running the QUIC client with reconnect
//!   ([`crate::net::connect_and_run`]);
//! - `haptic-loop`: the 1 kHz loop ([`crate::haptic`]) on absolute deadlines plus a short spin;
//! - `haptic-helper`: cloud indices, nodes for reconnections, the recording ([`crate::helper`]).
//!
//! The loop starts with the first session (it needs the telerobot's `Welcome` to know what to
//! render); until then the app waits, retrying the connection.

use std::time::{Duration, Instant};

use metrics::Series;
use node::operator::{OperatorConfig, OperatorNode};
use rt::monotonic_ns;
use rt::{Periodic, PeriodicConfig, Shutdown};
use sim::scene::Scene;

use crate::device::HapticDevice;
use crate::device::{DeviceError, DeviceSpec, OpenOptions, open_device};
use crate::haptic::{Exchange, HapticLoop, LoopEnd};
use crate::helper;
use crate::helper::Recording;
use crate::net::{self, NetConfig, NetError, OperatorLink};
use crate::report::{self, NetworkedReport, RunFacts};
use crate::safety::{SafetyConfig, SafetyError, SafetyLayer};
use node::{OperatorSettings, SettingsError};
use protocol::telerobot_to_operator::Welcome;
use record::RecordSink;
use record::schema::{RunEnd, RunStart};

/// Everything `operator run` needs, validated.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// The telerobot and the certificates.
    pub net: NetConfig,
    /// The device.
    pub device: DeviceSpec,
    /// Device settings.
    pub open: OpenOptions,
    /// Safety settings (the device's limits come from the device).
    pub safety: SafetyConfig,
    /// Run length \[s\] from the first session; `None`: until the shutdown signal.
    pub seconds: Option<f64>,
    /// Spin window of the loop (its period comes from the telerobot's control rate).
    pub periodic: PeriodicConfig,
    /// `SCHED_FIFO` priority of the loop thread, if wanted.
    pub realtime_priority: Option<u8>,
    /// How long to wait for the first session; `None`: until the shutdown signal.
    pub first_session_timeout: Option<Duration>,
    /// How the operator node decides contact and keeps in step.
    pub node: OperatorConfig,
    /// Report name: `networked`, or `demo`.
    pub experiment: String,
    /// What the run knows beyond the wire (the demo): the scene's truth, the seed and the set
    /// delay.
    pub known: Option<Known>,
    /// The recorder (`--record`, `--live`), if the run records: every tick, measurement,
    /// message taken, cloud, link statistics and event goes to it from the helper thread, and
    /// the run's start and end.
    pub record: Option<RecordSink>,
    /// Where the run's records are streamed as it goes (`--out`, checked before the run):
    /// `ticks.csv` and `measurements.csv`, flushed every [`crate::helper::STREAM_FLUSH`], so
    /// that a killed run leaves them readable up to the last flush.
    pub stream_to: Option<rt::OutDir>,
    /// A consumer of every tick and measurement as the run goes, and how many the run's own
    /// recording keeps (the soak: per-minute figures, flat memory). `None`: the recording keeps
    /// the first [`helper::MAX_RECORDED_TICKS`].
    pub tap: Option<helper::Tap>,
}

/// What the demo knows about the telerobot.
#[derive(Clone, Debug)]
pub struct Known {
    /// The telerobot's scene (its ground truth).
    pub scene: Scene,
    /// The telerobot's seed.
    pub seed: u64,
    /// The one-way delay set on the shim \[ms\].
    pub delay_ms: f64,
}

/// Why a run could not start or go on.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The device could not be opened.
    #[error(transparent)]
    Device(#[from] DeviceError),
    /// A safety setting is invalid.
    #[error(transparent)]
    Safety(#[from] SafetyError),
    /// The loop settings are invalid.
    #[error(transparent)]
    Loop(#[from] rt::PeriodicError),
    /// The telerobot refused us, or we refused it (certificates, version, busy).
    #[error(transparent)]
    Net(#[from] NetError),
    /// The telerobot's scene summary cannot be run (control rate, contact radii).
    #[error(transparent)]
    Settings(#[from] SettingsError),
    /// The operator node could not be built.
    #[error("operator node: {0}")]
    Node(#[from] node::telerobot::NodeError),
    /// No session within the timeout.
    #[error("no session with the telerobot at {addr} within {timeout:?}{last}")]
    NoSession {
        /// The telerobot's address.
        addr: std::net::SocketAddr,
        /// The timeout.
        timeout: Duration,
        /// Why the last attempt failed, if known.
        last: String,
    },
    /// Stopped before the first session.
    #[error("stopped before a session with the telerobot opened")]
    Stopped,
    /// A runtime, socket or thread could not be created.
    /// (The OS error is in the message, not the `source()`, so that printed error chains do not
    /// repeat it.)
    #[error("{what}: {error}")]
    Io {
        /// What was being created.
        what: &'static str,
        /// The operating system's reason.
        error: std::io::Error,
    },
}

fn io(what: &'static str) -> impl FnOnce(std::io::Error) -> RunError {
    move |error| RunError::Io { what, error }
}

/// A finished run: its report and the time series behind it.
pub struct Outcome {
    /// The report.
    pub report: NetworkedReport,
    /// The series (for the files of `--out`).
    pub series: Series,
    /// What the nodes knew at the end (the report's `NodeInfo`).
    pub nodes: metrics::NodeInfo,
    /// The newest surface frame received (the report's axes).
    pub frame: Option<protocol::telerobot_to_operator::SurfaceFrame>,
    /// The clock offset at the end (telerobot − operator) \[ns\].
    pub final_offset_ns: Option<i64>,
    /// Haptic-loop ticks run.
    pub ticks: u64,
    /// With a recorder: the haptic-loop period while it recorded and while it was paused
    /// (`helper::Recording::periods`).
    pub record_periods: Option<[rt::Summary; 2]>,
}

/// Runs the operator until the run's length or `shutdown`, then reports.
pub fn run(config: RunConfig, shutdown: Shutdown) -> Result<Outcome, RunError> {
    let run_started = Instant::now();
    let mut device = open_device(&config.device, &config.open)?;
    let spec = device.spec().clone();
    let mut safety = SafetyLayer::new(&spec, &config.safety)?;
    let forces = crate::cli::force_line(&config.device, &spec);
    if spec.outputs_force {
        tracing::info!(device = %config.device, name = %spec.name, "{forces}");
    } else {
        tracing::warn!(device = %config.device, name = %spec.name, "{forces}");
    }
    let (link, mut network) = Network::start(&config.net)?;

    // The first session: its Welcome says what to render.
    let session = match wait_for_session(&config, &link, &shutdown, &network.task) {
        Ok(session) => session,
        Err(e) => {
            let net_error = network.stop().err();
            return Err(net_error.map_or(e, RunError::Net));
        }
    };
    let welcome = link.status().welcome().ok_or(RunError::Stopped)?;
    let settings = OperatorSettings::from_welcome(&welcome.scene)?;
    tracing::info!(scene = %welcome.scene.name, rate_hz = welcome.scene.control_rate_hz,
        normal = ?welcome.scene.normal, tangential = ?welcome.scene.tangential,
        "session open: rendering the telerobot's scene");
    let node = first_node(&config, settings, device.as_mut(), &mut safety)?;
    let haptic = HapticLoop {
        node,
        session,
        device,
        safety,
        link: link.clone(),
        exchange: std::sync::Arc::new(Exchange::default()),
        shutdown: shutdown.clone(),
        // What is left of `--seconds` after waiting for the session.
        ticks: config.seconds.map(|s| {
            let left = (s - run_started.elapsed().as_secs_f64()).max(0.0);
            (left * 1e9 / settings.period_ns as f64).round() as u64
        }),
    };
    let loops = run_loops(&config, haptic, settings.period_ns, &welcome)?;
    report(&config, &welcome, settings.period_ns, &link, network, loops)
}

/// The network runtime (`operator-net`) and its one task: the QUIC client with reconnect.
struct Network {
    task: tokio::task::JoinHandle<Result<(), NetError>>,
    stop: Shutdown,
    runtime: tokio::runtime::Runtime,
}

impl Network {
    /// Starts the runtime and the client on it; returns the loop's end of the link too.
    fn start(net: &NetConfig) -> Result<(OperatorLink, Network), RunError> {
        let runtime =
            transport::network_runtime("operator-net").map_err(io("the network runtime"))?;
        let (link, net_io) = net::link(
            net::DEFAULT_OUTBOX_CAPACITY,
            net::DEFAULT_MEASUREMENT_CAPACITY,
        )
        .map_err(io("the loop's hand-off"))?;
        let net_stop = Shutdown::new();
        let task = {
            let stop = net_stop.clone();
            runtime.spawn(net::connect_and_run(net.clone(), net_io, async move {
                stop.wait().await;
            }))
        };
        Ok((
            link,
            Network {
                task,
                stop: net_stop,
                runtime,
            },
        ))
    }

    /// Stops the client and waits for it (at most 3 s); the error it ended with, if any.
    fn stop(&mut self) -> Result<(), NetError> {
        self.stop.trigger();
        let task = &mut self.task;
        self.runtime
            .block_on(async { tokio::time::timeout(Duration::from_secs(3), task).await })
            .ok()
            .and_then(Result::ok)
            .unwrap_or(Ok(()))
    }
}

/// Readies the loop for the session's `settings`: the overrun watchdog on its period, the
/// device read once, and the first operator node where the device stands.
fn first_node(
    config: &RunConfig,
    settings: OperatorSettings,
    device: &mut dyn HapticDevice,
    safety: &mut SafetyLayer,
) -> Result<Box<OperatorNode>, RunError> {
    // The loop runs at the telerobot's control rate: the overrun rule measures against it.
    let period = Duration::from_nanos(u64::try_from(settings.period_ns).unwrap_or(0));
    safety.set_loop_period(period)?;
    tracing::info!(period = ?period, allowance = ?config.safety.watchdog.max_overrun,
        "loop-overrun watchdog set to the session's tick period");
    device.update(Duration::ZERO)?;
    let start = safety.command_position(device.measured_cp(), device.clutch());
    Ok(Box::new(OperatorNode::new(settings, config.node, start)?))
}

/// What the two loop threads left, and the loop's schedule.
struct Loops {
    /// The haptic loop's end (`Err` if it panicked).
    end: std::thread::Result<LoopEnd>,
    /// The helper's recording (`Err` if it panicked).
    recording: std::thread::Result<Recording>,
    /// Tick 0's time [ns].
    start_ns: i64,
    /// The loop's timing.
    timing: std::sync::Arc<rt::LoopTiming>,
    /// Wall-clock length of the loop \[s\].
    wall_seconds: f64,
}

/// Starts the helper thread, then runs `haptic` on its own thread at `period_ns` until it
/// stops; then stops the helper.
fn run_loops(
    config: &RunConfig,
    haptic: HapticLoop,
    period_ns: i64,
    welcome: &Welcome,
) -> Result<Loops, RunError> {
    let helper_stop = Shutdown::new();
    let streams = match &config.stream_to {
        Some(dir) => Some(helper::Streams::open(dir).map_err(|e| RunError::Io {
            what: "the streamed records",
            error: std::io::Error::other(e.to_string()),
        })?),
        None => None,
    };
    let helper = helper::spawn(
        haptic.link.clone(),
        std::sync::Arc::clone(&haptic.exchange),
        haptic.session,
        config.node,
        helper::Outputs {
            record: config.record.clone(),
            streams,
            tap: config.tap.clone(),
        },
        helper_stop.clone(),
    )
    .map_err(io("the helper thread"))?;
    let periodic_config = PeriodicConfig {
        period_ns,
        ..config.periodic
    };
    let periodic = Periodic::new(periodic_config, monotonic_ns() + 2_000_000)?;
    let start_ns = periodic.start_ns();
    if let Some(sink) = &config.record {
        let start = run_start(config, &welcome.scene, start_ns, period_ns);
        sink.send_one(start_ns, record::Message::Run(Box::new(start)));
    }
    let timing = periodic.timing();
    if let Some(tap) = &config.tap {
        let start = helper::Tapped::Start {
            start_ns,
            period_ns,
            timing: std::sync::Arc::clone(&timing),
        };
        let _ = tap.to.send(start);
    }
    let started = Instant::now();
    let haptic = rt::spawn("haptic-loop", config.realtime_priority, move || {
        haptic.run(periodic)
    })
    .map_err(io("the haptic loop thread"))?;
    let end = haptic.join();
    let wall_seconds = started.elapsed().as_secs_f64();
    helper_stop.trigger();
    let recording = helper.join();
    Ok(Loops {
        end,
        recording,
        start_ns,
        timing,
        wall_seconds,
    })
}

/// After the loops: the link's counters, the network stopped, then the run's report.
fn report(
    config: &RunConfig,
    welcome: &Welcome,
    period_ns: i64,
    link: &OperatorLink,
    mut network: Network,
    loops: Loops,
) -> Result<Outcome, RunError> {
    let stats = link.stats();
    let mut final_link: transport::LinkReport = stats.into();
    let overwritten = link.measurements_overwritten();
    let net_result = network.stop();
    // quinn's counts are read once more when the session's link is dropped (the session's RTT
    // and clock are forgotten then, so they come from before).
    let closed = link.stats();
    final_link.sent = closed.sent;
    final_link.quinn_datagrams_transmitted = closed.quinn_datagrams_transmitted;
    final_link.quinn_congestion_events = closed.quinn_congestion_events;
    final_link.quinn_lost_packets = closed.quinn_lost_packets;
    final_link.max_gap_ms = closed.max_gap_ns as f64 / 1e6;
    let (Ok(end), Ok(recording)) = (loops.end, loops.recording) else {
        return Err(RunError::Io {
            what: "the haptic loop",
            error: std::io::Error::other("a loop thread panicked"),
        });
    };
    if let Err(e) = net_result {
        tracing::warn!("the network task ended with: {e}");
    }
    let facts = RunFacts {
        run: metrics::networked::NetworkedRun {
            experiment: config.experiment.clone(),
            scene: welcome.scene.name.clone(),
            left_out: welcome.scene.left_out.clone(),
            device: config.device.to_string(),
            seed: config.known.as_ref().map_or(0, |k| k.seed),
            set_delay_ms: config.known.as_ref().map(|k| k.delay_ms),
            start_ns: loops.start_ns,
            period_ns,
            final_offset_ns: stats.clock_offset_ns,
            frame: None,
        },
        truth: config.known.as_ref().map(|k| k.scene.clone()),
        link: final_link,
        measurements_overwritten: overwritten,
        timing: loops.timing.report(),
        wall_seconds: loops.wall_seconds,
    };
    let (series, report) = report::build(&facts, &recording, &end);
    let outcome = Outcome {
        report,
        series,
        nodes: report::node_info(facts.truth.as_ref(), &end),
        frame: end.frame,
        final_offset_ns: stats.clock_offset_ns,
        ticks: end.ticks,
        record_periods: config
            .record
            .as_ref()
            .map(|_| recording.periods.each_ref().map(rt::Histogram::summary)),
    };
    if let Some(sink) = &config.record {
        outcome.record_end(sink);
    }
    Ok(outcome)
}

/// The recording's `/run` of the operator side.
fn run_start(
    config: &RunConfig,
    scene: &protocol::telerobot_to_operator::SceneSummary,
    start_ns: i64,
    period_ns: i64,
) -> RunStart {
    RunStart {
        side: record::Side::Operator,
        experiment: config.experiment.clone(),
        start_ns,
        period_ns,
        scene_name: scene.name.clone(),
        left_out: scene.left_out.clone(),
        proxy_radii_m: scene.proxy_radii_m,
        device: Some(config.device.to_string()),
        seed: config.known.as_ref().map(|k| k.seed),
        set_delay_ms: config.known.as_ref().map(|k| k.delay_ms),
        scene: config.known.as_ref().map(|k| k.scene.clone()),
        config: None,
        axes: None,
        tool_start_m: None,
    }
}

impl Outcome {
    /// Records the run's end (`/run/end`): what the report needs beyond the recorded streams.
    /// The demo records it again once it has added the telerobot's and the shim's figures; a
    /// reader takes the last.
    pub fn record_end(&self, sink: &RecordSink) {
        self.record_end_with(sink, serde_json::Map::new());
    }

    /// [`Outcome::record_end`] with counters the operator does not know added (the demo's
    /// telerobot and shim figures, under their keys in its `report.json`).
    pub fn record_end_with(
        &self,
        sink: &RecordSink,
        extra: serde_json::Map<String, serde_json::Value>,
    ) {
        let mut counters = self.report.counters();
        if let Some(all) = counters.as_object_mut() {
            all.extend(extra);
        }
        let end = RunEnd {
            side: record::Side::Operator,
            ticks: self.ticks,
            nodes: Some(self.nodes.clone()),
            frame: self.frame.map(record::schema::FrameRec::from),
            final_offset_ns: self.final_offset_ns,
            counters: Some(counters),
            recorder_dropped: sink.dropped(),
        };
        sink.send_one(monotonic_ns(), record::Message::RunEnd(Box::new(end)));
    }
}

/// Waits for the first session; returns its number.
fn wait_for_session(
    config: &RunConfig,
    link: &OperatorLink,
    shutdown: &Shutdown,
    net_task: &tokio::task::JoinHandle<Result<(), NetError>>,
) -> Result<u64, RunError> {
    let waited = Instant::now();
    let mut logged = false;
    loop {
        let status = link.status();
        if status.connected() && status.welcome().is_some() {
            return Ok(status.session());
        }
        if net_task.is_finished() {
            // A refusal that retrying will not fix: the caller collects the task's error.
            return Err(RunError::Stopped);
        }
        if shutdown.wait_timeout(Duration::from_millis(10)) {
            return Err(RunError::Stopped);
        }
        // `--seconds` bounds the whole run, connected or not.
        let bound = [
            config.first_session_timeout,
            config
                .seconds
                .and_then(|s| Duration::try_from_secs_f64(s).ok()),
        ]
        .into_iter()
        .flatten()
        .min();
        if let Some(timeout) = bound
            && waited.elapsed() > timeout
        {
            return Err(RunError::NoSession {
                addr: config.net.connect,
                timeout,
                last: status
                    .last_disconnect()
                    .map_or(String::new(), |r| format!(" (last attempt: {r})")),
            });
        }
        if !logged && waited.elapsed() > Duration::from_secs(2) {
            logged = true;
            tracing::info!(telerobot = %config.net.connect, "waiting for the telerobot");
        }
    }
}
