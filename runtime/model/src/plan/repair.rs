//! Repair when the world contradicts the plan: a leg cannot be completed (the navigation is
//! blocked, a no-go area closes its way), and the run proposes what could be done instead, each
//! option a whole new plan that the run takes as it takes an update (`armor ctl update`: checked,
//! compiled and migrated, `super::migrate`), with its costs against what is left of the plan.
//!
//! The options: a way round through another waypoint of the plan, skipping the leg's
//! destination (the leg in force takes over the next leg), returning to where the plan starts,
//! and waiting (nothing changes). When the follower was stopped by something the plan's map
//! does not have ([`Situation::blockage`], an area the caller places where it stopped), every
//! option holds that area, so that none drives back through the way that was closed, and the
//! first way round is the leg driven on round it from where the robot is. The leg in force keeps its name in every option, so that the
//! migration finds it; only what comes after it changes. Pure: the paths' lengths come from the
//! caller ([`options`]'s `lengths`), which plans them on the world.

use std::collections::{BTreeMap, BTreeSet};

use crate::geo::Point;

use super::{Graphic, Leg, Plan};

/// What an option does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Kind {
    /// To the leg's destination round through another waypoint.
    WayRound,
    /// Give up the leg's destination, drive on to the next leg's.
    Skip,
    /// Drive back to where the plan starts and end there.
    Return,
    /// Change nothing: hold for an update or the operator.
    Wait,
    /// A late leg's deadline moved to when the robot is now expected there.
    PushBack,
    /// A late leg's deadline given up: the leg drives on with none.
    DropDeadline,
}

/// An option of a repair, with its costs.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    pub kind: Kind,
    /// What it does, in one sentence.
    pub summary: String,
    /// The waypoints it drives through before the rest of the plan.
    pub via: Vec<String>,
    /// The legs whose destinations it gives up.
    pub legs_dropped: Vec<String>,
    /// The plan to take as an update; none for a wait.
    pub plan: Option<Plan>,
    /// Metres left to drive from where the robot is to the end of the plan.
    pub distance_m: f64,
    /// Seconds that takes at the plan's speed, with the appointments, arrival actions
    /// (`for_secs`, at most) and waits; none for a wait.
    pub duration_secs: Option<f64>,
    /// The deadlines missed, a sentence each.
    pub deadlines_missed: Vec<String>,
}

/// Where the mission stands when a leg cannot be completed.
#[derive(Clone, Copy, Debug)]
pub struct Situation<'a> {
    pub plan: &'a Plan,
    /// Where the waypoints the robot can be at are, in the world frame.
    pub positions: &'a BTreeMap<String, Point>,
    /// The length of each leg of `plan` as planned (metres), `None` for a leg with no way.
    pub route_lengths_m: &'a [Option<f64>],
    /// The leg in force, by index in `plan`.
    pub index: usize,
    /// Where the robot believes it is.
    pub here: Point,
    /// The run's clock as a date (Unix seconds).
    pub now_unix_secs: f64,
    /// What stopped the follower, as a no-go area, when the plan's map has a way where it
    /// stopped: every option's plan holds it, and `lengths` is to plan round it.
    pub blockage: Option<&'a Graphic>,
}

/// The most ways round proposed (the shortest): more would bury the other options.
const MAX_WAYS_ROUND: usize = 3;

