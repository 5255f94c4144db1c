//! A run started from the studio: `armor run` as a child process (the same runtime as on the
//! command line), its output split into per-module logs, its control interface polled for the
//! state of every module and of the mission, operator requests sent to it, and the robot's data
//! read by a node of our own (see [`super::live`]). Nothing here blocks the frame: each of these
//! is a thread that writes into [`Shared`].

use std::collections::{BTreeMap, VecDeque};
use std::io::{BufRead, BufReader, Read};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_model::rehearsal::{AreaJudgement, ArrivalJudgement, Verdict};
use armor_protocol::{FiringRecord, MissionStatus, Request, RunFiles, Status};

use super::live::{self, Sources};
use super::updates::NoRunPlan;

/// How often the control interface is asked for the state.
const POLL_EVERY: Duration = Duration::from_millis(200);
/// Log lines kept (the oldest go first).
const MAX_LOG_LINES: usize = 20_000;
/// Bytes kept of one line of a module's output (the rest of a longer line is skipped), so that
/// the log holds at most `MAX_LOG_LINES × MAX_LINE_BYTES` (320 MiB) whatever a module prints.
const MAX_LINE_BYTES: usize = 16 * 1024;
/// Samples of each module's counters kept for its plots.
const MAX_HISTORY: usize = 240;
/// How long a stopped run has to end before it is killed.
const STOP_GRACE: Duration = Duration::from_secs(8);
/// How often the operator's teleoperation command is sent while held.
pub const TELEOP_EVERY: Duration = Duration::from_millis(100);
/// A driving command older than this when its turn comes (the control link was slow or being
/// reconnected) is dropped, never sent late: the operator has let go or sent a newer one.
const TELEOP_STALE: Duration = Duration::from_millis(300);

/// What a run is started with.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// A system or plan file.
    pub target: PathBuf,
    /// Run time passes this many times faster than real time.
    pub time_scale: f64,
    /// The date run time 0 stands for (RFC 3339), for a plan's dates.
    pub start_at: Option<String>,
    /// The folder the run works in: the sim finds its world and the recorder writes its file
    /// from there, as from the folder `armor run` is typed in.
    pub working_dir: PathBuf,
    /// Where the `armor` binary and the modules are.
    pub module_path: Vec<PathBuf>,
    /// What the live views subscribe to.
    pub sources: Sources,
    /// The shared secret's file (`armor run --secret`): the run requires it of every
    /// connection, the studio's own included.
    pub secret: Option<PathBuf>,
    /// Attached: ask the run for its files, once (without its system file, to draw it; with
    /// the system open, for the plan it plays, which the operator edits and sends).
    pub ask_files: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    Info,
    Warn,
    Error,
}

#[derive(Clone, Debug)]
pub struct LogLine {
    /// Seconds since the run started (real time).
    pub at_secs: f64,
    /// The module that wrote it, or `armor` for the supervisor.
    pub source: String,
    pub level: Level,
    pub text: String,
}

/// A module's counters at one moment, for rates and cycle times.
#[derive(Clone, Debug)]
pub struct Sample {
    pub at_secs: f64,
    pub stats: armor_module_api::protocol::NodeStats,
}

/// What the threads of a run write and the frame reads.
#[derive(Default)]
pub struct Shared {
    pub logs: VecDeque<LogLine>,
    /// Lines dropped from the front of `logs`.
    pub logs_dropped: usize,
    pub status: Option<Status>,
    /// Each module's counters over time (oldest first).
    pub history: BTreeMap<String, VecDeque<Sample>>,
    pub control_addr: Option<SocketAddr>,
    /// The answers to the operator's requests, for the status line.
    pub replies: Vec<(bool, String)>,
    /// How the run ended, once it has.
    pub ended: Option<String>,
    /// A simulated plan run's verdict by the simulator's truth (the report's `rehearsal`),
    /// once the run has ended.
    pub rehearsal: Option<Verdict>,
    /// The control interface does not answer (why), since when (real seconds of the session);
    /// it is asked again at every poll.
    pub connection_lost: Option<(f64, String)>,
    pub live: live::SharedLive,
    /// The run's files, asked of a run attached without its system file
    /// ([`Request::Files`]); taken by the view, which attaches again with them.
    pub files: Option<RunFiles>,
    /// The role the studio proved at the run's control interface (`None`: the run has no
    /// secret, and anyone who reaches it operates).
    pub role: Option<armor_protocol::Role>,
    /// The run's answers to the plan updates the studio sent, oldest first; taken by the view.
    pub update_answers: Vec<UpdateAnswer>,
    /// The plan the run plays, as the run sent it once it reported an update taken (its own,
    /// `armor ctl update` from elsewhere, an area a module reported); `None` before any.
    pub running_plan: Option<RunningPlan>,
}

