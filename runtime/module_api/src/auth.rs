//! Authenticated (and, on request, encrypted) links: with a shared secret, every connection
//! (agent, config server, control, module to module) runs a Noise handshake after its hello,
//! before any other frame is accepted.
//!
//! **Handshake.** [`NOISE_PATTERN`], `Noise_NNpsk0_25519_AESGCM_SHA256`, from the `snow` crate:
//! the dialer is the Noise initiator, the listener the responder, so the roles are part of the
//! construction and a listener cannot be used as an oracle for its own proofs. The pre-shared
//! key depends on who the dialer says it is (its *identity*, sent in clear before the first
//! Noise message and bound to the handshake by the prologue) and on the listener:
//!
//! | listener | pre-shared key |
//! | --- | --- |
//! | agent, config server | the dialer's module key, `K(name)` |
//! | a module's data port | the link key `K(provider) → name`, which the agent hands out |
//! | control interface | the operator key |
//!
//! The dialer's first transport message (an empty payload, [`confirm`](Dialer::finish)) proves
//! it holds the session's keys, so a recorded first message replayed by someone else goes no
//! further. Keys are derived from the run's secret with HKDF-SHA256 ([`Secret`]); a module is
//! given only its own key ([`Key`], over the descriptor `ARMOR_KEY_FD`), never the secret, so it can prove no other
//! name than its own.
//!
//! **Records.** When either side asks for encryption, each side's bytes after its last
//! handshake message are Noise transport messages, each behind a `u16` little-endian length:
//! AES-256-GCM with the keys of the Noise split (initiator to responder first), the nonce
//! Noise's counter (32 zero bits, then the counter as a big-endian `u64`), no associated data.
//! Encryption runs through `ring` ([`Sealer`], [`Opener`]); the handshake is `snow`'s.

use std::fmt;
use std::io::{self, Read, Write};
use std::path::Path;
use std::sync::Arc;

use ring::aead::{AES_256_GCM, Aad, LessSafeKey, Nonce, Tag, UnboundKey};

/// The environment variable that names the run's secret file (tools, the studio, standalone
/// modules).
pub const ENV_SECRET_FILE: &str = "ARMOR_SECRET_FILE";
/// The environment variable that names the file descriptor a module reads its own key from
/// (64 hex digits, then end of file), set by `armor run` and `armor host`. The key itself is
/// never in the environment: a process of the same user reads `/proc/PID/environ`. A number of
/// a descriptor is no secret; the module reads the key and closes the descriptor at start.
pub const ENV_KEY_FD: &str = "ARMOR_KEY_FD";
/// Set to `1` by `armor run --encrypt`: every link of the module is encrypted.
pub const ENV_ENCRYPT: &str = "ARMOR_ENCRYPT";

/// The Noise protocol every authenticated connection runs.
pub const NOISE_PATTERN: &str = "Noise_NNpsk0_25519_AESGCM_SHA256";
/// The prologue: these bytes, then the identity's length (one byte) and the identity.
pub const PROLOGUE_LABEL: &[u8] = b"ARMOR/1 ";

/// Bytes of a key.
pub const KEY_BYTES: usize = 32;
/// The shortest secret accepted, in bytes: as long as a key, so that a recorded handshake
/// cannot be guessed offline. A shorter passphrase is stretched with Argon2id first
/// ([`stretch_passphrase`], `armor secret new --passphrase`).
pub const MIN_SECRET_BYTES: usize = 32;
/// Argon2id's memory for a passphrase, in KiB (64 MiB): each guess of an offline attacker
/// costs as much.
pub const PASSPHRASE_MEMORY_KIB: u32 = 64 * 1024;
/// Argon2id's passes over that memory.
pub const PASSPHRASE_PASSES: u32 = 3;
/// Bytes of a passphrase's salt.
pub const SALT_BYTES: usize = 16;
/// The longest identity a dialer may claim, in bytes.
pub const MAX_IDENTITY_BYTES: usize = 255;
/// The largest handshake message of the pattern (an ephemeral key, one payload byte, a tag).
pub const MAX_HANDSHAKE_BYTES: usize = 1 + MAX_IDENTITY_BYTES + 32 + 1 + TAG_BYTES;
/// Bytes of an AEAD tag.
pub const TAG_BYTES: usize = 16;
/// The largest Noise message, and so the largest record after its length.
pub const MAX_RECORD_BYTES: usize = 65535;
/// The most plaintext one record carries.
pub const MAX_RECORD_PLAINTEXT: usize = MAX_RECORD_BYTES - TAG_BYTES;

const SALT: &[u8] = b"ARMOR/1 secret";
const FLAG_ENCRYPT: u8 = 1;

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
        "the secret in {path} is {len} bytes long; use {MIN_SECRET_BYTES} or more: `armor secret new -o FILE` writes a random one, `armor secret new --passphrase -o FILE` stretches a shorter passphrase"
    )]
    TooShort { path: String, len: usize },
    #[error("the key read from file descriptor {fd} ({ENV_KEY_FD}) must be {} hex digits", KEY_BYTES * 2)]
    BadKey { fd: String },
    #[error("cannot read the key from file descriptor {fd} ({ENV_KEY_FD}): {source}")]
    KeyFd { fd: String, source: std::io::Error },
    #[error("stretching the passphrase: {0}")]
    Stretch(String),
    #[error(
        "{path} is not a role's key: expected one line `observer HEX` or `operator HEX` (written by armor secret derive)"
    )]
    BadRoleKey { path: String },
    #[error("{path} holds the {role} key, which proves only the name `{identity}`, not `{name}`")]
    RoleKeyForAnotherName {
        path: String,
        role: &'static str,
        identity: &'static str,
        name: String,
    },
}

/// Why a handshake failed.
#[derive(Debug, thiserror::Error)]
pub enum AuthError {
    #[error(
        "the peer does not hold the key for `{0}`: wrong secret, or a name that is not its own"
    )]
    WrongKey(String),
    #[error("the peer's handshake message is malformed: {0}")]
    Malformed(&'static str),
    #[error("this side requires encrypted links and the peer would not encrypt")]
    NotEncrypted,
    #[error("handshake: {0}")]
    Noise(#[from] snow::Error),
}

/// A 32-byte key. Its `Debug` shows nothing of it.
#[derive(Clone, PartialEq, Eq)]
pub struct Key([u8; KEY_BYTES]);

impl fmt::Debug for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Key(..)")
    }
}

