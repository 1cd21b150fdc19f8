//! The shortest-distance problem of the proxy, solved analytically (thesis appendix C.2).
//!
//! Eq. 16 and 18 both ask for the distances `d` along a direction `c` from the proxy at which a
//! point, at offset `b` from the proxy, is exactly `a = (r1 + r2)/2` away (eq. 24):
//!
//! ```text
//! a − ‖b − d c‖ = 0                                  (24)
//! ‖c‖² d² − 2 (b·c) d + ‖b‖² − a² = 0                (28, after squaring; a ≥ 0 so no root is spurious)
//! d = [ (b·c) ± √((b·c)² − ‖c‖² (‖b‖² − a²)) ] / ‖c‖²
//! ```
//!
//! Eq. 29 as printed, `[2(b·c) ± √((b·c)² − 4(‖b‖² − a²)‖c‖²)] / (2‖c‖²)`, mixes two scalings
//! of the quadratic formula: with the linear coefficient `−2(b·c)` the discriminant is
//! `4(b·c)² − 4‖c‖²(‖b‖² − a²)`. The printed form is wrong whenever `b·c ≠ 0`
//! (see the tests, which check the form above against a numeric root finder).
//!
//! The roots are computed without cancellation (`q = h + sign(h)·√disc`, roots `q/‖c‖²` and
//! `(‖b‖² − a²)/q`), so a root near zero keeps its relative precision.

use crate::vec3::{self, Vec3};

/// Both real roots `(low, high)` of eq. 28 for `a − ‖b − d c‖ = 0`, or `None` when the line
/// `d ↦ d c` never comes within `a` of `b` (non-real roots) or `c` is zero or not finite.
pub fn sphere_line_roots(a: f64, b: [f64; 3], c: [f64; 3]) -> Option<(f64, f64)> {
    let cc = vec3::norm2(c);
    if !(cc > 0.0 && cc.is_finite()) {
        return None;
    }
    let h = vec3::dot(b, c);
    let k = vec3::norm2(b) - a * a;
    let disc = h * h - cc * k;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let q = h + disc.sqrt().copysign(h);
    let (r1, r2) = if q == 0.0 {
        // h = 0 and disc = 0, hence k = 0: a double root at 0.
        (0.0, 0.0)
    } else {
        (q / cc, k / q)
    };
    Some((r1.min(r2), r1.max(r2)))
}

/// Eq. 16 for one point: the distance `d ≥ 0` a sphere of radius `a` can travel from the proxy
/// along the unit direction `dir` before it touches the point at offset `b` (the smallest
/// non-negative root; negative and non-real roots are rejected). `None` when the point is never
/// touched. A point already closer than `a` blocks at once (`Some(0)`) if the motion approaches
/// it, and never if the motion leaves it (the distance then only grows).
#[inline]
pub fn first_touch(a: f64, b: Vec3, dir: Vec3) -> Option<f64> {
    let h = vec3::dot(b, dir);
    if vec3::norm2(b) <= a * a {
        return (h > 0.0).then_some(0.0);
    }
    if h <= 0.0 {
        // Both roots (if real) share the sign of b·dir: the point is behind.
        return None;
    }
    sphere_line_roots(a, b, dir).map(|(low, _)| low.max(0.0))
}

