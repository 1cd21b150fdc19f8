//! The operator's QUIC client (`DESIGN.md` §7): connects to the pinned telerobot, opens the
//! session, pumps datagrams between the connection and the haptic loop, and reconnects.
//!
//! - The TLS handshake accepts only the telerobot certificate given in [`NetConfig`] (exact DER,
//!   [`transport::pin`]) and presents the operator's own, which the telerobot must trust.
//! - Control stream: `Hello` → `Welcome` (its scene summary in [`SessionStatus::welcome`]), or a
//!   `Refused` surfaced as [`NetError::Handshake`] (busy, version mismatch naming both versions).
//! - Session: commands from the loop's outbox as datagrams; a `Ping` every
//!   [`NetConfig::ping_interval`] feeding a `ClockOffsetEstimator`; incoming `Parameters`,
//!   `Contact` and `StateSync` into latest-value slots (stale and duplicate ones dropped per kind
//!   with `LatestSeq`), `Measurement`s into a bounded queue, clouds (one stream each) into a
//!   latest-cloud slot; anything else counted as garbage.
//! - **Reconnects** with exponential backoff when the telerobot goes away or cannot be reached;
//!   refusals and certificate failures are returned, not retried (they will not fix themselves).
//!
//! Logging: one event per connect, refusal and disconnect; nothing per datagram. Not here: the
//! haptic loop (it gets an [`OperatorLink`]), rendering, devices.

mod link;
mod session;

use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr};
use std::sync::Arc;
use std::time::Duration;

use protocol::handshake::HandshakeError;
use rustls_pki_types::CertificateDer;
use tokio::sync::watch;
use transport::{CloseCode, EndpointError, Identity, LinkTuning, TelerobotPin};

pub use link::{
    DEFAULT_MEASUREMENT_CAPACITY, DEFAULT_OUTBOX_CAPACITY, NetIo, OperatorLink, SessionStatus, link,
};

/// Everything the client needs.
#[derive(Clone, Debug)]
pub struct NetConfig {
    /// The telerobot's UDP address.
    pub connect: SocketAddr,
    /// The operator's certificate and key (the telerobot must trust the certificate).
    pub identity: Identity,
    /// The only telerobot certificate accepted.
    pub telerobot_cert: CertificateDer<'static>,
    /// Where `telerobot_cert` came from (its file), for the mismatch error.
    pub telerobot_cert_source: String,
    /// Our name in the `Hello` (the telerobot's log; what a second operator is told).
    pub operator_name: String,
    /// Ask for point clouds (local contact detection needs them). Default true.
    pub want_clouds: bool,
    /// quinn settings ([`LinkTuning::default`] for the rig).
    pub tuning: LinkTuning,
    /// Period of the clock-offset `Ping`. Default 100 ms (network notes §5.2): the estimator
    /// keeps the least-delayed of the last 16, i.e. a 1.6 s window that follows drift.
    pub ping_interval: Duration,
    /// How long connecting plus `Hello`/`Welcome` may take. Default 10 s (several round trips at
    /// 800 ms).
    pub handshake_timeout: Duration,
    /// First wait before reconnecting; doubled after each failed attempt. Default 250 ms.
    pub reconnect_initial: Duration,
    /// Longest wait between attempts. Default 4 s.
    pub reconnect_max: Duration,
    /// Cloud streams the telerobot may have open at once. Default 16: a stream holds its slot
    /// until this side has read it and the credit is back, a round trip (0.8 s at 400 ms), and
    /// a loss recovery more when one of its ~25 packets is lost (40 % of frames at 2 % loss).
    /// With 4, the soak (400 ms, 2 % loss) got 2 frames a second of 29, each over a second old,
    /// and contact on the sliding object suffered. With 64, a 2 s outage left up to 64 frames
    /// (2.2 MB) to send at once, more than the 2 MiB congestion window, and the datagrams
    /// waited behind them: a second outage after the first. 16 frames stay under a quarter of
    /// the window. A frame waiting for a slot is superseded by the next one (latest wins).
    pub max_cloud_streams: u32,
    /// A telerobot that answers "busy" is asked again (with the backoff) until the run ends,
    /// instead of ending the run. Default true; `--no-wait` turns it off.
    pub wait_when_busy: bool,
}

