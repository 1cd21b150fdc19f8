//! `operator run --out`: nothing lost (issue 11, finding 2). The directory is checked before the
//! run, and the records are streamed as the run goes, so that a run killed with SIGKILL leaves
//! them readable.

#![allow(clippy::unwrap_used)]

use std::process::{Command, Stdio};
use std::time::Duration;

use transport::Identity;

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("operator-killed-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Before: nothing was written while the run went on; a SIGKILLed operator lost everything.
#[test]
fn a_killed_run_leaves_readable_records() {
    let _serial = testkit::serial();
    let dir = temp_dir("kill");
    let (operator, _, _) = Identity::generate_files(&dir, "operator", &["operator"]).unwrap();
    let (telerobot, telerobot_crt, _) =
        Identity::generate_files(&dir, "telerobot", &["telerobot"]).unwrap();
    let tr = testkit::daemons::telerobot(&telerobot, &[&operator], 0.0);
    let out = dir.join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_operator"))
        .args(["run", "--device", "scripted:exp1", "--seconds", "60"])
        .arg("--connect")
        .arg(tr.local_addr().to_string())
        .arg("--identity")
        .arg(&dir)
        .arg("--trust")
        .arg(&telerobot_crt)
        .arg("--out")
        .arg(&out)
        .args(["--spin-us", "50"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    testkit::daemons::wait_connected(&tr);
    std::thread::sleep(Duration::from_secs(3));
    child.kill().unwrap(); // SIGKILL: no handler runs
    child.wait().unwrap();
    tr.stop();
    let ticks = std::fs::read_to_string(out.join("ticks.csv")).unwrap();
    let measurements = std::fs::read_to_string(out.join("measurements.csv")).unwrap();
    assert!(
        !out.join("report.json").exists(),
        "killed before any report"
    );
    for (name, text, columns) in [("ticks", &ticks, 9), ("measurements", &measurements, 11)] {
        let lines: Vec<&str> = text.lines().collect();
        // About 3 s at 1 kHz, flushed every 250 ms; every line whole (the last flush ended a
        // line).
        assert!(lines.len() > 2000, "{name}: {} lines", lines.len());
        assert!(text.ends_with('\n'), "{name}: a partial last line");
        for (i, line) in lines.iter().enumerate().skip(1) {
            let fields: Vec<&str> = line.split(',').collect();
            assert_eq!(fields.len(), columns, "{name} line {}: {line}", i + 1);
            assert!(fields[3].parse::<f64>().unwrap().is_finite(), "{line}");
        }
    }
    // Tick numbers follow each other.
    let first: Vec<u64> = ticks
        .lines()
        .skip(1)
        .take(100)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect();
    assert!(first.windows(2).all(|w| w[1] > w[0]), "{first:?}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Before: `--out` naming a file was found only after the whole session had run.
#[test]
fn an_out_path_that_cannot_be_written_is_refused_before_the_run() {
    let dir = temp_dir("refused");
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let started = std::time::Instant::now();
    let output = Command::new(env!("CARGO_BIN_EXE_operator"))
        .args(["run", "--device", "scripted:exp1", "--seconds", "60"])
        .arg("--out")
        .arg(&file)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("exists and is not a directory"), "{stderr}");
    assert!(started.elapsed() < Duration::from_secs(10), "ran first");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Before: with nothing listening the operator retried forever despite `--seconds`, logged only
/// idle timeouts at info, and its log file got colour escapes.
#[test]
fn a_telerobot_that_never_answers_is_named_at_warn_and_seconds_end_the_run() {
    let dir = temp_dir("silent");
    Identity::generate_files(&dir, "operator", &["operator"]).unwrap();
    let (_, telerobot_crt, _) =
        Identity::generate_files(&dir, "telerobot", &["telerobot"]).unwrap();
    let closed = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let addr = closed.local_addr().unwrap();
    drop(closed);
    let started = std::time::Instant::now();
    let output = Command::new(env!("CARGO_BIN_EXE_operator"))
        .args(["run", "--device", "scripted:exp1", "--seconds", "7"])
        .arg("--connect")
        .arg(addr.to_string())
        .arg("--identity")
        .arg(&dir)
        .arg("--trust")
        .arg(&telerobot_crt)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(started.elapsed() < Duration::from_secs(12), "{stderr}");
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr
            .lines()
            .any(|l| l.contains("WARN") && l.contains(&format!("no answer from {addr}"))),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!(
            "no session with the telerobot at {addr} within 7s"
        )),
        "{stderr}"
    );
    assert!(
        !stderr.contains('\x1b'),
        "colour escapes in a log that is not a terminal"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
