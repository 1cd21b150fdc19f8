//! Holes in the cloud, bridged by the fitted plane.
//!
//! A depth camera leaves holes: single missing pixels (10–40 % of them at grazing angles and on
//! dark surfaces) and patches of several centimetres where a surface is reflective or black. The
//! thesis's proxy (appendix C) touches *points*: above a hole wider than its rest sphere it finds
//! no point within `r2`, reports free space, and its free step sweeps into the hole toward the
//! HIP, which is below the surface. Once through, it reads the surface from the wrong side
//! (inverted contact). Measured before this module: exp 3 with 10 % random dropout, 88 % error
//! after stable, every contact from 13 s on lost or inverted.
//!
//! Where the points around the proxy are a plane with holes in it, the proxy touches the
//! **plane** instead: the moving-least-squares surface `f(x) = n(x)·(x − a(x))` of Adamson and
//! Alexa ("Approximating and intersecting surfaces from points", SGP 2003), with `a` the
//! Wendland-weighted centroid and `n` the normal of the weighted plane fit of eq. 14–15 — the
//! quantities the proxy computes already. The plane bridges the points at a position when
//! - they span a plane within the proxy's noise band: their weighted RMS distance to the fitted
//!   plane, `√λ_min`, is at most [`MAX_RESIDUAL_OF_BAND`] (0.6) of `r2 − r1`, the band the radii
//!   are chosen for (the scene validation holds the noise to half of it,
//!   [`super::ProxyConfig`]);
//! - they **surround** the foot of the position on that plane: seen from the foot, no empty
//!   angular sector of the plane is wider than about [`MAX_GAP_DEG`] (150°). Beyond an edge of
//!   a surface every point lies in one half-plane (an empty sector of 180° or more); inside a
//!   round hole of radius `R` the widest empty sector seen from anywhere in it stays under 150°
//!   while `R` is under 0.97 of the support's in-plane reach (computed), so holes of nearly
//!   `r3` in radius are bridged wherever the proxy is over them;
//! - they are enough: at least [`MIN_POINTS`] effective points.
//!
//! Where the points within `r3` lack points around the foot, the proxy fits the plane once more
//! over `2 r3` (`proxy.rs`): a patch of several centimetres is surrounded at that scale, an
//! edge still is not.
//!
//! Points standing more than [`OBSTACLE_OF_RESIDUAL`] standard deviations of the fit above the
//! plane, that height held to [`OBSTACLE_BANDS`] of the band (half a band for a perfect fit), are not noise on it but
//! something on the surface (a cable, a step, a box on the table): they stay obstacles the proxy
//! touches as points. Neither they nor points as far below the plane (the table past the edge
//! of a board lying on it) count toward surrounding the foot. Where the points are not a plane within the band
//! at all — edges, corners, curved or stepped surfaces — the proxy touches the points exactly
//! as the thesis's does. Noise no longer decides contact where the plane bridges: the proxy
//! rests at `(r1 + r2)/2` from the fitted plane, not from whichever noisy point is highest.

use super::SurfaceFrame;
use super::distance::{clearing_distance, first_touch};
use super::neighbours::Neighbour;
use crate::vec3::{self, Vec3};

/// The widest empty angular sector around the foot that still counts as surrounded [°].
/// Beyond an edge every point is in one half-plane: 180° or more. 150° keeps five bins of
/// margin for the binning and the grid; within a hole it is the far side's reach that matters.
pub const MAX_GAP_DEG: f64 = 150.0;

/// How far the points may lie from a bridging plane: their weighted RMS distance at most this
/// share of the band `r2 − r1`. The scene rule holds the noise to half the band (`r2 − r1` ≥
/// 2σ); a fifth more leaves room for the fit, and something standing on the surface that lifts
/// the fit further (a 4 mm cable on the exp-1 table: 1.6 mm against the 1.2 mm allowed) leaves
/// the points to the thesis's proxy.
pub const MAX_RESIDUAL_OF_BAND: f64 = 0.6;

