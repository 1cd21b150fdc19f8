//! The operator's 1 kHz haptic loop: device → operator node → safety layer → device force, and
//! the command out. It steps `mmt`'s operator node exactly as the in-process harness does
//! (`lab::experiment`), on its own OS thread.
//!
//! Per tick (tick `k`, nominal time `now = start + k·period`; the node's time is always nominal,
//! the device's and the safety layer's is the tick's actual start):
//! 1. a fresh node prepared for a new session (a reconnect: new `Welcome`, new model) is swapped
//!    in, the old one handed back to be dropped off this thread;
//! 2. the newest `Parameters`, `Contact` and `StateSync` of this session go to the node
//!    (latest-value slots, lock-free); the newest cloud index (built by the helper thread);
//! 3. the device is read; the safety layer maps its position (the device's clutch input, the
//!    position scale) — [`sample_device`];
//! 4. the node renders the force from its local model and makes the command — with the link
//!    stalled it keeps rendering from the last model it has;
//! 5. the safety layer shapes the force (saturation, workspace, watchdog, rate) for `servo_cf`;
//! 6. the command goes to the network task while a session is open; a [`TickRecord`] goes to the
//!    helper thread for the report and, with `--record`/`--live`, the recording (the record
//!    carries the messages the tick took, so the recording needs no second path to the loop).
//!
//! Nothing here allocates, frees, locks or logs per tick (the safety layer and the device log one
//! event when a rule starts or stops acting, or the device faults).

use std::sync::Arc;
use std::time::Duration;

use mmt::contact::CloudIndex;
use mmt::render::RendererStats;
use node::operator::{OperatorNode, OperatorStats};
use protocol::telerobot_to_operator::{Contact, Message, Parameters, StateSync, SurfaceFrame};
use rt::{Periodic, Shutdown, Tick};
use transport::Mailbox;

use crate::device::{ForceRecord, HapticDevice};
use crate::net::OperatorLink;
use crate::safety::{ForceTick, Model, SafetyLayer, SafetyStats};
use mmt::vec3::Vec3;

/// Tick records the helper thread may lag behind by: 8 s at 1 kHz.
pub const TICK_QUEUE: usize = 8192;

/// Cloud indices the loop may retire between two helper rounds. The loop retires one for each
/// index it takes, and the helper hands over at most one a round, after draining these: at
/// most a couple wait at any time. A push into a full queue would drop, and free, on the loop.
const RETIRED_CLOUDS: usize = 8;

/// What one tick did, for the report and the recording (by tick number). Plain values: pushing
/// one allocates nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TickRecord {
    /// Tick number (the command's sample time is `start + index·period`).
    pub index: u64,
    /// The session whose node ran the tick.
    pub session: u64,
    /// The tick's nominal time, the command's sample time [ns, `rt::monotonic_ns`].
    pub sample_time_ns: i64,
    /// When the tick actually started [ns].
    pub started_ns: i64,
    /// The device's measured position \[m\] (device coordinates) and velocity \[m/s\].
    pub device_m: [[f64; 3]; 2],
    /// Position handed to the node (the command) \[m\], world frame.
    pub position_m: [f64; 3],
    /// Velocity handed to the node \[m/s\].
    pub velocity_m_per_s: [f64; 3],
    /// The node's force \[N\]: what the model renders, before the safety layer.
    pub force_n: [f64; 3],
    /// The force written to the device \[N\], after the safety layer.
    pub force_device_n: [f64; 3],
    /// The node is in contact.
    pub in_contact: bool,
    /// The node renders a model.
    pub rendering: bool,
    /// The model rendered is the telerobot's reduced first model (massless), not the whole
    /// structure.
    pub reduced: bool,
    /// The node's local proxy \[m\], while it runs.
    pub proxy_m: Option<[f64; 3]>,
    /// The safety rules acting (`SafetyLayer::active_bits`).
    pub safety_bits: u32,
    /// Device faults so far.
    pub device_faults: u64,
    /// The parameters the tick took, with their arrival time [ns].
    pub parameters: Option<(Parameters, i64)>,
    /// The telerobot contact state the tick took, with its arrival time [ns].
    pub contact: Option<(Contact, i64)>,
    /// The state sync the tick took, with its arrival time [ns].
    pub state_sync: Option<(StateSync, i64)>,
}

