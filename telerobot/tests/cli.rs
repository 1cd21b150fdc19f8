//! `telerobot gen-cert` and `telerobot run`'s network flags.

#![allow(clippy::unwrap_used)]

use clap::Parser;
use telerobot::cli::{Cli, Command, RunConfig, gen_cert};

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
    // The built-in exp-1 scene by default, the tool 1 cm above its surface.
    assert_eq!(config.scene.name, "exp1");
    assert_eq!(config.start_m, [0.0, 0.0, 0.01]);
    assert_eq!(config.scene_summary().cloud_rate_hz, Some(30.0));
    assert_eq!(config.periodic.spin_ns, 100_000);
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
    let Command::Run(args) = parse(&run_line(&[])) else {
        panic!()
    };
    let e = RunConfig::from_args(&args).unwrap_err().to_string();
    assert!(e.contains("/nonexistent/telerobot.crt"), "{e}");
}

#[test]
fn scene_and_loop_flags_are_checked() {
    let run_args = |extra: &[&str]| {
        let Command::Run(args) = parse(&run_line(extra)) else {
            panic!()
        };
        args
    };
    let e = RunConfig::from_args(&run_args(&["--scene", "/nonexistent/s.toml"]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("cannot read scene file /nonexistent/s.toml"),
        "{e}"
    );
    // A directory: the OS's reason once in the printed chain (it was printed twice).
    let dir = temp_dir("scene-dir");
    std::fs::create_dir_all(&dir).unwrap();
    let e = RunConfig::from_args(&run_args(&["--scene", dir.to_str().unwrap()])).unwrap_err();
    let mut chain = e.to_string();
    let mut source = std::error::Error::source(&e);
    while let Some(s) = source {
        chain = format!("{chain}: {s}");
        source = s.source();
    }
    assert_eq!(chain.matches("os error 21").count(), 1, "{chain}");
    std::fs::remove_dir_all(&dir).unwrap();
    let bad = temp_dir("scene").with_extension("toml");
    std::fs::write(&bad, "name = \"x\"\n[environment]\nmass_kg = -1.0\n").unwrap();
    let e = RunConfig::from_args(&run_args(&["--scene", bad.to_str().unwrap()]))
        .unwrap_err()
        .to_string();
    assert!(e.contains(bad.to_str().unwrap()), "{e}");
    std::fs::remove_file(&bad).unwrap();
    let e = RunConfig::from_args(&run_args(&["--spin-us", "500"]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("--spin-us 500"), "{e}");
    let e = Cli::try_parse_from(run_line(&["--realtime-priority", "0"]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("--realtime-priority"), "{e}");
}

/// `telerobot run` with valid flags (files that do not exist) and `extra`.
fn run_line<'a>(extra: &[&'a str]) -> Vec<&'a str> {
    let mut args = vec![
        "telerobot",
        "run",
        "--listen",
        "0.0.0.0:1",
        "--identity",
        "/nonexistent",
        "--trust",
        "y",
    ];
    args.extend_from_slice(extra);
    args
}

/// `run_line` with `extra`, parsed.
fn run_args(extra: &[&str]) -> telerobot::cli::RunArgs {
    let Command::Run(args) = parse(&run_line(extra)) else {
        panic!()
    };
    args
}

#[test]
fn robot_ros2_takes_the_domain_remappings_qos_and_conventions() {
    use telerobot::robot::RobotConfig;
    let args = run_args(&[
        "--robot",
        "ros2",
        "--ros-domain",
        "7",
        "--topic",
        "robot_pose=/franka_robot_state_broadcaster/current_pose",
        "--topic",
        "robot_twist=none",
        "--topic",
        "target_pose=/cartesian_impedance_controller/target_pose",
        "--qos",
        "state=reliable,keep-last-5",
        "--wrench-sign",
        "by-tool",
        "--command-frame",
        "fr3_link0",
    ]);
    let RobotConfig::Ros2 { graph, bridge } = args.robot.robot_config().unwrap() else {
        panic!("expected ros2")
    };
    assert_eq!(graph.domain_id, 7);
    assert_eq!(
        bridge.topics.robot_pose.as_str(),
        "/franka_robot_state_broadcaster/current_pose"
    );
    assert_eq!(
        bridge.topics.target_pose.as_str(),
        "/cartesian_impedance_controller/target_pose"
    );
    // No twist topic: the velocity comes from the pose.
    assert!(bridge.topics.robot_twist.is_none() && !bridge.state.twist);
    assert!(bridge.state_qos.reliable && bridge.state_qos.depth == 5);
    assert!(!bridge.command_qos.reliable && bridge.settings_qos.transient_local);
    assert_eq!(bridge.state.wrench_sign, ros2::state::WrenchSign::ByTool);
    assert_eq!(bridge.command_frame.as_deref(), Some("fr3_link0"));
    // The default: the scene's simulated world.
    assert_eq!(
        run_args(&[]).robot.robot_config().unwrap(),
        RobotConfig::Sim
    );
}