/// The run's answer to a plan update the studio sent ([`RunSession::send_update`]) or a repair
/// option it chose ([`RunSession::repair`]).
#[derive(Clone, Debug, PartialEq)]
pub struct UpdateAnswer {
    /// Whether the run took it; `false` when it refused it, and when no answer came (the
    /// message says which).
    pub taken: bool,
    /// The run's words (`update 3 taken: …`, `update 4 refused: …`), or why there is none.
    pub message: String,
    /// The plan sent; none for a repair (the run makes its plan).
    pub text: Option<String>,
}

/// The plan a run plays, as it sent it ([`Request::Files`]) after reporting an update taken.
#[derive(Clone, Debug, PartialEq)]
pub struct RunningPlan {
    /// The number of the last update taken that the run had reported when it was asked.
    pub after_update: u32,
    /// The plan's text, or why the run did not send it.
    pub text: Result<String, NoRunPlan>,
}

impl Shared {
    fn log(&mut self, line: LogLine) {
        if self.logs.len() == MAX_LOG_LINES {
            self.logs.pop_front();
            self.logs_dropped += 1;
        }
        self.logs.push_back(line);
    }
}

pub type SharedRef = Arc<Mutex<Shared>>;

pub fn lock(shared: &SharedRef) -> MutexGuard<'_, Shared> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

pub struct RunSession {
    pub options: RunOptions,
    child: Option<Child>,
    pub shared: SharedRef,
    requests: Sender<Request>,
    teleop: Sender<(f64, f64, Instant)>,
    /// Set when the run is asked to stop: every thread of the session ends.
    stop: Arc<AtomicBool>,
    /// Watching a run started elsewhere (no process of ours).
    attached: bool,
    stop_asked: Option<Instant>,
    report: PathBuf,
    started: Instant,
}

impl RunSession {
    /// Starts `armor run` on the options' target.
    pub fn start(options: RunOptions, ctx: &egui::Context) -> anyhow::Result<RunSession> {
        let armor = armor_binary(&options.module_path)?;
        let report = std::env::temp_dir().join(format!(
            "armor-studio-{}-{}.json",
            std::process::id(),
            armor_module_api::clock::unix_now_ns()
        ));
        let mut command = Command::new(&armor);
        command
            .arg("run")
            .arg(std::path::absolute(&options.target).unwrap_or_else(|_| options.target.clone()))
            .arg("--time-scale")
            .arg(options.time_scale.to_string())
            .arg("--report")
            .arg(&report)
            // With access lists in the system, the studio's node may still watch everything.
            .arg("--observer")
            .arg(super::live::NODE_NAME)
            .current_dir(&options.working_dir)
            .env(
                armor_runtime::probe::ENV_MODULE_PATH,
                std::env::join_paths(&options.module_path).unwrap_or_default(),
            )
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        if let Some(date) = &options.start_at {
            command.arg("--start-at").arg(date);
        }
        // The secret is the one the Run view shows, never one the environment adds unseen.
        command.env_remove(armor_module_api::auth::ENV_SECRET_FILE);
        if let Some(secret) = &options.secret {
            command.arg("--secret").arg(secret);
        }
        // The run dies with the studio, and a terminal's Ctrl-C reaches only the studio.
        armor_runtime::process::die_with_parent(&mut command);
        let mut child = command
            .spawn()
            .with_context(|| format!("cannot start {}", armor.display()))?;
        let started = Instant::now();
        let (control_tx, control_rx) = mpsc::channel();
        let mut session = RunSession::watch(options, control_rx, report, started, ctx);
        let shared = &session.shared;
        read_output(
            child.stdout.take(),
            Source::Modules(control_tx),
            shared,
            started,
            ctx,
        );
        read_output(
            child.stderr.take(),
            Source::Supervisor,
            shared,
            started,
            ctx,
        );
        session.child = Some(child);
        Ok(session)
    }

    /// Watches a run started elsewhere (`armor run` in a terminal), through its control
    /// interface at `control`: the same views, without its logs.
    pub fn attach(options: RunOptions, control: SocketAddr, ctx: &egui::Context) -> RunSession {
        let (control_tx, control_rx) = mpsc::channel();
        let _ = control_tx.send(control);
        let mut session =
            RunSession::watch(options, control_rx, PathBuf::new(), Instant::now(), ctx);
        session.attached = true;
        lock(&session.shared).control_addr = Some(control);
        session
    }

