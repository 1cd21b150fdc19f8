//! The demo run: throw-away certificates in a temporary directory, the telerobot daemon on the
//! built-in exp-1 scene, the netem shim delaying each direction, and the operator app with the
//! scripted exp-1 device — then the report. The same code paths as the two binaries:
//! [`telerobot::Telerobot::start`] (what `telerobot run` runs) and [`operator::app::run`] (what
//! `operator run` runs).
//!
//! ```text
//!  operator app ──QUIC/UDP──▶ netem shim (delay each way) ──▶ telerobot daemon
//!  127.0.0.1:*                127.0.0.1:*                      127.0.0.1:*
//! ```

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use netem::{LinkConfig, ShimConfig};
use rt::{PeriodicConfig, Shutdown};
use sim::scene::Scene;
use telerobot::Telerobot;
use transport::LinkTuning;
use transport::identity::{self, Identity};

use operator::app::{self, Known, RunConfig, RunError};
use operator::device::{DeviceSpec, OpenOptions};
use operator::net::NetConfig;
use operator::safety::SafetyConfig;

use crate::report::{DemoReport, ShimReport};

/// The demo's settings.
#[derive(Clone, Debug)]
pub struct DemoConfig {
    /// One-way delay each way \[ms\], 0 to 2000. Default 400 (the thesis's experiment 3).
    pub delay_ms: f64,
    /// Length of the run \[s\], 5 to 600. Default 20.
    pub seconds: f64,
    /// Spin window of both loops \[µs\] (the shim spins half of it), 0 to 200. Default 100.
    pub spin_us: f64,
    /// Seed of the simulated telerobot. Default 1.
    pub seed: u64,
    /// `SCHED_FIFO` priority of both loops, if wanted (needs `CAP_SYS_NICE`). Default none.
    pub realtime_priority: Option<u8>,
    /// Put the netem shim between the two. Default true; without it (and `delay_ms` 0) the
    /// operator connects to the telerobot directly: the loopback latency figure.
    pub via_shim: bool,
    /// The recorder both sides record to (one file), if the demo records.
    pub record: Option<record::RecordSink>,
    /// The telerobot's scene. Default the built-in exp-1 scene.
    pub scene: Scene,
    /// The telerobot's robot. Default its simulated world; `ros2` drives a robot on a ROS 2
    /// graph (the test arm, in the ROS 2 figures).
    pub robot: telerobot::robot::RobotConfig,
    /// Where the operator streams its records as the run goes (the demo's `--out`).
    pub stream_to: Option<rt::OutDir>,
    /// Random loss the shim adds in each direction \[%\], 0 to 50. Default 0.
    pub loss_pct: f64,
    /// Uniform jitter (half-width) the shim adds in each direction \[ms\], 0 to 100. Default 0.
    pub jitter_ms: f64,
    /// The operator node's settings (its prior). Default `OperatorConfig::default()`.
    pub node: node::operator::OperatorConfig,
    /// The soak's consumer of every tick and measurement; with it, runs up to 24 h are allowed
    /// (the operator's recording keeps only the tap's `keep_ticks`). Default none: up to 600 s.
    pub tap: Option<operator::helper::Tap>,
}

impl Default for DemoConfig {
    fn default() -> Self {
        DemoConfig {
            delay_ms: 400.0,
            seconds: 20.0,
            spin_us: 100.0,
            seed: 1,
            realtime_priority: None,
            node: node::operator::OperatorConfig::default(),
            via_shim: true,
            record: None,
            scene: Scene::exp1(),
            robot: telerobot::robot::RobotConfig::Sim,
            stream_to: None,
            loss_pct: 0.0,
            jitter_ms: 0.0,
            tap: None,
        }
    }
}