/// Fewest points a bridging plane rests on, counted as the fit's effective number
/// `(Σψ)²/Σψ²`: a plane through fewer says little, and the Wendland weights can let two or three
/// points near the foot outweigh a ring of far ones (measured at the rim of a hole patch: 26
/// points, 6.8 effective, the plane tilted 5°). A full plane at the exp-1 spacing and radii has
/// 35–40.
pub const MIN_POINTS: f64 = 12.0;

/// Angular bins of the enclosure test, one bit each: 5.6° per bin.
const BINS: u32 = 64;

/// Empty runs of this many bins or more are gaps of about [`MAX_GAP_DEG`] or more: a run of
/// `k` empty bins is a gap between `k` and `k + 2` bin widths, so the cut-off is blurred by a
/// bin either side (26 bins: 146–158°; 25 accepted: 141–152°).
const MAX_EMPTY_BINS: u32 = (MAX_GAP_DEG / 360.0 * BINS as f64) as u32;

/// A point standing more than this many standard deviations of the fit (its RMS residual)
/// above the bridging plane is not noise on it but something on the surface — a cable, a step,
/// a box on the table — and the proxy touches it as a point, as the thesis's does. Gaussian
/// noise puts one point in 30,000 that high.
pub const OBSTACLE_OF_RESIDUAL: f64 = 4.0;

/// The obstacle height is held between these many bands (`r2 − r1`): not below half a band,
/// where a nearly exact cloud would make every grid ripple an obstacle, and not above one and a
/// half, three standard deviations of the largest noise the band is chosen for (`ProxyConfig`:
/// `r2 − r1` ≥ 2σ), so that a noisy fit does not hide what stands on it.
pub const OBSTACLE_BANDS: [f64; 2] = [0.5, 1.5];

/// The plane fitted at a position, as the surface module computes it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Fit {
    /// Unit normal toward the position.
    pub normal: Vec3,
    /// Height of the position above the plane along `normal` [m].
    pub height_m: f64,
    /// Weighted RMS distance of the points to the plane [m].
    pub residual_m: f64,
    /// The fit's effective number of points, `(Σψ)²/Σψ²`.
    pub effective_points: f64,
}

/// A plane that bridges the points around a position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct BridgePlane {
    /// Height of the position above the plane along the surface's normal [m]: ≥ 0 as fitted
    /// (the normal is oriented toward the position); negative once the proxy keeps the side it
    /// was touching from (`proxy.rs`).
    pub height_m: f64,
    /// Points higher than this above the plane are obstacles [m] ([`OBSTACLE_OF_RESIDUAL`]
    /// standard deviations of the fit, held to [`OBSTACLE_BANDS`] of the band).
    pub obstacle_above_m: f64,
    /// Squared distance [m²] from the position to the nearest obstacle (∞ without one).
    pub obstacle_d2: f64,
}

impl BridgePlane {
    /// Whether the point at offset `y` from the position stands out of the plane of unit normal
    /// `n` as an obstacle.
    pub(crate) fn is_obstacle(&self, y: Vec3, n: Vec3) -> bool {
        vec3::dot(y, n) + self.height_m > self.obstacle_above_m
    }

    /// The squared distance eq. 15's states are read from: to the plane (negative below it)
    /// or to the nearest obstacle, whichever is nearer.
    pub(crate) fn distance2(&self) -> f64 {
        (self.height_m * self.height_m.abs()).min(self.obstacle_d2)
    }

    /// Eq. 16 on the plane: how far the proxy can move along the unit `dir`, at most `reach`
    /// [m], before it comes within `rest` of the plane (of unit normal `n`) or of an obstacle
    /// among the points at offsets `points` from it.
    pub(crate) fn free_reach(
        &self,
        n: Vec3,
        dir: Vec3,
        reach: f64,
        rest: f64,
        points: impl Iterator<Item = Vec3>,
    ) -> f64 {
        let approach = -vec3::dot(n, dir);
        let to_plane = if approach > 0.0 {
            ((self.height_m - rest) / approach).max(0.0)
        } else {
            f64::INFINITY
        };
        points
            .filter(|y| self.is_obstacle(*y, n))
            .filter_map(|y| first_touch(rest, y, dir))
            .fold(reach.min(to_plane), f64::min)
    }

