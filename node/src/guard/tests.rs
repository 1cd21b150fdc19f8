use super::*;

const MS: i64 = 1_000_000;

fn target(p: Vec3) -> Target {
    Target {
        position_m: p,
        velocity_m_per_s: [0.0; 3],
        command_sample_time_ns: 7,
        holding: false,
    }
}

fn guard() -> CommandGuard {
    CommandGuard::new(CommandLimits::around([0.0; 3], 0.3)).unwrap()
}

fn close(a: Vec3, b: Vec3) -> bool {
    vec3::norm(vec3::sub(a, b)) < 1e-12
}

#[test]
fn nothing_is_commanded_before_a_state() {
    let mut g = guard();
    for k in 0..10 {
        let (cmd, _) = g.apply(k * MS, &target([0.0, 0.0, 0.01]));
        assert!(cmd.is_none());
    }
    assert_eq!(g.stats().no_state_ticks, 10);
    // A non-finite reading is not a state.
    g.on_reading(10 * MS, [f64::NAN, 0.0, 0.0]);
    assert!(g.apply(11 * MS, &target([0.0; 3])).0.is_none());
    g.on_reading(11 * MS, [0.0, 0.0, 0.01]);
    let (cmd, _) = g.apply(12 * MS, &target([0.0, 0.0, 0.0101]));
    assert!(close(cmd.unwrap().position_m, [0.0, 0.0, 0.0101]));
}

#[test]
fn a_stale_state_holds_the_last_command_until_the_state_returns() {
    let mut g = guard();
    g.on_reading(0, [0.0, 0.0, 0.01]);
    let mut p = [0.0, 0.0, 0.01];
    for k in 1..=50 {
        p[0] += 0.0001; // 0.1 m/s
        let (cmd, started) = g.apply(k * MS, &target(p));
        assert!(!started.stale_state);
        assert!(close(cmd.unwrap().position_m, p), "tick {k}");
    }
    // No reading since t = 0: at 50 ms it is still fresh (timeout is "older than 50 ms").
    let held = p;
    p[0] += 0.0001;
    let (cmd, started) = g.apply(51 * MS, &target(p));
    let cmd = cmd.unwrap();
    assert!(started.stale_state && cmd.holding && close(cmd.position_m, held));
    assert_eq!(cmd.velocity_m_per_s, [0.0; 3]);
    for k in 52..100 {
        p[0] += 0.0001;
        let (cmd, started) = g.apply(k * MS, &target(p));
        assert!(!started.stale_state, "logged once per episode");
        assert!(close(cmd.unwrap().position_m, held));
    }
    let s = g.stats().stale_state;
    assert_eq!((s.episodes, s.ticks), (1, 49));
    // The state returns: the target is far now, so the limits ramp to it.
    g.on_reading(100 * MS, [0.005, 0.0, 0.01]);
    let (cmd, _) = g.apply(100 * MS, &target(p));
    let step = vec3::norm(vec3::sub(cmd.unwrap().position_m, held));
    assert!((step - 0.001).abs() < 1e-12, "1 m/s × 1 ms, got {step}");
    assert_eq!(g.stats().max_speed.episodes, 1);
}

#[test]
fn the_workspace_box_clamps_per_axis() {
    let mut g = CommandGuard::new(CommandLimits {
        max_step_m: 0.1,
        max_speed_m_per_s: 3.0,
        ..CommandLimits::around([0.0; 3], 0.3)
    })
    .unwrap();
    g.on_reading(0, [0.29, 0.0, -0.29]);
    let (cmd, started) = g.apply(MS, &target([0.31, 0.0, -0.4]));
    assert!(started.workspace);
    assert!(close(cmd.unwrap().position_m, [0.3, 0.0, -0.3]));
    let mut g = CommandGuard::new(CommandLimits::around([0.0; 3], 0.3)).unwrap();
    g.on_reading(0, [0.3, 0.0, 0.0]);
    for k in 1..=5 {
        let (cmd, _) = g.apply(k * MS, &target([0.5, 0.0, 0.0]));
        assert!(close(cmd.unwrap().position_m, [0.3, 0.0, 0.0]));
    }
    let w = g.stats().workspace;
    assert_eq!((w.episodes, w.ticks), (1, 5));
}

