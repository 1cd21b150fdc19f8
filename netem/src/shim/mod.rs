//! The real-time UDP shim: a proxy that applies a [`Link`] to each direction.
//!
//! ```text
//!  client ──▶ front socket (--listen) ──up──▶ back socket ──▶ --forward
//!  client ◀── front socket            ◀─down── back socket ◀── --forward
//! ```
//!
//! - **One client at a time**, learnt NAT-style: the most recent sender to the front socket is
//!   the client, and down packets go to it. A new client address replaces the old one (so a
//!   restarted or migrated QUIC client keeps working); packets already queued for the old client
//!   go to the new one. For several clients, run several shims.
//! - **Threads** (std, no async runtime): one receive thread per socket stamps [`now_ns`] as soon
//!   as `recv_from` returns, asks its direction's [`Link`] for the packet's fate and hands the
//!   copies to the **one scheduler thread**. The scheduler owns a [`DueQueue`] keyed by
//!   `(due, seq)`, waits on its input channel until `due − spin window` (so a packet due earlier
//!   wakes it), busy-spins the rest, and sends. A writer thread writes the optional CSV log.
//! - **Buffers** are 65 536 bytes: nothing is truncated.
//! - **Live reconfiguration**: [`ShimHandle::set_config`] swaps a direction's settings between two
//!   packets; PRNG, counters and packets in flight are kept.
//! - **Shutdown** is prompt: sockets have 20 ms read timeouts, the scheduler waits at most 20 ms,
//!   and [`ShimHandle::shutdown`] joins every thread. Packets still queued are discarded and
//!   counted.
//!
//! Times on the shim's axis (what the link model, the queue and the log take) are
//! [`rt::monotonic_ns`] as `u64` ([`now_ns`]), so an in-process peer compares its own stamps
//! with the log directly.

mod log;
mod stats;
mod worker;

use std::fmt;
use std::fs::File;
use std::io::BufWriter;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::sync::mpsc;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

use thiserror::Error;

use rt::Histogram;

use crate::model::{ConfigError, Link, LinkConfig};
use crate::queue::DueQueue;

/// Default spin window of the scheduler \[ns\] ([`rt::clock::DEFAULT_SPIN_WINDOW_NS`]).
pub const DEFAULT_SPIN_WINDOW_NS: u64 = rt::clock::DEFAULT_SPIN_WINDOW_NS.unsigned_abs();

/// Now on the shim's time axis: [`rt::monotonic_ns`] as `u64` \[ns\].
pub fn now_ns() -> u64 {
    rt::monotonic_ns().unsigned_abs()
}

pub use log::CSV_HEADER;
pub use stats::{DirectionStats, ShimStats};
pub use worker::RECV_BUFFER_BYTES;

/// How long a blocked socket or the idle scheduler waits before checking for shutdown.
const POLL: Duration = Duration::from_millis(20);

/// A direction through the shim.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Direction {
    /// From the client (front socket) towards `--forward`.
    Up,
    /// From `--forward` back to the client.
    Down,
}

impl Direction {
    /// Both directions.
    pub const ALL: [Direction; 2] = [Direction::Up, Direction::Down];

    fn index(self) -> usize {
        match self {
            Direction::Up => 0,
            Direction::Down => 1,
        }
    }

    /// The seed of this direction's link, derived from the shim's seed (SplitMix64 of the seed
    /// and the direction) so the two directions draw independent streams.
    pub fn link_seed(self, seed: u64) -> u64 {
        let mut z = seed ^ (0x9E37_79B9_7F4A_7C15u64.wrapping_mul(self.index() as u64 + 1));
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Direction::Up => "up",
            Direction::Down => "down",
        })
    }
}

