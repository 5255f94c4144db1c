//! The run's health stream and fallback sources, with faults injected on a real `armor run`:
//! the mapper that gives the follower its pose is killed (SIGKILL), then stopped (SIGSTOP),
//! while the robot drives. The follower's pose moves to the simulator's odometry (its
//! fallback) and back when the mapper recovers, the robot arrives, and a `monitor` module
//! hears every report of the stream in the order the run sent them.
#![allow(clippy::unwrap_used)]

use std::process::Command;
use std::time::{Duration, Instant};

use armor_module_api::types::Pose2D;
use armor_module_api::{Event, ModuleSpec, Node};
use armor_tests::mission::MISSION_DEADLINE;
use armor_tests::{
    PATIENCE, Proc, bin, bin_dir, ctl_status, field, test_node, wait_until, workspace_root,
};

const SIGKILL: i32 = 9;
const SIGSTOP: i32 = 19;

const SYSTEM: &str = r#"<system name="fallback">
  <module name="sim" type="sim"><param name="world" value="yard.world"/></module>
  <module name="mapper" type="mapper"/>
  <module name="follower" type="follower">
    <param name="world" value="yard.world"/>
    <param name="goal_x_m" value="28"/>
    <param name="goal_y_m" value="4"/>
    <param name="blocked_after_secs" value="20"/>
  </module>
  <module name="avoider" type="avoider"/>
  <module name="mux" type="mux"/>
  <module name="monitor" type="monitor"/>
  <link from="sim.odometry" to="mapper.odometry"/>
  <link from="sim.scan" to="mapper.scan"/>
  <link from="mapper.pose" to="follower.odometry"/>
  <link from="sim.odometry" to="follower.odometry" fallback="1"/>
  <link from="sim.scan" to="avoider.scan"/>
  <link from="sim.scan" to="follower.scan"/>
  <link from="follower.cmd_desired" to="avoider.cmd_desired"/>
  <link from="avoider.cmd_vel" to="mux.auto"/>
  <link from="mux.cmd_vel" to="sim.cmd_vel"/>
  <link from="armor.health" to="monitor.health"/>
</system>"#;

fn pid_of(status: &serde_json::Value, module: &str) -> Option<i32> {
    status["modules"]
        .as_array()?
        .iter()
        .find(|row| row["name"] == module && row["state"] == "running")?["pid"]
        .as_i64()
        .map(|pid| pid as i32)
}

/// The robot's true x, as the simulator last published it, reading `node` for up to `for_secs`.
fn true_x(node: &mut Node, pose: &armor_module_api::Input<Pose2D>, last: &mut f64, wait: Duration) {
    let deadline = Instant::now() + wait;
    while Instant::now() < deadline {
        if let Ok(Event::Input(_)) = node.next_event(Some(Duration::from_millis(20))) {
            while let Ok(Some(sample)) = node.take(pose) {
                *last = sample.value.x_m;
            }
        }
    }
}

/// The health reports as the run logged them (`mapper failed (its connection closed)`), and as
/// the monitor did, with its sequence numbers.
fn reports(run: &Proc) -> (Vec<String>, Vec<(u64, String)>) {
    let lines = run.lines();
    let sent = lines
        .iter()
        .filter_map(|line| {
            line.split_once("health: `")
                .map(|(_, rest)| rest.replacen('`', "", 1))
        })
        .collect();
    let heard = lines
        .iter()
        .filter(|line| line.starts_with("[monitor]"))
        .filter_map(|line| {
            let rest = line.split_once("health #")?.1;
            let (seq, rest) = rest.split_once(" at ")?;
            let report = rest.split_once(" later): ")?.1;
            Some((seq.parse().ok()?, report.to_owned()))
        })
        .collect();
    (sent, heard)
}

