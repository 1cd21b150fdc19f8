use proptest::prelude::*;

use super::*;

const MS: Duration = Duration::from_millis(1);
const INSIDE: Vec3 = [0.0; 3];
const FRESH: Model = Model::Rendering {
    params_age: Duration::ZERO,
};

fn omega() -> DeviceCapabilities {
    DeviceCapabilities::omega7("test")
}

fn layer(config: SafetyConfig) -> SafetyLayer {
    SafetyLayer::new(&omega(), &config).unwrap()
}

/// A layer whose rate limit does not interfere.
fn fast() -> SafetyLayer {
    layer(SafetyConfig {
        max_force_rate_n_per_s: 1e12,
        ..SafetyConfig::default()
    })
}

fn tick(k: u32, force_n: Vec3) -> ForceTick {
    ForceTick {
        now: k * MS,
        measured_cp: INSIDE,
        model: FRESH,
        force_n,
    }
}

/// A default layer after `ticks` ticks of a steady force along x (reached after the ramp-up).
fn holding(force_x: f64, ticks: u32) -> SafetyLayer {
    let mut s = layer(SafetyConfig::default());
    for k in 0..ticks {
        s.filter_force(&tick(k, [force_x, 0.0, 0.0]));
    }
    s
}

fn close(a: Vec3, b: Vec3) -> bool {
    vec3::norm(vec3::sub(a, b)) < 1e-9
}

#[test]
fn nan_storm_from_rest_writes_only_zero() {
    let mut s = layer(SafetyConfig::default());
    let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    for k in 0..300u32 {
        let f = [bad[k as usize % 3], 1.0, -1.0];
        assert_eq!(s.filter_force(&tick(k, f)), [0.0; 3]);
    }
    assert_eq!(s.stats().non_finite_force.episodes, 1);
    assert_eq!(s.stats().non_finite_force.ticks, 300);
}

#[test]
fn nan_cuts_a_held_force_to_zero_at_once_and_force_returns_rate_limited() {
    let mut s = holding(5.0, 20);
    assert!(close(
        s.filter_force(&tick(20, [5.0, 0.0, 0.0])),
        [5.0, 0.0, 0.0]
    ));
    assert_eq!(s.filter_force(&tick(21, [f64::NAN, 0.0, 0.0])), [0.0; 3]);
    // Back: 1 N per tick (1000 N/s at 1 kHz).
    assert!(close(
        s.filter_force(&tick(22, [5.0, 0.0, 0.0])),
        [1.0, 0.0, 0.0]
    ));
}

proptest! {
    /// Whatever the renderer outputs, the device sees finite forces within the limit, and zero
    /// on every tick whose input was not finite.
    #[test]
    fn output_is_always_finite_and_bounded(
        inputs in proptest::collection::vec(
            (prop_oneof![
                Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY), -1e6..1e6f64
            ], -50.0..50.0f64, -0.2..0.2f64),
            1..400,
        )
    ) {
        let mut s = layer(SafetyConfig::default());
        for (k, (fx, fy, x)) in inputs.into_iter().enumerate() {
            let k = u32::try_from(k).unwrap();
            let t = ForceTick { measured_cp: [x, 0.0, 0.0], ..tick(k, [fx, fy, 0.0]) };
            let out = s.filter_force(&t);
            prop_assert!(vec3::is_finite(out));
            prop_assert!(vec3::norm(out) <= 12.0 + 1e-9);
            if !fx.is_finite() {
                prop_assert_eq!(out, [0.0; 3]);
            }
        }
    }
}

#[test]
fn force_step_beyond_the_rate_limit_is_spread_over_ticks() {
    let mut s = layer(SafetyConfig::default());
    let mut out = Vec::new();
    for k in 0..12 {
        out.push(s.filter_force(&tick(k, [0.0, 10.0, 0.0]))[1]);
    }
    // 1000 N/s × 1 ms = 1 N per tick (the first tick uses the nominal period).
    let want = [
        1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 10.0, 10.0,
    ];
    for (got, want) in out.iter().zip(want) {
        assert!((got - want).abs() < 1e-9, "{out:?}");
    }
    assert_eq!(s.stats().rate_limited.episodes, 1);
    // Ticks 0–8 are limited; tick 9 reaches 10 N with a step of exactly 1 N.
    assert_eq!(s.stats().rate_limited.ticks, 9);
    // Down as well.
    let down = s.filter_force(&tick(12, [0.0; 3]));
    assert!(close(down, [0.0, 9.0, 0.0]));
}

