//! The table `armor run PLAN` prints when the run ends: each leg of the plan, the length of its
//! planned path and how far the robot drove it, its appointment, when it set off and arrived
//! (run time), its deadline and how it stood against it, and the events modules reported on
//! the way. In a simulated run it adds each arrival's true error (the simulator's truth, by
//! `armor_model::rehearsal`), each no-go area's least distance to the robot's true footprint,
//! and the rehearsal's verdict.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use armor_model::geo;
use armor_model::rehearsal::Verdict;

use crate::progress::{LegExtras, LegPlan};

/// What a leg did, from the controller's first firings and markings (run seconds).
#[derive(Debug, PartialEq)]
pub struct LegRun {
    pub name: String,
    pub from: String,
    pub to: String,
    pub length_m: f64,
    /// How far the robot drove while on it (odometry), when known.
    pub driven_m: Option<f64>,
    /// Its appointment: not to set off before.
    pub not_before_secs: Option<f64>,
    /// When the robot set off on it (its drive place was first marked).
    pub started_secs: Option<f64>,
    /// When it arrived (its arrival transition first fired).
    pub arrived_secs: Option<f64>,
    /// Its `arrive_by`, in run seconds from the run's start date.
    pub deadline_secs: Option<f64>,
    /// The events modules reported while it was under way.
    pub events: Vec<String>,
    /// Its actions' switches to alternatives, in the order they happened.
    pub switches: Vec<String>,
}

/// Each leg as the run went.
pub fn legs(
    plans: &[LegPlan],
    first_fired: &BTreeMap<String, f64>,
    first_marked: &BTreeMap<String, f64>,
    extras: &[LegExtras],
) -> Vec<LegRun> {
    plans
        .iter()
        .enumerate()
        .map(|(index, leg)| {
            let arrived = format!("{}_arrived", leg.name);
            let extras = extras.get(index).cloned().unwrap_or_default();
            LegRun {
                name: leg.name.clone(),
                from: leg.from.clone(),
                to: leg.to.clone(),
                length_m: geo::path_length(&leg.route),
                driven_m: extras.driven_m,
                not_before_secs: leg.not_before_secs,
                started_secs: first_marked.get(&format!("{}_drive", leg.name)).copied(),
                arrived_secs: first_fired
                    .iter()
                    .filter(|(name, _)| name.starts_with(&arrived))
                    .map(|(_, at)| *at)
                    .reduce(f64::min),
                deadline_secs: leg.deadline_secs,
                events: extras.events,
                switches: {
                    let mut fired: Vec<(f64, &String)> = leg
                        .switches
                        .iter()
                        .filter_map(|(transition, text)| {
                            Some((*first_fired.get(transition)?, text))
                        })
                        .collect();
                    fired.sort_by(|a, b| a.0.total_cmp(&b.0));
                    fired.into_iter().map(|(_, text)| text.clone()).collect()
                },
            }
        })
        .collect()
}

/// Events in order, a run of the same one counted (`follower.replanned ×2`).
fn events_text(events: &[String]) -> String {
    let mut runs: Vec<(&str, usize)> = Vec::new();
    for event in events {
        match runs.last_mut() {
            Some((last, count)) if last == event => *count += 1,
            _ => runs.push((event, 1)),
        }
    }
    let text: Vec<String> = runs
        .into_iter()
        .map(|(event, count)| match count {
            1 => event.to_owned(),
            n => format!("{event} ×{n}"),
        })
        .collect();
    if text.is_empty() {
        "-".to_owned()
    } else {
        text.join(", ")
    }
}

/// The heading of the true errors' column.
const TRUE_ERROR: &str = "true error";

/// What the truth says beyond the legs: each no-go area's least distance to the robot's true
/// footprint, then the verdict (`rehearsal passed …` or `rehearsal FAILED: …`), one line each.
pub fn truth_lines(truth: &Verdict) -> Vec<String> {
    let mut lines = truth.area_lines();
    lines.push(truth.headline());
    lines
}

