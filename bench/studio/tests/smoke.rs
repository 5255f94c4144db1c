//! The binary itself, as `armor-bench` runs it. Having an integration test also makes
//! `cargo test --workspace` build `armor-studio-bench` next to `armor-bench`, which relays its
//! lines (`armor_bench`'s `studio_figures_are_relayed_from_armor_studio`).

use std::process::Command;

fn studio_bench(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_armor-studio-bench"))
        .args(args)
        .output()
        .expect("armor-studio-bench runs")
}

#[test]
fn a_named_figure_is_one_json_line_with_its_reference() {
    let output = studio_bench(&["--quick", "studio_load_ms_1000_blocks"]);
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{}\n{stdout}\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
    );
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|line| serde_json::from_str(line).expect("a JSON line"))
        .collect();
    assert_eq!(lines.len(), 1, "{stdout}");
    assert_eq!(lines[0]["bench"], "studio_load_ms_1000_blocks");
    assert!(
        lines[0]["ours"].as_f64().is_some_and(|ms| ms > 0.0),
        "{stdout}"
    );
    assert!(
        lines[0]["reference"].as_f64().is_some_and(|ms| ms > 0.0),
        "{stdout}"
    );
}

#[test]
fn monitor_without_its_arguments_says_how_it_is_used() {
    let output = studio_bench(&["monitor"]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("usage: armor-studio-bench monitor"),
        "{stderr}"
    );
}
