//! The two nodes of the system (`DESIGN.md` §3): plain structs stepped with `now` and inputs,
//! producing outputs and `protocol` messages. The networked daemons run exactly these nodes; the
//! in-process experiment harness (`lab::experiment`) runs them over the `netem` link model.
//!
//! - [`telerobot::TelerobotNode`]: bridge sample → contact on the live cloud → estimators →
//!   gates → parameter, contact, state-sync, measurement and cloud messages.
//! - [`operator::OperatorNode`]: device position → contact on the latest received cloud (remote
//!   contact as fallback) → renderers with the latest accepted parameters → force and a command.
//!
//! Both decide contact the same way ([`ContactTracker`]): the proxy touches the cloud **and** the
//! tool is below the locally fitted surface. The proxy says which surface the tool is at, and its
//! orientation; the plane test says whether the tool is actually pressing into it (the proxy alone
//! reports contact up to `r2` before the surface). The surface frame is frozen for a contact
//! episode: a frame that wobbled with cloud noise would turn a 5 cm tangential displacement into
//! millimetres of spurious motion on the other axes.

mod history;
pub mod operator;
mod playout;
pub mod telerobot;
mod tracker;
mod wire;

pub use tracker::{ContactTracker, Tracked};
pub use wire::{
    contact_state_to_wire, gated_from_wire, parameter_set, structure_from_wire, structure_to_wire,
    surface_frame_from_wire, surface_frame_to_wire,
};

use mmt::contact::ProxyConfig;
use mmt::estimator::EstimatorConfig;
use mmt::model::Structure;
use mmt::render::RendererConfig;
use mmt::rls::ColumnScales;
use serde::{Deserialize, Serialize};
use sim::scene::Scene;

/// Settings both nodes derive from a scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NodeSettings {
    /// The scene.
    pub scene: Scene,
    /// Loop period [ns].
    pub period_ns: i64,
    /// Contact detector.
    pub proxy: ProxyConfig,
    /// Normal-axis estimator.
    pub normal: EstimatorConfig,
    /// Tangential estimator (both tangents share one model).
    pub tangential: EstimatorConfig,
    /// Renderer settings (the operator's device damping enters here).
    pub renderer: RendererConfig,
    /// Period of the telerobot's state-sync messages [ns]. Default 10 ms.
    pub sync_period_ns: i64,
    /// Period at which the last parameters are sent again, in case one was lost [ns]. Default
    /// 100 ms.
    pub parameter_resend_ns: i64,
    /// Commands older than this make the telerobot hold still [ns]. Default 50 ms.
    pub command_timeout_ns: i64,
}

impl NodeSettings {
    /// The settings of `scene`: the scene's filter cut-off and forgetting, column scales from the
    /// exp-1 excitation scaled to the scene's stiffness, the scene's proxy radii.
    pub fn from_scene(scene: &Scene) -> NodeSettings {
        let rate = scene.rates.control_hz;
        let estimator = |structure: Structure, axes: usize| {
            let mut c = EstimatorConfig::new(structure, axes);
            c.filter.svf.cutoff_hz = scene.model.filter_cutoff_hz;
            c.filter.svf.sample_period_s = 1.0 / rate;
            c.forgetting = scene.model.forgetting;
            // Expected excitation: a few centimetres at about 1 Hz, force at the contact stiffness.
            let k = scene.environment.k_contact_n_per_m;
            let x = if structure == Structure::KelvinVoigt {
                0.004
            } else {
                0.03
            };
            c.scales = ColumnScales::for_excitation(
                x,
                (k * x).clamp(0.1, 100.0),
                2.0 * std::f64::consts::PI,
            )
            .unwrap_or_else(ColumnScales::exp1);
            c
        };
        NodeSettings {
            period_ns: (1e9 / rate).round() as i64,
            proxy: scene.proxy.config(rate),
            normal: estimator(scene.model.normal_structure(), 1),
            tangential: estimator(scene.model.tangential_structure(), 2),
            renderer: RendererConfig {
                rate_hz: rate,
                ..RendererConfig::default()
            },
            sync_period_ns: 10_000_000,
            parameter_resend_ns: 100_000_000,
            command_timeout_ns: 50_000_000,
            scene: scene.clone(),
        }
    }
}
#[cfg(test)]
mod tests;
