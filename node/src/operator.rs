//! The operator node: device position → contact on the latest received cloud (remote contact as
//! fallback) → renderers with the latest accepted, smoothed parameters → force (`DESIGN.md` §6).
//!
//! Received messages are handed over as they arrive ([`OperatorNode::on_message`]); each tick
//! ([`OperatorNode::step`]) takes the device position and velocity and returns the force to
//! display and the command to send. Beyond the thesis:
//! - **local contact** on the delayed cloud (thesis H.2.1): making and breaking contact is felt at
//!   once, not a round trip later; the telerobot's contact state is the fallback;
//! - **state sync**: the telerobot's estimate of the object's state (contact deflection, mass
//!   velocity) at a past sample time is blended in (gain ≈ 0.1, §11.6) by rewinding the renderers
//!   to that tick and replaying the stored inputs to now;
//! - **model start mid-contact** (§11.5): when the first (or a new) model arrives during a
//!   contact, the episode is replayed from its onset with the new model instead of starting from
//!   F = 0 now; the whole set that follows the telerobot's reduced first model (its massless
//!   part, a sliding set with `m = 0`) is a new model in this sense;
//! - **a prior** (issue 13): until the first model arrives, the normal axis renders a passive
//!   spring–damper and the tangents a passive object ([`mmt::model::prior::Prior`]), so contact
//!   is felt from its first tick. The first model takes over in a linear hand-over
//!   (`RendererConfig::handover_s`): the normal's parameters are blended, and on the tangents
//!   the offset between the prior's force and the model's at the first model tick falls to 0
//!   (the model's renderers run beside the prior's from the episode's onset, replayed at model
//!   start, so their mass state is the model's own);
//! - **the cloud moved by the predicted slide** (issue 13 item 6): when the cloud is the sliding
//!   object's surface, the proxy runs on the newest frame moved by the slide the node's own model
//!   predicts since the frame's capture (`operator/slide.rs`).

mod prior;
mod slide;
mod stats;
pub use prior::{GatedPrior, gate_prior};
pub use stats::OperatorStats;

use prior::{PriorStage, set_tangential_targets};
use slide::Slide;

use std::sync::Arc;

use mmt::contact::{CloudIndex, ContactOutput, ContactState, Moved, Proxy};
use mmt::model::Structure;
use mmt::model::prior::{Choice, Prior};
use mmt::render::{KelvinVoigtRenderer, RendererStats, ShearRenderer, SlidingMassRenderer};
use mmt::vec3;
use protocol::Header;
use protocol::operator_to_telerobot::Command;
use protocol::telerobot_to_operator::{self as wire, Message};
use serde::{Deserialize, Serialize};

use crate::history::{AxisCorrection, Correction, History, Replay};
use crate::settings::OperatorSettings;
use crate::telerobot::NodeError;
use crate::tracker::{ContactTracker, Tracked};
use crate::wire::{gated_from_wire, is_massless, surface_frame_from_wire};

/// How the operator decides contact and keeps in step. A field left out of serialised settings
/// takes [`OperatorConfig::default`]'s value.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct OperatorConfig {
    /// Detect contact locally on the received cloud (else use the telerobot's contact state).
    pub local_contact: bool,
    /// Apply the telerobot's state-sync messages.
    pub state_sync: bool,
    /// Blending gain of a state sync in (0, 1]. Default 0.1 (§11.6: replacing outright injects
    /// b2 × velocity noise).
    pub sync_gain: f64,
    /// Replay the current contact episode when a model arrives mid-contact (§11.5).
    pub replay_on_model_start: bool,
    /// What the normal and tangential axes render before the first model (`None`: nothing,
    /// free space). Default: [`Prior::generic`].
    pub prior: Option<Prior>,
    /// Render the scene's prior instead of [`OperatorConfig::prior`] when the scene declares
    /// one (`OperatorSettings::prior`, from the `Welcome`). Default: true (`--prior scene`).
    pub prefer_scene_prior: bool,
    /// Move a cloud that follows the object (`OperatorSettings::cloud_follows_object`) by the
    /// slide the rendered model predicts since the frame's capture. Default: true.
    pub move_cloud_with_slide: bool,
}

impl OperatorConfig {
    /// This configuration with a `--prior` choice ([`mmt::model::prior::parse`]).
    pub fn with_prior(self, choice: Choice) -> OperatorConfig {
        OperatorConfig {
            prior: choice.prior,
            prefer_scene_prior: choice.prefer_scene,
            ..self
        }
    }

