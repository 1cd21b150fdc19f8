use super::*;

fn target(position_m: Vec3, velocity_m_per_s: Vec3) -> Target {
    Target {
        position_m,
        velocity_m_per_s,
        command_sample_time_ns: 7,
        holding: false,
    }
}

fn limits() -> MotionLimits {
    MotionLimits::around([0.0, 0.0, 0.0])
}

#[test]
fn a_command_far_away_is_clamped_into_the_box_one_step_per_tick() {
    let mut g = MotionGuard::new(limits());
    let mut at = [0.0, 0.0, 0.01];
    for tick in 0..1000 {
        let t = g.limit(&target([1e306, 0.0, 0.01], [0.0; 3]), at);
        let step = vec3::norm(vec3::sub(t.position_m, at));
        assert!(
            step <= MotionLimits::MAX_STEP_M * (1.0 + 1e-12),
            "{tick}: {step}"
        );
        assert!(
            limits().contains(t.position_m),
            "{tick}: {:?}",
            t.position_m
        );
        assert_eq!(t.command_sample_time_ns, 7);
        at = t.position_m;
    }
    // 0.25 m at 1 mm per tick: at the wall after 250 ticks, and held there.
    assert_eq!(at, [0.25, 0.0, 0.01]);
    let s = g.stats();
    assert_eq!(
        s.workspace,
        LimitCount {
            ticks: 1000,
            episodes: 1
        }
    );
    // 250 steps, the last one within rounding of a whole step.
    assert!((249..=250).contains(&s.step.ticks), "{:?}", s.step);
    assert_eq!(s.step.episodes, 1);
    assert_eq!(s.speed, LimitCount::default());
}

#[test]
fn motion_within_the_limits_is_untouched_and_not_counted() {
    let mut g = MotionGuard::new(limits());
    let mut at = [0.0; 3];
    for k in 0..2000 {
        let t = k as f64 * 1e-3;
        // 3 cm at 2 Hz: 0.38 m/s at most.
        let w = 2.0 * std::f64::consts::PI * 2.0;
        let wanted = target(
            [0.03 * (w * t).sin(), 0.0, 0.0],
            [0.03 * w * (w * t).cos(), 0.0, 0.0],
        );
        let out = g.limit(&wanted, at);
        assert_eq!(out, wanted);
        at = out.position_m;
    }
    assert_eq!(g.stats(), GuardStats::default());
}

#[test]
fn speed_is_clamped_and_no_velocity_points_out_of_a_face() {
    let mut g = MotionGuard::new(limits());
    let t = g.limit(&target([0.0; 3], [3.0, 4.0, 0.0]), [0.0; 3]);
    assert!((vec3::norm(t.velocity_m_per_s) - 1.0).abs() < 1e-12);
    assert!((t.velocity_m_per_s[0] - 0.6).abs() < 1e-12);
    assert_eq!(
        g.stats().speed,
        LimitCount {
            ticks: 1,
            episodes: 1
        }
    );
    // At the +x wall asking for more: the outward velocity is dropped.
    let mut g = MotionGuard::new(limits());
    let t = g.limit(
        &target([0.3, 0.0, 0.0], [0.5, 0.1, 0.0]),
        [0.2495, 0.0, 0.0],
    );
    assert_eq!(t.position_m, [0.25, 0.0, 0.0]);
    assert_eq!(t.velocity_m_per_s, [0.0, 0.1, 0.0]);
    // Two episodes of the speed limit with a quiet tick between.
    let mut g = MotionGuard::new(limits());
    for v in [2.0, 2.0, 0.1, 2.0] {
        g.limit(&target([0.0; 3], [v, 0.0, 0.0]), [0.0; 3]);
    }
    assert_eq!(
        g.stats().speed,
        LimitCount {
            ticks: 3,
            episodes: 2
        }
    );
}

