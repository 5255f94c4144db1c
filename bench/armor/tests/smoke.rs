//! `armor-bench --quick` runs end to end and prints well-formed lines; no timing is asserted.
//!
//! It needs the module binaries next to `armor-bench` (in `target/debug`), which are built when
//! the whole workspace's tests are (`cargo test --workspace`).
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::{Command, Output};

const BENCH: &str = env!("CARGO_BIN_EXE_armor-bench");

fn bench(args: &[&str]) -> Output {
    Command::new(BENCH)
        .args(args)
        // Module binaries come from next to armor-bench, whatever the caller's environment.
        .env_remove("ARMOR_MODULE_PATH")
        .env_remove("ARMOR_SUPERVISOR")
        .output()
        .unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn quick_run_prints_one_json_line_per_benchmark() {
    let folder = Path::new(BENCH).parent().unwrap();
    for module in [
        "armor",
        "armor-mod-echo",
        "armor-mod-sink",
        "armor-mod-sim",
        "armor-mod-mux",
    ] {
        assert!(
            folder.join(module).is_file(),
            "{module} is missing from {}: build the whole workspace (cargo test --workspace)",
            folder.display()
        );
    }
    // (name, unit, whether it is a distribution)
    let expected = [
        ("latency_64b", "us", true),
        ("throughput_64b", "msg/s", false),
        ("event_to_start_ms", "ms", true),
        ("reachability_states_per_s", "states/s", false),
        ("sim_realtime_factor", "sim s/s", false),
        ("mapper_scan_ms", "ms", true),
        ("latency_64kib", "us", true),
        ("throughput_1kib", "msg/s", false),
        ("pull_latest", "us", true),
    ];
    let names: Vec<&str> = expected.iter().map(|(name, _, _)| *name).collect();
    let mut args = vec!["--quick"];
    args.extend(&names);
    let output = bench(&args);
    let stdout = text(&output.stdout);
    assert!(
        output.status.success(),
        "{}\nstdout:\n{stdout}\nstderr:\n{}",
        output.status,
        text(&output.stderr)
    );
    let lines: Vec<&str> = stdout.lines().collect();
    assert_eq!(lines.len(), expected.len(), "stdout:\n{stdout}");
    for (line, (name, unit, distribution)) in lines.iter().zip(expected) {
        let value: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(value["bench"], name, "{line}");
        assert_eq!(value["unit"], unit, "{line}");
        for field in ["ours", "reference", "ratio"] {
            let number = value[field].as_f64();
            assert!(
                number.is_some_and(|x| x.is_finite() && x > 0.0),
                "{field} is not a positive number: {line}"
            );
        }
        if distribution {
            for field in ["p50", "p99", "reference_p50", "reference_p99"] {
                assert!(
                    value[field].as_f64().is_some_and(|x| x > 0.0),
                    "{field} missing: {line}"
                );
            }
        }
    }
    // Five dining philosophers: the companion Pell number Q(5).
    let reachability: serde_json::Value = serde_json::from_str(lines[3]).unwrap();
    assert_eq!(reachability["states"], 82, "{}", lines[3]);
    // The robot's figures say what they are measured against.
    let sim: serde_json::Value = serde_json::from_str(lines[4]).unwrap();
    assert_eq!(sim["goal"], 50.0, "{}", lines[4]);
    assert!(sim["reference_is"].is_string(), "{}", lines[4]);
    let mapper: serde_json::Value = serde_json::from_str(lines[5]).unwrap();
    assert!(mapper["reference_is"].is_string(), "{}", lines[5]);
    // The messaging benches say their size.
    for (line, bytes) in [(lines[0], 64), (lines[6], 64 * 1024), (lines[7], 1024)] {
        let value: serde_json::Value = serde_json::from_str(line).unwrap();
        assert_eq!(value["bytes"], bytes, "{line}");
    }
}

#[test]
fn unknown_benchmark_is_refused_by_name() {
    let output = bench(&["--quick", "latency_64b", "no_such_bench"]);
    assert!(!output.status.success());
    assert!(
        output.stdout.is_empty(),
        "nothing runs: {}",
        text(&output.stdout)
    );
    let stderr = text(&output.stderr);
    assert!(
        stderr.contains("unknown benchmark `no_such_bench`") && stderr.contains("latency_64b"),
        "{stderr}"
    );
}

#[test]
fn list_names_every_benchmark() {
    let output = bench(&["--list"]);
    assert!(output.status.success());
    let stdout = text(&output.stdout);
    for name in [
        "latency_64b",
        "latency_1kib",
        "latency_64kib",
        "latency_1mib",
        "pull_latest",
        "discovery_ms",
        "throughput_1mib",
        "throughput_64b",
        "throughput_1kib",
        "throughput_64kib",
        "fanout_64b",
        "startup_10_modules",
        "event_to_start_ms",
        "reachability_states_per_s",
        "sim_realtime_factor",
        "mapper_scan_ms",
        "loop_closure_error_m",
    ] {
        assert!(stdout.contains(name), "{stdout}");
    }
}

/// Not a timing: the mapper's error after the loop is the same on any machine and load, so its
/// goal is checked here.
#[test]
fn loop_closure_meets_its_goal_on_the_quick_seed() {
    let output = bench(&["--quick", "loop_closure_error_m"]);
    let stdout = text(&output.stdout);
    assert!(
        output.status.success(),
        "{}\nstdout:\n{stdout}\nstderr:\n{}",
        output.status,
        text(&output.stderr)
    );
    let value: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(value["bench"], "loop_closure_error_m", "{stdout}");
    assert_eq!(value["unit"], "m", "{stdout}");
    let without = value["reference"].as_f64().unwrap();
    let ratio = value["ratio"].as_f64().unwrap();
    assert!(without > 0.2, "the mapper alone must drift: {stdout}");
    assert!(
        ratio <= value["goal_ratio_at_most"].as_f64().unwrap(),
        "{stdout}"
    );
}

/// `armor-bench --quick NAMES…`, which must succeed: its lines, one for each name.
fn relayed(names: &[&str]) -> Vec<serde_json::Value> {
    let mut args = vec!["--quick"];
    args.extend(names);
    let output = bench(&args);
    let stdout = text(&output.stdout);
    assert!(
        output.status.success(),
        "{}\nstdout:\n{stdout}\nstderr:\n{}",
        output.status,
        text(&output.stderr)
    );
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|line| serde_json::from_str(line).unwrap())
        .collect();
    assert_eq!(lines.len(), names.len(), "stdout:\n{stdout}");
    lines
}

