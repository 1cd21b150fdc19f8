//! Synthetic point clouds from a scene description: planes, boxes and spheres sampled on a grid
//! of given spacing, with seeded Gaussian noise, dropout, and poses that move with time.
//!
//! Randomness is an argument (`&mut impl Rng`, e.g. `rand_pcg::Pcg64::seed_from_u64(seed)`):
//! the same scene, time and generator state give the same points, bit for bit.

use rand::Rng;
use rand_distr::{Distribution, Normal};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use mmt::cloud::{CloudError, CloudFrame, Pose};
use mmt::vec3::{self, Vec3};

/// Most points one synthetic frame may hold (guards against a spacing typo asking for 10¹²).
pub const MAX_SYNTHETIC_POINTS: usize = 50_000_000;

/// A surface in its own (object) frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Shape {
    /// A rectangular patch of the local `z = 0` plane, centred on the origin, outward normal
    /// `+z`. Sizes [m] along local x and y. Placed at any orientation by the object's pose
    /// ([`Pose::aligning_z_to`] makes a pose from a normal).
    Plane {
        /// Extent along local x [m].
        size_x_m: f64,
        /// Extent along local y [m].
        size_y_m: f64,
    },
    /// A box centred on the origin, edges along the local axes; all six faces are sampled (the
    /// points on an edge appear once per face meeting there).
    Box {
        /// Edge lengths along local x, y, z [m].
        size_m: [f64; 3],
    },
    /// A sphere centred on the origin (Fibonacci lattice, one point per `spacing²` of area).
    Sphere {
        /// Radius [m].
        radius_m: f64,
    },
}

/// How an object's pose changes with time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Motion {
    /// The pose never changes.
    Static,
    /// The object slides at a constant world-frame velocity [m/s] from its pose at `t = 0`.
    Linear {
        /// Velocity [m/s], world frame.
        velocity_m_per_s: [f64; 3],
    },
}

/// One object of a synthetic scene.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneObject {
    /// Its surface, in the object frame.
    pub shape: Shape,
    /// Object pose at `t = 0` (world ← object).
    pub pose: Pose,
    /// How the pose changes with time.
    pub motion: Motion,
}

impl SceneObject {
    /// A static object.
    pub fn fixed(shape: Shape, pose: Pose) -> Self {
        Self {
            shape,
            pose,
            motion: Motion::Static,
        }
    }

    /// The pose (world ← object) at time `t_s` [s].
    pub fn pose_at(&self, t_s: f64) -> Pose {
        match self.motion {
            Motion::Static => self.pose,
            Motion::Linear { velocity_m_per_s } => Pose {
                rotation: self.pose.rotation,
                translation_m: vec3::add(
                    self.pose.translation_m,
                    vec3::scale(velocity_m_per_s, t_s),
                ),
            },
        }
    }

    /// Signed distance [m] of world point `p_m` to the true (noise-free) surface at `t_s`:
    /// positive outside. A plane counts as unbounded here (height above it along its normal).
    pub fn signed_distance(&self, t_s: f64, p_m: [f64; 3]) -> f64 {
        let pose = self.pose_at(t_s);
        // Into the object frame: Rᵀ (p − t).
        let d = vec3::sub(p_m, pose.translation_m);
        let r = &pose.rotation;
        let local = [0, 1, 2].map(|j| r[0][j] * d[0] + r[1][j] * d[1] + r[2][j] * d[2]);
        self.shape.signed_distance(local)
    }
}

impl Shape {
    /// Signed distance [m] of a point in the object frame: positive outside.
    pub fn signed_distance(&self, p: [f64; 3]) -> f64 {
        match *self {
            Shape::Plane { .. } => p[2],
            Shape::Sphere { radius_m } => vec3::norm(p) - radius_m,
            Shape::Box { size_m } => {
                let q = [0, 1, 2].map(|i| p[i].abs() - size_m[i] / 2.0);
                let outside = vec3::norm(q.map(|v| v.max(0.0)));
                let inside = q[0].max(q[1]).max(q[2]).min(0.0);
                outside + inside
            }
        }
    }
}

/// A scene of objects seen by a simulated depth sensor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SyntheticCloud {
    /// The objects.
    pub objects: Vec<SceneObject>,
    /// Grid spacing of the sampled points [m]. A 640×480 camera 0.6 m from a table sees about
    /// 1 mm; the proxy needs `(r1 + r2)/2 > spacing/√2` (see [`mmt::contact::ProxyConfig`]).
    pub spacing_m: f64,
    /// Standard deviation of the Gaussian noise added to each coordinate of each point [m].
    /// 0 for exact points. The proxy wants `r2 − r1` at least the noise magnitude.
    pub noise_std_m: f64,
    /// Fraction of points dropped at random, in `[0, 1)` (missing depth pixels).
    pub dropout_fraction: f64,
    /// Where the sensor is (recorded in the frame; the points are generated in the world frame).
    pub sensor_pose: Pose,
}

