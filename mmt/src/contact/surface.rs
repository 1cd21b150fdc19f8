//! The local surface around the proxy: Wendland weights (eq. 15), the normal (eq. 14), the
//! weighted centroid, and the surface frame built from the normal.

use serde::{Deserialize, Serialize};

use super::bridge::{self, BridgePlane};
use super::neighbours::Neighbour;
use crate::vec3::{self, Vec3};

/// The Wendland weight of eq. 15 for a point at distance `r` [m]: 1 within `r1`, 0 from `r3`
/// on, and `(1 − t)⁴ (4t + 1)` with `t = (r − r1)/(r3 − r1)` between (C² smooth at both ends).
#[inline]
pub fn wendland(r: f64, r1: f64, r3: f64) -> f64 {
    Wendland::new(r1, r3).weight(r)
}

/// A right-handed orthonormal frame on the surface: `tangent1 × tangent2 = normal`.
///
/// The tangents are a deterministic function of the normal alone: `tangent1` is the projection
/// onto the tangent plane of the world axis least aligned with the normal, normalised;
/// `tangent2 = normal × tangent1`. Axes whose `|n_i|` is within
/// [`SurfaceFrame::AXIS_TIE`] of the smallest count as tied, and ties go to x, then y: a
/// horizontal table (`normal ≈ +z`) gets `tangent1 = +x`, `tangent2 = +y` even when its
/// estimated normal wobbles by a few degrees (an exact tie-break would flip the tangents by 90°
/// whenever `|n_x|` and `|n_y|` swap order). The frame jumps only where that choice changes,
/// which no axis-aligned surface comes near; the chosen axis has `|n_i| ≤ 1/√3 + 0.1`, so
/// its projection never degenerates.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfaceFrame {
    /// Unit normal, out of the surface toward the free side.
    pub normal: [f64; 3],
    /// First unit tangent.
    pub tangent1: [f64; 3],
    /// Second unit tangent, `normal × tangent1`.
    pub tangent2: [f64; 3],
}

impl SurfaceFrame {
    /// How much more aligned with the normal than the least-aligned axis another axis may be
    /// and still count as tied (`|n_i| − min_j |n_j|`): 0.1, about 6°.
    pub const AXIS_TIE: f64 = 0.1;

    /// The frame of a normal (normalised here). `None` when it is zero or not finite.
    pub fn from_normal(normal: [f64; 3]) -> Option<SurfaceFrame> {
        let n = vec3::normalize(normal)?;
        let abs = n.map(f64::abs);
        let least = abs[0].min(abs[1]).min(abs[2]);
        let axis = (0..3).find(|&i| abs[i] <= least + Self::AXIS_TIE)?;
        let mut e = [0.0; 3];
        e[axis] = 1.0;
        // |n_axis| ≤ 1/√3 + 0.1 < 0.68: the projection has length > 0.73.
        let tangent1 = vec3::normalize(vec3::sub(e, vec3::scale(n, n[axis])))?;
        let tangent2 = vec3::cross(n, tangent1);
        Some(SurfaceFrame {
            normal: n,
            tangent1,
            tangent2,
        })
    }

    /// World vector → `(normal, tangent1, tangent2)` components.
    pub fn to_local(&self, v: [f64; 3]) -> [f64; 3] {
        [
            vec3::dot(v, self.normal),
            vec3::dot(v, self.tangent1),
            vec3::dot(v, self.tangent2),
        ]
    }
}

/// How the proxy estimates the surface normal from the points within `r3`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum NormalEstimator {
    /// Eq. 14 as printed: the Wendland-weighted sum of the unit directions from the points to
    /// the proxy. Exact on clean clouds, but it is the gradient of a distance field, so on a
    /// noisy cloud it tilts toward whichever bump the proxy rests on (≈ 5° at 0.5 mm noise
    /// with the default radii).
    WeightedDirections,
    /// The normal of the Wendland-weighted least-squares plane through the points (smallest
    /// eigenvector of their weighted covariance), oriented to the proxy's side by eq. 14. Same
    /// weights, same support, but it averages the noise out instead of following it. Falls back
    /// to eq. 14 where the points do not span a plane (a line, a single point).
    #[default]
    WeightedPlaneFit,
}

