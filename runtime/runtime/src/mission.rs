//! Mission files: a Petri net over a system file, or a plan that compiles into one. Loading one
//! loads and checks its system, compiles a plan on its world (every leg planned for the robot
//! the plan and the system describe), then checks every name the net uses against the system
//! and analyses the net (deadlocks, dead transitions, places never marked, unboundedness)
//! before anything runs.

use std::path::{Path, PathBuf};

use armor_model::SystemConfig;
use armor_model::net::{self, MissionNet};
use armor_model::plan::{self, Compiled, Plan};
use armor_model::world::World;
use armor_module_api::xml::{self, Located, Pos};

use crate::load::{Diagnostics, Loaded, load_system, read_source};
use crate::paths;

/// More reachable markings than this and the analysis says so instead of going on.
pub const ANALYSIS_LIMIT_STATES: usize = 1_000_000;

/// What kind of document a file holds, from its top element.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DocumentKind {
    System,
    Mission,
    Pnml,
    Plan,
}

/// Reads a file's top element to tell systems from missions. Errors are reported as for a load.
pub fn document_kind(file: &Path) -> Result<DocumentKind, Diagnostics> {
    kind_of(file, &read_source(file)?)
}

fn kind_of(file: &Path, text: &str) -> Result<DocumentKind, Diagnostics> {
    let fail = |message: String, pos: Pos| Diagnostics {
        file: file.to_path_buf(),
        problems: vec![Located::new(pos, message)],
    };
    let root = xml::parse(text).map_err(|err| fail(err.message, err.pos))?;
    match root.name.as_str() {
        "system" => Ok(DocumentKind::System),
        "mission" => Ok(DocumentKind::Mission),
        "pnml" => Ok(DocumentKind::Pnml),
        "plan" => Ok(DocumentKind::Plan),
        other => Err(fail(
            format!("expected <system>, <mission>, <plan> or <pnml> at the top, found <{other}>"),
            root.pos,
        )),
    }
}

/// A checked mission with its checked system.
#[derive(Clone, Debug)]
pub struct LoadedMission {
    pub file: PathBuf,
    pub net: MissionNet,
    pub system_file: PathBuf,
    pub system: Loaded,
    /// Reachable markings of the untimed net.
    pub states: usize,
    /// The compiled plan, when the file is a plan.
    pub compiled: Option<Compiled>,
    /// The date the plan is made for (its `start`), when the file is a plan that gives one.
    pub planned_start_unix_secs: Option<f64>,
    /// The plan, when the file is one.
    pub plan: Option<Plan>,
}

impl LoadedMission {
    /// What may keep the mission from going as planned without stopping it (a plan's time
    /// constraints that cannot all be met).
    pub fn warnings(&self) -> &[Located] {
        self.compiled
            .as_ref()
            .map_or(&[], |compiled| compiled.warnings.as_slice())
    }
}

/// Reads a mission file (our XML, PNML, or a plan), loads its system, and checks both.
pub fn load_mission(file: &Path, module_path: &[PathBuf]) -> Result<LoadedMission, Diagnostics> {
    load_mission_counted(file, module_path).map_err(|(diagnostics, _)| diagnostics)
}

/// [`load_mission`], with the number of reachable markings also when the net's analysis finds
/// problems (a net that ends has dead markings: its count is still worth comparing with the
/// published one); `None` when the net was not analysed.
pub fn load_mission_counted(
    file: &Path,
    module_path: &[PathBuf],
) -> Result<LoadedMission, (Diagnostics, Option<usize>)> {
    load_mission_inner(file, module_path).map_err(|(diagnostics, states)| (*diagnostics, states))
}

fn load_mission_inner(
    file: &Path,
    module_path: &[PathBuf],
) -> Result<LoadedMission, (Box<Diagnostics>, Option<usize>)> {
    load_kept(file, module_path, &mut PlanMemory::default())
}

fn load_kept(
    file: &Path,
    module_path: &[PathBuf],
    memory: &mut PlanMemory,
) -> Result<LoadedMission, (Box<Diagnostics>, Option<usize>)> {
    let text = read_source(file).map_err(|diagnostics| (Box::new(diagnostics), None))?;
    let base = file.parent().unwrap_or_else(|| Path::new("."));
    load_text(file, &text, base, module_path, memory)
}

/// [`load_mission`] for a run: what it plans (the world loaded, the legs' paths, the
/// costmap) is kept in `memory`, for its updates.
pub fn load_mission_kept(
    file: &Path,
    module_path: &[PathBuf],
    memory: &mut PlanMemory,
) -> Result<LoadedMission, Diagnostics> {
    load_kept(file, module_path, memory).map_err(|(diagnostics, _)| *diagnostics)
}

