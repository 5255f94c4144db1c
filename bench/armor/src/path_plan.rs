//! `path_plan_ms` and `check_plan_100_legs_ms`: the path planner of `armor_model::planner` on
//! a 100 m × 100 m world at 5 cm (4 M cells) with 200 obstacles (blocks, discs and long thin
//! walls, placed at random with a fixed seed).
//!
//! `path_plan_ms`: 50 random pairs of free places that a path joins, each planned from scratch
//! on the same costmap (`Planner::plan`: the checks of both ends, the straight line when it is
//! free, A*, smoothing), p50 and p99. The reference is the `pathfinding` crate's `astar` on the
//! same grid, from the same start cell to the same goal cell, with the same step costs and the
//! same heuristic: a grid search only, no smoothing. Both must find the same cost (checked).
//! Goal: p99 under 50 ms and ratio ≤ 1. Each pair is timed three times on each side and the
//! fastest kept (the machines are shared; with 50 pairs, p99 is the slowest pair). Also
//! reported: the costmap's build time, our grid search alone, and the cells A* reached.
//!
//! `check_plan_100_legs_ms`: a plan of 101 waypoints and 100 legs on that world compiled and
//! checked as `armor check` does (every leg planned on the world, then the names against the
//! robot's system and the reachability analysis). Goal: under 1 s. The reference is the same
//! plan with no world (its legs straight lines: what checking cost before plans knew the map).

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow, ensure};
use armor_model::SystemConfig;
use armor_model::geo::LatLon;
use armor_model::plan::{self, Plan};
use armor_model::planner::{Costmap, CostmapSettings, Planner, Robot, heuristic};
use armor_model::world::{Point, World};
use armor_module_api::ModuleDescription;
use armor_module_catalog::sim::rng::Rng;

use crate::Settings;
use crate::compile_plan;
use armor_bench_report::{Report, median};

pub const NAME: &str = "path_plan_ms";
pub const NAME_CHECK: &str = "check_plan_100_legs_ms";

const SEED: u64 = 26;
const SIDE_M: f64 = 100.0;
const OBSTACLES: usize = 200;
/// Each pair is timed this many times, each side, and the fastest time kept.
const REPEAT: usize = 3;
const ORIGIN: LatLon = LatLon::new(43.5615, 1.469);

/// The bench's world: 200 obstacles at random in a 100 m square, the start corner clear.
pub fn world() -> anyhow::Result<World> {
    World::parse(&world_text(), "bench.world").map_err(|err| anyhow!("the bench's world: {err}"))
}

/// The bench's world as its file writes it.
pub(crate) fn world_text() -> String {
    let mut rng = Rng::new(SEED, 1);
    let mut text = format!(
        "name bench\norigin {} {}\nstart 1 1 0\nboundary 0,0 {SIDE_M},0 {SIDE_M},{SIDE_M} 0,{SIDE_M} 0,0\n",
        ORIGIN.lat_deg, ORIGIN.lon_deg
    );
    let mut placed = 0;
    while placed < OBSTACLES {
        let mut uniform = |lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
        let (x, y) = (uniform(1.0, SIDE_M - 1.0), uniform(1.0, SIDE_M - 1.0));
        if x < 4.0 && y < 4.0 {
            continue;
        }
        let kind = uniform(0.0, 3.0) as u32;
        let (w, h) = match kind {
            0 => (uniform(0.5, 6.0), uniform(0.5, 6.0)),
            1 if uniform(0.0, 1.0) < 0.5 => (uniform(4.0, 16.0), uniform(0.2, 0.5)),
            1 => (uniform(0.2, 0.5), uniform(4.0, 16.0)),
            _ => {
                text.push_str(&format!("circle {x:.2},{y:.2} {:.2}\n", uniform(0.3, 3.0)));
                placed += 1;
                continue;
            }
        };
        text.push_str(&format!(
            "rect {x:.2},{y:.2} {:.2},{:.2}\n",
            (x + w).min(SIDE_M - 0.1),
            (y + h).min(SIDE_M - 0.1)
        ));
        placed += 1;
    }
    text
}

