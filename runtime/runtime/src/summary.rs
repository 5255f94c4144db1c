//! The table `armor run PLAN` prints when the run ends: each leg of the plan, when it started
//! and arrived (run time), the length of its planned path, and how it stood against its
//! deadline.

use std::fmt::Write as _;

use armor_model::geo;
use armor_model::plan::{Compiled, Plan};

/// What a leg did, from the controller's first firings and markings (run seconds).
#[derive(Debug, PartialEq)]
pub struct LegRun {
    pub name: String,
    pub from: String,
    pub to: String,
    pub length_m: f64,
    /// When the robot set off on it (its drive place was first marked).
    pub started_secs: Option<f64>,
    /// When it arrived (its arrival transition first fired).
    pub arrived_secs: Option<f64>,
    /// Its `arrive_by`, in run seconds from the run's start date.
    pub deadline_secs: Option<f64>,
}

/// Each leg of `plan` as the run went, `start_unix_secs` being the date the run started at.
pub fn legs(
    plan: &Plan,
    compiled: &Compiled,
    first_fired: &std::collections::BTreeMap<String, f64>,
    first_marked: &std::collections::BTreeMap<String, f64>,
    start_unix_secs: f64,
) -> Vec<LegRun> {
    plan.legs
        .iter()
        .enumerate()
        .map(|(index, leg)| {
            let arrived = format!("{}_arrived", leg.name);
            LegRun {
                name: leg.name.clone(),
                from: leg.from.clone(),
                to: leg.to.clone(),
                length_m: compiled
                    .routes
                    .get(index)
                    .map_or(0.0, |route| geo::path_length(route)),
                started_secs: first_marked.get(&format!("{}_drive", leg.name)).copied(),
                arrived_secs: first_fired
                    .iter()
                    .filter(|(name, _)| name.starts_with(&arrived))
                    .map(|(_, at)| *at)
                    .reduce(f64::min),
                deadline_secs: leg.arrive_by_unix_secs.map(|at| at - start_unix_secs),
            }
        })
        .collect()
}

/// The legs as a table, one line each.
pub fn table(legs: &[LegRun]) -> String {
    let mut out = String::new();
    let width = legs
        .iter()
        .map(|leg| leg.name.len())
        .max()
        .unwrap_or(3)
        .max(3);
    let _ = writeln!(
        out,
        "{:width$}  {:>8}  {:>9}  {:>9}  against its deadline",
        "leg", "length", "set off", "arrived"
    );
    let secs = |at: Option<f64>| at.map_or("-".to_owned(), |at| format!("{at:.1} s"));
    for leg in legs {
        let against = match (leg.arrived_secs, leg.deadline_secs) {
            (Some(arrived), Some(deadline)) if arrived <= deadline => {
                format!("{:.1} s early", deadline - arrived)
            }
            (Some(arrived), Some(deadline)) => format!("{:.1} s late", arrived - deadline),
            (None, Some(_)) => "not reached".to_owned(),
            (_, None) => "no deadline".to_owned(),
        };
        let _ = writeln!(
            out,
            "{:width$}  {:>6.1} m  {:>9}  {:>9}  {against}   ({} → {})",
            leg.name,
            leg.length_m,
            secs(leg.started_secs),
            secs(leg.arrived_secs),
            leg.from,
            leg.to
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_says_early_late_and_not_reached() {
        let leg = |name: &str, arrived: Option<f64>, deadline: Option<f64>| LegRun {
            name: name.to_owned(),
            from: "a".to_owned(),
            to: "b".to_owned(),
            length_m: 12.34,
            started_secs: Some(1.0),
            arrived_secs: arrived,
            deadline_secs: deadline,
        };
        let table = table(&[
            leg("advance", Some(20.6), Some(60.0)),
            leg("cross", Some(70.0), Some(65.5)),
            leg("climb", None, Some(100.0)),
            leg("regroup", Some(90.0), None),
        ]);
        let lines: Vec<&str> = table.lines().collect();
        assert_eq!(lines.len(), 5, "{table}");
        assert!(
            lines[1].starts_with("advance") && lines[1].contains("39.4 s early"),
            "{table}"
        );
        assert!(
            lines[1].contains("12.3 m") && lines[1].contains("20.6 s"),
            "{table}"
        );
        assert!(lines[2].contains("4.5 s late"), "{table}");
        assert!(
            lines[3].contains("not reached") && lines[3].contains("  -  "),
            "{table}"
        );
        assert!(lines[4].contains("no deadline"), "{table}");
    }
}