#[test]
fn saturation_keeps_direction() {
    let mut s = fast();
    let out = s.filter_force(&tick(0, [30.0, -40.0, 0.0]));
    assert!(close(out, [7.2, -9.6, 0.0]), "{out:?}");
    assert_eq!(s.stats().saturated.ticks, 1);
    // Below the limit nothing changes.
    let out = s.filter_force(&tick(1, [3.0, -4.0, 0.0]));
    assert!(close(out, [3.0, -4.0, 0.0]));
}

#[test]
fn a_lower_force_limit_applies() {
    let mut s = layer(SafetyConfig {
        force_limit_n: Some(2.0),
        max_force_rate_n_per_s: 1e12,
        ..SafetyConfig::default()
    });
    assert_eq!(s.max_force_n(), 2.0);
    assert!(close(
        s.filter_force(&tick(0, [0.0, 0.0, -9.0])),
        [0.0, 0.0, -2.0]
    ));
}

#[test]
fn workspace_spring_pushes_back_and_has_priority() {
    let mut s = fast();
    // 10 mm outside the 75 mm sphere along +x: 500 N/m × 0.01 m = 5 N inward.
    let outside = [0.085, 0.0, 0.0];
    let t = |k, f| ForceTick {
        measured_cp: outside,
        ..tick(k, f)
    };
    assert!(close(s.filter_force(&t(0, [0.0; 3])), [-5.0, 0.0, 0.0]));
    // A sideways renderer force is shrunk so the total stays at 12 N; the spring is intact.
    let out = s.filter_force(&t(1, [0.0, 12.0, 0.0]));
    assert!(
        (out[0] + 5.0).abs() < 1e-9 && (vec3::norm(out) - 12.0).abs() < 1e-9,
        "{out:?}"
    );
    // A renderer pushing outward cannot cancel the push-back beyond the budget.
    let out = s.filter_force(&t(2, [12.0, 0.0, 0.0]));
    assert!(close(out, [7.0, 0.0, 0.0]), "{out:?}");
    let out = s.filter_force(&t(3, [-12.0, 0.0, 0.0]));
    assert!(close(out, [-12.0, 0.0, 0.0]), "{out:?}");
    assert_eq!(s.stats().workspace.episodes, 1);
    // Inside again: no spring.
    assert!(close(
        s.filter_force(&tick(4, [1.0, 0.0, 0.0])),
        [1.0, 0.0, 0.0]
    ));
}

#[test]
fn workspace_stiffness_is_capped_at_the_device_maximum() {
    let mut s = layer(SafetyConfig {
        workspace_stiffness_n_per_m: 1e6,
        max_force_rate_n_per_s: 1e12,
        ..SafetyConfig::default()
    });
    let t = ForceTick {
        measured_cp: [0.0, 0.0, 0.076],
        ..tick(0, [0.0; 3])
    };
    // 5000 N/m × 1 mm = 5 N (not 1000 N, not even 12 N).
    assert!(close(s.filter_force(&t), [0.0, 0.0, -5.0]));
}

/// Runs a constant 6 N renderer force; `gap_at` inserts a late tick, `model` gives the model
/// (and its parameter age) per tick. Returns the output magnitudes at each tick time [ms].
fn run_watchdog(
    ticks: u32,
    gap_at: Option<u32>,
    model: impl Fn(u32) -> Model,
) -> (Vec<(u32, f64)>, SafetyLayer) {
    let mut s = layer(SafetyConfig::default());
    let mut out = Vec::new();
    let mut t = 0;
    for k in 0..ticks {
        t += if Some(k) == gap_at { 6 } else { 1 };
        let f = s.filter_force(&ForceTick {
            now: t * MS,
            measured_cp: INSIDE,
            model: model(t),
            force_n: [6.0, 0.0, 0.0],
        });
        out.push((t, f[0]));
    }
    (out, s)
}

fn assert_no_step(out: &[(u32, f64)]) {
    // Skip the start, where the rate limit ramps the force up at 1 N per tick.
    for w in out[10..].windows(2) {
        // The fade is 6 N / 50 ms = 0.12 N/ms (0.72 N over the 6 ms gap); the fade-in is slower.
        let (dt, df) = (f64::from(w[1].0 - w[0].0), (w[1].1 - w[0].1).abs());
        assert!(df <= 0.12 * dt.min(3.0) + 1e-9, "step {w:?}");
    }
}

