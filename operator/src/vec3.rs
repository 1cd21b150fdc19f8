//! Tiny allocation-free helpers on `[f64; 3]`, the vector type of the device and safety layers.
//! Not a linear-algebra library: only what the 1 kHz path needs.

/// A 3-vector in device or world coordinates (units given by the caller: [m], [m/s], [N]).
pub type Vec3 = [f64; 3];

/// The zero vector.
pub const ZERO: Vec3 = [0.0; 3];

/// `a + b`.
#[must_use]
pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a − b`.
#[must_use]
pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `s · a`.
#[must_use]
pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

/// Dot product.
#[must_use]
pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Euclidean norm.
#[must_use]
pub fn norm(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

/// True when every component is finite.
#[must_use]
pub fn is_finite(a: Vec3) -> bool {
    a.iter().all(|c| c.is_finite())
}

/// `a` shortened to norm `max` if longer, direction kept. `max` must be ≥ 0.
#[must_use]
pub fn clamp_norm(a: Vec3, max: f64) -> Vec3 {
    let n = norm(a);
    if n > max && n > 0.0 {
        scale(a, max / n)
    } else {
        a
    }
}
