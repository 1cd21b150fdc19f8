//! The haptic loop's helper thread: everything the loop must not do itself.
//!
//! Every 2 ms it
//! - holds a newly received cloud to the real-time budget (`mmt::contact::budget`, at the
//!   `Welcome`'s proxy radii, loop rate and cloud rate: a peer's frame the proxy could not step
//!   on at the loop rate is voxel-downsampled, or refused when only a voxel the proxy slips
//!   through would fit; counted in the report, logged once), builds its kd-tree and hands the
//!   loop an `Arc` of it; drops the indices the loop replaced (the loop may hold the last
//!   reference of one, and never frees it itself);
//! - on a new session (a reconnect) builds a fresh operator node from the new `Welcome` and hands
//!   it to the loop; drops the nodes the loop retired;
//! - drains the loop's tick records and the telerobot's measurements into the recording the
//!   report is computed from, each measurement stamped with the current clock-offset estimate;
//!   with `--out`, appends both to `ticks.csv` and `measurements.csv` ([`Streams`]) and flushes
//!   them every [`STREAM_FLUSH`]: a run killed with SIGKILL leaves both readable up to the last
//!   flush (the series joins them: a measurement's `command_sample_time_ns` is
//!   `start_ns + tick·period`, the first line's comment gives both).
//! - with `--record`/`--live`, hands the same records, the clouds, the link statistics (10 Hz)
//!   and the safety and device events (from the records' flags) to the recorder
//!   ([`record::RecordSink`]): one batch per round, never waiting.
//! - with a [`Tap`] (the soak), hands the same tick and measurement samples to its channel, one
//!   batch per round, and keeps at most the tap's `keep_ticks` in the recording: memory stays
//!   flat however long the run.

use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use cloud_io::voxel::VoxelGrid;
use metrics::networked::{MeasurementSample, TickSample};
use mmt::cloud::{CloudFrame, Pose};
use mmt::contact::budget::CloudBudget;
use mmt::contact::{CloudIndex, ProxyConfig};
use node::operator::{OperatorConfig, OperatorNode};
use record::schema::{
    CloudRec, ContactRec, EventRec, Level, LinkRec, MeasurementRec, OperatorTick, ParametersRec,
    SafetyFlags, StateSyncRec,
};
use record::{Message, RecordSink, Side, Timed};
use rt::Shutdown;

use crate::haptic::{Exchange, TickRecord};
use crate::net::OperatorLink;
use node::OperatorSettings;
use protocol::telerobot_to_operator::SceneSummary;

