//! The telerobot node: bridge sample → contact on the live cloud → estimators → gates →
//! messages (thesis fig. 4 and appendix D; `DESIGN.md` §5).
//!
//! Per tick the owner (the daemon's 1 kHz loop, or the experiment harness):
//! 1. hands over commands as they arrive ([`TelerobotNode::on_command`]);
//! 2. asks where the robot should go ([`TelerobotNode::target`]: the latest command, or hold still
//!    when commands are older than the timeout);
//! 3. moves the robot and reads its sensors (the bridge); installs the newest camera frame's
//!    index if one was taken ([`TelerobotNode::set_cloud`]; the frame itself goes to the operator
//!    as [`crate::cloud_to_wire`] makes it);
//! 4. steps the node with the sample ([`TelerobotNode::step`]), which returns the datagrams of
//!    the tick: `Contact` and `Measurement` every tick, `Parameters` when a set is confirmed (and
//!    again every 100 ms), `StateSync` every 10 ms in contact. Their headers carry only the
//!    sample time: the endpoint's session stamps the rest (`protocol::session::Session::stamp`).

use std::sync::Arc;

use mmt::contact::{CloudIndex, ContactOutput, ContactState, Proxy, SurfaceFrame};
use mmt::estimator::{AxisSample, Estimator, EstimatorError, EstimatorStats, Update};
use mmt::model::Structure;
use mmt::model::gates::Gated;
use mmt::vec3;
use protocol::Header;
use protocol::telerobot_to_operator::{self as wire, AxisState, Datagram};

use crate::bridge::{RobotSample, Target};
use crate::continuity::Continuity;
use crate::observer::Observer;
use crate::playout::{Playout, Push};
use crate::settings::TelerobotSettings;
use crate::tracker::{ContactTracker, Tracked};
use crate::wire::{contact_state_to_wire, parameter_set, surface_frame_to_wire};

mod stats;
pub use stats::TelerobotStats;

/// Normal force on the tool above which the normal contact counts as loaded [N]: three standard
/// deviations of the Franka-like force noise.
pub const NORMAL_LOADED_N: f64 = 0.06;

/// A command as the telerobot uses it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CommandSample {
    /// Operator's sample time of the command [ns].
    pub sample_time_ns: i64,
    /// Target position [m], world frame.
    pub position_m: [f64; 3],
    /// Target velocity [m/s].
    pub velocity_m_per_s: [f64; 3],
    /// When it arrived [ns, telerobot clock].
    pub received_ns: i64,
}

/// The telerobot node.
pub struct TelerobotNode {
    settings: TelerobotSettings,
    proxy: Proxy,
    cloud: Option<Arc<CloudIndex>>,
    tracker: ContactTracker,
    normal: Option<Estimator>,
    tangential: Option<Estimator>,
    observer: [Observer; 2],
    playout: Playout,
    continuity: Continuity,
    hold_position: Option<[f64; 3]>,
    out: Vec<Datagram>,
    model_id: u32,
    latest_normal: Option<Gated>,
    latest_tangential: Option<Gated>,
    parameters_sent_ns: Option<i64>,
    next_sync_ns: i64,
    episode_onset_ns: Option<i64>,
    frame_id: u64,
    last_frame: Option<SurfaceFrame>,
    shear_anchor: [f64; 2],
    reconstruction: Option<(f64, f64)>,
    updates: [Option<Update>; 2],
    /// The session's first accepted command's lag (arrival − sample time) \[ns\].
    reference_lag_ns: Option<i64>,
    stats: TelerobotStats,
}

impl TelerobotNode {
    /// A node for `settings`, the tool starting at `tool_m`.
    pub fn new(settings: TelerobotSettings, tool_m: [f64; 3]) -> Result<Self, NodeError> {
        let estimator =
            |c: &mmt::estimator::EstimatorConfig| -> Result<Option<Estimator>, NodeError> {
                if c.structure == Structure::Free {
                    Ok(None)
                } else {
                    Ok(Some(Estimator::new(*c)?))
                }
            };
        Ok(TelerobotNode {
            proxy: Proxy::new(settings.proxy, tool_m)
                .map_err(|e| NodeError::Proxy(e.to_string()))?,
            cloud: None,
            tracker: ContactTracker::new(settings.period_ns as f64 * 1e-9),
            normal: estimator(&settings.normal)?,
            tangential: estimator(&settings.tangential)?,
            observer: [Observer::default(); 2],
            playout: Playout::new(),
            continuity: Continuity::default(),
            hold_position: None,
            out: Vec::with_capacity(8),
            model_id: 0,
            latest_normal: None,
            latest_tangential: None,
            parameters_sent_ns: None,
            next_sync_ns: 0,
            episode_onset_ns: None,
            frame_id: 0,
            last_frame: None,
            shear_anchor: [0.0; 2],
            reconstruction: None,
            updates: [None; 2],
            reference_lag_ns: None,
            stats: TelerobotStats::default(),
            settings,
        })
    }

