//! `telerobot run --record` as the process a lab runs (issue 15): a session recorded, then Ctrl-C,
//! and the file is finalised — renamed into place, complete, read back with every channel.

#![allow(clippy::unwrap_used)]

use std::io::{BufRead, BufReader, Read};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use record::{Kind, Side};
use testkit::process::{exited, interrupt};
use transport::Identity;

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("telerobot-rec-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// Reads the child's log until the start line and returns the address it listens on, with the
/// log so far.
fn listening(child: &mut Child) -> (SocketAddr, BufReader<std::process::ChildStderr>, String) {
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut log = String::new();
    loop {
        let mut line = String::new();
        assert!(stderr.read_line(&mut line).unwrap() > 0, "exited:\n{log}");
        log.push_str(&line);
        if line.contains("telerobot running") {
            let addr = line
                .split_whitespace()
                .find_map(|w| w.strip_prefix("addr="))
                .unwrap();
            return (addr.parse().unwrap(), stderr, log);
        }
    }
}

/// The telerobot's own records among `items`.
fn ours<T>(items: &[(Side, T)]) -> usize {
    items.iter().filter(|(s, _)| *s == Side::Telerobot).count()
}

/// Before: `--record` on the telerobot was tested only in-process, and Ctrl-C finalisation only
/// through the recorder's own API; a daemon stopped by Ctrl-C might have left a `.partial` file.
#[test]
fn ctrl_c_finalises_the_telerobots_recording_of_a_session() {
    let _serial = testkit::serial();
    let dir = temp_dir("ctrl-c");
    let (operator, operator_crt, _) =
        Identity::generate_files(&dir, "operator", &["operator"]).unwrap();
    let (telerobot, _, _) = Identity::generate_files(&dir, "telerobot", &["telerobot"]).unwrap();
    let file = dir.join("telerobot.mcap");
    let mut child = Command::new(env!("CARGO_BIN_EXE_telerobot"))
        .args(["run", "--listen", "127.0.0.1:0", "--identity"])
        .arg(&dir)
        .arg("--trust")
        .arg(&operator_crt)
        .arg("--record")
        .arg(&file)
        .args(["--spin-us", "50"])
        .env("RUST_LOG", "info")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let (addr, mut stderr, mut log) = listening(&mut child);
    assert!(
        record::partial_path(&file).exists(),
        "written as it goes, under its partial name"
    );
    let session = testkit::daemons::spawn_operator(testkit::daemons::operator_config(
        addr, &operator, &telerobot, "alice", 4.0, 0.0,
    ))
    .join()
    .unwrap()
    .unwrap();
    assert!(session.ticks > 3000, "{} ticks", session.ticks);
    interrupt(&child);
    let status = exited(&mut child, Duration::from_secs(20));
    stderr.read_to_string(&mut log).unwrap();
    assert!(status.success(), "{status:?}\n{log}");
    assert!(log.contains("Ctrl-C: shutting down"), "{log}");

    assert!(
        !record::partial_path(&file).exists(),
        "left partial:\n{log}"
    );
    let rec = record::read(&file, &[]).unwrap();
    assert_eq!(rec.kind(), Some(Kind::Telerobot), "{}", rec.describe());
    assert_eq!(rec.truncated, None, "finalised, not cut short");
    assert!(rec.run(Side::Telerobot).is_some(), "{}", rec.describe());
    assert!(
        rec.end(Side::Telerobot).is_some(),
        "no run end: {}",
        rec.describe()
    );
    // The 4 s session at 1 kHz, and what the estimator and the contact detector published.
    assert!(
        rec.telerobot_ticks.len() > 3000,
        "{} telerobot ticks",
        rec.telerobot_ticks.len()
    );
    assert!(ours(&rec.parameters) > 0, "{}", rec.describe());
    assert!(ours(&rec.contacts) > 0, "{}", rec.describe());
    assert!(ours(&rec.clouds) > 0, "{}", rec.describe());
    // Every tick in order of its time, none repeated.
    assert!(
        rec.telerobot_ticks
            .windows(2)
            .all(|w| w[1].t_ns > w[0].t_ns),
        "ticks out of order or repeated"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
