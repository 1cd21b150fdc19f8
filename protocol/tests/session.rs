//! Properties of the session logic on arbitrary input: a peer's headers and our clock readings
//! can be anything without a panic, and the latest-wins rule holds.

mod common;

use common::arb_header;
use proptest::prelude::*;
use protocol::clock::ClockOffsetEstimator;
use protocol::session::{Arrival, SequenceTracker, Session};
use protocol::telerobot_to_operator::Pong;

proptest! {
    #[test]
    fn only_newer_datagrams_are_accepted(seqs in proptest::collection::vec(0u64..200, 0..300)) {
        let mut t = SequenceTracker::new();
        let mut newest = 0;
        for seq in seqs {
            let arrival = t.observe(seq);
            prop_assert_eq!(arrival.is_accepted(), seq > newest);
            if let Arrival::Newer { skipped } = arrival {
                prop_assert_eq!(skipped, seq - newest - 1);
                newest = seq;
            }
        }
        let s = t.stats();
        prop_assert_eq!(s.received, s.accepted + s.stale);
        prop_assert!(s.duplicates + s.late <= s.stale);
        prop_assert!(s.late <= s.gaps);
        prop_assert_eq!(s.gaps + s.accepted, newest);
    }

    #[test]
    fn arbitrary_headers_and_times_never_panic(
        steps in proptest::collection::vec((arb_header(), any::<i64>(), any::<i64>()), 0..50),
    ) {
        let mut s = Session::new();
        for (header, now, max_age) in steps {
            s.on_receive(&header, now);
            let _ = s.next_header(now, now);
            let _ = s.is_stale(now, max_age);
        }
        if let Some(rtt) = s.rtt().latest_ns() {
            prop_assert!(rtt >= 0);
        }
    }

    #[test]
    fn arbitrary_pongs_never_panic(
        pongs in proptest::collection::vec((any::<[i64; 4]>(), 0u64..4), 0..30),
    ) {
        let mut est = ClockOffsetEstimator::new();
        for ([t1_ns, t2_ns, t3_ns, t4], id) in pongs {
            let _ = est.ping(t1_ns);
            if let Some(s) = est.on_pong(&Pong { id, t1_ns, t2_ns, t3_ns }, t4) {
                prop_assert!(s.delay_ns >= 0);
            }
        }
    }
}

/// Two sessions over a scripted link at 1 kHz both ways, 40 ms one way: every fifth operator
/// datagram is lost, and every seventh telerobot datagram takes 1.5 ms longer, so that it arrives
/// after its successor.
#[test]
fn a_scripted_lossy_link_gives_exact_rtt_and_counts() {
    const MS: i64 = 1_000_000;
    let (mut op, mut tr) = (Session::new(), Session::new());
    let (mut to_tr, mut to_op) = (Vec::new(), Vec::new());
    for tick in 0..1_000_i64 {
        let now = tick * MS;
        let h = op.next_header(now, now);
        if h.seq % 5 != 0 {
            to_tr.push((now + 40 * MS, h));
        }
        let extra = if tick % 7 == 6 { 3 * MS / 2 } else { 0 };
        to_op.push((now + 40 * MS + extra, tr.next_header(now, now)));
        for (at, h) in to_tr.extract_if(.., |(at, _)| *at <= now) {
            tr.on_receive(&h, at);
        }
        for (at, h) in to_op.extract_if(.., |(at, _)| *at <= now) {
            op.on_receive(&h, at);
        }
    }
    // Operator seq n leaves at n − 1 ms, reaches the telerobot 40 ms later (after its send of
    // that tick), is echoed 1 ms later with a 1 ms hold and comes back 40 ms after that: the
    // RTT is exactly the link's 80 ms, for every sample.
    assert_eq!(op.rtt().min_ns(), Some(80 * MS));
    assert_eq!(op.rtt().smoothed_ns(), Some(80 * MS));
    assert_eq!(op.rtt().variation_ns(), 0);
    // Seqs 1..=960 have arrived by the end; 192 of them are multiples of 5, the last of which
    // (960) no newer datagram has skipped yet.
    let s = tr.stats();
    assert_eq!((s.accepted, s.gaps, s.stale, s.lost()), (768, 191, 0, 191));
    // Each delayed telerobot datagram is skipped by its successor, then arrives late: reordered,
    // not lost — all but the last (sent at 958 ms, due at 999.5 ms), still on its way.
    let s = op.stats();
    assert_eq!((s.gaps, s.late, s.duplicates, s.lost()), (137, 136, 0, 1));
}

/// The operator's admission: the latest-value kinds are used only when newest of their kind,
/// measurements whenever first seen, nothing twice.
#[test]
fn admission_keeps_the_newest_of_each_kind_and_every_first_measurement() {
    use protocol::Header;
    use protocol::telerobot_to_operator::{Admission, Message};
    let header = |seq| Header {
        seq,
        ..Header::unstamped(0)
    };
    let sample = |kind: &str| {
        common::telerobot_samples()
            .into_iter()
            .find(|m| m.kind() == kind)
            .expect("the samples hold every kind")
    };
    let contact = |seq| {
        let Message::Contact(c) = sample("Contact") else {
            unreachable!()
        };
        Message::Contact(protocol::telerobot_to_operator::Contact {
            header: header(seq),
            ..c
        })
    };
    let measurement = |seq| {
        let Message::Measurement(m) = sample("Measurement") else {
            unreachable!()
        };
        Message::Measurement(protocol::telerobot_to_operator::Measurement {
            header: header(seq),
            ..m
        })
    };
    let (mut session, mut admission) = (Session::new(), Admission::default());
    let mut admit = |m: &Message| admission.admit(m, session.on_receive(m.header().unwrap(), 0));
    assert!(admit(&contact(5)));
    assert!(!admit(&contact(5)), "a duplicate");
    assert!(
        !admit(&contact(4)),
        "late and older than the newest contact"
    );
    assert!(admit(&measurement(3)), "late for the direction, first seen");
    assert!(!admit(&measurement(3)), "a duplicate measurement");
    assert!(admit(&contact(6)));
    assert!(!admit(&contact(u64::MAX)), "implausibly far ahead");
}
