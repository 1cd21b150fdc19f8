//! Shared helpers for the end-to-end tests in `tests/tests/`: the real daemons started through
//! the functions the binaries run — [`telerobot::Telerobot::start`] (what `telerobot run` runs
//! until Ctrl-C) and [`operator::app::run`] (what `operator run` runs) — the netem shim between
//! them, and hand-made peers for what a correct daemon never sends (another version, garbage).
//!
//! The tests run real-time loops that spin: they must not overlap. Each holds [`serial`] for its
//! whole run.

#![allow(clippy::unwrap_used, clippy::missing_panics_doc)]

use std::net::{SocketAddr, UdpSocket};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use netem::{LinkConfig, ShimConfig, ShimHandle};
use operator::app::{self, Known, Outcome, RunConfig, RunError};
use operator::device::{DeviceSpec, OpenOptions};
use operator::net::NetConfig;
use operator::safety::SafetyConfig;
use protocol::operator_to_telerobot::{self as o2t, Hello};
use protocol::telerobot_to_operator::{self as t2o, Welcome};
use rt::{PeriodicConfig, Shutdown};
use sim::scene::Scene;
use telerobot::Telerobot;
use transport::{Identity, LinkTuning, OperatorPins, SERVER_NAME, TelerobotPin, framing};

/// Held by each test for its whole run (poison-tolerant: one failed test does not fail the rest).
pub fn serial() -> MutexGuard<'static, ()> {
    static SERIAL: Mutex<()> = Mutex::new(());
    SERIAL.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Spin window of both loops and the shim in the tests [ns]: short, the machine has 2 cores.
pub const SPIN_NS: i64 = 50_000;

/// Certificates of both sides (in memory; the CLI tests cover the files).
pub struct Certs {
    /// The telerobot's.
    pub telerobot: Identity,
    /// The operator's.
    pub operator: Identity,
}

impl Certs {
    /// Fresh certificates.
    pub fn new() -> Certs {
        Certs {
            telerobot: Identity::generate(&["telerobot"]).unwrap(),
            operator: Identity::generate(&["operator"]).unwrap(),
        }
    }
}

impl Default for Certs {
    fn default() -> Self {
        Certs::new()
    }
}

/// The tuning both sides use: the defaults with the delay hint.
pub fn tuning(delay_ms: f64) -> LinkTuning {
    LinkTuning::with_expected_delay_ms(delay_ms.max(1.0)).unwrap()
}

/// The telerobot daemon on the built-in exp-1 scene on a free loopback port, trusting `trusted`.
pub fn telerobot(identity: &Identity, trusted: &[&Identity], delay_ms: f64) -> Telerobot {
    Telerobot::start(telerobot_config(
        identity,
        trusted,
        delay_ms,
        "127.0.0.1:0".parse().unwrap(),
    ))
    .unwrap()
}

/// The telerobot daemon on `listen`, or `None` while the port is still taken.
pub fn telerobot_on(
    identity: &Identity,
    trusted: &[&Identity],
    listen: SocketAddr,
) -> Option<Telerobot> {
    match Telerobot::start(telerobot_config(identity, trusted, 0.0, listen)) {
        Ok(t) => Some(t),
        Err(telerobot::DaemonError::Net(telerobot::net::NetError::Bind { .. })) => None,
        Err(e) => panic!("{e}"),
    }
}

fn telerobot_config(
    identity: &Identity,
    trusted: &[&Identity],
    delay_ms: f64,
    listen: SocketAddr,
) -> telerobot::RunConfig {
    let scene = Scene::exp1();
    telerobot::RunConfig {
        listen,
        identity: identity.clone(),
        trusted_operators: trusted
            .iter()
            .map(|i| ("test.crt".into(), i.cert.clone()))
            .collect(),
        tuning: tuning(delay_ms),
        start_m: telerobot::RunConfig::default_start(&scene),
        limits: scene.command_limits(),
        robot: telerobot::robot::RobotConfig::Sim,
        scene,
        seed: 1,
        periodic: PeriodicConfig {
            spin_ns: SPIN_NS,
            ..PeriodicConfig::default()
        },
        realtime_priority: None,
    }
}

/// The netem shim in front of `forward`, `delay_ms` each way.
pub fn shim(forward: SocketAddr, delay_ms: f64) -> ShimHandle {
    let mut config = ShimConfig::new("127.0.0.1:0".parse().unwrap(), forward);
    let delay = LinkConfig::delay((delay_ms * 1e6).round() as u64);
    config.up = delay.clone();
    config.down = delay;
    config.spin_window_ns = SPIN_NS as u64;
    netem::shim::start(config).unwrap()
}