/// Checks a mission given as `text` as [`load_mission`] checks a file, its relative names (the
/// system, the world, the base map) found from `base` rather than from the file's folder:
/// a plan update sent to a run is checked against the running plan's folder, and its problems
/// are said at `file`, the name the operator gave.
/// What it plans is kept in `memory`, and what `memory` holds that still holds is reused: the
/// world when its files did not change, the legs' paths that nothing changed
/// (`armor_model::plan::memory`).
pub fn load_mission_text(
    file: &Path,
    text: &str,
    base: &Path,
    module_path: &[PathBuf],
    memory: &mut PlanMemory,
) -> Result<LoadedMission, Diagnostics> {
    load_text(file, text, base, module_path, memory).map_err(|(diagnostics, _)| *diagnostics)
}

fn load_text(
    file: &Path,
    text: &str,
    base: &Path,
    module_path: &[PathBuf],
    memory: &mut PlanMemory,
) -> Result<LoadedMission, (Box<Diagnostics>, Option<usize>)> {
    let unanalysed = |diagnostics: Diagnostics| (Box::new(diagnostics), None);
    let fail = |problems| Diagnostics {
        file: file.to_path_buf(),
        problems,
    };
    let text = text.to_owned();
    // A plan is compiled once its system (and so its world) is known.
    let source = match kind_of(file, &text).map_err(unanalysed)? {
        DocumentKind::Plan => Err(Plan::parse(&text).map_err(fail).map_err(unanalysed)?),
        DocumentKind::Pnml => Ok(net::from_pnml(&text).map_err(fail).map_err(unanalysed)?),
        _ => Ok(MissionNet::parse(&text).map_err(fail).map_err(unanalysed)?),
    };
    let (system_name, pos) = match &source {
        Ok(net) => (net.system.clone(), net.pos),
        Err(plan) => (plan.system.clone(), plan.pos),
    };
    if system_name.is_empty() {
        return Err(unanalysed(fail(vec![Located::new(
            pos,
            match source {
                Ok(_) => {
                    "the mission names no system file (attribute `system`; `armor import \
                          NET.pnml --system FILE` writes it)"
                }
                Err(_) => "the plan names no system file (attribute `system`)",
            },
        )])));
    }
    let system_file = base.join(&system_name);
    if let Err(err) = std::fs::metadata(&system_file) {
        return Err(unanalysed(fail(vec![Located::new(
            pos,
            format!(
                "cannot read the mission's system file `{system_name}` ({}): {err}",
                system_file.display()
            ),
        )])));
    }
    let system = load_system(&system_file, module_path).map_err(unanalysed)?;
    let planned_start_unix_secs = source.as_ref().err().and_then(|plan| plan.start_unix_secs);
    let plan = source.as_ref().err().cloned();
    let (net, compiled) = match source {
        Ok(net) => (net, None),
        Err(plan) => {
            let system_dir = system_file.parent().unwrap_or(base);
            let world = memory
                .world(&plan, &system.system, base, system_dir, module_path)
                .map_err(|err| unanalysed(fail(vec![Located::new(plan.pos, err.to_string())])))?;
            // The robot's size comes from the plan, else from the system's modules.
            let (robot, radius_source) =
                plan::robot_explained(&plan, Some(&system.system), &system.descriptions);
            // The times are checked at the speed the robot can drive, not a faster one the plan
            // assumes (a ground station's cruise speed).
            let limit = speed_limit(&plan, &system);
            let mut timed = plan.clone();
            if let Some((limit_mps, _)) = &limit {
                timed.navigation.speed_mps = timed.navigation.speed_mps.min(*limit_mps);
            }
            let mut compiled =
                plan::compile_with(&timed, world.as_ref(), &robot, &mut memory.paths).map_err(
                    |mut problems| {
                        for problem in &mut problems {
                            // Every message about the robot's size says where the size comes from.
                            if problem.message.contains(" keeps ") {
                                problem.message.push_str(&format!(
                                    " (the robot's radius, {} m: {radius_source})",
                                    armor_model::geo::round_mm(robot.radius_m)
                                ));
                            }
                        }
                        unanalysed(fail(problems))
                    },
                )?;
            if let Some((limit_mps, why)) = limit
                && plan.navigation.speed_mps > limit_mps
            {
                compiled.warnings.push(Located::new(
                    if plan.navigation.pos == Pos::default() {
                        plan.pos
                    } else {
                        plan.navigation.pos
                    },
                    format!(
                        "the plan's speed, {} m/s, is more than the robot drives ({limit_mps} \
                         m/s: {why}): its times are checked at {limit_mps} m/s",
                        plan.navigation.speed_mps
                    ),
                ));
            }
            if let Some(warning) = start_warning(&plan, &compiled, world.as_ref(), &system) {
                compiled.warnings.push(warning);
            }
            compiled.warnings.sort_by_key(|warning| warning.pos);
            if let Some(basemap) = &plan.basemap {
                plan_basemap(&basemap.href, base, module_path).map_err(|message| {
                    unanalysed(fail(vec![Located::new(basemap.pos, message)]))
                })?;
            }
            (compiled.net.clone(), Some(compiled))
        }
    };
    let mut problems = net::check_names(&net, &system.system, &system.descriptions);
    let analysis = net::analyse(&net, ANALYSIS_LIMIT_STATES);
    problems.extend(analysis.problems(&net));
    problems.sort_by_key(|problem| problem.pos);
    if !problems.is_empty() {
        return Err((Box::new(fail(problems)), Some(analysis.states)));
    }
    Ok(LoadedMission {
        file: file.to_path_buf(),
        net,
        system_file,
        system,
        states: analysis.states,
        compiled,
        planned_start_unix_secs,
        plan,
    })
}

