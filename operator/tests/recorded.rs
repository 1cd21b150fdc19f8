//! `operator run --record` as the process a user runs (issue 15): Ctrl-C finalises the recording,
//! and `--device replay:FILE.mcap` plays its device trajectory back through a whole session.

#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Duration;

use record::replay::{DeviceSample, device_trajectory};
use record::{Kind, Side};
use testkit::process::{exited, interrupt};
use transport::Identity;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("operator-rec-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `operator run` on `device` for `seconds`, to `addr`, with the identities in `dir`.
fn operator(dir: &Path, addr: std::net::SocketAddr, device: &str, seconds: &str) -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_operator"));
    command
        .args(["run", "--device", device, "--seconds", seconds])
        .arg("--connect")
        .arg(addr.to_string())
        .arg("--identity")
        .arg(dir)
        .arg("--trust")
        .arg(dir.join("telerobot.crt"))
        .args(["--spin-us", "50"])
        .stdout(Stdio::null());
    command
}

/// The distance from `p` to the recorded path `path` near time `t_s` (the segments that overlap
/// `t_s ± window_s`): the replay interpolates linearly between recorded samples, so a replayed
/// point lies on a segment. A segment counts by its span, not by its start: the ticks carry the
/// time the device was read, and a stall of the recording's loop leaves one segment longer than
/// the window (CI: a point 37 µm "off" the path lay on a segment that started too early).
fn off_path(path: &[DeviceSample], t_s: f64, p: [f64; 3], window_s: f64) -> f64 {
    let dist = |a: [f64; 3], b: [f64; 3]| {
        let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
        let len2 = ab.iter().map(|v| v * v).sum::<f64>();
        let s = if len2 > 0.0 {
            (ab.iter().zip(&ap).map(|(x, y)| x * y).sum::<f64>() / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (0..3)
            .map(|i| (ap[i] - s * ab[i]).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    path.windows(2)
        .filter(|w| w[0].0 < t_s + window_s && w[1].0 > t_s - window_s)
        .map(|w| dist(w[0].1, w[1].1))
        .fold(f64::INFINITY, f64::min)
}

/// Before: Ctrl-C finalisation was tested only through the recorder's API and the MCAP replay
/// device only by unit tests; neither as a user meets them.
#[test]
fn ctrl_c_finalises_the_recording_and_the_replay_plays_it_back() {
    let _serial = testkit::serial();
    let dir = temp_dir("ctrl-c");
    let (me, _, _) = Identity::generate_files(&dir, "operator", &["operator"]).unwrap();
    let (telerobot, _, _) = Identity::generate_files(&dir, "telerobot", &["telerobot"]).unwrap();
    let tr = testkit::daemons::telerobot(&telerobot, &[&me], 0.0);
    let first = dir.join("first.mcap");
    let log = dir.join("first.log");
    let mut child = operator(&dir, tr.local_addr(), "scripted:exp1", "60")
        .arg("--record")
        .arg(&first)
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    testkit::daemons::wait_connected(&tr);
    std::thread::sleep(Duration::from_secs(4));
    interrupt(&child);
    let status = exited(&mut child, Duration::from_secs(20));
    let text = std::fs::read_to_string(&log).unwrap();
    assert!(status.success(), "{status:?}\n{text}");
    assert!(text.contains("Ctrl-C: shutting down"), "{text}");
    assert!(
        !record::partial_path(&first).exists(),
        "left partial:\n{text}"
    );
    let rec = record::read(&first, &[]).unwrap();
    assert_eq!(rec.kind(), Some(Kind::Operator), "{}", rec.describe());
    assert_eq!(rec.truncated, None, "finalised, not cut short");
    assert!(rec.end(Side::Operator).is_some(), "{}", rec.describe());
    assert!(
        rec.operator_ticks.len() > 3000,
        "{} ticks",
        rec.operator_ticks.len()
    );
    let recorded = device_trajectory(&rec);
    let moved = recorded
        .iter()
        .map(|s| (s.1[0] - recorded[0].1[0]).abs() + (s.1[2] - recorded[0].1[2]).abs())
        .fold(0.0, f64::max);
    assert!(moved > 0.01, "the script hardly moved: {moved} m");

    // The recording drives a second session as its device, under the name a killed run leaves
    // (it was taken for a CSV file by its extension).
    let second = dir.join("second.mcap");
    let partial = dir.join("killed.mcap.partial");
    std::fs::copy(&first, &partial).unwrap();
    let device = format!("replay:{}", partial.display());
    let output = operator(&dir, tr.local_addr(), &device, "3")
        .arg("--record")
        .arg(&second)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    tr.stop();
    let replayed = device_trajectory(&record::read(&second, &[]).unwrap());
    assert!(replayed.len() > 2000, "{} ticks replayed", replayed.len());
    // Every replayed position lies on the recorded path, at its time (within the few
    // milliseconds by which the two runs' first ticks may differ).
    let worst = replayed
        .iter()
        .filter(|s| s.0 < recorded.last().unwrap().0)
        .map(|s| off_path(&recorded, s.0, s.1, 0.02))
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-9,
        "a replayed position {worst} m off the recorded path"
    );
    let end = replayed.last().unwrap();
    let far = off_path(&recorded, end.0, end.1, 0.02);
    assert!(far < 1e-9, "the last replayed position is {far} m off");
    std::fs::remove_dir_all(&dir).unwrap();
}