    /// A command arrived. It is held until its turn ([`super::playout`]); duplicates, commands
    /// older than the one executing and non-finite ones are dropped and counted. A command whose
    /// lag (arrival − sample time) is further than the limit from the session's first command's
    /// has an implausible playout time (a clock jumping by hours would hold every later command
    /// back, or make it stale): it is refused and counted.
    pub fn on_command(&mut self, command: CommandSample) {
        let finite = command
            .position_m
            .iter()
            .chain(&command.velocity_m_per_s)
            .all(|v| v.is_finite());
        if !finite {
            self.stats.stale_commands += 1;
            return;
        }
        let lag = command.received_ns.saturating_sub(command.sample_time_ns);
        let reference = *self.reference_lag_ns.get_or_insert(lag);
        if lag.saturating_sub(reference).saturating_abs() > self.settings.limits.max_clock_jump_ns {
            self.stats.implausible_commands += 1;
            return;
        }
        match self.playout.push(command) {
            Push::Stale => self.stats.stale_commands += 1,
            Push::Queued => self.stats.commands += 1,
            Push::Overflow => {
                self.stats.commands += 1;
                self.stats.skipped_commands += 1;
            }
        }
    }

    /// Where the robot should be this tick: the command whose turn it is, or — when no command
    /// arrived for longer than the timeout, or none came yet — hold still where the robot is.
    pub fn target(&mut self, now_ns: i64, robot_position_m: [f64; 3]) -> Target {
        let (current, skipped) = self.playout.advance(now_ns);
        self.stats.skipped_commands += skipped as u64;
        if self.playout.stopped() {
            // The robot is stopped for want of commands, not by the operator: the force
            // transient that follows is the motion's, not a new object's.
            self.stats.stopped_ticks += 1;
            for e in [&mut self.normal, &mut self.tangential]
                .into_iter()
                .flatten()
            {
                e.mute_new_object_detector();
            }
        }
        let fresh = self
            .playout
            .last_received_ns()
            .is_some_and(|r| now_ns - r <= self.settings.command_timeout_ns);
        match current {
            Some(c) if fresh => {
                self.hold_position = None;
                if let Some(lag) = self
                    .playout
                    .played_lag_ns()
                    .filter(|_| !self.playout.stopped())
                {
                    self.stats.played_ticks += 1;
                    self.stats.played_lag_us_sum =
                        self.stats.played_lag_us_sum.saturating_add(lag / 1000);
                }
                let (position_m, velocity_m_per_s) =
                    self.continuity
                        .pass(now_ns, c.position_m, c.velocity_m_per_s);
                Target {
                    position_m,
                    velocity_m_per_s,
                    command_sample_time_ns: c.sample_time_ns,
                    holding: false,
                }
            }
            c => {
                self.stats.holding_ticks += 1;
                let hold = *self.hold_position.get_or_insert(robot_position_m);
                self.continuity.hold(now_ns, hold);
                Target {
                    position_m: hold,
                    velocity_m_per_s: [0.0; 3],
                    command_sample_time_ns: c.map_or(0, |c| c.sample_time_ns),
                    holding: true,
                }
            }
        }
    }

