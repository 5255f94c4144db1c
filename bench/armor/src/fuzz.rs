//! `fuzz_execs`: inputs run through every parser's fuzz target (`fuzz/run.sh`), and the crashes
//! found (must be 0). One line for all targets: `ours` is the total, `targets` has each target's
//! executions and crashes. Needs cargo-fuzz; without it the bench fails, saying how to install it
//! (a figure of 0 would read as a parser that runs nothing).

use std::path::Path;
use std::process::Command;

use anyhow::{Context as _, bail};

use crate::Settings;
use armor_bench_report::Report;

pub const NAME: &str = "fuzz_execs";

const RUN_SH: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../fuzz/run.sh");

fn cargo_fuzz_available() -> bool {
    Command::new("cargo")
        .args(["fuzz", "--version"])
        .output()
        .is_ok_and(|out| out.status.success())
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let seconds: u32 = if settings.quick { 1 } else { 5 };
    let missing = if !Path::new(RUN_SH).exists() {
        Some(format!("{RUN_SH} not found (run from a source checkout)"))
    } else if !cargo_fuzz_available() {
        Some("cargo-fuzz is not installed (cargo install cargo-fuzz --locked)".to_owned())
    } else {
        None
    };
    if let Some(why) = missing {
        bail!("cannot measure: {why}");
    }
    let out = Command::new(RUN_SH)
        .arg(seconds.to_string())
        .output()
        .with_context(|| format!("running {RUN_SH}"))?;
    // Exit 1 is a crash, reported in the figures; anything else is a failure to run.
    if !matches!(out.status.code(), Some(0 | 1)) {
        bail!(
            "{RUN_SH} failed ({}):\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let mut total = 0.0;
    let mut crashes = 0;
    let mut targets = serde_json::Map::new();
    for line in String::from_utf8_lossy(&out.stdout).lines() {
        let value: serde_json::Value = serde_json::from_str(line)
            .with_context(|| format!("{RUN_SH} printed `{line}`, not a JSON line"))?;
        let target = value["target"].as_str().unwrap_or("?").to_owned();
        let execs = value["ours"].as_f64().unwrap_or(0.0);
        let found = value["crashes"].as_u64().unwrap_or(0);
        total += execs;
        crashes += found;
        targets.insert(
            target,
            serde_json::json!({ "execs": execs, "crashes": found }),
        );
    }
    if targets.is_empty() {
        bail!("{RUN_SH} reported no target");
    }
    if crashes > 0 {
        eprintln!(
            "{NAME}: {crashes} crash(es); inputs in fuzz/artifacts/, logs in fuzz/logs/:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(Report::single(NAME, "execs", total, 0.0)
        .with("crashes", crashes)
        .with("goal", "crashes = 0")
        .with("seconds_per_target", seconds)
        .with("reference_is", "none (0): a fuzzer has no baseline")
        .with("targets", targets))
}
