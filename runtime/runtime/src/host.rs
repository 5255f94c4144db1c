//! `armor host`: the daemon of one computer of a robot. The supervisor (`armor run`) connects to
//! it, proves the run's secret like any peer (identity [`SUPERVISOR_IDENTITY`], the link always
//! encrypted), and asks it to start, signal and watch the modules placed on that computer
//! (`<module … host="robot1">`); the daemon streams their output lines and exit statuses back.
//! The supervisor keeps the restart policy and the lease: a crash is reported, and the module is
//! started again through the daemon. When the daemon hears nothing from the supervisor for its
//! orphan time (`--orphan-secs`), or the connection closes and no supervisor comes back within
//! it, it kills every module it started: a robot does not drive on without its controller.
//!
//! Messages are the run's wire frames (JSON messages, see `docs/protocol.md`), [`ToHost`] one
//! way and [`FromHost`] the other. The client side, which `armor run` and `armor check` use, is
//! [`crate::hosts`].

use std::collections::HashMap;
use std::io::Read;
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::mpsc::{self, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use armor_module_api::ENV_RUN_DIR;
use armor_module_api::auth::{Admit, ENV_ENCRYPT, ENV_KEY_FD, ENV_SECRET_FILE, Listen, Secret};
use armor_module_api::clock::unix_now_ns;
use armor_module_api::wire::WireError;
use armor_module_api::wire::blocking::{self, SecureStream};
use serde::{Deserialize, Serialize};

use crate::probe;

/// The daemon's first line on stdout, followed by the address it listens on.
pub const HOST_READY_PREFIX: &str = "armor host listening on ";
/// The identity the supervisor proves to a host daemon (with the key the secret derives for it).
pub const SUPERVISOR_IDENTITY: &str = "armor.run";
/// How long the daemon keeps its modules without hearing from the supervisor, by default.
pub const DEFAULT_ORPHAN: Duration = Duration::from_secs(3);
/// The most connections that only ask questions (`armor check`) served at once: each holds two
/// threads until it has been quiet for a while, and without a secret anyone on the machine may
/// ask. One more is refused, and told why.
const MAX_QUERIES: usize = 4;
/// How often the supervisor says it is alive.
pub const PING_EVERY: Duration = Duration::from_millis(250);
/// Milliseconds added to the time the daemon reports (`time`): a clock that is off, made on
/// purpose, for the tests of the supervisor's skew check. Never set it on a robot.
pub const ENV_CLOCK_OFFSET_MS: &str = "ARMOR_HOST_CLOCK_OFFSET_MS";

/// From the supervisor to a host daemon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum ToHost {
    /// The first message: which run this is, and the orphan time the supervisor asks for (the
    /// daemon takes the shorter of it and its own). With `query` (`armor check`), the
    /// connection only asks questions: it does not take the host over from a run.
    Hello {
        run: String,
        orphan_ms: u64,
        #[serde(default)]
        query: bool,
    },
    /// What time is it on the host? (clock skew)
    Time {
        id: u64,
    },
    /// Which of these module types has the host no binary for?
    Check {
        id: u64,
        types: Vec<String>,
    },
    /// Start a module. `generation` tells this start from the module's earlier ones. The
    /// daemon builds the module's environment from these checked values itself (and, with a
    /// secret, derives the module's key from it): nothing else of the message reaches the
    /// process, so a supervisor cannot hand a module `LD_PRELOAD` or any other variable.
    Spawn {
        name: String,
        module_type: String,
        generation: u64,
        /// The run's agent and supervisor, `IP:PORT`.
        agent: String,
        supervisor: String,
        epoch_ns: u64,
        time_scale: f64,
        /// Whether the module's links are encrypted (only with a secret).
        #[serde(default)]
        encrypt: bool,
    },
    /// Send a signal to a module's process group.
    Signal {
        name: String,
        generation: u64,
        signal: i32,
    },
    Ping,
}

/// From a host daemon to the supervisor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum FromHost {
    /// The answer to `hello`: the host's name and module path.
    Welcome {
        host: String,
        module_path: Vec<String>,
    },
    Time {
        id: u64,
        unix_ns: u64,
    },
    Check {
        id: u64,
        missing: Vec<String>,
    },
    Started {
        name: String,
        generation: u64,
        pid: u32,
    },
    SpawnFailed {
        name: String,
        generation: u64,
        error: String,
    },
    /// One line of a module's standard output or error.
    Log {
        name: String,
        line: String,
    },
    /// The module's process ended; `status` is the raw wait status.
    Exited {
        name: String,
        generation: u64,
        status: i32,
    },
    /// The daemon refuses the connection (another run holds it, bad first message).
    Refused {
        message: String,
    },
    Pong,
}