impl Key {
    /// The link key a dialer that says it is `dialer` uses towards the holder of this module
    /// key (HKDF-Expand with this key as the pseudo-random key).
    pub fn link_key(&self, dialer: &str) -> Key {
        expand(&self.0, &[b"link:", dialer.as_bytes()])
    }

    pub fn to_hex(&self) -> String {
        hex(&self.0)
    }

    pub fn from_hex(text: &str) -> Option<Key> {
        unhex(text).map(Key)
    }

    /// The module key behind `ARMOR_KEY_FD`, if set: read to the end, after which the
    /// descriptor is closed (see [`crate::hardening::take_key_fd`]).
    pub fn from_fd_env() -> Result<Option<Key>, SecretError> {
        let Some(fd) = std::env::var(ENV_KEY_FD).ok().filter(|fd| !fd.is_empty()) else {
            return Ok(None);
        };
        let text = crate::hardening::take_key_fd(&fd).map_err(|source| SecretError::KeyFd {
            fd: fd.clone(),
            source,
        })?;
        Key::from_hex(&text)
            .map(Some)
            .ok_or(SecretError::BadKey { fd })
    }
}

fn expand(prk: &[u8; KEY_BYTES], info: &[&[u8]]) -> Key {
    // A 32-byte pseudo-random key is what HKDF-Expand takes; 32 bytes of output always fit.
    let mut okm = [0; KEY_BYTES];
    if let Ok(hkdf) = hkdf::Hkdf::<sha2::Sha256>::from_prk(prk) {
        let _ = hkdf.expand_multi_info(info, &mut okm);
    }
    Key(okm)
}

/// The run's shared secret, kept as its HKDF pseudo-random key; cheap to clone.
#[derive(Clone)]
pub struct Secret(Arc<[u8; KEY_BYTES]>);

impl fmt::Debug for Secret {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("Secret(..)")
    }
}

impl Secret {
    /// Reads a secret file, refusing one that others may read or that is too short. Trailing
    /// line breaks are not part of the secret (editors add them).
    pub fn load(path: &Path) -> Result<Secret, SecretError> {
        let mut bytes = read_private(path)?;
        while bytes.last().is_some_and(|&b| b == b'\n' || b == b'\r') {
            bytes.pop();
        }
        if bytes.len() < MIN_SECRET_BYTES {
            return Err(SecretError::TooShort {
                path: path.display().to_string(),
                len: bytes.len(),
            });
        }
        Ok(Secret::from_bytes(&bytes))
    }

    /// The secret named by `ARMOR_SECRET_FILE`, if it is set.
    pub fn from_env() -> Result<Option<Secret>, SecretError> {
        match std::env::var_os(ENV_SECRET_FILE) {
            Some(path) if !path.is_empty() => Secret::load(Path::new(&path)).map(Some),
            _ => Ok(None),
        }
    }

    /// The secret as `armor run` hands it to its agent over a pipe (read back by
    /// [`Secret::from_fd_env`]): its pseudo-random key, hex.
    pub fn to_hex(&self) -> String {
        Key(*self.0).to_hex()
    }

    /// The secret handed over a descriptor named by `ARMOR_KEY_FD` (the agent `armor run`
    /// starts), read and closed as a module's key is; `None` when the variable is not set.
    pub fn from_fd_env() -> Result<Option<Secret>, SecretError> {
        Ok(Key::from_fd_env()?.map(|key| Secret(Arc::new(key.0))))
    }

    /// A secret from bytes (tests, tools): HKDF-Extract with the salt `ARMOR/1 secret`.
    pub fn from_bytes(bytes: &[u8]) -> Secret {
        let (prk, _) = hkdf::Hkdf::<sha2::Sha256>::extract(Some(SALT), bytes);
        Secret(Arc::new(prk.into()))
    }

    /// The key of the module (or observer) named `name`: HKDF-Expand, info `module:NAME`.
    pub fn module_key(&self, name: &str) -> Key {
        expand(&self.0, &[b"module:", name.as_bytes()])
    }

    /// The key of the run's control interface: HKDF-Expand, info `operator`.
    pub fn operator_key(&self) -> Key {
        expand(&self.0, &[b"operator"])
    }

    /// The key of a role at the run's control interface: the operator key, or for an
    /// observer HKDF-Expand with info `observer`. Neither key reveals the secret or the other.
    pub fn role_key(&self, role: Role) -> Key {
        match role {
            Role::Operator => self.operator_key(),
            Role::Observer => expand(&self.0, &[b"observer"]),
        }
    }
}

/// Who a control client is: an observer reads the run's status and data, an operator may also
/// command it. The role is the identity the client proves at the control interface.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    Observer,
    Operator,
}

impl Role {
    pub fn as_str(self) -> &'static str {
        match self {
            Role::Observer => "observer",
            Role::Operator => "operator",
        }
    }

    pub fn parse(text: &str) -> Option<Role> {
        match text {
            "observer" => Some(Role::Observer),
            "operator" => Some(Role::Operator),
            _ => None,
        }
    }

    /// The name a holder of this role's key proves at the agent and at data ports, to read the
    /// run's data. It is not an identifier, so no module of a system can bear it, and the agent
    /// knows it for a reader: it registers nothing for it.
    pub fn data_identity(self) -> &'static str {
        match self {
            Role::Observer => "role:observer",
            Role::Operator => "role:operator",
        }
    }

    /// The role whose [`Role::data_identity`] `identity` is.
    pub fn of_data_identity(identity: &str) -> Option<Role> {
        [Role::Observer, Role::Operator]
            .into_iter()
            .find(|role| role.data_identity() == identity)
    }
}

/// The bytes of a file only its owner may read (a secret, a role's key); one that others may
/// read is refused before it is read, since it must be taken as known.
pub fn read_private(path: &Path) -> Result<Vec<u8>, SecretError> {
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
    std::fs::read(path).map_err(read_err)
}

