//! The daemon's recording (`--record`, `--live`): the housekeeping thread's part — the loop's
//! tick records in, batches of recorded messages out, with the link statistics and the session
//! events — and the run's `/run` and `/run/end`. The camera thread hands the recorder its frames
//! itself ([`crate::camera`]).

use std::sync::Arc;

use record::schema::{
    ContactRec, EventRec, Level, LinkRec, ParametersRec, RunEnd, RunStart, StateSyncRec,
    TelerobotTick,
};
use record::{Message, RecordSink, Side, Timed};
use rt::monotonic_ns;
use transport::Mailbox;

use crate::control::TickRecord;
use crate::daemon::{RunConfig, Summary};
use crate::net::TelerobotLink;

/// The recording's part of the housekeeping: the loop's tick records in, batches out.
pub(crate) struct Forward {
    sink: RecordSink,
    ticks: Arc<Mailbox<TickRecord>>,
    batch: Vec<Timed>,
    /// The session of the last tick (a change is an event).
    session: u64,
    /// When the link statistics are next due [ns].
    link_due: i64,
}

/// How often the link statistics go to the recording [ns].
const LINK_EVERY_NS: i64 = 100_000_000;

/// The loop's tick records' mailbox (`capacity` records), while the daemon records.
pub(crate) fn tick_mailbox(
    record: Option<&RecordSink>,
    capacity: usize,
) -> Option<Arc<Mailbox<TickRecord>>> {
    record.map(|_| Arc::new(Mailbox::new(capacity)))
}

/// Records the daemon's `/run`, while it records.
pub(crate) fn record_start(config: &RunConfig, start_ns: i64, period_ns: i64) {
    if let Some(sink) = &config.record {
        let start = run_start(config, start_ns, period_ns);
        sink.send_one(start_ns, Message::Run(Box::new(start)));
    }
}

/// Records the daemon's `/run/end`: its summary, and what its node knew.
pub(crate) fn record_end(sink: &RecordSink, ticks: u64, summary: &Summary) {
    let nodes = metrics::NodeInfo {
        parameters: summary.parameters.clone(),
        telerobot: summary.last.node,
        ..metrics::NodeInfo::default()
    };
    let end = RunEnd {
        side: Side::Telerobot,
        ticks,
        nodes: Some(nodes),
        frame: None,
        final_offset_ns: None,
        counters: serde_json::to_value(summary).ok(),
        recorder_dropped: sink.dropped(),
    };
    sink.send_one(monotonic_ns(), Message::RunEnd(Box::new(end)));
}

/// The daemon's `/run`.
fn run_start(config: &RunConfig, start_ns: i64, period_ns: i64) -> RunStart {
    let summary = config.scene_summary();
    let frame = mmt::contact::SurfaceFrame::from_normal(config.scene.surface.normal);
    RunStart {
        side: Side::Telerobot,
        experiment: "telerobot".to_owned(),
        start_ns,
        period_ns,
        scene_name: summary.name,
        left_out: summary.left_out,
        proxy_radii_m: summary.proxy_radii_m,
        device: None,
        seed: Some(config.seed),
        set_delay_ms: None,
        scene: Some(config.scene.clone()),
        config: None,
        axes: frame.map(|f| [f.tangent2, f.normal]),
        tool_start_m: Some(config.start_m),
    }
}

impl Forward {
    /// Forwards what `ticks` receives to `sink`.
    pub(crate) fn new((sink, ticks): (RecordSink, Arc<Mailbox<TickRecord>>)) -> Forward {
        Forward {
            sink,
            ticks,
            batch: Vec::new(),
            session: 0,
            link_due: monotonic_ns(),
        }
    }

    /// Hands what came since the last round to the recorder.
    pub(crate) fn round(&mut self, link: &TelerobotLink) {
        let paused = self.sink.is_paused();
        while let Some(t) = self.ticks.take() {
            if !paused {
                self.tick(&t);
            }
        }
        if paused {
            return;
        }
        let now = monotonic_ns();
        if now >= self.link_due {
            self.link_due = now + LINK_EVERY_NS;
            let status = link.status();
            let rec = LinkRec::new(status.connected(), status.session(), &link.stats());
            self.push(now, Message::Link(Side::Telerobot, Box::new(rec)));
        }
        if !self.batch.is_empty() {
            self.sink.send(std::mem::take(&mut self.batch));
        }
    }

    /// The motion guard's and the robot's events (`source` "guard"), at `t_ns`.
    pub(crate) fn events(&mut self, t_ns: i64, events: Vec<(Level, String)>) {
        if self.sink.is_paused() {
            return;
        }
        for (level, text) in events {
            let rec = EventRec {
                level,
                source: "guard",
                text,
            };
            self.push(t_ns, Message::Event(rec));
        }
    }

    fn push(&mut self, t_ns: i64, message: Message) {
        self.batch.push(Timed { t_ns, message });
    }

    fn tick(&mut self, t: &TickRecord) {
        let at = t.now_ns;
        if t.session != self.session {
            self.session = t.session;
            let text = format!("session {}: an operator's commands arrive", t.session);
            self.push(
                at,
                Message::Event(EventRec {
                    level: Level::Info,
                    source: "session",
                    text,
                }),
            );
        }
        let tick = TelerobotTick::new(
            t.session,
            t.index,
            at,
            &t.target,
            &t.sample,
            t.cloud_captured_ns,
            t.measurement.as_ref(),
            &t.estimators,
        );
        self.push(at, Message::TelerobotTick(Box::new(tick)));
        if let Some(c) = &t.contact {
            let rec = ContactRec::new(t.session, c, None);
            self.push(at, Message::Contact(Side::Telerobot, Box::new(rec)));
        }
        if let Some(p) = &t.parameters {
            let rec = ParametersRec::new(t.session, p, None);
            self.push(at, Message::Parameters(Side::Telerobot, Box::new(rec)));
        }
        if let Some(s) = &t.state_sync {
            let rec = StateSyncRec::new(t.session, s, None);
            self.push(at, Message::StateSync(Side::Telerobot, Box::new(rec)));
        }
    }
}
