//! The `telerobot` commands behind the thin `main.rs`: argument types (clap), their validation
//! into config structs, and one function per subcommand.
//!
//! - `telerobot gen-cert --out DIR` — writes `DIR/telerobot.crt` and `DIR/telerobot.key`.
//! - `telerobot run --listen ADDR --identity DIR --trust OPERATOR_CRT` — validates everything
//!   network-related into a [`RunConfig`], creates the hand-off, and calls [`telerobot_loop`],
//!   which is **not built yet**.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};
use protocol::telerobot_to_operator::SceneSummary;
use rustls_pki_types::CertificateDer;
use transport::LinkTuning;
use transport::identity::{self, Identity, IdentityError};
use transport::tuning::TuningError;

use crate::net::{self, NetConfig, NetIo, TelerobotLink};

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

/// `telerobot run` options.
#[derive(Clone, Debug, Args)]
pub struct RunArgs {
    /// UDP address to listen on, IP:PORT (e.g. 0.0.0.0:4433).
    #[arg(long, value_name = "ADDR", value_parser = parse_addr)]
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
}

/// `telerobot run`'s network settings, validated.
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
}

fn parse_addr(text: &str) -> Result<SocketAddr, String> {
    text.parse()
        .map_err(|_| format!("'{text}' is not IP:PORT (e.g. 0.0.0.0:4433 or [::]:4433)"))
}

impl RunConfig {
    /// Reads the identity and the trusted certificates; every error names the file.
    pub fn from_args(args: &RunArgs) -> Result<RunConfig, ConfigError> {
        let identity = Identity::read_pem(&args.identity, IDENTITY_NAME)?;
        let trusted_operators = args
            .trust
            .iter()
            .map(|path| identity::read_cert(path).map(|cert| (path.clone(), cert)))
            .collect::<Result<_, _>>()?;
        Ok(RunConfig {
            listen: args.listen,
            identity,
            trusted_operators,
            tuning: LinkTuning::with_expected_delay_ms(args.expected_delay_ms)?,
        })
    }

    /// The server's configuration once the scene is known.
    pub fn net_config(&self, scene: SceneSummary) -> NetConfig {
        let mut config = NetConfig::new(
            self.listen,
            self.identity.clone(),
            self.trusted_operators
                .iter()
                .map(|(_, c)| c.clone())
                .collect(),
            scene,
        );
        config.tuning = self.tuning.clone();
        config
    }
}

/// `telerobot gen-cert`: writes the identity and says what to do with it.
pub fn gen_cert(args: &GenCertArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let names: Vec<&str> = args.names.iter().map(String::as_str).collect();
    let (_, cert, key) = Identity::generate_files(&args.out, IDENTITY_NAME, &names)?;
    out.write_all(identity::handover_note(&cert, &key, "operator run --trust").as_bytes())?;
    Ok(())
}

/// `telerobot run`: validates the configuration, creates the hand-off, and starts the loop.
pub fn run(args: &RunArgs) -> anyhow::Result<()> {
    let config = RunConfig::from_args(args)?;
    for (path, _) in &config.trusted_operators {
        tracing::info!(file = %path.display(), "trusting operator certificate");
    }
    let (link, io) = net::link(net::DEFAULT_OUTBOX_CAPACITY)?;
    telerobot_loop(config, link, io)
}

/// ──────────── NOT BUILT YET: the telerobot's real-time loop (another engineer's task). ────────────
///
/// Receives the validated network configuration and both halves of the hand-off. It is to load
/// the scene, start a tokio runtime running
/// `net::serve(config.net_config(scene), io, shutdown)`, and run the 1 kHz loop on its own
/// thread with `link` (`link.latest_command()` in, `link.send(..)` out).
pub fn telerobot_loop(config: RunConfig, link: TelerobotLink, io: NetIo) -> anyhow::Result<()> {
    let _ = (config, link, io);
    anyhow::bail!("telerobot loop not built yet (the network configuration is valid)")
}
