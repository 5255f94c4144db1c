//! `teleop`: velocity commands from an operator, over a line protocol on a TCP socket.
//!
//! The module listens on `listen`, logs `teleop listening on ADDR` (with the port chosen when
//! `listen` asks for port 0) and tells the supervisor that address (its `teleop` endpoint), so
//! that the operator drives through the run's control interface (`armor ctl teleop`, the
//! studio) wherever the module runs. Each line a client sends is one command, answered by one
//! line, `ok` or `error: WHY`:
//!
//! - `v LINEAR ANGULAR`: drive at LINEAR m/s and turn at ANGULAR rad/s (counter-clockwise),
//!   clamped to `max_speed_mps` and `max_turn_radps`;
//! - `stop`: command zero.
//!
//! When the run has a secret, the port speaks the run's wire protocol instead of lines: the
//! client proves the link key of this module's key for the name it claims (as at a data port,
//! `docs/protocol.md`), the link is encrypted, and each command and answer is a JSON string in
//! a message frame. The supervisor's relay is such a client; a process without a key is
//! closed without a byte and drives nothing.
//!
//! A command is held for `deadman_secs` of *wall-clock* time: an operator who stops sending
//! stops the robot. The operator lives in wall time (the studio and `armor ctl teleop` send
//! ten commands a second of it, whatever the run's time scale), so a dead-man in run time
//! expired between two of their commands at high scales (at ×10 half a second of run time is
//! 50 ms) and the mux switched between teleop and the other sources many times a second. The
//! price of wall time is that a lost link drives on for `deadman_secs × scale` of run time:
//! with the default half a second at ×10, five simulated seconds, at most 2.5 simulated metres
//! at the default `max_speed_mps` (0.25 m on a robot at ×1). Half a second is kept knowingly:
//! a studio drawing its frames slowly (software rendering) may miss a send or two, and a
//! shorter time would stop and restart the robot under the operator's finger.
//!
//! The module publishes the current command at least 20 times per second of wall time and at
//! least 20 times per second of run time (the faster of the two): the mux judges its inputs'
//! freshness in run time, and a release is seen within 50 ms of wall time at any scale. It
//! serves its clients from the same loop, with non-blocking sockets. It is an operator
//! interface, so the mission controller never stops it.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::time::{Duration, Instant};

use armor_module_api::auth::{Listen, Sealer};
use armor_module_api::handshake_deadline::HandshakeDeadline;
use armor_module_api::types::Twist;
use armor_module_api::wire::{Frame, FrameReader, HELLO, WireError};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;

pub const TYPE: &str = "teleop";
/// The endpoint the module says it listens at (`docs/protocol.md`, section 4.2), where the
/// supervisor relays `armor ctl teleop`.
pub const ENDPOINT: &str = "teleop";

/// How often the module serves its clients and publishes the command, in wall time and in run
/// time, whichever comes first.
const TICK_SECS: f64 = 0.05;
/// Longest command line accepted, in bytes.
const MAX_LINE: usize = 256;
/// At most this many operators at once; more are told so and disconnected.
const MAX_CLIENTS: usize = 16;
/// A client that leaves this many bytes of replies unread is disconnected.
const MAX_UNREAD: usize = 64 * 1024;

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Operator velocity commands over TCP: lines `v LINEAR ANGULAR` or `stop`, answered `ok` \
         or `error: ...`; commands are clamped and held for deadman_secs of wall time, after \
         which it commands zero.",
    )
    .category(armor_module_api::Category::Operator)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .output::<Twist>(
        "cmd_vel",
        "the operator's command, 20 times per second of wall time and at least 20 per second \
         of run time (zero when no command arrived within deadman_secs of wall time)",
    )
    .param(
        ParamSpec::new(
            "listen",
            ParamType::String,
            "the TCP address to listen on for operators (port 0: any free port; the address is \
             logged as `teleop listening on ADDR` and told to the supervisor, which relays \
             `armor ctl teleop` there: a teleop on another host than the supervisor's listens \
             on that host's address the supervisor reaches, such as 10.0.0.2:0, in a run with \
             a secret, so that only the run's relay, over an encrypted link, can drive; \
             without a secret keep it on 127.0.0.1); read at start only",
        )
        .default("127.0.0.1:0"),
    )
    .param(
        ParamSpec::new(
            "max_speed_mps",
            ParamType::Float,
            "linear speeds are clamped to ± this (0 or more)",
        )
        .min(0.0)
        .unit("m/s")
        .default("0.5"),
    )
    .param(
        ParamSpec::new(
            "max_turn_radps",
            ParamType::Float,
            "turning speeds are clamped to ± this (0 or more)",
        )
        .min(0.0)
        .unit("rad/s")
        .default("1.0"),
    )
    .param(
        ParamSpec::new(
            "deadman_secs",
            ParamType::Float,
            "a command is held this long in wall-clock time, whatever the run's time scale, \
             then zero is commanded until the next one (greater than 0; a lost link drives on \
             for this times the time scale in run time)",
        )
        .above(0.0)
        .unit("s")
        .default("0.5"),
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let listen: String = node.param("listen")?;
    let listen = listen.trim();
    let listener =
        TcpListener::bind(listen).map_err(|err| format!("cannot listen on `{listen}`: {err}"))?;
    listener.set_nonblocking(true)?;
    let addr = listener.local_addr()?;
    tracing::info!("teleop listening on {addr}");
    // The supervisor relays the operator's commands here (`armor ctl teleop`, the studio).
    node.set_endpoint(crate::teleop::ENDPOINT, &addr.to_string());
    let listen = node.service_listen();
    if listen.is_some() {
        tracing::info!("the run has a secret: commands only over an authenticated, encrypted link");
    }
    serve(node, Server::new(listener, listen))
}