pub struct HostOptions {
    pub listener: TcpListener,
    /// The run's secret; `None` only on a loopback listener (see [`check_listen`]).
    /// The host's name, as the system declares it (for logs).
    pub name: String,
    pub module_path: Vec<PathBuf>,
    pub secret: Option<Secret>,
    /// Modules are killed after this long without the supervisor.
    pub orphan: Duration,
}

/// The address `armor host` listens on when not told: every interface with a secret, loopback
/// without (a stranger on the network must never reach a daemon that starts programs).
pub fn default_listen(with_secret: bool) -> std::net::SocketAddr {
    let ip = if with_secret {
        std::net::Ipv4Addr::UNSPECIFIED
    } else {
        std::net::Ipv4Addr::LOCALHOST
    };
    std::net::SocketAddr::from((ip, DEFAULT_PORT))
}

/// The port of a host daemon unless its `<host>` says another.
pub const DEFAULT_PORT: u16 = 7410;

/// Refuses an address beyond loopback without a secret, saying why.
pub fn check_listen(addr: std::net::SocketAddr, with_secret: bool) -> Result<(), String> {
    if with_secret || addr.ip().is_loopback() {
        return Ok(());
    }
    Err(format!(
        "refusing to listen on {addr} without a secret: anyone who reaches it could start \
         programs on this machine. Give --secret FILE (the run's secret), or listen on \
         127.0.0.1"
    ))
}

/// The variables the daemon sets for a module, removed from what the module inherits of the
/// daemon's own environment (which its operator set, not the network).
const MODULE_VARS: [&str; 8] = [
    armor_module_api::ENV_MODULE,
    armor_module_api::ENV_AGENT,
    armor_module_api::ENV_SUPERVISOR,
    armor_module_api::clock::ENV_EPOCH,
    armor_module_api::clock::ENV_TIME_SCALE,
    ENV_KEY_FD,
    ENV_ENCRYPT,
    ENV_RUN_DIR,
];

/// The longest module name or type the daemon takes.
const MAX_NAME_BYTES: usize = 128;

/// A module name or type as a system may write it: letters, digits, `_`, `-` and `.` (no
/// `/`, so a type names a file in a folder of the module path and nothing else).
fn check_name(what: &str, name: &str) -> Result<(), String> {
    let fine = !name.is_empty()
        && name.len() <= MAX_NAME_BYTES
        && !name.starts_with('.')
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'));
    if fine {
        Ok(())
    } else {
        Err(format!(
            "refused a {what} that is not a name (letters, digits, `_`, `-`, `.`; at most \
             {MAX_NAME_BYTES} bytes): {:?}",
            name.chars().take(MAX_NAME_BYTES).collect::<String>()
        ))
    }
}

/// The module's environment from a spawn request, every value checked: names, addresses,
/// numbers; the key derived here from the daemon's own secret.
fn module_env(
    secret: Option<&Secret>,
    name: &str,
    agent: &str,
    supervisor: &str,
    epoch_ns: u64,
    time_scale: f64,
    encrypt: bool,
) -> Result<Vec<(&'static str, String)>, String> {
    let address = |what: &str, text: &str| {
        text.parse::<std::net::SocketAddr>()
            .map(|addr| addr.to_string())
            .map_err(|_| format!("refused a {what} address that is not IP:PORT"))
    };
    if !(time_scale.is_finite() && time_scale > 0.0) {
        return Err("refused a time scale that is not a positive number".to_owned());
    }
    let mut env = vec![
        (armor_module_api::ENV_MODULE, name.to_owned()),
        (armor_module_api::ENV_AGENT, address("agent", agent)?),
        (
            armor_module_api::ENV_SUPERVISOR,
            address("supervisor", supervisor)?,
        ),
        (armor_module_api::clock::ENV_EPOCH, epoch_ns.to_string()),
        (
            armor_module_api::clock::ENV_TIME_SCALE,
            time_scale.to_string(),
        ),
    ];
    if secret.is_some() && encrypt {
        env.push((ENV_ENCRYPT, "1".to_owned()));
    }
    Ok(env)
}

/// A module the daemon started, by name.
struct Running {
    generation: u64,
    pid: u32,
}

