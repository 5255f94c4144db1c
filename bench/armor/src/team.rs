//! The team's figures (issue 41), relayed as the studio's are:
//!
//! - `team_status_latency_ms` and `team_bandwidth_kbps_per_robot` from `armor-team bench`, the
//!   only program that links zenoh (`armor-bench` does not, so that `cargo build` of the rest
//!   builds no zenoh);
//! - `station_frame_ms_20_robots` from `armor-studio-bench` (the station view is egui's).

use std::process::Command;

use anyhow::Context as _;
use armor_bench_report::Report;

use crate::Settings;
use crate::procs::sibling_binary;

pub const NAME_LATENCY: &str = "team_status_latency_ms";
pub const NAME_BANDWIDTH: &str = "team_bandwidth_kbps_per_robot";
pub const NAME_STATION_FRAME: &str = "station_frame_ms_20_robots";

pub fn run_latency(settings: &Settings) -> anyhow::Result<Report> {
    relay("armor-team", &["bench"], NAME_LATENCY, "ms", settings)
}

pub fn run_bandwidth(settings: &Settings) -> anyhow::Result<Report> {
    relay("armor-team", &["bench"], NAME_BANDWIDTH, "kbit/s", settings)
}

pub fn run_station_frame(settings: &Settings) -> anyhow::Result<Report> {
    relay(
        "armor-studio-bench",
        &[],
        NAME_STATION_FRAME,
        "ms",
        settings,
    )
}

/// Runs `program ARGS… NAME [--quick]` and takes its line for `name` as this report.
fn relay(
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
