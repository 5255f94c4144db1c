//! `fallback_switch_ms` and `health_broadcast_ms`: the run's health stream and fallback sources
//! under `armor run`, faults injected with signals.
//!
//! - `fallback_switch_ms`: a `watch` checker takes `primary.count`, with `backup.count` as its
//!   fallback (both counters at 500 Hz). The primary is SIGKILLed (then, in a second series,
//!   SIGSTOPped); measured from the signal to the checker's `restarted` event, which it reports
//!   on its first value over a new link: here, the first from the fallback. The bench waits for
//!   the switch back to the restarted primary before the next fault. Reference for SIGKILL:
//!   from the SIGKILL of a process to the EOF on a TCP connection to it, the floor of noticing
//!   a death; for SIGSTOP: the lease, before which a stopped module cannot be told from a slow
//!   one (goals: SIGKILL p99 under 50 ms, SIGSTOP under the lease plus 10 %).
//! - `health_broadcast_ms`: twenty `monitor` modules subscribed to `armor.health`; a `victim`
//!   counter is SIGKILLed again and again, and each monitor logs how long after the report's
//!   stamp it heard it (the stamp is taken when the config server sees the victim's connection
//!   close). Reference: the same small message written by one thread to twenty TCP connections,
//!   each read by a thread of its own, from the write to each receipt (goal p99 under 5 ms).
//!   Both figures come through the event's trip and log lines: the wait for the line itself
//!   is not counted.

use std::io::{Read as _, Write as _};
use std::net::{TcpListener, TcpStream};
use std::process::Command;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_bench_report::Report;
use armor_module_api::{ENV_MODULE, ENV_SUPERVISOR};

use crate::Settings;
use crate::procs::{ChildGuard, sibling_binary};

pub const NAME_SWITCH: &str = "fallback_switch_ms";
pub const NAME_BROADCAST: &str = "health_broadcast_ms";

/// The lease the switch bench runs with.
const LEASE: Duration = Duration::from_millis(500);
/// Time between two faults: at most three crashes of one module in the supervisor's ten-second
/// window, so that it never gives up.
const SPACING: Duration = Duration::from_millis(3_500);
const WAIT: Duration = Duration::from_secs(10);
const STOP_TIMEOUT: Duration = Duration::from_secs(10);
const SUBSCRIBERS: usize = 20;

const SWITCH_SYSTEM: &str = r#"<system name="bench_fallback">
  <module name="primary" type="counter" restart="always"><param name="period_secs" value="0.002"/></module>
  <module name="backup" type="counter"><param name="period_secs" value="0.002"/></module>
  <module name="watch" type="checker"/>
  <link from="primary.count" to="watch.input"/>
  <link from="backup.count" to="watch.input" fallback="1"/>
</system>
"#;

pub fn run_switch(settings: &Settings) -> anyhow::Result<Report> {
    let faults = if settings.quick { 2 } else { 8 };
    let (kill_ms, stop_ms) = {
        let mut run = Run::start("bench_fallback", SWITCH_SYSTEM, &["--lease-secs", "0.5"])?;
        run.wait_line("the watch linked", |line| {
            line.starts_with("[watch]").then_some(())
        })?;
        let kill = run.switches(libc::SIGKILL, faults)?;
        let stop = run.switches(libc::SIGSTOP, faults)?;
        run.child.stop(STOP_TIMEOUT)?;
        (kill, stop)
    };
    let eof: Vec<Duration> = (0..faults)
        .map(|_| death_to_eof())
        .collect::<anyhow::Result<_>>()?;
    let lease = vec![LEASE; stop_ms.len()];
    let stop = Report::distribution(NAME_SWITCH, "ms", 1e3, &stop_ms, &lease);
    Ok(Report::distribution(NAME_SWITCH, "ms", 1e3, &kill_ms, &eof)
        .with("faults", kill_ms.len())
        .with("sigstop_p50", stop.p50.unwrap_or_default())
        .with("sigstop_p99", stop.p99.unwrap_or_default())
        .with("lease_ms", LEASE.as_secs_f64() * 1e3)
        .with("goal", "SIGKILL p99 < 50 ms; SIGSTOP p99 < lease + 10 %")
        .with(
            "reference_is",
            "SIGKILL of a process to EOF on a TCP connection to it; for SIGSTOP, the lease",
        ))
}

