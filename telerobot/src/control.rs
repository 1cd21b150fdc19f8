//! The telerobot's 1 kHz loop: steps `mmt`'s telerobot node exactly as the in-process harness
//! does (`lab::experiment`), against the robot bridge, on its own OS thread.
//!
//! Per tick (at the tick's nominal time `now`):
//! 1. every command queued since the last tick goes to the node (its playout buffer orders them);
//!    a command of a newer session swaps in a fresh node (new operator, new clock, new model);
//! 2. the newest camera index, if any, is installed ([`crate::camera`] builds it off this thread,
//!    and drops the one it replaces);
//! 3. the node says where the robot goes (the command whose turn it is, or hold still when the
//!    newest command is older than 50 ms); the motion guard bounds it (`node::guard`: nothing
//!    before the robot's first state, hold on a state older than 50 ms, workspace box, step,
//!    speed; a reading not finite is a fault, the bridge recovers), whatever the bridge; the
//!    bridge moves and measures;
//! 4. the node steps with a new measurement, at the measurement's own time (a simulator's is
//!    the tick; a ROS 2 robot's its header stamp; a tick that brought none, or a stale state,
//!    steps nothing); its messages go to the network task's outbox while an operator is
//!    connected;
//! 5. every 10 ticks a [`LoopSnapshot`] goes to the housekeeping thread; with `--record` or
//!    `--live`, every tick a [`TickRecord`] too (plain values: the recording is written there).
//!
//! Nothing here allocates, frees, locks or logs: commands, indices, snapshots, tick records and
//! datagrams move through the lock-free [`transport::Mailbox`]es; fresh nodes are built, and old
//! ones dropped, by the housekeeping thread ([`Spares`]).

use std::sync::Arc;

use mmt::estimator::EstimatorStats;
use node::telerobot::{CommandSample, TelerobotNode, TelerobotStats};
use node::{BridgeSample, GuardStats, Guarded, Reading, RobotBridge, Target, TelerobotSettings};
use protocol::telerobot_to_operator::{
    Contact, ContactState, Datagram, Measurement, Parameters, StateSync,
};
use record::schema::EstimatorSnapshot;
use rt::{Periodic, Shutdown, Tick};
use transport::Mailbox;

use crate::camera::{CameraFeed, CameraPose};
use crate::net::TelerobotLink;

/// Ticks between two [`LoopSnapshot`]s.
const SNAPSHOT_EVERY: u64 = 10;

/// What the loop looks like, published every [`SNAPSHOT_EVERY`] ticks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoopSnapshot {
    /// Tick number.
    pub tick: u64,
    /// The tick's time [ns, `monotonic_ns`].
    pub now_ns: i64,
    /// The session whose commands the node executes (0 before the first command).
    pub session: u64,
    /// The robot holds still (no command fresher than the timeout).
    pub holding: bool,
    /// Tool position \[m\].
    pub tool_m: [f64; 3],
    /// The node's counters (this session's node).
    pub node: TelerobotStats,
    /// The node's estimators are all confident.
    pub stable: bool,
    /// Nodes built on the loop thread because no spare was ready (should stay 0).
    pub inline_node_builds: u64,
    /// The motion guard's counters, since the daemon started (every session).
    pub guard: GuardStats,
    /// Ticks whose bridge sample was new (the node stepped).
    pub fresh_samples: u64,
    /// The node's estimators' counters (normal, tangential; this session's node).
    pub estimators: (Option<EstimatorStats>, Option<EstimatorStats>),
}

/// Tick records the housekeeping thread may lag behind by: 8 s at 1 kHz.
pub const TICK_QUEUE: usize = 8192;

/// What one tick did, for the recording: plain values (pushing one allocates nothing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TickRecord {
    /// Tick number.
    pub index: u64,
    /// The tick's nominal time [ns].
    pub now_ns: i64,
    /// The session whose commands run.
    pub session: u64,
    /// Where the robot was sent.
    pub target: Target,
    /// What the bridge gave.
    pub sample: BridgeSample,
    /// Capture time of the camera frame installed this tick [ns].
    pub cloud_captured_ns: Option<i64>,
    /// The node's datagrams of the tick.
    pub contact: Option<Contact>,
    /// The measurement datagram.
    pub measurement: Option<Measurement>,
    /// The parameters datagram, when one was sent.
    pub parameters: Option<Parameters>,
    /// The state-sync datagram, when one was sent.
    pub state_sync: Option<StateSync>,
    /// The estimators, `[normal, tangential]`.
    pub estimators: [Option<EstimatorSnapshot>; 2],
}

/// Fresh nodes for new sessions, and old nodes to drop, exchanged with the housekeeping thread.
pub struct Spares {
    /// A node built off the loop thread at the robot's current position.
    pub spare: Mailbox<Box<TelerobotNode>>,
    /// Nodes the loop replaced, to be dropped off the loop thread.
    pub retired: Mailbox<Box<TelerobotNode>>,
}

impl Default for Spares {
    fn default() -> Self {
        Spares {
            spare: Mailbox::latest(),
            retired: Mailbox::new(4),
        }
    }
}

