//! The network half of the `operator` command line: `gen-cert`, and the `run` flags that say
//! where the telerobot is and which certificates to present and pin.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;

use clap::Args;
use transport::identity::{self, Identity, IdentityError};
use transport::tuning::TuningError;
use transport::{LinkTuning, address};

use crate::net::NetConfig;

/// The identity name: files `operator.crt` / `operator.key`.
pub const IDENTITY_NAME: &str = "operator";

/// `operator gen-cert` options.
#[derive(Clone, Debug, Args)]
pub struct GenCertArgs {
    /// Directory to write operator.crt and operator.key into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Names to put in the certificate; informational only, the telerobot compares the whole
    /// certificate.
    #[arg(long = "name", value_name = "NAME", default_values_t = ["operator".to_owned()])]
    pub names: Vec<String>,
}

/// `operator run` network options: all three of `--connect`, `--identity` and `--trust`, or
/// none (device check only).
#[derive(Clone, Debug, Args)]
pub struct NetArgs {
    /// The telerobot's UDP address, IP:PORT (e.g. 192.168.1.20:4433).
    #[arg(long, value_name = "ADDR", value_parser = address::parse_connect_addr, requires_all = ["identity", "trust"])]
    pub connect: Option<SocketAddr>,
    /// Directory holding operator.crt and operator.key (from `operator gen-cert`).
    #[arg(long, value_name = "DIR", requires_all = ["connect", "trust"])]
    pub identity: Option<PathBuf>,
    /// The telerobot's certificate (its telerobot.crt): the only one accepted.
    #[arg(long, value_name = "TELEROBOT_CRT", requires_all = ["connect", "identity"])]
    pub trust: Option<PathBuf>,
    /// Our name, shown in the telerobot's log and to other operators while we are in control.
    #[arg(
        long = "operator-name",
        value_name = "NAME",
        default_value = "operator"
    )]
    pub operator_name: String,
    /// Expected one-way delay of the link [ms]; sets QUIC's initial RTT estimate.
    #[arg(long, value_name = "MS", default_value_t = 20.0)]
    pub expected_delay_ms: f64,
    /// End the run when the telerobot is busy (another operator in control), instead of asking
    /// again until `--seconds` is over.
    #[arg(long)]
    pub no_wait: bool,
}

/// Why the network flags could not be turned into a [`NetConfig`].
#[derive(Debug, thiserror::Error)]
pub enum NetArgsError {
    /// A certificate or key file is missing or unreadable.
    #[error(transparent)]
    Identity(#[from] IdentityError),
    /// `--expected-delay-ms` is out of range.
    #[error("--expected-delay-ms: {0}")]
    Tuning(#[from] TuningError),
    /// The operator name is empty or too long.
    #[error("--operator-name '{0}': expected 1 to 64 characters")]
    Name(String),
}

impl NetArgs {
    /// The client configuration, or `None` when no network flags were given. Reads the identity
    /// and the pinned certificate; every error names the file.
    pub fn config(&self) -> Result<Option<NetConfig>, NetArgsError> {
        let (Some(connect), Some(dir), Some(trust)) = (self.connect, &self.identity, &self.trust)
        else {
            return Ok(None);
        };
        let name_len = self.operator_name.chars().count();
        if !(1..=64).contains(&name_len) {
            return Err(NetArgsError::Name(self.operator_name.clone()));
        }
        let identity = Identity::read_pem(dir, IDENTITY_NAME)?;
        let pinned = identity::read_cert(trust)?;
        let mut config = NetConfig::new(
            connect,
            identity,
            pinned,
            trust.display().to_string(),
            self.operator_name.clone(),
        );
        config.tuning = LinkTuning::with_expected_delay_ms(self.expected_delay_ms)?;
        config.wait_when_busy = !self.no_wait;
        Ok(Some(config))
    }
}

/// `operator gen-cert`: writes the identity and says what to do with it.
pub fn gen_cert(args: &GenCertArgs, out: &mut dyn Write) -> anyhow::Result<()> {
    let names: Vec<&str> = args.names.iter().map(String::as_str).collect();
    let (_, cert, key) = Identity::generate_files(&args.out, IDENTITY_NAME, &names)?;
    out.write_all(identity::handover_note(&cert, &key, "telerobot run --trust").as_bytes())?;
    Ok(())
}
