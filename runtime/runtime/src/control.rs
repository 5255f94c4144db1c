//! The operator's hold on a run (adjustable autonomy): ask for the state of every module and of
//! the mission, start and stop modules by hand, and pause, resume, abort a mission or fire a
//! transition by hand. `armor run` serves it on a TCP port; `armor ctl` and the studio's run
//! view are its clients, through [`Client`].
//!
//! The link is the run's wire protocol (`docs/protocol.md`): hellos, then JSON messages in
//! frames, each request numbered from 1 and its reply carrying the same number:
//!
//! ```text
//! → {"seq":1,"request":{"command":"fire","transition":"leave_wp1"}}
//! ← {"seq":1,"reply":{"ok":true,"message":"fired `leave_wp1`","status":{...}}}
//! → {"seq":2,"request":{"command":"teleop","linear":0.3,"angular":0}}
//! ← {"seq":2,"reply":{"ok":true,"message":"teleop `teleop`: driving at 0.3 0","status":null}}
//! ```
//!
//! With a shared secret the client proves a role's key in the Noise handshake of the data
//! links (identity `operator` or `observer`), and the link is encrypted: nobody on the path
//! reads it, and a record changed, replayed, reordered or dropped fails to open, which ends
//! the connection. The run sends nothing to a client before its valid first handshake message.
//!
//! `teleop` is relayed to the run's teleop module (see [`crate::teleop_relay`]) and answered
//! with the module's own answer; `files` returns what a client that attaches without the
//! system file needs to draw the run ([`RunFiles`]).

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc::{self, Sender};
use std::time::Duration;

use armor_model::net::Marking;

pub use crate::behaviour::BehaviourState;
use armor_module_api::auth::{Admit, Dial, Listen, Secret};
pub use armor_module_api::auth::{Role, RoleKey};
use armor_module_api::protocol::NodeStats;
use armor_module_api::wire::blocking::{self, SecureReader, SecureStream, SecureWriter};
use armor_module_api::wire::{MAX_FRAME_BYTES, WireError};
use serde::{Deserialize, Serialize};

pub const ENV_CONTROL: &str = "ARMOR_CONTROL";
/// A request longer than this is not a request.
const MAX_REQUEST_BYTES: usize = 64 * 1024;
const REPLY_TIMEOUT: Duration = Duration::from_secs(5);

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum Request {
    Status,
    Pause,
    Resume,
    Abort,
    Fire {
        transition: String,
    },
    /// Start a controllable module by hand, whatever the mission wants, until released.
    StartModule {
        module: String,
    },
    /// Stop a controllable module by hand, until released.
    StopModule {
        module: String,
    },
    /// Give a module back to the mission (or, without one, to running).
    ReleaseModule {
        module: String,
    },
    /// Drive the robot: relayed to the run's teleop module (`module`, or the only module of
    /// type `teleop`), which holds the command for its dead-man time: an operator sends it again
    /// while driving. Zero speeds are sent as `stop`.
    Teleop {
        linear: f64,
        angular: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        module: Option<String>,
    },
    /// The run's files, for a client that attaches without them: the system file, the
    /// mission's and the files the system's parameters name ([`RunFiles`]).
    Files,
    /// Tell the localiser where the robot is (rviz's "2D Pose Estimate"): its `set_pose`
    /// parameter is set to `X Y HEADING_DEG` over the system file's, for the rest of the run.
    /// `module`, or the only module of type `localiser`.
    SetPose {
        x_m: f64,
        y_m: f64,
        heading_deg: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        module: Option<String>,
    },
}

/// A run's state: every module, and the mission if there is one.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Status {
    pub system: String,
    pub run_secs: f64,
    pub time_scale: f64,
    /// The agent's address, for a client that wants to subscribe to the run's data.
    pub agent: String,
    pub modules: Vec<ModuleStatus>,
    pub mission: Option<MissionStatus>,
    /// The latest changes of behaviour states, oldest first (at most
    /// [`crate::behaviour::MAX_CHANGES`]).
    #[serde(default)]
    pub behaviour_changes: Vec<BehaviourChange>,
}

