//! `plan_update_ms`: from `armor ctl update` of a 100-leg plan on the bench's 100 m world (one
//! waypoint far ahead moved, the leg being driven unchanged) to the new net running (the run's
//! answer, sent once the nets are swapped), while a simulated robot drives the first leg; goal
//! p99 under 200 ms. The reference, measured in the same run between the updates: the same
//! plan compiled and checked from scratch in this process (every leg planned on the world), the
//! work an update cannot do without.
//!
//! The follower must not stop for an update: its commanded speed (`follower.cmd_desired`,
//! recorded) stays above zero from each update sent to its answer: `cmd_stopped_during_updates`
//! counts the commands in those spans that stop the robot (no speed and no turn: any fails the
//! bench),
//! `cmd_during_updates` all of them, and the `_between_updates` counts the same between the
//! updates. A command with no forward speed but a turn is the follower turning in place at a
//! sharp corner of its path, which it does whether an update is under way or not.
//!
//! Where the reference's time goes, phase by phase (p50 of each, `reference_phases_p50_ms`):
//! reading the plan, loading the world, building the costmap, planning the hundred legs on it,
//! building the net (every path known), and checking the net (names and reachability). An
//! update reuses the world, the costmap and the paths of the legs it did not change
//! (`armor_model::plan::memory`), so it pays for two legs and the rest.

use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use anyhow::{Context as _, anyhow, bail, ensure};
use armor_bench_report::Report;
use armor_model::SystemConfig;
use armor_model::geo::LatLon;
use armor_model::plan::{self, Plan};
use armor_model::world::Point;
use armor_module_api::{ENV_MODULE, ENV_SUPERVISOR};
use armor_protocol::{Client, Request};
use armor_runtime::probe::ENV_MODULE_PATH;

use crate::Settings;
use crate::compile_plan;
use crate::path_plan;
use crate::procs::{ChildGuard, sibling_binary};

