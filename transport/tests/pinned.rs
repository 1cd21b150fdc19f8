//! The pinned configurations and the framing over real loopback QUIC.

#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::sync::Arc;

use transport::endpoint::{self, CertificateFailure, certificate_failure};
use transport::framing::{self, FrameError, MAX_CONTROL_FRAME_BYTES};
use transport::{Identity, LinkTuning, OperatorPins, SERVER_NAME, TelerobotPin};

struct Server {
    endpoint: quinn::Endpoint,
    pins: Arc<OperatorPins>,
    addr: SocketAddr,
}

fn server(identity: &Identity, trusted: &Identity) -> Server {
    let pins = OperatorPins::new(vec![trusted.cert.clone()]);
    let config =
        endpoint::server_config(identity, Arc::clone(&pins), &LinkTuning::default()).unwrap();
    let endpoint = quinn::Endpoint::server(config, "127.0.0.1:0".parse().unwrap()).unwrap();
    let addr = endpoint.local_addr().unwrap();
    Server {
        endpoint,
        pins,
        addr,
    }
}

fn client(identity: &Identity, pinned: &Identity) -> (quinn::Endpoint, Arc<TelerobotPin>) {
    let pin = TelerobotPin::new(pinned.cert.clone(), "telerobot.crt");
    let config =
        endpoint::client_config(identity, Arc::clone(&pin), &LinkTuning::default(), 4).unwrap();
    let mut endpoint = quinn::Endpoint::client("127.0.0.1:0".parse().unwrap()).unwrap();
    endpoint.set_default_client_config(config);
    (endpoint, pin)
}

/// Connects and makes the server accept; returns the client's view of the outcome.
async fn attempt(
    server: &Server,
    client: &quinn::Endpoint,
) -> (
    Result<(), quinn::ConnectionError>,
    Result<(), quinn::ConnectionError>,
) {
    let accept = async {
        let incoming = server.endpoint.accept().await.unwrap();
        let conn = incoming.await?;
        let (_send, mut recv) = conn.accept_bi().await?;
        let mut buf = Vec::new();
        framing::read_frame(&mut recv, &mut buf).await.unwrap();
        assert_eq!(buf, b"hello");
        Ok(())
    };
    let connect = async {
        let conn = client.connect(server.addr, SERVER_NAME).unwrap().await?;
        let (mut send, _recv) = conn.open_bi().await?;
        if let Err(FrameError::Write(quinn::WriteError::ConnectionLost(e))) =
            framing::write_frame(&mut send, b"hello").await
        {
            return Err(e);
        }
        // A refused certificate only shows once the server has answered.
        Err(conn.closed().await)
    };
    tokio::join!(accept, connect)
}

#[tokio::test]
async fn trusted_peers_connect_and_frames_arrive() {
    let (tr, op) = (
        Identity::generate(&["telerobot"]).unwrap(),
        Identity::generate(&["operator"]).unwrap(),
    );
    let server = server(&tr, &op);
    let (client, _) = client(&op, &tr);
    let server_side = async {
        let conn = server.endpoint.accept().await.unwrap().await.unwrap();
        let (mut send, mut recv) = conn.accept_bi().await.unwrap();
        let mut buf = Vec::new();
        framing::read_frame(&mut recv, &mut buf).await.unwrap();
        framing::write_frame(&mut send, &buf).await.unwrap();
        let mut uni = conn.open_uni().await.unwrap();
        framing::write_cloud(&mut uni, &[7u8; 100_000])
            .await
            .unwrap();
        conn.closed().await
    };
    let client_side = async {
        let conn = client
            .connect(server.addr, SERVER_NAME)
            .unwrap()
            .await
            .unwrap();
        assert_eq!(
            conn.handshake_data()
                .unwrap()
                .downcast::<quinn::crypto::rustls::HandshakeData>()
                .unwrap()
                .protocol
                .unwrap(),
            transport::ALPN
        );
        let (mut send, mut recv) = conn.open_bi().await.unwrap();
        framing::write_frame(&mut send, b"ping").await.unwrap();
        let mut buf = Vec::new();
        framing::read_frame(&mut recv, &mut buf).await.unwrap();
        assert_eq!(buf, b"ping");
        let mut uni = conn.accept_uni().await.unwrap();
        assert_eq!(
            framing::read_cloud(&mut uni).await.unwrap(),
            vec![7u8; 100_000]
        );
        let too_long = vec![0u8; MAX_CONTROL_FRAME_BYTES as usize + 1];
        assert!(matches!(
            framing::write_frame(&mut send, &too_long).await,
            Err(FrameError::TooLong { .. })
        ));
        conn.close(0u32.into(), b"done");
    };
    let (_, ()) = tokio::join!(server_side, client_side);
}

#[tokio::test]
async fn an_untrusted_client_certificate_is_refused_by_the_server() {
    let (tr, op, stranger) = (
        Identity::generate(&["telerobot"]).unwrap(),
        Identity::generate(&["operator"]).unwrap(),
        Identity::generate(&["stranger"]).unwrap(),
    );
    let server = server(&tr, &op);
    let (client, pin) = client(&stranger, &tr);
    let (accepted, connected) = attempt(&server, &client).await;
    let server_error = accepted.unwrap_err();
    assert_eq!(
        certificate_failure(&server_error),
        Some(CertificateFailure::RefusedByUs),
        "{server_error}"
    );
    let client_error = connected.unwrap_err();
    assert_eq!(
        certificate_failure(&client_error),
        Some(CertificateFailure::RefusedByPeer),
        "{client_error}"
    );
    assert!(endpoint::describe_close(&client_error).contains("not in its trusted set"));
    assert_eq!((server.pins.rejections(), pin.rejections()), (1, 0));
}

#[tokio::test]
async fn a_server_certificate_other_than_the_pinned_one_is_refused_by_the_client() {
    let (tr, op, impostor) = (
        Identity::generate(&["telerobot"]).unwrap(),
        Identity::generate(&["operator"]).unwrap(),
        Identity::generate(&["telerobot"]).unwrap(),
    );
    let server = server(&impostor, &op);
    let (client, pin) = client(&op, &tr);
    let connect = client.connect(server.addr, SERVER_NAME).unwrap();
    let accept = async { server.endpoint.accept().await.unwrap().await };
    let (accepted, connected) = tokio::join!(accept, connect);
    let client_error = connected.unwrap_err();
    assert_eq!(
        certificate_failure(&client_error),
        Some(CertificateFailure::RefusedByUs),
        "{client_error}"
    );
    assert!(accepted.is_err());
    assert_eq!((server.pins.rejections(), pin.rejections()), (0, 1));
}
