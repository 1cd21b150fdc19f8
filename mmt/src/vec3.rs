//! Small 3-vector helpers on `[f64; 3]`, shared by the point-cloud and contact modules.
//!
//! Plain arrays keep the hot loops free of conversions and make the arithmetic order explicit
//! (bit-for-bit determinism depends on it).

pub(crate) type V3 = [f64; 3];

#[inline]
pub(crate) fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline]
pub(crate) fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline]
pub(crate) fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

#[inline]
pub(crate) fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline]
pub(crate) fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline]
pub(crate) fn norm2(a: V3) -> f64 {
    dot(a, a)
}

#[inline]
pub(crate) fn norm(a: V3) -> f64 {
    norm2(a).sqrt()
}

/// `a / |a|`, or `None` when `|a|` is zero or not finite.
#[inline]
pub(crate) fn normalize(a: V3) -> Option<V3> {
    let n = norm(a);
    (n > 0.0 && n.is_finite()).then(|| scale(a, 1.0 / n))
}

#[inline]
pub(crate) fn is_finite(a: V3) -> bool {
    a.iter().all(|v| v.is_finite())
}

#[inline]
pub(crate) fn from_f32(p: [f32; 3]) -> V3 {
    [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]
}

/// Rounds to the nearest `f32` per component (the storage type of cloud points).
#[inline]
pub(crate) fn to_f32(p: V3) -> [f32; 3] {
    [p[0] as f32, p[1] as f32, p[2] as f32]
}
