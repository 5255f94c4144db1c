//! Framing: the bytes on every ArMoR TCP connection (documented in `docs/protocol.md`).
//!
//! A connection starts with both sides sending a 6-byte hello, `ARMR` followed by the protocol
//! version as a little-endian `u16`. After it come frames: a little-endian `u32` length (of what
//! follows it), one kind byte, then the payload. The length is checked against
//! [`MAX_FRAME_BYTES`] before anything is allocated, so a peer announcing 4 GiB costs nothing.
//!
//! With a shared secret ([`crate::auth`]), the dialer sends the first Noise handshake message
//! right after its hello, the listener answers, and the dialer confirms; neither takes any other
//! frame before. On an encrypted link each side's bytes after its last handshake frame are
//! records ([`crate::auth::Sealer`]) that carry the frames.

use std::collections::VecDeque;
use std::io::{self, Read, Write};

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::auth::{
    AuthError, Dial, Dialer, Listen, Listener, MAX_HANDSHAKE_BYTES, OpenedReader, Opener, Sealer,
};

pub const MAGIC: [u8; 4] = *b"ARMR";
pub const VERSION: u16 = 1;
pub const HELLO: [u8; 6] = [
    MAGIC[0],
    MAGIC[1],
    MAGIC[2],
    MAGIC[3],
    VERSION as u8,
    (VERSION >> 8) as u8,
];
/// Largest frame (kind byte and payload) a peer may send.
pub const MAX_FRAME_BYTES: usize = 64 * 1024 * 1024;

/// A control message, as UTF-8 JSON (see [`crate::protocol`]).
pub const KIND_MESSAGE: u8 = 1;
/// A data sample: `seq: u64 LE`, `stamp_ns: u64 LE`, then the encoded datum.
pub const KIND_DATA: u8 = 2;
const DATA_HEADER_BYTES: usize = 16;
/// The dialer's first handshake message: its identity, then Noise's `psk, e`.
pub const KIND_HANDSHAKE_FIRST: u8 = 3;
/// The listener's answer: Noise's `e, ee`.
pub const KIND_HANDSHAKE_ANSWER: u8 = 4;
/// The dialer's confirmation: its first Noise transport message, empty.
pub const KIND_HANDSHAKE_CONFIRM: u8 = 5;
/// The most a reader takes from a peer before it has authenticated: a hello and a handshake
/// frame fit many times over.
const PREAUTH_READ_BYTES: usize = 1024;

#[derive(Debug, thiserror::Error)]
pub enum WireError {
    #[error("peer is not an ArMoR endpoint (bad hello {0:02x?})")]
    BadMagic([u8; 4]),
    #[error("peer speaks protocol version {0}, this side speaks {VERSION}")]
    BadVersion(u16),
    #[error("peer announced a frame of {0} bytes, more than the {MAX_FRAME_BYTES} allowed")]
    FrameTooLarge(usize),
    #[error("empty frame (no kind byte)")]
    EmptyFrame,
    #[error("unknown frame kind {0}")]
    UnknownKind(u8),
    #[error("data frame of {0} bytes is shorter than its 16-byte header")]
    ShortData(usize),
    #[error("bad message: {0}")]
    BadMessage(#[from] serde_json::Error),
    #[error("expected a control message, got a data frame")]
    UnexpectedData,
    #[error("connection closed")]
    Closed,
    #[error(
        "the peer asks for authentication and this side has no shared secret (armor run --secret FILE, or ARMOR_SECRET_FILE)"
    )]
    AuthNotConfigured,
    #[error("the peer sent {0} before authenticating: this side requires the shared secret")]
    Unauthenticated(&'static str),
    #[error("authentication failed: {0}")]
    AuthFailed(#[from] AuthError),
    #[error(
        "the peer closed the connection during the handshake: it does not take the key offered for `{0}` (another secret, or a name that is not this module's own)"
    )]
    HandshakeRefused(String),
    #[error("handshake frame of {0} bytes (at most {MAX_HANDSHAKE_BYTES})")]
    BadAuthFrame(usize),
    #[error(transparent)]
    Io(#[from] io::Error),
}

pub fn check_hello(hello: &[u8; 6]) -> Result<(), WireError> {
    let magic = [hello[0], hello[1], hello[2], hello[3]];
    if magic != MAGIC {
        return Err(WireError::BadMagic(magic));
    }
    let version = u16::from_le_bytes([hello[4], hello[5]]);
    if version != VERSION {
        return Err(WireError::BadVersion(version));
    }
    Ok(())
}

/// One decoded frame.
#[derive(Clone, Debug, PartialEq)]
pub enum Frame {
    Message(Vec<u8>),
    Data(DataFrame),
    /// A handshake frame (kind 3, 4 or 5), taken by the [`FrameReader`] itself.
    Handshake(u8, Vec<u8>),
    /// Not from the wire: the reader took a step of the handshake; get it with
    /// [`FrameReader::take_auth_step`].
    AuthStep,
}

