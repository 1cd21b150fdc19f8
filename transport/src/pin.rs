//! Both sides pinned: TLS 1.3 configurations (rustls, ring provider) that accept exactly the
//! peer certificates they were given.
//!
//! - The **telerobot** (server) requires a client certificate and accepts it only if its DER is
//!   byte-for-byte one of the trusted operator certificates ([`OperatorPins`]).
//! - The **operator** (client) accepts the server only if its end-entity certificate is
//!   byte-for-byte the pinned telerobot certificate ([`TelerobotPin`]); the server name is not
//!   checked (the pin is stronger than any name).
//!
//! There is no CA and no chain building: the certificates are self-signed ([`crate::Identity`]).
//! The handshake signatures are still verified with the ring provider's algorithms, so a peer
//! that presents a trusted certificate without holding its private key fails.
//!
//! A rejection is counted (`rejections()`), so that the side that refused and the side that was
//! refused can say why in words ([`crate::endpoint`] maps the TLS alerts).

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use rustls::client::danger::{HandshakeSignatureValid, ServerCertVerified, ServerCertVerifier};
use rustls::crypto::{CryptoProvider, WebPkiSupportedAlgorithms};
use rustls::server::danger::{ClientCertVerified, ClientCertVerifier};
use rustls::{CertificateError, DigitallySignedStruct, DistinguishedName, SignatureScheme};
use rustls_pki_types::{CertificateDer, ServerName, UnixTime};

/// The ring crypto provider, the only one in the dependency tree (no aws-lc-rs).
pub fn provider() -> Arc<CryptoProvider> {
    Arc::new(rustls::crypto::ring::default_provider())
}

/// The handshake-signature methods both verifier traits have, checked with the ring provider's
/// algorithms (`self.algorithms`): pinning replaces chain validation, not proof of the key.
macro_rules! signature_checks {
    () => {
        fn verify_tls12_signature(
            &self,
            message: &[u8],
            cert: &CertificateDer<'_>,
            dss: &DigitallySignedStruct,
        ) -> Result<HandshakeSignatureValid, rustls::Error> {
            rustls::crypto::verify_tls12_signature(message, cert, dss, &self.algorithms)
        }

        fn verify_tls13_signature(
            &self,
            message: &[u8],
            cert: &CertificateDer<'_>,
            dss: &DigitallySignedStruct,
        ) -> Result<HandshakeSignatureValid, rustls::Error> {
            rustls::crypto::verify_tls13_signature(message, cert, dss, &self.algorithms)
        }

        fn supported_verify_schemes(&self) -> Vec<SignatureScheme> {
            self.algorithms.supported_schemes()
        }
    };
}

/// The operator certificates a telerobot trusts, compared by exact DER.
#[derive(Debug)]
pub struct OperatorPins {
    trusted: Vec<CertificateDer<'static>>,
    algorithms: WebPkiSupportedAlgorithms,
    rejections: AtomicU64,
}

impl OperatorPins {
    /// Trusts exactly `trusted`.
    pub fn new(trusted: Vec<CertificateDer<'static>>) -> Arc<OperatorPins> {
        Arc::new(OperatorPins {
            trusted,
            algorithms: provider().signature_verification_algorithms,
            rejections: AtomicU64::new(0),
        })
    }

    /// How many client certificates were refused since start.
    pub fn rejections(&self) -> u64 {
        self.rejections.load(Relaxed)
    }
}

impl ClientCertVerifier for OperatorPins {
    fn client_auth_mandatory(&self) -> bool {
        true
    }

    fn root_hint_subjects(&self) -> &[DistinguishedName] {
        &[]
    }

    fn verify_client_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _now: UnixTime,
    ) -> Result<ClientCertVerified, rustls::Error> {
        if self
            .trusted
            .iter()
            .any(|t| t.as_ref() == end_entity.as_ref())
        {
            Ok(ClientCertVerified::assertion())
        } else {
            self.rejections.fetch_add(1, Relaxed);
            // Sent to the operator as the `access_denied` alert, which it reports as "not in
            // the telerobot's trusted set".
            Err(rustls::Error::InvalidCertificate(
                CertificateError::ApplicationVerificationFailure,
            ))
        }
    }

    signature_checks!();
}

/// The one telerobot certificate an operator accepts, compared by exact DER.
pub struct TelerobotPin {
    pinned: CertificateDer<'static>,
    /// Where the pin came from (a file path), for the error message.
    source: String,
    algorithms: WebPkiSupportedAlgorithms,
    rejections: AtomicU64,
}

impl fmt::Debug for TelerobotPin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TelerobotPin")
            .field("source", &self.source)
            .field("rejections", &self.rejections)
            .finish_non_exhaustive()
    }
}

impl TelerobotPin {
    /// Accepts exactly `pinned`; `source` says where it came from (e.g. the file name).
    pub fn new(pinned: CertificateDer<'static>, source: impl Into<String>) -> Arc<TelerobotPin> {
        Arc::new(TelerobotPin {
            pinned,
            source: source.into(),
            algorithms: provider().signature_verification_algorithms,
            rejections: AtomicU64::new(0),
        })
    }

    /// Where the pinned certificate came from.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// How many server certificates were refused since start.
    pub fn rejections(&self) -> u64 {
        self.rejections.load(Relaxed)
    }
}

impl ServerCertVerifier for TelerobotPin {
    fn verify_server_cert(
        &self,
        end_entity: &CertificateDer<'_>,
        _intermediates: &[CertificateDer<'_>],
        _server_name: &ServerName<'_>,
        _ocsp_response: &[u8],
        _now: UnixTime,
    ) -> Result<ServerCertVerified, rustls::Error> {
        pinned(
            std::slice::from_ref(&self.pinned),
            end_entity,
            &self.rejections,
        )
        .map(|()| ServerCertVerified::assertion())
    }

    signature_checks!();
}

/// Whether `end_entity` is byte-for-byte one of `accepted`; a refusal is counted and becomes the
/// `access_denied` alert, which the refused side reports as "not in its trusted set"
/// ([`crate::endpoint::certificate_failure`]).
fn pinned(
    accepted: &[CertificateDer<'static>],
    end_entity: &CertificateDer<'_>,
    rejections: &AtomicU64,
) -> Result<(), rustls::Error> {
    if accepted.iter().any(|a| a.as_ref() == end_entity.as_ref()) {
        Ok(())
    } else {
        rejections.fetch_add(1, Relaxed);
        Err(rustls::Error::InvalidCertificate(
            CertificateError::ApplicationVerificationFailure,
        ))
    }
}