/// `operator run` with the scripted exp-1 device for `seconds`, to `addr`, presenting `me` and
/// pinning `pinned`. `known_delay_ms`: the set delay, for the report.
pub fn operator_config(
    addr: SocketAddr,
    me: &Identity,
    pinned: &Identity,
    name: &str,
    seconds: f64,
    known_delay_ms: f64,
) -> RunConfig {
    let mut net = NetConfig::new(addr, me.clone(), pinned.cert.clone(), "pinned.crt", name);
    net.tuning = tuning(known_delay_ms);
    RunConfig {
        net,
        device: DeviceSpec::Scripted {
            name: "exp1".into(),
        },
        open: OpenOptions {
            scripted_length_s: Some(seconds),
            ..OpenOptions::default()
        },
        safety: SafetyConfig::default(),
        seconds: Some(seconds),
        periodic: PeriodicConfig {
            spin_ns: SPIN_NS,
            ..PeriodicConfig::default()
        },
        realtime_priority: None,
        first_session_timeout: Some(Duration::from_secs(15)),
        node: node::operator::OperatorConfig::default(),
        experiment: "e2e".into(),
        known: Some(Known {
            scene: Scene::exp1(),
            seed: 1,
            delay_ms: known_delay_ms,
        }),
    }
}

/// The telerobot behind a shim of `delay_ms` each way, and the configuration of an operator
/// ("alice", scripted exp-1 for `seconds`) connecting through the shim.
pub fn through_shim(
    certs: &Certs,
    delay_ms: f64,
    seconds: f64,
) -> (Telerobot, ShimHandle, RunConfig) {
    let tr = telerobot(&certs.telerobot, &[&certs.operator], delay_ms);
    let shim = shim(tr.local_addr(), delay_ms);
    let config = operator_config(
        shim.local_addr(),
        &certs.operator,
        &certs.telerobot,
        "alice",
        seconds,
        delay_ms,
    );
    (tr, shim, config)
}

/// Runs the operator app on its own thread.
pub fn spawn_operator(config: RunConfig) -> JoinHandle<Result<Outcome, RunError>> {
    std::thread::spawn(move || app::run(config, Shutdown::new()))
}

/// Polls `f` every 5 ms until it gives a value or `timeout` passes.
pub fn wait_for<T>(timeout: Duration, mut f: impl FnMut() -> Option<T>) -> Option<T> {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return Some(v);
        }
        if start.elapsed() > timeout {
            return None;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// Waits (up to 15 s) until an operator is in control of `tr`.
pub fn wait_connected(tr: &Telerobot) {
    let connected = wait_for(Duration::from_secs(15), || {
        tr.link().status().connected().then_some(())
    });
    assert!(connected.is_some(), "no operator in control within 15 s");
}

/// Sends raw UDP junk (not QUIC) to `addr`.
pub fn udp_junk(addr: SocketAddr, count: usize) {
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    for i in 0..count {
        let junk = [0xde, 0xad, 0xbe, 0xef, i as u8, 0, 0, 0, 0x55];
        let _ = socket.send_to(&junk[..1 + i % junk.len()], addr);
    }
}

/// A single-threaded tokio runtime for the hand-made peers.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap()
}

/// A hand-made operator: a pinned QUIC connection and its control stream, no haptic loop.
pub struct RawOperator {
    /// The connection.
    pub conn: quinn::Connection,
    send: quinn::SendStream,
    recv: quinn::RecvStream,
    _endpoint: quinn::Endpoint,
}

impl RawOperator {
    /// Connects to `addr`, presenting `me` and pinning `telerobot`.
    pub async fn connect(addr: SocketAddr, me: &Identity, telerobot: &Identity) -> RawOperator {
        let pin = TelerobotPin::new(telerobot.cert.clone(), "telerobot.crt");
        let config = transport::endpoint::client_config(me, pin, &tuning(1.0), 4).unwrap();
        let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).unwrap();
        endpoint.set_default_client_config(config);
        let conn = endpoint.connect(addr, SERVER_NAME).unwrap().await.unwrap();
        let (send, recv) = conn.open_bi().await.unwrap();
        RawOperator {
            conn,
            send,
            recv,
            _endpoint: endpoint,
        }
    }

    /// Sends a `Hello` speaking `version`; returns the telerobot's answer.
    pub async fn hello(&mut self, name: &str, version: u16) -> t2o::Message {
        let hello = o2t::Message::Hello(Hello {
            version,
            operator_name: name.into(),
            want_clouds: false,
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
        let config = transport::endpoint::server_config(me, pins, &tuning(1.0)).unwrap();
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
