//! Child processes: finding their binaries, and a guard that never leaves one behind.

use std::collections::VecDeque;
use std::io::{BufRead as _, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow, bail};
use armor_module_api::{ENV_MODULE, ENV_SUPERVISOR};
use armor_runtime::probe;

use crate::Settings;
use armor_bench_report::Report;

/// Stderr lines kept to explain a child's failure.
const TAIL_LINES: usize = 20;
/// How long a graceful guard waits after SIGTERM before SIGKILL.
const DROP_GRACE: Duration = Duration::from_secs(3);

/// A module binary from the module path (`$ARMOR_MODULE_PATH`, else this executable's folder).
pub fn module_binary(module_type: &str) -> anyhow::Result<PathBuf> {
    let path = probe::module_path();
    probe::find_module(&path, module_type).ok_or_else(|| {
        anyhow!(
            "no {}{module_type} in {}: build the whole workspace first \
             (cargo build --release --workspace)",
            probe::BINARY_PREFIX,
            path.iter()
                .map(|dir| dir.display().to_string())
                .collect::<Vec<_>>()
                .join(":")
        )
    })
}

/// A module process run by hand (standalone, on the agent at `--agent`).
pub fn module_command(module_type: &str, args: &[&str]) -> anyhow::Result<Command> {
    let mut command = Command::new(module_binary(module_type)?);
    command
        .args(args)
        .env_remove(ENV_SUPERVISOR)
        .env_remove(ENV_MODULE);
    Ok(command)
}

/// `armor-mod-echo` named `echo`, its input bound to the bench node's output `ping`, with the
/// key `security` gives it.
pub fn spawn_echo(agent: &str, security: &crate::harness::Security) -> anyhow::Result<ChildGuard> {
    let mut command = module_command(
        "echo",
        &[
            "--name",
            "echo",
            "--agent",
            agent,
            "--bind",
            "input=bench.ping",
        ],
    )?;
    security.module_env(&mut command, "echo")?;
    ChildGuard::spawn("armor-mod-echo", command)
}

/// A binary next to this executable (`armor` next to `armor-bench`).
pub fn sibling_binary(name: &str) -> anyhow::Result<PathBuf> {
    let exe = std::env::current_exe().context("cannot locate this executable")?;
    let binary = exe.with_file_name(name);
    if !binary.is_file() {
        bail!(
            "no {} next to {}: build the whole workspace first (cargo build --release --workspace)",
            name,
            exe.display()
        );
    }
    Ok(binary)
}

/// This very executable, to run it in a hidden reference mode.
pub fn self_command() -> anyhow::Result<Command> {
    Ok(Command::new(
        std::env::current_exe().context("cannot locate this executable")?,
    ))
}

/// A child process that is killed when the guard is dropped (on success, error or panic), or by
/// the kernel if this process dies without dropping it (`PR_SET_PDEATHSIG`). Its
/// stderr is read on a thread: every line is sent to [`ChildGuard::take_lines`] and the last ones are
/// kept to explain a failure. Its stdout, when captured ([`ChildGuard::spawn_capturing_stdout`]),
/// is read on another thread and sent to [`ChildGuard::take_stdout_lines`].
pub struct ChildGuard {
    name: String,
    child: Child,
    exited: Option<ExitStatus>,
    lines: Option<Receiver<String>>,
    stdout_lines: Option<Receiver<String>>,
    tail: Arc<Mutex<VecDeque<String>>>,
    reader: Option<JoinHandle<()>>,
    graceful: bool,
}

impl ChildGuard {
    /// Starts `command` with stdin and stdout closed and stderr captured.
    pub fn spawn(name: &str, command: Command) -> anyhow::Result<Self> {
        Self::spawn_with(name, command, false)
    }

    /// Like [`ChildGuard::spawn`], with stdout captured too, line by line.
    pub fn spawn_capturing_stdout(name: &str, command: Command) -> anyhow::Result<Self> {
        Self::spawn_with(name, command, true)
    }

