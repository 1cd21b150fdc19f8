//! One operator connection: the control-stream handshake, then the session pump.

use std::sync::Arc;
use std::time::Duration;

use bytes::Bytes;
use protocol::clock::answer_ping;
use protocol::handshake::accept_hello;
use protocol::operator_to_telerobot as o2t;
use protocol::session::Arrival;
use protocol::telerobot_to_operator::{self as t2o, CloudFrame, Refusal, Refused, Welcome};
use quinn::{Connection, RecvStream, SendStream};
use rt::monotonic_ns;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;
use transport::endpoint::describe_close;
use transport::framing::{self, FrameError, STALE_CLOUD_CODE};
use transport::{CloseCode, DatagramLink, Received};

use super::claim::{Control, peer_certificate};
use super::link::{CloudOutcome, Shared};
use super::slot::Contender;
use super::{Bells, Context};

/// How often a session looks whether its operator sent anything (any packet) since last time.
const LIVENESS_SAMPLE: Duration = Duration::from_millis(100);

/// Runs the handshake and, if the operator is accepted, the session until it ends.
pub(super) async fn run(connection: Connection, context: &Context) {
    let remote = connection.remote_address();
    let (mut send, mut recv) =
        match tokio::time::timeout(context.handshake_timeout, opening(&connection)).await {
            Ok(Ok(streams)) => streams,
            Ok(Err(reason)) => {
                tracing::info!(%remote, %reason, "operator left before its Hello");
                return;
            }
            Err(_) => {
                tracing::warn!(%remote, timeout = ?context.handshake_timeout,
                    "operator sent no Hello in time; closing");
                connection.close(CloseCode::ProtocolViolation.code(), b"no Hello in time");
                return;
            }
        };
    let mut frame = Vec::new();
    let hello = match tokio::time::timeout(
        context.handshake_timeout,
        framing::read_frame(&mut recv, &mut frame),
    )
    .await
    {
        Ok(Ok(())) => accept_hello(&frame),
        Ok(Err(e)) => Err(Refusal::Other(format!("could not read the Hello: {e}"))),
        Err(_) => Err(Refusal::Other("no Hello in time".to_owned())),
    };
    let hello = match hello {
        Ok(hello) => hello,
        Err(refusal) => return refuse(&connection, send, refusal, context).await,
    };
    let operator = hello.operator_name;
    let certificate = peer_certificate(&connection);
    let contender = Contender {
        name: identity_of(&operator, certificate.as_deref(), &context.trusted),
        certificate,
        connection: connection.clone(),
    };
    let mut control = match context.claims.claim(contender).await {
        Ok(control) => control,
        Err(refused) => {
            let refusal = match refused.holder() {
                Some(holder) => Refusal::Busy {
                    controlling_operator: holder.to_owned(),
                },
                None => Refusal::Other(refused.to_string()),
            };
            if let Refusal::Busy { .. } = refusal {
                tracing::info!(%remote, %operator, why = %refused, "refusing operator: {refusal}");
            }
            return refuse(&connection, send, refusal, context).await;
        }
    };
    let welcome = t2o::Message::Welcome(Welcome {
        version: protocol::PROTOCOL_VERSION,
        scene: context.scene.clone(),
    });
    if let Err(e) = framing::write_frame(&mut send, &t2o::encode(&welcome)).await {
        tracing::info!(%remote, %operator, "operator left during the handshake: {e}");
        return;
    }
    let status = &context.shared.status;
    let session = status.begin(&operator, monotonic_ns());
    tracing::info!(%remote, %operator, session, want_clouds = hello.want_clouds,
        "operator connected and in control");
    let reason = pump(
        &connection,
        recv,
        &mut control,
        context,
        session,
        hello.want_clouds,
    )
    .await;
    // Ended before the slot is given back, so that a next operator's `begin` is not undone.
    status.end();
    drop(control);
    tracing::info!(%remote, %operator, session, %reason, "operator disconnected");
}

/// Waits for the operator's control stream.
async fn opening(connection: &Connection) -> Result<(SendStream, RecvStream), String> {
    connection.accept_bi().await.map_err(|e| describe_close(&e))
}