/// A synthetic scene that cannot be sampled.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SyntheticError {
    /// A parameter is outside its range.
    #[error("{field} = {value}, expected {expected}")]
    Invalid {
        /// Which parameter.
        field: &'static str,
        /// Its value.
        value: f64,
        /// The allowed range.
        expected: &'static str,
    },
    /// The scene would produce more than [`MAX_SYNTHETIC_POINTS`] points.
    #[error("the scene would produce {count} points, expected at most {max}")]
    TooManyPoints {
        /// Points the scene would produce.
        count: u64,
        /// The limit.
        max: usize,
    },
    /// The generated points do not make a frame (an object placed beyond 1000 km).
    #[error(transparent)]
    Cloud(#[from] CloudError),
}

impl SyntheticCloud {
    /// One static object, exact points, no dropout.
    pub fn single(object: SceneObject, spacing_m: f64) -> Self {
        Self {
            objects: vec![object],
            spacing_m,
            noise_std_m: 0.0,
            dropout_fraction: 0.0,
            sensor_pose: Pose::IDENTITY,
        }
    }

    /// Checks every parameter; returns the number of points before dropout.
    pub fn validate(&self) -> Result<u64, SyntheticError> {
        positive("spacing_m", self.spacing_m)?;
        if !(self.noise_std_m >= 0.0 && self.noise_std_m.is_finite()) {
            return Err(invalid("noise_std_m", self.noise_std_m, "finite and >= 0"));
        }
        if !(0.0..1.0).contains(&self.dropout_fraction) {
            return Err(invalid(
                "dropout_fraction",
                self.dropout_fraction,
                "in [0, 1)",
            ));
        }
        let mut count = 0u64;
        for object in &self.objects {
            validate_object(object)?;
            count = count.saturating_add(shape_point_count(&object.shape, self.spacing_m));
        }
        if count > MAX_SYNTHETIC_POINTS as u64 {
            return Err(SyntheticError::TooManyPoints {
                count,
                max: MAX_SYNTHETIC_POINTS,
            });
        }
        Ok(count)
    }

    /// The frame at time `timestamp_ns` [ns since the scene's start]: every object at its pose
    /// at that time, sampled on the grid, each point kept with probability
    /// `1 − dropout_fraction` and then moved by Gaussian noise on each coordinate.
    /// Draws from `rng` in a fixed order (per point: the dropout draw, then x, y, z noise).
    pub fn frame<R: Rng + ?Sized>(
        &self,
        timestamp_ns: i64,
        rng: &mut R,
    ) -> Result<CloudFrame, SyntheticError> {
        let count = self.validate()?;
        let t_s = timestamp_ns as f64 * 1e-9;
        let noise = (self.noise_std_m > 0.0)
            .then(|| Normal::new(0.0, self.noise_std_m))
            .transpose()
            .map_err(|_| invalid("noise_std_m", self.noise_std_m, "finite and >= 0"))?;
        let keep = 1.0 - self.dropout_fraction;
        let mut points = Vec::with_capacity(usize::try_from(count).unwrap_or(0));
        for object in &self.objects {
            let pose = object.pose_at(t_s);
            for_each_surface_point(&object.shape, self.spacing_m, |local| {
                if self.dropout_fraction > 0.0 && rng.random::<f64>() >= keep {
                    return;
                }
                let mut p = pose.transform_point(local);
                if let Some(noise) = &noise {
                    for c in &mut p {
                        *c += noise.sample(rng);
                    }
                }
                points.push(vec3::to_f32(p));
            });
        }
        Ok(CloudFrame::new(points, timestamp_ns, self.sensor_pose)?)
    }
}

fn invalid(field: &'static str, value: f64, expected: &'static str) -> SyntheticError {
    SyntheticError::Invalid {
        field,
        value,
        expected,
    }
}

fn positive(field: &'static str, value: f64) -> Result<(), SyntheticError> {
    if value > 0.0 && value.is_finite() {
        Ok(())
    } else {
        Err(invalid(field, value, "finite and > 0"))
    }
}

