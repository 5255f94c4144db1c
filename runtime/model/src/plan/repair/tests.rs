use super::*;
use crate::geo::LatLon;
use crate::plan::{Compiled, compile};

const START: &str = "2026-11-23T08:00:00Z";

/// Seconds after the plan's start, as a date.
fn at(secs: u32) -> String {
    crate::net::format_rfc3339(
        crate::net::parse_rfc3339(START).unwrap_or_default() + f64::from(secs),
    )
}

/// A plan with no world (straight paths): `home` (0, 0), `gate` (20, 0), `east` (20, 20),
/// `north` (0, 20); legs `out` home → gate (due at 100 s), `up` gate → east, `back` east → home;
/// 1 m/s.
fn square(out_by_secs: u32) -> (Plan, Compiled) {
    let origin = LatLon::new(43.5615, 1.469);
    let waypoint = |name: &str, x: f64, y: f64| {
        let position = LatLon::from_local(Point::new(x, y), origin);
        format!(
            "<waypoint name=\"{name}\" lat=\"{:.9}\" lon=\"{:.9}\"/>",
            position.lat_deg, position.lon_deg
        )
    };
    let text = format!(
        "<plan name=\"p\" system=\"s.xml\" start=\"{START}\"><origin lat=\"43.5615\" lon=\"1.469\"/>\
         <navigation module=\"follower\" speed_mps=\"1\"/>{}{}{}{}\
         <leg name=\"out\" from=\"home\" to=\"gate\" arrive_by=\"{}\" wait_secs=\"5\"/>\
         <leg name=\"up\" from=\"gate\" to=\"east\"/>\
         <leg name=\"back\" from=\"east\" to=\"home\"/>\
         <contingency on=\"blocked\" do=\"repair\"/></plan>",
        waypoint("home", 0.0, 0.0),
        waypoint("gate", 20.0, 0.0),
        waypoint("east", 20.0, 20.0),
        waypoint("north", 0.0, 20.0),
        at(out_by_secs),
    );
    let plan = Plan::parse(&text).expect("the test plan parses");
    let compiled = compile(&plan, None).expect("the test plan compiles");
    (plan, compiled)
}

/// The lengths of the legs as compiled.
fn lengths_of(compiled: &Compiled) -> Vec<Option<f64>> {
    compiled
        .routes
        .iter()
        .map(|route| Some(crate::geo::path_length(route)))
        .collect()
}

/// Straight-line lengths, but no way across the segment x = 10 for |y| < 5 (a wall on the
/// leg `out`'s line).
fn straight_but_walled(pairs: &[(Point, Point)]) -> Vec<Option<f64>> {
    pairs
        .iter()
        .map(|&(a, b)| {
            let crosses = (a.x < 10.0) != (b.x < 10.0) && {
                let t = (10.0 - a.x) / (b.x - a.x);
                (a.y + t * (b.y - a.y)).abs() < 5.0
            };
            (!crosses).then(|| a.distance(b))
        })
        .collect()
}

/// The options for leg `index` of `plan`, the robot `here`, `now_secs` after the plan's start,
/// on the walled square.
fn proposed(
    plan: &Plan,
    compiled: &Compiled,
    index: usize,
    here: Point,
    now_secs: f64,
) -> Vec<Candidate> {
    options(
        Situation {
            plan,
            positions: &compiled.positions,
            route_lengths_m: &lengths_of(compiled),
            index,
            here,
            now_unix_secs: plan.start_unix_secs.unwrap_or_default() + now_secs,
            blockage: None,
        },
        straight_but_walled,
    )
}

/// What a repair proposes, a line each: kind, via, legs dropped, metres, seconds, deadlines.
fn check(out_by_secs: u32, now_secs: f64, here: Point, expected: &[&str]) {
    let (plan, compiled) = square(out_by_secs);
    let options = proposed(&plan, &compiled, 0, here, now_secs);
    let shown: Vec<String> = options
        .iter()
        .map(|option| {
            format!(
                "{:?} via {:?} dropping {:?}: {} m, {:?} s, missed {:?}",
                option.kind,
                option.via,
                option.legs_dropped,
                option.distance_m,
                option.duration_secs,
                option.deadlines_missed
            )
        })
        .collect();
    assert_eq!(shown, expected, "options: {options:#?}");
}

#[test]
fn options_are_costed_to_the_plans_end_and_ranked() {
    // The robot is at (5, 0) on `out`, walled from `gate`. Round through `east`: 25 m in a
    // line (it crosses x = 10 at y = 6.7, past the wall's end), then `east` → `gate` (20 m),
    // then the plan's `up` (20) and `back` (28.3), and `gate`'s wait of 5 s. Round through
    // `north`: 20.6 + 28.3 (`north` → `gate` crosses x = 10 at y = 10) + 20 + 28.3. Skipping
    // `gate` drives to `east` (25 m), then `back` (28.3). Waiting: the plan as it was drawn, 20 +
    // 20 + 28.3. No return: `out` leaves from where the plan starts.
    check(
        1000,
        0.0,
        Point::new(5.0, 0.0),
        &[
            "WayRound via [\"east\"] dropping []: 93.3 m, Some(98.3) s, missed []",
            "WayRound via [\"north\"] dropping []: 97.2 m, Some(102.2) s, missed []",
            "Skip via [] dropping [\"out\"]: 53.3 m, Some(53.3) s, missed []",
            "Wait via [] dropping []: 68.3 m, None s, missed []",
        ],
    );
}

