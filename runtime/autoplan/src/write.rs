//! A route written as an ordinary plan (legs, arrivals, appointments, deadlines), and what the
//! planner found said in the operator's words.

use armor_model::geo::round_mm;
use armor_model::plan::{Leg, Plan};

use crate::explain::{Conflict, Constraint};
use crate::{Instance, Route};

/// `plan` with the route's legs in place of its objectives: a leg to each objective served, in
/// order (named `to_OBJECTIVE`, with its arrival action and wait), and one to the end place. A
/// leg whose objective opens later than the robot would arrive leaves later (`not_before`),
/// so that it arrives as the window opens; one with a limit gets it as its `arrive_by` (the
/// hard `by`, else the `due`).
pub fn plan(plan: &Plan, instance: &Instance, route: &Route) -> Plan {
    let mut written = plan.clone();
    written.objectives = None;
    written.legs.clear();
    written
        .waypoints
        .extend(crate::instance::own_waypoints(&instance.objectives));
    let problem = &instance.problem;
    let mut from = instance.start.clone();
    let mut node = 0;
    let mut left_ds = 0;
    // Departures to the second, never before the time planned (the robot would arrive before
    // the window opens).
    let at_date = |ds: i32| {
        instance
            .start_unix_secs
            .map(|start| start.round() + (f64::from(ds) / 10.0).ceil())
    };
    for (&task, &arrival_ds) in route.order.iter().zip(&route.arrival_ds) {
        let objective = &instance.objectives.objectives[task];
        let next = crate::Problem::node(task);
        // The robot waits where it is for the window, rather than at the objective early, and
        // leaves late enough to arrive no sooner driving as fast as it can, its arrival
        // reported as it comes within the navigation's tolerance (rounded down: later).
        let fastest_ds = instance.length(node, next).map_or(0, |length| {
            let secs = (length - instance.arrival_tolerance_m).max(0.0) / instance.fastest_mps;
            (secs * 10.0).floor().clamp(0.0, f64::from(i32::MAX / 4)) as i32
        });
        let leave_ds = arrival_ds - fastest_ds;
        let not_before = (objective.not_before_unix_secs.is_some() && leave_ds > left_ds)
            .then(|| at_date(leave_ds))
            .flatten();
        written.legs.push(Leg {
            name: format!("to_{}", objective.name),
            from: from.clone(),
            to: objective.waypoint().to_owned(),
            arrival: objective.arrival.clone(),
            wait_secs: objective.wait_secs,
            not_before_unix_secs: not_before,
            arrive_by_unix_secs: objective.by_unix_secs.or(objective.due_unix_secs),
            pos: objective.pos,
            ..Leg::default()
        });
        from = objective.waypoint().to_owned();
        node = next;
        left_ds = arrival_ds + problem.tasks[task].service_ds;
    }
    if let Some(end) = &instance.end
        && *end != from
    {
        written.legs.push(Leg {
            name: format!("to_{end}"),
            from,
            to: end.clone(),
            pos: instance.objectives.pos,
            ..Leg::default()
        });
    }
    written
}

/// A time of the plan in words: the time of day when the plan has a start (`08:03:20`), else
/// seconds from the start (`+200 s`).
pub fn time_words(instance: &Instance, ds: i32) -> String {
    match instance.start_unix_secs {
        Some(start) => {
            // In whole tenths, so that no binary fraction shows (`08:00:24.1`, not
            // `08:00:24.09999990463256836`).
            let tenths = (start * 10.0).round() as i64 + i64::from(ds);
            let date = armor_model::net::format_rfc3339(tenths.div_euclid(10) as f64);
            // 2026-11-23T08:03:20Z: the time of day is after the `T`.
            let time = date
                .split_once('T')
                .map_or(date.as_str(), |(_, time)| time)
                .trim_end_matches('Z');
            match tenths.rem_euclid(10) {
                0 => time.strip_suffix(":00").unwrap_or(time).to_owned(),
                tenth => format!("{time}.{tenth}"),
            }
        }
        None => format!("+{} s", round_mm(f64::from(ds) / 10.0)),
    }
}

/// Seconds in words (`80 s`, `2.5 s`).
pub fn secs(ds: i32) -> String {
    format!("{} s", round_mm(f64::from(ds) / 10.0))
}

/// One constraint in the operator's words (`` `north` by 08:03 ``).
pub fn constraint_words(instance: &Instance, constraint: Constraint) -> String {
    let problem = &instance.problem;
    let name = |task: usize| &instance.objectives.objectives[task].name;
    match constraint {
        Constraint::Must(task) => format!("`{}` must be served", name(task)),
        Constraint::NotBefore(task) => format!(
            "`{}` not before {}",
            name(task),
            time_words(instance, problem.tasks[task].not_before_ds.unwrap_or(0))
        ),
        Constraint::By(task) => format!(
            "`{}` by {}",
            name(task),
            time_words(instance, problem.tasks[task].by_ds.unwrap_or(0))
        ),
        Constraint::Precedence(index) => {
            let (first, then) = problem.precedences[index];
            format!("`{}` before `{}`", name(first), name(then))
        }
        Constraint::MaxDistance => format!(
            "the robot drives at most {} m",
            round_mm(f64::from(problem.max_distance_dm.unwrap_or(0)) / 10.0)
        ),
        Constraint::MaxTime => format!(
            "the plan ends by {}",
            time_words(instance, problem.max_time_ds.unwrap_or(0))
        ),
        Constraint::MaxCharge => format!(
            "the plan uses at most {} % of the battery",
            round_mm(
                f64::from(problem.max_charge.map_or(0, |limit| limit.max)) / crate::FULL_CHARGE
                    * 100.0
            )
        ),
    }
}

