//! The real-time budget of a point cloud: whether the proxy can step on it at the loop rate, and
//! whether its frames can be indexed at the camera rate, estimated before the cloud reaches a
//! loop (issue 11, item 5).
//!
//! # The model
//!
//! - **Per tick.** A proxy step visits the points within its largest query radius `R`
//!   ([`query_radius_m`]: the wide plane's `2 r3` where the proxy bridges holes, else half a
//!   sweep segment plus `r3`, plus the reuse margin: 61 mm at the exp-1 radii, 24.5 mm at the
//!   defaults) once per query, and a worst tick runs several queries
//!   (two sweeps of up to four segments) and the surface passes over the same points. Its cost
//!   is therefore `fixed + per_point · P`, `P` the most points any ball of radius `R` holds. `P`
//!   comes from the cloud's density: [`points_in_ball`] for any point set (counts on a grid of
//!   cells of edge `≈ R/2`: a bound, about 2–2.7× the true count on a surface),
//!   [`grid_points_in_ball`] the same bound for a square grid of known spacing, without the
//!   points. The step must fit in [`CloudBudget::step_share`] of the tick.
//! - **Per frame.** Building a frame's kd-tree and density bound costs about
//!   `build_ns_per_point` per point off the loop (the camera thread, the operator's helper), and
//!   a 2-core machine also runs both 1 kHz loops: `points · frame rate · build cost` must stay
//!   within [`CloudBudget::index_share`] of one core. A frame also has at most
//!   [`CloudBudget::max_points`] points (memory, wire size, a one-off build).
//!
//! The costs are figures measured on the reference machine (`mmt cloud-budget`, README
//! "Point-cloud budget"); the estimate is pure arithmetic on them — no clock is read here.

use std::collections::HashMap;
use std::hash::BuildHasherDefault;

use thiserror::Error;

use super::ProxyConfig;
use super::density::CellHasher;

/// The proxy's largest query radius [m] for `config`: every point a step can visit lies within
/// it of some query centre.
pub fn query_radius_m(config: &ProxyConfig) -> f64 {
    super::proxy::max_query_radius_m(config)
}

/// Why a budget estimate cannot be made.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum BudgetError {
    /// A radius or spacing is not a finite number > 0.
    #[error("{field} = {value} m, expected a finite length > 0")]
    NotPositive {
        /// The quantity.
        field: &'static str,
        /// Its value [m].
        value: f64,
    },
    /// A point has a NaN or infinite coordinate.
    #[error("point {index} is {point:?}, expected finite coordinates")]
    NonFinitePoint {
        /// Index of the point.
        index: usize,
        /// The point [m].
        point: [f32; 3],
    },
}

/// [`points_in_ball`] of a square grid of spacing `spacing_m` [m] in an axis-aligned plane,
/// without the points: a block of five cells of edge `c = R/1.999` spans `5c` along each
/// in-plane axis and holds at most `⌊5c/s⌋ + 1` grid points along it, so
/// `(⌊5c/s⌋ + 1)²`. The same bound as for a point set (the cost per point is calibrated on it),
/// about twice the `π R²/s²` points really in the ball.
pub fn grid_points_in_ball(spacing_m: f64, radius_m: f64) -> Result<usize, BudgetError> {
    positive("spacing_m", spacing_m)?;
    positive("radius_m", radius_m)?;
    let per_axis = (5.0 * radius_m / CELLS_PER_RADIUS / spacing_m).floor() + 1.0;
    Ok((per_axis * per_axis).min(usize::MAX as f64) as usize)
}

/// Cells per query radius of [`points_in_ball`]'s grid: just under 2, so that a ball spans
/// less than two cells either side of the cell its centre is in, whatever the rounding.
const CELLS_PER_RADIUS: f64 = 1.999;

/// At least the number of `points` [m] within `radius_m` [m] of any centre.
///
/// The points are counted in cubic cells of edge `c = R/1.999`: a ball whose centre lies in a
/// cell spans less than `2c` either side of it, so its points lie in the `5 × 5 × 5` cells
/// around; the bound is the largest such block sum over all cells (each occupied cell adds its
/// count to the 125 blocks it belongs to). On a surface the block covers about twice the
/// ball's disc; coincident points are counted as many times as they occur. Cost: 125 map
/// updates per occupied cell.
pub fn points_in_ball(points: &[[f32; 3]], radius_m: f64) -> Result<usize, BudgetError> {
    positive("radius_m", radius_m)?;
    let cell_m = radius_m / CELLS_PER_RADIUS;
    let mut cells: CellMap = HashMap::default();
    for (index, p) in points.iter().enumerate() {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(BudgetError::NonFinitePoint { index, point: *p });
        }
        // Saturating casts: points beyond ±2e9 cells (2e6 m at 1 mm) share the edge cells,
        // which only loosens the bound.
        let key = p.map(|v| (f64::from(v) / cell_m).floor() as i32);
        *cells.entry((key[0], key[1], key[2])).or_insert(0) += 1;
    }
    let mut blocks: CellMap = HashMap::default();
    blocks.reserve(cells.len() * 8);
    for (&(i, j, k), &n) in &cells {
        for di in -2..=2 {
            for dj in -2..=2 {
                for dk in -2..=2 {
                    let key = (
                        i.saturating_add(di),
                        j.saturating_add(dj),
                        k.saturating_add(dk),
                    );
                    *blocks.entry(key).or_insert(0) += n;
                }
            }
        }
    }
    Ok(blocks.values().copied().max().unwrap_or(0))
}

