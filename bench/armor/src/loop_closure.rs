//! `loop_closure_error_m`: how far the mapper's pose is from the truth when the robot is back
//! at its start after once round a 100 m ring corridor (`sim::tour::RING_FLOOR`, the mapper's
//! loop closure test), with loop closure, against the same mapper without it (the scan matcher
//! alone) on the same scans. Goal: at least 5 times smaller (`ratio` ≤ 0.2).
//!
//! The scans and odometry come from the headless simulator with its default noise, made once
//! before either mapper sees them (the drive steers from the true pose, so it does not depend
//! on the mapper). The figure is the median over a few seeds (three, one with `--quick`); each
//! seed's figures are in `runs`. Both mappers run in this process, one after the other.

use anyhow::anyhow;
use armor_module_api::types::{LaserScan, Pose2D};
use armor_module_catalog::mapper::{Mapper, Settings as MapperSettings};
use armor_module_catalog::sim::tour::{RING_FLOOR, RING_LOOP, Tour};
use armor_module_catalog::sim::world::World;
use armor_module_catalog::sim::{SimParams, Simulator};

use crate::Settings;
use armor_bench_report::{Report, median};

pub const NAME: &str = "loop_closure_error_m";
/// The loop takes about 7 000 steps; a stuck robot ends the tour here.
const MAX_STEPS: u64 = 20_000;

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let seeds: &[u64] = if settings.quick { &[1] } else { &[1, 2, 3] };
    let (mut with, mut without, mut runs) = (Vec::new(), Vec::new(), Vec::new());
    for &seed in seeds {
        let (scans, truth) = ring_scans(seed)?;
        let on = final_error(&scans, truth, true)?;
        let off = final_error(&scans, truth, false)?;
        runs.push(serde_json::json!({
            "seed": seed,
            "with_m": armor_bench_report::round(on),
            "without_m": armor_bench_report::round(off),
        }));
        with.push(on);
        without.push(off);
    }
    Ok(Report::single(NAME, "m", median(&with), median(&without))
        .with(
            "reference_is",
            "the same mapper without loop closure (the scan matcher alone), on the same scans",
        )
        .with("goal_ratio_at_most", 0.2)
        .with("loop_m", 100.0)
        .with("runs", runs))
}

/// The mapper's error against the truth after the last scan.
fn final_error(
    scans: &[(LaserScan, Pose2D)],
    truth: Pose2D,
    loop_closure: bool,
) -> anyhow::Result<f64> {
    let settings = MapperSettings {
        loop_closure,
        ..MapperSettings::default()
    };
    let mut mapper = Mapper::new(settings).map_err(|err| anyhow!("{err}"))?;
    let mut pose = truth;
    for (scan, odometry) in scans {
        pose = mapper
            .on_scan(scan, *odometry)
            .map_err(|err| anyhow!("the mapper refused a scan: {err}"))?;
    }
    Ok((pose.x_m - truth.x_m).hypot(pose.y_m - truth.y_m))
}

/// The scans of one drive round the ring, each with the odometry of its step, and the true pose
/// at the last one.
fn ring_scans(seed: u64) -> anyhow::Result<(Vec<(LaserScan, Pose2D)>, Pose2D)> {
    let world = World::parse(RING_FLOOR, "ring.world").map_err(|err| anyhow!("{err}"))?;
    let params = SimParams {
        seed,
        ..SimParams::default()
    };
    let mut sim = Simulator::new(world, params).map_err(|err| anyhow!("{err}"))?;
    let mut tour = Tour::new(RING_LOOP, MAX_STEPS);
    let mut scans = Vec::new();
    let mut truth = sim.truth();
    while let Some(report) = tour.next_scan(&mut sim) {
        scans.push((sim.scan().clone(), report.odometry.pose_in_odom));
        truth = report.truth;
    }
    if !tour.finished() {
        return Err(anyhow!(
            "the simulated robot got stuck at {:?} after {} steps",
            sim.truth(),
            tour.steps()
        ));
    }
    Ok((scans, truth))
}