    /// Eq. 18 on the plane: how far out along `n` the proxy must move for the plane and every
    /// obstacle within `r1` (among the points at offsets `points`) to be `rest` away.
    pub(crate) fn clearance(
        &self,
        n: Vec3,
        rest: f64,
        r1: f64,
        points: impl Iterator<Item = Vec3>,
    ) -> f64 {
        points
            .filter(|y| vec3::norm2(*y) < r1 * r1 && self.is_obstacle(*y, n))
            .filter_map(|y| clearing_distance(rest, y, n))
            .fold((rest - self.height_m).max(0.0), f64::max)
    }

    /// Pushing in (`n·u < 0`, `u` toward the HIP) also settles the proxy down to `rest` from
    /// the plane: eq. 22 alone leaves it wherever it first came within `r2`, and the plane's
    /// wobble from frame to frame (noise, holes) would then take it beyond `r2` now and then —
    /// contact would flicker. Never toward the plane otherwise, never past `rest`.
    pub(crate) fn settle(&self, u: Vec3, n: Vec3, rest: f64) -> Vec3 {
        if vec3::dot(n, u) < 0.0 && self.height_m > rest {
            vec3::scale(n, rest - self.height_m)
        } else {
            [0.0; 3]
        }
    }
}

/// The plane `fit` if it bridges the points within `support_m` of `centre`: planar within
/// [`MAX_RESIDUAL_OF_BAND`] of `band_m`, at least [`MIN_POINTS`] effective points, and the points surrounding the foot of
/// `centre` on the plane (no empty sector of about [`MAX_GAP_DEG`] or more). Points standing
/// more than [`OBSTACLE_OF_RESIDUAL`] standard deviations of the fit (held to [`OBSTACLE_BANDS`]
/// of the band) above the plane are obstacles, counted apart; neither
/// they nor points as far below it are part of what surrounds the foot.
pub(crate) fn bridge(
    centre: Vec3,
    neighbours: &[Neighbour],
    support_m: f64,
    fit: &Fit,
    band_m: f64,
) -> Option<BridgePlane> {
    if !(fit.residual_m <= MAX_RESIDUAL_OF_BAND * band_m && fit.effective_points >= MIN_POINTS) {
        return None;
    }
    let frame = SurfaceFrame::from_normal(fit.normal)?;
    let [low, high] = OBSTACLE_BANDS.map(|k| k * band_m);
    let mut plane = BridgePlane {
        height_m: fit.height_m,
        obstacle_above_m: (OBSTACLE_OF_RESIDUAL * fit.residual_m).clamp(low, high),
        obstacle_d2: f64::INFINITY,
    };
    let support_sq = support_m * support_m;
    let mut occupied: u64 = 0;
    for nb in neighbours {
        let y = vec3::sub(nb.point, centre);
        let d2 = vec3::norm2(y);
        if d2 > support_sq {
            continue;
        }
        // Height of the point above the plane: beyond the obstacle height either way it is not
        // part of the plane (above: an obstacle; below: a surface beyond an edge, e.g. the
        // table past a board lying on it) and does not surround the foot.
        let above = vec3::dot(y, frame.normal) + plane.height_m;
        if above > plane.obstacle_above_m {
            plane.obstacle_d2 = plane.obstacle_d2.min(d2);
            continue;
        }
        if above < -plane.obstacle_above_m {
            continue;
        }
        let (u, v) = (vec3::dot(y, frame.tangent1), vec3::dot(y, frame.tangent2));
        if u * u + v * v >= 1e-12 {
            occupied |= 1 << bin(v, u);
        }
    }
    (widest_empty_run(occupied) < MAX_EMPTY_BINS).then_some(plane)
}

/// The bin of the direction `atan2(y, x)`, in `0..BINS`.
fn bin(y: f64, x: f64) -> u32 {
    let turn = (fast_atan2(y, x) + std::f64::consts::PI) / std::f64::consts::TAU;
    ((turn * BINS as f64) as u32).min(BINS - 1)
}