#[test]
fn loop_overrun_fades_to_zero_and_recovers() {
    let (out, s) = run_watchdog(700, Some(100), |_| FRESH);
    let at = |t: u32| {
        out.iter()
            .find(|(tt, _)| *tt == t)
            .map(|(_, f)| *f)
            .unwrap()
    };
    assert!((at(100) - 6.0).abs() < 1e-9);
    assert!(at(110) < 6.0 && at(110) > 0.0, "fading, not stepping");
    assert_eq!(at(160), 0.0, "zero after the fade");
    assert_eq!(at(200), 0.0, "held during the recovery hold");
    assert!(at(250) > 0.0 && at(250) < 6.0, "fading back in");
    assert!((at(600) - 6.0).abs() < 1e-9, "recovered");
    assert_no_step(&out);
    assert_eq!(s.stats().loop_overrun.episodes, 1);
    assert_eq!(s.stats().watchdog_fading.episodes, 1);
}

#[test]
fn stale_parameters_fade_out_and_fresh_ones_fade_back_in() {
    // Parameters stop arriving at t = 100 ms (age grows), resume at 900 ms.
    let age = |t: u32| Model::Rendering {
        params_age: if (100..900).contains(&t) {
            (t - 100) * MS
        } else {
            Duration::ZERO
        },
    };
    let (out, s) = run_watchdog(1500, None, age);
    let at = |t: u32| out[(t - 1) as usize].1;
    assert!((at(600) - 6.0).abs() < 1e-9, "age 500 ms is still fresh");
    assert!(at(620) < 6.0 && at(620) > 0.0, "fading");
    assert_eq!(at(700), 0.0);
    assert_eq!(at(950), 0.0, "recovery hold");
    assert!((at(1400) - 6.0).abs() < 1e-9, "recovered");
    assert_no_step(&out);
    assert_eq!(s.stats().stale_params.episodes, 1);
}

/// Ticks at `period` for 2 s with one tick `late` beyond its deadline half-way (if any);
/// returns the overrun episodes.
fn overruns_at(period: Duration, late: Option<Duration>) -> u64 {
    let mut s = layer(SafetyConfig::default());
    s.set_loop_period(period).unwrap();
    assert_eq!(s.loop_period(), period);
    let ticks = (2.0 / period.as_secs_f64()) as u32;
    let mut now = Duration::ZERO;
    for k in 0..ticks {
        now += period;
        if k == ticks / 2 {
            now += late.unwrap_or_default();
        }
        s.filter_force(&ForceTick {
            now,
            ..tick(0, [1.0, 0.0, 0.0])
        });
    }
    s.stats().loop_overrun.episodes
}

/// Regression: the overrun rule measured against a fixed 1 ms whatever the control rate, so a
/// 200 Hz loop overran on every tick and a 2 kHz one could lose 2.5 ms unnoticed.
#[test]
fn the_overrun_rule_follows_the_loop_period() {
    let allowance = WatchdogConfig::default().max_overrun;
    for hz in [200u64, 2000] {
        let period = Duration::from_nanos(1_000_000_000 / hz);
        assert_eq!(overruns_at(period, None), 0, "{hz} Hz healthy");
        // Late by just under and just over the allowance.
        let under = allowance - Duration::from_micros(10);
        let over = allowance + Duration::from_micros(10);
        assert_eq!(
            overruns_at(period, Some(under)),
            0,
            "{hz} Hz within the allowance"
        );
        assert_eq!(
            overruns_at(period, Some(over)),
            1,
            "{hz} Hz beyond the allowance"
        );
    }
    let mut s = layer(SafetyConfig::default());
    assert!(s.set_loop_period(Duration::ZERO).is_err());
}

/// Regression: every healthy session started with a stale-params trip, because the telerobot
/// sends parameters only after the first contact and "none yet" counted as stale — and the fade
/// also switched the workspace spring off.
#[test]
fn no_model_yet_is_not_stale_and_the_workspace_spring_acts() {
    let mut s = layer(SafetyConfig::default());
    let outside = [0.085, 0.0, 0.0];
    let mut last = [0.0; 3];
    for k in 0..300u32 {
        last = s.filter_force(&ForceTick {
            now: k * MS,
            measured_cp: outside,
            model: Model::None,
            force_n: [0.0; 3],
        });
    }
    // 500 N/m × 10 mm = 5 N inward, at full strength.
    assert!(close(last, [-5.0, 0.0, 0.0]), "{last:?}");
    let st = s.stats();
    assert_eq!(st.stale_params.episodes, 0);
    assert_eq!(st.watchdog_fading.episodes, 0);
    assert_eq!(st.workspace.episodes, 1);
    assert_eq!(s.watchdog_gain(), 1.0);
}

