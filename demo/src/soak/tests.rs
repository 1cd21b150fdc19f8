use super::*;

const MS: i64 = 1_000_000;
const START: i64 = 5_000 * MS;

fn start(minutes: &mut Minutes) {
    let timing = Arc::new(rt::LoopTiming::new(MS, 0));
    let taken = minutes.take(Tapped::Start {
        start_ns: START,
        period_ns: MS,
        timing,
    });
    assert!(taken.is_empty());
}

/// Ticks `from..to` rendering `gain` times the measured force, their measurements arriving
/// 800 ms after the command (except those of `hole`, never arriving).
fn batch(from: u64, to: u64, gain: f64, hole: std::ops::Range<u64>) -> Tapped {
    let force = |k: u64| [0.3 * (k as f64 * 0.01).sin(), 0.0, -2.0];
    let ticks = (from..to)
        .map(|k| TickSample {
            index: k,
            sample_time_ns: None,
            position_m: [0.0; 3],
            force_n: force(k).map(|f| f * gain),
            in_contact: true,
            rendering: true,
            reduced: false,
        })
        .collect();
    let measurements = (from..to)
        .filter(|k| !hole.contains(k))
        .map(|k| {
            let command = START + k as i64 * MS;
            MeasurementSample {
                sample_time_ns: command,
                send_time_ns: command,
                command_sample_time_ns: command,
                force_on_tool_n: force(k),
                in_contact: true,
                estimator_stable: true,
                reconstruction: None,
                received_ns: command + 800 * MS,
                offset_ns: Some(0),
            }
        })
        .collect();
    Tapped::Batch {
        ticks,
        measurements,
        models: Vec::new(),
    }
}

#[test]
fn each_minute_gets_its_own_error_once_its_measurements_are_back() {
    let mut m = Minutes::new("soak", 400.0, 3.0);
    start(&mut m);
    // Minute 0 renders 10 % too much, minute 1 20 %; nothing closes before the lag has passed.
    assert!(m.take(batch(0, 60_000, 1.1, 0..0)).is_empty());
    assert!(m.take(batch(60_000, 62_999, 1.2, 0..0)).is_empty());
    let done = m.take(batch(62_999, 63_001, 1.2, 0..0));
    assert_eq!(done.len(), 1);
    let first = done[0];
    assert_eq!(
        (first.minute, first.ticks, first.measurements),
        (0, 60_000, 60_000)
    );
    assert!(
        (first.error_after_stable_pct.unwrap() - 10.0).abs() < 1e-6,
        "{first:?}"
    );
    assert!((first.error_pct.unwrap() - 10.0).abs() < 1e-6);
    assert_eq!(first.in_contact_pct, 100.0);
    assert_eq!(first.outages, 0);
    // The rest of minute 1 and a bit of minute 2; the run ends: minute 1 closes by the lag, the
    // partial minute 2 at the end.
    let done = m.take(batch(63_001, 125_000, 1.2, 0..0));
    assert_eq!(done.len(), 1);
    assert!((done[0].error_after_stable_pct.unwrap() - 20.0).abs() < 1e-6);
    assert_eq!(done[0].ticks, 60_000);
    let last = m.finish().unwrap();
    assert_eq!((last.minute, last.ticks), (2, 5_000));
    assert!(m.finish().is_none(), "a minute is closed once");
}

#[test]
fn a_hole_in_the_arrivals_is_an_outage_of_its_minute() {
    let mut m = Minutes::new("soak", 400.0, 3.0);
    start(&mut m);
    // Measurements of commands 70,000..70,300 never arrive: arrivals 69,999 → 70,300 ms after
    // the start (+800 ms): one 301 ms gap, in minute 1 (arrivals are counted by arrival time).
    let done = m.take(batch(0, 125_000, 1.0, 70_000..70_300));
    assert_eq!(done.len(), 2);
    assert_eq!(done[0].outages, 0);
    assert_eq!(done[1].outages, 1);
    assert_eq!(done[1].longest_outage_ms, 301.0);
    assert_eq!(done[1].measurements, 59_700);
    assert!(done[1].error_after_stable_pct.unwrap().abs() < 1e-9);
}