#[test]
fn a_deadline_missed_ranks_an_option_after_those_that_meet_it() {
    // `out` is due 57 s after the start and it is 10 s past it: through `east` `gate` is
    // reached 10 + 25 + 20 = 55 s in (met), through `north` at 10 + 20.6 + 28.3 = 58.9 s
    // (missed), which ranks it after the way round that meets it, still before the options
    // that give up a destination.
    check(
        57,
        10.0,
        Point::new(5.0, 0.0),
        &[
            "WayRound via [\"east\"] dropping []: 93.3 m, Some(98.3) s, missed []",
            "WayRound via [\"north\"] dropping []: 97.2 m, Some(102.2) s, missed [\"leg `out_via_north` due by 08:00:57, arrives 08:00:58\"]",
            "Skip via [] dropping [\"out\"]: 53.3 m, Some(53.3) s, missed []",
            "Wait via [] dropping []: 68.3 m, None s, missed []",
        ],
    );
}

#[test]
fn an_option_with_a_drive_that_has_no_way_is_not_proposed() {
    // The robot at (12, 0), past the wall: the way to `north` crosses it (at y = 3.3), so
    // it is not proposed. Through `east`: 21.5 + 20 + 20 + 28.3;
    // skipping: 21.5 + 28.3.
    check(
        1000,
        0.0,
        Point::new(12.0, 0.0),
        &[
            "WayRound via [\"east\"] dropping []: 89.8 m, Some(94.8) s, missed []",
            "Skip via [] dropping [\"out\"]: 49.8 m, Some(49.8) s, missed []",
            "Wait via [] dropping []: 68.3 m, None s, missed []",
        ],
    );
}

#[test]
fn the_return_ends_the_plan_where_it_started() {
    let (plan, compiled) = square(1000);
    // On `up`, at (20, 10), nothing walled: the return drives 22.4 m home and drops the rest.
    let options = proposed(&plan, &compiled, 1, Point::new(20.0, 10.0), 0.0);
    let back = options
        .iter()
        .find(|option| option.kind == Kind::Return)
        .expect("a return is proposed");
    assert_eq!(
        (back.distance_m, back.legs_dropped.clone()),
        (22.4, vec!["up".to_owned(), "back".to_owned()])
    );
    let legs: Vec<(&str, &str)> = back
        .plan
        .iter()
        .flat_map(|plan| &plan.legs)
        .map(|leg| (leg.from.as_str(), leg.to.as_str()))
        .collect();
    assert_eq!(legs, [("home", "gate"), ("gate", "home")]);
}

#[test]
fn each_option_is_a_plan_that_keeps_the_leg_in_force_and_compiles() {
    let (plan, compiled) = square(1000);
    let options = proposed(&plan, &compiled, 0, Point::new(5.0, 0.0), 0.0);
    let routes: Vec<Vec<(String, String, String)>> = options
        .iter()
        .filter_map(|option| option.plan.as_ref())
        .map(|plan| {
            assert!(compile(plan, None).is_ok(), "{}", plan.to_xml());
            assert!(
                crate::plan::Plan::parse(&plan.to_xml()).is_ok(),
                "{}",
                plan.to_xml()
            );
            plan.legs
                .iter()
                .map(|leg| (leg.name.clone(), leg.from.clone(), leg.to.clone()))
                .collect()
        })
        .collect();
    let leg = |name: &str, from: &str, to: &str| (name.to_owned(), from.to_owned(), to.to_owned());
    assert_eq!(
        routes,
        vec![
            vec![
                leg("out", "home", "east"),
                leg("out_via_east", "east", "gate"),
                leg("up", "gate", "east"),
                leg("back", "east", "home"),
            ],
            vec![
                leg("out", "home", "north"),
                leg("out_via_north", "north", "gate"),
                leg("up", "gate", "east"),
                leg("back", "east", "home"),
            ],
            vec![leg("out", "home", "east"), leg("back", "east", "home")],
        ]
    );
    // The way round keeps the leg's deadline and wait for the leg that reaches `gate`.
    let round = options[0].plan.as_ref().expect("a plan");
    assert_eq!(
        (round.legs[0].arrive_by_unix_secs, round.legs[0].wait_secs),
        (None, None)
    );
    assert_eq!(round.legs[1].wait_secs, Some(5.0));
    assert!(round.legs[1].arrive_by_unix_secs.is_some());
}

