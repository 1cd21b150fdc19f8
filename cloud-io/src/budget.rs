//! A cloud held to the real-time budget (`mmt::contact::budget`) by voxel downsampling: what a
//! cloud file, a camera frame or a frame received from a peer goes through before it is indexed
//! for a 1 kHz loop.
//!
//! The frame size is brought in first (cheap: a count), then the points in the proxy's query
//! ball (estimated on the points, `budget::points_in_ball`); each round grows the voxel by the
//! square root of the worst ratio (a surface's points scale with `1/voxel²`), at least 5 %. A
//! voxel at or beyond the largest spacing the proxy cannot slip through
//! ([`ProxyConfig::max_point_spacing_m`]) is refused instead: coarser centroids would let the
//! proxy through the surface.

use mmt::contact::ProxyConfig;
use mmt::contact::budget::{self, BudgetError, CloudBudget, CloudLoad, OverBudget};
use thiserror::Error;

use crate::voxel::{VoxelError, VoxelGrid, initial_voxel};

/// Most downsampling rounds before giving up (each grows the voxel by at least 5 %).
const ROUNDS: usize = 24;

/// What the budget did to a cloud.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BudgetFit {
    /// The load as given.
    pub before: CloudLoad,
    /// What it exceeded.
    pub reason: OverBudget,
    /// The voxel edge used [m].
    pub voxel_m: f64,
    /// The load after downsampling.
    pub after: CloudLoad,
}

impl std::fmt::Display for BudgetFit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} points over the real-time budget ({}); voxel-downsampled at {:.2} mm to {} \
             points, at most {} in the query ball (worst step ≈ {:.0} µs)",
            self.before.points,
            self.reason,
            self.voxel_m * 1e3,
            self.after.points,
            self.after.points_in_ball,
            self.after.worst_step_us
        )
    }
}

/// Why a cloud cannot be brought within the budget.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BudgetFitError {
    /// The points or the radii cannot be estimated (a NaN point, a bad radius).
    #[error("point-cloud budget: {0}")]
    Estimate(#[from] BudgetError),
    /// The voxel grid refused the points.
    #[error("point-cloud budget: voxel grid: {0}")]
    Voxel(#[from] VoxelError),
    /// Only a voxel the proxy slips through would bring it in.
    #[error(
        "{points} points cannot run at the loop rate: {reason}; fitting needs a voxel of \
         {voxel_mm:.2} mm or more, beyond the {slip_mm:.2} mm the proxy slips through \
         (√2·(r1+r2)/2): reduce the cloud (voxel_m, max_points) or proxy.r3_m"
    )]
    TooDense {
        /// Points given.
        points: usize,
        /// What the last attempt exceeded.
        reason: OverBudget,
        /// The voxel that would be needed [mm].
        voxel_mm: f64,
        /// The proxy's slip spacing [mm].
        slip_mm: f64,
    },
}