/// What a step of the handshake asks of the connection.
#[derive(Debug, Default)]
pub struct AuthStep {
    /// Frame bytes to send now, as they are, before anything else.
    pub reply: Vec<u8>,
    /// Seal what this side sends after `reply`.
    pub sealer: Option<Sealer>,
    /// The handshake is over: the peer is authenticated.
    pub done: bool,
    /// The identity the dialer proved (on the listener's side).
    pub peer: Option<String>,
    /// The handshake's hash, once it is over ([`crate::auth::Session::binding`]).
    pub binding: Option<Vec<u8>>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct DataFrame {
    pub seq: u64,
    pub stamp_ns: u64,
    pub payload: Vec<u8>,
}

impl Frame {
    pub fn message<T: DeserializeOwned>(&self) -> Result<T, WireError> {
        match self {
            Frame::Message(json) => Ok(serde_json::from_slice(json)?),
            Frame::Data(_) => Err(WireError::UnexpectedData),
            Frame::Handshake(..) | Frame::AuthStep => Err(WireError::AuthNotConfigured),
        }
    }
}

/// Appends one message frame to `out`.
pub fn encode_message<T: Serialize>(out: &mut Vec<u8>, message: &T) -> Result<(), WireError> {
    let start = out.len();
    out.extend_from_slice(&[0; 4]);
    out.push(KIND_MESSAGE);
    serde_json::to_writer(&mut *out, message)?;
    finish_frame(out, start)
}

/// Appends one data frame to `out`; the payload is written by `write_payload`.
pub fn encode_data(
    out: &mut Vec<u8>,
    seq: u64,
    stamp_ns: u64,
    write_payload: impl FnOnce(&mut Vec<u8>) -> Result<(), WireError>,
) -> Result<(), WireError> {
    let start = out.len();
    out.extend_from_slice(&[0; 4]);
    out.push(KIND_DATA);
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&stamp_ns.to_le_bytes());
    if let Err(err) = write_payload(out) {
        out.truncate(start);
        return Err(err);
    }
    finish_frame(out, start)
}

/// Appends the header of a data frame whose `payload_len` bytes of payload follow separately
/// (written from the caller's buffer, not copied behind the header).
pub fn encode_data_header(
    out: &mut Vec<u8>,
    seq: u64,
    stamp_ns: u64,
    payload_len: usize,
) -> Result<(), WireError> {
    let len = 1 + DATA_HEADER_BYTES + payload_len;
    if len > MAX_FRAME_BYTES {
        return Err(WireError::FrameTooLarge(len));
    }
    out.extend_from_slice(&(len as u32).to_le_bytes());
    out.push(KIND_DATA);
    out.extend_from_slice(&seq.to_le_bytes());
    out.extend_from_slice(&stamp_ns.to_le_bytes());
    Ok(())
}

/// Appends a handshake frame to `out`.
pub fn encode_handshake(out: &mut Vec<u8>, kind: u8, body: &[u8]) {
    out.extend_from_slice(&(1 + body.len() as u32).to_le_bytes());
    out.push(kind);
    out.extend_from_slice(body);
}

fn finish_frame(out: &mut Vec<u8>, start: usize) -> Result<(), WireError> {
    let len = out.len() - start - 4;
    if len > MAX_FRAME_BYTES {
        out.truncate(start);
        return Err(WireError::FrameTooLarge(len));
    }
    out[start..start + 4].copy_from_slice(&(len as u32).to_le_bytes());
    Ok(())
}

/// Reassembles frames from a byte stream that arrives in arbitrary pieces (non-blocking sockets).
/// A reader made with [`FrameReader::expecting_hello`] first checks the peer's hello.
#[derive(Default)]
pub struct FrameReader {
    /// Initialised storage; the bytes received and not yet decoded are `buf[start..end]`. It is
    /// grown, never zeroed again, so a peer trickling bytes costs no more than their copy.
    buf: Vec<u8>,
    start: usize,
    end: usize,
    hello_pending: bool,
    /// A large data frame being read straight into its own payload buffer.
    large: Option<LargeFrame>,
    /// The last read filled less than the room it had: the socket was drained.
    drained: bool,
    /// This side's handshake, when the connection must authenticate.
    auth: Option<Box<AuthState>>,
    /// The step of the handshake the last [`Frame::AuthStep`] stands for.
    step: Option<AuthStep>,
    /// On an encrypted link, what opens the peer's records.
    opener: Option<Box<Opener>>,
}

enum AuthState {
    /// The dialer, waiting for the answer (boxed: a Noise handshake state is large).
    Dialer(Option<Box<Dialer>>),
    /// The listener, waiting for the first message.
    Listening(Listen),
    /// The listener, waiting for the confirmation.
    Answered(Option<Listener>),
    /// The peer is authenticated: ordinary frames may pass.
    Done,
}

/// A data frame whose payload is read directly where the receiver will keep it (no copy). The
/// payload's capacity is its final length and its length what has arrived: reads fill the
/// spare capacity, which is never zeroed first.
struct LargeFrame {
    seq: u64,
    stamp_ns: u64,
    payload: Vec<u8>,
    len: usize,
}

/// The most a single read reserves room for, whatever length a peer announces.
const MAX_READ_BYTES: usize = 16 * 1024 * 1024;
const MIN_READ_BYTES: usize = 64 * 1024;
/// An idle reader gives back storage beyond this.
const IDLE_KEEP_BYTES: usize = 4 * 1024 * 1024;
/// Data frames from this size on are read straight into their payload buffer.
const LARGE_FRAME_BYTES: usize = 256 * 1024;
/// Payloads from this size on are sent from the caller's bytes (see `Datum::split_encoding`).
pub const LARGE_PAYLOAD_BYTES: usize = LARGE_FRAME_BYTES;

impl FrameReader {
    /// For a new connection: the first six bytes must be a valid hello.
    pub fn expecting_hello() -> Self {
        Self {
            hello_pending: true,
            ..Self::default()
        }
    }

