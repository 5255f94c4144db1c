//! `armor plan OBJECTIVES.xml -o PLAN.xml`: the constraint planner on a plan file's
//! `<objectives>` (`armor_autoplan`), its world and its system's robot; the best plan found
//! written as an ordinary plan, checked as `armor check` would, or why none can be.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context as _;
use armor_autoplan::{Instance, Outcome, write};
use armor_model::plan::{self, Plan};
use armor_model::plural;
use armor_module_api::xml::Located;

use crate::load::{Diagnostics, load_system, read_source};
use crate::mission;

/// How `armor plan` was asked to plan.
#[derive(Clone, Debug)]
pub struct Request {
    pub objectives: PathBuf,
    pub output: PathBuf,
    /// How long the solver may search for a better plan.
    pub limit: Duration,
    pub module_path: Vec<PathBuf>,
}

/// A plan of objectives loaded with its system and world, and its problem built.
struct Prepared {
    plan: Plan,
    /// The plan file's folder, which its file names are relative to.
    base: PathBuf,
    instance: Instance,
    on_world: bool,
    radius_m: f64,
}

/// Reads the plan, its system and world, places its objectives and plans the ways between
/// them; every problem located in the file.
fn prepare(file: &Path, module_path: &[PathBuf]) -> Result<Prepared, Diagnostics> {
    let fail = |problems: Vec<Located>| Diagnostics {
        file: file.to_path_buf(),
        problems,
    };
    let text = read_source(file)?;
    let plan = Plan::parse(&text).map_err(fail)?;
    let base = file
        .parent()
        .unwrap_or_else(|| Path::new("."))
        .to_path_buf();
    let system_file = base.join(&plan.system);
    let system = load_system(&system_file, module_path)?;
    let system_dir = system_file.parent().unwrap_or(&base);
    let world = mission::plan_world(&plan, &system.system, &base, system_dir, module_path)
        .map_err(|message| fail(vec![Located::new(plan.pos, message)]))?;
    let robot = plan::robot(&plan, Some(&system.system), &system.descriptions);
    // Times at the speed the robot really drives, as `armor check` checks them.
    let limit = mission::speed_limit(&plan, &system).map(|(limit, _)| limit);
    let speed_mps = limit.map_or(plan.navigation.speed_mps, |limit| {
        plan.navigation.speed_mps.min(limit)
    });
    let mut instance =
        armor_autoplan::instance(&plan, world.as_ref(), &robot, speed_mps).map_err(fail)?;
    instance.fastest_mps = limit.map_or(speed_mps, |limit| limit.max(speed_mps));
    instance.arrival_tolerance_m =
        mission::module_number(&system, &plan.navigation.module, "tolerance_m")
            .map_or(0.3, |(tolerance, _)| tolerance.max(0.0));
    if let Some(share) = instance.objectives.max_charge {
        let (per_m, per_hour) = battery_drain(&system).ok_or_else(|| {
            fail(vec![Located::new(
                instance.objectives.pos,
                "`max_charge` needs a battery model: no module of the system has \
                 battery_drain_per_m and battery_drain_per_hour (the simulator `sim` has)",
            )])
        })?;
        instance.problem.max_charge =
            Some(armor_autoplan::ChargeLimit::new(per_m, per_hour, share));
    }
    Ok(Prepared {
        plan,
        base,
        instance,
        on_world: world.is_some(),
        radius_m: robot.radius_m,
    })
}

/// How the system's battery drains (per metre, per hour): the parameters of its first module
/// that has them (the simulator's), given in the system file or by default.
fn battery_drain(system: &crate::load::Loaded) -> Option<(f64, f64)> {
    system.system.modules.iter().find_map(|module| {
        let value = |name: &str| -> Option<f64> {
            let text = match module.param(name) {
                Some(param) => param.value.clone(),
                None => system
                    .descriptions
                    .get(&module.module_type)?
                    .param(name)?
                    .default
                    .clone()?,
            };
            text.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0)
        };
        Some((
            value("battery_drain_per_m")?,
            value("battery_drain_per_hour")?,
        ))
    })
}

/// `armor check` of a plan of objectives that has no legs yet: `None` when `file` is not one
/// (it is checked as any other file), else what `armor plan` would start from, or its problems.
pub fn check(file: &Path, module_path: &[PathBuf]) -> Option<Result<String, Diagnostics>> {
    let text = std::fs::read_to_string(file).ok()?;
    let plan = Plan::parse(&text).ok()?;
    if plan.objectives.is_none() || !plan.legs.is_empty() {
        return None;
    }
    Some(prepare(file, module_path).map(|prepared| {
        let problem = &prepared.instance.problem;
        let ways = problem.travel_ds.iter().flatten().flatten().count();
        format!(
            "objectives of plan `{}`: {}, {} planned between their places (`armor plan` makes \
             its legs)",
            prepared.plan.name,
            plural(problem.tasks.len(), "objective"),
            plural(ways, "way")
        )
    }))
}

