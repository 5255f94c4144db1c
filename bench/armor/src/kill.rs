//! `kill_recover_ms` and `messages_lost_under_kill`.
//!
//! - `kill_recover_ms`: `armor run` of a `victim` counter feeding a `watch` checker; the victim
//!   is SIGKILLed again and again, and the supervisor restarts it.
//!   From the SIGKILL to the checker's `restarted` event, which it reports on
//!   the first value from the new process — the module restarted (after the supervisor's
//!   backoff, which doubles for crashes within ten seconds: the kills are spaced so that there
//!   are at most three in a window), registered, found and relinked, and a message delivered.
//!   Reference: spawning the same binary with `--describe` until it exits, the floor of any
//!   restart. The output also gives each restart's backoff (from the supervisor's log) and the
//!   median time beyond it: what the runtime itself adds.
//! - `messages_lost_under_kill`: the killed provider's own link, against what the protocol
//!   promises a reliable subscriber when its provider dies (docs/protocol.md 4.3, "When a
//!   provider dies"): of each provider process, a prefix of what it published, in order, each
//!   sample once, ending no earlier than the last sample written to its connection; every sample
//!   of a dead process before any of its successor's. The provider is this binary in a hidden
//!   mode (`--kill-victim AGENT GENERATION PERIOD_US`), module `victim`, publishing
//!   `GENERATION << 32 | N` for N = 1, 2, … every millisecond, each sent and flushed before it
//!   prints N on its standard output (a pipe, which keeps what a killed process wrote). The bench
//!   hosts the subscriber (a reliable input bound to `victim.count`), SIGKILLs the provider while
//!   it streams, reads from the pipe the last N it had written, and starts the next generation at
//!   once (a restart without backoff, the hardest case for ordering across the restart). `ours`
//!   counts what breaks the promise: samples written before the kill that never arrived (in the
//!   middle or at the end of a generation), duplicates, and samples out of order within a
//!   generation or across the restart. The reference is the promise: 0. The samples a new
//!   generation published before the subscriber relinked are not promised (no history) and are
//!   given beside it (`not_promised_head_missed`).

use std::collections::{BTreeMap, HashSet};
use std::io::Write as _;
use std::path::Path;
use std::process::{Command, ExitCode};
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use armor_module_api::types::Counter;
use armor_module_api::{ENV_MODULE, ENV_SUPERVISOR, Event, Input, ModuleSpec, Node, Standalone};

use crate::Settings;
use crate::harness::{self, LINK_TIMEOUT};
use crate::procs::{ChildGuard, module_binary, self_command, sibling_binary};
use armor_bench_report::{Report, median};

pub const NAME_RECOVER: &str = "kill_recover_ms";
pub const NAME_LOST: &str = "messages_lost_under_kill";

/// Time between two kills: three kills at most in the supervisor's ten-second crash window.
const SPACING: Duration = Duration::from_millis(3_500);
/// How long one recovery may take before the bench gives up.
const RECOVER_TIMEOUT: Duration = Duration::from_secs(10);
const STOP_TIMEOUT: Duration = Duration::from_secs(10);

const SYSTEM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- armor-bench kill_recover_ms -->
<system name="bench_kill">
  <module name="victim" type="counter" restart="always">
    <param name="period_secs" value="0.01"/>
  </module>
  <module name="watch" type="checker"/>
  <link from="victim.count" to="watch.input"/>
</system>
"#;

/// What one run of the scenario measured.
struct Outcome {
    recover_ms: Vec<f64>,
    /// The supervisor's backoff before each restart, from its log.
    backoff_ms: Vec<f64>,
    spawn_ms: Vec<f64>,
}

pub fn run_recover(settings: &Settings) -> anyhow::Result<Report> {
    let outcome = scenario(settings)?;
    Ok(Report::single(
        NAME_RECOVER,
        "ms",
        median(&outcome.recover_ms),
        median(&outcome.spawn_ms),
    )
    .with("p99", percentile_99(&outcome.recover_ms))
    .with("kills", outcome.recover_ms.len())
    .with("backoff_ms", outcome.backoff_ms.clone())
    .with(
        "beyond_backoff_ms_p50",
        median(
            &outcome
                .recover_ms
                .iter()
                .zip(&outcome.backoff_ms)
                .map(|(recover, backoff)| recover - backoff)
                .collect::<Vec<_>>(),
        ),
    )
    .with(
        "reference_is",
        "spawning armor-mod-counter --describe until it exits",
    ))
}