    /// For a connection this side opened, authenticating as `dial` says (when given): returns
    /// the reader and what to send first (the hello, and the first handshake frame). The
    /// answer comes out as [`Frame::AuthStep`]; nothing else passes before.
    pub fn dialer(dial: Option<&Dial>) -> Result<(Self, Vec<u8>), AuthError> {
        let mut greeting = HELLO.to_vec();
        let auth = match dial {
            Some(dial) => {
                let (dialer, first) = Dialer::start(dial)?;
                encode_handshake(&mut greeting, KIND_HANDSHAKE_FIRST, &first);
                Some(Box::new(AuthState::Dialer(Some(Box::new(dialer)))))
            }
            None => None,
        };
        let reader = Self {
            hello_pending: true,
            auth,
            ..Self::default()
        };
        Ok((reader, greeting))
    }

    /// For a connection this side accepted, admitting peers as `listen` says (when given): the
    /// dialer's first message and its confirmation come out as [`Frame::AuthStep`]s; nothing
    /// else passes before. This side sends its hello first ([`HELLO`]).
    pub fn listener(listen: Option<Listen>) -> Self {
        Self {
            hello_pending: true,
            auth: listen.map(|listen| Box::new(AuthState::Listening(listen))),
            ..Self::default()
        }
    }

    /// A reader that goes on where a blocking handshake left off: `leftover` are bytes read
    /// and not yet decoded (plaintext), `opener` opens the peer's records on an encrypted link.
    pub fn resume(leftover: &[u8], opener: Option<Opener>) -> Self {
        Self {
            buf: leftover.to_vec(),
            end: leftover.len(),
            opener: opener.map(Box::new),
            ..Self::default()
        }
    }

    /// The bytes read and not decoded, and the opener: for a blocking stream that takes the
    /// connection over once the handshake is done.
    pub fn into_parts(self) -> (Vec<u8>, Option<Opener>) {
        (
            self.buf[self.start..self.end].to_vec(),
            self.opener.map(|opener| *opener),
        )
    }

    /// The step of the handshake that the last [`Frame::AuthStep`] announced.
    pub fn take_auth_step(&mut self) -> AuthStep {
        self.step.take().unwrap_or_default()
    }

    /// Checks the peer's hello if it has arrived, and decodes nothing more; whether it has.
    pub fn take_hello(&mut self) -> Result<bool, WireError> {
        if self.hello_pending && self.end - self.start >= HELLO.len() {
            let mut hello = [0; 6];
            hello.copy_from_slice(&self.buf[self.start..self.start + HELLO.len()]);
            check_hello(&hello)?;
            self.start += HELLO.len();
            self.hello_pending = false;
        }
        Ok(!self.hello_pending)
    }

    /// Whether the hello is in and the handshake under way.
    pub fn hello_received_and_authenticating(&self) -> bool {
        !self.hello_pending && self.auth_pending()
    }

    /// Whether the connection is authenticated (or needs no authentication) and the hello in.
    pub fn is_open(&self) -> bool {
        !self.hello_pending && !self.auth_pending()
    }

    fn auth_pending(&self) -> bool {
        self.auth
            .as_ref()
            .is_some_and(|auth| !matches!(**auth, AuthState::Done))
    }

    /// Whether the last read found the socket drained (it returned less than it had room for),
    /// so that waiting for readiness is enough to learn of more data.
    pub fn drained(&self) -> bool {
        self.drained
    }

    /// Whether the opener of an encrypted link holds a whole record or plaintext that no read
    /// has taken yet (then the socket need not say anything for there to be frames).
    pub fn has_buffered_records(&self) -> bool {
        self.opener
            .as_ref()
            .is_some_and(|opener| opener.has_buffered())
    }

    /// Reads once from `source` (through the opener on an encrypted link). `Ok(0)` means the
    /// peer closed the connection.
    pub fn fill_from(&mut self, source: &mut impl Read) -> io::Result<usize> {
        self.fill(source, false)
    }

    /// [`FrameReader::fill_from`] for a blocking socket.
    pub fn fill_from_blocking(&mut self, source: &mut impl Read) -> io::Result<usize> {
        self.fill(source, true)
    }

    fn fill(&mut self, source: &mut impl Read, blocking: bool) -> io::Result<usize> {
        match self.opener.take() {
            Some(mut opener) => {
                let result = self.fill_raw(&mut OpenedReader {
                    opener: &mut opener,
                    source,
                    blocking,
                });
                opener.shrink_if_idle();
                self.opener = Some(opener);
                result
            }
            None => self.fill_raw(source),
        }
    }

    fn fill_raw(&mut self, source: &mut impl Read) -> io::Result<usize> {
        if let Some(large) = &mut self.large {
            let room = large.len - large.payload.len();
            let before = large.payload.len();
            // `read_to_end` reads into the spare capacity without zeroing it when `source`
            // implements `read_buf` (std's `TcpStream` does, mio's does not: the connections
            // in `net/` are std streams), and keeps what it read when the socket runs dry
            // (`WouldBlock`), which is then only "drained".
            let result = source.take(room as u64).read_to_end(&mut large.payload);
            let got = large.payload.len() - before;
            return match result {
                Ok(_) if got == 0 => Ok(0),
                Ok(_) => {
                    self.drained = false;
                    Ok(got)
                }
                Err(err) if err.kind() == io::ErrorKind::WouldBlock && got > 0 => {
                    self.drained = true;
                    Ok(got)
                }
                Err(err) => Err(err),
            };
        }
        if self.start == self.end {
            self.start = 0;
            self.end = 0;
            if self.buf.len() > IDLE_KEEP_BYTES {
                self.buf = Vec::new();
            }
        }
        // Room for the rest of the pending frame when it is large, so it comes in few reads,
        // but never more than a bounded chunk on a peer's word.
        let pending = self.pending_frame_len().unwrap_or(0);
        let mut want = pending
            .saturating_sub(self.end - self.start)
            .clamp(MIN_READ_BYTES, MAX_READ_BYTES);
        if self.hello_pending || self.auth_pending() {
            // A stranger costs at most this much storage.
            want = PREAUTH_READ_BYTES;
        }
        if self.buf.len() - self.end < want && self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        if self.buf.len() - self.end < want {
            self.buf.resize(self.end + want, 0);
        }
        // At most `want`: storage grown for an earlier frame must not pull a whole large frame
        // in here, where it would be copied out, rather than into its own payload buffer.
        let room = (self.buf.len() - self.end).min(want);
        let got = source.read(&mut self.buf[self.end..self.end + room])?;
        self.end += got;
        self.drained = got < room;
        Ok(got)
    }

