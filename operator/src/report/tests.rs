use super::*;
use crate::device::{BackendReport, DeviceSpec, OpenOptions, open_device};
use crate::haptic::LoopEnd;

fn facts() -> RunFacts {
    RunFacts {
        run: metrics::networked::NetworkedRun {
            experiment: "networked".into(),
            scene: "exp1".into(),
            device: "scripted:hold".into(),
            period_ns: 1_000_000,
            ..Default::default()
        },
        truth: None,
        link: LinkReport::default(),
        measurements_overwritten: 0,
        timing: TimingReport::default(),
        wall_seconds: 0.0,
    }
}

/// A report whose loop ended with these safety counters and renderer counters.
fn report(safety: SafetyStats, renderers: Vec<RendererStats>) -> NetworkedReport {
    let spec = DeviceSpec::Scripted {
        name: "hold".into(),
    };
    let device = open_device(&spec, &OpenOptions::default()).unwrap();
    let end = LoopEnd {
        force_record: *device.force_record(),
        device,
        safety,
        node: Default::default(),
        renderers,
        ticks: 0,
        frame: None,
        parameters: None,
        sessions: 1,
        prior: None,
    };
    build(&facts(), &Recording::default(), &end).1
}

fn trip(episodes: u64) -> crate::safety::TripCount {
    crate::safety::TripCount {
        episodes,
        ticks: 10 * episodes,
        active: false,
    }
}

/// The table's value for the row starting with `name`.
fn value<'a>(table: &'a str, name: &str) -> &'a str {
    table
        .lines()
        .find(|l| l.starts_with(name))
        .map(|l| l[name.len()..].trim())
        .unwrap_or_else(|| panic!("no row '{name}' in\n{table}"))
}

/// Regression: the non-finite, overrun, stale-parameter and clutch counters were in the JSON
/// only.
#[test]
fn the_table_shows_every_trip_counter() {
    let safety = SafetyStats {
        non_finite_force: trip(1),
        non_finite_position: trip(2),
        non_finite_velocity: trip(3),
        saturated: trip(4),
        rate_limited: trip(5),
        workspace: trip(6),
        loop_overrun: trip(7),
        stale_params: trip(8),
        watchdog_fading: trip(9),
        clutch: trip(10),
        scale_rejections: 11,
        ..SafetyStats::default()
    };
    let t = table(&report(safety, Vec::new()), &PeerFigures::default());
    assert_eq!(
        value(&t, "safety episodes: watchdog / rate / max / workspace"),
        "9 / 5 / 4 / 6"
    );
    assert_eq!(
        value(&t, "  loop overrun / stale parameters / clutch"),
        "7 / 8 / 10"
    );
    assert_eq!(
        value(&t, "  non-finite force / position / velocity"),
        "1 / 2 / 3"
    );
    assert_eq!(value(&t, "  position-scale changes refused"), "11");
    assert_eq!(value(&t, "device state, faults"), "Disabled / 0");
}

/// Issue 11: the clouds the real-time budget reduced or refused were counted in the JSON only.
#[test]
fn the_table_shows_the_clouds_over_budget_on_both_sides() {
    let mut r = report(SafetyStats::default(), Vec::new());
    r.clouds = (120, 3);
    r.clouds_over_budget = (7, 2);
    let peer = PeerFigures {
        telerobot_camera: Some([(300, 4), (9, 1)]),
        played_lag_ms: Some(51.234),
        ..PeerFigures::default()
    };
    let t = table(&r, &peer);
    assert_eq!(
        value(&t, "  telerobot played the path at (mean)"),
        "51.23 ms"
    );
    assert_eq!(value(&t, "cloud frames indexed / refused"), "120 / 3");
    assert_eq!(
        value(&t, "  over the budget: downsampled / refused"),
        "7 / 2"
    );
    assert_eq!(
        value(&t, "telerobot camera frames sent / refused"),
        "300 / 4"
    );
    assert_eq!(
        value(&t, "  over its budget: downsampled / refused"),
        "9 / 1"
    );
    // Without the telerobot in the process (operator run), its rows are left out.
    assert!(!table(&r, &PeerFigures::default()).contains("telerobot camera"));
}

/// The renderability gate and Colgate's clip say so in the networked report.
#[test]
fn renderer_counters_are_reported() {
    let normal = RendererStats {
        ticks: 100,
        unresolved_ticks: 12,
        clipped_ticks: 3,
        ..RendererStats::default()
    };
    let tangential = RendererStats {
        ticks: 100,
        unresolved_ticks: 1,
        ..RendererStats::default()
    };
    let r = report(SafetyStats::default(), vec![normal, tangential]);
    let t = table(&r, &PeerFigures::default());
    assert_eq!(
        value(&t, "renderer ticks: unresolved (gate) / clipped"),
        "13 / 3"
    );
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(json["renderers"][0]["unresolved_ticks"], 12);
    assert_eq!(json["renderers"][0]["clipped_ticks"], 3);
    assert_eq!(json["renderers"][1]["unresolved_ticks"], 1);
    assert_eq!(json["safety"]["non_finite_velocity"]["episodes"], 0);
}

