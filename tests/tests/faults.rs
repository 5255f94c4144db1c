//! Faults a robot meets, caused for real on a running `armor run`: a module stopped with SIGSTOP
//! (it must be declared dead within the heartbeat lease and restarted), or paused briefly (it
//! must not be).
#![allow(clippy::unwrap_used)]

use std::process::Command;
use std::time::{Duration, Instant};

use armor_tests::{PATIENCE, Proc, bin, field, process_alive, workspace_root};

const SIGSTOP: i32 = 19;
const SIGCONT: i32 = 18;

/// The lease the tests run with: short, so that they are quick, and far above the milliseconds
/// an idle module takes to answer a ping.
const LEASE_SECS: &str = "0.5";

fn armor_run_demo() -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(workspace_root().join("missions/demo/system.xml"))
            .args(["--lease-secs", LEASE_SECS])
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir()),
    )
}

/// The pid `armor run` logged for `module`, at or after line `skip`.
fn started_pid(run: &Proc, skip: usize, module: &str) -> i32 {
    let line = run.wait_for_from(
        skip,
        &format!("saying {module} started"),
        PATIENCE,
        |line| line.contains("module started") && field(line, "module") == Some(module),
    );
    field(&line, "pid").unwrap().parse().unwrap()
}

fn checker_in_order(line: &str) -> bool {
    line.starts_with("[checker]") && line.contains("received ") && line.ends_with("in order")
}

#[test]
fn a_stopped_module_is_declared_dead_within_the_lease_and_restarted() {
    let run = armor_run_demo();
    let counter = started_pid(&run, 0, "counter");
    run.wait_for("the checker", PATIENCE, checker_in_order);
    let before = run.line_count();
    let stopped_at = Instant::now();
    armor_tests::signal(counter, SIGSTOP);
    let line = run.wait_for_from(before, "the heartbeat verdict", PATIENCE, |line| {
        line.contains("has not answered") && line.contains("`counter`")
    });
    let declared_after = stopped_at.elapsed();
    // A lease of 0.5 s, pings every 0.125 s: declared dead between 0.5 and about 0.75 s after
    // the last answer; a busy machine may add a little.
    assert!(
        declared_after >= Duration::from_millis(350) && declared_after < Duration::from_secs(5),
        "declared dead after {declared_after:?}: {line}"
    );
    let restarted = started_pid(&run, before, "counter");
    assert_ne!(restarted, counter);
    armor_tests::wait_until("the stopped process is gone", PATIENCE, || {
        !process_alive(counter)
    });
    // Data flows again, from the new process, in order.
    let relinked = run.line_count();
    run.wait_for_from(
        relinked,
        "the checker after the restart",
        PATIENCE,
        checker_in_order,
    );
}

#[test]
fn a_module_paused_for_less_than_the_lease_is_left_alone() {
    let run = armor_run_demo();
    let counter = started_pid(&run, 0, "counter");
    run.wait_for("the checker", PATIENCE, checker_in_order);
    let before = run.line_count();
    armor_tests::signal(counter, SIGSTOP);
    // The fault itself: a pause of a fraction of the lease (not a wait for anything).
    std::thread::sleep(Duration::from_millis(150));
    armor_tests::signal(counter, SIGCONT);
    // Two more checker reports prove time has passed well beyond the lease with the module
    // running; by then a wrong verdict would have been logged.
    let first = run.wait_for_from(before, "the checker", PATIENCE, checker_in_order);
    let after_first = run
        .lines()
        .iter()
        .position(|line| *line == first)
        .unwrap_or(before)
        + 1;
    run.wait_for_from(after_first, "the checker again", PATIENCE, checker_in_order);
    let lines = run.lines();
    assert!(
        !lines[before..]
            .iter()
            .any(|line| line.contains("has not answered")),
        "{}",
        lines[before..].join("\n")
    );
    assert!(
        process_alive(counter),
        "the paused counter was not restarted"
    );
}
