//! `auto_plan_20_objectives_ms` and `auto_plan_quality`: the constraint planner (`armor plan`,
//! `armor_autoplan`) on seeded instances of 20 objectives on the path planner's bench world
//! (100 m × 100 m, 200 obstacles): random reachable places, a third of them with a window that
//! opens later, some due by a time, some with a hard limit, priorities 1 to 3, half of them
//! optional, driven at 0.5 m/s.
//!
//! `auto_plan_20_objectives_ms`: the time to the first plan the solver proves feasible, the
//! distance matrix included (one search from each place to all the others on the costmap), p50
//! and p99, and the matrix alone (`matrix_*`); beside it the time to the best plan within a 2 s
//! limit. The reference is nearest neighbour plus
//! 2-opt on the same matrix (the matrix included too). Goal: a first plan under 200 ms.
//!
//! `auto_plan_quality`: the same instances, the solver's plan within 2 s against the
//! heuristic's, in the lexicographic order (most priority served, then least lateness, then
//! least distance): how many the solver does better, as well, or worse (goal: never worse), and
//! the median of distance driven (ours, reference) among those where both serve as much at the
//! same lateness. The solver is measured unseeded, and seeded with the heuristic's plan as
//! `armor plan` runs it (`seeded_*`: never worse by construction).

use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow, bail};
use armor_autoplan::{Outcome, heuristic};
use armor_model::geo::LatLon;
use armor_model::plan::Plan;
use armor_model::planner::{Costmap, CostmapSettings, Planner, Robot};
use armor_model::world::{Point, World};
use armor_module_catalog::sim::rng::Rng;

use crate::Settings;
use crate::path_plan;
use armor_bench_report::{Report, median};

pub const NAME: &str = "auto_plan_20_objectives_ms";
pub const NAME_QUALITY: &str = "auto_plan_quality";

const SEED: u64 = 40;
const OBJECTIVES: usize = 20;
const SPEED_MPS: f64 = 0.5;
const LIMIT: Duration = Duration::from_secs(2);
/// The plans start at 2026-11-23T08:00:00Z.
const START_UNIX_SECS: f64 = 1_795_420_800.0;

/// The plan of instance `index`: 20 objectives at places reachable from the start.
fn plan_text(world: &World, planner: &mut Planner, index: u64) -> String {
    let mut rng = Rng::new(SEED + index, 1);
    let free = |rng: &mut Rng, planner: &Planner| loop {
        let p = Point::new(rng.uniform() * 100.0, rng.uniform() * 100.0);
        let map = planner.costmap();
        if map.blocker_at(p).is_none() && !map.is_lethal_at(p) {
            return p;
        }
    };
    let home = free(&mut rng, planner);
    let mut places = Vec::new();
    while places.len() < OBJECTIVES {
        let p = free(&mut rng, planner);
        if planner.plan(home, p).is_ok() {
            places.push(p);
        }
    }
    let (lat, lon) = world.origin_lat_lon();
    let origin = LatLon::new(lat, lon);
    let at = |p: Point| {
        let at = LatLon::from_local(p, origin);
        format!("lat=\"{:.9}\" lon=\"{:.9}\"", at.lat_deg, at.lon_deg)
    };
    let date = |secs: f64| armor_model::net::format_rfc3339(START_UNIX_SECS + secs.round());
    let mut text = format!(
        "<plan name=\"bench\" system=\"system.xml\" world=\"bench.world\" start=\"{}\">\n\
         <navigation speed_mps=\"{SPEED_MPS}\"/>\n<waypoint name=\"home\" {}/>\n\
         <objectives from=\"home\" to=\"home\">\n",
        date(0.0),
        at(home)
    );
    for (i, p) in places.iter().enumerate() {
        let mut attrs = format!("name=\"o{i}\" {}", at(*p));
        let mut draw = |lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
        let opens = draw(0.0, 1500.0);
        if draw(0.0, 1.0) < 0.33 {
            attrs.push_str(&format!(" not_before=\"{}\"", date(opens)));
        }
        let due = opens + draw(300.0, 1800.0);
        if draw(0.0, 1.0) < 0.4 {
            attrs.push_str(&format!(" due=\"{}\"", date(due)));
        }
        if draw(0.0, 1.0) < 0.2 {
            attrs.push_str(&format!(" by=\"{}\"", date(due + 900.0)));
        }
        attrs.push_str(&format!(
            " priority=\"{}\"",
            1 + (draw(0.0, 3.0) as u32).min(2)
        ));
        if draw(0.0, 1.0) < 0.5 {
            attrs.push_str(" optional=\"true\"");
        }
        attrs.push_str(&format!(" wait_secs=\"{}\"", draw(0.0, 20.0).round()));
        text.push_str(&format!("<objective {attrs}/>\n"));
    }
    text.push_str("</objectives>\n</plan>\n");
    text
}

