//! The `mmt` binary's handling of a user's mistakes.

#![allow(clippy::unwrap_used)]

use std::ffi::OsStr;
use std::process::Command;

/// Runs `mmt` with `args` and `RUST_BACKTRACE` set (a user's mistake must still print no
/// backtrace): its exit status and stderr.
fn mmt<S: AsRef<OsStr>>(args: impl IntoIterator<Item = S>) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_mmt"))
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    (out.status.code(), String::from_utf8(out.stderr).unwrap())
}

/// A scene path that is a directory: one message naming the path and the OS's reason once, exit
/// status 1, and no backtrace even with `RUST_BACKTRACE` set (`main` returned the error to the
/// runtime, which printed its Debug form with a stack trace).
#[test]
fn a_bad_path_prints_one_message_and_no_backtrace() {
    let dir = std::env::temp_dir();
    let scene = dir.to_str().unwrap();
    let (status, stderr) = mmt(["experiment", "exp1", "--seconds", "1", "--scene", scene]);
    assert_eq!(status, Some(1), "{stderr}");
    assert!(!stderr.contains("backtrace"), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.contains(&*dir.to_string_lossy()), "{stderr}");
    assert_eq!(stderr.matches("os error 21").count(), 1, "{stderr}");
}

/// A run refused for its settings leaves no recording behind (it left a 405-byte file).
#[test]
fn a_refused_run_writes_no_recording() {
    let file = std::env::temp_dir().join(format!("mmt-refused-{}.mcap", std::process::id()));
    let _ = std::fs::remove_file(&file);
    let record = file.to_str().unwrap();
    let (status, stderr) = mmt([
        "experiment",
        "exp1",
        "--seconds",
        "0.05",
        "--record",
        record,
    ]);
    assert_eq!(status, Some(1), "{stderr}");
    assert!(
        stderr.contains("--seconds 0.05: expected in [1, 3600] s"),
        "{stderr}"
    );
    assert!(!file.exists(), "{} was written", file.display());
    assert!(!file.with_extension("mcap.partial").exists());
}

/// Issue 11: a range error named the harness's field (`delay_ms = -5`), not the flag the user
/// typed. Both forms of a negative value now name the flag.
#[test]
fn a_range_error_names_the_flag() {
    for args in [&["--delay-ms", "-5"][..], &["--delay-ms=-5"]] {
        let (status, stderr) = mmt(["experiment", "exp1", "--seconds", "5"].iter().chain(args));
        assert_eq!(status, Some(1), "{stderr}");
        assert_eq!(
            stderr.trim(),
            "mmt: --delay-ms -5: expected in [0, 5000] ms"
        );
    }
}

/// An unknown `mmt benchmark --structure` is refused before anything runs, with the values it
/// takes, and no backtrace.
#[test]
fn an_unknown_benchmark_structure_names_the_values() {
    let (status, stderr) = mmt(["benchmark", "--structure", "nope"]);
    assert_eq!(status, Some(2), "{stderr}");
    assert!(
        stderr.contains("invalid value 'nope' for '--structure"),
        "{stderr}"
    );
    assert!(stderr.contains("object, whole, select"), "{stderr}");
    assert!(!stderr.contains("backtrace"), "{stderr}");
}

/// `--out` (and `work-precision --plot`) naming a file where a directory must be: refused
/// before anything runs, with one message and exit status 1. Before, `mmt benchmark` ran every
/// case (minutes) and then failed to create the directory, losing the run; its files, and those
/// of `mmt report` and `mmt work-precision`, were written in place, not atomically.
#[test]
fn an_output_directory_that_is_a_file_is_refused_before_the_run() {
    let file = std::env::temp_dir().join(format!("mmt-out-is-a-file-{}", std::process::id()));
    std::fs::write(&file, "x").unwrap();
    let path = file.to_str().unwrap();
    let plot = file.join("wp.svg");
    let runs: [&[&str]; 3] = [
        &[
            "benchmark",
            "--motions",
            "exp1",
            "--delays-ms",
            "0",
            "--out",
            path,
        ],
        &["report", "missing.mcap", "--out", path],
        &["work-precision", "--plot", plot.to_str().unwrap()],
    ];
    for args in runs {
        let (status, stderr) = mmt(args);
        assert_eq!(status, Some(1), "{args:?}: {stderr}");
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.contains(path), "{args:?}: {stderr}");
        assert!(
            stderr.contains(&format!("{} ", args[args.len() - 2])),
            "{args:?}: {stderr}"
        );
        assert!(!stderr.contains("cases"), "{args:?} ran: {stderr}");
        assert!(!stderr.contains("backtrace"), "{args:?}: {stderr}");
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "x");
    let _ = std::fs::remove_file(&file);
}
