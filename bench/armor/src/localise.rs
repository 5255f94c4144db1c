//! `localise_ms_per_scan` and `localise_error_m`: the localiser's filter (Monte Carlo
//! localisation, `armor_module_catalog::localiser::mcl`) on the warehouse round
//! (`sim::tour::WAREHOUSE_ROUND`, about 45 m: the main aisle, the cross aisle, the south aisle
//! and back), driven once by the headless simulator with its default noise before anything is
//! timed.
//!
//! - `localise_ms_per_scan`: one filter update (motion, weighing, resampling, estimate) with
//!   1,000 particles and the simulator's 360-beam scan, every scan updated; per-scan
//!   distribution (`p50`, `p99`) in milliseconds, in this process, on one thread, against the
//!   scan period (100 ms) as the budget. Beside it, the thread's own time on a CPU per update
//!   (`on_cpu_*`) and per phase of it (`phases_on_cpu_ms`, see `mcl::Phase`): a wall-clock p99
//!   far above the on-CPU one is the machine's load, not the filter's work.
//! - `localise_error_m`: the mean distance between the localiser's estimate and the
//!   simulator's truth at every scan of the same round (the module's default settings), against
//!   odometry alone in the same run; `max` and `odometry_max` beside.

use std::time::{Duration, Instant};

use anyhow::anyhow;
use armor_module_api::types::{LaserScan, Pose2D};
use armor_module_catalog::localiser::mcl::{Filter, Map, Phase, Settings as MclSettings};
use armor_module_catalog::sim::tour::{Tour, WAREHOUSE_ROUND};
use armor_module_catalog::sim::world::World;
use armor_module_catalog::sim::{SimParams, Simulator};

use crate::Settings;
use armor_bench_report::{Report, percentile, round as significant};

pub const NAME_MS: &str = "localise_ms_per_scan";
pub const NAME_ERROR: &str = "localise_error_m";
const WAREHOUSE_WORLD: &str = include_str!("../../../assets/worlds/warehouse.world");
/// The round takes about 4 000 steps; a stuck robot ends the tour here.
const MAX_STEPS: u64 = 20_000;
const SCAN_PERIOD: Duration = Duration::from_millis(100);

/// One scan of the round: the scan, the odometry and the truth of its step.
struct Sample {
    scan: LaserScan,
    odometry: Pose2D,
    truth: Pose2D,
}

/// The calling thread's time on a CPU so far, in nanoseconds (`CLOCK_THREAD_CPUTIME_ID`: exact,
/// where the scheduler's own statistics advance by whole ticks of 4 ms).
fn thread_cpu_ns() -> u64 {
    let now = rustix::time::clock_gettime(rustix::time::ClockId::ThreadCPUTime);
    u64::try_from(now.tv_sec).unwrap_or(0) * 1_000_000_000 + u64::try_from(now.tv_nsec).unwrap_or(0)
}

fn warehouse() -> anyhow::Result<World> {
    World::parse(WAREHOUSE_WORLD, "warehouse.world").map_err(|err| anyhow!("{err}"))
}

fn round(limit: usize) -> anyhow::Result<Vec<Sample>> {
    let mut sim =
        Simulator::new(warehouse()?, SimParams::default()).map_err(|err| anyhow!("{err}"))?;
    let mut tour = Tour::new(WAREHOUSE_ROUND, MAX_STEPS);
    let mut samples = Vec::new();
    while samples.len() < limit
        && let Some(report) = tour.next_scan(&mut sim)
    {
        samples.push(Sample {
            scan: sim.scan().clone(),
            odometry: report.odometry.pose_in_odom,
            truth: report.truth,
        });
    }
    if samples.len() < limit && !tour.finished() {
        return Err(anyhow!(
            "the simulated robot got stuck at {:?} after {} steps",
            sim.truth(),
            tour.steps()
        ));
    }
    Ok(samples)
}

fn filter(settings: MclSettings) -> anyhow::Result<Filter> {
    let world = warehouse()?;
    let map = Map::new(&world, settings.sigma_hit_m, settings.robot_radius_m)
        .map_err(|err| anyhow!("{err}"))?;
    Ok(Filter::new(settings, map, world.start(), 1))
}

