//! The supervisor's side of the host daemons ([`crate::host`]): one [`HostLink`] per declared
//! host, which connects (and connects again after a loss), measures the host's clock against
//! ours, starts modules there and follows them as [`RemoteChild`]ren, the remote counterpart of
//! a `std::process::Child`. `armor check` asks a host which module types it lacks with
//! [`missing_types`].

use std::collections::HashMap;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs as _};
use std::process::ExitStatus;
use std::sync::mpsc::{self, Sender};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use armor_model::HostDecl;
use armor_module_api::auth::{Dial, Secret};
use armor_module_api::clock::unix_now_ns;
use armor_module_api::wire::blocking::{self, SecureWriter};

use crate::host::{FromHost, PING_EVERY, SUPERVISOR_IDENTITY, ToHost};

/// How long a connection attempt may take.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(1);
/// Silence from a host after which it is lost (it answers every ping).
pub const HOST_SILENCE: Duration = Duration::from_secs(2);
/// Round trips the clock offset is measured over, at each join.
const CLOCK_SAMPLES: usize = 5;
/// Between two connection attempts to a host that is away.
const RETRY_EVERY: Duration = Duration::from_millis(300);
/// The raw wait status of a module that went with its host (as if killed by SIGKILL).
const LOST_STATUS: i32 = libc::SIGKILL;
/// The raw wait status of a module its host could not start (as if it exited with 127).
const NOT_STARTED_STATUS: i32 = 127 << 8;

/// What a link reports to the run, taken with [`HostLink::take_notes`].
#[derive(Clone, Debug, PartialEq)]
pub enum HostNote {
    /// Connected (again); the host's clock minus ours and the round trip it was measured over.
    Joined { offset_ms: f64, round_trip_ms: f64 },
    /// The connection is gone: its modules are taken as ended.
    Lost { why: String },
    /// A connection attempt failed (reported once until it joins).
    Unreachable { why: String },
    /// A line of a module's output.
    Log { module: String, line: String },
    /// The host could not start a module.
    SpawnFailed { module: String, error: String },
}

#[derive(Default)]
struct Child {
    generation: u64,
    pid: Option<u32>,
    /// The raw wait status, once it ended.
    status: Option<i32>,
}

#[derive(Default)]
struct LinkState {
    writer: Option<SecureWriter>,
    /// Bumped at every connection, so that a late reader of an old one changes nothing.
    connection: u64,
    children: HashMap<String, Child>,
    notes: Vec<HostNote>,
    /// The host's clock minus ours, in ms, from the latest connection.
    offset_ms: Option<f64>,
    replies: HashMap<u64, Sender<FromHost>>,
    next_id: u64,
    unreachable_said: bool,
}

struct Shared {
    name: String,
    addr: String,
    secret: Option<Secret>,
    run: String,
    orphan: Duration,
    state: Mutex<LinkState>,
}

/// The supervisor's link to one host daemon; cheap to clone.
#[derive(Clone)]
pub struct HostLink(Arc<Shared>);

/// What a host needs to know of the run to start one of its modules.
#[derive(Clone, Copy, Debug)]
pub struct SpawnRun {
    pub agent: SocketAddr,
    pub supervisor: SocketAddr,
    pub epoch_ns: u64,
    pub time_scale: f64,
    pub encrypt: bool,
}

impl std::fmt::Debug for HostLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "HostLink({} at {})", self.0.name, self.0.addr)
    }
}

/// A module started on a host: what the supervisor holds instead of a `Child`.
#[derive(Debug)]
pub struct RemoteChild {
    link: HostLink,
    name: String,
    generation: u64,
}

/// Resolves `host:port` (a name or an address).
fn resolve(addr: &str) -> std::io::Result<SocketAddr> {
    addr.to_socket_addrs()?
        .next()
        .ok_or_else(|| std::io::Error::other(format!("`{addr}` resolves to no address")))
}

