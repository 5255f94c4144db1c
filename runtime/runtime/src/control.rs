//! The operator's hold on a run (adjustable autonomy): ask for the state of every module and of
//! the mission, start and stop modules by hand, and pause, resume, abort a mission or fire a
//! transition by hand. `armor run` serves it on a TCP port as JSON lines, one request and one
//! reply per line; `armor ctl` and the studio's run view are its clients.
//!
//! ```text
//! → {"command":"fire","transition":"leave_wp1"}
//! ← {"ok":true,"message":"fired `leave_wp1`","status":{...}}
//! → {"command":"teleop","linear":0.3,"angular":0}
//! ← {"ok":true,"message":"teleop `teleop`: driving at 0.3 0","status":null}
//! → {"command":"files"}
//! ← {"ok":true,"message":"the run's files (…)","status":null,"files":{"system":{…},…}}
//! ```
//!
//! `teleop` is relayed to the run's teleop module (see [`crate::teleop_relay`]) and answered
//! with the module's own answer; `files` returns what a client that attaches without the
//! system file needs to draw the run ([`RunFiles`]).
//!
//! With a shared secret (see `armor_module_api::auth`) the client speaks first and both sides
//! prove the secret before any request, in three lines (hex bytes):
//!
//! ```text
//! → {"challenge":"…"}
//! ← {"challenge":"…","proof":"…"}
//! → {"proof":"…"}
//! ```

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::sync::mpsc::{self, Sender};
use std::time::Duration;

use armor_model::net::Marking;

pub use crate::behaviour::BehaviourState;
use armor_module_api::auth::{Admit, Dial, Dialer, Key, Listen, Listener, Secret};
use armor_module_api::protocol::NodeStats;
use serde::{Deserialize, Serialize};

pub const ENV_CONTROL: &str = "ARMOR_CONTROL";
/// A request line longer than this is not a request.
const MAX_LINE_BYTES: u64 = 64 * 1024;
/// A reply line longer than this is not a reply: a status, or the run's files (a world or a
/// ROS map's image among them).
const MAX_REPLY_BYTES: u64 = 64 * 1024 * 1024;
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

/// One line of the authentication exchange: a Noise handshake message, in hex.
#[derive(Debug, Default, Serialize, Deserialize)]
struct AuthLine {
    #[serde(default)]
    noise: String,
}

/// The identity a control client claims (its key is the operator key, whatever the name).
const OPERATOR: &str = "operator";
/// The most control connections that have not authenticated yet; more are closed at once.
const MAX_PENDING_CLIENTS: usize = 32;
/// A handshake line is short: a few hundred hex digits.
const MAX_AUTH_LINE_BYTES: u64 = 2048;

/// Serves the control interface on `addr`, handing each request to `requests`; with a
/// `secret`, only to clients that prove the operator key derived from it.
pub fn serve(
    addr: SocketAddr,
    requests: Sender<Incoming>,
    secret: Option<Secret>,
) -> std::io::Result<SocketAddr> {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicUsize, Ordering};
    let listener = TcpListener::bind(addr)?;
    let local = listener.local_addr()?;
    let operator = secret.map(|secret| secret.operator_key());
    let pending = Arc::new(AtomicUsize::new(0));
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            if operator.is_some() && pending.load(Ordering::Relaxed) >= MAX_PENDING_CLIENTS {
                tracing::warn!(
                    "{MAX_PENDING_CLIENTS} control clients are authenticating: refused another"
                );
                continue;
            }
            let requests = requests.clone();
            let operator = operator.clone();
            let pending = Arc::clone(&pending);
            pending.fetch_add(1, Ordering::Relaxed);
            std::thread::spawn(move || {
                if let Err(err) = serve_client(stream, &requests, operator.as_ref(), &pending) {
                    tracing::warn!("control client: {err}");
                }
            });
        }
    });
    Ok(local)
}

fn read_line(reader: &mut BufReader<TcpStream>, limit: u64) -> std::io::Result<Option<String>> {
    let mut line = String::new();
    if reader.take(limit).read_line(&mut line)? == 0 {
        return Ok(None);
    }
    Ok(Some(line))
}

fn write_json(writer: &mut TcpStream, value: &impl Serialize) -> std::io::Result<()> {
    let mut text = serde_json::to_string(value).map_err(std::io::Error::other)?;
    text.push('\n');
    writer.write_all(text.as_bytes())
}

fn auth_line(bytes: &[u8]) -> AuthLine {
    AuthLine {
        noise: bytes.iter().map(|b| format!("{b:02x}")).collect(),
    }
}

fn from_hex(text: &str) -> Option<Vec<u8>> {
    let text = text.trim();
    if !text.len().is_multiple_of(2) || !text.is_ascii() {
        return None;
    }
    (0..text.len() / 2)
        .map(|i| u8::from_str_radix(&text[i * 2..i * 2 + 2], 16).ok())
        .collect()
}

fn noise_of(line: &str) -> Option<Vec<u8>> {
    serde_json::from_str::<AuthLine>(line)
        .ok()
        .and_then(|auth| from_hex(&auth.noise))
        .filter(|bytes| !bytes.is_empty())
}