/// What the haptic loop exchanges with the helper thread (all lock-free).
pub struct Exchange {
    /// Helper → loop: `(session, index)` of the newest received cloud.
    pub clouds: Mailbox<(u64, Arc<CloudIndex>)>,
    /// Helper → loop: a node for a newer session.
    pub spare: Mailbox<(u64, Box<OperatorNode>)>,
    /// Loop → helper: nodes replaced, to drop.
    pub retired: Mailbox<Box<OperatorNode>>,
    /// Loop → helper: cloud indices replaced (or of an old session), to drop: the loop may hold
    /// an index's last reference, and dropping that frees it.
    pub retired_clouds: Mailbox<Arc<CloudIndex>>,
    /// Loop → helper: one record per tick.
    pub ticks: Mailbox<TickRecord>,
}

impl Default for Exchange {
    fn default() -> Self {
        Exchange {
            clouds: Mailbox::latest(),
            spare: Mailbox::latest(),
            retired: Mailbox::new(4),
            retired_clouds: Mailbox::new(RETIRED_CLOUDS),
            ticks: Mailbox::new(TICK_QUEUE),
        }
    }
}

/// The loop's parts.
pub(crate) struct HapticLoop {
    pub(crate) node: Box<OperatorNode>,
    /// The session the node belongs to.
    pub(crate) session: u64,
    pub(crate) device: Box<dyn HapticDevice>,
    pub(crate) safety: SafetyLayer,
    pub(crate) link: OperatorLink,
    pub(crate) exchange: Arc<Exchange>,
    pub(crate) shutdown: Shutdown,
    /// Stop after this many ticks (`--seconds`), or at the shutdown signal.
    pub(crate) ticks: Option<u64>,
}

/// What the loop hands back when it stops.
pub struct LoopEnd {
    /// The device (closed: disabled, its backend's report final).
    pub device: Box<dyn HapticDevice>,
    /// What the safety layer did.
    pub safety: SafetyStats,
    /// The forces written to the device.
    pub force_record: ForceRecord,
    /// The last node's counters.
    pub node: OperatorStats,
    /// The last node's renderer counters: the normal axis first (if the model has one), then
    /// each rendered tangential axis.
    pub renderers: Vec<RendererStats>,
    /// Ticks run (the last tick's number + 1).
    pub ticks: u64,
    /// The newest surface frame the telerobot reported (the report's axes).
    pub frame: Option<SurfaceFrame>,
    /// The newest parameters received.
    pub parameters: Option<Parameters>,
    /// Sessions whose node the loop ran.
    pub sessions: u64,
    /// The last node's prior (what it renders before its first model).
    pub prior: Option<mmt::model::prior::Prior>,
}

impl HapticLoop {
    /// Runs until the tick budget or the shutdown signal.
    pub(crate) fn run(mut self, mut periodic: Periodic) -> LoopEnd {
        let start_ns = periodic.start_ns();
        let mut state = State {
            start_ns,
            last_params_ns: None,
            frame: None,
            parameters: None,
            sessions: 1,
            ticks: 0,
        };
        if let Err(e) = self.device.enable(Duration::ZERO) {
            tracing::error!("cannot enable the device: {e}; forces stay off");
        }
        loop {
            let tick = periodic.wait();
            if self.shutdown.is_triggered() || self.ticks.is_some_and(|n| tick.index >= n) {
                break;
            }
            self.tick(tick, &mut state);
            state.ticks = tick.index + 1;
        }
        let end = Duration::from_nanos(u64::try_from(rt::monotonic_ns() - start_ns).unwrap_or(0));
        // Closed before the report is built: a backend's last counts (its closing zero
        // included) are in it.
        if let Err(e) = self.device.close(end) {
            tracing::warn!("disabling the device: {e}");
        }
        LoopEnd {
            safety: self.safety.stats(),
            force_record: *self.device.force_record(),
            node: self.node.stats(),
            prior: self.node.prior(),
            renderers: self.node.renderer_stats(),
            device: self.device,
            ticks: state.ticks,
            frame: state.frame,
            parameters: state.parameters,
            sessions: state.sessions,
        }
    }

