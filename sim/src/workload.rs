//! The standard contact workload: a noisy horizontal plane of exactly `N` points and a HIP path
//! that sweeps in and out of contact while sliding. `mmt contact-bench` and the criterion bench
//! (`benches/contact.rs`) both measure it, so their figures describe the same thing.

use rand::SeedableRng;
use rand_pcg::Pcg64;

use crate::synthetic::{SceneObject, Shape, SyntheticCloud, SyntheticError};
use mmt::cloud::{CloudFrame, Pose};
use mmt::contact::ProxyConfig;

/// Point spacing of the workload plane [m]: a 640×480 depth image of a table at ~0.6 m.
pub const SPACING_M: f64 = 0.001;

/// A cloud and a HIP path to step a proxy along.
#[derive(Clone, Debug)]
pub struct Workload {
    /// The plane `z = 0`, `N` points on a 1 mm grid (row-major, like a depth image), noisy.
    pub frame: CloudFrame,
    /// One HIP position per tick [m] at `config.rate_hz`.
    pub hips: Vec<[f64; 3]>,
    /// The proxy parameters (defaults).
    pub config: ProxyConfig,
}

/// A plane of exactly `points` points (a `⌈√N⌉`-wide grid, at least 2 × 2, cut to `N`: one or
/// two points are a corner of a 2 × 2 patch), Gaussian noise of
/// `noise_std_m` [m] per coordinate from `seed`, and `steps` HIP positions: 10 mm above to
/// 10 mm below the plane at 2 Hz while circling at 0.25 Hz over the middle of the patch (at
/// most 0.15 m/s), so the proxy makes and breaks contact and slides over fresh points.
pub fn plane_sweep(
    points: usize,
    steps: usize,
    noise_std_m: f64,
    seed: u64,
) -> Result<Workload, SyntheticError> {
    let nx = (points as f64).sqrt().ceil().max(2.0);
    let ny = (points as f64 / nx).ceil().max(2.0);
    let scene = SyntheticCloud {
        noise_std_m,
        ..SyntheticCloud::single(
            SceneObject::fixed(
                Shape::Plane {
                    size_x_m: (nx - 1.0) * SPACING_M,
                    size_y_m: (ny - 1.0) * SPACING_M,
                },
                Pose::IDENTITY,
            ),
            SPACING_M,
        )
    };
    let mut cloud = scene
        .frame(0, &mut Pcg64::seed_from_u64(seed))?
        .into_points();
    cloud.truncate(points);
    let frame = CloudFrame::new(cloud, 0, Pose::IDENTITY)?;
    // The patch spans y ∈ [−(ny−1)/2, …]·s before the cut; circle well inside what is left.
    let radius = 0.25 * (ny - 1.0).min(nx - 1.0) * SPACING_M;
    let config = ProxyConfig::default();
    let hips = (0..steps)
        .map(|k| {
            let t = k as f64 / config.rate_hz;
            let (s, c) = (std::f64::consts::TAU * 0.25 * t).sin_cos();
            let z = 0.010 * (std::f64::consts::TAU * 2.0 * t).cos();
            [radius * c, radius * s - 0.25 * radius, z]
        })
        .collect();
    Ok(Workload {
        frame,
        hips,
        config,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use mmt::contact::{CloudIndex, Proxy};

    #[test]
    fn the_workload_has_n_points_and_makes_and_breaks_contact() {
        let w = plane_sweep(10_000, 2_000, 0.0005, 3).unwrap();
        assert_eq!(w.frame.len(), 10_000);
        let index = CloudIndex::build(&w.frame).unwrap();
        let mut proxy = Proxy::new(w.config, w.hips[0]).unwrap();
        let touching = w
            .hips
            .iter()
            .filter(|h| proxy.step(**h, &index).state.is_touching())
            .count();
        // Below the plane for about half of each 0.5 s period.
        assert!((600..1_400).contains(&touching), "{touching}");
    }

    /// Regression: one or two points made a grid one point wide, refused as
    /// `plane.size_x_m = 0`.
    #[test]
    fn tiny_workloads_have_exactly_n_points() {
        for points in 1..=5 {
            let w = plane_sweep(points, 10, 0.0005, 3).unwrap();
            assert_eq!(w.frame.len(), points);
            let index = CloudIndex::build(&w.frame).unwrap();
            let mut proxy = Proxy::new(w.config, w.hips[0]).unwrap();
            for hip in &w.hips {
                proxy.step(*hip, &index);
            }
        }
    }
}