pub(crate) fn planner(world: &World) -> anyhow::Result<(Planner, Duration)> {
    let start = Instant::now();
    let costmap = Costmap::for_world(world, &Robot::default(), &[], &CostmapSettings::default())
        .map_err(|err| anyhow!("{err}"))?;
    let built = start.elapsed();
    Ok((Planner::new(costmap), built))
}

/// A random place where the robot may be.
fn free_place(rng: &mut Rng, planner: &Planner) -> Point {
    loop {
        let p = Point::new(rng.uniform() * SIDE_M, rng.uniform() * SIDE_M);
        if planner.costmap().blocker_at(p).is_none() && !planner.costmap().is_lethal_at(p) {
            return p;
        }
    }
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let pairs = if settings.quick { 5 } else { 50 };
    let world = world()?;
    let (mut planner, built) = planner(&world)?;
    let mut rng = Rng::new(SEED, 2);
    let mut ours = Vec::with_capacity(pairs);
    let mut searches = Vec::with_capacity(pairs);
    let mut reference = Vec::with_capacity(pairs);
    let mut cut = 0;
    let mut lengths = Vec::new();
    let mut reached = Vec::new();
    while ours.len() < pairs {
        let (start, goal) = (
            free_place(&mut rng, &planner),
            free_place(&mut rng, &planner),
        );
        // Each side is timed `REPEAT` times and the fastest kept: the machines are shared,
        // and a neighbour's burst would otherwise decide the p99 of 50 samples.
        let mut took = Duration::MAX;
        let mut planned = None;
        for _ in 0..REPEAT {
            let began = Instant::now();
            let result = planner.plan(start, goal);
            took = took.min(began.elapsed());
            planned = Some(result);
        }
        let Some(Ok(path)) = planned else {
            cut += 1;
            continue;
        };
        ours.push(took);
        lengths.push(path.length_m);
        let map = planner.costmap();
        let (from, to) = (
            map.cell_of(start).context("start on the map")?,
            map.cell_of(goal).context("goal on the map")?,
        );
        let mut took = Duration::MAX;
        let mut found = None;
        for _ in 0..REPEAT {
            let began = Instant::now();
            found = reference_astar(map, from, to).map(|(_, cost)| cost);
            took = took.min(began.elapsed());
        }
        reference.push(took);
        let mut took = Duration::MAX;
        let mut cost = None;
        for _ in 0..REPEAT {
            let began = Instant::now();
            cost = planner.grid_search(from, to);
            took = took.min(began.elapsed());
        }
        searches.push(took);
        reached.push(planner.cells_reached() as f64);
        ensure!(
            found == cost,
            "the reference A* and ours disagree from {start} to {goal}: {found:?} vs {cost:?}"
        );
    }
    let search_ms: Vec<f64> = searches.iter().map(|d| d.as_secs_f64() * 1e3).collect();
    let mut sorted = search_ms.clone();
    sorted.sort_by(f64::total_cmp);
    Ok(Report::distribution(NAME, "ms", 1e3, &ours, &reference)
        .with(
            "reference_is",
            "pathfinding::astar on the same grid, cells and costs (grid search only)",
        )
        .with("cells", planner.costmap().costs().len())
        .with("costmap_build_ms", round(built.as_secs_f64() * 1e3))
        .with(
            "our_search_p50_ms",
            round(armor_bench_report::percentile(&sorted, 0.5)),
        )
        .with(
            "our_search_p99_ms",
            round(armor_bench_report::percentile(&sorted, 0.99)),
        )
        .with("pairs", pairs)
        .with("pairs_cut_skipped", cut)
        .with("median_length_m", round(median(&lengths)))
        .with("median_cells_reached", median(&reached))
        .with(
            "most_cells_reached",
            reached.iter().copied().fold(0.0, f64::max),
        )
        .with("goal_p99_ms", 50)
        .with("goal_ratio", 1))
}

fn round(value: f64) -> f64 {
    (value * 1000.0).round() / 1000.0
}

/// `pathfinding`'s A* over the costmap's cells, with our step costs and heuristic.
fn reference_astar(map: &Costmap, from: usize, to: usize) -> Option<(Vec<usize>, u32)> {
    let width = map.width() as i64;
    let (goal_x, goal_y) = (to as i64 % width, to as i64 / width);
    pathfinding::directed::astar::astar(
        &from,
        |&cell| map.neighbours(cell),
        |&cell| {
            let (x, y) = (cell as i64 % width, cell as i64 / width);
            heuristic(
                (x - goal_x).unsigned_abs() as u32,
                (y - goal_y).unsigned_abs() as u32,
            )
        },
        |&cell| cell == to,
    )
}