    /// The threads that poll the control interface and drive the teleop module.
    fn watch(
        options: RunOptions,
        control_rx: Receiver<SocketAddr>,
        report: PathBuf,
        started: Instant,
        ctx: &egui::Context,
    ) -> RunSession {
        let shared: SharedRef = Arc::default();
        let stop = Arc::new(AtomicBool::new(false));
        let (requests, requests_rx) = mpsc::channel();
        {
            let shared = Arc::clone(&shared);
            let stop = Arc::clone(&stop);
            let ctx = ctx.clone();
            let options = options.clone();
            std::thread::spawn(move || {
                poll_control(
                    &control_rx,
                    &requests_rx,
                    &shared,
                    &stop,
                    started,
                    &ctx,
                    options,
                )
            });
        }
        let (teleop, teleop_rx) = mpsc::channel();
        {
            let shared = Arc::clone(&shared);
            let stop = Arc::clone(&stop);
            let secret = options.secret.clone();
            std::thread::spawn(move || drive(&teleop_rx, &shared, &stop, secret.as_deref()));
        }
        RunSession {
            options,
            child: None,
            shared,
            requests,
            teleop,
            stop,
            attached: false,
            stop_asked: None,
            report,
            started,
        }
    }

    pub fn shared(&self) -> MutexGuard<'_, Shared> {
        lock(&self.shared)
    }

    /// Real seconds since the run started.
    pub fn elapsed_secs(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// The run's process id (the supervisor's).
    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(Child::id)
    }

    /// Sends an operator request; its answer shows in [`Shared::replies`].
    pub fn request(&self, request: Request) {
        let _ = self.requests.send(request);
    }

    /// Sends `text`, a whole plan, to the run as an update of the plan it plays (what `armor
    /// ctl update` sends; `file` names it in the run's records); its answer shows in
    /// [`Shared::update_answers`].
    pub fn send_update(&self, file: String, text: String) {
        let _ = self.requests.send(Request::Update { file, text });
    }

    /// Applies option `option` of the repair the mission proposes (`armor ctl repair N`): an
    /// update the run makes; its answer shows in [`Shared::update_answers`].
    pub fn repair(&self, option: u32) {
        let _ = self.requests.send(Request::Repair { option });
    }

    /// Drives the robot through the run's control interface, which relays to its teleop
    /// module: `linear` m/s, `angular` rad/s. The module holds a command for its dead-man time,
    /// so a command must be sent again while held.
    pub fn teleop(&self, linear: f64, angular: f64) {
        let _ = self.teleop.send((linear, angular, Instant::now()));
    }

    /// Watching a run started elsewhere: stopping only detaches.
    pub fn is_attached(&self) -> bool {
        self.attached
    }

    pub fn is_running(&self) -> bool {
        self.child.is_some() || (self.attached && !self.stop.load(Ordering::Relaxed))
    }

    pub fn is_stopping(&self) -> bool {
        self.stop_asked.is_some() && self.child.is_some()
    }

    /// Asks the run to stop as Ctrl-C would: it stops every module in order, then exits.
    pub fn stop(&mut self) {
        if self.attached {
            // Not ours to stop: stop watching.
            self.stop.store(true, Ordering::Relaxed);
            return;
        }
        if let (Some(child), None) = (&self.child, self.stop_asked) {
            armor_runtime::process::kill(child.id() as libc::pid_t, libc::SIGINT);
            self.stop_asked = Some(Instant::now());
        }
    }

    /// Notices the end of the run (called every frame): reads its report, and kills a run that
    /// was asked to stop and has not within the grace time. Returns true when it just ended.
    pub fn poll(&mut self) -> bool {
        let Some(child) = &mut self.child else {
            return false;
        };
        let status = match child.try_wait() {
            Ok(Some(status)) => status,
            Ok(None) => {
                if self.stop_asked.is_some_and(|at| at.elapsed() > STOP_GRACE) {
                    let _ = child.kill();
                }
                return false;
            }
            Err(err) => {
                tracing::warn!("cannot watch the run: {err}");
                return false;
            }
        };
        self.child = None;
        self.stop.store(true, Ordering::Relaxed);
        let report = read_report(&self.report);
        let _ = std::fs::remove_file(&self.report);
        let mut shared = self.shared();
        let ended = match (&report, status.code()) {
            // A mission that completed on the robot's word but not on the truth's did not pass:
            // the verdict goes with the outcome, never the outcome alone.
            (Some(report), _) => match &report.rehearsal {
                Some(verdict) => format!(
                    "ended: mission {}, rehearsal {} by the simulator's truth",
                    report.outcome,
                    if verdict.passed { "passed" } else { "FAILED" }
                ),
                None => format!("ended: mission {}", report.outcome),
            },
            (None, Some(0)) => "ended".to_owned(),
            (None, Some(code)) => format!("ended with status {code}"),
            (None, None) => "was killed".to_owned(),
        };
        shared.ended = Some(ended);
        shared.rehearsal = report.as_ref().and_then(|report| report.rehearsal.clone());
        if let (Some(report), Some(status)) = (report, shared.status.as_mut())
            && let Some(mission) = &mut status.mission
        {
            report.apply(mission);
        }
        true
    }
}