/// Connects to a host daemon, proves the secret and says hello; returns the stream and the
/// host's welcome.
fn connect(
    addr: &str,
    secret: Option<&Secret>,
    run: &str,
    orphan: Duration,
    query: bool,
) -> anyhow::Result<(blocking::SecureReader, SecureWriter, FromHost)> {
    use anyhow::Context as _;
    let socket = resolve(addr)?;
    let stream = TcpStream::connect_timeout(&socket, CONNECT_TIMEOUT)
        .with_context(|| format!("cannot reach {addr}"))?;
    stream.set_nodelay(true)?;
    stream.set_read_timeout(Some(CONNECT_TIMEOUT * 3))?;
    let dial = secret.map(|secret| Dial {
        key: secret.module_key(SUPERVISOR_IDENTITY),
        identity: SUPERVISOR_IDENTITY.to_owned(),
        encrypt: true,
    });
    let stream = blocking::dial(stream, dial.as_ref()).map_err(|err| {
        anyhow::anyhow!(
            "{addr}: {err} (does the host daemon run with the same secret as this run?)"
        )
    })?;
    let (mut reader, mut writer) = stream.split();
    blocking::write_message(
        &mut writer,
        &ToHost::Hello {
            run: run.to_owned(),
            orphan_ms: orphan.as_millis().try_into().unwrap_or(u64::MAX),
            query,
        },
    )?;
    let welcome: FromHost = blocking::read_message(&mut reader).map_err(|err| {
        anyhow::anyhow!(
            "{addr} did not welcome us: {err} (with --secret, the host daemon must have the same secret)"
        )
    })?;
    if let FromHost::Refused { message } = welcome {
        anyhow::bail!("{addr} refused: {message}");
    }
    Ok((reader, writer, welcome))
}

impl HostLink {
    /// Starts following the host: connects in the background, and again whenever it is lost.
    pub fn start(decl: &HostDecl, secret: Option<Secret>, run: &str, orphan: Duration) -> Self {
        let link = HostLink(Arc::new(Shared {
            name: decl.name.clone(),
            addr: decl.daemon_addr(),
            secret,
            run: run.to_owned(),
            orphan,
            state: Mutex::new(LinkState::default()),
        }));
        let background = link.clone();
        std::thread::spawn(move || background.keep_connected());
        link
    }

    pub fn name(&self) -> &str {
        &self.0.name
    }

    pub fn addr(&self) -> &str {
        &self.0.addr
    }

    fn lock(&self) -> MutexGuard<'_, LinkState> {
        self.0.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    pub fn is_connected(&self) -> bool {
        self.lock().writer.is_some()
    }

    /// The host's clock minus ours (ms), as measured when it last joined.
    pub fn offset_ms(&self) -> Option<f64> {
        self.lock().offset_ms
    }