/// What the daemon holds between connections.
struct Daemon {
    name: String,
    module_path: Vec<PathBuf>,
    secret: Option<Secret>,
    orphan: Duration,
    modules: Mutex<HashMap<String, Running>>,
    /// The connection serving now (its number); an older one stops when it sees a newer.
    session: Mutex<u64>,
    /// Connections that only ask questions, open now (at most [`MAX_QUERIES`]).
    queries: std::sync::atomic::AtomicUsize,
    /// Added to the time reported ([`ENV_CLOCK_OFFSET_MS`]).
    clock_offset_ns: i64,
}

/// Serves supervisors on the listener until the process ends.
pub fn serve(options: HostOptions) {
    let listen = options.secret.clone().map(|secret| Listen {
        admit: Admit::Modules(secret),
        encrypt: true,
    });
    let authenticated = options.secret.is_some();
    let daemon = Arc::new(Daemon {
        name: options.name,
        module_path: options.module_path,
        secret: options.secret.clone(),
        orphan: options.orphan,
        modules: Mutex::new(HashMap::new()),
        session: Mutex::new(0),
        queries: std::sync::atomic::AtomicUsize::new(0),
        clock_offset_ns: std::env::var(ENV_CLOCK_OFFSET_MS)
            .ok()
            .and_then(|ms| ms.trim().parse::<i64>().ok())
            .map_or(0, |ms| ms.saturating_mul(1_000_000)),
    });
    // A supervisor sends its `hello` right behind the wire's: without a secret, a peer that
    // does not costs no thread.
    crate::gate::serve_requests(
        options.listener,
        listen,
        crate::gate::MAX_HELLO_BYTES,
        move |stream, proven| {
            if authenticated && proven.as_deref() != Some(SUPERVISOR_IDENTITY) {
                tracing::warn!(
                    ?proven,
                    "refused a connection that is not a supervisor's ({SUPERVISOR_IDENTITY})"
                );
                return;
            }
            let daemon = Arc::clone(&daemon);
            std::thread::spawn(move || daemon.session(stream));
        },
    );
}

