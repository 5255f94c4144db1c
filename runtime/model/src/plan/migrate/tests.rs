use std::collections::{BTreeSet, VecDeque};

use super::*;
use crate::geo::{LatLon, Point};
use crate::net::{Engine, MissionNet};
use crate::plan::compile;
use crate::random::SplitMix64;

fn origin() -> LatLon {
    LatLon::new(43.5615, 1.469)
}

/// A leg of a random plan, as drawn.
#[derive(Clone, Debug)]
struct LegSpec {
    /// `None`: no `name` attribute (named `legN` after its position).
    name: Option<String>,
    /// Its destination; it starts where the leg before it ends (the first one at `w0`).
    to: usize,
    arrival: bool,
    wait_secs: Option<u32>,
    /// Seconds after the plan's start.
    not_before: Option<u32>,
    arrive_by: Option<u32>,
    hold: bool,
}

/// A plan drawn at random: waypoints on a 200 m square, legs between them, square no-go areas.
#[derive(Clone, Debug)]
struct PlanSpec {
    waypoints: Vec<Point>,
    legs: Vec<LegSpec>,
    areas: Vec<Point>,
}

const START: &str = "2026-11-23T08:00:00Z";

fn at(secs: u32) -> String {
    crate::net::format_rfc3339(
        crate::net::parse_rfc3339(START).unwrap_or_default() + f64::from(secs),
    )
}

impl PlanSpec {
    fn random(rng: &mut SplitMix64, serial: &mut usize) -> PlanSpec {
        let waypoints = (0..2 + rng.next_u64() % 6)
            .map(|_| Point::new(rng.uniform(0.0, 200.0), rng.uniform(0.0, 200.0)))
            .collect::<Vec<_>>();
        let mut legs: Vec<LegSpec> = Vec::new();
        for _ in 0..1 + rng.next_u64() % 6 {
            let mut leg = LegSpec::random(rng, waypoints.len(), serial);
            // Never to where it starts.
            let from = legs.last().map_or(0, |before| before.to);
            if leg.to == from {
                leg.to = (from + 1) % waypoints.len();
            }
            legs.push(leg);
        }
        PlanSpec {
            waypoints,
            legs,
            areas: Vec::new(),
        }
    }

    fn xml(&self) -> String {
        let mut text = format!(
            "<plan name=\"p\" system=\"s.xml\" start=\"{START}\"><origin lat=\"43.5615\" lon=\"1.469\"/>\
             <navigation module=\"follower\"/>"
        );
        for (index, point) in self.waypoints.iter().enumerate() {
            let position = LatLon::from_local(*point, origin());
            text.push_str(&format!(
                "<waypoint name=\"w{index}\" lat=\"{:.8}\" lon=\"{:.8}\"/>",
                position.lat_deg, position.lon_deg
            ));
        }
        let mut from = 0;
        for leg in &self.legs {
            text.push_str("<leg");
            if let Some(name) = &leg.name {
                text.push_str(&format!(" name=\"{name}\""));
            }
            text.push_str(&format!(" from=\"w{from}\" to=\"w{}\"", leg.to));
            from = leg.to;
            if let Some(wait) = leg.wait_secs {
                text.push_str(&format!(" wait_secs=\"{wait}\""));
            }
            if let Some(secs) = leg.not_before {
                text.push_str(&format!(" not_before=\"{}\"", at(secs)));
            }
            if let Some(secs) = leg.arrive_by {
                text.push_str(&format!(" arrive_by=\"{}\"", at(secs)));
            }
            text.push('>');
            if leg.arrival {
                text.push_str(
                    "<arrival until=\"observer.observation_done\" for_secs=\"30\">\
                     <module name=\"observer\"/></arrival>",
                );
            }
            // A blocked leg holds for the operator, or is skipped.
            text.push_str(if leg.hold {
                "<contingency on=\"blocked\" do=\"hold\"/>"
            } else {
                "<contingency on=\"blocked\" do=\"skip\"/>"
            });
            text.push_str("</leg>");
        }
        for (index, corner) in self.areas.iter().enumerate() {
            text.push_str(&format!("<area name=\"a{index}\" kind=\"no-go\">"));
            for (dx, dy) in [(0.0, 0.0), (8.0, 0.0), (8.0, 8.0), (0.0, 8.0)] {
                let position =
                    LatLon::from_local(Point::new(corner.x + dx, corner.y + dy), origin());
                text.push_str(&format!(
                    "<point lat=\"{:.8}\" lon=\"{:.8}\"/>",
                    position.lat_deg, position.lon_deg
                ));
            }
            text.push_str("</area>");
        }
        text.push_str("</plan>");
        text
    }

