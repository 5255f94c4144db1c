//! `kill_recover_ms` and `messages_lost_under_kill`: `armor run` of two links, a `victim`
//! counter feeding a `watch` checker and a `steady` counter at 1 kHz feeding `steady_check`;
//! the victim is SIGKILLed again and again.
//!
//! - `kill_recover_ms`: from the SIGKILL to the checker's `restarted` event, which it reports on
//!   the first value from the new process — the module restarted (after the supervisor's
//!   backoff, which doubles for crashes within ten seconds: the kills are spaced so that there
//!   are at most three in a window), registered, found and relinked, and a message delivered.
//!   Reference: spawning the same binary with `--describe` until it exits, the floor of any
//!   restart. The output also gives each restart's backoff (from the supervisor's log) and the
//!   median time beyond it: what the runtime itself adds.
//! - `messages_lost_under_kill`: on the steady link, the values that went missing, came twice or
//!   out of order while the victim was killed, from the checker's own count (reliable input,
//!   sequence-checked). It must be 0; the reference is 0.

use std::path::Path;
use std::process::Command;
use std::sync::mpsc::{Receiver, RecvTimeoutError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_module_api::{ENV_MODULE, ENV_SUPERVISOR};

use crate::Settings;
use crate::procs::{ChildGuard, module_binary, sibling_binary};
use armor_bench_report::{Report, median};

pub const NAME_RECOVER: &str = "kill_recover_ms";
pub const NAME_LOST: &str = "messages_lost_under_kill";

/// Time between two kills: three kills at most in the supervisor's ten-second crash window.
const SPACING: Duration = Duration::from_millis(3_500);
/// How long one recovery may take before the bench gives up.
const RECOVER_TIMEOUT: Duration = Duration::from_secs(10);
const STOP_TIMEOUT: Duration = Duration::from_secs(10);

const SYSTEM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<!-- armor-bench kill_recover_ms / messages_lost_under_kill -->
<system name="bench_kill">
  <module name="victim" type="counter" restart="always">
    <param name="period_secs" value="0.01"/>
  </module>
  <module name="watch" type="checker"/>
  <module name="steady" type="counter">
    <param name="period_secs" value="0.001"/>
  </module>
  <module name="steady_check" type="checker">
    <param name="report_every" value="500"/>
  </module>
  <link from="victim.count" to="watch.input"/>
  <link from="steady.count" to="steady_check.input"/>
</system>
"#;

/// What one run of the scenario measured.
struct Outcome {
    recover_ms: Vec<f64>,
    /// The supervisor's backoff before each restart, from its log.
    backoff_ms: Vec<f64>,
    spawn_ms: Vec<f64>,
    /// Values the steady checker should have had between the first and last summaries, minus
    /// those it had.
    lost: i64,
    /// Out-of-order values and relinks on the steady link.
    disorder: u64,
    steady_received: u64,
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

pub fn run_lost(settings: &Settings) -> anyhow::Result<Report> {
    let outcome = scenario(settings)?;
    let bad = outcome.lost.unsigned_abs() + outcome.disorder;
    let mut report = Report::single(NAME_LOST, "messages", bad as f64, 0.0)
        .with("kills", outcome.recover_ms.len())
        .with("lost", outcome.lost)
        .with("out_of_order_or_relinked", outcome.disorder)
        .with("delivered", outcome.steady_received);
    // 0 against 0: the ratio says nothing, so it is 1 when nothing was lost.
    report.ratio = if bad == 0 { 1.0 } else { f64::INFINITY };
    Ok(report)
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
    let first = log.wait(&lines, &mut run, "a steady summary", |log| log.steady)?;
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
    // Two more summaries, so that the last one counts values sent after the last kill.
    let seen = log.steady_summaries;
    log.wait(
        &lines,
        &mut run,
        "steady summaries after the kills",
        |log| (log.steady_summaries >= seen + 2).then_some(()),
    )?;
    let last = log.steady.unwrap_or(first);
    run.stop(STOP_TIMEOUT)?;
    let expected = last.last_value as i64 - first.last_value as i64;
    let received = last.received as i64 - first.received as i64;
    Ok(Outcome {
        recover_ms,
        backoff_ms,
        spawn_ms,
        lost: expected - received,
        disorder: last.out_of_order + log.steady_relinks,
        steady_received: last.received,
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

/// A summary line of a checker: `received N values, last V, in order | K out of order`.
#[derive(Clone, Copy, Debug, Default)]
struct Summary {
    received: u64,
    last_value: u64,
    out_of_order: u64,
}

impl Summary {
    fn parse(line: &str) -> Option<Summary> {
        let rest = line.split("received ").nth(1)?;
        let mut words = rest.split([' ', ',']).filter(|w| !w.is_empty());
        let received = words.next()?.parse().ok()?;
        let _values = words.next()?;
        let _last = words.next()?;
        let last_value = words.next()?.parse().ok()?;
        let out_of_order = match words.next()? {
            "in" => 0,
            count => count.parse().ok()?,
        };
        Some(Summary {
            received,
            last_value,
            out_of_order,
        })
    }
}

/// What `armor run`'s log said so far.
#[derive(Default)]
struct Log {
    victim_pid: Option<libc::pid_t>,
    backoff_ms: Option<f64>,
    watch_values: bool,
    restarts_seen: u32,
    steady: Option<Summary>,
    steady_summaries: u64,
    steady_relinks: u64,
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
        } else if line.contains("event steady_check.") {
            self.steady_relinks += 1;
        } else if line.starts_with("[steady_check]")
            && let Some(summary) = Summary::parse(line)
        {
            self.steady = Some(summary);
            self.steady_summaries += 1;
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
    fn checker_summaries() {
        let s = Summary::parse("[steady_check]  INFO received 500 values, last 512, in order")
            .expect("parsed");
        assert_eq!((s.received, s.last_value, s.out_of_order), (500, 512, 0));
        let s =
            Summary::parse("[w]  INFO received 7 values, last 9, 2 out of order").expect("parsed");
        assert_eq!((s.received, s.last_value, s.out_of_order), (7, 9, 2));
        assert!(Summary::parse("nothing here").is_none());
    }
}
