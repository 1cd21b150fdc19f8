//! The haptic loop's helper thread: everything the loop must not do itself.
//!
//! Every 2 ms it
//! - builds the kd-tree of a newly received cloud and hands the loop an `Arc` of it (keeping the
//!   last few alive itself, so the loop never frees one);
//! - on a new session (a reconnect) builds a fresh operator node from the new `Welcome` and hands
//!   it to the loop; drops the nodes the loop retired;
//! - drains the loop's tick records and the telerobot's measurements into the recording the
//!   report is computed from, each measurement stamped with the current clock-offset estimate;
//!   with `--out`, appends both to `ticks.csv` and `measurements.csv` ([`Streams`]) and flushes
//!   them every [`STREAM_FLUSH`]: a run killed with SIGKILL leaves both readable up to the last
//!   flush (the series joins them: a measurement's `command_sample_time_ns` is
//!   `start_ns + tick·period`, the first line's comment gives both).

use std::collections::VecDeque;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use mmt::cloud::{CloudFrame, Pose};
use mmt::contact::CloudIndex;
use node::operator::{OperatorConfig, OperatorNode};
use protocol::telerobot_to_operator::Measurement;
use rt::Shutdown;

use crate::haptic::{Exchange, TickRecord};
use crate::net::OperatorLink;
use node::OperatorSettings;

/// How often the helper wakes.
const POLL: Duration = Duration::from_millis(2);
/// Cloud indices kept alive here.
const KEEP: usize = 4;
/// Most ticks recorded: one hour at 1 kHz (about 200 MB); the report covers the first hour.
pub const MAX_RECORDED_TICKS: usize = 3_600_000;

/// How often the streamed records are flushed to the operating system.
pub const STREAM_FLUSH: Duration = Duration::from_millis(250);

/// The run's records streamed to `--out` as they come.
#[derive(Debug)]
pub struct Streams {
    ticks: rt::out::Stream,
    measurements: rt::out::Stream,
    line: String,
    flushed: std::time::Instant,
    warned: bool,
}

impl Streams {
    /// Creates (truncates) `ticks.csv` and `measurements.csv` in `dir`.
    pub fn open(dir: &rt::OutDir) -> Result<Streams, rt::OutError> {
        Ok(Streams {
            ticks: dir.stream(
                "ticks.csv",
                "tick,x_m,y_m,z_m,rendered_x_n,rendered_y_n,rendered_z_n,in_contact,rendering",
            )?,
            measurements: dir.stream(
                "measurements.csv",
                "received_ns,offset_ns,command_sample_time_ns,x_m,y_m,z_m,\
                 measured_x_n,measured_y_n,measured_z_n,in_contact,estimator_stable",
            )?,
            line: String::with_capacity(256),
            flushed: std::time::Instant::now(),
            warned: false,
        })
    }

    fn tick(&mut self, t: &TickRecord) {
        use std::fmt::Write as _;
        self.line.clear();
        let (p, f) = (t.position_m, t.force_n);
        let _ = write!(
            self.line,
            "{},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{},{}",
            t.index,
            p[0],
            p[1],
            p[2],
            f[0],
            f[1],
            f[2],
            u8::from(t.in_contact),
            u8::from(t.rendering)
        );
        self.ticks.line(&self.line);
    }

    fn measurement(&mut self, m: &MeasurementRecord) {
        use std::fmt::Write as _;
        self.line.clear();
        let (p, f) = (m.message.position_m, m.message.force_on_tool_n);
        let _ = write!(
            self.line,
            "{},{},{},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{},{}",
            m.received_ns,
            m.offset_ns.map_or(String::new(), |o| o.to_string()),
            m.message.command_sample_time_ns,
            p[0],
            p[1],
            p[2],
            f[0],
            f[1],
            f[2],
            u8::from(m.message.in_contact),
            u8::from(m.message.estimator_stable)
        );
        self.measurements.line(&self.line);
    }

    fn flush(&mut self, now: bool) {
        if !now && self.flushed.elapsed() < STREAM_FLUSH {
            return;
        }
        self.flushed = std::time::Instant::now();
        self.ticks.flush();
        self.measurements.flush();
        if !self.warned && (self.ticks.failed() || self.measurements.failed()) {
            self.warned = true;
            tracing::warn!(file = %self.ticks.path().display(),
                "streaming the records failed (disk full?): the report at the end still comes");
        }
    }
}

/// A measurement as received.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeasurementRecord {
    /// The message.
    pub message: Measurement,
    /// When it arrived [ns, operator clock].
    pub received_ns: i64,
    /// The clock-offset estimate when it was taken (telerobot − operator) \[ns\].
    pub offset_ns: Option<i64>,
}

