//! `sim_realtime_factor`: simulated seconds per wall second of the robot demo system,
//! `missions/robot/system.xml` (the sim in the yard with its default laser, 360 beams at 10 Hz,
//! physics at 50 Hz, and the follower, avoider, observer, teleop and mux that file wires), run
//! by `armor run` pinned to one core (`taskset -c`; every module inherits the pinning). The
//! issue's goal is at least 50 on one core; the output carries it as `goal`.
//!
//! The figure is what the sim actually simulates, not what was asked of it. The sim falls behind
//! when the machine cannot keep up and then skips ahead (see `sim::body`), so the run-clock stamps
//! of its outputs follow the requested time scale whatever it achieves. Instead, the bench
//! subscribes to `sim.odometry`, which the sim publishes once per physics step, and counts steps
//! by the samples' sequence numbers over a window of wall time: factor = steps / rate_hz / wall
//! seconds (rate_hz, the beams and the laser rate are read from the sim's own log line).
//!
//! Timer-driven modules (the mux, teleop) work in proportion to the requested time scale, not to
//! what the sim achieves, so asking for an absurd scale would load the core with them and
//! understate the system. The bench asks for 50, then doubles the scale while the system keeps
//! up (achieves at least 90 % of it); `ours` is the best factor achieved, `runs` lists
//! `[requested, achieved]`.
//!
//! The reference is the bare `Simulator` of the same world and settings stepped in this process
//! (no processes, no messages, the robot at its start pose): the ceiling set by the simulation
//! itself, so `ratio` is the share of it the whole system keeps.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow, bail};
use armor_module_api::types::Odometry;
use armor_module_api::{ENV_MODULE, ENV_SUPERVISOR, Event, ModuleSpec};
use armor_module_catalog::sim::world::World;
use armor_module_catalog::sim::{SimParams, Simulator};

use crate::Settings;
use crate::harness::{self, LINK_TIMEOUT, STALL_TIMEOUT};
use crate::procs::{ChildGuard, module_binary, sibling_binary};
use armor_bench_report::Report;

pub const NAME: &str = "sim_realtime_factor";
pub const NAME_MONITOR: &str = "monitor_overhead";
/// The goal for the monitor: the robot keeps at least this share of its speed.
pub const MONITOR_GOAL: f64 = 0.9;
/// The goal: at least this many simulated seconds per wall second, on one core.
pub const GOAL: f64 = 50.0;
const SYSTEM_XML: &str = include_str!("../../../missions/robot/system.xml");
const YARD_WORLD: &str = include_str!("../../../assets/worlds/yard.world");
/// The world file name the system asks for, written next to it.
const WORLD_FILE: &str = "yard.world";
/// A run keeps up when it achieves at least this share of the requested time scale.
const KEEPS_UP: f64 = 0.9;
/// The largest time scale asked for.
const MAX_SCALE: f64 = 6400.0;
const STOP_TIMEOUT: Duration = Duration::from_secs(10);

struct Timing {
    /// Wall time after the first odometry before the window opens (links, start-up).
    warm_up: Duration,
    window: Duration,
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let timing = if settings.quick {
        Timing {
            warm_up: Duration::from_millis(300),
            window: Duration::from_millis(700),
        }
    } else {
        Timing {
            warm_up: Duration::from_secs(2),
            window: Duration::from_secs(4),
        }
    };
    let armor = sibling_binary("armor")?;
    module_binary("sim")?;
    let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
    std::fs::write(dir.path().join("system.xml"), without_recorder(SYSTEM_XML)?)
        .context("cannot write the system file")?;
    std::fs::write(dir.path().join(WORLD_FILE), YARD_WORLD)
        .context("cannot write the world file")?;
    let core = one_core();
    if core.is_none() {
        eprintln!("note: {NAME}: no taskset, or no CPU list: the system runs on every core");
    }
    let mut runs = Vec::new();
    let mut best = 0.0_f64;
    let mut scale = GOAL;
    loop {
        let achieved = system_factor(&armor, dir.path(), scale, core, &timing, None)?;
        runs.push([scale, round2(achieved)]);
        best = best.max(achieved);
        if settings.quick || achieved < KEEPS_UP * scale || scale >= MAX_SCALE {
            break;
        }
        scale *= 2.0;
    }
    let reference = headless_factor(timing.window)?;
    Ok(Report::single(NAME, "sim s/s", best, reference)
        .with("goal", GOAL)
        .with(
            "reference_is",
            "the bare Simulator of the same world stepped in one thread (no processes, no messages)",
        )
        .with("runs", serde_json::json!(runs))
        .with("one_core", core.is_some()))
}

