//! The `telerobot` commands behind the thin `main.rs`: argument types (clap), their validation
//! into config structs, and one function per subcommand.
//!
//! - `telerobot gen-cert --out DIR` — writes `DIR/telerobot.crt` and `DIR/telerobot.key`.
//! - `telerobot run [--scene FILE] --listen ADDR --identity DIR --trust OPERATOR_CRT
//!   [--record FILE.mcap] [--live [ADDR]]` — validates the scene, the identity, the trusted
//!   certificates and the loop settings into a [`RunConfig`] and runs the daemon
//!   ([`crate::run`]) until Ctrl-C.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};
use rt::{PeriodicConfig, Shutdown};
use sim::scene::{Scene, SceneError};
use transport::identity::{self, Identity, IdentityError};
use transport::tuning::TuningError;
use transport::{LinkTuning, address};

pub use crate::daemon::RunConfig;

/// The identity name: files `telerobot.crt` / `telerobot.key`.
pub const IDENTITY_NAME: &str = "telerobot";

/// Telerobot side of the model-mediated teleoperation system.
#[derive(Debug, Parser)]
#[command(name = "telerobot", version, about)]
pub struct Cli {
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
#[allow(clippy::large_enum_variant)] // parsed once at start; boxing buys nothing
pub enum Command {
    /// Make the telerobot's certificate and key (DIR/telerobot.crt, DIR/telerobot.key).
    GenCert(GenCertArgs),
    /// Serve operators and run the telerobot loop.
    Run(RunArgs),
}

/// `telerobot gen-cert` options.
#[derive(Clone, Debug, Args)]
pub struct GenCertArgs {
    /// Directory to write telerobot.crt and telerobot.key into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Names to put in the certificate (DNS names or IP addresses); informational only, the
    /// operator pins the whole certificate.
    #[arg(long = "name", value_name = "NAME", default_values_t = ["telerobot".to_owned(), "localhost".to_owned()])]
    pub names: Vec<String>,
}

/// `telerobot run` options. Negative numbers are values (`--spin-us -1` is refused by the range
/// check, as `--spin-us=-1` is, not taken for a flag).
#[derive(Clone, Debug, Args)]
#[command(allow_negative_numbers = true)]
pub struct RunArgs {
    /// UDP address to listen on, IP:PORT (e.g. 0.0.0.0:4433).
    #[arg(long, value_name = "ADDR", value_parser = address::parse_listen_addr)]
    pub listen: SocketAddr,
    /// Directory holding telerobot.crt and telerobot.key (from `telerobot gen-cert`).
    #[arg(long, value_name = "DIR")]
    pub identity: PathBuf,
    /// Certificate of an operator allowed to connect (its operator.crt); repeat for several.
    #[arg(long = "trust", value_name = "OPERATOR_CRT", required = true)]
    pub trust: Vec<PathBuf>,
    /// Expected one-way delay of the link [ms]; sets QUIC's initial RTT estimate.
    #[arg(long, value_name = "MS", default_value_t = 20.0)]
    pub expected_delay_ms: f64,
    /// Scene file (TOML, e.g. scenes/exp1.toml); default: the built-in exp-1 scene.
    #[arg(long, value_name = "FILE")]
    pub scene: Option<PathBuf>,
    /// Seed of the simulated sensors' and camera's noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Busy-spin before each loop deadline [µs], 0 to 200 (absorbs the kernel timer's lateness;
    /// costs that share of a core).
    #[arg(long, value_name = "US", default_value_t = 100.0)]
    pub spin_us: f64,
    /// Run the loop thread under SCHED_FIFO at this priority (1-99; needs CAP_SYS_NICE).
    #[arg(long, value_name = "PRIO", value_parser = rt::thread::parse_priority)]
    pub realtime_priority: Option<u8>,
    /// Recording and live view.
    #[command(flatten)]
    pub record: record::cli::RecordArgs,
    /// The robot and its command limits.
    #[command(flatten)]
    pub robot: crate::robot::RobotArgs,
}

/// Why the command line could not be turned into a [`RunConfig`].
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// A certificate or key file is missing or unreadable.
    #[error(transparent)]
    Identity(#[from] IdentityError),
    /// `--expected-delay-ms` is out of range.
    #[error("--expected-delay-ms: {0}")]
    Tuning(#[from] TuningError),
    /// The scene file could not be read.
    // The OS's reason is in the message and not a `source`: the binaries print error chains,
    // and it was printed twice ("Is a directory (os error 21): Is a directory (os error 21)").
    #[error("cannot read scene file {file}: {error}")]
    SceneFile {
        /// The file.
        file: String,
        /// The operating system's reason.
        error: std::io::Error,
    },
    /// The scene is invalid (the message names the field, the value and the allowed range).
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// `--spin-us` is out of range.
    #[error("--spin-us {0}: expected 0 to 200 µs")]
    Spin(f64),
    /// A robot option.
    #[error(transparent)]
    Robot(#[from] crate::robot::RobotArgsError),
}

impl RunConfig {
    /// Reads the scene, the identity and the trusted certificates; every error names the file.
    pub fn from_args(args: &RunArgs) -> Result<RunConfig, ConfigError> {
        let scene = match &args.scene {
            Some(path) => {
                let file = path.display().to_string();
                let text =
                    std::fs::read_to_string(path).map_err(|error| ConfigError::SceneFile {
                        file: file.clone(),
                        error,
                    })?;
                let mut scene = Scene::from_toml(&text, &file)?;
                // A cloud file is named relative to the scene file.
                if let Some(cloud) = scene.cloud.path.take() {
                    let resolved = crate::camera::file::resolve(&cloud, Some(path));
                    scene.cloud.path = Some(resolved.display().to_string());
                }
                scene
            }
            None => Scene::exp1(),
        };
        if !(args.spin_us.is_finite() && (0.0..=200.0).contains(&args.spin_us)) {
            return Err(ConfigError::Spin(args.spin_us));
        }
        let identity = Identity::read_pem(&args.identity, IDENTITY_NAME)?;
        let trusted_operators = args
            .trust
            .iter()
            .map(|path| identity::read_cert(path).map(|cert| (path.clone(), cert)))
            .collect::<Result<_, _>>()?;
        let robot = args.robot.robot_config()?;
        let limits = args.robot.limits(&scene)?;
        Ok(RunConfig {
            robot,
            limits,
            listen: args.listen,
            identity,
            trusted_operators,
            tuning: LinkTuning::with_expected_delay_ms(args.expected_delay_ms)?,
            start_m: RunConfig::default_start(&scene),
            scene,
            seed: args.seed,
            periodic: PeriodicConfig {
                spin_ns: (args.spin_us * 1e3).round() as i64,
                ..PeriodicConfig::default()
            },
            realtime_priority: args.realtime_priority,
            record: None,
        })
    }
}

/// `telerobot gen-cert`: writes the identity and says what to do with it.
pub fn gen_cert(args: &GenCertArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let names: Vec<&str> = args.names.iter().map(String::as_str).collect();
    let (_, cert, key) = Identity::generate_files(&args.out, IDENTITY_NAME, &names)?;
    out.write_all(identity::handover_note(&cert, &key, "operator run --trust").as_bytes())?;
    Ok(())
}

/// `telerobot run`: validates the configuration, then runs the daemon until `shutdown` (Ctrl-C
/// or SIGTERM in the binary). With `--record`, the file is closed on every way out (the
/// recorder is finished, or dropped on an error).
pub fn run(args: &RunArgs, shutdown: Shutdown) -> anyhow::Result<()> {
    let mut config = RunConfig::from_args(args)?;
    let recorder = args
        .record
        .start(record::Kind::Telerobot, rt::monotonic_ns())?;
    if let Some(addr) = recorder.as_ref().and_then(record::Recorder::live_addr) {
        tracing::info!("live view: open ws://{addr} in Foxglove or Lichtblick");
    }
    config.record = recorder.as_ref().map(record::Recorder::sink);
    crate::run(config, shutdown)?;
    if let Some(recorder) = recorder {
        let report = recorder.finish()?;
        tracing::info!("{}", record::cli::summary(&report));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;

    /// Issue 11: `--spin-us -1` gave clap's "unexpected argument '-1'" while `--spin-us=-1`
    /// gave the range error; both forms now give the range error.
    #[test]
    fn a_negative_number_is_a_value_in_both_forms() {
        let parse = |spin: &[&str]| {
            let mut argv = vec![
                "telerobot",
                "run",
                "--listen",
                "127.0.0.1:0",
                "--identity",
                "/nonexistent",
                "--trust",
                "/nonexistent.crt",
            ];
            argv.extend_from_slice(spin);
            let Command::Run(args) = Cli::try_parse_from(argv).unwrap().command else {
                panic!("not run")
            };
            RunConfig::from_args(&args).unwrap_err().to_string()
        };
        let spaced = parse(&["--spin-us", "-1"]);
        assert_eq!(spaced, parse(&["--spin-us=-1"]));
        assert_eq!(spaced, "--spin-us -1: expected 0 to 200 µs");
    }

    /// Issue 11: `--realtime-priority -1` got clap's "invalid digit found in string"; now both
    /// forms name the range.
    #[test]
    fn a_bad_priority_names_the_range_in_both_forms() {
        for flag in [
            &["--realtime-priority", "-1"][..],
            &["--realtime-priority=-1"],
        ] {
            let mut argv = vec!["telerobot", "run", "--listen", "127.0.0.1:0"];
            argv.extend_from_slice(flag);
            let message = Cli::try_parse_from(argv).unwrap_err().to_string();
            assert!(
                message.contains("expected a SCHED_FIFO priority, an integer from 1 to 99"),
                "{message}"
            );
        }
    }
}