type CellMap = HashMap<(i32, i32, i32), usize, BuildHasherDefault<CellHasher>>;

fn positive(field: &'static str, value: f64) -> Result<(), BudgetError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(BudgetError::NotPositive { field, value })
    }
}

/// What a cloud may cost, and the measured costs the estimate is made of. The defaults are
/// this project's 2-core reference machine; a scene's `[cloud.budget]` table overrides any of
/// them for a faster (or slower) robot PC.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CloudBudget {
    /// Fraction of a tick (`1/rate_hz` of the proxy) its worst step may take. Default 0.25: the
    /// haptic tick also renders, exchanges messages and waits on a shared 2-core machine.
    pub step_share: f64,
    /// Fixed cost of a worst-case step [ns], whatever the cloud. Default 10,000: a worst tick
    /// on a sparse plane is 4–6 µs (`mmt cloud-budget`), doubled.
    pub step_fixed_ns: f64,
    /// Cost of a worst-case step per point of the bound on the largest query ball
    /// ([`points_in_ball`], about 2.7 times the most one query visits on a plane) [ns/point].
    /// Default 10: the median worst tick (four queries) measured 4.2 ns per bound point
    /// (11 ns per visited point) on planes of 0.25–4.5 mm (`mmt cloud-budget`, loaded 2-core
    /// machine), with a margin of about 2.3 for the ticks above the median.
    pub step_ns_per_point: f64,
    /// Fraction of one core the indexing of a moving cloud's frames may take. Default 0.25:
    /// the camera thread and the operator's helper each index every frame, next to two 1 kHz
    /// loops on two cores.
    pub index_share: f64,
    /// Cost of indexing one point (kd-tree and density bound) [ns/point]. Default 150: 130–220
    /// measured for 63 k – 1 M points on the loaded reference machine (`mmt cloud-budget`),
    /// about 80 when it is idle (`mmt contact-bench`).
    pub build_ns_per_point: f64,
    /// Most points in one frame, whatever the rate. Default 1,000,000: an index holds about
    /// 30 bytes per point (resident, `mmt cloud-budget`) and each side keeps up to five (the
    /// last four and the loop's) plus frames in flight at 12 bytes per point — about 170 MB per
    /// process at this limit (the 4.9 M-point cloud of the finding took 0.9 GB) — and a static
    /// cloud's one-off build stays near 0.15 s.
    pub max_points: usize,
}

impl CloudBudget {
    /// Name, value and expectation of the first field out of its range, if any.
    pub fn invalid_field(&self) -> Option<(&'static str, f64, &'static str)> {
        let share = |v: f64| v.is_finite() && v > 0.0 && v <= 1.0;
        let cost = |v: f64, most: f64| v.is_finite() && v > 0.0 && v <= most;
        let checks = [
            (
                "step_share",
                self.step_share,
                share(self.step_share),
                "a share of the tick in (0, 1]",
            ),
            (
                "step_fixed_ns",
                self.step_fixed_ns,
                self.step_fixed_ns.is_finite() && (0.0..=1e6).contains(&self.step_fixed_ns),
                "in [0, 1,000,000] ns",
            ),
            (
                "step_ns_per_point",
                self.step_ns_per_point,
                cost(self.step_ns_per_point, 1e4),
                "in (0, 10,000] ns per point",
            ),
            (
                "index_share",
                self.index_share,
                share(self.index_share),
                "a share of one core in (0, 1]",
            ),
            (
                "build_ns_per_point",
                self.build_ns_per_point,
                cost(self.build_ns_per_point, 1e5),
                "in (0, 100,000] ns per point",
            ),
            (
                "max_points",
                self.max_points as f64,
                (1..=4 * 1024 * 1024).contains(&self.max_points),
                "1 to 4,194,304 points (the largest cloud the protocol carries)",
            ),
        ];
        checks
            .into_iter()
            .find(|(_, _, ok, _)| !ok)
            .map(|(name, value, _, expected)| (name, value, expected))
    }
}

impl Default for CloudBudget {
    fn default() -> Self {
        Self {
            step_share: 0.25,
            step_fixed_ns: 10_000.0,
            step_ns_per_point: 10.0,
            index_share: 0.25,
            build_ns_per_point: 150.0,
            max_points: 1_000_000,
        }
    }
}

