//! The haptic loop's helper thread: everything the loop must not do itself.
//!
//! Every 2 ms it
//! - builds the kd-tree of a newly received cloud and hands the loop an `Arc` of it (keeping the
//!   last few alive itself, so the loop never frees one);
//! - on a new session (a reconnect) builds a fresh operator node from the new `Welcome` and hands
//!   it to the loop; drops the nodes the loop retired;
//! - drains the loop's tick records and the telerobot's measurements into the recording the
//!   report is computed from, each measurement stamped with the current clock-offset estimate.

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
            };
            while !stop.wait_timeout(POLL) {
                helper.round();
            }
            helper.round();
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
}

impl Helper {
    fn round(&mut self) {
        self.cloud();
        self.sessions();
        while self.exchange.retired.take().is_some() {}
        let r = &mut self.recording;
        while let Some(t) = self.exchange.ticks.take() {
            if r.ticks.len() < MAX_RECORDED_TICKS {
                r.ticks.push(t);
            } else {
                r.ticks_not_kept += 1;
            }
        }
        let offset_ns = self.link.stats().clock_offset_ns;
        while let Some(m) = self.link.measurement() {
            if r.measurements.len() < MAX_RECORDED_TICKS {
                r.measurements.push(MeasurementRecord {
                    message: m.message,
                    received_ns: m.received_ns,
                    offset_ns,
                });
            }
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
