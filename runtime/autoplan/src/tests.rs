//! Seeded random instances checked against exhaustive search: the solver's route is optimal in
//! the lexicographic order and keeps every constraint; an instance made infeasible on purpose
//! gets a conflict that is infeasible on its own and feasible without any one of its members.

use std::time::Duration;

use armor_model::geo::LatLon;
use armor_model::plan::{self, Plan};
use armor_model::planner::random::{self, RandomWorld, SplitMix64};
use armor_model::planner::{Costmap, CostmapSettings, Planner, Robot};
use armor_model::world::Point;

use crate::explain::Constraint;
use crate::{ChargeLimit, Outcome, Problem, Route, Task, explain, heuristic, solve};

/// Proving the least lateness of eight tasks took the solver up to 14 s on an idle machine of
/// these, and the second phase may use half of what the first leaves: a busy machine needs the
/// room (an instance proven early ends early).
const LIMIT: Duration = Duration::from_secs(120);

/// A random instance: `n` places in a 60 m square driven at 1 m/s, windows, priorities,
/// optional tasks, precedences and an endurance drawn from `seed`.
fn random_problem(seed: u64, n: usize) -> Problem {
    let mut rng = SplitMix64(seed);
    let mut pick = |lo: f64, hi: f64| rng.uniform(lo, hi);
    let points: Vec<(f64, f64)> = (0..n + 2)
        .map(|_| (pick(0.0, 60.0), pick(0.0, 60.0)))
        .collect();
    let mut travel_ds = vec![vec![None; n + 2]; n + 2];
    let mut distance_dm = vec![vec![0; n + 2]; n + 2];
    for from in 0..=n {
        for to in 1..n + 2 {
            if from == to {
                continue;
            }
            let (a, b) = (points[from], points[to]);
            let metres = (a.0 - b.0).hypot(a.1 - b.1);
            travel_ds[from][to] = Some((metres * 10.0).ceil() as i32);
            distance_dm[from][to] = (metres * 10.0).round() as i32;
        }
    }
    let tasks = (0..n)
        .map(|_| {
            let open = pick(0.0, 1500.0) as i32;
            let width = pick(300.0, 2500.0) as i32;
            Task {
                service_ds: pick(0.0, 100.0) as i32,
                not_before_ds: (pick(0.0, 1.0) < 0.4).then_some(open),
                due_ds: (pick(0.0, 1.0) < 0.5).then_some(open + width / 2),
                by_ds: (pick(0.0, 1.0) < 0.4).then_some(open + width),
                priority: 1 + (pick(0.0, 3.0) as i32).min(2),
                must: pick(0.0, 1.0) < 0.3,
            }
        })
        .collect();
    let mut precedences = Vec::new();
    for _ in 0..n / 3 {
        let a = (pick(0.0, n as f64) as usize).min(n - 1);
        let b = (pick(0.0, n as f64) as usize).min(n - 1);
        if a < b {
            precedences.push((a, b));
        }
    }
    let max_distance_dm = (pick(0.0, 1.0) < 0.3).then_some(pick(1500.0, 4000.0) as i32);
    Problem {
        tasks,
        travel_ds,
        distance_dm,
        precedences,
        max_distance_dm,
        max_time_ds: None,
        max_charge: (pick(0.0, 1.0) < 0.3).then(|| ChargeLimit::new(0.002, 0.1, pick(0.3, 0.6))),
    }
}

/// The best route by trying every order of every subset of the tasks.
fn exhaustive(problem: &Problem) -> Option<Route> {
    fn extend(
        problem: &Problem,
        order: &mut Vec<usize>,
        used: &mut Vec<bool>,
        best: &mut Option<Route>,
    ) {
        if let Some(route) = problem.evaluate(order)
            && best
                .as_ref()
                .is_none_or(|best| route.cost.key() < best.cost.key())
        {
            *best = Some(route);
        }
        for task in 0..problem.tasks.len() {
            if used[task] {
                continue;
            }
            used[task] = true;
            order.push(task);
            extend(problem, order, used, best);
            order.pop();
            used[task] = false;
        }
    }
    let mut best = None;
    extend(
        problem,
        &mut Vec::new(),
        &mut vec![false; problem.tasks.len()],
        &mut best,
    );
    best
}

