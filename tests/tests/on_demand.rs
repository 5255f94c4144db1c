//! Activation on demand, seen as a user sees it: `armor run` of a mission whose places name only
//! what they mean, and `armor ctl status` saying which modules run and why while it goes.
#![allow(clippy::unwrap_used)]

use std::process::Command;

use armor_tests::mission::armor_run;
use armor_tests::{
    PATIENCE, Proc, bin, bin_dir, ctl, ctl_status, field, wait_until, workspace_root,
};
use serde_json::Value;

/// A module's row of a status: its state and why it runs (`null` when nothing needs it).
fn module(status: &Value, name: &str) -> (String, Value) {
    let row = status["modules"]
        .as_array()
        .unwrap()
        .iter()
        .find(|row| row["name"] == name)
        .unwrap_or_else(|| panic!("no module `{name}` in {status:#}"));
    (
        row["state"].as_str().unwrap().to_owned(),
        row["why"].clone(),
    )
}

fn marked(status: &Value, place: &str) -> bool {
    status["mission"]["marking"][place].as_u64().unwrap_or(0) > 0
}

fn control_addr(run: &Proc) -> String {
    let line = run.wait_for("with the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    field(&line, "addr").unwrap().to_owned()
}

/// Waits until the status satisfies `condition`, and returns it.
fn wait_status(addr: &str, what: &str, condition: impl Fn(&Value) -> bool) -> Value {
    let mut last = Value::Null;
    wait_until(what, PATIENCE, || {
        last = ctl_status(addr);
        condition(&last)
    });
    last
}

/// A chain `source → relay → sink`, none controllable by name in the mission but the sink: the
/// place naming the sink brings its provider, and a place naming nothing idles both; the operator
/// starting the source by hand brings nothing downstream of it.
#[test]
fn a_place_brings_the_providers_of_what_it_names_and_idles_them_after() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("system.xml"),
        r#"<system name="chain">
  <module name="source" type="counter"><param name="period_secs" value="0.05"/></module>
  <module name="relay" type="checker"/>
  <module name="sink" type="checker"/>
  <module name="spare" type="counter" activation="explicit"/>
  <module name="steady" type="checker" activation="always"/>
  <link from="source.count" to="relay.input"/>
  <link from="relay.received" to="sink.input"/>
  <link from="spare.count" to="steady.input"/>
</system>"#,
    )
    .unwrap();
    let mission = dir.path().join("mission.xml");
    std::fs::write(
        &mission,
        r#"<mission name="on-demand" system="system.xml">
  <place name="checking" tokens="1"><module name="sink"/></place>
  <place name="resting"/>
  <place name="done" final="true"/>
  <transition name="rest" event="sink.out_of_order"><input place="checking"/><output place="resting"/></transition>
  <transition name="finish" event="sink.out_of_order"><input place="resting"/><output place="done"/></transition>
</mission>"#,
    )
    .unwrap();
    let report = dir.path().join("report.json");
    let run = armor_run(&mission, &report, &[]);
    let addr = control_addr(&run);

    // Every module's process is started with the run, an explicit one too, which then waits
    // stopped: until it has connected it says `starting`, for as long as a slow machine takes.
    let checking = wait_status(&addr, "the chain running for the sink", |status| {
        ["source", "relay", "sink"]
            .iter()
            .all(|name| module(status, name).0 == "running")
            && module(status, "spare").0 != "starting"
    });
    assert_eq!(module(&checking, "sink").1, "place checking");
    assert_eq!(module(&checking, "relay").1, "needed by sink.input");
    assert_eq!(module(&checking, "source").1, "needed by relay.input");
    // An explicit module is not pulled in by the one that always runs and reads it.
    assert_eq!(module(&checking, "steady").1, "always");
    assert_eq!(
        module(&checking, "spare"),
        ("stopped".to_owned(), Value::Null)
    );
    let (_, text) = ctl(&addr, &["status"]);
    assert!(
        text.contains("source (counter): running, needed by relay.input"),
        "{text}"
    );
    run.wait_for("from the sink's first values", PATIENCE, |line| {
        line.starts_with("[sink]") && line.contains("received 10 values")
    });

    assert!(ctl(&addr, &["fire", "rest"]).0);
    let resting = wait_status(&addr, "the chain idle", |status| {
        marked(status, "resting")
            && ["source", "relay", "sink"]
                .iter()
                .all(|name| module(status, name).0 == "stopped")
    });
    assert_eq!(module(&resting, "source").1, Value::Null);
    let (_, text) = ctl(&addr, &["status"]);
    assert!(
        text.contains("source (counter): stopped, not needed"),
        "{text}"
    );

    // By hand, the source runs for itself: nothing it feeds is started for it.
    assert!(ctl(&addr, &["start", "source"]).0);
    let by_hand = wait_status(&addr, "the source started by hand", |status| {
        module(status, "source").0 == "running"
    });
    assert_eq!(module(&by_hand, "source").1, "by hand");
    assert_eq!(module(&by_hand, "relay").0, "stopped");
    // The relay by hand brings the source it needs, which runs on after its release.
    assert!(ctl(&addr, &["release", "source"]).0);
    assert!(ctl(&addr, &["start", "relay"]).0);
    let relay = wait_status(&addr, "the relay started by hand", |status| {
        module(status, "relay").0 == "running" && module(status, "source").1 != "by hand"
    });
    assert_eq!(module(&relay, "source").1, "needed by relay.input");
    assert_eq!(module(&relay, "sink").0, "stopped");
}