/// Eq. 18 for one point: the distance `d ≥ 0` along the unit normal `n` after which the point
/// at offset `b` is `a` away and stays at least that far (the largest root). `None` when the
/// point is already clear of the sphere for every `d ≥ 0` or never within `a` of the line.
#[inline]
pub fn clearing_distance(a: f64, b: Vec3, n: Vec3) -> Option<f64> {
    sphere_line_roots(a, b, n)
        .map(|(_, high)| high)
        .filter(|&high| high >= 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    /// `f(d) = a − ‖b − d c‖`: concave, maximal at `d* = b·c/‖c‖²`.
    fn f(a: f64, b: Vec3, c: Vec3, d: f64) -> f64 {
        a - vec3::norm(vec3::sub(b, vec3::scale(c, d)))
    }

    /// Bisection for the sign change of `f` between `lo` and `hi`.
    fn bisect(a: f64, b: Vec3, c: Vec3, mut lo: f64, mut hi: f64) -> f64 {
        let f_lo = f(a, b, c, lo);
        for _ in 0..200 {
            let mid = 0.5 * (lo + hi);
            if (f(a, b, c, mid) >= 0.0) == (f_lo >= 0.0) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }

    fn random_v3(rng: &mut Pcg64, scale: f64) -> Vec3 {
        [0; 3].map(|_| rng.random_range(-scale..scale))
    }

    #[test]
    fn analytic_roots_match_a_numeric_root_finder() {
        let mut rng = Pcg64::seed_from_u64(2024);
        let (mut real, mut none) = (0, 0);
        for _ in 0..20_000 {
            let a = rng.random_range(1e-4..5e-3);
            let b = random_v3(&mut rng, 0.004);
            let c = random_v3(&mut rng, 2.0);
            let cc = vec3::norm2(c);
            let d_star = vec3::dot(b, c) / cc;
            let peak = f(a, b, c, d_star);
            match sphere_line_roots(a, b, c) {
                None => {
                    assert!(peak < 1e-12, "missed roots: peak {peak}");
                    none += 1;
                }
                Some((low, high)) => {
                    assert!(peak > -1e-12, "spurious roots: peak {peak}");
                    let span = (a + vec3::norm(b)) / cc.sqrt() + 1.0;
                    let num_low = bisect(a, b, c, d_star - span, d_star);
                    let num_high = bisect(a, b, c, d_star, d_star + span);
                    let tol = 1e-9 * (1.0 + span);
                    assert!((low - num_low).abs() < tol, "low {low} vs {num_low}");
                    assert!((high - num_high).abs() < tol, "high {high} vs {num_high}");
                    // The roots solve eq. 24 itself, not only the squared form.
                    assert!(f(a, b, c, low).abs() < 1e-12 && f(a, b, c, high).abs() < 1e-12);
                    real += 1;
                }
            }
        }
        assert!(real > 2_000 && none > 2_000, "real {real}, none {none}");
    }

    #[test]
    fn eq_29_as_printed_is_wrong_and_the_corrected_form_is_right() {
        // b along c: the line passes through the point, roots at |b| ± a.
        let (a, b, c) = (1.0, [3.0, 0.0, 0.0], [1.0, 0.0, 0.0]);
        assert_eq!(sphere_line_roots(a, b, c), Some((2.0, 4.0)));
        let (bc, bb, cc) = (vec3::dot(b, c), vec3::norm2(b), vec3::norm2(c));
        let printed_disc = bc * bc - 4.0 * (bb - a * a) * cc;
        // 9 − 32 < 0: the printed formula finds no real root where there are two.
        assert!(printed_disc < 0.0);
    }

    #[test]
    fn tiny_roots_keep_their_precision() {
        // A point about to be touched: the first root is 1e-12 m next to a 2 mm radius. The
        // exact root for the stored numbers is |b| − a (exact in floating point: Sterbenz).
        let a = 0.002;
        let b = [0.0, 0.0, -(a + 1e-12)];
        let exact = -b[2] - a;
        let (low, high) = sphere_line_roots(a, b, [0.0, 0.0, -1.0]).unwrap();
        assert!((low - exact).abs() < 1e-18, "{low} vs {exact}");
        assert!((high - (2.0 * a + exact)).abs() < 1e-17, "{high}");
    }

    #[test]
    fn first_touch_and_clearing_distance_pick_the_right_root() {
        let a = 0.002;
        let down = [0.0, 0.0, -1.0];
        // A point 5 mm below: touched after 3 mm.
        let t = first_touch(a, [0.0, 0.0, -0.005], down).unwrap();
        assert!((t - 0.003).abs() < 1e-15);
        // Behind the motion, or beside it and too far: never.
        assert_eq!(first_touch(a, [0.0, 0.0, 0.005], down), None);
        assert_eq!(first_touch(a, [0.003, 0.0, -0.005], down), None);
        // Already inside: blocks if approached, not if left.
        assert_eq!(first_touch(a, [0.0, 0.0, -0.001], down), Some(0.0));
        assert_eq!(first_touch(a, [0.0, 0.0, 0.001], down), None);
        // Entrenched 0.5 mm from a point below: move up until it is 2 mm away.
        let up = [0.0, 0.0, 1.0];
        let d = clearing_distance(a, [0.0, 0.0, -0.0005], up).unwrap();
        assert!((d - 0.0015).abs() < 1e-15);
        // A point off to the side at 1 mm: up by √(a² − 1 mm²).
        let d = clearing_distance(a, [0.001, 0.0, 0.0], up).unwrap();
        assert!((d - (a * a - 1e-6f64).sqrt()).abs() < 1e-15);
        assert_eq!(clearing_distance(a, [0.0, 0.0, -0.01], up), None);
    }
}
