//! The trust model over zenoh: the run's Noise keys and roles, end to end between a station
//! and a robot's bridge.
//!
//! A station proves a role (`observer` or `operator`) to one robot's bridge with the Noise
//! handshake the control link uses (`Noise_NNpsk0`, the role's key as the pre-shared key),
//! carried in one zenoh query: the station's first message goes out as the query's payload and
//! the bridge's answer comes back as its reply. The prologue binds the session to the robot's
//! name and the role, so a hello recorded on the way to one robot proves nothing to another,
//! and an observer's key cannot claim the operator's role. Whoever holds neither key gets no
//! answer at all.
//!
//! Samples then travel sealed with the session's keys. A radio loses and, through relays,
//! reorders samples, which the control link's implicit nonces would take for an attack: so
//! each sample carries its nonce (Noise's stateless transport) and the receiver keeps a window
//! of the last [`WINDOW`] nonces, which refuses a replay but takes a sample that overtook
//! another.

use armor_module_api::auth::{KEY_BYTES, Key, Role, unhex};

/// The Noise pattern of the control link's handshake, reused as it is.
pub const PATTERN: &str = "Noise_NNpsk0_25519_AESGCM_SHA256";
/// What the prologue starts with, so that no handshake of another ArMoR link passes for one
/// of the team's.
const PROLOGUE_LABEL: &[u8] = b"ARMOR-TEAM/1 ";
/// Noise's limit on one message.
const MAX_MESSAGE_BYTES: usize = 65535;
/// The AEAD tag each sealed sample carries.
const TAG_BYTES: usize = 16;
/// How far behind the newest nonce a sample may arrive and still be taken.
pub const WINDOW: u64 = 64;

/// Why a handshake or a sample was refused. None of them tells the peer anything.
#[derive(Debug, thiserror::Error)]
pub enum SealError {
    #[error("the hello is malformed: {0}")]
    Malformed(&'static str),
    #[error("the peer does not hold the key of the role `{0}`")]
    WrongKey(String),
    #[error("the sample is too short to hold a nonce and a tag")]
    Short,
    #[error("the sample's nonce {0} was seen already or is too old (a replay)")]
    Replayed(u64),
    #[error("the sample does not open with this session's key: changed, or not for it")]
    Forged,
    #[error("the sample is larger than a Noise message ({0} bytes)")]
    TooLarge(usize),
    #[error("handshake: {0}")]
    Noise(#[from] snow::Error),
}

fn key_bytes(key: &Key) -> [u8; KEY_BYTES] {
    // A key's hex form is always 64 digits, which read back whole.
    unhex(&key.to_hex()).unwrap_or([0; KEY_BYTES])
}

fn prologue(robot: &str, role: Role) -> Vec<u8> {
    let mut prologue = PROLOGUE_LABEL.to_vec();
    for part in [robot, role.as_str()] {
        // Robot names are checked to be short identifiers (`crate::check_robot_name`).
        prologue.push(part.len().min(255) as u8);
        prologue.extend_from_slice(part.as_bytes());
    }
    prologue
}

fn builder<'a>(
    psk: &'a [u8; KEY_BYTES],
    prologue: &'a [u8],
) -> Result<snow::Builder<'a>, SealError> {
    Ok(snow::Builder::new(PATTERN.parse()?)
        .psk(0, psk)?
        .prologue(prologue)?)
}

/// A station's side of a handshake, waiting for the robot's answer.
pub struct Hello {
    handshake: snow::HandshakeState,
    pub role: Role,
}

impl std::fmt::Debug for Hello {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Hello").field("role", &self.role).finish()
    }
}

impl Hello {
    /// Starts a handshake with `robot` as `role`; the bytes are the query's payload: the role's
    /// name (length first) and the Noise message `psk, e`.
    pub fn start(robot: &str, role: Role, key: &Key) -> Result<(Hello, Vec<u8>), SealError> {
        let psk = key_bytes(key);
        let prologue = prologue(robot, role);
        let mut handshake = builder(&psk, &prologue)?.build_initiator()?;
        let mut body = vec![role.as_str().len() as u8];
        body.extend_from_slice(role.as_str().as_bytes());
        let mut message = [0; 128];
        let len = handshake.write_message(&[], &mut message)?;
        body.extend_from_slice(&message[..len]);
        Ok((Hello { handshake, role }, body))
    }

    /// Takes the robot's answer, which proves it holds the role's key too: the session.
    pub fn finish(mut self, answer: &[u8]) -> Result<Channel, SealError> {
        let mut payload = [0; 128];
        self.handshake
            .read_message(answer, &mut payload)
            .map_err(|_| SealError::WrongKey(self.role.as_str().to_owned()))?;
        Ok(Channel::new(
            self.handshake.into_stateless_transport_mode()?,
        ))
    }
}

/// The keys a robot's bridge admits stations with: one per role, both derived from the run's
/// secret (`Secret::role_key`), so a station proves the same role key as at the control link.
#[derive(Clone, Debug)]
pub struct Admit {
    pub operator: Key,
    pub observer: Key,
}

