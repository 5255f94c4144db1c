//! The config server: each module connects to it at start, says who it is, and gets its port
//! bindings and parameters. The same connection carries control (start, stop, shutdown) to the
//! module and event reports back.
//!
//! It watches the system file (its parent folder, since editors save by renaming a new file over
//! the old) and reloads it on change: a valid edit reaches every module whose configuration it
//! changes; an invalid one is reported with `FILE:LINE:COL` and the last good one stays in force.
//!
//! Heartbeat: every module is pinged several times per lease; one that has sent nothing (its
//! answers included) for a whole lease is reported [`ServerEvent::Unresponsive`] — stopped
//! (SIGSTOP) or stuck in its own code — and the supervisor handles it as a crash. A module's
//! event loop answers pings by itself whenever the module waits for its next event.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::io::Write as _;
use std::net::{IpAddr, SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use crate::behaviour::{self, Behaviours};
use armor_model::system::{Reason, demand};
use armor_model::{Endpoint, ModuleInstance};
use armor_module_api::Clock;
use armor_module_api::auth::{Admit, Listen, Secret};
use armor_module_api::protocol::{FromSupervisor, ModuleConfig, NodeStats, ToSupervisor};
use armor_module_api::wire::blocking::{SecureStream, SecureWriter};
use armor_module_api::wire::{WireError, blocking};
use notify::{RecursiveMode, Watcher as _};

use crate::health::HealthBook;
use crate::load::{Loaded, load_system};

const HANDSHAKE_TIMEOUT: Duration = Duration::from_secs(5);
/// Editors write a file in several steps; wait for this much quiet before reloading.
const SETTLE: Duration = Duration::from_millis(50);
/// Pings per lease: a module answers within a fraction of the lease when it is alive.
const PINGS_PER_LEASE: u32 = 4;
/// Checks of silence per lease: a module silent for a lease is found stalled at most a
/// sixteenth of a lease later.
const CHECKS_PER_LEASE: u32 = 16;
/// A write to a module that does not read (stopped) gives up after this long, so that one such
/// module never holds up the others.
const WRITE_TIMEOUT: Duration = Duration::from_secs(1);

/// What the config server tells the supervisor.
#[derive(Debug)]
pub enum ServerEvent {
    /// A module connected and got its configuration.
    Connected {
        module: String,
        pid: u32,
    },
    Ready {
        module: String,
    },
    Event {
        module: String,
        name: String,
    },
    /// A no-go area reported by a module (`{"type": "area", …}`), corners in the world frame.
    AreaReported {
        module: String,
        name: String,
        points_m: Vec<[f64; 2]>,
    },
    Disconnected {
        module: String,
    },
    /// A connected module has sent nothing, not even an answer to a ping, for a whole lease.
    Unresponsive {
        module: String,
        silent_for: Duration,
    },
    /// A valid edit of the system file is now in force.
    Reloaded(Arc<Loaded>),
}

struct ModuleConn {
    conn_id: u64,
    writer: SecureWriter,
    sent: ModuleConfig,
    /// When the module last sent anything.
    last_heard: Instant,
    /// Reported unresponsive since it was last heard (reported once).
    reported: bool,
    /// Where the module's own services listen (`endpoint` messages), an unspecified address
    /// already replaced by the one its connection comes from.
    endpoints: BTreeMap<String, String>,
    /// The address the module's connection comes from.
    peer: Option<IpAddr>,
}

/// What the mission controller wants of the modules right now.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Control {
    /// The modules the mission wants for themselves, each with why (`place cross_drive`);
    /// `None` without a mission: every module. The modules they need follow
    /// ([`armor_model::system::demand`]).
    pub wanted: Option<BTreeMap<String, String>>,
    /// Modules that idle whatever needs them: those of a place entered again, for a moment,
    /// so that they start afresh.
    pub held: BTreeSet<String>,
    /// Parameter values of the marked places, over the system file's: module → name → value.
    pub overlays: BTreeMap<String, BTreeMap<String, String>>,
}