/// The options for `situation`, best first: those that give up fewer destinations, then miss
/// fewer deadlines, then take less time; the wait last. `lengths` plans the way between each
/// pair of points (on one costmap) and gives its length in metres, `None` where there is no
/// way; an option with a drive that has no way is not proposed.
pub fn options(
    situation: Situation<'_>,
    lengths: impl FnOnce(&[(Point, Point)]) -> Vec<Option<f64>>,
) -> Vec<Candidate> {
    let Situation {
        plan,
        positions,
        route_lengths_m,
        index,
        ..
    } = situation;
    let Some(leg) = plan.legs.get(index) else {
        return Vec::new();
    };
    let mut drafts = Vec::new();
    for waypoint in &plan.waypoints {
        let name = &waypoint.name;
        if *name == leg.to || *name == leg.from || !positions.contains_key(name) {
            continue;
        }
        let mut new = plan.clone();
        let via_name = unique_leg_name(plan, &format!("{}_via_{name}", leg.name));
        let on = Leg {
            name: via_name.clone(),
            from: name.clone(),
            not_before_unix_secs: None,
            ..leg.clone()
        };
        let first = &mut new.legs[index];
        first.to = name.clone();
        first.arrival = None;
        first.wait_secs = None;
        first.arrive_by_unix_secs = None;
        new.legs.insert(index + 1, on);
        drafts.push(Draft {
            kind: Kind::WayRound,
            summary: format!(
                "round through `{name}`: leg `{}` to `{name}`, then `{via_name}` on to `{}`",
                leg.name, leg.to
            ),
            via: vec![name.clone()],
            legs_dropped: Vec::new(),
            plan: new,
        });
    }
    // Round what stopped the follower: the leg itself, from where the robot is, on a map that
    // now has it (the cheapest way round, when the map leaves one).
    if let Some(area) = situation.blockage {
        drafts.insert(
            0,
            Draft {
                kind: Kind::WayRound,
                summary: format!(
                    "drive on to `{}` round what stopped the robot (no-go area `{}`)",
                    leg.to, area.name
                ),
                via: Vec::new(),
                legs_dropped: Vec::new(),
                plan: plan.clone(),
            },
        );
    }
    drafts.extend(skip_draft(plan, index));
    // A leg cannot end where it starts: on a leg that leaves the plan's start, the return is
    // not proposed (the operator aborts, or updates the plan with a leg back).
    if let Some(start) = plan.legs.first().map(|first| first.from.clone())
        && start != leg.to
        && start != leg.from
    {
        let mut new = plan.clone();
        new.legs.truncate(index + 1);
        let first = &mut new.legs[index];
        first.to = start.clone();
        first.arrival = None;
        first.wait_secs = None;
        first.arrive_by_unix_secs = None;
        first.not_before_unix_secs = None;
        drafts.push(Draft {
            kind: Kind::Return,
            summary: format!("return to `{start}`, where the plan starts, and end there"),
            via: Vec::new(),
            legs_dropped: plan.legs[index..]
                .iter()
                .map(|leg| leg.name.clone())
                .collect(),
            plan: new,
        });
    }
    if let Some(area) = situation.blockage {
        for draft in &mut drafts {
            draft.plan.graphics.push(area.clone());
        }
    }
    let mut candidates = cost_all(situation, drafts, lengths);
    candidates.sort_by(|a, b| {
        let key = |candidate: &Candidate| {
            (
                candidate.legs_dropped.len(),
                candidate.deadlines_missed.len(),
            )
        };
        key(a).cmp(&key(b)).then(
            a.duration_secs
                .unwrap_or(f64::INFINITY)
                .total_cmp(&b.duration_secs.unwrap_or(f64::INFINITY)),
        )
    });
    let mut ways_round = 0;
    candidates.retain(|candidate| {
        if candidate.kind != Kind::WayRound {
            return true;
        }
        ways_round += 1;
        ways_round <= MAX_WAYS_ROUND
    });
    // An empty sum of floats is -0.0, which would print as `-0.0 m` (every leg left cut).
    let planned: f64 = route_lengths_m.iter().skip(index).flatten().sum::<f64>() + 0.0;
    candidates.push(wait(planned));
    candidates
}

/// How much longer than at the plan's speed a deadline pushed back gives the rest of the drive:
/// the robot turns and speeds up, and a deadline pushed back to the very second would be
/// missed again.
const PUSH_BACK_SPARE: f64 = 0.2;

