//! The path handed to the robot is kept continuous in position and velocity.
//!
//! The playout's path breaks in two ways when commands come late. When its extrapolation along
//! the last command's velocity is overtaken by the command that was late, the path snaps onto
//! the interpolated one: measured on a demo over a jittery 50 ms link, 0.13 mm in one tick while
//! the velocity said 38 mm/s. When the extrapolation runs out, the path stops at once from the
//! operator's speed. A real arm cannot follow either (a tracking controller turns them into force
//! spikes), and in the simulated world the tool's position and velocity disagree for that tick:
//! the estimator read the force spike as a new object and threw its model away.
//!
//! So a break is absorbed into an offset, `e` (with its rate `ė`), that the output carries on top
//! of the playout's path and that decays as a critically damped second-order system,
//! `ë + 2ωė + ω²e = 0`: the output goes on from where it was, at the velocity it had, and joins
//! the path within about `5/ω` (35 ms), its acceleration bounded by the break's size. Faster is
//! harsher on the arm; slower made the telerobot lag: with ω = 50 the end-to-end delay measured
//! over loopback rose by 5–15 ms on this loaded machine (the output was in a blend a third of the
//! time); at 150 the delay tests then in use passed. A break is
//! a step away from where the output's own velocity leads (beyond what [`MAX_ACCEL`] explains in
//! one tick), or a step in velocity beyond that acceleration. While no break has happened the
//! path passes through bit for bit.

use mmt::vec3;

/// The offset's decay rate ω \[rad/s\]: a time constant of 6.7 ms.
const OMEGA: f64 = 150.0;
/// The largest acceleration a smooth path has \[m/s²\]: three times the exp-1 multisine's peak
/// (about 6 m/s²); a human hand's stays below it at 1 kHz sampling. Anything more is a break.
const MAX_ACCEL: f64 = 30.0;
/// A position step allowance on top of `MAX_ACCEL·dt²` for a device's velocity noise \[m\].
const POSITION_SLACK_M: f64 = 5e-6;
/// The largest break blended \[m, m/s\]: beyond, the path passes through as it is and the motion
/// guard's step and speed limits bound the way there (a blend of a 30 cm jump would reach 5 m/s).
const LARGEST_BREAK: (f64, f64) = (0.005, 0.5);
/// The offset is dropped once both it and its rate are this small \[m, m/s\].
const SETTLED: (f64, f64) = (1e-7, 1e-5);

/// The output's state between ticks.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Continuity {
    /// The last path given: its position \[m\] and velocity \[m/s\] (none while holding).
    path: Option<([f64; 3], [f64; 3])>,
    /// The last output: its time \[ns\], position \[m\] and velocity \[m/s\].
    out: Option<(i64, [f64; 3], [f64; 3])>,
    /// The offset `e` \[m\] and its rate `ė` \[m/s\] at the last output.
    offset: Option<([f64; 3], [f64; 3])>,
    /// Breaks of the path.
    pub(super) breaks: u64,
    /// Of them, too large to blend ([`LARGEST_BREAK`]).
    pub(super) unblended_breaks: u64,
    /// Ticks handed on with an offset.
    pub(super) blended_ticks: u64,
}

impl Continuity {
    /// The output for the playout's path `(position, velocity)` at `now_ns`.
    pub(super) fn pass(
        &mut self,
        now_ns: i64,
        position: [f64; 3],
        velocity: [f64; 3],
    ) -> ([f64; 3], [f64; 3]) {
        let Some((then, q0, u0)) = self.out else {
            self.path = Some((position, velocity));
            self.out = Some((now_ns, position, velocity));
            return (position, velocity);
        };
        let dt = now_ns.saturating_sub(then).max(0) as f64 * 1e-9;
        // A break of the path itself (the offset's own decay is smooth by construction), or the
        // path taken up again after a hold.
        let broken = self.path.is_none_or(|(p0, v0)| {
            let step = vec3::sub(position, vec3::add(p0, vec3::scale(v0, dt)));
            let jump = vec3::sub(velocity, v0);
            vec3::norm(step) > MAX_ACCEL * dt * dt + POSITION_SLACK_M
                || vec3::norm(jump) > MAX_ACCEL * dt.max(1e-3)
        });
        self.path = Some((position, velocity));
        let (e, de) = if broken {
            // The output goes on from where it was, at the velocity it had.
            self.breaks += 1;
            let led = vec3::add(q0, vec3::scale(u0, dt));
            let (e, de) = (vec3::sub(led, position), vec3::sub(u0, velocity));
            if vec3::norm(e) > LARGEST_BREAK.0 || vec3::norm(de) > LARGEST_BREAK.1 {
                self.unblended_breaks += 1;
                ([0.0; 3], [0.0; 3])
            } else {
                (e, de)
            }
        } else {
            match self.offset {
                Some((e, de)) => decay(e, de, dt),
                None => ([0.0; 3], [0.0; 3]),
            }
        };
        let settled = vec3::norm(e) < SETTLED.0 && vec3::norm(de) < SETTLED.1;
        self.offset = (!settled).then_some((e, de));
        let out = match self.offset {
            Some((e, de)) => {
                self.blended_ticks += 1;
                (vec3::add(position, e), vec3::add(velocity, de))
            }
            None => (position, velocity),
        };
        self.out = Some((now_ns, out.0, out.1));
        out
    }

