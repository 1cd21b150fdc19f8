//! End-to-end over loopback: the telerobot daemon and the operator app, started through the
//! functions the binaries run, with the netem shim between them.
//!
//! One test binary; every test holds [`serial`] (they run spinning real-time loops and must not
//! overlap on a 2-core machine). Bounds are generous: CI is a busy VM. The precise figures come
//! from `operator demo` and the examples (README).

#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use netem::{Direction, Loss};
use operator::app::{self, RunError};
use operator::net::NetError;
use protocol::PROTOCOL_VERSION;
use protocol::handshake::HandshakeError;
use protocol::operator_to_telerobot::{self as o2t, Command};
use protocol::telerobot_to_operator::{self as t2o, Refusal, Welcome};
use rt::Shutdown;
use rt::monotonic_ns;
use testkit::daemons::*;
use testkit::peers::*;
use testkit::*;
use transport::Identity;

/// One delay case: 10 s of the exp-1 script through the shim. The shim holds the commands for
/// the set delay; the telerobot plays them at that delay plus what its playout adds for the
/// jitter it sees (none on a quiet link; on a loaded two-core machine the loopback path itself
/// jitters by milliseconds); and the cross-correlation of the rendered and the measured force
/// finds the delay the robot played at.
///
/// Before, the test held the measured delay to the set one ±5 ms, which a loaded machine broke
/// for a sound system (8.4 ms at 0 ms set, with an uplink p99 of 12 ms; 18.8 ms with one of
/// 26 ms): the figure is the playout's, not the link's alone.
fn delay_is_reproduced(delay_ms: f64) {
    let _serial = serial();
    let (tr, shim, config) = through_shim(&Certs::new(), delay_ms, 10.0);
    let outcome = spawn_operator(config).join().unwrap().unwrap();
    let summary = tr.stop();
    shim.shutdown().unwrap();
    let r = &outcome.report;
    let measured = r.measured_delay_ms.unwrap_or(f64::NAN);
    let played = summary.last.node.mean_played_lag_ms().unwrap_or(f64::NAN);
    let uplink = summary.command_latency;
    let context = format!(
        "set {delay_ms} ms, measured {measured} ms ({:?}), played at {played} ms, uplink {uplink:?}",
        r.delay_estimate
    );
    // The shim: half the commands arrive no sooner than the set delay, and within 5 ms of it
    // (the loopback path's own latency, a few ms on a loaded machine).
    let median = uplink.p50_us * 1e-3;
    assert!(
        median >= delay_ms - 0.5 && median <= delay_ms + 5.0,
        "{context}"
    );
    // The playout: at the set delay at least, and within 5 ms of the link's slowest 1 % (after a
    // stall it takes the longer lag at once and returns at 2 % of real time: a 136 ms
    // command at 100 ms set held the mean 1.2 ms above the p99 in one CI run here).
    assert!(
        played >= delay_ms - 0.5 && played <= uplink.p99_us * 1e-3 + 5.0,
        "{context}"
    );
    // The figure: the delay the robot played at (a mean, where the correlation weighs the
    // moving stretches: they differ by 2–4 ms when the playout lag varies).
    assert!((measured - played).abs() <= 5.0, "{context}");
    // The model was rendered, and close to the measured force (the precise figure: the demo).
    let error = r.experiment.rms_error_pct_after_stable.unwrap_or(f64::NAN);
    assert!(error < 15.0, "RMS error after stable {error} %");
    assert_eq!((r.sessions, summary.sessions), (1, 1));
    assert!(r.link.received > 5000, "{:?}", r.link);
    assert!(summary.last.node.commands > 5000, "{:?}", summary.last);
    // A healthy session: no model before the first contact is not "stale parameters".
    assert_eq!(r.safety.stale_params.episodes, 0, "{:?}", r.safety);
    // quinn put every datagram it was handed on the wire, both ways, but for the few handed
    // over as the connection closed, and its controller never saw congestion: nothing was held
    // back inside quinn (the delay is the shim's alone). "A few" is the last tens of
    // milliseconds of sending at about 1 kHz: a loaded 2-core run left 14 and 16 (its send
    // task stalled up to 29 ms), where a hold-back inside quinn would leave thousands.
    for (side, l) in [("operator", &r.link), ("telerobot", &summary.link)] {
        let untransmitted = l.sent - l.quinn_datagrams_transmitted.min(l.sent);
        assert!(
            untransmitted <= 50,
            "{side}: {untransmitted} not on the wire: {l:?}"
        );
        assert_eq!(l.quinn_congestion_events, 0, "{side}: {l:?}");
    }
}