/// `problem` with only the constraints of `keep` among those an operator gives.
fn only(problem: &Problem, keep: &[Constraint]) -> Problem {
    let mut relaxed = problem.clone();
    for (task, spec) in relaxed.tasks.iter_mut().enumerate() {
        if !keep.contains(&Constraint::Must(task)) {
            spec.must = false;
        }
        if !keep.contains(&Constraint::NotBefore(task)) {
            spec.not_before_ds = None;
        }
        if !keep.contains(&Constraint::By(task)) {
            spec.by_ds = None;
        }
    }
    relaxed.precedences = problem
        .precedences
        .iter()
        .enumerate()
        .filter(|(index, _)| keep.contains(&Constraint::Precedence(*index)))
        .map(|(_, &pair)| pair)
        .collect();
    if !keep.contains(&Constraint::MaxDistance) {
        relaxed.max_distance_dm = None;
    }
    if !keep.contains(&Constraint::MaxTime) {
        relaxed.max_time_ds = None;
    }
    if !keep.contains(&Constraint::MaxCharge) {
        relaxed.max_charge = None;
    }
    relaxed
}

#[test]
fn random_instances_are_solved_to_optimality() {
    let mut solved = 0;
    let mut proven = 0;
    for seed in 0..18u64 {
        let n = 3 + (seed as usize % 6);
        let problem = random_problem(seed, n);
        let best = exhaustive(&problem);
        match (solve(&problem, LIMIT), best) {
            (Outcome::Solved(found), Some(best)) => {
                // The best whether or not the solver could prove it in its time.
                proven += usize::from(found.optimal);
                assert_eq!(
                    found.route.cost.key(),
                    best.cost.key(),
                    "seed {seed} ({n} tasks): solver {:?}, exhaustive {:?}",
                    found.route,
                    best
                );
                // Every constraint holds in the route the solver gives (evaluate checks them
                // all and gives the same route back).
                assert_eq!(
                    problem.evaluate(&found.route.order).as_ref(),
                    Some(&found.route)
                );
                solved += 1;
            }
            (Outcome::Infeasible, None) => {}
            (outcome, best) => panic!("seed {seed}: solver {outcome:?}, exhaustive {best:?}"),
        }
    }
    assert!(
        solved >= 9,
        "only {solved} of 18 random instances were feasible"
    );
    // On a busy machine a proof may take longer than the limit; most take a fraction of it.
    assert!(
        proven * 5 >= solved * 4,
        "only {proven} of {solved} proven the best in {LIMIT:?}"
    );
}

#[test]
fn infeasible_instances_get_a_minimal_conflict() {
    let mut explained = 0;
    for seed in 100..160u64 {
        let n = 3 + (seed as usize % 4);
        let mut problem = random_problem(seed, n);
        // Made infeasible on purpose: every task must be served within a narrow window.
        let mut rng = SplitMix64(seed);
        for task in &mut problem.tasks {
            task.must = true;
            let open = rng.uniform(0.0, 1200.0) as i32;
            task.not_before_ds = Some(open);
            task.by_ds = Some(open + rng.uniform(100.0, 600.0) as i32);
        }
        if exhaustive(&problem).is_some() {
            continue;
        }
        assert_eq!(solve(&problem, LIMIT), Outcome::Infeasible, "seed {seed}");
        let conflict = match explain(&problem, LIMIT) {
            Err(Some(conflict)) => conflict,
            other => panic!("seed {seed}: an infeasible instance explained as {other:?}"),
        };
        assert!(conflict.minimal, "seed {seed}: {conflict:?}");
        assert!(!conflict.constraints.is_empty(), "seed {seed}");
        assert!(
            exhaustive(&only(&problem, &conflict.constraints)).is_none(),
            "seed {seed}: {conflict:?} is feasible on its own"
        );
        for (index, _) in conflict.constraints.iter().enumerate() {
            let mut without = conflict.constraints.clone();
            without.remove(index);
            assert!(
                exhaustive(&only(&problem, &without)).is_some(),
                "seed {seed}: {conflict:?} stays infeasible without {:?}",
                conflict.constraints[index]
            );
        }
        explained += 1;
    }
    assert!(explained >= 5, "only {explained} instances were infeasible");
}

