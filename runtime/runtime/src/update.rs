//! Plan updates sent to a running mission (`armor ctl update PLAN.xml`, [`Request::Update`]):
//! the new plan is checked as `armor check` checks a file (its relative names found from the
//! running plan's folder), compiled, and the mission moved to its net between two firings
//! (`armor_model::plan::migrate` says where; the controller swaps the nets). A leg in force that
//! changed gets its path planned again from where the robot believes it is (its odometry), so
//! that the follower does not drive back to the leg's start. Anything that keeps the update from
//! being taken is said in words, and the mission goes on unchanged; every update, taken or
//! not, is numbered and recorded (`docs/plans.md`, "Updates to a running mission").
//!
//! A no-go area reported from outside ([`check_area`]: `armor ctl area`, a module's `area`
//! message) is the running plan with the area added, checked and taken the same way; one that
//! leaves the leg in force no way from the robot is taken all the same, and the leg blocked.
//!
//! [`Request::Update`]: armor_protocol::Request::Update

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use armor_model::SystemConfig;
use armor_model::geo::{self, Point};
use armor_model::net::{Marking, MissionNet};
use armor_model::plan::memory::Reuse;
use armor_model::plan::migrate::{self, Migration};
use armor_model::plan::{Compiled, Origin, Plan};
use armor_model::planner::{Path as PlannedPath, PathError};
use armor_model::world::World;
use armor_protocol::Request;
use serde_json::json;

use crate::config_server::ConfigServer;
use crate::controller::Controller;
use crate::mission::{LoadedMission, PlanMemory, load_mission_text};
use crate::progress::{self, Progress};

/// The plan a run plays, as it stands after the updates taken so far.
#[derive(Clone, Debug)]
pub struct Running {
    /// The plan file the run was started with: an update's relative names are found from its
    /// folder.
    pub file: PathBuf,
    pub system_file: PathBuf,
    pub plan: Plan,
    pub compiled: Compiled,
    /// The world and the paths planned so far, which an update reuses where they hold.
    pub memory: PlanMemory,
}

/// An update checked, compiled and migrated, ready to be swapped in.
#[derive(Debug)]
pub struct Prepared {
    pub plan: Plan,
    /// The new plan compiled, as it is: what the next update is compared with, and whose
    /// routes the summary's table measures.
    pub compiled: Compiled,
    /// The net to play: the compiled one, its places naming subsystems expanded, and the leg
    /// in force driven on the path planned from where the robot is (replaced) or on the one
    /// the run gave it (unchanged).
    pub net: MissionNet,
    pub migration: Migration,
    /// What the update does, in one sentence; then, a line each, the warnings `armor check`
    /// would print for the plan (time constraints that cannot all be met).
    pub message: String,
    /// The event the new net hears at once (the navigation's `blocked`), when an area reported
    /// leaves the leg in force no way from where the robot is.
    pub blocked: Option<String>,
}

/// Where the robot is and when it is, for the update.
#[derive(Clone, Copy, Debug)]
pub struct Now {
    /// Where the robot believes it is (its odometry), when the run's node has it.
    pub robot_at: Option<Point>,
    /// The run's clock as a date (Unix seconds), against which the plan's dates are judged.
    pub unix_secs: f64,
}

/// An update checked and compiled: what does not depend on where the mission stands.
#[derive(Debug)]
pub struct Checked {
    /// The file the operator sent, as named.
    file: String,
    loaded: LoadedMission,
    plan: Plan,
    compiled: Compiled,
    /// Whether it is an area reported from outside ([`check_area`]): one that leaves the leg in
    /// force no way is taken all the same, and the leg is blocked.
    reported: bool,
    /// Whether it is an option of a repair: once taken, a leg held drives again, from where
    /// the robot is.
    repair: bool,
    /// How many of its legs were planned, and how many kept the paths planned before.
    reuse: Reuse,
}

impl Checked {
    /// Whether it is an option of a repair ([`Asked::Repair`]).
    pub fn is_repair(&self) -> bool {
        self.repair
    }
}

/// Why an update is refused, in the operator's words (docs/plans.md lists every reason).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Refused(pub String);

impl From<String> for Refused {
    fn from(why: String) -> Refused {
        Refused(why)
    }
}

fn refused<T>(why: impl Into<String>) -> Result<T, Refused> {
    Err(Refused(why.into()))
}