    /// One tick: the bridge's sample for the command being executed. Returns the datagrams to
    /// send (unstamped: the endpoint's session stamps them).
    pub fn step(
        &mut self,
        now_ns: i64,
        command_sample_time_ns: i64,
        sample: &RobotSample,
    ) -> &[Datagram] {
        self.out.clear();
        self.stats.ticks += 1;
        self.reconstruction = None;
        self.updates = [None; 2];
        if !sample.is_finite() {
            self.stats.rejected_samples += 1;
            return &self.out;
        }
        let detected = match &self.cloud {
            Some(cloud) => self.proxy.step(sample.position_m, cloud.as_ref()),
            None => geometric_contact(&self.settings, sample.position_m),
        };
        let tracked = self.tracker.update(&detected, sample.position_m);
        if tracked.onset {
            self.stats.contact_onsets += 1;
            self.episode_onset_ns = Some(now_ns);
        }
        if tracked.release {
            self.episode_onset_ns = None;
        }
        if let Some(f) = tracked.frame {
            self.last_frame = Some(f);
        }
        let prior = self.tangential.as_ref().map(|e| e.theta());
        self.estimate(now_ns, sample, &tracked);
        self.reconstruction =
            prior.and_then(|theta| reconstruction(&theta, self.tangential.as_ref()?));
        self.emit(now_ns, command_sample_time_ns, sample, &detected, &tracked);
        &self.out
    }

    /// Runs both estimators in the episode's frame and the state observers.
    fn estimate(&mut self, now_ns: i64, sample: &RobotSample, tracked: &Tracked) {
        let t = now_ns as f64 * 1e-9;
        let frame = tracked.frame.or(self.last_frame);
        let Some(frame) = frame else { return };
        let in_contact = tracked.in_contact;
        let mut new_object = false;
        if let Some(est) = &mut self.normal {
            let s = AxisSample {
                position_m: tracked.normal_position_m.unwrap_or(0.0),
                velocity_m_per_s: vec3::dot(sample.velocity_m_per_s, frame.normal),
                force_n: vec3::dot(sample.force_on_tool_n, frame.normal),
            };
            // The surface pushes, never pulls: while the linear law would pull (lifting off fast)
            // the force is clamped at 0, which the linear regression would read as low damping.
            let loaded = s.force_n - est.tare_n()[0] > NORMAL_LOADED_N;
            let u = est.step(t, &[s], in_contact && loaded);
            self.updates[0] = Some(u);
            new_object |= u.new_object;
            if let Some(g) = u.confirmed {
                self.latest_normal = Some(g);
                self.parameters_sent_ns = None;
            }
        }
        let tangents = [frame.tangent1, frame.tangent2];
        let mut samples = tangents.map(|axis| AxisSample {
            position_m: vec3::dot(sample.position_m, axis),
            velocity_m_per_s: vec3::dot(sample.velocity_m_per_s, axis),
            force_n: vec3::dot(sample.force_on_tool_n, axis),
        });
        if self.settings.tangential.structure == Structure::KelvinVoigt {
            // An anchored element: its law is in the displacement from where contact began.
            if tracked.onset {
                self.shear_anchor = [samples[0].position_m, samples[1].position_m];
            }
            for (s, a) in samples.iter_mut().zip(self.shear_anchor) {
                s.position_m -= a;
            }
        }
        if let Some(est) = &mut self.tangential {
            let u = est.step(t, &samples, in_contact);
            self.updates[1] = Some(u);
            new_object |= u.new_object;
            if let Some(g) = u.confirmed {
                self.latest_tangential = Some(g);
                self.parameters_sent_ns = None;
            }
            let tare = [est.tare_n()[0], est.tare_n()[1]];
            if let Some(p) = self.latest_tangential.and_then(|g| g.sliding_mass()) {
                for (i, obs) in self.observer.iter_mut().enumerate() {
                    let force = samples[i].force_n - tare[i];
                    obs.step(
                        &p,
                        samples[i].velocity_m_per_s,
                        force,
                        in_contact,
                        tracked.onset,
                        self.settings.period_ns as f64 * 1e-9,
                    );
                }
            }
        }
        // The node's model: the first from either group's first contact, then one more on each
        // tick either group declares a new object (the normal's first fit on a re-touch as much
        // as the tangents' detector).
        let started = self
            .normal
            .iter()
            .chain(&self.tangential)
            .any(|e| e.model_id() > 0);
        if self.model_id == 0 && started {
            self.model_id = 1;
        } else if new_object && self.model_id > 0 {
            self.model_id += 1;
        }
    }