impl Drop for RunSession {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(mut child) = self.child.take() {
            // The supervisor's children die with it (PR_SET_PDEATHSIG).
            let _ = child.kill();
            let _ = child.wait();
        }
        let _ = std::fs::remove_file(&self.report);
    }
}

/// The `armor` binary: next to the modules, else on the `PATH`.
fn armor_binary(module_path: &[PathBuf]) -> anyhow::Result<PathBuf> {
    let beside = module_path
        .iter()
        .map(|dir| dir.join("armor"))
        .find(|file| file.is_file());
    if let Some(file) = beside {
        return Ok(file);
    }
    std::env::var_os("PATH")
        .into_iter()
        .flat_map(|path| std::env::split_paths(&path).collect::<Vec<_>>())
        .map(|dir| dir.join("armor"))
        .find(|file| file.is_file())
        .context("no `armor` binary next to the modules or on the PATH")
}

enum Source {
    /// `armor run`'s stdout: module lines (`[name] text`) and its control address.
    Modules(Sender<SocketAddr>),
    /// `armor run`'s own log, on stderr.
    Supervisor,
}

fn read_output(
    pipe: Option<impl Read + Send + 'static>,
    source: Source,
    shared: &SharedRef,
    started: Instant,
    ctx: &egui::Context,
) {
    let Some(pipe) = pipe else {
        return;
    };
    let shared = Arc::clone(shared);
    let ctx = ctx.clone();
    std::thread::spawn(move || {
        let mut reader = BufReader::new(pipe);
        let mut bytes = Vec::new();
        // A read error is the end of the pipe: the process is gone.
        while let Ok(true) = read_line_bounded(&mut reader, &mut bytes, MAX_LINE_BYTES) {
            // Lossy: a module that prints bytes that are not UTF-8 must not stop its log (the
            // pipe would then fill and block the run).
            let line = String::from_utf8_lossy(&bytes).into_owned();
            let at_secs = started.elapsed().as_secs_f64();
            let (module, text) = match &source {
                Source::Modules(control) => {
                    if let Some(addr) = line
                        .strip_prefix(armor_runtime::CONTROL_READY_PREFIX)
                        .and_then(|addr| addr.trim().parse().ok())
                    {
                        lock(&shared).control_addr = Some(addr);
                        let _ = control.send(addr);
                        continue;
                    }
                    match line
                        .strip_prefix('[')
                        .and_then(|rest| rest.split_once("] "))
                    {
                        Some((module, text)) => (module.to_owned(), strip_timestamp(text)),
                        None => ("armor".to_owned(), line.clone()),
                    }
                }
                Source::Supervisor => ("armor".to_owned(), strip_timestamp(&line)),
            };
            let level = if text.contains("ERROR") {
                Level::Error
            } else if text.contains("WARN") {
                Level::Warn
            } else {
                Level::Info
            };
            let mut shared = lock(&shared);
            shared.log(LogLine {
                at_secs,
                source: module,
                level,
                text,
            });
            drop(shared);
            ctx.request_repaint_after(Duration::from_millis(100));
        }
    });
}

/// Reads one line into `line` without its end (`\n` or `\r\n`), keeping at most `max_bytes` of
/// it and skipping the rest; false at the end of the stream.
fn read_line_bounded(
    reader: &mut impl BufRead,
    line: &mut Vec<u8>,
    max_bytes: usize,
) -> std::io::Result<bool> {
    line.clear();
    let mut read_any = false;
    loop {
        let available = reader.fill_buf()?;
        if available.is_empty() {
            break;
        }
        read_any = true;
        let end = available.iter().position(|&byte| byte == b'\n');
        let part = &available[..end.unwrap_or(available.len())];
        let room = max_bytes.saturating_sub(line.len());
        line.extend_from_slice(&part[..part.len().min(room)]);
        match end {
            Some(end) => {
                reader.consume(end + 1);
                break;
            }
            None => {
                let all = available.len();
                reader.consume(all);
            }
        }
    }
    if line.last() == Some(&b'\r') {
        line.pop();
    }
    Ok(read_any)
}