/// A passphrase stretched into a secret of [`KEY_BYTES`] with Argon2id
/// ([`PASSPHRASE_MEMORY_KIB`] of memory, [`PASSPHRASE_PASSES`] passes, one lane) and `salt`:
/// an offline guesser pays that for every word it tries against a recorded handshake. The
/// salt is not secret; the same passphrase and salt give the same secret on every computer.
pub fn stretch_passphrase(passphrase: &[u8], salt: &[u8]) -> Result<[u8; KEY_BYTES], SecretError> {
    use argon2::{Algorithm, Argon2, Params, Version};
    let params = Params::new(PASSPHRASE_MEMORY_KIB, PASSPHRASE_PASSES, 1, Some(KEY_BYTES))
        .map_err(|err| SecretError::Stretch(err.to_string()))?;
    let mut out = [0; KEY_BYTES];
    Argon2::new(Algorithm::Argon2id, Version::V0x13, params)
        .hash_password_into(passphrase, salt, &mut out)
        .map_err(|err| SecretError::Stretch(err.to_string()))?;
    Ok(out)
}

/// `N` bytes from the system's random source (a new secret, a salt).
pub fn random_bytes<const N: usize>() -> Result<[u8; N], SecretError> {
    let mut bytes = [0; N];
    getrandom::fill(&mut bytes)
        .map_err(|err| SecretError::Stretch(format!("no randomness: {err}")))?;
    Ok(bytes)
}

/// Bytes as lowercase hex (a secret file, a salt).
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Exactly `N` bytes written as hex (either case, spaces round it ignored); `None` for any
/// other text.
pub fn unhex<const N: usize>(text: &str) -> Option<[u8; N]> {
    let text = text.trim();
    if text.len() != N * 2 || !text.is_ascii() {
        return None;
    }
    let mut bytes = [0; N];
    for (i, byte) in bytes.iter_mut().enumerate() {
        *byte = u8::from_str_radix(&text[i * 2..i * 2 + 2], 16).ok()?;
    }
    Some(bytes)
}

/// A role's key as a file holds it (`armor secret derive`): one line, `ROLE HEX`.
#[derive(Clone, Debug)]
pub struct RoleKey {
    pub role: Role,
    pub key: Key,
}

impl RoleKey {
    /// The line a role's key file holds.
    pub fn to_line(&self) -> String {
        format!("{} {}\n", self.role.as_str(), self.key.to_hex())
    }

    /// Reads a role's key file, refusing one that others may read.
    pub fn load(path: &Path) -> Result<RoleKey, SecretError> {
        let shown = path.display().to_string();
        let text = String::from_utf8(read_private(path)?).map_err(|_| SecretError::BadRoleKey {
            path: shown.clone(),
        })?;
        let mut words = text.split_whitespace();
        match (
            words.next().and_then(Role::parse),
            words.next().and_then(Key::from_hex),
            words.next(),
        ) {
            (Some(role), Some(key), None) => Ok(RoleKey { role, key }),
            _ => Err(SecretError::BadRoleKey { path: shown }),
        }
    }
}

/// What a node proves itself with: its own module key, and whether its links are encrypted.
#[derive(Clone, Debug)]
pub struct Credentials {
    pub key: Key,
    pub encrypt: bool,
}

impl Credentials {
    /// A module's credentials from its environment: the key behind `ARMOR_KEY_FD` (set by
    /// `armor run`), else the
    /// key of `name` derived from the secret in `secret_file` or `ARMOR_SECRET_FILE`; with
    /// `ARMOR_ENCRYPT=1` (or `encrypt`), encrypted links.
    pub fn for_module(
        name: &str,
        secret_file: Option<&Path>,
        encrypt: bool,
    ) -> Result<Option<Credentials>, SecretError> {
        let encrypt = encrypt || std::env::var(ENV_ENCRYPT).is_ok_and(|value| value == "1");
        let key = match secret_file {
            // A role's key (`armor secret derive`) proves the role's reader name only.
            Some(file) => match RoleKey::load(file) {
                Ok(role_key) if Role::of_data_identity(name) == Some(role_key.role) => {
                    Some(role_key.key)
                }
                Ok(role_key) => {
                    return Err(SecretError::RoleKeyForAnotherName {
                        path: file.display().to_string(),
                        role: role_key.role.as_str(),
                        identity: role_key.role.data_identity(),
                        name: name.to_owned(),
                    });
                }
                Err(SecretError::BadRoleKey { .. }) => {
                    let secret = Secret::load(file)?;
                    Some(match Role::of_data_identity(name) {
                        Some(role) => secret.role_key(role),
                        None => secret.module_key(name),
                    })
                }
                Err(err) => return Err(err),
            },
            None => match Key::from_fd_env()? {
                Some(key) => Some(key),
                None => Secret::from_env()?.map(|secret| secret.module_key(name)),
            },
        };
        Ok(key.map(|key| Credentials { key, encrypt }))
    }

    /// How this node dials the agent or the config server.
    pub fn dial(&self, identity: &str) -> Dial {
        Dial {
            key: self.key.clone(),
            identity: identity.to_owned(),
            encrypt: self.encrypt,
        }
    }

    /// How this node admits subscribers at its data port.
    pub fn listen(&self) -> Listen {
        Listen {
            admit: Admit::LinksTo(self.key.clone()),
            encrypt: self.encrypt,
        }
    }
}

/// How a listener finds the pre-shared key for the identity a dialer claims.
#[derive(Clone, Debug)]
pub enum Admit {
    /// The config server and `armor host`: the claimed name's module key.
    Modules(Secret),
    /// The agent: the claimed name's module key, or for a role's reader name
    /// ([`Role::data_identity`]) that role's key, so that an observer or an operator may look
    /// data up (and nothing more: the agent registers nothing for it).
    Agent(Secret),
    /// A module's data port: the link key of this module's key for the claimed name.
    LinksTo(Key),
    /// The control interface: the identity names the role (`observer`, else `operator`), and
    /// the key is that role's. A run without observers admits only the operator.
    Control { operator: Key, observer: Key },
}

impl Admit {
    fn key_for(&self, identity: &str) -> Key {
        match self {
            Admit::Modules(secret) => secret.module_key(identity),
            Admit::Agent(secret) => match Role::of_data_identity(identity) {
                Some(role) => secret.role_key(role),
                None => secret.module_key(identity),
            },
            Admit::LinksTo(key) => key.link_key(identity),
            Admit::Control { operator, observer } => match Role::parse(identity) {
                Some(Role::Observer) => observer.clone(),
                _ => operator.clone(),
            },
        }
    }
}

/// A listener's side of authentication: whom it admits and whether it insists on encryption.
#[derive(Clone, Debug)]
pub struct Listen {
    pub admit: Admit,
    pub encrypt: bool,
}