    fn tick(&mut self, tick: Tick, state: &mut State) {
        // The tick's time is when it ran, not its deadline: the device is read now, and a command
        // must carry the time its position was read. After a stall the loop catches up several
        // ticks within microseconds; stamped with their deadlines, they would give the telerobot
        // a path that holds for the stall and then jumps (its estimator took that for a new
        // object), though the hand moved smoothly.
        let now = tick.started_ns;
        let actual =
            Duration::from_nanos(u64::try_from(tick.started_ns - state.start_ns).unwrap_or(0));
        if let Some((session, node)) = self.exchange.spare.take() {
            if session > self.session {
                let old = std::mem::replace(&mut self.node, node);
                self.exchange.retired.push(old);
                self.session = session;
                state.last_params_ns = None;
                state.sessions += 1;
            } else {
                // Dropped by the helper, like every node the loop lets go.
                self.exchange.retired.push(node);
            }
        }
        let mut record = TickRecord {
            index: tick.index,
            session: self.session,
            sample_time_ns: now,
            started_ns: tick.started_ns,
            ..TickRecord::default()
        };
        self.take_messages(now, state, &mut record);
        install_cloud(&self.exchange, &mut self.node, self.session);
        let Sample {
            measured_cp: measured,
            measured_cv,
            position,
            velocity,
        } = sample_device(self.device.as_mut(), &mut self.safety, actual);
        let out = self.node.step(now, position, velocity);
        let force = self.safety.filter_force(&ForceTick {
            now: actual,
            measured_cp: measured,
            model: model_age(out.rendering, state.last_params_ns, tick.started_ns),
            force_n: out.force_n,
        });
        // A refused write faults the device, which then holds zero by itself.
        let _ = self.device.servo_cf(actual, force);
        if self.link.status().connected() {
            self.link.send_command(out.command);
        }
        self.exchange.ticks.push(TickRecord {
            device_m: [measured, measured_cv],
            position_m: position,
            velocity_m_per_s: velocity,
            force_n: out.force_n,
            force_device_n: force,
            in_contact: out.in_contact,
            rendering: out.rendering,
            reduced: out.reduced,
            proxy_m: self.node.proxy_m(),
            safety_bits: self.safety.active_bits(),
            device_faults: self.device.fault_count(),
            ..record
        });
    }

    /// Hands this session's newest network values to the node (and notes them in the record).
    fn take_messages(&mut self, now: i64, state: &mut State, record: &mut TickRecord) {
        let session = self.session;
        if let Some(p) = self.link.parameters().filter(|r| r.session == session) {
            state.last_params_ns = Some(p.received_ns);
            state.parameters = Some(p.message);
            record.parameters = Some((p.message, p.received_ns));
            self.node.on_message(&Message::Parameters(p.message), now);
        }
        if let Some(c) = self.link.contact().filter(|r| r.session == session) {
            if c.message.frame.is_some() {
                state.frame = c.message.frame;
            }
            record.contact = Some((c.message, c.received_ns));
            self.node.on_message(&Message::Contact(c.message), now);
        }
        if let Some(s) = self.link.state_sync().filter(|r| r.session == session) {
            record.state_sync = Some((s.message, s.received_ns));
            self.node.on_message(&Message::StateSync(s.message), now);
        }
    }
}

/// One tick's device sample, through the safety layer's position path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Sample {
    /// The device's measured position [m] (device coordinates), for the force path.
    pub(crate) measured_cp: Vec3,
    /// The device's measured velocity [m/s] (device coordinates).
    pub(crate) measured_cv: Vec3,
    /// The commanded position [m]: clutch and scale applied.
    pub(crate) position: Vec3,
    /// The commanded velocity [m/s]: scaled, zero while clutched.
    pub(crate) velocity: Vec3,
}