pub const NAME: &str = "plan_update_ms";
/// How long `armor run` has to stop after SIGTERM.
const STOP_TIMEOUT: Duration = Duration::from_secs(20);
/// How long `armor run` may take to load, compile and check the plan and set the robot off
/// (the plan's hundred legs are planned on the world first).
const START_TIMEOUT: Duration = Duration::from_secs(120);
/// The waypoint moved by each update: far ahead of the robot, which drives the first leg.
const MOVED: &str = "w60";
/// How far it moves, north, and back with the next update (metres).
const MOVE_M: f64 = 0.3;

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let rounds = if settings.quick { 5 } else { 40 };
    let dir = tempfile::tempdir().context("cannot make a temporary folder")?;
    let world = path_plan::world()?;
    let (mut planner, _) = path_plan::planner(&world)?;
    let text = path_plan::plan_text(&world, &mut planner, 101)
        // The follower alone drives (no avoider): what is measured is the update.
        .replace(
            "<navigation><module name=\"avoider\"/></navigation>",
            "<navigation speed_mps=\"0.5\"/>\n<throughout><module name=\"recorder\"/></throughout>",
        );
    drop(planner);
    let plan = Plan::parse(&text).map_err(|problems| anyhow!("the plan: {problems:?}"))?;
    let (lat, lon) = world.origin_lat_lon();
    let origin = LatLon::new(lat, lon);
    let first = plan
        .waypoint("w0")
        .map(|waypoint| waypoint.position.to_local(origin))
        .context("the plan has no w0")?;
    // The robot starts at the first waypoint.
    let world_text = path_plan::world_text().replace(
        "start 1 1 0",
        &format!("start {:.3} {:.3} 0", first.x, first.y),
    );
    ensure!(
        world_text != path_plan::world_text(),
        "the world has no start line"
    );
    let recording = dir.path().join("cmd.mcap");
    let write = |name: &str, text: &str| -> anyhow::Result<()> {
        let file = dir.path().join(name);
        std::fs::write(&file, text).with_context(|| format!("cannot write {}", file.display()))
    };
    write("bench.world", &world_text)?;
    write("system.xml", &system_xml(&recording))?;
    write("plan.xml", &text)?;
    // The two plans the updates alternate between: the waypoint moved, and back.
    let moved = moved_plan(&plan, origin, MOVE_M)?;
    let plans = [moved, text.clone()];
    let system = SystemConfig::parse(&system_xml(&recording))
        .map_err(|problems| anyhow!("the bench's system does not parse: {problems:?}"))?;
    let descriptions = [
        armor_module_catalog::nav::follower::spec(),
        armor_module_catalog::sim::spec(),
        armor_module_catalog::recorder::spec(),
    ]
    .into_iter()
    .map(|spec| {
        let description = spec.description().clone();
        (description.module_type.clone(), description)
    })
    .collect();
    let from_scratch = |text: &str| -> anyhow::Result<plan::Compiled> {
        let plan = Plan::parse(text).map_err(|p| anyhow!("plan: {p:?}"))?;
        let robot = plan::robot(&plan, None, &Default::default());
        let compiled = plan::compile_for(&plan, Some(&world), &robot)
            .map_err(|p| anyhow!("compile: {p:?}"))?;
        compile_plan::check(&compiled.net, &system, &descriptions)?;
        Ok(compiled)
    };
    for text in &plans {
        from_scratch(text).context("an update's plan does not compile")?;
    }

    let armor = sibling_binary("armor")?;
    let exe = std::env::current_exe().context("cannot locate this executable")?;
    let exe_dir = exe.parent().context("this executable has no folder")?;
    let mut command = Command::new(&armor);
    command
        .arg("run")
        .arg(dir.path().join("plan.xml"))
        .arg("--no-run-folder")
        .env(ENV_MODULE_PATH, exe_dir)
        .env("ARMOR_LOG", "info")
        .env_remove(ENV_SUPERVISOR)
        .env_remove(ENV_MODULE)
        .current_dir(dir.path());
    let mut child = ChildGuard::spawn_capturing_stdout("armor run", command)?.graceful();
    let lines = child.merged_lines()?;
    let addr = child.wait_line(&lines, "its control address", START_TIMEOUT, |line| {
        line.strip_prefix(armor_runtime::CONTROL_READY_PREFIX)
            .map(|addr| addr.trim().to_owned())
    })?;
    let mut client = Client::connect(
        addr.parse::<std::net::SocketAddr>()
            .with_context(|| format!("the control address `{addr}`"))?,
        None,
    )?;
    // The robot under way on the first leg before the first update.
    let give_up = Instant::now() + START_TIMEOUT;
    loop {
        let status = client.call(&Request::Status)?.status.unwrap_or_default();
        let moving = status
            .mission
            .as_ref()
            .is_some_and(|mission| mission.marking.contains_key("leg1_drive"))
            && status.run_secs > 3.0;
        if moving {
            break;
        }
        ensure!(Instant::now() < give_up, "the robot never set off");
        child.check_alive()?;
        std::thread::sleep(Duration::from_millis(100));
    }
    let mut ours = Vec::with_capacity(rounds);
    let mut reference = Vec::with_capacity(rounds);
    let mut phases: Vec<[f64; PHASES.len()]> = Vec::with_capacity(rounds);
    // Each update's span on the run's clock: from its answer's run time back by its duration.
    let mut spans = Vec::with_capacity(rounds);
    for round in 0..rounds {
        let text = &plans[round % 2];
        let sent = Instant::now();
        let reply = client.call(&Request::Update {
            file: format!("plan-{round}.xml"),
            text: text.clone(),
        })?;
        let took = sent.elapsed();
        ensure!(
            reply.ok,
            "update {round} refused after {:.0} ms: {}; the updates before it took {:?} ms",
            took.as_secs_f64() * 1e3,
            reply.message,
            ours.iter()
                .map(|took: &Duration| (took.as_secs_f64() * 1e3).round())
                .collect::<Vec<_>>()
        );
        let answered_secs = reply.status.as_ref().map_or(0.0, |status| status.run_secs);
        let marking = reply
            .status
            .and_then(|status| status.mission)
            .map(|mission| mission.marking)
            .unwrap_or_default();
        ensure!(
            marking.contains_key("leg1_drive"),
            "the robot left the first leg during the updates ({marking:?}): a longer first leg \
             is needed"
        );
        ours.push(took);
        spans.push((answered_secs - took.as_secs_f64(), answered_secs));
        let began = Instant::now();
        std::hint::black_box(from_scratch(text)?);
        reference.push(began.elapsed());
        phases.push(phases_of(text, &system, &descriptions)?);
    }
    let status = child.terminate(STOP_TIMEOUT)?;
    // The mission never ends here: SIGTERM stops it unfinished, which `armor run` says with a
    // failure status; the recording is saved all the same.
    let _ = status;
    let [during, stopped, between, stopped_between] = commands_in(&recording, &spans)?;
    ensure!(
        during > 0,
        "no command of the follower was recorded during the updates"
    );
    // The follower drives on through an update: a command that stops the robot in one is a
    // defect, not a figure (it was a replan's, which the follower now steers on at once).
    ensure!(
        stopped == 0,
        "the follower commanded a stop {stopped} times in the {during} commands recorded during \
         the updates ({stopped_between} in the {between} between them)"
    );
    let phases_p50: serde_json::Map<String, serde_json::Value> = PHASES
        .iter()
        .enumerate()
        .map(|(index, name)| {
            let values: Vec<f64> = phases.iter().map(|phase| phase[index]).collect();
            (
                (*name).to_owned(),
                armor_bench_report::round(armor_bench_report::median(&values)).into(),
            )
        })
        .collect();
    Ok(Report::distribution(NAME, "ms", 1e3, &ours, &reference)
        .with(
            "reference_is",
            "the same plan compiled and checked from scratch in this process",
        )
        .with("reference_phases_p50_ms", phases_p50)
        .with("legs", plan.legs.len())
        .with("updates", rounds)
        .with("cmd_during_updates", during)
        .with("cmd_stopped_during_updates", stopped)
        .with("cmd_between_updates", between)
        .with("cmd_stopped_between_updates", stopped_between)
        .with(
            "goal",
            "p99 < 200 ms, and no command at zero during an update",
        ))
}

