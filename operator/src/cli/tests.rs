use super::*;

fn no_sdk() -> SdkProbe {
    SdkProbe {
        library: Err(DeviceError::SdkLoad(sdk::SdkLoadError::Library {
            library: "libdhd.so".into(),
            chosen_by: "default",
            searched: sdk::SEARCH_PATH.into(),
            reason: "libdhd.so: cannot open shared object file".into(),
        })),
        devices: Vec::new(),
    }
}

#[test]
fn devices_report_on_a_bare_machine_says_so() {
    let text = render_devices(&Ok((Vec::new(), 3)), &no_sdk());
    assert!(
        text.contains("none recognised (3 HID device(s) present"),
        "{text}"
    );
    assert!(
        text.contains("not available: cannot load the Force Dimension SDK library 'libdhd.so'")
    );
    assert!(text.contains("MMT_FD_SDK_LIB"));
    assert!(text.contains("No haptic device found on this machine"));
    // Every backend with what it can and cannot do.
    for line in [
        "scripted:NAME",
        "replay:FILE.csv",
        "spacemouse      NO",
        "omega           yes",
    ] {
        assert!(text.contains(line), "missing '{line}' in\n{text}");
    }
    assert!(
        text.contains("12 N") && text.contains("5000 N/m") && text.contains("sphere r = 0.075 m")
    );
    // The damping each backend offers (the passivity controller's limit).
    assert!(text.contains("max damping"), "{text}");
    let omega = text
        .lines()
        .find(|l| l.contains("omega           yes"))
        .unwrap();
    assert!(omega.contains("30 N·s/m"), "{omega}");
    let spacemouse = text
        .lines()
        .find(|l| l.contains("spacemouse      NO"))
        .unwrap();
    assert!(!spacemouse.contains("N·s/m"), "{spacemouse}");
}

#[test]
fn devices_report_lists_recognised_devices() {
    let hid = Ok((
        vec![HidEntry {
            vendor_id: 0x256f,
            product_id: 0xc635,
            model: "SpaceMouse Compact",
            product: Some("SpaceMouse Compact".into()),
            path: "/dev/hidraw3".into(),
        }],
        5,
    ));
    let sdk = SdkProbe {
        library: Ok("/opt/sdk/libdhd.so".into()),
        devices: vec![Ok("omega.7".into())],
    };
    let text = render_devices(&hid, &sdk);
    assert!(text.contains("256f:c635  SpaceMouse Compact"), "{text}");
    assert!(text.contains("/dev/hidraw3"));
    assert!(text.contains("loaded /opt/sdk/libdhd.so"));
    assert!(text.contains("device 0: omega.7"));
    assert!(text.contains("A force-feedback device is available"));
}

#[test]
fn devices_command_works_without_devices_or_sdk() {
    let args = DevicesArgs {
        sdk: SdkArgs {
            fd_sdk_lib: Some("/nonexistent/libdhd.so".into()),
            fd_watchdog_ms: 20.0,
            fd_velocity_threshold: None,
        },
    };
    let mut out = Vec::new();
    devices(&args, &mut out).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(text.contains("/nonexistent/libdhd.so"), "{text}");
    assert!(text.contains("Backends:"));
}

#[test]
fn run_parses_the_device_and_stops_before_the_network() {
    let cli = Cli::try_parse_from(["operator", "run", "--device", "scripted:hold"]).unwrap();
    let Command::Run(args) = cli.command else {
        panic!("not run")
    };
    let mut out = Vec::new();
    let code = run(&args, Shutdown::new(), &mut out).unwrap();
    // A device check that opened the device succeeded (it exited 2 before).
    assert_eq!(code, ExitCode::SUCCESS);
    let text = String::from_utf8(out).unwrap();
    assert!(text.contains("scripted:hold"), "{text}");
    assert!(text.contains("WARNING"), "{text}");
    assert!(text.contains("no telerobot given"), "{text}");
}