impl NetConfig {
    /// A configuration with the defaults above.
    pub fn new(
        connect: SocketAddr,
        identity: Identity,
        telerobot_cert: CertificateDer<'static>,
        telerobot_cert_source: impl Into<String>,
        operator_name: impl Into<String>,
    ) -> NetConfig {
        NetConfig {
            connect,
            identity,
            telerobot_cert,
            telerobot_cert_source: telerobot_cert_source.into(),
            operator_name: operator_name.into(),
            want_clouds: true,
            tuning: LinkTuning::default(),
            ping_interval: Duration::from_millis(100),
            handshake_timeout: Duration::from_secs(10),
            reconnect_initial: Duration::from_millis(250),
            reconnect_max: Duration::from_secs(4),
            max_cloud_streams: 16,
            wait_when_busy: true,
        }
    }
}

/// Why the client stopped (other than being told to).
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// The telerobot's TLS handshake refused the operator's certificate.
    #[error("the telerobot refused our certificate: not in its trusted set")]
    NotTrusted,
    /// The telerobot presented another certificate than the pinned one.
    #[error("the telerobot's certificate does not match the pinned certificate {pinned}")]
    PinMismatch {
        /// The pinned certificate's file.
        pinned: String,
    },
    /// The telerobot refused the session (busy, version mismatch, …) or its answer was wrong.
    #[error(transparent)]
    Handshake(#[from] HandshakeError),
    /// The TLS/QUIC configuration could not be built.
    #[error(transparent)]
    Endpoint(#[from] EndpointError),
    /// The local UDP socket could not be opened.
    #[error("cannot open a UDP socket: {0}")]
    Bind(std::io::Error),
}

/// Connects, runs sessions and reconnects until `shutdown` completes (then says `Bye` and
/// closes) or the telerobot refuses us for good (the error says why).
pub async fn connect_and_run(
    config: NetConfig,
    io: NetIo,
    shutdown: impl Future<Output = ()>,
) -> Result<(), NetError> {
    let pin = TelerobotPin::new(config.telerobot_cert.clone(), &config.telerobot_cert_source);
    let client_config = transport::endpoint::client_config(
        &config.identity,
        Arc::clone(&pin),
        &config.tuning,
        config.max_cloud_streams,
    )?;
    let bind: SocketAddr = if config.connect.is_ipv6() {
        (Ipv6Addr::UNSPECIFIED, 0).into()
    } else {
        (Ipv4Addr::UNSPECIFIED, 0).into()
    };
    let mut endpoint = quinn::Endpoint::client(bind).map_err(NetError::Bind)?;
    endpoint.set_default_client_config(client_config);
    let (stop_tx, stop_rx) = watch::channel(false);
    let mut client = session::Client {
        endpoint: endpoint.clone(),
        config: &config,
        io,
        pin,
        stop: stop_rx,
        warned_no_answer: false,
    };
    tokio::pin!(shutdown);
    let mut wait = config.reconnect_initial;
    let result = loop {
        let attempt = client.run();
        tokio::pin!(attempt);
        let ended = tokio::select! {
            ended = &mut attempt => ended,
            () = &mut shutdown => {
                let _ = stop_tx.send(true);
                attempt.await
            }
        };
        match ended {
            session::Ended::Stopped => break Ok(()),
            session::Ended::Fatal(e) => {
                tracing::error!("giving up: {e}");
                break Err(e);
            }
            session::Ended::Lost { had_session } => {
                if had_session {
                    wait = config.reconnect_initial;
                }
                tracing::info!(retry_in = ?wait, "reconnecting");
                tokio::select! {
                    () = tokio::time::sleep(wait) => {}
                    () = &mut shutdown => break Ok(()),
                }
                wait = (wait * 2).min(config.reconnect_max);
            }
        }
    };
    endpoint.close(CloseCode::Shutdown.code(), b"operator stopping");
    let _ = tokio::time::timeout(Duration::from_secs(1), endpoint.wait_idle()).await;
    result
}