/// The phases of compiling a plan from scratch, as [`phases_of`] times them.
const PHASES: [&str; 6] = [
    "parse",
    "world",
    "costmap",
    "legs_planned",
    "net_built",
    "net_checked",
];

/// How long each of [`PHASES`] takes for the plan `text` (ms).
fn phases_of(
    text: &str,
    system: &SystemConfig,
    descriptions: &std::collections::BTreeMap<String, armor_module_api::ModuleDescription>,
) -> anyhow::Result<[f64; PHASES.len()]> {
    // The start and end of each phase.
    let mut spans: Vec<(Instant, Instant)> = Vec::with_capacity(PHASES.len());
    let mut began = Instant::now();
    let lap = |spans: &mut Vec<(Instant, Instant)>, began: &mut Instant| {
        let now = Instant::now();
        spans.push((*began, now));
        *began = now;
    };
    let plan = Plan::parse(text).map_err(|p| anyhow!("plan: {p:?}"))?;
    let robot = plan::robot(&plan, None, &Default::default());
    lap(&mut spans, &mut began);
    let world = path_plan::world()?;
    lap(&mut spans, &mut began);
    // The bench's plan has no no-go area: the legs' ends are its waypoints in the world frame.
    let origin = plan::plan_origin(&plan, Some(&world)).context("the plan has no frame")?;
    let at = |name: &str| {
        plan.waypoint(name)
            .map(|waypoint| waypoint.position.to_local(origin))
    };
    let pairs: Vec<(Point, Point)> = plan
        .legs
        .iter()
        .filter_map(|leg| Some((at(&leg.from)?, at(&leg.to)?)))
        .collect();
    ensure!(
        pairs.len() == plan.legs.len(),
        "a leg of the plan has an end not placed"
    );
    let costmap = armor_model::planner::Costmap::for_world(
        &world,
        &robot,
        &[],
        &armor_model::planner::CostmapSettings::default(),
    )?;
    let planner = armor_model::planner::Planner::new(costmap);
    lap(&mut spans, &mut began);
    std::hint::black_box(planner.plan_many(&pairs));
    lap(&mut spans, &mut began);
    // With every path known already, what is left is placing the waypoints and building the
    // net: the memory is filled first, untimed.
    let mut memory = plan::memory::PathMemory::default();
    plan::compile_with(&plan, Some(&world), &robot, &mut memory)
        .map_err(|p| anyhow!("compile: {p:?}"))?;
    began = Instant::now();
    let compiled = plan::compile_with(&plan, Some(&world), &robot, &mut memory)
        .map_err(|p| anyhow!("compile: {p:?}"))?;
    lap(&mut spans, &mut began);
    compile_plan::check(&compiled.net, system, descriptions)?;
    lap(&mut spans, &mut began);
    let mut times = [0.0; PHASES.len()];
    for (time, (from, to)) in times.iter_mut().zip(spans) {
        *time = (to - from).as_secs_f64() * 1e3;
    }
    Ok(times)
}

