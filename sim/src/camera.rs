//! The simulated depth camera of a scene.

use crate::holes::{self, HolePatches};
use crate::scene::{CloudKind, Scene, WindowCentre};
use crate::world::World;
use mmt::cloud::{CloudError, CloudFrame, Pose};
use mmt::vec3;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal, StandardNormal};
use rand_pcg::Pcg64;

/// The simulated depth camera: the object's (large) contact face seen in a window of the scene's
/// `cloud.size_m` centred on the tool or on the surface point (`cloud.centre`), sampled on a grid
/// fixed to the object — the points move with the object as it slides — with the scene's noise
/// (per coordinate, and along the ray growing with the range), random dropout, and hole patches
/// fixed to the face ([`crate::holes`]).
pub struct Camera {
    enabled: bool,
    moving: bool,
    period_ns: i64,
    next_ns: i64,
    rng: Pcg64,
    noise: Option<Normal<f64>>,
    dropout: f64,
    holes: HolePatches,
    depth_noise_per_m: f64,
    camera_distance_m: f64,
    spacing_m: f64,
    window_m: [f64; 2],
    follows_tool: bool,
    origin: [f64; 3],
}

impl Camera {
    /// The camera of `scene`, its noise (and its hole patches) seeded from `seed`.
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
            holes: HolePatches::new(c.holes, c.hole_radius_m, seed.wrapping_add(404)),
            depth_noise_per_m: c.depth_noise_per_m,
            camera_distance_m: c.camera_distance_m,
            spacing_m: c.spacing_m,
            window_m: c.size_m,
            follows_tool: c.centre == WindowCentre::Tool,
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
        let f = *world.frame();
        let centre = if self.follows_tool {
            let rel = vec3::sub(tool_m, self.origin);
            [vec3::dot(rel, f.tangent1), vec3::dot(rel, f.tangent2)]
        } else {
            [0.0; 2]
        };
        let origin = self.origin;
        let on_face = move |u: f64, v: f64| {
            vec3::add(
                origin,
                vec3::add(vec3::scale(f.tangent1, u), vec3::scale(f.tangent2, v)),
            )
        };
        // Above the window's centre, along the normal.
        let camera_m = vec3::add(
            on_face(centre[0], centre[1]),
            vec3::scale(f.normal, self.camera_distance_m),
        );
        let s = self.spacing_m;
        // The window in face coordinates (the grid and the holes move with the object).
        let window = |axis: usize| {
            let half = 0.5 * self.window_m[axis];
            [
                centre[axis] - half - offset[axis],
                centre[axis] + half - offset[axis],
            ]
        };
        let (face_u, face_v) = (window(0), window(1));
        let disks = self.holes.disks_in(face_u, face_v);
        let range = |r: [f64; 2]| (r[0] / s).ceil() as i64..=(r[1] / s).floor() as i64;
        let mut points = Vec::new();
        for i in range(face_u) {
            for j in range(face_v) {
                if self.dropout > 0.0 && self.rng.random::<f64>() < self.dropout {
                    continue;
                }
                let (fu, fv) = (i as f64 * s, j as f64 * s);
                if holes::covered(&disks, fu, fv) {
                    continue;
                }
                let mut p = on_face(offset[0] + fu, offset[1] + fv);
                if let Some(noise) = &self.noise {
                    for c in &mut p {
                        *c += noise.sample(&mut self.rng);
                    }
                }
                if self.depth_noise_per_m > 0.0 {
                    p = self.along_ray(p, camera_m);
                }
                points.push(p.map(|c| c as f32));
            }
        }
        CloudFrame::new(points, now_ns, Pose::default()).map(Some)
    }

    /// `p` moved along the ray from `camera_m` by the depth noise at its range.
    fn along_ray(&mut self, p: [f64; 3], camera_m: [f64; 3]) -> [f64; 3] {
        let ray = vec3::sub(p, camera_m);
        let range = vec3::norm(ray);
        if !(range > 0.0) {
            return p;
        }
        let z: f64 = StandardNormal.sample(&mut self.rng);
        let sigma = holes::depth_sigma_m(self.depth_noise_per_m, range);
        vec3::add(p, vec3::scale(ray, sigma * z / range))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// The frame's extent along the scene's tangents `[min, max]` per axis \[m\].
    fn extent(frame: &CloudFrame, scene: &Scene, world: &World) -> [[f64; 2]; 2] {
        let f = world.frame();
        let mut out = [[f64::INFINITY, f64::NEG_INFINITY]; 2];
        for p in frame.points() {
            let rel = vec3::sub(p.map(f64::from), scene.surface.point_m);
            for (axis, t) in [f.tangent1, f.tangent2].into_iter().enumerate() {
                let u = vec3::dot(rel, t);
                out[axis] = [out[axis][0].min(u), out[axis][1].max(u)];
            }
        }
        out
    }

    /// Issue 13, item 6: a window that follows the tool is, at the operator, centred where the
    /// tool was a round trip ago; at 2 s one way the exp-3 path left it. A window fixed on the
    /// surface point does not move with the tool.
    #[test]
    fn the_window_follows_the_tool_or_stays_on_the_surface_point() {
        let mut scene = Scene::exp1();
        scene.cloud.noise_m = 0.0;
        let world = World::new(&scene, scene.surface.point_m, 1).unwrap();
        let f = *world.frame();
        let away = vec3::add(
            scene.surface.point_m,
            vec3::add(
                vec3::scale(f.tangent1, 0.08),
                vec3::scale(f.tangent2, -0.05),
            ),
        );
        let half = scene.cloud.size_m.map(|s| s / 2.0);
        let spacing = scene.cloud.spacing_m;
        for (centre, expected) in [
            (WindowCentre::Tool, [0.08, -0.05]),
            (WindowCentre::Surface, [0.0, 0.0]),
        ] {
            scene.cloud.centre = centre;
            let mut camera = Camera::new(&scene, 1);
            let frame = camera.frame(0, &world, away, &[0.0; 2]).unwrap().unwrap();
            let e = extent(&frame, &scene, &world);
            for axis in 0..2 {
                let mid = (e[axis][0] + e[axis][1]) / 2.0;
                assert!(
                    (mid - expected[axis]).abs() <= spacing,
                    "{centre:?} axis {axis}: centred at {mid}, expected {}",
                    expected[axis]
                );
                let width = e[axis][1] - e[axis][0];
                assert!((width - 2.0 * half[axis]).abs() <= 2.0 * spacing, "{width}");
            }
        }
    }
}
