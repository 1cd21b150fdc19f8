//! The live view: a Foxglove WebSocket server (`foxglove.websocket.v1`, which Lichtblick and
//! the Foxglove app speak, and the SDK's name for it, `foxglove.sdk.v1`).
//!
//! On connection a viewer gets `serverInfo` and an `advertise` of every channel known so far
//! (new channels are advertised as they appear); it subscribes to what it shows, and gets each
//! message as a binary `MessageData` frame (opcode 1, subscription id, log time, payload).
//!
//! A slow or vanished viewer never slows the recorder, let alone the loops: [`LiveServer::offer`]
//! only tries to put a message on each subscribed viewer's bounded queue
//! ([`CLIENT_QUEUE`] messages); a full queue drops the message and counts it, per viewer and in
//! total ([`LiveReport`]). A viewer that stops reading altogether (a stalled TCP window) just
//! keeps its queue full. The server runs on its own one-thread tokio runtime (`live-view`).
//!
//! What it is not: no client publishing, services, parameters or assets (the view is read-only),
//! no TLS (it binds loopback unless told otherwise).

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
use std::sync::{Arc, Mutex, PoisonError};

use base64::Engine as _;
use futures_util::{SinkExt as _, StreamExt as _};
use serde::Serialize;
use tokio::net::{TcpListener, TcpSocket, TcpStream};
use tokio::sync::mpsc;
use tokio_tungstenite::tungstenite::handshake::server::{Request, Response};
use tokio_tungstenite::tungstenite::http::{HeaderValue, StatusCode};
use tokio_tungstenite::tungstenite::{Bytes, Message as Ws};

use crate::encode::ChannelSchema;

/// Messages queued per viewer before new ones are dropped: about 2 s of the decimated streams.
pub const CLIENT_QUEUE: usize = 1024;
/// The kernel's send buffer per viewer \[bytes\] (Linux doubles it): a few frames of the scene
/// and cloud, ample for a viewer that keeps up, even over a network.
pub const VIEWER_SEND_BUFFER: u32 = 256 << 10;
/// The subprotocols accepted, in order of preference.
pub const SUBPROTOCOLS: [&str; 2] = ["foxglove.websocket.v1", "foxglove.sdk.v1"];

/// What the live view did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LiveReport {
    /// Viewers that connected.
    pub clients: u64,
    /// Messages queued for viewers.
    pub sent: u64,
    /// Messages dropped because a viewer's queue was full.
    pub dropped: u64,
}

/// Why the live view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The runtime, the socket or the thread.
    #[error("live view on {addr}: {error}")]
    Io {
        /// The address asked for.
        addr: SocketAddr,
        /// The OS error.
        error: std::io::Error,
    },
}

/// A running live view.
pub struct LiveServer {
    shared: Arc<Shared>,
    addr: SocketAddr,
    runtime: Option<tokio::runtime::Runtime>,
}

/// One channel as advertised.
#[derive(Clone, Debug)]
struct Channel {
    id: u32,
    topic: String,
    schema: ChannelSchema,
    /// A latched topic keeps its last message (log time, payload) for viewers who subscribe
    /// after it was sent: the run's start and end, sent once.
    last: Option<(u64, Bytes)>,
    latched: bool,
}

/// The topics whose last message a new subscriber gets at once.
const LATCHED: [&str; 2] = [crate::schema::topic::RUN, crate::schema::topic::RUN_END];

/// A `messageData` frame: opcode 1, the subscription id, the log time, the payload.
fn message_data(sub: u32, log_time_ns: u64, payload: &[u8]) -> Ws {
    let mut bytes = Vec::with_capacity(13 + payload.len());
    bytes.push(1);
    bytes.extend_from_slice(&sub.to_le_bytes());
    bytes.extend_from_slice(&log_time_ns.to_le_bytes());
    bytes.extend_from_slice(payload);
    Ws::Binary(Bytes::from(bytes))
}

/// A connected viewer as the publisher sees it.
struct Client {
    id: u64,
    /// Channel id → the viewer's subscription id.
    subscriptions: HashMap<u32, u32>,
    queue: mpsc::Sender<Ws>,
    dropped: u64,
}

#[derive(Default)]
struct Registry {
    channels: Vec<Channel>,
    clients: Vec<Client>,
    next_client: u64,
}

#[derive(Default)]
struct Shared {
    registry: Mutex<Registry>,
    clients: AtomicU64,
    sent: AtomicU64,
    dropped: AtomicU64,
}