    /// The plan and its net, or `None` when this drawing does not compile (an area over a
    /// waypoint, a leg from a waypoint to itself).
    fn compiled(&self) -> Option<(Plan, Compiled)> {
        let plan = Plan::parse(&self.xml()).ok()?;
        let compiled = compile(&plan, None).ok()?;
        Some((plan, compiled))
    }
}

impl LegSpec {
    fn random(rng: &mut SplitMix64, waypoints: usize, serial: &mut usize) -> LegSpec {
        let to = (rng.next_u64() % waypoints as u64) as usize;
        *serial += 1;
        let chance = |rng: &mut SplitMix64, percent: u64| rng.next_u64() % 100 < percent;
        let not_before = chance(rng, 30).then(|| (rng.next_u64() % 600) as u32);
        LegSpec {
            // A quarter of the legs have no name of their own.
            name: (!chance(rng, 25)).then(|| format!("l{serial}")),
            to,
            arrival: chance(rng, 40),
            wait_secs: chance(rng, 30).then_some(5),
            not_before,
            // A deadline after the appointment, when there is one.
            arrive_by: chance(rng, 30)
                .then(|| not_before.unwrap_or_default() + 60 + (rng.next_u64() % 900) as u32),
            hold: chance(rng, 50),
        }
    }
}

/// One edit an operator might make to a running plan.
fn edit(spec: &PlanSpec, rng: &mut SplitMix64, serial: &mut usize) -> (PlanSpec, &'static str) {
    let mut new = spec.clone();
    let legs = new.legs.len();
    let any_leg = |rng: &mut SplitMix64| (rng.next_u64() % legs as u64) as usize;
    let what = match rng.next_u64() % 9 {
        0 => {
            let index = (rng.next_u64() % new.waypoints.len() as u64) as usize;
            new.waypoints[index].x += rng.uniform(-20.0, 20.0);
            new.waypoints[index].y += rng.uniform(-20.0, 20.0);
            "move a waypoint"
        }
        1 => {
            new.legs
                .push(LegSpec::random(rng, new.waypoints.len(), serial));
            "add a leg at the end"
        }
        2 => {
            let index = (rng.next_u64() % (legs as u64 + 1)) as usize;
            let leg = LegSpec::random(rng, new.waypoints.len(), serial);
            new.legs.insert(index, leg);
            "insert a leg"
        }
        3 if legs > 1 => {
            new.legs.remove(any_leg(rng));
            "remove a leg"
        }
        4 => {
            let index = any_leg(rng);
            *serial += 1;
            new.legs[index].name = Some(format!("renamed{serial}"));
            "rename a leg"
        }
        5 if legs > 1 => {
            let (a, b) = (any_leg(rng), any_leg(rng));
            new.legs.swap(a, b);
            "swap two legs"
        }
        6 => {
            new.areas
                .push(Point::new(rng.uniform(0.0, 190.0), rng.uniform(0.0, 190.0)));
            "add a no-go area"
        }
        7 => {
            let index = any_leg(rng);
            let leg = &mut new.legs[index];
            leg.not_before = leg.not_before.map_or(Some(300), |secs| Some(secs + 120));
            leg.arrive_by = leg.arrive_by.map(|secs| secs + 120);
            "move an appointment later"
        }
        _ => {
            let index = any_leg(rng);
            let leg = &mut new.legs[index];
            leg.arrival = !leg.arrival;
            leg.wait_secs = leg.wait_secs.xor(Some(5));
            leg.hold = !leg.hold;
            "change what a leg does"
        }
    };
    (new, what)
}

/// A marking of `net` reached by a random walk of `steps` firings from its initial one
/// (stopping at a final place), as a run would reach it.
fn random_marking(net: &MissionNet, rng: &mut SplitMix64, steps: u64) -> Marking {
    let mut engine = Engine::new(net);
    for _ in 0..steps {
        let enabled = engine.enabled();
        if enabled.is_empty() || engine.is_final() {
            break;
        }
        let pick = &enabled[(rng.next_u64() % enabled.len() as u64) as usize];
        if engine.fire_by_hand(pick, 0.0).is_err() {
            break;
        }
    }
    engine.marking()
}