struct State {
    secret: Option<Secret>,
    loaded: Arc<Loaded>,
    control: Control,
    conns: HashMap<String, ModuleConn>,
    next_conn_id: u64,
    /// The operator's hand on controllable modules (true: started, false: stopped), over
    /// the controller's wishes until released.
    overrides: BTreeMap<String, bool>,
    /// Parameter values the operator set (module → name → value), over the system file's and
    /// the controller's, for the rest of the run.
    param_overrides: BTreeMap<String, BTreeMap<String, String>>,
    /// What each module last said of its work (with its answers to pings).
    stats: HashMap<String, NodeStats>,
    /// The modules that run and why: the controller's wishes and the operator's hand, closed
    /// over what they need (updated by [`State::push_changes`]).
    demand: BTreeMap<String, Reason>,
    /// The run's health: which modules are down, which sources inputs take.
    health: HealthBook,
    /// What behaviours and arbiters said, the states that follow and their time line.
    behaviours: Behaviours,
    /// What each module last asked to keep for its next process (`ToSupervisor::Keep`), by
    /// module name, for the rest of the run: a restarted module gets it before its
    /// configuration.
    kept: HashMap<String, String>,
}

impl State {
    /// A module's configuration: the system file's, under the controller's overlay.
    fn config_of(&self, module: &str) -> Option<ModuleConfig> {
        let instance = self.loaded.system.module(module)?;
        let mut config = self.loaded.module_config(instance)?;
        if let Some(overlay) = self.control.overlays.get(module) {
            config.params.extend(overlay.clone());
        }
        if let Some(set) = self.param_overrides.get(module) {
            config.params.extend(set.clone());
        }
        config.active = self.demand.contains_key(module);
        for (input, source) in &mut config.inputs {
            let endpoint = Endpoint::new(module, input);
            *source = self
                .health
                .source_for(&self.loaded.system, &endpoint, source);
        }
        Some(config)
    }

    /// Notes a health report, sends it to every connected module, then moves the inputs whose
    /// sources it changed.
    fn report_health(&mut self, module: &str, kind: &str, reason: &str) {
        // The supervisor may see a process end before this server sees its connection close:
        // the failure is told first all the same, once.
        if matches!(kind, "restarting" | "gave_up") && !self.health.failure_reported(module) {
            let how = reason.split(';').next().unwrap_or(reason);
            self.report_health(module, "failed", how);
        }
        let (seq, health) = self.health.report(module, kind, reason);
        let message = FromSupervisor::Health { seq, health };
        for conn in self.conns.values_mut() {
            if blocking::write_message(&mut conn.writer, &message).is_ok() {
                let _ = conn.writer.flush();
            }
        }
        self.push_changes();
    }

    /// Which modules run and why, from the controller's wishes and the operator's hand.
    fn compute_demand(&self) -> BTreeMap<String, Reason> {
        let system = &self.loaded.system;
        let mut wanted: BTreeMap<String, String> = match &self.control.wanted {
            Some(wanted) => wanted.clone(),
            None => system
                .modules
                .iter()
                .map(|module| (module.name.clone(), "no mission".to_owned()))
                .collect(),
        };
        let mut held = self.control.held.clone();
        for (module, started) in &self.overrides {
            if *started {
                wanted.insert(module.clone(), "by hand".to_owned());
                held.remove(module);
            } else {
                held.insert(module.clone());
            }
        }
        let controllable = |instance: &ModuleInstance| {
            self.loaded
                .descriptions
                .get(&instance.module_type)
                .is_none_or(|description| description.controllable)
        };
        demand(system, controllable, &wanted, &held)
    }

    /// A behaviour's or an arbiter's word (`Applicable`, `Winner`, or either in a pong's
    /// stats), and the states that follow.
    fn note_behaviour(&mut self, module: &str, applicable: Option<bool>, winner: Option<Winner>) {
        if let Some(applicable) = applicable {
            self.behaviours.set_applicable(module, applicable);
        }
        if let Some(winner) = winner {
            let publisher = winner.and_then(|input| {
                let conn = self.conns.get(module)?;
                Some(behaviour::publisher(conn.sent.inputs.get(&input)?).to_owned())
            });
            self.behaviours.set_winner(module, publisher);
        }
        self.update_behaviours();
    }

