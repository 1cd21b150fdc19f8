//! `telerobot gen-cert` and `telerobot run`'s network flags.

#![allow(clippy::unwrap_used)]

use clap::Parser;
use telerobot::cli::{Cli, Command, RunConfig, gen_cert, run};

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("telerobot-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn parse(args: &[&str]) -> Command {
    Cli::try_parse_from(args).unwrap().command
}

#[test]
fn gen_cert_writes_a_usable_identity_and_run_validates_it() {
    let dir = temp_dir("ok");
    let Command::GenCert(g) = parse(&["telerobot", "gen-cert", "--out", dir.to_str().unwrap()])
    else {
        panic!()
    };
    let mut out = Vec::new();
    gen_cert(&g, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(
        text.contains("telerobot.crt") && text.contains("operator run --trust"),
        "{text}"
    );
    let crt = dir.join("telerobot.crt");
    let Command::Run(args) = parse(&[
        "telerobot",
        "run",
        "--listen",
        "127.0.0.1:4433",
        "--identity",
        dir.to_str().unwrap(),
        "--trust",
        crt.to_str().unwrap(),
    ]) else {
        panic!()
    };
    let config = RunConfig::from_args(&args).unwrap();
    assert_eq!(config.trusted_operators.len(), 1);
    let e = run(&args).unwrap_err().to_string();
    assert!(e.contains("telerobot loop not built yet"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_flags_and_files_are_named() {
    let e = Cli::try_parse_from([
        "telerobot",
        "run",
        "--listen",
        "4433",
        "--identity",
        "x",
        "--trust",
        "y",
    ])
    .unwrap_err()
    .to_string();
    assert!(e.contains("'4433' is not IP:PORT"), "{e}");
    let e = Cli::try_parse_from([
        "telerobot",
        "run",
        "--listen",
        "0.0.0.0:1",
        "--identity",
        "x",
    ])
    .unwrap_err()
    .to_string();
    assert!(e.contains("--trust"), "{e}");
    let Command::Run(args) = parse(&[
        "telerobot",
        "run",
        "--listen",
        "0.0.0.0:1",
        "--identity",
        "/nonexistent",
        "--trust",
        "y",
    ]) else {
        panic!()
    };
    let e = RunConfig::from_args(&args).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/telerobot.crt"), "{e}");
}