/// Everything recorded during a run.
#[derive(Debug, Default)]
pub struct Recording {
    /// One record per tick, in tick order (gaps where the loop skipped ticks).
    pub ticks: Vec<TickRecord>,
    /// Measurements in arrival order.
    pub measurements: Vec<MeasurementRecord>,
    /// Tick records beyond [`MAX_RECORDED_TICKS`], not kept.
    pub ticks_not_kept: u64,
    /// Cloud frames indexed, and refused (bad points).
    pub clouds: (u64, u64),
    /// Nodes built for reconnections.
    pub reconnect_nodes: u64,
}

/// Starts the helper; `session` is the session of the loop's first node, `config` the operator
/// node's settings for the nodes it builds. It stops (and returns the recording) at `stop`.
pub fn spawn(
    link: OperatorLink,
    exchange: Arc<Exchange>,
    session: u64,
    config: OperatorConfig,
    streams: Option<Streams>,
    stop: Shutdown,
) -> std::io::Result<JoinHandle<Recording>> {
    std::thread::Builder::new()
        .name("haptic-helper".to_owned())
        .spawn(move || {
            let mut helper = Helper {
                link,
                exchange,
                session,
                config,
                kept: VecDeque::with_capacity(KEEP + 1),
                recording: Recording::default(),
                streams,
            };
            while !stop.wait_timeout(POLL) {
                helper.round();
            }
            helper.round();
            if let Some(s) = &mut helper.streams {
                s.flush(true);
            }
            helper.recording
        })
}

struct Helper {
    link: OperatorLink,
    exchange: Arc<Exchange>,
    session: u64,
    config: OperatorConfig,
    kept: VecDeque<Arc<CloudIndex>>,
    recording: Recording,
    streams: Option<Streams>,
}

impl Helper {
    fn round(&mut self) {
        self.cloud();
        self.sessions();
        while self.exchange.retired.take().is_some() {}
        let r = &mut self.recording;
        while let Some(t) = self.exchange.ticks.take() {
            if let Some(s) = &mut self.streams {
                s.tick(&t);
            }
            if r.ticks.len() < MAX_RECORDED_TICKS {
                r.ticks.push(t);
            } else {
                r.ticks_not_kept += 1;
            }
        }
        let offset_ns = self.link.stats().clock_offset_ns;
        while let Some(m) = self.link.measurement() {
            let record = MeasurementRecord {
                message: m.message,
                received_ns: m.received_ns,
                offset_ns,
            };
            if let Some(s) = &mut self.streams {
                s.measurement(&record);
            }
            if r.measurements.len() < MAX_RECORDED_TICKS {
                r.measurements.push(record);
            }
        }
        if let Some(s) = &mut self.streams {
            s.flush(false);
        }
    }

    fn cloud(&mut self) {
        let Some(received) = self.link.cloud() else {
            return;
        };
        let wire = *received.message;
        let index = CloudFrame::new(wire.points, wire.timestamp_ns, Pose::default())
            .ok()
            .and_then(|frame| CloudIndex::build(&frame).ok());
        match index {
            Some(index) => {
                let index = Arc::new(index);
                self.kept.push_back(Arc::clone(&index));
                if self.kept.len() > KEEP {
                    self.kept.pop_front();
                }
                self.exchange.clouds.push((received.session, index));
                self.recording.clouds.0 += 1;
            }
            None => self.recording.clouds.1 += 1,
        }
    }

    /// A new session: a fresh node for it, from its `Welcome`, at the device's last position.
    fn sessions(&mut self) {
        let status = self.link.status();
        let session = status.session();
        if session <= self.session || !status.connected() {
            return;
        }
        let Some(welcome) = status.welcome() else {
            return;
        };
        self.session = session;
        let position = self
            .recording
            .ticks
            .last()
            .map_or([0.0; 3], |t| t.position_m);
        let node = OperatorSettings::from_welcome(&welcome.scene)
            .map_err(|e| e.to_string())
            .and_then(|s| OperatorNode::new(s, self.config, position).map_err(|e| e.to_string()));
        match node {
            Ok(node) => {
                self.exchange.spare.push((session, Box::new(node)));
                self.recording.reconnect_nodes += 1;
                tracing::info!(session, scene = %welcome.scene.name,
                    "reconnected: rendering starts again with the next model");
            }
            Err(e) => tracing::error!(session, "cannot set up the operator node: {e}"),
        }
    }
}
