//! Rigid poses (rotation + translation) for sensors and synthetic objects.

use serde::{Deserialize, Serialize};

use crate::vec3::{self, Vec3};

/// A rigid transform `x_parent = R · x_child + t`: where a child frame (a sensor, an object) sits
/// in its parent frame (the world). Translation in metres; `R` a proper rotation matrix
/// (orthonormal, determinant +1), row-major.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    /// Rotation matrix `R`, row-major: `R[i][j]`.
    pub rotation: [[f64; 3]; 3],
    /// Translation `t` [m].
    pub translation_m: [f64; 3],
}

impl Default for Pose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Pose {
    /// No rotation, no translation.
    pub const IDENTITY: Pose = Pose {
        rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        translation_m: [0.0; 3],
    };

    /// A pure translation [m].
    pub fn from_translation(translation_m: [f64; 3]) -> Pose {
        Pose {
            translation_m,
            ..Pose::IDENTITY
        }
    }

    /// Rotation by the rotation vector `rv` (axis × angle [rad], Rodrigues' formula), then
    /// translation. A zero vector is no rotation.
    pub fn from_rotation_vector(rv: [f64; 3], translation_m: [f64; 3]) -> Pose {
        let angle = vec3::norm(rv);
        let Some(axis) = vec3::normalize(rv) else {
            return Pose::from_translation(translation_m);
        };
        Pose {
            rotation: axis_angle_matrix(axis, angle),
            translation_m,
        }
    }

    /// The rotation as a unit quaternion `[x, y, z, w]` (Shepperd's method: the largest of the
    /// four diagonal combinations is the pivot, so no division by a small number).
    pub fn quaternion_xyzw(&self) -> [f64; 4] {
        let r = &self.rotation;
        let trace = r[0][0] + r[1][1] + r[2][2];
        let q = if trace > r[0][0].max(r[1][1]).max(r[2][2]) {
            let s = 2.0 * (1.0 + trace).sqrt();
            [
                (r[2][1] - r[1][2]) / s,
                (r[0][2] - r[2][0]) / s,
                (r[1][0] - r[0][1]) / s,
                0.25 * s,
            ]
        } else if r[0][0] >= r[1][1] && r[0][0] >= r[2][2] {
            let s = 2.0 * (1.0 + r[0][0] - r[1][1] - r[2][2]).sqrt();
            [
                0.25 * s,
                (r[0][1] + r[1][0]) / s,
                (r[0][2] + r[2][0]) / s,
                (r[2][1] - r[1][2]) / s,
            ]
        } else if r[1][1] >= r[2][2] {
            let s = 2.0 * (1.0 + r[1][1] - r[0][0] - r[2][2]).sqrt();
            [
                (r[0][1] + r[1][0]) / s,
                0.25 * s,
                (r[1][2] + r[2][1]) / s,
                (r[0][2] - r[2][0]) / s,
            ]
        } else {
            let s = 2.0 * (1.0 + r[2][2] - r[0][0] - r[1][1]).sqrt();
            [
                (r[0][2] + r[2][0]) / s,
                (r[1][2] + r[2][1]) / s,
                0.25 * s,
                (r[1][0] - r[0][1]) / s,
            ]
        };
        let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
        q.map(|c| c / n)
    }

    /// Rotation from a quaternion `w + xi + yj + zk` (normalised here), then translation.
    /// `None` when the quaternion has zero or non-finite norm.
    pub fn from_quaternion(wxyz: [f64; 4], translation_m: [f64; 3]) -> Option<Pose> {
        let n = wxyz.iter().map(|c| c * c).sum::<f64>().sqrt();
        if !(n > 0.0 && n.is_finite()) {
            return None;
        }
        let [w, x, y, z] = wxyz.map(|c| c / n);
        let rotation = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        Some(Pose {
            rotation,
            translation_m,
        })
    }

    /// The pose whose local `+z` axis points along `normal` (shortest-arc rotation from `+z`),
    /// with its origin at `origin_m`: the natural pose of a plane with that outward normal.
    /// `None` when `normal` is zero or not finite.
    pub fn aligning_z_to(normal: [f64; 3], origin_m: [f64; 3]) -> Option<Pose> {
        let n = vec3::normalize(normal)?;
        let z = [0.0, 0.0, 1.0];
        let axis = vec3::cross(z, n);
        let sin = vec3::norm(axis);
        let cos = vec3::dot(z, n);
        let rotation = match vec3::normalize(axis) {
            Some(axis) => axis_angle_matrix(axis, sin.atan2(cos)),
            // Parallel or anti-parallel to +z.
            None if cos > 0.0 => Pose::IDENTITY.rotation,
            None => axis_angle_matrix([1.0, 0.0, 0.0], std::f64::consts::PI),
        };
        Some(Pose {
            rotation,
            translation_m: origin_m,
        })
    }