/// A tracing line without its leading date (`2026-11-23T06:40:00.123456Z  INFO …`).
fn strip_timestamp(text: &str) -> String {
    let trimmed = text.trim_end();
    match trimmed.split_once(' ') {
        Some((first, rest)) if first.len() >= 20 && first.ends_with('Z') && first.contains('T') => {
            rest.trim_start().to_owned()
        }
        _ => trimmed.to_owned(),
    }
}

/// Asks the run for its state every [`POLL_EVERY`] and sends the operator's requests, once the
/// control address is known; starts the live data node once the agent's is. Both prove the
/// options' secret when there is one.
fn poll_control(
    control: &Receiver<SocketAddr>,
    requests: &Receiver<Request>,
    shared: &SharedRef,
    stop: &Arc<AtomicBool>,
    started: Instant,
    ctx: &egui::Context,
    options: RunOptions,
) {
    let RunOptions {
        sources,
        secret: secret_file,
        ask_files,
        ..
    } = options;
    let mut want_files = ask_files;
    // The last update taken whose plan the run was asked for, and the one to ask it for at
    // the next poll: the plan it plays has changed, whoever changed it.
    let mut plan_asked_after = 0;
    let mut want_plan: Option<u32> = None;
    let addr = loop {
        if stop.load(Ordering::Relaxed) {
            return;
        }
        match control.recv_timeout(POLL_EVERY) {
            Ok(addr) => break addr,
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => return,
        }
    };
    // A role's key (an observer's, say) or the secret itself, which acts as the operator.
    let secret = match secret_file.as_deref().map(armor_protocol::key_from_file) {
        Some(Ok(secret)) => Some(secret),
        Some(Err(err)) => {
            lock(shared).replies.push((false, err.to_string()));
            None
        }
        None => None,
    };
    let mut live_started = false;
    let mut next_poll = Instant::now();
    let mut client: Option<armor_protocol::Client> = None;
    while !stop.load(Ordering::Relaxed) {
        let request =
            match requests.recv_timeout(next_poll.saturating_duration_since(Instant::now())) {
                Ok(request) => request,
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    next_poll = Instant::now() + POLL_EVERY;
                    Request::Status
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => return,
            };
        let polled = request == Request::Status;
        let plan_after = want_plan.filter(|_| polled && !want_files);
        let request = if polled && (want_files || plan_after.is_some()) {
            Request::Files
        } else {
            request
        };
        if plan_after.is_some() {
            want_plan = None;
        }
        let is_status = matches!(request, Request::Status | Request::Files);
        // One connection for every poll and request, opened again after an error.
        let reply = match client.as_mut() {
            Some(open) => open.call(&request),
            None => armor_protocol::Client::connect_with(addr, secret.as_ref()).and_then(
                |mut opened| {
                    lock(shared).role = opened.role();
                    let reply = opened.call(&request);
                    client = Some(opened);
                    reply
                },
            ),
        };
        // As anyhow, so that `{err:#}` shows the causes.
        let reply = reply.map_err(anyhow::Error::from);
        if reply.is_err() {
            client = None;
        }
        let at_secs = started.elapsed().as_secs_f64();
        let mut shared_now = lock(shared);
        match reply {
            Ok(reply) => {
                shared_now.connection_lost = None;
                match (&request, plan_after) {
                    (Request::Update { .. } | Request::Repair { .. }, _) => {
                        shared_now.update_answers.push(UpdateAnswer {
                            taken: reply.ok,
                            message: reply.message,
                            text: sent_plan(&request),
                        });
                    }
                    (_, Some(after_update)) => {
                        let text = match reply.files.and_then(|files| files.mission) {
                            Some(mission) => Ok(mission.text),
                            None if reply.ok => {
                                Err(NoRunPlan::NotSent("its answer held none".to_owned()))
                            }
                            None => Err(NoRunPlan::NotSent(reply.message)),
                        };
                        shared_now.running_plan = Some(RunningPlan { after_update, text });
                    }
                    (_, None) => {
                        if !is_status || (reply.files.is_none() && request == Request::Files) {
                            shared_now.replies.push((reply.ok, reply.message));
                        }
                        if request == Request::Files {
                            // Asked once: a run that cannot send them is watched without them.
                            want_files = false;
                        }
                        if let Some(files) = reply.files {
                            shared_now.files = Some(files);
                        }
                    }
                }
                if let Some(status) = reply.status {
                    // An update taken that the studio has not seen the plan of: ask for it.
                    let last_taken = status
                        .mission
                        .iter()
                        .flat_map(|mission| &mission.updates)
                        .filter(|update| update.taken)
                        .map(|update| update.number)
                        .max();
                    if let Some(last_taken) = last_taken
                        && last_taken > plan_asked_after
                    {
                        plan_asked_after = last_taken;
                        want_plan = Some(last_taken);
                    }
                    for module in &status.modules {
                        if let Some(stats) = &module.stats {
                            let history =
                                shared_now.history.entry(module.name.clone()).or_default();
                            if history.back().is_none_or(|last| &last.stats != stats) {
                                if history.len() == MAX_HISTORY {
                                    history.pop_front();
                                }
                                history.push_back(Sample {
                                    at_secs,
                                    stats: stats.clone(),
                                });
                            }
                        }
                    }
                    if !live_started && let Ok(agent) = status.agent.parse::<SocketAddr>() {
                        live_started = true;
                        live::start(
                            agent,
                            secret_file.clone(),
                            sources.clone(),
                            &shared_now.live,
                            stop,
                            ctx,
                        );
                    }
                    shared_now.status = Some(status);
                }
            }
            Err(err) => {
                if shared_now.connection_lost.is_none() {
                    shared_now.connection_lost = Some((at_secs, format!("{err:#}")));
                }
                match &request {
                    // The run may have taken it before the link broke: its list of updates
                    // says, once the link is back.
                    Request::Update { .. } | Request::Repair { .. } => {
                        shared_now.update_answers.push(UpdateAnswer {
                            taken: false,
                            message: format!(
                                "no answer from the run ({err:#}): whether it took the update, \
                                 its list of updates will say once the link is back"
                            ),
                            text: sent_plan(&request),
                        });
                    }
                    _ if !is_status => shared_now.replies.push((false, format!("{err:#}"))),
                    _ => {}
                }
                // Asked again at the next poll.
                if let Some(after_update) = plan_after {
                    want_plan = Some(after_update);
                }
                // The run's last state stays shown.
            }
        }
        drop(shared_now);
        ctx.request_repaint();
    }
}