/// Checks and compiles `text` (named `file` by the operator) as an update of the `running`
/// plan: the slow part of an update, which the run does before it looks at the mission's
/// marking. The error is why the update is refused, in words.
pub fn check(
    running: &mut Running,
    file: &str,
    text: &str,
    module_path: &[PathBuf],
) -> Result<Checked, Refused> {
    let base = running.file.parent().unwrap_or_else(|| Path::new("."));
    let loaded = load_mission_text(
        Path::new(file),
        text,
        base,
        module_path,
        &mut running.memory,
    )
    .map_err(|diagnostics| format!("the update does not check: {diagnostics}"))?;
    let (Some(plan), Some(compiled)) = (loaded.plan.clone(), loaded.compiled.clone()) else {
        return refused(
            "the update is a mission net, not a plan: a running plan is updated with a plan",
        );
    };
    if !same_file(&loaded.system_file, &running.system_file) {
        return refused(format!(
            "the update is over the system `{}`, the run over `{}`: an update cannot change the \
             system (stop the run and start the new one)",
            loaded.system_file.display(),
            running.system_file.display()
        ));
    }
    Ok(Checked {
        file: file.to_owned(),
        loaded,
        plan,
        compiled,
        reported: false,
        repair: false,
        reuse: running.memory.paths.last(),
    })
}

/// An update asked of the run, before it is checked.
#[derive(Clone, Debug)]
pub enum Asked {
    /// A whole plan (`armor ctl update PLAN.xml`), named `file` by the operator.
    Plan { file: String, text: String },
    /// A no-go area to add to the running plan.
    Area(ReportedArea),
    /// An option of the repair proposed (`armor ctl repair N`, or the plan's default): a whole
    /// plan, recorded under `label`.
    Repair { label: String, plan: Box<Plan> },
}

impl Asked {
    /// The update a control request asks for; any other request is given back.
    pub fn of(request: Request) -> Result<Asked, Request> {
        match request {
            Request::Update { file, text } => Ok(Asked::Plan { file, text }),
            Request::Area { name, points_m } => Ok(Asked::Area(ReportedArea {
                name,
                points_m,
                by: "the operator".to_owned(),
            })),
            other => Err(other),
        }
    }

    /// The name the update is recorded under.
    pub fn label(&self) -> String {
        match self {
            Asked::Plan { file, .. } => file.clone(),
            Asked::Area(area) => area.label(),
            Asked::Repair { label, .. } => label.clone(),
        }
    }

    /// [`check`] or [`check_area`].
    pub fn check(
        &self,
        running: &mut Running,
        module_path: &[PathBuf],
    ) -> Result<Checked, Refused> {
        match self {
            Asked::Plan { file, text } => check(running, file, text, module_path),
            Asked::Area(area) => check_area(running, area, module_path),
            Asked::Repair { label, plan } => {
                let mut checked = check(running, label, &plan.to_xml(), module_path)?;
                checked.repair = true;
                Ok(checked)
            }
        }
    }
}

/// A no-go area reported from outside the plan (`armor ctl area`, a module's `area` message).
#[derive(Clone, Debug)]
pub struct ReportedArea {
    pub name: String,
    /// Its corners in the world frame, in metres.
    pub points_m: Vec<[f64; 2]>,
    /// Who reported it, as the records say it: `the operator`, ``module `radio` ``.
    pub by: String,
}

impl ReportedArea {
    /// The name its update is recorded under, in place of a file's.
    pub fn label(&self) -> String {
        format!("area `{}` reported by {}", self.name, self.by)
    }
}

/// Checks the running plan with `area` added to it as a no-go area, as [`check`] checks a plan
/// sent whole: an area reported is an update like any other. The error says why the area is
/// refused: fewer than three corners, an outline that crosses itself, a name the plan has.
pub fn check_area(
    running: &mut Running,
    area: &ReportedArea,
    module_path: &[PathBuf],
) -> Result<Checked, Refused> {
    let plan = with_area(running, area)?;
    let mut checked = check(running, &area.label(), &plan.to_xml(), module_path)?;
    checked.reported = true;
    Ok(checked)
}