#[test]
fn stale_parameters_fade_the_renderer_but_never_the_workspace_spring() {
    let mut s = layer(SafetyConfig::default());
    let outside = [0.085, 0.0, 0.0];
    let stale = Model::Rendering {
        params_age: Duration::from_secs(2),
    };
    let mut last = [0.0; 3];
    for k in 0..300u32 {
        last = s.filter_force(&ForceTick {
            now: k * MS,
            measured_cp: outside,
            model: stale,
            force_n: [0.0, 4.0, 0.0],
        });
    }
    // The renderer's sideways 4 N is gone, the spring's 5 N inward is intact.
    assert!(close(last, [-5.0, 0.0, 0.0]), "{last:?}");
    assert_eq!(s.stats().stale_params.episodes, 1);
    assert_eq!(s.watchdog_gain(), 0.0);
}

#[test]
fn a_loop_overrun_fades_the_workspace_spring_too() {
    let mut s = layer(SafetyConfig::default());
    let outside = [0.085, 0.0, 0.0];
    let mut t = 0;
    let mut out = Vec::new();
    for k in 0..100u32 {
        t += if k == 50 { 10 } else { 1 };
        out.push(s.filter_force(&ForceTick {
            now: t * MS,
            measured_cp: outside,
            model: Model::None,
            force_n: [0.0; 3],
        }));
    }
    assert!(close(out[49], [-5.0, 0.0, 0.0]));
    assert_eq!(
        out[99], [0.0; 3],
        "zero force while the loop's timing is lost"
    );
    assert_eq!(s.stats().loop_overrun.episodes, 1);
}

#[test]
fn clutch_holds_the_command_and_release_continues_without_a_jump() {
    let mut s = fast();
    assert_eq!(
        s.command_position([0.01, 0.0, 0.0], false),
        [0.01, 0.0, 0.0]
    );
    // Engaged: the device moves 3 cm, the command holds.
    for x in [0.02, 0.03, 0.04] {
        assert_eq!(s.command_position([x, 0.0, 0.0], true), [0.01, 0.0, 0.0]);
    }
    // Released: continues from the held position.
    assert_eq!(
        s.command_position([0.04, 0.0, 0.0], false),
        [0.01, 0.0, 0.0]
    );
    let c = s.command_position([0.05, 0.0, 0.0], false);
    assert!(close(c, [0.02, 0.0, 0.0]), "{c:?}");
    assert_eq!(s.stats().clutch.episodes, 1);
}

#[test]
fn clutch_replaces_the_renderer_force_by_zero_without_a_step() {
    let mut s = holding(5.0, 10);
    s.command_position(INSIDE, true);
    let f = s.filter_force(&tick(10, [5.0, 0.0, 0.0]));
    assert!(close(f, [4.0, 0.0, 0.0]), "rate limited toward zero: {f:?}");
}

#[test]
fn scale_change_does_not_move_the_command() {
    let mut s = fast();
    s.command_position([0.02, 0.0, 0.0], false);
    s.set_position_scale(3.0).unwrap();
    assert!(close(
        s.command_position([0.02, 0.0, 0.0], false),
        [0.02, 0.0, 0.0]
    ));
    assert!(close(
        s.command_position([0.03, 0.0, 0.0], false),
        [0.05, 0.0, 0.0]
    ));
}

#[test]
fn scaling_rejects_zero_negative_nan_and_inf() {
    let mut s = fast();
    s.set_position_scale(2.0).unwrap();
    for bad in [
        0.0,
        -0.0,
        -1.0,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        20.01,
        1e308,
    ] {
        let e = s.set_position_scale(bad).unwrap_err();
        assert!(
            e.to_string().contains("expected a finite number > 0"),
            "{e}"
        );
        assert!(PositionScale::new(bad).is_err());
        let cfg = SafetyConfig {
            position_scale: bad,
            ..SafetyConfig::default()
        };
        assert!(SafetyLayer::new(&omega(), &cfg).is_err());
    }
    assert_eq!(s.stats().scale_rejections, 8);
    assert_eq!(s.position_map().scale().get(), 2.0, "old scale kept");
    s.set_position_scale(PositionScale::MAX).unwrap();
}

