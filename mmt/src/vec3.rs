//! Small 3-vector helpers on `[f64; 3]`: the one vector type of the system, from the cloud and
//! contact math to the device and safety layers. Not a linear-algebra library: only what the
//! 1 kHz paths need, allocation-free.
//!
//! Plain arrays keep the hot loops free of conversions and make the arithmetic order explicit
//! (bit-for-bit determinism depends on it).

/// A 3-vector (units given by the caller: [m], [m/s], [N]).
pub type Vec3 = [f64; 3];

/// The zero vector.
pub const ZERO: Vec3 = [0.0; 3];

/// `a + b`.
#[inline]
#[must_use]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
#[inline]
#[must_use]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `s · a`.
#[inline]
#[must_use]
pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Dot product.
#[inline]
#[must_use]
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product `a × b`.
#[inline]
#[must_use]
pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// Squared Euclidean norm.
#[inline]
#[must_use]
pub fn norm2(a: Vec3) -> f64 {
    dot(a, a)
}

/// Euclidean norm.
#[inline]
#[must_use]
pub fn norm(a: Vec3) -> f64 {
    norm2(a).sqrt()
}

/// `a / |a|`, or `None` when `|a|` is zero or not finite.
#[inline]
#[must_use]
pub fn normalize(a: Vec3) -> Option<Vec3> {
    let n = norm(a);
    (n > 0.0 && n.is_finite()).then(|| scale(a, 1.0 / n))
}

/// True when every component is finite.
#[inline]
#[must_use]
pub fn is_finite(a: Vec3) -> bool {
    a.iter().all(|v| v.is_finite())
}

/// `a` shortened to norm `max` if longer, direction kept. `max` must be ≥ 0.
#[inline]
#[must_use]
pub fn clamp_norm(a: Vec3, max: f64) -> Vec3 {
    let n = norm(a);
    if n > max && n > 0.0 {
        scale(a, max / n)
    } else {
        a
    }
}

/// Widens a cloud point.
#[inline]
#[must_use]
pub fn from_f32(p: [f32; 3]) -> Vec3 {
    [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]
}

/// Rounds to the nearest `f32` per component (the storage type of cloud points).
#[inline]
#[must_use]
pub fn to_f32(p: Vec3) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clamp_norm_keeps_direction_and_short_vectors() {
        assert_eq!(clamp_norm([3.0, 4.0, 0.0], 2.5), [1.5, 2.0, 0.0]);
        assert_eq!(clamp_norm([0.3, 0.4, 0.0], 2.5), [0.3, 0.4, 0.0]);
        assert_eq!(clamp_norm(ZERO, 0.0), ZERO);
    }

    #[test]
    fn cross_is_right_handed_and_normalize_refuses_zero() {
        assert_eq!(cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
        assert_eq!(normalize(ZERO), None);
        assert_eq!(normalize([f64::INFINITY, 0.0, 0.0]), None);
        assert_eq!(normalize([0.0, 2.0, 0.0]), Some([0.0, 1.0, 0.0]));
    }
}