    fn emit(
        &mut self,
        now_ns: i64,
        command_time: i64,
        sample: &RobotSample,
        detected: &ContactOutput,
        tracked: &Tracked,
    ) {
        let resend = self
            .parameters_sent_ns
            .is_none_or(|t| now_ns - t >= self.settings.parameter_resend_ns);
        if resend && (self.latest_normal.is_some() || self.latest_tangential.is_some()) {
            self.parameters_sent_ns = Some(now_ns);
            let set = |g: &Option<Gated>| g.as_ref().and_then(|g| parameter_set(g, now_ns));
            self.out.push(Datagram::Parameters(wire::Parameters {
                header: Header::unstamped(now_ns),
                model_id: self.model_id,
                normal: set(&self.latest_normal),
                tangential: set(&self.latest_tangential),
            }));
        }
        self.out.push(Datagram::Contact(wire::Contact {
            header: Header::unstamped(now_ns),
            command_sample_time_ns: command_time,
            // The tracked contact: during the tracker's grace ticks the proxy may read Free while
            // the episode goes on.
            state: match (tracked.in_contact, detected.state) {
                (false, _) => wire::ContactState::Free,
                (true, ContactState::Free) => wire::ContactState::Contact,
                (true, s) => contact_state_to_wire(s),
            },
            proxy_position_m: if vec3::is_finite(detected.proxy_m) {
                detected.proxy_m
            } else {
                sample.position_m
            },
            normal: tracked.frame.map(|f| f.normal),
            frame: tracked.frame.as_ref().map(surface_frame_to_wire),
            surface_point_m: detected.surface_point_m,
            penetration_m: tracked.normal_position_m.map(|s| -s),
        }));
        if self
            .latest_tangential
            .and_then(|g| g.sliding_mass())
            .is_some()
            && now_ns >= self.next_sync_ns
        {
            self.next_sync_ns = now_ns + self.settings.sync_period_ns;
            self.out.push(Datagram::StateSync(wire::StateSync {
                header: Header::unstamped(now_ns),
                command_sample_time_ns: command_time,
                tangential: self.observer.map(|o| AxisState {
                    deflection_m: o.deflection_m,
                    mass_velocity_m_per_s: o.mass_velocity_m_per_s,
                }),
                in_contact: tracked.in_contact,
                episode_onset_ns: self.episode_onset_ns,
            }));
        }
        self.out.push(Datagram::Measurement(wire::Measurement {
            header: Header::unstamped(now_ns),
            command_sample_time_ns: command_time,
            position_m: sample.position_m,
            velocity_m_per_s: sample.velocity_m_per_s,
            force_on_tool_n: sample.force_on_tool_n,
            in_contact: tracked.in_contact,
            estimator_stable: self.is_stable(),
            reconstruction: self.reconstruction.map(|(y2, e2)| [y2, e2]),
        }));
    }

    /// Installs a cloud index (built off the real-time thread: the daemon's camera thread, or the
    /// harness; whoever built it also sends the frame to the operator); `frame_id` is the id it
    /// was sent with.
    /// Reserves the proxy's neighbour buffer for it (an allocation only when this cloud is
    /// denser than any before), so that no proxy step allocates.
    ///
    /// Returns the index it replaces: a real-time caller hands it back to be dropped off its
    /// thread (it may hold the last reference, and dropping that frees the whole index).
    pub fn set_cloud(&mut self, index: Arc<CloudIndex>, frame_id: u64) -> Option<Arc<CloudIndex>> {
        self.proxy.prepare(index.as_ref());
        self.frame_id = frame_id;
        self.cloud.replace(index)
    }

    /// Takes over, for a new session on the same robot, what `previous` knew of the geometry:
    /// its proxy (where the tool is relative to the cloud) and its cloud; everything estimated
    /// stays fresh. A proxy started at the tool cannot tell the inside of a surface from the
    /// outside: a tool left resting on the object or pressed into it gave the next session's
    /// proxy the wrong side, and that whole session felt contact in free space and none while
    /// pressing. `previous`'s proxy followed the tool there from free space. Swaps: nothing
    /// allocates.
    pub fn take_over_geometry(&mut self, previous: &mut TelerobotNode) {
        std::mem::swap(&mut self.proxy, &mut previous.proxy);
        std::mem::swap(&mut self.cloud, &mut previous.cloud);
        self.frame_id = previous.frame_id;
    }

    /// Counts a camera frame that could not be indexed.
    pub fn count_rejected_cloud(&mut self) {
        self.stats.rejected_clouds += 1;
    }

    /// The current tangential estimator (for reports).
    pub fn tangential_estimator(&self) -> Option<&Estimator> {
        self.tangential.as_ref()
    }