#[test]
fn a_late_leg_is_offered_its_deadline_pushed_back_or_dropped_or_the_skip() {
    // `out` was due 10 s after the start; it is 12 s in, the robot at (5, 0): 15 m left, at
    // 1 m/s, so it is now expected at `gate` 27 s in, 30 s with a fifth of the drive to spare.
    // Pushed back, the deadline is then; dropped,
    // there is none; either way the rest is the plan's (`out`'s wait of 5 s, `up` 20 m, `back`
    // 28.3 m). Skipping `gate` drives to `east` (25 m in a line from here) then `back`.
    let (plan, compiled) = square(10);
    let here = Point::new(5.0, 0.0);
    let options = late_options(
        Situation {
            plan: &plan,
            positions: &compiled.positions,
            route_lengths_m: &lengths_of(&compiled),
            index: 0,
            here,
            now_unix_secs: plan.start_unix_secs.unwrap_or_default() + 12.0,
            blockage: None,
        },
        |pairs| pairs.iter().map(|&(a, b)| Some(a.distance(b))).collect(),
    );
    let kinds: Vec<Kind> = options.iter().map(|option| option.kind).collect();
    assert_eq!(
        kinds,
        [Kind::PushBack, Kind::DropDeadline, Kind::Skip, Kind::Wait]
    );
    let deadline = |option: &Candidate| {
        option.plan.as_ref().map(|plan| {
            plan.legs[0]
                .arrive_by_unix_secs
                .map(|by| by - plan.start_unix_secs.unwrap_or_default())
        })
    };
    assert_eq!(deadline(&options[0]), Some(Some(30.0)));
    assert!(
        options[0].summary.contains("08:00:30"),
        "{}",
        options[0].summary
    );
    assert_eq!(deadline(&options[1]), Some(None));
    for option in &options[..2] {
        assert_eq!(option.distance_m, 63.3, "{option:#?}");
        assert_eq!(option.duration_secs, Some(68.3), "{option:#?}");
        assert!(option.deadlines_missed.is_empty(), "{option:#?}");
        let repaired = option.plan.as_ref().map(|plan| compile(plan, None));
        assert!(
            matches!(repaired, Some(Ok(_))),
            "{}: {repaired:?}",
            option.summary
        );
    }
    assert_eq!(options[2].legs_dropped, ["out"]);
    assert_eq!(options[2].distance_m, 53.3);
}

#[test]
fn what_stopped_the_follower_is_held_by_every_option_and_driven_round_first() {
    // The follower stopped at (5, 0) on `out` before something the map does not have; the
    // caller placed it as the area `out_blocked` and plans round it: the way to `gate` from
    // here, twice as long as the line (15 m), and any other way across x = 10 as long. Driving
    // on round it, 30 + 20 + 28.3 m and `gate`'s wait, is the cheapest way round, and ranks
    // first; the ways through another waypoint and the skip follow, each holding the area.
    let (plan, compiled) = square(1000);
    let area = Graphic {
        kind: crate::plan::GraphicKind::Area(crate::plan::AreaKind::NoGo),
        name: "out_blocked".to_owned(),
        points: [(6.0, -2.0), (7.0, -2.0), (7.0, 2.0), (6.0, 2.0)]
            .iter()
            .map(|&(x, y)| LatLon::from_local(Point::new(x, y), LatLon::new(43.5615, 1.469)))
            .collect(),
        margin_m: Some(0.1),
        ..Default::default()
    };
    let options = options(
        Situation {
            plan: &plan,
            positions: &compiled.positions,
            route_lengths_m: &lengths_of(&compiled),
            index: 0,
            here: Point::new(5.0, 0.0),
            now_unix_secs: plan.start_unix_secs.unwrap_or_default(),
            blockage: Some(&area),
        },
        |pairs| {
            pairs
                .iter()
                .zip(straight_but_walled(pairs))
                .map(|(&(a, b), line)| Some(line.unwrap_or(2.0 * a.distance(b))))
                .collect()
        },
    );
    let first = &options[0];
    assert_eq!(
        (
            first.kind,
            first.via.clone(),
            first.distance_m,
            first.duration_secs
        ),
        (Kind::WayRound, Vec::<String>::new(), 78.3, Some(83.3)),
        "{options:#?}"
    );
    assert_eq!(
        first.summary,
        "drive on to `gate` round what stopped the robot (no-go area `out_blocked`)"
    );
    let kinds: Vec<Kind> = options.iter().map(|option| option.kind).collect();
    assert_eq!(
        kinds,
        [
            Kind::WayRound,
            Kind::WayRound,
            Kind::WayRound,
            Kind::Skip,
            Kind::Wait
        ]
    );
    // Driving on changes nothing but the area; every option holds it and compiles.
    let driven_on = first.plan.as_ref().expect("a plan");
    assert_eq!(driven_on.legs, plan.legs);
    for option in options.iter().filter_map(|option| option.plan.as_ref()) {
        assert!(option.graphics.contains(&area), "{}", option.to_xml());
        assert!(compile(option, None).is_ok(), "{}", option.to_xml());
    }
}
