//! The network transport of a [`Node`](crate::Node): one thread, one mio poll, every connection
//! non-blocking. Nothing is handed between threads on the data path, which keeps a round trip
//! close to raw TCP.
//!
//! Links heal themselves: the agent connection is retried until it answers (then outputs are
//! registered again); an input whose provider goes away asks the agent again and reconnects; the
//! supervisor connection is retried and the configuration it sends is applied as a reload.
//!
//! An output is taken by push (each sample, or the newest), rate-limited push (`max_rate_hz`,
//! filtered at the provider) or pull ([`Node::pull_input`](crate::Node::pull_input): the
//! provider answers each request from the output's latest frame, kept by a swap, not a copy).
//! A data connection carries at most one subscription each way (`PeerLink`): two modules that
//! subscribe to each other share one, so that each message's TCP acknowledgement rides on the
//! reply. A frame of 64 KiB (`BATCH_BYTES`) or more to a reliable subscriber is written from the
//! module's own buffer, never copied: the connection asks the kernel for a send buffer of two
//! such frames, and what the socket does not take at once is written from the same buffer as it
//! drains. The loop blocks in `epoll_wait` between events and never spins: measured on a 2-core
//! machine, a spin before blocking cost more than it saved whenever the two ends shared a core
//! (`docs/performance.md`, "Transport speed").
//!
//! This file holds the connections and the loop (accepting, reading, timers, closing); each
//! role's messages are in a file of its own: `agent.rs` (the agent's and the supervisor's
//! links: registering, lookups, configuration), `provider.rs` (this module's outputs: publishing
//! to subscribers, pulls) and `subscriber.rs` (its inputs: linking to providers, answers,
//! relinking).

use std::io::{self, ErrorKind};
use std::net::{SocketAddr, TcpStream};
use std::os::fd::AsRawFd as _;
use std::time::{Duration, Instant};

use mio::net::TcpListener;
use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token};
use rustc_hash::FxHashMap;
use serde::Deserialize;

use crate::auth::{Credentials, Dial, Key, SealedWriter};
use crate::core::{ApiError, Core};
use crate::handshake_deadline::HandshakeDeadline;
use crate::protocol::{
    Advert, FromAgent, FromProvider, FromSupervisor, ToAgent, ToProvider, ToSupervisor,
};
use crate::wire::{Frame, FrameReader, OutBuffer, WireError};

mod agent;
mod provider;
mod subscriber;

const LISTENER: Token = Token(0);
const AGENT_RETRY: Duration = Duration::from_millis(250);
const SUPERVISOR_RETRY: Duration = Duration::from_millis(250);
const RELINK_DELAY: Duration = Duration::from_millis(100);
const UNKNOWN_RETRY: Duration = Duration::from_millis(200);
const LOOKUP_TIMEOUT: Duration = Duration::from_secs(2);
/// With a shared secret, how long a module waits for a peer whose first handshake message has
/// just proved a key to say who it is (its subscribe follows the handshake's round trip) before
/// it opens a connection of its own to a provider: the peer may be that provider, and the two
/// would share one.
const IDENTIFY_WAIT: Duration = Duration::from_millis(50);
/// How often it looks again meanwhile.
const IDENTIFY_POLL: Duration = Duration::from_millis(2);
/// The longest an input waits for peers to identify themselves, in all, however many key
/// holders keep connecting. A stranger's connection is no reason to wait at all: only a peer
/// whose first handshake message proved a key is waited for. That message must come with the
/// connect for this to keep shared connections: a dialer makes it before it connects and
/// writes it at once after (see [`Net::open`]). Made after the connect and written when the
/// poll next said the socket was writable, it came tens of milliseconds after the listener
/// had accepted and decided, and half of the pairs in `tests/tests/shared_link.rs` kept two
/// connections.
const IDENTIFY_WAIT_MAX: Duration = Duration::from_millis(200);
/// The most connections a module keeps that have not authenticated (or, without a secret,
/// subscribed) yet; the oldest is dropped for a new one. A stranger costs a socket and a
/// kilobyte until its handshake deadline.
const MAX_PENDING_PEERS: usize = 256;
/// Past this many buffered bytes a subscriber's data is written at once rather than batched.
const BATCH_BYTES: usize = 64 * 1024;
/// Past this many buffered bytes a reliable subscriber makes the publisher wait.
const RELIABLE_BACKLOG_BYTES: usize = 8 * 1024 * 1024;
/// The most send buffer a connection asks for large frames (Linux caps it at
/// `net.core.wmem_max` and doubles it).
const MAX_SEND_BUFFER: usize = 8 * 1024 * 1024;
/// How long a publisher waits for a reliable subscriber before dropping it.
const RELIABLE_STALL: Duration = Duration::from_secs(5);

