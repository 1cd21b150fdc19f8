//! Radius queries over a cloud: the kd-tree index the proxy runs on, and a brute-force scan with
//! the same contract (the reference for tests and the benchmark).

use std::sync::atomic::{AtomicU64, Ordering};

use kiddo::{ImmutableKdTree, SquaredEuclidean};
use thiserror::Error;

use super::density::DensityBound;
use crate::cloud::CloudFrame;
use crate::vec3::{self, Vec3};

/// A cloud point found by a radius query: its index in the frame and its position [m] in `f64`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Neighbour {
    /// Index of the point in the frame.
    pub index: u32,
    /// Position [m], world frame.
    pub point: [f64; 3],
}

/// Radius queries over a fixed set of points.
///
/// Contract, identical for every implementation so the proxy gives the same bits on any of
/// them: a point is within the radius iff `‖p − centre‖² ≤ radius²` evaluated in `f64` on the
/// point widened from `f32` (component differences, then the sum of squares in x, y, z order).
/// The visiting order is unspecified.
pub trait Neighbours {
    /// Calls `visit` once for every point within `radius_m` [m] of `centre_m`.
    fn for_each_within<F: FnMut(Neighbour)>(&self, centre_m: [f64; 3], radius_m: f64, visit: F);

    /// Identifies the point set: two values with the same id hold the same points (the proxy
    /// then reuses the last query of its previous step instead of repeating it). Unique per
    /// [`CloudIndex`] built in this process.
    fn cloud_id(&self) -> u64;

    /// Number of points.
    fn len(&self) -> usize;

    /// At least the number of points a query of `radius_m` [m] can visit, wherever its centre:
    /// what the proxy reserves for its neighbour buffer ([`crate::contact::Proxy::prepare`]).
    /// Every point by default; [`CloudIndex`] bounds it from the cloud's density.
    fn max_within(&self, radius_m: f64) -> usize {
        let _ = radius_m;
        self.len()
    }

    /// No points.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Why an index could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum IndexError {
    /// The kd-tree refused the points.
    #[error("kd-tree construction failed for {points} points: {reason}")]
    Construction {
        /// Number of points.
        points: usize,
        /// The kd-tree's message.
        reason: String,
    },
}

/// A cloud frame's points in an immutable kd-tree (`kiddo`), built once per frame.
///
/// The proxy holds no reference to it between steps: hand each step the index of the newest
/// frame (the telerobot's live cloud, the operator's delayed copy).
///
/// # Why the tree is built in a rotated frame
///
/// kiddo splits on x, y, z in turn. A depth camera mostly sees flat surfaces, and in a
/// gravity-aligned world they are axis-aligned: every third split of a table (`z = const`)
/// then cuts only its noise, the leaves grow three times wider than they need to be and a
/// radius query scans several times the points it returns. The tree therefore stores the
/// points rotated so that the cloud's flattest direction (smallest principal axis) lies along
/// `(1, 1, 1)/√3`: every axis then crosses the surface and every split is useful. Distances do
/// not change under a rotation; the answers are the world-frame points, as the contract says.
pub struct CloudIndex {
    tree: Option<ImmutableKdTree<f32, 3>>,
    points: Vec<[f32; 3]>,
    /// World → tree-frame rotation, row-major.
    to_tree: [[f64; 3]; 3],
    density: DensityBound,
    timestamp_ns: i64,
    id: u64,
}

/// Source of [`Neighbours::cloud_id`]s: only equality of ids matters, never their values, so
/// this shared counter cannot make two runs differ.
static NEXT_CLOUD_ID: AtomicU64 = AtomicU64::new(1);

/// A fresh [`Neighbours::cloud_id`], unique among every cloud index and view of this process
/// (e.g. a [`super::Moved`] view's, each time its offset changes).
pub fn next_cloud_id() -> u64 {
    NEXT_CLOUD_ID.fetch_add(1, Ordering::Relaxed)
}

impl std::fmt::Debug for CloudIndex {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CloudIndex")
            .field("points", &self.points.len())
            .field("timestamp_ns", &self.timestamp_ns)
            .finish_non_exhaustive()
    }
}

impl CloudIndex {
    /// Builds the kd-tree of a frame and counts its density (serial; about 20–30 ms for
    /// 640×480 points on one core, see `mmt contact-bench`).
    pub fn build(frame: &CloudFrame) -> Result<Self, IndexError> {
        let points = frame.points().to_vec();
        let to_tree = tree_rotation(&points);
        let tree = if points.is_empty() {
            None
        } else {
            let rotated: Vec<[f32; 3]> = points
                .iter()
                .map(|p| vec3::to_f32(rotate(&to_tree, vec3::from_f32(*p))))
                .collect();
            Some(ImmutableKdTree::new_from_slice(&rotated).map_err(|e| {
                IndexError::Construction {
                    points: points.len(),
                    reason: e.to_string(),
                }
            })?)
        };
        let density = DensityBound::new(&points);
        Ok(Self {
            tree,
            points,
            to_tree,
            density,
            timestamp_ns: frame.timestamp_ns(),
            id: next_cloud_id(),
        })
    }

