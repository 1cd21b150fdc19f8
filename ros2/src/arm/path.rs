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

/// Natural frequency of the tool's return to its path after a break in the path \[rad/s\]: a
/// Cartesian impedance controller's spring and damper (critically damped), 10 Hz.
const RETURN_OMEGA: f64 = 2.0 * std::f64::consts::PI * 10.0;
/// Largest acceleration of the tool while it returns to its path \[m/s²\] (a Panda's Cartesian
/// limit is 13 m/s²).
const MAX_ACCELERATION: f64 = 10.0;
/// How far the path may be from where the tool's own motion puts it (the mean of the two
/// velocities over the period) before that is a break in the path, and how close the tool must
/// come back to follow it exactly again \[m\]. A break is also a change of velocity beyond
/// [`MAX_ACCELERATION`].
const ON_PATH_M: f64 = 5e-6;

/// Where the tool actually goes: the path exactly while the path is one an arm can follow; across
/// a break in it (it holds after running out of targets, or jumps to a newer target) the tool
/// neither stops dead nor jumps, which no arm does, but returns to the path as an impedance
/// controller holding a moved equilibrium would: critically damped at [`RETURN_OMEGA`] about the
/// path (whose acceleration is fed forward), its acceleration limited to [`MAX_ACCELERATION`].
/// Its position and velocity always agree (each period moves it by the mean of its two
/// velocities). The telerobot's `node::continuity` blends its own path's breaks the same way
/// (an offset decaying at 150 rad/s, no acceleration limit); this is the arm's side.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Follower {
    /// The tool's position and velocity, once it has any.
    state: Option<([f64; 3], [f64; 3])>,
    /// Returning to the path after a break.
    returning: bool,
    /// Breaks, and periods spent returning.
    breaks: (u64, u64),
    /// The path's velocity at the last period (its acceleration is fed forward).
    last_v_r: [f64; 3],
}

impl Follower {
    /// Breaks in the path, and periods spent returning to it.
    pub(super) fn breaks(&self) -> (u64, u64) {
        self.breaks
    }

