//! The simulated robot's missions (`missions/robot/`), run headless by `armor run` faster than
//! real time, as a user would: each must end in its final place with exactly the planned
//! arrivals, observations and waits, without the robot touching anything and without the
//! follower ever being stuck. A goal inside an obstacle ends the mission in its contingency.
#![allow(clippy::unwrap_used)]

use std::process::Command;

use armor_tests::mission::{Finished, MISSION_DEADLINE, armor_run};
use armor_tests::{PATIENCE, bin, bin_dir, field, process_alive, workspace_root};

/// The one leg ended in `aborted_leg` because the follower was blocked, the robot having touched
/// nothing.
fn assert_aborted_without_a_collision(run: &Finished) {
    assert_eq!(run.fired_names(), ["blocked_1"]);
    assert_eq!(run.final_marking(), serde_json::json!({ "aborted_leg": 1 }));
    assert!(
        run.any_line(
            |line| line.starts_with("[follower]") && line.contains("no progress towards the goal")
        ),
        "{}",
        run.lines.join("\n")
    );
    assert!(
        !run.any_line(|line| line.contains("event sim.collision")),
        "the robot hit something:\n{}",
        run.lines.join("\n")
    );
}

/// Runs a mission to its end; it must exit 0 within [`MISSION_DEADLINE`].
fn run_mission(mission: &std::path::Path) -> Finished {
    armor_tests::mission::run_mission(mission, &[], MISSION_DEADLINE)
}

fn robot_mission(name: &str) -> std::path::PathBuf {
    workspace_root().join("missions/robot").join(name)
}

#[test]
fn the_yard_patrol_looks_around_waits_and_comes_back_clean() {
    let run = run_mission(&robot_mission("yard.xml"));
    assert_eq!(
        run.fired_names(),
        [
            "arrived_1",
            "observed_1",
            "arrived_2",
            "arrived_3",
            "waited_3",
            "arrived_4"
        ]
    );
    assert_eq!(run.final_marking(), serde_json::json!({ "done": 1 }));
    run.assert_clean();
    // A full turn at the observer's 0.6 rad/s takes 10.5 s of run time; the wait is 3 s.
    let observing = run.between("arrived_1", "observed_1");
    assert!(observing >= 10.0, "observed for {observing} s");
    let waiting = run.between("arrived_3", "waited_3");
    assert!(waiting >= 3.0, "waited for {waiting} s");
    // The mux handed the robot from navigation to the observer and back.
    for source in ["auto", "observe", "none"] {
        assert!(
            run.any_line(
                |line| line.starts_with("[mux]") && line.contains(&format!("in control: {source}"))
            ),
            "mux never gave control to {source}:\n{}",
            run.lines.join("\n")
        );
    }
}

#[test]
fn the_building_mission_goes_through_two_doorways_clean() {
    let run = run_mission(&robot_mission("building.xml"));
    assert_eq!(
        run.fired_names(),
        [
            "arrived_1",
            "arrived_2",
            "arrived_3",
            "arrived_4",
            "arrived_5"
        ]
    );
    assert_eq!(run.final_marking(), serde_json::json!({ "done": 1 }));
    run.assert_clean();
}

#[test]
fn the_field_mission_crosses_the_clutter_clean() {
    let run = run_mission(&robot_mission("field.xml"));
    assert_eq!(
        run.fired_names(),
        ["arrived_1", "arrived_2", "arrived_3", "arrived_4"]
    );
    assert_eq!(run.final_marking(), serde_json::json!({ "done": 1 }));
    run.assert_clean();
}