    fn spawn_with(name: &str, mut command: Command, capture_stdout: bool) -> anyhow::Result<Self> {
        // A module handed its key reads it on stdin (`Security::module_env`).
        let keyed = command
            .get_envs()
            .any(|(var, value)| var == armor_module_api::auth::ENV_KEY_FD && value.is_some());
        if !keyed {
            command.stdin(Stdio::null());
        }
        command
            .stdout(if capture_stdout {
                Stdio::piped()
            } else {
                Stdio::null()
            })
            .stderr(Stdio::piped());
        armor_runtime::process::die_with_parent(&mut command);
        let mut child = command
            .spawn()
            .with_context(|| format!("cannot start {name} ({:?})", command.get_program()))?;
        let tail = Arc::new(Mutex::new(VecDeque::new()));
        let (sender, receiver) = mpsc::channel();
        let reader = child.stderr.take().map(|stderr| {
            let tail = Arc::clone(&tail);
            std::thread::spawn(move || {
                for line in BufReader::new(stderr).lines() {
                    let Ok(line) = line else { break };
                    {
                        let mut tail = tail.lock().unwrap_or_else(PoisonError::into_inner);
                        if tail.len() == TAIL_LINES {
                            tail.pop_front();
                        }
                        tail.push_back(line.clone());
                    }
                    // Nobody listening is fine: the tail still has the line.
                    let _ = sender.send(line);
                }
            })
        });
        let mut guard = Self::new(name, child, Some(receiver), tail, reader);
        if let Some(stdout) = guard.child.stdout.take() {
            let (sender, receiver) = mpsc::channel();
            // Ends with the pipe, and keeps draining it when nobody listens any more, so that
            // the child never blocks on a full pipe.
            std::thread::spawn(move || {
                for line in BufReader::new(stdout).lines() {
                    let Ok(line) = line else { break };
                    let _ = sender.send(line);
                }
            });
            guard.stdout_lines = Some(receiver);
        }
        Ok(guard)
    }

    /// Starts a short-lived `command` with no pipes and no death signal: nothing between it and
    /// the clock (a `pre_exec` hook would make std fork instead of posix_spawn). Only the guard
    /// kills it.
    pub fn spawn_quiet(name: &str, mut command: Command) -> anyhow::Result<Self> {
        command
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        let child = command
            .spawn()
            .with_context(|| format!("cannot start {name} ({:?})", command.get_program()))?;
        Ok(Self::new(name, child, None, Arc::default(), None))
    }

    fn new(
        name: &str,
        child: Child,
        lines: Option<Receiver<String>>,
        tail: Arc<Mutex<VecDeque<String>>>,
        reader: Option<JoinHandle<()>>,
    ) -> Self {
        Self {
            name: name.to_owned(),
            child,
            exited: None,
            lines,
            stdout_lines: None,
            tail,
            reader,
            graceful: false,
        }
    }

    /// On drop, SIGTERM first and SIGKILL only if it does not stop (for `armor run`, which
    /// then stops its own children in order).
    pub fn graceful(mut self) -> Self {
        self.graceful = true;
        self
    }

    /// The child's stderr, line by line (for a child started with [`ChildGuard::spawn`]; once).
    pub fn take_lines(&mut self) -> Option<Receiver<String>> {
        self.lines.take()
    }

    /// The child's stdout, line by line (for a child started with
    /// [`ChildGuard::spawn_capturing_stdout`]; once).
    pub fn take_stdout_lines(&mut self) -> Option<Receiver<String>> {
        self.stdout_lines.take()
    }

    /// Whether the child has exited (and how), without waiting.
    pub fn try_exited(&mut self) -> anyhow::Result<Option<ExitStatus>> {
        if self.exited.is_none() {
            self.exited = self
                .child
                .try_wait()
                .with_context(|| format!("cannot wait for {}", self.name))?;
        }
        Ok(self.exited)
    }

    /// An error if the child has exited: it was meant to keep running.
    pub fn check_alive(&mut self) -> anyhow::Result<()> {
        match self.try_exited()? {
            None => Ok(()),
            Some(status) => Err(self.failure(&format!("exited early ({status})"))),
        }
    }