fn validate_object(object: &SceneObject) -> Result<(), SyntheticError> {
    if !object.pose.is_finite() {
        return Err(invalid("pose", f64::NAN, "finite entries"));
    }
    if let Motion::Linear { velocity_m_per_s } = object.motion
        && !vec3::is_finite(velocity_m_per_s)
    {
        return Err(invalid(
            "velocity_m_per_s",
            vec3::norm(velocity_m_per_s),
            "finite",
        ));
    }
    match object.shape {
        Shape::Plane { size_x_m, size_y_m } => {
            positive("plane.size_x_m", size_x_m)?;
            positive("plane.size_y_m", size_y_m)
        }
        Shape::Box { size_m } => {
            positive("box.size_m[0]", size_m[0])?;
            positive("box.size_m[1]", size_m[1])?;
            positive("box.size_m[2]", size_m[2])
        }
        Shape::Sphere { radius_m } => positive("sphere.radius_m", radius_m),
    }
}

/// Grid points along an extent: `n` points at exactly `spacing`, centred, covering as much of
/// `size` as fits (`size = (n − 1)·spacing` gives `n` points).
fn grid_count(size: f64, spacing: f64) -> u64 {
    // The small slack makes an exact multiple count in spite of rounding.
    (size / spacing + 1e-9).floor() as u64 + 1
}

fn grid_coord(i: u64, n: u64, spacing: f64) -> f64 {
    (i as f64 - (n - 1) as f64 / 2.0) * spacing
}

fn sphere_count(radius: f64, spacing: f64) -> u64 {
    ((4.0 * std::f64::consts::PI * radius * radius) / (spacing * spacing))
        .round()
        .max(1.0) as u64
}

fn shape_point_count(shape: &Shape, spacing: f64) -> u64 {
    match *shape {
        Shape::Plane { size_x_m, size_y_m } => {
            grid_count(size_x_m, spacing).saturating_mul(grid_count(size_y_m, spacing))
        }
        Shape::Box { size_m } => {
            let n = size_m.map(|s| grid_count(s, spacing));
            2u64.saturating_mul(
                n[0].saturating_mul(n[1])
                    .saturating_add(n[1].saturating_mul(n[2]))
                    .saturating_add(n[0].saturating_mul(n[2])),
            )
        }
        Shape::Sphere { radius_m } => sphere_count(radius_m, spacing),
    }
}

/// Calls `f` with every nominal (noise-free) surface point, object frame, in a fixed order.
fn for_each_surface_point(shape: &Shape, spacing: f64, mut f: impl FnMut(Vec3)) {
    match *shape {
        Shape::Plane { size_x_m, size_y_m } => {
            grid_face(size_x_m, size_y_m, spacing, |u, v| f([u, v, 0.0]));
        }
        Shape::Box { size_m } => {
            let h = size_m.map(|s| s / 2.0);
            for sign in [1.0, -1.0] {
                grid_face(size_m[0], size_m[1], spacing, |u, v| f([u, v, sign * h[2]]));
                grid_face(size_m[1], size_m[2], spacing, |u, v| f([sign * h[0], u, v]));
                grid_face(size_m[0], size_m[2], spacing, |u, v| f([u, sign * h[1], v]));
            }
        }
        Shape::Sphere { radius_m } => {
            let n = sphere_count(radius_m, spacing);
            let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
            for i in 0..n {
                let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = golden * i as f64;
                f(vec3::scale([r * phi.cos(), r * phi.sin(), z], radius_m));
            }
        }
    }
}