/// What the points within `r3` of a position say about the surface there.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct LocalSurface {
    /// Unit normal toward `centre`'s side; `None` without points or when eq. 14 cancels.
    pub normal: Option<Vec3>,
    /// A point on the fitted surface next to `centre` (see [`local_surface`]); `None` when every
    /// weight is 0.
    pub centroid: Option<Vec3>,
    /// Squared distance to the nearest point [m²] (∞ without points).
    pub nearest_d2: f64,
    /// Points within `r3`.
    pub count: usize,
    /// The weighted RMS distance of the points to the fitted plane [m]; `None` without a plane
    /// fit (eq. 14, or points that span no plane).
    pub residual_m: Option<f64>,
    /// The fitted plane where it bridges the points (see [`super::bridge`]); `None` elsewhere,
    /// where the points themselves are the surface.
    pub plane: Option<BridgePlane>,
    /// Radius of the ball the surface was computed over [m] (`r3`, or wider where only a wider
    /// plane bridges the points).
    pub support_m: f64,
}

/// Below this ratio `|n'| / Σψ` the weighted directions of eq. 14 cancel and give no direction.
const DEGENERATE_NORMAL: f64 = 1e-9;

/// The plane fit is used when the covariance's middle eigenvalue is at least this many times
/// its smallest (the points spread in two directions, not along a line).
const PLANARITY: f64 = 2.0;

/// Eq. 14–15 at `centre` over the neighbours within `r3` (others in the slice are ignored),
/// and whether the fitted plane bridges them there (points within `band_m` of it; `r2 − r1`
/// for the proxy, [`super::bridge`]; `None`: never). The slice is summed in its order: the same
/// slice gives the same bits; another backend's order agrees to rounding.
pub(crate) fn local_surface(
    centre: Vec3,
    neighbours: &[Neighbour],
    (r1, r3, band_m): (f64, f64, Option<f64>),
    estimator: NormalEstimator,
    with_point: bool,
) -> LocalSurface {
    let psi = Wendland::new(r1, r3);
    let (sums, normal, residual_m) = oriented_normal(centre, neighbours, &psi, estimator);
    let centroid = if with_point {
        surface_point(centre, neighbours, &psi, &sums, normal)
    } else {
        None
    };
    let plane = match (normal, residual_m, band_m) {
        (Some(n), Some(residual), Some(band)) => {
            // The plane passes through the weighted mean, `centre + m1/Σψ`.
            let height = -vec3::dot(n, sums.m1) / sums.weight;
            let fit = bridge::Fit {
                normal: n,
                height_m: height,
                residual_m: residual,
                effective_points: sums.effective(),
            };
            bridge::bridge(centre, neighbours, r3, &fit, band)
        }
        _ => None,
    };
    LocalSurface {
        normal,
        centroid,
        nearest_d2: sums.nearest_d2,
        count: sums.count,
        residual_m,
        plane,
        support_m: r3,
    }
}

/// The weighted sums, the unit normal toward `centre` (eq. 14, or the plane fit oriented toward
/// the proxy's side) and, for a plane fit, the points' RMS distance to the plane.
fn oriented_normal(
    centre: Vec3,
    neighbours: &[Neighbour],
    psi: &Wendland,
    estimator: NormalEstimator,
) -> (Sums, Option<Vec3>, Option<f64>) {
    if estimator == NormalEstimator::WeightedDirections {
        let sums = Sums::gather::<true>(centre, neighbours, psi);
        let normal = sums.eq14();
        return (sums, normal, None);
    }
    let sums = Sums::gather::<false>(centre, neighbours, psi);
    // Orient toward the proxy: the proxy sits on the free side of the weighted centroid. Where
    // that is ambiguous, or the points span no plane, eq. 14 decides.
    let away = vec3::scale(sums.m1, -1.0);
    let plane = plane_normal(&sums);
    let toward = |n: Vec3, side: Vec3| {
        if vec3::dot(n, side) < 0.0 {
            vec3::scale(n, -1.0)
        } else {
            n
        }
    };
    let normal = match plane.map(|(n, _)| n) {
        Some(n) if vec3::dot(n, away).abs() > 1e-6 * vec3::norm(away) => Some(toward(n, away)),
        Some(n) => Sums::gather::<true>(centre, neighbours, psi)
            .eq14()
            .map(|side| toward(n, side)),
        None if sums.count > 0 => Sums::gather::<true>(centre, neighbours, psi).eq14(),
        None => None,
    };
    (sums, normal, plane.map(|(_, residual)| residual))
}