/// A dialer's side: the key, the identity it claims, and whether it asks for encryption.
#[derive(Clone, Debug)]
pub struct Dial {
    pub key: Key,
    pub identity: String,
    pub encrypt: bool,
}

fn builder<'a>(key: &'a Key, prologue: &'a [u8]) -> Result<snow::Builder<'a>, AuthError> {
    let params = NOISE_PATTERN.parse()?;
    Ok(snow::Builder::new(params)
        .psk(0, &key.0)?
        .prologue(prologue)?)
}

fn prologue(identity: &str) -> Vec<u8> {
    let mut prologue = PROLOGUE_LABEL.to_vec();
    prologue.push(identity.len() as u8);
    prologue.extend_from_slice(identity.as_bytes());
    prologue
}

/// What the end of a handshake leaves to a connection: how to seal what this side sends and
/// open what it receives, when the link is encrypted.
#[derive(Debug)]
pub struct Session {
    /// The peer's proven identity (the listener's is not named: the dialer chose it).
    pub peer: Option<String>,
    pub sealer: Option<Sealer>,
    pub opener: Option<Opener>,
    /// The handshake's hash, the same on both sides and on no other connection: what a
    /// [`reverse_proof`] is bound to.
    pub binding: Vec<u8>,
}

/// A provider's proof, sent with a subscription on a connection its subscriber opened, that it
/// holds `link_key` (the one the agent issued it for the subscriber's data port), bound to
/// `binding` (the connection's handshake hash): HKDF-Expand with the link key, info
/// `reverse:` and the binding; hex. Someone who reads it learns nothing of the key and cannot
/// use it on another connection.
pub fn reverse_proof(link_key: &Key, binding: &[u8]) -> String {
    expand(&link_key.0, &[b"reverse:", binding]).to_hex()
}

/// Whether `proof` is [`reverse_proof`] of `link_key` and `binding`, compared in constant time.
pub fn check_reverse_proof(link_key: &Key, binding: &[u8], proof: &str) -> bool {
    let expected = reverse_proof(link_key, binding);
    expected.len() == proof.len()
        && expected
            .bytes()
            .zip(proof.bytes())
            .fold(0, |diff, (a, b)| diff | (a ^ b))
            == 0
}

/// The dialer after its first message.
pub struct Dialer {
    handshake: snow::HandshakeState,
    encrypt: bool,
    identity: String,
}

impl fmt::Debug for Dialer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Dialer")
            .field("identity", &self.identity)
            .finish()
    }
}

impl Dialer {
    /// Starts a handshake; the bytes are the body of the first handshake frame (identity
    /// length, identity, Noise message `psk, e` with the flags byte as its payload).
    pub fn start(dial: &Dial) -> Result<(Dialer, Vec<u8>), AuthError> {
        let identity = dial.identity.as_bytes();
        if identity.is_empty() || identity.len() > MAX_IDENTITY_BYTES {
            return Err(AuthError::Malformed("an identity of 1 to 255 bytes"));
        }
        let prologue = prologue(&dial.identity);
        let mut handshake = builder(&dial.key, &prologue)?.build_initiator()?;
        let mut body = vec![identity.len() as u8];
        body.extend_from_slice(identity);
        let mut message = [0; MAX_HANDSHAKE_BYTES];
        let flags = if dial.encrypt { FLAG_ENCRYPT } else { 0 };
        let len = handshake.write_message(&[flags], &mut message)?;
        body.extend_from_slice(&message[..len]);
        Ok((
            Dialer {
                handshake,
                encrypt: dial.encrypt,
                identity: dial.identity.clone(),
            },
            body,
        ))
    }

    /// Takes the listener's answer (which proves the listener holds the key); returns the
    /// confirmation to send (the first transport message: an empty payload) and the session.
    pub fn finish(mut self, answer: &[u8]) -> Result<(Vec<u8>, Session), AuthError> {
        let mut payload = [0; MAX_HANDSHAKE_BYTES];
        let len = self
            .handshake
            .read_message(answer, &mut payload)
            .map_err(|_| AuthError::WrongKey(self.identity.clone()))?;
        let encrypt = match payload[..len] {
            [flags] => flags & FLAG_ENCRYPT != 0,
            _ => {
                return Err(AuthError::Malformed(
                    "the answer's payload is one flags byte",
                ));
            }
        };
        if self.encrypt && !encrypt {
            return Err(AuthError::NotEncrypted);
        }
        let binding = self.handshake.get_handshake_hash().to_vec();
        let (to_listener, from_listener) = self.handshake.dangerously_get_raw_split();
        let mut sealer = Sealer::new(&to_listener);
        let confirm = sealer.seal_message(&[]);
        let session = Session {
            binding,
            peer: None,
            sealer: encrypt.then_some(sealer),
            opener: encrypt.then(|| Opener::new(&from_listener)),
        };
        Ok((confirm, session))
    }
}

/// The listener after it answered, waiting for the dialer's confirmation.
pub struct Listener {
    identity: String,
    binding: Vec<u8>,
    confirm: Opener,
    opener: Option<Opener>,
}

impl fmt::Debug for Listener {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Listener")
            .field("identity", &self.identity)
            .finish()
    }
}

impl Listener {
    /// Takes the dialer's first message; returns the answer to send, and the sealer for what
    /// this side sends after it when the link is encrypted. A wrong key fails here, after a
    /// few hashes and no Diffie-Hellman.
    pub fn accept(
        listen: &Listen,
        body: &[u8],
    ) -> Result<(Listener, Vec<u8>, Option<Sealer>), AuthError> {
        let (&len, rest) = body
            .split_first()
            .ok_or(AuthError::Malformed("an empty first message"))?;
        let len = usize::from(len);
        if len == 0 || rest.len() < len {
            return Err(AuthError::Malformed("an identity of 1 to 255 bytes"));
        }
        let (identity, message) = rest.split_at(len);
        let identity = std::str::from_utf8(identity)
            .map_err(|_| AuthError::Malformed("an identity in UTF-8"))?
            .to_owned();
        let key = listen.admit.key_for(&identity);
        let prologue = prologue(&identity);
        let mut handshake = builder(&key, &prologue)?.build_responder()?;
        let mut payload = [0; MAX_HANDSHAKE_BYTES];
        let got = handshake
            .read_message(message, &mut payload)
            .map_err(|_| AuthError::WrongKey(identity.clone()))?;
        let asked = match payload[..got] {
            [flags] => flags & FLAG_ENCRYPT != 0,
            _ => return Err(AuthError::Malformed("the first payload is one flags byte")),
        };
        let encrypt = asked || listen.encrypt;
        let mut answer = [0; MAX_HANDSHAKE_BYTES];
        let flags = if encrypt { FLAG_ENCRYPT } else { 0 };
        let len = handshake.write_message(&[flags], &mut answer)?;
        let binding = handshake.get_handshake_hash().to_vec();
        let (from_dialer, to_dialer) = handshake.dangerously_get_raw_split();
        Ok((
            Listener {
                identity,
                binding,
                confirm: Opener::new(&from_dialer),
                opener: None,
            }
            .with_opener(encrypt),
            answer[..len].to_vec(),
            encrypt.then(|| Sealer::new(&to_dialer)),
        ))
    }