/// Two legs in a row to the same goal: the second must end with its own `goal_reached`. The
/// follower is active in both places and its goal does not change, so nothing would tell it that
/// a new leg began: the controller starts the modules of a place entered afresh.
#[test]
fn two_legs_in_a_row_to_the_same_goal_both_arrive() {
    let system = robot_mission("system.xml");
    let leg = |name: &str, tokens: u32| {
        format!(
            r#"<place name="{name}" tokens="{tokens}">
    <module name="follower"/>
    <module name="avoider"/>
    <param module="follower" name="goal_x_m" value="6"/>
    <param module="follower" name="goal_y_m" value="4"/>
  </place>"#
        )
    };
    let mission = format!(
        r#"<mission name="same-goal-twice" system="{}">
  {}
  {}
  <place name="done" final="true"/>
  <transition name="arrived_1" event="follower.goal_reached">
    <input place="leg_1"/>
    <output place="leg_2"/>
  </transition>
  <transition name="arrived_2" event="follower.goal_reached">
    <input place="leg_2"/>
    <output place="done"/>
  </transition>
</mission>"#,
        system.display(),
        leg("leg_1", 1),
        leg("leg_2", 0)
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("same-goal.xml");
    std::fs::write(&file, mission).unwrap();
    let run = run_mission(&file);
    assert_eq!(run.fired_names(), ["arrived_1", "arrived_2"]);
    assert_eq!(run.final_marking(), serde_json::json!({ "done": 1 }));
    run.assert_clean();
}

/// A one-leg yard mission whose goal lies inside the shipping container (18..30 × 8..10.4), with
/// or without a way out when the follower reports `blocked`.
fn into_the_container(handled: bool) -> String {
    one_leg("into-the-container", (24.0, 9.2), handled)
}

/// A one-leg yard mission named `name` to `goal`, with or without a way out when the follower
/// reports `blocked`.
fn one_leg(name: &str, (goal_x_m, goal_y_m): (f64, f64), handled: bool) -> String {
    let system = robot_mission("system.xml");
    let contingency = if handled {
        r#"
  <place name="aborted_leg" final="true"/>
  <transition name="blocked_1" event="follower.blocked">
    <input place="leg_1"/>
    <output place="aborted_leg"/>
  </transition>"#
    } else {
        ""
    };
    format!(
        r#"<mission name="{name}" system="{}">
  <place name="leg_1" tokens="1">
    <module name="follower"/>
    <module name="avoider"/>
    <param module="follower" name="goal_x_m" value="{goal_x_m}"/>
    <param module="follower" name="goal_y_m" value="{goal_y_m}"/>
  </place>
  <place name="done" final="true"/>
  <transition name="arrived_1" event="follower.goal_reached">
    <input place="leg_1"/>
    <output place="done"/>
  </transition>{contingency}
</mission>"#,
        system.display()
    )
}

/// Nothing refuses a goal inside an obstacle: `armor check` knows no world, and the follower
/// drives towards it until the avoider holds the robot in front of the container. The follower
/// then reports `blocked`. Unhandled, that leaves the mission waiting for `goal_reached` for
/// ever (it would end only by `--for`, with status 0, or by an operator's abort); handled, the
/// mission ends at once in its `aborted_leg` place (a final place, so status 0 too: the report
/// and the log say how it ended).
#[test]
fn a_goal_inside_an_obstacle_ends_the_mission_in_its_contingency() {
    let dir = tempfile::tempdir().unwrap();
    let handled = dir.path().join("handled.xml");
    let unhandled = dir.path().join("unhandled.xml");
    std::fs::write(&handled, into_the_container(true)).unwrap();
    std::fs::write(&unhandled, into_the_container(false)).unwrap();
    for mission in [&handled, &unhandled] {
        let output = Command::new(bin("armor"))
            .arg("check")
            .arg(mission)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .output()
            .unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stdout)
        );
    }

    let stuck = armor_run(&unhandled, &dir.path().join("unhandled.json"), &[]);
    let run = run_mission(&handled);
    assert_aborted_without_a_collision(&run);
    assert!(
        run.any_line(|line| line.contains("mission `into-the-container` complete: {aborted_leg}")),
        "{}",
        run.lines.join("\n")
    );

    // Without the contingency the same report changes nothing: the mission still waits.
    let line = stuck.wait_for("with the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();
    stuck.wait_for("reporting the follower blocked", MISSION_DEADLINE, |line| {
        line.contains("event follower.blocked")
    });
    let status = Command::new(bin("armor"))
        .args(["ctl", "--addr", &addr, "status"])
        .output()
        .unwrap();
    let status = String::from_utf8_lossy(&status.stdout);
    assert!(
        status.contains("arrived_1 (waits for follower.goal_reached)"),
        "{status}"
    );
    assert!(status.contains(": {leg_1}, "), "{status}");
    assert!(process_alive(stuck.pid()), "{}", stuck.lines().join("\n"));
    assert!(!stuck.lines().iter().any(|line| line.contains("fired")));
}

/// A goal outside the world (the yard is 40 m × 30 m): the robot drives east until the avoider
/// has slowed it to a halt in front of the boundary, never touching it nor leaving the world,
/// and the follower reports `blocked`, which ends the mission in its contingency.
#[test]
fn a_goal_outside_the_world_ends_in_the_contingency_without_a_collision() {
    let dir = tempfile::tempdir().unwrap();
    let mission = dir.path().join("outside.xml");
    std::fs::write(&mission, one_leg("beyond-the-fence", (60.0, 2.0), true)).unwrap();
    assert_aborted_without_a_collision(&run_mission(&mission));
}