/// Before: after a 5.5 s telerobot outage the report said "longest gap 2.2 ms" (the gap was kept
/// per session) and no figure gave the outage.
#[test]
fn an_outage_across_a_reconnect_is_counted_and_its_windows_marked() {
    use metrics::networked::{MeasurementSample, TickSample};
    let f = facts();
    let spec = DeviceSpec::Scripted {
        name: "hold".into(),
    };
    let device = open_device(&spec, &OpenOptions::default()).unwrap();
    let end = LoopEnd {
        force_record: *device.force_record(),
        device,
        safety: SafetyStats::default(),
        node: Default::default(),
        renderers: vec![],
        ticks: 0,
        frame: None,
        parameters: None,
        sessions: 2,
        prior: None,
    };
    let mut rec = Recording::default();
    // 10 s of ticks; measurements every ms but for 2.0 s to 7.5 s.
    for k in 0..10_000u64 {
        rec.ticks.push(TickSample {
            index: k,
            ..Default::default()
        });
        let t = f.run.start_ns + k as i64 * f.run.period_ns;
        if !(2_000..7_500).contains(&k) {
            rec.measurements.push(MeasurementSample {
                command_sample_time_ns: t,
                received_ns: t,
                ..Default::default()
            });
        }
    }
    let (_, r) = build(&f, &rec, &end);
    assert_eq!(r.outages.count, 1);
    assert!(
        (r.outages.longest_ms - 5_501.0).abs() < 1e-6,
        "{:?}",
        r.outages
    );
    let marked: Vec<f64> = r
        .experiment
        .error_over_time
        .iter()
        .filter(|w| w.outage)
        .map(|w| w.t_s)
        .collect();
    assert_eq!(marked, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
    let t = table(&r, &PeerFigures::default());
    assert_eq!(
        value(&t, "outages (no measurement ≥ 100 ms), all sessions"),
        "1 · longest 5501 ms · total 5501 ms"
    );
}

/// Every refusal of the ROS 2 device is in the table, not in the JSON only.
#[test]
fn the_table_shows_the_ros2_devices_refusals_and_commands() {
    use ros2::haptic::{CommandCounts, GateCounts, HapticReport, IoReport};
    let mut r = report(SafetyStats::default(), Vec::new());
    assert!(!table(&r, &PeerFigures::default()).contains("ros2 device"));
    let device = HapticReport {
        domain_id: 7,
        topics: "pose = /fd/ee_pose".into(),
        velocity_from: "the pose, differentiated over 10 ms",
        writes_force: true,
        effective_rate_hz: 999.5,
        latency: rt::Summary::default(),
        samples_not_taken: 0,
        io: IoReport {
            gate: GateCounts {
                poses: 100,
                accepted: 88,
                out_of_order: 1,
                duplicates: 2,
                malformed_stamps: 3,
                non_finite: 4,
                out_of_range: 5,
                impossible_jumps: 6,
                twists_refused: 7,
                wrong_frame: 11,
                from_future: 12,
                ..GateCounts::default()
            },
            undecodable: 8,
            commands: CommandCounts {
                published: 90,
                zero: 40,
                before_pose: 9,
                stale_zeroed: 10,
                stale_episodes: 1,
                watchdog_zeroed: 2,
                publish_errors: 4,
            },
            ..IoReport::default()
        },
    };
    r.device_backend = Some(BackendReport::Ros2(Box::new(device.clone())));
    let t = table(&r, &PeerFigures::default());
    assert_eq!(
        value(&t, "ros2 device: poses received / accepted"),
        "100 / 88"
    );
    assert_eq!(
        value(&t, "  refused: other frame / from the future"),
        "11 / 12"
    );
    assert_eq!(
        value(&t, "  refused: out of order / duplicate / malformed"),
        "1 / 2 / 3"
    );
    assert_eq!(
        value(&t, "  refused: non-finite / out of range / jump"),
        "4 / 5 / 6"
    );
    assert_eq!(value(&t, "  undecodable messages, twists refused"), "8, 7");
    assert_eq!(
        value(&t, "  commands published (zero) / errors"),
        "90 (40) / 4"
    );
    assert_eq!(value(&t, "  dropped before a pose"), "9");
    assert_eq!(
        value(&t, "  zeroed: stale pose (episodes) / watchdog"),
        "10 (1) / 2"
    );
    let json = serde_json::to_value(&r).unwrap();
    assert_eq!(
        json["device_backend"]["ros2"]["gate"]["impossible_jumps"],
        6
    );
    assert_eq!(json["device_backend"]["ros2"]["commands"]["before_pose"], 9);
    // Input only: said so, no command rows.
    r.device_backend = Some(BackendReport::Ros2(Box::new(HapticReport {
        writes_force: false,
        ..device
    })));
    let t = table(&r, &PeerFigures::default());
    assert_eq!(value(&t, "  commands"), "none: forces NOT written");
}
