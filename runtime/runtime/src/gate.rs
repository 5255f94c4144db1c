//! The door of every server of a run (agent, config server, control interface) and of
//! `armor host`: connections are accepted on one thread, without blocking, and get a thread of
//! their own only once they have passed the handshake (with a secret) or sent their first
//! request whole behind their hello (without).
//! Until then a peer costs a socket and at most a kilobyte of buffer; at most [`MAX_PENDING`]
//! are kept, the oldest that has not proved a key dropped first for a new one, and none longer
//! than its [`HandshakeDeadline`]: a short one for the first message, which a stranger does not
//! pass, and a round trip more once it proved a key. A thousand idle connections thus cost a
//! few hundred kilobytes and never keep a module or an operator from getting in. With a secret,
//! the door sends nothing, not even its hello, before a valid first handshake message.
//!
//! Without a secret there is no key to tell a stranger by, so [`serve_requests`] opens a
//! connection only once its first request has arrived whole, within the first message's
//! deadline: every client of these servers sends one right behind its hello (a module its
//! registration to the agent and its `hello` to the config server, `armor ctl` its request, a
//! supervisor its `hello` to `armor host`), while a peer that says its hello and nothing more
//! costs no thread and is closed.

use std::collections::HashMap;
use std::io::{ErrorKind, Read as _, Write as _};
use std::net::TcpStream;
use std::os::fd::AsRawFd as _;
use std::time::Instant;

use armor_module_api::auth::{Listen, SealedWriter, Sealer};
use armor_module_api::handshake_deadline::HandshakeDeadline;
use armor_module_api::wire::blocking::SecureStream;
use armor_module_api::wire::{Frame, FrameReader, HELLO, OutBuffer, WireError};
use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token};

/// The most connections kept before their handshake is over.
pub const MAX_PENDING: usize = 256;

/// The most a first message that says who is there (a module's `hello` to the config server, a
/// supervisor's to `armor host`: a name and a few numbers) may weigh before the connection is
/// open, without a secret.
pub const MAX_HELLO_BYTES: usize = 64 * 1024;

const LISTENER: Token = Token(0);

struct Pending {
    stream: TcpStream,
    reader: FrameReader,
    out: OutBuffer,
    sealer: Option<Sealer>,
    peer: Option<String>,
    /// With a secret, the hello goes out with the answer to a valid first handshake message:
    /// a stranger gets not a byte.
    hello_owed: bool,
    deadline: HandshakeDeadline,
    /// Without a secret: the bytes of the first request as they arrive (the hello taken),
    /// until it is whole.
    first_request: Option<Vec<u8>>,
}

/// How a connection is opened, and what it may send first.
#[derive(Clone, Copy)]
struct Opening {
    /// Without a secret, wait for the first request before opening, and refuse one longer
    /// than this (bytes).
    first_request_at_most: Option<usize>,
}

/// Accepts on `listener` until the process ends, and hands each connection that is open to
/// `handle`, with the peer's proven identity: with `listen`, once the handshake passed; without,
/// once its first request (at most `max_request_bytes`) has arrived whole with its hello, so
/// that a peer that says its hello and nothing more costs no thread. Refusals are logged at
/// `warn` with what the peer did wrong.
pub fn serve_requests(
    listener: std::net::TcpListener,
    listen: Option<Listen>,
    max_request_bytes: usize,
    mut handle: impl FnMut(SecureStream, Option<String>),
) {
    let opening = Opening {
        first_request_at_most: listen.is_none().then_some(max_request_bytes),
    };
    if let Err(err) = run(listener, listen, opening, &mut handle) {
        tracing::error!("a server stopped accepting connections: {err}");
    }
}

