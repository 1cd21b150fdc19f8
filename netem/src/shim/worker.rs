//! The shim's threads: a receive loop per socket and the scheduler.

use std::io::ErrorKind;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::sync::mpsc::{self, RecvTimeoutError, TryRecvError};
use std::time::{Duration, Instant};

use super::log::{LogFate, LogRecord, LogSink};
use super::{Direction, POLL, Shared, ShimError, lock};
use rt::thread::{set_realtime_priority, set_timer_slack_ns};

use super::now_ns;
use crate::model::{Delivery, DropReason, Fate};
use crate::queue::{Due, DueQueue};

/// Receive buffer size [bytes]: larger than any UDP payload, so nothing is ever truncated.
pub const RECV_BUFFER_BYTES: usize = 65_536;

/// The two sockets: `front` faces the client, `back` is connected to the forward address.
#[derive(Clone, Debug)]
pub(super) struct Sockets {
    front: Arc<UdpSocket>,
    back: Arc<UdpSocket>,
    pub(super) front_addr: SocketAddr,
}

impl Sockets {
    pub(super) fn open(
        listen: SocketAddr,
        forward: SocketAddr,
        read_timeout: Duration,
    ) -> Result<Self, ShimError> {
        let socket_error = |what, addr| move |source| ShimError::Socket { what, addr, source };
        let front = UdpSocket::bind(listen)
            .map_err(socket_error("cannot bind the front socket to", listen))?;
        let any: SocketAddr = if forward.is_ipv4() {
            (Ipv4Addr::UNSPECIFIED, 0).into()
        } else {
            (Ipv6Addr::UNSPECIFIED, 0).into()
        };
        let back =
            UdpSocket::bind(any).map_err(socket_error("cannot bind the back socket to", any))?;
        back.connect(forward)
            .map_err(socket_error("cannot connect the back socket to", forward))?;
        front
            .set_read_timeout(Some(read_timeout))
            .map_err(socket_error("cannot set a read timeout on", listen))?;
        back.set_read_timeout(Some(read_timeout))
            .map_err(socket_error("cannot set a read timeout on", forward))?;
        let front_addr = front
            .local_addr()
            .map_err(socket_error("cannot read the address of", listen))?;
        Ok(Self {
            front: Arc::new(front),
            back: Arc::new(back),
            front_addr,
        })
    }

    /// The socket packets of `direction` arrive on.
    pub(super) fn receiving(&self, direction: Direction) -> Arc<UdpSocket> {
        Arc::clone(match direction {
            Direction::Up => &self.front,
            Direction::Down => &self.back,
        })
    }
}

/// One packet copy on its way to the scheduler.
#[derive(Debug)]
pub(super) struct Packet {
    direction: Direction,
    packet: u64,
    arrival_ns: u64,
    fate: LogFate,
    bytes: Vec<u8>,
}

/// A receive loop: stamps, decides the fate, hands copies to the scheduler.
pub(super) struct Receiver {
    pub(super) direction: Direction,
    pub(super) shared: Arc<Shared>,
    pub(super) socket: Arc<UdpSocket>,
    pub(super) tx: mpsc::Sender<(u64, u64, Packet)>,
    pub(super) log: LogSink,
}

impl Receiver {
    pub(super) fn run(self) {
        let mut buf = vec![0u8; RECV_BUFFER_BYTES];
        let mut packet = 0u64;
        while !self.shared.stop.load(Relaxed) {
            let (len, from) = match self.socket.recv_from(&mut buf) {
                Ok(received) => received,
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                    ) =>
                {
                    continue;
                }
                Err(_) => {
                    // E.g. ECONNREFUSED on the back socket while nothing listens at --forward.
                    self.shared.recv_errors.fetch_add(1, Relaxed);
                    std::thread::sleep(Duration::from_millis(1));
                    continue;
                }
            };
            let arrival_ns = now_ns();
            if self.direction == Direction::Up {
                self.learn_client(from);
            }
            let fate = self.shared.link(self.direction).offer(arrival_ns, len);
            let bytes = buf.get(..len).unwrap_or_default();
            let sent = match fate {
                Fate::Dropped(reason) => {
                    self.log_drop(packet, len, arrival_ns, reason);
                    true
                }
                Fate::Delivered {
                    original,
                    duplicate,
                } => {
                    let copy_sent = duplicate.is_none_or(|copy| {
                        self.schedule(packet, arrival_ns, copy, LogFate::Duplicate, bytes)
                    });
                    let fate = if original.reordered {
                        LogFate::Reordered
                    } else {
                        LogFate::Forwarded
                    };
                    copy_sent && self.schedule(packet, arrival_ns, original, fate, bytes)
                }
            };
            if !sent {
                break; // The scheduler is gone: shutting down.
            }
            packet += 1;
        }
    }

    fn learn_client(&self, from: SocketAddr) {
        let mut client = lock(&self.shared.client);
        if *client != Some(from) {
            if client.is_some() {
                self.shared.client_changes.fetch_add(1, Relaxed);
            }
            *client = Some(from);
        }
    }

    fn schedule(
        &self,
        packet: u64,
        arrival_ns: u64,
        delivery: Delivery,
        fate: LogFate,
        bytes: &[u8],
    ) -> bool {
        let seq = self.shared.next_seq.fetch_add(1, Relaxed);
        let item = Packet {
            direction: self.direction,
            packet,
            arrival_ns,
            fate,
            bytes: bytes.to_vec(),
        };
        self.tx.send((delivery.due_ns, seq, item)).is_ok()
    }

    fn log_drop(&self, packet: u64, len: usize, arrival_ns: u64, reason: DropReason) {
        self.log.record(LogRecord {
            dir: self.direction,
            packet,
            seq: None,
            len,
            arrival_ns,
            due_ns: None,
            release_ns: None,
            fate: match reason {
                DropReason::Loss => LogFate::Lost,
                DropReason::Limit => LogFate::Limit,
            },
        });
    }
}

