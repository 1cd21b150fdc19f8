//! The simulated depth camera of a scene.

use crate::scene::{CloudKind, Scene};
use crate::world::World;
use mmt::cloud::{CloudError, CloudFrame, Pose};
use mmt::vec3;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_pcg::Pcg64;

/// The simulated depth camera: the object's (large) contact face seen in a window of the scene's
/// `cloud.size_m` centred on the tool, sampled on a grid fixed to the object — the points move
/// with the object as it slides — with the scene's noise and dropout.
pub struct Camera {
    enabled: bool,
    moving: bool,
    period_ns: i64,
    next_ns: i64,
    rng: Pcg64,
    noise: Option<Normal<f64>>,
    dropout: f64,
    spacing_m: f64,
    window_m: [f64; 2],
    origin: [f64; 3],
}

impl Camera {
    /// The camera of `scene`, its noise seeded from `seed`.
    pub fn new(scene: &Scene, seed: u64) -> Self {
        let c = &scene.cloud;
        Camera {
            enabled: c.source == CloudKind::Plane,
            moving: c.moving,
            period_ns: (1e9 / c.rate_hz).round() as i64,
            next_ns: 0,
            rng: Pcg64::seed_from_u64(seed.wrapping_add(303)),
            noise: (c.noise_m > 0.0)
                .then(|| Normal::new(0.0, c.noise_m).ok())
                .flatten(),
            dropout: c.dropout,
            spacing_m: c.spacing_m,
            window_m: c.size_m,
            origin: scene.surface.point_m,
        }
    }

    /// A frame if one is due: the face around the tool at `tool_m`, the object slid by
    /// `offset` along the tangents.
    pub fn frame(
        &mut self,
        now_ns: i64,
        world: &World,
        tool_m: [f64; 3],
        offset: &[f64; 2],
    ) -> Result<Option<CloudFrame>, CloudError> {
        if !self.enabled || now_ns < self.next_ns || (!self.moving && self.next_ns > 0) {
            return Ok(None);
        }
        self.next_ns = now_ns + self.period_ns;
        let f = world.frame();
        let rel = vec3::sub(tool_m, self.origin);
        let centre = [vec3::dot(rel, f.tangent1), vec3::dot(rel, f.tangent2)];
        let s = self.spacing_m;
        // Grid indices of the object's face inside the window (the grid moves with the object).
        let range = |axis: usize| {
            let lo = ((centre[axis] - 0.5 * self.window_m[axis] - offset[axis]) / s).ceil() as i64;
            let hi = ((centre[axis] + 0.5 * self.window_m[axis] - offset[axis]) / s).floor() as i64;
            lo..=hi
        };
        let mut points = Vec::new();
        for i in range(0) {
            for j in range(1) {
                if self.dropout > 0.0 && self.rng.random::<f64>() < self.dropout {
                    continue;
                }
                let (u, v) = (offset[0] + i as f64 * s, offset[1] + j as f64 * s);
                let mut p = vec3::add(
                    self.origin,
                    vec3::add(vec3::scale(f.tangent1, u), vec3::scale(f.tangent2, v)),
                );
                if let Some(noise) = &self.noise {
                    for c in &mut p {
                        *c += noise.sample(&mut self.rng);
                    }
                }
                points.push(p.map(|c| c as f32));
            }
        }
        CloudFrame::new(points, now_ns, Pose::default()).map(Some)
    }
}