/// Reads the device at `now` and maps the reading through the safety layer: the device's clutch
/// input and the position scale; non-finite readings guarded. A device that fails faults itself
/// (forces off, logged once); the last reading is kept.
pub(crate) fn sample_device(
    device: &mut dyn HapticDevice,
    safety: &mut SafetyLayer,
    now: Duration,
) -> Sample {
    let _ = device.update(now);
    let measured_cp = device.measured_cp();
    let measured_cv = device.measured_cv();
    let position = safety.command_position(measured_cp, device.clutch());
    let velocity = safety.command_velocity(measured_cv);
    Sample {
        measured_cp,
        measured_cv,
        position,
        velocity,
    }
}

/// Installs the helper's newest cloud index, if one came for this `session`; the index it
/// replaces, or one of an old session, goes back to the helper to be dropped: the loop may hold
/// its last reference, and dropping that would free a kd-tree on the loop.
fn install_cloud(exchange: &Exchange, node: &mut OperatorNode, session: u64) {
    let Some((from, index)) = exchange.clouds.take() else {
        return;
    };
    let done = if from == session {
        node.set_cloud(index)
    } else {
        Some(index)
    };
    if let Some(done) = done {
        exchange.retired_clouds.push(done);
    }
}

/// What the parameter-age rule sees: a model only while the node renders one (before the first
/// parameters there is none, and nothing to be stale). Rendering without a known arrival time
/// cannot happen (the node renders only after parameters this loop handed it) and counts as
/// stale.
fn model_age(rendering: bool, last_params_ns: Option<i64>, now_ns: i64) -> Model {
    if !rendering {
        return Model::None;
    }
    let params_age = last_params_ns.map_or(Duration::MAX, |t| {
        Duration::from_nanos(u64::try_from(now_ns - t).unwrap_or(0))
    });
    Model::Rendering { params_age }
}

/// The loop's own bookkeeping.
struct State {
    start_ns: i64,
    last_params_ns: Option<i64>,
    frame: Option<SurfaceFrame>,
    parameters: Option<Parameters>,
    sessions: u64,
    ticks: u64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::device::{
        Backend, DeviceCapabilities, DeviceError, DeviceReading, ManagedConfig, ManagedDevice,
    };
    use crate::safety::SafetyConfig;

    /// Plays readings, one per `read`.
    struct Readings {
        caps: DeviceCapabilities,
        readings: std::vec::IntoIter<DeviceReading>,
    }

    impl Backend for Readings {
        fn capabilities(&self) -> &DeviceCapabilities {
            &self.caps
        }
        fn read(&mut self, _now: Duration) -> Result<DeviceReading, DeviceError> {
            Ok(self.readings.next().unwrap_or_default())
        }
        fn write_force(&mut self, _force_n: Vec3) -> Result<(), DeviceError> {
            Ok(())
        }
        fn set_force_enabled(&mut self, _on: bool) -> Result<(), DeviceError> {
            Ok(())
        }
    }

    fn device(readings: Vec<DeviceReading>) -> ManagedDevice<Readings> {
        let backend = Readings {
            caps: DeviceCapabilities::omega7("test"),
            readings: readings.into_iter(),
        };
        ManagedDevice::new(backend, ManagedConfig::default()).unwrap()
    }

    fn reading(x: f64, vx: f64, clutch: bool) -> DeviceReading {
        DeviceReading {
            position_m: [x, 0.0, 0.0],
            velocity_m_per_s: [vx, 0.0, 0.0],
            clutch,
        }
    }

