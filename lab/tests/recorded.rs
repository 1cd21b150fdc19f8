//! A recorded experiment's report, computed again from its recording (`mmt report FILE.mcap`),
//! is the run's report; the estimator replayed on its measurement stream (`mmt estimate --from`)
//! publishes the run's parameter sets bit for bit; recordings of the wrong kind are refused.

#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use lab::analysis::estimate_from::{EstimateFromConfig, estimate_from};
use lab::experiment::{ExperimentConfig, Kind, run_recorded};
use lab::recorded::{files, report_file};
use record::{Recorder, RecorderConfig};
use sim::scene::Scene;

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lab-recorded-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Runs `kind` for `seconds` with a recording; the live run's report and series.
fn recorded_run(
    kind: Kind,
    seconds: f64,
    path: &std::path::Path,
) -> (metrics::Series, metrics::ExperimentReport) {
    let mut config = ExperimentConfig::new(kind, Scene::exp1());
    config.seconds = seconds;
    let recorder = Recorder::start(RecorderConfig {
        mcap: Some(path.to_owned()),
        live: None,
        kind: record::Kind::Experiment,
        clock_origin_ns: 0,
    })
    .unwrap();
    let live = run_recorded(&config, &mut |_| {}, Some(recorder.sink()), None).unwrap();
    let report = recorder.finish().unwrap();
    assert_eq!(report.dropped, 0);
    live
}

#[test]
fn the_report_of_a_recording_is_the_runs_report() {
    let path = temp("exp3.mcap");
    let (series, live) = recorded_run(Kind::Exp3, 8.0, &path);
    let r = report_file(&path).unwrap();
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert!(!r.networked);
    assert_eq!(r.series.len(), series.len());
    // The same figures: the whole report, value for value (floats bit for bit).
    assert_eq!(r.json, serde_json::to_value(&live).unwrap());
    // And the same files (report.json, series.csv, the plots), byte for byte.
    let from_recording = files(&r).unwrap();
    let from_run = lab::report::files(&live, &series).unwrap();
    assert_eq!(from_recording.len(), from_run.len());
    for ((name_a, a), (name_b, b)) in from_recording.iter().zip(&from_run) {
        assert_eq!(name_a, name_b);
        assert!(a == b, "{name_a} differs");
    }
}

#[test]
fn the_estimator_replayed_on_a_recording_publishes_the_runs_parameters() {
    let path = temp("exp1.mcap");
    recorded_run(Kind::Exp1, 6.0, &path);
    let r = estimate_from(&path, &EstimateFromConfig::default()).unwrap();
    assert!(r.ticks >= 5900, "{}", r.ticks);
    assert!(r.parameter_messages > 0);
    assert!(r.same_as_recorded, "{r:?}");
    // Another forgetting factor is another estimator: not the recorded sets.
    let other = estimate_from(
        &path,
        &EstimateFromConfig {
            forgetting: Some(0.999),
            cutoff_hz: None,
        },
    )
    .unwrap();
    assert!(!other.same_as_recorded);
}

/// A recorder of a telerobot recording to `path`.
fn telerobot_recorder(path: &std::path::Path) -> Recorder {
    Recorder::start(RecorderConfig {
        mcap: Some(path.to_owned()),
        live: None,
        kind: record::Kind::Telerobot,
        clock_origin_ns: 0,
    })
    .unwrap()
}

#[test]
fn recordings_of_the_wrong_kind_are_refused_saying_what_they_are() {
    let path = temp("telerobot.mcap");
    let recorder = telerobot_recorder(&path);
    recorder.finish().unwrap();
    let e = report_file(&path).unwrap_err().to_string();
    assert!(e.contains("telerobot"), "{e}");
    assert!(e.contains("mmt report needs"), "{e}");
    let not_mcap = temp("not.mcap");
    std::fs::write(&not_mcap, "t_s,x,y,z\n0,0,0,0\n").unwrap();
    let e = report_file(&not_mcap).unwrap_err().to_string();
    assert!(e.contains(&not_mcap.display().to_string()), "{e}");
}