/// `armor-team` (zenoh) and `armor-studio-bench` measure the team's figures; the relay keeps
/// their percentiles and what they are measured against.
#[test]
fn team_figures_are_relayed_from_armor_team_and_the_studio() {
    let lines = relayed(&["team_status_latency_ms", "station_frame_ms_20_robots"]);
    assert_eq!(lines[0]["bench"], "team_status_latency_ms");
    for field in ["p50", "p99", "reference_p50", "reference_p99"] {
        assert!(
            lines[0][field].as_f64().is_some_and(|x| x > 0.0),
            "{field}: {}",
            lines[0]
        );
    }
    assert_eq!(lines[1]["bench"], "station_frame_ms_20_robots");
    assert_eq!(lines[1]["reference"], 33.0, "{}", lines[1]);
    for line in &lines {
        assert_eq!(line["unit"], "ms", "{line}");
        assert!(line["reference_is"].is_string(), "{line}");
    }
}

#[test]
fn studio_figures_are_relayed_from_armor_studio() {
    let lines = relayed(&["studio_frame_ms_1000_blocks", "studio_load_ms_1000_blocks"]);
    assert_eq!(lines[0]["bench"], "studio_frame_ms_1000_blocks");
    assert_eq!(lines[0]["blocks"], 1000);
    assert_eq!(lines[0]["links"], 1500);
    assert_eq!(lines[1]["bench"], "studio_load_ms_1000_blocks");
    for line in &lines {
        assert_eq!(line["unit"], "ms", "{line}");
        assert!(line["ours"].as_f64().is_some_and(|x| x > 0.0), "{line}");
    }
}

#[test]
fn fuzz_execs_fails_clearly_without_cargo_fuzz() {
    use std::os::unix::fs::PermissionsExt as _;
    // A `cargo` that knows no `fuzz`, first on the PATH: what a machine without cargo-fuzz has.
    let dir = tempfile::tempdir().unwrap();
    let cargo = dir.path().join("cargo");
    std::fs::write(
        &cargo,
        "#!/bin/sh\necho 'error: no such command: `fuzz`' >&2\nexit 101\n",
    )
    .unwrap();
    std::fs::set_permissions(&cargo, std::fs::Permissions::from_mode(0o755)).unwrap();
    let path = format!(
        "{}:{}",
        dir.path().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let output = Command::new(BENCH)
        .args(["--quick", "fuzz_execs"])
        .env("PATH", path)
        .output()
        .unwrap();
    assert!(!output.status.success(), "a figure of 0 must not pass");
    assert!(
        output.stdout.is_empty(),
        "no line: {}",
        text(&output.stdout)
    );
    let stderr = text(&output.stderr);
    assert!(
        stderr.contains("fuzz_execs") && stderr.contains("cargo-fuzz is not installed"),
        "{stderr}"
    );
}

#[test]
fn messages_lost_under_kill_checks_the_killed_providers_own_link() {
    let output = bench(&["--quick", "messages_lost_under_kill"]);
    let stdout = text(&output.stdout);
    assert!(
        output.status.success(),
        "{}\nstdout:\n{stdout}\nstderr:\n{}",
        output.status,
        text(&output.stderr)
    );
    let line: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(line["bench"], "messages_lost_under_kill", "{line}");
    assert_eq!(line["kills"], 2, "{line}");
    // The promise of docs/protocol.md: nothing written before a kill is lost, doubled or
    // reordered.
    assert_eq!(line["ours"], 0.0, "{line}");
    assert!(
        line["written_before_kills"].as_u64().is_some_and(|n| n > 0),
        "{line}"
    );
    // Three generations, each on a link of its own.
    assert_eq!(line["links"], 3, "{line}");
}
