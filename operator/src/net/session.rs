//! One connection attempt and, if it is accepted, the session pump.

use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use protocol::clock::ClockOffsetEstimator;
use protocol::handshake::{HandshakeError, accept_welcome};
use protocol::operator_to_telerobot::{self as o2t, Hello};
use protocol::telerobot_to_operator::{self as t2o, Admission, CloudFrame, Refusal};
use quinn::{Connection, ConnectionError, ReadError, SendStream, WriteError};
use rt::monotonic_ns;
use tokio::sync::{mpsc, watch};
use tokio::task::JoinSet;
use tokio::time::MissedTickBehavior;
use transport::endpoint::{CertificateFailure, certificate_failure, describe_close};
use transport::framing::{self, FrameError};
use transport::{CloseCode, DatagramLink, Received, SERVER_NAME, TelerobotPin};

use super::link::Shared;
use super::{NetConfig, NetError, NetIo};

/// How a connection attempt ended.
pub(super) enum Ended {
    /// We were told to stop (and said `Bye` if a session was open).
    Stopped,
    /// The telerobot could not be reached, or the session was lost: try again.
    Lost {
        /// Whether a session had been opened (resets the backoff).
        had_session: bool,
    },
    /// A refusal that retrying will not fix.
    Fatal(NetError),
}

/// What [`super::connect_and_run`] keeps across attempts.
pub(super) struct Client<'a> {
    pub(super) endpoint: quinn::Endpoint,
    pub(super) config: &'a NetConfig,
    pub(super) io: NetIo,
    pub(super) pin: Arc<TelerobotPin>,
    pub(super) stop: watch::Receiver<bool>,
    /// "No answer" was said at warn level (once; later attempts at info).
    pub(super) warned_no_answer: bool,
}

/// Why the handshake did not open a session.
enum Failure {
    Fatal(NetError),
    Lost(String),
}