/// The surface point: weighted by the distance *along the surface* once the normal is known.
/// Weights by the 3-D distance favour the points noise moved toward the proxy, which puts the
/// surface too close to it by a fraction of the noise (a −5 % stiffness bias on a 2000 N/m wall
/// at 0.5 mm noise, measured); in-plane distances do not depend on that noise.
///
/// It is then slid along the fitted plane to the foot of `centre`: the same plane, the same
/// height along this normal, but a point next to the tool. A caller that measures the height
/// along another normal (the tracker's, frozen at the onset) is then off by the angle between
/// the two times the tool's distance from the point — millimetres from the foot, where the
/// centroid is up to r3 away over a hole.
fn surface_point(
    centre: Vec3,
    neighbours: &[Neighbour],
    psi: &Wendland,
    sums: &Sums,
    normal: Option<Vec3>,
) -> Option<Vec3> {
    normal
        .and_then(|n| {
            in_plane_centroid(centre, neighbours, psi, n)
                .map(|c| vec3::sub(centre, vec3::scale(n, vec3::dot(n, vec3::sub(centre, c)))))
        })
        .or_else(|| {
            (sums.weight > 0.0).then(|| vec3::add(centre, vec3::scale(sums.m1, 1.0 / sums.weight)))
        })
}

/// `Σψ(|y − (y·n) n|) x / Σψ`: the centroid weighted by in-plane distance.
fn in_plane_centroid(
    centre: Vec3,
    neighbours: &[Neighbour],
    psi: &Wendland,
    n: Vec3,
) -> Option<Vec3> {
    let (mut weight, mut m1) = (0.0, [0.0; 3]);
    for nb in neighbours {
        let y = vec3::sub(nb.point, centre);
        let along = vec3::sub(y, vec3::scale(n, vec3::dot(y, n)));
        let w = psi.weight(vec3::norm(along));
        if w > 0.0 && vec3::norm2(y) < psi.r3 * psi.r3 {
            weight += w;
            m1 = vec3::add(m1, vec3::scale(y, w));
        }
    }
    (weight > 0.0).then(|| vec3::add(centre, vec3::scale(m1, 1.0 / weight)))
}

/// Eq. 15 with its constant `1/(r3 − r1)` folded.
struct Wendland {
    r1: f64,
    r3: f64,
    inv_span: f64,
}

impl Wendland {
    fn new(r1: f64, r3: f64) -> Self {
        Self {
            r1,
            r3,
            inv_span: 1.0 / (r3 - r1),
        }
    }

    #[inline(always)]
    fn weight(&self, r: f64) -> f64 {
        if r <= self.r1 {
            1.0
        } else if r >= self.r3 {
            0.0
        } else {
            let t = (r - self.r1) * self.inv_span;
            let s = 1.0 - t;
            let s2 = s * s;
            s2 * s2 * (4.0 * t + 1.0)
        }
    }
}

/// Weighted sums over the points within `r3`, of the offsets `y = x − centre` (small numbers:
/// no cancellation against the absolute position).
struct Sums {
    count: usize,
    nearest_d2: f64,
    /// `Σψ`.
    weight: f64,
    /// `Σψ²`: with `Σψ`, the fit's effective number of points `(Σψ)²/Σψ²` (Kish).
    weight2: f64,
    /// `Σψ y`.
    m1: Vec3,
    /// `Σψ y yᵀ`: xx, xy, xz, yy, yz, zz.
    m2: [f64; 6],
    /// Eq. 14's `n'`, `Σψ (−y)/‖y‖` (only gathered when asked: it costs a division per point).
    directions: Vec3,
}

