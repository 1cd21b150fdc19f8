//! The telerobot's QUIC server (`DESIGN.md` §7): who may connect, the handshake, and the pump
//! between one connection and the real-time loop.
//!
//! - Listens on [`NetConfig::listen`]; the TLS handshake admits only operators whose certificate
//!   is in [`NetConfig::trusted_operators`] (exact DER, [`transport::pin`]).
//! - **One controlling operator at a time.** The operator opens the control stream and sends
//!   `Hello`; the answer is `Welcome { scene }`, or `Refused { VersionMismatch }` naming both
//!   versions, or `Refused { Busy { controlling_operator } }` while another is in control. A
//!   refused connection is then closed with [`transport::CloseCode::Refused`] and the reason.
//!   A connection presenting the certificate of the operator in control is that operator again
//!   (its app restarted before the old connection timed out): it takes over, and the old
//!   connection is closed with [`transport::CloseCode::Replaced`]. So does any trusted operator
//!   when nothing (no datagram, no keep-alive) was heard from the one in control for the
//!   silence limit (max(1 s, 2 × keep-alive, 2 × expected RTT)): a killed operator app sends no
//!   CONNECTION_CLOSE, and its slot must not wait for quinn's 5 s idle timeout. The rule is a state machine
//!   (`slot`, no I/O, tested transition by transition); `claim` is its async shell.
//! - In a session: `Command` datagrams (the newest of their direction, or reordered ones, which
//!   the node's playout buffer still orders) go to the loop's command queue stamped with their
//!   receipt time; `Ping`s are answered at once with a `Pong`; everything else is garbage,
//!   counted and ignored. The loop's outbox is drained into datagrams as soon as it rings; cloud
//!   frames go on a stream each.
//! - When the operator leaves (Bye, close, idle timeout) the slot is free again.
//!
//! Logging: one event per connect, refusal and disconnect (with the reason); nothing per
//! datagram. Not here: the real-time loop (it gets a [`TelerobotLink`]), the robot, the scene.

mod claim;
mod link;
mod session;
mod slot;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use protocol::telerobot_to_operator::SceneSummary;
use rustls_pki_types::CertificateDer;
use tokio::task::JoinSet;
use transport::endpoint::{self, CertificateFailure};
use transport::handoff::BellListener;
use transport::{CloseCode, EndpointError, Identity, LinkTuning, OperatorPins};

pub use link::{
    COMMAND_QUEUE_CAPACITY, DEFAULT_OUTBOX_CAPACITY, NetIo, SessionStatus, TelerobotLink, link,
};

/// Everything the server needs.
#[derive(Clone, Debug)]
pub struct NetConfig {
    /// UDP address to listen on (port 0: any free port, see [`Server::local_addr`]).
    pub listen: SocketAddr,
    /// The telerobot's certificate and key.
    pub identity: Identity,
    /// Operator certificates allowed to connect (exact DER match).
    pub trusted_operators: Vec<CertificateDer<'static>>,
    /// Where each trusted certificate came from (a file name), in the same order; may be empty.
    /// With the certificate's fingerprint it names the operator in control to a refused one.
    pub trusted_labels: Vec<String>,
    /// What the operator must render; sent in the `Welcome`.
    pub scene: SceneSummary,
    /// quinn settings ([`LinkTuning::default`] for the rig).
    pub tuning: LinkTuning,
    /// How long a connected operator has to open the control stream and send `Hello`. Default
    /// 10 s: several round trips of the slowest link we test (800 ms).
    pub handshake_timeout: Duration,
    /// How long a refused operator is given to read the `Refused` and close by itself before the
    /// telerobot closes the connection. Default 3 s (> one 800 ms round trip, with margin).
    pub refusal_linger: Duration,
}

impl NetConfig {
    /// A configuration with the defaults above.
    pub fn new(
        listen: SocketAddr,
        identity: Identity,
        trusted_operators: Vec<CertificateDer<'static>>,
        scene: SceneSummary,
    ) -> NetConfig {
        NetConfig {
            listen,
            identity,
            trusted_operators,
            trusted_labels: Vec::new(),
            scene,
            tuning: LinkTuning::default(),
            handshake_timeout: Duration::from_secs(10),
            refusal_linger: Duration::from_secs(3),
        }
    }
}

/// Why the server could not start.
#[derive(Debug, thiserror::Error)]
pub enum NetError {
    /// The TLS/QUIC configuration could not be built.
    #[error(transparent)]
    Endpoint(#[from] EndpointError),
    /// The UDP socket could not be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The operating system's reason.
        source: std::io::Error,
    },
}

