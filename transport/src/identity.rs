//! Who an endpoint is: a self-signed certificate and its private key, made with `rcgen`, kept as
//! PEM files (`DIR/<name>.crt`, `DIR/<name>.key`), and the certificates an endpoint pins.
//!
//! The certificates are self-signed and never checked against a CA: each side is told exactly
//! which certificate its peer must present ([`crate::pin`]). Names in the certificate (DNS or IP
//! subject alternative names) are informational only.

use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};

use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer, PrivatePkcs8KeyDer};
use thiserror::Error;

/// Why an identity or a pinned certificate could not be made, written or read. Every variant
/// names the file and what was wrong with it.
#[derive(Debug, Error)]
pub enum IdentityError {
    /// `rcgen` refused to make the certificate (e.g. a name that is not a valid DNS name).
    #[error("cannot generate a certificate for {names:?}: {source}")]
    Generate {
        /// The subject alternative names asked for.
        names: Vec<String>,
        /// `rcgen`'s reason.
        source: rcgen::Error,
    },
    /// A file or directory could not be created or read.
    #[error("{what} {}: {error}", path.display())]
    Io {
        /// What was being done, e.g. "cannot write the private key".
        what: &'static str,
        /// The file or directory.
        path: PathBuf,
        /// The operating system's reason.
        error: std::io::Error,
    },
    /// The file is there but holds no usable PEM object of the expected kind.
    #[error("{} is not a {expected} in PEM form: {detail}", path.display())]
    Pem {
        /// The file.
        path: PathBuf,
        /// What it should hold, e.g. "certificate" or "PKCS#8 private key".
        expected: &'static str,
        /// What the PEM parser said.
        detail: String,
    },
    /// The file would be overwritten; `gen-cert` never replaces an identity silently.
    #[error("{} already exists: remove it first to make a new identity", path.display())]
    Exists {
        /// The file.
        path: PathBuf,
    },
}

/// A certificate and its private key: what an endpoint presents in the TLS handshake.
#[derive(Debug)]
pub struct Identity {
    /// The self-signed certificate (DER).
    pub cert: CertificateDer<'static>,
    /// Its private key (PKCS#8 DER).
    pub key: PrivatePkcs8KeyDer<'static>,
}

impl Clone for Identity {
    fn clone(&self) -> Self {
        Identity {
            cert: self.cert.clone(),
            key: self.key.clone_key(),
        }
    }
}

/// A certificate's short fingerprint: the first 8 bytes of the SHA-256 of its DER, in hex
/// (`sha256:1a2b…`): what names an operator's identity in logs and refusals (its self-chosen
/// name is not an identity).
pub fn fingerprint(der: &[u8]) -> String {
    let digest = ring::digest::digest(&ring::digest::SHA256, der);
    let hex: String = digest.as_ref()[..8]
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    format!("sha256:{hex}")
}

/// The certificate file of identity `name` in `dir`: `dir/<name>.crt`.
pub fn cert_path(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.crt"))
}

/// The private key file of identity `name` in `dir`: `dir/<name>.key`.
pub fn key_path(dir: &Path, name: &str) -> PathBuf {
    dir.join(format!("{name}.key"))
}

impl Identity {
    /// A new self-signed certificate (ECDSA P-256) whose subject alternative names are `names`
    /// (strings that parse as IP addresses become IP SANs, the rest DNS names).
    pub fn generate(names: &[&str]) -> Result<Identity, IdentityError> {
        Ok(generate(names)?.0)
    }

    /// Generates an identity like [`Identity::generate`] and writes it as `dir/<name>.crt` and
    /// `dir/<name>.key` (mode 0600 on Unix), creating `dir` if needed. Refuses to overwrite
    /// either file. Returns the identity and the two paths.
    pub fn generate_files(
        dir: &Path,
        name: &str,
        names: &[&str],
    ) -> Result<(Identity, PathBuf, PathBuf), IdentityError> {
        let (identity, cert_pem, key_pem) = generate(names)?;
        fs::create_dir_all(dir).map_err(|error| IdentityError::Io {
            what: "cannot create the directory",
            path: dir.to_owned(),
            error,
        })?;
        let (cert_file, key_file) = (cert_path(dir, name), key_path(dir, name));
        for path in [&cert_file, &key_file] {
            if path.exists() {
                return Err(IdentityError::Exists { path: path.clone() });
            }
        }
        write_new(
            &key_file,
            key_pem.as_bytes(),
            0o600,
            "cannot write the private key",
        )?;
        write_new(
            &cert_file,
            cert_pem.as_bytes(),
            0o644,
            "cannot write the certificate",
        )?;
        Ok((identity, cert_file, key_file))
    }