fn grid_face(size_u: f64, size_v: f64, spacing: f64, mut f: impl FnMut(f64, f64)) {
    let (nu, nv) = (grid_count(size_u, spacing), grid_count(size_v, spacing));
    for j in 0..nv {
        let v = grid_coord(j, nv, spacing);
        for i in 0..nu {
            f(grid_coord(i, nu, spacing), v);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_pcg::Pcg64;

    fn plane_scene(noise: f64, dropout: f64) -> SyntheticCloud {
        let pose = Pose::aligning_z_to([0.2, -0.3, 0.9], [0.1, 0.2, 0.3]).unwrap();
        SyntheticCloud {
            noise_std_m: noise,
            dropout_fraction: dropout,
            ..SyntheticCloud::single(
                SceneObject::fixed(
                    Shape::Plane {
                        size_x_m: 0.1,
                        size_y_m: 0.05,
                    },
                    pose,
                ),
                0.001,
            )
        }
    }

    #[test]
    fn plane_grid_has_exact_count_spacing_and_lies_on_the_plane() {
        let scene = plane_scene(0.0, 0.0);
        assert_eq!(scene.validate().unwrap(), 101 * 51);
        let frame = scene.frame(0, &mut Pcg64::seed_from_u64(1)).unwrap();
        assert_eq!(frame.len(), 101 * 51);
        let object = &scene.objects[0];
        for p in frame.points() {
            let d = object.signed_distance(0.0, vec3::from_f32(*p));
            assert!(d.abs() < 1e-7, "off the plane by {d}");
        }
        let (a, b) = (
            vec3::from_f32(frame.points()[0]),
            vec3::from_f32(frame.points()[1]),
        );
        assert!((vec3::norm(vec3::sub(a, b)) - 0.001).abs() < 1e-7);
    }

    #[test]
    fn same_seed_same_bits_different_seed_different_cloud() {
        let scene = plane_scene(0.0005, 0.1);
        let a = scene.frame(5, &mut Pcg64::seed_from_u64(42)).unwrap();
        let b = scene.frame(5, &mut Pcg64::seed_from_u64(42)).unwrap();
        let c = scene.frame(5, &mut Pcg64::seed_from_u64(43)).unwrap();
        let bits = |f: &CloudFrame| -> Vec<[u32; 3]> {
            f.points().iter().map(|p| p.map(f32::to_bits)).collect()
        };
        assert_eq!(bits(&a), bits(&b));
        assert_ne!(bits(&a), bits(&c));
    }

    #[test]
    fn noise_and_dropout_have_the_requested_statistics() {
        let scene = plane_scene(0.0005, 0.2);
        let frame = scene.frame(0, &mut Pcg64::seed_from_u64(7)).unwrap();
        let n_nominal = 101.0 * 51.0;
        let kept = frame.len() as f64 / n_nominal;
        assert!((kept - 0.8).abs() < 0.02, "kept {kept}");
        // Distance to the plane is the noise along the normal: std 0.5 mm.
        let d: Vec<f64> = frame
            .points()
            .iter()
            .map(|p| scene.objects[0].signed_distance(0.0, vec3::from_f32(*p)))
            .collect();
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let std = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
        assert!(mean.abs() < 3e-5, "mean {mean}");
        assert!((std - 0.0005).abs() < 2.5e-5, "std {std}");
    }

    #[test]
    fn box_and_sphere_points_lie_on_their_surfaces() {
        for shape in [
            Shape::Box {
                size_m: [0.1, 0.06, 0.04],
            },
            Shape::Sphere { radius_m: 0.05 },
        ] {
            let object = SceneObject::fixed(
                shape,
                Pose::from_rotation_vector([0.1, 0.2, 0.3], [0.0, 0.0, 0.5]),
            );
            let scene = SyntheticCloud::single(object, 0.002);
            let frame = scene.frame(0, &mut Pcg64::seed_from_u64(1)).unwrap();
            assert_eq!(frame.len() as u64, scene.validate().unwrap());
            for p in frame.points() {
                let d = object.signed_distance(0.0, vec3::from_f32(*p));
                assert!(d.abs() < 1e-6, "{shape:?}: off the surface by {d}");
            }
        }
    }

    #[test]
    fn a_sliding_object_moves_with_time() {
        let mut scene = plane_scene(0.0, 0.0);
        scene.objects[0].motion = Motion::Linear {
            velocity_m_per_s: [0.0, 0.0, 0.1],
        };
        let a = scene.frame(0, &mut Pcg64::seed_from_u64(1)).unwrap();
        let b = scene
            .frame(500_000_000, &mut Pcg64::seed_from_u64(1))
            .unwrap();
        let dz = b.points()[0][2] - a.points()[0][2];
        assert!((dz - 0.05).abs() < 1e-6, "{dz}");
        assert!(
            scene.objects[0]
                .signed_distance(0.5, vec3::from_f32(b.points()[9]))
                .abs()
                < 1e-6
        );
    }

    #[test]
    fn invalid_scenes_name_the_field() {
        let mut scene = plane_scene(0.0, 0.0);
        scene.spacing_m = 0.0;
        let err = scene.validate().unwrap_err();
        assert!(err.to_string().contains("spacing_m = 0"), "{err}");
        let mut scene = plane_scene(0.0, 1.0);
        assert!(matches!(
            scene.validate(),
            Err(SyntheticError::Invalid {
                field: "dropout_fraction",
                ..
            })
        ));
        scene.dropout_fraction = 0.0;
        scene.spacing_m = 1e-9;
        assert!(matches!(
            scene.validate(),
            Err(SyntheticError::TooManyPoints { .. })
        ));
    }
}