    /// The prior this configuration renders with `settings`: the scene's when it declares one
    /// and [`OperatorConfig::prefer_scene_prior`] is set, else [`OperatorConfig::prior`].
    pub fn prior_for(&self, settings: &OperatorSettings) -> Option<Prior> {
        match settings.prior {
            Some(scene) if self.prefer_scene_prior => Some(scene),
            _ => self.prior,
        }
    }
}

impl Default for OperatorConfig {
    fn default() -> Self {
        OperatorConfig {
            local_contact: true,
            state_sync: true,
            sync_gain: 0.1,
            replay_on_model_start: true,
            prior: Some(Prior::generic()),
            prefer_scene_prior: true,
            move_cloud_with_slide: true,
        }
    }
}

/// One tick's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OperatorOutput {
    /// Force to display: the force on the tool [N], world frame.
    pub force_n: [f64; 3],
    /// Command to send to the telerobot (its header unstamped: the endpoint's session stamps it).
    pub command: Command,
    /// In contact this tick (as the renderer sees it).
    pub in_contact: bool,
    /// A model is being rendered.
    pub rendering: bool,
    /// The model rendered is the telerobot's reduced first model (the massless part of its
    /// structure, published while the whole structure was not identified); false when none is.
    pub reduced: bool,
}

/// The tangential renderer of one axis, by structure.
#[derive(Clone, Debug)]
pub(super) enum Tangential {
    Free,
    Sliding(SlidingMassRenderer),
    Shear(ShearRenderer),
}

/// The operator node.
pub struct OperatorNode {
    settings: OperatorSettings,
    config: OperatorConfig,
    proxy: Proxy,
    cloud: Option<Arc<CloudIndex>>,
    tracker: ContactTracker,
    remote: Option<wire::Contact>,
    normal: Option<KelvinVoigtRenderer>,
    pub(super) tangential: [Tangential; 2],
    history: History,
    /// The tangents' prior, then their hand-over to the first model.
    prior_tangential: PriorStage,
    /// The prior's renderers, one per tangent (kept in place after the hand-over: the loop
    /// frees nothing).
    prior_axes: [Tangential; 2],
    /// The hand-over's length [ticks].
    handover_ticks: u32,
    episode_onset_ns: Option<i64>,
    /// What is rendered before the first model ([`OperatorConfig::prior_for`]).
    prior: Option<Prior>,
    /// The model being rendered: its id, and whether it is the reduced (massless) stage.
    model_stage: Option<(u32, bool)>,
    rendering: bool,
    remote_in_contact: bool,
    last_sync_ns: Option<i64>,
    /// The object's predicted slide, and the newest frame's view moved by it.
    slide: Slide,
    stats: OperatorStats,
}

impl OperatorNode {
    /// A node for `settings`, the device starting at `device_m`.
    pub fn new(
        settings: OperatorSettings,
        config: OperatorConfig,
        device_m: [f64; 3],
    ) -> Result<Self, NodeError> {
        let r = settings.renderer;
        let prior = config.prior_for(&settings);
        let gated = match &prior {
            Some(p) => {
                p.validate()?;
                gate_prior(p, settings.normal, settings.tangential)
                    .map_err(NodeError::PriorRejected)?
            }
            None => GatedPrior::default(),
        };
        let normal = match settings.normal {
            Structure::Free => None,
            _ => {
                let mut renderer = KelvinVoigtRenderer::new(r)?;
                if let Some(g) = &gated.normal {
                    renderer.set_prior(g);
                }
                Some(renderer)
            }
        };
        let tangent = || -> Result<Tangential, NodeError> {
            Ok(match settings.tangential {
                Structure::Free => Tangential::Free,
                Structure::KelvinVoigt => Tangential::Shear(ShearRenderer::new(r)?),
                Structure::SlidingMass { .. } => Tangential::Sliding(SlidingMassRenderer::new(r)?),
            })
        };
        let mut prior_axes = [tangent()?, tangent()?];
        let prior_tangential = match &gated.tangential {
            Some(g) => {
                set_tangential_targets(&mut prior_axes, g);
                PriorStage::Prior
            }
            None => PriorStage::Done,
        };
        Ok(OperatorNode {
            proxy: Proxy::new(settings.proxy, device_m)
                .map_err(|e| NodeError::Proxy(e.to_string()))?,
            cloud: None,
            tracker: ContactTracker::new(settings.period_ns as f64 * 1e-9),
            remote: None,
            normal,
            tangential: [tangent()?, tangent()?],
            history: History::new(),
            prior_tangential,
            prior_axes,
            handover_ticks: r.handover_ticks(),
            episode_onset_ns: None,
            prior,
            model_stage: None,
            rendering: false,
            remote_in_contact: false,
            last_sync_ns: None,
            slide: Slide::new(settings.period_ns as f64 * 1e-9),
            stats: OperatorStats::default(),
            config,
            settings,
        })
    }

