//! What a real depth camera's cloud has that a grid has not: **clustered holes** — patches of
//! several centimetres with no depth, where a surface is dark, shiny or seen at a grazing angle
//! — and **depth-dependent noise**, which grows with the square of the range along the ray
//! (issue 14; the simulated camera of a scene uses both, [`crate::camera`]).
//!
//! The holes are a Boolean model: disks with Poisson-distributed centres on the object's face,
//! radii uniform in `[0.5, 1.5] × hole_radius_m`, so that a given fraction of the face is covered
//! on average. They are a property of the surface (a dark patch stays dark): fixed to the face,
//! they move with the object and are the same in every frame. Each cell of a coarse lattice
//! draws its own disks from a generator seeded by the cell's indices, so any window of an
//! unbounded face is generated alike, without state, in any order.

use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Poisson};
use rand_pcg::Pcg64;

/// A hole patch: a disk on the face, in face coordinates [m].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disk {
    /// Centre `(u, v)` along the face's two tangents [m].
    pub centre_m: [f64; 2],
    /// Radius [m].
    pub radius_m: f64,
}

/// The hole patches of a face: a covered fraction and a mean radius, seeded.
#[derive(Clone, Debug)]
pub struct HolePatches {
    radius_m: f64,
    cell_m: f64,
    per_cell: Option<Poisson<f64>>,
    seed: u64,
}

/// `E[r²] / R²` for radii uniform in `[0.5 R, 1.5 R]`: `(1.5³ − 0.5³) / 3`.
const MEAN_SQUARED_RADIUS: f64 = 13.0 / 12.0;

impl HolePatches {
    /// Patches covering `fraction` of the face on average (in `[0, 1)`), of mean radius
    /// `radius_m` (> 0) [m], drawn from `seed`. A fraction of 0 makes no hole.
    ///
    /// The covered fraction of a Boolean model of intensity `λ` is `1 − exp(−λ π E[r²])`,
    /// hence `λ = −ln(1 − fraction) / (π E[r²])`.
    pub fn new(fraction: f64, radius_m: f64, seed: u64) -> Self {
        // Cells of three mean radii: a disk reaches at most 1.5 radii, half a cell, into a
        // neighbour, so a point is covered only by disks of its own cell and the 8 around it.
        let cell_m = 3.0 * radius_m;
        let intensity = -(1.0 - fraction).ln()
            / (std::f64::consts::PI * MEAN_SQUARED_RADIUS)
            / (radius_m * radius_m);
        let mean = intensity * cell_m * cell_m;
        HolePatches {
            radius_m,
            cell_m,
            per_cell: (mean > 0.0 && mean.is_finite())
                .then(|| Poisson::new(mean).ok())
                .flatten(),
            seed,
        }
    }

    /// Every disk that reaches the rectangle `u_m[0]..u_m[1]` × `v_m[0]..v_m[1]` of the face
    /// (face coordinates [m]), in a fixed order.
    pub fn disks_in(&self, u_m: [f64; 2], v_m: [f64; 2]) -> Vec<Disk> {
        let Some(per_cell) = &self.per_cell else {
            return Vec::new();
        };
        let reach = 1.5 * self.radius_m;
        let cells = |r: [f64; 2]| {
            let lo = ((r[0] - reach) / self.cell_m).floor() as i64;
            let hi = ((r[1] + reach) / self.cell_m).floor() as i64;
            lo..=hi
        };
        let mut disks = Vec::new();
        for i in cells(u_m) {
            for j in cells(v_m) {
                let mut rng = Pcg64::seed_from_u64(cell_seed(self.seed, i, j));
                let count = per_cell.sample(&mut rng) as usize;
                for _ in 0..count {
                    let centre_m = [
                        (i as f64 + rng.random::<f64>()) * self.cell_m,
                        (j as f64 + rng.random::<f64>()) * self.cell_m,
                    ];
                    let radius_m = self.radius_m * rng.random_range(0.5..1.5);
                    let near = |c: f64, r: [f64; 2]| c + radius_m >= r[0] && c - radius_m <= r[1];
                    if near(centre_m[0], u_m) && near(centre_m[1], v_m) {
                        disks.push(Disk { centre_m, radius_m });
                    }
                }
            }
        }
        disks
    }
}

