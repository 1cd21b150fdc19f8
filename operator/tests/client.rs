//! `operator::net::connect_and_run` against `telerobot::net::serve` (and against a hand-made
//! telerobot where the test needs one that misbehaves), over loopback QUIC without delay.

#![allow(clippy::unwrap_used)]

use std::time::Duration;

use operator::net::NetError;
use protocol::Header;
use protocol::operator_to_telerobot as o2t;
use protocol::telerobot_to_operator::Datagram;
use protocol::telerobot_to_operator::{self as t2o, CloudFrame, Measurement, Welcome};
use testkit::net::*;
use testkit::*;
use transport::framing;
use transport::{Identity, OperatorPins};

const WAIT: Duration = Duration::from_secs(5);

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_session_carries_commands_state_clouds_and_clock_both_ways() {
    let certs = Certs::new();
    let tr = TelerobotServer::start(
        &certs.telerobot,
        "127.0.0.1:0".parse().unwrap(),
        &[&certs.operator],
    );
    let op = OperatorClient::start(tr.addr, &certs.operator, &certs.telerobot, "alice");
    eventually(WAIT, || op.link.status().connected().then_some(())).await;
    let welcome = op.link.status().welcome().unwrap();
    assert_eq!(welcome.scene, wall_summary());
    assert_eq!(tr.link.status().operator().as_deref(), Some("alice"));

    // Operator → telerobot: a command reaches the loop's slot.
    op.link.send_command(command(0.5));
    let got = eventually(WAIT, || tr.link.next_command()).await;
    assert_eq!(got.message.position_m[0], 0.5);

    // Telerobot → operator: contact into its slot, measurements queued, a cloud on a stream.
    tr.link.send(Datagram::Contact(contact(
        got.message.header.sample_time_ns,
    )));
    let c = eventually(WAIT, || op.link.contact()).await;
    assert_eq!(
        c.message.command_sample_time_ns,
        got.message.header.sample_time_ns
    );
    for i in 0..3 {
        tr.link.send(Datagram::Measurement(Measurement {
            header: Header::default(),
            command_sample_time_ns: i,
            position_m: [0.0; 3],
            velocity_m_per_s: [0.0; 3],
            force_on_tool_n: [0.0, 0.0, i as f64],
            in_contact: false,
            estimator_stable: false,
            reconstruction: None,
        }));
    }
    for i in 0..3 {
        let m = eventually(WAIT, || op.link.measurement()).await;
        assert_eq!(
            m.message.command_sample_time_ns, i,
            "queued in order, not collapsed"
        );
    }
    tr.link.send_cloud(Box::new(CloudFrame {
        frame_id: 9,
        timestamp_ns: 1,
        sensor_position_m: [0.0; 3],
        sensor_orientation_xyzw: [0.0, 0.0, 0.0, 1.0],
        points: vec![[0.5, 0.25, 0.0]; 10_000],
    }));
    let cloud = eventually(WAIT, || op.link.cloud()).await;
    assert_eq!(
        (cloud.message.frame_id, cloud.message.points.len()),
        (9, 10_000)
    );

    // Pings give a clock offset (same clock here: about zero) and echoes an RTT.
    let stats = eventually(WAIT, || {
        Some(op.link.stats()).filter(|s| s.clock_offset_ns.is_some() && s.rtt_latest_ns.is_some())
    })
    .await;
    assert!(stats.clock_offset_ns.unwrap().abs() < 5 * MS, "{stats:?}");
    assert_eq!(stats.garbage, 0);

    op.stop().await.unwrap();
    eventually(WAIT, || (!tr.link.status().connected()).then_some(())).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_telerobot_with_another_certificate_is_refused_naming_the_pinned_file() {
    let certs = Certs::new();
    let impostor = Certs {
        telerobot: Identity::generate(&["telerobot"]).unwrap(),
        operator: certs.operator.clone(),
    };
    let tr = TelerobotServer::start(
        &impostor.telerobot,
        "127.0.0.1:0".parse().unwrap(),
        &[&certs.operator],
    );
    let op = OperatorClient::start(tr.addr, &certs.operator, &certs.telerobot, "alice");
    let error = op.task.await.unwrap().unwrap_err();
    assert!(matches!(error, NetError::PinMismatch { .. }), "{error:?}");
    assert_eq!(
        error.to_string(),
        "the telerobot's certificate does not match the pinned certificate certs/telerobot.crt"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_operator_the_telerobot_does_not_trust_is_told_so() {
    let certs = Certs::new();
    let stranger = Identity::generate(&["stranger"]).unwrap();
    let tr = TelerobotServer::start(
        &certs.telerobot,
        "127.0.0.1:0".parse().unwrap(),
        &[&certs.operator],
    );
    let op = OperatorClient::start(tr.addr, &stranger, &certs.telerobot, "mallory");
    let error = op.task.await.unwrap().unwrap_err();
    assert!(matches!(error, NetError::NotTrusted), "{error:?}");
    assert_eq!(
        error.to_string(),
        "the telerobot refused our certificate: not in its trusted set"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_second_operator_gets_busy_and_the_first_one_stays_in_control() {
    let certs = Certs::new();
    let bob = Identity::generate(&["bob"]).unwrap();
    let tr = TelerobotServer::start(
        &certs.telerobot,
        "127.0.0.1:0".parse().unwrap(),
        &[&certs.operator, &bob],
    );
    let alice = OperatorClient::start(tr.addr, &certs.operator, &certs.telerobot, "alice");
    eventually(WAIT, || alice.link.status().connected().then_some(())).await;
    // `--no-wait`: the refusal ends the client.
    let second = OperatorClient::start_with(tr.addr, &bob, &certs.telerobot, "bob", |c| {
        c.wait_when_busy = false;
    });
    let error = second.task.await.unwrap().unwrap_err().to_string();
    // The operator in control is named by its certificate (the name is self-chosen).
    let fingerprint = transport::identity::fingerprint(&certs.operator.cert);
    assert_eq!(
        error,
        format!(
            "the telerobot refused the session: telerobot is busy: 'alice' (certificate \
             {fingerprint}) is in control"
        )
    );
    assert!(alice.link.status().connected());
    alice.link.send_command(command(1.0));
    eventually(WAIT, || tr.link.next_command()).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_operator_reconnects_when_the_telerobot_comes_back() {
    let certs = Certs::new();
    let tr = TelerobotServer::start(
        &certs.telerobot,
        "127.0.0.1:0".parse().unwrap(),
        &[&certs.operator],
    );
    let addr = tr.addr;
    let op = OperatorClient::start(addr, &certs.operator, &certs.telerobot, "alice");
    eventually(WAIT, || op.link.status().connected().then_some(())).await;
    tr.stop().await;
    eventually(WAIT, || (!op.link.status().connected()).then_some(())).await;
    assert!(
        op.link
            .status()
            .last_disconnect()
            .unwrap()
            .contains("shutting down")
    );

    let tr = TelerobotServer::restart(&certs.telerobot, addr, &[&certs.operator]).await;
    eventually(Duration::from_secs(10), || {
        (op.link.status().session() == 2 && op.link.status().connected()).then_some(())
    })
    .await;
    op.link.send_command(command(2.0));
    let got = eventually(WAIT, || tr.link.next_command()).await;
    assert_eq!((got.message.position_m[0], got.session), (2.0, 1));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn garbage_datagrams_from_the_telerobot_are_counted_and_ignored() {
    let certs = Certs::new();
    // A hand-made telerobot: welcomes, then sends garbage around two valid datagrams.
    let pins = OperatorPins::new(vec![certs.operator.cert.clone()]);
    let config =
        transport::endpoint::server_config(&certs.telerobot, pins, &tuning(400.0)).unwrap();
    let endpoint = quinn::Endpoint::server(config, "127.0.0.1:0".parse().unwrap()).unwrap();
    let op = OperatorClient::start(
        endpoint.local_addr().unwrap(),
        &certs.operator,
        &certs.telerobot,
        "alice",
    );
    let conn = endpoint.accept().await.unwrap().await.unwrap();
    let (mut send, mut recv) = conn.accept_bi().await.unwrap();
    let mut hello = Vec::new();
    framing::read_frame(&mut recv, &mut hello).await.unwrap();
    let welcome = t2o::Message::Welcome(Welcome {
        version: protocol::PROTOCOL_VERSION,
        scene: wall_summary(),
    });
    framing::write_frame(&mut send, &t2o::encode(&welcome))
        .await
        .unwrap();

    let mut valid = contact(0);
    valid.header.seq = 1;
    let valid = t2o::encode(&t2o::Message::Contact(valid));
    let garbage: Vec<Vec<u8>> = vec![
        vec![0xde, 0xad, 0xbe, 0xef, 0x01],
        vec![1],
        valid[..valid.len() - 2].to_vec(),
        o2t::encode(&o2t::Message::Command(command(1.0))),
        t2o::encode(&welcome),
    ];
    for g in &garbage {
        conn.send_datagram(g.clone().into()).unwrap();
    }
    conn.send_datagram(valid.into()).unwrap();
    let c = eventually(WAIT, || op.link.contact()).await;
    assert_eq!(c.message.header.seq, 1);
    eventually(WAIT, || {
        (op.link.stats().garbage == garbage.len() as u64).then_some(())
    })
    .await;
    assert!(op.link.status().connected());
}
