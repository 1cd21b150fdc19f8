//! Voxel-grid downsampling: one point per occupied voxel, the centroid of the points in it.
//!
//! Voxels are the cubes `[i·s, (i+1)·s) × [j·s, …) × [k·s, …)` of edge `s` anchored at the world
//! origin (so consecutive frames share a grid). The output is ordered by voxel index `(i, j, k)`
//! lexicographically, and each centroid is summed in `f64` in input order: the result depends only
//! on the input, never on hashing.

use thiserror::Error;

/// Why a downsampling request was refused.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum VoxelError {
    /// The voxel edge is not a positive finite length.
    #[error("voxel_m = {value}, expected finite and > 0")]
    InvalidSize {
        /// The value given [m].
        value: f64,
    },
    /// A coordinate divided by the voxel edge does not fit a voxel index.
    #[error(
        "point {index}: coordinate {coordinate} m / voxel {voxel_m} m is beyond ±2^53 voxels, \
         expected a larger voxel"
    )]
    IndexOverflow {
        /// Index of the point.
        index: usize,
        /// The coordinate [m].
        coordinate: f64,
        /// The voxel edge [m].
        voxel_m: f64,
    },
    /// A coordinate is not finite.
    #[error("point {index}: coordinate {value} is not finite")]
    NonFinite {
        /// Index of the point.
        index: usize,
        /// The value.
        value: f32,
    },
}

/// Downsamples `points` [m] to one centroid per voxel of edge `voxel_m` [m].
pub fn voxel_downsample(points: &[[f32; 3]], voxel_m: f64) -> Result<Vec<[f32; 3]>, VoxelError> {
    if !(voxel_m > 0.0 && voxel_m.is_finite()) {
        return Err(VoxelError::InvalidSize { value: voxel_m });
    }
    const LIMIT: f64 = 9_007_199_254_740_992.0; // 2^53: every index exact in f64 and i64
    let mut keyed = Vec::with_capacity(points.len());
    for (index, p) in points.iter().enumerate() {
        let mut key = [0i64; 3];
        for (k, &c) in key.iter_mut().zip(p) {
            if !c.is_finite() {
                return Err(VoxelError::NonFinite { index, value: c });
            }
            let cell = (f64::from(c) / voxel_m).floor();
            if cell.abs() > LIMIT {
                return Err(VoxelError::IndexOverflow {
                    index,
                    coordinate: f64::from(c),
                    voxel_m,
                });
            }
            *k = cell as i64;
        }
        keyed.push((key, index));
    }
    // Stable order: by voxel, then by input index within a voxel.
    keyed.sort_unstable();
    let mut out = Vec::new();
    let mut rest = keyed.as_slice();
    while let Some(&(key, _)) = rest.first() {
        let len = rest.iter().take_while(|(k, _)| *k == key).count();
        let (voxel, tail) = rest.split_at(len);
        let mut sum = [0.0f64; 3];
        for &(_, i) in voxel {
            for (s, c) in sum.iter_mut().zip(points[i]) {
                *s += f64::from(c);
            }
        }
        out.push(sum.map(|s| (s / len as f64) as f32));
        rest = tail;
    }
    Ok(out)
}

/// [`voxel_downsample`] with buffers kept between calls, for a camera stream: a hash grid (open
/// addressing on the packed voxel index) instead of a sort of every point. The output is the
/// same, bit for bit: centroids summed in `f64` in input order, ordered by voxel index.
/// Allocates only while its buffers grow to the largest frame seen.
///
/// Voxel indices must fit in ±2^20 per axis (±1 km at 1 mm voxels); beyond that it falls back to
/// [`voxel_downsample`].
#[derive(Debug, Default)]
pub struct VoxelGrid {
    /// Open-addressing table: an index into `entries`, or `EMPTY`.
    table: Vec<u32>,
    entries: Vec<Entry>,
    order: Vec<u32>,
}

#[derive(Clone, Copy, Debug)]
struct Entry {
    key: u64,
    sum: [f64; 3],
    count: u32,
}

const EMPTY: u32 = u32::MAX;
/// Voxel indices are packed in 21 bits per axis, offset by 2^20.
const PACK_LIMIT: f64 = 1_048_576.0;

impl VoxelGrid {
    /// An empty grid (buffers grow on first use).
    pub fn new() -> VoxelGrid {
        VoxelGrid::default()
    }