    fn with_opener(mut self, encrypt: bool) -> Self {
        if encrypt {
            // The records after the confirmation continue its nonce sequence.
            self.opener = Some(Opener {
                key: self.confirm.key.clone(),
                nonce: 1,
                buf: Vec::new(),
                start: 0,
                end: 0,
                plain: 0..0,
            });
        }
        self
    }

    /// The identity the dialer claims (proven once [`Listener::confirm`] succeeds).
    pub fn identity(&self) -> &str {
        &self.identity
    }

    /// Checks the dialer's confirmation: it holds this session's keys, so it is no replay.
    pub fn confirm(mut self, confirm: &[u8]) -> Result<Session, AuthError> {
        let mut message = confirm.to_vec();
        if self.confirm.open_message(&mut message).is_none() {
            return Err(AuthError::WrongKey(self.identity));
        }
        Ok(Session {
            binding: self.binding,
            peer: Some(self.identity),
            sealer: None,
            opener: self.opener,
        })
    }
}

/// A ring AES-256-GCM key with the key bytes of a Noise split. Clonable for the listener's
/// confirmation, which shares the records' key.
#[derive(Clone)]
struct AeadKey(Arc<LessSafeKey>);

impl AeadKey {
    fn new(bytes: &[u8; 32]) -> AeadKey {
        // AES-256 takes exactly 32 bytes, which a Noise split gives.
        let unbound = UnboundKey::new(&AES_256_GCM, bytes)
            .unwrap_or_else(|_| unreachable!("a 32-byte key is an AES-256 key"));
        AeadKey(Arc::new(LessSafeKey::new(unbound)))
    }
}

fn noise_nonce(counter: u64) -> Nonce {
    let mut nonce = [0; 12];
    nonce[4..].copy_from_slice(&counter.to_be_bytes());
    Nonce::assume_unique_for_key(nonce)
}

/// Encrypts what one side sends, record after record.
pub struct Sealer {
    key: AeadKey,
    nonce: u64,
}

impl fmt::Debug for Sealer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Sealer")
            .field("nonce", &self.nonce)
            .finish()
    }
}

impl Sealer {
    fn new(key: &[u8; 32]) -> Sealer {
        Sealer {
            key: AeadKey::new(key),
            nonce: 0,
        }
    }

    fn next_nonce(&mut self) -> Nonce {
        let nonce = noise_nonce(self.nonce);
        self.nonce += 1;
        nonce
    }

    /// One Noise transport message of `plain` (at most [`MAX_RECORD_PLAINTEXT`] bytes), without
    /// a length.
    fn seal_message(&mut self, plain: &[u8]) -> Vec<u8> {
        let mut out = plain.to_vec();
        let tag = self.seal_in_place(&mut out);
        out.extend_from_slice(tag.as_ref());
        out
    }

    fn seal_in_place(&mut self, bytes: &mut [u8]) -> Tag {
        let nonce = self.next_nonce();
        self.key
            .0
            .seal_in_place_separate_tag(nonce, Aad::empty(), bytes)
            .unwrap_or_else(|_| unreachable!("a record is far below AES-GCM's limit"))
    }

    /// Appends `plain` to `out` as records (each a `u16` length, the ciphertext and its tag).
    pub fn seal_records(&mut self, plain: &[u8], out: &mut Vec<u8>) {
        self.seal_parts(&[plain], out);
    }

    /// [`Sealer::seal_records`] of the bytes of `parts` one after the other (a frame's header
    /// and its payload), copied once, into `out`, where they are sealed in place.
    pub fn seal_parts(&mut self, parts: &[&[u8]], out: &mut Vec<u8>) {
        let total: usize = parts.iter().map(|part| part.len()).sum();
        let records = total.div_ceil(MAX_RECORD_PLAINTEXT);
        out.reserve(total + records * (2 + TAG_BYTES));
        let mut parts = parts.iter().copied().filter(|part| !part.is_empty());
        let mut current: &[u8] = parts.next().unwrap_or_default();
        let mut left = total;
        while left > 0 {
            let take = left.min(MAX_RECORD_PLAINTEXT);
            out.extend_from_slice(&((take + TAG_BYTES) as u16).to_le_bytes());
            let start = out.len();
            let mut wanted = take;
            while wanted > 0 {
                if current.is_empty() {
                    current = parts.next().unwrap_or_default();
                }
                let n = wanted.min(current.len());
                out.extend_from_slice(&current[..n]);
                current = &current[n..];
                wanted -= n;
            }
            let tag = self.seal_in_place(&mut out[start..]);
            out.extend_from_slice(tag.as_ref());
            left -= take;
        }
    }
}

/// Decrypts what the peer sends: ciphertext is read into its own buffer, each whole record is
/// opened in place there, and its plaintext handed out.
pub struct Opener {
    key: AeadKey,
    nonce: u64,
    buf: Vec<u8>,
    /// Ciphertext not yet opened is `buf[start..end]`.
    start: usize,
    end: usize,
    /// The opened plaintext not yet handed out.
    plain: std::ops::Range<usize>,
}

impl fmt::Debug for Opener {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Opener")
            .field("nonce", &self.nonce)
            .finish()
    }
}

/// Room for eight whole records: reads are large (each asks for at least half of this), and a
/// record always fits after a compaction.
const OPENER_BYTES: usize = 8 * (2 + MAX_RECORD_BYTES);

fn bad_record() -> io::Error {
    io::Error::new(
        io::ErrorKind::InvalidData,
        "an encrypted record failed authentication (altered, or not from the peer)",
    )
}