/// One instance measured.
struct Measured {
    /// The distance matrix alone (the costmap and the ways between every two places).
    matrix: Duration,
    /// The matrix and the solver's first proven plan.
    first: Duration,
    /// The matrix and the best within the limit.
    best: Duration,
    /// The matrix and the heuristic.
    heuristic: Duration,
    /// `None`: no plan within the limit.
    ours: Option<armor_autoplan::Cost>,
    theirs: Option<armor_autoplan::Cost>,
    /// The solver seeded with the heuristic's plan, within the same limit.
    seeded: Option<armor_autoplan::Cost>,
    proven: bool,
}

fn measure(world: &World, text: &str) -> anyhow::Result<Measured> {
    let plan = Plan::parse(text).map_err(|problems| anyhow!("the bench's plan: {problems:?}"))?;
    let began = Instant::now();
    let instance = armor_autoplan::instance(&plan, Some(world), &Robot::default(), SPEED_MPS)
        .map_err(|problems| anyhow!("the bench's objectives: {problems:?}"))?;
    let matrix = began.elapsed();
    let began = Instant::now();
    // No plan within the limit counts as the limit for the first plan, and as worse.
    let solved = match armor_autoplan::solve(&instance.problem, LIMIT) {
        Outcome::Solved(solved) => Some(solved),
        Outcome::Unknown => None,
        Outcome::Infeasible => bail!("the bench's instance is infeasible"),
    };
    let solving = began.elapsed();
    let began = Instant::now();
    let theirs = heuristic::nearest_neighbour_2opt(&instance.problem);
    let heuristic = began.elapsed();
    let seeded = match armor_autoplan::solve_from(&instance.problem, LIMIT, theirs.as_ref()) {
        Outcome::Solved(solved) => Some(solved.route.cost),
        _ => None,
    };
    Ok(Measured {
        matrix,
        first: matrix + solved.as_ref().map_or(LIMIT, |solved| solved.first_found),
        best: matrix + solving,
        heuristic: matrix + heuristic,
        ours: solved.as_ref().map(|solved| solved.route.cost),
        theirs: theirs.map(|route| route.cost),
        seeded,
        proven: solved.is_some_and(|solved| solved.optimal),
    })
}