#[test]
fn nothing_before_the_start_and_no_ticks_give_no_minute() {
    let mut m = Minutes::new("soak", 400.0, 3.0);
    assert!(
        m.take(batch(0, 100_000, 1.0, 0..0)).is_empty(),
        "no schedule yet"
    );
    let mut m = Minutes::new("soak", 400.0, 3.0);
    start(&mut m);
    assert!(m.finish().is_none());
}

fn row(minute: u64, rss_mb: f64, error: f64) -> Minute {
    Minute {
        minute,
        in_contact_pct: 100.0,
        rss_mb,
        error_after_stable_pct: Some(error),
        cpu_pct: 50.0 + minute as f64,
        overruns: 2,
        outages: 1,
        ..Minute::default()
    }
}

#[test]
fn the_verdict_is_exact_on_known_rows() {
    // Memory 100 MB, then growing by 0.5 MB a minute: 30 MB an hour from the second minute.
    let errors = [9.0, 3.0, 3.2, 2.9, 5.0];
    let rows: Vec<Minute> = (0..5)
        .map(|k| {
            row(
                k,
                100.0 + if k == 0 { 40.0 } else { 0.5 * k as f64 },
                errors[k as usize],
            )
        })
        .collect();
    let v = Verdict::of(&rows);
    assert_eq!(v.minutes, 5);
    assert!((v.rss_growth_mb_per_h - 30.0).abs() < 1e-9, "{v:?}");
    assert_eq!(v.rss_mb, (100.5, 102.0));
    assert_eq!(v.rss_max_mb, 140.0);
    assert_eq!(v.error_median_pct, Some(3.2));
    assert!((v.error_max_deviation_pts.unwrap() - 5.8).abs() < 1e-12);
    assert_eq!(v.minutes_beyond_1_pt, 2);
    assert_eq!(v.cpu_median_pct, 52.0);
    assert_eq!((v.overruns, v.outages), (10, 5));
    assert_eq!(v.minutes_in_contact, 5);
    // A minute mostly out of contact (a lift-off) is shown but not judged.
    let mut lifted = rows.clone();
    lifted[4].in_contact_pct = 17.0;
    lifted[4].error_after_stable_pct = Some(100.0);
    let v = Verdict::of(&lifted);
    assert_eq!(v.minutes_in_contact, 4);
    assert_eq!(v.error_median_pct, Some(3.1));
    assert_eq!(v.minutes_beyond_1_pt, 1);
    // Nothing: no panic, no figure.
    let empty = Verdict::of(&[]);
    assert_eq!(empty.error_median_pct, None);
    assert_eq!(empty.rss_growth_mb_per_h, 0.0);
    // A NaN error is no median's.
    assert_eq!(median(&[f64::NAN, 1.0, 3.0]), Some(2.0));
}

#[test]
fn the_process_usage_is_read_on_linux() {
    if cfg!(target_os = "linux") {
        let (rss, cpu) = process_usage().unwrap();
        assert!(rss > 1.0 && rss < 100_000.0, "{rss} MB");
        assert!(cpu >= 0.0);
    }
}

/// Issue 11's soak: the error spikes came with resets of the telerobot's model, which no column
/// showed. A new model id the loop takes is counted in the minute of its tick.
#[test]
fn each_new_model_is_counted_in_its_minute() {
    let mut m = Minutes::new("soak", 400.0, 3.0);
    start(&mut m);
    let with_models = |b: Tapped, at: Vec<(u64, u32)>| match b {
        Tapped::Batch {
            ticks,
            measurements,
            ..
        } => Tapped::Batch {
            ticks,
            measurements,
            models: at,
        },
        other => other,
    };
    assert!(
        m.take(with_models(batch(0, 60_000, 1.0, 0..0), vec![(1_200, 1)]))
            .is_empty()
    );
    let mut done = m.take(with_models(
        batch(60_000, 125_000, 1.0, 0..0),
        vec![(61_000, 2), (119_999, 3), (120_000, 4)],
    ));
    done.extend(m.finish());
    let models: Vec<u64> = done.iter().map(|r| r.models).collect();
    assert_eq!(models, [1, 2, 1]);
}
