//! `armor run PLAN` as a new user runs it: on a terminal it draws a live line (the leg, the
//! distance left, the next time constraint, the run time); it ends with a table of the legs;
//! and it leaves everything in a folder of its own under `runs/` that a second run never
//! touches.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use armor_tests::mission::TIME_SCALE;
use armor_tests::{Proc, bin, bin_dir, workspace_root};

/// `armor run PLAN` under a pseudo-terminal (`script`), so that the progress line is drawn;
/// what the terminal showed is written to `typescript`.
fn run_on_a_terminal(plan: &Path, runs: &Path, typescript: &Path) -> Proc {
    // A wide terminal, so that the line is drawn whole.
    let command = format!(
        "stty rows 50 cols 200; {} run {} --time-scale {TIME_SCALE}",
        bin("armor").display(),
        plan.display()
    );
    Proc::start(
        Command::new(armor_tests::tools::program("script"))
            .args(["-qfec", &command])
            .arg(typescript)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .env(armor_runtime::run_dir::ENV_RUNS_DIR, runs)
            .current_dir(workspace_root()),
    )
}

/// The folders under `runs`, sorted.
fn folders(runs: &Path) -> Vec<PathBuf> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(runs)
        .map(|entries| entries.map(|entry| entry.unwrap().path()).collect())
        .unwrap_or_default();
    found.sort();
    found
}

/// What a terminal shows, without its escape sequences, one line per carriage return or line
/// feed.
fn screen_lines(typescript: &Path) -> Vec<String> {
    let raw = String::from_utf8_lossy(&std::fs::read(typescript).unwrap()).into_owned();
    let mut plain = String::new();
    let mut chars = raw.chars().peekable();
    while let Some(c) = chars.next() {
        if c == '\u{1b}' {
            // CSI: ESC [ params final-byte.
            if chars.peek() == Some(&'[') {
                chars.next();
                for c in chars.by_ref() {
                    if ('@'..='~').contains(&c) {
                        break;
                    }
                }
            }
            continue;
        }
        plain.push(if c == '\r' { '\n' } else { c });
    }
    plain
        .lines()
        .map(str::trim)
        .filter(|line| !line.is_empty())
        .map(str::to_owned)
        .collect()
}