    fn pending_frame_len(&self) -> Option<usize> {
        if self.hello_pending || self.end - self.start < 4 {
            return None;
        }
        let header = &self.buf[self.start..self.start + 4];
        Some(u32::from_le_bytes([header[0], header[1], header[2], header[3]]) as usize + 4)
    }

    /// The next complete frame, if any (handshake frames are handled here).
    pub fn next_frame(&mut self) -> Result<Option<Frame>, WireError> {
        loop {
            let Some(frame) = self.next_wire_frame()? else {
                return Ok(None);
            };
            if let Some(frame) = self.admit(frame)? {
                return Ok(Some(frame));
            }
        }
    }

    /// Lets a frame through, or takes part in the handshake (the step is kept for
    /// [`FrameReader::take_auth_step`]), or refuses the peer.
    fn admit(&mut self, frame: Frame) -> Result<Option<Frame>, WireError> {
        let Some(auth) = &mut self.auth else {
            return match frame {
                Frame::Handshake(..) => Err(WireError::AuthNotConfigured),
                frame => Ok(Some(frame)),
            };
        };
        let (kind, body) = match frame {
            Frame::Handshake(kind, body) => (kind, body),
            frame if matches!(**auth, AuthState::Done) => return Ok(Some(frame)),
            Frame::Data(_) => return Err(WireError::Unauthenticated("data")),
            _ => return Err(WireError::Unauthenticated("a message")),
        };
        let step = match (&mut **auth, kind) {
            (AuthState::Dialer(dialer), KIND_HANDSHAKE_ANSWER) => {
                let dialer = dialer
                    .take()
                    .ok_or(WireError::Unauthenticated("a second answer"))?;
                let (confirm, session) = dialer.finish(&body)?;
                let mut reply = Vec::new();
                encode_handshake(&mut reply, KIND_HANDSHAKE_CONFIRM, &confirm);
                **auth = AuthState::Done;
                self.start_opening(session.opener);
                AuthStep {
                    reply,
                    sealer: session.sealer,
                    done: true,
                    peer: None,
                    binding: Some(session.binding),
                }
            }
            (AuthState::Listening(listen), KIND_HANDSHAKE_FIRST) => {
                let (listener, answer, sealer) = Listener::accept(listen, &body)?;
                let mut reply = Vec::new();
                encode_handshake(&mut reply, KIND_HANDSHAKE_ANSWER, &answer);
                **auth = AuthState::Answered(Some(listener));
                AuthStep {
                    reply,
                    sealer,
                    done: false,
                    peer: None,
                    binding: None,
                }
            }
            (AuthState::Answered(listener), KIND_HANDSHAKE_CONFIRM) => {
                let listener = listener
                    .take()
                    .ok_or(WireError::Unauthenticated("a second confirmation"))?;
                let session = listener.confirm(&body)?;
                **auth = AuthState::Done;
                self.start_opening(session.opener);
                AuthStep {
                    reply: Vec::new(),
                    sealer: None,
                    done: true,
                    peer: session.peer,
                    binding: Some(session.binding),
                }
            }
            _ => return Err(WireError::Unauthenticated("a handshake frame out of turn")),
        };
        self.step = Some(step);
        Ok(Some(Frame::AuthStep))
    }

    /// From here on the peer's bytes are records: what was read past the handshake is
    /// ciphertext, and moves to the opener.
    fn start_opening(&mut self, opener: Option<Opener>) {
        if let Some(mut opener) = opener {
            opener.push_ciphertext(&self.buf[self.start..self.end]);
            self.start = self.end;
            self.opener = Some(Box::new(opener));
        }
    }

    fn next_wire_frame(&mut self) -> Result<Option<Frame>, WireError> {
        if let Some(large) = &self.large {
            if large.payload.len() < large.len {
                return Ok(None);
            }
            return Ok(self.large.take().map(|large| {
                Frame::Data(DataFrame {
                    seq: large.seq,
                    stamp_ns: large.stamp_ns,
                    payload: large.payload,
                })
            }));
        }
        if !self.take_hello()? {
            return Ok(None);
        }
        let Some(total) = self.pending_frame_len() else {
            return Ok(None);
        };
        let len = total - 4;
        if len > MAX_FRAME_BYTES {
            return Err(WireError::FrameTooLarge(len));
        }
        if self.auth_pending() && len > 1 + MAX_HANDSHAKE_BYTES {
            // Nothing a stranger may send is larger than a handshake frame.
            return Err(WireError::Unauthenticated(
                "a frame larger than a handshake's",
            ));
        }
        let buffered = self.end - self.start;
        let prefix = 4 + 1 + DATA_HEADER_BYTES;
        if len >= LARGE_FRAME_BYTES
            && buffered < total
            && buffered >= prefix
            && self.buf[self.start + 4] == KIND_DATA
        {
            if self.auth_pending() {
                // No room is made for a large frame from a peer that has not authenticated.
                return Err(WireError::Unauthenticated("data"));
            }
            self.start_large(total);
            return self.next_wire_frame();
        }
        if buffered < total {
            return Ok(None);
        }
        let body = &self.buf[self.start + 4..self.start + total];
        self.start += total;
        decode_body(body).map(Some)
    }

