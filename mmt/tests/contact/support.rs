//! Scenes, drivers and measures shared by the contact tests.

use mmt::cloud::{CloudFrame, Pose};
use mmt::contact::{CloudIndex, ContactOutput, Proxy, ProxyConfig};
use rand::SeedableRng;
use rand_pcg::Pcg64;
use sim::synthetic::{Motion, SceneObject, Shape, SyntheticCloud};

pub const RATE_HZ: f64 = 1000.0;

pub fn config() -> ProxyConfig {
    ProxyConfig::default()
}

/// The thesis's proxy: points only, no plane bridging the holes (appendix C as printed).
pub fn points_only() -> ProxyConfig {
    ProxyConfig {
        bridge_holes: false,
        ..config()
    }
}

/// A square plane patch of `size` [m] through `origin` with outward `normal`.
pub fn plane(normal: [f64; 3], origin: [f64; 3], size: f64) -> SceneObject {
    SceneObject::fixed(
        Shape::Plane {
            size_x_m: size,
            size_y_m: size,
        },
        Pose::aligning_z_to(normal, origin).unwrap(),
    )
}

pub fn sliding(mut object: SceneObject, velocity: [f64; 3]) -> SceneObject {
    object.motion = Motion::Linear {
        velocity_m_per_s: velocity,
    };
    object
}

pub struct Sensor {
    pub spacing: f64,
    pub noise: f64,
    pub dropout: f64,
    pub seed: u64,
}

impl Sensor {
    pub fn exact() -> Self {
        Self {
            spacing: 0.001,
            noise: 0.0,
            dropout: 0.0,
            seed: 1,
        }
    }

    pub fn noisy(noise: f64) -> Self {
        Self {
            noise,
            ..Self::exact()
        }
    }
}

pub fn frame(object: &SceneObject, sensor: &Sensor, t_ns: i64) -> CloudFrame {
    let scene = SyntheticCloud {
        noise_std_m: sensor.noise,
        dropout_fraction: sensor.dropout,
        ..SyntheticCloud::single(*object, sensor.spacing)
    };
    let mut rng =
        Pcg64::seed_from_u64(sensor.seed ^ (t_ns as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    scene.frame(t_ns, &mut rng).unwrap()
}

pub fn index(object: &SceneObject, sensor: &Sensor) -> CloudIndex {
    CloudIndex::build(&frame(object, sensor, 0)).unwrap()
}

/// Steps a proxy (started at the first HIP) along `hips` on a static cloud.
pub fn run(config: ProxyConfig, index: &CloudIndex, hips: &[[f64; 3]]) -> Vec<ContactOutput> {
    let mut proxy = Proxy::new(config, hips[0]).unwrap();
    hips.iter().map(|h| proxy.step(*h, index)).collect()
}

/// Straight-line HIP path from `from` to `to` at `speed` [m/s], one point per tick, ending
/// with `hold` ticks at `to`.
pub fn path(from: [f64; 3], to: [f64; 3], speed: f64, hold: usize) -> Vec<[f64; 3]> {
    let d = sub(to, from);
    let len = norm(d);
    let ticks = (len / (speed / RATE_HZ)).ceil() as usize;
    let mut out: Vec<[f64; 3]> = (0..=ticks)
        .map(|k| add(from, scale(d, (k as f64 / ticks as f64).min(1.0))))
        .collect();
    out.extend(std::iter::repeat_n(to, hold));
    out
}

/// Concatenates paths.
pub fn chain(parts: &[Vec<[f64; 3]>]) -> Vec<[f64; 3]> {
    parts.concat()
}

pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}

pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

pub fn unit(a: [f64; 3]) -> [f64; 3] {
    scale(a, 1.0 / norm(a))
}

/// Angle between two directions [deg].
pub fn angle_deg(a: [f64; 3], b: [f64; 3]) -> f64 {
    (dot(a, b) / (norm(a) * norm(b)))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Two unit vectors spanning the plane orthogonal to `n`.
pub fn tangents(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let e = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let t1 = unit(sub(e, scale(n, dot(e, n))));
    (t1, cross(n, t1))
}

/// Every number in an output is finite (undefined quantities are `None`, never NaN).
pub fn assert_finite(o: &ContactOutput) {
    let mut v: Vec<f64> = o.proxy_m.to_vec();
    v.extend(o.normal.into_iter().flatten());
    v.extend(
        o.frame
            .iter()
            .flat_map(|f| [f.normal, f.tangent1, f.tangent2])
            .flatten(),
    );
    v.extend(o.penetration_m);
    v.extend(o.surface_point_m.into_iter().flatten());
    assert!(v.iter().all(|x| x.is_finite()), "{o:?}");
    assert_eq!(o.normal.is_some(), o.frame.is_some());
}

/// Distance [m] from `p` to the nearest point of the index (brute force).
pub fn nearest_point_distance(index: &CloudIndex, p: [f64; 3]) -> f64 {
    index
        .points()
        .iter()
        .map(|q| norm(sub([q[0] as f64, q[1] as f64, q[2] as f64], p)))
        .fold(f64::INFINITY, f64::min)
}
