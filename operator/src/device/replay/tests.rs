use super::*;
use std::path::PathBuf;

fn parse(text: &str) -> Result<ReplayTrajectory, ReplayError> {
    ReplayTrajectory::parse(text, "run.csv")
}

fn err(text: &str) -> String {
    parse(text).unwrap_err().to_string()
}

#[test]
fn interpolates_position_and_given_velocity() {
    let r = parse("t_s,x,y,z,vx,vy,vz\n0,0,0,0,1,0,0\n1,1,2,3,3,0,0\n").unwrap();
    let s = r.sample(0.25);
    assert_eq!(s.position_m, [0.25, 0.5, 0.75]);
    assert_eq!(s.velocity_m_per_s, [1.5, 0.0, 0.0]);
    assert_eq!(r.duration_s(), Some(1.0));
    assert_eq!(r.name(), "run.csv");
}

#[test]
fn finite_difference_velocity_when_absent() {
    // x = t², sampled at 0, 1, 2: central difference at 1 is exact (2), ends one-sided.
    let r = parse("# comment\n\nt_s, x, y, z\n0,0,0,0\n1,1,0,0\n2,4,0,0\n").unwrap();
    assert_eq!(r.sample(1.0).velocity_m_per_s, [2.0, 0.0, 0.0]);
    assert_eq!(r.sample(0.5).velocity_m_per_s, [1.5, 0.0, 0.0]);
    assert_eq!(r.len(), 3);
}

#[test]
fn holds_the_ends_with_zero_velocity() {
    let r = parse("t_s,x,y,z\n1,1,0,0\n2,2,0,0\n").unwrap();
    assert_eq!(r.sample(0.0).position_m, [1.0, 0.0, 0.0]);
    assert_eq!(r.sample(9.0).position_m, [2.0, 0.0, 0.0]);
    assert_eq!(r.sample(9.0).velocity_m_per_s, [0.0; 3]);
    assert_eq!(r.sample(f64::NAN).position_m, [1.0, 0.0, 0.0]);
    let single = parse("t_s,x,y,z\n0,5,6,7\n").unwrap();
    assert_eq!(single.sample(3.0).position_m, [5.0, 6.0, 7.0]);
}

#[test]
fn empty_files_are_refused() {
    assert!(err("").contains("the file is empty"), "{}", err(""));
    let e = err("t_s,x,y,z\n\n# only a comment\n");
    assert!(
        e.contains("run.csv") && e.contains("no sample after the header"),
        "{e}"
    );
}

#[test]
fn missing_or_wrong_header_names_the_expected_one() {
    let e = err("0,0,0,0\n");
    assert!(
        e.contains("line 1") && e.contains("t_s,x,y,z") && e.contains("found '0,0,0,0'"),
        "{e}"
    );
    assert!(err("time,x,y,z\n0,0,0,0\n").contains("found 'time,x,y,z'"));
}

#[test]
fn non_numeric_field_names_line_and_column() {
    let e = err("t_s,x,y,z\n0,0,0,0\n0.1,0,abc,0\n");
    assert_eq!(
        e,
        "run.csv: line 3, column 3 (y): expected a number, found 'abc'"
    );
}

#[test]
fn nan_and_inf_are_refused() {
    let e = err("t_s,x,y,z\n0,NaN,0,0\n");
    assert!(
        e.contains("line 2, column 2 (x): expected a finite number, found 'NaN'"),
        "{e}"
    );
    let e = err("t_s,x,y,z,vx,vy,vz\n0,0,0,0,0,0,inf\n");
    assert!(e.contains("column 7 (vz)") && e.contains("inf"), "{e}");
}

#[test]
fn non_monotonic_time_is_refused() {
    let e = err("t_s,x,y,z\n0,0,0,0\n0.5,0,0,0\n0.5,0,0,0\n");
    assert!(
        e.contains("line 4, column 1 (t_s): time 0.5 s is not after the previous sample's 0.5 s"),
        "{e}"
    );
    assert!(err("t_s,x,y,z\n1,0,0,0\n0,0,0,0\n").contains("line 3"));
}