    /// Waits until the link is up, at most `timeout`.
    pub fn wait_connected(&self, timeout: Duration) -> bool {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if self.is_connected() {
                return true;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        self.is_connected()
    }

    pub fn take_notes(&self) -> Vec<HostNote> {
        std::mem::take(&mut self.lock().notes)
    }

    fn send(&self, message: &ToHost) -> bool {
        let mut state = self.lock();
        let Some(writer) = &mut state.writer else {
            return false;
        };
        if blocking::write_message(writer, message).is_err() {
            let _ = writer.get_ref().shutdown(std::net::Shutdown::Both);
            return false;
        }
        true
    }

    /// Sends a request and waits for its answer.
    fn ask(&self, make: impl FnOnce(u64) -> ToHost, timeout: Duration) -> Option<FromHost> {
        let (tx, rx) = mpsc::channel();
        let id = {
            let mut state = self.lock();
            state.next_id += 1;
            let id = state.next_id;
            state.replies.insert(id, tx);
            id
        };
        let sent = self.send(&make(id));
        let answer = sent.then(|| rx.recv_timeout(timeout).ok()).flatten();
        self.lock().replies.remove(&id);
        answer
    }

    /// The module types of `types` the host has no binary for; `None` if it did not answer.
    pub fn missing(&self, types: Vec<String>) -> Option<Vec<String>> {
        match self.ask(|id| ToHost::Check { id, types }, HOST_SILENCE)? {
            FromHost::Check { missing, .. } => Some(missing),
            _ => None,
        }
    }

    /// Asks the host to start a module for this run (the host builds its environment from
    /// `run` and derives its key from its own secret).
    pub fn spawn(&self, name: &str, module_type: &str, run: &SpawnRun) -> Option<RemoteChild> {
        let generation = {
            let mut state = self.lock();
            state.writer.as_ref()?;
            let child = state.children.entry(name.to_owned()).or_default();
            child.generation += 1;
            child.pid = None;
            child.status = None;
            child.generation
        };
        let message = ToHost::Spawn {
            name: name.to_owned(),
            module_type: module_type.to_owned(),
            generation,
            agent: run.agent.to_string(),
            supervisor: run.supervisor.to_string(),
            epoch_ns: run.epoch_ns,
            time_scale: run.time_scale,
            encrypt: run.encrypt,
        };
        if !self.send(&message) {
            return None;
        }
        Some(RemoteChild {
            link: self.clone(),
            name: name.to_owned(),
            generation,
        })
    }

    fn keep_connected(&self) {
        loop {
            match connect(
                &self.0.addr,
                self.0.secret.as_ref(),
                &self.0.run,
                self.0.orphan,
                false,
            ) {
                Ok((reader, writer, _welcome)) => {
                    let connection = {
                        let mut state = self.lock();
                        state.writer = Some(writer);
                        state.connection += 1;
                        state.unreachable_said = false;
                        state.connection
                    };
                    self.follow(reader, connection);
                }
                Err(err) => {
                    let mut state = self.lock();
                    if !state.unreachable_said {
                        state.unreachable_said = true;
                        state.notes.push(HostNote::Unreachable {
                            why: format!("{err:#}"),
                        });
                    }
                }
            }
            std::thread::sleep(RETRY_EVERY);
        }
    }

    /// Reads the host's messages until the connection is lost, pinging it meanwhile.
    fn follow(&self, mut reader: blocking::SecureReader, connection: u64) {
        let pinger = self.clone();
        std::thread::spawn(move || {
            while pinger.lock().connection == connection && pinger.send(&ToHost::Ping) {
                std::thread::sleep(PING_EVERY);
            }
        });
        let _ = reader.get_ref().set_read_timeout(Some(HOST_SILENCE));
        // The clock, as NTP does: over a few round trips (answered by the reader below), the
        // one that took least bounds the error best (half its round trip).
        let measurer = self.clone();
        std::thread::spawn(move || {
            let mut best: Option<(f64, f64)> = None;
            for _ in 0..CLOCK_SAMPLES {
                let sent = unix_now_ns();
                let answer = measurer.ask(|id| ToHost::Time { id }, HOST_SILENCE);
                let back = unix_now_ns();
                let Some(FromHost::Time { unix_ns, .. }) = answer else {
                    break;
                };
                let middle = sent as f64 / 2.0 + back as f64 / 2.0;
                let offset_ms = (unix_ns as f64 - middle) / 1e6;
                let round_trip_ms = back.saturating_sub(sent) as f64 / 1e6;
                if best.is_none_or(|(_, best_trip)| round_trip_ms < best_trip) {
                    best = Some((offset_ms, round_trip_ms));
                }
            }
            let (offset_ms, round_trip_ms) = best.unwrap_or((f64::NAN, f64::NAN));
            let mut state = measurer.lock();
            if best.is_some() {
                state.offset_ms = Some(offset_ms);
            }
            state.notes.push(HostNote::Joined {
                offset_ms,
                round_trip_ms,
            });
        });
        let why = loop {
            let message = match blocking::read_message::<FromHost>(&mut reader) {
                Ok(message) => message,
                Err(err) => break format!("{err}"),
            };
            let mut state = self.lock();
            match message {
                FromHost::Pong | FromHost::Welcome { .. } | FromHost::Refused { .. } => {}
                FromHost::Time { id, .. } | FromHost::Check { id, .. } => {
                    if let Some(reply) = state.replies.remove(&id) {
                        let _ = reply.send(message);
                    }
                }
                FromHost::Log { name, line } => {
                    state.notes.push(HostNote::Log { module: name, line });
                }
                FromHost::Started {
                    name,
                    generation,
                    pid,
                } => {
                    if let Some(child) = state.children.get_mut(&name)
                        && child.generation == generation
                    {
                        child.pid = Some(pid);
                    }
                }
                FromHost::SpawnFailed {
                    name,
                    generation,
                    error,
                } => {
                    if let Some(child) = state.children.get_mut(&name)
                        && child.generation == generation
                    {
                        child.status = Some(NOT_STARTED_STATUS);
                    }
                    state.notes.push(HostNote::SpawnFailed {
                        module: name,
                        error,
                    });
                }
                FromHost::Exited {
                    name,
                    generation,
                    status,
                } => {
                    if let Some(child) = state.children.get_mut(&name)
                        && child.generation == generation
                    {
                        child.status = Some(status);
                    }
                }
            }
        };
        let mut state = self.lock();
        if let Some(writer) = state.writer.take() {
            let _ = writer.get_ref().shutdown(std::net::Shutdown::Both);
        }
        state.connection += 1;
        for child in state.children.values_mut() {
            child.status.get_or_insert(LOST_STATUS);
        }
        state.notes.push(HostNote::Lost { why });
    }
}

impl RemoteChild {
    /// The process id on its host, once started there.
    pub fn id(&self) -> Option<u32> {
        let state = self.link.lock();
        state
            .children
            .get(&self.name)
            .filter(|child| child.generation == self.generation)
            .and_then(|child| child.pid)
    }