/// The options for a leg whose deadline (`arrive_by`) has passed before it arrived
/// (`situation`'s leg in force), best first: its deadline pushed back to when the robot is now
/// expected there (from where it is, at the plan's speed, with a fifth of the drive to spare,
/// rounded up to the second), its deadline dropped, skipping its destination for the next
/// leg's, and waiting last. `lengths` plans as for [`options`].
pub fn late_options(
    situation: Situation<'_>,
    lengths: impl FnOnce(&[(Point, Point)]) -> Vec<Option<f64>>,
) -> Vec<Candidate> {
    let Situation {
        plan,
        route_lengths_m,
        index,
        now_unix_secs,
        ..
    } = situation;
    let Some(leg) = plan.legs.get(index) else {
        return Vec::new();
    };
    let mut drafts = Vec::new();
    let mut dropped = plan.clone();
    dropped.legs[index].arrive_by_unix_secs = None;
    drafts.push(Draft {
        kind: Kind::DropDeadline,
        summary: format!(
            "drop the deadline: leg `{}` drives on to `{}` with none",
            leg.name, leg.to
        ),
        via: Vec::new(),
        legs_dropped: Vec::new(),
        plan: dropped,
    });
    drafts.extend(skip_draft(plan, index));
    // The first pair planned is the first draft's first drive, from where the robot is to the
    // leg's destination: its length says when the robot is now expected there.
    let mut to_destination_m = None;
    let mut candidates = cost_all(situation, drafts, |pairs| {
        let planned = lengths(pairs);
        to_destination_m = planned.first().copied().flatten();
        planned
    });
    if let (Some(length), Some(drop)) = (
        to_destination_m,
        candidates
            .iter()
            .find(|candidate| candidate.kind == Kind::DropDeadline),
    ) {
        let speed_mps = plan.navigation.speed_mps.max(f64::EPSILON);
        let expected = (now_unix_secs + length / speed_mps * (1.0 + PUSH_BACK_SPARE)).ceil();
        let mut pushed = drop.clone();
        if let Some(new) = &mut pushed.plan {
            new.legs[index].arrive_by_unix_secs = Some(expected);
        }
        pushed.kind = Kind::PushBack;
        pushed.summary = format!(
            "push the deadline back to {}, when the robot is now expected at `{}` with a fifth \
             of the drive to spare",
            clock(expected),
            leg.to
        );
        candidates.insert(0, pushed);
    }
    let planned: f64 = route_lengths_m.iter().skip(index).flatten().sum::<f64>() + 0.0;
    candidates.push(wait(planned));
    candidates
}

/// Skipping the destination of leg `index`: it takes the next leg over (none on the last leg).
fn skip_draft(plan: &Plan, index: usize) -> Option<Draft> {
    let leg = plan.legs.get(index)?;
    let next = plan.legs.get(index + 1)?;
    let mut new = plan.clone();
    let taken = new.legs.remove(index + 1);
    let first = &mut new.legs[index];
    // The leg in force keeps its name and its contingencies (its place, held, must stay
    // where the migration finds it) and takes the rest of the next leg over.
    first.to = taken.to;
    first.during = taken.during;
    first.arrival = taken.arrival;
    first.wait_secs = taken.wait_secs;
    first.arrive_by_unix_secs = taken.arrive_by_unix_secs;
    first.not_before_unix_secs = None;
    Some(Draft {
        kind: Kind::Skip,
        summary: format!(
            "skip `{}`: leg `{}` drives on to `{}`, in place of leg `{}`",
            leg.to, leg.name, next.to, next.name
        ),
        via: Vec::new(),
        legs_dropped: vec![leg.name.clone()],
        plan: new,
    })
}

/// Waiting where the robot is, with `planned_m` left to drive as planned.
fn wait(planned_m: f64) -> Candidate {
    Candidate {
        kind: Kind::Wait,
        summary: "wait where the robot is for an update (an area lifted) or the operator"
            .to_owned(),
        via: Vec::new(),
        legs_dropped: Vec::new(),
        plan: None,
        distance_m: round_dm(planned_m),
        duration_secs: None,
        deadlines_missed: Vec::new(),
    }
}

/// An option before its costs are known.
struct Draft {
    kind: Kind,
    summary: String,
    via: Vec<String>,
    legs_dropped: Vec<String>,
    plan: Plan,
}

