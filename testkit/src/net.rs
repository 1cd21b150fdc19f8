//! The two daemons' network tasks alone, in one process: a telerobot server, an operator
//! client, a stand-in telerobot loop that answers every command with a `Contact`, and a 1 kHz
//! command source — for the transport's and the clients' tests and the latency example.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::Duration;

use operator::net::{self as op_net, NetError, OperatorLink};
use protocol::Header;
use protocol::operator_to_telerobot::Command;
use protocol::telerobot_to_operator::{Contact, ContactState, Datagram};
use rt::monotonic_ns;
use telerobot::net::{self as tr_net, TelerobotLink};
use tokio::sync::oneshot;
use transport::{Identity, OperatorPins};

use crate::{MS, tuning, wall_summary};

/// How long a refused operator is given to read its `Refused` in the tests (the daemon's default
/// is 3 s).
pub const REFUSAL_LINGER: Duration = Duration::from_millis(500);

/// A running telerobot server (network task only), welcoming with [`wall_summary`]; stopped by
/// [`TelerobotServer::stop`] or on drop.
pub struct TelerobotServer {
    /// Where it listens.
    pub addr: SocketAddr,
    /// The loop's side of the hand-off.
    pub link: TelerobotLink,
    /// Its certificate and key.
    pub identity: Identity,
    /// Its pins (refusal counts).
    pub pins: Arc<OperatorPins>,
    stop: Option<oneshot::Sender<()>>,
    task: tokio::task::JoinHandle<()>,
}

impl TelerobotServer {
    /// Starts a server presenting `identity` on `listen`, trusting `trusted` (in a tokio
    /// runtime), with the tests' tuning (400 ms delay hint).
    pub fn start(identity: &Identity, listen: SocketAddr, trusted: &[&Identity]) -> Self {
        Self::try_start(identity, listen, trusted).unwrap()
    }

    /// [`TelerobotServer::start`], failing if the address is taken.
    pub fn try_start(
        identity: &Identity,
        listen: SocketAddr,
        trusted: &[&Identity],
    ) -> Result<Self, tr_net::NetError> {
        let mut config = tr_net::NetConfig::new(
            listen,
            identity.clone(),
            trusted.iter().map(|i| i.cert.clone()).collect(),
            wall_summary(),
        );
        config.tuning = tuning(400.0);
        config.refusal_linger = REFUSAL_LINGER;
        let (link, io) = tr_net::link(tr_net::DEFAULT_OUTBOX_CAPACITY).unwrap();
        let server = tr_net::bind(config)?;
        let (addr, pins) = (server.local_addr().unwrap(), server.pins());
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(server.serve(io, async {
            let _ = stopped.await;
        }));
        Ok(TelerobotServer {
            addr,
            link,
            identity: identity.clone(),
            pins,
            stop: Some(stop),
            task,
        })
    }

    /// Starts a server on `listen` again, retrying for up to 5 s while the previous server's
    /// socket is still being released (quinn's endpoint driver lets go of it asynchronously).
    pub async fn restart(identity: &Identity, listen: SocketAddr, trusted: &[&Identity]) -> Self {
        for _ in 0..100 {
            match Self::try_start(identity, listen, trusted) {
                Ok(t) => return t,
                Err(tr_net::NetError::Bind { .. }) => {
                    tokio::time::sleep(Duration::from_millis(50)).await;
                }
                Err(e) => panic!("{e}"),
            }
        }
        panic!("{listen} still in use after 5 s")
    }

    /// Shuts the server down (connections closed) and waits for it.
    pub async fn stop(mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        let _ = (&mut self.task).await;
    }
}

/// A running operator client (network task only).
pub struct OperatorClient {
    /// The loop's side of the hand-off.
    pub link: OperatorLink,
    stop: Option<oneshot::Sender<()>>,
    /// The client's task.
    pub task: tokio::task::JoinHandle<Result<(), NetError>>,
}

impl OperatorClient {
    /// Starts a client connecting to `addr` as `name`, presenting `me` and pinning `pinned`,
    /// with the tests' tuning and a 500 ms longest reconnection wait.
    pub fn start(addr: SocketAddr, me: &Identity, pinned: &Identity, name: &str) -> Self {
        Self::start_with(addr, me, pinned, name, |_| {})
    }

    /// [`OperatorClient::start`] with `adjust` applied to the client's configuration.
    pub fn start_with(
        addr: SocketAddr,
        me: &Identity,
        pinned: &Identity,
        name: &str,
        adjust: impl FnOnce(&mut op_net::NetConfig),
    ) -> Self {
        let mut config = op_net::NetConfig::new(
            addr,
            me.clone(),
            pinned.cert.clone(),
            "certs/telerobot.crt",
            name,
        );
        config.tuning = tuning(400.0);
        config.reconnect_max = Duration::from_millis(500);
        adjust(&mut config);
        let (link, io) = op_net::link(
            op_net::DEFAULT_OUTBOX_CAPACITY,
            op_net::DEFAULT_MEASUREMENT_CAPACITY,
        )
        .unwrap();
        let (stop, stopped) = oneshot::channel::<()>();
        let task = tokio::spawn(op_net::connect_and_run(config, io, async {
            let _ = stopped.await;
        }));
        OperatorClient {
            link,
            stop: Some(stop),
            task,
        }
    }

    /// Says Bye, stops, and returns how the client ended.
    pub async fn stop(mut self) -> Result<(), NetError> {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        (&mut self.task).await.unwrap()
    }
}

/// A command sampled now, to `x` along the first axis.
pub fn command(x: f64) -> Command {
    Command {
        header: Header::unstamped(monotonic_ns()),
        position_m: [x, 0.0, 0.0],
        velocity_m_per_s: [0.0; 3],
    }
}

/// A contact state answering a command sampled at `command_sample_time_ns`.
pub fn contact(command_sample_time_ns: i64) -> Contact {
    Contact {
        header: Header::unstamped(monotonic_ns()),
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
    /// Calls `tick` every 100 µs on a new thread.
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
/// command's extra delay (`received − sample − nominal`) \[ns\].
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