/// Everything the shim needs to start.
#[derive(Clone, Debug)]
pub struct ShimConfig {
    /// Address of the front socket the client sends to (port 0: any free port).
    pub listen: SocketAddr,
    /// Where up packets go.
    pub forward: SocketAddr,
    /// Client → forward settings.
    pub up: LinkConfig,
    /// Forward → client settings.
    pub down: LinkConfig,
    /// Seed of both links' PRNGs (see [`Direction::link_seed`]). Default 0.
    pub seed: u64,
    /// How long before a packet's due time the scheduler stops sleeping and spins [ns]. Default
    /// [`DEFAULT_SPIN_WINDOW_NS`] (200 µs). 0 never spins (lateness then is the timer's, tens of
    /// µs); more than ~200 µs costs CPU shared with the real-time loops.
    pub spin_window_ns: u64,
    /// Write the per-packet CSV log here ([`CSV_HEADER`]). Default none.
    pub log_path: Option<PathBuf>,
    /// Run the scheduler thread under `SCHED_FIFO` at this priority (1..=99). Default none
    /// (ordinary scheduling). On a loaded machine this is what bounds the lateness tail: without
    /// it the woken scheduler waits for a CPU behind other work. Needs `CAP_SYS_NICE`; if refused
    /// the shim runs anyway and reports why in [`ShimStats::realtime_error`].
    pub realtime_priority: Option<u8>,
}

impl ShimConfig {
    /// A shim from `listen` to `forward` with perfect links and the defaults above.
    pub fn new(listen: SocketAddr, forward: SocketAddr) -> Self {
        Self {
            listen,
            forward,
            up: LinkConfig::default(),
            down: LinkConfig::default(),
            seed: 0,
            spin_window_ns: DEFAULT_SPIN_WINDOW_NS,
            log_path: None,
            realtime_priority: None,
        }
    }
}

/// Why the shim could not start or stop cleanly.
#[derive(Debug, Error)]
pub enum ShimError {
    /// A direction's settings are out of range.
    #[error("{direction} link: {error}")]
    Config {
        /// The direction.
        direction: Direction,
        /// What is wrong.
        error: ConfigError,
    },
    /// A socket could not be set up.
    #[error("{what} {addr}")]
    Socket {
        /// What was being done, e.g. "cannot bind the front socket to".
        what: &'static str,
        /// The address involved.
        addr: SocketAddr,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The log file could not be created.
    #[error("cannot create the packet log {path}")]
    Log {
        /// The path given.
        path: PathBuf,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// The real-time priority is out of range.
    #[error("real-time priority {0}: expected 1..=99 (SCHED_FIFO)")]
    Priority(u8),
    /// A thread could not be started.
    #[error("cannot start the {thread} thread")]
    Spawn {
        /// The thread's name.
        thread: &'static str,
        /// The operating system's reason.
        source: std::io::Error,
    },
    /// A thread panicked (a bug).
    #[error("the {0} thread panicked")]
    Panicked(&'static str),
    /// `forward` is the shim's own front socket: every packet would loop through the shim
    /// forever.
    #[error(
        "--forward {forward} is the shim's own --listen socket {listen}: packets would loop \
         through the shim; expected the server's address"
    )]
    ForwardsToItself {
        /// The front socket's bound address.
        listen: SocketAddr,
        /// The forward address given.
        forward: SocketAddr,
    },
}

/// Whether packets sent to `forward` would arrive at the front socket bound at `front`
/// (the same address, or the same port on loopback behind an unspecified bind).
fn forwards_to_itself(front: SocketAddr, forward: SocketAddr) -> bool {
    front == forward
        || (front.port() == forward.port()
            && (front.ip().is_unspecified() || front.ip().is_loopback())
            && (forward.ip().is_loopback() || forward.ip().is_unspecified()))
}

/// State shared by the handle and the threads.
#[derive(Debug)]
struct Shared {
    stop: AtomicBool,
    links: [Mutex<Link>; 2],
    client: Mutex<Option<SocketAddr>>,
    forwarded: [AtomicU64; 2],
    send_errors: [AtomicU64; 2],
    out_of_order: [AtomicU64; 2],
    lateness: [Histogram; 2],
    no_client: AtomicU64,
    recv_errors: AtomicU64,
    client_changes: AtomicU64,
    discarded_at_shutdown: AtomicU64,
    log_records_dropped: AtomicU64,
    log_error: Mutex<Option<String>>,
    realtime_error: Mutex<Option<String>>,
    next_seq: AtomicU64,
}

impl Shared {
    fn link(&self, direction: Direction) -> MutexGuard<'_, Link> {
        lock(&self.links[direction.index()])
    }
}