/// A module's behaviour state changed (`state` none: it went away).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct BehaviourChange {
    pub run_secs: f64,
    pub module: String,
    pub state: Option<BehaviourState>,
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MissionStatus {
    pub name: String,
    pub paused: bool,
    pub marking: Marking,
    /// Transitions that may fire now or later, each with what it waits for.
    pub enabled: Vec<Enabled>,
    pub active_modules: Vec<String>,
    /// The latest firings, oldest first, and how many there were in all.
    pub firings: Vec<FiringRecord>,
    pub firings_total: usize,
    /// `complete`, `aborted`, `deadlock` or `failed` once the mission has ended.
    pub outcome: Option<String>,
}

/// An enabled transition and what it still waits for (an event, the rest of a delay, a date,
/// the operator); nothing when it fires at the next step.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Enabled {
    pub transition: String,
    pub waits_for: Vec<String>,
}

impl std::fmt::Display for Enabled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.transition)?;
        if !self.waits_for.is_empty() {
            write!(f, " (waits for {})", self.waits_for.join(", "))?;
        }
        Ok(())
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct FiringRecord {
    pub run_secs: f64,
    pub transition: String,
    pub by_hand: bool,
}

/// A module's process and activity, as the run view's module monitor shows it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ModuleState {
    /// Its process is up, not yet configured.
    #[default]
    Starting,
    /// Configured and at work.
    Running,
    /// Configured and idle: the mission (or the operator) stopped it.
    Stopped,
    /// Its process died; it is started again after a backoff.
    Crashed,
    /// Started again after a crash, not yet configured.
    Restarting,
    /// Crashed too often (or with restart `never`): given up.
    Failed,
    /// Ended on its own, successfully.
    Exited,
    /// Stopped with the whole run (a monitor's word once the run is over: the run itself
    /// never reports it).
    Ended,
}

impl ModuleState {
    pub fn as_str(self) -> &'static str {
        match self {
            ModuleState::Starting => "starting",
            ModuleState::Running => "running",
            ModuleState::Stopped => "stopped",
            ModuleState::Crashed => "crashed",
            ModuleState::Restarting => "restarting",
            ModuleState::Failed => "failed",
            ModuleState::Exited => "exited",
            ModuleState::Ended => "ended with the run",
        }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ModuleStatus {
    pub name: String,
    pub module_type: String,
    pub state: ModuleState,
    /// Whether the mission (and the operator) can start and stop it.
    pub controllable: bool,
    /// The operator's hand on it: started (`true`) or stopped (`false`) until released.
    pub manual: Option<bool>,
    pub pid: Option<u32>,
    pub restarts: u32,
    /// How its process last ended, when it crashed (`was killed by signal 9`).
    pub last_exit: Option<String>,
    /// What it did so far, as of its last answer to a ping.
    pub stats: Option<NodeStats>,
    /// Why it runs (or would, once up): `place cross_drive`, `needed by follower.odometry`,
    /// `carries follower.cmd_desired`, `by hand`, `always`, `not controllable`, `no mission`;
    /// `None` when nothing needs it and it idles.
    #[serde(default)]
    pub why: Option<String>,
    /// A behaviour's state (`slept`, `checking`, `ready`, `winner`); none for a module that
    /// never said whether it applies.
    #[serde(default)]
    pub behaviour: Option<BehaviourState>,
    /// An arbiter's winner: the module whose command is in control.
    #[serde(default)]
    pub winner: Option<String>,
    /// The subsystems it is in, outermost first (empty: none).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub subsystems: Vec<String>,
    /// The declared host it runs on (`armor host`), or `None` for the supervisor's machine.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub host: Option<String>,
    /// Where its own services listen, name → address, as it said (the teleop's `teleop`).
    #[serde(default, skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub endpoints: std::collections::BTreeMap<String, String>,
}

/// A file of the run, as the run's machine has it.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FileText {
    /// Its path on the run's machine (for messages: the client need not have it).
    pub path: String,
    pub text: String,
}