#[test]
fn non_finite_measured_position_holds_the_command() {
    let mut s = fast();
    s.command_position([0.01, 0.02, 0.03], false);
    assert_eq!(
        s.command_position([f64::NAN, 0.0, 0.0], false),
        [0.01, 0.02, 0.03]
    );
    assert_eq!(s.stats().non_finite_position.episodes, 1);
}

#[derive(Clone, Debug)]
enum Op {
    Move(Vec3, bool),
    Scale(f64),
}

fn op() -> impl Strategy<Value = Op> {
    let step = -0.005..0.005f64;
    prop_oneof![
        8 => (step.clone(), step.clone(), step, any::<bool>())
            .prop_map(|(x, y, z, c)| Op::Move([x, y, z], c)),
        1 => prop_oneof![0.1..10.0f64, Just(0.0), Just(-1.0), Just(f64::NAN)].prop_map(Op::Scale),
    ]
}

proptest! {
    /// Any clutch and scale sequence gives a continuous commanded position: each tick it moves
    /// at most `scale × device motion` (zero while clutched), never a jump.
    #[test]
    fn any_clutch_sequence_gives_a_continuous_command(ops in proptest::collection::vec(op(), 1..300)) {
        let mut s = fast();
        let mut measured = [0.0; 3];
        let mut last = s.command_position(measured, false);
        for op in ops {
            match op {
                Op::Scale(f) => { let _ = s.set_position_scale(f); }
                Op::Move(d, clutch) => {
                    let next = vec3::add(measured, d);
                    let c = s.command_position(next, clutch);
                    let bound = s.position_map().scale().get() * vec3::norm(d) + 1e-12;
                    prop_assert!(vec3::norm(vec3::sub(c, last)) <= bound,
                        "jump {:?} → {:?} for device step {:?}", last, c, d);
                    if s.position_map().clutched() {
                        prop_assert_eq!(c, last);
                    }
                    measured = next;
                    last = c;
                }
            }
        }
    }
}

#[test]
fn stats_serialise_for_reports() {
    let mut s = layer(SafetyConfig::default());
    s.filter_force(&tick(0, [f64::NAN, 0.0, 0.0]));
    let json = serde_json::to_value(s.stats()).unwrap();
    assert_eq!(json["non_finite_force"]["episodes"], 1);
    assert_eq!(json["ticks"], 1);
    assert!(json["non_finite_force"].get("active").is_none());
}

#[test]
fn invalid_settings_are_refused_with_the_field() {
    let bad = [
        SafetyConfig {
            max_force_rate_n_per_s: 0.0,
            ..SafetyConfig::default()
        },
        SafetyConfig {
            force_limit_n: Some(f64::NAN),
            ..SafetyConfig::default()
        },
        SafetyConfig {
            workspace_stiffness_n_per_m: -1.0,
            ..SafetyConfig::default()
        },
        SafetyConfig {
            watchdog: WatchdogConfig {
                fade_out: Duration::ZERO,
                ..WatchdogConfig::default()
            },
            ..SafetyConfig::default()
        },
        SafetyConfig {
            watchdog: WatchdogConfig {
                recovery_hold: Duration::from_millis(10),
                ..WatchdogConfig::default()
            },
            ..SafetyConfig::default()
        },
    ];
    for cfg in bad {
        let e = SafetyLayer::new(&omega(), &cfg).unwrap_err().to_string();
        assert!(e.starts_with("invalid safety setting"), "{e}");
    }
}

#[test]
fn a_device_without_force_output_gets_zero() {
    let caps = DeviceCapabilities {
        max_force_n: 0.0,
        max_stiffness_n_per_m: 0.0,
        outputs_force: false,
        ..omega()
    };
    let mut s = SafetyLayer::new(&caps, &SafetyConfig::default()).unwrap();
    let t = ForceTick {
        measured_cp: [1.0, 0.0, 0.0],
        ..tick(0, [5.0, 0.0, 0.0])
    };
    assert_eq!(s.filter_force(&t), [0.0; 3]);
}

// ---- Passivity at the device port ----

/// A layer with no rate limit and the given passivity settings.
fn passivity_layer(passivity: PassivityConfig) -> SafetyLayer {
    layer(SafetyConfig {
        max_force_rate_n_per_s: 1e12,
        passivity,
        ..SafetyConfig::default()
    })
}