#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    Agent,
    Supervisor,
    /// A data connection with another module, opened to subscribe or accepted on the data
    /// listener (then waiting for the peer's `Subscribe`).
    Peer(PeerLink),
}

/// What a data connection carries: at most one subscription each way, so that the data frames
/// of a direction belong to one subscription. Two modules that subscribe to each other share
/// one connection when they can: each message's ACK then rides on the answer, as over a raw
/// TCP ping-pong, instead of taking a trip of its own (see docs/performance.md).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct PeerLink {
    /// This module's input fed by the peer on this connection.
    input: Option<usize>,
    /// The peer's subscription to one of this module's outputs.
    serving: Option<Serving>,
    /// The peer's data listener: where this module connected, or the address the peer's
    /// subscribe gave. A subscription to a provider at that address may use this connection.
    peer_addr: Option<SocketAddr>,
    /// `Unsubscribe`s sent and not yet answered: until then, the data frames and answers that
    /// come belong to a subscription given up, and are dropped.
    unsubscribing: u8,
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Serving {
    output: usize,
    reliable: bool,
    /// The least time between two samples sent (a subscriber's `max_rate_hz`).
    min_interval: Option<Duration>,
    /// Sent a sample only when it asks ([`ToProvider::Pull`]).
    pull: bool,
}

/// A control message on a data connection, which may carry subscriptions both ways.
#[derive(Deserialize)]
#[serde(untagged)]
enum PeerMessage {
    Request(ToProvider),
    Answer(FromProvider),
}