/// The running plan with `area` added to it as a no-go area (default margin), or why the area
/// is refused before the plan is checked: fewer than three corners, an outline that crosses
/// itself, a name the plan has, no frame to place it in.
pub fn with_area(running: &Running, area: &ReportedArea) -> Result<Plan, Refused> {
    let name = &area.name;
    let valid_name = name
        .chars()
        .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
        && name.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_');
    if !valid_name {
        return refused(format!(
            "the area's name `{name}` is not a name: ASCII letters, digits, `_` and `-`, starting \
             with a letter or `_`"
        ));
    }
    if area.points_m.len() < 3 {
        return refused(format!(
            "area `{name}` has {} corners: an area needs at least 3",
            area.points_m.len()
        ));
    }
    let corners: Vec<Point> = area
        .points_m
        .iter()
        .map(|&[x, y]| Point::new(x, y))
        .collect();
    if let Some(bad) = corners.iter().find(|corner| !corner.is_finite()) {
        return refused(format!(
            "area `{name}` has a corner that is not a number: ({}, {})",
            bad.x, bad.y
        ));
    }
    if geo::Polygon::new(corners.clone()).crosses_itself() {
        return refused(format!(
            "area `{name}`: its outline crosses itself, so it has no clear inside"
        ));
    }
    if running
        .plan
        .graphics
        .iter()
        .any(|graphic| graphic.name == *name)
    {
        return refused(format!(
            "the plan has an element named `{name}` already: report the area under another name"
        ));
    }
    let Some(origin) = running.compiled.origin else {
        return refused(
            "the running plan has no geographic frame (no world, no origin) to place the area in",
        );
    };
    let mut plan = running.plan.clone();
    plan.graphics.push(armor_model::plan::Graphic {
        kind: armor_model::plan::GraphicKind::Area(armor_model::plan::AreaKind::NoGo),
        name: name.clone(),
        points: corners
            .iter()
            .map(|&corner| geo::LatLon::from_local(corner, origin))
            .collect(),
        ..Default::default()
    });
    Ok(plan)
}

