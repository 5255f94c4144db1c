//! Alternative strategies in a plan, with faults injected on a real `armor run`: a leg records
//! the mapper's estimate while it drives, and has an alternative that records the odometry
//! instead when the mapper fails for good; the mapper is killed (SIGKILL) each time it comes
//! back until its supervisor gives up on it, the mission switches to the alternative and
//! completes, and its report and summary show the switch.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeSet;
use std::process::Command;
use std::time::Duration;

use armor_tests::{PATIENCE, Proc, bin, bin_dir, ctl_status, field, wait_until, workspace_root};
use serde_json::Value;

const SIGKILL: i32 = 9;

/// The robot in the yard; the follower drives on the localiser's pose (on the yard's map, so
/// that it truly arrives, as the run's rehearsal judges by the simulator's truth), with or
/// without the mapper (which runs all the time: it is not controllable), and two recorders,
/// one of the mapper's pose, one of the odometry, for the plan's two ways.
const SYSTEM: &str = r#"<system name="alternatives">
  <module name="sim" type="sim"><param name="world" value="yard.world"/></module>
  <module name="mapper" type="mapper"/>
  <module name="localiser" type="localiser"><param name="world" value="yard.world"/></module>
  <module name="map_recorder" type="recorder">
    <param name="record" value="mapper.pose"/>
    <param name="file" value="map.mcap"/>
  </module>
  <module name="odometry_recorder" type="recorder">
    <param name="record" value="sim.odometry"/>
    <param name="file" value="odometry.mcap"/>
  </module>
  <module name="follower" type="follower">
    <param name="world" value="yard.world"/>
    <param name="goal_x_m" value="30"/>
    <param name="goal_y_m" value="4"/>
    <param name="blocked_after_secs" value="20"/>
  </module>
  <module name="avoider" type="avoider"/>
  <module name="mux" type="mux"/>
  <link from="sim.odometry" to="mapper.odometry"/>
  <link from="sim.scan" to="mapper.scan"/>
  <link from="sim.odometry" to="localiser.odometry"/>
  <link from="sim.scan" to="localiser.scan"/>
  <link from="localiser.pose" to="follower.odometry"/>
  <link from="localiser.estimate" to="follower.estimate"/>
  <link from="sim.scan" to="avoider.scan"/>
  <link from="sim.scan" to="follower.scan"/>
  <link from="follower.cmd_desired" to="avoider.cmd_desired"/>
  <link from="avoider.cmd_vel" to="mux.auto"/>
  <link from="mux.cmd_vel" to="sim.cmd_vel"/>
</system>"#;

/// From the yard's start (4, 4) to (30, 4), 26 m along the south of the yard: about 50 s of
/// run time, 25 s of real time at the scale the test runs at, long enough to kill the mapper
/// six times on the way.
const PLAN: &str = r#"<plan name="alternatives" system="system.xml">
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="east" lat="43.5615360" lon="1.4693720"/>
  <leg name="out" from="home" to="east">
    <during>
      <module name="map_recorder"/>
      <alternative name="odometry" on="mapper">
        <module name="odometry_recorder"/>
      </alternative>
    </during>
  </leg>
</plan>"#;

fn row<'a>(status: &'a Value, module: &str) -> Option<&'a Value> {
    status["modules"]
        .as_array()?
        .iter()
        .find(|row| row["name"] == module)
}

#[test]
fn a_leg_switches_to_its_alternative_when_the_mapper_is_given_up_and_the_mission_completes() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("system.xml"), SYSTEM).unwrap();
    let plan = dir.path().join("plan.xml");
    std::fs::write(&plan, PLAN).unwrap();
    let report = dir.path().join("report.json");
    let runs = dir.path().join("runs");
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&plan)
            .args(["--time-scale", "2", "--report"])
            .arg(&report)
            .arg("--runs-dir")
            .arg(&runs)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(workspace_root()),
    );
    let line = run.wait_for("with the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();

    // Each process of the mapper killed as soon as it runs, until its supervisor gives up
    // (more than five crashes in ten seconds).
    let mut killed = BTreeSet::new();
    wait_until("the mapper given up", Duration::from_secs(60), || {
        let status = ctl_status(&addr);
        let Some(mapper) = row(&status, "mapper") else {
            return false;
        };
        if mapper["state"] == "failed" {
            return true;
        }
        if mapper["state"] == "running"
            && let Some(pid) = mapper["pid"].as_i64()
            && killed.insert(pid)
        {
            armor_tests::signal(pid as i32, SIGKILL);
        }
        false
    });
    assert!(killed.len() > 5, "killed {killed:?}");
    let status = run.wait_exit(Duration::from_secs(120));
    let lines = run.lines();
    assert!(status.success(), "{status}:\n{}", lines.join("\n"));

    let report: Value = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["outcome"], "complete", "{report:#}");
    let timeline = report["timeline"].as_array().unwrap();
    // The failure for good is taken by the switch to the alternative...
    let failed = timeline
        .iter()
        .find(|entry| entry["kind"] == "failed")
        .unwrap_or_else(|| panic!("no failure in {report:#}"));
    assert_eq!(failed["module"], "mapper");
    assert_eq!(
        failed["latched_by"],
        serde_json::json!(["out_drive_mapper_failed"])
    );
    let fired: Vec<&str> = timeline
        .iter()
        .filter(|entry| entry["kind"] == "fired")
        .map(|entry| entry["transition"].as_str().unwrap())
        .collect();
    assert_eq!(fired, ["out_drive_mapper_failed", "out_arrived_odometry"]);
    // ...which records the odometry instead of the mapper's pose.
    let switch = timeline
        .iter()
        .position(|entry| entry["transition"] == "out_drive_mapper_failed")
        .unwrap();
    let switched = timeline[switch..]
        .iter()
        .find(|entry| entry["kind"] == "demand")
        .unwrap_or_else(|| panic!("no demand after the switch in {report:#}"));
    assert_eq!(switched["running"]["follower"], "place out_drive_odometry");
    assert_eq!(
        switched["running"]["odometry_recorder"],
        "place out_drive_odometry"
    );
    assert!(
        switched["running"].get("map_recorder").is_none(),
        "{switched:#}"
    );
    // The follower drove on through the switch: both ways run it alike, so it is not
    // started again on its path.
    assert!(
        !lines
            .iter()
            .any(|line| line.contains("restarting the modules of a place entered")),
        "{}",
        lines.join("\n")
    );
    // The run's summary says so too, and each way left its recording in the run's folder.
    let folder = std::fs::read_dir(&runs)
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .find(|dir| dir.join("summary.txt").exists())
        .unwrap_or_else(|| panic!("no summary.txt under {}", runs.display()));
    let summary = std::fs::read_to_string(folder.join("summary.txt")).unwrap();
    for file in ["map.mcap", "odometry.mcap"] {
        assert!(
            folder.join(file).exists(),
            "no {file} in {}",
            folder.display()
        );
    }
    assert!(summary.contains("complete"), "{summary}");
    assert!(
        summary.contains("switched to `odometry`: `mapper` failed"),
        "{summary}"
    );
}