/// `atan2(y, x)` within 0.0039 rad (0.22°, well under a bin), without the library call:
/// `atan a ≈ (π/4) a + 0.273 a (1 − |a|)` on `|a| ≤ 1` (Rajan et al., "Efficient
/// approximations for the arctangent function", IEEE Signal Processing Magazine, 2006), then
/// the octant.
fn fast_atan2(y: f64, x: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI};
    let atan = |a: f64| FRAC_PI_4 * a + 0.273 * a * (1.0 - a.abs());
    if x.abs() >= y.abs() {
        if x == 0.0 {
            return 0.0;
        }
        let base = atan(y / x);
        if x > 0.0 {
            base
        } else if y >= 0.0 {
            base + PI
        } else {
            base - PI
        }
    } else {
        let base = -atan(x / y);
        if y > 0.0 {
            base + FRAC_PI_2
        } else {
            base - FRAC_PI_2
        }
    }
}

/// The longest circular run of zero bits in `mask` (all `BINS` when it is 0).
fn widest_empty_run(mask: u64) -> u32 {
    if mask == 0 {
        return BINS;
    }
    // Rotate a set bit to the top: no run of zeros then wraps around.
    let rotated = mask.rotate_right(mask.trailing_zeros() + 1);
    let (mut widest, mut run) = (0, 0);
    for k in 0..BINS {
        if rotated & (1 << k) == 0 {
            run += 1;
            widest = widest.max(run);
        } else {
            run = 0;
        }
    }
    widest
}

#[cfg(test)]
mod tests {
    use super::*;

    fn neighbours(points: impl IntoIterator<Item = Vec3>) -> Vec<Neighbour> {
        points
            .into_iter()
            .enumerate()
            .map(|(k, point)| Neighbour {
                index: k as u32,
                point,
            })
            .collect()
    }

    /// A 1 mm grid on z = 0 over `[-half, half]²`, without the points `hole` says.
    fn grid(half: i32, hole: impl Fn(f64, f64) -> bool) -> Vec<Neighbour> {
        neighbours(
            (-half..=half)
                .flat_map(|i| (-half..=half).map(move |j| [i as f64 * 1e-3, j as f64 * 1e-3, 0.0]))
                .filter(|p| !hole(p[0], p[1])),
        )
    }

    #[test]
    fn the_fast_arctangent_is_within_a_quarter_degree_everywhere() {
        let mut worst: f64 = 0.0;
        for k in 0..100_000 {
            let theta = -std::f64::consts::PI + k as f64 * std::f64::consts::TAU / 100_000.0;
            let (y, x) = (theta.sin() * 3.7, theta.cos() * 3.7);
            worst = worst.max((fast_atan2(y, x) - y.atan2(x)).abs());
        }
        assert!(worst < 0.0039, "{worst}");
        assert_eq!(fast_atan2(0.0, 0.0), 0.0);
    }

    #[test]
    fn the_widest_empty_run_wraps_around() {
        assert_eq!(widest_empty_run(0), 64);
        assert_eq!(widest_empty_run(u64::MAX), 0);
        assert_eq!(widest_empty_run(1), 63);
        // Bits 0 and 63 set: the run between them is 62.
        assert_eq!(widest_empty_run(1 | 1 << 63), 62);
        // Bits 10 and 20: 9 zeros between, 53 around the wrap.
        assert_eq!(widest_empty_run(1 << 10 | 1 << 20), 53);
    }

    /// `bridge` over the plane z = 0, seen from `at`, with a perfect fit.
    fn over_table(at: Vec3, points: &[Neighbour], support: f64) -> Option<BridgePlane> {
        let fit = Fit {
            normal: [0.0, 0.0, 1.0],
            height_m: at[2],
            residual_m: 0.0,
            effective_points: 100.0,
        };
        bridge(at, points, support, &fit, 0.002)
    }