/// Every marking reachable from `engine`'s, firing any enabled transition (the untimed net: a
/// run can take any of them), each with the transitions enabled there.
fn reachable(engine: &Engine) -> Vec<(Marking, Vec<String>)> {
    let mut seen = BTreeSet::new();
    let mut queue = VecDeque::from([engine.clone()]);
    let mut found = Vec::new();
    while let Some(engine) = queue.pop_front() {
        let marking = engine.marking();
        if !seen.insert(format!("{marking:?}")) {
            continue;
        }
        let enabled = engine.enabled();
        for name in &enabled {
            let mut next = engine.clone();
            if next.fire_by_hand(name, 0.0).is_ok() {
                queue.push_back(next);
            }
        }
        found.push((marking, enabled));
    }
    found
}

/// The first marked place that comes from a leg, and that leg's index.
fn in_force(old: &Compiled, marking: &Marking) -> Option<(String, usize)> {
    marking.keys().find_map(|place| match old.trace.get(place) {
        Some(Origin::Leg(index)) => Some((place.clone(), *index)),
        _ => None,
    })
}

/// What a migration did wrong, in words.
#[derive(Debug)]
struct Wrong(String);

impl std::fmt::Display for Wrong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl From<&str> for Wrong {
    fn from(why: &str) -> Wrong {
        Wrong(why.to_owned())
    }
}

fn wrong<T>(why: String) -> Result<T, Wrong> {
    Err(Wrong(why))
}

/// What any migration must give, judged from the plans and the nets alone: the legs done are
/// the new plan's first legs by name, the marking is in the first undone leg of the new plan
/// (the one in force), no transition of a leg done is enabled in any marking reachable from
/// it, and it is reachable in the new net from its initial marking.
fn check(
    old_plan: &Plan,
    old: &Compiled,
    marking: &Marking,
    new_plan: &Plan,
    new: &Compiled,
    migration: &Migration,
) -> Result<(), Wrong> {
    let (_, in_force) = in_force(old, marking).ok_or("the old marking is in no leg")?;
    let done_before: Vec<&str> = old_plan.legs[..in_force]
        .iter()
        .map(|leg| leg.name.as_str())
        .collect();
    let done_after: Vec<&str> = new_plan
        .legs
        .iter()
        .take(done_before.len())
        .map(|leg| leg.name.as_str())
        .collect();
    if done_before != done_after || migration.done != done_before {
        return wrong(format!(
            "legs done {done_before:?}, the new plan's first legs {done_after:?}, the \
             migration's done {:?}",
            migration.done
        ));
    }
    let first_undone = done_before.len();
    let undone = new_plan
        .legs
        .get(first_undone)
        .ok_or("the new plan has no leg after those done")?;
    if undone.name != old_plan.legs[in_force].name {
        return wrong(format!(
            "the first undone leg of the new plan is `{}`, the leg in force was `{}`",
            undone.name, old_plan.legs[in_force].name
        ));
    }
    for place in migration.marking.keys() {
        if new.trace.get(place) != Some(&Origin::Leg(first_undone)) {
            return wrong(format!(
                "`{place}` is marked, which is not of leg `{}` (the first undone)",
                undone.name
            ));
        }
    }
    let before = Engine::new(&new.net);
    let engine = Engine::resume(&new.net, &migration.marking, &before, false, 0.0)
        .map_err(|err| Wrong(err.to_string()))?;
    for (marking, enabled) in reachable(&engine) {
        for transition in enabled {
            if let Some(Origin::Leg(index)) = new.trace.get(&transition)
                && *index < first_undone
            {
                return wrong(format!(
                    "`{transition}` of leg `{}`, done, is enabled again in {}",
                    new_plan.legs[*index].name,
                    crate::net::marking_text(&marking)
                ));
            }
        }
    }
    let reachable_from_start = reachable(&Engine::new(&new.net));
    if !reachable_from_start
        .iter()
        .any(|(marking, _)| *marking == migration.marking)
    {
        return wrong(format!(
            "{} is not reachable in the new net",
            crate::net::marking_text(&migration.marking)
        ));
    }
    Ok(())
}