#[test]
fn garbage_targets_hold_and_a_robot_outside_the_box_is_brought_in_gently() {
    let mut g = MotionGuard::new(limits());
    let t = g.limit(
        &target([f64::NAN, 0.0, 0.0], [f64::INFINITY; 3]),
        [0.01, 0.0, 0.0],
    );
    assert_eq!(t.position_m, [0.01, 0.0, 0.0]);
    assert_eq!(t.velocity_m_per_s, [0.0; 3]);
    // The tool starts 10 cm outside: the first target is one step toward the box, not a jump.
    let mut g = MotionGuard::new(limits());
    let t = g.limit(&target([0.35, 0.0, 0.0], [0.0; 3]), [0.35, 0.0, 0.0]);
    assert_eq!(t.position_m, [0.349, 0.0, 0.0]);
    // A tool that is not finite either: the box's centre is the reference.
    let mut g = MotionGuard::new(limits());
    let t = g.limit(&target([f64::NAN; 3], [0.0; 3]), [f64::NAN; 3]);
    assert_eq!(t.position_m, [0.0; 3]);
}

#[test]
fn limits_are_validated_against_their_ceilings() {
    assert_eq!(limits().validate(), Ok(()));
    let bad = |f: fn(&mut MotionLimits)| {
        let mut l = limits();
        f(&mut l);
        l.validate().unwrap_err().to_string()
    };
    assert!(bad(|l| l.max_step_m = 0.0).contains("max_step_m = 0"));
    assert!(bad(|l| l.max_step_m = f64::NAN).contains("max_step_m"));
    assert!(bad(|l| l.max_speed_m_per_s = 1e308).contains("at most 2 m/s"));
    assert!(bad(|l| l.workspace_max_m[1] = -1.0).contains("axis 1"));
    assert!(bad(|l| l.workspace_max_m[2] = 1e300).contains("at most 4 m wide"));
    assert!(bad(|l| l.max_clock_jump_ns = 0).contains("0.1 to 60 s"));
}

/// A bridge that reads NaN after `poison_after` steps until it is recovered.
struct Fragile {
    tool_m: Vec3,
    steps: u32,
    poison_after: u32,
    recoverable: bool,
    recovered_at: Vec<Vec3>,
}

impl RobotBridge for Fragile {
    fn tool_m(&self) -> Option<Vec3> {
        Some(self.tool_m)
    }
    fn step(&mut self, _now_ns: i64, target: Option<&Target>) -> BridgeSample {
        self.steps += 1;
        self.tool_m = if self.steps > self.poison_after {
            [f64::NAN; 3]
        } else {
            target.map_or(self.tool_m, |t| t.position_m)
        };
        BridgeSample {
            measured: crate::RobotSample {
                position_m: self.tool_m,
                ..Default::default()
            },
            tool_m: self.tool_m,
            object_slide_m: [0.0; 2],
            reading: Reading::ThisTick,
        }
    }
    fn recover(&mut self, tool_m: Vec3) -> bool {
        self.recovered_at.push(tool_m);
        if self.recoverable {
            self.tool_m = tool_m;
            self.steps = 0;
            self.poison_after = u32::MAX;
        }
        self.recoverable
    }
}

fn fragile(poison_after: u32, recoverable: bool) -> Fragile {
    Fragile {
        tool_m: [0.0; 3],
        steps: 0,
        poison_after,
        recoverable,
        recovered_at: Vec::new(),
    }
}

#[test]
fn a_reading_that_is_not_finite_is_a_fault_the_bridge_recovers_from() {
    let mut g = Guarded::new(fragile(3, true), limits());
    for k in 1..=3 {
        let s = g.step(0, Some(&target([0.001 * k as f64, 0.0, 0.0], [0.0; 3])));
        assert!(s.measured.is_finite());
    }
    let s = g.step(0, Some(&target([0.004, 0.0, 0.0], [0.0; 3])));
    assert!(!s.measured.is_finite());
    // Recovered at the last finite position, counted once.
    assert_eq!(g.bridge().recovered_at, vec![[0.003, 0.0, 0.0]]);
    assert_eq!((g.stats().faults, g.stats().recovered), (1, 1));
    assert_eq!(g.tool_m(), Some([0.003, 0.0, 0.0]));
    let s = g.step(0, Some(&target([0.004, 0.0, 0.0], [0.0; 3])));
    assert!(s.measured.is_finite());
    // Healthy at the next session: nothing to do.
    assert!(!g.begin_session());
    assert_eq!(g.stats().faults, 1);
}