fn lock<T>(mutex: &Mutex<T>) -> MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A running shim. Dropping it shuts it down (ignoring errors); call
/// [`shutdown`](Self::shutdown) to get the final counters.
#[derive(Debug)]
pub struct ShimHandle {
    shared: Arc<Shared>,
    local_addr: SocketAddr,
    threads: Vec<(&'static str, JoinHandle<()>)>,
}

/// Starts the shim: binds, connects, spawns the threads, and returns at once.
pub fn start(config: ShimConfig) -> Result<ShimHandle, ShimError> {
    let link = |direction: Direction, link_config: &LinkConfig| {
        Link::new(link_config.clone(), direction.link_seed(config.seed))
            .map(Mutex::new)
            .map_err(|error| ShimError::Config { direction, error })
    };
    let links = [
        link(Direction::Up, &config.up)?,
        link(Direction::Down, &config.down)?,
    ];
    if let Some(priority) = config.realtime_priority.filter(|p| !(1..=99).contains(p)) {
        return Err(ShimError::Priority(priority));
    }
    let sockets = worker::Sockets::open(config.listen, config.forward, POLL)?;
    let local_addr = sockets.front_addr;
    if forwards_to_itself(local_addr, config.forward) {
        return Err(ShimError::ForwardsToItself {
            listen: local_addr,
            forward: config.forward,
        });
    }
    let writer = match &config.log_path {
        Some(path) => Some(log::create(path).map_err(|source| ShimError::Log {
            path: path.clone(),
            source,
        })?),
        None => None,
    };
    let shared = Arc::new(Shared::new(links));
    let mut handle = ShimHandle {
        shared: Arc::clone(&shared),
        local_addr,
        threads: Vec::with_capacity(4),
    };
    let log_tx = match writer {
        Some(out) => Some(handle.start_log_writer(out)?),
        None => None,
    };
    let sink = log::LogSink::new(log_tx, Arc::clone(&shared));
    let packet_tx = handle.start_scheduler(&config, &sockets, sink.clone())?;
    for direction in Direction::ALL {
        handle.start_receiver(direction, &sockets, packet_tx.clone(), sink.clone())?;
    }
    Ok(handle)
}

impl Shared {
    /// The state of a shim that has not started: no client, every counter at zero.
    fn new(links: [Mutex<Link>; 2]) -> Shared {
        Shared {
            stop: AtomicBool::new(false),
            links,
            client: Mutex::new(None),
            forwarded: Default::default(),
            send_errors: Default::default(),
            out_of_order: Default::default(),
            lateness: [Histogram::new(), Histogram::new()],
            no_client: AtomicU64::new(0),
            recv_errors: AtomicU64::new(0),
            client_changes: AtomicU64::new(0),
            discarded_at_shutdown: AtomicU64::new(0),
            log_records_dropped: AtomicU64::new(0),
            log_error: Mutex::new(None),
            realtime_error: Mutex::new(None),
            next_seq: AtomicU64::new(0),
        }
    }
}

impl ShimHandle {
    /// Starts the thread that writes the packet log to `out`; returns its input.
    fn start_log_writer(
        &mut self,
        out: BufWriter<File>,
    ) -> Result<mpsc::SyncSender<log::LogRecord>, ShimError> {
        let (tx, rx) = mpsc::sync_channel(log::LOG_CHANNEL_CAPACITY);
        let shared = Arc::clone(&self.shared);
        self.spawn("netem-log", move || {
            log::write_all(out, rx, &shared.log_error);
        })?;
        Ok(tx)
    }