impl Client<'_> {
    /// One attempt: connect, handshake, and the session until it ends.
    pub(super) async fn run(&mut self) -> Ended {
        let shared = Arc::clone(&self.io.shared);
        let status = &shared.status;
        status.attempt();
        let mut stop = self.stop.clone();
        let opened = tokio::select! {
            opened = tokio::time::timeout(self.config.handshake_timeout, self.open()) => opened,
            () = stopped(&mut stop) => return Ended::Stopped,
        };
        let (connection, control) = match opened {
            Ok(Ok(opened)) => opened,
            Ok(Err(Failure::Fatal(e))) => {
                status.end(&e.to_string());
                return Ended::Fatal(e);
            }
            Ok(Err(Failure::Lost(reason))) => {
                self.log_lost(&reason);
                status.end(&reason);
                return Ended::Lost { had_session: false };
            }
            Err(_) => {
                let reason = format!(
                    "no answer from {} within {:?}",
                    self.config.connect, self.config.handshake_timeout
                );
                self.log_lost(&reason);
                status.end(&reason);
                return Ended::Lost { had_session: false };
            }
        };
        let (stopped, reason) = self.pump(&connection, control).await;
        status.end(&reason);
        tracing::info!(telerobot = %self.config.connect, %reason, "session ended");
        if stopped {
            Ended::Stopped
        } else {
            Ended::Lost { had_session: true }
        }
    }

    /// An attempt that opened no session: a telerobot that does not answer (or is busy) is said
    /// once at warn level, naming the address; every attempt at info.
    fn log_lost(&mut self, reason: &str) {
        let silent = reason.starts_with("no answer") || reason.contains("timed out");
        if silent && !self.warned_no_answer {
            self.warned_no_answer = true;
            tracing::warn!(telerobot = %self.config.connect, %reason,
                "no answer from {}: retrying until the run ends", self.config.connect);
        } else {
            tracing::info!(telerobot = %self.config.connect, %reason, "could not open a session");
        }
    }

    /// Connects and exchanges `Hello`/`Welcome`.
    async fn open(&self) -> Result<(Connection, SendStream), Failure> {
        let rejections = self.pin.rejections();
        let lost = |e: ConnectionError| self.classify(e, rejections);
        let connecting = self
            .endpoint
            .connect(self.config.connect, SERVER_NAME)
            .map_err(|e| Failure::Lost(format!("cannot connect: {e}")))?;
        let connection = connecting.await.map_err(lost)?;
        let (mut send, mut recv) = connection.open_bi().await.map_err(lost)?;
        let hello = o2t::Message::Hello(Hello {
            version: protocol::PROTOCOL_VERSION,
            operator_name: self.config.operator_name.clone(),
            want_clouds: self.config.want_clouds,
        });
        framing::write_frame(&mut send, &o2t::encode(&hello))
            .await
            .map_err(|e| self.frame_failure(e, rejections))?;
        let mut frame = Vec::new();
        framing::read_frame(&mut recv, &mut frame)
            .await
            .map_err(|e| self.frame_failure(e, rejections))?;
        match accept_welcome(&frame) {
            Ok(welcome) => {
                let session = self.io.shared.status.begin(welcome.clone(), monotonic_ns());
                tracing::info!(telerobot = %self.config.connect, session,
                    scene = %welcome.scene.name, "session open");
                Ok((connection, send))
            }
            Err(e) => {
                connection.close(CloseCode::Refused.code(), e.to_string().as_bytes());
                if let HandshakeError::Refused(refusal) = &e {
                    tracing::warn!(telerobot = %self.config.connect, "refused: {refusal}");
                    if self.config.wait_when_busy && matches!(refusal, Refusal::Busy { .. }) {
                        return Err(Failure::Lost(format!("{refusal}; waiting for the slot")));
                    }
                }
                Err(Failure::Fatal(e.into()))
            }
        }
    }

    /// Certificate refusals are fatal; anything else is a lost attempt.
    fn classify(&self, error: ConnectionError, rejections_before: u64) -> Failure {
        match certificate_failure(&error) {
            Some(CertificateFailure::RefusedByPeer) => Failure::Fatal(NetError::NotTrusted),
            Some(CertificateFailure::RefusedByUs) if self.pin.rejections() > rejections_before => {
                Failure::Fatal(NetError::PinMismatch {
                    pinned: self.pin.source().to_owned(),
                })
            }
            _ => Failure::Lost(describe_close(&error)),
        }
    }

    fn frame_failure(&self, error: FrameError, rejections_before: u64) -> Failure {
        match error {
            FrameError::Read(ReadError::ConnectionLost(e))
            | FrameError::Write(WriteError::ConnectionLost(e)) => {
                self.classify(e, rejections_before)
            }
            other => Failure::Lost(format!("control stream: {other}")),
        }
    }

    /// The session; returns whether it ended because we were told to stop, and why it ended.
    async fn pump(&mut self, connection: &Connection, mut control: SendStream) -> (bool, String) {
        let shared = Arc::clone(&self.io.shared);
        let session = shared.status.session();
        shared.outbox.mailbox().clear();
        let mut state = Incoming {
            link: DatagramLink::new(Arc::clone(&shared.stats)),
            clock: ClockOffsetEstimator::new(),
            admission: Admission::default(),
            newest_cloud: None,
            shared: Arc::clone(&shared),
            session,
        };
        let mut ping = tokio::time::interval(self.config.ping_interval);
        ping.set_missed_tick_behavior(MissedTickBehavior::Delay);
        let (cloud_tx, mut cloud_rx) = mpsc::channel(4);
        let mut cloud_readers = JoinSet::new();
        let mut stop = self.stop.clone();
        loop {
            tokio::select! {
                () = stopped(&mut stop) => {
                    say_bye(connection, &mut control).await;
                    return (true, "operator stopping (said Bye)".to_owned());
                }
                datagram = connection.read_datagram() => match datagram {
                    Ok(bytes) => state.on_datagram(&bytes),
                    Err(e) => return (false, describe_close(&e)),
                },
                rung = self.io.bell.wait() => {
                    if let Err(e) = rung {
                        return (false, format!("outbox doorbell failed: {e}"));
                    }
                    while let Some(mut command) = shared.outbox.mailbox().take() {
                        state.link.stamp(&mut command.header, monotonic_ns());
                        let message = o2t::Message::Command(command);
                        state.link.send(connection, |buf| o2t::encode_into(&message, buf));
                    }
                },
                _ = ping.tick() => {
                    let message = o2t::Message::Ping(state.clock.ping(monotonic_ns()));
                    state.link.send(connection, |buf| o2t::encode_into(&message, buf));
                    state.link.publish_rtt_median();
                },
                stream = connection.accept_uni() => match stream {
                    Ok(mut recv) => {
                        let tx = cloud_tx.clone();
                        cloud_readers.spawn(async move {
                            let Ok(bytes) = framing::read_cloud(&mut recv).await else { return };
                            let _ = tx.send(bytes).await;
                        });
                    }
                    Err(e) => return (false, describe_close(&e)),
                },
                Some(bytes) = cloud_rx.recv() => state.on_cloud(&bytes),
                Some(_) = cloud_readers.join_next(), if !cloud_readers.is_empty() => {}
            }
        }
    }
}

