//! The two daemons' network tasks in one process, for the operator's tests and the latency
//! example: a telerobot server, an operator client, a stand-in telerobot loop that answers
//! every command with a `Contact`, and a 1 kHz command source.

#![allow(clippy::unwrap_used, dead_code)]

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use operator::net::{self as op_net, NetError, OperatorLink};
use protocol::Header;
use protocol::operator_to_telerobot::Command;
use protocol::telerobot_to_operator::Datagram;
use protocol::telerobot_to_operator::{Contact, ContactState, ModelStructure, SceneSummary};
use rt::monotonic_ns;
use telerobot::net::{self as tr_net, TelerobotLink};
use tokio::sync::oneshot;
use transport::Identity;

pub const MS: i64 = 1_000_000;

pub fn scene() -> SceneSummary {
    SceneSummary {
        name: "wall".into(),
        normal: ModelStructure::KelvinVoigt,
        tangential: ModelStructure::Free,
        control_rate_hz: 1000.0,
        cloud_rate_hz: None,
        left_out: vec![],
        proxy_radii_m: [0.004, 0.006, 0.03],
    }
}

/// Certificates of both sides.
pub struct Certs {
    pub telerobot: Identity,
    pub operator: Identity,
}

impl Certs {
    pub fn new() -> Certs {
        Certs {
            telerobot: Identity::generate(&["telerobot"]).unwrap(),
            operator: Identity::generate(&["operator"]).unwrap(),
        }
    }
}

/// A running telerobot server; stopped by [`Telerobot::stop`] or on drop.
pub struct Telerobot {
    pub addr: SocketAddr,
    pub link: TelerobotLink,
    stop: Option<oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<()>,
}

pub fn start_telerobot(certs: &Certs, listen: SocketAddr, trusted: &[&Identity]) -> Telerobot {
    try_start_telerobot(certs, listen, trusted).unwrap()
}

/// Starts a telerobot on `listen` again, retrying for up to 5 s while the previous server's
/// socket is still being released (quinn's endpoint driver lets go of it asynchronously).
pub async fn restart_telerobot(
    certs: &Certs,
    listen: SocketAddr,
    trusted: &[&Identity],
) -> Telerobot {
    for _ in 0..100 {
        match try_start_telerobot(certs, listen, trusted) {
            Ok(t) => return t,
            Err(tr_net::NetError::Bind { .. }) => {
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
            Err(e) => panic!("{e}"),
        }
    }
    panic!("{listen} still in use after 5 s")
}

fn try_start_telerobot(
    certs: &Certs,
    listen: SocketAddr,
    trusted: &[&Identity],
) -> Result<Telerobot, tr_net::NetError> {
    let mut config = tr_net::NetConfig::new(
        listen,
        certs.telerobot.clone(),
        trusted.iter().map(|i| i.cert.clone()).collect(),
        scene(),
    );
    config.tuning = tuning();
    let (link, io) = tr_net::link(tr_net::DEFAULT_OUTBOX_CAPACITY).unwrap();
    let server = tr_net::bind(config)?;
    let addr = server.local_addr().unwrap();
    let (stop, stopped) = oneshot::channel::<()>();
    let task = tokio::spawn(server.serve(io, async {
        let _ = stopped.await;
    }));
    Ok(Telerobot {
        addr,
        link,
        stop: Some(stop),
        task,
    })
}

impl Telerobot {
    /// Shuts the server down (connections closed) and waits for it.
    pub async fn stop(mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        let _ = (&mut self.task).await;
    }
}

/// The tuning both sides use in the tests: the defaults with the 400 ms delay hint.
pub fn tuning() -> transport::LinkTuning {
    transport::LinkTuning::with_expected_delay_ms(400.0).unwrap()
}

/// A running operator client.
pub struct Operator {
    pub link: OperatorLink,
    stop: Option<oneshot::Sender<()>>,
    pub task: tokio::task::JoinHandle<Result<(), NetError>>,
}

pub fn start_operator(addr: SocketAddr, me: &Identity, pinned: &Identity, name: &str) -> Operator {
    let mut config = op_net::NetConfig::new(
        addr,
        me.clone(),
        pinned.cert.clone(),
        "certs/telerobot.crt",
        name,
    );
    config.tuning = tuning();
    config.reconnect_max = Duration::from_millis(500);
    let (link, io) = op_net::link(
        op_net::DEFAULT_OUTBOX_CAPACITY,
        op_net::DEFAULT_MEASUREMENT_CAPACITY,
    )
    .unwrap();
    let (stop, stopped) = oneshot::channel::<()>();
    let task = tokio::spawn(op_net::connect_and_run(config, io, async {
        let _ = stopped.await;
    }));
    Operator {
        link,
        stop: Some(stop),
        task,
    }
}

impl Operator {
    /// Says Bye, stops, and returns how the client ended.
    pub async fn stop(mut self) -> Result<(), NetError> {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        (&mut self.task).await.unwrap()
    }
}

/// A command sampled now.
pub fn command(x: f64) -> Command {
    Command {
        header: Header {
            sample_time_ns: monotonic_ns(),
            ..Header::default()
        },
        position_m: [x, 0.0, 0.0],
        velocity_m_per_s: [0.0; 3],
    }
}

/// A contact state answering a command sampled at `command_sample_time_ns`.
pub fn contact(command_sample_time_ns: i64) -> Contact {
    Contact {
        header: Header {
            sample_time_ns: monotonic_ns(),
            ..Header::default()
        },
        command_sample_time_ns,
        state: ContactState::Free,
        proxy_position_m: [0.0; 3],
        normal: None,
        frame: None,
        surface_point_m: None,
        penetration_m: None,
    }
}

/// A thread standing in for a real-time loop, polling every 100 µs until dropped.
pub struct Poller {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Poller {
    pub fn start(mut tick: impl FnMut() + Send + 'static) -> Poller {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            while !flag.load(Ordering::Relaxed) {
                tick();
                std::thread::sleep(Duration::from_micros(100));
            }
        });
        Poller {
            stop,
            thread: Some(thread),
        }
    }
}

