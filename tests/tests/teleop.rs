//! Driving a run through its control interface (`armor ctl teleop`): the teleop module tells
//! the supervisor where it listens (its `teleop` endpoint, shown by `armor ctl status`), the
//! supervisor relays the operator's commands there and answers with the module's own answer;
//! the robot moves while commanded and the module's dead-man stops it when commands stop; a
//! teleop module killed and restarted on another port is followed.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use armor_module_api::types::Pose2D;
use armor_module_api::{Event, ModuleSpec, Node};
use armor_tests::{
    PATIENCE, ctl, ctl_status, driven_system, run_with_control, signal, test_node, wait_until,
};

/// The teleop module's endpoint and pid in the run's status, once it is running and said it.
fn teleop_endpoint(addr: &str) -> Option<(String, i32)> {
    let status = ctl_status(addr);
    let pad = status["modules"]
        .as_array()?
        .iter()
        .find(|module| module["name"] == "pad")?
        .clone();
    if pad["state"] != "running" {
        return None;
    }
    Some((
        pad["endpoints"]["teleop"].as_str()?.to_owned(),
        i32::try_from(pad["pid"].as_i64()?).ok()?,
    ))
}

/// The robot's true position, newest sample taken within `wait`.
fn position(node: &mut Node, pose: &armor_module_api::Input<Pose2D>, wait: Duration) -> (f64, f64) {
    let deadline = Instant::now() + wait;
    let mut last = None;
    while Instant::now() < deadline || last.is_none() {
        assert!(Instant::now() < deadline + PATIENCE, "no pose from the sim");
        if let Ok(Event::Input(_)) = node.next_event(Some(Duration::from_millis(20))) {
            while let Ok(Some(sample)) = node.take(pose) {
                last = Some((sample.value.x_m, sample.value.y_m));
            }
        }
    }
    last.unwrap()
}

fn distance(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

#[test]
fn armor_ctl_teleop_drives_the_robot_and_the_dead_man_stops_it() {
    let dir = tempfile::tempdir().unwrap();
    let (run, addr) = run_with_control(&driven_system(dir.path()));
    let mut endpoint = None;
    wait_until("the teleop's endpoint in the status", PATIENCE, || {
        endpoint = teleop_endpoint(&addr);
        endpoint.is_some()
    });
    let (endpoint, pad_pid) = endpoint.unwrap();
    assert!(endpoint.starts_with("127.0.0.1:"), "{endpoint}");
    let (ok, text) = ctl(&addr, &["status"]);
    assert!(ok);
    assert!(
        text.contains(&format!("teleop at {endpoint}")),
        "armor ctl status shows where the teleop listens:\n{text}"
    );

    let agent = ctl_status(&addr)["agent"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();
    let mut watcher = test_node(
        ModuleSpec::new("watcher", "the test's eye on the robot").input::<Pose2D>("pose", "truth"),
        agent,
        &[("pose", "sim.pose_truth")],
    );
    let pose = watcher.input::<Pose2D>("pose").unwrap();
    let start = position(&mut watcher, &pose, Duration::from_millis(300));

    // Held for a second and a half, ten commands a second: the robot drives.
    let (ok, text) = ctl(&addr, &["teleop", "0.3", "0", "--for", "1.5"]);
    assert!(ok, "{text}");
    assert!(text.contains("teleop `pad`"), "{text}");
    let driven = position(&mut watcher, &pose, Duration::from_millis(200));
    assert!(
        distance(start, driven) > 0.2,
        "the robot did not move: {start:?} → {driven:?}"
    );

    // One command, then nothing: the module's dead-man (half a second) stops the robot.
    let before = position(&mut watcher, &pose, Duration::from_millis(200));
    let (ok, text) = ctl(&addr, &["teleop", "0.3", "0"]);
    assert!(ok, "{text}");
    let mut last = before;
    let mut still_since: Option<Instant> = None;
    wait_until("the robot stopped by the dead-man", PATIENCE, || {
        let now = position(&mut watcher, &pose, Duration::from_millis(100));
        let still = distance(now, last) < 1e-9;
        last = now;
        if !still {
            still_since = None;
        } else if still_since.get_or_insert_with(Instant::now).elapsed()
            > Duration::from_millis(500)
        {
            return true;
        }
        false
    });
    let coasted = distance(before, last);
    assert!(
        coasted > 0.0 && coasted < 0.6,
        "one command drives for the dead-man time only: moved {coasted} m"
    );

    // `stop`, and what is refused, in the operator's words.
    let (ok, text) = ctl(&addr, &["teleop", "stop"]);
    assert!(ok, "{text}");
    let (ok, text) = ctl(&addr, &["teleop", "0.3", "0", "--module", "joystick"]);
    assert!(!ok);
    assert!(text.contains("no teleop module `joystick`"), "{text}");

    // The teleop module killed: restarted on another port, which the relay follows.
    signal(pad_pid, 9);
    let mut again = None;
    wait_until("the teleop back with a new endpoint", PATIENCE, || {
        again = teleop_endpoint(&addr).filter(|(_, pid)| *pid != pad_pid);
        again.is_some()
    });
    let before = position(&mut watcher, &pose, Duration::from_millis(200));
    let (ok, text) = ctl(&addr, &["teleop", "0.3", "0", "--for", "1"]);
    assert!(ok, "{text}");
    let after = position(&mut watcher, &pose, Duration::from_millis(200));
    assert!(
        distance(before, after) > 0.1,
        "not driven after the restart: {before:?} → {after:?}"
    );
    drop(run);
}