    /// Waits for the child to exit on its own, at most `timeout`.
    pub fn wait_exit(&mut self, timeout: Duration) -> anyhow::Result<ExitStatus> {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.try_exited()? {
                return Ok(status);
            }
            if Instant::now() >= deadline {
                return Err(self.failure(&format!("still running after {timeout:?}")));
            }
            // Fine-grained: the start-up reference times short-lived children with this.
            std::thread::sleep(Duration::from_micros(200));
        }
    }

    /// Sends SIGTERM and waits for the child to exit, at most `timeout`.
    pub fn terminate(&mut self, timeout: Duration) -> anyhow::Result<ExitStatus> {
        if self.try_exited()?.is_none()
            && let Ok(pid) = libc::pid_t::try_from(self.child.id())
        {
            armor_runtime::process::kill(pid, libc::SIGTERM);
        }
        self.wait_exit(timeout)
    }

    /// Waits at most `timeout` for a line from `lines` (the child's, from
    /// [`ChildGuard::take_lines`] or [`ChildGuard::take_stdout_lines`]) that `pick` turns into a
    /// value; `what` names it in the error. Fails at once if the child exits.
    pub fn wait_line<T>(
        &mut self,
        lines: &Receiver<String>,
        what: &str,
        timeout: Duration,
        mut pick: impl FnMut(&str) -> Option<T>,
    ) -> anyhow::Result<T> {
        let give_up = Instant::now() + timeout;
        loop {
            match lines.recv_timeout(Duration::from_millis(50)) {
                Ok(line) => {
                    if let Some(value) = pick(&line) {
                        return Ok(value);
                    }
                }
                Err(RecvTimeoutError::Timeout) => {
                    self.check_alive()?;
                    if Instant::now() >= give_up {
                        return Err(self.failure(&format!("did not log {what} within {timeout:?}")));
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    self.check_alive()?;
                    return Err(self.failure("closed its output"));
                }
            }
        }
    }

    /// Its process id.
    pub fn id(&self) -> u32 {
        self.child.id()
    }

    /// Its stderr and captured stdout as one stream of lines (`armor run` logs on stderr, its
    /// modules' lines come on stdout), in the order they are read.
    pub fn merged_lines(&mut self) -> anyhow::Result<Receiver<String>> {
        let (Some(stderr), Some(stdout)) = (self.take_lines(), self.take_stdout_lines()) else {
            anyhow::bail!("{}: no output to read", self.name);
        };
        let (merged, lines) = std::sync::mpsc::channel();
        for source in [stderr, stdout] {
            let merged = merged.clone();
            std::thread::spawn(move || {
                for line in source {
                    if merged.send(line).is_err() {
                        return;
                    }
                }
            });
        }
        Ok(lines)
    }

    /// Sends SIGTERM and expects the child to exit well within `timeout`.
    pub fn stop(&mut self, timeout: Duration) -> anyhow::Result<()> {
        let status = self.terminate(timeout)?;
        if status.success() {
            Ok(())
        } else {
            Err(self.failure(&format!("stopped badly after SIGTERM ({status})")))
        }
    }

    /// An error naming the child, with the last lines of its stderr.
    pub fn failure(&mut self, what: &str) -> anyhow::Error {
        // Give the reader a moment to collect what a dying child wrote last.
        if let Some(reader) = &self.reader {
            let deadline = Instant::now() + Duration::from_millis(200);
            while !reader.is_finished() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        let tail = self.tail.lock().unwrap_or_else(PoisonError::into_inner);
        if tail.is_empty() {
            anyhow!("{} {what}", self.name)
        } else {
            let lines: Vec<String> = tail.iter().map(|line| format!("  | {line}")).collect();
            anyhow!(
                "{} {what}; its last stderr lines:\n{}",
                self.name,
                lines.join("\n")
            )
        }
    }
}

impl Drop for ChildGuard {
    fn drop(&mut self) {
        if matches!(self.try_exited(), Ok(Some(_))) {
            return;
        }
        if self.graceful && self.terminate(DROP_GRACE).is_ok() {
            return;
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs the sibling binary `program ARGS… NAME [--quick]` and takes its line for `name` as a
/// report of its own: the figures measured where `armor-bench` must not link the code (egui,
/// zenoh).
pub fn relay(
    program: &str,
    args: &[&str],
    name: &'static str,
    unit: &'static str,
    settings: &Settings,
) -> anyhow::Result<Report> {
    let program = sibling_binary(program)?;
    let mut command = Command::new(&program);
    command.args(args).arg(name);
    if settings.quick {
        command.arg("--quick");
    }
    let output = command
        .output()
        .with_context(|| format!("cannot run {}", program.display()))?;
    anyhow::ensure!(
        output.status.success(),
        "{} {name} failed ({}): {}",
        program.display(),
        output.status,
        String::from_utf8_lossy(&output.stderr).trim()
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    let line = stdout
        .lines()
        .find(|line| line.contains(&format!("\"{name}\"")))
        .with_context(|| format!("{} printed no `{name}` line: {stdout}", program.display()))?;
    let mut fields: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(line).with_context(|| format!("not a report line: {line}"))?;
    // A line that could not run here says why (`armor-team bench` without root): relayed as
    // it is, with no figures.
    if let Some(why) = fields.get("skipped").and_then(serde_json::Value::as_str) {
        return Ok(Report::single(name, unit, f64::NAN, f64::NAN).with("skipped", why));
    }
    let number = |key: &str| fields.get(key).and_then(serde_json::Value::as_f64);
    let (Some(ours), Some(reference)) = (number("ours"), number("reference")) else {
        anyhow::bail!("`ours` or `reference` missing from {line}");
    };
    let mut report = Report::single(name, unit, ours, reference);
    report.p50 = number("p50");
    report.p99 = number("p99");
    report.reference_p50 = number("reference_p50");
    report.reference_p99 = number("reference_p99");
    for key in [
        "bench",
        "ours",
        "reference",
        "unit",
        "ratio",
        "p50",
        "p99",
        "reference_p50",
        "reference_p99",
    ] {
        fields.remove(key);
    }
    for (key, value) in fields {
        report = report.with(&key, value);
    }
    Ok(report)
}