/// The value of a module's number parameter: the system file's, else its description's
/// default; with whether the system file gives it.
pub(crate) fn module_number(loaded: &Loaded, module: &str, param: &str) -> Option<(f64, bool)> {
    let module = loaded.system.module(module)?;
    let (value, given) = match module.param(param) {
        Some(value) => (value.value.clone(), true),
        None => (
            loaded
                .descriptions
                .get(&module.module_type)?
                .param(param)?
                .default
                .clone()?,
            false,
        ),
    };
    value
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|value| value.is_finite())
        .map(|value| (value, given))
}

/// The modules that simulate the robot: those given a `world` to run in.
fn simulators(loaded: &Loaded) -> impl Iterator<Item = &armor_model::ModuleInstance> {
    loaded.system.modules.iter().filter(|module| {
        module
            .param("world")
            .is_some_and(|param| !param.value.trim().is_empty())
    })
}

/// The fastest the robot drives on the plan's legs: the least `max_speed_mps` of its navigation
/// module, their companions and the simulator, and which module sets it, in words.
pub fn speed_limit(plan: &Plan, loaded: &Loaded) -> Option<(f64, String)> {
    let navigation = &plan.navigation;
    let drivers = std::iter::once(navigation.module.as_str())
        .chain(navigation.companions.iter().map(String::as_str))
        .chain(simulators(loaded).map(|module| module.name.as_str()));
    drivers
        .filter_map(|module| {
            let (speed, given) = module_number(loaded, module, "max_speed_mps")?;
            (speed > 0.0).then(|| {
                (
                    speed,
                    format!(
                        "module `{module}`'s {}max_speed_mps",
                        if given { "" } else { "default " }
                    ),
                )
            })
        })
        .fold(None, |least: Option<(f64, String)>, this| match least {
            Some(least) if least.0 <= this.0 => Some(least),
            _ => Some(this),
        })
}

/// When the system simulates the robot on the plan's world and the robot starts further from
/// where the plan's first leg starts than the navigation module's tolerance (its first leg
/// would then be driven from elsewhere, or count as arrived too soon), a warning that says so.
fn start_warning(
    plan: &Plan,
    compiled: &plan::Compiled,
    world: Option<&World>,
    loaded: &Loaded,
) -> Option<Located> {
    let world = world?;
    simulators(loaded).next()?;
    let first = plan.legs.first()?;
    let planned = compiled.positions.get(&first.from)?;
    let start = world.start();
    let off_m = (start.x_m - planned.x).hypot(start.y_m - planned.y);
    let tolerance_m = module_number(loaded, &plan.navigation.module, "tolerance_m")
        .map_or(0.3, |(tolerance, _)| tolerance);
    let mm = armor_model::geo::round_mm;
    let cm = |value: f64| mm((value * 100.0).round() / 100.0);
    (off_m > tolerance_m).then(|| {
        Located::new(
            first.pos,
            format!(
                "the simulated robot starts at ({}, {}) in the world `{}`, {} m from `{}` where \
                 the plan starts (at ({}, {})): its first leg is driven from there. Move the \
                 world's start there (a ROS map: `start: [{}, {}, 0]` in its YAML; without it \
                 the robot starts at the free place nearest the map's origin)",
                cm(start.x_m),
                cm(start.y_m),
                world.name(),
                cm(off_m),
                first.from,
                cm(planned.x),
                cm(planned.y),
                cm(planned.x),
                cm(planned.y)
            ),
        )
    })
}