#[test]
fn bad_robot_options_are_named() {
    let error = |extra: &[&str]| {
        let args = run_args(extra);
        args.robot
            .robot_config()
            .map(|_| ())
            .and_then(|()| args.robot.limits(&sim::scene::Scene::exp1()).map(|_| ()))
            .unwrap_err()
            .to_string()
    };
    for (extra, message) in [
        (
            &["--ros-domain", "3"][..],
            "--ros-domain applies to --robot ros2 only",
        ),
        (
            &["--robot", "ros2", "--ros-domain", "233"][..],
            "--ros-domain",
        ),
        (
            &["--robot", "ros2", "--topic", "robot_pos=/x"][..],
            "robot_pos",
        ),
        (
            &["--robot", "ros2", "--topic", "robot_pose=not a topic"][..],
            "not a topic",
        ),
        (&["--robot", "ros2", "--qos", "state=fast"][..], "fast"),
        (&["--workspace", "1,2"][..], "--workspace \"1,2\""),
        (&["--max-step-m", "-0.001"][..], "max_step_m"),
        (&["--workspace", "0.1,0,0,-0.1,1,1"][..], "workspace"),
    ] {
        let e = error(extra);
        assert!(e.contains(message), "{extra:?}: {e}");
    }
    let e = Cli::try_parse_from(run_line(&["--robot", "ur"]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("ur"), "{e}");
}

/// Log lines written to a pipe or a file carry no colour escapes (they did, whatever stderr was).
#[test]
fn logs_to_a_pipe_are_plain_text() {
    use std::io::{BufRead, BufReader, Read};
    use std::process::{Command as Process, Stdio};
    let dir = temp_dir("plain-logs");
    let Command::GenCert(g) = parse(&["telerobot", "gen-cert", "--out", dir.to_str().unwrap()])
    else {
        panic!()
    };
    gen_cert(&g, &mut Vec::new()).unwrap();
    let crt = dir.join("telerobot.crt");
    let mut child = Process::new(env!("CARGO_BIN_EXE_telerobot"))
        .args(["run", "--listen", "127.0.0.1:0", "--identity"])
        .arg(&dir)
        .arg("--trust")
        .arg(&crt)
        .env("RUST_LOG", "info")
        .env_remove("NO_COLOR")
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stderr = BufReader::new(child.stderr.take().unwrap());
    let mut log = String::new();
    while !log.contains("telerobot running") {
        let mut line = String::new();
        if stderr.read_line(&mut line).unwrap() == 0 {
            break;
        }
        log.push_str(&line);
    }
    let _ = Process::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status();
    stderr.read_to_string(&mut log).unwrap();
    let status = child.wait().unwrap();
    assert!(log.contains("telerobot running"), "{log}");
    assert!(
        !log.contains('\u{1b}'),
        "colour escapes in a piped log:\n{log:?}"
    );
    assert!(status.success(), "{status:?}\n{log}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An unreadable scene file: the OS's reason once (it was printed twice: the message showed its
/// cause and the error chain printed it again), exit status 1, no backtrace.
#[test]
fn a_bad_scene_path_says_why_once() {
    let dir = std::env::temp_dir();
    let ids = temp_dir("bad-scene");
    let Command::GenCert(g) = parse(&["telerobot", "gen-cert", "--out", ids.to_str().unwrap()])
    else {
        panic!()
    };
    gen_cert(&g, &mut Vec::new()).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_telerobot"))
        .args(["run", "--listen", "127.0.0.1:0", "--identity"])
        .arg(&ids)
        .arg("--trust")
        .arg(ids.join("telerobot.crt"))
        .arg("--scene")
        .arg(&dir)
        .env("RUST_BACKTRACE", "1")
        .output()
        .unwrap();
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert_eq!(stderr.matches("os error 21").count(), 1, "{stderr}");
    assert!(!stderr.contains("backtrace"), "{stderr}");
    std::fs::remove_dir_all(&ids).unwrap();
}