    fn update_behaviours(&mut self) {
        let active = self
            .conns
            .iter()
            .map(|(name, conn)| (name.clone(), conn.sent.active))
            .collect();
        self.behaviours.update(&active, Instant::now());
    }

    /// Sends every connected module whose configuration changed its new one (and a start or
    /// stop if that is what changed). Returns the modules updated.
    fn push_changes(&mut self) -> Vec<String> {
        self.demand = self.compute_demand();
        let mut updated = Vec::new();
        let mut switched = Vec::new();
        // Modules that stop go first, so two modules commanding the same thing never overlap;
        // then the others, in name order.
        let mut names: Vec<(bool, String)> = self
            .conns
            .iter()
            .map(|(name, conn)| {
                let starts = self
                    .config_of(name)
                    .is_some_and(|config| config.active && !conn.sent.active);
                (starts, name.clone())
            })
            .collect();
        names.sort();
        for (_, name) in names {
            let Some(config) = self.config_of(&name) else {
                continue;
            };
            let Some(conn) = self.conns.get_mut(&name) else {
                continue;
            };
            if config == conn.sent {
                continue;
            }
            let mut message_ok = true;
            for (input, source) in &config.inputs {
                if let Some(before) = conn.sent.inputs.get(input)
                    && before != source
                {
                    switched.push((name.clone(), format!("{name}.{input}: {before} → {source}")));
                }
            }
            let activity_changed = config.active != conn.sent.active;
            let mut as_sent = config.clone();
            as_sent.active = conn.sent.active;
            if as_sent != conn.sent {
                message_ok &= blocking::write_message(
                    &mut conn.writer,
                    &FromSupervisor::Config(config.clone()),
                )
                .is_ok();
            }
            if activity_changed {
                let message = if config.active {
                    FromSupervisor::Start
                } else {
                    FromSupervisor::Stop
                };
                message_ok &= blocking::write_message(&mut conn.writer, &message).is_ok();
            }
            let _ = conn.writer.flush();
            if message_ok {
                updated.push(name);
            }
            conn.sent = config;
        }
        updated.sort();
        for (module, reason) in switched {
            self.report_health(&module, "switched", &reason);
        }
        self.update_behaviours();
        updated
    }
}

/// An arbiter's winning input, as said (`Some(None)`: none wins).
type Winner = Option<String>;

/// An endpoint as the status shows it, or why it is refused: a short name and an `IP:PORT`, at
/// most [`MAX_ENDPOINTS`] a module, whatever a module says, so the status stays small. An
/// unspecified address (`0.0.0.0`, `::`) listens on every interface of the module's host: the
/// one its connection comes from (`peer`) is where the supervisor reaches it.
fn checked_endpoint(
    endpoints: &BTreeMap<String, String>,
    name: &str,
    address: &str,
    peer: Option<IpAddr>,
) -> Result<String, String> {
    if name.is_empty() || name.len() > MAX_ENDPOINT_NAME_BYTES {
        return Err(format!(
            "a name of {} bytes (1 to {MAX_ENDPOINT_NAME_BYTES})",
            name.len()
        ));
    }
    let Ok(addr) = address.parse::<SocketAddr>() else {
        return Err(format!(
            "`{name}`: an address of {} bytes that is not IP:PORT",
            address.len()
        ));
    };
    if !endpoints.contains_key(name) && endpoints.len() >= MAX_ENDPOINTS {
        return Err(format!("`{name}`: a module has at most {MAX_ENDPOINTS}"));
    }
    Ok(match peer {
        Some(peer) if addr.ip().is_unspecified() => SocketAddr::new(peer, addr.port()),
        _ => addr,
    }
    .to_string())
}

/// The most endpoints a module may say it serves.
const MAX_ENDPOINTS: usize = 16;
/// The longest endpoint name.
const MAX_ENDPOINT_NAME_BYTES: usize = 64;
/// The longest message a module sends the config server (a pong with its statistics).
const MAX_MESSAGE_BYTES: usize = 1024 * 1024;