/// A robot's answer to a station's hello: the role it proved, the session, and the reply.
pub fn accept(
    robot: &str,
    admit: &Admit,
    body: &[u8],
) -> Result<(Role, Channel, Vec<u8>), SealError> {
    let (&len, rest) = body
        .split_first()
        .ok_or(SealError::Malformed("an empty hello"))?;
    let len = usize::from(len);
    if rest.len() < len {
        return Err(SealError::Malformed("a role's name cut short"));
    }
    let (role, message) = rest.split_at(len);
    let role = std::str::from_utf8(role)
        .ok()
        .and_then(Role::parse)
        .ok_or(SealError::Malformed("a role, `observer` or `operator`"))?;
    let psk = key_bytes(match role {
        Role::Operator => &admit.operator,
        Role::Observer => &admit.observer,
    });
    let prologue = prologue(robot, role);
    let mut handshake = builder(&psk, &prologue)?.build_responder()?;
    let mut payload = [0; 128];
    handshake
        .read_message(message, &mut payload)
        .map_err(|_| SealError::WrongKey(role.as_str().to_owned()))?;
    let mut answer = [0; 128];
    let len = handshake.write_message(&[], &mut answer)?;
    Ok((
        role,
        Channel::new(handshake.into_stateless_transport_mode()?),
        answer[..len].to_vec(),
    ))
}

/// The nonces seen lately, newest first as bits: a replay is refused, a late sample taken once.
#[derive(Debug, Default)]
struct Window {
    newest: Option<u64>,
    /// Bit `i`: nonce `newest - i` was taken.
    seen: u64,
}

impl Window {
    fn fresh(&self, nonce: u64) -> bool {
        match self.newest {
            None => true,
            Some(newest) if nonce > newest => true,
            Some(newest) => {
                let behind = newest - nonce;
                behind < WINDOW && self.seen & (1 << behind) == 0
            }
        }
    }

    fn mark(&mut self, nonce: u64) {
        match self.newest {
            Some(newest) if nonce <= newest => self.seen |= 1 << (newest - nonce),
            Some(newest) => {
                let ahead = nonce - newest;
                self.seen = if ahead >= WINDOW {
                    0
                } else {
                    self.seen << ahead
                };
                self.seen |= 1;
                self.newest = Some(nonce);
            }
            None => {
                self.seen = 1;
                self.newest = Some(nonce);
            }
        }
    }
}

/// A session's two directions: samples this side seals, and those it opens.
pub struct Channel {
    transport: snow::StatelessTransportState,
    next_nonce: u64,
    window: Window,
    /// Samples opened, and one past the highest nonce opened: the peer numbers every sample it
    /// seals, so their difference is what was lost on the way (the link's quality).
    opened: u64,
    sent: u64,
}

impl std::fmt::Debug for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Channel")
            .field("next_nonce", &self.next_nonce)
            .finish()
    }
}

impl Channel {
    fn new(transport: snow::StatelessTransportState) -> Channel {
        Channel {
            transport,
            next_nonce: 0,
            window: Window::default(),
            opened: 0,
            sent: 0,
        }
    }

    /// `plain` sealed: its nonce (8 bytes, big-endian), then the ciphertext and its tag.
    pub fn seal(&mut self, plain: &[u8]) -> Result<Vec<u8>, SealError> {
        if plain.len() + TAG_BYTES > MAX_MESSAGE_BYTES {
            return Err(SealError::TooLarge(plain.len()));
        }
        let nonce = self.next_nonce;
        self.next_nonce += 1;
        let mut sealed = vec![0; 8 + plain.len() + TAG_BYTES];
        sealed[..8].copy_from_slice(&nonce.to_be_bytes());
        let len = self
            .transport
            .write_message(nonce, plain, &mut sealed[8..])?;
        sealed.truncate(8 + len);
        Ok(sealed)
    }

    /// Opens a sample the peer sealed; refuses one changed, forged, replayed or too old.
    pub fn open(&mut self, sealed: &[u8]) -> Result<Vec<u8>, SealError> {
        if sealed.len() < 8 + TAG_BYTES {
            return Err(SealError::Short);
        }
        if sealed.len() > 8 + MAX_MESSAGE_BYTES {
            return Err(SealError::TooLarge(sealed.len()));
        }
        let (nonce, cipher) = sealed.split_at(8);
        let mut bytes = [0; 8];
        bytes.copy_from_slice(nonce);
        let nonce = u64::from_be_bytes(bytes);
        if !self.window.fresh(nonce) {
            return Err(SealError::Replayed(nonce));
        }
        let mut plain = vec![0; cipher.len()];
        let len = self
            .transport
            .read_message(nonce, cipher, &mut plain)
            .map_err(|_| SealError::Forged)?;
        plain.truncate(len);
        self.window.mark(nonce);
        self.opened += 1;
        self.sent = self.sent.max(nonce + 1);
        Ok(plain)
    }