/// Every instance measured once (they take seconds each: the two benches share them).
fn measure_all(settings: &Settings) -> anyhow::Result<Vec<Measured>> {
    let count = if settings.quick { 2 } else { 12 };
    let world = path_plan::world()?;
    let costmap = Costmap::for_world(&world, &Robot::default(), &[], &CostmapSettings::default())
        .map_err(|err| anyhow!("{err}"))?;
    let mut planner = Planner::new(costmap);
    (0..count)
        .map(|index| {
            let text = plan_text(&world, &mut planner, index);
            measure(&world, &text).with_context(|| format!("instance {index}"))
        })
        .collect()
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let measured = measure_all(settings)?;
    let first: Vec<Duration> = measured.iter().map(|m| m.first).collect();
    let reference: Vec<Duration> = measured.iter().map(|m| m.heuristic).collect();
    let mut best: Vec<f64> = measured
        .iter()
        .map(|m| m.best.as_secs_f64() * 1e3)
        .collect();
    best.sort_by(f64::total_cmp);
    let mut matrix: Vec<f64> = measured
        .iter()
        .map(|m| m.matrix.as_secs_f64() * 1e3)
        .collect();
    matrix.sort_by(f64::total_cmp);
    Ok(Report::distribution(NAME, "ms", 1e3, &first, &reference)
        .with(
            "reference_is",
            "nearest neighbour + 2-opt on the same distance matrix (the matrix included)",
        )
        .with("instances", measured.len())
        .with("objectives", OBJECTIVES)
        .with(
            "matrix_p50_ms",
            armor_bench_report::round(armor_bench_report::percentile(&matrix, 0.5)),
        )
        .with(
            "matrix_p99_ms",
            armor_bench_report::round(armor_bench_report::percentile(&matrix, 0.99)),
        )
        .with(
            "best_within_2s_p50_ms",
            armor_bench_report::round(armor_bench_report::percentile(&best, 0.5)),
        )
        .with(
            "best_within_2s_p99_ms",
            armor_bench_report::round(armor_bench_report::percentile(&best, 0.99)),
        )
        .with(
            "proven_best_within_2s",
            measured.iter().filter(|m| m.proven).count(),
        )
        .with("goal_first_p99_ms", 200))
}

pub fn run_quality(settings: &Settings) -> anyhow::Result<Report> {
    let measured = measure_all(settings)?;
    let (mut better, mut equal, mut worse) = (0, 0, 0);
    let (mut heuristic_failed, mut nothing) = (0usize, 0usize);
    let (mut seeded_better, mut seeded_equal, mut seeded_worse) = (0, 0, 0);
    let (mut ours_m, mut theirs_m) = (Vec::new(), Vec::new());
    // No plan is worse than any plan, and as good as no plan.
    let key = |cost: Option<armor_autoplan::Cost>| {
        cost.map_or((i32::MAX, i32::MAX, i32::MAX), |cost| cost.key())
    };
    for m in &measured {
        heuristic_failed += usize::from(m.theirs.is_none());
        nothing += usize::from(m.ours.is_none());
        match key(m.seeded).cmp(&key(m.theirs)) {
            std::cmp::Ordering::Less => seeded_better += 1,
            std::cmp::Ordering::Equal => seeded_equal += 1,
            std::cmp::Ordering::Greater => seeded_worse += 1,
        }
        match key(m.ours).cmp(&key(m.theirs)) {
            std::cmp::Ordering::Less => better += 1,
            std::cmp::Ordering::Equal => equal += 1,
            std::cmp::Ordering::Greater => worse += 1,
        }
        if let (Some(ours), Some(theirs)) = (m.ours, m.theirs)
            && (ours.priority, ours.lateness_ds) == (theirs.priority, theirs.lateness_ds)
        {
            ours_m.push(f64::from(ours.distance_dm) / 10.0);
            theirs_m.push(f64::from(theirs.distance_dm) / 10.0);
        }
    }
    let ours_priority: Vec<f64> = measured
        .iter()
        .map(|m| f64::from(m.ours.map_or(0, |cost| cost.priority)))
        .collect();
    let theirs_priority: Vec<f64> = measured
        .iter()
        .map(|m| f64::from(m.theirs.map_or(0, |cost| cost.priority)))
        .collect();
    Ok(Report::single(
        NAME_QUALITY,
        "m driven (median, same priority and lateness)",
        median(&ours_m),
        median(&theirs_m),
    )
    .with(
        "reference_is",
        "nearest neighbour + 2-opt, on the same instances in the same run (`solver_*`: \
         unseeded; `seeded_*`: seeded with it, as armor plan runs)",
    )
    .with("solver_better", better)
    .with("solver_equal", equal)
    .with("solver_worse", worse)
    .with("solver_found_nothing_in_2s", nothing)
    .with("seeded_better", seeded_better)
    .with("seeded_equal", seeded_equal)
    .with("seeded_worse", seeded_worse)
    .with("heuristic_found_nothing", heuristic_failed)
    .with("median_priority_served", median(&ours_priority))
    .with("reference_median_priority_served", median(&theirs_priority))
    .with("goal_solver_worse", 0))
}