/// A bound server, not yet serving.
#[derive(Debug)]
pub struct Server {
    endpoint: quinn::Endpoint,
    pins: Arc<OperatorPins>,
    config: NetConfig,
}

/// Binds the server (inside a tokio runtime).
pub fn bind(config: NetConfig) -> Result<Server, NetError> {
    let pins = OperatorPins::new(config.trusted_operators.clone());
    let server_config =
        endpoint::server_config(&config.identity, Arc::clone(&pins), &config.tuning)?;
    let endpoint =
        quinn::Endpoint::server(server_config, config.listen).map_err(|source| NetError::Bind {
            addr: config.listen,
            source,
        })?;
    Ok(Server {
        endpoint,
        pins,
        config,
    })
}

/// Binds and serves until `shutdown` completes: [`bind`] then [`Server::serve`].
pub async fn serve(
    config: NetConfig,
    io: NetIo,
    shutdown: impl Future<Output = ()>,
) -> Result<(), NetError> {
    bind(config)?.serve(io, shutdown).await;
    Ok(())
}

/// The network side of the loop's two outboxes: in the controlling-operator slot while nobody
/// is in control, the session's while one is.
#[derive(Debug)]
struct Bells {
    datagrams: BellListener,
    clouds: BellListener,
}

/// The slot every connection task claims ([`slot`] is the rule, [`claim`] the waiting).
type Claims = claim::Claims<Bells, quinn::Connection>;

/// What every connection task shares.
struct Context {
    /// Trusted certificates (DER) and where each came from.
    trusted: Vec<(Vec<u8>, String)>,
    shared: Arc<link::Shared>,
    claims: Arc<Claims>,
    scene: SceneSummary,
    handshake_timeout: Duration,
    refusal_linger: Duration,
}

impl Server {
    /// The address the server listens on.
    pub fn local_addr(&self) -> std::io::Result<SocketAddr> {
        self.endpoint.local_addr()
    }

    /// How many operator certificates the TLS handshake refused since start.
    pub fn untrusted_refusals(&self) -> u64 {
        self.pins.rejections()
    }

    /// A handle that reports [`Server::untrusted_refusals`] while the server runs.
    pub fn pins(&self) -> Arc<OperatorPins> {
        Arc::clone(&self.pins)
    }

    /// Accepts operators until `shutdown` completes, then closes every connection
    /// ([`CloseCode::Shutdown`]) and waits (≤ 1 s) for the peers to be told.
    pub async fn serve(self, io: NetIo, shutdown: impl Future<Output = ()>) {
        let trusted = self
            .config
            .trusted_operators
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let label = self.config.trusted_labels.get(i).cloned();
                (c.to_vec(), label.unwrap_or_default())
            })
            .collect();
        let context = Arc::new(Context {
            trusted,
            shared: io.shared,
            claims: Claims::new(
                Bells {
                    datagrams: io.datagram_bell,
                    clouds: io.cloud_bell,
                },
                slot::TAKEOVER_WAIT,
                slot::silence_limit(&self.config.tuning),
            ),
            scene: self.config.scene.clone(),
            handshake_timeout: self.config.handshake_timeout,
            refusal_linger: self.config.refusal_linger,
        });
        tracing::info!(listen = ?self.endpoint.local_addr().ok(), "telerobot listening");
        let mut tasks = JoinSet::new();
        tokio::pin!(shutdown);
        loop {
            tokio::select! {
                () = &mut shutdown => break,
                incoming = self.endpoint.accept() => {
                    let Some(incoming) = incoming else { break };
                    tasks.spawn(connection(incoming, Arc::clone(&context)));
                }
                Some(_) = tasks.join_next(), if !tasks.is_empty() => {}
            }
        }
        self.endpoint
            .close(CloseCode::Shutdown.code(), b"telerobot shutting down");
        let _ = tokio::time::timeout(Duration::from_secs(1), async {
            while tasks.join_next().await.is_some() {}
            self.endpoint.wait_idle().await;
        })
        .await;
        tracing::info!("telerobot stopped listening");
    }
}

/// One incoming connection: TLS handshake (pins), then the control-stream handshake and the
/// session.
async fn connection(incoming: quinn::Incoming, context: Arc<Context>) {
    let remote = incoming.remote_address();
    let connection = match incoming.await {
        Ok(c) => c,
        Err(e) => {
            match endpoint::certificate_failure(&e) {
                Some(CertificateFailure::RefusedByUs) => tracing::warn!(
                    %remote,
                    "refused an operator: its certificate is not in the trusted set"
                ),
                _ => tracing::info!(%remote, reason = %endpoint::describe_close(&e),
                    "connection attempt failed"),
            }
            return;
        }
    };
    session::run(connection, &context).await;
}