impl Opener {
    fn new(key: &[u8; 32]) -> Opener {
        Opener {
            key: AeadKey::new(key),
            nonce: 0,
            buf: Vec::new(),
            start: 0,
            end: 0,
            plain: 0..0,
        }
    }

    fn open_message(&mut self, message: &mut [u8]) -> Option<usize> {
        let nonce = noise_nonce(self.nonce);
        self.nonce += 1;
        let plain = self
            .key
            .0
            .open_in_place(nonce, Aad::empty(), message)
            .ok()?;
        Some(plain.len())
    }

    /// Ciphertext that arrived before this opener took over the connection.
    pub fn push_ciphertext(&mut self, bytes: &[u8]) {
        self.make_room(bytes.len());
        self.buf[self.end..self.end + bytes.len()].copy_from_slice(bytes);
        self.end += bytes.len();
    }

    fn make_room(&mut self, want: usize) {
        if self.plain.is_empty() && self.start > 0 && self.buf.len() - self.end < want {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
            self.plain = 0..0;
        }
        if self.buf.len() - self.end < want {
            self.buf.resize(self.end + want, 0);
        }
    }

    /// Opens the next whole record, if one is buffered.
    fn open_next(&mut self) -> io::Result<bool> {
        let buffered = self.end - self.start;
        if buffered < 2 {
            return Ok(false);
        }
        let len = usize::from(u16::from_le_bytes([
            self.buf[self.start],
            self.buf[self.start + 1],
        ]));
        if len < TAG_BYTES {
            return Err(bad_record());
        }
        if buffered < 2 + len {
            return Ok(false);
        }
        let body = self.start + 2;
        let nonce = noise_nonce(self.nonce);
        self.nonce += 1;
        let plain_len = self
            .key
            .0
            .open_in_place(nonce, Aad::empty(), &mut self.buf[body..body + len])
            .map_err(|_| bad_record())?
            .len();
        self.plain = body..body + plain_len;
        self.start = body + len;
        Ok(true)
    }

    /// Reads plaintext into `out` through this opener from `source`. Like a socket read, it
    /// returns less than `out` holds only when `source` has nothing more now (or is closed),
    /// so that a short read still means "drained" to an edge-triggered poll.
    ///
    /// A blocking source (`blocking`) returns as soon as some plaintext is there, as a
    /// blocking socket's read does.
    pub fn read_via(
        &mut self,
        source: &mut impl Read,
        out: &mut [u8],
        blocking: bool,
    ) -> io::Result<usize> {
        let mut filled = 0;
        loop {
            if !self.plain.is_empty() {
                let n = self.plain.len().min(out.len() - filled);
                out[filled..filled + n]
                    .copy_from_slice(&self.buf[self.plain.start..self.plain.start + n]);
                self.plain.start += n;
                filled += n;
                if filled == out.len() || blocking {
                    return Ok(filled);
                }
            }
            if self.open_next()? {
                continue;
            }
            self.make_room(OPENER_BYTES / 2);
            match source.read(&mut self.buf[self.end..]) {
                Ok(0) if filled > 0 => return Ok(filled),
                Ok(0) => return Ok(0),
                Ok(got) => self.end += got,
                Err(err) if err.kind() == io::ErrorKind::WouldBlock && filled > 0 => {
                    return Ok(filled);
                }
                Err(err) if err.kind() == io::ErrorKind::Interrupted => {}
                Err(err) => return Err(err),
            }
        }
    }

    /// Whether plaintext, or a whole record, waits here (to be read before the socket says
    /// more has come).
    pub fn has_buffered(&self) -> bool {
        if !self.plain.is_empty() {
            return true;
        }
        let buffered = self.end - self.start;
        buffered >= 2
            && buffered
                >= 2 + usize::from(u16::from_le_bytes([
                    self.buf[self.start],
                    self.buf[self.start + 1],
                ]))
    }

    /// Gives storage back when idle.
    pub fn shrink_if_idle(&mut self) {
        if self.start == self.end && self.plain.is_empty() {
            self.start = 0;
            self.end = 0;
            if self.buf.len() > OPENER_BYTES {
                self.buf = Vec::new();
            }
        }
    }
}

/// A `Read` over a source through an [`Opener`].
pub struct OpenedReader<'a, R> {
    pub opener: &'a mut Opener,
    pub source: &'a mut R,
    pub blocking: bool,
}

impl<R: Read> Read for OpenedReader<'_, R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.opener.read_via(self.source, buf, self.blocking)
    }
}

/// What a connection writes through: the socket itself, or, once the link is encrypted,
/// records sealed from what is written. Bytes written before sealing starts (the handshake's
/// own frames, counted by `raw_budget`) go out as they are.
#[derive(Debug)]
pub struct SealedWriter<W> {
    pub inner: W,
    sealer: Option<Sealer>,
    raw_budget: usize,
    /// Sealed records not yet taken by `inner`.
    pending: Vec<u8>,
    written: usize,
}

/// How much plaintext one write seals at most: a few records, so that a reliable subscriber's
/// backlog stays in the connection's own queue rather than here.
const SEAL_CHUNK_BYTES: usize = 4 * MAX_RECORD_PLAINTEXT;

impl<W: Write> SealedWriter<W> {
    pub fn new(inner: W) -> Self {
        SealedWriter {
            inner,
            sealer: None,
            raw_budget: 0,
            pending: Vec::new(),
            written: 0,
        }
    }

    /// From now on, the first `raw_bytes` written go out as they are, the rest sealed.
    pub fn start_sealing(&mut self, sealer: Sealer, raw_bytes: usize) {
        self.sealer = Some(sealer);
        self.raw_budget = raw_bytes;
    }

    pub fn is_sealing(&self) -> bool {
        self.sealer.is_some()
    }

    /// Sealed bytes waiting for the socket.
    pub fn pending_bytes(&self) -> usize {
        self.pending.len() - self.written
    }

    /// Seals a whole frame, given in `parts`, straight into what waits for the socket (one copy
    /// instead of two through the connection's own queue); only when sealing is under way and
    /// nothing else waits. `false` when it could not.
    pub fn seal_frame(&mut self, parts: &[&[u8]]) -> bool {
        match &mut self.sealer {
            Some(sealer) if self.raw_budget == 0 && self.pending.is_empty() => {
                sealer.seal_parts(parts, &mut self.pending);
                true
            }
            _ => false,
        }
    }

