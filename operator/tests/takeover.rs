//! Issue 11: the control slot is freed as soon as the operator in control is known dead. A
//! SIGKILLed operator app sends no CONNECTION_CLOSE; before, another trusted operator was
//! refused as busy until quinn's idle timeout (5 s) ended the dead connection. Now the
//! telerobot takes a controller it has heard nothing from (no datagram, no keep-alive) for the
//! silence limit (max(1 s, 2 × keep-alive, 2 × expected RTT): 1 s here) as dead when another
//! trusted operator asks for the slot.

#![allow(clippy::unwrap_used)]

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use testkit::daemons::{operator_config, spawn_operator};
use testkit::wait_for;
use transport::Identity;

/// The `operator run` child named `alice`, in control of the telerobot at `addr` until killed.
fn alice(addr: std::net::SocketAddr, dir: &std::path::Path, trust: &std::path::Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_operator"))
        .args(["run", "--device", "scripted:hold", "--seconds", "60"])
        .args(["--operator-name", "alice", "--spin-us", "50"])
        .arg("--connect")
        .arg(addr.to_string())
        .arg("--identity")
        .arg(dir)
        .arg("--trust")
        .arg(trust)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

fn in_control(tr: &telerobot::Telerobot, who: &str) -> bool {
    tr.link().status().operator().as_deref() == Some(who)
}

/// Round 0: bob asks once (`--no-wait`) 1.5 s after alice was killed — past the silence limit,
/// well before the idle timeout — and gets control (before: refused as busy, the run failed).
/// Rounds 1–3: bob starts waiting the moment alice is killed; the time until he is in control
/// is printed (`-- --nocapture`), not asserted (no timing thresholds in tests).
#[test]
fn a_killed_controller_loses_the_slot_to_another_trusted_operator() {
    let _serial = testkit::serial();
    let dir = std::env::temp_dir().join(format!("operator-takeover-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let alice_dir = dir.join("alice");
    let (alice_identity, _, _) =
        Identity::generate_files(&alice_dir, "operator", &["operator"]).unwrap();
    let bob = testkit::identity("bob");
    let (telerobot, telerobot_crt, _) =
        Identity::generate_files(&dir, "telerobot", &["telerobot"]).unwrap();
    let tr = testkit::daemons::telerobot(&telerobot, &[&alice_identity, &bob], 0.0);
    let addr = tr.local_addr();
    for round in 0..4 {
        let mut child = alice(addr, &alice_dir, &telerobot_crt);
        let up = wait_for(Duration::from_secs(15), || {
            in_control(&tr, "alice").then_some(())
        });
        assert!(up.is_some(), "round {round}: alice never got control");
        std::thread::sleep(Duration::from_millis(500));
        child.kill().unwrap(); // SIGKILL: no CONNECTION_CLOSE, no Bye
        child.wait().unwrap();
        let killed = Instant::now();
        if round == 0 {
            std::thread::sleep(Duration::from_millis(1500));
            let mut config = operator_config(addr, &bob, &telerobot, "bob", 1.0, 0.0);
            config.net.wait_when_busy = false;
            let outcome = spawn_operator(config).join().unwrap();
            assert!(outcome.is_ok(), "bob was refused: {:?}", outcome.err());
            assert!(tr.link().status().refused_busy() == 0);
        } else {
            let config = operator_config(addr, &bob, &telerobot, "bob", 6.0, 0.0);
            let bob_run = spawn_operator(config);
            let took = wait_for(Duration::from_secs(15), || {
                in_control(&tr, "bob").then(|| killed.elapsed())
            });
            eprintln!("round {round}: bob in control {took:?} after alice was SIGKILLed");
            assert!(took.is_some(), "round {round}: bob never got control");
            let outcome = bob_run.join().unwrap();
            assert!(outcome.is_ok(), "round {round}: {:?}", outcome.err());
        }
        let free = wait_for(Duration::from_secs(5), || {
            (!tr.link().status().connected()).then_some(())
        });
        assert!(free.is_some(), "round {round}: bob's session did not end");
    }
    tr.stop();
    std::fs::remove_dir_all(&dir).unwrap();
}