#[test]
fn bad_device_values_fail_at_parse_time_with_the_allowed_forms() {
    let e = Cli::try_parse_from(["operator", "run", "--device", "phantom"]).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("'phantom'")
            && msg.contains(
                "scripted:NAME, replay:FILE.csv, replay:FILE.mcap, spacemouse, omega, ros2"
            ),
        "{msg}"
    );
}

#[test]
fn spacemouse_warning_says_there_is_no_force() {
    let w = no_force_warning(&DeviceSpec::SpaceMouse);
    assert!(w.contains("NO force output"), "{w}");
}

#[test]
fn bad_watchdog_is_refused() {
    let cli = Cli::try_parse_from([
        "operator",
        "run",
        "--device",
        "omega",
        "--fd-watchdog-ms",
        "40",
    ])
    .unwrap();
    let Command::Run(args) = cli.command else {
        panic!("not run")
    };
    let e = run(&args, Shutdown::new(), &mut Vec::new())
        .unwrap_err()
        .to_string();
    assert!(e.contains("31.875 ms"), "{e}");
}

fn run_args(extra: &[&str]) -> RunArgs {
    let mut argv = vec!["operator", "run", "--device", "scripted:hold"];
    argv.extend_from_slice(extra);
    let Command::Run(args) = Cli::try_parse_from(argv).unwrap().command else {
        panic!("not run")
    };
    *args
}

#[test]
fn device_origin_is_parsed_checked_and_applied() {
    assert_eq!(run_args(&[]).safety().unwrap().device_origin_m, [0.0; 3]);
    let args = run_args(&["--device-origin", "0.1,-0.05,0.2"]);
    let safety = args.safety().unwrap();
    assert_eq!(safety.device_origin_m, [0.1, -0.05, 0.2]);
    // The commanded position is the origin plus the scaled device position.
    let mut layer = crate::safety::SafetyLayer::new(
        &crate::device::DeviceCapabilities::omega7("test"),
        &safety,
    )
    .unwrap();
    let commanded = layer.command_position([0.01, 0.0, -0.01], false);
    for (c, e) in commanded.iter().zip([0.11, -0.05, 0.19]) {
        assert!((c - e).abs() < 1e-15, "{commanded:?}");
    }
    let nan = crate::safety::SafetyConfig {
        device_origin_m: [f64::NAN, 0.0, 0.0],
        ..safety
    };
    let e =
        crate::safety::SafetyLayer::new(&crate::device::DeviceCapabilities::omega7("test"), &nan)
            .unwrap_err()
            .to_string();
    assert!(e.contains("device_origin_m") && e.contains("±10 m"), "{e}");
    for bad in ["1,2", "a,0,0", "0,0,nan", "0,0,11", "1,2,3,4"] {
        let argv = [
            "operator",
            "run",
            "--device",
            "scripted:hold",
            "--device-origin",
            bad,
        ];
        let e = Cli::try_parse_from(argv).unwrap_err().to_string();
        assert!(
            e.contains("--device-origin") && e.contains(&format!("`{bad}`: expected X,Y,Z")),
            "{e}"
        );
    }
}

#[test]
fn position_scale_is_checked_and_applied() {
    assert_eq!(run_args(&[]).safety().unwrap().position_scale, 1.0);
    let args = run_args(&["--position-scale", "0.25"]);
    assert_eq!(args.safety().unwrap().position_scale, 0.25);
    for (bad, shown) in [
        ("0", "0"),
        ("-2", "-2"),
        ("nan", "NaN"),
        ("inf", "inf"),
        ("1e3", "1000"),
        ("20.5", "20.5"),
    ] {
        let flag = format!("--position-scale={bad}");
        let args = run_args(&[&flag]);
        // Refused before the device is opened or the network is looked at.
        let e = run(&args, Shutdown::new(), &mut Vec::new())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&format!(
                "--position-scale {shown}: expected a finite number > 0"
            )),
            "{e}"
        );
    }
}

