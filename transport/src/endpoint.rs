//! quinn endpoint configurations for the two roles, the ALPN, the application close codes, and
//! what a failed connection means in words.

use std::sync::Arc;

use quinn::crypto::rustls::{QuicClientConfig, QuicServerConfig};
use quinn::{ConnectionError, TransportErrorCode, VarInt};
use rustls::client::Resumption;
use rustls::server::NoServerSessionStorage;

use crate::identity::Identity;
use crate::pin::{OperatorPins, TelerobotPin, provider};
use crate::tuning::{LinkTuning, StreamLimits, TuningError};

/// Version of the transport layout: ALPN, stream roles, control-stream framing
/// ([`crate::framing`]). It changes only when that layout does.
///
/// The message version ([`protocol::PROTOCOL_VERSION`]) is deliberately **not** in the ALPN: two
/// builds with different message versions must still complete the TLS handshake, so that the
/// telerobot can answer the `Hello` with `Refused { VersionMismatch }` naming both versions. With
/// the message version in the ALPN they would fail with a bare `no_application_protocol` alert.
pub const FRAMING_VERSION: u16 = 1;

/// The ALPN protocol both sides offer: `mmt-teleop/<FRAMING_VERSION>`.
pub const ALPN: &[u8] = b"mmt-teleop/1";

/// The TLS server name the operator sends. Not checked by the pinned verifier (the certificate
/// is compared whole); it only has to be a valid name.
pub const SERVER_NAME: &str = "telerobot";

/// Application close codes (QUIC `CONNECTION_CLOSE` of type application), with a reason text.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CloseCode {
    /// The session ended normally (`Bye`, or the operator app stopping).
    Normal,
    /// The telerobot refused the session (busy, version mismatch, bad first message); the
    /// `Refused` message on the control stream says why.
    Refused,
    /// The side closing is shutting down.
    Shutdown,
    /// The peer broke the control-stream protocol (oversized frame, unexpected message).
    ProtocolViolation,
    /// A newer connection with the same certificate took the session over (the operator app
    /// restarted before the telerobot noticed the old connection was gone).
    Replaced,
}

impl CloseCode {
    /// The wire value.
    pub fn code(self) -> VarInt {
        VarInt::from_u32(match self {
            CloseCode::Normal => 0,
            CloseCode::Refused => 1,
            CloseCode::Shutdown => 2,
            CloseCode::ProtocolViolation => 3,
            CloseCode::Replaced => 4,
        })
    }

    /// The code for a wire value, if it is one of ours.
    pub fn from_code(code: VarInt) -> Option<CloseCode> {
        [
            CloseCode::Normal,
            CloseCode::Refused,
            CloseCode::Shutdown,
            CloseCode::ProtocolViolation,
            CloseCode::Replaced,
        ]
        .into_iter()
        .find(|c| c.code() == code)
    }
}