/// A refusal must be right too: the rule it names holds.
fn check_refusal(
    old_plan: &Plan,
    old: &Compiled,
    marking: &Marking,
    new_plan: &Plan,
    new: &Compiled,
    refusal: &Refusal,
) -> Result<(), Wrong> {
    match (refusal, in_force(old, marking).map(|(_, index)| index)) {
        (Refusal::NotInALeg { .. }, None) => Ok(()),
        (Refusal::LegInForceRemoved { leg, .. }, Some(index)) => {
            (old_plan.legs[index].name == *leg && !new_plan.legs.iter().any(|new| new.name == *leg))
                .then_some(())
                .ok_or_else(|| Wrong(format!("refused as removing `{leg}`, which the update has")))
        }
        (Refusal::DoneLegsDiffer { .. }, Some(index)) => {
            let names = |legs: &[crate::plan::Leg]| {
                legs.iter().map(|leg| leg.name.clone()).collect::<Vec<_>>()
            };
            let position = new_plan
                .legs
                .iter()
                .position(|leg| leg.name == old_plan.legs[index].name)
                .ok_or("refused for the legs done, but the leg in force is gone")?;
            (names(&old_plan.legs[..index]) != names(&new_plan.legs[..position]))
                .then_some(())
                .ok_or_else(|| Wrong::from("refused for the legs done, which match"))
        }
        (Refusal::PlaceGone { place, .. }, Some(_)) => new
            .net
            .place(place)
            .is_none()
            .then_some(())
            .ok_or_else(|| Wrong(format!("refused as `{place}` gone, which the update has"))),
        (refusal, _) => wrong(format!("unexpected refusal: {refusal}")),
    }
}

/// A migration planted wrong: the leg in force found by its position in the new plan rather
/// than by its name.
fn by_position(
    old_plan: &Plan,
    old: &Compiled,
    marking: &Marking,
    new_plan: &Plan,
    new: &Compiled,
) -> Option<Migration> {
    let (place, index) = in_force(old, marking)?;
    let leg = new_plan.legs.get(index)?;
    let old_leg = &old_plan.legs[index];
    let after = place.replacen(&old_leg.name, &leg.name, 1);
    new.net.place(&after)?;
    Some(Migration {
        marking: [(after.clone(), 1)].into(),
        done: old_plan.legs[..index]
            .iter()
            .map(|leg| leg.name.clone())
            .collect(),
        leg: leg.name.clone(),
        index,
        place_before: place,
        place_after: after,
        changed: true,
    })
}

/// A migration planted wrong: the new plan started from its first leg, whatever was done.
fn from_the_start(
    old_plan: &Plan,
    old: &Compiled,
    marking: &Marking,
    _new_plan: &Plan,
    new: &Compiled,
) -> Option<Migration> {
    let (place, index) = in_force(old, marking)?;
    Some(Migration {
        marking: new.net.initial_marking(),
        done: old_plan.legs[..index]
            .iter()
            .map(|leg| leg.name.clone())
            .collect(),
        leg: old_plan.legs[index].name.clone(),
        index,
        place_before: place,
        place_after: String::new(),
        changed: true,
    })
}

#[test]
fn migrations_of_random_plans_under_random_edits_keep_done_legs_done_seed_3901() {
    let mut rng = SplitMix64(3901);
    let mut serial = 0;
    let (mut accepted, mut refused, mut caught_position, mut caught_start) = (0, 0, 0, 0);
    let mut edits = BTreeSet::new();
    for round in 0..400 {
        let spec = PlanSpec::random(&mut rng, &mut serial);
        let Some((old_plan, old)) = spec.compiled() else {
            continue;
        };
        let steps = rng.next_u64() % 12;
        let marking = random_marking(&old.net, &mut rng, steps);
        let (new_spec, what) = edit(&spec, &mut rng, &mut serial);
        let Some((new_plan, new)) = new_spec.compiled() else {
            continue;
        };
        let context = || {
            format!(
                "round {round} ({what}) in {}:\nold {}\nnew {}",
                crate::net::marking_text(&marking),
                spec.xml(),
                new_spec.xml()
            )
        };
        match migrate(&old_plan, &old, &marking, &new_plan, &new) {
            Ok(migration) => {
                accepted += 1;
                edits.insert(what);
                if let Err(why) = check(&old_plan, &old, &marking, &new_plan, &new, &migration) {
                    panic!("{why}\n{}", context());
                }
            }
            Err(refusal) => {
                refused += 1;
                if let Err(why) =
                    check_refusal(&old_plan, &old, &marking, &new_plan, &new, &refusal)
                {
                    panic!("{why}\n{}", context());
                }
            }
        }
        // The planted migrations must be caught whenever they differ from the right one.
        for (wrong, caught) in [
            (
                by_position as fn(&_, &_, &_, &_, &_) -> _,
                &mut caught_position,
            ),
            (from_the_start, &mut caught_start),
        ] {
            if let Some(migration) = wrong(&old_plan, &old, &marking, &new_plan, &new)
                && check(&old_plan, &old, &marking, &new_plan, &new, &migration).is_err()
            {
                *caught += 1;
            }
        }
    }
    assert!(
        accepted > 100 && refused > 20,
        "{accepted} accepted, {refused} refused"
    );
    assert!(edits.len() >= 8, "edits accepted: {edits:?}");
    assert!(
        caught_position > 10 && caught_start > 10,
        "the planted wrong migrations were caught {caught_position} and {caught_start} times"
    );
}

