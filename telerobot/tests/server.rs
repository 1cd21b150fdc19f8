//! `telerobot::net::serve` over loopback QUIC, driven by a hand-made operator (so that the tests
//! can send what a correct operator never would: another version, garbage datagrams).

#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use protocol::operator_to_telerobot::{self as o2t, Command, Hello, Ping};
use protocol::telerobot_to_operator::Datagram;
use protocol::telerobot_to_operator::{
    self as t2o, Contact, ContactState, ModelStructure, Refusal, SceneSummary,
};
use protocol::{Header, PROTOCOL_VERSION};
use rt::monotonic_ns;
use telerobot::net::{self, NetConfig, TelerobotLink};
use tokio::sync::oneshot;
use transport::endpoint::{CertificateFailure, certificate_failure};
use transport::framing;
use transport::{CloseCode, Identity, LinkTuning, SERVER_NAME, TelerobotPin};

fn scene() -> SceneSummary {
    SceneSummary {
        name: "wall".into(),
        normal: ModelStructure::KelvinVoigt,
        tangential: ModelStructure::Free,
        control_rate_hz: 1000.0,
        cloud_rate_hz: None,
        left_out: vec![],
        proxy_radii_m: [0.004, 0.006, 0.03],
    }
}

/// A running server; stops when dropped.
struct Telerobot {
    addr: SocketAddr,
    link: TelerobotLink,
    identity: Identity,
    _stop: oneshot::Sender<()>,
    pins: Arc<transport::OperatorPins>,
}

fn start(trusted: &[&Identity]) -> Telerobot {
    let identity = Identity::generate(&["telerobot"]).unwrap();
    let mut config = NetConfig::new(
        "127.0.0.1:0".parse().unwrap(),
        identity.clone(),
        trusted.iter().map(|i| i.cert.clone()).collect(),
        scene(),
    );
    config.refusal_linger = Duration::from_millis(500);
    let (link, io) = net::link(net::DEFAULT_OUTBOX_CAPACITY).unwrap();
    let server = net::bind(config).unwrap();
    let (addr, pins) = (server.local_addr().unwrap(), server.pins());
    let (stop, stopped) = oneshot::channel::<()>();
    tokio::spawn(server.serve(io, async {
        let _ = stopped.await;
    }));
    Telerobot {
        addr,
        link,
        identity,
        _stop: stop,
        pins,
    }
}

/// A hand-made operator connection with its control stream.
struct RawOperator {
    conn: quinn::Connection,
    send: quinn::SendStream,
    recv: quinn::RecvStream,
    _endpoint: quinn::Endpoint,
}

async fn connect(
    telerobot: &Telerobot,
    me: &Identity,
) -> Result<RawOperator, quinn::ConnectionError> {
    let pin = TelerobotPin::new(telerobot.identity.cert.clone(), "telerobot.crt");
    let config = transport::endpoint::client_config(me, pin, &LinkTuning::default(), 4).unwrap();
    let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).unwrap();
    endpoint.set_default_client_config(config);
    let conn = endpoint
        .connect(telerobot.addr, SERVER_NAME)
        .unwrap()
        .await?;
    let (send, recv) = conn.open_bi().await?;
    Ok(RawOperator {
        conn,
        send,
        recv,
        _endpoint: endpoint,
    })
}

impl RawOperator {
    /// Sends a Hello of `version` and returns the telerobot's answer.
    async fn hello(&mut self, name: &str, version: u16) -> t2o::Message {
        let hello = o2t::Message::Hello(Hello {
            version,
            operator_name: name.into(),
            want_clouds: false,
        });
        framing::write_frame(&mut self.send, &o2t::encode(&hello))
            .await
            .unwrap();
        let mut buf = Vec::new();
        framing::read_frame(&mut self.recv, &mut buf).await.unwrap();
        t2o::decode(&buf).unwrap()
    }

    fn datagram(&self, message: &o2t::Message) {
        self.conn
            .send_datagram(o2t::encode(message).into())
            .unwrap();
    }

    fn command(&self, seq: u64, x: f64) {
        self.datagram(&o2t::Message::Command(Command {
            header: Header {
                seq,
                sample_time_ns: monotonic_ns(),
                send_time_ns: monotonic_ns(),
                ..Header::default()
            },
            position_m: [x, 0.0, 0.0],
            velocity_m_per_s: [0.0; 3],
        }));
    }

    /// Waits for the next datagram that decodes.
    async fn next_datagram(&self) -> t2o::Message {
        loop {
            let bytes = self.conn.read_datagram().await.unwrap();
            if let Ok(m) = t2o::decode(&bytes) {
                return m;
            }
        }
    }
}

/// Polls `f` every 5 ms until it gives a value (panics after 5 s).
async fn eventually<T>(mut f: impl FnMut() -> Option<T>) -> T {
    for _ in 0..1000 {
        if let Some(v) = f() {
            return v;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    }
    panic!("condition not met within 5 s")
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
        (PROTOCOL_VERSION, scene())
    );
    assert!(tr.link.status().connected());
    assert_eq!(tr.link.status().operator().as_deref(), Some("alice"));

    raw.command(1, 0.25);
    let got = eventually(|| tr.link.next_command()).await;
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
    eventually(|| (!tr.link.status().connected()).then_some(())).await;
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
    assert_eq!(
        refused.reason,
        Refusal::Busy {
            controlling_operator: "alice".into()
        }
    );
    second.conn.close(0u32.into(), b"ok");
    assert_eq!(tr.link.status().refused_busy(), 1);
    assert_eq!(tr.link.status().operator().as_deref(), Some("alice"));

    first.conn.close(0u32.into(), b"leaving");
    eventually(|| (!tr.link.status().connected()).then_some(())).await;
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
    let got = eventually(|| tr.link.next_command()).await;
    assert_eq!(got.message.position_m[0], 0.25);
    // Another operator is still refused while the restarted one is in control.
    let mut other = connect(&tr, &b).await.unwrap();
    let answer = other.hello("bob", PROTOCOL_VERSION).await;
    assert!(
        matches!(&answer, t2o::Message::Refused(r) if r.reason == Refusal::Busy {
            controlling_operator: "alice".into()
        }),
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
    eventually(|| tr.link.next_command()).await;

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
    let got = eventually(|| tr.link.next_command()).await;
    assert_eq!(got.message.position_m[0], 3.0, "the session goes on");
    let stats = eventually(|| Some(tr.link.stats()).filter(|s| s.garbage == sent)).await;
    assert_eq!((stats.accepted, stats.lost), (2, 1), "{stats:?}");
    assert!(tr.link.status().connected());
}