#[test]
fn a_bridge_that_cannot_recover_is_reported_at_every_session_and_never_trusted() {
    let mut g = Guarded::new(fragile(0, false), limits());
    g.step(0, Some(&target([0.001, 0.0, 0.0], [0.0; 3])));
    assert_eq!((g.stats().faults, g.stats().recovered), (1, 0));
    // Its position is not finite: the guard reports the last safe one.
    assert_eq!(g.tool_m(), Some([0.0; 3]));
    assert!(g.begin_session());
    assert_eq!(g.stats().faults, 2);
}

const MS: i64 = 1_000_000;

/// A robot whose states arrive when the test says, stamped (a ROS 2 robot's, say).
#[derive(Default)]
struct Remote {
    /// The newest state the robot reported.
    state: Option<Vec3>,
    /// A state to hand over on the next step: when it was read, where the tool was.
    arriving: Option<(i64, Vec3)>,
    /// What the bridge was told, tick by tick.
    told: Vec<Option<Target>>,
}

impl RobotBridge for Remote {
    fn tool_m(&self) -> Option<Vec3> {
        self.state
    }
    fn step(&mut self, _now_ns: i64, target: Option<&Target>) -> BridgeSample {
        self.told.push(target.copied());
        let Some((t, p)) = self.arriving.take() else {
            return BridgeSample {
                reading: if self.state.is_some() {
                    Reading::Repeated
                } else {
                    Reading::Nothing
                },
                ..BridgeSample::default()
            };
        };
        self.state = Some(p);
        BridgeSample {
            measured: crate::RobotSample {
                position_m: p,
                ..Default::default()
            },
            tool_m: p,
            object_slide_m: [0.0; 2],
            reading: Reading::Stamped {
                sample_time_ns: t,
                command_sample_time_ns: 0,
            },
        }
    }
}

#[test]
fn nothing_is_commanded_before_the_robots_first_state() {
    let mut g = Guarded::new(Remote::default(), limits());
    assert_eq!(g.tool_m(), None);
    for k in 0..10 {
        g.step(k * MS, Some(&target([0.0, 0.0, 0.01], [0.0; 3])));
        assert!(g.commanded().is_none());
    }
    assert!(g.bridge().told.iter().all(Option::is_none));
    assert_eq!(g.stats().no_state_ticks, 10);
    // A state that is not finite is not a state (and is a fault).
    g.bridge.arriving = Some((10 * MS, [f64::NAN, 0.0, 0.0]));
    g.step(10 * MS, None);
    assert_eq!(g.stats().faults, 1);
    g.bridge.arriving = Some((11 * MS, [0.0, 0.0, 0.01]));
    g.step(11 * MS, None);
    g.bridge.arriving = Some((12 * MS, [0.0, 0.0, 0.01]));
    g.step(12 * MS, Some(&target([0.0, 0.0, 0.0101], [0.0; 3])));
    let told = g.bridge().told.last().unwrap().unwrap();
    assert!(vec3::norm(vec3::sub(told.position_m, [0.0, 0.0, 0.0101])) < 1e-12);
    // The tick that brought the bad state still had none; none counted since.
    assert_eq!(g.stats().no_state_ticks, 11);
}