pub fn run_ms(settings: &Settings) -> anyhow::Result<Report> {
    let limit = if settings.quick { 40 } else { usize::MAX };
    let samples = round(limit)?;
    let mut filter = filter(MclSettings {
        min_particles: 1000,
        max_particles: 1000,
        update_min_m: 0.0,
        update_min_rad: 0.0,
        ..MclSettings::default()
    })?;
    let mut ours = Vec::with_capacity(samples.len());
    let mut on_cpu = Vec::with_capacity(samples.len());
    let mut phases: Vec<Vec<f64>> = vec![Vec::with_capacity(samples.len()); Phase::ALL.len()];
    for sample in &samples {
        let cpu_before = thread_cpu_ns();
        let start = Instant::now();
        let mut last = cpu_before;
        filter.update_marked(sample.odometry, &sample.scan, &mut |phase| {
            let now = thread_cpu_ns();
            if let Some(index) = Phase::ALL.iter().position(|p| *p == phase) {
                phases[index].push(now.saturating_sub(last) as f64 / 1e6);
            }
            last = now;
        });
        ours.push(start.elapsed());
        on_cpu.push(thread_cpu_ns().saturating_sub(cpu_before) as f64 / 1e6);
    }
    let p50p99 = |values: &mut Vec<f64>| {
        values.sort_by(f64::total_cmp);
        (
            significant(percentile(values, 0.5)),
            significant(percentile(values, 0.99)),
        )
    };
    let mut phase_figures = serde_json::Map::new();
    for (phase, values) in Phase::ALL.iter().zip(&mut phases) {
        let (median, tail) = p50p99(values);
        phase_figures.insert(
            phase.name().to_owned(),
            serde_json::json!({
                "p50": median,
                "p99": tail,
                "max": significant(values.last().copied().unwrap_or(0.0)),
            }),
        );
    }
    let (cpu_p50, cpu_p99) = p50p99(&mut on_cpu);
    Ok(
        Report::distribution(NAME_MS, "ms", 1e3, &ours, &[SCAN_PERIOD])
            .with("phases_on_cpu_ms", phase_figures)
            .with("on_cpu_p50", cpu_p50)
            .with("on_cpu_p99", cpu_p99)
            .with(
                "on_cpu_max",
                significant(on_cpu.last().copied().unwrap_or(0.0)),
            )
            .with(
                "on_cpu_is",
                "the thread's own time on a CPU per update (CLOCK_THREAD_CPUTIME_ID): what the \
                 wall-clock figures are less the time the machine ran something else",
            )
            .with(
                "reference_is",
                "the scan period (the sim scans at 10 Hz): the budget",
            )
            .with("particles", 1000)
            .with(
                "beams_in_scan",
                samples.first().map_or(0, |s| s.scan.ranges_m.len()),
            )
            .with("scans", samples.len())
            .with("goal", "p99 < 2 ms"),
    )
}

pub fn run_error(settings: &Settings) -> anyhow::Result<Report> {
    let limit = if settings.quick { 40 } else { usize::MAX };
    let samples = round(limit)?;
    let mut filter = filter(MclSettings::default())?;
    let distance = |a: Pose2D, b: Pose2D| (a.x_m - b.x_m).hypot(a.y_m - b.y_m);
    let mut ours = Vec::with_capacity(samples.len());
    let mut odometry = Vec::with_capacity(samples.len());
    for sample in &samples {
        filter.update(sample.odometry, &sample.scan);
        ours.push(distance(filter.estimate().pose, sample.truth));
        odometry.push(distance(sample.odometry, sample.truth));
    }
    let mean = |values: &[f64]| values.iter().sum::<f64>() / values.len().max(1) as f64;
    let max = |values: &[f64]| values.iter().copied().fold(0.0, f64::max);
    Ok(
        Report::single(NAME_ERROR, "m", mean(&ours), mean(&odometry))
            .with("reference_is", "odometry alone, in the same run")
            .with("max", max(&ours))
            .with("odometry_max", max(&odometry))
            .with("scans", samples.len())
            .with(
                "goal",
                "mean <= 0.1 m, max <= 0.25 m, >= 10x better than odometry",
            ),
    )
}