/// The module's loop, serving `server`'s clients.
fn serve(node: &mut Node, mut server: Server) -> BodyResult {
    let output = node.output::<Twist>("cmd_vel")?;
    let mut limits = Limits::read(node)?;
    let mut command = Command::default();
    // Wall time: the operator's time (see the module's documentation).
    let tick = tick_period(node.clock().scale());
    let mut deadline = Instant::now();
    loop {
        match node.next_event_until(deadline)? {
            Event::Timeout => {
                let now = Instant::now();
                deadline = now + tick;
                server.poll(|line| command.handle(line, &limits, now));
                node.send(&output, &command.current(now, limits.deadman()))?;
            }
            Event::ParamsChanged(names) => {
                if names.iter().any(|name| name == "listen") {
                    tracing::warn!("`listen` is read at start only: still on {}", server.addr());
                }
                match Limits::read(node) {
                    Ok(new) => limits = new,
                    Err(err) => tracing::error!("{err}; keeping the previous settings"),
                }
            }
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

/// How long between two ticks in wall time: [`TICK_SECS`] of wall time, or of run time when
/// that is shorter (a run faster than real time).
fn tick_period(scale: f64) -> Duration {
    let run_tick_secs = if scale.is_finite() && scale > 1.0 {
        TICK_SECS / scale
    } else {
        TICK_SECS
    };
    Duration::from_secs_f64(run_tick_secs)
}

/// The teleop's tunable parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    pub max_speed_mps: f64,
    pub max_turn_radps: f64,
    pub deadman_secs: f64,
}

impl Limits {
    fn read(node: &Node) -> Result<Self, BodyError> {
        Ok(Self {
            max_speed_mps: node.param::<f64>("max_speed_mps")?,
            max_turn_radps: node.param::<f64>("max_turn_radps")?,
            deadman_secs: node.param::<f64>("deadman_secs")?,
        })
    }

    /// The dead-man time in wall time (the parameter is checked above 0 where it is read; a
    /// huge value saturates rather than panics).
    fn deadman(&self) -> Duration {
        Duration::try_from_secs_f64(self.deadman_secs).unwrap_or(Duration::MAX)
    }
}

/// The operator's latest command and when it came, in wall time.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Command {
    twist: Twist,
    at: Option<Instant>,
}

impl Command {
    /// Takes one command line; returns the reply (without its newline).
    fn handle(&mut self, line: &str, limits: &Limits, now: Instant) -> String {
        match parse(line, limits) {
            Ok(twist) => {
                self.twist = twist;
                self.at = Some(now);
                "ok".to_owned()
            }
            Err(why) => format!("error: {why}"),
        }
    }

    /// What to publish at `now`: the command, or zero once it is `deadman` old.
    fn current(&self, now: Instant, deadman: Duration) -> Twist {
        match self.at {
            Some(at) if now.saturating_duration_since(at) < deadman => self.twist,
            _ => Twist::default(),
        }
    }
}

/// Reads a command line: `v LINEAR ANGULAR` (clamped) or `stop`.
fn parse(line: &str, limits: &Limits) -> Result<Twist, String> {
    let words: Vec<&str> = line.split_whitespace().collect();
    match words.as_slice() {
        ["stop"] => Ok(Twist::default()),
        ["v", linear, angular] => {
            let number = |text: &str, what: &str| match text.parse::<f64>() {
                Ok(value) if value.is_finite() => Ok(value),
                _ => Err(format!("{what} `{text}` is not a finite number")),
            };
            Ok(Twist {
                linear_mps: number(linear, "LINEAR")?
                    .clamp(-limits.max_speed_mps, limits.max_speed_mps),
                angular_radps: number(angular, "ANGULAR")?
                    .clamp(-limits.max_turn_radps, limits.max_turn_radps),
            })
        }
        ["v", ..] => Err("expected `v LINEAR ANGULAR` (m/s, rad/s)".to_owned()),
        _ => Err(format!(
            "unknown command `{line}`: expected `v LINEAR ANGULAR` or `stop`"
        )),
    }
}

/// The listening socket and the connected operators, all non-blocking.
struct Server {
    listener: TcpListener,
    /// With a secret: how clients authenticate.
    listen: Option<Listen>,
    clients: Vec<Client>,
}

/// A client's link when the run has a secret.
struct Secure {
    reader: FrameReader,
    sealer: Option<Sealer>,
    /// The hello goes out with the answer to a valid first handshake message: a stranger gets
    /// not a byte.
    hello_owed: bool,
    /// Until the handshake is done: short for the first message, a round trip more once it
    /// proved a key (a slow radio link).
    deadline: Option<HandshakeDeadline>,
}

struct Client {
    stream: TcpStream,
    peer: SocketAddr,
    /// Bytes received but not yet a whole line.
    inbox: Vec<u8>,
    /// Replies not yet written.
    outbox: Vec<u8>,
    /// The current line is too long: skip it up to its end.
    skipping: bool,
    /// The client hung up or failed: drop it once its replies are written (or cannot be).
    gone: bool,
    /// The authenticated link, when the run has a secret (else lines in the clear).
    secure: Option<Secure>,
}

impl Server {
    fn new(listener: TcpListener, listen: Option<Listen>) -> Self {
        Self {
            listener,
            listen,
            clients: Vec::new(),
        }
    }

    fn addr(&self) -> String {
        self.listener
            .local_addr()
            .map_or_else(|err| format!("(unknown: {err})"), |addr| addr.to_string())
    }

    /// Takes a connection accepted elsewhere.
    fn adopt(&mut self, stream: TcpStream, peer: SocketAddr) {
        let ready = stream
            .set_nonblocking(true)
            .and_then(|()| stream.set_nodelay(true));
        if let Err(err) = ready {
            tracing::warn!("dropping operator {peer}: {err}");
            return;
        }
        if self.clients.len() >= MAX_CLIENTS {
            // Strangers still in their handshake make room: the oldest goes.
            let oldest = self
                .clients
                .iter()
                .enumerate()
                .filter_map(|(at, client)| {
                    let deadline = client.secure.as_ref()?.deadline?;
                    // A stranger goes before a client whose first message proved a key.
                    Some(((deadline.has_proved(), deadline.at()), at))
                })
                .min();
            match oldest {
                Some((_, at)) => {
                    self.clients.remove(at);
                }
                None => {
                    tracing::warn!("refusing operator {peer}: {MAX_CLIENTS} already connected");
                    if self.listen.is_none() {
                        let _ = (&stream).write(b"error: too many operators connected\n");
                    }
                    return;
                }
            }
        }
        let secure = self.listen.clone().map(|listen| Secure {
            reader: FrameReader::listener(Some(listen)),
            sealer: None,
            hello_owed: true,
            deadline: Some(HandshakeDeadline::accepted(Instant::now())),
        });
        if secure.is_none() {
            tracing::info!("operator connected from {peer}");
        }
        self.clients.push(Client {
            stream,
            peer,
            inbox: Vec::new(),
            outbox: Vec::new(),
            skipping: false,
            gone: false,
            secure,
        });
    }

    /// Accepts new operators, hands each complete line to `handle` and queues its reply, writes
    /// what the sockets take, and drops the clients that are gone. Never blocks.
    fn poll(&mut self, mut handle: impl FnMut(&str) -> String) {
        loop {
            match self.listener.accept() {
                Ok((stream, peer)) => self.adopt(stream, peer),
                Err(err) if err.kind() == ErrorKind::Interrupted => {}
                Err(err) => {
                    if err.kind() != ErrorKind::WouldBlock {
                        tracing::warn!("cannot accept an operator: {err}");
                    }
                    break;
                }
            }
        }
        let now = Instant::now();
        for client in &mut self.clients {
            if client.secure.is_some() {
                client.serve_secure(&mut handle, now);
            } else {
                client.receive();
                client.answer(&mut handle);
            }
            client.send();
        }
        self.clients.retain(|client| {
            let keep = !client.gone;
            let opened = client
                .secure
                .as_ref()
                .is_none_or(|secure| secure.deadline.is_none());
            if !keep && opened {
                tracing::info!("operator {} disconnected", client.peer);
            }
            keep
        });
    }
}

impl Client {
    /// Reads what an authenticating (or authenticated) client sent, answers its handshake and
    /// its commands; a client that fails the handshake, or does not finish it in time, goes.
    fn serve_secure(&mut self, handle: &mut impl FnMut(&str) -> String, now: Instant) {
        if let Err(err) = self.advance_secure(handle) {
            match err {
                WireError::Closed => {}
                err => tracing::warn!("refused {}: {err}", self.peer),
            }
            self.gone = true;
        }
        let late = self
            .secure
            .as_ref()
            .and_then(|secure| secure.deadline)
            .is_some_and(|deadline| deadline.expired(now));
        if late {
            tracing::warn!(
                "{} did not finish its handshake in time: dropped",
                self.peer
            );
            self.gone = true;
        }
    }

    fn advance_secure(&mut self, handle: &mut impl FnMut(&str) -> String) -> Result<(), WireError> {
        let Some(secure) = self.secure.as_mut() else {
            return Ok(());
        };
        loop {
            if secure.reader.take_hello()?
                && let Some(frame) = secure.reader.next_frame()?
            {
                match frame {
                    Frame::AuthStep => {
                        let step = secure.reader.take_auth_step();
                        if std::mem::take(&mut secure.hello_owed) {
                            self.outbox.extend_from_slice(&HELLO);
                            if let Some(deadline) = secure.deadline.as_mut() {
                                deadline.proved(Instant::now());
                            }
                        }
                        self.outbox.extend_from_slice(&step.reply);
                        secure.sealer = step.sealer.or(secure.sealer.take());
                        if step.done {
                            secure.deadline = None;
                            tracing::info!(
                                "operator {} connected as `{}`",
                                self.peer,
                                step.peer.as_deref().unwrap_or("?")
                            );
                        }
                    }
                    frame => {
                        let line: String = frame.message()?;
                        let reply = if line.len() > MAX_LINE {
                            format!("error: line longer than {MAX_LINE} bytes")
                        } else {
                            handle(line.trim())
                        };
                        let mut plain = Vec::new();
                        armor_module_api::wire::encode_message(&mut plain, &reply)?;
                        let Some(sealer) = secure.sealer.as_mut() else {
                            return Err(WireError::Unauthenticated("an unencrypted link"));
                        };
                        sealer.seal_records(&plain, &mut self.outbox);
                    }
                }
                continue;
            }
            match secure.reader.fill_from(&mut self.stream) {
                Ok(0) => return Err(WireError::Closed),
                Ok(_) => {}
                Err(err) if err.kind() == ErrorKind::WouldBlock => return Ok(()),
                Err(err) if err.kind() == ErrorKind::Interrupted => {}
                Err(err) => return Err(err.into()),
            }
        }
    }

    fn receive(&mut self) {
        let mut buffer = [0u8; 1024];
        loop {
            match self.stream.read(&mut buffer) {
                Ok(0) => {
                    self.gone = true;
                    break;
                }
                Ok(count) => self.inbox.extend_from_slice(&buffer[..count]),
                Err(err) if err.kind() == ErrorKind::Interrupted => {}
                Err(err) if err.kind() == ErrorKind::WouldBlock => break,
                Err(err) => {
                    tracing::warn!("operator {}: {err}", self.peer);
                    self.gone = true;
                    break;
                }
            }
        }
    }

    fn answer(&mut self, handle: &mut impl FnMut(&str) -> String) {
        while let Some(end) = self.inbox.iter().position(|byte| *byte == b'\n') {
            let line: Vec<u8> = self.inbox.drain(..=end).collect();
            if std::mem::take(&mut self.skipping) {
                continue;
            }
            let reply = if line.len() > MAX_LINE + 1 {
                format!("error: line longer than {MAX_LINE} bytes")
            } else {
                let text = String::from_utf8_lossy(&line);
                let text = text.trim();
                if text.is_empty() {
                    continue;
                }
                handle(text)
            };
            self.queue(&reply);
        }
        if self.inbox.len() > MAX_LINE {
            self.inbox.clear();
            if !self.skipping {
                self.skipping = true;
                self.queue(&format!("error: line longer than {MAX_LINE} bytes"));
            }
        }
    }

    fn queue(&mut self, reply: &str) {
        self.outbox.extend_from_slice(reply.as_bytes());
        self.outbox.push(b'\n');
    }

    fn send(&mut self) {
        while !self.outbox.is_empty() {
            match self.stream.write(&self.outbox) {
                Ok(0) => {
                    self.gone = true;
                    break;
                }
                Ok(count) => {
                    self.outbox.drain(..count);
                }
                Err(err) if err.kind() == ErrorKind::Interrupted => {}
                Err(err) if err.kind() == ErrorKind::WouldBlock => break,
                Err(_) => {
                    self.gone = true;
                    break;
                }
            }
        }
        if self.outbox.len() > MAX_UNREAD {
            tracing::warn!("operator {} does not read its replies", self.peer);
            self.gone = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};
    use std::io::{BufRead, BufReader};
    use std::time::Duration;

    fn limits() -> Limits {
        Limits {
            max_speed_mps: 0.5,
            max_turn_radps: 1.0,
            deadman_secs: 0.5,
        }
    }

    fn twist(linear_mps: f64, angular_radps: f64) -> Twist {
        Twist {
            linear_mps,
            angular_radps,
        }
    }

    #[test]
    fn commands_are_parsed_and_clamped() {
        let limits = limits();
        assert_eq!(parse("v 0.2 -0.3", &limits), Ok(twist(0.2, -0.3)));
        assert_eq!(parse("  v   3  -7 ", &limits), Ok(twist(0.5, -1.0)));
        assert_eq!(parse("v -3 7", &limits), Ok(twist(-0.5, 1.0)));
        assert_eq!(parse("stop", &limits), Ok(Twist::default()));
    }

    /// `secs` seconds after `start`.
    fn at(start: Instant, secs: f64) -> Instant {
        start + Duration::from_secs_f64(secs)
    }

    #[test]
    fn garbage_is_an_error_and_leaves_the_command_alone() {
        let limits = limits();
        let start = Instant::now();
        let mut command = Command::default();
        assert_eq!(command.handle("v 0.2 0.1", &limits, at(start, 1.0)), "ok");
        for garbage in [
            "fly", "v", "v 1", "v 1 2 3", "v one 2", "v NaN 0", "v 0 inf", "stop now",
        ] {
            let reply = command.handle(garbage, &limits, at(start, 1.1));
            assert!(reply.starts_with("error: "), "{garbage}: {reply}");
        }
        assert_eq!(
            command.current(at(start, 1.2), limits.deadman()),
            twist(0.2, 0.1)
        );
    }

    #[test]
    fn the_dead_man_zeroes_an_old_command() {
        let limits = limits();
        let deadman = limits.deadman();
        let start = Instant::now();
        let mut command = Command::default();
        assert_eq!(
            command.current(start, deadman),
            Twist::default(),
            "no command yet"
        );
        command.handle("v 0.3 0.2", &limits, at(start, 10.0));
        assert_eq!(command.current(at(start, 10.0), deadman), twist(0.3, 0.2));
        assert_eq!(command.current(at(start, 10.49), deadman), twist(0.3, 0.2));
        assert_eq!(command.current(at(start, 10.5), deadman), Twist::default());
        command.handle("v 0.1 0", &limits, at(start, 11.0));
        assert_eq!(
            command.current(at(start, 11.2), deadman),
            twist(0.1, 0.0),
            "a new command"
        );
        command.handle("stop", &limits, at(start, 11.3));
        assert_eq!(command.current(at(start, 11.4), deadman), Twist::default());
    }

    #[test]
    fn ticks_twenty_times_a_second_of_wall_time_or_of_run_time_when_faster() {
        assert_eq!(tick_period(1.0), Duration::from_millis(50));
        assert_eq!(tick_period(0.1), Duration::from_millis(50), "slower runs");
        assert_eq!(tick_period(10.0), Duration::from_millis(5));
        assert_eq!(tick_period(f64::NAN), Duration::from_millis(50));
    }

    /// A server whose client has sent `lines`, already received on the server's side.
    fn connected(lines: &[u8]) -> (Server, TcpStream) {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let mut client = TcpStream::connect(listener.local_addr().expect("addr")).expect("connect");
        client.write_all(lines).expect("write");
        let (stream, peer) = listener.accept().expect("accept");
        let mut peeked = vec![0; lines.len()];
        while stream.peek(&mut peeked).expect("peek") < lines.len() {}
        listener.set_nonblocking(true).expect("non-blocking");
        let mut server = Server::new(listener, None);
        server.adopt(stream, peer);
        client
            .set_read_timeout(Some(Duration::from_secs(10)))
            .expect("timeout");
        (server, client)
    }

    fn replies(client: TcpStream, count: usize) -> Vec<String> {
        BufReader::new(client)
            .lines()
            .take(count)
            .map(|line| line.expect("reply"))
            .collect()
    }

    #[test]
    fn serves_the_socket_from_its_loop() {
        let (server, client) = connected(b"v 5 -9\nfly\n\nv 1\n");
        let mut bench = TestBench::new(&spec(), &[("deadman_secs", "60")]).expect("bench");
        bench.script([Step::Timeouts(2)]);
        serve(bench.node(), server).expect("serve");
        let replies = replies(client, 3);
        assert_eq!(replies[0], "ok");
        assert!(
            replies[1].starts_with("error: unknown command `fly`"),
            "{replies:?}"
        );
        assert!(replies[2].starts_with("error: "), "{replies:?}");
        assert_eq!(
            bench.sent::<Twist>("cmd_vel").expect("sent"),
            [twist(0.5, -1.0); 2],
            "clamped, and held"
        );
    }

    #[test]
    fn refuses_overlong_lines_and_goes_on() {
        let mut lines = vec![b'x'; 2000];
        lines.extend_from_slice(b"\nstop\n");
        lines.extend(std::iter::repeat_n(b'y', 300));
        lines.extend_from_slice(b"\nv 0.1 0\n");
        let (server, client) = connected(&lines);
        let mut bench = TestBench::new(&spec(), &[("deadman_secs", "60")]).expect("bench");
        bench.script([Step::Timeouts(1)]);
        serve(bench.node(), server).expect("serve");
        let replies = replies(client, 4);
        assert!(replies[0].starts_with("error: line longer"), "{replies:?}");
        assert_eq!(replies[1], "ok");
        assert!(replies[2].starts_with("error: line longer"), "{replies:?}");
        assert_eq!(replies[3], "ok");
        assert_eq!(
            bench.sent::<Twist>("cmd_vel").expect("sent"),
            [twist(0.1, 0.0)]
        );
    }

    #[test]
    fn publishes_zero_without_an_operator_and_survives_a_bad_live_limit() {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        listener.set_nonblocking(true).expect("non-blocking");
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        bench.script([
            Step::Timeouts(2),
            Step::param("max_speed_mps", "-1"),
            Step::Timeouts(1),
        ]);
        serve(bench.node(), Server::new(listener, None)).expect("serve");
        assert_eq!(
            bench.sent::<Twist>("cmd_vel").expect("sent"),
            [Twist::default(); 3]
        );
    }

    #[test]
    fn tells_the_supervisor_where_it_listens() {
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        bench.script([Step::Timeouts(1)]);
        body(bench.node()).expect("body");
        let endpoints = bench.endpoints();
        assert_eq!(endpoints.len(), 1, "{endpoints:?}");
        let addr = endpoints[0]
            .strip_prefix("teleop 127.0.0.1:")
            .unwrap_or_else(|| panic!("{endpoints:?}"));
        assert!(addr.parse::<u16>().is_ok_and(|port| port > 0), "{addr}");
    }

    #[test]
    fn refuses_an_address_it_cannot_listen_on() {
        let mut bench = TestBench::new(&spec(), &[("listen", "nowhere")]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse");
        assert!(
            err.to_string().contains("cannot listen on `nowhere`"),
            "{err}"
        );
    }
}