    /// The private key in the form rustls takes.
    pub fn private_key(&self) -> PrivateKeyDer<'static> {
        PrivateKeyDer::Pkcs8(self.key.clone_key())
    }

    /// Reads `dir/<name>.crt` and `dir/<name>.key`.
    pub fn read_pem(dir: &Path, name: &str) -> Result<Identity, IdentityError> {
        let cert = read_cert(&cert_path(dir, name))?;
        let key_file = key_path(dir, name);
        let bytes = read(&key_file, "cannot read the private key")?;
        let key = PrivatePkcs8KeyDer::from_pem_slice(&bytes).map_err(|e| IdentityError::Pem {
            path: key_file,
            expected: "PKCS#8 private key",
            detail: e.to_string(),
        })?;
        Ok(Identity { cert, key })
    }
}

/// What `gen-cert` prints after writing `cert` and `key`: where they are and that the
/// certificate goes to the peer, which passes it as `peer_flag` (e.g. `operator run --trust`).
pub fn handover_note(cert: &Path, key: &Path, peer_flag: &str) -> String {
    format!(
        "wrote {} and {}\ngive {} to the peer ({peer_flag} {}); keep {} private\n",
        cert.display(),
        key.display(),
        file_name(cert),
        cert.display(),
        file_name(key),
    )
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(
        || path.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// Reads the first certificate of a PEM file (what `gen-cert` writes, what `--trust` names).
pub fn read_cert(path: &Path) -> Result<CertificateDer<'static>, IdentityError> {
    let bytes = read(path, "cannot read the certificate")?;
    CertificateDer::from_pem_slice(&bytes).map_err(|e| IdentityError::Pem {
        path: path.to_owned(),
        expected: "certificate",
        detail: e.to_string(),
    })
}

/// The identity and its certificate and key as PEM text (rcgen's encoding).
fn generate(names: &[&str]) -> Result<(Identity, String, String), IdentityError> {
    let names: Vec<String> = names.iter().map(|n| (*n).to_owned()).collect();
    let certified = rcgen::generate_simple_self_signed(names.clone())
        .map_err(|source| IdentityError::Generate { names, source })?;
    let identity = Identity {
        cert: certified.cert.der().clone(),
        key: PrivatePkcs8KeyDer::from(certified.signing_key.serialize_der()),
    };
    Ok((
        identity,
        certified.cert.pem(),
        certified.signing_key.serialize_pem(),
    ))
}

fn read(path: &Path, what: &'static str) -> Result<Vec<u8>, IdentityError> {
    fs::read(path).map_err(|error| IdentityError::Io {
        what,
        path: path.to_owned(),
        error,
    })
}

/// Creates `path` (which must not exist) with `mode` and writes `contents`.
fn write_new(
    path: &Path,
    contents: &[u8],
    mode: u32,
    what: &'static str,
) -> Result<(), IdentityError> {
    let mut options = fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, mode);
    #[cfg(not(unix))]
    let _ = mode;
    let io = |error| IdentityError::Io {
        what,
        path: path.to_owned(),
        error,
    };
    let mut file = options.open(path).map_err(io)?;
    file.write_all(contents).map_err(io)?;
    file.sync_all().map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pem_written_by_rcgen_reads_back() {
        let dir = std::env::temp_dir().join(format!("transport-identity-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let (id, crt, key) =
            Identity::generate_files(&dir, "telerobot", &["telerobot", "127.0.0.1"]).unwrap();
        let back = Identity::read_pem(&dir, "telerobot").unwrap();
        assert_eq!(back.cert, id.cert);
        assert_eq!(back.key.secret_pkcs8_der(), id.key.secret_pkcs8_der());
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            assert_eq!(
                fs::metadata(&key).unwrap().permissions().mode() & 0o777,
                0o600
            );
        }
        let again = Identity::generate_files(&dir, "telerobot", &["x"]).unwrap_err();
        assert!(again.to_string().contains("already exists"), "{again}");
        fs::write(&crt, "not pem").unwrap();
        let bad = read_cert(&crt).unwrap_err().to_string();
        assert!(
            bad.contains("telerobot.crt") && bad.contains("not a certificate"),
            "{bad}"
        );
        let missing = Identity::read_pem(&dir, "nobody").unwrap_err().to_string();
        assert!(missing.contains("nobody.crt"), "{missing}");
        fs::remove_dir_all(&dir).unwrap();
    }
}