/// The victim's publishing period.
const VICTIM_PERIOD_US: u64 = 1_000;
/// How long each generation streams, once linked, before it is killed: spread so that the kill
/// falls at different points of the period.
const STREAM_MS: [u64; 8] = [137, 211, 89, 263, 173, 59, 301, 127];
/// Samples of a generation to see before it counts as linked.
const LINKED_AFTER: u64 = 20;

pub fn run_lost(settings: &Settings) -> anyhow::Result<Report> {
    let kills = if settings.quick { 2 } else { 8 };
    let agent = harness::agent()?;
    let spec = ModuleSpec::new("bench", "armor-bench: the killed provider's subscriber")
        .input::<Counter>("count", "the victim's values, every one");
    let mut node = harness::connect(spec, agent, &[("count", "victim.count")])?;
    let input = node.reliable_input::<Counter>("count")?;
    let agent = agent.to_string();
    let mut tally = LinkTally::default();
    let mut written = Vec::with_capacity(kills);
    let mut victim = Victim::start(&agent, 0)?;
    for generation in 0..kills as u64 {
        let linked =
            tally.receive_until(&mut node, &input, Instant::now() + LINK_TIMEOUT, |tally| {
                tally.received_of(generation) >= LINKED_AFTER
            })?;
        if !linked {
            return Err(victim.child.failure(&format!(
                "generation {generation}: no samples in {LINK_TIMEOUT:?}"
            )));
        }
        let streamed = Duration::from_millis(STREAM_MS[generation as usize % STREAM_MS.len()]);
        tally.receive_until(&mut node, &input, Instant::now() + streamed, |_| false)?;
        written.push(victim.kill()?);
        victim = Victim::start(&agent, generation + 1)?;
    }
    let last = kills as u64;
    let linked =
        tally.receive_until(&mut node, &input, Instant::now() + LINK_TIMEOUT, |tally| {
            tally.received_of(last) >= LINKED_AFTER
        })?;
    if !linked {
        return Err(victim.child.failure("the last generation never linked"));
    }
    drop(victim);
    let verdict = tally.verdict(&written);
    let broken = verdict.broken();
    let mut report = Report::single(NAME_LOST, "messages", broken as f64, 0.0)
        .with("kills", kills)
        .with("lost_in_the_middle", verdict.lost_middle)
        .with("lost_at_the_kill", verdict.lost_tail)
        .with("duplicated", verdict.duplicated)
        .with("reordered", verdict.reordered)
        .with("reordered_across_restart", verdict.across_restart)
        .with("written_before_kills", verdict.written)
        .with("delivered", tally.received)
        .with("not_promised_head_missed", verdict.head_missed)
        .with("links", tally.links.len())
        .with(
            "goal",
            "0: the promise of docs/protocol.md 4.3, \"When a provider dies\"",
        )
        .with(
            "reference_is",
            "what the protocol promises a reliable subscriber of a killed provider: every \
             sample written to the connection before the kill delivered, once, in order, and \
             before any of the restarted provider's",
        );
    // 0 against 0: the ratio says nothing, so it is 1 when the promise held.
    report.ratio = if broken == 0 { 1.0 } else { f64::INFINITY };
    Ok(report)
}

/// One generation of the killed provider: this binary as module `victim`.
struct Victim {
    child: ChildGuard,
    lines: Receiver<String>,
}

impl Victim {
    /// Starts generation `generation` and waits until it is connected to the agent. A name still
    /// held by the killed generation is refused for a moment: then it tries again.
    fn start(agent: &str, generation: u64) -> anyhow::Result<Victim> {
        let deadline = Instant::now() + LINK_TIMEOUT;
        loop {
            let mut command = self_command()?;
            command.args([
                "--kill-victim",
                agent,
                &generation.to_string(),
                &VICTIM_PERIOD_US.to_string(),
            ]);
            let mut child = ChildGuard::spawn_capturing_stdout("the victim", command)?;
            let lines = child
                .take_stdout_lines()
                .context("the victim's standard output")?;
            match lines.recv_timeout(deadline.saturating_duration_since(Instant::now())) {
                Ok(line) if line == "ready" => return Ok(Victim { child, lines }),
                Ok(line) => bail!("the victim said `{line}` before `ready`"),
                Err(_) if Instant::now() < deadline => {
                    // It exited before it was connected (its name still taken): again.
                    child.wait_exit(Duration::from_secs(5))?;
                    std::thread::sleep(Duration::from_millis(20));
                }
                Err(_) => return Err(child.failure("no `ready` from the victim")),
            }
        }
    }

