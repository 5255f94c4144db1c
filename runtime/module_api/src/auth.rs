//! Authenticated links: with a shared secret, every connection (agent, config server, control,
//! module to module) proves after its hello that both ends hold the secret, before any other
//! frame is accepted.
//!
//! Each side sends a challenge of 32 random bytes right after its hello. On the peer's
//! challenge it answers with a proof, `HMAC-SHA256(secret, "ARMR proof" ‖ peer's challenge ‖ own
//! challenge)`, and it accepts the peer only once the peer's proof — the same over the two
//! challenges in the other order — checks out. Fresh challenges make a recorded proof worthless,
//! and the order of the challenges in the MAC keeps a peer from passing our own proof back.
//!
//! The secret is a file readable by its owner only (`chmod 600`), given to `armor run --secret`
//! and passed to modules as `ARMOR_SECRET_FILE`.

use std::fmt;
use std::path::Path;
use std::sync::Arc;

use hmac::{Hmac, Mac};
use sha2::Sha256;

/// The environment variable that names the secret file for a module.
pub const ENV_SECRET_FILE: &str = "ARMOR_SECRET_FILE";

/// Bytes of a challenge and of a proof.
pub const NONCE_BYTES: usize = 32;

/// The shortest secret accepted, in bytes.
pub const MIN_SECRET_BYTES: usize = 16;

const PROOF_LABEL: &[u8] = b"ARMR proof";

pub type Nonce = [u8; NONCE_BYTES];
pub type Proof = [u8; NONCE_BYTES];

#[derive(Debug, thiserror::Error)]
pub enum SecretError {
    #[error("cannot read the secret file {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error(
        "the secret file {path} can be read by others (mode {mode:o}): make it readable by its owner only (chmod 600)"
    )]
    Exposed { path: String, mode: u32 },
    #[error(
        "the secret in {path} is {len} bytes long; use {MIN_SECRET_BYTES} or more (for example 32 random bytes, base64)"
    )]
    TooShort { path: String, len: usize },
}

/// A shared secret; cheap to clone.
#[derive(Clone)]
pub struct Secret(Arc<[u8]>);

impl fmt::Debug for Secret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Secret(..)")
    }
}

impl Secret {
    /// Reads a secret file, refusing one that others may read or that is too short. Trailing
    /// line breaks are not part of the secret (editors add them).
    pub fn load(path: &Path) -> Result<Secret, SecretError> {
        use std::os::unix::fs::PermissionsExt as _;
        let shown = path.display().to_string();
        let read_err = |source| SecretError::Read {
            path: shown.clone(),
            source,
        };
        let mode = std::fs::metadata(path)
            .map_err(read_err)?
            .permissions()
            .mode();
        if mode & 0o077 != 0 {
            return Err(SecretError::Exposed {
                path: shown,
                mode: mode & 0o777,
            });
        }
        let mut bytes = std::fs::read(path).map_err(read_err)?;
        while bytes.last().is_some_and(|&b| b == b'\n' || b == b'\r') {
            bytes.pop();
        }
        if bytes.len() < MIN_SECRET_BYTES {
            return Err(SecretError::TooShort {
                path: shown,
                len: bytes.len(),
            });
        }
        Ok(Secret(bytes.into()))
    }

    /// The secret named by `ARMOR_SECRET_FILE`, if it is set.
    pub fn from_env() -> Result<Option<Secret>, SecretError> {
        match std::env::var_os(ENV_SECRET_FILE) {
            Some(path) if !path.is_empty() => Secret::load(Path::new(&path)).map(Some),
            _ => Ok(None),
        }
    }

    /// A secret from bytes (tests, tools).
    pub fn from_bytes(bytes: &[u8]) -> Secret {
        Secret(bytes.into())
    }

    fn mac(&self, first: &Nonce, second: &Nonce) -> Proof {
        // HMAC takes keys of any length; `new_from_slice` cannot fail for it.
        let Ok(mut mac) = Hmac::<Sha256>::new_from_slice(&self.0) else {
            return [0; NONCE_BYTES];
        };
        mac.update(PROOF_LABEL);
        mac.update(first);
        mac.update(second);
        mac.finalize().into_bytes().into()
    }
}

/// One side's part of the handshake on one connection.
#[derive(Clone, Debug)]
pub struct Handshake {
    secret: Secret,
    own: Nonce,
}

impl Handshake {
    /// A handshake with a fresh random challenge.
    pub fn new(secret: &Secret) -> Handshake {
        let mut own = [0; NONCE_BYTES];
        // Without the system's random source the handshake cannot be safe; an all-zero
        // challenge would still authenticate (both ends need the secret) but could be replayed,
        // so it is logged loudly.
        if let Err(err) = getrandom::fill(&mut own) {
            tracing::error!("no random numbers for an authentication challenge: {err}");
        }
        Handshake {
            secret: secret.clone(),
            own,
        }
    }

    /// The challenge to send after the hello.
    pub fn challenge(&self) -> &Nonce {
        &self.own
    }

    /// The proof to send in answer to the peer's challenge.
    pub fn proof_for(&self, peer: &Nonce) -> Proof {
        self.secret.mac(peer, &self.own)
    }

    /// Whether `proof` is the peer's answer to our challenge (`peer` is its own challenge).
    pub fn verify(&self, peer: &Nonce, proof: &Proof) -> bool {
        let Ok(mut mac) = Hmac::<Sha256>::new_from_slice(&self.secret.0) else {
            return false;
        };
        mac.update(PROOF_LABEL);
        mac.update(&self.own);
        mac.update(peer);
        // `verify_slice` compares in constant time.
        mac.verify_slice(proof).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_sides_prove_the_secret_and_a_stranger_cannot() {
        let secret = Secret::from_bytes(b"0123456789abcdef0123");
        let a = Handshake::new(&secret);
        let b = Handshake::new(&secret);
        assert_ne!(a.challenge(), b.challenge());
        assert!(b.verify(a.challenge(), &a.proof_for(b.challenge())));
        assert!(a.verify(b.challenge(), &b.proof_for(a.challenge())));
        // Our own proof passed back is refused; so is a proof made with another secret.
        assert!(!a.verify(b.challenge(), &a.proof_for(b.challenge())));
        let stranger = Handshake::new(&Secret::from_bytes(b"another secret, as long"));
        assert!(!a.verify(stranger.challenge(), &stranger.proof_for(a.challenge())));
    }

    #[test]
    fn secret_files_must_be_private_and_long_enough() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("secret");
        std::fs::write(&file, "0123456789abcdef0123\n").expect("write");
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o644)).expect("chmod");
        let err = Secret::load(&file).expect_err("exposed");
        assert!(err.to_string().contains("mode 644"), "{err}");
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).expect("chmod");
        let secret = Secret::load(&file).expect("private");
        assert_eq!(&*secret.0, b"0123456789abcdef0123");
        std::fs::write(&file, "short\n").expect("write");
        let err = Secret::load(&file).expect_err("short");
        assert!(err.to_string().contains("5 bytes long"), "{err}");
        let err = Secret::load(&dir.path().join("none")).expect_err("missing");
        assert!(err.to_string().contains("cannot read"), "{err}");
    }
}