#[test]
fn delay_is_reproduced_at_0_ms() {
    delay_is_reproduced(0.0);
}

#[test]
fn delay_is_reproduced_at_100_ms() {
    delay_is_reproduced(100.0);
}

#[test]
fn delay_is_reproduced_at_400_ms() {
    delay_is_reproduced(400.0);
}

#[test]
fn a_2_s_outage_heals_without_restart() {
    let _serial = serial();
    let (tr, shim, config) = through_shim(&Certs::new(), 100.0, 14.0);
    let operator = spawn_operator(config);
    wait_connected(&tr);
    // 6 s in: the second contact episode of the script, with a model rendered.
    std::thread::sleep(Duration::from_secs(6));
    let normal = shim.config(Direction::Up);
    let mut cut = normal.clone();
    cut.loss = Loss::Random { probability: 1.0 };
    let outage = Instant::now();
    for d in Direction::ALL {
        shim.set_config(d, cut.clone()).unwrap();
    }
    // The telerobot holds still once its newest command is 50 ms old.
    std::thread::sleep(Duration::from_millis(400));
    let held = tr.snapshot();
    assert!(held.holding, "{held:?}");
    while outage.elapsed() < Duration::from_millis(1900) {
        let s = tr.snapshot();
        assert!(s.holding, "{s:?}");
        assert_eq!(s.tool_m, held.tool_m, "the robot moved during the outage");
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_secs(2).saturating_sub(outage.elapsed()));
    for d in Direction::ALL {
        shim.set_config(d, normal.clone()).unwrap();
    }
    // Commands flow again: the robot follows the operator.
    wait_for(Duration::from_secs(3), || {
        (!tr.snapshot().holding).then_some(())
    })
    .unwrap();
    let outcome = operator.join().unwrap().unwrap();
    let summary = tr.stop();
    let shim_stats = shim.shutdown().unwrap();
    // The outage was real: 2 s of a 1 kHz command stream (1,449 dropped in one CI run on a loaded
    // 2-core machine, whose operator loop sent 940 a second over the run).
    assert!(shim_stats.up.dropped_loss > 1000, "{shim_stats:?}");

    // No reconnection was needed on either side.
    let r = &outcome.report;
    assert_eq!((r.sessions, summary.sessions), (1, 1));
    // The outage is told on both sides: one, about 2 s long (issue 11: it was hidden).
    for (side, o) in [("operator", r.outages), ("telerobot", summary.outages)] {
        assert_eq!(o.count, 1, "{side}: {o:?}");
        assert!((1_700.0..=2_700.0).contains(&o.longest_ms), "{side}: {o:?}");
    }
    let marked = r.experiment.error_over_time.iter().filter(|w| w.outage);
    assert!(
        (2..=4).contains(&marked.count()),
        "{:?}",
        r.experiment.error_over_time
    );
    // The outage in the operator's series: the longest run of commands without a measurement.
    let s = &outcome.series;
    let first = s.rendering.iter().position(|r| *r).unwrap();
    let (mut start, mut len, mut run_start, mut run) = (0, 0, 0, 0);
    for k in first..s.len() {
        if s.measured[k].is_none() {
            if run == 0 {
                run_start = k;
            }
            run += 1;
            if run > len {
                (start, len) = (run_start, run);
            }
        } else {
            run = 0;
        }
    }
    assert!((1700..=2600).contains(&len), "outage of {len} ticks");
    // The operator kept rendering from its local model all through it...
    let window = start..start + len;
    assert!(s.rendering[window.clone()].iter().all(|r| *r));
    let in_contact: Vec<usize> = window.filter(|&k| s.contact_local[k]).collect();
    assert!(
        in_contact.len() > 1000,
        "{} ticks in contact",
        in_contact.len()
    );
    let felt = in_contact
        .iter()
        .filter(|&&k| norm(s.rendered[k]) > 0.1)
        .count();
    assert!(
        felt * 10 >= in_contact.len() * 9,
        "{felt} of {}",
        in_contact.len()
    );
    // ... and measurements came back after it.
    let after = s.measured[start + len..].iter().flatten().count();
    assert!(after > 1500, "{after} measurements after the outage");
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

#[test]
fn untrusted_and_wrong_certificates_are_refused_with_clear_errors() {
    let _serial = serial();
    let certs = Certs::new();
    let stranger = Identity::generate(&["stranger"]).unwrap();
    let tr = telerobot(&certs.telerobot, &[&certs.operator], 0.0);

    // An operator certificate the telerobot was not told to trust.
    let config = operator_config(
        tr.local_addr(),
        &stranger,
        &certs.telerobot,
        "mallory",
        5.0,
        0.0,
    );
    let e = app::run(config, Shutdown::new()).err().unwrap();
    assert!(matches!(e, RunError::Net(NetError::NotTrusted)), "{e:?}");
    assert_eq!(
        e.to_string(),
        "the telerobot refused our certificate: not in its trusted set"
    );
    assert!(tr.untrusted_refusals() >= 1);

    // A telerobot that is not the one pinned.
    let config = operator_config(
        tr.local_addr(),
        &certs.operator,
        &stranger,
        "alice",
        5.0,
        0.0,
    );
    let e = app::run(config, Shutdown::new()).err().unwrap();
    assert!(
        matches!(&e, RunError::Net(NetError::PinMismatch { pinned }) if pinned == "pinned.crt"),
        "{e:?}"
    );
    assert!(
        e.to_string()
            .contains("does not match the pinned certificate pinned.crt"),
        "{e}"
    );
    assert_eq!(tr.stop().sessions, 0);
}

#[test]
fn a_second_operator_is_refused_while_one_is_connected() {
    let _serial = serial();
    let certs = Certs::new();
    let bob = Identity::generate(&["bob"]).unwrap();
    let tr = telerobot(&certs.telerobot, &[&certs.operator, &bob], 0.0);
    let alice = spawn_operator(operator_config(
        tr.local_addr(),
        &certs.operator,
        &certs.telerobot,
        "alice",
        5.0,
        0.0,
    ));
    wait_connected(&tr);
    let mut config = operator_config(tr.local_addr(), &bob, &certs.telerobot, "bob", 2.0, 0.0);
    config.net.wait_when_busy = false; // --no-wait
    let e = app::run(config, Shutdown::new()).err().unwrap();
    assert!(
        matches!(
            &e,
            RunError::Net(NetError::Handshake(HandshakeError::Refused(Refusal::Busy {
                controlling_operator
            }))) if controlling_operator.starts_with("'alice' (certificate test.crt, sha256:")
        ),
        "{e:?}"
    );
    assert!(
        e.to_string()
            .contains("telerobot is busy: 'alice' (certificate test.crt, sha256:"),
        "{e}"
    );
    // Alice was not disturbed.
    let outcome = alice.join().unwrap().unwrap();
    assert_eq!(outcome.report.sessions, 1);
    // Once she has left, bob is accepted, with a fresh node (built off the loop thread).
    let config = operator_config(tr.local_addr(), &bob, &certs.telerobot, "bob", 3.0, 0.0);
    let outcome = app::run(config, Shutdown::new()).unwrap();
    assert!(
        outcome.report.measurements.0 > 2000,
        "{:?}",
        outcome.report.measurements
    );
    let s = tr.snapshot();
    assert_eq!((s.session, s.inline_node_builds), (2, 0), "{s:?}");
    assert!(s.node.commands > 2000 && s.node.commands < 3500, "{s:?}");
    let summary = tr.stop();
    assert_eq!((summary.sessions, summary.refusals), (2, 1));
}

/// Before: a busy telerobot ended the second operator's run at once. Now it waits and asks
/// again until `--seconds` is over: bob gets the slot once alice has left.
#[test]
fn a_busy_telerobot_makes_the_operator_wait_for_the_slot() {
    let _serial = serial();
    let certs = Certs::new();
    let bob = Identity::generate(&["bob"]).unwrap();
    let tr = telerobot(&certs.telerobot, &[&certs.operator, &bob], 0.0);
    let alice = spawn_operator(operator_config(
        tr.local_addr(),
        &certs.operator,
        &certs.telerobot,
        "alice",
        3.0,
        0.0,
    ));
    wait_connected(&tr);
    let config = operator_config(tr.local_addr(), &bob, &certs.telerobot, "bob", 8.0, 0.0);
    let started = Instant::now();
    let outcome = app::run(config, Shutdown::new()).unwrap();
    // `--seconds` bounded the whole run, the wait included.
    assert!(
        started.elapsed() < Duration::from_secs(10),
        "{:?}",
        started.elapsed()
    );
    assert_eq!(outcome.report.sessions, 1);
    assert!(
        outcome.report.measurements.0 > 2000,
        "{:?}",
        outcome.report.measurements
    );
    assert_eq!(alice.join().unwrap().unwrap().report.sessions, 1);
    let summary = tr.stop();
    assert_eq!(summary.sessions, 2);
    assert!(summary.refusals >= 1, "{summary:?}");
}

/// Before: with nothing listening, the operator retried forever despite `--seconds`.
#[test]
fn seconds_bound_a_run_that_never_connects() {
    let certs = Certs::new();
    // A port with nothing behind it.
    let closed = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let addr = closed.local_addr().unwrap();
    drop(closed);
    let mut config = operator_config(addr, &certs.operator, &certs.telerobot, "alice", 3.0, 0.0);
    config.first_session_timeout = None; // what `operator run` uses
    let started = Instant::now();
    let e = app::run(config, Shutdown::new()).err().unwrap();
    assert!(
        started.elapsed() < Duration::from_secs(6),
        "{:?}",
        started.elapsed()
    );
    let text = e.to_string();
    assert!(
        text.contains(&format!(
            "no session with the telerobot at {addr} within 3s"
        )),
        "{text}"
    );
}

#[test]
fn the_operator_reconnects_when_the_telerobot_comes_back() {
    let _serial = serial();
    let certs = Certs::new();
    let tr = telerobot(&certs.telerobot, &[&certs.operator], 0.0);
    let addr = tr.local_addr();
    let operator = spawn_operator(operator_config(
        addr,
        &certs.operator,
        &certs.telerobot,
        "alice",
        12.0,
        0.0,
    ));
    wait_connected(&tr);
    std::thread::sleep(Duration::from_secs(3));
    let first = tr.stop();
    assert_eq!(first.sessions, 1);
    // The same telerobot again, on the same port (retried while the old socket is released).
    let tr = wait_for(Duration::from_secs(5), || {
        telerobot_on(&certs.telerobot, &[&certs.operator], addr)
    })
    .unwrap();
    let reconnected = wait_for(Duration::from_secs(10), || {
        tr.link().status().connected().then_some(())
    });
    assert!(reconnected.is_some(), "the operator did not come back");
    let outcome = operator.join().unwrap().unwrap();
    let second = tr.stop();
    let r = &outcome.report;
    // One haptic loop all along, a fresh node for the second session.
    assert_eq!(r.sessions, 2);
    assert!(r.loop_timing.ticks >= 11_900, "{:?}", r.loop_timing);
    assert!(second.last.node.commands > 2000, "{:?}", second.last);
    let after = outcome.series.measured[9_000..].iter().flatten().count();
    assert!(after > 2000, "{after} measurements in the last 3 s");
}

/// Found by the soak (2 % loss, 400 ms): each camera frame waited for a stream while the
/// operator's stream limit was full, deaf to the newer frame that made it stale — 30 frames a
/// second kept alive, memory growing by 1 MB/s. Now every frame is sent or superseded.
#[test]
fn frames_the_operator_cannot_take_yet_are_superseded_not_kept() {
    let _serial = serial();
    let certs = Certs::new();
    let rt = runtime();
    let tr = telerobot(&certs.telerobot, &[&certs.operator], 0.0);
    let raw = rt.block_on(async {
        let mut raw =
            RawOperator::connect(tr.local_addr(), &certs.operator, &certs.telerobot).await;
        let answer = raw
            .hello_wanting_clouds("reads-nothing", PROTOCOL_VERSION, true)
            .await;
        assert!(matches!(answer, t2o::Message::Welcome(_)), "{answer:?}");
        // Never accepting a cloud stream: after 4 (its limit) the telerobot cannot open more.
        tokio::time::sleep(Duration::from_secs(3)).await;
        raw
    });
    // Counted while the session runs: at the stop, frames still waiting fail with the
    // connection, whatever they waited for.
    let (sent, superseded, failed) = tr.link().status().clouds();
    let summary = tr.stop();
    drop(raw);
    let (frames, _) = summary.camera_frames;
    assert!(frames >= 30, "{frames} camera frames in 3 s");
    assert!(
        sent <= 5,
        "{sent} frames sent to a peer whose stream limit is 4"
    );
    assert!(
        sent + superseded + failed >= frames / 2,
        "{frames} frames: {sent} sent, {superseded} superseded, {failed} failed — the rest kept"
    );
}

/// The idle daemon spun its 1 kHz loop for nobody (10 % of a core): now its ticks go on
/// without the spin while no operator is connected, and a session is served at once.
#[test]
fn the_loop_idles_without_an_operator_and_serves_one_at_once() {
    let _serial = serial();
    let certs = Certs::new();
    let rt = runtime();
    let tr = telerobot(&certs.telerobot, &[&certs.operator], 0.0);
    std::thread::sleep(Duration::from_millis(500));
    let idle = tr.timing();
    assert!(idle.ticks >= 300, "{idle:?}");
    assert!(
        idle.idle_ticks + 2 >= idle.ticks,
        "served ticks with nobody connected: {idle:?}"
    );
    rt.block_on(async {
        let mut raw =
            RawOperator::connect(tr.local_addr(), &certs.operator, &certs.telerobot).await;
        let answer = raw.hello("alice", PROTOCOL_VERSION).await;
        assert!(matches!(answer, t2o::Message::Welcome(_)), "{answer:?}");
        let served = tr.timing();
        tokio::time::sleep(Duration::from_millis(300)).await;
        let later = tr.timing();
        let idled = later.idle_ticks - served.idle_ticks;
        assert!(idled <= 2, "{idled} idle ticks while connected");
        assert!(later.ticks - served.ticks >= 200, "{later:?}");
        raw.conn.close(0u32.into(), b"done");
    });
    let summary = tr.stop();
    assert!(summary.timing.idle_ticks >= idle.idle_ticks);
}

#[test]
fn a_version_mismatch_is_refused_naming_both_versions() {
    let _serial = serial();
    let certs = Certs::new();
    let newer = PROTOCOL_VERSION + 1;
    let rt = runtime();

    // A newer operator at the real telerobot.
    let tr = telerobot(&certs.telerobot, &[&certs.operator], 0.0);
    let answer = rt.block_on(async {
        let mut raw =
            RawOperator::connect(tr.local_addr(), &certs.operator, &certs.telerobot).await;
        raw.hello("future", newer).await
    });
    let t2o::Message::Refused(refused) = answer else {
        panic!("{answer:?}")
    };
    assert_eq!(
        refused.reason.to_string(),
        format!(
            "protocol version mismatch: telerobot speaks {PROTOCOL_VERSION}, operator speaks {newer}"
        )
    );
    assert_eq!(tr.stop().sessions, 0);

    // The real operator at a newer telerobot.
    let welcome = Welcome {
        version: newer,
        scene: telerobot_summary(),
    };
    let raw = RawTelerobot::start(&rt, &certs.telerobot, &certs.operator, welcome, vec![]);
    let config = operator_config(
        raw.addr,
        &certs.operator,
        &certs.telerobot,
        "alice",
        2.0,
        0.0,
    );
    let e = app::run(config, Shutdown::new()).err().unwrap();
    assert_eq!(
        e.to_string(),
        format!(
            "protocol version mismatch: operator speaks {PROTOCOL_VERSION}, telerobot speaks {newer}"
        )
    );
}

/// The exp-1 scene's summary, as the daemon sends it.
fn telerobot_summary() -> t2o::SceneSummary {
    sim::scene::Scene::exp1().summary()
}

#[test]
fn garbage_datagrams_to_either_port_are_counted_and_ignored() {
    let _serial = serial();
    let certs = Certs::new();
    let rt = runtime();

    // To the telerobot: a hand-made operator in control sends garbage around valid commands;
    // plain UDP junk hits the port as well.
    let tr = telerobot(&certs.telerobot, &[&certs.operator], 0.0);
    udp_junk(tr.local_addr(), 20);
    let garbage: Vec<Vec<u8>> = vec![
        vec![0xde, 0xad, 0xbe, 0xef],
        vec![1],
        o2t::encode(&o2t::Message::Bye),
        t2o::encode(&t2o::Message::Welcome(Welcome {
            version: PROTOCOL_VERSION,
            scene: telerobot_summary(),
        })),
    ];
    let sent = garbage.len() as u64;
    let raw = rt.block_on(async {
        let mut raw =
            RawOperator::connect(tr.local_addr(), &certs.operator, &certs.telerobot).await;
        assert!(matches!(
            raw.hello("raw", PROTOCOL_VERSION).await,
            t2o::Message::Welcome(_)
        ));
        for g in &garbage {
            raw.conn.send_datagram(g.clone().into()).unwrap();
        }
        for seq in 1..=300u64 {
            let command = o2t::Message::Command(Command {
                header: protocol::Header {
                    seq,
                    sample_time_ns: monotonic_ns(),
                    send_time_ns: monotonic_ns(),
                    ..protocol::Header::default()
                },
                position_m: [0.0, 0.0, 0.01],
                velocity_m_per_s: [0.0; 3],
            });
            raw.conn
                .send_datagram(o2t::encode(&command).into())
                .unwrap();
            tokio::time::sleep(Duration::from_millis(1)).await;
        }
        raw
    });
    let counted = wait_for(Duration::from_secs(5), || {
        (tr.link().stats().garbage == sent).then_some(())
    });
    assert!(counted.is_some(), "{:?}", tr.link().stats());
    // The loop went on executing the valid commands.
    let executed = wait_for(Duration::from_secs(5), || {
        let s = tr.snapshot();
        (s.node.commands >= 250).then_some(s)
    });
    assert!(executed.is_some(), "{:?}", tr.snapshot());
    assert!(tr.link().status().connected());
    drop(raw);
    tr.stop();

    // To the operator: a hand-made telerobot sends garbage; plain UDP junk hits its port too.
    let welcome = Welcome {
        version: PROTOCOL_VERSION,
        scene: telerobot_summary(),
    };
    let garbage: Vec<Vec<u8>> = vec![
        vec![0xde, 0xad, 0xbe, 0xef],
        vec![2],
        o2t::encode(&o2t::Message::Bye),
        t2o::encode(&t2o::Message::Welcome(welcome.clone())),
        vec![0xff; 300],
    ];
    let sent = garbage.len() as u64;
    let raw = RawTelerobot::start(&rt, &certs.telerobot, &certs.operator, welcome, garbage);
    let operator = spawn_operator(operator_config(
        raw.addr,
        &certs.operator,
        &certs.telerobot,
        "alice",
        3.0,
        0.0,
    ));
    let conn = wait_for(Duration::from_secs(10), || raw.conn.lock().unwrap().clone()).unwrap();
    udp_junk(conn.remote_address(), 20);
    let outcome = operator.join().unwrap().unwrap();
    assert_eq!(
        outcome.report.link.garbage, sent,
        "{:?}",
        outcome.report.link
    );
    assert_eq!(outcome.report.sessions, 1);
    assert!(outcome.report.loop_timing.ticks >= 2900);
}

/// The README's first command, `demo`, end to end at a short length: the JSON on stdout parses
/// and names the set delay's measurement, and the report, series and plots are written. Then
/// `operator run`'s files (report and series, no plots: the daemons link no plotting library)
/// are drawn by `mmt plot` to the same plots.
#[test]
fn the_demo_command_runs_and_writes_its_report() {
    use clap::Parser;
    let _serial = serial();
    let out = std::env::temp_dir().join(format!("mmt-demo-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let args = demo::cli::Cli::try_parse_from([
        "demo",
        // 8 s: on a loaded machine the model may be rendered late, and the delay estimate
        // needs a few seconds of rendered contact.
        "--seconds",
        "8",
        "--delay-ms",
        "50",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap();
    let mut stdout = Vec::new();
    demo::cli::run_cmd(&args, rt::Shutdown::new(), &mut stdout).unwrap();
    let json: serde_json::Value = serde_json::from_slice(&stdout).expect("stdout is JSON");
    let delay = json["measured_delay_ms"].as_f64();
    // The delay the robot played at (the set 50 ms, plus what the playout added for the
    // loopback's jitter on this machine: `delay_is_reproduced`).
    let node: node::telerobot::TelerobotStats =
        serde_json::from_value(json["telerobot"]["last"]["node"].clone()).unwrap();
    let played = node.mean_played_lag_ms().unwrap();
    assert!(played >= 49.5, "{played} ms");
    assert!(
        delay.is_some_and(|d| (d - played).abs() <= 5.0),
        "{delay:?} against {played} ms"
    );
    for key in ["rms_error_pct_after_stable", "bands", "loop_timing", "link"] {
        assert!(!json[key].is_null(), "{key} missing or null");
    }
    for file in [
        "report.json",
        "series.csv",
        "force.svg",
        "force.png",
        "error.svg",
        "spectrum.svg",
    ] {
        let len = std::fs::metadata(out.join(file)).map_or(0, |m| m.len());
        assert!(len > 0, "{file} not written");
    }
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["measured_delay_ms"], json["measured_delay_ms"]);
    // An `operator run --out` directory has the report and the series; `mmt plot` draws them.
    let run_dir = out.join("operator-run");
    std::fs::create_dir_all(&run_dir).unwrap();
    for file in ["report.json", "series.csv"] {
        std::fs::copy(out.join(file), run_dir.join(file)).unwrap();
    }
    let written = lab::cli::plot::plot_dir(&run_dir).unwrap();
    assert_eq!(written.len(), 6, "{written:?}");
    for file in ["force.svg", "error.svg", "spectrum.svg", "force.png"] {
        let (ours, demo) = (run_dir.join(file), out.join(file));
        let len = std::fs::metadata(&ours).map_or(0, |m| m.len());
        assert!(len > 0, "{file} not drawn");
        if file.ends_with(".svg") {
            // The same figures from the CSV's rounding: the same number of drawn elements.
            let count =
                |p: &std::path::Path| std::fs::read_to_string(p).unwrap().matches('<').count();
            assert_eq!(count(&ours), count(&demo), "{file}");
        }
    }
    std::fs::remove_dir_all(&out).unwrap();
}

/// 5 % loss and 2 ms jitter each way through the shim: the 1 kHz datagram streams never stall for
/// 50 ms (quinn retransmits nothing of them and holds nothing back), and the model still renders.
#[test]
fn loss_and_jitter_do_not_stall_the_datagram_streams() {
    let _serial = serial();
    let (tr, shim, config) = through_shim(&Certs::new(), 50.0, 8.0);
    let mut impaired = shim.config(Direction::Up);
    impaired.loss = Loss::Random { probability: 0.05 };
    impaired.jitter_ns = 2_000_000;
    for d in Direction::ALL {
        shim.set_config(d, impaired.clone()).unwrap();
    }
    let outcome = spawn_operator(config).join().unwrap().unwrap();
    let summary = tr.stop();
    shim.shutdown().unwrap();
    let r = &outcome.report;
    for (side, l) in [("operator", &r.link), ("telerobot", &summary.link)] {
        eprintln!(
            "{side}: longest gap {:.1} ms, {} lost",
            l.max_gap_ms, l.lost
        );
        assert!(l.lost > 100, "{side}: the loss was applied: {l:?}");
        assert!(
            l.max_gap_ms > 0.0 && l.max_gap_ms < 50.0,
            "{side}: longest gap {} ms",
            l.max_gap_ms
        );
    }
    let error = r.experiment.rms_error_pct_after_stable.unwrap_or(f64::NAN);
    assert!(error < 15.0, "RMS error after stable {error} %");
}

/// Issue 13 item 5, end to end: the telerobot's scene declares a prior of its object; its
/// `Welcome` carries it to the operator app, which renders it (the default `--prior scene`)
/// and reports it, with the error of each stage.
#[test]
fn the_scene_prior_reaches_the_operator_app() {
    let _serial = serial();
    let guess = mmt::model::prior::Guess {
        k_contact_n_per_m: Some(420.0),
        b_contact_ns_per_m: Some(45.0),
        spread: 0.0,
        ..mmt::model::prior::Guess::default()
    };
    let (tr, shim, config) = through_shim_with(&Certs::new(), 0.0, 4.0, |c| {
        c.scene.prior = Some(guess);
    });
    let outcome = spawn_operator(config).join().unwrap().unwrap();
    tr.stop();
    shim.shutdown().unwrap();
    let r = &outcome.report.experiment;
    let prior = r.prior.expect("a prior was rendered");
    assert_eq!(prior.source, mmt::model::prior::PriorSource::Scene);
    assert_eq!(
        (prior.normal.k_n_per_m, prior.normal.b_ns_per_m),
        (420.0, 45.0)
    );
    let stages = r.stage_errors;
    assert!(
        stages.seconds[0] > 0.0 && stages.prior_pct.is_some(),
        "{stages:?}"
    );
}
