//! The whole daemons, started through the functions the binaries run —
//! [`telerobot::Telerobot::start`] (what `telerobot run` runs until Ctrl-C) and
//! [`operator::app::run`] (what `operator run` runs) — with the netem shim between them.

use std::net::SocketAddr;
use std::thread::JoinHandle;
use std::time::Duration;

use netem::ShimHandle;
use operator::app::{self, Known, Outcome, RunConfig, RunError};
use operator::device::{DeviceSpec, OpenOptions};
use operator::net::NetConfig;
use operator::safety::SafetyConfig;
use rt::{PeriodicConfig, Shutdown};
use sim::scene::Scene;
use telerobot::Telerobot;
use transport::Identity;

use crate::{Certs, SPIN_NS, shim, tuning, wait_for};

/// The telerobot daemon on the built-in exp-1 scene on a free loopback port, trusting `trusted`.
pub fn telerobot(identity: &Identity, trusted: &[&Identity], delay_ms: f64) -> Telerobot {
    Telerobot::start(telerobot_config(
        identity,
        trusted,
        delay_ms,
        "127.0.0.1:0".parse().unwrap(),
    ))
    .unwrap()
}

/// The telerobot daemon on `listen`, or `None` while the port is still taken.
pub fn telerobot_on(
    identity: &Identity,
    trusted: &[&Identity],
    listen: SocketAddr,
) -> Option<Telerobot> {
    match Telerobot::start(telerobot_config(identity, trusted, 0.0, listen)) {
        Ok(t) => Some(t),
        Err(telerobot::DaemonError::Net(telerobot::net::NetError::Bind { .. })) => None,
        Err(e) => panic!("{e}"),
    }
}

fn telerobot_config(
    identity: &Identity,
    trusted: &[&Identity],
    delay_ms: f64,
    listen: SocketAddr,
) -> telerobot::RunConfig {
    let scene = Scene::exp1();
    telerobot::RunConfig {
        listen,
        identity: identity.clone(),
        trusted_operators: trusted
            .iter()
            .map(|i| ("test.crt".into(), i.cert.clone()))
            .collect(),
        tuning: tuning(delay_ms),
        start_m: telerobot::RunConfig::default_start(&scene),
        limits: scene.motion_limits(),
        robot: telerobot::robot::RobotConfig::Sim,
        scene,
        seed: 1,
        periodic: PeriodicConfig {
            spin_ns: SPIN_NS,
            ..PeriodicConfig::default()
        },
        realtime_priority: None,
        record: None,
    }
}

/// `operator run` with the scripted exp-1 device for `seconds`, to `addr`, presenting `me` and
/// pinning `pinned`. `known_delay_ms`: the set delay, for the report.
pub fn operator_config(
    addr: SocketAddr,
    me: &Identity,
    pinned: &Identity,
    name: &str,
    seconds: f64,
    known_delay_ms: f64,
) -> RunConfig {
    let mut net = NetConfig::new(addr, me.clone(), pinned.cert.clone(), "pinned.crt", name);
    net.tuning = tuning(known_delay_ms);
    RunConfig {
        net,
        device: DeviceSpec::Scripted {
            name: "exp1".into(),
        },
        open: OpenOptions {
            scripted_length_s: Some(seconds),
            ..OpenOptions::default()
        },
        safety: SafetyConfig::default(),
        seconds: Some(seconds),
        periodic: PeriodicConfig {
            spin_ns: SPIN_NS,
            ..PeriodicConfig::default()
        },
        realtime_priority: None,
        first_session_timeout: Some(Duration::from_secs(15)),
        node: node::operator::OperatorConfig::default(),
        experiment: "e2e".into(),
        known: Some(Known {
            scene: Scene::exp1(),
            seed: 1,
            delay_ms: known_delay_ms,
        }),
        record: None,
        stream_to: None,
        tap: None,
    }
}

/// The telerobot behind a shim of `delay_ms` each way, and the configuration of an operator
/// ("alice", scripted exp-1 for `seconds`) connecting through the shim.
pub fn through_shim(
    certs: &Certs,
    delay_ms: f64,
    seconds: f64,
) -> (Telerobot, ShimHandle, RunConfig) {
    through_shim_with(certs, delay_ms, seconds, |_| {})
}

/// [`through_shim`], with `tweak` applied to the telerobot's configuration before it starts
/// (a recorder, say).
pub fn through_shim_with(
    certs: &Certs,
    delay_ms: f64,
    seconds: f64,
    tweak: impl FnOnce(&mut telerobot::RunConfig),
) -> (Telerobot, ShimHandle, RunConfig) {
    let mut config = telerobot_config(
        &certs.telerobot,
        &[&certs.operator],
        delay_ms,
        "127.0.0.1:0".parse().unwrap(),
    );
    tweak(&mut config);
    let tr = Telerobot::start(config).unwrap();
    let shim = shim(tr.local_addr(), delay_ms);
    let config = operator_config(
        shim.local_addr(),
        &certs.operator,
        &certs.telerobot,
        "alice",
        seconds,
        delay_ms,
    );
    (tr, shim, config)
}

/// Runs the operator app on its own thread.
pub fn spawn_operator(config: RunConfig) -> JoinHandle<Result<Outcome, RunError>> {
    std::thread::spawn(move || app::run(config, Shutdown::new()))
}

/// Waits (up to 15 s) until an operator is in control of `tr`.
pub fn wait_connected(tr: &Telerobot) {
    let connected = wait_for(Duration::from_secs(15), || {
        tr.link().status().connected().then_some(())
    });
    assert!(connected.is_some(), "no operator in control within 15 s");
}
