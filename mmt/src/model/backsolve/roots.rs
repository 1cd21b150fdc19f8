//! Real roots of quadratics and cubics, for the closed-form candidates of the back-solve.

/// Real roots of `a x² + b x + c` (numerically stable form), or of the linear equation if `a = 0`.
pub(crate) fn quadratic_roots(a: f64, b: f64, c: f64) -> [Option<f64>; 2] {
    if a == 0.0 {
        return [(b != 0.0).then(|| -c / b), None];
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 || !disc.is_finite() {
        return [None, None];
    }
    let q = -0.5 * (b + b.signum() * disc.sqrt());
    let r1 = q / a;
    let r2 = if q != 0.0 { c / q } else { r1 };
    [Some(r1), Some(r2)]
}

/// Real roots of `a x³ + b x² + c x + d` (trigonometric/Cardano form, each root polished by two
/// Newton steps). Falls back to the quadratic when `a = 0`.
pub(crate) fn cubic_roots(a: f64, b: f64, c: f64, d: f64) -> [Option<f64>; 3] {
    if a == 0.0 || !a.is_finite() {
        let [r0, r1] = quadratic_roots(b, c, d);
        return [r0, r1, None];
    }
    let (p2, p1, p0) = (b / a, c / a, d / a);
    // Depressed cubic t³ + P t + Q with x = t − p2/3.
    let shift = p2 / 3.0;
    let pp = p1 - p2 * p2 / 3.0;
    let qq = 2.0 * p2 * p2 * p2 / 27.0 - p2 * p1 / 3.0 + p0;
    let disc = (qq / 2.0).powi(2) + (pp / 3.0).powi(3);
    let mut roots = [None; 3];
    if disc > 0.0 {
        let sq = disc.sqrt();
        let t = (-qq / 2.0 + sq).cbrt() + (-qq / 2.0 - sq).cbrt();
        roots[0] = Some(t - shift);
    } else if pp == 0.0 {
        roots[0] = Some(-shift);
    } else {
        let r = (-pp / 3.0).sqrt();
        let phi = (-qq / (2.0 * r * r * r)).clamp(-1.0, 1.0).acos();
        for (k, root) in roots.iter_mut().enumerate() {
            let t = 2.0 * r * ((phi + 2.0 * std::f64::consts::PI * k as f64) / 3.0).cos();
            *root = Some(t - shift);
        }
    }
    let poly = |x: f64| ((x + p2) * x + p1) * x + p0;
    let dpoly = |x: f64| (3.0 * x + 2.0 * p2) * x + p1;
    for root in roots.iter_mut().flatten() {
        for _ in 0..2 {
            let dp = dpoly(*root);
            if dp != 0.0 {
                let next = *root - poly(*root) / dp;
                if next.is_finite() {
                    *root = next;
                }
            }
        }
    }
    roots.map(|r| r.filter(|v| v.is_finite()))
}