/// Why the demo failed.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// A setting out of range.
    #[error("{field} = {value} is out of range: expected {expected}")]
    Setting {
        /// The setting.
        field: &'static str,
        /// Its value.
        value: f64,
        /// The range.
        expected: &'static str,
    },
    /// The certificates could not be made.
    #[error("throw-away certificates: {0}")]
    Identity(#[from] transport::IdentityError),
    /// The link tuning.
    #[error(transparent)]
    Tuning(#[from] transport::tuning::TuningError),
    /// The telerobot daemon could not start.
    #[error("telerobot: {0}")]
    Telerobot(#[from] telerobot::DaemonError),
    /// The shim could not start.
    #[error("netem shim: {0}")]
    Shim(#[from] netem::shim::ShimError),
    /// The operator app failed.
    #[error("operator: {0}")]
    Operator(#[from] RunError),
}

impl DemoConfig {
    /// Checks every setting against its range.
    pub fn validate(&self) -> Result<(), DemoError> {
        let check = |field, value: f64, ok: bool, expected| {
            if ok {
                Ok(())
            } else {
                Err(DemoError::Setting {
                    field,
                    value,
                    expected,
                })
            }
        };
        check(
            "--delay-ms",
            self.delay_ms,
            (0.0..=2000.0).contains(&self.delay_ms),
            "0 to 2000 ms",
        )?;
        if self.tap.is_some() {
            check(
                "--minutes",
                self.seconds / 60.0,
                (60.0..=86_460.0).contains(&self.seconds),
                "1 to 1440 minutes",
            )?;
        } else {
            check(
                "--seconds",
                self.seconds,
                (5.0..=600.0).contains(&self.seconds),
                "5 to 600 s",
            )?;
        }
        check(
            "--loss-pct",
            self.loss_pct,
            (0.0..=50.0).contains(&self.loss_pct),
            "0 to 50 %",
        )?;
        check(
            "--jitter-ms",
            self.jitter_ms,
            (0.0..=100.0).contains(&self.jitter_ms),
            "0 to 100 ms",
        )?;
        check(
            "--loss-pct/--jitter-ms without the shim",
            self.loss_pct + self.jitter_ms,
            self.via_shim || self.loss_pct + self.jitter_ms == 0.0,
            "0 (only the shim adds loss and jitter)",
        )?;
        check(
            "--delay-ms without the shim",
            self.delay_ms,
            self.via_shim || self.delay_ms == 0.0,
            "0 ms (only the shim adds delay)",
        )?;
        check(
            "--spin-us",
            self.spin_us,
            (0.0..=200.0).contains(&self.spin_us),
            "0 to 200 µs",
        )
    }
}

/// What a demo run gives: its report and the operator's series (for the files of `--out`).
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The report.
    pub report: DemoReport,
    /// The operator's series.
    pub series: metrics::Series,
    /// With a recorder: the haptic-loop period while it recorded and while it was paused.
    pub record_periods: Option<[rt::Summary; 2]>,
}

/// Runs the demo (about `seconds` plus a few seconds of set-up). `shutdown` ends it early.
pub fn run(config: &DemoConfig, shutdown: Shutdown) -> Result<Outcome, DemoError> {
    config.validate()?;
    // Written to files and read back, as `gen-cert` and the two `run`s do.
    let certs = Certificates::generate()?;
    let tuning = LinkTuning::with_expected_delay_ms(config.delay_ms)?;
    let spin_ns = (config.spin_us * 1e3).round() as i64;
    let periodic = PeriodicConfig {
        spin_ns,
        ..PeriodicConfig::default()
    };
    let loopback: SocketAddr = ([127, 0, 0, 1], 0).into();
    let scene = config.scene.clone();
    let telerobot = Telerobot::start(telerobot::RunConfig {
        listen: loopback,
        identity: Identity::read_pem(certs.dir.path(), "telerobot")?,
        trusted_operators: vec![(
            certs.operator.clone(),
            identity::read_cert(&certs.operator)?,
        )],
        tuning: tuning.clone(),
        start_m: telerobot::RunConfig::default_start(&scene),
        limits: scene.motion_limits(),
        robot: config.robot.clone(),
        scene: scene.clone(),
        seed: config.seed,
        periodic,
        realtime_priority: config.realtime_priority,
        record: config.record.clone(),
    })?;
    let shim = if config.via_shim {
        Some(start_shim(
            config,
            loopback,
            telerobot.local_addr(),
            spin_ns,
        )?)
    } else {
        None
    };
    let connect = shim
        .as_ref()
        .map_or(telerobot.local_addr(), netem::ShimHandle::local_addr);
    tracing::info!(telerobot = %telerobot.local_addr(), %connect, delay_ms = config.delay_ms,
        "demo: telerobot up");

    let net = operator_net(&certs, connect, tuning)?;
    let operator = app::run(operator_config(config, net, periodic, scene), shutdown);
    let summary = telerobot.stop();
    let shim_stats = shim.map(netem::ShimHandle::shutdown).transpose();
    let mut operator = operator?;
    let shim_stats = shim_stats?;
    operator.report.experiment.telerobot_stats = summary.last.node;
    operator.nodes.telerobot = summary.last.node;
    let report = DemoReport {
        run: operator.report.clone(),
        telerobot: summary,
        shim: shim_stats.as_ref().map(ShimReport::from),
    };
    if let Some(sink) = &config.record {
        // Again, now with the telerobot's and the shim's figures: the reader takes the last.
        let extra = [
            ("telerobot", serde_json::to_value(&report.telerobot)),
            ("shim", serde_json::to_value(report.shim)),
        ];
        let extra = extra
            .into_iter()
            .filter_map(|(k, v)| Some((k.to_owned(), v.ok()?)))
            .collect();
        operator.record_end_with(sink, extra);
    }
    Ok(Outcome {
        report,
        series: operator.series,
        record_periods: operator.record_periods,
    })
}

/// Starts the netem shim on `listen`, delaying each direction to `telerobot` by the demo's
/// delay and spinning half the loops' spin window.
fn start_shim(
    config: &DemoConfig,
    listen: SocketAddr,
    telerobot: SocketAddr,
    spin_ns: i64,
) -> Result<netem::ShimHandle, DemoError> {
    let mut delay = LinkConfig::delay((config.delay_ms * 1e6).round() as u64);
    delay.jitter_ns = (config.jitter_ms * 1e6).round() as u64;
    if config.loss_pct > 0.0 {
        delay.loss = netem::Loss::Random {
            probability: config.loss_pct / 100.0,
        };
    }
    let mut shim_config = ShimConfig::new(listen, telerobot);
    shim_config.up = delay.clone();
    shim_config.down = delay;
    shim_config.spin_window_ns = u64::try_from(spin_ns / 2).unwrap_or(0);
    Ok(netem::shim::start(shim_config)?)
}

/// The operator's connection to `connect`, with its identity and the telerobot's pinned
/// certificate.
fn operator_net(
    certs: &Certificates,
    connect: SocketAddr,
    tuning: LinkTuning,
) -> Result<NetConfig, DemoError> {
    let mut net = NetConfig::new(
        connect,
        Identity::read_pem(certs.dir.path(), "operator")?,
        identity::read_cert(&certs.telerobot)?,
        certs.telerobot.display().to_string(),
        "demo",
    );
    net.tuning = tuning;
    Ok(net)
}

/// The operator app's settings: the scripted exp-1 device for the demo's length, told the
/// scene, seed and delay it runs against.
fn operator_config(
    config: &DemoConfig,
    net: NetConfig,
    periodic: PeriodicConfig,
    scene: Scene,
) -> RunConfig {
    let device = DeviceSpec::Scripted {
        name: "exp1".to_owned(),
    };
    RunConfig {
        net,
        device,
        open: OpenOptions {
            scripted_length_s: Some(config.seconds),
            ..OpenOptions::default()
        },
        safety: SafetyConfig::default(),
        seconds: Some(config.seconds),
        periodic,
        realtime_priority: config.realtime_priority,
        first_session_timeout: Some(Duration::from_secs(15)),
        node: config.node,
        experiment: "demo".to_owned(),
        known: Some(Known {
            scene,
            seed: config.seed,
            delay_ms: config.delay_ms,
        }),
        // Each camera frame is recorded once, by the telerobot.
        record: config
            .record
            .as_ref()
            .map(record::RecordSink::without_clouds),
        stream_to: config.stream_to.clone(),
        tap: config.tap.clone(),
    }
}

/// The throw-away certificates of both ends, as files in a temporary directory.
struct Certificates {
    dir: TempDir,
    /// The telerobot's certificate file.
    telerobot: PathBuf,
    /// The operator's certificate file.
    operator: PathBuf,
}

impl Certificates {
    fn generate() -> Result<Certificates, DemoError> {
        let dir = TempDir::new();
        let names = ["telerobot", "localhost"];
        let (_, telerobot, _) = Identity::generate_files(dir.path(), "telerobot", &names)?;
        let (_, operator, _) = Identity::generate_files(dir.path(), "operator", &["operator"])?;
        Ok(Certificates {
            dir,
            telerobot,
            operator,
        })
    }
}

/// A temporary directory removed on drop.
struct TempDir(PathBuf);

impl TempDir {
    fn new() -> TempDir {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        TempDir(std::env::temp_dir().join(format!("mmt-demo-{}-{nanos}", std::process::id())))
    }

    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}