/// Migrates a `checked` update of the `running` plan from `marking`, the leg in force that
/// changed planned again from where the robot is; the error is why the update is refused.
pub fn prepare(
    running: &Running,
    checked: Checked,
    module_path: &[PathBuf],
    mission: (&MissionNet, &Marking),
    now: Now,
) -> Result<Prepared, Refused> {
    let Checked {
        loaded,
        plan,
        compiled,
        reported,
        reuse,
        ..
    } = checked;
    let (played, marking) = mission;
    let mut net = compiled.net.with_subsystems_expanded(&loaded.system.system);
    let base = running.file.parent().unwrap_or_else(|| Path::new("."));
    let migration = migrate::migrate(&running.plan, &running.compiled, marking, &plan, &compiled)
        .map_err(|refusal| refusal.to_string())?;
    let leg = &plan.legs[migration.index];
    let navigation = plan.navigation.module.clone();
    let drives = compiled
        .net
        .place(&migration.place_after)
        .is_some_and(|place| {
            place
                .params
                .iter()
                .any(|param| param.module == navigation && param.name == "path")
        });
    let mut how = if migration.changed {
        format!("replaced at once in `{}`", migration.place_after)
    } else {
        format!("goes on unchanged in `{}`", migration.place_after)
    };
    let area_names = |compiled: &Compiled| {
        compiled
            .keepouts
            .iter()
            .map(|keepout| keepout.name.clone())
            .collect::<Vec<_>>()
    };
    let (old_areas, new_areas) = (area_names(&running.compiled), area_names(&compiled));
    let (areas_added, areas_removed) = difference(
        old_areas.iter().map(String::as_str),
        new_areas.iter().map(String::as_str),
    );
    let mut blocked = None;
    let path_param = (navigation.as_str(), "path");
    if !migration.changed {
        // The leg goes on as the run plays it: with the path an earlier update planned from
        // where the robot was, if one did, not the plan's from the leg's start. Only where the
        // plan's own route for the place is the one it was, though: a drive place not entered
        // yet that the update routes anew (an area added while the robot waits at the leg's
        // gate) takes its new route.
        migrate::set_leg_param(
            &mut net,
            &compiled.trace,
            migration.index,
            path_param,
            |place| {
                let route = |net: &MissionNet| migrate::param_of(net, place, path_param);
                (route(&running.compiled.net) == route(&compiled.net))
                    .then(|| route(played))
                    .flatten()
            },
        );
    }
    if migration.changed && drives {
        match now.robot_at {
            Some(here) => {
                let goal = *compiled.positions.get(&leg.to).ok_or_else(|| {
                    format!("waypoint `{}` of leg `{}` is not placed", leg.to, leg.name)
                })?;
                let system_dir = loaded.system_file.parent().unwrap_or(base);
                // A copy of the run's memory: its costmap is shared, not copied, and the
                // paths it remembers are the ones the check just planned.
                let mut memory = running.memory.clone();
                let world = memory
                    .world(&plan, &loaded.system.system, base, system_dir, module_path)
                    .map_err(|err| err.to_string())?;
                let path = match plan_one(&mut memory, world.as_ref(), &compiled, here, goal)? {
                    Ok(path) => Some(path),
                    // An area reported is a fact, not a wish: it is taken all the same, and
                    // the leg is blocked (the plan's contingency on `blocked` applies, holding
                    // by default), so that the operator can update or abort.
                    Err(err) if reported => {
                        blocked = Some(format!(
                            "{}.{}",
                            plan.navigation.module, plan.navigation.blocked_event
                        ));
                        let names = areas_added
                            .iter()
                            .map(|name| format!("`{name}`"))
                            .collect::<Vec<_>>()
                            .join(", ");
                        how = format!(
                            "blocked: with the no-go area {names} there is no way from where the \
                             robot is, ({}, {}), to `{}` ({err}): the plan's contingency on \
                             `blocked` applies",
                            geo::round_mm(here.x),
                            geo::round_mm(here.y),
                            leg.to
                        );
                        None
                    }
                    Err(err) => {
                        return refused(format!(
                            "leg `{}` in force changed, and there is no way from where the \
                             robot is, ({}, {}), to `{}`: {err}",
                            leg.name,
                            geo::round_mm(here.x),
                            geo::round_mm(here.y),
                            leg.to
                        ));
                    }
                };
                if let Some(path) = path {
                    let value = path.format();
                    migrate::set_leg_param(
                        &mut net,
                        &compiled.trace,
                        migration.index,
                        path_param,
                        |_| Some(value.clone()),
                    );
                    how.push_str(&format!(
                        ", its path planned again from where the robot is, ({}, {}): {} m to `{}`",
                        geo::round_mm((here.x * 100.0).round() / 100.0),
                        geo::round_mm((here.y * 100.0).round() / 100.0),
                        geo::round_mm((geo::path_length(&path.points) * 10.0).round() / 10.0),
                        leg.to
                    ));
                }
            }
            None => how.push_str(
                ", from its start (where the robot is is not known: no odometry is followed)",
            ),
        }
    }
    let mut parts = vec![format!("leg `{}` in force {how}", leg.name)];
    let (added, removed) = difference(
        running.plan.legs.iter().map(|leg| leg.name.as_str()),
        plan.legs.iter().map(|leg| leg.name.as_str()),
    );
    parts.extend(listed("legs added", &added));
    parts.extend(listed("legs removed", &removed));
    parts.extend(listed("no-go areas added", &areas_added));
    parts.extend(listed("no-go areas removed", &areas_removed));
    parts.extend(listed(
        "legs routed anew",
        &routed_anew(running, (&plan, &compiled), migration.index),
    ));
    parts.extend(times(&plan, &migration, now.unix_secs));
    parts.push(format!(
        "paths planned for {} of its {} legs, the others kept",
        reuse.planned,
        plan.legs.len()
    ));
    Ok(Prepared {
        plan,
        compiled,
        net,
        migration,
        message: std::iter::once(parts.join("; "))
            .chain(loaded.warnings().iter().map(|warning| {
                format!(
                    "{}:{}: warning: {}",
                    loaded.file.display(),
                    warning.pos,
                    warning.message
                )
            }))
            .collect::<Vec<_>>()
            .join("\n"),
        blocked,
    })
}

/// The legs of both plans from the one in force on (`from`, in the new plan), by name, whose
/// planned route the update changed (a waypoint moved, an area across it): the follower drives
/// the new one when it gets there.
fn routed_anew(
    running: &Running,
    (plan, compiled): (&Plan, &Compiled),
    from: usize,
) -> Vec<String> {
    plan.legs
        .iter()
        .zip(&compiled.routes)
        .skip(from)
        .filter(|(leg, route)| {
            running
                .plan
                .legs
                .iter()
                .position(|old| old.name == leg.name)
                .and_then(|old| running.compiled.routes.get(old))
                .is_some_and(|old| old != *route)
        })
        .map(|(leg, _)| leg.name.clone())
        .collect()
}