impl Shared {
    fn registry(&self) -> std::sync::MutexGuard<'_, Registry> {
        self.registry.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

impl LiveServer {
    /// Binds `addr` and starts serving.
    pub fn start(addr: SocketAddr) -> Result<LiveServer, LiveError> {
        let io = |error| LiveError::Io { addr, error };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("live-view")
            .enable_all()
            .build()
            .map_err(io)?;
        // Bound here, on the caller's thread, so that starting works inside another runtime too.
        let listener = {
            let _entered = runtime.enter();
            let socket = if addr.is_ipv4() {
                TcpSocket::new_v4()
            } else {
                TcpSocket::new_v6()
            }
            .map_err(io)?;
            socket.set_reuseaddr(true).map_err(io)?;
            // Inherited by every viewer's socket: what a stalled viewer holds in the kernel is
            // bounded, so its own queue fills and drops (counted) within a second or two, and a
            // slow one sees fresh data rather than megabytes of backlog.
            socket
                .set_send_buffer_size(VIEWER_SEND_BUFFER)
                .map_err(io)?;
            socket.bind(addr).map_err(io)?;
            socket.listen(64).map_err(io)?
        };
        let bound = listener.local_addr().map_err(io)?;
        let shared = Arc::new(Shared::default());
        runtime.spawn(accept(listener, Arc::clone(&shared)));
        tracing::info!(addr = %bound, "live view: open ws://{bound} in Foxglove or Lichtblick");
        Ok(LiveServer {
            shared,
            addr: bound,
            runtime: Some(runtime),
        })
    }

    /// The address it listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }

    /// Viewers connected now.
    pub fn viewers(&self) -> usize {
        self.shared.registry().clients.len()
    }

    /// The channel id of `topic`, advertising it to every viewer the first time.
    pub fn channel(&self, topic: &str, schema: &ChannelSchema) -> u32 {
        let mut reg = self.shared.registry();
        if let Some(c) = reg.channels.iter().find(|c| c.topic == topic) {
            return c.id;
        }
        let channel = Channel {
            id: reg.channels.len() as u32 + 1,
            topic: topic.to_owned(),
            schema: schema.clone(),
            last: None,
            latched: LATCHED.contains(&topic),
        };
        let advert = advertise(std::slice::from_ref(&channel));
        for client in &mut reg.clients {
            // A full queue drops the advert: that viewer will not see the channel (counted).
            if client.queue.try_send(advert.clone()).is_err() {
                client.dropped += 1;
                self.shared.dropped.fetch_add(1, Relaxed);
            }
        }
        let id = channel.id;
        reg.channels.push(channel);
        id
    }

    /// Offers one message to every viewer subscribed to `channel`; never waits. A viewer whose
    /// queue is full misses it (counted).
    pub fn offer(&self, channel: u32, log_time_ns: u64, payload: &[u8]) {
        let mut reg = self.shared.registry();
        if let Some(c) = reg
            .channels
            .iter_mut()
            .find(|c| c.id == channel && c.latched)
        {
            c.last = Some((log_time_ns, Bytes::copy_from_slice(payload)));
        }
        for client in &mut reg.clients {
            let Some(&sub) = client.subscriptions.get(&channel) else {
                continue;
            };
            match client
                .queue
                .try_send(message_data(sub, log_time_ns, payload))
            {
                Ok(()) => {
                    self.shared.sent.fetch_add(1, Relaxed);
                }
                Err(_) => {
                    client.dropped += 1;
                    self.shared.dropped.fetch_add(1, Relaxed);
                }
            }
        }
    }

    /// What it did so far.
    pub fn report(&self) -> LiveReport {
        LiveReport {
            clients: self.shared.clients.load(Relaxed),
            sent: self.shared.sent.load(Relaxed),
            dropped: self.shared.dropped.load(Relaxed),
        }
    }

    /// Closes every connection and stops the runtime.
    pub fn stop(mut self) -> LiveReport {
        let report = self.report();
        self.shared.registry().clients.clear();
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_timeout(std::time::Duration::from_millis(200));
        }
        report
    }
}

impl Drop for LiveServer {
    fn drop(&mut self) {
        if let Some(rt) = self.runtime.take() {
            rt.shutdown_background();
        }
    }
}

async fn accept(listener: TcpListener, shared: Arc<Shared>) {
    loop {
        let Ok((stream, peer)) = listener.accept().await else {
            continue;
        };
        let shared = Arc::clone(&shared);
        tokio::spawn(async move {
            if let Err(e) = serve(stream, peer, &shared).await {
                tracing::info!(%peer, "live view: viewer left: {e}");
            }
        });
    }
}

/// One viewer: the handshake, `serverInfo` and the adverts, then its subscriptions in and its
/// queue out, until it leaves.
async fn serve(stream: TcpStream, peer: SocketAddr, shared: &Shared) -> Result<(), String> {
    let _ = stream.set_nodelay(true);
    let ws = tokio_tungstenite::accept_hdr_async(stream, negotiate)
        .await
        .map_err(|e| e.to_string())?;
    let (mut sink, mut stream) = ws.split();
    let (queue, mut outgoing) = mpsc::channel(CLIENT_QUEUE);
    let id = {
        let mut reg = shared.registry();
        let id = reg.next_client;
        reg.next_client += 1;
        let _ = queue.try_send(server_info());
        let _ = queue.try_send(advertise(&reg.channels));
        reg.clients.push(Client {
            id,
            subscriptions: HashMap::new(),
            queue,
            dropped: 0,
        });
        id
    };
    shared.clients.fetch_add(1, Relaxed);
    tracing::info!(%peer, "live view: viewer connected");
    let writer = async {
        while let Some(m) = outgoing.recv().await {
            if sink.send(m).await.is_err() {
                break;
            }
        }
    };
    let reader = async {
        while let Some(Ok(m)) = stream.next().await {
            if let Ws::Text(text) = m {
                on_request(shared, id, text.as_str());
            }
        }
    };
    tokio::select! {
        () = writer => {},
        () = reader => {},
    }
    let mut reg = shared.registry();
    if let Some(c) = reg.clients.iter().find(|c| c.id == id) {
        tracing::info!(%peer, dropped = c.dropped, "live view: viewer disconnected");
    }
    reg.clients.retain(|c| c.id != id);
    Ok(())
}

