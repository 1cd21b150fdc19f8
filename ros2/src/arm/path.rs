//! The test arm's commanded path: the targets it received, played at their stamps.
//!
//! A tracking controller that moved the tool to the newest target on arrival (the arm's first
//! form) put the DDS delivery jitter into the motion: a target delivered a millisecond late, or
//! two in one tick, shifted the tool by a tick's travel (50 µm at 5 cm/s) while the velocity it
//! reported was the commanded one. The world it simulates takes the tool's position and
//! velocity as given, so its forces answered a motion whose position and velocity disagreed:
//! the telerobot's estimator fitted them ten times worse than the simulated bridge's (issue 14).
//! A driver's interpolator (ros2_control's trajectory controllers) plays targets by their
//! stamps instead; so does this: at time `t` the tool is on the straight segment between the
//! targets around `t − PLAYOUT_NS`, at that segment's velocity, so position and velocity
//! always agree. Past the newest target it goes on along the newest commanded velocity for at
//! most [`MAX_EXTRAPOLATION_NS`], then holds.

/// How long after its stamp a target is played \[ns\]: one tick of a 1 kHz driver.
pub(super) const PLAYOUT_NS: i64 = 1_000_000;
/// How far past the newest target the path goes on along its velocity \[ns\].
pub(super) const MAX_EXTRAPOLATION_NS: i64 = 10_000_000;
/// Targets kept (older ones are behind the playout time).
const KEPT: usize = 16;
/// Two targets further apart are not interpolated between (the path holds after the first) \[ns\].
const MAX_SEGMENT_NS: i64 = 50_000_000;

/// One received target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Point {
    /// Its header stamp \[ns, ROS time\].
    pub(super) stamp_ns: i64,
    /// Position \[m\].
    pub(super) position_m: [f64; 3],
    /// The commanded velocity \[m/s\] (of the same stamp, or the poses' difference).
    pub(super) velocity_m_per_s: [f64; 3],
}

/// The targets in stamp order.
#[derive(Clone, Debug, Default)]
pub(super) struct TargetPath {
    points: Vec<Point>,
}

impl TargetPath {
    pub(super) fn new() -> TargetPath {
        TargetPath {
            points: Vec::with_capacity(KEPT + 1),
        }
    }

    /// The newest target, if any.
    pub(super) fn newest(&self) -> Option<&Point> {
        self.points.last()
    }

    /// Adds a target newer than every one held (an older or equal stamp is ignored: false).
    pub(super) fn push(&mut self, p: Point) -> bool {
        if self.newest().is_some_and(|n| p.stamp_ns <= n.stamp_ns) {
            return false;
        }
        if self.points.len() == KEPT {
            self.points.remove(0);
        }
        self.points.push(p);
        true
    }

    /// Where the tool is at time `now_ns` (ROS time), and its velocity: `None` before the first
    /// target's turn (the tool holds where it is).
    pub(super) fn at(&self, now_ns: i64) -> Option<([f64; 3], [f64; 3])> {
        let tau = now_ns - PLAYOUT_NS;
        let after = self.points.iter().position(|p| p.stamp_ns > tau);
        let before = match after {
            Some(0) => return None,
            Some(i) => self.points[i - 1],
            None => *self.points.last()?,
        };
        let next = after
            .map(|i| self.points[i])
            .filter(|n| n.stamp_ns - before.stamp_ns <= MAX_SEGMENT_NS);
        let Some(next) = next else {
            // Past the newest target (or before one too far to interpolate to): along its
            // velocity, then held where that ended.
            let ahead = tau - before.stamp_ns;
            let v = before.velocity_m_per_s;
            let h = ahead.min(MAX_EXTRAPOLATION_NS) as f64 * 1e-9;
            let position = std::array::from_fn(|k| before.position_m[k] + v[k] * h);
            let moving = ahead < MAX_EXTRAPOLATION_NS;
            return Some((position, if moving { v } else { [0.0; 3] }));
        };
        let span = (next.stamp_ns - before.stamp_ns) as f64;
        let s = (tau - before.stamp_ns) as f64 / span;
        let velocity =
            std::array::from_fn(|k| (next.position_m[k] - before.position_m[k]) / (span * 1e-9));
        let position = std::array::from_fn(|k| {
            before.position_m[k] + s * (next.position_m[k] - before.position_m[k])
        });
        Some((position, velocity))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn point(ms: i64, x: f64, vx: f64) -> Point {
        Point {
            stamp_ns: ms * MS,
            position_m: [x, 0.0, 0.0],
            velocity_m_per_s: [vx, 0.0, 0.0],
        }
    }

    /// Targets along x = 0.05·t, delivered late and in bunches: the tool is where the path was
    /// a tick ago, whenever each target came, at the path's velocity.
    #[test]
    fn the_path_is_played_by_stamp_whatever_the_delivery() {
        let mut path = TargetPath::new();
        assert_eq!(path.at(5 * MS), None);
        // Targets 1..=3 arrive together; the tool at 3.5 ms is at 2.5 ms of the path.
        for ms in 1..=3 {
            assert!(path.push(point(ms, 0.05 * ms as f64 * 1e-3, 0.05)));
        }
        let (p, v) = path.at(3 * MS + MS / 2).unwrap();
        assert!((p[0] - 0.05 * 2.5e-3).abs() < 1e-15, "{p:?}");
        assert!((v[0] - 0.05).abs() < 1e-12, "{v:?}");
        // Target 4 is late: at 5.5 ms the path goes on from 3 along its velocity, and where
        // target 4 then says it is agrees.
        let (early, _) = path.at(5 * MS + MS / 2).unwrap();
        assert!(path.push(point(4, 0.05 * 4e-3, 0.05)));
        let (late, _) = path.at(5 * MS + MS / 2).unwrap();
        assert!((early[0] - late[0]).abs() < 1e-15, "{early:?} {late:?}");
        // An older or repeated target is ignored.
        assert!(!path.push(point(4, 1.0, 0.0)));
        assert!(!path.push(point(2, 1.0, 0.0)));
    }

    /// Before the first target's turn there is no path; past the newest target it goes on along
    /// its velocity for 10 ms, then holds; targets over 50 ms apart are not interpolated across.
    #[test]
    fn the_path_starts_at_the_first_target_and_holds_after_the_last() {
        let mut path = TargetPath::new();
        path.push(point(10, 0.0, 0.1));
        assert_eq!(path.at(10 * MS), None, "its turn is a tick after its stamp");
        let (p, _) = path.at(11 * MS).unwrap();
        assert_eq!(p[0], 0.0);
        let (held, v) = path.at(100 * MS).unwrap();
        assert!((held[0] - 0.1 * 0.01).abs() < 1e-15, "{held:?}");
        assert_eq!(v, [0.0; 3]);
        path.push(point(200, 0.5, 0.0));
        let (p, v) = path.at(150 * MS).unwrap();
        assert_eq!((p, v), (held, [0.0; 3]), "still held where it was");
        for ms in 201..=230 {
            path.push(point(ms, 0.5, 0.0));
        }
        assert_eq!(path.points.len(), KEPT);
    }
}