fn run(
    listener: std::net::TcpListener,
    listen: Option<Listen>,
    opening: Opening,
    handle: &mut impl FnMut(SecureStream, Option<String>),
) -> std::io::Result<()> {
    listener.set_nonblocking(true)?;
    let mut listener = mio::net::TcpListener::from_std(listener);
    let mut poll = Poll::new()?;
    poll.registry()
        .register(&mut listener, LISTENER, Interest::READABLE)?;
    let mut events = Events::with_capacity(256);
    let mut pending: HashMap<Token, Pending> = HashMap::new();
    let mut next_token = 1;
    loop {
        let now = Instant::now();
        let timeout = pending
            .values()
            .map(|conn| conn.deadline.at().saturating_duration_since(now))
            .min();
        if let Err(err) = poll.poll(&mut events, timeout)
            && err.kind() != ErrorKind::Interrupted
        {
            return Err(err);
        }
        let mut ready: Vec<Token> = events.iter().map(|event| event.token()).collect();
        while let Some(token) = ready.pop() {
            if token == LISTENER {
                // What a new connection brought with it (a dialer's hello and first message
                // come with the connect) is read at once: a key holder's first message then
                // counts before more strangers arrive.
                ready.extend(accept_all(
                    &listener,
                    &poll,
                    &mut pending,
                    &mut next_token,
                    &listen,
                ));
                continue;
            }
            let Some(conn) = pending.get_mut(&token) else {
                continue;
            };
            match advance(conn, opening) {
                Ok(false) => {}
                Ok(true) => {
                    if let Some(conn) = remove(&poll, &mut pending, token)
                        && let Some((stream, peer)) = open(conn)
                    {
                        handle(stream, peer);
                    }
                }
                Err(err) => {
                    let peer = conn.stream.peer_addr().ok();
                    match err {
                        WireError::Closed => tracing::debug!(?peer, "closed before its hello"),
                        err => tracing::warn!(?peer, "refused a connection: {err}"),
                    }
                    remove(&poll, &mut pending, token);
                }
            }
        }
        let now = Instant::now();
        let expired: Vec<Token> = pending
            .iter()
            .filter(|(_, conn)| conn.deadline.expired(now))
            .map(|(&token, _)| token)
            .collect();
        for token in expired {
            if let Some(conn) = remove(&poll, &mut pending, token) {
                tracing::warn!(
                    peer = ?conn.stream.peer_addr().ok(),
                    proved_a_key = conn.deadline.has_proved(),
                    "a peer did not finish its handshake in time; dropped"
                );
            }
        }
    }
}

/// Accepts every waiting connection; returns their tokens.
fn accept_all(
    listener: &mio::net::TcpListener,
    poll: &Poll,
    pending: &mut HashMap<Token, Pending>,
    next_token: &mut usize,
    listen: &Option<Listen>,
) -> Vec<Token> {
    let mut accepted = Vec::new();
    loop {
        let stream = match listener.accept() {
            Ok((stream, _)) => TcpStream::from(stream),
            Err(err) if err.kind() == ErrorKind::WouldBlock => return accepted,
            Err(err) => {
                // Out of descriptors, say: the pending ones will free some.
                tracing::warn!("accept failed: {err}");
                return accepted;
            }
        };
        // The oldest stranger goes first: a peer whose first handshake message proved a key
        // is dropped only when every pending peer has.
        if pending.len() >= MAX_PENDING
            && let Some(oldest) = pending
                .iter()
                .min_by_key(|(_, conn)| (!conn.hello_owed, conn.deadline.at()))
                .map(|(&token, _)| token)
        {
            tracing::debug!("{MAX_PENDING} connections in their handshake: dropped the oldest");
            remove(poll, pending, oldest);
        }
        let token = Token(*next_token);
        *next_token += 1;
        let registered = stream.set_nodelay(true).and_then(|()| {
            poll.registry().register(
                &mut SourceFd(&stream.as_raw_fd()),
                token,
                Interest::READABLE,
            )
        });
        if let Err(err) = registered {
            tracing::warn!("cannot watch a new connection: {err}");
            continue;
        }
        let mut out = OutBuffer::default();
        if listen.is_none() {
            out.push_encoded(&HELLO);
        }
        let mut conn = Pending {
            stream,
            reader: FrameReader::listener(listen.clone()),
            out,
            sealer: None,
            peer: None,
            hello_owed: listen.is_some(),
            deadline: HandshakeDeadline::accepted(Instant::now()),
            first_request: None,
        };
        // The hello (if any yet) is six bytes: a new socket takes them at once.
        if let Err(err) = conn.out.flush_to(&mut conn.stream) {
            tracing::debug!("cannot greet a new connection: {err}");
            let _ = poll
                .registry()
                .deregister(&mut SourceFd(&conn.stream.as_raw_fd()));
            continue;
        }
        pending.insert(token, conn);
        accepted.push(token);
    }
}