    /// `R · v` (a direction: no translation).
    pub fn rotate(&self, v: [f64; 3]) -> [f64; 3] {
        let r = &self.rotation;
        [vec3::dot(r[0], v), vec3::dot(r[1], v), vec3::dot(r[2], v)]
    }

    /// `R · p + t` (a point).
    pub fn transform_point(&self, p: [f64; 3]) -> [f64; 3] {
        vec3::add(self.rotate(p), self.translation_m)
    }

    /// The composition `self ∘ inner`: first `inner`, then `self`.
    pub fn compose(&self, inner: &Pose) -> Pose {
        let mut rotation = [[0.0; 3]; 3];
        for (i, row) in rotation.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = (0..3)
                    .map(|k| self.rotation[i][k] * inner.rotation[k][j])
                    .sum();
            }
        }
        Pose {
            rotation,
            translation_m: self.transform_point(inner.translation_m),
        }
    }

    /// Every entry finite.
    pub fn is_finite(&self) -> bool {
        self.rotation.iter().all(|r| vec3::is_finite(*r)) && vec3::is_finite(self.translation_m)
    }
}

/// Rodrigues' rotation matrix about a unit `axis` by `angle` [rad].
fn axis_angle_matrix(axis: Vec3, angle: f64) -> [[f64; 3]; 3] {
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    let [x, y, z] = axis;
    [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c],
    ]
}

#[cfg(test)]
mod tests {
    #[test]
    fn quaternion_round_trip() {
        for rv in [
            [0.0, 0.0, 0.0],
            [0.3, -1.2, 0.7],
            [3.1, 0.0, 0.0],
            [0.0, -3.0, 0.1],
            [0.0, 0.0, 3.1],
        ] {
            let p = super::Pose::from_rotation_vector(rv, [1.0, 2.0, 3.0]);
            let [x, y, z, w] = p.quaternion_xyzw();
            let back = super::Pose::from_quaternion([w, x, y, z], p.translation_m).unwrap();
            for i in 0..3 {
                for j in 0..3 {
                    assert!(
                        (back.rotation[i][j] - p.rotation[i][j]).abs() < 1e-12,
                        "{rv:?}"
                    );
                }
            }
        }
    }

    use super::*;

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        vec3::norm(vec3::sub(a, b)) < 1e-12
    }

    #[test]
    fn aligning_z_maps_plus_z_to_the_normal() {
        for n in [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.3, -0.5, 0.8],
            [-0.2, 0.1, -0.97],
        ] {
            let pose = Pose::aligning_z_to(n, [1.0, 2.0, 3.0]).unwrap();
            let unit = vec3::normalize(n).unwrap();
            assert!(close(pose.rotate([0.0, 0.0, 1.0]), unit), "{n:?}");
            // Proper rotation: columns orthonormal, right-handed.
            let ex = pose.rotate([1.0, 0.0, 0.0]);
            let ey = pose.rotate([0.0, 1.0, 0.0]);
            assert!(close(vec3::cross(ex, ey), unit));
            assert!(close(pose.transform_point([0.0; 3]), [1.0, 2.0, 3.0]));
        }
        assert!(Pose::aligning_z_to([0.0; 3], [0.0; 3]).is_none());
    }

    #[test]
    fn quaternion_and_rotation_vector_agree() {
        let angle: f64 = 0.7;
        let axis = vec3::normalize([1.0, -2.0, 0.5]).unwrap();
        let a = Pose::from_rotation_vector(vec3::scale(axis, angle), [0.0; 3]);
        let half = angle / 2.0;
        let q = [
            half.cos(),
            axis[0] * half.sin(),
            axis[1] * half.sin(),
            axis[2] * half.sin(),
        ];
        // Scaled quaternion: normalised internally.
        let b = Pose::from_quaternion(q.map(|c| 3.0 * c), [0.0; 3]).unwrap();
        for v in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.2, 0.3, -0.9]] {
            assert!(close(a.rotate(v), b.rotate(v)));
        }
        assert!(Pose::from_quaternion([0.0; 4], [0.0; 3]).is_none());
    }

    #[test]
    fn compose_applies_inner_first() {
        let inner =
            Pose::from_rotation_vector([0.0, 0.0, std::f64::consts::FRAC_PI_2], [1.0, 0.0, 0.0]);
        let outer = Pose::from_translation([0.0, 0.0, 5.0]);
        let p = [1.0, 0.0, 0.0];
        let expected = outer.transform_point(inner.transform_point(p));
        assert!(close(outer.compose(&inner).transform_point(p), expected));
        assert!(close(expected, [1.0, 1.0, 5.0]));
    }
}