    /// The robot is told to hold still at `position` (no fresh command): when the path is taken
    /// up again, the output starts from there at rest and joins it.
    /// Before any path (the session's first command) there is nothing to go on from: the first
    /// path passes through as it is, as far as the motion guard lets it.
    pub(super) fn hold(&mut self, now_ns: i64, position: [f64; 3]) {
        if self.out.is_none() {
            return;
        }
        self.path = None;
        self.offset = None;
        self.out = Some((now_ns, position, [0.0; 3]));
    }
}

/// The offset and its rate `dt` seconds on: `e(t) = (e₀ + (ė₀ + ωe₀)t)·exp(−ωt)`,
/// `ė(t) = (ė₀ − ω(ė₀ + ωe₀)t)·exp(−ωt)`.
fn decay(e: [f64; 3], de: [f64; 3], dt: f64) -> ([f64; 3], [f64; 3]) {
    let k = (-OMEGA * dt).exp();
    let c: [f64; 3] = std::array::from_fn(|i| de[i] + OMEGA * e[i]);
    (
        std::array::from_fn(|i| (e[i] + c[i] * dt) * k),
        std::array::from_fn(|i| (de[i] - OMEGA * c[i] * dt) * k),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    /// A position and a velocity.
    type State = ([f64; 3], [f64; 3]);

    /// Runs `path(t)` (position, velocity at `t` seconds) through a fresh pass at 1 kHz for
    /// `ticks`; returns the outputs and the pass.
    fn run(ticks: i64, path: impl Fn(f64) -> State) -> (Vec<State>, Continuity) {
        let mut c = Continuity::default();
        let out = (0..ticks)
            .map(|k| {
                let (p, v) = path(k as f64 * 1e-3);
                c.pass(k * MS, p, v)
            })
            .collect();
        (out, c)
    }

    #[test]
    fn a_smooth_path_passes_bit_for_bit() {
        // The exp-1 multisine's scale: 4 cm at 2 Hz (peak acceleration 6.3 m/s²).
        let w = 2.0 * std::f64::consts::PI * 2.0;
        let path = |t: f64| {
            (
                [0.04 * (w * t).sin(), 0.0, 0.0],
                [0.04 * w * (w * t).cos(), 0.0, 0.0],
            )
        };
        let (out, c) = run(2000, path);
        for (k, o) in out.iter().enumerate() {
            assert_eq!(*o, path(k as f64 * 1e-3));
        }
        assert_eq!((c.breaks, c.blended_ticks), (0, 0));
    }

    #[test]
    fn a_snap_is_blended_with_position_and_velocity_continuous() {
        // At 20 ms the path snaps 0.13 mm ahead and its velocity from 15 to 38 mm/s (the demo's
        // case); the output goes on from where it was and joins the new path.
        let path = |t: f64| {
            if t < 0.020 {
                ([0.015 * t, 0.0, 0.0], [0.015, 0.0, 0.0])
            } else {
                (
                    [0.015 * 0.020 + 0.13e-3 + 0.038 * (t - 0.020), 0.0, 0.0],
                    [0.038, 0.0, 0.0],
                )
            }
        };
        let (out, c) = run(300, path);
        assert_eq!(c.breaks, 1);
        let mut largest_accel: f64 = 0.0;
        for w in out.windows(2) {
            let (step, dv) = (w[1].0[0] - w[0].0[0], w[1].1[0] - w[0].1[0]);
            // Position steps agree with the velocities around them.
            assert!(
                (step - 0.5e-3 * (w[0].1[0] + w[1].1[0])).abs() < 2e-6,
                "{w:?}"
            );
            largest_accel = largest_accel.max((dv / 1e-3).abs());
        }
        // Bounded by ω²·|e₀| + 2ω·|ė₀| (2.9 + 6.9 m/s²), against the snap's 130 m/s² (0.13 mm
        // in one tick).
        assert!(largest_accel < 10.0, "{largest_accel} m/s²");
        // Joined within 200 ms: the offset is gone, the path passes through again.
        let last = out[299];
        assert_eq!(last, path(0.299));
        assert!(c.blended_ticks < 250, "{}", c.blended_ticks);
    }

    #[test]
    fn an_instant_stop_decelerates_and_comes_back_to_the_stop() {
        // Moving at 0.25 m/s, the path stops dead at 10 ms (its extrapolation ran out).
        let path = |t: f64| {
            let t = t.min(0.010);
            (
                [0.25 * t, 0.0, 0.0],
                [if t < 0.010 { 0.25 } else { 0.0 }, 0.0, 0.0],
            )
        };
        let (out, c) = run(400, path);
        assert_eq!(c.breaks, 1);
        let stop = 0.25 * 0.010;
        let overshoot = out.iter().map(|o| o.0[0] - stop).fold(0.0, f64::max);
        // e peaks at ė₀/(ω·e) = 0.25/(150·2.718) = 0.61 mm.
        assert!(
            (overshoot - 0.25 / (OMEGA * std::f64::consts::E)).abs() < 5e-5,
            "{overshoot}"
        );
        assert!((out[399].0[0] - stop).abs() < 1e-6, "{:?}", out[399]);
        assert!(out[399].1[0].abs() < 1e-4, "{:?}", out[399]);
    }

    #[test]
    fn the_decay_is_the_exact_solution_of_the_critically_damped_system() {
        // Stepped in one go or in a thousand small steps: the same, and e'' + 2ωė + ω²e = 0.
        let (e0, de0) = ([1e-3, -2e-3, 0.5e-3], [0.02, 0.0, -0.01]);
        let once = decay(e0, de0, 0.05);
        let mut many = (e0, de0);
        for _ in 0..1000 {
            many = decay(many.0, many.1, 0.05e-3);
        }
        for i in 0..3 {
            assert!((once.0[i] - many.0[i]).abs() < 1e-15);
            assert!((once.1[i] - many.1[i]).abs() < 1e-13);
        }
        // From rest at e₀ = 1 mm: e(t) = e₀(1 + ωt)e^{−ωt}.
        let (e, _) = decay([1e-3, 0.0, 0.0], [0.0; 3], 0.04);
        let exact = 1e-3 * (1.0 + OMEGA * 0.04) * (-OMEGA * 0.04f64).exp();
        assert!((e[0] - exact).abs() < 1e-18);
    }

    #[test]
    fn a_break_too_large_to_blend_passes_through() {
        let mut c = Continuity::default();
        c.pass(0, [0.0; 3], [0.0; 3]);
        c.hold(MS, [0.0; 3]);
        let far = ([0.3, 0.0, 0.0], [0.0; 3]);
        assert_eq!(c.pass(2 * MS, far.0, far.1), far);
        assert_eq!((c.breaks, c.unblended_breaks, c.blended_ticks), (1, 1, 0));
        // From rest, a stop from 0.6 m/s is too fast a break too.
        c.pass(3 * MS, [0.3006, 0.0, 0.0], [0.6, 0.0, 0.0]);
        assert_eq!((c.breaks, c.unblended_breaks), (2, 2));
    }

    #[test]
    fn after_a_hold_the_path_is_joined_from_rest_where_the_robot_held() {
        let mut c = Continuity::default();
        c.pass(0, [0.0; 3], [0.1, 0.0, 0.0]);
        c.hold(MS, [1e-4, 0.0, 0.0]);
        // Taken up again 0.6 mm away and moving: the output starts where it held, at rest.
        let (p, v) = c.pass(2 * MS, [7e-4, 0.0, 0.0], [0.1, 0.0, 0.0]);
        assert!(
            (p[0] - 1e-4).abs() < 1e-12 && v[0].abs() < 1e-12,
            "{p:?} {v:?}"
        );
        assert_eq!(c.breaks, 1);
        let mut last = (p, v);
        for k in 3..400 {
            let t = (k - 2) as f64 * 1e-3;
            last = c.pass(k * MS, [7e-4 + 0.1 * t, 0.0, 0.0], [0.1, 0.0, 0.0]);
        }
        assert_eq!(last.0[0], 7e-4 + 0.1 * 0.397);
    }
}