/// Two legs drawn by hand: `first` from w0 to w1, `second` from w1 to w2.
fn yard(second_to: Point, areas: Vec<Point>) -> (Plan, Compiled) {
    let leg = |name: &str, to| LegSpec {
        name: Some(name.to_owned()),
        to,
        arrival: false,
        wait_secs: None,
        not_before: None,
        arrive_by: None,
        hold: true,
    };
    PlanSpec {
        waypoints: vec![Point::new(0.0, 0.0), Point::new(50.0, 0.0), second_to],
        legs: vec![leg("first", 1), leg("second", 2)],
        areas,
    }
    .compiled()
    .expect("compiles")
}

#[test]
fn the_leg_in_force_goes_on_unchanged_or_is_replaced_when_it_changed() {
    let (plan, compiled) = yard(Point::new(50.0, 50.0), Vec::new());
    let driving_first: Marking = [("first_drive".to_owned(), 1)].into();
    // The waypoint of the next leg moved: the leg in force goes on as it was.
    let (moved_plan, moved) = yard(Point::new(60.0, 40.0), Vec::new());
    let migration =
        migrate(&plan, &compiled, &driving_first, &moved_plan, &moved).expect("migrates");
    assert_eq!(migration.place_after, "first_drive");
    assert!(!migration.changed);
    // An area across the leg in force: its path changes, and it is replaced.
    let (fenced_plan, fenced) = yard(Point::new(50.0, 50.0), vec![Point::new(20.0, -4.0)]);
    let migration =
        migrate(&plan, &compiled, &driving_first, &fenced_plan, &fenced).expect("migrates");
    assert!(migration.changed, "{migration:?}");
    // Driving the second leg, the first is done: an update without it is refused, and so is
    // one without the leg in force.
    let driving_second: Marking = [("second_drive".to_owned(), 1)].into();
    let mut without_first = moved_plan.clone();
    without_first.legs.remove(0);
    let text = without_first.to_xml();
    let without_first = Plan::parse(&text).expect("reads");
    let compiled_without = compile(&without_first, None).expect("compiles");
    let refusal = migrate(
        &plan,
        &compiled,
        &driving_second,
        &without_first,
        &compiled_without,
    )
    .expect_err("refused");
    assert_eq!(
        refusal.to_string(),
        "the legs done (`first`) must be, by name and in this order, the first legs of the \
         update, followed by `second` in force; the update has none before it"
    );
    let refusal = migrate(
        &plan,
        &compiled,
        &driving_first,
        &without_first,
        &compiled_without,
    )
    .expect_err("refused");
    assert_eq!(
        refusal.to_string(),
        "the update removes leg `first`, which is in force (in `first_drive`): keep a leg of \
         that name, or abort the mission"
    );
    // Held on the second leg, with an update that no longer holds: no place to go on from.
    let held: Marking = [("second_hold".to_owned(), 1)].into();
    let no_hold =
        Plan::parse(&plan.to_xml().replacen("do=\"hold\"", "do=\"skip\"", 2)).expect("reads");
    let no_hold_compiled = compile(&no_hold, None).expect("compiles");
    let refusal =
        migrate(&plan, &compiled, &held, &no_hold, &no_hold_compiled).expect_err("refused");
    assert!(
        refusal
            .to_string()
            .starts_with("leg `second` is in `second_hold`, which the update does not have"),
        "{refusal}"
    );
    // The mission over: nothing to update.
    let done: Marking = [("done".to_owned(), 1)].into();
    assert!(matches!(
        migrate(&plan, &compiled, &done, &moved_plan, &moved),
        Err(Refusal::NotInALeg { .. })
    ));
}

#[test]
fn a_marking_in_two_legs_is_ambiguous() {
    let (plan, compiled) = yard(Point::new(50.0, 50.0), Vec::new());
    let both: Marking = [
        ("first_drive".to_owned(), 1),
        ("second_drive".to_owned(), 1),
    ]
    .into();
    let refusal = migrate(&plan, &compiled, &both, &plan, &compiled).expect_err("refused");
    assert_eq!(
        refusal.to_string(),
        "the marking ({first_drive, second_drive}) is in several legs at once: which one is in \
         force is ambiguous"
    );
}