/// What a client needs to draw a run it did not start ([`Request::Files`]).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RunFiles {
    /// The system file.
    pub system: FileText,
    /// The mission the run plays, a plan or a net, when it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mission: Option<FileText>,
    /// The files the system's `file` parameters name (the simulated world), as the run found
    /// them.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub params: Vec<ParamFile>,
    /// The description of every module type the system uses, in the describe format
    /// (`docs/protocol.md`, section 5), so that a client without the module binaries knows
    /// their ports.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub descriptions: Vec<String>,
}

/// A file a module's parameter names.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct ParamFile {
    pub module: String,
    pub param: String,
    pub file: FileText,
    /// The files it names in turn, by their names relative to its folder: a ROS map's image.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub beside: Vec<BinaryFile>,
}

/// A file that need not be text, its bytes in base64.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BinaryFile {
    /// Its name as the file that names it writes it.
    pub name: String,
    pub base64: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Reply {
    pub ok: bool,
    pub message: String,
    pub status: Option<Status>,
    /// The answer to [`Request::Files`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub files: Option<RunFiles>,
}

/// A request from a client, with where to send the answer.
pub type Incoming = (Request, Sender<Reply>);

/// A request on the control link, numbered by the client from 1: the run answers only the
/// next number, so a request replayed, reordered or dropped on the way ends the connection.
#[derive(Debug, Serialize, Deserialize)]
struct ToRun {
    seq: u64,
    request: Request,
}

/// The answer to request `seq`.
#[derive(Debug, Serialize, Deserialize)]
struct FromRun {
    seq: u64,
    reply: Reply,
}

/// The most control connections open at once (authenticated, with a secret); more are closed
/// at once. Connections still in their handshake are the gate's, bounded there.
const MAX_CLIENTS: usize = 64;
/// An open connection that sends nothing for this long is closed (the studio polls twice a
/// second; `armor ctl` sends at once).
const IDLE_TIMEOUT: Duration = Duration::from_secs(60);

/// Serves the control interface on `addr`, handing each request to `requests`. With a
/// `secret`, the link is a Noise transport like the data links: through the run's gate
/// ([`crate::gate`]: no thread and not a byte for a stranger, a deadline on the whole
/// handshake), encrypted, and only for clients that prove the key of a role (operator or
/// observer, [`Secret::role_key`]); an observer's commands are refused.
pub fn serve(
    addr: SocketAddr,
    requests: Sender<Incoming>,
    secret: Option<Secret>,
) -> std::io::Result<SocketAddr> {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    let listen = secret.map(|secret| Listen {
        admit: Admit::Control {
            operator: secret.role_key(Role::Operator),
            observer: secret.role_key(Role::Observer),
        },
        encrypt: true,
    });
    let open = Arc::new(AtomicUsize::new(0));
    std::thread::spawn(move || {
        crate::gate::serve(listener, listen, move |stream, proven| {
            // Without a secret there is no role to prove: whoever reaches the (loopback)
            // port operates.
            let role = match proven.as_deref().map(Role::parse) {
                None => Role::Operator,
                Some(Some(role)) => role,
                Some(None) => return,
            };
            if open.load(Ordering::Relaxed) >= MAX_CLIENTS {
                tracing::warn!("{MAX_CLIENTS} control clients are connected: refused another");
                return;
            }
            open.fetch_add(1, Ordering::Relaxed);
            let requests = requests.clone();
            let open = Arc::clone(&open);
            std::thread::spawn(move || {
                if let Err(err) = serve_client(stream, role, &requests) {
                    tracing::warn!("control client ({}): {err:#}", role.as_str());
                }
                open.fetch_sub(1, Ordering::Relaxed);
            });
        });
    });
    Ok(local)
}

