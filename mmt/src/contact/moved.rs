//! A cloud seen moved by a translation, without rebuilding its index: what the operator runs its
//! proxy on when the object it shows has slid since the frame was captured (issue 13 item 6).

use super::neighbours::{Neighbour, Neighbours};
use crate::vec3::{self, Vec3};

/// The points of `cloud`, each moved by `offset_m` [m]: a query about `centre` asks `cloud`
/// about `centre − offset` and moves each answer back by `offset`.
///
/// Same contract as any [`Neighbours`] up to the rounding of the move: a point within the radius
/// of the moved query is exactly a point of `cloud` within the radius of `centre − offset`
/// (one rounding of the centre, not of each point).
#[derive(Clone, Copy, Debug)]
pub struct Moved<'a, N> {
    cloud: &'a N,
    offset_m: Vec3,
    id: u64,
}

impl<'a, N: Neighbours> Moved<'a, N> {
    /// `cloud` moved by `offset_m` [m], under `id`: a value from [`super::next_cloud_id`], kept for as
    /// long as the cloud and the offset stay the same (the proxy reuses a query made on the
    /// same id) and replaced whenever either changes.
    pub fn new(cloud: &'a N, offset_m: Vec3, id: u64) -> Self {
        Self {
            cloud,
            offset_m,
            id,
        }
    }
}

impl<N: Neighbours> Neighbours for Moved<'_, N> {
    fn for_each_within<F: FnMut(Neighbour)>(
        &self,
        centre_m: [f64; 3],
        radius_m: f64,
        mut visit: F,
    ) {
        let offset = self.offset_m;
        self.cloud
            .for_each_within(vec3::sub(centre_m, offset), radius_m, |nb| {
                visit(Neighbour {
                    index: nb.index,
                    point: vec3::add(nb.point, offset),
                });
            });
    }

    fn cloud_id(&self) -> u64 {
        self.id
    }

    fn len(&self) -> usize {
        self.cloud.len()
    }

    fn max_within(&self, radius_m: f64) -> usize {
        self.cloud.max_within(radius_m)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::cloud::{CloudFrame, Pose};
    use crate::contact::next_cloud_id;
    use crate::contact::{CloudIndex, Proxy, ProxyConfig};

    /// A 0.2 m square of the plane z = 0, 4.5 mm spacing, each point moved by `by`.
    fn plane(by: [f32; 3]) -> CloudIndex {
        let mut points = Vec::new();
        for i in -22..=22 {
            for j in -22..=22 {
                let (x, y) = (i as f32 * 0.0045, j as f32 * 0.0045);
                points.push([x + by[0], y + by[1], by[2]]);
            }
        }
        CloudIndex::build(&CloudFrame::new(points, 0, Pose::default()).unwrap()).unwrap()
    }

    #[test]
    fn a_moved_view_answers_as_the_moved_points_do() {
        let by = [0.0125f32, -0.0075, 0.002];
        let offset = by.map(f64::from);
        let (base, moved) = (plane([0.0; 3]), plane(by));
        let view = Moved::new(&base, offset, next_cloud_id());
        for centre in [[0.01, 0.02, 0.004], [-0.05, 0.03, 0.0], [0.1, 0.1, 0.01]] {
            let mut a = Vec::new();
            view.for_each_within(centre, 0.012, |nb| a.push(nb));
            let mut b = Vec::new();
            moved.for_each_within(centre, 0.012, |nb| b.push(nb));
            a.sort_by_key(|n| n.index);
            b.sort_by_key(|n| n.index);
            // Points exactly on the sphere may fall either side of the one rounding: none here.
            assert_eq!(a.len(), b.len(), "{centre:?}");
            for (p, q) in a.iter().zip(&b) {
                assert_eq!(p.index, q.index);
                for k in 0..3 {
                    assert!((p.point[k] - q.point[k]).abs() < 1e-7, "{p:?} {q:?}");
                }
            }
        }
        assert_ne!(view.cloud_id(), base.cloud_id());
        assert_eq!(view.len(), base.len());
    }

    /// The proxy on a moved view stops where it stops on the moved cloud: a plane raised by
    /// 5 mm holds the proxy 5 mm higher.
    #[test]
    fn the_proxy_touches_a_moved_view_where_the_moved_cloud_is() {
        let by = [0.003f32, 0.0, 0.005];
        let (base, moved) = (plane([0.0; 3]), plane(by));
        let view = Moved::new(&base, by.map(f64::from), next_cloud_id());
        let config = ProxyConfig::default();
        let start = [0.0, 0.0, 0.03];
        let (mut p, mut q) = (
            Proxy::new(config, start).unwrap(),
            Proxy::new(config, start).unwrap(),
        );
        for k in 0..400 {
            let hip = [0.0, 0.0, 0.03 - 0.0001 * f64::from(k)];
            let (a, b) = (p.step(hip, &view), q.step(hip, &moved));
            assert_eq!(a.state, b.state, "tick {k}");
            for i in 0..3 {
                assert!((a.proxy_m[i] - b.proxy_m[i]).abs() < 1e-9, "tick {k}");
            }
        }
        assert!((p.position()[2] - 0.005 - config.r1_m).abs() < 1e-3);
    }
}