    #[test]
    fn a_hole_is_surrounded_and_an_edge_is_not() {
        let r3 = 0.012;
        let surrounded = |at: Vec3, points: &[Neighbour]| over_table(at, points, r3).is_some();
        // Above a full plane, at any height within reach.
        let plane = grid(20, |_, _| false);
        for z in [0.0, 0.002, 0.011] {
            assert!(surrounded([0.0003, -0.0002, z], &plane), "{z}");
        }
        // A round hole of radius 9 mm (0.75 r3): surrounded from its centre and near its rim.
        let hole = grid(25, |x, y| x * x + y * y < 0.009f64.powi(2));
        for x in [0.0, 0.004, 0.0085] {
            assert!(surrounded([x, 0.0, 0.002], &hole), "x {x}");
        }
        // A half-plane (x ≤ 0): inside it surrounded, on or beyond its edge not.
        let half = grid(20, |x, _| x > 1e-9);
        assert!(surrounded([-0.003, 0.0, 0.002], &half));
        for x in [0.0, 0.0005, 0.004] {
            assert!(!surrounded([x, 0.0, 0.002], &half), "x {x}");
        }
        // A quarter plane's corner, seen from beyond: not surrounded.
        let quarter = grid(20, |x, y| x > 1e-9 || y > 1e-9);
        assert!(!surrounded([0.002, 0.002, 0.002], &quarter));
        // Nothing within reach: not surrounded.
        assert!(!surrounded([0.0, 0.0, 0.05], &plane));
    }

    #[test]
    fn points_standing_out_of_the_plane_are_obstacles_not_support() {
        // A ridge 4 mm tall along y at x = 3 mm on a full plane: two bands (2 mm) above it.
        let mut points = grid(20, |_, _| false);
        let ridge = (-20..=20).map(|j| [0.003, j as f64 * 1e-3, 0.004]);
        points.extend(neighbours(ridge));
        let at = [0.0, 0.0, 0.002];
        let plane = over_table(at, &points, 0.012).unwrap();
        assert_eq!(plane.obstacle_above_m, 0.001);
        // The nearest ridge point is 3 mm across and 2 mm up.
        assert!(
            (plane.obstacle_d2 - 13e-6).abs() < 1e-12,
            "{}",
            plane.obstacle_d2
        );
        assert!(plane.is_obstacle([0.003, 0.0, 0.002], [0.0, 0.0, 1.0]));
        // A perfect fit: half a band (1 mm) above the plane is the obstacle height.
        assert!(!plane.is_obstacle([0.003, 0.0, -0.0012], [0.0, 0.0, 1.0]));
        // A half-plane with only obstacles beyond its edge is still an edge.
        let mut half = grid(20, |x, _| x > 1e-9);
        half.extend(neighbours((1..=10).map(|i| [i as f64 * 1e-3, 0.0, 0.01])));
        assert!(over_table([0.002, 0.0, 0.002], &half, 0.012).is_none());
    }

    #[test]
    fn too_few_points_a_residual_beyond_the_band_or_garbage_do_not_bridge() {
        let ring = neighbours((0..12).map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 12.0;
            [0.005 * a.cos(), 0.005 * a.sin(), 0.0]
        }));
        let at = [0.0, 0.0, 0.002];
        let fit = |residual_m, effective_points| Fit {
            normal: [0.0, 0.0, 1.0],
            height_m: 0.002,
            residual_m,
            effective_points,
        };
        let band = 0.002;
        assert!(bridge(at, &ring, 0.012, &fit(0.001, 12.0), band).is_some());
        assert!(bridge(at, &ring, 0.012, &fit(0.0013, 12.0), band).is_none());
        assert!(bridge(at, &ring, 0.012, &fit(0.0, 11.9), band).is_none());
        assert!(bridge(at, &ring, 0.012, &fit(f64::NAN, 12.0), band).is_none());
        assert!(bridge(at, &ring, 0.012, &fit(0.0, f64::NAN), band).is_none());
        let degenerate = Fit {
            normal: [0.0; 3],
            ..fit(0.0, 12.0)
        };
        assert!(bridge(at, &ring, 0.012, &degenerate, band).is_none());
    }
}