/// A cloud's estimated load on the loops.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CloudLoad {
    /// Points in a frame.
    pub points: usize,
    /// At least the points within [`CloudLoad::query_radius_m`] of any centre.
    pub points_in_ball: usize,
    /// The proxy's largest query radius [m].
    pub query_radius_m: f64,
    /// Estimated worst-case proxy step [µs].
    pub worst_step_us: f64,
    /// The tick's share the step may take [µs].
    pub step_limit_us: f64,
    /// Estimated indexing time of one frame [ms].
    pub build_ms: f64,
    /// Frames indexed per second (`None`: a static cloud, indexed once).
    pub frame_rate_hz: Option<f64>,
}

/// Which part of the budget a cloud exceeds.
#[derive(Debug, Clone, Copy, PartialEq, Error)]
pub enum OverBudget {
    /// The worst proxy step would exceed its share of the tick.
    #[error(
        "up to {points_in_ball} points within the proxy's {radius_mm:.1} mm query radius: a \
         worst-case step of about {worst_step_us:.0} µs, over its {limit_us:.0} µs share of the \
         tick (at most {max_points_in_ball} points)"
    )]
    Step {
        /// The estimate.
        points_in_ball: usize,
        /// The most that fits.
        max_points_in_ball: usize,
        /// Query radius [mm].
        radius_mm: f64,
        /// Estimated worst step [µs].
        worst_step_us: f64,
        /// The step's share of the tick [µs].
        limit_us: f64,
    },
    /// The frames are too large for their rate (or at all).
    #[error(
        "{points} points per frame{rate}: indexing needs about {build_ms:.0} ms per frame, \
         over the budget of {max_points} points per frame",
        rate = frame_rate_hz.map_or_else(String::new, |r| format!(" at {r} Hz"))
    )]
    Frame {
        /// Points per frame.
        points: usize,
        /// The most that fits.
        max_points: usize,
        /// Frame rate [Hz] (`None`: static).
        frame_rate_hz: Option<f64>,
        /// Estimated index build [ms].
        build_ms: f64,
    },
}

impl CloudBudget {
    /// The most points the largest query ball may hold at the proxy's rate.
    pub fn max_points_in_ball(&self, config: &ProxyConfig) -> usize {
        let tick_ns = 1e9 / config.rate_hz;
        let spare = self.step_share * tick_ns - self.step_fixed_ns;
        (spare / self.step_ns_per_point).max(0.0) as usize
    }

    /// The most points per frame at `frame_rate_hz` (`None`: a static cloud).
    pub fn max_points(&self, frame_rate_hz: Option<f64>) -> usize {
        match frame_rate_hz {
            Some(rate) if rate > 0.0 => {
                let per_frame = self.index_share * 1e9 / (rate * self.build_ns_per_point);
                self.max_points.min(per_frame.max(0.0) as usize)
            }
            _ => self.max_points,
        }
    }

    /// The load of a cloud of `points` points, at most `points_in_ball` of them in the query ball
    /// of `config`, indexed at `frame_rate_hz`.
    pub fn load(
        &self,
        config: &ProxyConfig,
        points: usize,
        points_in_ball: usize,
        frame_rate_hz: Option<f64>,
    ) -> CloudLoad {
        CloudLoad {
            points,
            points_in_ball,
            query_radius_m: query_radius_m(config),
            worst_step_us: (self.step_fixed_ns + self.step_ns_per_point * points_in_ball as f64)
                / 1e3,
            step_limit_us: self.step_share * 1e6 / config.rate_hz,
            build_ms: self.build_ns_per_point * points as f64 / 1e6,
            frame_rate_hz,
        }
    }

    /// Whether `load` fits; the first part it exceeds otherwise (the step first).
    pub fn check(&self, config: &ProxyConfig, load: &CloudLoad) -> Result<(), OverBudget> {
        let max_in_ball = self.max_points_in_ball(config);
        if load.points_in_ball > max_in_ball {
            return Err(OverBudget::Step {
                points_in_ball: load.points_in_ball,
                max_points_in_ball: max_in_ball,
                radius_mm: load.query_radius_m * 1e3,
                worst_step_us: load.worst_step_us,
                limit_us: load.step_limit_us,
            });
        }
        let max_points = self.max_points(load.frame_rate_hz);
        if load.points > max_points {
            return Err(OverBudget::Frame {
                points: load.points,
                max_points,
                frame_rate_hz: load.frame_rate_hz,
                build_ms: load.build_ms,
            });
        }
        Ok(())
    }

    /// How much a surface cloud's spacing must grow for `load` to fit (1 when it fits): points
    /// per frame and per ball both fall as `1/spacing²` on a surface.
    pub fn spacing_factor(&self, config: &ProxyConfig, load: &CloudLoad) -> f64 {
        let in_ball = load.points_in_ball as f64 / self.max_points_in_ball(config).max(1) as f64;
        let frame = load.points as f64 / self.max_points(load.frame_rate_hz).max(1) as f64;
        in_ball.max(frame).max(1.0).sqrt()
    }
}

#[cfg(test)]
mod tests;
