//! The operator node's settings from the telerobot's `Welcome`.
//!
//! A remote operator does not have the telerobot's scene file: the `Welcome`'s scene summary
//! says what to render (the model structure per axis group), at which rate, and the contact
//! detector's three radii, so the operator's local detector makes and breaks contact where the
//! telerobot's does. The renderer settings are operator-side (defaults at the control rate). The
//! scene inside the settings is a template whose ground truth the operator node never reads.

use mmt::contact::ProxyError;
use node::{NodeSettings, structure_from_wire};
use protocol::telerobot_to_operator::SceneSummary;
use sim::scene::{ProxySection, Scene};

/// The control rates the haptic loop runs at \[Hz\].
pub const RATE_RANGE_HZ: std::ops::RangeInclusive<f64> = 100.0..=10_000.0;

/// A `Welcome` the operator cannot run with.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// The control rate is outside [`RATE_RANGE_HZ`].
    #[error("the telerobot's control rate {0} Hz is out of range: expected 100 to 10 000 Hz")]
    Rate(f64),
    /// The contact detector's radii do not make a detector.
    #[error("the telerobot's contact detector: {0}")]
    Proxy(#[from] ProxyError),
}

/// The operator node's settings for the telerobot's scene summary.
pub fn node_settings(summary: &SceneSummary) -> Result<NodeSettings, SettingsError> {
    let rate = summary.control_rate_hz;
    if !RATE_RANGE_HZ.contains(&rate) {
        return Err(SettingsError::Rate(rate));
    }
    let [r1_m, r2_m, r3_m] = summary.proxy_radii_m;
    let proxy = ProxySection { r1_m, r2_m, r3_m };
    proxy.config(rate).validate()?;
    let mut scene = Scene::exp1();
    scene.name = summary.name.clone();
    scene.rates.control_hz = rate;
    scene.proxy = proxy;
    let mut settings = NodeSettings::from_scene(&scene);
    settings.normal.structure = structure_from_wire(summary.normal);
    settings.tangential.structure = structure_from_wire(summary.tangential);
    Ok(settings)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mmt::model::Structure;
    use node::structure_to_wire;

    fn summary(scene: &Scene) -> SceneSummary {
        SceneSummary {
            name: scene.name.clone(),
            normal: structure_to_wire(scene.model.normal_structure()),
            tangential: structure_to_wire(scene.model.tangential_structure()),
            control_rate_hz: scene.rates.control_hz,
            cloud_rate_hz: Some(scene.cloud.rate_hz),
            left_out: scene.left_out(),
            proxy_radii_m: [scene.proxy.r1_m, scene.proxy.r2_m, scene.proxy.r3_m],
        }
    }

    #[test]
    fn the_shipped_scenes_give_the_settings_of_their_files() {
        for scene in [Scene::exp1(), Scene::wall()] {
            let from_file = NodeSettings::from_scene(&scene);
            let remote = node_settings(&summary(&scene)).unwrap();
            assert_eq!(remote.period_ns, from_file.period_ns);
            assert_eq!(remote.proxy, from_file.proxy);
            assert_eq!(remote.renderer, from_file.renderer);
            assert_eq!(remote.normal.structure, from_file.normal.structure);
            assert_eq!(remote.tangential.structure, from_file.tangential.structure);
        }
        let wall = node_settings(&summary(&Scene::wall())).unwrap();
        assert_eq!(wall.tangential.structure, Structure::KelvinVoigt);
    }

    #[test]
    fn the_telerobots_radii_are_used_and_checked() {
        let mut scene = Scene::exp1();
        scene.proxy = ProxySection {
            r1_m: 0.001,
            r2_m: 0.003,
            r3_m: 0.012,
        };
        let settings = node_settings(&summary(&scene)).unwrap();
        assert_eq!(
            (
                settings.proxy.r1_m,
                settings.proxy.r2_m,
                settings.proxy.r3_m
            ),
            (0.001, 0.003, 0.012)
        );
        let mut s = summary(&scene);
        s.proxy_radii_m = [0.003, 0.001, 0.012];
        assert_eq!(
            node_settings(&s).unwrap_err().to_string(),
            "the telerobot's contact detector: r1_m = 0.003, r2_m = 0.001, r3_m = 0.012: \
             expected r1 < r2 < r3"
        );
    }

    #[test]
    fn a_rate_out_of_range_is_refused() {
        let mut s = summary(&Scene::exp1());
        s.control_rate_hz = 50.0;
        assert!(node_settings(&s).unwrap_err().to_string().contains("50 Hz"));
    }
}
