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
    let fail = |problems| Diagnostics {
        file: file.to_path_buf(),
        problems,
    };
    let text = read_source(file)?;
    // A plan is compiled once its system (and so its world) is known.
    let source = match kind_of(file, &text)? {
        DocumentKind::Plan => Err(Plan::parse(&text).map_err(fail)?),
        DocumentKind::Pnml => Ok(net::from_pnml(&text).map_err(fail)?),
        _ => Ok(MissionNet::parse(&text).map_err(fail)?),
    };
    let (system_name, pos) = match &source {
        Ok(net) => (net.system.clone(), net.pos),
        Err(plan) => (plan.system.clone(), plan.pos),
    };
    if system_name.is_empty() {
        return Err(fail(vec![Located::new(
            pos,
            "the mission names no system file (attribute `system`)",
        )]));
    }
    let base = file.parent().unwrap_or_else(|| Path::new("."));
    let system_file = base.join(&system_name);
    if let Err(err) = std::fs::metadata(&system_file) {
        return Err(fail(vec![Located::new(
            pos,
            format!(
                "cannot read the mission's system file `{system_name}` ({}): {err}",
                system_file.display()
            ),
        )]));
    }
    let system = load_system(&system_file, module_path)?;
    let planned_start_unix_secs = source.as_ref().err().and_then(|plan| plan.start_unix_secs);
    let plan = source.as_ref().err().cloned();
    let (net, compiled) = match source {
        Ok(net) => (net, None),
        Err(plan) => {
            let system_dir = system_file.parent().unwrap_or(base);
            let world = plan_world(&plan, &system.system, base, system_dir, module_path)
                .map_err(|message| fail(vec![Located::new(plan.pos, message)]))?;
            // The robot's size comes from the plan, else from the system's modules.
            let robot = plan::robot(&plan, Some(&system.system), &system.descriptions);
            let compiled = plan::compile_for(&plan, world.as_ref(), &robot).map_err(fail)?;
            if let Some(basemap) = &plan.basemap {
                plan_basemap(&basemap.href, base, module_path)
                    .map_err(|message| fail(vec![Located::new(basemap.pos, message)]))?;
            }
            (compiled.net.clone(), Some(compiled))
        }
    };
    let mut problems = net::check_names(&net, &system.system, &system.descriptions);
    let analysis = net::analyse(&net, ANALYSIS_LIMIT_STATES);
    problems.extend(analysis.problems(&net));
    problems.sort_by_key(|problem| problem.pos);
    if !problems.is_empty() {
        return Err(fail(problems));
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
    let path = paths::resolve(&name, base, module_path, "worlds")
        .map_err(|err| format!("the world: {err}"))?;
    armor_model::world::load(&path, &mut |path| std::fs::read(path))
        .map(Some)
        .map_err(|err| format!("the world does not load: {err}"))
}