/// What the loop needs.
pub(crate) struct ControlLoop {
    pub(crate) node: Box<TelerobotNode>,
    pub(crate) settings: TelerobotSettings,
    /// The robot, behind the motion guard (`node::guard`).
    pub(crate) bridge: Guarded<Box<dyn RobotBridge>>,
    /// Where the model and contact state are published besides the operator (a ROS 2 robot's
    /// `/mmt/theta` and `/mmt/in_contact`).
    pub(crate) outlet: Option<ros2::ModelOutlet>,
    pub(crate) link: TelerobotLink,
    pub(crate) camera: Arc<CameraFeed>,
    pub(crate) spares: Arc<Spares>,
    pub(crate) snapshots: Arc<Mailbox<LoopSnapshot>>,
    /// Command receipt − command sample time \[ns\] (one host: the uplink's one-way latency), to
    /// the housekeeping thread.
    pub(crate) command_latency: Arc<Mailbox<i64>>,
    /// Every tick's record, to the housekeeping thread, while the run records.
    pub(crate) records: Option<Arc<Mailbox<TickRecord>>>,
    pub(crate) shutdown: Shutdown,
}

/// What the loop hands back when it stops.
pub(crate) struct LoopEnd {
    pub(crate) node: Box<TelerobotNode>,
    pub(crate) last: LoopSnapshot,
}

impl ControlLoop {
    /// Runs until the shutdown signal.
    pub(crate) fn run(mut self, mut periodic: Periodic) -> LoopEnd {
        let mut state = State::default();
        loop {
            // Idle while no operator is connected: the same ticks (the robot is read and held),
            // without the spin before each (issue 11: 10 % of a core for nobody). The session's
            // status flips with the Welcome, before its first command.
            periodic.set_idle(!self.link.status().connected());
            let tick = periodic.wait();
            if self.shutdown.is_triggered() {
                break;
            }
            self.tick(tick, &mut state);
        }
        LoopEnd {
            last: state.snapshot(&self.node, self.bridge.stats()),
            node: self.node,
        }
    }

    fn tick(&mut self, tick: Tick, state: &mut State) {
        let now = tick.deadline_ns;
        while let Some(c) = self.link.next_command() {
            if c.session < state.session {
                continue; // left over from an earlier session
            }
            if c.session > state.session {
                if state.session != 0 {
                    self.fresh_node(state);
                }
                // Whatever the last session left: a robot not finite is recovered and reported.
                self.bridge.begin_session();
                state.session = c.session;
            }
            let header = c.message.header;
            self.command_latency
                .push(c.received_ns - header.sample_time_ns);
            self.node.on_command(CommandSample {
                sample_time_ns: header.sample_time_ns,
                position_m: c.message.position_m,
                velocity_m_per_s: c.message.velocity_m_per_s,
                received_ns: c.received_ns,
            });
        }
        let cloud_captured_ns = install_cloud(&self.camera, &mut self.node);
        let wanted = self.bridge.tool_m().map(|tool| self.node.target(now, tool));
        let sample = self.bridge.step(now, wanted.as_ref());
        let target = self.bridge.commanded().copied();
        self.camera.pose.push(CameraPose {
            now_ns: now,
            tool_m: sample.tool_m,
            object_offset_m: sample.object_slide_m,
        });
        let command_ns = target.map_or(0, |t| t.command_sample_time_ns);
        self.use_sample(now, command_ns, &sample, state);
        while let Some(more) = self.bridge.next_reading() {
            self.use_sample(now, command_ns, &more, state);
        }
        if let Some(records) = &self.records {
            records.push(tick_record(
                &self.node,
                [tick.index, state.session],
                now,
                // No target (no robot state yet): recorded as holding where the tool is.
                target.unwrap_or(Target {
                    position_m: sample.tool_m,
                    velocity_m_per_s: [0.0; 3],
                    command_sample_time_ns: 0,
                    holding: true,
                }),
                sample,
                cloud_captured_ns,
            ));
        }
        state.tick = tick.index;
        state.now_ns = now;
        state.holding = target.is_none_or(|t| t.holding);
        if let Some(tool) = self.bridge.tool_m() {
            state.tool_m = tool;
        }
        if tick.index.is_multiple_of(SNAPSHOT_EVERY) {
            self.snapshots
                .push(state.snapshot(&self.node, self.bridge.stats()));
        }
    }

    /// Steps the node with a new sample, at the sample's own time; a repeated one, or none, steps
    /// nothing.
    fn use_sample(
        &mut self,
        now: i64,
        command_ns: i64,
        sample: &node::BridgeSample,
        state: &mut State,
    ) {
        let (sample_ns, command_ns) = match sample.reading {
            Reading::ThisTick => (now, command_ns),
            Reading::Stamped {
                sample_time_ns,
                command_sample_time_ns,
            } => (sample_time_ns, command_sample_time_ns),
            Reading::Repeated | Reading::Nothing => return,
        };
        // A stale state is not estimated from (the guard holds the robot meanwhile).
        if self.bridge.state_is_stale(now) {
            return;
        }
        state.fresh_samples += 1;
        let connected = self.link.status().connected();
        let datagrams = self.node.step(sample_ns, command_ns, &sample.measured);
        for d in datagrams {
            if let Some(outlet) = self.outlet.as_mut() {
                match d {
                    Datagram::Parameters(p) => outlet.parameters(p),
                    Datagram::Contact(c) => outlet.contact(c.state != ContactState::Free),
                    _ => {}
                }
            }
            if connected {
                self.link.send(*d);
            }
        }
    }