#[test]
fn a_stale_state_holds_the_last_command_until_the_state_returns() {
    let mut g = Guarded::new(Remote::default(), limits());
    g.bridge.arriving = Some((0, [0.0, 0.0, 0.01]));
    g.step(0, None);
    let mut p = [0.0, 0.0, 0.01];
    for k in 1..=50 {
        p[0] += 0.0001; // 0.1 m/s
        g.step(k * MS, Some(&target(p, [0.1, 0.0, 0.0])));
        let c = g.commanded().unwrap();
        assert!(!c.holding && c.position_m == p, "tick {k}");
        assert!(!g.state_is_stale(k * MS));
    }
    // No state since t = 0: at 50 ms it is still fresh (the timeout is "older than 50 ms").
    let held = p;
    for k in 51..100 {
        p[0] += 0.0001;
        g.step(k * MS, Some(&target(p, [0.1, 0.0, 0.0])));
        let c = g.commanded().unwrap();
        assert!(c.holding && c.position_m == held, "tick {k}");
        assert_eq!(c.velocity_m_per_s, [0.0; 3]);
        assert!(g.state_is_stale(k * MS));
    }
    assert_eq!(
        g.stats().stale_state,
        LimitCount {
            ticks: 49,
            episodes: 1
        }
    );
    // The state returns: the target is far now, so the step limit ramps to it.
    g.bridge.arriving = Some((100 * MS, [0.005, 0.0, 0.01]));
    g.step(100 * MS, None);
    assert!(!g.state_is_stale(100 * MS));
    g.step(101 * MS, Some(&target(p, [0.0; 3])));
    let step = vec3::norm(vec3::sub(g.commanded().unwrap().position_m, held));
    assert!((step - MotionLimits::MAX_STEP_M).abs() < 1e-12, "{step}");
    assert_eq!(g.stats().step.episodes, 1);
    assert_eq!(g.stats().stale_state.episodes, 1);
}

#[test]
fn a_new_session_limits_from_the_robot_not_the_last_session() {
    let mut g = Guarded::new(Remote::default(), limits());
    g.bridge.arriving = Some((0, [0.0; 3]));
    g.step(0, None);
    g.step(MS, Some(&target([0.0005, 0.0, 0.0], [0.0; 3])));
    assert!(!g.begin_session());
    g.bridge.arriving = Some((2 * MS, [0.1, 0.0, 0.0]));
    g.step(2 * MS, None);
    g.step(3 * MS, Some(&target([0.1, 0.0, 0.0], [0.0; 3])));
    assert_eq!(g.commanded().unwrap().position_m, [0.1, 0.0, 0.0]);
}

mod properties {
    use super::*;
    use proptest::prelude::*;

    /// Any f64, the awkward ones over-represented.
    fn any_value() -> impl Strategy<Value = f64> {
        prop_oneof![
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(1e306),
            Just(-1e306),
            Just(f64::MAX),
            -1.0..1.0f64,
            any::<f64>(),
        ]
    }

    fn any_vec() -> impl Strategy<Value = Vec3> {
        [any_value(), any_value(), any_value()]
    }

    proptest! {
        /// Whatever the operator sends, tick after tick: the commanded position stays in the box
        /// (once in), moves at most one step, and the commanded speed stays under the limit.
        #[test]
        fn every_target_is_bounded(targets in proptest::collection::vec((any_vec(), any_vec()), 1..200)) {
            let l = limits();
            let mut g = MotionGuard::new(l);
            let mut at = [0.0; 3];
            for (p, v) in targets {
                let t = g.limit(&target(p, v), at);
                prop_assert!(vec3::is_finite(t.position_m) && vec3::is_finite(t.velocity_m_per_s));
                prop_assert!(l.contains(t.position_m), "{:?}", t.position_m);
                prop_assert!(vec3::norm(vec3::sub(t.position_m, at)) <= l.max_step_m * (1.0 + 1e-9));
                prop_assert!(vec3::norm(t.velocity_m_per_s) <= l.max_speed_m_per_s * (1.0 + 1e-9));
                at = t.position_m;
            }
        }
    }
}