#[test]
fn a_killed_or_frozen_mapper_does_not_stop_the_robot() {
    let dir = tempfile::tempdir().unwrap();
    let system = dir.path().join("system.xml");
    std::fs::write(&system, SYSTEM).unwrap();
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&system)
            .args(["--time-scale", "2", "--lease-secs", "0.5"])
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(workspace_root()),
    );
    let line = run.wait_for("with the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();
    run.wait_for("every module configured", PATIENCE, |line| {
        line.contains("modules configured")
    });
    let first = ctl_status(&addr);
    let agent = first["agent"].as_str().unwrap().parse().unwrap();
    let mut watcher = test_node(
        ModuleSpec::new("watcher", "the test's eye on the robot").input::<Pose2D>("pose", "truth"),
        agent,
        &[("pose", "sim.pose_truth")],
    );
    let pose = watcher.input::<Pose2D>("pose").unwrap();
    let mut x = 0.0;
    let start = Instant::now();
    while x < 5.0 {
        assert!(start.elapsed() < PATIENCE, "the robot never left (x = {x})");
        true_x(&mut watcher, &pose, &mut x, Duration::from_millis(100));
    }

    // SIGKILL: failed at once, the pose from the odometry, the mapper back, the pose from it.
    let mapper = pid_of(&first, "mapper").unwrap();
    armor_tests::signal(mapper, SIGKILL);
    run.wait_for("the switch back after the kill", PATIENCE, |line| {
        line.starts_with("[monitor]") && line.contains("sim.odometry → mapper.pose")
    });
    let before = x;
    true_x(&mut watcher, &pose, &mut x, Duration::from_millis(500));
    assert!(
        x > before,
        "the robot stopped after the kill: {before} → {x}"
    );

    // SIGSTOP: stalled within the lease, the fallback, then killed, restarted, switched back.
    let mut mapper = None;
    wait_until("the new mapper", PATIENCE, || {
        mapper = pid_of(&ctl_status(&addr), "mapper");
        mapper.is_some()
    });
    let skip = run.line_count();
    armor_tests::signal(mapper.unwrap(), SIGSTOP);
    run.wait_for_from(skip, "the switch back after the stop", PATIENCE, |line| {
        line.starts_with("[monitor]") && line.contains("sim.odometry → mapper.pose")
    });
    let before = x;
    true_x(&mut watcher, &pose, &mut x, Duration::from_millis(500));
    assert!(
        x > before,
        "the robot stopped after the stop: {before} → {x}"
    );

    run.wait_for("the robot at its goal", MISSION_DEADLINE, |line| {
        line.contains("event follower.goal_reached")
    });
    wait_until("the monitor caught up", PATIENCE, || {
        let (sent, heard) = reports(&run);
        sent.len() == heard.len()
    });
    let (sent, heard) = reports(&run);
    let numbered: Vec<(u64, String)> = (1..).zip(sent).collect();
    assert_eq!(heard, numbered, "every report, in order");
    let about_mapper: Vec<&str> = heard
        .iter()
        .filter(|(_, report)| report.starts_with("mapper "))
        .map(|(_, report)| report.split(' ').nth(1).unwrap())
        .collect();
    assert_eq!(
        about_mapper,
        [
            "failed",
            "restarting",
            "recovered",
            "stalled",
            "failed",
            "restarting",
            "recovered"
        ]
    );
    let switches: Vec<&str> = heard
        .iter()
        .filter_map(|(_, report)| report.strip_prefix("follower switched (follower.odometry: "))
        .collect();
    assert_eq!(
        switches,
        [
            "mapper.pose → sim.odometry)",
            "sim.odometry → mapper.pose)",
            "mapper.pose → sim.odometry)",
            "sim.odometry → mapper.pose)"
        ]
    );
    // The follower heard, on its input, that its provider failed: at the kill and at the stop.
    let told = run
        .lines()
        .iter()
        .filter(|line| {
            line.starts_with("[follower]") && line.contains("provider of `odometry` failed")
        })
        .count();
    assert_eq!(told, 2);
    run.signal(2);
    let _ = run.wait_exit(PATIENCE);
}