/// `mmt experiment NAME --seconds SECONDS --record file --out out`, returned once its partial
/// recording holds `bytes` or more.
fn recording_experiment(
    name: &str,
    seconds: &str,
    file: &std::path::Path,
    out: &std::path::Path,
    bytes: u64,
) -> std::process::Child {
    use std::time::{Duration, Instant};
    let child = std::process::Command::new(env!("CARGO_BIN_EXE_mmt"))
        .args(["experiment", name, "--seconds", seconds, "--record"])
        .arg(file)
        .arg("--out")
        .arg(out)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while std::fs::metadata(record::partial_path(file)).map_or(0, |m| m.len()) < bytes {
        assert!(started.elapsed() < Duration::from_secs(60), "no recording");
        std::thread::sleep(Duration::from_millis(5));
    }
    child
}

/// Before: `mmt experiment` had no Ctrl-C handling; an interrupted run with `--record` left
/// only `FILE.mcap.partial`. It now stops at its next progress point, closes the recording as
/// on any error (renamed into place, readable), writes no report and says where it stopped.
#[test]
fn ctrl_c_stops_an_experiment_and_finalises_its_recording() {
    let file = temp("interrupted.mcap");
    let out = temp("interrupted-out");
    // Recording, well into the run (the partial file has a chunk or more).
    let child = recording_experiment("exp3", "3600", &file, &out, 2 << 20);
    testkit::process::interrupt(&child);
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("interrupted at"), "{stderr}");
    assert!(
        stderr.contains("the recording up to then is in"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!record::partial_path(&file).exists(), "left partial");
    let rec = record::read(&file, &[]).unwrap();
    assert_eq!(rec.kind(), Some(record::Kind::Experiment));
    assert_eq!(rec.truncated, None, "closed, not cut short");
    assert!(rec.telerobot_ticks.len() > 1000, "{}", rec.describe());
    assert!(
        !out.join("report.json").exists(),
        "a report of a run that did not end"
    );
}

/// Before: the recorder was closed before the report was written, so a recording that could
/// not be closed (here: its final name taken, mid-run, by a directory) cost the run's report.
#[test]
fn a_recording_that_cannot_be_closed_still_leaves_the_runs_report() {
    let file = temp("taken.mcap");
    let out = temp("taken-out");
    let child = recording_experiment("exp1", "120", &file, &out, 1);
    std::fs::create_dir_all(file.join("in-the-way")).unwrap();
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("taken.mcap"), "{stderr}");
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(report.contains("rms_error_pct"), "{report}");
}

/// Before: `mmt estimate --from` built a node from the scene a recording's `/run` carried
/// without checking it as a scene file is checked. A recording whose scene holds a NaN mass
/// (written as `null`, read back as NaN) is now refused, naming the field.
#[test]
fn a_recorded_scene_is_checked_before_the_estimator_is_built_from_it() {
    let path = temp("bad-scene.mcap");
    let recorder = telerobot_recorder(&path);
    let mut scene = Scene::exp1();
    scene.environment.mass_kg = f64::NAN;
    let run = record::schema::RunStart {
        side: record::Side::Telerobot,
        experiment: "telerobot".to_owned(),
        start_ns: 0,
        period_ns: 1_000_000,
        scene_name: scene.name.clone(),
        left_out: Vec::new(),
        proxy_radii_m: [0.004, 0.006, 0.03],
        device: None,
        seed: Some(1),
        set_delay_ms: None,
        scene: Some(scene),
        config: None,
        axes: None,
        tool_start_m: Some([0.0, 0.0, 0.01]),
    };
    let sink = recorder.sink();
    sink.send_one(0, record::Message::Run(Box::new(run)));
    let ticks = (0..10)
        .map(|k| record::Timed {
            t_ns: k * 1_000_000,
            message: record::Message::TelerobotTick(Box::default()),
        })
        .collect();
    assert!(sink.send(ticks));
    recorder.finish().unwrap();
    let e = estimate_from(&path, &EstimateFromConfig::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("mass_kg"), "{e}");
    assert!(e.contains("bad-scene.mcap"), "{e}");
}