    /// Starts the scheduler thread, which releases packets on time; returns its input.
    fn start_scheduler(
        &mut self,
        config: &ShimConfig,
        sockets: &worker::Sockets,
        log: log::LogSink,
    ) -> Result<mpsc::Sender<(u64, u64, worker::Packet)>, ShimError> {
        let (packet_tx, packet_rx) = mpsc::channel();
        let scheduler = worker::Scheduler {
            shared: Arc::clone(&self.shared),
            sockets: sockets.clone(),
            rx: packet_rx,
            queue: DueQueue::new(),
            spin_window_ns: config.spin_window_ns,
            realtime_priority: config.realtime_priority,
            log,
            highest_released: [None; 2],
        };
        self.spawn("netem-scheduler", move || scheduler.run())?;
        Ok(packet_tx)
    }

    /// Starts the receive thread of `direction`, which hands packets to the scheduler by `tx`.
    fn start_receiver(
        &mut self,
        direction: Direction,
        sockets: &worker::Sockets,
        tx: mpsc::Sender<(u64, u64, worker::Packet)>,
        log: log::LogSink,
    ) -> Result<(), ShimError> {
        let receiver = worker::Receiver {
            direction,
            shared: Arc::clone(&self.shared),
            socket: sockets.receiving(direction),
            tx,
            log,
        };
        self.spawn(
            match direction {
                Direction::Up => "netem-recv-up",
                Direction::Down => "netem-recv-down",
            },
            move || receiver.run(),
        )
    }
}

/// Runs the shim until `stop` becomes true (checked every 50 ms), then shuts it down and returns
/// the final counters. This is what the `netem` binary calls.
pub fn run(config: ShimConfig, stop: &AtomicBool) -> Result<ShimStats, ShimError> {
    let handle = start(config)?;
    while !stop.load(Relaxed) {
        std::thread::sleep(Duration::from_millis(50));
    }
    handle.shutdown()
}

impl ShimHandle {
    /// The front socket's address: where the client sends.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The client's address, once one has sent.
    pub fn client_addr(&self) -> Option<SocketAddr> {
        *lock(&self.shared.client)
    }

    /// A snapshot of the counters.
    pub fn stats(&self) -> ShimStats {
        stats::snapshot(&self.shared)
    }

    /// The settings of one direction.
    pub fn config(&self, direction: Direction) -> LinkConfig {
        self.shared.link(direction).config().clone()
    }

    /// Changes one direction's settings from the next packet on (e.g. 100 % loss for an outage,
    /// then back). An invalid configuration is refused and the old one stays.
    pub fn set_config(&self, direction: Direction, config: LinkConfig) -> Result<(), ShimError> {
        self.shared
            .link(direction)
            .set_config(config)
            .map_err(|error| ShimError::Config { direction, error })
    }

    /// Stops every thread, waits for them (≈ 20 ms), flushes the log and returns the final
    /// counters.
    pub fn shutdown(mut self) -> Result<ShimStats, ShimError> {
        self.stop_and_join()?;
        Ok(self.stats())
    }

    fn spawn(
        &mut self,
        name: &'static str,
        body: impl FnOnce() + Send + 'static,
    ) -> Result<(), ShimError> {
        let thread = std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(body)
            .map_err(|source| ShimError::Spawn {
                thread: name,
                source,
            })?;
        self.threads.push((name, thread));
        Ok(())
    }

    fn stop_and_join(&mut self) -> Result<(), ShimError> {
        self.shared.stop.store(true, Relaxed);
        let mut result = Ok(());
        // Receivers and the scheduler first; the log writer ends when their senders are gone.
        for (name, thread) in self.threads.drain(..).rev() {
            if thread.join().is_err() && result.is_ok() {
                result = Err(ShimError::Panicked(name));
            }
        }
        result
    }
}

impl Drop for ShimHandle {
    fn drop(&mut self) {
        let _ = self.stop_and_join();
    }
}