#[test]
fn a_feasible_instance_has_nothing_to_explain() {
    let problem = random_problem(3, 5);
    let relaxed = only(&problem, &[]);
    assert_eq!(explain(&relaxed, LIMIT), Ok(()));
}

#[test]
fn the_heuristic_is_never_better_than_the_solver() {
    for seed in 200..212u64 {
        let problem = random_problem(seed, 7);
        if let (Outcome::Solved(found), Some(heuristic)) = (
            solve(&problem, LIMIT),
            heuristic::nearest_neighbour_2opt(&problem),
        ) {
            assert!(
                found.route.cost.key() <= heuristic.cost.key(),
                "seed {seed}"
            );
            assert!(problem.evaluate(&heuristic.order).is_some());
        }
    }
}

/// On seeded random worlds, the legs of the plan written from the objectives, read back from
/// its file and planned as `armor check` plans them, are the very ways the planner timed: the
/// same length to the bit, so the same times (the ways come from one search per place, the
/// legs from one search each).
#[test]
fn the_written_plan_s_legs_are_the_ways_the_planner_timed_seed_4041() {
    let robot = Robot::default();
    let speed_mps = 0.5;
    let shape = RandomWorld {
        origin: (43.5615, 1.469),
        ..RandomWorld::default()
    };
    let origin = LatLon::new(shape.origin.0, shape.origin.1);
    let mut rng = SplitMix64(4041);
    let (mut legs_compared, mut turning) = (0, 0);
    for index in 0..6 {
        let world = shape.draw(&mut rng);
        let costmap = Costmap::for_world(&world, &robot, &[], &CostmapSettings::default())
            .unwrap_or_else(|err| panic!("{err}"));
        let mut planner = Planner::new(costmap);
        // Places given to the billionth of a degree, finer than a plan file writes them (the
        // written plan moves them by a few millimetres: the planner times the ways from where
        // they will be written), where the robot may be, and reachable from home.
        let mut place = |rng: &mut SplitMix64, home: Option<Point>| loop {
            let p = random::free_place(rng, planner.costmap(), shape.side_m);
            let at = LatLon::from_local(p, origin);
            let (lat, lon) = (format!("{:.9}", at.lat_deg), format!("{:.9}", at.lon_deg));
            let read = |digits: usize| {
                let degrees = |text: &str| {
                    let value: f64 = text.parse().unwrap();
                    format!("{value:.digits$}").parse::<f64>().unwrap()
                };
                LatLon::new(degrees(&lat), degrees(&lon)).to_local(origin)
            };
            let (given, written) = (read(9), read(7));
            if planner.costmap().blocker_at(given).is_none()
                && planner.costmap().blocker_at(written).is_none()
                && home.is_none_or(|home| planner.plan(home, written).is_ok())
            {
                return (written, format!("lat=\"{lat}\" lon=\"{lon}\""));
            }
        };
        let (home, home_at) = place(&mut rng, None);
        let mut text = format!(
            "<plan name=\"random\" system=\"system.xml\" start=\"2026-11-23T08:00:00Z\">\n\
             <navigation speed_mps=\"{speed_mps}\"/>\n<waypoint name=\"home\" {home_at}/>\n\
             <objectives from=\"home\" to=\"home\">\n"
        );
        for objective in 0..7 {
            let (_, at) = place(&mut rng, Some(home));
            text.push_str(&format!("<objective name=\"o{objective}\" {at}/>\n"));
        }
        text.push_str("</objectives>\n</plan>\n");
        let plan = Plan::parse(&text).unwrap_or_else(|problems| panic!("{problems:?}"));
        let instance = crate::instance(&plan, Some(&world), &robot, speed_mps)
            .unwrap_or_else(|problems| panic!("world {index}: {problems:?}"));
        let route = heuristic::nearest_neighbour_2opt(&instance.problem)
            .unwrap_or_else(|| panic!("world {index}: no route"));
        let written = crate::write::plan(&plan, &instance, &route);
        let read = Plan::parse(&written.to_xml()).unwrap_or_else(|problems| panic!("{problems:?}"));
        let legs = plan::plan_legs(&read, Some(&world), &robot);
        assert!(
            legs.problems.is_empty(),
            "world {index}: {:?}",
            legs.problems
        );
        let end = instance.problem.end();
        let nodes: Vec<usize> = std::iter::once(0)
            .chain(route.order.iter().map(|&task| crate::Problem::node(task)))
            .chain([end])
            .collect();
        assert_eq!(legs.paths.len(), nodes.len() - 1, "world {index}");
        for (leg, (pair, path)) in nodes.windows(2).zip(&legs.paths).enumerate() {
            let (from, to) = (pair[0], pair[1]);
            let path = match path {
                Some(Ok(path)) => path,
                other => panic!("world {index}, leg {leg}: {other:?}"),
            };
            let context = format!("seed 4041, world {index}, leg {leg} ({from} to {to})");
            assert_eq!(
                instance.length(from, to).map(f64::to_bits),
                Some(path.length_m.to_bits()),
                "{context}"
            );
            assert_eq!(
                instance.problem.travel_ds[from][to],
                Some(crate::instance::ds_up(path.length_m / speed_mps)),
                "{context}"
            );
            legs_compared += 1;
            turning += usize::from(path.points.len() > 2);
        }
    }
    assert!(
        legs_compared >= 40 && turning >= 10,
        "{legs_compared} legs compared, {turning} of them turning"
    );
}