struct Conn {
    /// Writes go through it (sealed on an encrypted link); its `inner` is the socket, a std
    /// stream (non-blocking, registered by its descriptor) rather than mio's: std's reads fill
    /// a buffer's spare capacity without zeroing it first, which a large frame's payload is
    /// read into.
    link: SealedWriter<TcpStream>,
    reader: FrameReader,
    out: OutBuffer,
    role: Role,
    /// The input stopped reading: a reliable input's queue is full, or a large frame was just
    /// delivered. Reading goes on at the next turn of the loop with room (when the module next
    /// waits), so that a stream of camera frames is read one frame ahead of the module, not as
    /// many as the socket holds: the next frame's buffer then reuses the memory of the one the
    /// module has just dropped, still in the cache, as a reader reusing one buffer does.
    paused: bool,
    /// Until the handshake (with a secret) or the subscribe (without) is in: short for the
    /// first message, a round trip more once it proved a key.
    handshake_deadline: Option<HandshakeDeadline>,
    /// Messages queued before the handshake is over: they follow it, since the peer takes
    /// nothing before.
    held: Option<OutBuffer>,
    /// A listener with a secret owes the dialer its hello until the dialer's first handshake
    /// message proved the key: a stranger gets not a byte.
    hello_owed: bool,
    /// Until when an input looking for a provider waits for this accepted peer to say who it
    /// is: set when its first handshake message proved a key ([`IDENTIFY_WAIT`]).
    identify_by: Option<Instant>,
    /// The peer's module: proven by the handshake for a dialer, the provider dialled for a
    /// subscription; `None` without a secret.
    peer: Option<String>,
    /// This module opened the connection (to subscribe): the link key it proved was issued
    /// for that direction only, so a subscription from the peer needs a proof of its own.
    dialed: bool,
    /// The handshake's hash, once it is over (with a secret).
    binding: Option<Vec<u8>>,
    /// When a rate-limited subscriber was last sent a sample.
    last_sent: Option<Instant>,
    /// A subscriber pulled before its output had a sample: it gets the next one.
    pull_pending: bool,
    /// The send buffer asked of the socket for large frames (0: the system's, autotuned).
    send_buffer: usize,
    /// A large frame is being written from the publisher's own buffers
    /// ([`Net::finish_large_frame`]): nothing else may go to the socket until it is whole.
    writing_parts: bool,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Link {
    Down { retry_at: Instant },
    Up(Token),
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum InputLink {
    Unbound,
    Resolve { at: Instant },
    Asked { since: Instant },
    Connecting(Token),
    Linked(Token),
}

/// An input's first state: looked up at the agent if it has a source, unless the source is
/// the run's health stream, which the config server's connection brings.
fn resolve_or_unbound(slot: &crate::core::InputSlot) -> InputLink {
    match slot.source.as_deref() {
        Some(crate::protocol::HEALTH) | None => InputLink::Unbound,
        Some(_) => InputLink::Resolve { at: Instant::now() },
    }
}

pub(crate) struct Net {
    poll: Poll,
    events: Events,
    listener: TcpListener,
    listen_addr: SocketAddr,
    conns: FxHashMap<Token, Conn>,
    next_token: usize,
    agent_addr: SocketAddr,
    agent: Link,
    agent_lost_logged: bool,
    supervisor_addr: Option<SocketAddr>,
    supervisor: Link,
    inputs: Vec<InputLink>,
    subscribers: Vec<Vec<Token>>,
    /// Each output's latest frame, for pulls (empty before its first sample).
    latest: Vec<Vec<u8>>,
    /// The outputs pulled at least once: their large frames are kept too.
    pulled: Vec<bool>,
    /// With a shared secret, every connection authenticates.
    credentials: Option<Credentials>,
    /// The module's name, which it proves.
    name: String,
    /// Since when each input (by index) waits for peers to identify themselves.
    identify_since: FxHashMap<usize, Instant>,
    /// With a secret, the link key the agent gave each input (by index) for its provider's
    /// port: on a connection the provider opened, the input's subscription proves it.
    tickets: FxHashMap<usize, Key>,
}

impl Net {
    /// See [`crate::Node::service_listen`].
    pub(crate) fn service_listen(&self) -> Option<crate::auth::Listen> {
        self.credentials
            .as_ref()
            .map(|credentials| crate::auth::Listen {
                encrypt: true,
                ..credentials.listen()
            })
    }
}

impl Conn {
    /// Writes what is queued, then what the sealer holds; `Ok(true)` when all went out.
    fn flush(&mut self) -> io::Result<bool> {
        if self.writing_parts {
            return Ok(false);
        }
        Ok(self.link.flush_pending()?
            && self.out.flush_to(&mut self.link)?
            && self.link.flush_pending()?)
    }

    /// Bytes queued and not yet taken by the socket.
    fn pending_bytes(&self) -> usize {
        self.out.pending_bytes() + self.link.pending_bytes()
    }

    fn stream(&mut self) -> &mut TcpStream {
        &mut self.link.inner
    }

    /// Makes room in the socket's send buffer for two frames of `frame_len` bytes (up to the
    /// system's limit), so that a large frame goes to the kernel in one write from the sender's
    /// own bytes, as a blocking write does, instead of being copied into [`OutBuffer`] and
    /// written piecewise as the socket drains. Only ever grows the buffer.
    fn make_room_for(&mut self, frame_len: usize) {
        let want = frame_len.saturating_mul(2).min(MAX_SEND_BUFFER);
        if want <= self.send_buffer {
            return;
        }
        self.send_buffer = want;
        let socket = socket2::SockRef::from(&self.link.inner);
        // The kernel reports twice what it was asked (its bookkeeping); autotuning may have
        // grown it beyond `want` already.
        if socket
            .send_buffer_size()
            .is_ok_and(|current| current / 2 < want)
            && let Err(err) = socket.set_send_buffer_size(want)
        {
            tracing::debug!("cannot grow a send buffer: {err}");
        }
    }
}

impl Net {
    /// Binds the data listener and starts connecting to the agent. `supervisor` is an already
    /// configured connection to the supervisor, if the module runs under one.
    pub fn start(
        core: &mut Core,
        agent_addr: SocketAddr,
        supervisor: Option<(SocketAddr, crate::wire::blocking::SecureStream)>,
        credentials: Option<Credentials>,
    ) -> Result<Self, ApiError> {
        let poll = Poll::new()?;
        let bind_host = if core.config.host.is_empty() {
            "127.0.0.1"
        } else {
            core.config.host.as_str()
        };
        let bind: SocketAddr = format!("{bind_host}:0")
            .parse()
            .or_else(|_| format!("[{bind_host}]:0").parse())
            .map_err(|_| {
                io::Error::new(ErrorKind::InvalidInput, format!("bad host `{bind_host}`"))
            })?;
        let mut listener = TcpListener::bind(bind)?;
        let listen_addr = listener.local_addr()?;
        poll.registry()
            .register(&mut listener, LISTENER, Interest::READABLE)?;
        let now = Instant::now();
        let mut net = Self {
            poll,
            events: Events::with_capacity(256),
            listener,
            listen_addr,
            conns: FxHashMap::default(),
            next_token: 1,
            agent_addr,
            agent: Link::Down { retry_at: now },
            agent_lost_logged: false,
            supervisor_addr: None,
            supervisor: Link::Down { retry_at: now },
            inputs: Vec::new(),
            subscribers: vec![Vec::new(); core.outputs.len()],
            latest: Vec::new(),
            pulled: Vec::new(),
            credentials,
            identify_since: FxHashMap::default(),
            tickets: FxHashMap::default(),
            name: core.name.clone(),
        };
        if let Some((addr, stream)) = supervisor {
            net.supervisor_addr = Some(addr);
            // The hello exchange (and authentication) and the first configuration happened
            // before, blocking.
            let (stream, leftover, opener, link) = stream.into_parts();
            drop(stream);
            let token = net.register(
                link,
                FrameReader::resume(&leftover, opener),
                Role::Supervisor,
            )?;
            net.supervisor = Link::Up(token);
        }
        net.inputs = core.inputs.iter().map(resolve_or_unbound).collect();
        tracing::debug!(addr = %listen_addr, "data listener ready");
        net.connect_agent(core);
        Ok(net)
    }

    /// How many data connections this module has with others, linked or not yet.
    pub fn data_connections(&self) -> usize {
        self.conns
            .values()
            .filter(|conn| matches!(conn.role, Role::Peer(_)))
            .count()
    }

    /// Registers a connection whose reader is set up.
    fn register(
        &mut self,
        link: SealedWriter<TcpStream>,
        reader: FrameReader,
        role: Role,
    ) -> io::Result<Token> {
        let token = Token(self.next_token);
        self.next_token += 1;
        link.inner.set_nodelay(true)?;
        link.inner.set_nonblocking(true)?;
        self.poll.registry().register(
            &mut SourceFd(&link.inner.as_raw_fd()),
            token,
            Interest::READABLE | Interest::WRITABLE,
        )?;
        self.conns.insert(
            token,
            Conn {
                link,
                reader,
                out: OutBuffer::default(),
                role,
                paused: false,
                handshake_deadline: None,
                held: None,
                hello_owed: false,
                identify_by: None,
                peer: None,
                dialed: false,
                binding: None,
                last_sent: None,
                pull_pending: false,
                send_buffer: 0,
                writing_parts: false,
            },
        );
        Ok(token)
    }

    /// Opens a connection to `addr`, proving this module's identity with `key` (its own for
    /// the agent and the supervisor, the agent's link key for a provider).
    fn open(&mut self, addr: SocketAddr, role: Role, key: Option<Key>) -> io::Result<Token> {
        let dial = match (&self.credentials, key) {
            (Some(credentials), Some(key)) => Some(Dial {
                key,
                ..credentials.dial(&self.name)
            }),
            (Some(credentials), None) => Some(credentials.dial(&self.name)),
            (None, _) => None,
        };
        // The first handshake message is made before the connect (it costs a key exchange), so
        // that it follows the connect at once.
        let (reader, greeting) = FrameReader::dialer(dial.as_ref()).map_err(io::Error::other)?;
        let stream: TcpStream = mio::net::TcpStream::connect(addr)?.into();
        let token = self.register(SealedWriter::new(stream), reader, role)?;
        if let Some(conn) = self.conns.get_mut(&token) {
            conn.dialed = true;
            conn.out.push_encoded(&greeting);
            if dial.is_some() {
                conn.held = Some(OutBuffer::default());
            }
            // The greeting goes out with the connect (on loopback and most links the connect
            // is complete by now): the listener then sees a valid first message at once and
            // waits for this connection's subscribe rather than opening one of its own (see
            // `awaits_identification`). A socket still connecting takes it when writable; a
            // failed write shows at the next poll.
            let _ = conn.flush();
        }
        Ok(token)
    }

    fn queue_message<T: serde::Serialize>(&mut self, token: Token, message: &T) {
        if let Some(conn) = self.conns.get_mut(&token)
            && let Err(err) = conn
                .held
                .as_mut()
                .unwrap_or(&mut conn.out)
                .push_message(message)
        {
            tracing::error!("cannot encode a control message: {err}");
        }
    }

    pub fn flush_all(&mut self, core: &mut Core) {
        let mut broken = Vec::new();
        for (&token, conn) in &mut self.conns {
            if (!conn.out.is_empty() || conn.link.pending_bytes() > 0)
                && let Err(err) = conn.flush()
            {
                tracing::debug!(?token, "write failed: {err}");
                broken.push(token);
            }
        }
        for token in broken {
            self.close(core, token);
        }
    }

    /// One turn of the loop: write what is pending, wait for sockets or the next timer (or
    /// `deadline`), then handle what happened.
    pub fn poll_once(
        &mut self,
        core: &mut Core,
        deadline: Option<Instant>,
    ) -> Result<(), ApiError> {
        self.flush_all(core);
        self.resume_paused_inputs(core);
        if !core.events.is_empty() {
            return Ok(());
        }
        let now = Instant::now();
        let wake = [deadline, self.next_timer()].into_iter().flatten().min();
        let timeout = wake.map(|at| at.saturating_duration_since(now));
        if let Err(err) = self.poll.poll(&mut self.events, timeout)
            && err.kind() != ErrorKind::Interrupted
        {
            return Err(err.into());
        }
        let ready: Vec<(Token, Readable, bool)> = self
            .events
            .iter()
            .map(|event| {
                let readable = if event.is_read_closed() || event.is_error() {
                    Readable::ToTheEnd
                } else if event.is_readable() {
                    Readable::Yes
                } else {
                    Readable::No
                };
                (event.token(), readable, event.is_writable())
            })
            .collect();
        for (token, readable, writable) in ready {
            if token == LISTENER {
                self.accept_all(core);
                continue;
            }
            if writable && let Some(conn) = self.conns.get_mut(&token) {
                match conn.flush() {
                    Ok(_) => {}
                    Err(err) => {
                        self.fail(core, token, &err.into());
                        continue;
                    }
                }
            }
            match readable {
                Readable::No => {}
                Readable::Yes => self.read_conn(core, token, UntilBlocked::OrShortRead),
                Readable::ToTheEnd => self.read_conn(core, token, UntilBlocked::Always),
            }
        }
        self.run_timers(core);
        Ok(())
    }

    fn next_timer(&self) -> Option<Instant> {
        let agent_timer = match self.agent {
            Link::Down { retry_at } => Some(retry_at),
            Link::Up(_) => None,
        };
        let supervisor_timer = match self.supervisor {
            Link::Down { retry_at } if self.supervisor_addr.is_some() => Some(retry_at),
            _ => None,
        };
        let agent_up = matches!(self.agent, Link::Up(_));
        let inputs = self.inputs.iter().filter_map(|link| match *link {
            InputLink::Resolve { at } if agent_up => Some(at),
            InputLink::Asked { since } => Some(since + LOOKUP_TIMEOUT),
            _ => None,
        });
        let handshakes = self
            .conns
            .values()
            .filter_map(|conn| conn.handshake_deadline.map(|deadline| deadline.at()));
        [agent_timer, supervisor_timer]
            .into_iter()
            .flatten()
            .chain(inputs)
            .chain(handshakes)
            .min()
    }

    fn run_timers(&mut self, core: &mut Core) {
        let now = Instant::now();
        if let Link::Down { retry_at } = self.agent
            && retry_at <= now
        {
            self.connect_agent(core);
        }
        if let (Link::Down { retry_at }, Some(addr)) = (self.supervisor, self.supervisor_addr)
            && retry_at <= now
        {
            match self.open(addr, Role::Supervisor, None) {
                Ok(token) => {
                    self.supervisor = Link::Up(token);
                    let hello = ToSupervisor::Hello {
                        module: core.name.clone(),
                        pid: std::process::id(),
                    };
                    self.queue_message(token, &hello);
                }
                Err(_) => {
                    self.supervisor = Link::Down {
                        retry_at: now + SUPERVISOR_RETRY,
                    }
                }
            }
        }
        if let Link::Up(agent) = self.agent {
            for index in 0..self.inputs.len() {
                let due = match self.inputs[index] {
                    InputLink::Resolve { at } => at <= now,
                    InputLink::Asked { since } => since + LOOKUP_TIMEOUT <= now,
                    _ => false,
                };
                if let (true, Some(data_name)) = (due, core.inputs[index].source.clone()) {
                    self.inputs[index] = InputLink::Asked { since: now };
                    self.queue_message(agent, &ToAgent::Lookup { data_name });
                }
            }
        }
        let expired: Vec<Token> = self
            .conns
            .iter()
            .filter(|(_, conn)| {
                conn.handshake_deadline
                    .is_some_and(|deadline| deadline.expired(now))
            })
            .map(|(&token, _)| token)
            .collect();
        for token in expired {
            tracing::warn!("a peer did not finish its handshake in time; dropped");
            self.close(core, token);
        }
    }

    /// Accepts every pending connection and reads what it brought at once: a peer's subscribe
    /// is usually there already, and a connection choice may wait on it (see
    /// `join_peer_connection`).
    fn accept_all(&mut self, core: &mut Core) {
        let mut accepted = Vec::new();
        loop {
            match self.listener.accept() {
                Ok((stream, peer)) => {
                    self.make_room_for_a_peer(core);
                    let listen = self.credentials.as_ref().map(Credentials::listen);
                    let reader = FrameReader::listener(listen);
                    let stream: TcpStream = stream.into();
                    match self.register(
                        SealedWriter::new(stream),
                        reader,
                        Role::Peer(PeerLink::default()),
                    ) {
                        Ok(token) => {
                            tracing::debug!(%peer, "subscriber connecting");
                            if let Some(conn) = self.conns.get_mut(&token) {
                                conn.handshake_deadline =
                                    Some(HandshakeDeadline::accepted(Instant::now()));
                                if self.credentials.is_some() {
                                    conn.held = Some(OutBuffer::default());
                                    conn.hello_owed = true;
                                } else {
                                    conn.out.push_hello();
                                }
                            }
                            accepted.push(token);
                        }
                        Err(err) => tracing::warn!(%peer, "cannot set up a subscriber: {err}"),
                    }
                }
                Err(err) if err.kind() == ErrorKind::WouldBlock => break,
                Err(err) => {
                    tracing::warn!("accept failed: {err}");
                    break;
                }
            }
        }
        for token in accepted {
            self.read_conn(core, token, UntilBlocked::Always);
        }
    }

    /// Drops the oldest connection still in its handshake when [`MAX_PENDING_PEERS`] are.
    fn make_room_for_a_peer(&mut self, core: &mut Core) {
        let pending = self
            .conns
            .iter()
            // A stranger goes before a peer whose first message proved a key.
            .filter_map(|(&token, conn)| {
                conn.handshake_deadline
                    .map(|deadline| ((deadline.has_proved(), deadline.at()), token))
            });
        let (count, oldest) = pending.fold((0, None), |(count, oldest), item| {
            (count + 1, oldest.min(Some(item)).or(Some(item)))
        });
        if count >= MAX_PENDING_PEERS
            && let Some((_, token)) = oldest
        {
            tracing::debug!("too many peers in their handshake: dropped the oldest");
            self.close(core, token);
        }
    }

    fn resume_paused_inputs(&mut self, core: &mut Core) {
        let resumable: Vec<Token> = self
            .conns
            .iter()
            .filter(|(_, conn)| {
                conn.paused
                    && matches!(conn.role, Role::Peer(PeerLink { input: Some(i), .. }) if core.inputs[i].has_room())
            })
            .map(|(&token, _)| token)
            .collect();
        for token in resumable {
            if let Some(conn) = self.conns.get_mut(&token) {
                conn.paused = false;
            }
            // The socket's edges while paused were not acted on: read until it blocks.
            self.read_conn(core, token, UntilBlocked::Always);
        }
    }

    /// Handles what is buffered, then reads until the socket is drained (edge-triggered),
    /// handling each complete frame. A paused reliable input stops reading; whatever it already
    /// holds is handled first when it resumes. `until` says whether a short read may be taken
    /// for drained (see [`UntilBlocked`]).
    fn read_conn(&mut self, core: &mut Core, token: Token, until: UntilBlocked) {
        loop {
            if let Err(err) = self.handle_frames(core, token) {
                self.fail(core, token, &err);
                return;
            }
            let Some(conn) = self.conns.get_mut(&token) else {
                return;
            };
            if conn.paused {
                return;
            }
            match conn.reader.fill_from(&mut conn.link.inner) {
                Ok(0) => {
                    self.close(core, token);
                    return;
                }
                Ok(_) => {}
                Err(err) if err.kind() == ErrorKind::WouldBlock => return,
                Err(err) if err.kind() == ErrorKind::Interrupted => continue,
                Err(err) => {
                    self.fail(core, token, &err.into());
                    return;
                }
            }
            // A short read drained the socket: handle what came, and let readiness tell of more
            // (saves a read that would only say "would block").
            if until == UntilBlocked::OrShortRead && conn.reader.drained() {
                if let Err(err) = self.handle_frames(core, token) {
                    self.fail(core, token, &err);
                    return;
                }
                // Records read with the handshake's last frame wait in the opener: the socket
                // will not tell of them.
                if self
                    .conns
                    .get(&token)
                    .is_some_and(|conn| !conn.paused && conn.reader.has_buffered_records())
                {
                    continue;
                }
                return;
            }
        }
    }

    fn handle_frames(&mut self, core: &mut Core, token: Token) -> Result<(), WireError> {
        loop {
            let Some(conn) = self.conns.get_mut(&token) else {
                return Ok(());
            };
            if conn.paused {
                return Ok(());
            }
            let Some(frame) = conn.reader.next_frame()? else {
                return Ok(());
            };
            if let Frame::AuthStep = frame {
                let step = conn.reader.take_auth_step();
                if std::mem::take(&mut conn.hello_owed) {
                    conn.out.push_hello();
                    let now = Instant::now();
                    conn.identify_by = Some(now + IDENTIFY_WAIT);
                    if let Some(deadline) = conn.handshake_deadline.as_mut() {
                        deadline.proved(now);
                    }
                }
                conn.out.push_encoded(&step.reply);
                if let Some(sealer) = step.sealer {
                    // The handshake's frames go out as they are, everything after sealed.
                    let raw = conn.out.pending_bytes();
                    conn.link.start_sealing(sealer, raw);
                }
                if step.done {
                    if step.peer.is_some() {
                        conn.peer = step.peer;
                    }
                    conn.binding = step.binding;
                    if let Some(held) = conn.held.take() {
                        conn.out.append(held);
                    }
                }
                continue;
            }
            let role = conn.role;
            match role {
                Role::Agent => self.on_agent(core, frame.message()?),
                Role::Supervisor => self.on_supervisor(core, token, frame.message()?),
                Role::Peer(link) => self.on_peer(core, token, link, frame)?,
            }
        }
    }

    fn on_peer(
        &mut self,
        core: &mut Core,
        token: Token,
        link: PeerLink,
        frame: Frame,
    ) -> Result<(), WireError> {
        let refuse =
            |what: &'static str| Err(WireError::BadMessage(serde::de::Error::custom(what)));
        match frame {
            Frame::Message(_) => match frame.message::<PeerMessage>()? {
                PeerMessage::Request(ToProvider::Subscribe { .. }) if link.serving.is_some() => {
                    return refuse("a subscriber must not subscribe again");
                }
                PeerMessage::Request(subscribe @ ToProvider::Subscribe { .. }) => {
                    self.on_subscribe(core, token, subscribe);
                }
                PeerMessage::Request(ToProvider::Pull) => match link.serving {
                    Some(serving) => self.on_pull(token, serving.output),
                    None => return refuse("a pull before subscribing"),
                },
                PeerMessage::Request(ToProvider::Unsubscribe) => self.on_unsubscribe(core, token),
                PeerMessage::Answer(FromProvider::Unsubscribed) => {
                    if link.unsubscribing == 0 {
                        return refuse("an answer to no unsubscribe");
                    }
                    if let Some(Conn {
                        role: Role::Peer(link),
                        ..
                    }) = self.conns.get_mut(&token)
                    {
                        link.unsubscribing -= 1;
                    }
                    self.close_if_idle(token);
                }
                // The answer to a subscription given up since.
                PeerMessage::Answer(_) if link.unsubscribing > 0 => {}
                PeerMessage::Answer(answer) => match link.input {
                    Some(index) => self.on_answer(core, token, index, answer),
                    None => return refuse("an answer to no subscription"),
                },
            },
            // A sample of a subscription given up since.
            Frame::Data(_) if link.unsubscribing > 0 => {}
            Frame::Data(data) => {
                let Some(index) = link.input else {
                    return Err(WireError::UnexpectedData);
                };
                let large = data.payload.len() >= crate::wire::LARGE_PAYLOAD_BYTES;
                if (!core.deliver(index, data) || large)
                    && let Some(conn) = self.conns.get_mut(&token)
                {
                    conn.paused = true;
                }
            }
            // The reader handles handshake frames; none reaches a data link.
            Frame::Handshake(..) | Frame::AuthStep => {
                return Err(WireError::Unauthenticated("a handshake frame"));
            }
        }
        Ok(())
    }

    /// Closes `token` once it carries nothing either way (both sides gave their subscriptions
    /// up), after writing what is queued.
    fn close_if_idle(&mut self, token: Token) {
        let idle = self.conns.get(&token).is_some_and(|conn| {
            matches!(
                conn.role,
                Role::Peer(PeerLink {
                    input: None,
                    serving: None,
                    unsubscribing: 0,
                    ..
                })
            )
        });
        if idle && let Some(mut conn) = self.remove_conn(token) {
            let _ = conn.flush();
        }
    }

    fn fail(&mut self, core: &mut Core, token: Token, err: &WireError) {
        let role = self.conns.get(&token).map(|conn| conn.role);
        match role {
            Some(Role::Peer(PeerLink { input: None, .. })) => {
                tracing::warn!("dropping a peer: {err}");
            }
            _ => tracing::debug!(?role, "connection failed: {err}"),
        }
        self.close(core, token);
    }

    fn remove_conn(&mut self, token: Token) -> Option<Conn> {
        let conn = self.conns.remove(&token)?;
        let _ = self
            .poll
            .registry()
            .deregister(&mut SourceFd(&conn.link.inner.as_raw_fd()));
        Some(conn)
    }

    /// Forgets a connection and schedules whatever must replace it.
    fn close(&mut self, core: &mut Core, token: Token) {
        let Some(conn) = self.remove_conn(token) else {
            return;
        };
        let now = Instant::now();
        match conn.role {
            Role::Agent => {
                if !self.agent_lost_logged {
                    tracing::warn!(agent = %self.agent_addr, "agent unreachable; links keep flowing, retrying");
                    self.agent_lost_logged = true;
                }
                self.agent = Link::Down {
                    retry_at: now + AGENT_RETRY,
                };
            }
            Role::Supervisor => {
                tracing::warn!("lost the supervisor; retrying");
                self.supervisor = Link::Down {
                    retry_at: now + SUPERVISOR_RETRY,
                };
            }
            Role::Peer(link) => {
                if let Some(index) = link.input {
                    if matches!(self.inputs[index], InputLink::Linked(_)) {
                        tracing::info!(input = core.inputs[index].name, "provider gone; relinking");
                    }
                    self.inputs[index] = InputLink::Resolve {
                        at: now + RELINK_DELAY,
                    };
                }
                if let Some(Serving { output, .. }) = link.serving {
                    self.subscribers[output].retain(|&other| other != token);
                    tracing::info!(output = core.outputs[output].name, "subscriber left");
                }
            }
        }
    }
}

/// What a readiness event said of a connection's reading side.
#[derive(Clone, Copy)]
enum Readable {
    No,
    Yes,
    /// The peer closed (or the socket failed): the end must be read, however short the data
    /// before it.
    ToTheEnd,
}

/// How far [`Net::read_conn`] reads. Readiness is edge-triggered: an edge not acted on does not
/// come again, so a short read may be taken for "drained" only when the event that woke the
/// loop said nothing of the peer closing. A connection's end that is already in the socket
/// (the peer closed while its input was paused, or before it was accepted, or in the same
/// event as its last data) must be read now, or the link would wait for ever on a dead peer.
#[derive(Clone, Copy, PartialEq, Eq)]
enum UntilBlocked {
    OrShortRead,
    Always,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::InputSlot;

    #[test]
    fn an_input_is_looked_up_only_when_the_agent_can_name_its_provider() {
        let slot = |source: Option<&str>| {
            InputSlot::new(
                "scan".to_owned(),
                "LaserScan".to_owned(),
                source.map(str::to_owned),
                None,
            )
        };
        assert_eq!(resolve_or_unbound(&slot(None)), InputLink::Unbound);
        // The run's health stream comes on the supervisor's connection, not from a provider.
        assert_eq!(
            resolve_or_unbound(&slot(Some(crate::protocol::HEALTH))),
            InputLink::Unbound
        );
        assert!(matches!(
            resolve_or_unbound(&slot(Some("sim.scan"))),
            InputLink::Resolve { .. }
        ));
    }
}
