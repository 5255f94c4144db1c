//! Competing behaviours in a real run of the bundled mission over them
//! (`missions/robot/mission-behaviours.xml`, on `system-behaviours.xml`):
//! a crate the sim has and the world file does not makes the obstacle-avoidance behaviour (`vff`)
//! win control from go-to-goal (the follower) as the robot comes near, and give it back once
//! past, and stop wins once the goal is reached (the others asleep in the mission's last
//! place); `armor ctl status --json` shows every state and its time line, the text form each
//! module's behaviour, and the mission's report the same time line.
#![allow(clippy::unwrap_used)]

use std::process::Command;
use std::time::{Duration, Instant};

use armor_protocol::{BehaviourState, Status};
use armor_tests::{PATIENCE, Proc, bin, bin_dir, field, workspace_root};

/// Run time is twice real time; the robot meets the crate after about 10 s of run time.
const DEADLINE: Duration = Duration::from_secs(120);

fn ctl_status(addr: &str, json: bool) -> String {
    let mut command = Command::new(bin("armor"));
    command.args(["ctl", "--addr", addr, "status"]);
    if json {
        command.arg("--json");
    }
    let output = command.output().unwrap();
    assert!(output.status.success(), "{output:?}");
    String::from_utf8(output.stdout).unwrap()
}

fn state_of(status: &Status, module: &str) -> Option<BehaviourState> {
    status
        .modules
        .iter()
        .find(|m| m.name == module)
        .and_then(|m| m.behaviour)
}

#[test]
fn an_obstacle_makes_avoidance_win_and_then_give_control_back() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg("missions/robot/mission-behaviours.xml")
            .args(["--time-scale", "2", "--report"])
            .arg(&report)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(workspace_root()),
    );
    let line = run.wait_for("the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();

    let started = Instant::now();
    loop {
        assert!(
            started.elapsed() < DEADLINE,
            "vff never won and lost; the run said:\n{}",
            run.lines().join("\n")
        );
        let status: Status = serde_json::from_str(&ctl_status(&addr, true)).unwrap();
        let changes = |module: &str, state: BehaviourState| {
            status
                .behaviour_changes
                .iter()
                .position(|c| c.module == module && c.state == Some(state))
        };
        // The time line: vff became the winner, and after that the follower won again.
        if let Some(won) = changes("vff", BehaviourState::Winner) {
            let back = status.behaviour_changes[won..]
                .iter()
                .any(|c| c.module == "follower" && c.state == Some(BehaviourState::Winner));
            if back {
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    // The text form names each behaviour's state.
    let text = ctl_status(&addr, false);
    assert!(
        text.lines()
            .any(|l| l.starts_with("  vff (vff): running,") && l.contains(", behaviour ")),
        "{text}"
    );
    assert!(text.contains("arbiter (arbiter): running"), "{text}");
    // Past the crate the follower drives on to the goal, and once there the mission puts it
    // and vff to sleep: stop, the last resort, takes control.
    let status = loop {
        assert!(
            started.elapsed() < DEADLINE,
            "the goal was never reached; the run said:\n{}",
            run.lines().join("\n")
        );
        let status: Status = serde_json::from_str(&ctl_status(&addr, true)).unwrap();
        if state_of(&status, "stop") == Some(BehaviourState::Winner)
            && state_of(&status, "follower") == Some(BehaviourState::Slept)
            && state_of(&status, "vff") == Some(BehaviourState::Slept)
        {
            break status;
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(
        run.lines()
            .iter()
            .any(|l| l.contains("event follower.goal_reached"))
    );
    // The time line's times are run times, in order.
    let times: Vec<f64> = status
        .behaviour_changes
        .iter()
        .map(|c| c.run_secs)
        .collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
    assert!(
        times
            .iter()
            .all(|t| *t > 0.0 && *t <= status.run_secs + 0.5)
    );
    // At any moment, one winner at most, and it is the module the arbiter names.
    let arbiter = status.modules.iter().find(|m| m.name == "arbiter").unwrap();
    let winners: Vec<&str> = status
        .modules
        .iter()
        .filter(|m| m.behaviour == Some(BehaviourState::Winner))
        .map(|m| m.name.as_str())
        .collect();
    assert!(winners.len() <= 1, "{winners:?}");
    assert_eq!(winners.first().copied(), arbiter.winner.as_deref());
    assert_eq!(
        arbiter.behaviour, None,
        "the arbiter is no behaviour: it never says whether it applies"
    );

    // And the arbiter's own log and events tell the same story.
    let lines = run.lines();
    assert!(
        lines
            .iter()
            .any(|l| l.contains("[arbiter]") && l.contains("in control: candidate_1"))
    );
    assert!(
        lines
            .iter()
            .any(|l| l.contains("event arbiter.winner_changed"))
    );

    // The mission ends five seconds later, and its report has the same time line.
    let status = run.wait_exit(DEADLINE);
    assert!(status.success(), "{}", run.lines().join("\n"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["outcome"], "complete");
    let changes: Vec<(String, String)> = report["behaviour_changes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            (
                c["module"].as_str().unwrap().to_owned(),
                c["state"].as_str().unwrap_or("gone").to_owned(),
            )
        })
        .collect();
    let at = |module: &str, state: &str| {
        changes
            .iter()
            .position(|c| c.0 == module && c.1 == state)
            .unwrap_or_else(|| panic!("no {module} {state} in the report: {changes:?}"))
    };
    let last_stop_win = changes
        .iter()
        .rposition(|c| c.0 == "stop" && c.1 == "winner")
        .unwrap();
    assert!(last_stop_win > at("vff", "winner"), "{changes:?}");
    assert!(at("follower", "slept") > at("vff", "winner"), "{changes:?}");
}
