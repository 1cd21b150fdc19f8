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
    let live = run_recorded(&config, &mut |_| {}, Some(recorder.sink())).unwrap();
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

#[test]
fn recordings_of_the_wrong_kind_are_refused_saying_what_they_are() {
    let path = temp("telerobot.mcap");
    let recorder = Recorder::start(RecorderConfig {
        mcap: Some(path.clone()),
        live: None,
        kind: record::Kind::Telerobot,
        clock_origin_ns: 0,
    })
    .unwrap();
    recorder.finish().unwrap();
    let e = report_file(&path).unwrap_err().to_string();
    assert!(e.contains("telerobot"), "{e}");
    assert!(e.contains("mmt report needs"), "{e}");
    let not_mcap = temp("not.mcap");
    std::fs::write(&not_mcap, "t_s,x,y,z\n0,0,0,0\n").unwrap();
    let e = report_file(&not_mcap).unwrap_err().to_string();
    assert!(e.contains(&not_mcap.display().to_string()), "{e}");
}
