//! The simulated camera's cloud held to the real-time budget at scene load
//! (`mmt::contact::budget`): a plane window whose worst proxy step or whose frames at
//! `cloud.rate_hz` would not fit gets a coarser grid (the camera's "voxel"), and the scene
//! says so; a cloud that would need a grid the proxy can slip through is refused.
//!
//! Pure: the loaders log the warning ([`Scene::cloud_budget`]).

use std::fmt;

use mmt::contact::budget::{self, CloudBudget, CloudLoad, OverBudget};

use super::{CloudKind, Scene, SceneError};

/// What the budget did to a scene's simulated cloud: the spacing it had, the one it got, and
/// why.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudBudgetFit {
    /// The scene's spacing [m].
    pub spacing_from_m: f64,
    /// The spacing used [m].
    pub spacing_to_m: f64,
    /// The load at the scene's spacing.
    pub before: CloudLoad,
    /// The load at the spacing used.
    pub after: CloudLoad,
    /// What the scene's spacing exceeded.
    pub reason: OverBudget,
}

impl fmt::Display for CloudBudgetFit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "[cloud] plane at spacing_m = {} ({} points per frame) is over the real-time budget: \
             {}; downsampled to spacing_m = {:.6}: {} points per frame, at most {} in the query \
             ball (worst step ≈ {:.0} µs, index ≈ {:.1} ms per frame)",
            self.spacing_from_m,
            self.before.points,
            self.reason,
            self.spacing_to_m,
            self.after.points,
            self.after.points_in_ball,
            self.after.worst_step_us,
            self.after.build_ms
        )
    }
}

/// The load of a plane window of `size_m` at `spacing_m` under `proxy`, at `rate_hz` frames per
/// second (`None`: sent once).
fn plane_load(
    budget: &CloudBudget,
    scene: &Scene,
    spacing_m: f64,
) -> Result<CloudLoad, SceneError> {
    let c = &scene.cloud;
    let proxy = scene.proxy.config(scene.rates.control_hz);
    let in_ball =
        budget::grid_points_in_ball(spacing_m, budget::query_radius_m(&proxy)).map_err(|e| {
            SceneError::CloudBudget {
                origin: String::new(),
                detail: e.to_string(),
            }
        })?;
    let per_axis = |size: f64| (size / spacing_m).floor() as usize + 1;
    let points = per_axis(c.size_m[0]).saturating_mul(per_axis(c.size_m[1]));
    let rate = c.moving.then_some(c.rate_hz);
    Ok(budget.load(&proxy, points, in_ball.min(points), rate))
}

impl Scene {
    /// What the real-time budget did to this scene's cloud at load (`None`: nothing; always
    /// `None` unless `[cloud] source = "plane"`). Loaders show it as a warning.
    pub fn cloud_budget(&self) -> Option<&CloudBudgetFit> {
        self.cloud_budget.as_ref()
    }

    /// Holds a `plane` cloud to `budget`: grows `cloud.spacing_m` until the worst proxy step and
    /// the frames fit, or refuses the scene when that spacing is at or beyond the largest the
    /// plane may have (`max_plane_spacing_m`, the limit `validate` applies).
    pub(super) fn fit_cloud_budget(&mut self, budget: &CloudBudget) -> Result<(), SceneError> {
        if self.cloud.source != CloudKind::Plane {
            return Ok(());
        }
        let proxy = self.proxy.config(self.rates.control_hz);
        let from = self.cloud.spacing_m;
        let before = plane_load(budget, self, from)?;
        let Err(reason) = budget.check(&proxy, &before) else {
            return Ok(());
        };
        let slip_m = self.max_plane_spacing_m();
        let mut spacing = from * budget.spacing_factor(&proxy, &before);
        for _ in 0..32 {
            let load = plane_load(budget, self, spacing)?;
            if budget.check(&proxy, &load).is_ok() {
                break;
            }
            spacing *= 1.02;
        }
        let after = plane_load(budget, self, spacing)?;
        if spacing >= slip_m || budget.check(&proxy, &after).is_err() {
            return Err(SceneError::CloudBudget {
                origin: String::new(),
                detail: format!(
                    "spacing_m = {from} is over the real-time budget at {} Hz: {reason}. Fitting \
                     needs a spacing of {:.2} mm, at or beyond the {:.2} mm the proxy slips \
                     through or its plane lacks points (√2·(r1+r2)/2, and 48 points within \
                     r3); make proxy.r3_m or cloud.size_m smaller, or cloud.rate_hz lower",
                    proxy.rate_hz,
                    spacing * 1e3,
                    slip_m * 1e3
                ),
            });
        }
        self.cloud.spacing_m = spacing;
        self.cloud_budget = Some(CloudBudgetFit {
            spacing_from_m: from,
            spacing_to_m: spacing,
            before,
            after,
            reason,
        });
        Ok(())
    }
}