/// `monitor_overhead`: the system's factor with the studio's Run view watching it (status
/// polled, the studio's node subscribed to the poses and the scan, frames drawn at 30 Hz, on
/// the same core) against without, at the scale where the system alone does best. Each is
/// measured twice, alternately, and the better of each kept.
pub fn run_monitor(settings: &Settings) -> anyhow::Result<Report> {
    let timing = if settings.quick {
        Timing {
            warm_up: Duration::from_millis(500),
            window: Duration::from_millis(1000),
        }
    } else {
        Timing {
            warm_up: Duration::from_secs(2),
            window: Duration::from_secs(4),
        }
    };
    let armor = sibling_binary("armor")?;
    let studio = sibling_binary("armor-studio-bench")?;
    module_binary("sim")?;
    let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
    std::fs::write(dir.path().join("system.xml"), without_recorder(SYSTEM_XML)?)
        .context("cannot write the system file")?;
    std::fs::write(dir.path().join(WORLD_FILE), YARD_WORLD)
        .context("cannot write the world file")?;
    let core = one_core();
    // The scale the system alone does best at: doubled while it keeps up.
    let mut scale = GOAL;
    if !settings.quick {
        loop {
            let achieved = system_factor(&armor, dir.path(), scale, core, &timing, None)?;
            if achieved < KEEPS_UP * scale || scale >= MAX_SCALE {
                break;
            }
            scale *= 2.0;
        }
    }
    let rounds = if settings.quick { 1 } else { 3 };
    let (mut alone, mut watched) = (0.0_f64, 0.0_f64);
    let mut runs = Vec::new();
    for _ in 0..rounds {
        let without = system_factor(&armor, dir.path(), scale, core, &timing, None)?;
        let with = system_factor(&armor, dir.path(), scale, core, &timing, Some(&studio))?;
        runs.push([round2(without), round2(with)]);
        alone = alone.max(without);
        watched = watched.max(with);
    }
    Ok(Report::single(NAME_MONITOR, "sim s/s", watched, alone)
        .with("goal", MONITOR_GOAL)
        .with("time_scale", scale)
        .with(
            "reference_is",
            "the same system at the same time scale with no studio attached",
        )
        .with("runs_without_with", serde_json::json!(runs))
        .with("one_core", core.is_some()))
}

fn round2(value: f64) -> f64 {
    (value * 100.0).round() / 100.0
}

/// The CPU to pin the system to (the last this process may use), if `taskset` is there.
fn one_core() -> Option<usize> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let list = status
        .lines()
        .find_map(|line| line.strip_prefix("Cpus_allowed_list:"))?;
    let last = list.trim().rsplit([',', '-']).next()?.parse().ok()?;
    let taskset = Command::new("taskset").arg("--version").output().ok()?;
    taskset.status.success().then_some(last)
}

/// What the sim says of itself when it starts: physics and laser rates and beams.
#[derive(Clone, Copy, Debug, PartialEq)]
struct SimSetup {
    rate_hz: f64,
    beams: u64,
    laser_rate_hz: f64,
}

/// Reads `stepping at 50 Hz, scanning 360 beams at 10 Hz` from the sim's start-up line.
fn sim_setup(line: &str) -> Option<SimSetup> {
    let rest = line.split("stepping at ").nth(1)?;
    let words: Vec<&str> = rest.split_whitespace().collect();
    // ["50", "Hz,", "scanning", "360", "beams", "at", "10", "Hz"]
    match words.as_slice() {
        [
            rate,
            "Hz,",
            "scanning",
            beams,
            "beams",
            "at",
            laser_rate,
            "Hz",
            ..,
        ] => Some(SimSetup {
            rate_hz: rate.parse().ok()?,
            beams: beams.parse().ok()?,
            laser_rate_hz: laser_rate.parse().ok()?,
        }),
        _ => None,
    }
}

/// A `name=value` field of a log line, without quotes.
fn field<'a>(line: &'a str, name: &str) -> Option<&'a str> {
    line.split_whitespace()
        .find_map(|word| word.strip_prefix(name)?.strip_prefix('='))
        .map(|value| value.trim_matches('"'))
}