impl ModuleConn {
    /// Notes an endpoint the module said it listens at. An unspecified address (`0.0.0.0`, `::`)
    /// listens on every interface of the module's host: the one its connection comes from is
    /// where the supervisor reaches it.
    /// Notes an endpoint the module said it listens at ([`checked_endpoint`]); a refused one
    /// is dropped with a warning.
    fn note_endpoint(&mut self, name: String, address: &str) {
        match checked_endpoint(&self.endpoints, &name, address, self.peer) {
            Ok(address) => {
                self.endpoints.insert(name, address);
            }
            Err(why) => tracing::warn!("refused an endpoint: {why}"),
        }
    }
}

#[derive(Clone)]
pub struct ConfigServer {
    state: Arc<Mutex<State>>,
    events: Sender<ServerEvent>,
    addr: SocketAddr,
}

impl ConfigServer {
    /// Listens on `addr` and serves `loaded`, under `control`, until the process ends; with a
    /// `lease`, pings the modules and reports those silent for longer.
    pub fn start(
        addr: SocketAddr,
        loaded: Loaded,
        control: Control,
        lease: Option<Duration>,
        secret: Option<Secret>,
        clock: Clock,
    ) -> std::io::Result<(Self, Receiver<ServerEvent>)> {
        let listener = TcpListener::bind(addr)?;
        let (events, receiver) = mpsc::channel();
        let mut state = State {
            secret,
            loaded: Arc::new(loaded),
            control,
            conns: HashMap::new(),
            next_conn_id: 0,
            overrides: BTreeMap::new(),
            param_overrides: BTreeMap::new(),
            stats: HashMap::new(),
            demand: BTreeMap::new(),
            health: HealthBook::new(clock),
            behaviours: Behaviours::default(),
            kept: HashMap::new(),
        };
        state.demand = state.compute_demand();
        let server = Self {
            state: Arc::new(Mutex::new(state)),
            events,
            addr: listener.local_addr()?,
        };
        let accepting = server.clone();
        std::thread::spawn(move || accepting.accept_loop(listener));
        if let Some(lease) = lease {
            let pinging = server.clone();
            std::thread::spawn(move || pinging.heartbeat_loop(lease));
        }
        Ok((server, receiver))
    }

    /// Pings every module a few times per lease and reports those silent for a whole lease:
    /// on the health stream at once, and to the supervisor.
    fn heartbeat_loop(&self, lease: Duration) {
        for check in 1u32.. {
            std::thread::sleep(lease / CHECKS_PER_LEASE);
            let ping = check.is_multiple_of(CHECKS_PER_LEASE / PINGS_PER_LEASE);
            let now = Instant::now();
            let mut silent = Vec::new();
            {
                let mut state = self.lock();
                for (name, conn) in &mut state.conns {
                    let quiet = now.saturating_duration_since(conn.last_heard);
                    if quiet >= lease {
                        if !conn.reported {
                            conn.reported = true;
                            silent.push((name.clone(), quiet));
                        }
                        continue;
                    }
                    if ping {
                        let _ = blocking::write_message(&mut conn.writer, &FromSupervisor::Ping);
                    }
                }
                for (module, quiet) in &silent {
                    let reason = format!("no answer for {:.2} s", quiet.as_secs_f64());
                    state.report_health(module, "stalled", &reason);
                }
            }
            for (module, silent_for) in silent {
                let _ = self
                    .events
                    .send(ServerEvent::Unresponsive { module, silent_for });
            }
        }
    }