    /// One centroid per voxel of edge `voxel_m` of `points`, in `out` (cleared first).
    pub fn downsample(
        &mut self,
        points: &[[f32; 3]],
        voxel_m: f64,
        out: &mut Vec<[f32; 3]>,
    ) -> Result<(), VoxelError> {
        out.clear();
        if !(voxel_m > 0.0 && voxel_m.is_finite()) {
            return Err(VoxelError::InvalidSize { value: voxel_m });
        }
        self.entries.clear();
        self.reset_table(points.len().min(1 << 16));
        // A camera's points come row by row: consecutive points mostly share a voxel, so the
        // last voxel is tried before the table.
        let mut last: Option<(u64, usize)> = None;
        for (index, p) in points.iter().enumerate() {
            let Some(key) = pack(index, p, voxel_m)? else {
                // Beyond the packed range: the general (sorting) path.
                out.extend(voxel_downsample(points, voxel_m)?);
                return Ok(());
            };
            match last {
                Some((k, i)) if k == key => {
                    let e = &mut self.entries[i];
                    for (s, c) in e.sum.iter_mut().zip(p) {
                        *s += f64::from(*c);
                    }
                    e.count += 1;
                }
                _ => last = Some((key, self.add(key, p))),
            }
        }
        self.order.clear();
        self.order.extend(0..self.entries.len() as u32);
        let entries = &self.entries;
        self.order
            .sort_unstable_by_key(|&i| entries[i as usize].key);
        out.reserve(self.order.len());
        for &i in &self.order {
            let e = &entries[i as usize];
            let n = f64::from(e.count);
            out.push(e.sum.map(|s| (s / n) as f32));
        }
        Ok(())
    }

    /// [`VoxelGrid::downsample`] at `voxel_m` (none: every point), then, while more than
    /// `max_points` remain, again at a coarser voxel (the edge grows by `√(n / max)`, a
    /// surface's points scaling with `1/edge²`, at least 10 %). Returns the edge used and whether
    /// the budget acted.
    pub fn downsample_to_budget(
        &mut self,
        points: &[[f32; 3]],
        voxel_m: Option<f64>,
        max_points: usize,
        out: &mut Vec<[f32; 3]>,
    ) -> Result<(Option<f64>, bool), VoxelError> {
        match voxel_m {
            Some(v) => self.downsample(points, v, out)?,
            None => {
                out.clear();
                out.extend_from_slice(points);
            }
        }
        let max = max_points.max(1);
        let mut voxel = voxel_m;
        let mut acted = false;
        for _ in 0..16 {
            if out.len() <= max {
                break;
            }
            acted = true;
            let grow = (out.len() as f64 / max as f64).sqrt().max(1.1);
            let next = match voxel {
                Some(v) => v * grow,
                None => initial_voxel(out) * grow,
            };
            voxel = Some(next);
            // Coarsen from the original points: the centroids stay those of the points.
            self.downsample(points, next, out)?;
        }
        Ok((voxel, acted))
    }

    fn reset_table(&mut self, expected: usize) {
        let size = (expected * 2).next_power_of_two().max(1024);
        self.table.clear();
        self.table.resize(size, EMPTY);
    }

    /// Adds `p` to the voxel `key`; the voxel's entry index.
    fn add(&mut self, key: u64, p: &[f32; 3]) -> usize {
        if (self.entries.len() + 1) * 2 > self.table.len() {
            self.grow();
        }
        let mask = self.table.len() - 1;
        let mut slot = hash(key) & mask;
        loop {
            let i = self.table[slot];
            if i == EMPTY {
                self.table[slot] = self.entries.len() as u32;
                self.entries.push(Entry {
                    key,
                    sum: p.map(f64::from),
                    count: 1,
                });
                return self.entries.len() - 1;
            }
            let e = &mut self.entries[i as usize];
            if e.key == key {
                for (s, c) in e.sum.iter_mut().zip(p) {
                    *s += f64::from(*c);
                }
                e.count += 1;
                return i as usize;
            }
            slot = (slot + 1) & mask;
        }
    }

    fn grow(&mut self) {
        let size = self.table.len() * 2;
        self.table.clear();
        self.table.resize(size, EMPTY);
        let mask = size - 1;
        for (i, e) in self.entries.iter().enumerate() {
            let mut slot = hash(e.key) & mask;
            while self.table[slot] != EMPTY {
                slot = (slot + 1) & mask;
            }
            self.table[slot] = i as u32;
        }
    }
}

/// A first voxel for a budget with none configured: the edge at which the points' bounding box,
/// seen as a surface, holds about as many voxels as points.
pub(crate) fn initial_voxel(points: &[[f32; 3]]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for k in 0..3 {
            lo[k] = lo[k].min(f64::from(p[k]));
            hi[k] = hi[k].max(f64::from(p[k]));
        }
    }
    let mut ext: Vec<f64> = (0..3).map(|k| (hi[k] - lo[k]).max(0.0)).collect();
    ext.sort_by(f64::total_cmp);
    let area = (ext[1] * ext[2]).max(1e-12);
    (area / points.len().max(1) as f64).sqrt().max(1e-6)
}

/// The voxel index of `p`, packed; `None` beyond the packed range.
#[inline]
fn pack(index: usize, p: &[f32; 3], voxel_m: f64) -> Result<Option<u64>, VoxelError> {
    let mut key = 0u64;
    for &c in p {
        if !c.is_finite() {
            return Err(VoxelError::NonFinite { index, value: c });
        }
        let cell = (f64::from(c) / voxel_m).floor();
        if !(cell.abs() < PACK_LIMIT) {
            return Ok(None);
        }
        key = (key << 21) | ((cell + PACK_LIMIT) as u64);
    }
    Ok(Some(key))
}