    /// Swaps in the spare node (built off this thread); the old one goes back to be dropped.
    fn fresh_node(&mut self, state: &mut State) {
        let fresh = match self.spares.spare.take() {
            Some(node) => node,
            None => {
                // No spare ready (sessions changing faster than the housekeeping thread builds
                // them): build one here, once per session change, and count it.
                state.inline_node_builds += 1;
                let at = self.bridge.tool_m().unwrap_or(state.tool_m);
                match TelerobotNode::new(self.settings.clone(), at) {
                    Ok(node) => Box::new(node),
                    Err(_) => return, // the settings built the first node: cannot happen
                }
            }
        };
        let mut old = std::mem::replace(&mut self.node, fresh);
        // The robot did not move between the sessions: the proxy that followed it still knows
        // which side of the surface it is on; one started where it rests may not.
        self.node.take_over_geometry(&mut old);
        self.spares.retired.push(old);
    }
}

/// The loop's own bookkeeping.
#[derive(Debug, Default)]
struct State {
    tick: u64,
    now_ns: i64,
    session: u64,
    holding: bool,
    tool_m: [f64; 3],
    inline_node_builds: u64,
    fresh_samples: u64,
}

impl State {
    fn snapshot(&self, node: &TelerobotNode, guard: GuardStats) -> LoopSnapshot {
        LoopSnapshot {
            tick: self.tick,
            now_ns: self.now_ns,
            session: self.session,
            holding: self.holding,
            tool_m: self.tool_m,
            node: node.stats(),
            stable: node.is_stable(),
            inline_node_builds: self.inline_node_builds,
            guard,
            fresh_samples: self.fresh_samples,
            estimators: node.estimator_stats(),
        }
    }
}

/// Installs the camera's newest index, if one came, and returns its capture time [ns]; the index
/// it replaces goes back to the camera thread to be dropped: the loop may hold its last
/// reference, and dropping that would free a kd-tree on the loop.
fn install_cloud(camera: &CameraFeed, node: &mut TelerobotNode) -> Option<i64> {
    let (frame_id, index) = camera.index.take()?;
    let captured_ns = index.timestamp_ns();
    if let Some(old) = node.set_cloud(index, frame_id) {
        camera.retired.push(old);
    }
    Some(captured_ns)
}

/// This tick's record for the recording: plain values, built on the stack.
fn tick_record(
    node: &TelerobotNode,
    [index, session]: [u64; 2],
    now_ns: i64,
    target: Target,
    sample: BridgeSample,
    cloud_captured_ns: Option<i64>,
) -> TickRecord {
    let mut record = TickRecord {
        index,
        now_ns,
        session,
        target,
        sample,
        cloud_captured_ns,
        contact: None,
        measurement: None,
        parameters: None,
        state_sync: None,
        estimators: [None; 2],
    };
    for d in node.datagrams() {
        match *d {
            Datagram::Contact(c) => record.contact = Some(c),
            Datagram::Measurement(m) => record.measurement = Some(m),
            Datagram::Parameters(p) => record.parameters = Some(p),
            Datagram::StateSync(s) => record.state_sync = Some(s),
        }
    }
    let [normal, tangential] = node.updates();
    record.estimators = [
        normal.zip(node.normal_estimator()),
        tangential.zip(node.tangential_estimator()),
    ]
    .map(|e| e.map(|(u, est)| EstimatorSnapshot::of(est, u)));
    record
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CI (stop 27): the camera thread kept the last four indices alive, but when it published
    /// four more while the loop held one (a stalled loop), the loop's next install dropped that
    /// one's last reference and freed it on the loop. Now the loop hands back every index it
    /// replaces, whoever else still holds it.
    #[test]
    fn the_loop_hands_back_every_cloud_index_it_replaces() {
        let settings = sim::scene::Scene::exp1().telerobot_settings();
        let mut node = TelerobotNode::new(settings, [0.0, 0.0, 0.01]).unwrap();
        let camera = CameraFeed::default();
        assert_eq!(install_cloud(&camera, &mut node), None);
        let first = mmt::testutil::plane_index(10, 7);
        let weak = Arc::downgrade(&first);
        camera.index.push((1, first));
        assert_eq!(install_cloud(&camera, &mut node), Some(7));
        assert!(camera.retired.is_empty());
        assert_eq!(weak.strong_count(), 1, "the node holds the last reference");
        camera.index.push((2, mmt::testutil::plane_index(11, 9)));
        assert_eq!(install_cloud(&camera, &mut node), Some(9));
        assert_eq!(weak.strong_count(), 1, "not dropped on the loop");
        assert_eq!(camera.retired.len(), 1);
        while camera.retired.take().is_some() {}
        assert_eq!(weak.strong_count(), 0);
    }
}