/// Sends `Refused`, gives the operator time to read it and close, then closes.
async fn refuse(
    connection: &Connection,
    mut send: SendStream,
    refusal: Refusal,
    context: &Context,
) {
    context
        .shared
        .status
        .count_refusal(matches!(refusal, Refusal::Busy { .. }));
    if !matches!(refusal, Refusal::Busy { .. }) {
        tracing::info!(remote = %connection.remote_address(), "refusing operator: {refusal}");
    }
    let reason = refusal.to_string();
    let message = t2o::Message::Refused(Refused { reason: refusal });
    if framing::write_frame(&mut send, &t2o::encode(&message))
        .await
        .is_ok()
    {
        let _ = send.finish();
        let _ = tokio::time::timeout(context.refusal_linger, connection.closed()).await;
    }
    connection.close(CloseCode::Refused.code(), reason.as_bytes());
}

/// The session: datagrams both ways, clouds out, the control stream watched for `Bye`. Returns
/// why it ended.
async fn pump(
    connection: &Connection,
    recv: RecvStream,
    control: &mut Control<Bells, Connection>,
    context: &Context,
    session: u64,
    want_clouds: bool,
) -> String {
    let shared = &context.shared;
    let Some(liveness) = control.liveness() else {
        return "internal error: the session holds no slot".to_owned();
    };
    let Some(bells) = control.bells() else {
        return "internal error: the session holds no doorbells".to_owned();
    };
    // Every packet from the operator (datagrams, acknowledgements, keep-alives) counts as
    // hearing from it; sampled every 100 ms, so a dead operator is seen within the silence limit
    // plus 100 ms (`slot::silence_limit`).
    let mut listening = tokio::time::interval(LIVENESS_SAMPLE);
    listening.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut packets_in = connection.stats().udp_rx.datagrams;
    // Whatever the loop queued while nobody was connected is stale.
    shared.outbox.mailbox().clear();
    shared.commands.clear();
    let mut link = DatagramLink::new(Arc::clone(&shared.stats));
    let mut clouds = CloudSender::default();
    let mut control_stream = tokio::spawn(watch_control(recv));
    let reason = loop {
        let Bells {
            datagrams,
            clouds: cloud_bell,
        } = &mut *bells;
        tokio::select! {
            datagram = connection.read_datagram() => match datagram {
                Ok(bytes) => on_datagram(&bytes, &mut link, connection, shared, session),
                Err(e) => break describe_close(&e),
            },
            rung = datagrams.wait() => {
                if let Err(e) = rung {
                    break format!("outbox doorbell failed: {e}");
                }
                while let Some(mut datagram) = shared.outbox.mailbox().take() {
                    link.stamp(datagram.header_mut(), monotonic_ns());
                    link.send(connection, |buf| t2o::encode_datagram_into(&datagram, buf));
                }
            },
            rung = cloud_bell.wait() => {
                if let Err(e) = rung {
                    break format!("cloud doorbell failed: {e}");
                }
                if let Some(frame) = shared.clouds.mailbox().take().filter(|_| want_clouds) {
                    clouds.start(connection.clone(), frame, Arc::clone(shared));
                }
            },
            _ = listening.tick() => {
                let now_in = connection.stats().udp_rx.datagrams;
                if now_in != packets_in {
                    packets_in = now_in;
                    liveness.heard();
                }
            },
            ended = &mut control_stream => {
                let (code, reason) = ended.unwrap_or_else(|e| {
                    (CloseCode::ProtocolViolation, format!("control stream task failed: {e}"))
                });
                connection.close(code.code(), reason.as_bytes());
                break reason;
            },
        }
    };
    control_stream.abort();
    clouds.supersede();
    reason
}

/// Handles one datagram from the operator.
fn on_datagram(
    bytes: &Bytes,
    link: &mut DatagramLink,
    connection: &Connection,
    shared: &Shared,
    session: u64,
) {
    let received_ns = monotonic_ns();
    match o2t::decode(bytes) {
        Ok(o2t::Message::Command(command)) => {
            // Reordered commands go on too: the node's playout buffer puts them in order (or
            // drops them if their turn has passed). Duplicates stop here.
            if matches!(
                link.on_header(&command.header, received_ns),
                Arrival::Newer { .. } | Arrival::Late
            ) {
                shared.commands.push(Received {
                    message: command,
                    received_ns,
                    session,
                });
            }
        }
        Ok(o2t::Message::Ping(ping)) => {
            let pong = t2o::Message::Pong(answer_ping(&ping, received_ns, monotonic_ns()));
            link.send(connection, |buf| t2o::encode_into(&pong, buf));
        }
        Ok(o2t::Message::Hello(_) | o2t::Message::Bye) | Err(_) => shared.stats.count_garbage(),
    }
}