#[inline]
fn hash(key: u64) -> usize {
    (key.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 32) as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centroid_per_voxel_in_index_order() {
        let points = [
            [0.15, 0.05, 0.05],
            [-0.05, 0.05, 0.05], // voxel (-1, 0, 0)
            [0.05, 0.05, 0.05],
            [0.11, 0.01, 0.01], // voxel (1, 0, 0) with the first
            [0.01, 0.03, 0.09],
        ];
        let out = voxel_downsample(&points, 0.1).unwrap();
        assert_eq!(out.len(), 3);
        let expect = [[-0.05, 0.05, 0.05], [0.03, 0.04, 0.07], [0.13, 0.03, 0.03]];
        for (o, e) in out.iter().zip(expect) {
            for k in 0..3 {
                assert!((o[k] - e[k]).abs() < 1e-7, "{out:?}");
            }
        }
    }

    #[test]
    fn output_does_not_depend_on_input_order_beyond_rounding() {
        let points: Vec<[f32; 3]> = (0..1000)
            .map(|i| {
                let f = i as f32;
                [(f * 0.37).sin(), (f * 0.11).cos(), (f * 0.07).sin() * 0.5]
            })
            .collect();
        let a = voxel_downsample(&points, 0.25).unwrap();
        let mut reversed = points.clone();
        reversed.reverse();
        let b = voxel_downsample(&reversed, 0.25).unwrap();
        assert_eq!(a.len(), b.len());
        for (p, q) in a.iter().zip(&b) {
            for k in 0..3 {
                assert!((p[k] - q[k]).abs() < 1e-6);
            }
        }
        assert!(a.len() < points.len());
    }

    #[test]
    fn rejects_bad_voxel_sizes() {
        for v in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                voxel_downsample(&[[0.0; 3]], v),
                Err(VoxelError::InvalidSize { .. })
            ));
        }
        assert!(matches!(
            voxel_downsample(&[[1.0e6, 0.0, 0.0]], 1e-12),
            Err(VoxelError::IndexOverflow { index: 0, .. })
        ));
        assert_eq!(voxel_downsample(&[], 0.1).unwrap(), Vec::<[f32; 3]>::new());
    }

    #[test]
    fn the_grid_gives_the_sorted_result_bit_for_bit() {
        let points: Vec<[f32; 3]> = (0..20_000)
            .map(|i| {
                let f = i as f32;
                [
                    (f * 0.37).sin() * 0.3,
                    (f * 0.11).cos() * 0.2,
                    (f * 0.07).sin() * 0.05 - 0.5,
                ]
            })
            .collect();
        let mut grid = VoxelGrid::new();
        let mut out = Vec::new();
        for v in [0.001, 0.0045, 0.02, 0.25, 10.0] {
            grid.downsample(&points, v, &mut out).unwrap();
            assert_eq!(out, voxel_downsample(&points, v).unwrap(), "voxel {v}");
        }
        // Beyond the packed range: the sorting path, same answer.
        let far = [[9.0e5, 0.0, 0.0], [9.0e5, 1e-4, 0.0], [-9.0e5, 0.0, 0.0]];
        grid.downsample(&far, 0.001, &mut out).unwrap();
        assert_eq!(out, voxel_downsample(&far, 0.001).unwrap());
        assert!(matches!(
            grid.downsample(&[[f32::NAN, 0.0, 0.0]], 0.01, &mut out),
            Err(VoxelError::NonFinite { index: 0, .. })
        ));
        assert!(matches!(
            grid.downsample(&points, 0.0, &mut out),
            Err(VoxelError::InvalidSize { .. })
        ));
    }

    #[test]
    fn the_budget_coarsens_until_the_cloud_fits() {
        // A 1 mm grid of 200 × 200 points on a plane.
        let points: Vec<[f32; 3]> = (0..40_000)
            .map(|i| [(i % 200) as f32 * 0.001, (i / 200) as f32 * 0.001, 0.0])
            .collect();
        let mut grid = VoxelGrid::new();
        let mut out = Vec::new();
        let (v, acted) = grid
            .downsample_to_budget(&points, Some(0.002), 50_000, &mut out)
            .unwrap();
        assert_eq!((v, acted, out.len()), (Some(0.002), false, 10_000));
        let (v, acted) = grid
            .downsample_to_budget(&points, Some(0.002), 1_000, &mut out)
            .unwrap();
        assert!(
            acted && out.len() <= 1_000 && out.len() > 300,
            "{v:?} {}",
            out.len()
        );
        let (v, acted) = grid
            .downsample_to_budget(&points, None, 2_000, &mut out)
            .unwrap();
        assert!(
            acted && v.is_some() && out.len() <= 2_000,
            "{v:?} {}",
            out.len()
        );
        let (v, acted) = grid
            .downsample_to_budget(&points, None, 40_000, &mut out)
            .unwrap();
        assert_eq!((v, acted, out.len()), (None, false, 40_000));
    }
}