    /// SIGKILLs it and returns the last sample number it had written (and printed).
    fn kill(mut self) -> anyhow::Result<u64> {
        armor_runtime::process::kill(self.child.id() as libc::pid_t, libc::SIGKILL);
        self.child.wait_exit(Duration::from_secs(5))?;
        let mut last = 0;
        // The pipe ends with the process: what it printed is all there.
        while let Ok(line) = self.lines.recv_timeout(Duration::from_secs(5)) {
            last = line
                .parse()
                .with_context(|| format!("the victim printed `{line}`"))?;
        }
        Ok(last)
    }
}

/// The hidden `--kill-victim AGENT GENERATION PERIOD_US` mode: module `victim` publishing
/// `GENERATION << 32 | N` for N = 1, 2, … every PERIOD_US, each sent and flushed (written to
/// its subscribers' connections) before N is printed; `ready` first, once connected.
pub fn victim_main(agent: &str, generation: u64, period_us: u64) -> anyhow::Result<ExitCode> {
    let spec = ModuleSpec::new(
        "victim",
        "armor-bench: the provider messages_lost_under_kill kills",
    )
    .output::<Counter>("count", "GENERATION << 32 | N, N = 1, 2, …");
    let mut node = Node::connect(
        spec,
        Standalone {
            name: Some("victim".to_owned()),
            agent: Some(agent.to_owned()),
            ..Standalone::default()
        },
    )
    .context("the victim cannot connect")?;
    let count = node.output::<Counter>("count")?;
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "ready")?;
    stdout.flush()?;
    let period = Duration::from_micros(period_us);
    let mut next = Instant::now();
    for n in 1u64.. {
        node.send(&count, &Counter(generation << 32 | n))?;
        node.flush()?;
        writeln!(stdout, "{n}")?;
        stdout.flush()?;
        next += period;
        loop {
            match node.next_event_until(next)? {
                Event::Timeout => break,
                Event::Shutdown => return Ok(ExitCode::SUCCESS),
                _ => {}
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// What the subscriber received, sample by sample, in the order it came.
#[derive(Default)]
struct LinkTally {
    received: u64,
    /// The links samples came by (a new one each time the input relinked).
    links: HashSet<u64>,
    /// Per generation: the first and the highest sample number received, and how many.
    generations: BTreeMap<u64, Generation>,
    /// The highest generation seen so far.
    newest: Option<u64>,
    duplicated: u64,
    reordered: u64,
    across_restart: u64,
    /// Samples missing between two received ones of a generation.
    gaps: u64,
    seen: HashSet<u64>,
}

#[derive(Clone, Copy, Debug, Default)]
struct Generation {
    first: u64,
    highest: u64,
    count: u64,
}

/// The promise checked: what broke it, and what is not promised.
#[derive(Debug, Default, PartialEq, Eq)]
struct Verdict {
    lost_middle: u64,
    lost_tail: u64,
    duplicated: u64,
    reordered: u64,
    across_restart: u64,
    head_missed: u64,
    written: u64,
}

impl Verdict {
    fn broken(&self) -> u64 {
        self.lost_middle + self.lost_tail + self.duplicated + self.reordered + self.across_restart
    }
}

impl LinkTally {
    fn received_of(&self, generation: u64) -> u64 {
        self.generations.get(&generation).map_or(0, |g| g.count)
    }

    fn take(&mut self, value: u64, link: u64) {
        self.received += 1;
        self.links.insert(link);
        let (generation, n) = (value >> 32, value & 0xffff_ffff);
        if !self.seen.insert(value) {
            self.duplicated += 1;
            return;
        }
        if self.newest.is_some_and(|newest| generation < newest) {
            self.across_restart += 1;
        }
        self.newest = Some(
            self.newest
                .map_or(generation, |newest| newest.max(generation)),
        );
        let entry = self.generations.entry(generation).or_insert(Generation {
            first: n,
            highest: n - 1,
            count: 0,
        });
        entry.count += 1;
        if n < entry.highest {
            self.reordered += 1;
            // It filled a gap counted before.
            self.gaps = self.gaps.saturating_sub(1);
        } else {
            self.gaps += n - entry.highest - 1;
            entry.highest = n;
        }
    }

    /// Receives until `done` (then true) or `until` (then whether `done` holds).
    fn receive_until(
        &mut self,
        node: &mut Node,
        input: &Input<Counter>,
        until: Instant,
        done: impl Fn(&LinkTally) -> bool,
    ) -> anyhow::Result<bool> {
        loop {
            if done(self) {
                return Ok(true);
            }
            match node.next_event_until(until)? {
                Event::Input(port) if port == input.id() => {
                    while let Some(sample) = node.take(input)? {
                        self.take(sample.value.0, sample.link);
                    }
                }
                Event::Timeout if Instant::now() >= until => return Ok(done(self)),
                _ => {}
            }
        }
    }

    /// The promise against `written`, the last sample number each killed generation wrote.
    fn verdict(&self, written: &[u64]) -> Verdict {
        let mut verdict = Verdict {
            lost_middle: self.gaps,
            duplicated: self.duplicated,
            reordered: self.reordered,
            across_restart: self.across_restart,
            ..Verdict::default()
        };
        for (generation, &last_written) in written.iter().enumerate() {
            // A killed generation none of whose samples came: all it wrote is lost.
            if !self.generations.contains_key(&(generation as u64)) {
                verdict.written += last_written;
                verdict.lost_tail += last_written;
            }
        }
        for (generation, generation_stats) in &self.generations {
            verdict.head_missed += generation_stats.first - 1;
            if let Some(&last_written) = written.get(*generation as usize) {
                // A sample received beyond the last printed one was written just before the
                // kill (between its flush and its line): it was written all the same.
                let last_written = last_written.max(generation_stats.highest);
                verdict.written += last_written;
                verdict.lost_tail += last_written - generation_stats.highest;
            }
        }
        verdict
    }
}

fn percentile_99(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    armor_bench_report::percentile(&sorted, 0.99)
}

fn scenario(settings: &Settings) -> anyhow::Result<Outcome> {
    let kills = if settings.quick { 2 } else { 8 };
    let armor = sibling_binary("armor")?;
    let counter = module_binary("counter")?;
    let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
    let file = dir.path().join("system.xml");
    std::fs::write(&file, SYSTEM).with_context(|| format!("cannot write {}", file.display()))?;
    let mut command = Command::new(&armor);
    command
        .arg("run")
        .arg(&file)
        .env("ARMOR_LOG", "info")
        .env_remove(ENV_SUPERVISOR)
        .env_remove(ENV_MODULE);
    let mut run = ChildGuard::spawn_capturing_stdout("armor run", command)?.graceful();
    let lines = run.merged_lines()?;
    let mut log = Log::default();
    let mut victim = log.wait(&lines, &mut run, "the victim's pid", |log| log.victim_pid)?;
    log.wait(&lines, &mut run, "the watch linked", |log| {
        log.watch_values.then_some(())
    })?;
    let mut recover_ms = Vec::with_capacity(kills);
    let mut backoff_ms = Vec::with_capacity(kills);
    let mut spawn_ms = Vec::with_capacity(kills);
    for _ in 0..kills {
        let killed_at = Instant::now();
        armor_runtime::process::kill(victim, libc::SIGKILL);
        log.restarts_seen = 0;
        log.victim_pid = None;
        log.wait(&lines, &mut run, "the watch's `restarted` event", |log| {
            (log.restarts_seen > 0).then_some(())
        })?;
        recover_ms.push(killed_at.elapsed().as_secs_f64() * 1e3);
        backoff_ms.push(log.backoff_ms.take().unwrap_or(0.0));
        victim = log.wait(&lines, &mut run, "the victim's new pid", |log| {
            log.victim_pid
        })?;
        spawn_ms.push(describe_spawn(&counter)?);
        let next = killed_at + SPACING;
        while Instant::now() < next {
            log.poll(&lines, next.saturating_duration_since(Instant::now()));
        }
    }
    run.stop(STOP_TIMEOUT)?;
    Ok(Outcome {
        recover_ms,
        backoff_ms,
        spawn_ms,
    })
}

/// Milliseconds to spawn `armor-mod-counter --describe` and see it exit.
pub fn describe_spawn(counter: &Path) -> anyhow::Result<f64> {
    let start = Instant::now();
    let mut command = Command::new(counter);
    command.arg("--describe");
    let mut child = ChildGuard::spawn_quiet("armor-mod-counter --describe", command)?;
    let status = child.wait_exit(STOP_TIMEOUT)?;
    if !status.success() {
        return Err(child.failure(&format!("failed ({status})")));
    }
    Ok(start.elapsed().as_secs_f64() * 1e3)
}

/// What `armor run`'s log said so far.
#[derive(Default)]
struct Log {
    victim_pid: Option<libc::pid_t>,
    backoff_ms: Option<f64>,
    watch_values: bool,
    restarts_seen: u32,
}

impl Log {
    fn take(&mut self, line: &str) {
        if line.contains("module started") && line.contains("module=\"victim\"") {
            self.victim_pid = line
                .split("pid=")
                .nth(1)
                .and_then(|rest| rest.split_whitespace().next())
                .and_then(|pid| pid.parse().ok());
        } else if line.contains("module=\"victim\"") && line.contains("restarting in ") {
            self.backoff_ms = line
                .split("restarting in ")
                .nth(1)
                .and_then(|rest| rest.split("ms").next())
                .and_then(|ms| ms.trim().parse().ok());
        } else if line.starts_with("[watch]") && line.contains("received ") {
            self.watch_values = true;
        } else if line.contains("event watch.restarted") {
            self.restarts_seen += 1;
        }
    }

    /// Takes the lines that come within `timeout`.
    fn poll(&mut self, lines: &Receiver<String>, timeout: Duration) {
        let until = Instant::now() + timeout;
        while let Ok(line) = lines.recv_timeout(until.saturating_duration_since(Instant::now())) {
            self.take(&line);
        }
    }

    /// Reads lines until `ready` gives a value, at most [`RECOVER_TIMEOUT`].
    fn wait<T>(
        &mut self,
        lines: &Receiver<String>,
        run: &mut ChildGuard,
        what: &str,
        ready: impl Fn(&Log) -> Option<T>,
    ) -> anyhow::Result<T> {
        let deadline = Instant::now() + RECOVER_TIMEOUT;
        loop {
            if let Some(value) = ready(self) {
                return Ok(value);
            }
            let left = deadline.saturating_duration_since(Instant::now());
            match lines.recv_timeout(left.min(Duration::from_millis(200))) {
                Ok(line) => self.take(&line),
                Err(RecvTimeoutError::Timeout) if left.is_zero() => {
                    return Err(run.failure(&format!("no sign of {what}")));
                }
                Err(RecvTimeoutError::Timeout) => run.check_alive()?,
                Err(RecvTimeoutError::Disconnected) => {
                    return Err(run.failure(&format!("ended before {what}")));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_promise_is_checked_sample_by_sample() {
        let value = |generation: u64, n: u64| generation << 32 | n;
        let mut tally = LinkTally::default();
        // Generation 0 from 1 to 5, killed after writing 6; generation 1 joined at 3.
        for n in 1..=5 {
            tally.take(value(0, n), 1);
        }
        for n in 3..=4 {
            tally.take(value(1, n), 2);
        }
        assert_eq!(tally.verdict(&[6]).broken(), 1, "one lost at the kill");
        assert_eq!(tally.verdict(&[6]).head_missed, 2, "not promised");
        // A late sample of generation 0, a duplicate, a gap and a step back in generation 1.
        tally.take(value(0, 6), 1);
        tally.take(value(1, 4), 2);
        tally.take(value(1, 7), 2);
        tally.take(value(1, 6), 2);
        let verdict = tally.verdict(&[6]);
        assert_eq!(
            verdict,
            Verdict {
                lost_middle: 1,
                lost_tail: 0,
                duplicated: 1,
                reordered: 1,
                across_restart: 1,
                head_missed: 2,
                written: 6,
            }
        );
        // A printed count below what arrived: the kill fell between the flush and the line.
        let mut tally = LinkTally::default();
        for n in 1..=4 {
            tally.take(value(0, n), 1);
        }
        assert_eq!(tally.verdict(&[3]).broken(), 0);
        // A generation of which nothing came lost all it wrote.
        assert_eq!(tally.verdict(&[4, 9]).lost_tail, 9);
    }
}