fn observe_only() -> PassivityConfig {
    PassivityConfig {
        control: false,
        ..PassivityConfig::default()
    }
}

/// The hand moves the device along x, `x = A sin ωt` (A = 20 mm, 1 Hz), for `ticks` ticks of
/// 1 ms; `env(k, x, v)` is the renderer's force along x. Returns the positions and the forces
/// written.
fn drive(
    s: &mut SafetyLayer,
    ticks: u32,
    env: impl Fn(u32, f64, f64) -> f64,
) -> (Vec<f64>, Vec<f64>) {
    let (a, w) = (0.02, std::f64::consts::TAU);
    let (mut xs, mut out) = (Vec::new(), Vec::new());
    for k in 0..ticks {
        let t = f64::from(k) * 1e-3;
        let (x, v) = (a * (w * t).sin(), a * w * (w * t).cos());
        let f = s.filter_force(&ForceTick {
            measured_cp: [x, 0.0, 0.0],
            ..tick(k, [env(k, x, v), 0.0, 0.0])
        });
        assert!(vec3::is_finite(f));
        assert_eq!((f[1], f[2]), (0.0, 0.0));
        xs.push(x);
        out.push(f[0]);
    }
    (xs, out)
}

/// `E(n) = −Σ F(j−1)·(x(j) − x(j−1))`, recomputed outside the layer from what it wrote.
fn port_energy(xs: &[f64], out: &[f64]) -> Vec<f64> {
    let mut e = vec![0.0];
    for j in 1..xs.len() {
        let last = e[j - 1];
        e.push(last - out[j - 1] * (xs[j] - xs[j - 1]));
    }
    e
}

/// A spring rendered with a zero-order hold is active by exactly `½k Σ Δx²` (Colgate's point):
/// the observer's energy is the closed form `½k x² − ½k Σ Δx²`.
#[test]
fn the_observer_measures_a_held_spring_exactly() {
    let k = 500.0;
    let mut s = passivity_layer(observe_only());
    let (xs, out) = drive(&mut s, 3000, |_, x, _| -k * x);
    assert!(
        out.iter().zip(&xs).all(|(f, x)| (f + k * x).abs() <= 1e-12),
        "observing changes nothing"
    );
    let mut sum_d2 = 0.0;
    let mut min_exact = 0.0f64;
    for j in 1..xs.len() {
        sum_d2 += (xs[j] - xs[j - 1]).powi(2);
        min_exact = min_exact.min(0.5 * k * xs[j] * xs[j] - 0.5 * k * sum_d2);
    }
    let n = xs.len() - 1;
    let exact = 0.5 * k * xs[n] * xs[n] - 0.5 * k * sum_d2;
    let p = s.stats().passivity;
    assert!(
        (p.energy_j - exact).abs() < 1e-12,
        "{} vs {exact}",
        p.energy_j
    );
    assert!((p.min_energy_j - min_exact).abs() < 1e-12);
    assert!(p.min_energy_j < 0.0, "a held spring is active");
    assert_eq!(p.controlling.ticks, 0);
}

/// A negative damper (an active environment, 10 N·s/m) is held at zero energy by the
/// controller: the energy at the port, recomputed from the forces actually written, never goes
/// below one tick's prediction error after the first tick. Without the controller it loses b∫v² (≈ 0.24 J in 3 s).
#[test]
fn the_controller_keeps_an_active_environment_passive() {
    let b = 10.0;
    let env = |_, _, v: f64| b * v;
    let mut observed = passivity_layer(observe_only());
    drive(&mut observed, 3000, env);
    let loose = observed.stats().passivity.min_energy_j;
    assert!(loose < -0.2, "uncontrolled energy {loose} J");

    let mut s = passivity_layer(PassivityConfig::default());
    let (xs, out) = drive(&mut s, 3000, env);
    let energy = port_energy(&xs, &out);
    // The first interval cannot be predicted (no displacement yet); from the next tick on the
    // controller holds the energy at zero.
    assert!(energy[1] < 0.0);
    let min = energy[2..].iter().copied().fold(f64::INFINITY, f64::min);
    assert!(min > -1e-5, "controlled energy reached {min} J");
    let p = s.stats().passivity;
    assert!((p.energy_j - energy[energy.len() - 1]).abs() < 1e-12);
    assert!(p.controlling.ticks > 2000, "{:?}", p.controlling);
    assert_eq!(p.capped.ticks, 0);
    assert!(p.dissipated_j > 0.2, "{}", p.dissipated_j);
}