    /// Hands over a message from the telerobot.
    pub fn on_message(&mut self, message: &Message, now_ns: i64) {
        match message {
            Message::Parameters(p) => self.on_parameters(p),
            Message::Contact(c)
                if self
                    .remote
                    .is_none_or(|r| c.command_sample_time_ns >= r.command_sample_time_ns) =>
            {
                self.remote = Some(*c);
            }
            Message::StateSync(s) => self.on_sync(s, now_ns),
            Message::Cloud(frame) => self.on_cloud(frame),
            _ => {}
        }
    }

    /// Installs a cloud: builds its index (the daemon may instead build it off the haptic thread
    /// and call [`Self::set_cloud`]).
    fn on_cloud(&mut self, frame: &wire::CloudFrame) {
        if !self.config.local_contact {
            return; // contact comes from the telerobot: the cloud is not needed here
        }
        let built = mmt::cloud::CloudFrame::new(
            frame.points.clone(),
            frame.timestamp_ns,
            mmt::cloud::Pose::default(),
        )
        .ok()
        .and_then(|f| CloudIndex::build(&f).ok());
        match built {
            Some(index) => drop(self.set_cloud(Arc::new(index))),
            None => self.stats.rejected_clouds += 1,
        }
    }

    /// Installs an already built cloud index (built off the haptic thread, or shared).
    /// Reserves the proxy's neighbour buffer for it (an allocation only when this cloud is denser
    /// than any before), so that no proxy step allocates.
    ///
    /// Returns the index it replaces: a real-time caller hands it back to be dropped off its
    /// thread (it may hold the last reference, and dropping that frees the whole index).
    pub fn set_cloud(&mut self, index: Arc<CloudIndex>) -> Option<Arc<CloudIndex>> {
        self.proxy.prepare(index.as_ref());
        self.stats.clouds += 1;
        self.cloud.replace(index)
    }

    fn on_parameters(&mut self, p: &wire::Parameters) {
        let mut accepted = false;
        // Each group's set to its own renderers (a wall's are all Kelvin–Voigt).
        for (set, normal) in [(p.normal, true), (p.tangential, false)] {
            match set.map(|s| gated_from_wire(&s)).transpose() {
                Ok(None) => {}
                Ok(Some(g)) => {
                    let any = if normal {
                        self.normal.as_mut().is_some_and(|r| r.set_target(&g))
                    } else {
                        set_tangential_targets(&mut self.tangential, &g)
                    };
                    accepted |= any;
                    if any {
                        self.stats.parameter_sets += 1;
                    }
                }
                Err(_) => self.stats.parameter_rejections += 1,
            }
        }
        if !accepted {
            return;
        }
        // Rendering starts once every axis group has a model.
        let normal_ready = self.normal.as_ref().is_none_or(|r| r.target().is_some());
        let tangential_ready = self.tangential.iter().all(|t| match t {
            Tangential::Sliding(r) => r.target().is_some(),
            Tangential::Shear(r) => r.has_target(),
            Tangential::Free => true,
        });
        self.rendering = normal_ready && tangential_ready;
        if !self.rendering {
            return;
        }
        // The telerobot's reduced first model (its massless part, `EstimatorConfig::reduced_model`)
        // is a stage of its own: the whole set that follows it starts its mass from the episode's
        // replay like any new model, not from the massless model's state.
        let reduced = match &p.tangential {
            Some(set) => is_massless(set),
            None => self.rendering_reduced(),
        };
        let stage = (p.model_id, reduced);
        if self.model_stage != Some(stage) {
            self.model_stage = Some(stage);
            self.stats.models += 1;
            if self.config.replay_on_model_start
                && let Some(onset) = self.episode_onset_ns
            {
                // Render the whole episode (as far as the history reaches) with the new model.
                let ticks = self
                    .history
                    .replay(Replay::FromOnset { onset_ns: onset }, &mut self.tangential);
                self.stats.model_replays += 1;
                self.stats.replayed_ticks += ticks as u64;
            }
        }
    }