/// The plan an update request sends, if it sends one.
fn sent_plan(request: &Request) -> Option<String> {
    match request {
        Request::Update { text, .. } => Some(text.clone()),
        _ => None,
    }
}

/// Whether the run can be driven: a teleop module is at work and has said where it listens
/// (the supervisor relays the operator's commands there).
pub fn can_drive(status: &Status) -> bool {
    status.modules.iter().any(|module| {
        module.module_type == armor_protocol::TELEOP_TYPE
            && module.state == armor_protocol::ModuleState::Running
            && module
                .endpoints
                .contains_key(armor_protocol::TELEOP_ENDPOINT)
    })
}

/// Sends the operator's driving commands as `teleop` requests on a connection of its own to
/// the run's control interface (which relays them to the teleop module), so that polling never
/// delays them. Only the newest command is sent, and only while fresh: one that waited behind a
/// lost or slow link is dropped, never replayed once the link is back; and a studio whose link
/// is lost commands nothing, so the module's dead-man stops the robot.
fn drive(
    commands: &Receiver<(f64, f64, Instant)>,
    shared: &SharedRef,
    stop: &AtomicBool,
    secret_file: Option<&Path>,
) {
    let secret = secret_file.and_then(|file| armor_protocol::key_from_file(file).ok());
    let mut client: Option<armor_protocol::Client> = None;
    let mut last_error: Option<String> = None;
    while !stop.load(Ordering::Relaxed) {
        let mut command = match commands.recv_timeout(Duration::from_millis(200)) {
            Ok(command) => command,
            Err(mpsc::RecvTimeoutError::Timeout) => continue,
            Err(mpsc::RecvTimeoutError::Disconnected) => return,
        };
        while let Ok(newer) = commands.try_recv() {
            command = newer;
        }
        let (linear, angular, at) = command;
        if at.elapsed() > TELEOP_STALE {
            continue;
        }
        let Some(addr) = lock(shared).control_addr else {
            continue;
        };
        let request = Request::Teleop {
            linear,
            angular,
            module: None,
        };
        let reply = match client.as_mut() {
            Some(open) => open.call(&request),
            None => armor_protocol::Client::connect_with(addr, secret.as_ref()).and_then(
                |mut opened| {
                    let reply = opened.call(&request);
                    client = Some(opened);
                    reply
                },
            ),
        };
        let error = match reply.map_err(anyhow::Error::from) {
            Ok(reply) if reply.ok => None,
            Ok(reply) => Some(reply.message),
            Err(err) => {
                client = None;
                Some(format!("driving: {err:#}"))
            }
        };
        // Each new problem once on the status line, not ten times a second.
        if error.is_some() && error != last_error {
            lock(shared)
                .replies
                .push((false, error.clone().unwrap_or_default()));
        }
        last_error = error;
    }
}