    /// Moves the frame at `start` (a data frame of `total` bytes, header buffered) to its own
    /// payload buffer, which the following reads fill directly.
    fn start_large(&mut self, total: usize) {
        let header = &self.buf[self.start + 5..self.start + 5 + DATA_HEADER_BYTES];
        let mut seq = [0; 8];
        let mut stamp = [0; 8];
        seq.copy_from_slice(&header[..8]);
        stamp.copy_from_slice(&header[8..]);
        let payload_start = self.start + 5 + DATA_HEADER_BYTES;
        let len = total - 5 - DATA_HEADER_BYTES;
        let mut payload = Vec::with_capacity(len);
        let already = (self.end - payload_start).min(len);
        payload.extend_from_slice(&self.buf[payload_start..payload_start + already]);
        self.start = payload_start + already;
        self.large = Some(LargeFrame {
            seq: u64::from_le_bytes(seq),
            stamp_ns: u64::from_le_bytes(stamp),
            payload,
            len,
        });
    }
}

fn decode_body(body: &[u8]) -> Result<Frame, WireError> {
    let (&kind, rest) = body.split_first().ok_or(WireError::EmptyFrame)?;
    match kind {
        KIND_MESSAGE => Ok(Frame::Message(rest.to_vec())),
        KIND_DATA => {
            if rest.len() < DATA_HEADER_BYTES {
                return Err(WireError::ShortData(rest.len()));
            }
            let (header, payload) = rest.split_at(DATA_HEADER_BYTES);
            let mut seq = [0; 8];
            let mut stamp = [0; 8];
            seq.copy_from_slice(&header[..8]);
            stamp.copy_from_slice(&header[8..]);
            Ok(Frame::Data(DataFrame {
                seq: u64::from_le_bytes(seq),
                stamp_ns: u64::from_le_bytes(stamp),
                payload: payload.to_vec(),
            }))
        }
        KIND_HANDSHAKE_FIRST | KIND_HANDSHAKE_ANSWER | KIND_HANDSHAKE_CONFIRM => {
            if rest.len() > MAX_HANDSHAKE_BYTES {
                return Err(WireError::BadAuthFrame(rest.len()));
            }
            Ok(Frame::Handshake(kind, rest.to_vec()))
        }
        other => Err(WireError::UnknownKind(other)),
    }
}

/// Bytes waiting to be written to a non-blocking socket, kept with their frame boundaries so
/// that a subscriber that wants only the latest value can drop stale frames it has not started
/// to receive.
#[derive(Default)]
pub struct OutBuffer {
    buf: Vec<u8>,
    written: usize,
    /// Offsets in `buf` where frames begin; a frame starting at or after `written` has not
    /// started to go out.
    frame_starts: VecDeque<usize>,
}

impl OutBuffer {
    pub fn pending_bytes(&self) -> usize {
        self.buf.len() - self.written
    }

    pub fn is_empty(&self) -> bool {
        self.pending_bytes() == 0
    }

    pub fn push_hello(&mut self) {
        self.frame_starts.push_back(self.buf.len());
        self.buf.extend_from_slice(&HELLO);
    }

    /// Whole frames (or a hello) encoded elsewhere, such as a handshake's.
    pub fn push_encoded(&mut self, bytes: &[u8]) {
        if !bytes.is_empty() {
            self.frame_starts.push_back(self.buf.len());
            self.buf.extend_from_slice(bytes);
        }
    }

    /// Appends what `other` holds and has not started to send.
    pub fn append(&mut self, other: OutBuffer) {
        let offset = self.buf.len();
        self.frame_starts.extend(
            other
                .frame_starts
                .iter()
                .filter(|&&start| start >= other.written)
                .map(|start| start - other.written + offset),
        );
        self.buf.extend_from_slice(&other.buf[other.written..]);
    }

    pub fn push_message<T: Serialize>(&mut self, message: &T) -> Result<(), WireError> {
        let start = self.buf.len();
        encode_message(&mut self.buf, message)?;
        self.frame_starts.push_back(start);
        Ok(())
    }

    /// Appends encoded frame bytes. With `latest_only`, frames queued behind the one being
    /// written are dropped first: the reader only ever wants the newest.
    pub fn push_frame(&mut self, frame: &[u8], latest_only: bool) {
        self.push_frame_parts(&[frame], latest_only);
    }

    /// [`OutBuffer::push_frame`] for a frame in pieces (a header, then its payload).
    pub fn push_frame_parts(&mut self, parts: &[&[u8]], latest_only: bool) {
        if latest_only {
            let unstarted = self
                .frame_starts
                .partition_point(|&start| start < self.written);
            if let Some(&cut) = self.frame_starts.get(unstarted) {
                self.buf.truncate(cut);
                self.frame_starts.truncate(unstarted);
            }
        }
        self.frame_starts.push_back(self.buf.len());
        for part in parts {
            self.buf.extend_from_slice(part);
        }
    }