/// The key a control client proves, from a file: a role's key (`armor secret derive`), or the
/// run's secret itself, which acts as the operator.
pub fn key_from_file(
    path: &std::path::Path,
) -> Result<RoleKey, armor_module_api::auth::SecretError> {
    match RoleKey::load(path) {
        Ok(key) => Ok(key),
        Err(armor_module_api::auth::SecretError::BadRoleKey { .. }) => {
            Secret::load(path).map(|secret| RoleKey {
                role: Role::Operator,
                key: secret.role_key(Role::Operator),
            })
        }
        Err(err) => Err(err),
    }
}

/// Whether the peer closed (or reset) the connection.
fn closed(err: &WireError) -> bool {
    match err {
        WireError::Closed => true,
        WireError::Io(err) => matches!(
            err.kind(),
            std::io::ErrorKind::ConnectionReset | std::io::ErrorKind::BrokenPipe
        ),
        _ => false,
    }
}

/// Whether a role may make a request: an observer only reads.
pub fn allowed(role: Role, request: &Request) -> bool {
    role == Role::Operator || matches!(request, Request::Status | Request::Files)
}

/// Reads one frame of at most `limit` bytes and decodes its message.
fn read_bounded<T: serde::de::DeserializeOwned>(
    reader: &mut impl std::io::Read,
    limit: usize,
) -> Result<T, WireError> {
    let mut header = [0; 4];
    read_exact(reader, &mut header)?;
    let len = u32::from_le_bytes(header) as usize;
    if len > limit {
        return Err(WireError::FrameTooLarge(len));
    }
    let mut frame = header.to_vec();
    frame.resize(4 + len, 0);
    read_exact(reader, &mut frame[4..])?;
    blocking::read_message(&mut frame.as_slice())
}

fn read_exact(reader: &mut impl std::io::Read, buf: &mut [u8]) -> Result<(), WireError> {
    reader.read_exact(buf).map_err(|err| match err.kind() {
        std::io::ErrorKind::UnexpectedEof => WireError::Closed,
        _ => WireError::Io(err),
    })
}

fn serve_client(
    stream: SecureStream,
    role: Role,
    requests: &Sender<Incoming>,
) -> anyhow::Result<()> {
    use anyhow::Context as _;
    stream.get_ref().set_read_timeout(Some(IDLE_TIMEOUT))?;
    stream.get_ref().set_nodelay(true)?;
    let (mut reader, mut writer) = stream.split();
    let mut expected = 1;
    loop {
        let message: ToRun = match read_bounded(&mut reader, MAX_REQUEST_BYTES) {
            Ok(message) => message,
            Err(WireError::Closed) => return Ok(()),
            Err(err) => return Err(err).context("bad request"),
        };
        if message.seq != expected {
            anyhow::bail!(
                "request numbered {} where {expected} was due: replayed, reordered or dropped on the way",
                message.seq
            );
        }
        expected += 1;
        let reply = if allowed(role, &message.request) {
            let (tx, rx) = mpsc::channel();
            if requests.send((message.request, tx)).is_err() {
                return Ok(());
            }
            rx.recv_timeout(REPLY_TIMEOUT).unwrap_or_else(|_| Reply {
                ok: false,
                message: "the run did not answer".to_owned(),
                status: None,
                files: None,
            })
        } else {
            Reply {
                ok: false,
                message: "refused: an observer's key may read the run, not command it (give an operator's key)".to_owned(),
                status: None,
                files: None,
            }
        };
        blocking::write_message(
            &mut writer,
            &FromRun {
                seq: message.seq,
                reply,
            },
        )?;
    }
}

/// Sends one request to a run's control interface and returns its reply; with a `secret`, first
/// proves it (and checks the run's proof).
pub fn request(
    addr: SocketAddr,
    request: &Request,
    secret: Option<&Secret>,
) -> anyhow::Result<Reply> {
    Client::connect(addr, secret)?.call(request)
}