/// What `armor run --report` wrote when the mission ended.
struct Report {
    outcome: String,
    marking: Option<armor_model::net::Marking>,
    firings: Vec<FiringRecord>,
    rehearsal: Option<Verdict>,
}

impl Report {
    /// Brings the last status up to the end of the run.
    fn apply(self, mission: &mut MissionStatus) {
        if let Some(marking) = self.marking {
            mission.marking = marking;
        }
        mission.firings_total = self.firings.len();
        mission.firings = self.firings;
        mission.enabled.clear();
        mission.outcome = Some(self.outcome);
    }
}

fn read_report(file: &Path) -> Option<Report> {
    let text = std::fs::read_to_string(file).ok()?;
    let report: serde_json::Value = serde_json::from_str(&text).ok()?;
    let timeline = report["timeline"].as_array()?;
    let marking = timeline
        .iter()
        .rev()
        .find_map(|entry| serde_json::from_value(entry["marking"].clone()).ok());
    let firings = timeline
        .iter()
        .filter(|entry| entry["kind"] == "fired")
        .map(|entry| FiringRecord {
            run_secs: entry["at_secs"]
                .as_f64()
                .or_else(|| entry["run_secs"].as_f64())
                .unwrap_or_default(),
            transition: entry["transition"].as_str().unwrap_or_default().to_owned(),
            by_hand: entry["by_hand"].as_bool().unwrap_or(false),
        })
        .collect();
    Some(Report {
        outcome: report["outcome"].as_str()?.to_owned(),
        marking,
        firings,
        rehearsal: rehearsal(&report["rehearsal"]),
    })
}

