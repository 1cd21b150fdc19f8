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
}