/// Runs the system at `scale` and measures the sim's achieved factor over the window.
fn system_factor(
    armor: &Path,
    dir: &Path,
    scale: f64,
    core: Option<usize>,
    timing: &Timing,
    studio: Option<&Path>,
) -> anyhow::Result<f64> {
    let pinned = |program: &Path| match core {
        Some(core) => {
            let mut command = Command::new("taskset");
            command.arg("-c").arg(core.to_string()).arg(program);
            command
        }
        None => Command::new(program),
    };
    let mut command = pinned(armor);
    command
        .arg("run")
        .arg("system.xml")
        .arg("--time-scale")
        .arg(scale.to_string())
        .current_dir(dir)
        // The lines read are logged at `info`, whatever the caller's filter.
        .env("ARMOR_LOG", "info")
        .env_remove(ENV_SUPERVISOR)
        .env_remove(ENV_MODULE);
    let mut child = ChildGuard::spawn_capturing_stdout("armor run", command)?.graceful();
    // `armor run` logs on stderr, its modules' lines go to its stdout.
    let (Some(lines), Some(module_lines)) = (child.take_lines(), child.take_stdout_lines()) else {
        bail!("armor run: no output to read");
    };
    let agent = child.wait_line(&lines, "its agent's address", LINK_TIMEOUT, |line| {
        line.contains("agent started")
            .then(|| field(line, "addr")?.parse().ok())
            .flatten()
    })?;
    let control = child.wait_line(&module_lines, "its control address", LINK_TIMEOUT, |line| {
        line.strip_prefix(armor_runtime::CONTROL_READY_PREFIX)
            .map(|addr| addr.trim().to_owned())
    })?;
    // The studio watches for longer than the measurement; it is killed after it.
    let _studio = match studio {
        Some(studio) => {
            let mut command = pinned(studio);
            command
                .args(["monitor", &control, "system.xml"])
                .arg((3.0 * (timing.warm_up + timing.window).as_secs_f64() + 10.0).to_string())
                .current_dir(dir)
                .env_remove(ENV_SUPERVISOR)
                .env_remove(ENV_MODULE);
            Some(ChildGuard::spawn_quiet(
                "armor-studio-bench monitor",
                command,
            )?)
        }
        None => None,
    };
    let setup = child.wait_line(&module_lines, "the sim's start", LINK_TIMEOUT, |line| {
        line.starts_with("[sim]").then(|| sim_setup(line)).flatten()
    })?;
    if setup.beams != 360 || setup.laser_rate_hz != 10.0 {
        bail!("the demo system's laser is {setup:?}, not 360 beams at 10 Hz");
    }
    let spec = ModuleSpec::new("bench", "counts the sim's physics steps")
        .input::<Odometry>("odometry", "the sim's odometry, one per physics step");
    let mut node = harness::connect(spec, agent, &[("odometry", "sim.odometry")])?;
    let odometry = node.input::<Odometry>("odometry")?;
    // (wall time, sequence number, link) of the latest sample.
    let mut next_sample = |child: &mut ChildGuard| -> anyhow::Result<(Instant, u64, u64)> {
        let give_up = Instant::now() + STALL_TIMEOUT;
        loop {
            let deadline = (Instant::now() + Duration::from_millis(100)).min(give_up);
            match node.next_event_until(deadline)? {
                Event::Input(port) if port == odometry.id() => {
                    if let Some(sample) = node.take(&odometry)? {
                        return Ok((Instant::now(), sample.seq, sample.link));
                    }
                }
                Event::Shutdown => bail!("the bench's node was shut down"),
                _ => {
                    child.check_alive()?;
                    if Instant::now() >= give_up {
                        return Err(child.failure(&format!(
                            "sent no odometry to the bench within {STALL_TIMEOUT:?}"
                        )));
                    }
                }
            }
        }
    };
    let (first_at, _, _) = next_sample(&mut child)?;
    let (mut start, mut start_seq, mut start_link) = next_sample(&mut child)?;
    while start < first_at + timing.warm_up {
        (start, start_seq, start_link) = next_sample(&mut child)?;
    }
    let (end, end_seq, end_link) = loop {
        let sample = next_sample(&mut child)?;
        if sample.0 >= start + timing.window {
            break sample;
        }
    };
    if end_link != start_link {
        return Err(child.failure("restarted the sim during the measurement"));
    }
    let steps = end_seq.saturating_sub(start_seq);
    let factor = steps as f64 / setup.rate_hz / (end - start).as_secs_f64();
    drop(node);
    child.stop(STOP_TIMEOUT)?;
    Ok(factor)
}

/// The system without its recorders, which missions start when they want a record (run without
/// a mission, one would record the whole time and weigh on the figure).
fn without_recorder(system: &str) -> anyhow::Result<String> {
    let mut system = armor_model::SystemConfig::parse(system)
        .map_err(|problems| anyhow::anyhow!("the robot system does not parse: {problems:?}"))?;
    system
        .modules
        .retain(|module| module.module_type != "recorder");
    Ok(system.to_xml())
}

/// Simulated seconds per wall second of the bare simulator, stepped for about `window`.
fn headless_factor(window: Duration) -> anyhow::Result<f64> {
    let world = World::parse(YARD_WORLD, WORLD_FILE).map_err(|err| anyhow!("{err}"))?;
    let mut sim = Simulator::new(world, SimParams::default()).map_err(|err| anyhow!("{err}"))?;
    let start = Instant::now();
    loop {
        for _ in 0..50 {
            sim.step();
        }
        let elapsed = start.elapsed();
        if elapsed >= window {
            return Ok(sim.time() / elapsed.as_secs_f64());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_sims_start_up_line() {
        let line = "[sim]  INFO world `Open yard` (yard.world): 12 shapes, start at (4.00, 4.00); \
                    stepping at 50 Hz, scanning 360 beams at 10 Hz";
        assert_eq!(
            sim_setup(line),
            Some(SimSetup {
                rate_hz: 50.0,
                beams: 360,
                laser_rate_hz: 10.0
            })
        );
        assert_eq!(sim_setup("stepping at fast Hz"), None);
        assert_eq!(
            field("INFO agent started pid=12 addr=127.0.0.1:4000", "addr"),
            Some("127.0.0.1:4000")
        );
    }
}