    /// The tool's position and velocity after one period `dt_s` toward the path's point
    /// `(x_r, v_r)`.
    pub(super) fn step(&mut self, x_r: [f64; 3], v_r: [f64; 3], dt_s: f64) -> ([f64; 3], [f64; 3]) {
        let last_v_r = std::mem::replace(&mut self.last_v_r, v_r);
        let Some((x, v)) = self.state else {
            self.state = Some((x_r, v_r));
            return (x_r, v_r);
        };
        let follows = (0..3).all(|k| {
            let moved = x[k] + 0.5 * (v[k] + v_r[k]) * dt_s;
            (x_r[k] - moved).abs() <= ON_PATH_M && (v_r[k] - v[k]).abs() <= MAX_ACCELERATION * dt_s
        });
        if !self.returning && follows {
            self.state = Some((x_r, v_r));
            return (x_r, v_r);
        }
        if !self.returning {
            self.breaks.0 += 1;
        }
        self.breaks.1 += 1;
        self.returning = true;
        let w = RETURN_OMEGA;
        // The path's own acceleration fed forward (a break's is not an arm's: limited), so the
        // tool converges onto an accelerating path instead of lagging it.
        let a_r =
            |k: usize| ((v_r[k] - last_v_r[k]) / dt_s).clamp(-MAX_ACCELERATION, MAX_ACCELERATION);
        // The spring and damper act on where the tool would be at the path's time without them.
        let mut a: [f64; 3] = std::array::from_fn(|k| {
            let v_free = v[k] + a_r(k) * dt_s;
            let x_free = x[k] + 0.5 * (v[k] + v_free) * dt_s;
            a_r(k) + w * w * (x_r[k] - x_free) + 2.0 * w * (v_r[k] - v_free)
        });
        let norm = a.iter().map(|c| c * c).sum::<f64>().sqrt();
        if norm > MAX_ACCELERATION {
            a = a.map(|c| c * MAX_ACCELERATION / norm);
        }
        let v_next: [f64; 3] = std::array::from_fn(|k| v[k] + a[k] * dt_s);
        let x_next: [f64; 3] = std::array::from_fn(|k| x[k] + 0.5 * (v[k] + v_next[k]) * dt_s);
        self.returning = !(0..3).all(|k| {
            (x_r[k] - x_next[k]).abs() <= ON_PATH_M
                && (v_r[k] - v_next[k]).abs() <= MAX_ACCELERATION * dt_s
        });
        self.state = Some((x_next, v_next));
        (x_next, v_next)
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

    /// A path an arm can follow is followed exactly; one that stops dead and one that jumps are
    /// not: the tool comes back to them without a velocity change beyond the acceleration limit,
    /// its position always moving by the mean of its velocities, and then follows exactly again.
    #[test]
    fn the_tool_returns_to_a_broken_path_as_an_arm_would() {
        let dt = 1e-3;
        let mut f = Follower::default();
        let check =
            |f: &mut Follower, prev: &mut ([f64; 3], [f64; 3]), x: [f64; 3], v: [f64; 3]| {
                let (xt, vt) = f.step(x, v, dt);
                assert!(
                    (vt[0] - prev.1[0]).abs() <= MAX_ACCELERATION * dt + 1e-12,
                    "{vt:?} {prev:?}"
                );
                let moved = prev.0[0] + 0.5 * (prev.1[0] + vt[0]) * dt;
                // (Back on the path it is placed on it: within `ON_PATH_M`.)
                assert!(
                    (xt[0] - moved).abs() <= ON_PATH_M + 1e-12,
                    "{xt:?} {prev:?}"
                );
                *prev = (xt, vt);
                (xt, vt)
            };
        // Along x = 0.1·t: exact.
        let mut prev = f.step([0.0; 3], [0.1, 0.0, 0.0], dt);
        for k in 1..=50 {
            let t = k as f64 * dt;
            let (x, v) = check(&mut f, &mut prev, [0.1 * t, 0.0, 0.0], [0.1, 0.0, 0.0]);
            assert_eq!((x[0], v[0]), (0.1 * t, 0.1));
        }
        // The path holds at 5 mm: the tool decelerates, overshoots by at most v²/2a, comes back.
        let hold = [0.1 * 0.05, 0.0, 0.0];
        let mut furthest: f64 = 0.0;
        for _ in 0..300 {
            let (x, _) = check(&mut f, &mut prev, hold, [0.0; 3]);
            furthest = furthest.max(x[0] - hold[0]);
        }
        assert!(
            furthest > 0.0 && furthest <= 0.1 * 0.1 / (2.0 * MAX_ACCELERATION) + 1e-4,
            "{furthest}"
        );
        assert_eq!(
            f.step(hold, [0.0; 3], dt),
            (hold, [0.0; 3]),
            "back on the path"
        );
        prev = (hold, [0.0; 3]);
        // The path jumps 1 mm ahead and moves on: the tool catches up, then follows exactly.
        for k in 1..=400 {
            let x = hold[0] + 1e-3 + 0.02 * k as f64 * dt;
            check(&mut f, &mut prev, [x, 0.0, 0.0], [0.02, 0.0, 0.0]);
        }
        let x = hold[0] + 1e-3 + 0.02 * 401.0 * dt;
        assert_eq!(f.step([x, 0.0, 0.0], [0.02, 0.0, 0.0], dt).0[0], x);
        prev = ([x, 0.0, 0.0], [0.02, 0.0, 0.0]);
        // A jump onto a path accelerating at 2 m/s²: caught up within 0.3 s, not lagged behind.
        let (x0, a) = (x + 2e-3, 2.0);
        let on = |k: i64| {
            let t = k as f64 * dt;
            (
                [x0 + 0.02 * t + 0.5 * a * t * t, 0.0, 0.0],
                [0.02 + a * t, 0.0, 0.0],
            )
        };
        for k in 1..=300 {
            let (x, v) = on(k);
            check(&mut f, &mut prev, x, v);
        }
        let (x, v) = on(301);
        assert_eq!(f.step(x, v, dt), (x, v), "on the accelerating path");
        assert_eq!(f.breaks().0, 3);
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
