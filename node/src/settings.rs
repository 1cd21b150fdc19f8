//! What each node needs to run, and where it comes from.
//!
//! - [`TelerobotSettings`]: the telerobot side's — the estimators of both axis groups, the
//!   contact detector, the message periods, and (for a simulated scene) the surface known in
//!   advance. A scene builds them (`sim::scene::Scene::telerobot_settings`).
//! - [`OperatorSettings`]: the operator side's — the model structures to render, the control
//!   rate and the contact detector's radii, all from the telerobot's `Welcome`
//!   ([`OperatorSettings::from_welcome`]); the renderer's settings are the operator's own. A
//!   remote operator knows nothing else of the telerobot's scene, and needs nothing else.

use mmt::contact::{ProxyConfig, ProxyError};
use mmt::estimator::EstimatorConfig;
use mmt::model::Structure;
use mmt::model::prior::Prior;
use mmt::render::RendererConfig;
use protocol::telerobot_to_operator::SceneSummary;
use serde::{Deserialize, Serialize};

use crate::guard::MotionLimits;
use crate::operator::gate_prior;
use crate::wire::{prior_from_wire, structure_from_wire};

/// The control rates the loops run at \[Hz\].
pub const RATE_RANGE_HZ: std::ops::RangeInclusive<f64> = 100.0..=10_000.0;

/// The telerobot node's settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TelerobotSettings {
    /// Loop period \[ns\].
    pub period_ns: i64,
    /// Contact detector.
    pub proxy: ProxyConfig,
    /// Normal-axis estimator.
    pub normal: EstimatorConfig,
    /// Tangential estimator (both tangents share one model).
    pub tangential: EstimatorConfig,
    /// Period of the state-sync messages \[ns\]. Default 10 ms.
    pub sync_period_ns: i64,
    /// Period at which the last parameters are sent again, in case one was lost \[ns\]. Default
    /// 100 ms.
    pub parameter_resend_ns: i64,
    /// Commands older than this make the telerobot hold still \[ns\]. Default 50 ms.
    pub command_timeout_ns: i64,
    /// A contact surface known in advance (a simulated scene's), used for contact until the
    /// first cloud arrives; `None` for a real robot, which knows only what its camera sees.
    pub known_surface: Option<KnownSurface>,
    /// What the robot may be told to do, whatever the operator sends (the scene's `[limits]`,
    /// or [`MotionLimits::around`] its surface point).
    pub limits: MotionLimits,
    /// The scene's prior of its object, for the operator (the `Welcome` carries it); the
    /// telerobot itself does not use it.
    #[serde(default)]
    pub prior: Option<Prior>,
    /// The cloud is the object's surface and slides with it (for the operator, which moves it by
    /// its predicted slide; the `Welcome` carries it).
    #[serde(default)]
    pub cloud_follows_object: bool,
}

/// A plane through `point_m` with outward unit `normal`, world frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct KnownSurface {
    /// A point of the surface \[m\].
    pub point_m: [f64; 3],
    /// Outward unit normal.
    pub normal: [f64; 3],
}

impl TelerobotSettings {
    /// Default state-sync period \[ns\]: 10 ms.
    pub const SYNC_PERIOD_NS: i64 = 10_000_000;
    /// Default parameter resend period \[ns\]: 100 ms.
    pub const PARAMETER_RESEND_NS: i64 = 100_000_000;
    /// Default command timeout \[ns\]: 50 ms.
    pub const COMMAND_TIMEOUT_NS: i64 = 50_000_000;

    /// The operator's view of these settings: what the `Welcome` carries, with the operator's
    /// default renderer (what a remote operator derives, [`OperatorSettings::from_welcome`]).
    pub fn operator_view(&self) -> OperatorSettings {
        OperatorSettings {
            period_ns: self.period_ns,
            proxy: self.proxy,
            normal: self.normal.structure,
            tangential: self.tangential.structure,
            renderer: RendererConfig {
                rate_hz: self.proxy.rate_hz,
                ..RendererConfig::default()
            },
            prior: self.prior,
            cloud_follows_object: self.cloud_follows_object,
        }
    }
}