#[test]
fn the_step_and_speed_limits_cut_every_move_and_count_it() {
    let limits = CommandLimits::around([0.0; 3], 0.3);
    let mut g = CommandGuard::new(limits).unwrap();
    g.on_reading(0, [0.0; 3]);
    assert!(g.apply(0, &target([0.0; 3])).0.is_some());
    // A 10 cm jump one tick later: the step limit cuts it to 2 mm, the speed to 1 mm.
    let (cmd, started) = g.apply(MS, &target([0.1, 0.0, 0.0]));
    assert!(started.max_speed && started.max_step);
    assert!(close(cmd.unwrap().position_m, [0.001, 0.0, 0.0]));
    // Within the limits: both stop acting.
    let (cmd, _) = g.apply(2 * MS, &target([0.0006, 0.0, 0.0]));
    assert!(close(cmd.unwrap().position_m, [0.0006, 0.0, 0.0]));
    assert!(!g.stats().max_step.active && !g.stats().max_speed.active);
    // After a 40 ms stall the speed would allow 20 mm: the step limit cuts it to 2 mm.
    g.on_reading(40 * MS, [0.0006, 0.0, 0.0]);
    let (cmd, started) = g.apply(42 * MS, &target([0.1, 0.0, 0.0]));
    assert!(started.max_step && !started.max_speed);
    assert!(close(cmd.unwrap().position_m, [0.0026, 0.0, 0.0]));
    // The commanded velocity is capped too.
    let mut t = target([0.0026, 0.0, 0.0]);
    t.velocity_m_per_s = [0.0, 3.0, 0.0];
    let (cmd, started) = g.apply(43 * MS, &t);
    assert!(started.max_speed);
    assert!(close(cmd.unwrap().velocity_m_per_s, [0.0, 1.0, 0.0]));
    let s = g.stats();
    assert_eq!((s.max_step.episodes, s.max_step.ticks), (2, 2));
    assert_eq!((s.max_speed.episodes, s.max_speed.ticks), (2, 2));
    // Every command within the limits passes unchanged: the exp-1 speeds.
    let mut g = CommandGuard::new(limits).unwrap();
    g.on_reading(0, [0.0; 3]);
    for k in 0..2000 {
        let t = k as f64 * 1e-3;
        let p = [0.07 * (1.3 * t).sin(), 0.03 * (5.0 * t).cos() - 0.03, 0.0];
        let (cmd, _) = g.apply(k * MS, &target(p));
        assert!(close(cmd.unwrap().position_m, p));
        g.on_reading(k * MS, p);
    }
    assert_eq!(
        g.stats().trips().iter().map(|(_, t)| t.ticks).sum::<u64>(),
        0
    );
}

#[test]
fn a_non_finite_target_holds_the_last_command() {
    let mut g = guard();
    g.on_reading(0, [0.0, 0.0, 0.01]);
    g.apply(MS, &target([0.0, 0.0, 0.0102]));
    let (cmd, started) = g.apply(2 * MS, &target([f64::NAN, 0.0, 0.0]));
    assert!(started.non_finite);
    let cmd = cmd.unwrap();
    assert!(cmd.holding && close(cmd.position_m, [0.0, 0.0, 0.0102]));
    let mut t = target([0.0; 3]);
    t.velocity_m_per_s[1] = f64::INFINITY;
    assert!(g.apply(3 * MS, &t).0.unwrap().holding);
    assert_eq!(g.stats().non_finite.ticks, 2);
}

#[test]
fn restart_limits_from_the_robot_not_the_last_session() {
    let mut g = guard();
    g.on_reading(0, [0.0; 3]);
    g.apply(MS, &target([0.0005, 0.0, 0.0]));
    g.restart();
    g.on_reading(2 * MS, [0.1, 0.0, 0.0]);
    let (cmd, _) = g.apply(2 * MS, &target([0.1, 0.0, 0.0]));
    assert!(close(cmd.unwrap().position_m, [0.1, 0.0, 0.0]));
}

#[test]
fn limits_are_validated() {
    let ok = CommandLimits::around([0.0; 3], 0.3);
    assert!(ok.validate().is_ok());
    let bad = [
        CommandLimits {
            max_step_m: 0.0,
            ..ok
        },
        CommandLimits {
            max_speed_m_per_s: f64::NAN,
            ..ok
        },
        CommandLimits {
            max_speed_m_per_s: 1e308,
            ..ok
        },
        CommandLimits {
            workspace_min_m: [0.0, 0.5, 0.0],
            ..ok
        },
        CommandLimits {
            workspace_max_m: [f64::INFINITY, 0.3, 0.3],
            ..ok
        },
        CommandLimits {
            state_timeout_ns: 0,
            ..ok
        },
    ];
    for limits in bad {
        let e = CommandGuard::new(limits).unwrap_err();
        assert!(e.to_string().starts_with("command limit "), "{e}");
    }
}