    /// Notes that `module` (on connection `conn_id`) was heard from.
    fn heard(&self, module: &str, conn_id: u64) {
        let mut state = self.lock();
        if let Some(conn) = state.conns.get_mut(module)
            && conn.conn_id == conn_id
        {
            conn.last_heard = Instant::now();
            conn.reported = false;
        }
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn loaded(&self) -> Arc<Loaded> {
        Arc::clone(&self.lock().loaded)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Sends a control message to a connected module. Returns whether it was connected.
    pub fn send(&self, module: &str, message: &FromSupervisor) -> bool {
        let mut state = self.lock();
        if *message == FromSupervisor::Shutdown {
            state.health.leaving(module);
        }
        let Some(conn) = state.conns.get_mut(module) else {
            return false;
        };
        blocking::write_message(&mut conn.writer, message).is_ok()
    }

    fn accept_loop(&self, listener: TcpListener) {
        // Parameters and control cross this link: with a secret it is always encrypted.
        let listen = self.lock().secret.clone().map(|secret| Listen {
            admit: Admit::Modules(secret),
            encrypt: true,
        });
        // A module sends its `hello` right behind the wire's: without a secret, a peer that
        // does not costs no thread.
        crate::gate::serve_requests(
            listener,
            listen,
            crate::gate::MAX_HELLO_BYTES,
            |stream, proven| {
                let server = self.clone();
                std::thread::spawn(move || server.serve(stream, proven));
            },
        );
    }

    fn serve(&self, stream: SecureStream, proven: Option<String>) {
        let peer = stream.get_ref().peer_addr().ok();
        let conn_id = {
            let mut state = self.lock();
            state.next_conn_id += 1;
            state.next_conn_id
        };
        let mut module = None;
        if let Err(err) = self.serve_module(stream, proven, conn_id, &mut module) {
            match err {
                WireError::Closed => {}
                err => tracing::warn!(?peer, ?module, "config server dropped a connection: {err}"),
            }
        }
        if let Some(module) = module {
            let mut state = self.lock();
            if state
                .conns
                .get(&module)
                .is_some_and(|conn| conn.conn_id == conn_id)
            {
                state.conns.remove(&module);
                state.stats.remove(&module);
                if state.health.closed_is_failure(&module)
                    && !state.health.failure_reported(&module)
                {
                    state.report_health(&module, "failed", "its connection closed");
                }
                state.behaviours.forget(&module);
                state.update_behaviours();
                drop(state);
                let _ = self.events.send(ServerEvent::Disconnected { module });
            }
        }
    }

    fn serve_module(
        &self,
        stream: SecureStream,
        proven: Option<String>,
        conn_id: u64,
        module: &mut Option<String>,
    ) -> Result<(), WireError> {
        stream.get_ref().set_nodelay(true)?;
        stream.get_ref().set_read_timeout(Some(HANDSHAKE_TIMEOUT))?;
        let peer = stream.get_ref().peer_addr().ok().map(|addr| addr.ip());
        let (mut reader, mut writer) = stream.split();
        let stream = &mut reader;
        let ToSupervisor::Hello { module: name, pid } =
            blocking::read_message_at_most(stream, MAX_MESSAGE_BYTES)?
        else {
            let message = "the first message must be `hello`".to_owned();
            blocking::write_message(&mut writer, &FromSupervisor::Error { message })?;
            return Ok(());
        };
        if let Some(proven) = proven.filter(|proven| *proven != name) {
            let message = format!("this connection proved to be `{proven}`, not `{name}`");
            tracing::warn!("{message}");
            blocking::write_message(&mut writer, &FromSupervisor::Error { message })?;
            return Ok(());
        }
        stream.get_ref().set_read_timeout(None)?;
        {
            let mut state = self.lock();
            let Some(config) = state.config_of(&name) else {
                drop(state);
                let message = format!("no module `{name}` in this system");
                tracing::warn!("{message}");
                blocking::write_message(&mut writer, &FromSupervisor::Error { message })?;
                return Ok(());
            };
            if let Some(kept) = state.kept.get(&name) {
                tracing::info!(module = name, "handing the module what it kept");
                blocking::write_message(
                    &mut writer,
                    &FromSupervisor::Kept {
                        state: kept.clone(),
                    },
                )?;
            }
            blocking::write_message(&mut writer, &FromSupervisor::Config(config.clone()))?;
            writer.get_ref().set_write_timeout(Some(WRITE_TIMEOUT))?;
            state.health.connected(&name);
            let older = state.conns.insert(
                name.clone(),
                ModuleConn {
                    conn_id,
                    writer,
                    sent: config,
                    last_heard: Instant::now(),
                    reported: false,
                    endpoints: BTreeMap::new(),
                    peer,
                },
            );
            // A module has one connection: an older one under its name (a process that is
            // gone, or without a secret any peer that said the name) is closed, so that its
            // thread ends and a name costs one thread however often it is said.
            if let Some(older) = older {
                let _ = older.writer.get_ref().shutdown(std::net::Shutdown::Both);
            }
        }
        *module = Some(name.clone());
        let _ = self.events.send(ServerEvent::Connected {
            module: name.clone(),
            pid,
        });
        loop {
            let message =
                blocking::read_message_at_most::<ToSupervisor>(stream, MAX_MESSAGE_BYTES)?;
            self.heard(&name, conn_id);
            let event = match message {
                ToSupervisor::Ready => {
                    let mut state = self.lock();
                    if state.health.is_down(&name) {
                        state.report_health(&name, "recovered", "configured and at work again");
                    }
                    drop(state);
                    ServerEvent::Ready {
                        module: name.clone(),
                    }
                }
                ToSupervisor::Event { name: event } => ServerEvent::Event {
                    module: name.clone(),
                    name: event,
                },
                ToSupervisor::Area {
                    name: area,
                    points_m,
                } => ServerEvent::AreaReported {
                    module: name.clone(),
                    name: area,
                    points_m,
                },
                ToSupervisor::Pong { stats } => {
                    if let Some(stats) = stats {
                        let mut state = self.lock();
                        if let Some(conn) = state.conns.get_mut(&name)
                            && conn.conn_id == conn_id
                        {
                            for (endpoint, address) in &stats.endpoints {
                                conn.note_endpoint(endpoint.clone(), address);
                            }
                        }
                        let winner = stats.winner.clone().map(Some);
                        state.note_behaviour(&name, stats.applicable, winner);
                        state.stats.insert(name.clone(), stats);
                    }
                    continue;
                }
                ToSupervisor::Applicable { applicable } => {
                    self.lock().note_behaviour(&name, Some(applicable), None);
                    continue;
                }
                ToSupervisor::Winner { input } => {
                    self.lock().note_behaviour(&name, None, Some(input));
                    continue;
                }
                ToSupervisor::Endpoint {
                    name: endpoint,
                    address,
                } => {
                    let mut state = self.lock();
                    if let Some(conn) = state.conns.get_mut(&name)
                        && conn.conn_id == conn_id
                    {
                        tracing::debug!(module = name, endpoint, address, "endpoint");
                        conn.note_endpoint(endpoint, &address);
                    }
                    continue;
                }
                ToSupervisor::Keep { state: kept } => {
                    if kept.len() <= armor_module_api::protocol::MAX_KEPT_BYTES {
                        let mut state = self.lock();
                        if state
                            .conns
                            .get(&name)
                            .is_some_and(|conn| conn.conn_id == conn_id)
                        {
                            state.kept.insert(name.clone(), kept);
                        }
                    } else {
                        // A module of another language learns it only from the run's log.
                        tracing::warn!(
                            module = name,
                            bytes = kept.len(),
                            "a `keep` over {} bytes is not kept",
                            armor_module_api::protocol::MAX_KEPT_BYTES
                        );
                    }
                    continue;
                }
                ToSupervisor::Hello { .. } => continue,
            };
            let _ = self.events.send(event);
        }
    }

    /// Puts a newly loaded system in force and sends each connected module its new
    /// configuration if it changed.
    pub fn apply(&self, loaded: Loaded) {
        let loaded = Arc::new(loaded);
        let updated = {
            let mut state = self.lock();
            state.loaded = Arc::clone(&loaded);
            state.push_changes()
        };
        if !updated.is_empty() {
            tracing::info!(modules = ?updated, "sent new configuration");
        }
        let _ = self.events.send(ServerEvent::Reloaded(loaded));
    }

    /// Puts the controller's wishes in force: modules stopped or started, place parameters.
    pub fn set_control(&self, control: Control) {
        let updated = {
            let mut state = self.lock();
            state.control = control;
            state.push_changes()
        };
        tracing::debug!(modules = ?updated, "control applied");
    }

    /// Starts (`Some(true)`) or stops (`Some(false)`) a controllable module by hand, whatever
    /// the controller wants, or gives it back to the controller (`None`).
    pub fn set_override(&self, module: &str, active: Option<bool>) -> Result<(), String> {
        let mut state = self.lock();
        let instance = state
            .loaded
            .system
            .module(module)
            .ok_or_else(|| format!("no module `{module}` in this system"))?;
        let controllable = state
            .loaded
            .descriptions
            .get(&instance.module_type)
            .is_some_and(|description| description.controllable);
        if !controllable {
            return Err(format!(
                "`{module}` is not controllable: it runs whenever its process does"
            ));
        }
        match active {
            Some(active) => state.overrides.insert(module.to_owned(), active),
            None => state.overrides.remove(module),
        };
        state.push_changes();
        Ok(())
    }

    /// Sets a module's parameter by hand, over the system file's and the controller's value,
    /// for the rest of the run; `module` `None`: the only module of type `module_type`. Returns
    /// the module's name. Refused for a module or parameter the system does not have, or a
    /// value the parameter's description refuses.
    pub fn set_param(
        &self,
        module: Option<&str>,
        module_type: &str,
        name: &str,
        value: &str,
    ) -> Result<String, String> {
        let mut state = self.lock();
        let module = match module {
            Some(module) => module.to_owned(),
            None => {
                let of_type: Vec<&str> = state
                    .loaded
                    .system
                    .modules
                    .iter()
                    .filter(|instance| instance.module_type == module_type)
                    .map(|instance| instance.name.as_str())
                    .collect();
                match of_type[..] {
                    [only] => only.to_owned(),
                    [] => return Err(format!("no module of type `{module_type}` in this system")),
                    _ => {
                        return Err(format!(
                            "several modules of type `{module_type}` ({}): name one",
                            of_type.join(", ")
                        ));
                    }
                }
            }
        };
        let instance = state
            .loaded
            .system
            .module(&module)
            .ok_or_else(|| format!("no module `{module}` in this system"))?;
        let spec = state
            .loaded
            .descriptions
            .get(&instance.module_type)
            .and_then(|description| description.params.iter().find(|p| p.name == name))
            .ok_or_else(|| format!("module `{module}` has no parameter `{name}`"))?;
        spec.check_value(value)
            .map_err(|why| format!("`{module}`.{name}: {why}"))?;
        state
            .param_overrides
            .entry(module.clone())
            .or_default()
            .insert(name.to_owned(), value.to_owned());
        state.push_changes();
        Ok(module)
    }

    /// For each connected module: whether it is active, and the operator's override if any.
    pub fn activity(&self) -> BTreeMap<String, (bool, Option<bool>)> {
        let state = self.lock();
        state
            .conns
            .iter()
            .map(|(name, conn)| {
                (
                    name.clone(),
                    (conn.sent.active, state.overrides.get(name).copied()),
                )
            })
            .collect()
    }

    /// Reports `kind` of `module` on the health stream (the supervisor's `restarting`,
    /// `gave_up`), to every module.
    pub fn report_health(&self, module: &str, kind: &str, reason: &str) {
        self.lock().report_health(module, kind, reason);
    }

    /// Why each module runs (those that idle are absent).
    pub fn demand(&self) -> BTreeMap<String, Reason> {
        self.lock().demand.clone()
    }

    /// Behaviour states, arbiters' winners and the time line of state changes.
    pub fn behaviours(&self) -> Behaviours {
        self.lock().behaviours.clone()
    }

    /// Where each connected module's own services listen (module → name → address).
    pub fn endpoints(&self) -> HashMap<String, BTreeMap<String, String>> {
        self.lock()
            .conns
            .iter()
            .filter(|(_, conn)| !conn.endpoints.is_empty())
            .map(|(name, conn)| (name.clone(), conn.endpoints.clone()))
            .collect()
    }

    /// What each module last said of its work.
    pub fn stats(&self) -> HashMap<String, NodeStats> {
        self.lock().stats.clone()
    }

    /// Watches `file` and reloads it on every change, until the process ends.
    pub fn watch(&self, file: &Path, module_path: Vec<PathBuf>) -> notify::Result<()> {
        let file = std::path::absolute(file)?;
        let folder = file
            .parent()
            .map(Path::to_path_buf)
            .unwrap_or_else(|| PathBuf::from("/"));
        let (tx, rx) = mpsc::channel();
        let mut watcher =
            notify::recommended_watcher(move |event: notify::Result<notify::Event>| {
                let _ = tx.send(event);
            })?;
        watcher.watch(&folder, RecursiveMode::NonRecursive)?;
        let server = self.clone();
        std::thread::spawn(move || {
            // The watcher lives as long as this thread.
            let _watcher = watcher;
            server.reload_loop(&file, &module_path, &rx);
        });
        Ok(())
    }

    fn reload_loop(
        &self,
        file: &Path,
        module_path: &[PathBuf],
        events: &Receiver<notify::Result<notify::Event>>,
    ) {
        let file_name = file.file_name();
        // Reading the file ourselves makes access events: only changes count.
        let concerns_file = |event: &notify::Result<notify::Event>| match event {
            Ok(event) => {
                !matches!(event.kind, notify::EventKind::Access(_))
                    && event.paths.iter().any(|path| path.file_name() == file_name)
            }
            Err(err) => {
                tracing::warn!("file watcher: {err}");
                false
            }
        };
        while let Ok(event) = events.recv() {
            if !concerns_file(&event) {
                continue;
            }
            // Let the editor finish writing: wait until no change has come for a moment.
            loop {
                match events.recv_timeout(SETTLE) {
                    Ok(event) if concerns_file(&event) => {}
                    Ok(_) => {}
                    Err(RecvTimeoutError::Timeout) => break,
                    Err(RecvTimeoutError::Disconnected) => return,
                }
            }
            if !file.exists() {
                tracing::warn!(file = %file.display(), "the system file is gone; the last good configuration stays in force");
                continue;
            }
            match load_system(file, module_path) {
                Ok(loaded) => {
                    if loaded.system == self.loaded().system {
                        continue;
                    }
                    tracing::info!(file = %file.display(), "configuration reloaded");
                    self.apply(loaded);
                }
                Err(diagnostics) => {
                    tracing::error!(
                        "the edited system file is invalid; the last good configuration stays in force:\n{diagnostics}"
                    );
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(
        endpoints: &[(&str, &str)],
        name: &str,
        address: &str,
        peer: Option<&str>,
    ) -> Result<String, String> {
        let endpoints = endpoints
            .iter()
            .map(|(name, address)| ((*name).to_owned(), (*address).to_owned()))
            .collect();
        let peer = peer.map(|peer| peer.parse().unwrap_or(IpAddr::from([0, 0, 0, 0])));
        checked_endpoint(&endpoints, name, address, peer)
    }

    #[test]
    fn endpoints_are_short_names_and_addresses_and_few() {
        assert_eq!(
            check(&[], "teleop", "127.0.0.1:4000", None),
            Ok("127.0.0.1:4000".to_owned())
        );
        // An unspecified address is where the module's connection comes from.
        assert_eq!(
            check(&[], "teleop", "0.0.0.0:4000", Some("10.0.0.2")),
            Ok("10.0.0.2:4000".to_owned())
        );
        // A megabyte of address, or of name, is refused without being kept.
        let huge = "x".repeat(1 << 20);
        assert!(check(&[], "teleop", &huge, None).is_err_and(|why| why.len() < 200));
        assert!(check(&[], &huge, "127.0.0.1:1", None).is_err_and(|why| why.len() < 200));
        assert!(check(&[], "", "127.0.0.1:1", None).is_err());
        // At most MAX_ENDPOINTS; saying one again at another port is fine.
        let names: Vec<String> = (0..MAX_ENDPOINTS).map(|n| format!("e{n}")).collect();
        let full: Vec<(&str, &str)> = names
            .iter()
            .map(|name| (name.as_str(), "127.0.0.1:1"))
            .collect();
        assert!(check(&full, "one_more", "127.0.0.1:2", None).is_err());
        assert!(check(&full, "e0", "127.0.0.1:2", None).is_ok());
    }
}