/// A passive environment (spring and damper with b > kT/2) is never touched: the force written
/// is the renderer's, bit for bit.
#[test]
fn a_passive_environment_is_left_alone() {
    let (k, b) = (500.0, 5.0);
    let mut s = passivity_layer(PassivityConfig::default());
    let (xs, out) = drive(&mut s, 3000, |_, x, v| -k * x - b * v);
    let p = s.stats().passivity;
    assert_eq!(p.controlling.ticks, 0, "{p:?}");
    assert!(p.min_energy_j >= 0.0);
    let (a, w) = (0.02, std::f64::consts::TAU);
    for (j, (x, f)) in xs.iter().zip(&out).enumerate() {
        let v = a * w * (w * j as f64 * 1e-3).cos();
        assert!((f + k * x + b * v).abs() <= 1e-12, "tick {j}: {f}");
    }
}

/// Beyond the device's damping limit the controller adds the limit and says so: a 100 N·s/m
/// negative damper against the omega's 30 N·s/m leaves 70 % of the activity.
#[test]
fn the_controller_damping_is_capped_at_the_device_limit() {
    let env = |_, _, v: f64| 100.0 * v;
    let mut observed = passivity_layer(observe_only());
    drive(&mut observed, 2000, env);
    let mut s = passivity_layer(PassivityConfig::default());
    drive(&mut s, 2000, env);
    let p = s.stats().passivity;
    assert!(p.capped.ticks > 1900, "{:?}", p.capped);
    let ratio = p.min_energy_j / observed.stats().passivity.min_energy_j;
    assert!((ratio - 0.7).abs() < 0.02, "ratio {ratio}");
}

/// The reserve is capped: energy a damper dissipated long ago does not pay for later activity.
/// With an unbounded reserve the 2 s of dissipation would hide the 2 s of activity after it.
#[test]
fn the_energy_reserve_is_capped() {
    let b = 20.0;
    let env = |k: u32, _, v: f64| if k < 2000 { -b * v } else { b * v };
    let mut unbounded = passivity_layer(PassivityConfig {
        energy_cap_j: 1e3,
        ..PassivityConfig::default()
    });
    drive(&mut unbounded, 4000, env);
    assert_eq!(unbounded.stats().passivity.controlling.ticks, 0);

    let cap = 0.01;
    let mut s = passivity_layer(PassivityConfig {
        energy_cap_j: cap,
        ..PassivityConfig::default()
    });
    let (xs, out) = drive(&mut s, 4000, env);
    let p = s.stats().passivity;
    assert!(p.controlling.ticks > 1500, "{:?}", p.controlling);
    assert!(p.energy_j <= cap && p.energy_j > -1e-5);
    // Recomputed with the cap, the port's energy matches and stays non-negative.
    let mut e = 0.0f64;
    for j in 1..xs.len() {
        e = (e - out[j - 1] * (xs[j] - xs[j - 1])).min(cap);
        assert!(e > -1e-5, "tick {j}: {e} J");
    }
    assert!((e - p.energy_j).abs() < 1e-12);
}

/// Garbage positions: a NaN interval and a 5 cm jump are left out of the energy and counted;
/// nothing non-finite comes out.
#[test]
fn position_glitches_are_left_out_of_the_energy() {
    let mut s = passivity_layer(PassivityConfig::default());
    let feed = |s: &mut SafetyLayer, k: u32, x: f64, f: f64| {
        s.filter_force(&ForceTick {
            measured_cp: [x, 0.0, 0.0],
            ..tick(k, [f, 0.0, 0.0])
        })
    };
    feed(&mut s, 0, 0.0, 2.0);
    feed(&mut s, 1, 0.001, 2.0); // E = −2 N · 1 mm = −2 mJ: the controller acts from here
    let after_first = s.stats().passivity.energy_j;
    assert!((after_first + 0.002).abs() < 1e-15);
    let f = feed(&mut s, 2, f64::NAN, 2.0);
    assert!(vec3::is_finite(f));
    let f = feed(&mut s, 3, 0.06, 2.0); // first finite sample after NaN: no interval
    assert!(vec3::is_finite(f));
    let f = feed(&mut s, 4, 0.0, 2.0); // 6 cm in one tick: a glitch
    assert!(vec3::is_finite(f));
    let p = s.stats().passivity;
    assert_eq!(p.glitches, 2);
    assert_eq!(p.energy_j, after_first);
}

