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

fn armor_run_file(file: &std::path::Path) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(file)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir()),
    )
}

/// `received N values, last V, …` of a checker's summary line.
fn summary(line: &str) -> (u64, u64) {
    let rest = line.split("received ").nth(1).unwrap();
    let words: Vec<&str> = rest.split([' ', ',']).filter(|w| !w.is_empty()).collect();
    (words[0].parse().unwrap(), words[3].parse().unwrap())
}

#[test]
fn killing_one_module_again_and_again_costs_other_links_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("system.xml");
    std::fs::write(
        &file,
        r#"<system name="kills">
  <module name="victim" type="counter" restart="always"><param name="period_secs" value="0.01"/></module>
  <module name="watch" type="checker"/>
  <module name="steady" type="counter"><param name="period_secs" value="0.002"/></module>
  <module name="steady_check" type="checker"><param name="report_every" value="100"/></module>
  <link from="victim.count" to="watch.input"/>
  <link from="steady.count" to="steady_check.input"/>
</system>"#,
    )
    .unwrap();
    let run = armor_run_file(&file);
    let steady = |line: &str| line.starts_with("[steady_check]") && line.contains("received ");
    let first = run.wait_for("a steady summary", PATIENCE, steady);
    let mut victim = started_pid(&run, 0, "victim");
    for _ in 0..3 {
        let before = run.line_count();
        armor_tests::signal(victim, 9);
        run.wait_for_from(
            before,
            "the watch seeing the new victim",
            PATIENCE,
            |line| line.contains("event watch.restarted"),
        );
        victim = started_pid(&run, before, "victim");
    }
    let skip = run.line_count();
    run.wait_for_from(skip, "a steady summary after the kills", PATIENCE, steady);
    let lines = run.lines();
    let last = lines.iter().rev().find(|line| steady(line)).unwrap();
    let ((n0, v0), (n1, v1)) = (summary(&first), summary(last));
    assert!(n1 > n0, "{first} / {last}");
    // Every value sent on the steady link between the two summaries arrived, once, in order.
    assert_eq!(v1 - v0, n1 - n0, "{first} / {last}");
    assert!(last.ends_with("in order"), "{last}");
    assert!(
        !lines
            .iter()
            .any(|line| line.contains("event steady_check.")),
        "the steady link was disturbed"
    );
}

#[test]
fn a_crash_looping_module_ends_failed_while_the_rest_runs_on() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("system.xml");
    // `broken` cannot listen where it is told (an address of no interface of this machine,
    // which no check can know): it exits at every start, again and again.
    std::fs::write(
        &file,
        std::fs::read_to_string(workspace_root().join("missions/demo/system.xml"))
            .unwrap()
            .replace(
                "</system>",
                r#"<module name="broken" type="teleop"><param name="listen" value="192.0.2.1:9"/></module></system>"#,
            ),
    )
    .unwrap();
    let run = armor_run_file(&file);
    run.wait_for("the verdict on the crash loop", PATIENCE, |line| {
        line.contains("giving up: module.broken.failed")
    });
    // Two checker reports after the verdict: the rest of the system runs on.
    let after = run.line_count();
    let first = run.wait_for_from(
        after,
        "the checker, still at work",
        PATIENCE,
        checker_in_order,
    );
    run.wait_for_from(after, "the checker, again", PATIENCE, |line| {
        checker_in_order(line) && line != first
    });
}

#[test]
fn a_hundred_config_edits_of_every_kind_reach_the_module_or_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("system.xml");
    let demo = std::fs::read_to_string(workspace_root().join("missions/demo/system.xml")).unwrap();
    let with_period = |period: &str| {
        demo.replace(
            r#"<param name="period_secs" value="0.1"/>"#,
            &format!(r#"<param name="period_secs" value="{period}"/>"#),
        )
    };
    std::fs::write(&file, with_period("0.1")).unwrap();
    let run = armor_run_file(&file);
    run.wait_for("all modules configured", PATIENCE, |line| {
        line.contains("all 2 modules configured")
    });
    let mut slowest = Duration::ZERO;
    for edit in 0..100 {
        let skip = run.line_count();
        let started = Instant::now();
        if edit % 5 == 4 {
            // Every fifth edit is broken: reported, and the last good configuration kept.
            std::fs::write(&file, with_period("fast")).unwrap();
            run.wait_for_from(skip, "the broken edit reported", PATIENCE, |line| {
                line.contains("`fast` is not a finite number")
            });
            continue;
        }
        let period = format!("{:.3}", 0.05 + edit as f64 * 0.001);
        let text = with_period(&period);
        match edit % 4 {
            // In place.
            0 => std::fs::write(&file, &text).unwrap(),
            // Truncated, then written in two steps.
            1 => {
                let mut out = std::fs::OpenOptions::new()
                    .write(true)
                    .truncate(true)
                    .open(&file)
                    .unwrap();
                let (head, tail) = text.split_at(text.len() / 2);
                std::io::Write::write_all(&mut out, head.as_bytes()).unwrap();
                std::io::Write::write_all(&mut out, tail.as_bytes()).unwrap();
            }
            // A new file renamed over the old one, as editors save.
            2 => {
                let new = dir.path().join(".system.xml.new");
                std::fs::write(&new, &text).unwrap();
                std::fs::rename(&new, &file).unwrap();
            }
            // Deleted, then created again.
            _ => {
                std::fs::remove_file(&file).unwrap();
                std::fs::write(&file, &text).unwrap();
            }
        }
        let expected = format!("period_secs is now {} s", period.trim_end_matches('0'));
        run.wait_for_from(
            skip,
            &format!("edit {edit}: {expected}"),
            PATIENCE,
            |line| line.starts_with("[counter]") && line.contains(&expected),
        );
        slowest = slowest.max(started.elapsed());
    }
    // Measured, not asserted (a shared machine): the issue asks for under a second.
    println!("slowest valid edit reached the counter after {slowest:?}");
    let lines = run.lines();
    assert!(lines.iter().any(|line| checker_in_order(line)));
}