    pub fn host(&self) -> &str {
        self.link.name()
    }

    /// How it ended, if it did (a module whose host is lost has ended as if killed).
    pub fn try_wait(&self) -> Option<ExitStatus> {
        use std::os::unix::process::ExitStatusExt as _;
        let state = self.link.lock();
        let child = state.children.get(&self.name)?;
        if child.generation != self.generation {
            // Started again since: this one is over.
            return Some(ExitStatus::from_raw(LOST_STATUS));
        }
        child.status.map(ExitStatus::from_raw)
    }

    /// Whether it ended because its host was lost rather than on its own.
    pub fn lost_with_host(&self) -> bool {
        !self.link.is_connected()
    }

    /// Sends a signal to its process group on the host.
    pub fn signal(&self, signal: i32) {
        self.link.send(&ToHost::Signal {
            name: self.name.clone(),
            generation: self.generation,
            signal,
        });
    }
}

/// Asks the daemon at `decl` which of `types` it has no binary for; `Err` when it cannot be
/// asked (not running, another secret).
pub fn missing_types(
    decl: &HostDecl,
    secret: Option<&Secret>,
    types: Vec<String>,
) -> anyhow::Result<Vec<String>> {
    // A query: the host stays with the run that uses it, if one does.
    let (mut reader, mut writer, _) = connect(
        &decl.daemon_addr(),
        secret,
        "armor check",
        Duration::ZERO,
        true,
    )?;
    blocking::write_message(&mut writer, &ToHost::Check { id: 1, types })?;
    loop {
        match blocking::read_message::<FromHost>(&mut reader)? {
            FromHost::Check { missing, .. } => return Ok(missing),
            FromHost::Refused { message } => anyhow::bail!("{message}"),
            _ => {}
        }
    }
}

/// A module's process as the supervisor holds it: a child of its own, or one on a host.
#[derive(Debug)]
pub enum ModuleChild {
    Local(std::process::Child),
    Remote(RemoteChild),
}

impl ModuleChild {
    /// Its process id (on its host, for a remote one; `None` until the host said).
    pub fn id(&self) -> Option<u32> {
        match self {
            ModuleChild::Local(child) => Some(child.id()),
            ModuleChild::Remote(child) => child.id(),
        }
    }

    pub fn try_wait(&mut self) -> std::io::Result<Option<ExitStatus>> {
        match self {
            ModuleChild::Local(child) => child.try_wait(),
            ModuleChild::Remote(child) => Ok(child.try_wait()),
        }
    }

    /// Sends a signal to the process (a remote one: to its process group).
    pub fn signal(&self, signal: i32) {
        match self {
            ModuleChild::Local(child) => {
                if let Ok(pid) = libc::pid_t::try_from(child.id()) {
                    crate::process::kill(pid, signal);
                }
            }
            ModuleChild::Remote(child) => child.signal(signal),
        }
    }

    /// SIGKILL to its process group, at once.
    pub fn kill_group(&self) {
        match self {
            ModuleChild::Local(child) => {
                if let Ok(pid) = libc::pid_t::try_from(child.id()) {
                    crate::process::kill(-pid, libc::SIGKILL);
                    crate::process::kill(pid, libc::SIGKILL);
                }
            }
            ModuleChild::Remote(child) => child.signal(libc::SIGKILL),
        }
    }

    /// Kills it and waits for its end (a remote one: as long as its host answers).
    pub fn kill_and_wait(&mut self) {
        match self {
            ModuleChild::Local(child) => {
                let _ = child.kill();
                let _ = child.wait();
            }
            ModuleChild::Remote(child) => {
                child.signal(libc::SIGKILL);
                let deadline = Instant::now() + HOST_SILENCE;
                while child.try_wait().is_none() && Instant::now() < deadline {
                    std::thread::sleep(Duration::from_millis(10));
                }
            }
        }
    }

    /// The host it runs on, for a remote one.
    pub fn host(&self) -> Option<&str> {
        match self {
            ModuleChild::Local(_) => None,
            ModuleChild::Remote(child) => Some(child.host()),
        }
    }
}
