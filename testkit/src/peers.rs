//! Hand-made peers: a pinned QUIC connection and its control stream without the daemon around
//! it, so a test can send what a correct peer never would (another version, garbage datagrams,
//! a crash without `Bye`).

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use protocol::Header;
use protocol::operator_to_telerobot::{self as o2t, Command, Hello};
use protocol::telerobot_to_operator::{self as t2o, Welcome};
use rt::monotonic_ns;
use transport::{Identity, LinkTuning, OperatorPins, SERVER_NAME, TelerobotPin, framing};

/// A hand-made operator: a pinned QUIC connection and its control stream, no haptic loop.
pub struct RawOperator {
    /// The connection.
    pub conn: quinn::Connection,
    /// The control stream, to write (a `Bye`, garbage).
    pub send: quinn::SendStream,
    recv: quinn::RecvStream,
    _endpoint: quinn::Endpoint,
}

impl RawOperator {
    /// Connects to `addr`, presenting `me` and pinning `telerobot`, and opens the control
    /// stream; the error is quinn's (a refused certificate, a closed connection).
    pub async fn try_connect(
        addr: SocketAddr,
        me: &Identity,
        telerobot: &Identity,
    ) -> Result<RawOperator, quinn::ConnectionError> {
        let pin = TelerobotPin::new(telerobot.cert.clone(), "telerobot.crt");
        let config =
            transport::endpoint::client_config(me, pin, &LinkTuning::default(), 4).unwrap();
        let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).unwrap();
        endpoint.set_default_client_config(config);
        let conn = endpoint.connect(addr, SERVER_NAME).unwrap().await?;
        let (send, recv) = conn.open_bi().await?;
        Ok(RawOperator {
            conn,
            send,
            recv,
            _endpoint: endpoint,
        })
    }

    /// [`RawOperator::try_connect`], which must succeed.
    pub async fn connect(addr: SocketAddr, me: &Identity, telerobot: &Identity) -> RawOperator {
        Self::try_connect(addr, me, telerobot).await.unwrap()
    }

    /// Sends a `Hello` speaking `version`; returns the telerobot's answer.
    pub async fn hello(&mut self, name: &str, version: u16) -> t2o::Message {
        self.hello_wanting_clouds(name, version, false).await
    }

    /// [`RawOperator::hello`], asking for the cloud frames if `want_clouds` (which this peer
    /// never reads: its stream limit fills, as a lossy link's does).
    pub async fn hello_wanting_clouds(
        &mut self,
        name: &str,
        version: u16,
        want_clouds: bool,
    ) -> t2o::Message {
        let hello = o2t::Message::Hello(Hello {
            version,
            operator_name: name.into(),
            want_clouds,
        });
        framing::write_frame(&mut self.send, &o2t::encode(&hello))
            .await
            .unwrap();
        let mut frame = Vec::new();
        framing::read_frame(&mut self.recv, &mut frame)
            .await
            .unwrap();
        t2o::decode(&frame).unwrap()
    }

    /// Sends `message` as a datagram.
    pub fn datagram(&self, message: &o2t::Message) {
        self.conn
            .send_datagram(o2t::encode(message).into())
            .unwrap();
    }

    /// Sends a command numbered `seq` to position `x` along the first axis, sampled now.
    pub fn command(&self, seq: u64, x: f64) {
        self.datagram(&o2t::Message::Command(Command {
            header: Header {
                seq,
                sample_time_ns: monotonic_ns(),
                send_time_ns: monotonic_ns(),
                ..Header::default()
            },
            position_m: [x, 0.0, 0.0],
            velocity_m_per_s: [0.0; 3],
        }));
    }

    /// Waits for the next datagram that decodes.
    pub async fn next_datagram(&self) -> t2o::Message {
        loop {
            let bytes = self.conn.read_datagram().await.unwrap();
            if let Ok(m) = t2o::decode(&bytes) {
                return m;
            }
        }
    }
}

/// A hand-made telerobot: accepts one operator, answers its `Hello` with `welcome`, then sends
/// `datagrams` and keeps the connection open until dropped.
pub struct RawTelerobot {
    /// Where it listens.
    pub addr: SocketAddr,
    /// The connection, once accepted.
    pub conn: Arc<Mutex<Option<quinn::Connection>>>,
    _task: tokio::task::JoinHandle<()>,
    _endpoint: quinn::Endpoint,
}

impl RawTelerobot {
    /// Starts it on `runtime`.
    pub fn start(
        runtime: &tokio::runtime::Runtime,
        me: &Identity,
        operator: &Identity,
        welcome: Welcome,
        datagrams: Vec<Vec<u8>>,
    ) -> RawTelerobot {
        let _entered = runtime.enter();
        let pins = OperatorPins::new(vec![operator.cert.clone()]);
        let config = transport::endpoint::server_config(me, pins, &crate::tuning(1.0)).unwrap();
        let endpoint = quinn::Endpoint::server(config, "127.0.0.1:0".parse().unwrap()).unwrap();
        let addr = endpoint.local_addr().unwrap();
        let conn = Arc::new(Mutex::new(None));
        let task = {
            let (endpoint, conn) = (endpoint.clone(), Arc::clone(&conn));
            runtime.spawn(async move {
                let Some(incoming) = endpoint.accept().await else {
                    return;
                };
                let Ok(c) = incoming.await else { return };
                let Ok((mut send, mut recv)) = c.accept_bi().await else {
                    return;
                };
                let mut hello = Vec::new();
                if framing::read_frame(&mut recv, &mut hello).await.is_err() {
                    return;
                }
                let answer = t2o::encode(&t2o::Message::Welcome(welcome));
                if framing::write_frame(&mut send, &answer).await.is_err() {
                    return;
                }
                for d in datagrams {
                    let _ = c.send_datagram(d.into());
                }
                *conn.lock().unwrap() = Some(c.clone());
                let _ = c.closed().await;
            })
        };
        RawTelerobot {
            addr,
            conn,
            _task: task,
            _endpoint: endpoint,
        }
    }
}

/// A one-worker tokio runtime for the hand-made peers.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap()
}