/// The server's side of the authentication (Noise, as the responder, with the operator key);
/// an error ends the connection.
fn authenticate_client(
    reader: &mut BufReader<TcpStream>,
    writer: &mut TcpStream,
    operator: &Key,
) -> std::io::Result<()> {
    let refuse = |writer: &mut TcpStream, message: &str| {
        let _ = write_json(
            writer,
            &Reply {
                ok: false,
                message: message.to_owned(),
                status: None,
                files: None,
            },
        );
        Err(std::io::Error::other(message.to_owned()))
    };
    let Some(line) = read_line(reader, MAX_AUTH_LINE_BYTES)? else {
        return Ok(());
    };
    let Some(first) = noise_of(&line) else {
        return refuse(
            writer,
            "this run requires the shared secret: give armor ctl --secret FILE (or ARMOR_SECRET_FILE)",
        );
    };
    let listen = Listen {
        admit: Admit::Operator(operator.clone()),
        encrypt: false,
    };
    let listener = match Listener::accept(&listen, &first) {
        Ok((listener, answer, _)) => {
            write_json(writer, &auth_line(&answer))?;
            listener
        }
        Err(_) => {
            return refuse(
                writer,
                "the handshake failed: another secret than this run's",
            );
        }
    };
    let Some(line) = read_line(reader, MAX_AUTH_LINE_BYTES)? else {
        return Err(std::io::Error::other("closed during authentication"));
    };
    match noise_of(&line).map(|confirm| listener.confirm(&confirm)) {
        Some(Ok(_)) => Ok(()),
        _ => refuse(
            writer,
            "the handshake failed: another secret than this run's",
        ),
    }
}

fn serve_client(
    stream: TcpStream,
    requests: &Sender<Incoming>,
    operator: Option<&Key>,
    pending: &std::sync::atomic::AtomicUsize,
) -> std::io::Result<()> {
    use std::sync::atomic::Ordering;
    let started = (|| {
        let writer = stream.try_clone()?;
        let mut reader = BufReader::with_capacity(MAX_AUTH_LINE_BYTES as usize, stream);
        let mut writer = writer;
        if let Some(operator) = operator {
            reader.get_ref().set_read_timeout(Some(REPLY_TIMEOUT))?;
            authenticate_client(&mut reader, &mut writer, operator)?;
            reader.get_ref().set_read_timeout(None)?;
        }
        Ok::<_, std::io::Error>((reader, writer))
    })();
    pending.fetch_sub(1, Ordering::Relaxed);
    let (mut reader, mut writer) = started?;
    loop {
        let mut line = String::new();
        if (&mut reader).take(MAX_LINE_BYTES).read_line(&mut line)? == 0 {
            return Ok(());
        }
        let reply = match serde_json::from_str::<Request>(&line) {
            Ok(request) => {
                let (tx, rx) = mpsc::channel();
                if requests.send((request, tx)).is_err() {
                    return Ok(());
                }
                rx.recv_timeout(REPLY_TIMEOUT).unwrap_or_else(|_| Reply {
                    ok: false,
                    message: "the run did not answer".to_owned(),
                    status: None,
                    files: None,
                })
            }
            Err(err) => Reply {
                ok: false,
                message: format!(
                    "bad request: {err} (expected e.g. {{\"command\":\"pause\"}} or {{\"command\":\"fire\",\"transition\":\"NAME\"}})"
                ),
                status: None,
                files: None,
            },
        };
        let mut text = serde_json::to_string(&reply).map_err(std::io::Error::other)?;
        text.push('\n');
        writer.write_all(text.as_bytes())?;
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
    reader: BufReader<TcpStream>,
    writer: TcpStream,
}

impl Client {
    /// Connects to the control interface at `addr`; with a `secret`, proves it (and checks the
    /// run's proof).
    pub fn connect(addr: SocketAddr, secret: Option<&Secret>) -> anyhow::Result<Client> {
        use anyhow::Context as _;
        let stream = TcpStream::connect_timeout(&addr, REPLY_TIMEOUT)
            .with_context(|| format!("cannot reach the run's control interface at {addr}"))?;
        stream.set_read_timeout(Some(REPLY_TIMEOUT * 2))?;
        stream.set_nodelay(true)?;
        let mut writer = stream.try_clone()?;
        let mut reader = BufReader::new(stream);
        if let Some(secret) = secret {
            let dial = Dial {
                key: secret.operator_key(),
                identity: OPERATOR.to_owned(),
                encrypt: false,
            };
            let (dialer, first) = Dialer::start(&dial)?;
            write_json(&mut writer, &auth_line(&first))?;
            let line =
                read_line(&mut reader, MAX_LINE_BYTES)?.context("the run closed the connection")?;
            if let Ok(Reply {
                ok: false, message, ..
            }) = serde_json::from_str::<Reply>(&line)
            {
                anyhow::bail!("the run refused: {message}");
            }
            let Some(answer) = noise_of(&line) else {
                anyhow::bail!(
                    "the run does not authenticate (started without --secret?): it answered `{}`",
                    line.trim()
                );
            };
            let Ok((confirm, _)) = dialer.finish(&answer) else {
                anyhow::bail!("the run's handshake does not match: it holds another secret");
            };
            write_json(&mut writer, &auth_line(&confirm))?;
        }
        Ok(Client { reader, writer })
    }

    /// Sends one request and waits for its reply. After an error the connection is in an
    /// unknown state: connect again.
    pub fn call(&mut self, request: &Request) -> anyhow::Result<Reply> {
        use anyhow::Context as _;
        write_json(&mut self.writer, request)?;
        let line =
            read_line(&mut self.reader, MAX_REPLY_BYTES)?.context("no reply from the run")?;
        serde_json::from_str(&line).with_context(|| format!("unreadable reply `{}`", line.trim()))
    }
}
