//! Support for the end-to-end suites in `tests/tests/`: find the workspace's binaries, start real
//! processes whose output is captured line by line, wait for a line with a deadline (never a bare
//! sleep), and kill every process a test started when it ends, even if it fails. [`mission`]
//! runs a mission or plan headless and reads its report; [`mcap`] reads what a recorder wrote;
//! [`check`] runs the one-shot commands (`armor check`, `armor compile`) and reads their errors;
//! [`tools`] finds the programs and Python modules from outside that the suites run; [`truth`]
//! reads the simulator's truth from a recording; [`rehearsal`] writes plans whose rehearsal
//! the truth judges.
#![allow(clippy::unwrap_used)]

pub mod check;
pub mod mcap;
pub mod mission;
pub mod rehearsal;
pub mod tools;
pub mod truth;

use std::io::{BufRead as _, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::{Duration, Instant};

/// Generous deadline for things that normally take milliseconds (CI machines are shared).
pub const PATIENCE: Duration = Duration::from_secs(20);

/// The folder of the workspace's binaries (`target/debug`), found from this test executable.
pub fn bin_dir() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable path");
    // target/debug/deps/suite-HASH → target/debug
    exe.parent()
        .and_then(Path::parent)
        .expect("test executable lives in target/<profile>/deps")
        .to_path_buf()
}

/// A binary of the workspace. `cargo test --workspace` builds them all before running tests.
pub fn bin(name: &str) -> PathBuf {
    let path = bin_dir().join(name);
    assert!(
        path.exists(),
        "{} is not built: run the suite with `cargo test --workspace`",
        path.display()
    );
    path
}

/// The root of the workspace (for `missions/`, `assets/`).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ is inside the workspace")
        .to_path_buf()
}

#[derive(Default)]
struct Output {
    lines: Vec<String>,
    closed_pipes: usize,
}

/// Where the runs of the tests make their folders: `target/tmp/test-runs`.
pub fn test_runs_dir() -> PathBuf {
    workspace_root().join("target/tmp/test-runs")
}

/// A running process whose stdout and stderr lines are collected. Killed (SIGKILL) on drop.
pub struct Proc {
    name: String,
    child: Child,
    output: Arc<(Mutex<Output>, Condvar)>,
}

