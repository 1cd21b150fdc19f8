//! How a robot arm's tool follows a commanded path: exactly while the path is one an arm can
//! follow, and across a break in it (the commands stopped, or jumped) as an impedance controller
//! would. The ROS 2 test arm (`ros2::arm`) moves its simulated tool this way, and the estimator's
//! tests reproduce its stops with it.

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
pub struct Follower {
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
    pub fn breaks(&self) -> (u64, u64) {
        self.breaks
    }

    /// The tool's position and velocity after one period `dt_s` toward the path's point
    /// `(x_r, v_r)`.
    pub fn step(&mut self, x_r: [f64; 3], v_r: [f64; 3], dt_s: f64) -> ([f64; 3], [f64; 3]) {
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
}