/// The plan updates asked for during the run, one line each: `update 1 at 35.2 s
/// (plan-east.xml): taken: leg `cross` in force goes on unchanged …` (a refusal's first line
/// only: a plan that does not check says all its problems in the log and the report).
pub fn update_lines(updates: &[armor_protocol::UpdateRecord]) -> Vec<String> {
    updates
        .iter()
        .map(|update| {
            format!(
                "update {} at {:.1} s ({}): {}: {}",
                update.number,
                update.run_secs,
                update.file,
                if update.taken { "taken" } else { "refused" },
                update.message.lines().next().unwrap_or_default()
            )
        })
        .collect()
}

/// The repair the mission proposes, as `armor ctl status` prints it: why, then an option a line,
/// numbered as `armor ctl repair N` takes them, each with its costs.
pub fn repair_lines(repair: &armor_protocol::Repair) -> Vec<String> {
    let mut lines = vec![format!(
        "repair proposed at {:.1} s for leg `{}`: {}{}",
        repair.run_secs,
        repair.leg,
        repair.why,
        match (repair.default_option, repair.default_at_run_secs) {
            (Some(number), None) => format!(" (the plan applies option {number})"),
            (Some(number), Some(at)) => format!(
                "; choose with `armor ctl repair N`, or the plan applies option {number} at \
                 {at:.1} s"
            ),
            (None, _) => "; choose with `armor ctl repair N`".to_owned(),
        }
    )];
    for option in &repair.options {
        let time = option
            .duration_secs
            .map_or_else(|| "until lifted".to_owned(), |secs| format!("{secs:.0} s"));
        let missed = if option.deadlines_missed.is_empty() {
            "no deadline missed".to_owned()
        } else {
            format!("misses {}", option.deadlines_missed.join("; "))
        };
        lines.push(format!(
            "  {}. {} ({}): {:.1} m, {time}, {missed}",
            option.number,
            option.summary,
            option.kind.as_str(),
            option.distance_m
        ));
    }
    lines
}