    /// Writes as much as the socket takes. `Ok(true)` when everything went out.
    pub fn flush_to(&mut self, sink: &mut impl Write) -> io::Result<bool> {
        while self.written < self.buf.len() {
            match sink.write(&self.buf[self.written..]) {
                Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
                Ok(n) => self.written += n,
                Err(err) if err.kind() == io::ErrorKind::WouldBlock => {
                    self.forget_written();
                    return Ok(false);
                }
                Err(err) if err.kind() == io::ErrorKind::Interrupted => {}
                Err(err) => return Err(err),
            }
        }
        self.buf.clear();
        self.written = 0;
        self.frame_starts.clear();
        Ok(true)
    }

    /// Drops bytes already sent, so a long backlog does not keep them.
    fn forget_written(&mut self) {
        while self
            .frame_starts
            .get(1)
            .is_some_and(|&next| next <= self.written)
        {
            self.frame_starts.pop_front();
        }
        let Some(&first) = self.frame_starts.front() else {
            return;
        };
        // Compact only when the sent part outweighs what is left, so each byte moves O(1) times.
        if first >= 1024 * 1024 && first >= self.buf.len() - first {
            self.buf.drain(..first);
            self.written -= first;
            for start in &mut self.frame_starts {
                *start -= first;
            }
        }
    }
}

/// Blocking helpers for simple peers (the agent, the config server, tools).
pub mod blocking {
    use std::net::TcpStream;

    use super::*;
    use crate::auth::SealedWriter;

    pub fn write_hello(stream: &mut impl Write) -> io::Result<()> {
        stream.write_all(&HELLO)
    }

    pub fn read_hello(stream: &mut impl Read) -> Result<(), WireError> {
        let mut hello = [0; 6];
        read_exact(stream, &mut hello)?;
        check_hello(&hello)
    }

    /// Opens a connection this side dialled: hellos both ways, then, with `dial`, the Noise
    /// handshake as the initiator (see [`crate::auth`]). Reads no more than a handshake needs
    /// before the peer is authenticated.
    pub fn dial(mut stream: TcpStream, dial: Option<&Dial>) -> Result<SecureStream, WireError> {
        let (mut reader, greeting) = FrameReader::dialer(dial)?;
        stream.write_all(&greeting)?;
        let mut writer = SealedWriter::new(stream.try_clone()?);
        match run_handshake(&mut stream, &mut reader, &mut writer) {
            Err(WireError::Closed) if let Some(dial) = dial => {
                Err(WireError::HandshakeRefused(dial.identity.clone()))
            }
            Err(WireError::Io(err))
                if err.kind() == io::ErrorKind::ConnectionReset
                    && let Some(dial) = dial =>
            {
                Err(WireError::HandshakeRefused(dial.identity.clone()))
            }
            Err(err) => Err(err),
            Ok(_) => Ok(SecureStream::new(stream, reader, writer)),
        }
    }

    /// Opens a connection this side accepted: hellos both ways, then, with `listen`, the Noise
    /// handshake as the responder. Returns the dialer's proven identity, if any. (The servers
    /// accept without blocking, so that strangers cost no thread; this is for tools and tests.)
    pub fn accept(
        mut stream: TcpStream,
        listen: Option<Listen>,
    ) -> Result<(SecureStream, Option<String>), WireError> {
        let mut reader = FrameReader::listener(listen);
        stream.write_all(&HELLO)?;
        let mut writer = SealedWriter::new(stream.try_clone()?);
        let peer = run_handshake(&mut stream, &mut reader, &mut writer)?;
        Ok((SecureStream::new(stream, reader, writer), peer))
    }

    /// Reads and answers handshake frames until the connection is open.
    fn run_handshake(
        stream: &mut TcpStream,
        reader: &mut FrameReader,
        writer: &mut SealedWriter<TcpStream>,
    ) -> Result<Option<String>, WireError> {
        let mut peer = None;
        loop {
            if reader.take_hello()? && reader.is_open() {
                return Ok(peer);
            }
            if reader.hello_received_and_authenticating()
                && let Some(frame) = reader.next_frame()?
            {
                let Frame::AuthStep = frame else {
                    return Err(WireError::Unauthenticated("a frame"));
                };
                let step = reader.take_auth_step();
                writer.inner.write_all(&step.reply)?;
                if let Some(sealer) = step.sealer {
                    writer.start_sealing(sealer, 0);
                }
                peer = peer.or(step.peer);
                continue;
            }
            match reader.fill_from_blocking(stream) {
                Ok(0) => return Err(WireError::Closed),
                Ok(_) => {}
                Err(err) if err.kind() == io::ErrorKind::Interrupted => {}
                Err(err) => return Err(err.into()),
            }
        }
    }

    /// A connection once its handshake is done: reads through the opener and writes through
    /// the sealer of an encrypted link, or straight through otherwise.
    #[derive(Debug)]
    pub struct SecureStream {
        pub reader: SecureReader,
        pub writer: SecureWriter,
    }

    /// The reading half of a [`SecureStream`].
    #[derive(Debug)]
    pub struct SecureReader {
        stream: TcpStream,
        /// Bytes read during the handshake and not decoded yet.
        leftover: Vec<u8>,
        at: usize,
        opener: Option<Opener>,
    }

    /// The writing half of a [`SecureStream`].
    #[derive(Debug)]
    pub struct SecureWriter(SealedWriter<TcpStream>);

    impl SecureStream {
        /// Wraps a stream that needs no handshake (the peer's hello already checked, no
        /// secret): for tools that speak to a listener of their own.
        pub fn plain(stream: TcpStream) -> io::Result<SecureStream> {
            let writer = SealedWriter::new(stream.try_clone()?);
            Ok(SecureStream::new(stream, FrameReader::default(), writer))
        }