/// 101 waypoints in one connected part of the bench's world, and 100 legs through them.
pub(crate) fn plan_text(world: &World, planner: &mut Planner, waypoints: usize) -> String {
    let mut rng = Rng::new(SEED, 3);
    let first = free_place(&mut rng, planner);
    let mut points = vec![first];
    while points.len() < waypoints {
        let p = free_place(&mut rng, planner);
        if planner.plan(first, p).is_ok() {
            points.push(p);
        }
    }
    let (lat, lon) = world.origin_lat_lon();
    let origin = LatLon::new(lat, lon);
    let mut text = String::from(
        "<plan name=\"tour\" system=\"system.xml\" world=\"bench.world\">\n\
         <navigation><module name=\"avoider\"/></navigation>\n",
    );
    for (i, p) in points.iter().enumerate() {
        let at = LatLon::from_local(*p, origin);
        text.push_str(&format!(
            "<waypoint name=\"w{i}\" lat=\"{:.9}\" lon=\"{:.9}\"/>\n",
            at.lat_deg, at.lon_deg
        ));
    }
    for i in 1..points.len() {
        text.push_str(&format!("<leg from=\"w{}\" to=\"w{i}\"/>\n", i - 1));
    }
    text.push_str("</plan>\n");
    text
}

pub fn run_check(settings: &Settings) -> anyhow::Result<Report> {
    let rounds = if settings.quick { 1 } else { 5 };
    let world = world()?;
    let (mut planner, _) = planner(&world)?;
    let text = plan_text(&world, &mut planner, 101);
    drop(planner);
    let system = SystemConfig::parse(compile_plan::SYSTEM)
        .map_err(|problems| anyhow!("the bench's system does not parse: {problems:?}"))?;
    let descriptions: BTreeMap<String, ModuleDescription> = compile_plan::descriptions();
    let check = |world: Option<&World>| -> anyhow::Result<plan::Compiled> {
        let plan = Plan::parse(&text).map_err(|p| anyhow!("plan: {p:?}"))?;
        let compiled = plan::compile(&plan, world).map_err(|p| anyhow!("compile: {p:?}"))?;
        compile_plan::check(&compiled.net, &system, &descriptions)?;
        Ok(compiled)
    };
    let compiled = check(Some(&world))?;
    let planned_m: f64 = compiled
        .routes
        .iter()
        .map(|route| armor_model::geo::path_length(route))
        .sum();
    // With no world the plan has no frame: the reference places it by an origin.
    let (lat, lon) = world.origin_lat_lon();
    let text_no_world = text.replace(
        " world=\"bench.world\">",
        &format!("><origin lat=\"{lat}\" lon=\"{lon}\"/>"),
    );
    let check_no_world = || -> anyhow::Result<plan::Compiled> {
        let plan = Plan::parse(&text_no_world).map_err(|p| anyhow!("plan: {p:?}"))?;
        let compiled = plan::compile(&plan, None).map_err(|p| anyhow!("compile: {p:?}"))?;
        compile_plan::check(&compiled.net, &system, &descriptions)?;
        Ok(compiled)
    };
    let straight_m: f64 = check_no_world()?
        .routes
        .iter()
        .map(|route| armor_model::geo::path_length(route))
        .sum();
    let mut ours = Vec::with_capacity(rounds);
    let mut reference = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let began = Instant::now();
        check(Some(&world))?;
        ours.push(began.elapsed().as_secs_f64() * 1e3);
        let began = Instant::now();
        check_no_world()?;
        reference.push(began.elapsed().as_secs_f64() * 1e3);
    }
    Ok(
        Report::single(NAME_CHECK, "ms", median(&ours), median(&reference))
            .with(
                "reference_is",
                "the same plan checked with no world (straight legs, no costmap)",
            )
            .with("legs", compiled.routes.len())
            .with("planned_m", round(planned_m))
            .with("straight_m", round(straight_m))
            .with("goal_ms", 1000),
    )
}
