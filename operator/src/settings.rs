//! The operator node's settings from the telerobot's `Welcome`.
//!
//! A remote operator does not have the telerobot's scene file: the `Welcome`'s scene summary
//! says what to render (the model structure per axis group) and at which rate. Everything else
//! the operator node uses is operator-side: the renderer settings (defaults at the control rate)
//! and the contact detector's three radii, which the summary does not carry — they are the
//! defaults every shipped scene uses (`mmt::scene::ProxySection::default`: 4, 6 and 30 mm). The
//! scene inside the settings is a template whose ground truth the operator node never reads.

use mmt::node::{NodeSettings, structure_from_wire};
use mmt::scene::{ProxySection, Scene};
use protocol::telerobot_to_operator::SceneSummary;

/// The control rates the haptic loop runs at \[Hz\].
pub const RATE_RANGE_HZ: std::ops::RangeInclusive<f64> = 100.0..=10_000.0;

/// A `Welcome` the operator cannot run with.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("the telerobot's control rate {0} Hz is out of range: expected 100 to 10 000 Hz")]
pub struct RateError(pub f64);

/// The operator node's settings for the telerobot's scene summary.
pub fn node_settings(summary: &SceneSummary) -> Result<NodeSettings, RateError> {
    let rate = summary.control_rate_hz;
    if !RATE_RANGE_HZ.contains(&rate) {
        return Err(RateError(rate));
    }
    let mut scene = Scene::exp1();
    scene.name = summary.name.clone();
    scene.rates.control_hz = rate;
    scene.proxy = ProxySection::default();
    let mut settings = NodeSettings::from_scene(&scene);
    settings.normal.structure = structure_from_wire(summary.normal);
    settings.tangential.structure = structure_from_wire(summary.tangential);
    Ok(settings)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mmt::model::Structure;
    use mmt::node::structure_to_wire;

    fn summary(scene: &Scene) -> SceneSummary {
        SceneSummary {
            name: scene.name.clone(),
            normal: structure_to_wire(scene.model.normal_structure()),
            tangential: structure_to_wire(scene.model.tangential_structure()),
            control_rate_hz: scene.rates.control_hz,
            cloud_rate_hz: Some(scene.cloud.rate_hz),
            left_out: scene.left_out(),
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
    fn a_rate_out_of_range_is_refused() {
        let mut s = summary(&Scene::exp1());
        s.control_rate_hz = 50.0;
        assert!(node_settings(&s).unwrap_err().to_string().contains("50 Hz"));
    }
}
