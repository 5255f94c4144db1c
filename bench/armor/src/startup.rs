//! `startup_10_modules`: `armor run` of a system of ten counters, timed from its spawn until it
//! logs that every module has its configuration, against spawning ten `armor-mod-counter
//! --describe` processes and waiting for all of them to exit.

use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use armor_module_api::{ENV_MODULE, ENV_SUPERVISOR};

use crate::Settings;
use crate::harness::LINK_TIMEOUT;
use crate::procs::{ChildGuard, module_binary, sibling_binary};
use armor_bench_report::{Report, median};

pub const NAME: &str = "startup_10_modules";
const MODULES: usize = 10;
/// How long `armor run` has to stop after SIGTERM.
const STOP_TIMEOUT: Duration = Duration::from_secs(10);

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let rounds = if settings.quick { 1 } else { 5 };
    let armor = sibling_binary("armor")?;
    let counter = module_binary("counter")?;
    let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
    let file = dir.path().join("system.xml");
    std::fs::write(&file, system_xml())
        .with_context(|| format!("cannot write {}", file.display()))?;
    let mut ours = Vec::with_capacity(rounds);
    let mut reference = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        ours.push(armor_startup(&armor, &file)?);
        reference.push(describe_spawns(&counter)?);
    }
    Ok(Report::single(
        NAME,
        "ms",
        median(&ours),
        median(&reference),
    ))
}

/// Ten counters named c0..c9, nothing linked.
fn system_xml() -> String {
    let mut xml = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n\
         <!-- armor-bench startup_10_modules: ten counters, nothing linked. -->\n\
         <system name=\"bench_startup\">\n",
    );
    for index in 0..MODULES {
        let _ = writeln!(xml, "  <module name=\"c{index}\" type=\"counter\"/>");
    }
    xml.push_str("</system>\n");
    xml
}

/// Milliseconds from spawning `armor run` on `file` (ten modules, wherever they run) until it
/// logs `all 10 modules configured`; no run folder is written.
pub fn armor_startup(armor: &Path, file: &Path) -> anyhow::Result<f64> {
    let mut command = Command::new(armor);
    command
        .arg("run")
        .arg(file)
        .arg("--no-run-folder")
        // The line waited for is logged at `info`, whatever the caller's filter.
        .env("ARMOR_LOG", "info")
        .env_remove(ENV_SUPERVISOR)
        .env_remove(ENV_MODULE);
    let expected = format!("all {MODULES} modules configured");
    let start = Instant::now();
    let mut child = ChildGuard::spawn("armor run", command)?.graceful();
    let Some(lines) = child.take_lines() else {
        bail!("armor run: no stderr to read");
    };
    child.wait_line(&lines, &format!("`{expected}`"), LINK_TIMEOUT, |line| {
        line.contains(&expected).then_some(())
    })?;
    let elapsed = start.elapsed();
    child.stop(STOP_TIMEOUT)?;
    Ok(elapsed.as_secs_f64() * 1e3)
}

/// Milliseconds to spawn ten `armor-mod-counter --describe` and see all of them exit.
fn describe_spawns(counter: &Path) -> anyhow::Result<f64> {
    let start = Instant::now();
    let mut children = Vec::with_capacity(MODULES);
    for _ in 0..MODULES {
        let mut command = Command::new(counter);
        command.arg("--describe");
        children.push(ChildGuard::spawn_quiet(
            "armor-mod-counter --describe",
            command,
        )?);
    }
    for child in &mut children {
        let status = child.wait_exit(STOP_TIMEOUT)?;
        if !status.success() {
            return Err(child.failure(&format!("failed ({status})")));
        }
    }
    Ok(start.elapsed().as_secs_f64() * 1e3)
}