#[test]
fn a_plan_run_shows_its_progress_ends_with_its_legs_and_leaves_a_folder() {
    let dir = tempfile::tempdir().unwrap();
    let runs = dir.path().join("runs");
    let plan = workspace_root().join("missions/robot/plan-yard.xml");

    let typescript = dir.path().join("first.typescript");
    let mut first = run_on_a_terminal(&plan, &runs, &typescript);
    let status = first.wait_exit(Duration::from_secs(90));
    let screen = screen_lines(&typescript);
    assert!(status.success(), "{status}\n{}", screen.join("\n"));

    // The live line, as the robot drove the first leg and waited for the second's appointment.
    let driving = screen
        .iter()
        .find(|line| line.contains("leg 1/4 advance (home → gate): ") && line.contains(" m left"))
        .unwrap_or_else(|| panic!("no progress of the first leg:\n{}", screen.join("\n")));
    assert!(
        driving.contains("arrive at gate by 60.0 s: ") && driving.contains("slack"),
        "{driving}"
    );
    assert!(
        screen
            .iter()
            .any(|line| line.contains("at gate after leg 1/4")
                && line.contains("cross sets off at 90.0 s")),
        "no wait for the appointment:\n{}",
        screen.join("\n")
    );

    // The table of legs, each driven about its planned length.
    let header = screen
        .iter()
        .position(|line| line.starts_with("leg ") && line.contains("driven"))
        .unwrap_or_else(|| panic!("no table:\n{}", screen.join("\n")));
    let rows = &screen[header + 1..header + 5];
    for (row, name) in rows.iter().zip(["advance", "cross", "climb", "regroup"]) {
        assert!(row.starts_with(name), "{row}");
        // The planned and driven lengths; the true error by the simulator follows them.
        let metres: Vec<f64> = row
            .split_whitespace()
            .collect::<Vec<_>>()
            .windows(2)
            .filter(|pair| pair[1] == "m")
            .map(|pair| pair[0].parse().unwrap())
            .collect();
        let [planned, driven, ..] = metres[..] else {
            panic!("planned and driven lengths in {row}");
        };
        assert!(
            (driven - planned).abs() < 0.25 * planned + 1.0,
            "driven {driven} m against {planned} m planned: {row}"
        );
        assert!(row.contains("follower.goal_reached"), "{row}");
    }

    // The folder: the log as printed, the report, the table and the recording.
    let made = folders(&runs);
    assert_eq!(made.len(), 1, "{made:?}");
    let folder = &made[0];
    let name = folder.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.starts_with("yard-recon-20"), "{name}");
    for file in ["log.txt", "report.json", "summary.txt", "yard-recon.mcap"] {
        assert!(
            folder.join(file).is_file(),
            "{file} in {}",
            folder.display()
        );
    }
    let log = std::fs::read_to_string(folder.join("log.txt")).unwrap();
    assert!(log.contains("mission `yard-recon` complete"), "{log}");
    assert!(log.contains("[follower]"), "modules' lines are in the log");
    let summary = std::fs::read_to_string(folder.join("summary.txt")).unwrap();
    assert!(summary.contains(rows[0].as_str()), "{summary}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(folder.join("report.json")).unwrap())
            .unwrap();
    assert_eq!(report["outcome"], "complete");
    assert!(
        screen
            .iter()
            .any(|line| line.contains("this run's folder: ") && line.contains("yard-recon.mcap")),
        "the last lines say where the run went"
    );

    // A second run, piped (no terminal: no progress line), never writes into the first's
    // folder.
    let recording = std::fs::read(folder.join("yard-recon.mcap")).unwrap();
    let mut second = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&plan)
            .args(["--time-scale", TIME_SCALE, "--runs-dir"])
            .arg(&runs)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(workspace_root()),
    );
    let status = second.wait_exit(Duration::from_secs(90));
    let lines = second.lines();
    assert!(status.success(), "{status}\n{}", lines.join("\n"));
    assert!(
        !lines.iter().any(|line| line.contains(" m left")),
        "a progress line where there is no terminal"
    );
    let made = folders(&runs);
    assert_eq!(made.len(), 2, "{made:?}");
    assert_eq!(
        std::fs::read(folder.join("yard-recon.mcap")).unwrap(),
        recording
    );
    assert!(made[1].join("yard-recon.mcap").is_file());
}

/// What a terminal showed of `armor ARGS…` (run under `script` with the workspace's modules).
fn on_a_terminal(args: &str, typescript: &Path) -> (std::process::ExitStatus, Vec<String>) {
    let command = format!("stty rows 50 cols 200; {} {args}", bin("armor").display());
    let mut run = Proc::start(
        Command::new(armor_tests::tools::program("script"))
            .args(["-qfec", &command])
            .arg(typescript)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(workspace_root()),
    );
    let status = run.wait_exit(Duration::from_secs(60));
    (status, screen_lines(typescript))
}

#[test]
fn long_commands_say_what_they_do_on_a_terminal_and_print_only_their_result_when_piped() {
    let dir = tempfile::tempdir().unwrap();
    let plan = workspace_root().join("missions/robot/plan-warehouse.xml");
    let (status, screen) = on_a_terminal(
        &format!("check {}", plan.display()),
        &dir.path().join("check"),
    );
    assert!(status.success(), "{}", screen.join("\n"));
    assert!(
        screen
            .iter()
            .any(|line| line.contains("checking ") && line.contains("planning each leg")),
        "{}",
        screen.join("\n")
    );
    assert!(screen.iter().any(|line| line.ends_with("reachable)")));

    let modules = bin_dir();
    let (status, screen) = on_a_terminal(
        &format!("probe --no-cache {}", modules.display()),
        &dir.path().join("probe"),
    );
    assert!(status.success(), "{}", screen.join("\n"));
    let count = armor_runtime::probe::list_modules(std::slice::from_ref(&modules)).len();
    assert!(
        screen
            .iter()
            .any(|line| line.contains(&format!("describing {count} module binaries"))),
        "{}",
        screen.join("\n")
    );

    // Piped, only the result.
    let mut piped = Proc::start(
        Command::new(bin("armor"))
            .arg("check")
            .arg(&plan)
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(workspace_root()),
    );
    assert!(piped.wait_exit(Duration::from_secs(60)).success());
    let lines = piped.lines();
    assert!(
        !lines.iter().any(|line| line.contains("checking ")),
        "{lines:?}"
    );
}