/// Holds `points` [m] to `budget` for a proxy with `proxy`'s radii and rate, frames indexed at
/// `frame_rate_hz` (`None`: once). Leaves them untouched and returns `None` when they fit;
/// otherwise replaces them with their voxel centroids at the first voxel that fits and says
/// what it did. `grid` is reused scratch.
pub fn fit_to_budget(
    points: &mut Vec<[f32; 3]>,
    proxy: &ProxyConfig,
    budget: &CloudBudget,
    frame_rate_hz: Option<f64>,
    grid: &mut VoxelGrid,
) -> Result<Option<BudgetFit>, BudgetFitError> {
    let radius = budget::query_radius_m(proxy);
    let max_points = budget.max_points(frame_rate_hz);
    let load_of = |pts: &[[f32; 3]]| -> Result<CloudLoad, BudgetFitError> {
        // A frame over the size limit is not estimated (125 map updates per occupied cell);
        // its ball is taken as every point, which only makes the first voxel coarser.
        let in_ball = if pts.len() > max_points {
            pts.len()
        } else {
            budget::points_in_ball(pts, radius)?.min(pts.len())
        };
        Ok(budget.load(proxy, pts.len(), in_ball, frame_rate_hz))
    };
    let before = load_of(points)?;
    let Err(reason) = budget.check(proxy, &before) else {
        return Ok(None);
    };
    let slip_m = proxy.max_point_spacing_m();
    let mut voxel = initial_voxel(points) * budget.spacing_factor(proxy, &before).max(1.05);
    let mut out = Vec::new();
    let mut last = reason;
    for _ in 0..ROUNDS {
        if voxel >= slip_m {
            break;
        }
        grid.downsample(points, voxel, &mut out)?;
        let after = load_of(&out)?;
        match budget.check(proxy, &after) {
            Ok(()) => {
                *points = out;
                return Ok(Some(BudgetFit {
                    before,
                    reason,
                    voxel_m: voxel,
                    after,
                }));
            }
            Err(r) => {
                last = r;
                voxel *= budget.spacing_factor(proxy, &after).max(1.05);
            }
        }
    }
    Err(BudgetFitError::TooDense {
        points: points.len(),
        reason: last,
        voxel_mm: voxel * 1e3,
        slip_mm: slip_m * 1e3,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A square grid of `n × n` points of spacing `s` in `z = 0`.
    fn grid(n: usize, s: f32) -> Vec<[f32; 3]> {
        (0..n)
            .flat_map(|i| (0..n).map(move |j| [i as f32 * s, j as f32 * s, 0.0]))
            .collect()
    }

    fn exp1() -> ProxyConfig {
        ProxyConfig {
            r1_m: 0.004,
            r2_m: 0.006,
            r3_m: 0.03,
            ..ProxyConfig::default()
        }
    }

    #[test]
    fn a_cloud_within_the_budget_is_untouched() {
        let mut points = grid(56, 0.0045);
        let copy = points.clone();
        let fit = fit_to_budget(
            &mut points,
            &exp1(),
            &CloudBudget::default(),
            Some(30.0),
            &mut VoxelGrid::new(),
        );
        assert_eq!(fit, Ok(None));
        assert_eq!(points, copy);
    }

    #[test]
    fn a_dense_cloud_is_downsampled_until_it_fits() {
        // 0.25 m at 0.25 mm: a million points, ~107,000 in the exp-1 query ball.
        let mut points = grid(1_001, 0.00025);
        let b = CloudBudget::default();
        let fit = fit_to_budget(&mut points, &exp1(), &b, Some(30.0), &mut VoxelGrid::new())
            .unwrap()
            .expect("over the budget");
        assert_eq!(fit.before.points, 1_002_001);
        assert!(fit.after.points == points.len() && points.len() <= b.max_points(Some(30.0)));
        assert!(fit.after.points_in_ball <= b.max_points_in_ball(&exp1()));
        assert!(fit.voxel_m < exp1().max_point_spacing_m());
        // The estimate on the result is what was reported.
        let ball = budget::points_in_ball(&points, budget::query_radius_m(&exp1())).unwrap();
        assert_eq!(ball.min(points.len()), fit.after.points_in_ball);
        let text = fit.to_string();
        assert!(
            text.starts_with("1002001 points over the real-time budget"),
            "{text}"
        );
        assert!(text.contains("voxel-downsampled at"), "{text}");
    }

    #[test]
    fn a_cloud_that_needs_a_voxel_the_proxy_slips_through_is_refused() {
        // r1 1 mm, r2 3 mm (slip spacing 2.83 mm), r3 100 mm (a 154 mm query ball): a solid
        // 78 mm block at 2 mm lies within one ball, and even at 2.83 mm it is ~21,000 points.
        let mut points: Vec<[f32; 3]> = (0..40)
            .flat_map(|i| {
                (0..40).flat_map(move |j| {
                    (0..40).map(move |k| [i as f32 * 0.002, j as f32 * 0.002, k as f32 * 0.002])
                })
            })
            .collect();
        let wide = ProxyConfig {
            r3_m: 0.1,
            ..ProxyConfig::default()
        };
        let e = fit_to_budget(
            &mut points,
            &wide,
            &CloudBudget::default(),
            Some(30.0),
            &mut VoxelGrid::new(),
        )
        .unwrap_err();
        assert!(
            matches!(e, BudgetFitError::TooDense { points: 64_000, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("the proxy slips through"), "{e}");
        assert_eq!(points.len(), 64_000);
    }

    #[test]
    fn garbage_is_an_error_not_a_panic() {
        let mut points = vec![[0.0, f32::NAN, 0.0]; 3];
        let e = fit_to_budget(
            &mut points,
            &exp1(),
            &CloudBudget::default(),
            None,
            &mut VoxelGrid::new(),
        )
        .unwrap_err();
        assert!(e.to_string().contains("point 0"), "{e}");
        let mut empty = Vec::new();
        let fit = fit_to_budget(
            &mut empty,
            &exp1(),
            &CloudBudget::default(),
            None,
            &mut VoxelGrid::new(),
        );
        assert_eq!(fit, Ok(None));
    }
}