    fn on_sync(&mut self, s: &wire::StateSync, now_ns: i64) {
        let replay = self.history.ticks_since(s.command_sample_time_ns);
        // Rate-limit long replays (large delays) to one every 50 ms.
        let min_interval = if replay.unwrap_or(0) > 100 {
            50_000_000
        } else {
            0
        };
        let usable = self.config.state_sync
            && s.in_contact
            && self.rendering
            && replay.is_some()
            && self
                .last_sync_ns
                .is_none_or(|last| now_ns - last >= min_interval)
            && s.tangential
                .iter()
                .all(|a| a.deflection_m.is_finite() && a.mass_velocity_m_per_s.is_finite());
        if !usable || !self.history.in_contact_at(s.command_sample_time_ns) {
            self.stats.syncs_skipped += 1;
            return;
        }
        self.last_sync_ns = Some(now_ns);
        let correction = Correction {
            axes: s.tangential.map(|a| AxisCorrection {
                deflection_m: a.deflection_m,
                mass_velocity_m_per_s: a.mass_velocity_m_per_s,
            }),
            gain: self.config.sync_gain,
        };
        let replay = Replay::Correct {
            at_ns: s.command_sample_time_ns,
            correction,
        };
        let ticks = self.history.replay(replay, &mut self.tangential);
        self.stats.syncs += 1;
        self.stats.replayed_ticks += ticks as u64;
    }

    /// One tick: device position [m] and velocity [m/s], world frame.
    pub fn step(
        &mut self,
        now_ns: i64,
        position_m: [f64; 3],
        velocity_m_per_s: [f64; 3],
    ) -> OperatorOutput {
        self.stats.ticks += 1;
        let command = Command {
            header: Header::unstamped(now_ns),
            position_m,
            velocity_m_per_s,
        };
        if !(vec3::is_finite(position_m) && vec3::is_finite(velocity_m_per_s)) {
            self.stats.rejected_inputs += 1;
            return OperatorOutput {
                force_n: [0.0; 3],
                command,
                in_contact: false,
                rendering: self.rendering,
                reduced: self.rendering_reduced(),
            };
        }
        let tracked = self.contact(position_m);
        if tracked.onset {
            self.stats.contact_onsets += 1;
            self.episode_onset_ns = Some(now_ns);
        }
        if !tracked.in_contact {
            self.episode_onset_ns = None;
        }
        let mut force = [0.0; 3];
        if let Some(frame) = tracked.frame {
            let in_contact = tracked.in_contact;
            if let (Some(r), Some(s)) = (&mut self.normal, tracked.normal_position_m) {
                let f = r.step(-s, -vec3::dot(velocity_m_per_s, frame.normal), in_contact);
                force = vec3::add(force, vec3::scale(frame.normal, f));
            }
            let tangents = [frame.tangent1, frame.tangent2];
            let mut inputs = [[0.0; 2]; 2];
            let mut f_model = [0.0; 2];
            for (i, axis) in tangents.iter().enumerate() {
                let (x, v) = (
                    vec3::dot(position_m, *axis),
                    vec3::dot(velocity_m_per_s, *axis),
                );
                inputs[i] = [x, v];
                f_model[i] = step_tangential(&mut self.tangential[i], x, v, in_contact);
            }
            let f_tangential = self.with_prior(f_model, inputs, in_contact);
            for (axis, f) in tangents.iter().zip(f_tangential) {
                force = vec3::add(force, vec3::scale(*axis, f));
            }
            self.slide.advance(now_ns, self.object_velocity(&tangents));
            self.history
                .push(now_ns, in_contact, inputs, &self.tangential);
        } else {
            self.slide.advance(now_ns, [0.0; 3]);
            self.history
                .push(now_ns, false, [[0.0; 2]; 2], &self.tangential);
        }
        self.advance_handover();
        OperatorOutput {
            force_n: force,
            command,
            in_contact: tracked.in_contact,
            rendering: self.rendering,
            reduced: self.rendering_reduced(),
        }
    }