    /// Writes what is sealed and waiting; `Ok(true)` when nothing is left.
    pub fn flush_pending(&mut self) -> io::Result<bool> {
        while self.written < self.pending.len() {
            match self.inner.write(&self.pending[self.written..]) {
                Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
                Ok(n) => self.written += n,
                Err(err) if err.kind() == io::ErrorKind::WouldBlock => return Ok(false),
                Err(err) if err.kind() == io::ErrorKind::Interrupted => {}
                Err(err) => return Err(err),
            }
        }
        self.pending.clear();
        self.written = 0;
        Ok(true)
    }
}

impl<W: Write> Write for SealedWriter<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.sealer.is_none() {
            return self.inner.write(buf);
        }
        if self.raw_budget > 0 {
            let take = buf.len().min(self.raw_budget);
            let n = self.inner.write(&buf[..take])?;
            self.raw_budget -= n;
            return Ok(n);
        }
        if !self.flush_pending()? {
            return Err(io::ErrorKind::WouldBlock.into());
        }
        let take = buf.len().min(SEAL_CHUNK_BYTES);
        if let Some(sealer) = &mut self.sealer {
            sealer.seal_records(&buf[..take], &mut self.pending);
        }
        // What the socket does not take now waits here, and goes first at the next write.
        match self.flush_pending() {
            Ok(_) => Ok(take),
            Err(err) if err.kind() == io::ErrorKind::WouldBlock => Ok(take),
            Err(err) => Err(err),
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        // A blocking writer never says "would block"; a non-blocking one is flushed by its
        // event loop instead.
        if self.flush_pending()? {
            self.inner.flush()
        } else {
            Err(io::ErrorKind::WouldBlock.into())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn secret() -> Secret {
        Secret::from_bytes(b"0123456789abcdef0123456789abcdef")
    }

    /// Runs a whole handshake in memory.
    fn handshake(dial: &Dial, listen: &Listen) -> Result<(Session, Session), AuthError> {
        let (dialer, first) = Dialer::start(dial)?;
        let (listener, answer, listener_sealer) = Listener::accept(listen, &first)?;
        let (confirm, dialer_session) = dialer.finish(&answer)?;
        let mut listener_session = listener.confirm(&confirm)?;
        listener_session.sealer = listener_sealer;
        Ok((dialer_session, listener_session))
    }

    fn dial(key: Key, identity: &str, encrypt: bool) -> Dial {
        Dial {
            key,
            identity: identity.into(),
            encrypt,
        }
    }

    #[test]
    fn a_module_proves_its_own_name_and_no_other() {
        let secret = secret();
        let listen = Listen {
            admit: Admit::Modules(secret.clone()),
            encrypt: false,
        };
        let (_, agent) = handshake(&dial(secret.module_key("nav"), "nav", false), &listen)
            .expect("its own name");
        assert_eq!(agent.peer.as_deref(), Some("nav"));
        // The key of `nav` does not pass as `sim`; nor does another secret's key.
        let err = handshake(&dial(secret.module_key("nav"), "sim", false), &listen)
            .expect_err("another name");
        assert!(matches!(err, AuthError::WrongKey(name) if name == "sim"));
        let stranger = Secret::from_bytes(b"another secret, just as long ...");
        assert!(handshake(&dial(stranger.module_key("nav"), "nav", false), &listen).is_err());
    }

    #[test]
    fn a_data_port_admits_the_holders_of_its_link_keys() {
        let secret = secret();
        let provider = secret.module_key("sim");
        let listen = Listen {
            admit: Admit::LinksTo(provider.clone()),
            encrypt: false,
        };
        let ticket = provider.link_key("nav");
        assert!(handshake(&dial(ticket.clone(), "nav", false), &listen).is_ok());
        assert!(handshake(&dial(ticket.clone(), "observer", false), &listen).is_err());
        // A module's own key is no ticket to another's port.
        assert!(handshake(&dial(secret.module_key("nav"), "nav", false), &listen).is_err());
        // The ticket admits one direction: `sim` subscribing back on nav's connection proves
        // the ticket the agent gave it for nav's port, bound to this connection.
        let (nav, sim) = handshake(&dial(ticket.clone(), "nav", false), &listen).expect("link");
        assert_eq!(nav.binding, sim.binding);
        let back = secret.module_key("nav").link_key("sim");
        let proof = reverse_proof(&back, &sim.binding);
        assert!(check_reverse_proof(&back, &nav.binding, &proof));
        // Its own ticket is no proof, nor is a proof made for another connection.
        assert!(!check_reverse_proof(
            &back,
            &nav.binding,
            &reverse_proof(&ticket, &sim.binding)
        ));
        let (other, _) = handshake(&dial(ticket, "nav", false), &listen).expect("again");
        assert!(!check_reverse_proof(&back, &other.binding, &proof));
    }

    #[test]
    fn a_replayed_first_message_never_gets_past_the_confirmation() {
        let secret = secret();
        let listen = Listen {
            admit: Admit::Modules(secret.clone()),
            encrypt: false,
        };
        let (dialer, first) =
            Dialer::start(&dial(secret.module_key("nav"), "nav", false)).expect("start");
        let (listener, answer, _) = Listener::accept(&listen, &first).expect("accept");
        let (confirm, _) = dialer.finish(&answer).expect("finish");
        listener.confirm(&confirm).expect("the genuine dialer");
        // The same first message again is answered (it proves only the key), but the old
        // confirmation does not fit the new session, and without the ephemeral key no new
        // one can be made.
        let (replayed, _, _) = Listener::accept(&listen, &first).expect("a replay is answered");
        assert!(replayed.confirm(&confirm).is_err());
    }

    #[test]
    fn the_listener_cannot_be_turned_into_an_oracle() {
        // A listener only ever answers as the Noise responder: its answer is no first message,
        // so it cannot be passed to another listener as the dialer's.
        let secret = secret();
        let listen = Listen {
            admit: Admit::Modules(secret.clone()),
            encrypt: false,
        };
        let (_, first) =
            Dialer::start(&dial(secret.module_key("nav"), "nav", false)).expect("start");
        let (_, answer, _) = Listener::accept(&listen, &first).expect("accept");
        let mut forged = vec![3];
        forged.extend_from_slice(b"nav");
        forged.extend_from_slice(&answer);
        assert!(Listener::accept(&listen, &forged).is_err());
    }

    fn round_trip(sending: &mut Session, receiving: &mut Session) {
        let plain: Vec<u8> = (0..200_000).map(|i| (i % 253) as u8).collect();
        let mut wire = Vec::new();
        sending
            .sealer
            .as_mut()
            .expect("sealed")
            .seal_records(&plain, &mut wire);
        assert!(!wire.windows(64).any(|w| w == &plain[1000..1064]));
        let opener = receiving.opener.as_mut().expect("opened");
        let mut source = &wire[..];
        let mut got = vec![0; plain.len()];
        let mut filled = 0;
        while filled < got.len() {
            filled += opener
                .read_via(&mut source, &mut got[filled..], false)
                .expect("open");
        }
        assert_eq!(got, plain);
    }

    #[test]
    fn encryption_is_used_when_either_side_asks_and_records_round_trip() {
        let secret = secret();
        for (dialer_asks, listener_insists) in [(true, false), (false, true), (true, true)] {
            let listen = Listen {
                admit: Admit::Modules(secret.clone()),
                encrypt: listener_insists,
            };
            let (mut dialer, mut listener) =
                handshake(&dial(secret.module_key("a"), "a", dialer_asks), &listen)
                    .expect("handshake");
            round_trip(&mut dialer, &mut listener);
            round_trip(&mut listener, &mut dialer);
        }
        let listen = Listen {
            admit: Admit::Modules(secret.clone()),
            encrypt: false,
        };
        let (dialer, listener) =
            handshake(&dial(secret.module_key("a"), "a", false), &listen).expect("handshake");
        assert!(dialer.sealer.is_none() && listener.opener.is_none());
    }

    #[test]
    fn a_frame_in_parts_is_sealed_as_one_stream() {
        let secret = secret();
        let listen = Listen {
            admit: Admit::Modules(secret.clone()),
            encrypt: true,
        };
        let (mut dialer, mut listener) =
            handshake(&dial(secret.module_key("a"), "a", false), &listen).expect("handshake");
        let header: Vec<u8> = (0..21).collect();
        let payload: Vec<u8> = (0..3 * MAX_RECORD_PLAINTEXT + 5)
            .map(|i| (i % 249) as u8)
            .collect();
        let mut wire = Vec::new();
        let sealer = dialer.sealer.as_mut().expect("sealed");
        sealer.seal_parts(&[&header, &[], &payload], &mut wire);
        sealer.seal_records(b"next", &mut wire);
        let whole: Vec<u8> = [&header[..], &payload, b"next"].concat();
        let opener = listener.opener.as_mut().expect("opened");
        let mut got = vec![0; whole.len()];
        let mut filled = 0;
        let mut source = &wire[..];
        while filled < got.len() {
            filled += opener
                .read_via(&mut source, &mut got[filled..], false)
                .expect("open");
        }
        assert_eq!(got, whole);
    }

    #[test]
    fn an_altered_record_is_refused() {
        let secret = secret();
        let listen = Listen {
            admit: Admit::Modules(secret.clone()),
            encrypt: true,
        };
        let (mut dialer, mut listener) =
            handshake(&dial(secret.module_key("a"), "a", false), &listen).expect("handshake");
        let mut wire = Vec::new();
        dialer
            .sealer
            .as_mut()
            .expect("sealed")
            .seal_records(b"move to (3, 4)", &mut wire);
        wire[5] ^= 1;
        let mut out = [0; 64];
        let err = listener
            .opener
            .as_mut()
            .expect("opened")
            .read_via(&mut &wire[..], &mut out, false)
            .expect_err("altered");
        assert_eq!(err.kind(), io::ErrorKind::InvalidData);
    }

    #[test]
    fn keys_are_derived_per_name_and_read_back_from_hex() {
        let secret = secret();
        assert_ne!(secret.module_key("a"), secret.module_key("b"));
        assert_ne!(secret.module_key("a"), secret.operator_key());
        let key = secret.module_key("a");
        assert_eq!(Key::from_hex(&key.to_hex()), Some(key.clone()));
        assert_eq!(Key::from_hex("00"), None);
        assert_eq!(format!("{key:?}"), "Key(..)");
    }

    #[test]
    fn secret_files_must_be_private_and_long_enough() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().expect("dir");
        let file = dir.path().join("secret");
        std::fs::write(&file, "0123456789abcdef0123456789abcdef\n").expect("write");
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o644)).expect("chmod");
        let err = Secret::load(&file).expect_err("exposed");
        assert!(err.to_string().contains("mode 644"), "{err}");
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).expect("chmod");
        let secret = Secret::load(&file).expect("private");
        // The trailing line break is not part of the secret.
        assert_eq!(
            secret.module_key("x"),
            Secret::from_bytes(b"0123456789abcdef0123456789abcdef").module_key("x")
        );
        std::fs::write(&file, "short\n").expect("write");
        let err = Secret::load(&file).expect_err("short");
        assert!(err.to_string().contains("5 bytes long"), "{err}");
        // Twenty bytes were enough before: no longer, whatever they are.
        std::fs::write(&file, "0123456789abcdef0123\n").expect("write");
        let err = Secret::load(&file).expect_err("short");
        assert!(err.to_string().contains("20 bytes long"), "{err}");
        assert!(err.to_string().contains("--passphrase"), "{err}");
        let err = Secret::load(&dir.path().join("none")).expect_err("missing");
        assert!(err.to_string().contains("cannot read"), "{err}");
        // A role's key file is held to the same rule, through the same check.
        let role = dir.path().join("role");
        std::fs::write(&role, "observer 00\n").expect("write");
        std::fs::set_permissions(&role, std::fs::Permissions::from_mode(0o640)).expect("chmod");
        let err = RoleKey::load(&role).expect_err("exposed");
        assert!(err.to_string().contains("mode 640"), "{err}");
    }

    #[test]
    fn a_passphrase_is_stretched_the_same_way_everywhere_and_the_salt_matters() {
        let salt = [7; SALT_BYTES];
        let one = stretch_passphrase(b"correct horse", &salt).expect("stretch");
        assert_eq!(
            one,
            stretch_passphrase(b"correct horse", &salt).expect("again")
        );
        assert_ne!(
            one,
            stretch_passphrase(b"correct horse", &[8; SALT_BYTES]).expect("salt")
        );
        assert_ne!(
            one,
            stretch_passphrase(b"correct horsf", &salt).expect("word")
        );
    }
}