    /// The indexed points [m].
    pub fn points(&self) -> &[[f32; 3]] {
        &self.points
    }

    /// Capture time of the frame [ns].
    pub fn timestamp_ns(&self) -> i64 {
        self.timestamp_ns
    }

    /// The same points scanned one by one (same answers, O(N) per query).
    pub fn brute_force(&self) -> BruteForce<'_> {
        BruteForce {
            points: &self.points,
            density: self.density,
            id: self.id,
        }
    }
}

impl Neighbours for CloudIndex {
    fn for_each_within<F: FnMut(Neighbour)>(
        &self,
        centre_m: [f64; 3],
        radius_m: f64,
        mut visit: F,
    ) {
        let (Some(tree), Some(ball)) = (&self.tree, Ball::new(centre_m, radius_m)) else {
            return;
        };
        // The tree works in f32: widen its radius by the worst rounding of the centre and of the
        // f32 distance, then decide membership exactly in f64 as the contract says.
        let slack = 8.0 * f64::from(f32::EPSILON) * (vec3::norm(centre_m) + radius_m) + 1e-12;
        let r_query = (radius_m + slack) as f32;
        let centre32 = vec3::to_f32(rotate(&self.to_tree, centre_m));
        tree.query(&centre32)
            .within::<SquaredEuclidean<f32>>(r_query * r_query)
            .unsorted()
            .visit(|found| {
                if let Some(&p) = self.points.get(found.item as usize) {
                    ball.offer(found.item, p, &mut visit);
                }
            });
    }

    fn cloud_id(&self) -> u64 {
        self.id
    }

    fn len(&self) -> usize {
        self.points.len()
    }

    fn max_within(&self, radius_m: f64) -> usize {
        self.density.max_within(radius_m)
    }
}

/// Every point tested in turn: the reference the kd-tree must agree with.
#[derive(Clone, Copy, Debug)]
pub struct BruteForce<'a> {
    points: &'a [[f32; 3]],
    density: DensityBound,
    id: u64,
}

impl<'a> BruteForce<'a> {
    /// Scans `points` [m] (at most `u32::MAX` of them are visited). Their density is not
    /// counted: [`Neighbours::max_within`] is every point.
    pub fn new(points: &'a [[f32; 3]]) -> Self {
        Self {
            points,
            density: DensityBound::everything(points.len()),
            id: next_cloud_id(),
        }
    }
}

impl Neighbours for BruteForce<'_> {
    fn for_each_within<F: FnMut(Neighbour)>(
        &self,
        centre_m: [f64; 3],
        radius_m: f64,
        mut visit: F,
    ) {
        let Some(ball) = Ball::new(centre_m, radius_m) else {
            return;
        };
        for (index, p) in (0..=u32::MAX).zip(self.points) {
            ball.offer(index, *p, &mut visit);
        }
    }

    fn cloud_id(&self) -> u64 {
        self.id
    }

    fn len(&self) -> usize {
        self.points.len()
    }

    fn max_within(&self, radius_m: f64) -> usize {
        self.density.max_within(radius_m)
    }
}

fn rotate(r: &[[f64; 3]; 3], v: Vec3) -> Vec3 {
    [vec3::dot(r[0], v), vec3::dot(r[1], v), vec3::dot(r[2], v)]
}