    /// Whether the model rendered is the telerobot's reduced first model.
    fn rendering_reduced(&self) -> bool {
        self.rendering && self.model_stage.is_some_and(|(_, reduced)| reduced)
    }

    /// Contact from the local proxy on the latest cloud, or from the telerobot's state.
    fn contact(&mut self, position_m: [f64; 3]) -> Tracked {
        if self.config.local_contact
            && let Some(cloud) = &self.cloud
        {
            let view = self.frame_command_ns(cloud).and_then(|command_ns| {
                self.slide.view(
                    mmt::contact::Neighbours::cloud_id(cloud.as_ref()),
                    command_ns,
                )
            });
            let out = match view {
                Some((by, id)) => self
                    .proxy
                    .step(position_m, &Moved::new(cloud.as_ref(), by, id)),
                None => self.proxy.step(position_m, cloud.as_ref()),
            };
            if let (true, Some(n)) = (out.state.is_touching(), out.normal) {
                self.slide.observe_normal(n);
            }
            return self.tracker.update(&out, position_m);
        }
        // Remote contact (the thesis): the telerobot's state as it arrives, its frame and surface.
        let Some(remote) = self.remote else {
            return Tracked::default();
        };
        let frame = remote.frame.as_ref().and_then(surface_frame_from_wire);
        let touching = !matches!(remote.state, wire::ContactState::Free);
        let out = ContactOutput {
            state: if touching {
                ContactState::Contact
            } else {
                ContactState::Free
            },
            step_state: ContactState::Free,
            proxy_m: remote.proxy_position_m,
            normal: frame.map(|f| f.normal),
            frame,
            penetration_m: remote.penetration_m,
            surface_point_m: remote.surface_point_m,
            points_used: 0,
        };
        // The telerobot's state decides contact, whatever the local position says (the thesis);
        // the local position only gives the depth for the normal axis.
        let mut t = self.tracker.update(&out, position_m);
        let in_contact = touching && t.frame.is_some();
        t.onset = in_contact && !self.remote_in_contact;
        t.release = !in_contact && self.remote_in_contact;
        t.in_contact = in_contact;
        self.remote_in_contact = in_contact;
        t
    }

    /// Renderer counters (normal, tangential axes).
    pub fn renderer_stats(&self) -> Vec<RendererStats> {
        let mut v: Vec<RendererStats> = self.normal.iter().map(|r| r.stats()).collect();
        for t in &self.tangential {
            match t {
                Tangential::Sliding(r) => v.push(r.stats()),
                Tangential::Shear(r) => v.push(r.stats()),
                Tangential::Free => {}
            }
        }
        v
    }

    /// The contact deflection and mass velocity of each sliding tangential axis (for drift
    /// reports).
    pub fn tangential_state(&self) -> [Option<(f64, f64)>; 2] {
        self.tangential.each_ref().map(|t| match t {
            Tangential::Sliding(r) => Some((r.deflection_m(), r.snapshot().mass_velocity_m_per_s)),
            _ => None,
        })
    }

    /// Counters.
    pub fn stats(&self) -> OperatorStats {
        OperatorStats {
            moved_clouds: self.slide.moved_views,
            largest_cloud_move_m: self.slide.largest_move_m,
            cloud_moves_beyond_history: self.slide.beyond_ring,
            ..self.stats
        }
    }

    /// Where the local proxy is \[m\], while it runs (local contact on, a cloud received).
    pub fn proxy_m(&self) -> Option<[f64; 3]> {
        (self.config.local_contact && self.cloud.is_some()).then(|| self.proxy.position())
    }

    /// A model is being rendered.
    pub fn is_rendering(&self) -> bool {
        self.rendering
    }

    /// The configuration.
    pub fn config(&self) -> &OperatorConfig {
        &self.config
    }

    /// What the node renders before its first model of an object: the scene's prior, its
    /// configuration's, or none ([`OperatorConfig::prior_for`]).
    pub fn prior(&self) -> Option<Prior> {
        self.prior
    }

    /// The settings.
    pub fn settings(&self) -> &OperatorSettings {
        &self.settings
    }
}

pub(super) fn step_tangential(t: &mut Tangential, x: f64, v: f64, in_contact: bool) -> f64 {
    match t {
        Tangential::Sliding(r) => r.step(x, v, in_contact),
        Tangential::Shear(r) => r.step(x, v, in_contact),
        Tangential::Free => 0.0,
    }
}
