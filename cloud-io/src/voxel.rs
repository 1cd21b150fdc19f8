//! Voxel-grid downsampling: one point per occupied voxel, the centroid of the points in it.
//!
//! Voxels are the cubes `[i·s, (i+1)·s) × [j·s, …) × [k·s, …)` of edge `s` anchored at the world
//! origin (so consecutive frames share a grid). The output is ordered by voxel index `(i, j, k)`
//! lexicographically, and each centroid is summed in `f64` in input order: the result depends only
//! on the input, never on hashing. A point's voxel index on each axis is `⌊c / s⌋` with the
//! quotient `c / s` rounded to `f64` (so a coordinate within a rounding of a face may fall on
//! either side of it, the same side in every implementation here).
//!
//! [`voxel_downsample`] is the definition (a sort of every point); [`VoxelGrid`] gives its
//! result bit for bit, faster and with buffers kept between frames.

use thiserror::Error;

mod grid;
mod radix;

pub use grid::VoxelGrid;

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
    let mut ext: [f64; 3] = std::array::from_fn(|k| (hi[k] - lo[k]).max(0.0));
    ext.sort_by(f64::total_cmp);
    let area = (ext[1] * ext[2]).max(1e-12);
    (area / points.len().max(1) as f64).sqrt().max(1e-6)
}

#[cfg(test)]
mod tests;
