//! `event_to_start_ms`: from a module reporting an event to the module of the next place
//! receiving its start command, through `armor run`'s mission controller (the report reaches
//! the config server, the controller fires the transition at once, the config server sends
//! `start`). The original system polled the modules' states once a second, so the same hop took
//! up to 1000 ms there; that is history, not the reference.
//!
//! Ours: two `benchprobe` modules (this binary, see [`crate::benchprobe`]) `a` and `b` under a
//! cyclic mission, `pa` {a} → on `a.tick` → `pb` {b} → on `b.tick` → `pa`, each reporting `tick`
//! as soon as it is started and printing both times on the run clock. Reference, measured in the
//! same run: the same two hops over raw TCP, the floor for "module → controller → module":
//! process A writes a byte to a relay (this process), which writes it to process B, and back the
//! other way; A's send to B's receive on the same clock (see [`hop_main`]).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::io::{ErrorKind, Read as _, Write as _};
use std::net::{TcpListener, TcpStream};
use std::process::{Command, ExitCode};
use std::sync::mpsc::RecvTimeoutError;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow, bail};
use armor_module_api::clock::{ENV_EPOCH, unix_now_ns};
use armor_module_api::{Clock, ENV_MODULE, ENV_SUPERVISOR};
use armor_runtime::probe::ENV_MODULE_PATH;

use crate::Settings;
use crate::benchprobe::{self, Kind, Line};
use crate::harness::{LINK_TIMEOUT, STALL_TIMEOUT};
use crate::procs::{ChildGuard, self_command, sibling_binary};
use armor_bench_report::Report;

pub const NAME: &str = "event_to_start_ms";
/// How long `armor run` has to stop after SIGTERM.
const STOP_TIMEOUT: Duration = Duration::from_secs(10);
/// How long the reference peers have to connect, and to exit once done.
const PEER_TIMEOUT: Duration = Duration::from_secs(10);

struct Counts {
    /// Hops timed, each side (half each way).
    samples: usize,
    /// Hops left out first, each side (the first ones pay for connections and cold caches).
    warm_up: usize,
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let counts = if settings.quick {
        Counts {
            samples: 50,
            warm_up: 4,
        }
    } else {
        Counts {
            samples: 2_000,
            warm_up: 20,
        }
    };
    // Half the reference before ArMoR and half after, so that a change in the machine's load
    // weighs on both alike.
    let half = Counts {
        samples: counts.samples.div_ceil(2),
        warm_up: counts.warm_up,
    };
    let mut reference = raw_hops(&half)?;
    let ours = armor_hops(&counts)?;
    reference.extend(raw_hops(&Counts {
        samples: counts.samples - half.samples,
        ..half
    })?);
    Ok(Report::distribution(NAME, "ms", 1e3, &ours, &reference))
}

/// The system: two probes.
fn system_xml() -> String {
    format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <!-- armor-bench {NAME}: two probes that report `{tick}` as soon as they start. -->\n\
         <system name=\"bench_event_to_start\">\n  \
           <module name=\"a\" type=\"{module_type}\"/>\n  \
           <module name=\"b\" type=\"{module_type}\"/>\n\
         </system>\n",
        tick = benchprobe::TICK,
        module_type = benchprobe::MODULE_TYPE,
    )
}

/// The mission: a token going round `pa` {a} and `pb` {b}, moved by their reports.
fn mission_xml() -> String {
    let mut xml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <!-- armor-bench {NAME}: a and b take turns, each started by the other's report. -->\n\
         <mission name=\"bench_event_to_start\" system=\"system.xml\">\n"
    );
    let _ = writeln!(
        xml,
        "  <place name=\"pa\" tokens=\"1\"><module name=\"a\"/></place>\n  \
         <place name=\"pb\"><module name=\"b\"/></place>"
    );
    for (name, from, module, to) in [("a_ticked", "pa", "a", "pb"), ("b_ticked", "pb", "b", "pa")] {
        let _ = writeln!(
            xml,
            "  <transition name=\"{name}\" event=\"{module}.{tick}\">\
             <input place=\"{from}\"/><output place=\"{to}\"/></transition>",
            tick = benchprobe::TICK,
        );
    }
    xml.push_str("</mission>\n");
    xml
}

