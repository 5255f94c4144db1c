//! `mapper_scan_ms`: the time the mapper takes to integrate one 360-beam scan, scan matching
//! (correlative search and ICP against the map so far), grid update and loop closure (on by
//! default: a keyframe every metre, its search for a loop, and the grid drawn again when one
//! closes, which shows in the p99) together, against the
//! grid update alone at the same pose (`Mapper::place_scan`: the floor every scan costs, so
//! `ratio` says what matching adds).
//!
//! The scans and odometry come from the headless simulator driven once round the office floor
//! of `building.world` (the mapper test's loop, about 900 scans, default noise), made before
//! anything is timed. Each side starts from an empty map and gets the same scans; the reference
//! places each one at the pose the mapper found for it, so both grids grow alike. Both are
//! per-scan distributions (`p50`, `p99`) in milliseconds, in this process, on one thread.
//!
//! For scale: the sim scans at 10 Hz, a scan every 100 ms of run time; at the 50× real time of
//! `sim_realtime_factor`'s goal that is every 2 ms of wall time.

use std::time::{Duration, Instant};

use anyhow::anyhow;
use armor_module_api::types::{LaserScan, Pose2D};
use armor_module_catalog::mapper::{Mapper, Settings as MapperSettings};
use armor_module_catalog::sim::tour::{BUILDING_LOOP, Tour};
use armor_module_catalog::sim::world::World;
use armor_module_catalog::sim::{SimParams, Simulator};

use crate::Settings;
use armor_bench_report::Report;

pub const NAME: &str = "mapper_scan_ms";
const BUILDING_WORLD: &str = include_str!("../../../assets/worlds/building.world");
/// The loop takes about 9 000 steps; a stuck robot ends the tour here.
const MAX_STEPS: u64 = 20_000;

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let limit = if settings.quick { 40 } else { usize::MAX };
    let scans = building_loop_scans(limit)?;
    let mut mapper = Mapper::new(MapperSettings::default()).map_err(|err| anyhow!("{err}"))?;
    let mut ours = Vec::with_capacity(scans.len());
    let mut poses = Vec::with_capacity(scans.len());
    for (scan, odometry) in &scans {
        let start = Instant::now();
        let pose = mapper
            .on_scan(scan, *odometry)
            .map_err(|err| anyhow!("the mapper refused a scan: {err}"))?;
        ours.push(start.elapsed());
        poses.push(pose);
    }
    let mut placer = Mapper::new(MapperSettings::default()).map_err(|err| anyhow!("{err}"))?;
    let mut reference: Vec<Duration> = Vec::with_capacity(scans.len());
    for ((scan, _), pose) in scans.iter().zip(&poses) {
        let start = Instant::now();
        placer
            .place_scan(scan, *pose)
            .map_err(|err| anyhow!("the mapper refused a scan: {err}"))?;
        reference.push(start.elapsed());
    }
    let stats = mapper.stats();
    Ok(Report::distribution(NAME, "ms", 1e3, &ours, &reference)
        .with(
            "reference_is",
            "the grid update alone (Mapper::place_scan at the same poses, no matching)",
        )
        .with("scans", scans.len())
        .with("matched", stats.matched)
        .with("scan_period_ms", 100.0))
}

/// The scans of one drive round the building loop, each with the odometry of its step (at
/// most `limit`).
fn building_loop_scans(limit: usize) -> anyhow::Result<Vec<(LaserScan, Pose2D)>> {
    let world = World::parse(BUILDING_WORLD, "building.world").map_err(|err| anyhow!("{err}"))?;
    let mut sim = Simulator::new(world, SimParams::default()).map_err(|err| anyhow!("{err}"))?;
    let mut tour = Tour::new(BUILDING_LOOP, MAX_STEPS);
    let mut scans = Vec::new();
    while scans.len() < limit
        && let Some(report) = tour.next_scan(&mut sim)
    {
        scans.push((sim.scan().clone(), report.odometry.pose_in_odom));
    }
    if scans.len() < limit && !tour.finished() {
        return Err(anyhow!(
            "the simulated robot got stuck at {:?} after {} steps",
            sim.truth(),
            tour.steps()
        ));
    }
    Ok(scans)
}