/// The one thread that releases packets on time.
pub(super) struct Scheduler {
    pub(super) shared: Arc<Shared>,
    pub(super) sockets: Sockets,
    pub(super) rx: mpsc::Receiver<(u64, u64, Packet)>,
    pub(super) queue: DueQueue<Packet>,
    pub(super) spin_window_ns: u64,
    pub(super) realtime_priority: Option<u8>,
    pub(super) log: LogSink,
    /// Highest arrival index released per direction, to count packets released out of order.
    pub(super) highest_released: [Option<u64>; 2],
}

impl Scheduler {
    pub(super) fn run(mut self) {
        set_timer_slack_ns(1);
        if let Some(Err(e)) = self.realtime_priority.map(set_realtime_priority) {
            *lock(&self.shared.realtime_error) = Some(e.to_string());
        }
        'outer: while !self.shared.stop.load(Relaxed) {
            loop {
                match self.rx.try_recv() {
                    Ok(item) => self.push(item),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => break 'outer,
                }
            }
            let Some(due) = self.queue.next_due_ns() else {
                if !self.wait(POLL) {
                    break;
                }
                continue;
            };
            let now = now_ns();
            if due > now.saturating_add(self.spin_window_ns) {
                // Sleep until due − spin window, or until a new packet (maybe due earlier) comes.
                let wait = Duration::from_nanos(due - now - self.spin_window_ns).min(POLL);
                if !self.wait(wait) {
                    break;
                }
                continue;
            }
            while now_ns() < due {
                match self.rx.try_recv() {
                    Ok(item) => {
                        self.push(item);
                        continue 'outer;
                    }
                    Err(TryRecvError::Empty) => std::hint::spin_loop(),
                    Err(TryRecvError::Disconnected) => break 'outer,
                }
            }
            while let Some(due) = self.queue.pop_due(now_ns()) {
                self.release(due);
            }
        }
        // Count what is queued, and what the receivers still hand over until they are gone.
        let mut left = self.queue.len();
        let deadline = Instant::now() + Duration::from_secs(1);
        while Instant::now() < deadline {
            match self.rx.recv_timeout(POLL) {
                Ok(_) => left += 1,
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        let left = u64::try_from(left).unwrap_or(u64::MAX);
        self.shared.discarded_at_shutdown.fetch_add(left, Relaxed);
    }

    fn push(&mut self, (due_ns, seq, packet): (u64, u64, Packet)) {
        self.queue.push(due_ns, seq, packet);
    }

    /// Waits up to `timeout` for a new packet; `false` once the receivers are gone.
    fn wait(&mut self, timeout: Duration) -> bool {
        match self.rx.recv_timeout(timeout) {
            Ok(item) => {
                self.push(item);
                true
            }
            Err(RecvTimeoutError::Timeout) => true,
            Err(RecvTimeoutError::Disconnected) => false,
        }
    }

    fn release(&mut self, due: Due<Packet>) {
        let Due { due_ns, seq, item } = due;
        let index = item.direction.index();
        let release_ns = now_ns();
        let sent = match item.direction {
            Direction::Up => Some(self.sockets.back.send(&item.bytes)),
            Direction::Down => {
                let client = *lock(&self.shared.client);
                client.map(|addr| self.sockets.front.send_to(&item.bytes, addr))
            }
        };
        self.shared.lateness[index]
            .record(i64::try_from(release_ns.saturating_sub(due_ns)).unwrap_or(i64::MAX));
        let fate = match sent {
            Some(Ok(_)) => {
                self.shared.forwarded[index].fetch_add(1, Relaxed);
                item.fate
            }
            Some(Err(_)) => {
                self.shared.send_errors[index].fetch_add(1, Relaxed);
                LogFate::SendError
            }
            None => {
                self.shared.no_client.fetch_add(1, Relaxed);
                LogFate::NoClient
            }
        };
        let highest = &mut self.highest_released[index];
        if highest.is_some_and(|h| item.packet < h) {
            self.shared.out_of_order[index].fetch_add(1, Relaxed);
        }
        *highest = Some(highest.map_or(item.packet, |h| h.max(item.packet)));
        self.log.record(LogRecord {
            dir: item.direction,
            packet: item.packet,
            seq: Some(seq),
            len: item.bytes.len(),
            arrival_ns: item.arrival_ns,
            due_ns: Some(due_ns),
            release_ns: Some(release_ns),
            fate,
        });
    }
}
