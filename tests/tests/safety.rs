//! Safety end to end: whatever an operator sends, the telerobot's motion stays bounded and one
//! session cannot poison the next (issue 11, finding 1).

#![allow(clippy::unwrap_used)]

use std::time::Duration;

use protocol::PROTOCOL_VERSION;
use telerobot::Summary;
use testkit::daemons::*;
use testkit::peers::*;
use testkit::*;

/// The figures of one normal 6 s exp-1 session compared between daemons.
#[derive(Debug)]
struct Figures {
    rows: usize,
    non_finite_forces: usize,
    rms_error_pct_after_stable: Option<f64>,
    time_to_stable_s: Option<f64>,
    summary: Summary,
}

/// A daemon; if `poison`, first a hand-made operator commands the tool to 1e306 m for 1 s (what
/// `operator run --position-scale 1e308` sent before the scale had a bound) and leaves; then
/// the scripted exp-1 operator runs a normal 6 s session.
fn session_after(certs: &Certs, poison: bool) -> Figures {
    let tr = telerobot(&certs.telerobot, &[&certs.operator], 0.0);
    let addr = tr.local_addr();
    if poison {
        runtime().block_on(async {
            let mut raw = RawOperator::connect(addr, &certs.operator, &certs.telerobot).await;
            raw.hello("mallory", PROTOCOL_VERSION).await;
            for seq in 1..=1000 {
                raw.command(seq, 1e306);
                tokio::time::sleep(Duration::from_millis(1)).await;
            }
            raw.conn.close(0u32.into(), b"done");
        });
        let left = wait_for(Duration::from_secs(10), || {
            (!tr.link().status().connected()).then_some(())
        });
        assert!(left.is_some(), "the hostile operator did not leave");
        let during = tr.snapshot();
        // The workspace box held the tool: never beyond its +x wall (0.25 m from the surface
        // point), one episode of the limit.
        assert!(during.tool_m[0] <= 0.25 + 1e-12, "{during:?}");
        assert!(during.guard.workspace.episodes >= 1, "{during:?}");
    }
    let config = operator_config(addr, &certs.operator, &certs.telerobot, "alice", 6.0, 0.0);
    let outcome = spawn_operator(config).join().unwrap().unwrap();
    let summary = tr.stop();
    let series = &outcome.series;
    let non_finite_forces = series
        .measured
        .iter()
        .flatten()
        .filter(|f| !f.iter().all(|v| v.is_finite()))
        .count();
    let r = &outcome.report.experiment;
    Figures {
        rows: series.measured.len(),
        non_finite_forces,
        rms_error_pct_after_stable: r.rms_error_pct_after_stable,
        time_to_stable_s: r.time_to_stable_s,
        summary,
    }
}

/// Before the motion guard, the world filled with NaN and 3,842 of 6,000 rows of the next,
/// normal session had no finite force, until the daemon was restarted.
#[test]
fn a_session_commanding_1e306_m_leaves_the_next_one_as_a_fresh_daemon_would() {
    let _serial = serial();
    let certs = Certs::new();
    let fresh = session_after(&certs, false);
    let poisoned = session_after(&certs, true);
    eprintln!("fresh: {fresh:?}\nafter the hostile session: {poisoned:?}");
    for f in [&fresh, &poisoned] {
        assert!(f.rows >= 5900, "{f:?}");
        assert_eq!(f.non_finite_forces, 0, "{f:?}");
        assert_eq!(f.summary.last.node.rejected_samples, 0, "{f:?}");
        assert_eq!(f.summary.last.guard.faults, 0, "{f:?}");
        assert!(f.time_to_stable_s.is_some(), "{f:?}");
    }
    // The normal session never met the workspace or the speed limit; the step limit acts only
    // on the few ticks where the loop, stalled by the loaded machine, skipped to a newer command
    // (or resumed after holding).
    let g = fresh.summary.last.guard;
    assert_eq!((g.workspace, g.speed), Default::default(), "{g:?}");
    assert!(g.step.ticks < 100, "{g:?}");
    // Accuracy as a fresh daemon's: 6 s runs on a loaded two-core machine spread by several
    // points each way (fresh 5.28 / 9.09 %, after the hostile session 9.13 / 6.83 %, in two
    // runs), so the bound is 5 points and 15 %. What this guards against fails far harder: a
    // session after a poisoned world had mostly NaN forces, and one whose proxy was left on the
    // wrong side of the surface never became stable (both checked above as well).
    let (a, b) = (
        fresh.rms_error_pct_after_stable.unwrap(),
        poisoned.rms_error_pct_after_stable.unwrap(),
    );
    assert!(
        (a - b).abs() <= 5.0 && a.max(b) < 15.0,
        "RMS error after stable: fresh {a:.2} %, after the hostile session {b:.2} %"
    );
}