/// Runs the mission and times the hops from the probes' lines.
fn armor_hops(counts: &Counts) -> anyhow::Result<Vec<Duration>> {
    let armor = sibling_binary("armor")?;
    let exe = std::env::current_exe().context("cannot locate this executable")?;
    let exe_dir = exe
        .parent()
        .context("this executable has no folder")?
        .to_path_buf();
    let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
    let link = dir.path().join(benchprobe::BINARY_NAME);
    std::os::unix::fs::symlink(&exe, &link)
        .with_context(|| format!("cannot make the symlink {}", link.display()))?;
    let write = |name: &str, text: String| -> anyhow::Result<()> {
        let file = dir.path().join(name);
        std::fs::write(&file, text).with_context(|| format!("cannot write {}", file.display()))
    };
    write("system.xml", system_xml())?;
    write("mission.xml", mission_xml())?;
    let module_path = std::env::join_paths([dir.path(), exe_dir.as_path()])
        .context("the temporary folder cannot go in a module path")?;
    let mut command = Command::new(&armor);
    command
        .arg("run")
        .arg(dir.path().join("mission.xml"))
        .env(ENV_MODULE_PATH, module_path)
        // The default level, whatever the caller's: the runtime as it is run.
        .env("ARMOR_LOG", "info")
        .env_remove(ENV_SUPERVISOR)
        .env_remove(ENV_MODULE);
    let mut child = ChildGuard::spawn_capturing_stdout("armor run", command)?.graceful();
    let Some(lines) = child.take_stdout_lines() else {
        bail!("armor run: no stdout to read");
    };
    let mut hops = Hops::default();
    let mut samples = Vec::with_capacity(counts.samples);
    let mut give_up = Instant::now() + LINK_TIMEOUT;
    while samples.len() < counts.samples {
        match lines.recv_timeout(Duration::from_millis(50)) {
            Ok(line) => {
                let Some((module, line)) = probe_line(&line) else {
                    continue;
                };
                if let Some((hop, elapsed)) = hops.add(module, line)? {
                    give_up = Instant::now() + STALL_TIMEOUT;
                    if hop > counts.warm_up as u64 {
                        samples.push(elapsed);
                    }
                }
            }
            Err(RecvTimeoutError::Timeout) => {
                child.check_alive()?;
                if Instant::now() >= give_up {
                    return Err(child.failure(&format!(
                        "timed {} of {} hops, then none for {:?}",
                        samples.len(),
                        counts.samples,
                        if hops.paired == 0 {
                            LINK_TIMEOUT
                        } else {
                            STALL_TIMEOUT
                        }
                    )));
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                child.check_alive()?;
                return Err(child.failure("closed its stdout"));
            }
        }
    }
    let status = child.terminate(STOP_TIMEOUT)?;
    if !status.success() {
        return Err(child.failure(&format!("stopped badly after SIGTERM ({status})")));
    }
    Ok(samples)
}

/// `[a] benchprobe start 3 NS` → (`a`, the line).
fn probe_line(text: &str) -> Option<(&str, Line)> {
    let rest = text.strip_prefix('[')?;
    let (module, rest) = rest.split_once("] ")?;
    Some((module, Line::parse(rest)?))
}

/// Pairs reports with the starts they cause. The token goes round, so hop `h` (from 1) is the
/// report of `a`'s activation `(h + 1) / 2` for odd `h`, of `b`'s activation `h / 2` for even
/// `h`; it starts `b`'s activation `(h + 1) / 2`, or `a`'s activation `h / 2 + 1`. `armor run`
/// copies each module's lines on its own thread, so lines of `a` and `b` may come out of order:
/// each side waits in its map for the other.
#[derive(Default)]
struct Hops {
    reports: HashMap<u64, u64>,
    starts: HashMap<u64, u64>,
    /// Hops whose start was the module's initial activation (no start command): not timed.
    untimed: Vec<u64>,
    paired: usize,
}

impl Hops {
    /// Takes a line; returns a hop and its duration when the line completes one.
    fn add(&mut self, module: &str, line: Line) -> anyhow::Result<Option<(u64, Duration)>> {
        let hop = match (module, line.kind) {
            ("a", Kind::Report) => line.count * 2 - 1,
            ("b", Kind::Report) => line.count * 2,
            ("b", Kind::Start | Kind::Active) => line.count * 2 - 1,
            // `a`'s first activation is the initial marking's: no hop leads to it.
            ("a", Kind::Start | Kind::Active) if line.count > 1 => (line.count - 1) * 2,
            ("a", _) => return Ok(None),
            _ => bail!("a line from an unexpected module `{module}`: {line:?}"),
        };
        if line.count == 0 {
            bail!("a probe counted from 0: {line:?}");
        }
        let (report_ns, start_ns) = match line.kind {
            Kind::Report => match self.starts.remove(&hop) {
                Some(start) => (line.ns, start),
                None => {
                    self.reports.insert(hop, line.ns);
                    return Ok(None);
                }
            },
            Kind::Active => {
                // A module that starts late gets its first activation in its configuration.
                self.untimed.push(hop);
                self.reports.remove(&hop);
                return Ok(None);
            }
            Kind::Start => match self.reports.remove(&hop) {
                Some(report) => (report, line.ns),
                None => {
                    if !self.untimed.contains(&hop) {
                        self.starts.insert(hop, line.ns);
                    }
                    return Ok(None);
                }
            },
        };
        if start_ns < report_ns {
            bail!(
                "hop {hop}: the start was seen {} ns before the report was made: the run clock \
                 is not shared, or the pairing is wrong",
                report_ns - start_ns
            );
        }
        self.paired += 1;
        Ok(Some((hop, Duration::from_nanos(start_ns - report_ns))))
    }
}

/// The reference: this process is the relay between two peers, this binary run as
/// `--raw-hop ADDR a|b COUNT`.
fn raw_hops(counts: &Counts) -> anyhow::Result<Vec<Duration>> {
    // Each peer sends half the hops; an odd count gets one more.
    let rounds = counts.samples.div_ceil(2) + counts.warm_up.div_ceil(2);
    let listener = TcpListener::bind("127.0.0.1:0").context("cannot listen for the peers")?;
    let addr = listener.local_addr()?.to_string();
    let epoch_ns = unix_now_ns().to_string();
    let mut peers = Vec::new();
    for role in ["a", "b"] {
        let mut command = self_command()?;
        command
            .arg("--raw-hop")
            .arg(&addr)
            .arg(role)
            .arg(rounds.to_string())
            .env(ENV_EPOCH, &epoch_ns);
        peers.push(ChildGuard::spawn_capturing_stdout(
            &format!("armor-bench --raw-hop {role}"),
            command,
        )?);
    }
    let (to_a, to_b) = accept_peers(&listener, &mut peers)?;
    let streams = [to_a, to_b];
    let mut byte = [0u8; 1];
    for _ in 0..rounds {
        // A's byte to B, then B's back to A.
        for (from, to) in [(0, 1), (1, 0)] {
            if let Err(err) = (&streams[from])
                .read_exact(&mut byte)
                .and_then(|()| (&streams[to]).write_all(&byte))
            {
                for peer in &mut peers {
                    peer.check_alive()?;
                }
                return Err(err).context("relaying between the reference peers");
            }
        }
    }
    let mut times = Vec::new();
    for peer in &mut peers {
        let status = peer.wait_exit(PEER_TIMEOUT)?;
        if !status.success() {
            return Err(peer.failure(&format!("failed ({status})")));
        }
        let lines = peer.take_stdout_lines().context("no stdout to read")?;
        let mut pairs: Vec<(u64, u64)> = Vec::with_capacity(rounds);
        // The reader thread is done once the pipe closes, soon after the exit.
        while let Ok(line) = lines.recv_timeout(PEER_TIMEOUT) {
            let (send, receive) = line
                .split_once(' ')
                .and_then(|(send, receive)| Some((send.parse().ok()?, receive.parse().ok()?)))
                .with_context(|| format!("unreadable line from a reference peer: `{line}`"))?;
            pairs.push((send, receive));
        }
        if pairs.len() != rounds {
            bail!(
                "a reference peer printed {} times instead of {rounds}",
                pairs.len()
            );
        }
        times.push(pairs);
    }
    let (a, b) = (&times[0], &times[1]);
    let mut samples = Vec::with_capacity(2 * rounds);
    for round in 0..rounds {
        // A's send to B's receive, then B's send to A's receive.
        for (send, receive) in [(a[round].0, b[round].1), (b[round].0, a[round].1)] {
            if receive < send {
                bail!(
                    "a reference hop was received {} ns before it was sent",
                    send - receive
                );
            }
            samples.push(Duration::from_nanos(receive - send));
        }
    }
    Ok(samples
        .into_iter()
        .skip(counts.warm_up)
        .take(counts.samples)
        .collect())
}

/// Accepts both peers; each says who it is with its first byte.
fn accept_peers(
    listener: &TcpListener,
    peers: &mut [ChildGuard],
) -> anyhow::Result<(TcpStream, TcpStream)> {
    listener.set_nonblocking(true)?;
    let deadline = Instant::now() + PEER_TIMEOUT;
    let (mut a, mut b) = (None, None);
    while a.is_none() || b.is_none() {
        match listener.accept() {
            Ok((mut stream, _)) => {
                stream.set_nonblocking(false)?;
                stream.set_nodelay(true)?;
                stream.set_read_timeout(Some(STALL_TIMEOUT))?;
                stream.set_write_timeout(Some(STALL_TIMEOUT))?;
                let mut role = [0u8; 1];
                stream
                    .read_exact(&mut role)
                    .context("a reference peer did not say who it is")?;
                match &role {
                    b"a" => a = Some(stream),
                    b"b" => b = Some(stream),
                    _ => bail!("a reference peer said it is {role:?}"),
                }
            }
            Err(err) if err.kind() == ErrorKind::WouldBlock => {
                for peer in peers.iter_mut() {
                    peer.check_alive()?;
                }
                if Instant::now() >= deadline {
                    bail!("the reference peers did not connect within {PEER_TIMEOUT:?}");
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            Err(err) => return Err(err).context("accept failed"),
        }
    }
    a.zip(b)
        .ok_or_else(|| anyhow!("unreachable: both peers connected"))
}

/// Hidden mode `--raw-hop ADDR ROLE ROUNDS`: a reference peer. `a` sends a byte and waits for
/// one back, ROUNDS times; `b` waits for a byte and sends one back. Both then print one line
/// per round, `SEND_NS RECEIVE_NS`, on the run clock (epoch from `$ARMOR_EPOCH_NS`, as under
/// `armor run`).
pub fn hop_main(addr: &str, role: &str, rounds: usize) -> anyhow::Result<ExitCode> {
    let sends_first = match role {
        "a" => true,
        "b" => false,
        _ => bail!("--raw-hop ROLE is `a` or `b`, not `{role}`"),
    };
    let clock = Clock::from_env();
    let mut stream = TcpStream::connect(addr).with_context(|| format!("cannot reach {addr}"))?;
    stream.set_nodelay(true)?;
    stream.write_all(role.as_bytes())?;
    let mut times = Vec::with_capacity(rounds);
    let mut byte = [1u8; 1];
    for _ in 0..rounds {
        if sends_first {
            let sent = clock.now_ns();
            stream.write_all(&byte)?;
            stream.read_exact(&mut byte)?;
            times.push((sent, clock.now_ns()));
        } else {
            stream.read_exact(&mut byte)?;
            let received = clock.now_ns();
            let sent = clock.now_ns();
            stream.write_all(&byte)?;
            times.push((sent, received));
        }
    }
    let mut out = String::with_capacity(rounds * 42);
    for (sent, received) in times {
        let _ = writeln!(out, "{sent} {received}");
    }
    let mut stdout = std::io::stdout().lock();
    stdout.write_all(out.as_bytes())?;
    stdout.flush()?;
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(kind: Kind, count: u64, ns: u64) -> Line {
        Line { kind, count, ns }
    }

    #[test]
    fn hops_pair_in_any_order() {
        let mut hops = Hops::default();
        // a starts active; b connects late and is active from its configuration too.
        assert_eq!(hops.add("a", line(Kind::Active, 1, 100)).ok(), Some(None));
        assert_eq!(hops.add("a", line(Kind::Report, 1, 110)).ok(), Some(None));
        assert_eq!(hops.add("b", line(Kind::Active, 1, 500)).ok(), Some(None));
        assert_eq!(hops.add("b", line(Kind::Report, 1, 510)).ok(), Some(None));
        // b's start is copied before a's report.
        assert_eq!(
            hops.add("a", line(Kind::Start, 2, 600)).ok(),
            Some(Some((2, Duration::from_nanos(90))))
        );
        assert_eq!(hops.add("a", line(Kind::Report, 2, 610)).ok(), Some(None));
        assert_eq!(
            hops.add("b", line(Kind::Start, 2, 700)).ok(),
            Some(Some((3, Duration::from_nanos(90))))
        );
        assert_eq!(hops.add("a", line(Kind::Start, 3, 900)).ok(), Some(None));
        assert_eq!(
            hops.add("b", line(Kind::Report, 2, 720)).ok(),
            Some(Some((4, Duration::from_nanos(180))))
        );
        assert_eq!(hops.paired, 3);
        assert!(hops.add("c", line(Kind::Start, 1, 1)).is_err());
        assert!(hops.add("b", line(Kind::Start, 3, 1)).is_ok());
        assert!(
            hops.add("a", line(Kind::Report, 3, 2)).is_err(),
            "start before report"
        );
    }

    #[test]
    fn probe_lines() {
        assert_eq!(
            probe_line("[b] benchprobe report 7 42"),
            Some(("b", line(Kind::Report, 7, 42)))
        );
        assert_eq!(probe_line("[a] INFO reporting event event=\"tick\""), None);
        assert_eq!(probe_line("benchprobe report 7 42"), None);
    }
}