/// Plans, writes and reports; the exit status is a failure when the file has problems, when
/// no plan could be made, or when a must-serve objective had to be dropped to make one.
pub fn run(request: &Request) -> anyhow::Result<ExitCode> {
    let Prepared {
        plan,
        base,
        mut instance,
        on_world,
        radius_m,
    } = match prepare(&request.objectives, &request.module_path) {
        Ok(prepared) => prepared,
        Err(diagnostics) => {
            println!("{diagnostics}");
            eprintln!("{}", plural(diagnostics.problems.len(), "problem"));
            return Ok(ExitCode::FAILURE);
        }
    };
    let file = &request.objectives;
    let speed_mps = instance.speed_mps;
    let n = instance.objectives.objectives.len();
    println!(
        "{}: {} and the ways between them planned on {} for a robot of radius {} m at {} m/s",
        file.display(),
        plural(n, "objective"),
        if on_world { "the world" } else { "open ground" },
        armor_model::geo::round_mm(radius_m),
        speed_mps
    );
    // When the must-serve objectives cannot all be served: say why, then make the objectives
    // to blame optional (the least priority first) until a plan can be made.
    let mut dropped_must: Vec<String> = Vec::new();
    let solved = loop {
        // The dispatcher's answer (nearest neighbour, 2-opt) is where the search starts: the
        // plan is never worse than it.
        let seed = armor_autoplan::heuristic::nearest_neighbour_2opt(&instance.problem);
        match armor_autoplan::solve_from(&instance.problem, request.limit, seed.as_ref()) {
            Outcome::Solved(solved) => break solved,
            Outcome::Unknown => {
                println!(
                    "no plan found in {} s: give `armor plan` more time (--time-limit)",
                    request.limit.as_secs_f64()
                );
                return Ok(ExitCode::FAILURE);
            }
            Outcome::Infeasible => {}
        }
        let conflict = match armor_autoplan::explain(&instance.problem, request.limit) {
            Err(Some(conflict)) => conflict,
            Ok(()) | Err(None) => {
                println!(
                    "the objectives cannot all be served, and the search for why ran out of its \
                     {} s (--time-limit)",
                    request.limit.as_secs_f64()
                );
                return Ok(ExitCode::FAILURE);
            }
        };
        println!(
            "cannot serve every objective: {}",
            write::conflict_words(&instance, &conflict)
        );
        let must = conflict
            .constraints
            .iter()
            .filter_map(|constraint| match constraint {
                armor_autoplan::Constraint::Must(task) => Some(*task),
                _ => None,
            })
            .min_by_key(|&task| (instance.problem.tasks[task].priority, task));
        let Some(task) = must else {
            println!("no plan written: none of these objectives may be dropped to make one");
            return Ok(ExitCode::FAILURE);
        };
        instance.problem.tasks[task].must = false;
        dropped_must.push(instance.objectives.objectives[task].name.clone());
        println!(
            "to make a plan, `{}` may be dropped (the least priority of those that must be \
             served)",
            instance.objectives.objectives[task].name
        );
    };
    let route = &solved.route;
    let mut written = write::plan(&plan, &instance, route);
    relocate(&mut written, &base, &request.output);
    crate::fs::write_atomically(&request.output, written.to_xml().as_bytes())
        .with_context(|| format!("cannot write {}", request.output.display()))?;
    print_route(&instance, &solved, request);
    let unserved: Vec<String> = (0..n)
        .filter(|task| !route.order.contains(task))
        .map(|task| format!("`{}`", instance.objectives.objectives[task].name))
        .collect();
    if !unserved.is_empty() {
        println!("not served: {}", unserved.join(", "));
    }
    // The plan written is checked as `armor check` checks any plan.
    match mission::load_mission(&request.output, &request.module_path) {
        Ok(loaded) => {
            for warning in loaded.warnings() {
                eprintln!(
                    "{}:{}: warning: {}",
                    request.output.display(),
                    warning.pos,
                    warning.message
                );
            }
        }
        Err(diagnostics) => {
            println!("{diagnostics}");
            println!("the plan written does not pass `armor check`");
            return Ok(ExitCode::FAILURE);
        }
    }
    Ok(if dropped_must.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::FAILURE
    })
}

fn print_route(instance: &Instance, solved: &armor_autoplan::Solved, request: &Request) {
    let route = &solved.route;
    let cost = &route.cost;
    let total_priority: i32 = instance
        .problem
        .tasks
        .iter()
        .map(|task| task.priority)
        .sum();
    println!(
        "{}: plan written: {} of {} served (priority {} of {}), {} late in all, {} m, ends at \
         {}; {}",
        request.output.display(),
        route.order.len(),
        plural(instance.problem.tasks.len(), "objective"),
        cost.priority,
        total_priority,
        write::secs(cost.lateness_ds),
        armor_model::geo::round_mm(f64::from(cost.distance_dm) / 10.0),
        write::time_words(instance, route.end_ds),
        if solved.optimal {
            "proven the best".to_owned()
        } else {
            format!(
                "the best found in {} s (--time-limit), not proven the best",
                request.limit.as_secs_f64()
            )
        }
    );
    for line in write::route_words(instance, route) {
        println!("  {line}");
    }
}

/// The written plan's files (system, world, base map) named from where it is written.
fn relocate(plan: &mut Plan, base: &Path, output: &Path) {
    let output_dir = output
        .parent()
        .filter(|dir| !dir.as_os_str().is_empty())
        .unwrap_or_else(|| Path::new("."));
    let moved = |name: &str| -> String {
        crate::fs::relative_path(&base.join(name), output_dir)
            .to_string_lossy()
            .into_owned()
    };
    plan.system = moved(&plan.system);
    if !plan.world.is_empty() && base.join(&plan.world).exists() {
        plan.world = moved(&plan.world);
    }
    if let Some(basemap) = &mut plan.basemap
        && base.join(&basemap.href).exists()
    {
        basemap.href = moved(&basemap.href);
    }
}