/// Plans the way from `here` to `goal` on `world` for the robot and round the no-go areas of
/// `compiled` (on the costmap `memory` keeps, when it is that one); the outer error is a
/// planner that could not work (the world not mapped).
fn plan_one(
    memory: &mut PlanMemory,
    world: Option<&World>,
    compiled: &Compiled,
    here: Point,
    goal: Point,
) -> Result<Result<PlannedPath, PathError>, Refused> {
    memory
        .paths
        .plan_others(world, &compiled.robot, &compiled.keepouts, &[(here, goal)])
        .map_err(|err| format!("the world cannot be mapped for planning: {err}"))?
        .into_iter()
        .next()
        .ok_or_else(|| Refused("the planner planned nothing".to_owned()))
}

/// The world the running plan is planned on (none: no world, round its areas only), as the
/// run keeps it.
pub fn world_of(
    running: &mut Running,
    system: &SystemConfig,
    module_path: &[PathBuf],
) -> Result<Option<World>, Refused> {
    let base = running.file.parent().unwrap_or_else(|| Path::new("."));
    let system_dir = running.system_file.parent().unwrap_or(base);
    Ok(running
        .memory
        .world(&running.plan, system, base, system_dir, module_path)
        .map_err(|err| err.to_string())?)
}

/// Before the operator's `LEG_retry` fires (a leg held drives again): plans the leg from where
/// the robot is (`here`) to its destination and gives the leg's drive places that path, as an
/// update gives a leg it replaces, so that the follower does not drive back to the leg's start.
/// Does nothing for another transition, or with no position; says what it did, or why the
/// plan's path is kept (no way from here: the follower finds that out and blocks again).
pub fn reroute_retry(
    controller: &mut Controller,
    running: &mut Running,
    transition: &str,
    here: Option<Point>,
    world: impl FnOnce(&mut Running) -> Result<Option<World>, Refused>,
) -> Option<String> {
    let Some(&Origin::Leg(index)) = running.compiled.trace.get(transition) else {
        return None;
    };
    let leg = running.plan.legs.get(index)?.clone();
    if transition != format!("{}_retry", leg.name) {
        return None;
    }
    let here = here?;
    let goal = *running.compiled.positions.get(&leg.to)?;
    let planned = world(running).and_then(|world| {
        plan_one(
            &mut running.memory,
            world.as_ref(),
            &running.compiled,
            here,
            goal,
        )
    });
    let at = format!("({}, {})", geo::round_mm(here.x), geo::round_mm(here.y));
    match planned {
        Ok(Ok(path)) => {
            let mut net = controller.net().clone();
            let value = path.format();
            migrate::set_leg_param(
                &mut net,
                &running.compiled.trace,
                index,
                (running.plan.navigation.module.as_str(), "path"),
                |_| Some(value.clone()),
            );
            match controller.reroute(net) {
                Ok(()) => Some(format!(
                    "leg `{}` drives again from where the robot is, {at}: {} m to `{}`",
                    leg.name,
                    geo::round_mm((geo::path_length(&path.points) * 10.0).round() / 10.0),
                    leg.to
                )),
                Err(err) => Some(format!(
                    "leg `{}` keeps its path: the net cannot go on with the new path: {err}",
                    leg.name
                )),
            }
        }
        Ok(Err(err)) => Some(format!(
            "leg `{}` keeps its planned path: there is no way from where the robot is, {at}, to \
             `{}`: {err}",
            leg.name, leg.to
        )),
        Err(why) => Some(format!("leg `{}` keeps its planned path: {why}", leg.name)),
    }
}

/// Whether two paths name the same file (as the system loads them).
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => a == b,
    }
}

/// The names of `new` not in `old`, and those of `old` not in `new`, each in its order.
fn difference<'a>(
    old: impl Iterator<Item = &'a str>,
    new: impl Iterator<Item = &'a str>,
) -> (Vec<String>, Vec<String>) {
    let old: Vec<&str> = old.collect();
    let new: Vec<&str> = new.collect();
    let old_set: BTreeSet<&str> = old.iter().copied().collect();
    let new_set: BTreeSet<&str> = new.iter().copied().collect();
    (
        new.iter()
            .filter(|name| !old_set.contains(*name))
            .map(|name| (*name).to_owned())
            .collect(),
        old.iter()
            .filter(|name| !new_set.contains(*name))
            .map(|name| (*name).to_owned())
            .collect(),
    )
}