    /// The current normal estimator (for reports).
    pub fn normal_estimator(&self) -> Option<&Estimator> {
        self.normal.as_ref()
    }

    /// Both estimators (where present) are confident.
    pub fn is_stable(&self) -> bool {
        [&self.normal, &self.tangential]
            .iter()
            .all(|e| e.as_ref().is_none_or(|e| e.is_confident()))
    }

    /// The datagrams of the last tick (what [`TelerobotNode::step`] returned).
    pub fn datagrams(&self) -> &[Datagram] {
        &self.out
    }

    /// What each estimator did this tick, `[normal, tangential]`: its gate verdict and any set
    /// it confirmed (`None`: the scene has no such estimator, or the tick ran none).
    pub fn updates(&self) -> [Option<Update>; 2] {
        self.updates
    }

    /// This tick's `(Σ y², Σ (y − ψᵀθ̂)²)` of the tangential estimator, `θ̂` from before the
    /// tick's update, while it is learning and confident (`None` otherwise): summed over a run,
    /// the a-priori reconstruction error (thesis: about 5 %).
    pub fn reconstruction(&self) -> Option<(f64, f64)> {
        self.reconstruction
    }

    /// The observer's contact deflection and mass velocity per tangential axis.
    pub fn observed_state(&self) -> [(f64, f64); 2] {
        self.observer
            .map(|o| (o.deflection_m, o.mass_velocity_m_per_s))
    }

    /// Counters.
    pub fn stats(&self) -> TelerobotStats {
        let c = &self.continuity;
        TelerobotStats {
            path_breaks: c.breaks,
            unblended_breaks: c.unblended_breaks,
            blended_ticks: c.blended_ticks,
            ..self.stats
        }
    }

    /// Estimator counters: (normal, tangential).
    pub fn estimator_stats(&self) -> (Option<EstimatorStats>, Option<EstimatorStats>) {
        (
            self.normal.as_ref().map(|e| e.stats()),
            self.tangential.as_ref().map(|e| e.stats()),
        )
    }

    /// The settings.
    pub fn settings(&self) -> &TelerobotSettings {
        &self.settings
    }
}

/// `(Σ y², Σ (y − ψᵀθ))` over the estimator's last regressions, if it is learning and confident.
fn reconstruction(theta: &mmt::model::Theta, est: &Estimator) -> Option<(f64, f64)> {
    use mmt::model::col;
    (est.phase() == mmt::estimator::Phase::Learning && est.is_confident()).then(|| {
        est.regressions()
            .iter()
            .map(|r| {
                (
                    r.y,
                    (0..col::COUNT).map(|i| theta.0[i] * r.psi[i]).sum::<f64>(),
                )
            })
            .fold((0.0, 0.0), |(a, b), (y, p)| {
                (a + y * y, b + (y - p) * (y - p))
            })
    })
}

/// Contact from the surface known in advance (a simulated scene's), before any cloud.
fn geometric_contact(settings: &TelerobotSettings, position_m: [f64; 3]) -> ContactOutput {
    let Some(s) = settings.known_surface else {
        return ContactOutput::free(position_m);
    };
    let frame = SurfaceFrame::from_normal(s.normal);
    let height = vec3::dot(vec3::sub(position_m, s.point_m), s.normal);
    let touching = height < settings.proxy.r2_m;
    ContactOutput {
        state: if touching {
            ContactState::Contact
        } else {
            ContactState::Free
        },
        step_state: ContactState::Free,
        proxy_m: position_m,
        normal: frame.map(|f| f.normal),
        frame,
        penetration_m: Some(-height),
        surface_point_m: Some(vec3::sub(position_m, vec3::scale(s.normal, height))),
        points_used: 0,
    }
}

/// Why a node could not be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NodeError {
    /// An estimator setting.
    #[error(transparent)]
    Estimator(#[from] EstimatorError),
    /// A contact-detector setting.
    #[error("contact detector: {0}")]
    Proxy(String),
    /// A renderer setting.
    #[error(transparent)]
    Renderer(#[from] mmt::render::ConfigError),
    /// The prior to render before the first model.
    #[error(transparent)]
    Prior(#[from] mmt::model::prior::PriorError),
    /// The prior passed its own check but not the renderer's gates.
    #[error("the prior is not renderable: {0}")]
    PriorRejected(mmt::model::gates::GateRejection),
}

#[cfg(test)]
#[path = "telerobot_tests.rs"]
mod tests;