    /// The samples opened so far, and those the peer sealed up to the latest opened (received
    /// or not).
    pub fn counts(&self) -> (u64, u64) {
        (self.opened, self.sent)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::auth::Secret;

    fn admit(secret: &Secret) -> Admit {
        Admit {
            operator: secret.role_key(Role::Operator),
            observer: secret.role_key(Role::Observer),
        }
    }

    fn pair(robot: &str, role: Role, secret: &Secret) -> Result<(Channel, Channel), SealError> {
        let (hello, body) = Hello::start(robot, role, &secret.role_key(role))?;
        let (proved, at_robot, answer) = accept(robot, &admit(secret), &body)?;
        assert_eq!(proved, role);
        Ok((hello.finish(&answer)?, at_robot))
    }

    #[test]
    fn the_samples_lost_on_the_way_are_counted_from_their_numbers() {
        let secret = Secret::from_bytes(&[9; 32]);
        let (mut station, mut robot) = pair("r1", Role::Observer, &secret).expect("a session");
        let sealed: Vec<Vec<u8>> = (0..6).map(|i| robot.seal(&[i]).expect("sealed")).collect();
        assert_eq!(station.counts(), (0, 0));
        // The radio loses the third and the last; the fifth overtakes the fourth.
        for i in [0, 1, 4, 3] {
            station.open(&sealed[i]).expect("opens");
        }
        assert_eq!(station.counts(), (4, 5), "4 of the first 5 received");
        // A replay is refused and not counted.
        assert!(station.open(&sealed[1]).is_err());
        assert_eq!(station.counts(), (4, 5));
    }

    #[test]
    fn both_roles_open_a_session_and_samples_pass_both_ways() {
        let secret = Secret::from_bytes(&[7; 32]);
        for role in [Role::Observer, Role::Operator] {
            let (mut station, mut robot) = pair("r1", role, &secret).expect("a session");
            let sealed = robot.seal(b"status").expect("sealed");
            assert!(
                !sealed.windows(6).any(|w| w == b"status"),
                "sealed in clear"
            );
            assert_eq!(station.open(&sealed).expect("opens"), b"status");
            let sealed = station.seal(b"beat").expect("sealed");
            assert_eq!(robot.open(&sealed).expect("opens"), b"beat");
        }
    }

    #[test]
    fn a_stranger_an_observer_claiming_operator_and_another_robot_are_refused() {
        let secret = Secret::from_bytes(&[7; 32]);
        let stranger = Secret::from_bytes(&[8; 32]);
        let (_, body) =
            Hello::start("r1", Role::Operator, &stranger.role_key(Role::Operator)).expect("hello");
        assert!(matches!(
            accept("r1", &admit(&secret), &body),
            Err(SealError::WrongKey(_))
        ));
        // An observer's key, claiming the operator's role.
        let (_, body) =
            Hello::start("r1", Role::Operator, &secret.role_key(Role::Observer)).expect("hello");
        assert!(matches!(
            accept("r1", &admit(&secret), &body),
            Err(SealError::WrongKey(_))
        ));
        // A hello for r1, shown to r2.
        let (_, body) =
            Hello::start("r1", Role::Operator, &secret.role_key(Role::Operator)).expect("hello");
        assert!(matches!(
            accept("r2", &admit(&secret), &body),
            Err(SealError::WrongKey(_))
        ));
        for broken in [
            &b""[..],
            &[9, b'o'],
            &[8, b'o', b'p', b'e', b'r', b'a', b't', b'o', b'r'],
        ] {
            assert!(accept("r1", &admit(&secret), broken).is_err());
        }
    }

    #[test]
    fn replays_and_forgeries_are_refused_and_late_samples_taken_once() {
        let secret = Secret::from_bytes(&[7; 32]);
        let (mut station, mut robot) = pair("r1", Role::Operator, &secret).expect("a session");
        let first = robot.seal(b"one").expect("sealed");
        let second = robot.seal(b"two").expect("sealed");
        assert_eq!(station.open(&second).expect("opens"), b"two");
        // Overtaken on the way: still taken, once.
        assert_eq!(station.open(&first).expect("opens"), b"one");
        assert!(matches!(station.open(&first), Err(SealError::Replayed(0))));
        assert!(matches!(station.open(&second), Err(SealError::Replayed(1))));
        let mut changed = robot.seal(b"three").expect("sealed");
        let last = changed.len() - 1;
        changed[last] ^= 1;
        assert!(matches!(station.open(&changed), Err(SealError::Forged)));
        assert!(matches!(station.open(&[0; 10]), Err(SealError::Short)));
        // Far behind the window: refused.
        let old = robot.seal(b"old").expect("sealed");
        for _ in 0..WINDOW {
            let newer = robot.seal(b"newer").expect("sealed");
            station.open(&newer).expect("opens");
        }
        assert!(matches!(station.open(&old), Err(SealError::Replayed(_))));
    }
}