impl Sums {
    #[inline(always)]
    fn gather<const DIRECTIONS: bool>(
        centre: Vec3,
        neighbours: &[Neighbour],
        psi: &Wendland,
    ) -> Self {
        let r3_sq = psi.r3 * psi.r3;
        let mut s = Sums {
            count: 0,
            nearest_d2: f64::INFINITY,
            weight: 0.0,
            weight2: 0.0,
            m1: [0.0; 3],
            m2: [0.0; 6],
            directions: [0.0; 3],
        };
        for nb in neighbours {
            let y = vec3::sub(nb.point, centre);
            let d2 = vec3::norm2(y);
            if d2 > r3_sq {
                continue;
            }
            s.count += 1;
            s.nearest_d2 = s.nearest_d2.min(d2);
            let r = d2.sqrt();
            let w = psi.weight(r);
            if DIRECTIONS && r > 0.0 {
                s.directions = vec3::sub(s.directions, vec3::scale(y, w / r));
            }
            let wy = vec3::scale(y, w);
            s.weight += w;
            s.weight2 += w * w;
            s.m1 = vec3::add(s.m1, wy);
            s.m2[0] += wy[0] * y[0];
            s.m2[1] += wy[0] * y[1];
            s.m2[2] += wy[0] * y[2];
            s.m2[3] += wy[1] * y[1];
            s.m2[4] += wy[1] * y[2];
            s.m2[5] += wy[2] * y[2];
        }
        s
    }

    /// The fit's effective number of points, `(Σψ)²/Σψ²` (Kish): the full count where the
    /// weights are equal, a few where a few near points outweigh the rest.
    fn effective(&self) -> f64 {
        if self.weight2 > 0.0 {
            self.weight * self.weight / self.weight2
        } else {
            0.0
        }
    }

    /// Eq. 14 normalised, `None` when the directions cancel.
    fn eq14(&self) -> Option<Vec3> {
        if vec3::norm(self.directions) > DEGENERATE_NORMAL * self.weight {
            vec3::normalize(self.directions)
        } else {
            None
        }
    }
}

/// Unit normal (either sign) of the weighted least-squares plane through the points — the
/// eigenvector of the smallest eigenvalue of their weighted covariance — and their weighted RMS
/// distance to that plane [m] (the eigenvalue's root). `None` when the points do not span a
/// plane.
fn plane_normal(s: &Sums) -> Option<(Vec3, f64)> {
    if s.weight <= 0.0 || !s.weight.is_finite() {
        return None;
    }
    let mean = vec3::scale(s.m1, 1.0 / s.weight);
    const UPPER: [[usize; 3]; 3] = [[0, 1, 2], [1, 3, 4], [2, 4, 5]];
    let cov: [[f64; 3]; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| s.m2[UPPER[i][j]] / s.weight - mean[i] * mean[j])
    });
    let ([smallest, middle, _], v) = symmetric3_smallest(&cov)?;
    if !(middle > 0.0 && middle >= PLANARITY * smallest.max(0.0)) {
        return None;
    }
    Some((vec3::normalize(v)?, smallest.max(0.0).sqrt()))
}

