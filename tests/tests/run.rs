//! `armor run` as a user runs it: real processes, real sockets, real files.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

use armor_tests::{PATIENCE, Proc, bin, field, process_alive, wait_until, workspace_root};

const SIGKILL: i32 = 9;
const SIGTERM: i32 = 15;

fn armor_run(system: &Path, extra: &[&str]) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(system)
            .args(extra)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir()),
    )
}

/// A copy of the demo system in a temporary folder, so that a test can edit it.
fn demo_copy(period_secs: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("system.xml");
    std::fs::write(&file, demo_xml(period_secs)).unwrap();
    (dir, file)
}

fn demo_xml(period_secs: &str) -> String {
    std::fs::read_to_string(workspace_root().join("missions/demo/system.xml"))
        .unwrap()
        .replace(
            r#"<param name="period_secs" value="0.1"/>"#,
            &format!(r#"<param name="period_secs" value="{period_secs}"/>"#),
        )
}

/// The pid `armor run` logged for a module (or the agent) it started, at or after line `skip`.
fn started_pid(run: &Proc, skip: usize, module: &str) -> i32 {
    let line = run.wait_for_from(
        skip,
        &format!("saying {module} started"),
        PATIENCE,
        |line| {
            if module == "agent" {
                line.contains("agent started")
            } else {
                line.contains("module started") && field(line, "module") == Some(module)
            }
        },
    );
    field(&line, "pid").unwrap().parse().unwrap()
}

/// The number of values the checker says it has received, in a `received N values` line.
fn received(line: &str) -> u64 {
    line.split("received ")
        .nth(1)
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

fn checker_in_order(line: &str) -> bool {
    line.starts_with("[checker]") && line.contains("received ") && line.ends_with("in order")
}

#[test]
fn demo_runs_in_order_and_stops_cleanly_on_sigterm() {
    let system = workspace_root().join("missions/demo/system.xml");
    let mut run = armor_run(&system, &["--time-scale", "10"]);
    let counter = started_pid(&run, 0, "counter");
    let checker = started_pid(&run, 0, "checker");
    let agent = started_pid(&run, 0, "agent");
    run.wait_for("saying all modules are configured", PATIENCE, |line| {
        line.contains("all 2 modules configured")
    });
    run.wait_for(
        "from the checker with 50 values in order",
        PATIENCE,
        |line| checker_in_order(line) && received(line) >= 50,
    );
    assert!(
        !run.lines().iter().any(|line| line.contains("out of order")),
        "{:#?}",
        run.lines()
    );
    run.signal(SIGTERM);
    let status = run.wait_exit(PATIENCE);
    assert!(status.success(), "armor run ended with {status}");
    for pid in [counter, checker, agent] {
        assert!(!process_alive(pid), "process {pid} outlived armor run");
    }
}

#[test]
fn children_die_with_a_killed_supervisor() {
    let system = workspace_root().join("missions/demo/system.xml");
    let run = armor_run(&system, &[]);
    let pids = [
        started_pid(&run, 0, "counter"),
        started_pid(&run, 0, "checker"),
        started_pid(&run, 0, "agent"),
    ];
    run.signal(SIGKILL);
    wait_until(
        "every child is gone after SIGKILL of armor run",
        PATIENCE,
        || pids.iter().all(|&pid| !process_alive(pid)),
    );
}

#[test]
fn a_killed_provider_is_restarted_and_relinked() {
    let system = workspace_root().join("missions/demo/system.xml");
    let run = armor_run(&system, &["--time-scale", "10"]);
    let counter = started_pid(&run, 0, "counter");
    run.wait_for("from the checker", PATIENCE, |line| {
        checker_in_order(line) && received(line) >= 20
    });
    let before_kill = run.line_count();
    armor_tests::signal(counter, SIGKILL);
    let restarted = started_pid(&run, before_kill, "counter");
    assert_ne!(restarted, counter);
    run.wait_for_from(
        before_kill,
        "saying the checker saw the provider restart",
        PATIENCE,
        |line| line.contains("event checker.restarted"),
    );
    // Data flows again from the new process, in order.
    let relinked = run.line_count();
    run.wait_for_from(
        relinked,
        "from the checker after relinking",
        PATIENCE,
        checker_in_order,
    );
}

#[test]
fn links_keep_flowing_without_the_agent_and_late_modules_still_find_providers() {
    let (_dir, file) = demo_copy("0.01");
    let run = armor_run(&file, &[]);
    let agent = started_pid(&run, 0, "agent");
    run.wait_for("from the checker", PATIENCE, checker_in_order);
    let before_kill = run.line_count();
    armor_tests::signal(agent, SIGKILL);
    // The link does not depend on the agent: values keep arriving, in order.
    let first = run.wait_for_from(
        before_kill,
        "from the checker after the agent died",
        PATIENCE,
        checker_in_order,
    );
    let later = run.wait_for_from(before_kill, "from the checker, later", PATIENCE, |line| {
        checker_in_order(line) && received(line) >= received(&first) + 20
    });
    assert!(received(&later) > received(&first));
    // The supervisor brings the agent back; a module added afterwards finds its provider.
    let new_agent = started_pid(&run, before_kill, "agent");
    assert_ne!(new_agent, agent);
    let with_second_checker = demo_xml("0.01").replace(
        "</system>",
        "  <module name=\"late\" type=\"checker\"/>\n  <link from=\"counter.count\" to=\"late.input\"/>\n</system>",
    );
    let before_edit = run.line_count();
    std::fs::write(&file, with_second_checker).unwrap();
    run.wait_for_from(before_edit, "from the late checker", PATIENCE, |line| {
        line.starts_with("[late]") && line.contains("received ")
    });
}

#[test]
fn config_edits_reach_modules_and_broken_edits_are_rejected() {
    let (dir, file) = demo_copy("0.5");
    let run = armor_run(&file, &[]);
    run.wait_for("saying all modules are configured", PATIENCE, |line| {
        line.contains("all 2 modules configured")
    });

    // An edit in place reaches the running counter (live tuning).
    let skip = run.line_count();
    std::fs::write(&file, demo_xml("0.05")).unwrap();
    run.wait_for_from(
        skip,
        "from the counter with the new period",
        PATIENCE,
        |line| {
            line.starts_with("[counter]") && line.contains("period_secs") && line.contains("0.05")
        },
    );

    // A broken edit is reported with its place; the last good configuration stays in force.
    let skip = run.line_count();
    std::fs::write(&file, demo_xml("fast")).unwrap();
    let file_name = file.display().to_string();
    run.wait_for_from(skip, "reporting the broken edit", PATIENCE, |line| {
        line.starts_with(&format!("{file_name}:5:31:"))
            && line.contains("parameter `period_secs` (float): `fast` is not a finite number")
    });
    run.wait_for_from(
        skip,
        "from the checker, still in order",
        PATIENCE,
        checker_in_order,
    );

    // Editors save by writing a new file and renaming it over the old one.
    let skip = run.line_count();
    let temporary = dir.path().join(".system.xml.swp");
    std::fs::write(&temporary, demo_xml("0.07")).unwrap();
    std::fs::rename(&temporary, &file).unwrap();
    run.wait_for_from(
        skip,
        "from the counter with the renamed-in period",
        PATIENCE,
        |line| {
            line.starts_with("[counter]") && line.contains("period_secs") && line.contains("0.07")
        },
    );

    // Deleted, then written again: the deletion is survived, the new file is read.
    let skip = run.line_count();
    std::fs::remove_file(&file).unwrap();
    run.wait_for_from(skip, "noticing the deletion", PATIENCE, |line| {
        line.contains("the system file is gone")
    });
    std::fs::write(&file, demo_xml("0.03")).unwrap();
    run.wait_for_from(
        skip,
        "from the counter with the recreated file's period",
        PATIENCE,
        |line| {
            line.starts_with("[counter]") && line.contains("period_secs") && line.contains("0.03")
        },
    );
}

#[test]
fn a_system_with_problems_does_not_start() {
    let (_dir, file) = demo_copy("-");
    let mut run = armor_run(&file, &[]);
    let status = run.wait_exit(PATIENCE);
    assert_eq!(status.code(), Some(1));
    assert!(
        run.lines()
            .iter()
            .any(|line| line.contains("`-` is not a finite number")),
        "{:#?}",
        run.lines()
    );
    assert!(
        !run.lines()
            .iter()
            .any(|line| line.contains("module started"))
    );
}