impl Proc {
    /// Hands a module started by `command` the key `key` as `armor run` does: over a pipe on
    /// its stdin, named by `ARMOR_KEY_FD`.
    pub fn with_key<'a>(
        command: &'a mut Command,
        key: &armor_module_api::auth::Key,
    ) -> &'a mut Command {
        armor_runtime::process::hand_over(command, &key.to_hex()).expect("a pipe");
        command
    }

    pub fn start(command: &mut Command) -> Proc {
        let name = command.get_program().to_string_lossy().into_owned();
        // Runs make their folders under the build's own temporary folder, not in the
        // workspace, unless the test names another.
        if !command
            .get_envs()
            .any(|(key, _)| key == armor_runtime::run_dir::ENV_RUNS_DIR)
        {
            command.env(armor_runtime::run_dir::ENV_RUNS_DIR, test_runs_dir());
        }
        // A module handed its key (`with_key`) reads it on stdin.
        if !command
            .get_envs()
            .any(|(key, value)| key == armor_module_api::auth::ENV_KEY_FD && value.is_some())
        {
            command.stdin(Stdio::null());
        }
        let mut child = command
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|err| panic!("cannot start {name}: {err}"));
        let output = Arc::new((Mutex::new(Output::default()), Condvar::new()));
        collect(child.stdout.take().unwrap(), Arc::clone(&output));
        collect(child.stderr.take().unwrap(), Arc::clone(&output));
        Proc {
            name,
            child,
            output,
        }
    }

    pub fn pid(&self) -> i32 {
        self.child.id() as i32
    }

    /// Every line so far, stdout and stderr interleaved as they arrived.
    pub fn lines(&self) -> Vec<String> {
        self.output.0.lock().unwrap().lines.clone()
    }

    /// Waits until a line satisfies `pred` and returns it; panics with the output so far if none
    /// does within `timeout` or the process closes its output first.
    pub fn wait_for(&self, what: &str, timeout: Duration, pred: impl Fn(&str) -> bool) -> String {
        self.wait_for_from(0, what, timeout, pred)
    }

    /// Like [`Proc::wait_for`], looking only at lines after the first `skip`.
    pub fn wait_for_from(
        &self,
        skip: usize,
        what: &str,
        timeout: Duration,
        pred: impl Fn(&str) -> bool,
    ) -> String {
        let deadline = Instant::now() + timeout;
        let (lock, changed) = &*self.output;
        let mut output = lock.lock().unwrap();
        loop {
            if let Some(line) = output.lines.iter().skip(skip).find(|line| pred(line)) {
                return line.clone();
            }
            let now = Instant::now();
            if now >= deadline || output.closed_pipes == 2 {
                let seen = output.lines.join("\n");
                drop(output);
                panic!(
                    "{}: no line {what} within {timeout:?}; output:\n{seen}",
                    self.name
                );
            }
            output = changed.wait_timeout(output, deadline - now).unwrap().0;
        }
    }

    /// Number of lines so far (to wait only for what comes after).
    pub fn line_count(&self) -> usize {
        self.output.0.lock().unwrap().lines.len()
    }

    pub fn signal(&self, signal: i32) {
        self::signal(self.pid(), signal);
    }

    /// Waits for the process to exit, at most `timeout`; returns its exit status.
    pub fn wait_exit(&mut self, timeout: Duration) -> std::process::ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                self.wait_for_pipes(deadline);
                return status;
            }
            assert!(
                Instant::now() < deadline,
                "{} did not exit within {timeout:?}; output:\n{}",
                self.name,
                self.lines().join("\n")
            );
            // Waiting on a child has no notification in std; poll it finely.
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Proc {
    /// Waits until the reader threads have seen both pipes close (or `deadline`), so that
    /// [`Proc::lines`] holds everything an exited process wrote. Children that kept the pipes
    /// open (a module outliving its supervisor would) make this give up at the deadline.
    fn wait_for_pipes(&self, deadline: Instant) {
        let (lock, changed) = &*self.output;
        let mut output = lock.lock().unwrap_or_else(PoisonError::into_inner);
        while output.closed_pipes < 2 {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return;
            }
            output = changed
                .wait_timeout(output, left)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn collect(pipe: impl Read + Send + 'static, output: Arc<(Mutex<Output>, Condvar)>) {
    std::thread::spawn(move || {
        let mut reader = BufReader::new(pipe);
        let mut line = Vec::new();
        loop {
            line.clear();
            let done = !matches!(reader.read_until(b'\n', &mut line), Ok(n) if n > 0);
            let (lock, changed) = &*output;
            let mut output = lock.lock().unwrap_or_else(PoisonError::into_inner);
            if done {
                output.closed_pipes += 1;
            } else {
                output
                    .lines
                    .push(String::from_utf8_lossy(&line).trim_end().to_owned());
            }
            changed.notify_all();
            if done {
                return;
            }
        }
    });
}

/// A node in this test process, standalone with the agent at `agent`, named after its module
/// type, its inputs bound as `binds` says (`input`, `module.output`).
pub fn test_node(
    spec: armor_module_api::ModuleSpec,
    agent: std::net::SocketAddr,
    binds: &[(&str, &str)],
) -> armor_module_api::Node {
    let name = spec.description().module_type.clone();
    armor_module_api::Node::connect(
        spec,
        armor_module_api::Standalone {
            name: Some(name),
            agent: Some(agent.to_string()),
            binds: binds
                .iter()
                .map(|(input, source)| ((*input).to_owned(), (*source).to_owned()))
                .collect(),
            ..armor_module_api::Standalone::default()
        },
    )
    .unwrap()
}

/// `armor agent` on a free loopback port, and its address (read from its first line).
pub fn start_agent() -> (Proc, std::net::SocketAddr) {
    start_agent_with(&[])
}

/// [`start_agent`] with more arguments (`--secret FILE`).
pub fn start_agent_with(args: &[&str]) -> (Proc, std::net::SocketAddr) {
    const READY: &str = "armor agent listening on ";
    let agent = Proc::start(
        Command::new(bin("armor"))
            .args(["agent", "--listen", "127.0.0.1:0"])
            .args(args),
    );
    let line = agent.wait_for("with the agent's address", PATIENCE, |line| {
        line.starts_with(READY)
    });
    let addr = line
        .trim_start_matches(READY)
        .parse()
        .unwrap_or_else(|err| panic!("the agent's address in `{line}`: {err}"));
    (agent, addr)
}

/// Sends a signal to a process (through the `kill` command: the workspace denies unsafe code).
pub fn signal(pid: i32, signal: i32) {
    let status = Command::new(tools::program("kill"))
        .arg(format!("-{signal}"))
        .arg(pid.to_string())
        .status()
        .expect("kill command");
    assert!(status.success(), "kill -{signal} {pid} failed");
}

/// Whether a process exists (and is not a zombie).
pub fn process_alive(pid: i32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).is_ok_and(|stat| {
        !stat
            .rsplit(')')
            .next()
            .unwrap_or("")
            .trim_start()
            .starts_with('Z')
    })
}

/// The control address a run prints once its control interface listens
/// (`armor_runtime::CONTROL_READY_PREFIX`).
pub fn control_address(run: &Proc) -> String {
    let line = run.wait_for("the control address", loaded(PATIENCE), |line| {
        line.starts_with(armor_runtime::CONTROL_READY_PREFIX)
    });
    line.trim_start_matches(armor_runtime::CONTROL_READY_PREFIX)
        .trim()
        .to_owned()
}

/// `armor run FILE --no-run-folder` with this build's modules, as in a terminal of its own, and
/// its control address.
pub fn run_with_control(file: &Path) -> (Proc, String) {
    let run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(file)
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let addr = control_address(&run);
    (run, addr)
}

/// A system in `dir` of the simulated robot on the yard and a teleop module `pad` that alone
/// commands it.
pub fn driven_system(dir: &Path) -> PathBuf {
    let world = workspace_root().join("assets/worlds/yard.world");
    let file = dir.join("driven.xml");
    std::fs::write(
        &file,
        format!(
            r#"<system name="driven">
  <module name="sim" type="sim"><param name="world" value="{}"/></module>
  <module name="pad" type="teleop"/>
  <link from="pad.cmd_vel" to="sim.cmd_vel"/>
</system>
"#,
            world.display()
        ),
    )
    .unwrap_or_else(|err| panic!("cannot write {}: {err}", file.display()));
    file
}

/// `armor ctl --addr ADDR ARGS…`: whether it succeeded, and what it printed.
pub fn ctl(addr: &str, args: &[&str]) -> (bool, String) {
    let output = Command::new(bin("armor"))
        .args(["ctl", "--addr", addr])
        .args(args)
        .output()
        .unwrap_or_else(|err| panic!("cannot run armor ctl: {err}"));
    (
        output.status.success(),
        String::from_utf8_lossy(&output.stdout).into_owned(),
    )
}

/// The run's status as `armor ctl status --json` prints it (after the reply's message line).
pub fn ctl_status(addr: &str) -> serde_json::Value {
    let (ok, text) = ctl(addr, &["status", "--json"]);
    assert!(ok, "{text}");
    let json = text.find('{').map_or("", |start| &text[start..]);
    serde_json::from_str(json).unwrap_or_else(|err| panic!("{err}: {text}"))
}

/// A connection to `addr` (the agent, a module's data port) as `identity`, proving `key`, not
/// asking for encryption.
pub fn dial_as(
    addr: std::net::SocketAddr,
    key: armor_module_api::auth::Key,
    identity: &str,
) -> Result<armor_module_api::wire::blocking::SecureStream, armor_module_api::wire::WireError> {
    let stream = std::net::TcpStream::connect(addr)?;
    stream.set_read_timeout(Some(PATIENCE))?;
    armor_module_api::wire::blocking::dial(
        stream,
        Some(&armor_module_api::auth::Dial {
            key,
            identity: identity.into(),
            encrypt: false,
        }),
    )
}

/// The most [`machine_slowness`] ever counts for: a deadline stretches at most this many times.
pub const MAX_SLOWNESS: f64 = 15.0;

/// How many times slower than on an idle machine the tests' processes may run now: the load
/// average of the last minute per core, at least 1, at most [`MAX_SLOWNESS`] (1 where the
/// kernel does not say). A run driven in real time at a load of 25 on two cores got its scans
/// late enough that fixed deadlines of 30 s failed.
pub fn machine_slowness() -> f64 {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as f64;
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|text| text.split_whitespace().next()?.parse::<f64>().ok())
        .unwrap_or(0.0);
    (load / cores).clamp(1.0, MAX_SLOWNESS)
}

