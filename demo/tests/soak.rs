//! The soak command end to end, for one minute over a lossy, jittery 50 ms link: a row is
//! written as the minute ends, the run's own recording stays at its first minute, and
//! soak.json holds the rows and the verdict.

#![allow(clippy::unwrap_used)]

use clap::Parser;
use demo::soak::cmd::{SoakCli, run_cmd};
use rt::Shutdown;

#[test]
fn a_one_minute_soak_writes_its_row_and_its_verdict() {
    let dir = std::env::temp_dir().join(format!("mmt-soak-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let args = SoakCli::try_parse_from([
        "soak",
        "--minutes",
        "1",
        "--delay-ms",
        "50",
        "--loss-pct",
        "2",
        "--jitter-ms",
        "2",
        "--out",
        dir.to_str().unwrap(),
    ])
    .unwrap();
    let mut printed = Vec::new();
    run_cmd(
        &args,
        Shutdown::new(),
        Box::new(std::io::sink()),
        &mut printed,
    )
    .unwrap();
    let printed = String::from_utf8(printed).unwrap();
    assert!(printed.contains("soak: 1 full minutes"), "{printed}");

    let csv = std::fs::read_to_string(dir.join("minutes.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 2, "{csv}");
    let row: Vec<&str> = lines[1].split(',').collect();
    assert_eq!(row[0], "0");
    let ticks: u64 = row[1].parse().unwrap();
    assert!(ticks > 59_000, "ticks {ticks}");
    // 2 % loss each way: about 96 % of the measurements come back.
    let measurements: f64 = row[2].parse().unwrap();
    assert!(
        (0.90..0.99).contains(&(measurements / ticks as f64)),
        "{measurements} of {ticks}"
    );
    let after_stable: f64 = row[5].parse().unwrap();
    assert!(
        after_stable > 0.0 && after_stable < 15.0,
        "{after_stable} %"
    );
    let rss: f64 = row[10].parse().unwrap();
    assert!(rss > 10.0, "{rss} MB");
    // The first contact's model, and at most one reset: the playout of jittery commands used to
    // make the telerobot's estimator reset about three times a minute.
    let models: u64 = row[12].parse().unwrap();
    assert!(
        (1..=2).contains(&models),
        "{models} model ids in the minute"
    );

    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("soak.json")).unwrap()).unwrap();
    assert_eq!(json["verdict"]["minutes"], 1);
    assert_eq!(json["rows"].as_array().unwrap().len(), 1);
    // The run's own report covers only the first minute it kept.
    let sim_seconds = json["end_report"]["sim_seconds"].as_f64().unwrap();
    assert!(sim_seconds <= 60.01, "{sim_seconds} s kept");
    std::fs::remove_dir_all(&dir).unwrap();
}