/// How often the helper wakes.
const POLL: Duration = Duration::from_millis(2);
/// Most ticks recorded: one hour at 1 kHz (about 200 MB); the report covers the first hour.
pub const MAX_RECORDED_TICKS: usize = 3_600_000;
/// How often the link statistics go to the recording.
const LINK_EVERY: Duration = Duration::from_millis(100);

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

    fn measurement(&mut self, m: &MeasurementRec) {
        use std::fmt::Write as _;
        self.line.clear();
        let (p, f) = (m.position_m, m.force_on_tool_n);
        let _ = write!(
            self.line,
            "{},{},{},{:.6},{:.6},{:.6},{:.5},{:.5},{:.5},{},{}",
            m.received_ns,
            m.offset_ns.map_or(String::new(), |o| o.to_string()),
            m.command_sample_time_ns,
            p[0],
            p[1],
            p[2],
            f[0],
            f[1],
            f[2],
            u8::from(m.in_contact),
            u8::from(m.estimator_stable)
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

/// Everything recorded during a run, for its report.
#[derive(Debug, Default)]
pub struct Recording {
    /// One record per tick, in tick order (gaps where the loop skipped ticks).
    pub ticks: Vec<TickSample>,
    /// Measurements in arrival order, each with the clock-offset estimate when it was taken.
    pub measurements: Vec<MeasurementSample>,
    /// Tick records beyond [`MAX_RECORDED_TICKS`] (or a tap's `keep_ticks`), not kept.
    pub ticks_not_kept: u64,
    /// Cloud frames indexed, and refused (bad points, or over the real-time budget).
    pub clouds: (u64, u64),
    /// Cloud frames over the real-time budget: downsampled to fit, and refused.
    pub clouds_over_budget: (u64, u64),
    /// Nodes built for reconnections.
    pub reconnect_nodes: u64,
    /// Haptic-loop periods (tick start to the next tick's start) while the recorder recorded
    /// (`[0]`) and while it was paused (`[1]`): what recording and the live view cost the loop,
    /// measured in one run (`demo --record-ab-s`). Counted from the first pause or resume on, so
    /// that the loop's start-up (connecting, first cloud, first model) weighs on neither half.
    /// Empty without a recorder, or if it was never paused.
    pub periods: [rt::Histogram; 2],
}

/// Where the helper sends what it takes, beyond the run's own recording.
#[derive(Debug, Default)]
pub struct Outputs {
    /// The recorder, if the run records.
    pub record: Option<RecordSink>,
    /// The streamed records (`--out`), if any.
    pub streams: Option<Streams>,
    /// The tap (the soak), if any.
    pub tap: Option<Tap>,
}

/// Starts the helper; `session` is the session of the loop's first node, `config` the operator
/// node's settings for the nodes it builds. It stops (and returns the recording) at `stop`.
pub fn spawn(
    link: OperatorLink,
    exchange: Arc<Exchange>,
    session: u64,
    config: OperatorConfig,
    outputs: Outputs,
    stop: Shutdown,
) -> std::io::Result<JoinHandle<Recording>> {
    let Outputs {
        record,
        streams,
        tap,
    } = outputs;
    std::thread::Builder::new()
        .name("haptic-helper".to_owned())
        .spawn(move || {
            let mut helper = Helper {
                link,
                exchange,
                session,
                config,
                recording: Recording::default(),
                record: record.map(|sink| Forward {
                    sink,
                    batch: Vec::new(),
                    last: None,
                    link_due: std::time::Instant::now(),
                    ab: AbWindow::default(),
                }),
                last_position: [0.0; 3],
                previous_tick: None,
                streams,
                keep: tap.as_ref().map_or(MAX_RECORDED_TICKS, |t| t.keep_ticks),
                tap: tap.map(TapRound::new),
                guard: CloudGuard::default(),
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
    recording: Recording,
    record: Option<Forward>,
    /// The commanded position of the last tick (where a reconnection's node starts).
    last_position: [f64; 3],
    /// The last tick's index and start [ns].
    previous_tick: Option<(u64, i64)>,
    streams: Option<Streams>,
    /// Most ticks and measurements the recording keeps.
    keep: usize,
    /// The tap, and this round's samples for it.
    tap: Option<TapRound>,
    guard: CloudGuard,
}

/// Holds frames received from the telerobot to the real-time budget (`mmt::contact::budget`)
/// before they are indexed: a peer's frame is not trusted to fit.
#[derive(Debug, Default)]
struct CloudGuard {
    budget: CloudBudget,
    grid: VoxelGrid,
    /// Frames downsampled to fit, and refused.
    counts: (u64, u64),
    /// A frame over the budget was logged (once per run).
    warned: bool,
    /// The session of the last frame held.
    last_session: Option<u64>,
}

impl CloudGuard {
    /// Holds `points`, a frame of `session`, to the budget at `scene`'s radii and rates (the
    /// defaults before a `Welcome`), downsampling if needed: `false` if refused. A session's
    /// first frame is held as static (the summary gives a rate for static clouds too).
    fn hold(
        &mut self,
        points: &mut Vec<[f32; 3]>,
        scene: Option<&SceneSummary>,
        session: u64,
    ) -> bool {
        let repeat = self.last_session.replace(session) == Some(session);
        let (proxy, rate) = scene.map_or((ProxyConfig::default(), Some(30.0)), |s| {
            let proxy = OperatorSettings::from_welcome(s)
                .map_or_else(|_| ProxyConfig::default(), |s| s.proxy);
            (proxy, s.cloud_rate_hz)
        });
        let rate = rate.filter(|_| repeat);
        let fit =
            cloud_io::budget::fit_to_budget(points, &proxy, &self.budget, rate, &mut self.grid);
        let first = !self.warned;
        match &fit {
            Ok(None) => return true,
            Ok(Some(fit)) => {
                self.counts.0 += 1;
                if first {
                    tracing::warn!(
                        "cloud from the telerobot: {fit} (logged once; counted in the report)"
                    );
                }
            }
            Err(e) => {
                self.counts.1 += 1;
                if first {
                    tracing::warn!(
                        "cloud from the telerobot refused: {e} (logged once; counted in the report)"
                    );
                }
            }
        }
        self.warned = true;
        fit.is_ok()
    }
}

/// What goes to the recorder: this round's batch, and what the events are edges of.
struct Forward {
    sink: RecordSink,
    batch: Vec<Timed>,
    /// The previous tick's safety flags and device fault count.
    last: Option<(SafetyFlags, u64)>,
    link_due: std::time::Instant,
    ab: AbWindow,
}

/// When the A/B halves of `--record-ab-s` are counted: from the first pause or resume on.
#[derive(Debug, Default)]
struct AbWindow {
    /// The sink's pause state at the last round.
    paused: Option<bool>,
    /// It has changed since the first round.
    toggled: bool,
}

impl AbWindow {
    /// Notes the sink's pause state at a round; true once it has been toggled.
    fn counting(&mut self, paused: bool) -> bool {
        self.toggled |= self.paused.is_some_and(|p| p != paused);
        self.paused = Some(paused);
        self.toggled
    }
}

impl Helper {
    fn round(&mut self) {
        // Dropped here, before a new cloud goes to the loop: the loop never frees an index.
        while self.exchange.retired_clouds.take().is_some() {}
        self.cloud();
        self.sessions();
        while self.exchange.retired.take().is_some() {}
        let recording = self.record.as_ref().is_some_and(|f| !f.sink.is_paused());
        let counting = self
            .record
            .as_mut()
            .is_some_and(|f| f.ab.counting(!recording));
        while let Some(t) = self.exchange.ticks.take() {
            self.last_position = t.position_m;
            if let Some((index, started_ns)) = self.previous_tick
                && counting
                && t.index == index + 1
            {
                self.recording.periods[usize::from(!recording)].record(t.started_ns - started_ns);
            }
            self.previous_tick = Some((t.index, t.started_ns));
            if let Some(s) = &mut self.streams {
                s.tick(&t);
            }
            let sample = TickSample {
                index: t.index,
                sample_time_ns: Some(t.sample_time_ns),
                position_m: t.position_m,
                force_n: t.force_n,
                in_contact: t.in_contact,
                rendering: t.rendering,
                reduced: t.reduced,
            };
            if let Some(tap) = &mut self.tap {
                tap.tick(sample, t.parameters.as_ref().map(|(p, _)| p.model_id));
            }
            let r = &mut self.recording;
            if r.ticks.len() < self.keep {
                r.ticks.push(sample);
            } else {
                r.ticks_not_kept += 1;
            }
            if let Some(f) = self.record.as_mut().filter(|_| recording) {
                f.tick(&t);
            }
        }
        let offset_ns = self.link.stats().clock_offset_ns;
        while let Some(m) = self.link.measurement() {
            let rec = MeasurementRec::new(m.session, &m.message, m.received_ns, offset_ns);
            if let Some(s) = &mut self.streams {
                s.measurement(&rec);
            }
            if let Some(tap) = &mut self.tap {
                tap.measurement(rec.sample());
            }
            let r = &mut self.recording;
            if r.measurements.len() < self.keep {
                r.measurements.push(rec.sample());
            }
            if let Some(f) = self.record.as_mut().filter(|_| recording) {
                f.push(m.received_ns, Message::Measurement(Box::new(rec)));
            }
        }
        if let Some(f) = self.record.as_mut().filter(|_| recording) {
            f.link(&self.link);
            f.flush();
        }
        if let Some(s) = &mut self.streams {
            s.flush(false);
        }
        self.tap_batch();
    }

    /// This round's samples to the tap, if it took any (a vanished consumer is forgotten).
    fn tap_batch(&mut self) {
        if self.tap.as_mut().is_some_and(|tap| !tap.send()) {
            self.tap = None;
        }
    }

    fn cloud(&mut self) {
        let Some(received) = self.link.cloud() else {
            return;
        };
        let wire = *received.message;
        if let Some(f) = self.record.as_mut().filter(|f| f.sink.wants_clouds()) {
            let cloud = CloudRec {
                frame_id: wire.frame_id,
                timestamp_ns: wire.timestamp_ns,
                points: Arc::new(wire.points.clone()),
            };
            f.push(received.received_ns, Message::Cloud(Side::Operator, cloud));
        }
        let mut points = wire.points;
        let welcome = self.link.status().welcome();
        let scene = welcome.as_ref().map(|w| &w.scene);
        if !self.guard.hold(&mut points, scene, received.session) {
            self.recording.clouds.1 += 1;
            self.recording.clouds_over_budget = self.guard.counts;
            return;
        }
        self.recording.clouds_over_budget = self.guard.counts;
        let index = CloudFrame::new(points, wire.timestamp_ns, Pose::default())
            .ok()
            .and_then(|frame| CloudIndex::build(&frame).ok());
        match index {
            Some(index) => {
                self.exchange
                    .clouds
                    .push((received.session, Arc::new(index)));
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
        let position = self.last_position;
        let node = OperatorSettings::from_welcome(&welcome.scene)
            .map_err(|e| e.to_string())
            .and_then(|s| OperatorNode::new(s, self.config, position).map_err(|e| e.to_string()));
        match node {
            Ok(node) => {
                self.exchange.spare.push((session, Box::new(node)));
                self.recording.reconnect_nodes += 1;
                tracing::info!(session, scene = %welcome.scene.name,
                    "reconnected: rendering starts again with the next model");
                if let Some(f) = &mut self.record {
                    f.event(
                        rt::monotonic_ns(),
                        Level::Info,
                        "session",
                        format!("session {session}: reconnected to the telerobot"),
                    );
                }
            }
            Err(e) => tracing::error!(session, "cannot set up the operator node: {e}"),
        }
    }
}

impl Forward {
    fn push(&mut self, t_ns: i64, message: Message) {
        self.batch.push(Timed { t_ns, message });
    }

    fn event(&mut self, t_ns: i64, level: Level, source: &'static str, text: String) {
        self.push(
            t_ns,
            Message::Event(EventRec {
                level,
                source,
                text,
            }),
        );
    }

    /// One tick: its record, the messages it took, and the safety and device events it began or
    /// ended.
    fn tick(&mut self, t: &TickRecord) {
        let at = t.sample_time_ns;
        let safety = SafetyFlags {
            bits: t.safety_bits,
        };
        let (last_safety, last_faults) = self.last.unwrap_or_default();
        for (rule, on) in last_safety.edges(safety) {
            let (level, what) = if on {
                (Level::Warning, "acting")
            } else {
                (Level::Info, "no longer acting")
            };
            self.event(at, level, "safety", format!("{rule}: {what}"));
        }
        if t.device_faults > last_faults {
            self.event(
                at,
                Level::Error,
                "device",
                format!("device fault ({} so far): forces off", t.device_faults),
            );
        }
        self.last = Some((safety, t.device_faults));
        if let Some((p, received)) = &t.parameters {
            let rec = ParametersRec::new(t.session, p, Some(*received));
            self.push(at, Message::Parameters(Side::Operator, Box::new(rec)));
        }
        if let Some((c, received)) = &t.contact {
            let rec = ContactRec::new(t.session, c, Some(*received));
            self.push(at, Message::Contact(Side::Operator, Box::new(rec)));
        }
        if let Some((s, received)) = &t.state_sync {
            let rec = StateSyncRec::new(t.session, s, Some(*received));
            self.push(at, Message::StateSync(Side::Operator, Box::new(rec)));
        }
        let tick = OperatorTick {
            session: t.session,
            index: t.index,
            sample_time_ns: t.sample_time_ns,
            started_ns: t.started_ns,
            device_position_m: t.device_m[0],
            device_velocity_m_per_s: t.device_m[1],
            command_position_m: t.position_m,
            command_velocity_m_per_s: t.velocity_m_per_s,
            force_rendered_n: t.force_n,
            force_device_n: t.force_device_n,
            in_contact: t.in_contact,
            rendering: t.rendering,
            reduced: t.reduced,
            proxy_m: t.proxy_m,
            safety,
            device_faults: t.device_faults,
            ..OperatorTick::default()
        };
        self.push(at, Message::OperatorTick(Box::new(tick)));
    }

    /// The link statistics, every [`LINK_EVERY`].
    fn link(&mut self, link: &OperatorLink) {
        if self.link_due.elapsed() < LINK_EVERY {
            return;
        }
        self.link_due = std::time::Instant::now();
        let status = link.status();
        let rec = LinkRec::new(status.connected(), status.session(), &link.stats());
        self.push(
            rt::monotonic_ns(),
            Message::Link(Side::Operator, Box::new(rec)),
        );
    }

    fn flush(&mut self) {
        if !self.batch.is_empty() {
            self.sink.send(std::mem::take(&mut self.batch));
        }
    }
}

mod tap;
use tap::TapRound;
pub use tap::{Tap, Tapped};

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn the_ab_halves_are_counted_from_the_first_toggle_on() {
        let mut ab = AbWindow::default();
        // The start-up, recording: in neither half.
        assert!(!ab.counting(false));
        assert!(!ab.counting(false));
        // Paused, then recording again: counted from the first change on, whatever follows.
        assert!(ab.counting(true));
        assert!(ab.counting(true));
        assert!(ab.counting(false));
        // Never toggled (a recorder without --record-ab-s): never counted.
        let mut never = AbWindow::default();
        assert!((0..10).all(|_| !never.counting(false)));
    }

    /// A square grid of `n × n` points of spacing `s` [m] on `z = 0`.
    fn grid(n: usize, s: f32) -> Vec<[f32; 3]> {
        (0..n)
            .flat_map(|i| (0..n).map(move |j| [i as f32 * s, j as f32 * s, 0.0]))
            .collect()
    }

    fn exp1() -> SceneSummary {
        sim::scene::Scene::exp1().summary()
    }

    /// Issue 11, finding 5 on the operator side: a peer's million-point frame (0.25 mm) no
    /// longer reaches the haptic loop's proxy unreduced.
    #[test]
    fn a_peer_frame_over_the_budget_is_downsampled_and_counted() {
        let mut guard = CloudGuard::default();
        let mut small = grid(56, 0.0045);
        assert!(guard.hold(&mut small, Some(&exp1()), 1));
        assert_eq!((small.len(), guard.counts), (3_136, (0, 0)));
        let mut big = grid(1_001, 0.00025);
        assert!(guard.hold(&mut big, Some(&exp1()), 1));
        assert_eq!(guard.counts, (1, 0));
        let b = CloudBudget::default();
        assert!(big.len() <= b.max_points(None), "{}", big.len());
        let proxy = OperatorSettings::from_welcome(&exp1()).unwrap().proxy;
        let r = mmt::contact::budget::query_radius_m(&proxy);
        let ball = mmt::contact::budget::points_in_ball(&big, r).unwrap();
        assert!(ball <= b.max_points_in_ball(&proxy), "{ball}");
    }

    #[test]
    fn a_peer_frame_that_cannot_fit_is_refused_and_counted() {
        // Default radii (slip spacing 2.83 mm) but r3 = 0.1 m: a solid 78 mm block at 2 mm
        // lies within one query ball and no voxel the proxy cannot slip through brings it in.
        let mut scene = exp1();
        scene.proxy_radii_m = [0.001, 0.003, 0.1];
        let mut block: Vec<[f32; 3]> = (0..64_000)
            .map(|k| [k % 40, k / 40 % 40, k / 1_600].map(|v| v as f32 * 0.002))
            .collect();
        let mut guard = CloudGuard::default();
        assert!(!guard.hold(&mut block, Some(&scene), 1));
        assert_eq!(guard.counts, (0, 1));
        // NaN points from a peer (the wire checks them, but the guard must not panic).
        let mut nan = vec![[f32::NAN, 0.0, 0.0]; 4];
        assert!(!guard.hold(&mut nan, None, 1));
        assert_eq!(guard.counts, (0, 2));
    }

    #[test]
    fn a_session_first_frame_is_held_as_static_and_the_next_at_the_cloud_rate() {
        // 0.25 m at 1 mm (63,000 points, under the step limit of the wide plane's 61 mm query
        // ball): indexed once it fits, at 30 Hz it does not.
        let frame = grid(251, 0.001);
        let mut guard = CloudGuard::default();
        let mut first = frame.clone();
        assert!(guard.hold(&mut first, Some(&exp1()), 3));
        assert_eq!((first.len(), guard.counts), (frame.len(), (0, 0)));
        let mut next = frame.clone();
        assert!(guard.hold(&mut next, Some(&exp1()), 3));
        assert_eq!(guard.counts, (1, 0));
        assert!(next.len() <= CloudBudget::default().max_points(Some(30.0)));
        // A new session starts again from a static first frame.
        let mut other = frame.clone();
        assert!(guard.hold(&mut other, Some(&exp1()), 4));
        assert_eq!((other.len(), guard.counts), (frame.len(), (1, 0)));
    }
}