#[test]
fn wrong_column_count_is_refused() {
    let e = err("t_s,x,y,z\n0,0,0,0\n1,0,0\n");
    assert_eq!(
        e,
        "run.csv: line 3: expected 4 columns (as in the header), found 3"
    );
    assert!(err("t_s,x,y,z,vx,vy,vz\n0,0,0,0\n").contains("expected 7 columns"));
}

#[test]
fn missing_file_names_it() {
    let e = ReplayTrajectory::load(Path::new("/nonexistent/run.csv"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/run.csv"), "{e}");
}

/// Regression: the app prints error chains (`{:#}`), and the OS error was both in the message
/// and the source, so it was printed twice.
#[test]
fn missing_file_error_says_the_os_error_once() {
    let e = ReplayTrajectory::load(Path::new("/nonexistent/run.csv")).unwrap_err();
    let chain = format!(
        "{:#}",
        anyhow::Error::from(crate::device::DeviceError::from(e))
    );
    assert_eq!(chain.matches("No such file").count(), 1, "{chain}");
    assert_eq!(
        chain,
        "cannot read replay file /nonexistent/run.csv: No such file or directory (os error 2)"
    );
}

#[test]
fn writer_output_replays_exactly() {
    let readings = [
        (0.0, [0.1, -0.2, 1.0 / 3.0], [0.0, 1e-9, -2.5]),
        (0.001, [0.1000001, -0.2, 0.3], [1.0, 2.0, 3.0]),
    ];
    let mut w = ReplayWriter::new(Vec::new()).unwrap();
    for (t, p, v) in readings {
        w.write(
            t,
            &DeviceReading {
                position_m: p,
                velocity_m_per_s: v,
                clutch: false,
            },
        )
        .unwrap();
    }
    let text = String::from_utf8(w.finish().unwrap()).unwrap();
    let r = parse(&text).unwrap();
    assert_eq!(r.samples.len(), readings.len());
    for (s, (t, p, v)) in r.samples.iter().zip(readings) {
        assert_eq!((s.t_s, s.position_m, s.velocity_m_per_s), (t, p, v));
    }
}

#[test]
fn writer_refuses_non_finite() {
    let mut w = ReplayWriter::new(Vec::new()).unwrap();
    let bad = DeviceReading {
        position_m: [f64::NAN, 0.0, 0.0],
        velocity_m_per_s: [0.0; 3],
        clutch: false,
    };
    assert!(w.write(0.0, &bad).is_err());
}

/// Writes a recording of `kind` holding `ticks` (the recorder's own writer and file format).
fn recording(name: &str, kind: record::Kind, ticks: &[record::schema::OperatorTick]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("replay-mcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    let recorder = record::Recorder::start(record::RecorderConfig {
        mcap: Some(path.clone()),
        live: None,
        kind,
        clock_origin_ns: 0,
    })
    .unwrap();
    let sink = recorder.sink();
    for t in ticks {
        assert!(sink.send_waiting(vec![record::Timed {
            t_ns: t.sample_time_ns,
            message: record::Message::OperatorTick(Box::new(*t)),
        }]));
    }
    recorder.finish().unwrap();
    path
}

#[test]
fn replays_the_device_trajectory_of_a_recording() {
    let tick = |k: u64| record::schema::OperatorTick {
        index: k,
        sample_time_ns: 5_000_000_000 + k as i64 * 1_000_000,
        device_position_m: [k as f64 * 1e-3, -(k as f64) * 2e-3, 0.1],
        device_velocity_m_per_s: [1.0, -2.0, 0.0],
        // What the device was commanded is not what it measured: the replay takes the latter.
        command_position_m: [9.0; 3],
        ..Default::default()
    };
    let ticks: Vec<_> = (0..200).map(tick).collect();
    let path = recording("op.mcap", record::Kind::Operator, &ticks);
    let r = ReplayTrajectory::from_recording(&path).unwrap();
    assert_eq!(r.len(), 200);
    assert_eq!(r.name(), "op.mcap");
    // Timed from the first tick.
    assert_eq!(r.duration_s(), Some(0.199));
    let s = r.sample(0.1);
    assert!((s.position_m[0] - 0.1).abs() < 1e-12, "{:?}", s.position_m);
    assert!((s.position_m[1] + 0.2).abs() < 1e-12, "{:?}", s.position_m);
    assert_eq!(s.velocity_m_per_s, [1.0, -2.0, 0.0]);
    // Through the device spec, as `--device replay:FILE.mcap` opens it.
    let spec: crate::device::DeviceSpec = format!("replay:{}", path.display()).parse().unwrap();
    assert!(crate::device::open_device(&spec, &crate::device::OpenOptions::default()).is_ok());
}

#[test]
fn refuses_recordings_without_haptic_ticks_saying_what_they_are() {
    let path = recording("tr.mcap", record::Kind::Telerobot, &[]);
    let e = ReplayTrajectory::from_recording(&path)
        .unwrap_err()
        .to_string();
    assert!(e.contains("telerobot"), "{e}");
    assert!(e.contains("replay:FILE.mcap needs"), "{e}");
    let empty = recording("empty.mcap", record::Kind::Operator, &[]);
    let e = ReplayTrajectory::from_recording(&empty)
        .unwrap_err()
        .to_string();
    assert!(e.contains("no haptic tick"), "{e}");
    let csv = std::env::temp_dir().join(format!("replay-mcap-{}-x.mcap", std::process::id()));
    std::fs::write(&csv, "t_s,x,y,z\n0,0,0,0\n").unwrap();
    let e = ReplayTrajectory::from_recording(&csv)
        .unwrap_err()
        .to_string();
    assert!(e.contains(&csv.display().to_string()), "{e}");
}

/// A number as a replay file could hold it: ordinary, extreme, or not a number at all.
fn token() -> impl proptest::strategy::Strategy<Value = String> {
    use proptest::prelude::*;
    prop_oneof![
        40 => (-2.0..2.0_f64).prop_map(|v| v.to_string()),
        6 => prop::sample::select(vec!["1e308", "-1e308", "5e-324", "-0", "1e300", "-1.7e308"])
            .prop_map(str::to_owned),
        1 => prop::num::f64::ANY.prop_map(|v| v.to_string()),
        1 => prop::sample::select(vec!["nan", "inf", "", "x", "0x10"]).prop_map(str::to_owned),
    ]
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(1024))]

    /// Issue 11: the device replay was not fuzzed. Whatever the lines hold, parsing never
    /// panics, and a trajectory it accepts gives finite positions and velocities at any time
    /// (a replay drives the commanded position).
    #[test]
    fn any_replay_text_is_refused_or_gives_a_finite_path(
        full in proptest::prelude::any::<bool>(),
        rows in proptest::collection::vec(proptest::collection::vec(token(), 7), 0..12),
        ragged in 0..20_usize,
        times in 0..3_u8,
        at in proptest::collection::vec(-1.0..20.0_f64, 8),
    ) {
        let mut text = String::from(if full { HEADER_FULL } else { HEADER_POSITION });
        text.push('\n');
        let columns = if full { 7 } else { 4 };
        for (k, row) in rows.iter().enumerate() {
            // Mostly the right number of columns; now and then one short.
            let n = if k == ragged { columns - 1 } else { columns };
            let mut row = row[..n].to_vec();
            match times {
                0 => row[0] = k.to_string(),
                // Steps of the smallest subnormal: a finite difference over them overflows.
                1 => row[0] = (k as f64 * 5e-324).to_string(),
                _ => {}
            }
            text.push_str(&row.join(","));
            text.push('\n');
        }
        let Ok(r) = parse(&text) else {
            return Ok(());
        };
        for t in at {
            let s = r.sample(t);
            proptest::prop_assert!(
                s.position_m.iter().chain(&s.velocity_m_per_s).all(|v| v.is_finite()),
                "at {t} s: {s:?} from\n{text}"
            );
        }
    }
}

/// Found by the property above: positions 1e308 apart gave a NaN velocity from an accepted
/// file. Such values are now refused by name, and so is a finite difference over too short a
/// time.
#[test]
fn positions_too_large_or_too_fast_are_refused() {
    let e = err("t_s,x,y,z\n0,0,0,1e308\n1,0,0,0\n");
    assert!(
        e.contains("line 2, column 4 (z)") && e.contains("at most 1,000,000"),
        "{e}"
    );
    let e = err("t_s,x,y,z\n0,0,0,0\n1e-300,0,0,1\n");
    assert!(
        e.contains("around t = 0 s") && e.contains("over 1,000,000 m/s"),
        "{e}"
    );
}