/// A device without damping to spare (max damping 0, as the SpaceMouse) is observed only.
#[test]
fn zero_damping_limit_observes_only() {
    let mut s = passivity_layer(PassivityConfig {
        max_damping_n_s_per_m: Some(0.0),
        ..PassivityConfig::default()
    });
    drive(&mut s, 1000, |_, _, v| 10.0 * v);
    let p = s.stats().passivity;
    assert_eq!(p.controlling.ticks, 0);
    assert!(p.min_energy_j < -0.01);
}

#[test]
fn invalid_passivity_settings_are_refused_with_the_field() {
    for (passivity, field) in [
        (
            PassivityConfig {
                max_damping_n_s_per_m: Some(-1.0),
                ..PassivityConfig::default()
            },
            "passivity.max_damping_n_s_per_m",
        ),
        (
            PassivityConfig {
                max_damping_n_s_per_m: Some(f64::NAN),
                ..PassivityConfig::default()
            },
            "passivity.max_damping_n_s_per_m",
        ),
        (
            PassivityConfig {
                energy_cap_j: 0.0,
                ..PassivityConfig::default()
            },
            "passivity.energy_cap_j",
        ),
    ] {
        let cfg = SafetyConfig {
            passivity,
            ..SafetyConfig::default()
        };
        let e = SafetyLayer::new(&omega(), &cfg).unwrap_err().to_string();
        assert!(e.contains(field), "{e}");
    }
}

/// Collects the `rule` field and level of every event.
#[derive(Clone, Default)]
struct Captured(std::sync::Arc<std::sync::Mutex<Vec<(tracing::Level, String)>>>);

impl<S: tracing::Subscriber> tracing_subscriber::Layer<S> for Captured {
    fn on_event(&self, event: &tracing::Event<'_>, _: tracing_subscriber::layer::Context<'_, S>) {
        struct Rule(Option<String>);
        impl tracing::field::Visit for Rule {
            fn record_str(&mut self, field: &tracing::field::Field, value: &str) {
                if field.name() == "rule" {
                    self.0 = Some(value.to_owned());
                }
            }
            fn record_debug(&mut self, _: &tracing::field::Field, _: &dyn std::fmt::Debug) {}
        }
        let mut rule = Rule(None);
        event.record(&mut rule);
        if let Some(rule) = rule.0 {
            self.0
                .lock()
                .unwrap()
                .push((*event.metadata().level(), rule));
        }
    }
}

/// Every trip is a log event — one warning when a rule starts acting and one note when it stops,
/// never one per tick — and a counter in the stats.
#[test]
fn every_trip_is_logged_once_per_episode_and_counted() {
    use tracing_subscriber::layer::SubscriberExt;
    let captured = Captured::default();
    let subscriber = tracing_subscriber::registry().with(captured.clone());
    let stats = tracing::subscriber::with_default(subscriber, || {
        let mut s = layer(SafetyConfig::default());
        let mut k = 0;
        let mut run = |s: &mut SafetyLayer, ticks: u32, f: Vec3| {
            for _ in 0..ticks {
                s.filter_force(&tick(k, f));
                k += 1;
            }
        };
        run(&mut s, 50, [f64::NAN, 0.0, 0.0]); // non-finite force, 50 ticks
        run(&mut s, 3000, [100.0, 0.0, 0.0]); // a step far above the rate limit, then saturation
        run(&mut s, 3000, [0.0; 3]);
        s.stats()
    });
    let events = captured.0.lock().unwrap().clone();
    let count = |level: tracing::Level, rule: &str| {
        events
            .iter()
            .filter(|(l, r)| *l == level && r == rule)
            .count() as u64
    };
    for (rule, episodes) in [
        ("non-finite force", stats.non_finite_force.episodes),
        ("rate limit", stats.rate_limited.episodes),
        ("saturation", stats.saturated.episodes),
    ] {
        assert!(episodes >= 1, "{rule}: {stats:?}");
        assert_eq!(
            count(tracing::Level::WARN, rule),
            episodes,
            "{rule}: {events:?}"
        );
        assert_eq!(
            count(tracing::Level::INFO, rule),
            episodes,
            "{rule}: {events:?}"
        );
    }
}