/// Regression: `operator run --json` printed a "network: …" line on stdout before the JSON.
#[test]
fn run_json_keeps_stdout_for_the_json() {
    let dir = std::env::temp_dir().join(format!("mmt-cli-json-{}", std::process::id()));
    transport::Identity::generate_files(&dir, "operator", &["operator"]).unwrap();
    let (_, telerobot_crt, _) =
        transport::Identity::generate_files(&dir, "telerobot", &["telerobot"]).unwrap();
    let identity = dir.to_str().unwrap().to_owned();
    let trust = telerobot_crt.to_str().unwrap().to_owned();
    let net = [
        "--connect",
        "127.0.0.1:9",
        "--identity",
        &identity,
        "--trust",
        &trust,
    ];
    for json in [true, false] {
        let mut argv = net.to_vec();
        if json {
            argv.push("--json");
        }
        let args = run_args(&argv);
        // Stopped before any session: the run ends at once, with nothing to report.
        let stop = Shutdown::new();
        stop.trigger();
        let mut out = Vec::new();
        assert!(run(&args, stop, &mut out).is_err());
        let text = String::from_utf8(out).unwrap();
        assert_eq!(
            text.contains("network: telerobot 127.0.0.1:9"),
            !json,
            "{text}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn loop_flags_are_checked() {
    let e = Cli::try_parse_from([
        "operator",
        "run",
        "--device",
        "scripted:exp1",
        "--realtime-priority",
        "100",
    ])
    .unwrap_err()
    .to_string();
    assert!(e.contains("--realtime-priority"), "{e}");
}

/// Issue 11: `--spin-us -3` gave clap's "unexpected argument '-3'" while `--spin-us=-3` gave
/// the range error — and without `--connect` the loop flags were not checked at all (exit 0),
/// with it only after the "network:" line. Both forms now give the range error, before
/// anything is printed.
#[test]
fn a_negative_number_is_a_value_in_both_forms() {
    for (flag, value) in [
        ("--position-scale", "-2"),
        ("--spin-us", "-3"),
        ("--seconds", "-1"),
    ] {
        let joined = format!("{flag}={value}");
        let mut errors = Vec::new();
        for argv in [vec![flag, value], vec![joined.as_str()]] {
            let args = run_args(&argv);
            let mut printed = Vec::new();
            let e = run(&args, Shutdown::new(), &mut printed).unwrap_err();
            assert!(printed.is_empty(), "{argv:?}: printed before the check");
            errors.push(e.to_string());
        }
        assert_eq!(errors[0], errors[1], "{flag}");
        assert!(
            errors[0].contains(flag) && errors[0].contains(value),
            "{}",
            errors[0]
        );
    }
}

/// Issue 13: `--prior` is checked before anything is printed or opened, and names what it wants.
#[test]
fn a_bad_prior_is_refused_before_anything_is_printed() {
    for bad in ["stiff", "5,x", "-1,20"] {
        let args = run_args(&["--prior", bad]);
        let mut printed = Vec::new();
        let e = run(&args, Shutdown::new(), &mut printed)
            .unwrap_err()
            .to_string();
        assert!(printed.is_empty(), "{bad}: printed before the check");
        assert!(e.starts_with(&format!("--prior {bad}: ")), "{e}");
    }
    let args = run_args(&["--prior", "none"]);
    assert_eq!(args.run.prior.node_config().unwrap().prior, None);
}

fn ros_run_args(extra: &[&str]) -> RunArgs {
    let mut argv = vec!["operator", "run", "--device", "ros2"];
    argv.extend_from_slice(extra);
    let Command::Run(args) = Cli::try_parse_from(argv).unwrap().command else {
        panic!("not run")
    };
    *args
}

#[test]
fn ros2_device_flags_make_the_device_config() {
    let args = ros_run_args(&[
        "--ros-domain",
        "7",
        "--topic",
        "pose=/left/fd/ee_pose",
        "--topic",
        "button=none",
        "--topic",
        "twist=/left/fd/ee_twist",
        "--qos",
        "state=reliable,keep-last-5",
        "--qos",
        "command=keep-last-2",
        "--ros-command-len",
        "7",
        "--ros-pose-frame",
        "omega_base",
    ]);
    let o = args.ros.options(&args.device).unwrap();
    assert_eq!(o.graph.unwrap().domain_id, 7);
    let d = o.device;
    assert_eq!(d.topics.pose.as_str(), "/left/fd/ee_pose");
    assert_eq!(d.topics.twist.unwrap().as_str(), "/left/fd/ee_twist");
    assert!(d.topics.button.is_none());
    assert_eq!(
        d.topics.command.unwrap().as_str(),
        "/fd/fd_controller/commands"
    );
    assert_eq!(d.state_qos.to_string(), "reliable,volatile,keep-last-5");
    assert_eq!(d.command_qos.to_string(), "reliable,volatile,keep-last-2");
    assert_eq!(d.command_len.get(), 7);
    assert_eq!(
        d.pose_frame,
        ros2::haptic::ExpectedFrame::Named("omega_base".into())
    );
    let args = ros_run_args(&["--ros-pose-frame", "any"]);
    let d = args.ros.options(&args.device).unwrap().device;
    assert_eq!(d.pose_frame, ros2::haptic::ExpectedFrame::Any);
    // No flags: forcedimension_ros2's defaults.
    let args = ros_run_args(&[]);
    let d = args.ros.options(&args.device).unwrap().device;
    assert_eq!(d, ros2::haptic::HapticConfig::default());
}

#[test]
fn bad_ros2_device_flags_are_refused_with_one_clear_message() {
    for (extra, says) in [
        (
            &["--topic", "wrench=/x"][..],
            "unknown key; expected one of pose, twist, button, command",
        ),
        (
            &["--topic", "pose=fd/ee_pose"],
            "topic pose = \"fd/ee_pose\" is not a valid ROS 2 name (not absolute",
        ),
        (
            &["--qos", "settings=reliable"],
            "unknown key; expected one of state, command",
        ),
        (
            &["--qos", "state=fast"],
            "QoS \"fast\": unknown or out-of-range part",
        ),
        (
            &["--ros-command-len", "8"],
            "--ros-command-len 8: expected 3 to 7",
        ),
        (
            &["--ros-pose-frame", "fd base"],
            "--ros-pose-frame \"fd base\": expected the poses' frame_id",
        ),
        (
            &["--ros-domain", "233"],
            "--ros-domain = \"233\": expected a ROS domain id, 0 to 232",
        ),
    ] {
        let args = ros_run_args(extra);
        let e = run(&args, Shutdown::new(), &mut Vec::new())
            .unwrap_err()
            .to_string();
        assert!(e.contains(says), "{extra:?}: {e}");
    }
    // The ROS 2 flags with another device.
    for (extra, flag) in [
        (&["--topic", "pose=/x"][..], "--topic"),
        (&["--ros-domain", "3"], "--ros-domain"),
        (&["--qos", "state=reliable"], "--qos"),
        (&["--ros-command-len", "3"], "--ros-command-len"),
        (&["--ros-pose-frame", "any"], "--ros-pose-frame"),
    ] {
        let e = run(&run_args(extra), Shutdown::new(), &mut Vec::new())
            .unwrap_err()
            .to_string();
        assert_eq!(e, format!("{flag} applies to --device ros2 only"));
    }
}

#[test]
fn the_start_message_says_plainly_whether_forces_are_written() {
    let caps = DeviceCapabilities::omega7("ROS 2 device");
    let line = force_line(&DeviceSpec::Ros2, &caps);
    assert!(line.starts_with("forces: WRITTEN"), "{line}");
    assert!(line.contains("nothing before the first pose"), "{line}");
    let input_only = DeviceCapabilities {
        outputs_force: false,
        ..caps.clone()
    };
    let line = force_line(&DeviceSpec::Ros2, &input_only);
    assert!(
        line.starts_with("WARNING:") && line.contains("NO force is written"),
        "{line}"
    );
    let line = force_line(&DeviceSpec::Omega, &caps);
    assert!(line.starts_with("forces: WRITTEN to the device"), "{line}");
    let scripted = DeviceSpec::Scripted {
        name: "hold".into(),
    };
    let line = force_line(&scripted, &input_only);
    assert!(line.contains("felt by no one"), "{line}");
}