pub fn run_broadcast(settings: &Settings) -> anyhow::Result<Report> {
    let faults = if settings.quick { 2 } else { 8 };
    let mut system = String::from(
        "<system name=\"bench_health\">\n  <module name=\"victim\" type=\"counter\" \
         restart=\"always\"/>\n",
    );
    for index in 0..SUBSCRIBERS {
        system.push_str(&format!(
            "  <module name=\"monitor{index}\" type=\"monitor\"/>\n  <link from=\"armor.health\" \
             to=\"monitor{index}.health\"/>\n"
        ));
    }
    system.push_str("</system>\n");
    let mut heard = Vec::new();
    {
        let mut run = Run::start("bench_health", &system, &[])?;
        run.wait_line("every module configured", |line| {
            line.contains("modules configured").then_some(())
        })?;
        for _ in 0..faults {
            let victim = run.pid_of("victim")?;
            armor_runtime::process::kill(victim, libc::SIGKILL);
            let mut seen = 0;
            while seen < SUBSCRIBERS {
                let lag = run.wait_line("each monitor's report of the victim", |line| {
                    let rest = line.split_once("(heard ")?.1;
                    let (lag, report) = rest.split_once(" ms later): ")?;
                    report
                        .starts_with("victim failed")
                        .then(|| lag.parse::<f64>().ok())?
                })?;
                heard.push(Duration::from_secs_f64(lag / 1e3));
                seen += 1;
            }
            run.pause(SPACING);
        }
        run.child.stop(STOP_TIMEOUT)?;
    }
    let reference: Vec<Duration> = (0..faults)
        .map(|_| fan_out(SUBSCRIBERS))
        .collect::<anyhow::Result<Vec<_>>>()?
        .concat();
    Ok(
        Report::distribution(NAME_BROADCAST, "ms", 1e3, &heard, &reference)
            .with("subscribers", SUBSCRIBERS)
            .with("faults", faults)
            .with("goal", "p99 < 5 ms")
            .with(
                "reference_is",
                "one small message written to 20 TCP connections, each read by its own thread",
            ),
    )
}

/// `armor run` of a system, its output read as one stream.
struct Run {
    child: ChildGuard,
    lines: Receiver<String>,
    /// Its control interface, for the modules' pids.
    control: std::net::SocketAddr,
    _dir: tempfile::TempDir,
}

impl Run {
    fn start(name: &str, system: &str, args: &[&str]) -> anyhow::Result<Run> {
        let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
        let file = dir.path().join(format!("{name}.xml"));
        std::fs::write(&file, system)
            .with_context(|| format!("cannot write {}", file.display()))?;
        let mut command = Command::new(sibling_binary("armor")?);
        command
            .arg("run")
            .arg(&file)
            .args(args)
            .env("ARMOR_LOG", "info")
            .env_remove(ENV_SUPERVISOR)
            .env_remove(ENV_MODULE);
        let mut child = ChildGuard::spawn_capturing_stdout("armor run", command)?.graceful();
        let lines = child.merged_lines()?;
        let control = child.wait_line(&lines, "its control address", WAIT, |line| {
            line.strip_prefix(armor_runtime::CONTROL_READY_PREFIX)?
                .trim()
                .parse()
                .ok()
        })?;
        Ok(Run {
            child,
            lines,
            control,
            _dir: dir,
        })
    }

    /// Reads lines until `pick` gives a value, at most [`WAIT`].
    fn wait_line<T>(
        &mut self,
        what: &str,
        pick: impl FnMut(&str) -> Option<T>,
    ) -> anyhow::Result<T> {
        self.child.wait_line(&self.lines, what, WAIT, pick)
    }

    /// Reads (and drops) lines for `duration`.
    fn pause(&mut self, duration: Duration) {
        let until = Instant::now() + duration;
        loop {
            match self
                .lines
                .recv_timeout(until.saturating_duration_since(Instant::now()))
            {
                Ok(_) => {}
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => return,
            }
        }
    }

