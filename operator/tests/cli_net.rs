//! `operator gen-cert` and `operator run`'s network flags.

#![allow(clippy::unwrap_used)]

use clap::Parser;
use operator::cli::{Cli, Command, gen_cert};

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("operator-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

#[test]
fn gen_cert_and_network_flags_make_a_client_config() {
    let dir = temp_dir("ok");
    let Command::GenCert(g) =
        Cli::try_parse_from(["operator", "gen-cert", "--out", dir.to_str().unwrap()])
            .unwrap()
            .command
    else {
        panic!()
    };
    gen_cert(&g, &mut Vec::new()).unwrap();
    let crt = dir.join("operator.crt");
    let Command::Run(args) = Cli::try_parse_from([
        "operator",
        "run",
        "--device",
        "scripted:hold",
        "--connect",
        "127.0.0.1:4433",
        "--identity",
        dir.to_str().unwrap(),
        "--trust",
        crt.to_str().unwrap(),
        "--expected-delay-ms",
        "400",
    ])
    .unwrap()
    .command
    else {
        panic!()
    };
    let config = args.net.config().unwrap().unwrap();
    assert_eq!(config.connect, "127.0.0.1:4433".parse().unwrap());
    assert_eq!(config.tuning.expected_one_way_delay.as_millis(), 400);
    // Stopped before a telerobot answered: says where it was going, then why it stopped.
    let stopped = rt::Shutdown::new();
    stopped.trigger();
    let mut out = Vec::new();
    let e = operator::cli::run(&args, stopped, &mut out)
        .unwrap_err()
        .to_string();
    assert!(String::from_utf8(out).unwrap().contains("pinned to"));
    assert!(e.contains("stopped before a session"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn network_flags_come_together_and_files_are_named() {
    let e = Cli::try_parse_from([
        "operator",
        "run",
        "--device",
        "scripted:hold",
        "--connect",
        "127.0.0.1:1",
    ])
    .unwrap_err()
    .to_string();
    assert!(e.contains("--identity") && e.contains("--trust"), "{e}");
    let Command::Run(args) = Cli::try_parse_from([
        "operator",
        "run",
        "--device",
        "scripted:hold",
        "--connect",
        "127.0.0.1:1",
        "--identity",
        "/nonexistent",
        "--trust",
        "t.crt",
    ])
    .unwrap()
    .command
    else {
        panic!()
    };
    let e = args.net.config().unwrap_err().to_string();
    assert!(e.contains("/nonexistent/operator.crt"), "{e}");
    let e = operator::cli::run(&args, rt::Shutdown::new(), &mut Vec::new())
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/operator.crt"), "{e}");
}