/// The verdict of the report's `rehearsal` section (`armor_runtime::rehearsal::report`), so
/// that the view words it as `armor run`'s summary does; `None` when there is none or it is
/// not one.
fn rehearsal(section: &serde_json::Value) -> Option<Verdict> {
    let number = |value: &serde_json::Value| value.as_f64();
    let text = |value: &serde_json::Value| value.as_str().map(str::to_owned);
    let arrivals = section["arrivals"]
        .as_array()?
        .iter()
        .map(|arrival| {
            Some(ArrivalJudgement {
                leg: text(&arrival["leg"])?,
                waypoint: text(&arrival["waypoint"])?,
                arrived_secs: number(&arrival["arrived_secs"])?,
                true_error_m: number(&arrival["true_error_m"]),
                truth_secs: number(&arrival["truth_secs"]),
                allowed_m: number(&arrival["allowed_m"])?,
                ok: arrival["ok"].as_bool()?,
            })
        })
        .collect::<Option<Vec<_>>>()?;
    let areas = section["no_go_areas"]
        .as_array()?
        .iter()
        .map(|area| {
            Some(AreaJudgement {
                area: text(&area["area"])?,
                least_distance_m: number(&area["least_distance_m"]),
                least_secs: number(&area["least_secs"]),
                first_met_secs: number(&area["first_met_secs"]),
                poses_met: usize::try_from(area["poses_met"].as_u64()?).ok()?,
                ok: area["ok"].as_bool()?,
            })
        })
        .collect::<Option<Vec<_>>>()?;
    Some(Verdict {
        passed: section["passed"].as_bool()?,
        true_poses: usize::try_from(section["true_poses"].as_u64()?).ok()?,
        robot_radius_m: number(&section["robot_radius_m"])?,
        tolerance_m: number(&section["tolerance_m"])?,
        allowed_m: number(&section["allowed_m"])?,
        arrivals,
        areas,
        failures: section["failures"]
            .as_array()?
            .iter()
            .map(text)
            .collect::<Option<Vec<_>>>()?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A run's control interface (the real one) whose requests a stand-in for the run records
    /// and answers `ok`, the first answer only after `first_delay` (a slow or lost link).
    fn fake_control(first_delay: Duration) -> (SocketAddr, Receiver<serde_json::Value>) {
        let (incoming, run) = mpsc::channel::<armor_runtime::control::Incoming>();
        let addr =
            armor_runtime::control::serve(SocketAddr::from(([127, 0, 0, 1], 0)), incoming, None)
                .expect("serve");
        let (seen, requests) = mpsc::channel();
        std::thread::spawn(move || {
            let mut delay = Some(first_delay);
            for (request, reply) in run {
                let _ = seen.send(serde_json::to_value(&request).expect("a request"));
                if let Some(delay) = delay.take() {
                    std::thread::sleep(delay);
                }
                let _ = reply.send(armor_protocol::Reply {
                    ok: true,
                    message: "ok".to_owned(),
                    status: None,
                    files: None,
                });
            }
        });
        (addr, requests)
    }

    #[test]
    fn driving_commands_that_waited_behind_a_slow_link_are_dropped_not_replayed() {
        let (addr, requests) = fake_control(Duration::from_millis(1200));
        let shared: SharedRef = Arc::default();
        lock(&shared).control_addr = Some(addr);
        let stop = Arc::new(AtomicBool::new(false));
        let (commands, commands_rx) = mpsc::channel();
        {
            let shared = Arc::clone(&shared);
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || drive(&commands_rx, &shared, &stop, None));
        }
        let linear = |request: serde_json::Value| request["linear"].as_f64();
        commands.send((0.1, 0.0, Instant::now())).expect("send");
        let first = requests
            .recv_timeout(Duration::from_secs(5))
            .expect("first");
        assert_eq!(first["command"], "teleop");
        assert_eq!(linear(first), Some(0.1));
        // While the link holds the first answer, the operator goes on driving, then lets go.
        for speed in [0.2, 0.3, 0.4] {
            commands.send((speed, 0.0, Instant::now())).expect("send");
            std::thread::sleep(Duration::from_millis(20));
        }
        // Once it answers, none of those is sent late; the next fresh command is.
        std::thread::sleep(Duration::from_millis(1500));
        commands.send((0.5, 0.0, Instant::now())).expect("send");
        let next = requests.recv_timeout(Duration::from_secs(5)).expect("next");
        assert_eq!(linear(next), Some(0.5), "a stale command was replayed");
        assert!(requests.try_recv().is_err());
        stop.store(true, Ordering::Relaxed);
    }

    #[test]
    fn the_reports_rehearsal_reads_back_as_the_verdict_it_was_written_from() {
        use armor_model::geo::{Point, Polygon};
        use armor_model::rehearsal::{Arrival, NoGoArea, Rules, TruePose, judge};
        let poses: Vec<TruePose> = (0..=20)
            .map(|i| TruePose {
                at_secs: f64::from(i),
                at: Point::new(f64::from(i) * 0.5, 2.0),
            })
            .collect();
        let arrivals = [
            Arrival {
                leg: "advance".into(),
                waypoint: "gate".into(),
                target: Point::new(10.0, 0.0),
                at_secs: 20.0,
            },
            Arrival {
                leg: "back".into(),
                waypoint: "home".into(),
                target: Point::new(0.0, 0.0),
                at_secs: 400.0,
            },
        ];
        let area = NoGoArea {
            name: "spill".into(),
            polygon: Polygon::new(vec![
                Point::new(4.0, 1.5),
                Point::new(6.0, 1.5),
                Point::new(6.0, 3.0),
                Point::new(4.0, 3.0),
            ]),
        };
        let rules = Rules {
            radius_m: 0.3,
            tolerance_m: 0.3,
        };
        let verdict = judge(&poses, &arrivals, &[area], rules);
        assert!(
            !verdict.passed && verdict.failures.len() >= 2,
            "{verdict:#?}"
        );
        let report = armor_runtime::rehearsal::report(&verdict, "sim.pose_truth");
        let text = serde_json::to_string(&report).unwrap_or_default();
        let back = rehearsal(&serde_json::from_str(&text).unwrap_or_default());
        assert_eq!(back, Some(verdict));
        assert_eq!(rehearsal(&serde_json::json!({"passed": true})), None);
        assert_eq!(rehearsal(&serde_json::Value::Null), None);
    }

    #[test]
    fn timestamps_are_taken_off_log_lines() {
        assert_eq!(
            strip_timestamp("2026-11-23T06:40:00.123456Z  INFO armor: fired `go`"),
            "INFO armor: fired `go`"
        );
        assert_eq!(strip_timestamp("counted 10"), "counted 10");
    }

    #[test]
    fn a_long_line_is_cut_and_bytes_that_are_not_text_do_not_stop_the_log() {
        let mut output = b"short\r\n".to_vec();
        output.extend(std::iter::repeat_n(b'x', 100_000));
        output.extend(b"\n\xFF\xFEbad\nlast without end");
        // Read in pieces of 7 bytes, as a pipe may give them.
        let mut reader = BufReader::with_capacity(7, output.as_slice());
        let mut line = Vec::new();
        let mut lines = Vec::new();
        while read_line_bounded(&mut reader, &mut line, 16).expect("a slice reads") {
            lines.push(String::from_utf8_lossy(&line).into_owned());
        }
        assert_eq!(
            lines,
            [
                "short",
                "xxxxxxxxxxxxxxxx",
                "\u{FFFD}\u{FFFD}bad",
                "last without end"
            ]
        );
    }
}