/// A plan whose legs name only the follower: the avoider its commands pass through runs while
/// it drives and idles while the robot waits at a waypoint, nothing else needing it; the
/// robot arrives.
#[test]
fn a_plan_naming_only_the_follower_drives_with_the_avoider_it_needs() {
    let dir = tempfile::tempdir().unwrap();
    let plan = dir.path().join("plan.xml");
    let system = workspace_root().join("missions/robot/system.xml");
    std::fs::write(
        &plan,
        format!(
            r#"<plan name="only-the-follower" system="{}">
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="east" lat="43.5615360" lon="1.4691986"/>
  <waypoint name="further" lat="43.5615360" lon="1.4692482"/>
  <leg name="out" from="home" to="east" wait_secs="60"/>
  <leg name="on" from="east" to="further"/>
</plan>"#,
            system.display()
        ),
    )
    .unwrap();
    let checked = Command::new(bin("armor"))
        .arg("check")
        .arg(&plan)
        .env("ARMOR_MODULE_PATH", bin_dir())
        .current_dir(workspace_root())
        .output()
        .unwrap();
    assert!(
        checked.status.success(),
        "{}",
        String::from_utf8_lossy(&checked.stdout)
    );
    let report = dir.path().join("report.json");
    let mut run = armor_run(&plan, &report, &[]);
    let addr = control_addr(&run);

    let driving = wait_status(&addr, "the first leg driven", |status| {
        marked(status, "out_drive") && module(status, "avoider").0 == "running"
    });
    assert_eq!(module(&driving, "follower").1, "place out_drive");
    assert_eq!(
        module(&driving, "avoider").1,
        "carries follower.cmd_desired"
    );
    assert_eq!(module(&driving, "sim").1, "not controllable");
    // The observer feeds only the mux: nothing needs it.
    assert_eq!(
        module(&driving, "observer"),
        ("stopped".to_owned(), Value::Null)
    );

    let waiting = wait_status(&addr, "the wait at the first waypoint", |status| {
        marked(status, "out_wait") && module(status, "avoider").0 == "stopped"
    });
    assert_eq!(module(&waiting, "avoider").1, Value::Null);
    assert_eq!(module(&waiting, "follower").0, "stopped");

    let status = run.wait_exit(armor_tests::mission::MISSION_DEADLINE);
    assert!(status.success(), "{status}:\n{}", run.lines().join("\n"));
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["outcome"], "complete", "{report:#}");
    let ran_avoider = report["timeline"]
        .as_array()
        .unwrap()
        .iter()
        .any(|entry| entry["kind"] == "demand" && entry["running"]["avoider"].is_string());
    assert!(
        ran_avoider,
        "the report names the avoider's runs: {report:#}"
    );
}