/// Costs every draft from where the robot is, planning the drives the running plan has no
/// route for in one call of `lengths`; drafts with a drive that has no way are left out.
fn cost_all(
    situation: Situation<'_>,
    drafts: Vec<Draft>,
    lengths: impl FnOnce(&[(Point, Point)]) -> Vec<Option<f64>>,
) -> Vec<Candidate> {
    let Situation {
        plan: running,
        positions,
        route_lengths_m,
        index,
        here,
        ..
    } = situation;
    // Each draft's drives from the leg in force on: a known length (a leg of the running plan
    // between the same waypoints), or a pair to plan.
    let mut pairs: Vec<(Point, Point)> = Vec::new();
    let mut drives: Vec<Vec<Option<Result<f64, usize>>>> = Vec::with_capacity(drafts.len());
    for draft in &drafts {
        let mut legs = Vec::new();
        for (k, leg) in draft.plan.legs.iter().enumerate().skip(index) {
            let known = (k > index)
                .then(|| {
                    running
                        .legs
                        .iter()
                        .position(|old| old.from == leg.from && old.to == leg.to)
                        .and_then(|old| route_lengths_m.get(old).copied().flatten())
                })
                .flatten();
            let start = if k == index {
                Some(here)
            } else {
                positions.get(&leg.from).copied()
            };
            let end = positions.get(&leg.to).copied();
            legs.push(match (known, start, end) {
                (Some(length), _, _) => Some(Ok(length)),
                (None, Some(start), Some(end)) => {
                    pairs.push((start, end));
                    Some(Err(pairs.len() - 1))
                }
                _ => None,
            });
        }
        drives.push(legs);
    }
    let planned = lengths(&pairs);
    let mut candidates = Vec::with_capacity(drafts.len());
    for (draft, legs) in drafts.into_iter().zip(drives) {
        let lengths: Option<Vec<f64>> = legs
            .into_iter()
            .map(|drive| match drive? {
                Ok(length) => Some(length),
                Err(pair) => planned.get(pair).copied().flatten(),
            })
            .collect();
        let Some(lengths) = lengths else {
            continue;
        };
        let (duration_secs, deadlines_missed) = timeline(situation, &draft.plan, &lengths);
        candidates.push(Candidate {
            kind: draft.kind,
            summary: draft.summary,
            via: draft.via,
            legs_dropped: draft.legs_dropped,
            distance_m: round_dm(lengths.iter().sum()),
            duration_secs: Some(round_dm(duration_secs)),
            deadlines_missed,
            plan: Some(draft.plan),
        });
    }
    candidates
}

/// How long the legs of `plan` from the leg in force on take, driven `lengths` metres each at
/// the plan's speed from now, with their appointments, arrival actions and waits; and the
/// deadlines they miss.
fn timeline(situation: Situation<'_>, plan: &Plan, lengths: &[f64]) -> (f64, Vec<String>) {
    let speed_mps = plan.navigation.speed_mps.max(f64::EPSILON);
    let mut at = situation.now_unix_secs;
    let mut missed = Vec::new();
    for (k, (leg, length)) in plan
        .legs
        .iter()
        .skip(situation.index)
        .zip(lengths)
        .enumerate()
    {
        if k > 0
            && let Some(from) = leg.not_before_unix_secs
        {
            at = at.max(from);
        }
        at += length / speed_mps;
        if let Some(by) = leg.arrive_by_unix_secs
            && at > by
        {
            missed.push(format!(
                "leg `{}` due by {}, arrives {}",
                leg.name,
                clock(by),
                clock(at)
            ));
        }
        at += leg
            .arrival
            .as_ref()
            .and_then(|arrival| arrival.for_secs)
            .unwrap_or(0.0)
            + leg.wait_secs.unwrap_or(0.0);
    }
    (at - situation.now_unix_secs, missed)
}

/// The time of day of a date, `HH:MM:SS`.
pub fn clock(unix_secs: f64) -> String {
    let text = crate::net::format_rfc3339(unix_secs);
    text.get(11..19).map_or(text.clone(), str::to_owned)
}

fn round_dm(value: f64) -> f64 {
    (value * 10.0).round() / 10.0
}

/// `wanted`, or `wanted_2`, `wanted_3`, … : the first no leg of `plan` is named.
fn unique_leg_name(plan: &Plan, wanted: &str) -> String {
    let taken: BTreeSet<&str> = plan.legs.iter().map(|leg| leg.name.as_str()).collect();
    if !taken.contains(wanted) {
        return wanted.to_owned();
    }
    (2..)
        .map(|n| format!("{wanted}_{n}"))
        .find(|name| !taken.contains(name.as_str()))
        .unwrap_or_else(|| wanted.to_owned())
}

#[cfg(test)]
mod tests;
