//! Every transition of the controlling-operator slot, without tokio.

use super::*;

/// The doorbells and connections are labels here: the rule does not look inside them.
type TestSlot = Slot<&'static str, &'static str>;

const WAIT_NS: i64 = 2_000_000_000;

/// The silence limit of these tests.
const SILENCE: Duration = Duration::from_secs(1);
const SILENCE_NS: i64 = 1_000_000_000;

fn slot() -> TestSlot {
    Slot::new("bells", TAKEOVER_WAIT, SILENCE)
}

/// Alice's certificate is `A`, Bob's `B`; `connection` labels the connection.
fn alice(connection: &'static str) -> Contender<&'static str> {
    contender("alice", b"A", connection)
}

fn bob() -> Contender<&'static str> {
    contender("bob", b"B", "b1")
}

fn contender(name: &str, certificate: &[u8], connection: &'static str) -> Contender<&'static str> {
    Contender {
        name: name.to_owned(),
        certificate: Some(certificate.to_vec()),
        connection,
    }
}

/// Claims and expects the slot.
fn grant(slot: &mut TestSlot, contender: Contender<&'static str>) -> Grant<&'static str> {
    match slot.claim(contender, 0) {
        Ok(Claimed::Granted(grant)) => grant,
        other => panic!("expected the slot, got {other:?}"),
    }
}

/// Claims and expects a refusal.
fn refusal(slot: &mut TestSlot, contender: Contender<&'static str>) -> ClaimError {
    match slot.claim(contender, 0) {
        Err(refused) => refused,
        Ok(claimed) => panic!("expected a refusal, got {claimed:?}"),
    }
}

/// Alice in control on `a1`, and her restarted app on `a2` taking over since `now_ns`: the
/// slot, the old session's grant, the newcomer's ticket and its deadline.
fn takeover(now_ns: i64) -> (TestSlot, Grant<&'static str>, Ticket, i64) {
    let mut slot = slot();
    let old = grant(&mut slot, alice("a1"));
    let ticket = match slot.claim(alice("a2"), now_ns) {
        Ok(Claimed::Replacing {
            ticket,
            old: "a1",
            why: Reason::Restarted,
        }) => ticket,
        other => panic!("expected a takeover closing a1, got {other:?}"),
    };
    match slot.replace(ticket, now_ns) {
        Ok(Replace::Waiting { until_ns }) => (slot, old, ticket, until_ns),
        other => panic!("expected to wait, got {other:?}"),
    }
}

fn holder(slot: &TestSlot) -> Option<&str> {
    match &slot.state {
        State::Held { holder, .. }
        | State::HandingOver {
            newcomer: holder, ..
        } => Some(&holder.contender.name),
        State::Free(_) | State::Vacant => None,
    }
}

fn is_free(slot: &TestSlot) -> bool {
    matches!(slot.state, State::Free("bells"))
}

fn busy(holder: &str) -> ClaimError {
    ClaimError::Busy {
        holder: holder.to_owned(),
    }
}

fn pending(holder: &str) -> ClaimError {
    ClaimError::TakeoverPending {
        holder: holder.to_owned(),
    }
}

#[test]
fn a_free_slot_is_granted_with_the_doorbells() {
    let mut slot = slot();
    assert_eq!(grant(&mut slot, alice("a1")).bells, "bells");
    assert_eq!(holder(&slot), Some("alice"));
}

#[test]
fn another_certificate_is_refused_as_busy_naming_the_holder() {
    let mut slot = slot();
    let _alice = grant(&mut slot, alice("a1"));
    let refused = refusal(&mut slot, bob());
    assert_eq!(refused, busy("alice"));
    assert_eq!(refused.holder(), Some("alice"));
    assert_eq!(refused.to_string(), "alice is in control");
    // Her name with another certificate is someone else.
    let impostor = contender("alice", b"A2", "a2");
    assert_eq!(refusal(&mut slot, impostor), busy("alice"));
    assert_eq!(holder(&slot), Some("alice"));
}

#[test]
fn no_certificate_never_matches_no_certificate() {
    let mut slot = slot();
    let anonymous = |connection| Contender {
        certificate: None,
        ..contender("anon", b"", connection)
    };
    let _first = grant(&mut slot, anonymous("x1"));
    assert_eq!(refusal(&mut slot, anonymous("x2")), busy("anon"));
}

#[test]
fn release_frees_the_slot_and_restores_the_doorbells() {
    let mut slot = slot();
    let alice = grant(&mut slot, alice("a1"));
    assert_eq!(slot.release(alice).ok(), Some(Released::Free));
    assert!(is_free(&slot));
    assert_eq!(grant(&mut slot, bob()).bells, "bells");
    assert_eq!(holder(&slot), Some("bob"));
}

#[test]
fn the_same_certificate_takes_over_once_the_old_session_releases() {
    let (mut slot, old, ticket, until_ns) = takeover(100);
    assert_eq!(until_ns, 100 + WAIT_NS);
    // The old session has not ended yet: wait, until the deadline at the latest.
    assert!(matches!(
        slot.replace(ticket, 200),
        Ok(Replace::Waiting { until_ns }) if until_ns == 100 + WAIT_NS
    ));
    // The old holder releases: the slot goes to the newcomer, not back to free.
    assert_eq!(slot.release(old).ok(), Some(Released::HandedOver));
    assert!(!matches!(slot.state, State::Free(_)));
    let Ok(Replace::Granted(new)) = slot.replace(ticket, 300) else {
        panic!("the takeover should be through")
    };
    assert_eq!(new.bells, "bells");
    // The newcomer holds the slot like any holder: refuses others, releases to free.
    assert_eq!(refusal(&mut slot, bob()), busy("alice"));
    assert_eq!(slot.release(new).ok(), Some(Released::Free));
    assert!(is_free(&slot));
}

#[test]
fn a_takeover_the_old_session_does_not_release_in_time_is_refused() {
    let (mut slot, old, ticket, until_ns) = takeover(100);
    assert!(matches!(
        slot.replace(ticket, until_ns - 1),
        Ok(Replace::Waiting { .. })
    ));
    let refused = slot.replace(ticket, until_ns).unwrap_err();
    let timed_out = ClaimError::TakeoverTimedOut {
        holder: "alice".to_owned(),
        waited: TAKEOVER_WAIT,
    };
    assert_eq!(refused, timed_out);
    assert_eq!(refused.holder(), Some("alice"));
    // The takeover is over: asking again is a mistake, and the old holder's release frees
    // the slot instead of handing it on.
    let again = slot.replace(ticket, until_ns + 1);
    assert_eq!(again.unwrap_err(), ClaimError::NotWaiting);
    assert_eq!(slot.release(old).ok(), Some(Released::Free));
    assert!(is_free(&slot));
}

#[test]
fn a_release_in_time_is_granted_even_if_asked_after_the_deadline() {
    let (mut slot, old, ticket, until_ns) = takeover(0);
    assert_eq!(slot.release(old).ok(), Some(Released::HandedOver));
    let late = slot.replace(ticket, until_ns + 1);
    assert!(matches!(late, Ok(Replace::Granted(_))), "{late:?}");
}

#[test]
fn while_a_takeover_waits_others_are_refused() {
    let (mut slot, old, ticket, _) = takeover(0);
    let refused = refusal(&mut slot, alice("a3"));
    assert_eq!(refused, pending("alice"));
    assert_eq!(refused.holder(), Some("alice"));
    assert_eq!(refusal(&mut slot, bob()), busy("alice"));
    // Handed over but not yet picked up: the same answers, naming the newcomer.
    assert_eq!(slot.release(old).ok(), Some(Released::HandedOver));
    assert_eq!(refusal(&mut slot, alice("a3")), pending("alice"));
    assert_eq!(refusal(&mut slot, bob()), busy("alice"));
    assert!(matches!(slot.replace(ticket, 3), Ok(Replace::Granted(_))));
}

#[test]
fn a_withdrawn_takeover_leaves_the_slot_to_the_old_holder() {
    let (mut slot, old, ticket, _) = takeover(0);
    slot.withdraw(ticket);
    let asked = slot.replace(ticket, 1);
    assert_eq!(asked.unwrap_err(), ClaimError::NotWaiting);
    // A new takeover may start; the old holder's release frees the slot once none waits.
    let Ok(Claimed::Replacing { ticket: again, .. }) = slot.claim(alice("a3"), 2) else {
        panic!("a new takeover should start")
    };
    slot.withdraw(again);
    assert_eq!(slot.release(old).ok(), Some(Released::Free));
    assert!(is_free(&slot));
}

#[test]
fn a_takeover_withdrawn_after_the_handover_frees_the_slot_with_the_doorbells() {
    let (mut slot, old, ticket, _) = takeover(0);
    assert_eq!(slot.release(old).ok(), Some(Released::HandedOver));
    slot.withdraw(ticket);
    assert!(is_free(&slot));
    assert_eq!(grant(&mut slot, bob()).bells, "bells");
}

#[test]
fn withdrawing_a_ticket_that_waits_for_nothing_changes_nothing() {
    let mut slot = slot();
    let alice = grant(&mut slot, alice("a1"));
    slot.withdraw(alice.ticket);
    assert_eq!(holder(&slot), Some("alice"));
    let asked = slot.replace(alice.ticket, 1);
    assert_eq!(asked.unwrap_err(), ClaimError::NotWaiting);
    assert_eq!(slot.release(alice).ok(), Some(Released::Free));
}

#[test]
fn a_grant_that_does_not_hold_the_slot_is_handed_back() {
    let mut slot = slot();
    let _alice = grant(&mut slot, alice("a1"));
    // A grant of another slot, for a ticket this one never gave.
    let mut other = Slot::new("other bells", TAKEOVER_WAIT, SILENCE);
    let first = grant(&mut other, bob());
    assert!(other.release(first).is_ok());
    let stranger = grant(&mut other, bob());
    let back = slot.release(stranger).unwrap_err();
    assert_eq!(back.bells, "other bells");
    assert_eq!(holder(&slot), Some("alice"));
}

#[test]
fn a_stale_ticket_does_not_touch_a_later_holder() {
    let mut slot = slot();
    let first = grant(&mut slot, alice("a1"));
    let stale = first.ticket;
    assert!(slot.release(first).is_ok());
    let _bob = grant(&mut slot, bob());
    slot.withdraw(stale);
    assert_eq!(slot.replace(stale, 0).unwrap_err(), ClaimError::NotWaiting);
    assert_eq!(holder(&slot), Some("bob"));
}

/// Issue 11: after the operator in control died (SIGKILL: no CONNECTION_CLOSE), another trusted
/// operator was refused as busy until quinn's idle timeout (5 s) ended the dead connection.
#[test]
fn a_holder_silent_for_the_limit_is_replaced_by_another_operator() {
    let mut slot = slot();
    let old = grant(&mut slot, alice("a1"));
    // Heard from at 0.5 s; at 1.5 s − 1 ns it has been silent just under the limit.
    slot.heard(old.ticket, SILENCE_NS / 2);
    let just_under = slot.claim(bob(), SILENCE_NS / 2 + SILENCE_NS - 1);
    assert_eq!(just_under.unwrap_err(), busy("alice"));
    let at_limit = SILENCE_NS / 2 + SILENCE_NS;
    let ticket = match slot.claim(bob(), at_limit) {
        Ok(Claimed::Replacing {
            ticket,
            old: "a1",
            why: Reason::Silent { silent },
        }) => {
            assert_eq!(silent, SILENCE);
            ticket
        }
        other => panic!("expected bob to replace the silent a1, got {other:?}"),
    };
    // While the dead session ends, others are refused, naming the holder.
    assert_eq!(
        refusal(&mut slot, contender("carol", b"C", "c1")),
        busy("alice")
    );
    assert_eq!(slot.release(old).ok(), Some(Released::HandedOver));
    let granted = slot.replace(ticket, at_limit + 1);
    assert!(matches!(granted, Ok(Replace::Granted(_))), "{granted:?}");
    assert_eq!(holder(&slot), Some("bob"));
}

#[test]
fn hearing_from_the_holder_keeps_it_in_control() {
    let mut slot = slot();
    let alice = grant(&mut slot, alice("a1"));
    for t in 1..=10 {
        slot.heard(alice.ticket, t * SILENCE_NS / 2);
        let now = t * SILENCE_NS / 2 + SILENCE_NS - 1;
        assert_eq!(slot.claim(bob(), now).unwrap_err(), busy("alice"), "{t}");
    }
    // A stale (or older) report does not move the time back, and another ticket's is ignored.
    slot.heard(alice.ticket, 0);
    slot.heard(Ticket(999), 100 * SILENCE_NS);
    let now = 5 * SILENCE_NS + SILENCE_NS - 1;
    assert_eq!(slot.claim(bob(), now).unwrap_err(), busy("alice"));
    assert!(matches!(
        slot.claim(bob(), 6 * SILENCE_NS),
        Ok(Claimed::Replacing { .. })
    ));
}

#[test]
fn the_silence_limit_follows_the_link() {
    let delay =
        |ms: f64| silence_limit(&transport::LinkTuning::with_expected_delay_ms(ms).unwrap());
    assert_eq!(delay(0.0), Duration::from_secs(1));
    assert_eq!(delay(20.0), Duration::from_secs(1));
    // 400 ms each way: two round trips of 810 ms.
    assert_eq!(delay(400.0), Duration::from_millis(1620));
    assert_eq!(delay(2000.0), Duration::from_millis(8020));
    let slow_keep_alive = transport::LinkTuning {
        keep_alive: Duration::from_millis(900),
        ..transport::LinkTuning::default()
    };
    assert_eq!(silence_limit(&slow_keep_alive), Duration::from_millis(1800));
}
