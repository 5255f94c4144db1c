//! Running a mission (or a plan) headless with `armor run --report`, as a user would, and
//! reading what the run left: its output and its report's timeline.

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use crate::{Proc, bin, bin_dir, workspace_root};

/// Run time passes this many times faster than real time: a mission of one to three simulated
/// minutes takes a few seconds. The sim, the follower and the avoider all run on the run clock,
/// and the follower declares a leg blocked only after `blocked_after_secs` of run time without
/// progress (the robot system files set 20 s, a second of real time at this scale), so a busy
/// machine slows a run down without failing it.
pub const TIME_SCALE: &str = "20";

/// How long a whole robot mission may take in real time: five to ten times what it needs on an
/// idle machine.
pub const MISSION_DEADLINE: Duration = Duration::from_secs(60);

/// The transitions the bundled yard reconnaissance (`missions/robot/plan-yard.xml`) fires when
/// all goes as planned, in order.
pub const YARD_FIRINGS: [&str; 7] = [
    "advance_arrived",
    "advance_arrival_done",
    "cross_appointment",
    "cross_arrived",
    "cross_waited",
    "climb_arrived",
    "regroup_arrived",
];

/// `armor run MISSION --time-scale TIME_SCALE --report REPORT EXTRA…`, with the workspace's
/// modules.
pub fn armor_run(mission: &Path, report: &Path, extra: &[&str]) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(mission)
            .args(["--time-scale", TIME_SCALE, "--report"])
            .arg(report)
            .args(extra)
            .env("ARMOR_MODULE_PATH", bin_dir())
            // The worlds are found from the files that name them; a recorder's relative
            // `file` is written in the current folder, here the workspace root.
            .current_dir(workspace_root()),
    )
}

/// Runs a mission to its end with `armor run … EXTRA…`; it must exit 0 within `deadline`,
/// its report saying `complete`.
pub fn run_mission(mission: &Path, extra: &[&str], deadline: Duration) -> Finished {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("report.json");
    let mut run = armor_run(mission, &report, extra);
    let status = run.wait_exit(deadline);
    let lines = run.lines();
    assert!(status.success(), "{status}:\n{}", lines.join("\n"));
    let report = serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let finished = Finished { lines, report };
    assert_eq!(
        finished.report["outcome"], "complete",
        "{:#}",
        finished.report
    );
    finished
}

/// What a finished run left: its output and its report.
pub struct Finished {
    pub lines: Vec<String>,
    pub report: serde_json::Value,
}

impl Finished {
    fn timeline(&self) -> &[serde_json::Value] {
        self.report["timeline"].as_array().unwrap()
    }

    /// The transitions fired, in order, with the run time of each.
    pub fn fired(&self) -> Vec<(String, f64)> {
        self.timeline()
            .iter()
            .filter(|entry| entry["kind"] == "fired")
            .map(|entry| {
                (
                    entry["transition"].as_str().unwrap().to_owned(),
                    entry["at_secs"].as_f64().unwrap(),
                )
            })
            .collect()
    }

    pub fn fired_names(&self) -> Vec<String> {
        self.fired().into_iter().map(|(name, _)| name).collect()
    }

    /// The run time `name` first fired at, if it did.
    pub fn fired_at(&self, name: &str) -> Option<f64> {
        self.fired()
            .into_iter()
            .find(|(fired, _)| fired == name)
            .map(|(_, at)| at)
    }

    /// The run time `place` was first entered at: 0 if it was marked from the start, else the
    /// firing after which it held a token; with the name of that firing.
    pub fn entered(&self, place: &str) -> Option<(f64, Option<String>)> {
        self.timeline().iter().find_map(|entry| {
            entry["marking"].get(place)?;
            match entry["kind"].as_str() {
                Some("started") => Some((0.0, None)),
                Some("fired") => Some((
                    entry["at_secs"].as_f64().unwrap(),
                    Some(entry["transition"].as_str().unwrap().to_owned()),
                )),
                _ => None,
            }
        })
    }

    /// Run time between two firings.
    pub fn between(&self, first: &str, second: &str) -> f64 {
        let at = |name: &str| {
            self.fired_at(name)
                .unwrap_or_else(|| panic!("`{name}` did not fire: {:?}", self.fired()))
        };
        at(second) - at(first)
    }

    /// The marking the mission completed in.
    pub fn final_marking(&self) -> serde_json::Value {
        let timeline = self.timeline();
        let complete = timeline
            .iter()
            .find(|entry| entry["kind"] == "complete")
            .unwrap_or_else(|| panic!("the mission did not complete: {timeline:#?}"));
        complete["marking"].clone()
    }

    pub fn any_line(&self, pred: impl Fn(&str) -> bool) -> bool {
        self.lines.iter().any(|line| pred(line))
    }

    /// The robot never touched anything, and the follower never gave up on a leg.
    pub fn assert_clean(&self) {
        let bad: Vec<&String> = self
            .lines
            .iter()
            .filter(|line| line.contains("event sim.collision") || line.contains("blocked"))
            .collect();
        assert!(bad.is_empty(), "{bad:#?}\n{}", self.lines.join("\n"));
    }
}