    /// Regression: the loop always passed "not clutched" and never applied a scale other than 1.
    #[test]
    fn the_devices_clutch_and_the_position_scale_reach_the_command() {
        // The hand moves +x by 10 mm per tick at 0.1 m/s; the clutch is held on ticks 2 and 3.
        let clutch = [false, false, true, true, false, false];
        let readings = clutch
            .iter()
            .enumerate()
            .map(|(k, c)| reading(0.01 * k as f64, 0.1, *c))
            .collect();
        let mut dev = device(readings);
        let mut safety = SafetyLayer::new(
            dev.spec(),
            &SafetyConfig {
                position_scale: 2.0,
                ..SafetyConfig::default()
            },
        )
        .unwrap();
        let samples: Vec<Sample> = (0..clutch.len() as u64)
            .map(|k| sample_device(&mut dev, &mut safety, Duration::from_millis(k)))
            .collect();
        let x: Vec<f64> = samples.iter().map(|s| s.position[0]).collect();
        let vx: Vec<f64> = samples.iter().map(|s| s.velocity[0]).collect();
        let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-12);
        // Scaled ×2; held while clutched; after release it continues from the held position
        // (no jump), again at twice the hand's motion.
        assert!(close(&x, &[0.0, 0.02, 0.02, 0.02, 0.02, 0.04]), "{x:?}");
        assert!(close(&vx, &[0.2, 0.2, 0.0, 0.0, 0.2, 0.2]), "{vx:?}");
        assert_eq!(samples[3].measured_cp, [0.03, 0.0, 0.0]);
        assert_eq!(safety.stats().clutch.episodes, 1);
    }

    /// Regression: a non-finite velocity from the device went to the node unguarded.
    #[test]
    fn a_non_finite_velocity_from_the_device_is_zeroed_and_counted() {
        let mut dev = device(vec![
            reading(0.01, 0.1, false),
            reading(0.01, f64::NAN, false),
            reading(0.01, f64::INFINITY, false),
            reading(0.01, 0.1, false),
        ]);
        let mut safety = SafetyLayer::new(dev.spec(), &SafetyConfig::default()).unwrap();
        let vx: Vec<f64> = (0..4u64)
            .map(|k| sample_device(&mut dev, &mut safety, Duration::from_millis(k)).velocity[0])
            .collect();
        assert_eq!(vx, [0.1, 0.0, 0.0, 0.1]);
        let t = safety.stats().non_finite_velocity;
        assert_eq!((t.episodes, t.ticks), (1, 2));
    }

    /// CI (stop 27): the loop freed cloud indices while recording. The helper kept the last four
    /// alive, but when four more came while the loop held one (a stalled loop, or a burst after
    /// a stalled helper), the loop's next install dropped that one's last reference. Now every
    /// index the loop lets go reaches the helper, whoever else still holds it.
    #[test]
    fn the_loop_hands_back_every_cloud_index_it_lets_go() {
        let summary = sim::scene::Scene::exp1().summary();
        let settings = node::OperatorSettings::from_welcome(&summary).unwrap();
        let mut node = OperatorNode::new(
            settings,
            node::operator::OperatorConfig::default(),
            [0.0; 3],
        )
        .unwrap();
        let exchange = Exchange::default();
        let send = |session, half| {
            let index = mmt::testutil::plane_index(half, 0);
            let weak = Arc::downgrade(&index);
            exchange.clouds.push((session, index));
            weak
        };
        let first = send(1, 10);
        install_cloud(&exchange, &mut node, 1);
        assert!(exchange.retired_clouds.is_empty());
        // The helper's only reference went with the hand-over: the node holds the last one.
        assert_eq!(first.strong_count(), 1);
        let second = send(1, 11);
        install_cloud(&exchange, &mut node, 1);
        let old_session = send(0, 12);
        install_cloud(&exchange, &mut node, 1);
        // Neither was dropped on the loop: both wait for the helper, which drops them.
        assert_eq!(exchange.retired_clouds.len(), 2);
        assert_eq!((first.strong_count(), old_session.strong_count()), (1, 1));
        assert_eq!(second.strong_count(), 1, "the node renders the newest");
        while exchange.retired_clouds.take().is_some() {}
        assert_eq!((first.strong_count(), old_session.strong_count()), (0, 0));
        assert_eq!(node.stats().clouds, 2);
    }

    #[test]
    fn no_model_is_never_stale_and_a_rendered_one_has_its_age() {
        assert_eq!(model_age(false, None, 5), Model::None);
        assert_eq!(model_age(false, Some(1), 5), Model::None);
        assert_eq!(
            model_age(true, Some(1_000), 3_000_000),
            Model::Rendering {
                params_age: Duration::from_nanos(2_999_000)
            }
        );
        assert_eq!(
            model_age(true, None, 5),
            Model::Rendering {
                params_age: Duration::MAX
            }
        );
    }
}