/// The legs as a table, one line each; with `truth` (a simulated run), each arrival's true
/// error in a column of its own.
pub fn table(legs: &[LegRun], truth: Option<&Verdict>) -> String {
    let mut out = String::new();
    let name_width = legs
        .iter()
        .map(|leg| leg.name.len())
        .max()
        .unwrap_or(3)
        .max(3);
    let ways: Vec<String> = legs
        .iter()
        .map(|leg| format!("{} → {}", leg.from, leg.to))
        .collect();
    let way_width = ways
        .iter()
        .map(|way| way.chars().count())
        .max()
        .unwrap_or(3)
        .max(3);
    let true_errors: Option<Vec<String>> = truth.map(|truth| {
        legs.iter()
            .map(|leg| truth.true_error_text(&leg.name))
            .collect()
    });
    let truth_width = true_errors.as_ref().map_or(0, |errors| {
        errors
            .iter()
            .map(|error| error.chars().count())
            .chain([TRUE_ERROR.len()])
            .max()
            .unwrap_or(0)
    });
    let truth_heading = match true_errors {
        Some(_) => format!("{TRUE_ERROR:truth_width$}  "),
        None => String::new(),
    };
    let _ = writeln!(
        out,
        "{:name_width$}  {:way_width$}  {:>8}  {:>8}  {:>10}  {:>8}  {:>8}  {:>8}  {:12}  {truth_heading}events",
        "leg",
        "way",
        "planned",
        "driven",
        "not before",
        "set off",
        "arrived",
        "deadline",
        "against it"
    );
    let secs = |at: Option<f64>| at.map_or("-".to_owned(), |at| format!("{at:.1} s"));
    let metres = |m: Option<f64>| m.map_or("-".to_owned(), |m| format!("{m:.1} m"));
    for (index, (leg, way)) in legs.iter().zip(&ways).enumerate() {
        let against = match (leg.arrived_secs, leg.deadline_secs) {
            (Some(arrived), Some(deadline)) if arrived <= deadline => {
                format!("{:.1} s early", deadline - arrived)
            }
            (Some(arrived), Some(deadline)) => format!("{:.1} s late", arrived - deadline),
            (None, Some(_)) => "not reached".to_owned(),
            (_, None) => "no deadline".to_owned(),
        };
        let true_error = match &true_errors {
            Some(errors) => format!("{:truth_width$}  ", errors[index]),
            None => String::new(),
        };
        // `{:width$}` counts chars, and the arrow is one.
        let _ = writeln!(
            out,
            "{:name_width$}  {way:way_width$}  {:>8}  {:>8}  {:>10}  {:>8}  {:>8}  {:>8}  {against:12}  {true_error}{}",
            leg.name,
            metres(Some(leg.length_m)),
            metres(leg.driven_m),
            secs(leg.not_before_secs),
            secs(leg.started_secs),
            secs(leg.arrived_secs),
            secs(leg.deadline_secs),
            events_text(&leg.events),
        );
        // What the leg switched to goes below it: the events' column is already wide.
        for switch in &leg.switches {
            let _ = writeln!(out, "{:name_width$}  {switch}", "");
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_model::geo::Point;

    #[test]
    fn the_switches_that_fired_go_under_their_leg_in_order() {
        let plan = LegPlan {
            name: "out".to_owned(),
            from: "home".to_owned(),
            to: "east".to_owned(),
            target: None,
            route: Vec::new(),
            not_before_secs: None,
            deadline_secs: None,
            switches: vec![
                (
                    "out_drive_mapper_failed".to_owned(),
                    "switched to `odometry`: `mapper` failed".to_owned(),
                ),
                (
                    "out_drive_odometry_sim_failed".to_owned(),
                    "switched to `alt2`: `sim` failed".to_owned(),
                ),
                (
                    "out_drive_camera_failed".to_owned(),
                    "switched to `alt3`: `camera` failed".to_owned(),
                ),
            ],
        };
        let fired = BTreeMap::from([
            ("out_drive_odometry_sim_failed".to_owned(), 9.0),
            ("out_drive_mapper_failed".to_owned(), 4.5),
        ]);
        let legs = legs(&[plan], &fired, &BTreeMap::new(), &[]);
        assert_eq!(
            legs[0].switches,
            [
                "switched to `odometry`: `mapper` failed",
                "switched to `alt2`: `sim` failed"
            ]
        );
        let table = table(&legs, None);
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 4, "{table}");
        assert_eq!(lines[2].trim(), "switched to `odometry`: `mapper` failed");
    }

    #[test]
    fn the_table_says_early_late_and_not_reached() {
        let leg = |name: &str, arrived: Option<f64>, deadline: Option<f64>| LegRun {
            name: name.to_owned(),
            from: "a".to_owned(),
            to: "b".to_owned(),
            length_m: 12.34,
            driven_m: Some(13.06),
            not_before_secs: None,
            started_secs: Some(1.0),
            arrived_secs: arrived,
            deadline_secs: deadline,
            events: vec![
                "follower.replanned".to_owned(),
                "follower.replanned".to_owned(),
                "follower.arrived".to_owned(),
            ],
            switches: Vec::new(),
        };
        let mut waited = leg("cross", Some(70.0), Some(65.5));
        waited.not_before_secs = Some(60.0);
        let mut unknown = leg("climb", None, Some(100.0));
        unknown.driven_m = None;
        unknown.events.clear();
        let table = table(
            &[
                leg("advance", Some(20.6), Some(60.0)),
                waited,
                unknown,
                leg("regroup", Some(90.0), None),
            ],
            None,
        );
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 5, "{table}");
        assert!(
            lines[1].starts_with("advance") && lines[1].contains("39.4 s early"),
            "{table}"
        );
        assert!(
            lines[1].contains("12.3 m")
                && lines[1].contains("13.1 m")
                && lines[1].contains("20.6 s"),
            "{table}"
        );
        assert!(
            lines[1].ends_with("follower.replanned ×2, follower.arrived"),
            "{table}"
        );
        assert!(
            lines[2].contains("4.5 s late") && lines[2].contains("60.0 s"),
            "{table}"
        );
        assert!(
            lines[3].contains("not reached")
                && lines[3].contains("  -  ")
                && lines[3].ends_with(" -"),
            "{table}"
        );
        assert!(lines[4].contains("no deadline"), "{table}");
        // Columns line up under their headings.
        let column = lines[0].find("against it").expect("heading");
        assert!(
            lines[1..]
                .iter()
                .all(|line| line.chars().nth(column).is_some()),
            "{table}"
        );
    }

    #[test]
    fn a_simulated_run_adds_each_true_error_the_areas_and_the_verdict() {
        use armor_model::geo::Polygon;
        use armor_model::rehearsal::{Arrival, NoGoArea, Rules, TruePose, judge};
        let run = |name: &str, arrived: Option<f64>| LegRun {
            name: name.to_owned(),
            from: "a".to_owned(),
            to: format!("{name}_end"),
            length_m: 12.0,
            driven_m: Some(12.1),
            not_before_secs: None,
            started_secs: Some(1.0),
            arrived_secs: arrived,
            deadline_secs: None,
            events: Vec::new(),
            switches: Vec::new(),
        };
        let poses = [
            TruePose {
                at_secs: 10.0,
                at: Point::new(12.0, 0.1),
            },
            TruePose {
                at_secs: 30.0,
                at: Point::new(12.0, 2.59),
            },
        ];
        let arrival = |leg: &str, at_secs: f64| Arrival {
            leg: leg.to_owned(),
            waypoint: format!("{leg}_end"),
            target: Point::new(12.0, 0.0),
            at_secs,
        };
        let area = NoGoArea {
            name: "spill".to_owned(),
            polygon: Polygon::new(vec![
                Point::new(0.0, 5.0),
                Point::new(1.0, 5.0),
                Point::new(1.0, 6.0),
            ]),
        };
        let rules = Rules {
            radius_m: 0.35,
            tolerance_m: 0.3,
        };
        let verdict = judge(
            &poses,
            &[arrival("advance", 10.0), arrival("regroup", 30.0)],
            &[area],
            rules,
        );
        let legs = [
            run("advance", Some(10.0)),
            run("regroup", Some(30.0)),
            run("climb", None),
        ];
        let table = table(&legs, Some(&verdict));
        let lines: Vec<&str> = table.lines().collect();
        // The heading is ASCII; the rows' arrows are one char of three bytes.
        let column = lines[0].find("true error").expect("the column");
        let cell = |row: usize| -> String { lines[row].chars().skip(column).collect() };
        assert_eq!(
            lines[0].find("events"),
            Some(column + "2.59 m (simulator) FAILED  ".len())
        );
        assert!(cell(1).starts_with("0.10 m (simulator)  "), "{table}");
        assert!(
            cell(2).starts_with("2.59 m (simulator) FAILED  -"),
            "{table}"
        );
        assert!(cell(3).starts_with("-  "), "{table}");
        let truth = truth_lines(&verdict);
        assert_eq!(truth.len(), 2);
        assert!(
            truth[0].starts_with("no-go area `spill`: the footprint"),
            "{truth:?}"
        );
        assert_eq!(
            truth[1],
            "rehearsal FAILED: leg `regroup` arrived 2.59 m from its waypoint `regroup_end` by \
             the simulator's truth (allowed 0.40 m)"
        );
        // Without the truth, no column.
        assert!(!super::table(&legs, None).contains("true error"));
    }
}