/// The operator node's settings.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OperatorSettings {
    /// Loop period \[ns\].
    pub period_ns: i64,
    /// Contact detector: the telerobot's radii, so both make and break contact at the same
    /// distance from the cloud.
    pub proxy: ProxyConfig,
    /// Model structure along the normal.
    pub normal: Structure,
    /// Model structure along the two tangents.
    pub tangential: Structure,
    /// Renderer settings (the operator's device damping enters here).
    pub renderer: RendererConfig,
    /// The scene's prior of its object, when it declares one: what the operator renders before
    /// the first model unless its user chose another
    /// ([`crate::operator::OperatorConfig::prefer_scene_prior`]).
    #[serde(default)]
    pub prior: Option<Prior>,
    /// The telerobot's cloud is the object's surface, slid with it: the operator moves each frame
    /// by the slide its own model predicts since the frame's capture (issue 13 item 6).
    #[serde(default)]
    pub cloud_follows_object: bool,
}

/// A `Welcome` the operator cannot run with.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// The control rate is outside [`RATE_RANGE_HZ`].
    #[error("the telerobot's control rate {0} Hz is out of range: expected 100 to 10 000 Hz")]
    Rate(f64),
    /// The contact detector's radii do not make a detector.
    #[error("the telerobot's contact detector: {0}")]
    Proxy(#[from] ProxyError),
    /// The scene's prior is not a passive model.
    #[error("the telerobot's scene {0}")]
    Prior(#[from] mmt::model::prior::PriorError),
    /// The scene's prior is passive but the renderers' gates refuse it for the scene's
    /// structures.
    #[error("the telerobot's scene prior cannot be rendered: {0}")]
    PriorRejected(mmt::model::gates::GateRejection),
}

impl OperatorSettings {
    /// The settings for the telerobot's scene summary: its structures, its rate and its
    /// detector's radii; the renderer's defaults at that rate.
    pub fn from_welcome(summary: &SceneSummary) -> Result<OperatorSettings, SettingsError> {
        let rate = summary.control_rate_hz;
        if !RATE_RANGE_HZ.contains(&rate) {
            return Err(SettingsError::Rate(rate));
        }
        let [r1_m, r2_m, r3_m] = summary.proxy_radii_m;
        let proxy = ProxyConfig {
            r1_m,
            r2_m,
            r3_m,
            rate_hz: rate,
            ..ProxyConfig::default()
        };
        proxy.validate()?;
        let normal = structure_from_wire(summary.normal);
        let tangential = structure_from_wire(summary.tangential);
        let prior = summary.prior.as_ref().map(prior_from_wire).transpose()?;
        if let Some(p) = &prior {
            gate_prior(p, normal, tangential).map_err(SettingsError::PriorRejected)?;
        }
        Ok(OperatorSettings {
            period_ns: (1e9 / rate).round() as i64,
            proxy,
            normal,
            tangential,
            renderer: RendererConfig {
                rate_hz: rate,
                ..RendererConfig::default()
            },
            prior,
            cloud_follows_object: summary.cloud_follows_object,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::structure_to_wire;

    fn summary(radii: [f64; 3], rate: f64) -> SceneSummary {
        SceneSummary {
            name: "test".to_owned(),
            normal: structure_to_wire(Structure::KelvinVoigt),
            tangential: structure_to_wire(Structure::SlidingMass {
                ground_spring: false,
                friction: true,
            }),
            control_rate_hz: rate,
            cloud_rate_hz: Some(30.0),
            left_out: vec![],
            proxy_radii_m: radii,
            prior: None,
            cloud_follows_object: true,
        }
    }

    #[test]
    fn the_telerobots_radii_structures_and_rate_are_used_and_checked() {
        let s = OperatorSettings::from_welcome(&summary([0.001, 0.003, 0.012], 500.0)).unwrap();
        assert_eq!(
            (s.proxy.r1_m, s.proxy.r2_m, s.proxy.r3_m),
            (0.001, 0.003, 0.012)
        );
        assert_eq!(
            (s.period_ns, s.proxy.rate_hz, s.renderer.rate_hz),
            (2_000_000, 500.0, 500.0)
        );
        assert_eq!(s.normal, Structure::KelvinVoigt);
        assert!(matches!(
            s.tangential,
            Structure::SlidingMass { friction: true, .. }
        ));
        let e = OperatorSettings::from_welcome(&summary([0.003, 0.001, 0.012], 1000.0));
        assert_eq!(
            e.unwrap_err().to_string(),
            "the telerobot's contact detector: r1_m = 0.003, r2_m = 0.001, r3_m = 0.012: \
             expected r1 < r2 < r3"
        );
    }

    #[test]
    fn a_rate_out_of_range_is_refused() {
        for rate in [50.0, 20_000.0, f64::NAN] {
            let e = OperatorSettings::from_welcome(&summary([0.001, 0.003, 0.012], rate));
            assert!(matches!(e, Err(SettingsError::Rate(_))), "{rate}");
        }
    }
}