/// The bench's robot: the simulator on the bench's world, the follower on its odometry, and a
/// recorder of the follower's commands.
fn system_xml(recording: &Path) -> String {
    format!(
        r#"<system name="bench-update">
  <module name="sim" type="sim">
    <param name="world" value="bench.world"/>
  </module>
  <module name="follower" type="follower">
    <param name="world" value="bench.world"/>
    <param name="goal_x_m" value="0"/>
    <param name="goal_y_m" value="0"/>
  </module>
  <module name="recorder" type="recorder">
    <param name="record" value="follower.cmd_desired"/>
    <param name="file" value="{}"/>
    <param name="compression" value="none"/>
  </module>
  <link from="sim.odometry" to="follower.odometry"/>
  <link from="sim.scan" to="follower.scan"/>
  <link from="follower.cmd_desired" to="sim.cmd_vel"/>
</system>
"#,
        recording.display()
    )
}

/// `plan` with [`MOVED`] moved `north_m` north, as XML.
fn moved_plan(plan: &Plan, origin: LatLon, north_m: f64) -> anyhow::Result<String> {
    let mut moved = plan.clone();
    let waypoint = moved
        .waypoints
        .iter_mut()
        .find(|waypoint| waypoint.name == MOVED)
        .with_context(|| format!("the plan has no {MOVED}"))?;
    let at = waypoint.position.to_local(origin);
    waypoint.position = LatLon::from_local(Point::new(at.x, at.y + north_m), origin);
    Ok(moved.to_xml())
}

/// The follower's recorded commands from the first span on: how many fall in `spans` (run
/// seconds), how many of those stop the robot (no speed, no turn), and the same two counts
/// outside the spans, for comparison.
fn commands_in(recording: &Path, spans: &[(f64, f64)]) -> anyhow::Result<[usize; 4]> {
    let bytes = std::fs::read(recording)
        .with_context(|| format!("cannot read the recording {}", recording.display()))?;
    // [in a span, of those at zero, outside, of those at zero]
    let mut counts = [0; 4];
    let first = spans.first().map_or(0.0, |&(from, _)| from);
    let last = spans.last().map_or(0.0, |&(_, to)| to);
    for message in mcap::MessageStream::new(&bytes).context("the recording is not MCAP")? {
        let message = message.context("a message of the recording")?;
        if message.channel.topic != "follower.cmd_desired" {
            continue;
        }
        let at_secs = message.log_time as f64 / 1e9;
        if at_secs < first || at_secs > last {
            continue;
        }
        let inside = spans
            .iter()
            .any(|&(from, to)| at_secs >= from && at_secs <= to);
        let twist: serde_json::Value = serde_json::from_slice(&message.data)
            .context("a command of the recording is not JSON")?;
        let (Some(linear), Some(angular)) = (
            twist["linear_mps"].as_f64(),
            twist["angular_radps"].as_f64(),
        ) else {
            bail!("a command of the recording is not a Twist: {twist}");
        };
        let at = if inside { 0 } else { 2 };
        counts[at] += 1;
        if linear <= 0.0 && angular == 0.0 {
            counts[at + 1] += 1;
        }
    }
    Ok(counts)
}