        /// A stream that goes on where `reader` (after a handshake) left off.
        pub fn new(
            stream: TcpStream,
            reader: FrameReader,
            writer: SealedWriter<TcpStream>,
        ) -> SecureStream {
            let (leftover, opener) = reader.into_parts();
            SecureStream {
                reader: SecureReader {
                    stream,
                    leftover,
                    at: 0,
                    opener,
                },
                writer: SecureWriter(writer),
            }
        }

        /// The socket, for timeouts and addresses.
        pub fn get_ref(&self) -> &TcpStream {
            &self.reader.stream
        }

        /// The two halves, for a reader thread and writers elsewhere.
        pub fn split(self) -> (SecureReader, SecureWriter) {
            (self.reader, self.writer)
        }

        /// What the non-blocking transport of a node takes over: the socket, the bytes read
        /// and not decoded, the opener and the writer's sealer.
        pub fn into_parts(self) -> (TcpStream, Vec<u8>, Option<Opener>, SealedWriter<TcpStream>) {
            let SecureReader {
                stream,
                mut leftover,
                at,
                opener,
            } = self.reader;
            leftover.drain(..at);
            (stream, leftover, opener, self.writer.0)
        }
    }

    impl SecureReader {
        pub fn get_ref(&self) -> &TcpStream {
            &self.stream
        }
    }

    impl SecureWriter {
        pub fn get_ref(&self) -> &TcpStream {
            &self.0.inner
        }
    }