/// Eigenvalues (ascending) of a symmetric 3×3 matrix and the eigenvector of the smallest, in
/// closed form: the trigonometric solution of the characteristic cubic (O. K. Smith, "Eigenvalues
/// of a symmetric 3 × 3 matrix", CACM 4(4), 1961), the vector as the longest cross product of two
/// rows of `A − λI`. `None` for an isotropic matrix (every direction an eigenvector) or
/// non-finite input.
fn symmetric3_smallest(a: &[[f64; 3]; 3]) -> Option<([f64; 3], Vec3)> {
    let p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    let q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    let p2 = (a[0][0] - q).powi(2) + (a[1][1] - q).powi(2) + (a[2][2] - q).powi(2) + 2.0 * p1;
    let p = (p2 / 6.0).sqrt();
    if !(p > 0.0 && p.is_finite()) {
        return None;
    }
    let b = |i: usize, j: usize| (a[i][j] - if i == j { q } else { 0.0 }) / p;
    let det = b(0, 0) * (b(1, 1) * b(2, 2) - b(1, 2) * b(2, 1))
        - b(0, 1) * (b(1, 0) * b(2, 2) - b(1, 2) * b(2, 0))
        + b(0, 2) * (b(1, 0) * b(2, 1) - b(1, 1) * b(2, 0));
    let phi = (det / 2.0).clamp(-1.0, 1.0).acos() / 3.0;
    let largest = q + 2.0 * p * phi.cos();
    let smallest = q + 2.0 * p * (phi + 2.0 * std::f64::consts::PI / 3.0).cos();
    let middle = 3.0 * q - largest - smallest;
    let rows: [Vec3; 3] = std::array::from_fn(|i| {
        std::array::from_fn(|j| a[i][j] - if i == j { smallest } else { 0.0 })
    });
    let v = [
        vec3::cross(rows[0], rows[1]),
        vec3::cross(rows[0], rows[2]),
        vec3::cross(rows[1], rows[2]),
    ]
    .into_iter()
    .max_by(|x, y| vec3::norm2(*x).total_cmp(&vec3::norm2(*y)))?;
    Some(([smallest, middle, largest], v))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The closed-form eigen-solution against nalgebra's iterative one on random symmetric
    /// positive semi-definite matrices, including nearly planar ones.
    #[test]
    fn closed_form_symmetric_eigen_matches_nalgebra() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for trial in 0..2000 {
            let flat = if trial % 2 == 0 { 1e-6 } else { 1.0 };
            let g: [[f64; 3]; 3] =
                std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            let scale = [
                1.0,
                rng.random_range(0.1..1.0),
                flat * rng.random_range(0.0..1.0),
            ];
            // A = G diag(scale) Gᵀ
            let a: [[f64; 3]; 3] = std::array::from_fn(|i| {
                std::array::from_fn(|j| (0..3).map(|k| g[i][k] * scale[k] * g[j][k]).sum())
            });
            let Some((values, v)) = symmetric3_smallest(&a) else {
                continue;
            };
            let m = nalgebra::Matrix3::from_fn(|i, j| a[i][j]);
            let e = nalgebra::SymmetricEigen::new(m);
            let mut reference: Vec<f64> = e.eigenvalues.iter().copied().collect();
            reference.sort_by(f64::total_cmp);
            let norm = reference[2].abs().max(1e-300);
            for k in 0..3 {
                assert!(
                    (values[k] - reference[k]).abs() < 1e-9 * norm,
                    "{values:?} vs {reference:?}"
                );
            }
            // A v = λ v for the smallest.
            let v = vec3::normalize(v).unwrap();
            let av: Vec3 = std::array::from_fn(|i| (0..3).map(|j| a[i][j] * v[j]).sum());
            let residual = vec3::norm(vec3::sub(av, vec3::scale(v, values[0])));
            assert!(
                residual < 1e-7 * norm,
                "trial {trial}: residual {residual:e}"
            );
        }
    }

    #[test]
    fn wendland_is_one_inside_zero_outside_smooth_between() {
        let (r1, r3) = (1.0, 3.0);
        assert_eq!(wendland(0.0, r1, r3), 1.0);
        assert_eq!(wendland(1.0, r1, r3), 1.0);
        assert_eq!(wendland(3.0, r1, r3), 0.0);
        assert_eq!(wendland(5.0, r1, r3), 0.0);
        // t = 0.5: (0.5)^4 · 3 = 0.1875.
        assert!((wendland(2.0, r1, r3) - 0.1875).abs() < 1e-15);
        // Monotone and continuous at both ends.
        let mut last = 1.0;
        for i in 0..=2000 {
            let w = wendland(1.0 + i as f64 * 1e-3, r1, r3);
            assert!(w <= last + 1e-15 && (last - w) < 1e-2);
            last = w;
        }
    }

    #[test]
    fn table_frame_is_x_y_z_and_every_frame_is_right_handed() {
        let f = SurfaceFrame::from_normal([0.0, 0.0, 2.0]).unwrap();
        assert_eq!(f.normal, [0.0, 0.0, 1.0]);
        assert_eq!(f.tangent1, [1.0, 0.0, 0.0]);
        assert_eq!(f.tangent2, [0.0, 1.0, 0.0]);
        let wall = SurfaceFrame::from_normal([1.0, 0.0, 0.0]).unwrap();
        assert_eq!(wall.tangent1, [0.0, 1.0, 0.0]);
        assert_eq!(wall.tangent2, [0.0, 0.0, 1.0]);
        // A table whose estimated normal leans a little either way keeps t1 ≈ +x.
        for n in [
            [0.03, 0.02, 1.0],
            [0.02, 0.03, 1.0],
            [-1e-16, 1e-17, 1.0],
            [0.0, -0.05, 1.0],
        ] {
            let f = SurfaceFrame::from_normal(n).unwrap();
            assert!(f.tangent1[0] > 0.99 && f.tangent2[1] > 0.99, "{n:?}: {f:?}");
        }
        // Clearly closer to y: y wins.
        let f = SurfaceFrame::from_normal([0.5, 0.1, 0.86]).unwrap();
        assert!(f.tangent1[1] > 0.99, "{f:?}");
        for n in [
            [0.3, -0.4, 0.8],
            [-1.0, -1.0, -1.0],
            [0.0, -1.0, 1e-9],
            [5.0, 1.0, 0.2],
        ] {
            let f = SurfaceFrame::from_normal(n).unwrap();
            let close = |a: Vec3, b: Vec3| vec3::norm(vec3::sub(a, b)) < 1e-12;
            assert!(close(vec3::cross(f.tangent1, f.tangent2), f.normal));
            assert!(vec3::dot(f.tangent1, f.normal).abs() < 1e-12);
            assert!((vec3::norm(f.tangent1) - 1.0).abs() < 1e-12);
            assert!(close(f.to_local(f.normal), [1.0, 0.0, 0.0]));
        }
        assert!(SurfaceFrame::from_normal([0.0; 3]).is_none());
        assert!(SurfaceFrame::from_normal([f64::NAN, 0.0, 1.0]).is_none());
    }

    #[test]
    fn local_surface_of_a_symmetric_patch_points_up_to_its_centroid() {
        let points: Vec<Neighbour> = (-3..=3)
            .flat_map(|i| (-3..=3).map(move |j| (i, j)))
            .enumerate()
            .map(|(k, (i, j))| Neighbour {
                index: k as u32,
                point: [i as f64 * 0.001, j as f64 * 0.001, 0.0],
            })
            .collect();
        let at = |centre: Vec3, estimator| {
            local_surface(
                centre,
                &points,
                (0.001, 0.006, Some(0.002)),
                estimator,
                true,
            )
        };
        for estimator in [
            NormalEstimator::WeightedDirections,
            NormalEstimator::WeightedPlaneFit,
        ] {
            let s = at([0.0, 0.0, 0.002], estimator);
            let n = s.normal.unwrap();
            assert!((n[2] - 1.0).abs() < 1e-12 && n[0].abs() < 1e-12, "{n:?}");
            assert!(vec3::norm(s.centroid.unwrap()) < 1e-12);
            assert!((s.nearest_d2 - 4e-6).abs() < 1e-18);
            assert_eq!(s.count, 49);
            // Below the patch the normal points down, toward the query point's side.
            assert!(at([0.0, 0.0, -0.002], estimator).normal.unwrap()[2] < -0.999);
        }
        // Points beyond r3 are not counted: from (6, 0, 2) mm a point is within 6 mm when
        // (6 − x)² + y² ≤ 32 mm²: all 7 of the columns x = 3 and 2 mm, 5 of x = 1 mm.
        let side = at([0.006, 0.0, 0.002], NormalEstimator::WeightedPlaneFit);
        assert_eq!(side.count, 7 + 7 + 5);
        let none = at([0.0, 0.0, 0.1], NormalEstimator::WeightedPlaneFit);
        assert_eq!((none.normal, none.centroid, none.count), (None, None, 0));
    }
}