/// Reads what the peer sent and answers the handshake; `Ok(true)` once the connection is open.
/// Frames of the service that came with the handshake stay undecoded in the reader.
fn advance(conn: &mut Pending, opening: Opening) -> Result<bool, WireError> {
    if conn.first_request.is_some() {
        return first_request(conn, opening);
    }
    loop {
        if conn.reader.take_hello()? {
            if conn.reader.is_open() {
                if opening.first_request_at_most.is_none() {
                    return Ok(true);
                }
                // What came with the hello is the start of the first request.
                let (received, _) = std::mem::take(&mut conn.reader).into_parts();
                conn.first_request = Some(received);
                return first_request(conn, opening);
            }
            if let Some(frame) = conn.reader.next_frame()? {
                // Before the connection is open only the handshake's steps come out.
                let Frame::AuthStep = frame else {
                    return Err(WireError::Unauthenticated("a frame"));
                };
                let step = conn.reader.take_auth_step();
                if std::mem::take(&mut conn.hello_owed) {
                    conn.out.push_encoded(&HELLO);
                    conn.deadline.proved(Instant::now());
                }
                conn.out.push_encoded(&step.reply);
                conn.sealer = step.sealer.or(conn.sealer.take());
                conn.peer = step.peer.or(conn.peer.take());
                conn.out.flush_to(&mut conn.stream)?;
                continue;
            }
        }
        match conn.reader.fill_from(&mut conn.stream) {
            Ok(0) => return Err(WireError::Closed),
            Ok(_) => {}
            Err(err) if err.kind() == ErrorKind::WouldBlock => return Ok(false),
            Err(err) if err.kind() == ErrorKind::Interrupted => {}
            Err(err) => return Err(err.into()),
        }
    }
}

/// The length of a frame, from the four bytes that start it.
const FRAME_LENGTH_BYTES: usize = 4;

/// Reads the first request of a connection without a secret, a little at a time (a peer costs
/// what it sent, never what it announces); `Ok(true)` once it is whole, with the reader
/// holding it.
fn first_request(conn: &mut Pending, opening: Opening) -> Result<bool, WireError> {
    let max_bytes = opening.first_request_at_most.unwrap_or(usize::MAX);
    let Some(received) = conn.first_request.as_mut() else {
        return Ok(true);
    };
    let mut chunk = [0; 1024];
    loop {
        if let Some(header) = received.first_chunk::<FRAME_LENGTH_BYTES>() {
            let frame_bytes = u32::from_le_bytes(*header) as usize;
            if frame_bytes > max_bytes {
                return Err(WireError::Io(std::io::Error::new(
                    ErrorKind::InvalidData,
                    format!("a first request of {frame_bytes} bytes (at most {max_bytes})"),
                )));
            }
            if received.len() >= FRAME_LENGTH_BYTES + frame_bytes {
                conn.reader = FrameReader::resume(received, None);
                conn.first_request = None;
                return Ok(true);
            }
        }
        match conn.stream.read(&mut chunk) {
            Ok(0) => return Err(WireError::Closed),
            Ok(got) => received.extend_from_slice(&chunk[..got]),
            Err(err) if err.kind() == ErrorKind::WouldBlock => return Ok(false),
            Err(err) if err.kind() == ErrorKind::Interrupted => {}
            Err(err) => return Err(err.into()),
        }
    }
}

fn remove(poll: &Poll, pending: &mut HashMap<Token, Pending>, token: Token) -> Option<Pending> {
    let conn = pending.remove(&token)?;
    let _ = poll
        .registry()
        .deregister(&mut SourceFd(&conn.stream.as_raw_fd()));
    Some(conn)
}

/// The open connection as a blocking stream for its own thread.
fn open(mut conn: Pending) -> Option<(SecureStream, Option<String>)> {
    let setup = conn.stream.set_nonblocking(false).and_then(|()| {
        // What the socket did not take of the answer goes now.
        conn.out.flush_to(&mut conn.stream)?;
        conn.stream.flush()?;
        conn.stream.try_clone()
    });
    let clone = match setup {
        Ok(clone) => clone,
        Err(err) => {
            tracing::debug!("lost a connection as it opened: {err}");
            return None;
        }
    };
    let mut writer = SealedWriter::new(clone);
    if let Some(sealer) = conn.sealer {
        writer.start_sealing(sealer, 0);
    }
    Some((
        SecureStream::new(conn.stream, conn.reader, writer),
        conn.peer,
    ))
}