/// The base map a plan names (`<basemap href>`), found from `plan_dir` as [`paths::resolve`]
/// says (bundled maps under `assets/maps/`) and opened.
pub fn plan_basemap(
    href: &str,
    plan_dir: &Path,
    module_path: &[PathBuf],
) -> Result<crate::basemap::Basemap, String> {
    let path = paths::resolve(href, plan_dir, module_path, "maps")
        .map_err(|err| format!("the base map: {err}"))?;
    crate::basemap::Basemap::open(&path).map_err(|err| format!("the base map: {err}"))
}

/// The world a plan is drawn on: the one it names (found from `plan_dir`, the plan file's
/// folder, as [`paths::resolve`] says), else the one its system's simulator loads (a module
/// parameter called `world`, found from `system_dir`); `None` when neither names one (a real
/// robot). A `.world` file or a ROS map_server map (`.yaml`).
pub fn plan_world(
    plan: &Plan,
    system: &SystemConfig,
    plan_dir: &Path,
    system_dir: &Path,
    module_path: &[PathBuf],
) -> Result<Option<World>, String> {
    PlanMemory::default()
        .world(plan, system, plan_dir, system_dir, module_path)
        .map_err(|err| err.to_string())
}

/// Why a plan's world could not be had.
#[derive(Debug, thiserror::Error)]
pub enum PlanWorldError {
    /// No file by the world's name, where the plan or the system names it.
    #[error("the world: {0}")]
    NotFound(String),
    /// The file is there but does not load.
    #[error("the world does not load: {0}")]
    Load(#[from] armor_model::world::WorldError),
}

/// The file of the world [`plan_world`] loads, `None` when the plan has none.
fn world_file(
    plan: &Plan,
    system: &SystemConfig,
    plan_dir: &Path,
    system_dir: &Path,
    module_path: &[PathBuf],
) -> Result<Option<PathBuf>, PlanWorldError> {
    let (name, base) = if plan.world.is_empty() {
        let from_system = system.modules.iter().find_map(|module| {
            module
                .param("world")
                .map(|param| param.value.clone())
                .filter(|value| !value.is_empty())
        });
        match from_system {
            Some(name) => (name, system_dir),
            None => return Ok(None),
        }
    } else {
        (plan.world.clone(), plan_dir)
    };
    paths::resolve(&name, base, module_path, "worlds")
        .map(Some)
        .map_err(PlanWorldError::NotFound)
}

/// What a run keeps between the plans it compiles (its own at the start, then each update's),
/// so that an update does only the work its changes need: the world as loaded, and the legs'
/// paths with the costmap they were planned on.
#[derive(Clone, Debug, Default)]
pub struct PlanMemory {
    world: Option<KeptWorld>,
    pub paths: plan::memory::PathMemory,
}

/// A world loaded, with what its files were when they were read.
#[derive(Clone, Debug)]
struct KeptWorld {
    file: PathBuf,
    /// Every file read (a ROS map's YAML and its image), with its size and modification time.
    read: Vec<(PathBuf, Option<(u64, std::time::SystemTime)>)>,
    world: World,
}

/// A file's size and modification time, what tells that it changed.
fn stamp(file: &Path) -> Option<(u64, std::time::SystemTime)> {
    let metadata = std::fs::metadata(file).ok()?;
    Some((metadata.len(), metadata.modified().ok()?))
}

impl PlanMemory {
    /// [`plan_world`], the world kept from the last call when it is the same file and none of
    /// the files it was read from has changed since.
    pub fn world(
        &mut self,
        plan: &Plan,
        system: &SystemConfig,
        plan_dir: &Path,
        system_dir: &Path,
        module_path: &[PathBuf],
    ) -> Result<Option<World>, PlanWorldError> {
        let Some(file) = world_file(plan, system, plan_dir, system_dir, module_path)? else {
            return Ok(None);
        };
        if let Some(kept) = &self.world
            && kept.file == file
            && kept
                .read
                .iter()
                .all(|(read, was)| was.is_some() && stamp(read) == *was)
        {
            return Ok(Some(kept.world.clone()));
        }
        let mut read = Vec::new();
        let world = armor_model::world_file::load(&file, &mut |path| {
            read.push((path.to_path_buf(), stamp(path)));
            std::fs::read(path)
        })?;
        self.world = Some(KeptWorld {
            file,
            read,
            world: world.clone(),
        });
        Ok(Some(world))
    }
}