/// The way between two nodes in words: `the 40 m between `gate` and `north` take 80 s at
/// 0.5 m/s`, or why there is none.
fn way_words(instance: &Instance, from: usize, to: usize) -> String {
    let node_name = |node: usize| -> String {
        if node == 0 {
            format!("`{}`", instance.start)
        } else if node <= instance.objectives.objectives.len() {
            format!("`{}`", instance.objectives.objectives[node - 1].name)
        } else {
            format!("`{}`", instance.end.as_deref().unwrap_or("the end"))
        }
    };
    let point = |node: usize| node.min(instance.points.len().saturating_sub(1));
    match instance.length_m[point(from)][point(to)] {
        Some(length) => format!(
            "the {} m from {} to {} take {} at {} m/s",
            round_mm((length * 10.0).round() / 10.0),
            node_name(from),
            node_name(to),
            secs(instance.problem.travel_ds[from][to].unwrap_or(0)),
            instance.speed_mps
        ),
        None => format!(
            "there is no way from {} to {}{}",
            node_name(from),
            node_name(to),
            instance.cut[point(from)][point(to)]
                .as_ref()
                .map(|why| format!(" ({why})"))
                .unwrap_or_default()
        ),
    }
}

/// A conflict in the operator's words: its constraints, and for the common cases the numbers
/// behind it (``the 40 m between them take 80 s at 0.5 m/s, the windows leave 50 s``).
pub fn conflict_words(instance: &Instance, conflict: &Conflict) -> String {
    let parts: Vec<String> = conflict
        .constraints
        .iter()
        .map(|&constraint| constraint_words(instance, constraint))
        .collect();
    let mut text = parts.join(", ");
    if let Some(why) = numbers(instance, conflict) {
        text.push_str(": ");
        text.push_str(&why);
    }
    if !conflict.minimal {
        text.push_str(" (the search for a smaller set ran out of time: it may not be minimal)");
    }
    text
}

/// The numbers behind a conflict between one or two objectives' windows, or the way from the
/// start to one.
fn numbers(instance: &Instance, conflict: &Conflict) -> Option<String> {
    let problem = &instance.problem;
    let mut tasks: Vec<usize> = conflict
        .constraints
        .iter()
        .filter_map(Constraint::task)
        .collect();
    tasks.sort_unstable();
    tasks.dedup();
    match tasks.as_slice() {
        [task] => {
            let node = crate::Problem::node(*task);
            let spec = &problem.tasks[*task];
            match problem.earliest_ds()[node] {
                None => Some(way_words(instance, 0, node)),
                Some(travel) => {
                    let by = spec.by_ds?;
                    let earliest = travel.max(spec.not_before_ds.unwrap_or(0));
                    Some(format!(
                        "{}: the earliest it is reached is {}, after {}",
                        way_words(instance, 0, node),
                        time_words(instance, earliest),
                        time_words(instance, by)
                    ))
                }
            }
        }
        [a, b] => {
            let earliest = problem.earliest_ds();
            // Either order fails; say why for each.
            let mut reasons = Vec::new();
            for (first, then) in [(*a, *b), (*b, *a)] {
                let (x, y) = (crate::Problem::node(first), crate::Problem::node(then));
                // The earliest the robot can be at the first: its window's opening, or the way
                // there from the start.
                let open = problem.tasks[first]
                    .not_before_ds
                    .unwrap_or(0)
                    .max(earliest[x].unwrap_or(0));
                let Some(by) = problem.tasks[then].by_ds else {
                    continue;
                };
                let service = problem.tasks[first].service_ds;
                match problem.travel_ds[x][y] {
                    Some(_) => {
                        let left = by - open - service;
                        reasons.push(format!(
                            "`{}` is reached at {} at the earliest, then {}{}: {}",
                            instance.objectives.objectives[first].name,
                            time_words(instance, open),
                            way_words(instance, x, y),
                            if service > 0 {
                                format!(" after {} there", secs(service))
                            } else {
                                String::new()
                            },
                            if left > 0 {
                                format!("the windows leave {}", secs(left))
                            } else {
                                format!(
                                    "`{}` must be reached by {}, before that",
                                    instance.objectives.objectives[then].name,
                                    time_words(instance, by)
                                )
                            }
                        ));
                    }
                    None => reasons.push(way_words(instance, x, y)),
                }
            }
            (!reasons.is_empty()).then(|| reasons.join("; "))
        }
        _ => None,
    }
}

/// A route in a line per objective: `1. `gate` at 08:01:12 (due 08:02)`, with the distance and
/// the end.
pub fn route_words(instance: &Instance, route: &Route) -> Vec<String> {
    let mut lines = Vec::new();
    for (rank, (&task, &arrival)) in route.order.iter().zip(&route.arrival_ds).enumerate() {
        let objective = &instance.objectives.objectives[task];
        let spec = &instance.problem.tasks[task];
        let mut line = format!(
            "{}. `{}` at {}",
            rank + 1,
            objective.name,
            time_words(instance, arrival)
        );
        if let Some(due) = spec.due_ds
            && arrival > due
        {
            line.push_str(&format!(
                ", {} late (due {})",
                secs(arrival - due),
                time_words(instance, due)
            ));
        }
        lines.push(line);
    }
    lines
}