    impl Read for SecureReader {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if self.at < self.leftover.len() {
                let n = buf.len().min(self.leftover.len() - self.at);
                buf[..n].copy_from_slice(&self.leftover[self.at..self.at + n]);
                self.at += n;
                if self.at == self.leftover.len() {
                    self.leftover = Vec::new();
                    self.at = 0;
                }
                return Ok(n);
            }
            match &mut self.opener {
                Some(opener) => opener.read_via(&mut self.stream, buf, true),
                None => self.stream.read(buf),
            }
        }
    }

    impl Write for SecureWriter {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.0.write(buf)
        }
        fn flush(&mut self) -> io::Result<()> {
            self.0.flush()
        }
    }

    impl Read for SecureStream {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            self.reader.read(buf)
        }
    }

    impl Write for SecureStream {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            self.writer.write(buf)
        }
        fn flush(&mut self) -> io::Result<()> {
            self.writer.flush()
        }
    }

    pub fn write_message<T: Serialize>(
        stream: &mut impl Write,
        message: &T,
    ) -> Result<(), WireError> {
        let mut out = Vec::new();
        encode_message(&mut out, message)?;
        stream.write_all(&out)?;
        Ok(())
    }

    pub fn read_frame(stream: &mut impl Read) -> Result<Frame, WireError> {
        let mut header = [0; 4];
        read_exact(stream, &mut header)?;
        let len = u32::from_le_bytes(header) as usize;
        if len > MAX_FRAME_BYTES {
            return Err(WireError::FrameTooLarge(len));
        }
        let mut body = vec![0; len];
        read_exact(stream, &mut body)?;
        decode_body(&body)
    }

    pub fn read_message<T: DeserializeOwned>(stream: &mut impl Read) -> Result<T, WireError> {
        read_frame(stream)?.message()
    }

    /// [`read_message`] refusing a frame longer than `limit` bytes before reading it: the
    /// servers' requests are small, and a peer must not make them hold a large frame.
    pub fn read_message_at_most<T: DeserializeOwned>(
        stream: &mut impl Read,
        limit: usize,
    ) -> Result<T, WireError> {
        let mut header = [0; 4];
        read_exact(stream, &mut header)?;
        let len = u32::from_le_bytes(header) as usize;
        if len > limit.min(MAX_FRAME_BYTES) {
            return Err(WireError::FrameTooLarge(len));
        }
        let mut body = vec![0; len];
        read_exact(stream, &mut body)?;
        decode_body(&body)?.message()
    }

    fn read_exact(stream: &mut impl Read, buf: &mut [u8]) -> Result<(), WireError> {
        stream.read_exact(buf).map_err(|err| match err.kind() {
            io::ErrorKind::UnexpectedEof => WireError::Closed,
            _ => WireError::Io(err),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reader that hands out its bytes a few at a time, like a slow socket.
    struct Trickle<'a> {
        bytes: &'a [u8],
        step: usize,
    }

    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = self.step.min(self.bytes.len()).min(buf.len());
            buf[..n].copy_from_slice(&self.bytes[..n]);
            self.bytes = &self.bytes[n..];
            Ok(n)
        }
    }

    fn decode_all(bytes: &[u8], step: usize) -> Result<Vec<Frame>, WireError> {
        let mut reader = FrameReader::expecting_hello();
        let mut source = Trickle { bytes, step };
        let mut frames = Vec::new();
        assert_eq!(reader.next_frame()?, None);
        loop {
            let got = reader.fill_from(&mut source)?;
            while let Some(frame) = reader.next_frame()? {
                frames.push(frame);
            }
            if got == 0 {
                return Ok(frames);
            }
        }
    }

    #[test]
    fn frames_survive_any_split() {
        let mut bytes = HELLO.to_vec();
        encode_message(
            &mut bytes,
            &serde_json::json!({"type": "lookup", "data_name": "a.b"}),
        )
        .expect("encode");
        encode_data(&mut bytes, 7, 99, |out| {
            out.extend_from_slice(&[1, 2, 3]);
            Ok(())
        })
        .expect("encode");
        let big = vec![0xAB; 3 * 1024 * 1024];
        encode_data(&mut bytes, 8, 100, |out| {
            out.extend_from_slice(&big);
            Ok(())
        })
        .expect("encode");
        for step in [1, 5, 4096, usize::MAX] {
            let frames = decode_all(&bytes, step).expect("decodes");
            assert_eq!(frames.len(), 3, "step {step}");
            assert_eq!(
                frames[1],
                Frame::Data(DataFrame {
                    seq: 7,
                    stamp_ns: 99,
                    payload: vec![1, 2, 3]
                })
            );
            assert!(matches!(&frames[2], Frame::Data(d) if d.seq == 8 && d.payload == big));
        }
    }

    /// A non-blocking socket: every other read has nothing (`WouldBlock`), the others a chunk.
    struct Stuttering<'a> {
        bytes: &'a [u8],
        step: usize,
        dry: bool,
    }

    impl Read for Stuttering<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            self.dry = !self.dry;
            if self.dry && !self.bytes.is_empty() {
                return Err(io::ErrorKind::WouldBlock.into());
            }
            let n = self.step.min(self.bytes.len()).min(buf.len());
            buf[..n].copy_from_slice(&self.bytes[..n]);
            self.bytes = &self.bytes[n..];
            Ok(n)
        }
    }

    #[test]
    fn a_large_frame_read_between_dry_spells_arrives_whole() {
        let mut bytes = HELLO.to_vec();
        let big: Vec<u8> = (0..1024 * 1024 + 7).map(|i| (i % 251) as u8).collect();
        for seq in [1, 2] {
            encode_data(&mut bytes, seq, 0, |out| {
                out.extend_from_slice(&big);
                Ok(())
            })
            .expect("encode");
        }
        encode_data(&mut bytes, 3, 0, |out| {
            out.push(9);
            Ok(())
        })
        .expect("encode");
        for step in [1000, 65536, 300_000] {
            let mut reader = FrameReader::expecting_hello();
            let mut source = Stuttering {
                bytes: &bytes,
                step,
                dry: false,
            };
            let mut frames = Vec::new();
            loop {
                match reader.fill_from(&mut source) {
                    Ok(0) => break,
                    Ok(_) => {}
                    Err(err) if err.kind() == io::ErrorKind::WouldBlock => {}
                    Err(err) => panic!("{err}"),
                }
                while let Some(frame) = reader.next_frame().expect("decodes") {
                    frames.push(frame);
                }
            }
            let payloads: Vec<(u64, usize)> = frames
                .iter()
                .map(|frame| match frame {
                    Frame::Data(data) => (data.seq, data.payload.len()),
                    other => panic!("{other:?}"),
                })
                .collect();
            assert_eq!(
                payloads,
                [(1, big.len()), (2, big.len()), (3, 1)],
                "step {step}"
            );
            for frame in &frames[..2] {
                assert!(matches!(frame, Frame::Data(data) if data.payload == big));
            }
        }
    }

    #[test]
    fn hostile_input_is_refused_before_allocation() {
        let mut bytes = HELLO.to_vec();
        bytes.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(
            decode_all(&bytes, 64),
            Err(WireError::FrameTooLarge(_))
        ));
        assert!(matches!(
            blocking::read_frame(&mut &u32::MAX.to_le_bytes()[..]),
            Err(WireError::FrameTooLarge(_))
        ));
        assert!(matches!(
            decode_all(b"GET / HTTP/1.1\r\n", 64),
            Err(WireError::BadMagic(_))
        ));
        assert!(matches!(
            decode_all(b"ARMR\x09\x00", 64),
            Err(WireError::BadVersion(9))
        ));
        let mut bytes = HELLO.to_vec();
        bytes.extend_from_slice(&[3, 0, 0, 0, KIND_DATA, 1, 2]);
        assert!(matches!(
            decode_all(&bytes, 64),
            Err(WireError::ShortData(2))
        ));
        let mut bytes = HELLO.to_vec();
        bytes.extend_from_slice(&[1, 0, 0, 0, 77]);
        assert!(matches!(
            decode_all(&bytes, 64),
            Err(WireError::UnknownKind(77))
        ));
    }

    /// A sink that accepts a fixed number of bytes, then would block.
    struct Choked {
        room: usize,
        got: Vec<u8>,
    }

    impl Write for Choked {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.room == 0 {
                return Err(io::ErrorKind::WouldBlock.into());
            }
            let n = self.room.min(buf.len());
            self.room -= n;
            self.got.extend_from_slice(&buf[..n]);
            Ok(n)
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn latest_only_drops_stale_frames_but_never_a_started_one() {
        let frame = |seq: u64| {
            let mut out = Vec::new();
            encode_data(&mut out, seq, 0, |_| Ok(())).expect("encode");
            out
        };
        let mut out = OutBuffer::default();
        let mut sink = Choked {
            room: 10,
            got: Vec::new(),
        };
        out.push_frame(&frame(1), true);
        assert!(!out.flush_to(&mut sink).expect("flush"));
        for seq in 2..10 {
            out.push_frame(&frame(seq), true);
        }
        sink.room = usize::MAX;
        assert!(out.flush_to(&mut sink).expect("flush"));
        let mut reader = FrameReader::default();
        reader.fill_from(&mut &sink.got[..]).expect("read");
        let mut seqs = Vec::new();
        while let Some(Frame::Data(data)) = reader.next_frame().expect("frame") {
            seqs.push(data.seq);
        }
        assert_eq!(seqs, [1, 9]);
    }
}