/// Accepts a viewer that offers one of [`SUBPROTOCOLS`], answering with it.
#[allow(clippy::result_large_err)] // tungstenite's callback type
fn negotiate(
    req: &Request,
    mut res: Response,
) -> Result<Response, tokio_tungstenite::tungstenite::handshake::server::ErrorResponse> {
    let offered: Vec<String> = req
        .headers()
        .get_all("sec-websocket-protocol")
        .iter()
        .filter_map(|h| h.to_str().ok())
        .flat_map(|h| h.split(',').map(|s| s.trim().to_owned()))
        .collect();
    let chosen = SUBPROTOCOLS
        .iter()
        .find(|p| offered.iter().any(|o| o == *p));
    match chosen {
        Some(p) => {
            res.headers_mut()
                .insert("sec-websocket-protocol", HeaderValue::from_static(p));
            Ok(res)
        }
        None => {
            let mut refusal = tokio_tungstenite::tungstenite::handshake::server::ErrorResponse::new(
                Some(format!(
                    "expected the subprotocol {} or {}",
                    SUBPROTOCOLS[0], SUBPROTOCOLS[1]
                )),
            );
            *refusal.status_mut() = StatusCode::BAD_REQUEST;
            Err(refusal)
        }
    }
}

/// A viewer's `subscribe` or `unsubscribe`; anything else is ignored.
fn on_request(shared: &Shared, id: u64, text: &str) {
    let Ok(v) = serde_json::from_str::<serde_json::Value>(text) else {
        return;
    };
    let mut reg = shared.registry();
    let known: Vec<(u32, Option<(u64, Bytes)>)> = reg
        .channels
        .iter()
        .map(|c| (c.id, c.last.clone()))
        .collect();
    let Some(client) = reg.clients.iter_mut().find(|c| c.id == id) else {
        return;
    };
    let number = |v: &serde_json::Value, key: &str| {
        v.get(key)
            .and_then(serde_json::Value::as_u64)
            .and_then(|n| u32::try_from(n).ok())
    };
    match v.get("op").and_then(serde_json::Value::as_str) {
        Some("subscribe") => {
            for s in v["subscriptions"].as_array().into_iter().flatten() {
                if let (Some(sub), Some(channel)) = (number(s, "id"), number(s, "channelId"))
                    && let Some((_, last)) = known.iter().find(|(c, _)| *c == channel)
                {
                    client.subscriptions.insert(channel, sub);
                    // A latched topic's last message, at once (dropped, counted, if full).
                    if let Some((t, payload)) = last
                        && client
                            .queue
                            .try_send(message_data(sub, *t, payload))
                            .is_err()
                    {
                        client.dropped += 1;
                        shared.dropped.fetch_add(1, Relaxed);
                    }
                }
            }
        }
        Some("unsubscribe") => {
            for sub in v["subscriptionIds"].as_array().into_iter().flatten() {
                if let Some(sub) = sub.as_u64() {
                    client.subscriptions.retain(|_, s| u64::from(*s) != sub);
                }
            }
        }
        _ => {}
    }
}

fn server_info() -> Ws {
    let info = serde_json::json!({
        "op": "serverInfo",
        "name": concat!("mmt ", env!("CARGO_PKG_VERSION")),
        "capabilities": [],
        "supportedEncodings": [],
        "metadata": {},
        "sessionId": format!("{}", std::process::id()),
    });
    Ws::Text(info.to_string().into())
}

fn advertise(channels: &[Channel]) -> Ws {
    let channels: Vec<serde_json::Value> = channels
        .iter()
        .map(|c| {
            let schema = match c.schema.schema_encoding {
                "protobuf" => base64::engine::general_purpose::STANDARD.encode(&c.schema.data),
                _ => String::from_utf8_lossy(&c.schema.data).into_owned(),
            };
            serde_json::json!({
                "id": c.id,
                "topic": c.topic,
                "encoding": c.schema.message_encoding,
                "schemaName": c.schema.name,
                "schemaEncoding": c.schema.schema_encoding,
                "schema": schema,
            })
        })
        .collect();
    Ws::Text(
        serde_json::json!({ "op": "advertise", "channels": channels })
            .to_string()
            .into(),
    )
}
