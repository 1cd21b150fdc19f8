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
//!   plane, `√λ_min`, is at most `r2 − r1`, the band the radii are chosen for (twice the noise
//!   the scene validation allows, [`super::ProxyConfig`]);
//! - they **surround** the foot of the position on that plane: seen from the foot, no empty
//!   angular sector of the plane is wider than [`MAX_GAP_DEG`] (150°). Beyond an edge of a
//!   surface every point lies in one half-plane (an empty sector of 180° or more); inside a
//!   round hole of radius `R` the widest empty sector seen from anywhere in it stays under 150°
//!   while `R` is under 0.97 of the reach (computed), so holes of nearly `r3` in radius are
//!   bridged wherever the proxy is over them;
//! - they are enough: at least [`MIN_POINTS`] effective points.
//!
//! Where the points within `r3` do not bridge, the proxy fits the plane once more over `2 r3`
//! (`proxy.rs`): a patch of several centimetres is surrounded at that scale (at the exp-1 radii,
//! holes up to about 5.8 cm in radius), an edge still is not.
//!
//! Elsewhere — at edges and corners, on curved, stepped or sparse points — the proxy touches
//! the points exactly as the thesis's does. Noise no longer decides contact where the plane
//! bridges: the proxy rests at `(r1 + r2)/2` from the fitted plane, not from whichever noisy
//! point is highest.

use super::neighbours::Neighbour;
use crate::vec3::{self, Vec3};

/// The widest empty angular sector around the foot that still counts as surrounded [°].
/// Beyond an edge every point is in one half-plane: 180° or more. 150° keeps five bins of
/// margin for the binning and the grid; within a hole it is the far side's reach that matters.
pub const MAX_GAP_DEG: f64 = 150.0;

/// Fewest points a bridging plane rests on, counted as the fit's effective number
/// `(Σψ)²/Σψ²`: a plane through fewer says little, and the Wendland weights can let two or three
/// points near the foot outweigh a ring of far ones (measured at the rim of a hole patch: 26
/// points, 6.8 effective, the plane tilted 5°). A full plane at the exp-1 spacing and radii has
/// 35–40.
pub const MIN_POINTS: f64 = 12.0;

/// Angular bins of the enclosure test, one bit each: 5.6° per bin.
const BINS: u32 = 64;

/// Empty runs of this many bins or more are gaps wider than [`MAX_GAP_DEG`] (a run of `k`
/// empty bins is a gap between `(k − 1)` and `(k + 1)` bin widths).
const MAX_EMPTY_BINS: u32 = (MAX_GAP_DEG / 360.0 * BINS as f64) as u32;

/// Whether the plane through the points bridges them at `centre`: planar within `band_m`
/// (weighted RMS residual `residual_m`), at least [`MIN_POINTS`] effective points
/// (`effective`), and the points within `r3` of `centre` surrounding its foot on the plane of
/// unit normal `n`.
pub(crate) fn bridges(
    centre: Vec3,
    neighbours: &[Neighbour],
    r3: f64,
    n: Vec3,
    residual_m: f64,
    band_m: f64,
    effective: f64,
) -> bool {
    residual_m <= band_m && effective >= MIN_POINTS && surrounds(centre, neighbours, r3, n)
}

/// Whether the points within `r3` of `centre`, projected on the plane of unit normal `n`, lie
/// around the foot of `centre` in every direction (no empty sector wider than [`MAX_GAP_DEG`]).
/// Points right below `centre` (within 1 µm of the foot) give no direction and are skipped.
pub(crate) fn surrounds(centre: Vec3, neighbours: &[Neighbour], r3: f64, n: Vec3) -> bool {
    let Some((t1, t2)) = tangents(n) else {
        return false;
    };
    let r3_sq = r3 * r3;
    let mut occupied: u64 = 0;
    for nb in neighbours {
        let y = vec3::sub(nb.point, centre);
        if vec3::norm2(y) > r3_sq {
            continue;
        }
        let (u, v) = (vec3::dot(y, t1), vec3::dot(y, t2));
        if u * u + v * v < 1e-12 {
            continue;
        }
        occupied |= 1 << bin(v, u);
    }
    widest_empty_run(occupied) < MAX_EMPTY_BINS
}

/// Two unit tangents of the unit normal `n` (any pair: the test is rotation invariant).
fn tangents(n: Vec3) -> Option<(Vec3, Vec3)> {
    let a = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let t1 = vec3::normalize(vec3::sub(a, vec3::scale(n, vec3::dot(a, n))))?;
    Some((t1, vec3::cross(n, t1)))
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

    #[test]
    fn a_hole_is_surrounded_and_an_edge_is_not() {
        let up = [0.0, 0.0, 1.0];
        let r3 = 0.012;
        // Above a full plane, at any height within reach.
        let plane = grid(20, |_, _| false);
        for z in [0.0, 0.002, 0.011] {
            assert!(surrounds([0.0003, -0.0002, z], &plane, r3, up), "{z}");
        }
        // A round hole of radius 9 mm (0.75 r3): surrounded from its centre and near its rim.
        let hole = grid(25, |x, y| x * x + y * y < 0.009f64.powi(2));
        for x in [0.0, 0.004, 0.0085] {
            assert!(surrounds([x, 0.0, 0.002], &hole, r3, up), "x {x}");
        }
        // A half-plane (x ≤ 0): inside it surrounded, on or beyond its edge not.
        let half = grid(20, |x, _| x > 1e-9);
        assert!(surrounds([-0.003, 0.0, 0.002], &half, r3, up));
        for x in [0.0, 0.0005, 0.004] {
            assert!(!surrounds([x, 0.0, 0.002], &half, r3, up), "x {x}");
        }
        // A quarter plane's corner, seen from beyond: not surrounded.
        let quarter = grid(20, |x, y| x > 1e-9 || y > 1e-9);
        assert!(!surrounds([0.002, 0.002, 0.002], &quarter, r3, up));
        // Nothing within reach, or a degenerate normal: not surrounded.
        assert!(!surrounds([0.0, 0.0, 0.05], &plane, r3, up));
        assert!(!surrounds([0.0; 3], &plane, r3, [0.0; 3]));
    }

    #[test]
    fn too_few_points_or_a_residual_beyond_the_band_do_not_bridge() {
        let up = [0.0, 0.0, 1.0];
        let ring = neighbours((0..12).map(|k| {
            let a = k as f64 * std::f64::consts::TAU / 12.0;
            [0.005 * a.cos(), 0.005 * a.sin(), 0.0]
        }));
        let at = [0.0, 0.0, 0.002];
        assert!(bridges(at, &ring, 0.012, up, 0.001, 0.002, 12.0));
        assert!(!bridges(at, &ring, 0.012, up, 0.0021, 0.002, 12.0));
        assert!(!bridges(at, &ring, 0.012, up, 0.0, 0.002, 11.9));
        assert!(!bridges(at, &ring, 0.012, up, f64::NAN, 0.002, 12.0));
        assert!(!bridges(at, &ring, 0.012, up, 0.0, 0.002, f64::NAN));
    }
}