/// Completes once the client is told to stop (or the sender is gone).
async fn stopped(stop: &mut watch::Receiver<bool>) {
    let _ = stop.wait_for(|s| *s).await;
}

/// Sends `Bye` and gives the telerobot a moment to close the connection in answer (it does at
/// once; the wait bounds a lost Bye).
async fn say_bye(connection: &Connection, control: &mut SendStream) {
    let bye = o2t::encode(&o2t::Message::Bye);
    if framing::write_frame(control, &bye).await.is_ok() {
        let _ = control.finish();
        let _ = tokio::time::timeout(Duration::from_secs(1), connection.closed()).await;
    }
    connection.close(CloseCode::Normal.code(), b"operator stopping");
}

/// The receive side of one session.
struct Incoming {
    link: DatagramLink,
    clock: ClockOffsetEstimator,
    /// Which datagrams to use (the harness applies the same rule).
    admission: Admission,
    newest_cloud: Option<u64>,
    shared: Arc<Shared>,
    session: u64,
}

impl Incoming {
    fn on_datagram(&mut self, bytes: &Bytes) {
        let now = monotonic_ns();
        let shared = Arc::clone(&self.shared);
        match t2o::decode(bytes) {
            Ok(t2o::Message::Pong(pong)) => {
                if self.clock.on_pong(&pong, now).is_some() {
                    let best = self.clock.best();
                    shared
                        .stats
                        .set_clock(best.map(|b| b.offset_ns), best.map(|b| b.delay_ns));
                }
            }
            Ok(
                message @ (t2o::Message::Parameters(_)
                | t2o::Message::Contact(_)
                | t2o::Message::StateSync(_)
                | t2o::Message::Measurement(_)),
            ) => {
                // Headers are on every datagram kind matched here.
                let header = message.header().copied().unwrap_or_default();
                let arrival = self.link.on_header(&header, now);
                if !self.admission.admit(&message, arrival) {
                    return;
                }
                // Latest-value slots, except measurements: queued for the report.
                match message {
                    t2o::Message::Parameters(m) => {
                        shared.parameters.push(self.received(m, now));
                    }
                    t2o::Message::Contact(m) => {
                        shared.contact.push(self.received(m, now));
                    }
                    t2o::Message::StateSync(m) => {
                        shared.state_sync.push(self.received(m, now));
                    }
                    t2o::Message::Measurement(m) => {
                        shared.measurements.push(self.received(m, now));
                    }
                    _ => {}
                }
            }
            Ok(t2o::Message::Welcome(_) | t2o::Message::Refused(_) | t2o::Message::Cloud(_))
            | Err(_) => shared.stats.count_garbage(),
        }
    }

    fn received<T>(&self, message: T, received_ns: i64) -> Received<T> {
        Received {
            message,
            received_ns,
            session: self.session,
        }
    }

    /// A whole cloud stream: published if it is a cloud newer than the one we have.
    fn on_cloud(&mut self, bytes: &[u8]) {
        match t2o::decode(bytes) {
            Ok(t2o::Message::Cloud(frame)) => {
                if self.newest_cloud.is_none_or(|id| frame.frame_id > id) {
                    self.newest_cloud = Some(frame.frame_id);
                    let frame: Box<CloudFrame> = Box::new(frame);
                    self.shared.cloud.push(self.received(frame, monotonic_ns()));
                }
            }
            Ok(_) | Err(_) => self.shared.stats.count_garbage(),
        }
    }
}
