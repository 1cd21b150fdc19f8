//! `telerobot::net::serve` over loopback QUIC, driven by a hand-made operator (so that the tests
//! can send what a correct operator never would: another version, garbage datagrams).

#![allow(clippy::unwrap_used)]

use std::time::Duration;

use protocol::operator_to_telerobot::{self as o2t, Command, Ping};
use protocol::telerobot_to_operator::{self as t2o, Contact, ContactState, Datagram, Refusal};
use protocol::{Header, PROTOCOL_VERSION};
use testkit::net::TelerobotServer;
use testkit::peers::RawOperator;
use testkit::{eventually, identity, wall_summary};
use transport::endpoint::{CertificateFailure, certificate_failure};
use transport::{CloseCode, Identity, framing};

/// A telerobot server presenting a fresh certificate, trusting `trusted`.
fn start(trusted: &[&Identity]) -> TelerobotServer {
    TelerobotServer::start(
        &identity("telerobot"),
        "127.0.0.1:0".parse().unwrap(),
        trusted,
    )
}

/// A hand-made operator presenting `me` to `telerobot`.
async fn connect(
    telerobot: &TelerobotServer,
    me: &Identity,
) -> Result<RawOperator, quinn::ConnectionError> {
    RawOperator::try_connect(telerobot.addr, me, &telerobot.identity).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_trusted_operator_is_welcomed_and_datagrams_flow_both_ways() {
    let op = Identity::generate(&["operator"]).unwrap();
    let tr = start(&[&op]);
    let mut raw = connect(&tr, &op).await.unwrap();
    let t2o::Message::Welcome(welcome) = raw.hello("alice", PROTOCOL_VERSION).await else {
        panic!("no Welcome")
    };
    assert_eq!(
        (welcome.version, welcome.scene),
        (PROTOCOL_VERSION, wall_summary())
    );
    assert!(tr.link.status().connected());
    assert_eq!(tr.link.status().operator().as_deref(), Some("alice"));

    raw.command(1, 0.25);
    let got = eventually(Duration::from_secs(5), || tr.link.next_command()).await;
    assert_eq!(got.message.position_m, [0.25, 0.0, 0.0]);
    assert_eq!(got.session, 1);
    assert!(got.received_ns >= got.message.header.sample_time_ns);

    let contact = Contact {
        header: Header {
            sample_time_ns: 42,
            ..Header::default()
        },
        command_sample_time_ns: got.message.header.sample_time_ns,
        state: ContactState::Contact,
        proxy_position_m: [0.1, 0.2, 0.3],
        normal: Some([0.0, 0.0, 1.0]),
        frame: None,
        surface_point_m: None,
        penetration_m: Some(0.001),
    };
    assert!(tr.link.send(Datagram::Contact(contact)));
    let t2o::Message::Contact(back) = raw.next_datagram().await else {
        panic!("not a Contact")
    };
    // The network task stamped the header: first datagram, echoing our command.
    assert_eq!((back.header.seq, back.header.sample_time_ns), (1, 42));
    assert_eq!(back.header.echo_seq, 1);
    assert_eq!(back.proxy_position_m, contact.proxy_position_m);

    raw.datagram(&o2t::Message::Ping(Ping { id: 1, t1_ns: 7 }));
    let t2o::Message::Pong(pong) = raw.next_datagram().await else {
        panic!("not a Pong")
    };
    assert_eq!((pong.id, pong.t1_ns), (1, 7));
    assert!(pong.t3_ns >= pong.t2_ns && pong.t2_ns > 0);

    // Bye ends the session and frees the slot.
    framing::write_frame(&mut raw.send, &o2t::encode(&o2t::Message::Bye))
        .await
        .unwrap();
    let closed = raw.conn.closed().await;
    assert!(closed.to_string().contains("Bye"), "{closed}");
    eventually(Duration::from_secs(5), || {
        (!tr.link.status().connected()).then_some(())
    })
    .await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_untrusted_operator_is_refused_in_the_tls_handshake() {
    let (op, stranger) = (
        Identity::generate(&["operator"]).unwrap(),
        Identity::generate(&["stranger"]).unwrap(),
    );
    let tr = start(&[&op]);
    let error = match connect(&tr, &stranger).await {
        Err(e) => e,
        Ok(mut raw) => {
            // The client may finish its side first; the refusal then closes the connection.
            let _ = framing::write_frame(&mut raw.send, b"x").await;
            raw.conn.closed().await
        }
    };
    assert_eq!(
        certificate_failure(&error),
        Some(CertificateFailure::RefusedByPeer),
        "{error}"
    );
    assert_eq!(tr.pins.rejections(), 1);
    assert!(!tr.link.status().connected());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_operator_is_refused_while_one_is_in_control_and_accepted_after() {
    let (a, b) = (
        Identity::generate(&["a"]).unwrap(),
        Identity::generate(&["b"]).unwrap(),
    );
    let tr = start(&[&a, &b]);
    let mut first = connect(&tr, &a).await.unwrap();
    assert!(matches!(
        first.hello("alice", PROTOCOL_VERSION).await,
        t2o::Message::Welcome(_)
    ));
    let mut second = connect(&tr, &b).await.unwrap();
    let answer = second.hello("bob", PROTOCOL_VERSION).await;
    let t2o::Message::Refused(refused) = answer else {
        panic!("{answer:?}")
    };
    // Named by its certificate (the server here has no file names for them).
    let alice = format!(
        "'alice' (certificate {})",
        transport::identity::fingerprint(&a.cert)
    );
    assert_eq!(
        refused.reason,
        Refusal::Busy {
            controlling_operator: alice
        }
    );
    second.conn.close(0u32.into(), b"ok");
    assert_eq!(tr.link.status().refused_busy(), 1);
    assert_eq!(tr.link.status().operator().as_deref(), Some("alice"));

    first.conn.close(0u32.into(), b"leaving");
    eventually(Duration::from_secs(5), || {
        (!tr.link.status().connected()).then_some(())
    })
    .await;
    let mut third = connect(&tr, &b).await.unwrap();
    assert!(matches!(
        third.hello("bob", PROTOCOL_VERSION).await,
        t2o::Message::Welcome(_)
    ));
    assert_eq!(tr.link.status().session(), 2);
    assert_eq!(tr.link.status().operator().as_deref(), Some("bob"));
}

/// An operator app that crashed and restarted (same certificate, old connection never closed)
/// takes its session over at once instead of being refused as busy until the idle timeout; a
/// different certificate is still refused.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_operator_in_control_connecting_again_replaces_its_old_connection() {
    let (a, b) = (
        Identity::generate(&["a"]).unwrap(),
        Identity::generate(&["b"]).unwrap(),
    );
    let tr = start(&[&a, &b]);
    let mut crashed = connect(&tr, &a).await.unwrap();
    assert!(matches!(
        crashed.hello("alice", PROTOCOL_VERSION).await,
        t2o::Message::Welcome(_)
    ));
    assert_eq!(tr.link.status().session(), 1);
    // The restarted app: same certificate, new endpoint; the old connection is still open.
    let mut restarted = connect(&tr, &a).await.unwrap();
    assert!(matches!(
        restarted.hello("alice", PROTOCOL_VERSION).await,
        t2o::Message::Welcome(_)
    ));
    let closed = crashed.conn.closed().await;
    let quinn::ConnectionError::ApplicationClosed(close) = &closed else {
        panic!("{closed:?}")
    };
    assert_eq!(close.error_code, CloseCode::Replaced.code());
    assert_eq!(tr.link.status().session(), 2);
    assert_eq!(tr.link.status().refused_busy(), 0);
    restarted.command(1, 0.25);
    let got = eventually(Duration::from_secs(5), || tr.link.next_command()).await;
    assert_eq!(got.message.position_m[0], 0.25);
    // Another operator is still refused while the restarted one is in control.
    let mut other = connect(&tr, &b).await.unwrap();
    let answer = other.hello("bob", PROTOCOL_VERSION).await;
    assert!(
        matches!(&answer, t2o::Message::Refused(r) if matches!(&r.reason, Refusal::Busy {
            controlling_operator
        } if controlling_operator.starts_with("'alice' (certificate sha256:"))),
        "{answer:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_hello_of_another_version_is_refused_naming_both_versions() {
    let op = Identity::generate(&["operator"]).unwrap();
    let tr = start(&[&op]);
    let mut raw = connect(&tr, &op).await.unwrap();
    let theirs = PROTOCOL_VERSION + 1;
    let answer = raw.hello("alice", theirs).await;
    let t2o::Message::Refused(refused) = answer else {
        panic!("{answer:?}")
    };
    assert_eq!(
        refused.reason,
        Refusal::VersionMismatch {
            ours: PROTOCOL_VERSION,
            theirs
        }
    );
    assert_eq!(
        refused.reason.to_string(),
        format!(
            "protocol version mismatch: telerobot speaks {PROTOCOL_VERSION}, operator speaks {theirs}"
        )
    );
    // The telerobot closes the connection with the reason once we have read it.
    let closed = raw.conn.closed().await;
    assert!(closed.to_string().contains("version mismatch"), "{closed}");
    assert_eq!(tr.link.status().refused_other(), 1);
    assert_eq!(tr.link.status().session(), 0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_datagrams_are_counted_and_ignored() {
    let op = Identity::generate(&["operator"]).unwrap();
    let tr = start(&[&op]);
    let mut raw = connect(&tr, &op).await.unwrap();
    raw.hello("alice", PROTOCOL_VERSION).await;
    raw.command(1, 1.0);
    eventually(Duration::from_secs(5), || tr.link.next_command()).await;

    let mut garbage: Vec<Vec<u8>> = Vec::new();
    // Pseudo-random bytes (fixed LCG), the version prefix then random, a truncated command,
    // a message of the other direction, a control message as a datagram.
    let mut x = 0x2545_f491_4f6c_dd1du64;
    for len in [1usize, 5, 17, 64, 300] {
        garbage.push(
            (0..len)
                .map(|_| {
                    x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                    (x >> 56) as u8
                })
                .collect(),
        );
    }
    garbage.push(vec![1, 0, 0xff, 0xff, 0xff]);
    let command = o2t::encode(&o2t::Message::Command(Command {
        header: Header {
            seq: 2,
            ..Header::default()
        },
        position_m: [2.0; 3],
        velocity_m_per_s: [0.0; 3],
    }));
    garbage.push(command[..command.len() - 3].to_vec());
    garbage.push(t2o::encode(&t2o::Message::Pong(
        protocol::telerobot_to_operator::Pong {
            id: 1,
            t1_ns: 2,
            t2_ns: 3,
            t3_ns: 4,
        },
    )));
    garbage.push(o2t::encode(&o2t::Message::Bye));
    let sent = garbage.len() as u64;
    for g in garbage {
        raw.conn.send_datagram(g.into()).unwrap();
    }
    raw.command(3, 3.0);
    let got = eventually(Duration::from_secs(5), || tr.link.next_command()).await;
    assert_eq!(got.message.position_m[0], 3.0, "the session goes on");
    let stats = eventually(Duration::from_secs(5), || {
        Some(tr.link.stats()).filter(|s| s.garbage == sent)
    })
    .await;
    assert_eq!((stats.accepted, stats.lost), (2, 1), "{stats:?}");
    assert!(tr.link.status().connected());
}