/// Why an endpoint configuration could not be built.
#[derive(Debug, thiserror::Error)]
pub enum EndpointError {
    /// rustls refused the certificate, the key or the protocol versions.
    #[error("TLS configuration: {0}")]
    Tls(#[from] rustls::Error),
    /// The TLS configuration has no cipher suite QUIC can start with.
    #[error("TLS configuration unusable for QUIC: {0}")]
    Quic(#[from] quinn::crypto::rustls::NoInitialCipherSuite),
    /// A tuning value is out of range.
    #[error(transparent)]
    Tuning(#[from] TuningError),
}

/// The telerobot's server configuration: presents `identity`, requires a client certificate in
/// `pins`, TLS 1.3 only, no session resumption, no 0-RTT; the operator may open one control
/// stream and no unidirectional stream.
pub fn server_config(
    identity: &Identity,
    pins: Arc<OperatorPins>,
    tuning: &LinkTuning,
) -> Result<quinn::ServerConfig, EndpointError> {
    let mut tls = rustls::ServerConfig::builder_with_provider(provider())
        .with_protocol_versions(&[&rustls::version::TLS13])?
        .with_client_cert_verifier(pins)
        .with_single_cert(vec![identity.cert.clone()], identity.private_key())?;
    tls.alpn_protocols = vec![ALPN.to_vec()];
    tls.max_early_data_size = 0;
    tls.send_tls13_tickets = 0;
    tls.session_storage = Arc::new(NoServerSessionStorage {});
    let crypto = QuicServerConfig::try_from(tls)?;
    let mut config = quinn::ServerConfig::with_crypto(Arc::new(crypto));
    config.transport_config(Arc::new(tuning.transport_config(StreamLimits {
        peer_bidi: 1,
        peer_uni: 0,
    })?));
    Ok(config)
}

/// The operator's client configuration: presents `identity`, accepts only the pinned telerobot
/// certificate, TLS 1.3 only, no resumption, no early data; the telerobot may have
/// `max_cloud_streams` cloud streams open at once and no bidirectional stream.
pub fn client_config(
    identity: &Identity,
    pin: Arc<TelerobotPin>,
    tuning: &LinkTuning,
    max_cloud_streams: u32,
) -> Result<quinn::ClientConfig, EndpointError> {
    let mut tls = rustls::ClientConfig::builder_with_provider(provider())
        .with_protocol_versions(&[&rustls::version::TLS13])?
        .dangerous()
        .with_custom_certificate_verifier(pin)
        .with_client_auth_cert(vec![identity.cert.clone()], identity.private_key())?;
    tls.alpn_protocols = vec![ALPN.to_vec()];
    tls.enable_early_data = false;
    tls.resumption = Resumption::disabled();
    let crypto = QuicClientConfig::try_from(tls)?;
    let mut config = quinn::ClientConfig::new(Arc::new(crypto));
    config.transport_config(Arc::new(tuning.transport_config(StreamLimits {
        peer_bidi: 0,
        peer_uni: max_cloud_streams,
    })?));
    Ok(config)
}

/// TLS alert `access_denied` (RFC 8446 §6.2): what the pinned verifiers send for a certificate
/// outside their set.
const ACCESS_DENIED: u8 = 49;

/// What a certificate-related connection failure means.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CertificateFailure {
    /// The peer refused **our** certificate (it closed with `access_denied`).
    RefusedByPeer,
    /// **We** refused the peer's certificate (our verifier failed the handshake).
    RefusedByUs,
}

/// Whether `error` is a pinned-certificate refusal, and by whom.
pub fn certificate_failure(error: &ConnectionError) -> Option<CertificateFailure> {
    let denied = TransportErrorCode::crypto(ACCESS_DENIED);
    match error {
        ConnectionError::ConnectionClosed(close) if close.error_code == denied => {
            Some(CertificateFailure::RefusedByPeer)
        }
        ConnectionError::TransportError(e) if e.code == denied => {
            Some(CertificateFailure::RefusedByUs)
        }
        _ => None,
    }
}

/// A one-line description of why a connection ended, for logs: our close codes by name,
/// certificate refusals in words, anything else as quinn says it.
pub fn describe_close(error: &ConnectionError) -> String {
    match (certificate_failure(error), error) {
        (Some(CertificateFailure::RefusedByPeer), _) => {
            "the peer refused our certificate (not in its trusted set)".to_owned()
        }
        (Some(CertificateFailure::RefusedByUs), _) => {
            "we refused the peer's certificate (not pinned / not trusted)".to_owned()
        }
        (None, ConnectionError::ApplicationClosed(close)) => {
            let reason = String::from_utf8_lossy(&close.reason);
            match CloseCode::from_code(close.error_code) {
                Some(code) => format!("closed by peer ({code:?}): {reason}"),
                None => format!("closed by peer (code {}): {reason}", close.error_code),
            }
        }
        (None, ConnectionError::TimedOut) => "timed out (idle: nothing heard from the peer)".into(),
        (None, other) => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_alpn_names_the_framing_version() {
        assert_eq!(ALPN, format!("mmt-teleop/{FRAMING_VERSION}").as_bytes());
    }

    #[test]
    fn close_codes_round_trip() {
        for c in [
            CloseCode::Normal,
            CloseCode::Refused,
            CloseCode::Shutdown,
            CloseCode::ProtocolViolation,
            CloseCode::Replaced,
        ] {
            assert_eq!(CloseCode::from_code(c.code()), Some(c));
        }
        assert_eq!(CloseCode::from_code(VarInt::from_u32(99)), None);
    }
}