/// A connection to a run's control interface, kept for many requests (authenticated once): the
/// studio's polls and the operator's driving commands, ten a second, need not each pay for a
/// connection and a handshake.
pub struct Client {
    reader: SecureReader,
    writer: SecureWriter,
    role: Option<Role>,
    seq: u64,
    /// The run's hello has not been read yet (a client without a key).
    hello_due: bool,
}

fn dial_role(dial: &Dial) -> Role {
    Role::parse(&dial.identity).unwrap_or(Role::Operator)
}

impl Client {
    /// Connects to the control interface at `addr`; with a `secret`, as the operator.
    pub fn connect(addr: SocketAddr, secret: Option<&Secret>) -> anyhow::Result<Client> {
        let key = secret.map(|secret| RoleKey {
            role: Role::Operator,
            key: secret.role_key(Role::Operator),
        });
        Client::connect_with(addr, key.as_ref())
    }

    /// Connects to the control interface at `addr`; with a role's `key`, proves it (and checks
    /// the run's proof) and encrypts the link.
    pub fn connect_with(addr: SocketAddr, key: Option<&RoleKey>) -> anyhow::Result<Client> {
        use anyhow::Context as _;
        let stream = TcpStream::connect_timeout(&addr, REPLY_TIMEOUT)
            .with_context(|| format!("cannot reach the run's control interface at {addr}"))?;
        stream.set_read_timeout(Some(REPLY_TIMEOUT * 2))?;
        stream.set_nodelay(true)?;
        let dial = key.map(|key| Dial {
            key: key.key.clone(),
            identity: key.role.as_str().to_owned(),
            encrypt: true,
        });
        // Without a key the run's hello is read with the first reply: a run that requires a
        // key sends nothing and closes at once, which the first call reports.
        let Some(dial) = dial else {
            blocking::write_hello(&mut &stream)?;
            let (reader, writer) = SecureStream::plain(stream)?.split();
            return Ok(Client {
                reader,
                writer,
                role: None,
                seq: 0,
                hello_due: true,
            });
        };
        let stream = match blocking::dial(stream, Some(&dial)) {
            Ok(stream) => stream,
            Err(WireError::HandshakeRefused(_)) => anyhow::bail!(
                "the run refused the handshake: it holds another secret, or runs without one"
            ),
            Err(err) => {
                return Err(err).with_context(|| {
                    format!("cannot open the control link at {addr} (is it a run's?)")
                });
            }
        };
        let (reader, writer) = stream.split();
        Ok(Client {
            reader,
            writer,
            role: Some(dial_role(&dial)),
            seq: 0,
            hello_due: false,
        })
    }

    /// The role this client proved, `None` without a secret (then it may do anything).
    pub fn role(&self) -> Option<Role> {
        self.role
    }

    /// Sends one request and waits for its reply. After an error the connection is in an
    /// unknown state: connect again.
    pub fn call(&mut self, request: &Request) -> anyhow::Result<Reply> {
        use anyhow::Context as _;
        self.seq += 1;
        blocking::write_message(
            &mut self.writer,
            &ToRun {
                seq: self.seq,
                request: request.clone(),
            },
        )?;
        let hello = if std::mem::take(&mut self.hello_due) {
            blocking::read_hello(&mut self.reader)
        } else {
            Ok(())
        };
        let answer =
            hello.and_then(|()| read_bounded::<FromRun>(&mut self.reader, MAX_FRAME_BYTES));
        let answer = match answer {
            Ok(answer) => answer,
            Err(err) if self.role.is_none() && self.seq == 1 && closed(&err) => anyhow::bail!(
                "the run closed the connection without a word: it requires the shared secret (armor ctl --secret FILE, or --key FILE)"
            ),
            Err(err) => return Err(err).context("no reply from the run"),
        };
        if answer.seq != self.seq {
            anyhow::bail!(
                "the run answered request {} where {} was due: the link was tampered with",
                answer.seq,
                self.seq
            );
        }
        Ok(answer.reply)
    }
}