impl Drop for Poller {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The stand-in telerobot loop: answers every command with a `Contact` and records each
/// command's extra delay (`received − sample − nominal`) [ns].
pub fn echo_loop(
    link: TelerobotLink,
    nominal_ns: i64,
    delays: Arc<std::sync::Mutex<Vec<i64>>>,
) -> Poller {
    Poller::start(move || {
        if let Some(c) = link.next_command() {
            let sample = c.message.header.sample_time_ns;
            delays
                .lock()
                .unwrap()
                .push(c.received_ns - sample - nominal_ns);
            link.send(Datagram::Contact(contact(sample)));
        }
    })
}

/// Sends commands at 1 kHz for `duration` (or until `stop`) from a thread, on absolute
/// deadlines without spinning; returns how many it sent.
pub fn command_source(
    link: OperatorLink,
    duration: Duration,
    stop: Arc<AtomicBool>,
) -> JoinHandle<u64> {
    std::thread::spawn(move || {
        let start = monotonic_ns();
        let count = duration.as_millis() as i64;
        for i in 0..count {
            if stop.load(Ordering::Relaxed) {
                return i as u64;
            }
            let due = start + i * MS;
            let now = monotonic_ns();
            if due > now {
                std::thread::sleep(Duration::from_nanos((due - now) as u64));
            }
            link.send_command(command(i as f64 * 1e-3));
        }
        count as u64
    })
}

/// p-quantile of `values` (sorted in place).
pub fn quantile(values: &mut [i64], p: f64) -> i64 {
    values.sort_unstable();
    let i = ((values.len() as f64 - 1.0) * p).round() as usize;
    values[i.min(values.len() - 1)]
}

/// Polls `f` every 5 ms until it gives a value, or panics after `timeout`.
pub async fn eventually<T>(timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = tokio::time::Instant::now() + timeout;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(
            tokio::time::Instant::now() < deadline,
            "condition not met within {timeout:?}"
        );
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
}