/// `base` stretched by the machine's slowness now ([`machine_slowness`]).
pub fn loaded(base: Duration) -> Duration {
    base.mul_f64(machine_slowness())
}

/// Waits until `condition` holds, at most `base` on an idle machine: the deadline stretches
/// with the greatest [`machine_slowness`] seen while waiting, so that a loaded machine slows a
/// test down without failing it, and an idle one still fails it in `base`.
pub fn wait_until_loaded(what: &str, base: Duration, mut condition: impl FnMut() -> bool) {
    let start = Instant::now();
    let mut slowness = machine_slowness();
    while !condition() {
        slowness = slowness.max(machine_slowness());
        let allowed = base.mul_f64(slowness);
        assert!(
            start.elapsed() < allowed,
            "{what}: not within {allowed:?} ({base:?} on an idle machine, the load per core \
             reaching {slowness:.1})"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// The run's status as `armor ctl status --json` prints it, or `None` when the run gave no
/// answer in time (a loaded machine: ask again) or none that reads.
pub fn try_ctl_status(addr: &str) -> Option<serde_json::Value> {
    let (ok, text) = ctl(addr, &["status", "--json"]);
    let json = text.find('{').map(|start| &text[start..])?;
    ok.then(|| serde_json::from_str(json).ok()).flatten()
}

/// Waits until `condition` holds, checking every few milliseconds, at most `timeout`.
pub fn wait_until(what: &str, timeout: Duration, mut condition: impl FnMut() -> bool) {
    let deadline = Instant::now() + timeout;
    while !condition() {
        assert!(Instant::now() < deadline, "{what}: not within {timeout:?}");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Pids of the processes whose parent is `pid`.
pub fn children_of(pid: i32) -> Vec<i32> {
    let Ok(entries) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    entries
        .filter_map(Result::ok)
        .filter_map(|entry| entry.file_name().to_str()?.parse::<i32>().ok())
        .filter(|&child| {
            std::fs::read_to_string(format!("/proc/{child}/stat")).is_ok_and(|stat| {
                stat.rsplit(')')
                    .next()
                    .and_then(|rest| rest.split_whitespace().nth(1))
                    .and_then(|ppid| ppid.parse::<i32>().ok())
                    == Some(pid)
            })
        })
        .collect()
}

/// A `name=value` field of a log line (`pid=1234`, `module="counter"`), without quotes.
pub fn field<'a>(line: &'a str, name: &str) -> Option<&'a str> {
    line.split_whitespace()
        .find_map(|word| word.strip_prefix(name)?.strip_prefix('='))
        .map(|value| value.trim_matches('"'))
}

/// A secret file in `dir` (32 bytes, readable by its owner only), for runs with `--secret`.
pub fn secret_file(dir: &Path) -> PathBuf {
    use std::os::unix::fs::PermissionsExt as _;
    let file = dir.join("secret");
    std::fs::write(&file, "a secret of thirty-two bytes, ok").unwrap();
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
    file
}

/// `armor secret derive --role ROLE --secret SECRET -o DIR/ROLE.key`: the role's key file.
pub fn role_key(secret: &Path, role: &str) -> PathBuf {
    let key = secret.with_file_name(format!("{role}.key"));
    let output = Command::new(bin("armor"))
        .args(["secret", "derive", "--role", role, "--secret"])
        .arg(secret)
        .arg("-o")
        .arg(&key)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    key
}

/// A mission in `dir` that waits an hour in its one place, running one counter: a run that stays
/// up until the test ends it (`armor ctl abort`).
pub fn waiting_mission(dir: &Path) -> PathBuf {
    std::fs::write(
        dir.join("system.xml"),
        r#"<system name="held">
  <module name="counter" type="counter"><param name="period_secs" value="0.1"/></module>
</system>
"#,
    )
    .unwrap();
    let mission = dir.join("mission.xml");
    std::fs::write(
        &mission,
        r#"<mission name="long" system="system.xml">
  <place name="counting" tokens="1"><module name="counter"/></place>
  <place name="done" final="true"/>
  <transition name="later" delay_secs="3600"><input place="counting"/><output place="done"/></transition>
</mission>
"#,
    )
    .unwrap();
    mission
}

/// A relay that delays every byte by `one_way` in each direction, as a slow radio link does
/// (there is no `tc netem` here): each direction's chunks are read at once and written when
/// their time has come.
pub fn slow_relay(target: std::net::SocketAddr, one_way: Duration) -> std::net::SocketAddr {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    std::thread::spawn(move || {
        for client in listener.incoming().flatten() {
            let Ok(server) = std::net::TcpStream::connect(target) else {
                continue;
            };
            let pump = |mut from: std::net::TcpStream, mut to: std::net::TcpStream| {
                let (chunks, delayed) = std::sync::mpsc::channel::<(Instant, Vec<u8>)>();
                std::thread::spawn(move || {
                    let mut buf = [0; 65536];
                    while let Ok(n @ 1..) = from.read(&mut buf) {
                        if chunks
                            .send((Instant::now() + one_way, buf[..n].to_vec()))
                            .is_err()
                        {
                            break;
                        }
                    }
                });
                std::thread::spawn(move || {
                    for (due, chunk) in delayed {
                        // The link's delay itself, not a wait for something to happen.
                        std::thread::sleep(due.saturating_duration_since(Instant::now()));
                        if std::io::Write::write_all(&mut to, &chunk).is_err() {
                            break;
                        }
                    }
                    let _ = to.shutdown(std::net::Shutdown::Both);
                });
            };
            pump(client.try_clone().unwrap(), server.try_clone().unwrap());
            pump(server, client);
        }
    });
    addr
}
