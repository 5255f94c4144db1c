//! Missions run headless by `armor run`, operated with `armor ctl`, as a user would.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::Command;

use armor_tests::{PATIENCE, Proc, bin, ctl, field, workspace_root};

fn armor_run(file: &Path, extra: &[&str]) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(file)
            .args(extra)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir()),
    )
}

/// Writes a system (the demo's modules, counter given `counter_params`) and a mission over it.
fn mission_files(counter_attrs: &str, counter_params: &str, mission: &str) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("system.xml"),
        format!(
            r#"<system name="s">
  <module name="counter" type="counter" {counter_attrs}>{counter_params}</module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>"#
        ),
    )
    .unwrap();
    std::fs::write(dir.path().join("mission.xml"), mission).unwrap();
    dir
}

#[test]
fn the_demo_mission_runs_to_its_final_place_and_reports_its_timeline() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let mission = workspace_root().join("missions/demo/mission.xml");
    let mut run = armor_run(
        &mission,
        &["--time-scale", "10", "--report", report.to_str().unwrap()],
    );
    let status = run.wait_exit(PATIENCE);
    assert!(status.success(), "{status}: {:#?}", run.lines());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let fired: Vec<(&str, f64)> = report["timeline"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|entry| entry["kind"] == "fired")
        .map(|entry| {
            (
                entry["transition"].as_str().unwrap(),
                entry["at_secs"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(
        fired.iter().map(|(name, _)| *name).collect::<Vec<_>>(),
        ["counted", "settled"]
    );
    // Ten values at 0.1 s of run time each, then the two-second delay, in run time.
    assert!(fired[0].1 >= 1.0, "{fired:?}");
    assert!(fired[1].1 - fired[0].1 >= 2.0, "{fired:?}");
    assert_eq!(report["outcome"], "complete");
    // The counter was stopped when its place emptied; the checker saw ten values in order.
    let lines = run.lines();
    assert!(
        lines.iter().any(|line| line.contains("stopped counter")),
        "{lines:#?}"
    );
    assert!(
        lines.iter().any(|line| line.contains("[checker]")
            && line.contains("received 10 values, last 10, in order"))
    );
}

#[test]
fn the_operator_pauses_resumes_and_fires_by_hand() {
    let dir = mission_files(
        "",
        r#"<param name="period_secs" value="0.05"/>"#,
        r#"<mission name="wait-for-the-operator" system="system.xml">
  <place name="waiting" tokens="1"><module name="counter"/><module name="checker"/></place>
  <place name="done" final="true"/>
  <transition name="go" event="checker.out_of_order"><input place="waiting"/><output place="done"/></transition>
</mission>"#,
    );
    let mut run = armor_run(&dir.path().join("mission.xml"), &[]);
    let line = run.wait_for("with the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();
    run.wait_for("from the counter's first values", PATIENCE, |line| {
        line.contains("received 10 values")
    });

    let (ok, status) = ctl(&addr, &["status"]);
    assert!(ok, "{status}");
    assert!(
        status.contains("go (waits for checker.out_of_order)"),
        "{status}"
    );

    let skip = run.line_count();
    let (ok, message) = ctl(&addr, &["pause"]);
    assert!(ok, "{message}");
    run.wait_for_from(skip, "saying the counter paused", PATIENCE, |line| {
        line.starts_with("[counter]") && line.contains("inactive")
    });
    let (ok, _) = ctl(&addr, &["pause"]);
    assert!(!ok, "pausing twice is refused");

    let skip = run.line_count();
    assert!(ctl(&addr, &["resume"]).0);
    run.wait_for_from(skip, "saying the counter resumed", PATIENCE, |line| {
        line.starts_with("[counter]") && line.contains("active: counting")
    });

    let (ok, message) = ctl(&addr, &["fire", "nonexistent"]);
    assert!(!ok);
    assert!(message.contains("no transition `nonexistent`"), "{message}");
    let (ok, message) = ctl(&addr, &["fire", "go"]);
    assert!(ok, "{message}");
    let status = run.wait_exit(PATIENCE);
    assert!(status.success(), "{status}");
}

#[test]
fn a_module_that_fails_for_good_takes_the_mission_to_its_contingency() {
    // `listener` (a teleop, which runs all the time) cannot listen where it is told (an address
    // of no interface of this machine, which no check can know): it fails at its first start
    // and is not restarted.
    let dir = mission_files(
        "",
        "",
        r#"<mission name="contingency" system="system.xml">
  <place name="counting" tokens="1"><module name="counter"/><module name="checker"/></place>
  <place name="safe" final="true"/>
  <place name="done" final="true"/>
  <transition name="fallback" event="module.listener.failed"><input place="counting"/><output place="safe"/></transition>
  <transition name="counted" event="counter.done"><input place="counting"/><output place="done"/></transition>
</mission>"#,
    );
    let system = dir.path().join("system.xml");
    let text = std::fs::read_to_string(&system).unwrap().replace(
        "</system>",
        r#"  <module name="listener" type="teleop" restart="never"><param name="listen" value="192.0.2.1:9"/></module>
</system>"#,
    );
    std::fs::write(&system, text).unwrap();
    let mut run = armor_run(&dir.path().join("mission.xml"), &[]);
    let status = run.wait_exit(PATIENCE);
    assert!(status.success(), "{status}: {:#?}", run.lines());
    assert!(
        run.lines()
            .iter()
            .any(|line| line.contains("fired `fallback`")),
        "{:#?}",
        run.lines()
    );
}

/// A mission that never ends by itself (the checker sees every value in order).
const ENDLESS: &str = r#"<mission name="endless" system="system.xml">
  <place name="waiting" tokens="1"><module name="counter"/><module name="checker"/></place>
  <place name="done" final="true"/>
  <transition name="go" event="checker.out_of_order"><input place="waiting"/><output place="done"/></transition>
</mission>"#;

#[test]
fn aborting_ends_the_run_with_a_failure() {
    let dir = mission_files("", "", ENDLESS);
    let mut run = armor_run(&dir.path().join("mission.xml"), &[]);
    let line = run.wait_for("with the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();
    assert!(ctl(&addr, &["abort"]).0);
    let status = run.wait_exit(PATIENCE);
    assert_eq!(status.code(), Some(1));
}

#[test]
fn armor_check_finds_what_would_go_wrong() {
    let dir = mission_files(
        "",
        "",
        r#"<mission name="broken" system="system.xml">
  <place name="a" tokens="1"><module name="counter"/><module name="ghost"/></place>
  <place name="b"/>
  <place name="done" final="true"/>
  <transition name="t1" event="counter.finished"><input place="a"/><output place="b"/></transition>
</mission>"#,
    );
    let output = Command::new(bin("armor"))
        .arg("check")
        .arg(dir.path().join("mission.xml"))
        .env("ARMOR_MODULE_PATH", armor_tests::bin_dir())
        .output()
        .unwrap();
    assert_eq!(output.status.code(), Some(1));
    let report = String::from_utf8_lossy(&output.stdout);
    for expected in ["ghost", "finished", "deadlock", "done"] {
        assert!(
            report.contains(expected),
            "`{expected}` missing from:\n{report}"
        );
    }
}

#[test]
fn a_mission_cut_short_by_for_ends_with_a_failure() {
    let dir = mission_files("", "", ENDLESS);
    let mut run = armor_run(&dir.path().join("mission.xml"), &["--for", "1"]);
    let status = run.wait_exit(PATIENCE);
    assert_eq!(status.code(), Some(1));
    assert!(
        run.lines()
            .iter()
            .any(|line| line.contains("run duration reached before the mission ended")),
        "{:#?}",
        run.lines()
    );
}

#[test]
fn a_plain_system_run_is_watched_and_its_modules_started_and_stopped_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let system = dir.path().join("system.xml");
    std::fs::copy(workspace_root().join("missions/demo/system.xml"), &system).unwrap();
    let run = armor_run(&system, &[]);
    let line = run.wait_for("with the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();
    let status = |addr: &str| -> serde_json::Value {
        let (ok, text) = ctl(addr, &["status", "--json"]);
        assert!(ok, "{text}");
        serde_json::from_str(&text[text.find('{').unwrap()..]).unwrap()
    };
    let module = |status: &serde_json::Value, name: &str| -> serde_json::Value {
        status["modules"]
            .as_array()
            .unwrap()
            .iter()
            .find(|module| module["name"] == name)
            .cloned()
            .unwrap()
    };
    let sent = |status: &serde_json::Value| {
        module(status, "counter")["stats"]["sent"]["counter.count"]
            .as_u64()
            .unwrap_or(0)
    };
    // The counters come with the answers to pings (four per 2 s lease): they grow.
    let mut first = 0;
    armor_tests::wait_until("the counter's count to grow", PATIENCE, || {
        let now = status(&addr);
        if first == 0 {
            first = sent(&now);
        }
        first > 0 && sent(&now) > first
    });
    let now = status(&addr);
    assert!(now["mission"].is_null(), "no mission: {now}");
    assert_eq!(module(&now, "counter")["state"], "running");
    assert!(module(&now, "checker")["stats"]["received"]["input"].as_u64() > Some(0));

    let (ok, text) = ctl(&addr, &["status"]);
    assert!(ok);
    assert!(text.contains("  counter (counter): running"), "{text}");

    let skip = run.line_count();
    let (ok, text) = ctl(&addr, &["stop", "counter"]);
    assert!(ok, "{text}");
    run.wait_for_from(skip, "the counter stopping", PATIENCE, |line| {
        line.starts_with("[counter]") && line.contains("inactive")
    });
    let stopped = status(&addr);
    assert_eq!(module(&stopped, "counter")["state"], "stopped");
    assert_eq!(module(&stopped, "counter")["manual"], false);
    let (ok, text) = ctl(&addr, &["stop", "nosuch"]);
    assert!(!ok, "{text}");
    assert!(text.contains("no module `nosuch`"), "{text}");

    let (ok, text) = ctl(&addr, &["release", "counter"]);
    assert!(ok, "{text}");
    let released = status(&addr);
    assert_eq!(module(&released, "counter")["state"], "running");
    assert!(module(&released, "counter")["manual"].is_null());
}
