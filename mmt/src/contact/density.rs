//! How many points a radius query can return at most: an upper bound from point counts on
//! nested cubic grids, computed once per cloud. The proxy reserves its neighbour buffer with it
//! when a cloud is set ([`crate::contact::Proxy::prepare`]), so that no step allocates however
//! dense the cloud or wherever the query falls (a fine grid, a small box inside the ball).
//!
//! # The bound
//!
//! A ball of radius `R` spans `2R` along each axis, so it meets at most `⌈2R/c⌉ + 1` cells of
//! edge `c` per axis and holds at most `(⌈2R/c⌉ + 1)³ · max_count(c)` points, where
//! `max_count(c)` is the fullest cell. Counting on several cell sizes and taking the smallest
//! bound keeps it within about ten to twenty times the true count on a plane (a ball of
//! the proxy's size on a 1 mm grid: ~1,100 points, bound ~16,000, 500 kB of buffer) — loose, but
//! a bound, and only memory.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// Edge of the finest grid's cells [m]. The proxy's queries are 12–20 mm at the default radii.
const FINEST_CELL_M: f64 = 0.016;

/// Clouds up to this many points are bounded by their size (512 kB of neighbour buffer).
const COUNT_ABOVE: usize = 16_384;

/// Grids of edge `FINEST_CELL_M · 2^k` for `k < LEVELS` (16 to 64 mm).
const LEVELS: usize = 3;

/// The fullest cell of each grid, and the number of points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct DensityBound {
    points: usize,
    max_count: [usize; LEVELS],
}

/// Cell counts; keys are tuples, which hash field by field (an array hashes as bytes).
type CellMap = HashMap<(i32, i32, i32), usize, BuildHasherDefault<CellHasher>>;

impl DensityBound {
    /// The trivial bound: every point (for point sets that were not counted).
    pub(super) fn everything(points: usize) -> Self {
        Self {
            points,
            max_count: [points; LEVELS],
        }
    }

    /// Counts `points` [m] on the grids: one hash-map pass over the points, then one over the
    /// occupied cells per coarser level. A cloud of at most [`COUNT_ABOVE`] points is not
    /// counted: every point is then a small enough bound, and the count would cost more than the
    /// buffer it saves (a camera window of a few thousand points, re-indexed at 30 Hz).
    pub(super) fn new(points: &[[f32; 3]]) -> Self {
        if points.len() <= COUNT_ABOVE {
            return Self::everything(points.len());
        }
        let mut max_count = [0; LEVELS];
        let mut cells = CellMap::default();
        for p in points {
            // |p| ≤ 1e6 m (a frame's limit): the cell indices fit an i32 (2.5e8 at 4 mm).
            let [i, j, k] = p.map(|v| (f64::from(v) / FINEST_CELL_M).floor() as i32);
            *cells.entry((i, j, k)).or_insert(0) += 1;
        }
        for slot in &mut max_count {
            *slot = cells.values().copied().max().unwrap_or(0);
            let mut coarser = CellMap::default();
            for (&(i, j, k), n) in &cells {
                let key = (i.div_euclid(2), j.div_euclid(2), k.div_euclid(2));
                *coarser.entry(key).or_insert(0) += n;
            }
            cells = coarser;
        }
        Self {
            points: points.len(),
            max_count,
        }
    }

    /// At least the number of points within `radius_m` [m] of any centre (0 for a negative
    /// or NaN radius, which a query answers with nothing).
    pub(super) fn max_within(&self, radius_m: f64) -> usize {
        if !(radius_m >= 0.0) {
            return 0;
        }
        let mut cell_m = FINEST_CELL_M;
        let mut best = self.points as f64;
        for &count in &self.max_count {
            // The relative slack covers the rounding of `x / c` at cell boundaries.
            let per_axis = (2.0 * radius_m / cell_m * (1.0 + 1e-9) + 1e-9).ceil() + 1.0;
            best = best.min(per_axis.powi(3) * count as f64);
            cell_m *= 2.0;
        }
        best as usize
    }
}

/// A multiplicative hash (FxHash's mixing step) for grid cells: the std SipHash costs several
/// times more per point on the index build.
#[derive(Default)]
pub(super) struct CellHasher(u64);

impl CellHasher {
    fn add(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.add(u64::from(b));
        }
    }

    fn write_i32(&mut self, v: i32) {
        self.add(u64::from(v as u32));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn count_within(points: &[[f32; 3]], c: [f64; 3], r: f64) -> usize {
        points
            .iter()
            .filter(|p| {
                let d: f64 = (0..3).map(|i| (f64::from(p[i]) - c[i]).powi(2)).sum();
                d <= r * r
            })
            .count()
    }

    #[test]
    fn the_bound_holds_on_grids_clusters_and_boxes_and_is_not_absurd() {
        let mut rng = Pcg64::seed_from_u64(4);
        // A 0.5 mm grid plane, a tight cluster, and a small box's surface.
        let grid: Vec<[f32; 3]> = (0..200)
            .flat_map(|i| (0..200).map(move |j| [i as f32 * 5e-4, j as f32 * 5e-4, 0.0]))
            .collect();
        let cluster: Vec<[f32; 3]> = (0..20_000)
            .map(|_| [0; 3].map(|_| rng.random_range(-1e-3f32..1e-3)))
            .collect();
        let cube: Vec<[f32; 3]> = (0..24_000)
            .map(|k| {
                let mut p = [0; 3].map(|_| rng.random_range(-0.01f32..0.01));
                p[k % 3] = if k % 2 == 0 { 0.01 } else { -0.01 };
                p
            })
            .collect();
        for points in [&grid, &cluster, &cube] {
            let bound = DensityBound::new(points);
            for r in [0.0, 0.001, 0.0125, 0.0185, 0.05] {
                let b = bound.max_within(r);
                assert!(b <= points.len());
                for _ in 0..200 {
                    let c = [0; 3].map(|_| rng.random_range(-0.02..0.1));
                    assert!(count_within(points, c, r) <= b, "r {r}");
                }
            }
        }
        // On the plane, the proxy's ball holds ~π·18.5²/0.25 ≈ 4,300 points: the bound is
        // a small multiple of that, not the whole cloud.
        let b = DensityBound::new(&grid).max_within(0.0185);
        assert!((4_300..80_000).contains(&b), "{b}");
        assert_eq!(DensityBound::new(&grid).max_within(f64::NAN), 0);
        assert_eq!(DensityBound::everything(7).max_within(1.0), 7);
        // Small clouds are bounded by their size, uncounted.
        assert_eq!(
            DensityBound::new(&grid[..COUNT_ABOVE]).max_within(0.001),
            COUNT_ABOVE
        );
        // (The three sets above are counted, not bounded by their size.)
        assert!(
            [&grid, &cluster, &cube]
                .iter()
                .all(|p| p.len() > COUNT_ABOVE)
        );
    }
}