/// The world → tree rotation: principal axes of the points (largest spread first), then the
/// fixed rotation taking the third (flattest) axis to `(1, 1, 1)/√3` and the others to
/// `(1, −1, 0)/√2` and `(1, 1, −2)/√6`. Identity for fewer than 3 points or a failed
/// decomposition (only the speed of queries depends on it, never their answers).
fn tree_rotation(points: &[[f32; 3]]) -> [[f64; 3]; 3] {
    const IDENTITY: [[f64; 3]; 3] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    if points.len() < 3 {
        return IDENTITY;
    }
    let n = points.len() as f64;
    let mean = points
        .iter()
        .fold([0.0; 3], |acc, p| vec3::add(acc, vec3::from_f32(*p)));
    let mean = vec3::scale(mean, 1.0 / n);
    let mut cov = nalgebra::Matrix3::<f64>::zeros();
    for p in points {
        let d = vec3::sub(vec3::from_f32(*p), mean);
        cov += nalgebra::Vector3::from(d) * nalgebra::RowVector3::from(d);
    }
    let Some(eigen) = nalgebra::SymmetricEigen::try_new(cov / n, 1e-12, 200) else {
        return IDENTITY;
    };
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eigen.eigenvalues[b].total_cmp(&eigen.eigenvalues[a]));
    let axis = |k: usize| {
        let c = eigen.eigenvectors.column(order[k]);
        [c[0], c[1], c[2]]
    };
    let (s2, s3, s6) = (2f64.sqrt(), 3f64.sqrt(), 6f64.sqrt());
    let targets = [
        [1.0 / s2, -1.0 / s2, 0.0],
        [1.0 / s6, 1.0 / s6, -2.0 / s6],
        [1.0 / s3, 1.0 / s3, 1.0 / s3],
    ];
    // R = Σ_k target_k ⊗ axis_k maps axis_k to target_k.
    let mut r = [[0.0; 3]; 3];
    for (k, t) in targets.iter().enumerate() {
        let a = axis(k);
        for (row, ti) in r.iter_mut().zip(t) {
            for (v, aj) in row.iter_mut().zip(a) {
                *v += ti * aj;
            }
        }
    }
    if r.iter().flatten().all(|v| v.is_finite()) {
        r
    } else {
        IDENTITY
    }
}

/// A radius query and the membership test of the [`Neighbours`] contract, shared by every
/// backend so they cannot disagree.
#[derive(Clone, Copy, Debug)]
struct Ball {
    centre: Vec3,
    r2: f64,
}

impl Ball {
    /// `None` (an empty answer) for a NaN or negative radius or a non-finite centre.
    fn new(centre: Vec3, radius: f64) -> Option<Ball> {
        (radius >= 0.0 && vec3::is_finite(centre)).then_some(Ball {
            centre,
            r2: radius * radius,
        })
    }

    /// Visits the point if it is in the ball.
    #[inline(always)]
    fn offer<F: FnMut(Neighbour)>(&self, index: u32, p: [f32; 3], visit: &mut F) {
        let point = vec3::from_f32(p);
        if vec3::norm2(vec3::sub(point, self.centre)) <= self.r2 {
            visit(Neighbour { index, point });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::Pose;
    use rand::{Rng, SeedableRng};
    use rand_pcg::Pcg64;

    fn collect<N: Neighbours>(n: &N, c: Vec3, r: f64) -> Vec<u32> {
        let mut v = Vec::new();
        n.for_each_within(c, r, |nb| v.push(nb.index));
        v.sort_unstable();
        v
    }

    #[test]
    fn kd_tree_and_brute_force_return_the_same_sets() {
        let mut rng = Pcg64::seed_from_u64(9);
        let points: Vec<[f32; 3]> = (0..20_000)
            .map(|_| [0; 3].map(|_| rng.random_range(-0.5f32..0.5) + 10.0))
            .collect();
        let frame = CloudFrame::new(points, 0, Pose::IDENTITY).unwrap();
        let index = CloudIndex::build(&frame).unwrap();
        let brute = index.brute_force();
        let mut total = 0;
        for _ in 0..300 {
            let c = [0; 3].map(|_| rng.random_range(9.4..10.6));
            let r = rng.random_range(0.0..0.08);
            let a = collect(&index, c, r);
            assert_eq!(a, collect(&brute, c, r));
            total += a.len();
        }
        assert!(total > 1000);
        // Boundary: a point exactly at the radius is inside for both.
        let p = vec3::from_f32(index.points()[17]);
        let c = vec3::add(p, [0.0, 0.0, 0.25]);
        assert!(collect(&index, c, 0.25).contains(&17));
        assert!(collect(&brute, c, 0.25).contains(&17));
    }

    #[test]
    fn an_index_can_be_handed_to_another_thread() {
        fn send_sync<T: Send + Sync>() {}
        send_sync::<CloudIndex>();
        send_sync::<crate::contact::Proxy>();
    }

    #[test]
    fn empty_clouds_and_bad_queries_find_nothing() {
        let frame = CloudFrame::new(Vec::new(), 0, Pose::IDENTITY).unwrap();
        let index = CloudIndex::build(&frame).unwrap();
        assert!(index.is_empty());
        assert!(collect(&index, [0.0; 3], 1.0).is_empty());
        let frame = CloudFrame::new(vec![[0.0; 3]], 0, Pose::IDENTITY).unwrap();
        let index = CloudIndex::build(&frame).unwrap();
        assert_eq!(collect(&index, [0.0; 3], 0.0), vec![0]);
        assert!(collect(&index, [f64::NAN, 0.0, 0.0], 1.0).is_empty());
        assert!(collect(&index, [0.0; 3], f64::NAN).is_empty());
        assert!(collect(&index.brute_force(), [0.0; 3], -1.0).is_empty());
    }
}