/// Whether a point `(u, v)` of the face [m] lies in one of `disks`.
pub fn covered(disks: &[Disk], u_m: f64, v_m: f64) -> bool {
    disks.iter().any(|d| {
        let (du, dv) = (u_m - d.centre_m[0], v_m - d.centre_m[1]);
        du * du + dv * dv <= d.radius_m * d.radius_m
    })
}

/// The standard deviation [m] of a depth camera's noise along the ray at `range_m` [m]:
/// `per_m · range²`. A stereo camera's depth error grows with the square of the range,
/// `z² · subpixel / (focal_px · baseline)` (Intel RealSense D400 datasheet, depth RMS error);
/// for a D435 (50 mm baseline, ~430 px focal length at 848 × 480, subpixel 0.08) that is about
/// 0.0037 /m: 1.3 mm at 0.6 m, 3 mm at 0.9 m.
pub fn depth_sigma_m(per_m: f64, range_m: f64) -> f64 {
    per_m * range_m * range_m
}

/// A seed per lattice cell: SplitMix64 steps over the seed and both indices.
fn cell_seed(seed: u64, i: i64, j: i64) -> u64 {
    let mix = |mut z: u64| {
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    let golden = 0x9e37_79b9_7f4a_7c15_u64;
    mix(mix(mix(seed.wrapping_add(golden)) ^ i as u64).wrapping_add(golden) ^ j as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The share of a lattice of sample points over `[−half, half]²` that the patches cover.
    fn covered_share(holes: &HolePatches, half: f64, step: f64) -> f64 {
        let disks = holes.disks_in([-half, half], [-half, half]);
        let n = (2.0 * half / step) as i64;
        let mut hit = 0;
        for a in 0..n {
            for b in 0..n {
                let (u, v) = (-half + a as f64 * step, -half + b as f64 * step);
                hit += usize::from(covered(&disks, u, v));
            }
        }
        hit as f64 / (n * n) as f64
    }

    #[test]
    fn the_patches_cover_the_fraction_asked_for_on_average() {
        for (fraction, radius) in [(0.1, 0.015), (0.3, 0.02), (0.5, 0.01)] {
            // A 2 m × 2 m face holds thousands of patches: the share is within a few percent.
            let shares: Vec<f64> = (1..=4)
                .map(|seed| covered_share(&HolePatches::new(fraction, radius, seed), 1.0, 0.004))
                .collect();
            let mean = shares.iter().sum::<f64>() / shares.len() as f64;
            assert!(
                (mean - fraction).abs() < 0.1 * fraction,
                "{fraction} at {radius} m: {shares:?}"
            );
        }
        assert_eq!(
            covered_share(&HolePatches::new(0.0, 0.015, 1), 0.3, 0.01),
            0.0
        );
    }

    #[test]
    fn the_patches_are_fixed_to_the_face_and_several_centimetres_wide() {
        let holes = HolePatches::new(0.2, 0.015, 7);
        // Any window sees the same disks where windows overlap, whatever order they come in.
        let wide = holes.disks_in([-0.2, 0.2], [-0.2, 0.2]);
        let part = holes.disks_in([0.05, 0.15], [-0.1, 0.0]);
        assert!(!part.is_empty());
        for d in &part {
            assert!(wide.contains(d), "{d:?}");
        }
        assert_eq!(part, holes.disks_in([0.05, 0.15], [-0.1, 0.0]));
        // Another seed, other patches.
        assert_ne!(
            wide,
            HolePatches::new(0.2, 0.015, 8).disks_in([-0.2, 0.2], [-0.2, 0.2])
        );
        // Diameters between 1.5 and 4.5 cm.
        assert!(wide.iter().all(|d| (0.0075..=0.0225).contains(&d.radius_m)));
        // Every disk that touches the window is in it: a point in a disk found from a lattice
        // scan is covered by the window's list.
        assert!(covered(&part, part[0].centre_m[0], part[0].centre_m[1]));
    }

    #[test]
    fn depth_noise_grows_with_the_square_of_the_range() {
        assert_eq!(depth_sigma_m(0.0037, 0.0), 0.0);
        assert!((depth_sigma_m(0.0037, 0.6) - 0.001332).abs() < 1e-12);
        assert!((depth_sigma_m(0.0037, 0.9) / depth_sigma_m(0.0037, 0.45) - 4.0).abs() < 1e-12);
    }
}