    /// The pid of `module`'s running process, from the run's status (asked until it runs).
    fn pid_of(&mut self, module: &str) -> anyhow::Result<libc::pid_t> {
        let addr = self.control;
        let deadline = Instant::now() + WAIT;
        loop {
            let reply = armor_protocol::request(addr, &armor_protocol::Request::Status, None)?;
            let pid = reply.status.and_then(|status| {
                status
                    .modules
                    .into_iter()
                    .find(|row| {
                        row.name == module && row.state == armor_protocol::ModuleState::Running
                    })
                    .and_then(|row| row.pid)
            });
            if let Some(pid) = pid {
                return Ok(pid as libc::pid_t);
            }
            if Instant::now() >= deadline {
                return Err(self.child.failure(&format!("`{module}` never ran again")));
            }
            self.pause(Duration::from_millis(20));
        }
    }

    /// `faults` times: `signal` to the primary, the time to the watch's first value from the
    /// fallback, then the switch back awaited and a pause.
    fn switches(&mut self, signal: libc::c_int, faults: usize) -> anyhow::Result<Vec<Duration>> {
        let mut switched = Vec::with_capacity(faults);
        for _ in 0..faults {
            let primary = self.pid_of("primary")?;
            let sent = Instant::now();
            armor_runtime::process::kill(primary, signal);
            self.wait_line("the watch's first value from the fallback", |line| {
                line.contains("event watch.restarted").then_some(())
            })?;
            switched.push(sent.elapsed());
            self.wait_line("the switch back to the primary", |line| {
                line.contains("backup.count → primary.count").then_some(())
            })?;
            self.pause(SPACING);
        }
        Ok(switched)
    }
}

/// From the SIGKILL of a process holding a TCP connection to the EOF at this end.
fn death_to_eof() -> anyhow::Result<Duration> {
    let mut peer = crate::raw::start_peer("--raw-echo", "1")?;
    // One echo first: the peer is up and reading.
    peer.stream.write_all(&[1])?;
    let mut byte = [0_u8; 1];
    peer.stream.read_exact(&mut byte)?;
    let pid = libc::pid_t::try_from(peer.child.id()).context("a pid")?;
    let killed = Instant::now();
    armor_runtime::process::kill(pid, libc::SIGKILL);
    loop {
        match peer.stream.read(&mut byte) {
            Ok(0) => return Ok(killed.elapsed()),
            Ok(_) => {}
            Err(err) if err.kind() == std::io::ErrorKind::ConnectionReset => {
                return Ok(killed.elapsed());
            }
            Err(err) => return Err(err).context("reading from the killed peer"),
        }
    }
}

/// One small message written to `count` TCP connections, each read on its own thread: from
/// the start of the writes to each receipt.
fn fan_out(count: usize) -> anyhow::Result<Vec<Duration>> {
    let listener = TcpListener::bind("127.0.0.1:0").context("cannot listen")?;
    let addr = listener.local_addr()?;
    let (done, results) = std::sync::mpsc::channel();
    // Every reader in its loop before the message goes.
    let ready = std::sync::Arc::new(std::sync::Barrier::new(count + 1));
    let mut readers = Vec::with_capacity(count);
    for _ in 0..count {
        let mut stream = TcpStream::connect(addr)?;
        stream.set_nodelay(true)?;
        let done = done.clone();
        let ready = std::sync::Arc::clone(&ready);
        readers.push(std::thread::spawn(move || {
            let mut message = [0_u8; 100];
            ready.wait();
            let read = stream.read_exact(&mut message);
            let _ = done.send((Instant::now(), read.is_ok()));
        }));
    }
    let mut writers = Vec::with_capacity(count);
    for _ in 0..count {
        let (stream, _) = listener.accept()?;
        stream.set_nodelay(true)?;
        writers.push(stream);
    }
    ready.wait();
    let start = Instant::now();
    for writer in &mut writers {
        writer.write_all(&[7_u8; 100])?;
    }
    let mut lags = Vec::with_capacity(count);
    for _ in 0..count {
        let (at, ok) = results
            .recv_timeout(WAIT)
            .context("a reader never got the message")?;
        anyhow::ensure!(ok, "a reader failed to read the message");
        lags.push(at.saturating_duration_since(start));
    }
    for reader in readers {
        let _ = reader.join();
    }
    Ok(lags)
}