fn listed(label: &str, names: &[String]) -> Option<String> {
    (!names.is_empty()).then(|| {
        format!(
            "{label}: {}",
            names
                .iter()
                .map(|name| format!("`{name}`"))
                .collect::<Vec<_>>()
                .join(", ")
        )
    })
}

/// The new plan's times judged against the run's clock (`now_unix_secs`) for the legs not done:
/// a deadline already passed makes its leg late at once, an appointment passed lets it leave at
/// once. The net's own transitions do so; this says it to the operator.
fn times(plan: &Plan, migration: &Migration, now_unix_secs: f64) -> Vec<String> {
    let clock = |unix_secs: f64| {
        let text = armor_model::net::format_rfc3339(unix_secs);
        text.get(11..19).map_or(text.clone(), str::to_owned)
    };
    let mut notes = Vec::new();
    for leg in &plan.legs[migration.index..] {
        if let Some(by) = leg.arrive_by_unix_secs
            && by <= now_unix_secs
        {
            notes.push(format!(
                "leg `{}` is due by {}, which has passed ({} now): it is late at once",
                leg.name,
                clock(by),
                clock(now_unix_secs)
            ));
        }
        let departed = leg.name == migration.leg && !migration.place_after.ends_with("_depart");
        if let Some(from) = leg.not_before_unix_secs
            && !departed
        {
            notes.push(if from <= now_unix_secs {
                format!(
                    "leg `{}`'s appointment, {}, has passed: it leaves as soon as it may",
                    leg.name,
                    clock(from)
                )
            } else {
                format!(
                    "leg `{}` leaves at {}, in {:.0} s",
                    leg.name,
                    clock(from),
                    from - now_unix_secs
                )
            });
        }
    }
    notes
}

/// What the supervisor needs to take an update.
pub struct Context<'a> {
    pub module_path: &'a [PathBuf],
    pub server: &'a ConfigServer,
    /// The date run time 0 stands for (the plan's start when rehearsed on its day).
    pub start_unix_secs: f64,
    pub run_secs: f64,
}

/// Takes a `checked` update (the controller swaps the nets, the progress line and the
/// rehearsal's judge follow the new legs and areas, `running` becomes the new plan) or refuses
/// it; either way it is numbered and recorded. The supervisor calls it once the module events
/// that came before it have been played on the running net, so that an event of the old leg
/// is never taken for one of the new. Returns whether it was taken and what to tell the
/// operator.
pub fn take(
    controller: &mut Controller,
    running: &mut Running,
    progress: Option<&mut Progress>,
    checked: Checked,
    context: &Context<'_>,
) -> (bool, String) {
    let file = checked.file.clone();
    let now = Now {
        robot_at: progress.as_ref().and_then(|progress| progress.robot_at()),
        unix_secs: context.start_unix_secs + context.run_secs,
    };
    let prepared = match prepare(
        running,
        checked,
        context.module_path,
        (controller.net(), &controller.marking()),
        now,
    ) {
        Ok(prepared) => prepared,
        Err(why) => return refuse(controller, &file, &why.0),
    };
    let Prepared {
        plan,
        compiled,
        net,
        migration,
        message,
        blocked,
    } = prepared;
    let details = json!({
        "legs_done": migration.done,
        "leg": migration.leg,
        "place_before": migration.place_before,
        "place_after": migration.place_after,
        "replaced": migration.changed,
        "blocked": blocked.is_some(),
    });
    let taken = crate::controller::Update {
        file: &file,
        message: &message,
        details,
        event: blocked,
    };
    match controller.update(
        net,
        &migration.marking,
        !migration.changed,
        taken,
        context.server,
    ) {
        Ok(number) => {
            if let Some(progress) = progress {
                progress.update(
                    progress::leg_plans(&plan, &compiled, context.start_unix_secs),
                    crate::rehearsal::areas(&compiled),
                );
            }
            running.plan = plan;
            running.compiled = compiled;
            (true, format!("update {number} taken: {message}"))
        }
        Err(why) => refuse(controller, &file, &why.0),
    }
}

/// Records an update refused (numbered) and says so.
pub fn refuse(controller: &mut Controller, file: &str, why: &str) -> (bool, String) {
    let number = controller.refuse_update(file, why);
    (false, format!("update {number} refused: {why}"))
}