/// Objectives as areas (issue 40): one the robot only reaches is placed at the point of it the
/// robot gets to first from the start, one it acts on at its centroid; an area walled in, and
/// one whose centroid is in a wall, are refused at the area's line.
#[test]
fn areas_are_reached_at_their_nearest_point_or_observed_from_their_centroid() {
    let world = armor_model::world::World::parse(
        "name t\norigin 43.56 1.469\nstart 2 2 0\nboundary 0,0 30,0 30,20 0,20 0,0\n\
         rect 8,0 8.3,12\n\
         rect 20,5 28,5.3\nrect 20,14.7 28,15\nrect 20,5 20.3,15\nrect 27.7,5 28,15\n",
        "t.world",
    )
    .unwrap_or_else(|err| panic!("{err}"));
    let origin = LatLon::new(43.56, 1.469);
    let at = |x: f64, y: f64| {
        let p = LatLon::from_local(Point::new(x, y), origin);
        format!("lat=\"{:.7}\" lon=\"{:.7}\"", p.lat_deg, p.lon_deg)
    };
    let area = |corners: &[(f64, f64)]| {
        let points: String = corners
            .iter()
            .map(|&(x, y)| format!("<point {}/>", at(x, y)))
            .collect();
        format!("<area>{points}</area>")
    };
    let square =
        |x0: f64, y0: f64, x1: f64, y1: f64| area(&[(x0, y0), (x1, y0), (x1, y1), (x0, y1)]);
    let text = |objectives: &str| {
        format!(
            "<plan name=\"p\" system=\"system.xml\" start=\"2026-11-23T08:00:00Z\">\n\
             <navigation speed_mps=\"0.5\"/>\n<waypoint name=\"home\" {}/>\n\
             <objectives from=\"home\" to=\"home\">\n{objectives}</objectives>\n</plan>\n",
            at(2.0, 2.0)
        )
    };
    let robot = Robot::default();
    let good = text(&format!(
        "<objective name=\"lot\">{}</objective>\n\
         <objective name=\"look\">{}<arrival for_secs=\"10\"><module name=\"observer\"/></arrival></objective>\n",
        square(12.0, 2.0, 16.0, 6.0),
        square(2.0, 14.0, 6.0, 18.0)
    ));
    let plan = Plan::parse(&good).unwrap_or_else(|problems| panic!("{problems:?}"));
    let instance = crate::instance(&plan, Some(&world), &robot, 0.5)
        .unwrap_or_else(|problems| panic!("{problems:?}"));
    let (lot, look) = (instance.points[1], instance.points[2]);
    // Reached from home round the top of the wall at x = 8: the area's first cell on that way
    // is at its top, near its left corner.
    let lot_area = armor_model::geo::Polygon::new(vec![
        Point::new(12.0, 2.0),
        Point::new(16.0, 2.0),
        Point::new(16.0, 6.0),
        Point::new(12.0, 6.0),
    ]);
    assert!(lot_area.contains(lot), "{lot}");
    assert!(lot.y > 5.8 && lot.x < 13.0, "{lot}");
    let way_in = instance.length(0, 1).unwrap_or(f64::NAN);
    for inner in [
        Point::new(14.0, 4.0),
        Point::new(12.2, 2.2),
        Point::new(15.8, 5.8),
    ] {
        let mut planner = Planner::new(
            Costmap::for_world(&world, &robot, &[], &CostmapSettings::default())
                .unwrap_or_else(|err| panic!("{err}")),
        );
        let further = planner
            .plan(instance.points[0], inner)
            .map(|path| path.length_m);
        assert!(
            further.as_ref().is_ok_and(|length| *length >= way_in - 0.1),
            "{inner} is nearer than {lot} ({further:?} against {way_in})"
        );
    }
    assert!(look.distance(Point::new(4.0, 16.0)) < 0.02, "{look}");
    // The written plan gives them as waypoints of their own, where they were placed.
    let route =
        heuristic::nearest_neighbour_2opt(&instance.problem).unwrap_or_else(|| panic!("no route"));
    let written = crate::write::plan(&plan, &instance, &route);
    let read = Plan::parse(&written.to_xml()).unwrap_or_else(|problems| panic!("{problems:?}"));
    let legs = plan::plan_legs(&read, Some(&world), &robot);
    assert!(legs.problems.is_empty(), "{:?}", legs.problems);
    assert_eq!(legs.positions.get("lot"), Some(&lot));

    // Walled in, and a centroid in a wall: refused at the area's line (the objective's is 5).
    let bad = text(&format!(
        "<objective name=\"room\">\n{}</objective>\n\
         <objective name=\"wall\">\n{}<arrival for_secs=\"10\"><module name=\"observer\"/></arrival></objective>\n",
        square(22.0, 8.0, 26.0, 12.0),
        square(7.0, 3.0, 9.3, 5.0)
    ));
    let plan = Plan::parse(&bad).unwrap_or_else(|problems| panic!("{problems:?}"));
    let problems: Vec<String> = match crate::instance(&plan, Some(&world), &robot, 0.5) {
        Ok(_) => panic!("a walled-in area was placed"),
        Err(problems) => problems.iter().map(ToString::to_string).collect(),
    };
    for (line, says) in [
        (
            6,
            "objective `room`: no part of its area can be reached from `home`",
        ),
        (8, "objective `wall` acts on its area from its centroid"),
    ] {
        assert!(
            problems
                .iter()
                .any(|problem| problem.starts_with(&format!("{line}:")) && problem.contains(says)),
            "no `{line}: {says}` in {problems:#?}"
        );
    }
}