impl Daemon {
    fn modules(&self) -> std::sync::MutexGuard<'_, HashMap<String, Running>> {
        self.modules
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn current_session(&self) -> u64 {
        *self
            .session
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    /// Kills every module this daemon started (SIGTERM to each process group, then SIGKILL).
    fn kill_all(&self, why: &str) {
        let pids: Vec<(String, u32)> = self
            .modules()
            .iter()
            .map(|(name, running)| (name.clone(), running.pid))
            .collect();
        if pids.is_empty() {
            return;
        }
        tracing::warn!("{why}: stopping {} module(s)", pids.len());
        for (name, pid) in &pids {
            tracing::info!(module = name, pid, "SIGTERM");
            signal_group(*pid, libc::SIGTERM);
        }
        let deadline = Instant::now() + Duration::from_secs(1);
        while Instant::now() < deadline && !self.modules().is_empty() {
            std::thread::sleep(Duration::from_millis(20));
        }
        let left: Vec<u32> = self.modules().values().map(|running| running.pid).collect();
        for pid in left {
            signal_group(pid, libc::SIGKILL);
        }
    }

    fn session(self: Arc<Self>, stream: SecureStream) {
        let peer = stream.get_ref().peer_addr().ok();
        let _ = stream.get_ref().set_nodelay(true);
        let _ = stream
            .get_ref()
            .set_read_timeout(Some(armor_module_api::handshake_deadline::CONFIRM_TIMEOUT));
        let (mut reader, mut writer) = stream.split();
        let (tx, rx) = mpsc::channel::<FromHost>();
        std::thread::spawn(move || {
            for message in rx {
                if blocking::write_message(&mut writer, &message).is_err() {
                    break;
                }
            }
            let _ = writer.get_ref().shutdown(std::net::Shutdown::Both);
        });
        let (orphan, query) = match self.read_hello(&mut reader, &tx) {
            Ok(hello) => hello,
            Err(err) => {
                tracing::warn!(?peer, "a peer dropped before its hello: {err}");
                return;
            }
        };
        if query {
            use std::sync::atomic::Ordering;
            if self.queries.fetch_add(1, Ordering::Relaxed) >= MAX_QUERIES {
                self.queries.fetch_sub(1, Ordering::Relaxed);
                tracing::warn!(?peer, "{MAX_QUERIES} queries are open: refused another");
                let _ = tx.send(FromHost::Refused {
                    message: format!(
                        "{MAX_QUERIES} connections are asking this host questions already: try again"
                    ),
                });
                return;
            }
            while let Ok(message) = blocking::read_message::<ToHost>(&mut reader) {
                if matches!(
                    message,
                    ToHost::Check { .. } | ToHost::Time { .. } | ToHost::Ping
                ) {
                    self.handle(message, &tx);
                }
            }
            self.queries.fetch_sub(1, Ordering::Relaxed);
            return;
        }
        let id = {
            let mut session = self
                .session
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            *session += 1;
            *session
        };
        // A new supervisor: whatever an earlier one left is not its to keep.
        self.kill_all("a new supervisor connected");
        tracing::info!(?peer, "supervisor connected");
        let _ = reader.get_ref().set_read_timeout(Some(PING_EVERY));
        let mut heard = Instant::now();
        let why = loop {
            if self.current_session() != id {
                break "another supervisor took over".to_owned();
            }
            if heard.elapsed() > orphan {
                break format!(
                    "no word from the supervisor for {:.1} s",
                    heard.elapsed().as_secs_f64()
                );
            }
            let message = match blocking::read_message::<ToHost>(&mut reader) {
                Ok(message) => message,
                Err(WireError::Io(err))
                    if matches!(
                        err.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    // Nothing within a ping: checked above against the orphan time. (A timeout
                    // cannot fall inside a frame: messages are small and sent whole.)
                    continue;
                }
                Err(err) => {
                    // The connection is gone: wait for a supervisor to come back.
                    tracing::warn!(?peer, "lost the supervisor: {err}");
                    self.wait_for_return(id, orphan);
                    return;
                }
            };
            heard = Instant::now();
            self.handle(message, &tx);
        };
        tracing::warn!(?peer, "{why}");
        if self.current_session() == id {
            self.kill_all(&why);
        }
    }

    /// After the connection closed: the modules keep running for the orphan time, unless a new
    /// supervisor connects before (which then owns the host).
    fn wait_for_return(&self, id: u64, orphan: Duration) {
        let deadline = Instant::now() + orphan;
        while Instant::now() < deadline {
            if self.current_session() != id {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        if self.current_session() == id {
            self.kill_all(&format!(
                "the supervisor did not come back within {:.1} s",
                orphan.as_secs_f64()
            ));
        }
    }

    fn read_hello(
        &self,
        reader: &mut impl Read,
        tx: &Sender<FromHost>,
    ) -> Result<(Duration, bool), WireError> {
        match blocking::read_message::<ToHost>(reader)? {
            ToHost::Hello {
                run,
                orphan_ms,
                query,
            } => {
                let orphan = Duration::from_millis(orphan_ms).min(self.orphan);
                if query {
                    tracing::debug!("`{run}` asks questions");
                } else {
                    tracing::info!(
                        run,
                        "serving run `{run}`; its modules stop {:.1} s after the supervisor is lost",
                        orphan.as_secs_f64()
                    );
                }
                let _ = tx.send(FromHost::Welcome {
                    host: self.name.clone(),
                    module_path: self
                        .module_path
                        .iter()
                        .map(|path| path.display().to_string())
                        .collect(),
                });
                Ok((orphan, query))
            }
            other => {
                let _ = tx.send(FromHost::Refused {
                    message: format!("the first message must be `hello`, not {other:?}"),
                });
                Err(WireError::Closed)
            }
        }
    }

    fn handle(self: &Arc<Self>, message: ToHost, tx: &Sender<FromHost>) {
        match message {
            ToHost::Hello { .. } => {}
            ToHost::Ping => {
                let _ = tx.send(FromHost::Pong);
            }
            ToHost::Time { id } => {
                let _ = tx.send(FromHost::Time {
                    id,
                    unix_ns: unix_now_ns().saturating_add_signed(self.clock_offset_ns),
                });
            }
            ToHost::Check { id, types } => {
                let missing = types
                    .into_iter()
                    .filter(|module_type| {
                        probe::find_module(&self.module_path, module_type).is_none()
                    })
                    .collect();
                let _ = tx.send(FromHost::Check { id, missing });
            }
            ToHost::Signal {
                name,
                generation,
                signal,
            } => {
                let pid = self
                    .modules()
                    .get(&name)
                    .filter(|running| running.generation == generation)
                    .map(|running| running.pid);
                if let Some(pid) = pid {
                    tracing::debug!(module = name, pid, signal, "signal");
                    signal_group(pid, signal);
                }
            }
            ToHost::Spawn {
                name,
                module_type,
                generation,
                agent,
                supervisor,
                epoch_ns,
                time_scale,
                encrypt,
            } => {
                let env = check_name("module name", &name)
                    .and_then(|()| check_name("module type", &module_type))
                    .and_then(|()| {
                        module_env(
                            self.secret.as_ref(),
                            &name,
                            &agent,
                            &supervisor,
                            epoch_ns,
                            time_scale,
                            encrypt,
                        )
                    });
                match env {
                    Ok(env) => self.spawn(name, &module_type, generation, &env, tx),
                    Err(error) => {
                        tracing::warn!("{error}");
                        let _ = tx.send(FromHost::SpawnFailed {
                            name: name.chars().take(MAX_NAME_BYTES).collect(),
                            generation,
                            error,
                        });
                    }
                }
            }
        }
    }

    fn spawn(
        self: &Arc<Self>,
        name: String,
        module_type: &str,
        generation: u64,
        env: &[(&'static str, String)],
        tx: &Sender<FromHost>,
    ) {
        let failed = |error: String| {
            tracing::error!(module = name, "{error}");
            let _ = tx.send(FromHost::SpawnFailed {
                name: name.clone(),
                generation,
                error,
            });
        };
        if let Some(running) = self.modules().get(&name) {
            // The supervisor thinks it ended (a lost connection): this start replaces it.
            signal_group(running.pid, libc::SIGKILL);
        }
        let Some(binary) = probe::find_module(&self.module_path, module_type) else {
            return failed(format!(
                "no binary for module type `{module_type}` on host `{}` (armor-mod-{module_type} in {})",
                self.name,
                self.module_path
                    .iter()
                    .map(|path| path.display().to_string())
                    .collect::<Vec<_>>()
                    .join(":")
            ));
        };
        let mut command = Command::new(&binary);
        // The daemon's own variables of a run (its secret file among them) are not the module's.
        command.env_remove(ENV_SECRET_FILE);
        for var in MODULE_VARS {
            command.env_remove(var);
        }
        command
            .envs(env.iter().map(|(key, value)| (key, value)))
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        // The module's key, derived here from the daemon's own secret, goes over a pipe: its
        // siblings read environments.
        if let Some(secret) = &self.secret {
            let key = secret.module_key(&name).to_hex();
            if let Err(err) = crate::process::hand_over(&mut command, &key) {
                return failed(format!("cannot hand {name} its key: {err:#}"));
            }
        }
        crate::process::die_with_parent(&mut command);
        let mut child = match command.spawn() {
            Ok(child) => child,
            Err(err) => return failed(format!("cannot start {}: {err}", binary.display())),
        };
        let pid = child.id();
        tracing::info!(module = name, pid, "module started");
        self.modules()
            .insert(name.clone(), Running { generation, pid });
        let _ = tx.send(FromHost::Started {
            name: name.clone(),
            generation,
            pid,
        });
        let out = forward_lines(&name, child.stdout.take(), tx.clone());
        let err = forward_lines(&name, child.stderr.take(), tx.clone());
        let daemon = Arc::clone(self);
        let tx = tx.clone();
        std::thread::spawn(move || {
            use std::os::unix::process::ExitStatusExt as _;
            let status = child.wait().map(|status| status.into_raw()).unwrap_or(-1);
            {
                let mut modules = daemon.modules();
                if modules
                    .get(&name)
                    .is_some_and(|running| running.generation == generation)
                {
                    modules.remove(&name);
                }
            }
            // Its last lines before its end.
            for thread in [out, err].into_iter().flatten() {
                let _ = thread.join();
            }
            tracing::info!(module = name, status, "module ended");
            let _ = tx.send(FromHost::Exited {
                name,
                generation,
                status,
            });
        });
    }
}

fn signal_group(pid: u32, signal: i32) {
    if let Ok(pid) = libc::pid_t::try_from(pid) {
        crate::process::kill(-pid, signal);
        crate::process::kill(pid, signal);
    }
}

/// Sends a child's output to the supervisor, one line at a time.
fn forward_lines(
    name: &str,
    pipe: Option<impl Read + Send + 'static>,
    tx: Sender<FromHost>,
) -> Option<std::thread::JoinHandle<()>> {
    let name = name.to_owned();
    Some(crate::log_pump::pump_lines(pipe?, move |line| {
        let _ = tx.send(FromHost::Log {
            name: name.clone(),
            line,
        });
    }))
}