/// Reads the control stream after the handshake until `Bye` or its end; returns how to close.
async fn watch_control(mut recv: RecvStream) -> (CloseCode, String) {
    let mut frame = Vec::new();
    match framing::read_frame(&mut recv, &mut frame).await {
        Ok(()) => match o2t::decode(&frame) {
            Ok(o2t::Message::Bye) => (CloseCode::Normal, "operator said Bye".to_owned()),
            Ok(other) => (
                CloseCode::ProtocolViolation,
                format!("unexpected {} on the control stream", other.kind()),
            ),
            Err(e) => (
                CloseCode::ProtocolViolation,
                format!("control stream message not understood: {e}"),
            ),
        },
        Err(FrameError::Finished) => (
            CloseCode::Normal,
            "operator closed the control stream".to_owned(),
        ),
        Err(e) => (CloseCode::ProtocolViolation, format!("control stream: {e}")),
    }
}

/// Sends cloud frames, each on its own stream; starting one resets the one still in flight.
#[derive(Default)]
struct CloudSender {
    in_flight: Option<(oneshot::Sender<()>, JoinHandle<()>)>,
}

impl CloudSender {
    fn start(&mut self, connection: Connection, frame: Box<CloudFrame>, shared: Arc<Shared>) {
        self.supersede();
        let (stale_tx, stale_rx) = oneshot::channel();
        let task = tokio::spawn(async move {
            let outcome = send_cloud(&connection, frame, stale_rx).await;
            shared.status.count_cloud(outcome);
        });
        self.in_flight = Some((stale_tx, task));
    }

    /// Tells the frame in flight (if any) that it is stale.
    fn supersede(&mut self) {
        if let Some((stale, task)) = self.in_flight.take()
            && !task.is_finished()
        {
            let _ = stale.send(());
        }
    }
}

/// Sends one frame on a stream of its own, unless a newer frame makes it stale first: while
/// the stream is being opened (the operator's stream limit is reached: its earlier frames are
/// still arriving, as under loss) as well as while it is written. Waiting for the stream
/// without listening for `stale` kept every frame of a lossy link alive — 30 a second, 1 MB/s
/// of memory in the soak.
async fn send_cloud(
    connection: &Connection,
    frame: Box<CloudFrame>,
    mut stale: oneshot::Receiver<()>,
) -> CloudOutcome {
    let bytes = t2o::encode(&t2o::Message::Cloud(*frame));
    let mut send = tokio::select! {
        opened = connection.open_uni() => match opened {
            Ok(send) => send,
            Err(_) => return CloudOutcome::Failed,
        },
        _ = &mut stale => return CloudOutcome::Superseded,
    };
    tokio::select! {
        written = framing::write_cloud(&mut send, &bytes) => match written {
            Ok(()) => CloudOutcome::Sent,
            Err(_) => CloudOutcome::Failed,
        },
        _ = stale => {
            let _ = send.reset(STALE_CLOUD_CODE);
            CloudOutcome::Superseded
        }
    }
}

/// How an operator is named to others: `'NAME' (certificate FILE, sha256:…)` — the certificate
/// is the identity (the name in the `Hello` is self-chosen, "operator" by default for everyone).
fn identity_of(name: &str, certificate: Option<&[u8]>, trusted: &[(Vec<u8>, String)]) -> String {
    let Some(der) = certificate else {
        return format!("'{name}' (no certificate)");
    };
    let fingerprint = transport::identity::fingerprint(der);
    match trusted.iter().find(|(c, _)| c == der) {
        Some((_, file)) if !file.is_empty() => {
            format!("'{name}' (certificate {file}, {fingerprint})")
        }
        _ => format!("'{name}' (certificate {fingerprint})"),
    }
}
