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
    /// A private key file that the group or others may read, write or run (Unix mode bits
    /// `0o077`). Refused, as ssh refuses such a key: the key is what lets its holder command the
    /// robot (or pose as it), and a key others could read must be taken as already leaked — a
    /// warning would be scrolled past on a robot PC that runs unattended.
    #[error(
        "{} has mode {mode:04o}: a private key must not be accessible to group or others; \
         run `chmod 600 {}`",
        path.display(),
        path.display()
    )]
    KeyAccessible {
        /// The key file.
        path: PathBuf,
        /// Its permission bits.
        mode: u32,
    },
    /// The certificate and the private key are not a pair (two identities' files mixed up).
    #[error(
        "{} and {} are not a pair: the private key does not belong to the certificate \
         (they come from different identities; use the .crt and .key that gen-cert wrote \
         together)",
        cert.display(),
        key.display()
    )]
    NotAPair {
        /// The certificate file.
        cert: PathBuf,
        /// The key file.
        key: PathBuf,
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

    /// Reads `dir/<name>.crt` and `dir/<name>.key`. Refuses a key file the group or others
    /// may access ([`IdentityError::KeyAccessible`], Unix) and a key that does not belong to the
    /// certificate ([`IdentityError::NotAPair`]).
    pub fn read_pem(dir: &Path, name: &str) -> Result<Identity, IdentityError> {
        let cert_file = cert_path(dir, name);
        let cert = read_cert(&cert_file)?;
        let key_file = key_path(dir, name);
        check_private(&key_file)?;
        let bytes = read(&key_file, "cannot read the private key")?;
        let key = PrivatePkcs8KeyDer::from_pem_slice(&bytes).map_err(|e| IdentityError::Pem {
            path: key_file.clone(),
            expected: "PKCS#8 private key",
            detail: e.to_string(),
        })?;
        let identity = Identity { cert, key };
        identity.check_pair(&cert_file, &key_file)?;
        Ok(identity)
    }

    /// Whether the key belongs to the certificate (its public key is the certificate's); the
    /// files are named in the error.
    fn check_pair(&self, cert_file: &Path, key_file: &Path) -> Result<(), IdentityError> {
        let signing =
            rustls::crypto::ring::sign::any_supported_type(&self.private_key()).map_err(|e| {
                IdentityError::Pem {
                    path: key_file.to_owned(),
                    expected: "supported private key (ECDSA, Ed25519 or RSA)",
                    detail: e.to_string(),
                }
            })?;
        let certified = rustls::sign::CertifiedKey::new(vec![self.cert.clone()], signing);
        match certified.keys_match() {
            Ok(()) => Ok(()),
            Err(rustls::Error::InconsistentKeys(rustls::InconsistentKeys::KeyMismatch)) => {
                Err(IdentityError::NotAPair {
                    cert: cert_file.to_owned(),
                    key: key_file.to_owned(),
                })
            }
            // The public key could not be derived from the key, or the certificate could not
            // be parsed: rustls says so at the handshake; nothing more is known here.
            Err(_) => Ok(()),
        }
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

/// Refuses a private key file whose mode grants the group or others any access (Unix; see
/// [`IdentityError::KeyAccessible`] for why refuse, not warn). The mode is the target's when
/// `path` is a symbolic link.
fn check_private(path: &Path) -> Result<(), IdentityError> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt as _;
        let metadata = fs::metadata(path).map_err(|error| IdentityError::Io {
            what: "cannot read the private key",
            path: path.to_owned(),
            error,
        })?;
        let mode = metadata.permissions().mode() & 0o7777;
        if mode & 0o077 != 0 {
            return Err(IdentityError::KeyAccessible {
                path: path.to_owned(),
                mode,
            });
        }
    }
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
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

    fn temp_dir(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("transport-identity-{name}-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        dir
    }

    /// Issue 11: a key file with mode 0644 was accepted silently.
    #[cfg(unix)]
    #[test]
    fn a_key_others_may_read_is_refused_naming_the_file_and_its_mode() {
        use std::os::unix::fs::PermissionsExt;
        let dir = temp_dir("mode");
        let (_, _, key) = Identity::generate_files(&dir, "operator", &["operator"]).unwrap();
        for mode in [0o644, 0o640, 0o604, 0o601, 0o610] {
            fs::set_permissions(&key, fs::Permissions::from_mode(mode)).unwrap();
            let e = Identity::read_pem(&dir, "operator").unwrap_err();
            assert!(
                matches!(e, IdentityError::KeyAccessible { mode: m, .. } if m == mode),
                "{mode:o}: {e:?}"
            );
            let text = e.to_string();
            let shown = format!("{mode:04o}");
            for part in [key.display().to_string(), shown, "chmod 600".to_owned()] {
                assert!(text.contains(&part), "{text}");
            }
        }
        for mode in [0o600, 0o400] {
            fs::set_permissions(&key, fs::Permissions::from_mode(mode)).unwrap();
            assert!(Identity::read_pem(&dir, "operator").is_ok(), "{mode:o}");
        }
        fs::remove_dir_all(&dir).unwrap();
    }

    /// Issue 11: a certificate and a key of two identities gave rustls's `KeyMismatch: keys may
    /// not be consistent` at the handshake, naming neither file.
    #[test]
    fn a_certificate_and_key_of_two_identities_are_refused_naming_both_files() {
        let dir = temp_dir("pair");
        let (_, crt, key) = Identity::generate_files(&dir, "operator", &["operator"]).unwrap();
        let other = dir.join("other");
        let (_, _, other_key) =
            Identity::generate_files(&other, "operator", &["operator"]).unwrap();
        // The other identity's key under this identity's name (rename keeps its mode, 0600).
        fs::rename(&other_key, &key).unwrap();
        let e = Identity::read_pem(&dir, "operator").unwrap_err();
        assert!(matches!(e, IdentityError::NotAPair { .. }), "{e:?}");
        let text = e.to_string();
        assert!(
            text.contains(&crt.display().to_string())
                && text.contains(&key.display().to_string())
                && text.contains("not a pair"),
            "{text}"
        );
        fs::remove_dir_all(&dir).unwrap();
    }
}
