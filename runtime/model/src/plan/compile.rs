//! Plan → mission net. Deterministic: the same plan gives the same net, with names that say
//! where each place and transition came from (`LEG_drive`, `LEG_arrived`, `LEG_hold`, …).
//!
//! For a leg `L` from `A` to `B`, followed by the entry of the next leg (or the final place
//! `done`):
//!
//! ```text
//! L_depart ──L_appointment (at not_before)──▶ L_drive ──L_arrived (reached)──▶ L_arrival
//!   ──L_arrival_done (until) / L_arrival_timeout (for_secs)──▶ L_wait ──L_waited (wait_secs)──▶ next
//! L_drive ──L_blocked──▶ contingency     L_drive ──L_late (at arrive_by)──▶ contingency
//! ```
//!
//! Each part is there only when the plan asks for it. Contingencies: `skip` goes to the next
//! leg's entry; `hold` goes to `L_hold`, which the operator leaves with `L_retry` (drive again)
//! or `L_skip`; `return` drives to the waypoint in `L_return` and ends in the final place
//! `returned_W` (a blocked return holds in `L_return_hold` until the operator retries);
//! `continue` (late only) drives on in `L_drive_late`. Without a contingency a blocked robot
//! holds, a late one continues, and a failure is left to the runtime (the mission fails).
//! The modules of `throughout` run in every place, the final ones too.
//!
//! An action with alternatives has a place per way (`L_drive`, `L_drive_ALT`, …; `L_arrival`,
//! `L_arrival_ALT`; late drives alike), each with the action's exits. From each way, the
//! failure of a module that a later way answers (`module.M.failed`) fires `PLACE_M_failed` into
//! the first such way; a failure that no later way answers is the contingency's, as above.

use std::collections::{BTreeMap, BTreeSet};

use armor_module_api::ModuleDescription;
use armor_module_api::xml::{Located, Pos};

use super::memory::PathMemory;
use super::{Action, ActionModule, Leg, Plan, Response, Strategy, Trigger};
use crate::SystemConfig;
use crate::geo::{self, LatLon, Polygon};
use crate::net::{Arc, Condition, MissionNet, Place, PlaceParam, Transition, format_date};
use crate::planner::{
    self, Blocker, Costmap, CostmapSettings, End, Keepout, Path, PathError, Planner, Robot,
};
use crate::world::{Point, World, shape_origin};

/// How far the follower's own detours round no-go areas keep its centre from them, in metres
/// (it routes round them itself until it drives the planned path): the default area margin
/// plus the default robot radius.
pub const CLEARANCE_M: f64 = 1.0;

/// Origins of the world frame closer than this are the same.
const ORIGIN_TOLERANCE_M: f64 = 1.0;

/// A compiled plan.
#[derive(Clone, Debug)]
pub struct Compiled {
    pub net: MissionNet,
    /// The plan element each place and transition comes from.
    pub trace: BTreeMap<String, Origin>,
    /// Each leg's planned path in the world frame, from its start to its end.
    pub routes: Vec<Vec<Point>>,
    /// Each waypoint in the world frame.
    pub positions: BTreeMap<String, Point>,
    /// The robot the paths were planned for.
    pub robot: Robot,
    /// The no-go areas in the world frame, each with its margin, as the legs were planned round
    /// them (what a rehearsal's truth is judged against).
    pub keepouts: Vec<Keepout>,
    /// The geographic point of the world frame's (0, 0): what turns a point reported in the
    /// world frame (an area reported during a run) into the plan's latitude and longitude.
    pub origin: Option<LatLon>,
    /// What may keep the plan from going as drawn without stopping it: time constraints that
    /// cannot all be met, with the numbers.
    pub warnings: Vec<Located>,
    /// The places and transitions of the actions' alternative ways, and the switches to them
    /// (drawn apart in the studio's net view).
    pub alternatives: BTreeSet<String>,
    /// The switches to alternatives, by transition name (what a run's summary reports).
    pub switches: BTreeMap<String, Switch>,
}

/// A transition that switches a leg's action to one of its alternatives.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Switch {
    /// The leg's index.
    pub leg: usize,
    /// The alternative switched to.
    pub to: String,
    /// The module whose failure for good switches.
    pub module: String,
}

/// Where a net element comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// The leg at this index.
    Leg(usize),
    /// The end of a return to this waypoint.
    Waypoint(String),
    /// The end of the whole plan.
    Plan,
}

/// The robot a plan's legs are planned for: the radius its `<navigation>` gives, else the
/// largest `robot_radius_m` of the system's modules (the value the system file gives, else the
/// module's default from `descriptions`: the simulator's and the avoider's), else
/// [`planner::DEFAULT_ROBOT_RADIUS_M`]; the clearance its `<navigation>` gives, else
/// [`planner::DEFAULT_CLEARANCE_M`].
pub fn robot(
    plan: &Plan,
    system: Option<&SystemConfig>,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> Robot {
    robot_explained(plan, system, descriptions).0
}

/// [`robot`], and where its radius comes from in words (`module `avoider`'s default
/// robot_radius_m, the largest of the system's`), for the messages that depend on it.
pub fn robot_explained(
    plan: &Plan,
    system: Option<&SystemConfig>,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> (Robot, String) {
    let navigation = &plan.navigation;
    let clearance_m = navigation
        .clearance_m
        .unwrap_or(planner::DEFAULT_CLEARANCE_M);
    if let Some(radius_m) = navigation.robot_radius_m {
        return (
            Robot {
                radius_m,
                clearance_m,
            },
            "the plan's <navigation robot_radius_m>".to_owned(),
        );
    }
    // Every module's radius: (value, module, whether the system file gives it).
    let radii: Vec<(f64, &str, bool)> = system
        .map(|system| {
            system
                .modules
                .iter()
                .filter_map(|module| {
                    let (value, given) = match module.param("robot_radius_m") {
                        Some(param) => (param.value.clone(), true),
                        None => (
                            descriptions
                                .get(&module.module_type)?
                                .params
                                .iter()
                                .find(|param| param.name == "robot_radius_m")?
                                .default
                                .clone()?,
                            false,
                        ),
                    };
                    let radius = value
                        .trim()
                        .parse::<f64>()
                        .ok()
                        .filter(|radius| radius.is_finite() && *radius >= 0.0)?;
                    Some((radius, module.name.as_str(), given))
                })
                .collect()
        })
        .unwrap_or_default();
    // The first of the largest, in the system file's order.
    let largest = radii
        .iter()
        .copied()
        .fold(None, |best: Option<(f64, &str, bool)>, this| match best {
            Some(best) if best.0 >= this.0 => Some(best),
            _ => Some(this),
        });
    match largest {
        Some((radius_m, module, given)) => {
            let others: Vec<String> = radii
                .iter()
                .filter(|(radius, name, _)| *name != module && *radius < radius_m)
                .map(|(radius, name, _)| format!("`{name}` {} m", geo::round_mm(*radius)))
                .collect();
            let mut source = format!(
                "module `{module}`'s {}robot_radius_m, the largest of the system's modules",
                if given { "" } else { "default " }
            );
            if !others.is_empty() {
                source.push_str(&format!(" ({})", others.join(", ")));
            }
            source.push_str(
                "; give <navigation robot_radius_m> or set it on that module for another robot",
            );
            (
                Robot {
                    radius_m,
                    clearance_m,
                },
                source,
            )
        }
        None => (
            Robot {
                radius_m: planner::DEFAULT_ROBOT_RADIUS_M,
                clearance_m,
            },
            "the planner's default".to_owned(),
        ),
    }
}

/// Compiles `plan` drawn on `world` (when the robot runs in one; without, the plan's origin
/// defines the frame), for the robot the plan describes ([`robot`] with no system). Every
/// problem is reported, at the plan element it concerns.
pub fn compile(plan: &Plan, world: Option<&World>) -> Result<Compiled, Vec<Located>> {
    compile_for(plan, world, &robot(plan, None, &BTreeMap::new()))
}

/// [`compile`] for a given robot: every leg planned on the world for it.
pub fn compile_for(
    plan: &Plan,
    world: Option<&World>,
    robot: &Robot,
) -> Result<Compiled, Vec<Located>> {
    compile_with(plan, world, robot, &mut PathMemory::default())
}

/// [`compile_for`], the legs' paths planned before kept where they still hold (`memory`): a
/// run compiles its plan's updates so.
pub fn compile_with(
    plan: &Plan,
    world: Option<&World>,
    robot: &Robot,
    memory: &mut PathMemory,
) -> Result<Compiled, Vec<Located>> {
    let legs = plan_legs_with(plan, world, robot, memory);
    let mut problems = legs.problems;
    for contingency in plan
        .contingencies
        .iter()
        .chain(plan.legs.iter().flat_map(|leg| &leg.contingencies))
    {
        if contingency.response == Response::Continue
            && !matches!(
                contingency.trigger,
                Trigger::Late | Trigger::LinkLost { .. }
            )
        {
            problems.push(Located::new(
                contingency.pos,
                "`continue` is only for on=\"late\" and on=\"link_lost\"",
            ));
        }
    }
    for leg in &plan.legs {
        for (tag, action) in [("during", &leg.during), ("arrival", &leg.arrival)] {
            if let Some(action) = action {
                problems.extend(action.alternative_problems(tag));
            }
        }
    }
    let throughout: Vec<&str> = plan
        .throughout
        .iter()
        .flat_map(|action| &action.modules)
        .map(|module| module.name.as_str())
        .collect();
    for (module, pos) in action_modules(plan) {
        if module == plan.navigation.module || plan.navigation.companions.contains(&module) {
            problems.push(Located::new(
                pos,
                format!(
                    "module `{module}` drives every leg (<navigation>); an action cannot run it \
                     with other parameters"
                ),
            ));
        }
        if throughout.contains(&module.as_str()) {
            problems.push(Located::new(
                pos,
                format!(
                    "module `{module}` runs throughout the mission (<throughout>); an action \
                     cannot run it again"
                ),
            ));
        }
    }
    if let Some(action) = &plan.throughout {
        for module in &action.modules {
            if module.name == plan.navigation.module
                || plan.navigation.companions.contains(&module.name)
            {
                problems.push(Located::new(
                    module.pos,
                    format!(
                        "module `{}` drives the legs (<navigation>): it cannot also run \
                         throughout the mission",
                        module.name
                    ),
                ));
            }
        }
    }
    let paths: Vec<Path> = legs
        .paths
        .into_iter()
        .filter_map(|path| path.and_then(Result::ok))
        .collect();
    if !problems.is_empty() || paths.len() != plan.legs.len() {
        problems.sort_by_key(|problem| problem.pos);
        return Err(problems);
    }
    let routes: Vec<Vec<Point>> = paths.iter().map(|path| path.points.clone()).collect();
    let mut warnings = time_warnings(plan, &routes);
    warnings.extend(frame_warning(plan, world));
    let mut builder = Builder::new(plan, &legs.positions, &legs.keepouts, &paths, robot);
    builder.build();
    let Builder {
        net,
        trace,
        alternatives,
        switches,
        ..
    } = builder;
    Ok(Compiled {
        net,
        trace,
        routes,
        positions: legs.positions,
        robot: *robot,
        keepouts: legs.keepouts,
        origin: legs.origin,
        warnings,
        alternatives,
        switches,
    })
}

/// What the planner makes of a plan's legs on its world.
#[derive(Clone, Debug, Default)]
pub struct LegPaths {
    /// The waypoints the robot can be at, in the world frame.
    pub positions: BTreeMap<String, Point>,
    /// Each leg's path, or why there is none; `None` when one of its ends is not placed (a
    /// waypoint that is missing, outside the world, or where the robot cannot be: reported on
    /// its own).
    pub paths: Vec<Option<Result<Path, PathError>>>,
    /// What is wrong, at the plan elements it concerns: the frame, areas that cross
    /// themselves, waypoints where the robot cannot be, legs with no way through.
    pub problems: Vec<Located>,
    /// The no-go areas in the world frame, as the robot keeps out of them.
    pub keepouts: Vec<Keepout>,
    /// The geographic point of the world frame's (0, 0), when the plan has a frame.
    pub origin: Option<LatLon>,
}

/// Places the waypoints and plans every leg of `plan` on `world` (with no world, round the
/// no-go areas only) for `robot`, as [`compile`] does: the studio draws these paths.
pub fn plan_legs(plan: &Plan, world: Option<&World>, robot: &Robot) -> LegPaths {
    plan_legs_with(plan, world, robot, &mut PathMemory::default())
}

/// [`plan_legs`], the paths planned before kept where they still hold (`memory`).
pub fn plan_legs_with(
    plan: &Plan,
    world: Option<&World>,
    robot: &Robot,
    memory: &mut PathMemory,
) -> LegPaths {
    let mut problems = Vec::new();
    let origin = frame_origin(plan, world, &mut problems);
    let keepouts = keepouts(plan, origin, &mut problems);
    let mut positions = BTreeMap::new();
    if let Some(origin) = origin {
        for waypoint in &plan.waypoints {
            let point = waypoint.position.to_local(origin);
            match planner::blocker_at(world, robot, &keepouts, point) {
                None => {
                    positions.insert(waypoint.name.clone(), point);
                }
                Some(why) => problems.push(Located::new(
                    waypoint.pos,
                    waypoint_problem(&waypoint.name, point, &why, world, robot, &keepouts),
                )),
            }
        }
    }
    // The legs whose ends are both placed are planned; on a world, all on one costmap.
    let ends: Vec<Option<(Point, Point)>> = plan
        .legs
        .iter()
        .map(|leg| Some((*positions.get(&leg.from)?, *positions.get(&leg.to)?)))
        .collect();
    let pairs: Vec<(Point, Point)> = ends.iter().flatten().copied().collect();
    let mut planned = memory
        .plan_pairs(world, robot, &keepouts, &pairs)
        .unwrap_or_else(|err| {
            problems.push(Located::new(
                plan.pos,
                format!("the world cannot be mapped for planning: {err}"),
            ));
            Vec::new()
        });
    planned.reverse();
    let mut paths = Vec::with_capacity(plan.legs.len());
    for (leg, ends) in plan.legs.iter().zip(&ends) {
        let result = match ends {
            Some(_) => planned.pop(),
            None => None,
        };
        if let Some(Err(err)) = &result {
            problems.push(Located::new(
                leg.pos,
                leg_problem(leg, err, world.is_some(), robot, &keepouts),
            ));
        }
        paths.push(result);
    }
    LegPaths {
        positions,
        paths,
        problems,
        keepouts,
        origin,
    }
}

/// Plans the way between each pair of points for `robot` on `world` (all on one costmap), or
/// round the no-go areas only when there is no world: the paths a plan's legs get, in the order
/// of `pairs`.
pub fn plan_pairs(
    world: Option<&World>,
    robot: &Robot,
    keepouts: &[Keepout],
    pairs: &[(Point, Point)],
) -> Result<Vec<Result<Path, PathError>>, planner::CostmapError> {
    Ok(match world {
        Some(_) if pairs.is_empty() => Vec::new(),
        Some(world) => {
            let costmap = Costmap::for_world(world, robot, keepouts, &CostmapSettings::default())?;
            Planner::new(costmap).plan_many(pairs)
        }
        None => pairs
            .iter()
            .map(|&(from, to)| {
                if planner::clear_of_keepouts(robot, keepouts, from, to) {
                    Ok(Path::new(vec![from, to]))
                } else {
                    planner::plan_path(None, robot, keepouts, from, to)
                }
            })
            .collect(),
    })
}

/// What the robot keeps from things, in words: `0.35 m from obstacles and 1 m from the no-go
/// areas`.
fn keeps(with_world: bool, robot: &Robot, keepouts: &[Keepout]) -> String {
    let mut parts = Vec::new();
    if with_world {
        parts.push(format!(
            "{} m from obstacles",
            geo::round_mm(robot.keep_m())
        ));
    }
    if let Some(first) = keepouts.first() {
        let keep = first.keep_m(robot);
        if keepouts.iter().all(|keepout| keepout.keep_m(robot) == keep) {
            parts.push(format!("{} m from the no-go areas", geo::round_mm(keep)));
        } else {
            parts.push("each no-go area's margin from it".to_owned());
        }
    }
    if parts.is_empty() {
        parts.push(format!(
            "{} m from obstacles",
            geo::round_mm(robot.keep_m())
        ));
    }
    parts.join(" and ")
}

fn leg_problem(
    leg: &Leg,
    err: &PathError,
    with_world: bool,
    robot: &Robot,
    keepouts: &[Keepout],
) -> String {
    match err {
        PathError::Cut(bottleneck) => format!(
            "leg `{}`: no way from `{}` to `{}` keeps {}; {bottleneck}",
            leg.name,
            leg.from,
            leg.to,
            keeps(with_world, robot, keepouts)
        ),
        PathError::Blocked { end, why, .. } => {
            let waypoint = match end {
                End::Start => &leg.from,
                End::Goal => &leg.to,
            };
            format!("leg `{}`: waypoint `{waypoint}` {why}", leg.name)
        }
    }
}

/// Why the robot cannot be at a waypoint, in the words of a plan's check.
fn waypoint_problem(
    name: &str,
    point: Point,
    why: &Blocker,
    world: Option<&World>,
    robot: &Robot,
    keepouts: &[Keepout],
) -> String {
    let world_name = world.map_or("", World::name);
    let mm = geo::round_mm;
    let robot_is = |keep: f64, extra: &str, extra_m: f64| {
        format!(
            "the robot keeps {} m from {} (radius {} m and {extra} {} m)",
            mm(keep),
            if extra == "clearance" {
                "obstacles".to_owned()
            } else {
                "it".to_owned()
            },
            mm(robot.radius_m),
            mm(extra_m)
        )
    };
    match why {
        Blocker::OutsideWorld => {
            let (min_x, max_x, min_y, max_y) = world.map_or((0.0, 0.0, 0.0, 0.0), |world| {
                let bounds = world.bounds();
                (bounds.min_x, bounds.max_x, bounds.min_y, bounds.max_y)
            });
            format!(
                "waypoint `{name}` is outside the world `{world_name}`: it is at {point} m, the \
                 world spans {} to {} m east and {} to {} m north",
                mm(min_x),
                mm(max_x),
                mm(min_y),
                mm(max_y)
            )
        }
        Blocker::InObstacle { line } => format!(
            "waypoint `{name}` at {point} m is inside the obstacle{} of the world `{world_name}`",
            shape_origin(*line)
        ),
        Blocker::NearObstacle {
            kind,
            line,
            distance_m,
            keep_m,
        } => format!(
            "waypoint `{name}` at {point} m {} the {kind}{} of the world `{world_name}`; {}",
            geo::is_from(*distance_m),
            shape_origin(*line),
            robot_is(*keep_m, "clearance", robot.clearance_m)
        ),
        Blocker::InArea { name: area } => {
            format!("waypoint `{name}` at {point} m is in the no-go area `{area}`")
        }
        Blocker::NearArea {
            name: area,
            distance_m,
            keep_m,
        } => {
            let margin = keepouts
                .iter()
                .find(|keepout| &keepout.name == area)
                .map_or(0.0, |keepout| keepout.margin_m);
            format!(
                "waypoint `{name}` at {point} m {} the no-go area `{area}`; {}",
                geo::is_from(*distance_m),
                robot_is(*keep_m, "margin", margin)
            )
        }
        Blocker::NoRoom => format!("waypoint `{name}` at {point} m {why}"),
    }
}

/// The geographic origin of the world frame: the world's, which the plan's must match.
/// The point of latitude and longitude the plan's world frame is measured from: its world's
/// origin, else its own `<origin>` (what is wrong with them is said by [`plan_legs`]).
pub fn plan_origin(plan: &Plan, world: Option<&World>) -> Option<LatLon> {
    frame_origin(plan, world, &mut Vec::new())
}

fn frame_origin(plan: &Plan, world: Option<&World>, problems: &mut Vec<Located>) -> Option<LatLon> {
    let world_origin = world.map(|world| {
        let (lat, lon) = world.origin_lat_lon();
        LatLon::new(lat, lon)
    });
    match (world_origin, plan.origin) {
        (Some(world_origin), Some(origin)) => {
            let offset = origin.to_local(world_origin);
            if offset.x.hypot(offset.y) > ORIGIN_TOLERANCE_M {
                problems.push(Located::new(
                    plan.pos,
                    format!(
                        "the plan's <origin> is {:.1} m from the origin of its world ({}, {}); \
                         remove it or make them agree",
                        offset.x.hypot(offset.y),
                        world_origin.lat_deg,
                        world_origin.lon_deg
                    ),
                ));
            }
            Some(world_origin)
        }
        (Some(origin), None) | (None, Some(origin)) => Some(origin),
        (None, None) => {
            problems.push(Located::new(
                plan.pos,
                "the plan has no world and no <origin>: give one of them so that its \
                 coordinates can be placed",
            ));
            None
        }
    }
}

/// How far the flat frame may be off a waypoint's true distance from its origin before a check
/// says so: the legs are planned and timed in that frame.
const FRAME_ERROR_LIMIT_M: f64 = 1.0;

/// The waypoint where the plan's flat frame (an equirectangular projection round its origin,
/// accurate to centimetres over a few kilometres) is furthest off the true distance from the
/// origin, when that is more than [`FRAME_ERROR_LIMIT_M`]: a plan drawn over hundreds of
/// kilometres is planned and timed on distorted distances.
fn frame_warning(plan: &Plan, world: Option<&World>) -> Option<Located> {
    let origin = match world {
        Some(world) => {
            let (lat, lon) = world.origin_lat_lon();
            LatLon::new(lat, lon)
        }
        None => plan.origin?,
    };
    let (worst, error_m, true_m) = plan
        .waypoints
        .iter()
        .map(|waypoint| {
            let local = waypoint.position.to_local(origin);
            let true_m = origin.great_circle_m(waypoint.position);
            (waypoint, (local.x.hypot(local.y) - true_m).abs(), true_m)
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    (error_m > FRAME_ERROR_LIMIT_M).then(|| {
        Located::new(
            worst.pos,
            format!(
                "waypoint `{}` is {:.1} km from the origin of the plan's frame, where its flat \
                 (local) projection is {:.0} m off the true distance: distances and times are \
                 only right within a few kilometres of the origin; split the plan, or give it \
                 an origin near its waypoints",
                worst.name,
                true_m / 1000.0,
                error_m
            ),
        )
    })
}

/// The no-go areas in the world frame, each with its margin.
fn keepouts(plan: &Plan, origin: Option<LatLon>, problems: &mut Vec<Located>) -> Vec<Keepout> {
    let Some(origin) = origin else {
        return Vec::new();
    };
    let mut keepouts = Vec::new();
    for area in plan.no_go_areas() {
        let polygon = Polygon::new(area.points.iter().map(|p| p.to_local(origin)).collect());
        if polygon.corners.len() < 3 {
            continue;
        }
        if polygon.crosses_itself() {
            problems.push(Located::new(
                area.pos,
                format!(
                    "area `{}`: its outline crosses itself, so it has no clear inside",
                    area.name
                ),
            ));
            continue;
        }
        keepouts.push(Keepout::new(
            area.name.clone(),
            polygon,
            area.margin_m.unwrap_or(planner::DEFAULT_AREA_MARGIN_M),
        ));
    }
    keepouts
}

/// The modules of the legs' actions and of their alternatives.
fn action_modules(plan: &Plan) -> Vec<(String, Pos)> {
    plan.legs
        .iter()
        .flat_map(|leg| leg.during.iter().chain(&leg.arrival))
        .flat_map(|action| {
            action.modules.iter().chain(
                action
                    .alternatives
                    .iter()
                    .flat_map(|alternative| &alternative.modules),
            )
        })
        .map(|module| (module.name.clone(), module.pos))
        .collect()
}

/// The earliest times the legs can start and end, against their appointments and deadlines.
fn time_warnings(plan: &Plan, routes: &[Vec<Point>]) -> Vec<Located> {
    let speed = plan.navigation.speed_mps;
    let mut warnings = Vec::new();
    // The earliest moment the robot can be at the start of the current leg, and since when
    // that is counted: (anchor date, metres and seconds of waiting since it).
    let mut anchor: Option<(f64, f64, f64)> = plan.start_unix_secs.map(|start| (start, 0.0, 0.0));
    // Whole seconds: the estimate is no finer, and the dates read better.
    let earliest = |anchor: (f64, f64, f64)| (anchor.0 + anchor.1 / speed + anchor.2).round();
    let explain = |anchor: (f64, f64, f64)| {
        format!(
            "{} m at {speed} m/s{} from {}",
            geo::round_mm((anchor.1 * 10.0).round() / 10.0),
            if anchor.2 > 0.0 {
                format!(" and {} s of waiting", anchor.2)
            } else {
                String::new()
            },
            format_date(anchor.0)
        )
    };
    for (leg, route) in plan.legs.iter().zip(routes) {
        if let Some(not_before) = leg.not_before_unix_secs {
            match anchor {
                Some(at) if earliest(at) > not_before + 0.5 => warnings.push(Located::new(
                    leg.pos,
                    format!(
                        "leg `{}`: the appointment to leave `{}` at {} is {:.0} s before the \
                         earliest possible arrival there ({}: {})",
                        leg.name,
                        leg.from,
                        format_date(not_before),
                        earliest(at) - not_before,
                        format_date(earliest(at)),
                        explain(at)
                    ),
                )),
                _ => anchor = Some((not_before, 0.0, 0.0)),
            }
        }
        let length = geo::path_length(route);
        anchor = anchor.map(|(at, metres, waits)| (at, metres + length, waits));
        if let (Some(deadline), Some(at)) = (leg.arrive_by_unix_secs, anchor)
            && earliest(at) > deadline + 0.5
        {
            warnings.push(Located::new(
                leg.pos,
                format!(
                    "leg `{}`: the deadline to reach `{}` at {} is {:.0} s before the earliest \
                     possible arrival ({}: {})",
                    leg.name,
                    leg.to,
                    format_date(deadline),
                    earliest(at) - deadline,
                    format_date(earliest(at)),
                    explain(at)
                ),
            ));
        }
        let waits = leg.wait_secs.unwrap_or(0.0);
        anchor = anchor.map(|(at, metres, waited)| (at, metres, waited + waits));
    }
    warnings
}

/// Builds the net leg by leg.
struct Builder<'a> {
    plan: &'a Plan,
    positions: &'a BTreeMap<String, Point>,
    /// Each leg's planned path.
    paths: &'a [Path],
    no_go: String,
    /// The areas' margins, `;` between them; empty when all are the default.
    no_go_margins: String,
    /// The robot the paths were planned for.
    robot: Robot,
    net: MissionNet,
    /// Also the names made so far (the net's own lookup is a linear search).
    trace: BTreeMap<String, Origin>,
    /// The modules whose failure some contingency handles.
    failure_modules: Vec<String>,
    /// The places and transitions that only an alternative way of an action has, and the
    /// switches to them.
    alternatives: BTreeSet<String>,
    /// (place, module): the failure of the module in the place switches to an alternative.
    switched: BTreeSet<(String, String)>,
    switches: BTreeMap<String, Switch>,
}

impl<'a> Builder<'a> {
    fn new(
        plan: &'a Plan,
        positions: &'a BTreeMap<String, Point>,
        keepouts: &[Keepout],
        paths: &'a [Path],
        robot: &Robot,
    ) -> Self {
        let polygons: Vec<Polygon> = keepouts
            .iter()
            .map(|keepout| keepout.polygon.clone())
            .collect();
        Self {
            plan,
            positions,
            paths,
            no_go: geo::format_polygons(&polygons),
            robot: *robot,
            no_go_margins: if keepouts
                .iter()
                .all(|keepout| keepout.margin_m == planner::DEFAULT_AREA_MARGIN_M)
            {
                String::new()
            } else {
                keepouts
                    .iter()
                    .map(|keepout| geo::round_mm(keepout.margin_m))
                    .collect::<Vec<_>>()
                    .join(";")
            },
            net: MissionNet {
                name: plan.name.clone(),
                system: plan.system.clone(),
                pos: plan.pos,
                ..MissionNet::default()
            },
            trace: BTreeMap::new(),
            failure_modules: plan.failure_modules(),
            alternatives: BTreeSet::new(),
            switched: BTreeSet::new(),
            switches: BTreeMap::new(),
        }
    }

    /// The place a leg starts in (or `done` after the last).
    fn entry(&self, index: usize) -> String {
        match self.plan.legs.get(index) {
            None => "done".into(),
            Some(leg) if leg.not_before_unix_secs.is_some() => format!("{}_depart", leg.name),
            Some(leg) => format!("{}_drive", leg.name),
        }
    }

    fn build(&mut self) {
        let plan = self.plan;
        for (index, leg) in plan.legs.iter().enumerate() {
            self.leg(index, leg);
        }
        self.place("done", Origin::Plan, plan.pos, Vec::new(), Vec::new());
        if let Some(done) = self.net.places.last_mut() {
            done.is_final = true;
        }
        let first = self.entry(0);
        if let Some(place) = self.net.places.iter_mut().find(|place| place.name == first) {
            place.tokens = 1;
        }
    }

    fn leg(&mut self, index: usize, leg: &Leg) {
        let name = &leg.name;
        let origin = || Origin::Leg(index);
        let next = self.entry(index + 1);
        // Which place follows the arrival, then the wait.
        let after_wait = next.clone();
        let after_arrival = if leg.wait_secs.is_some() {
            format!("{name}_wait")
        } else {
            after_wait.clone()
        };
        let after_drive = if leg.arrival.is_some() {
            format!("{name}_arrival")
        } else {
            after_arrival.clone()
        };
        let drive = format!("{name}_drive");
        let mut leg_places = Vec::new();
        if let Some(not_before) = leg.not_before_unix_secs {
            let depart = format!("{name}_depart");
            self.place(&depart, origin(), leg.pos, Vec::new(), Vec::new());
            self.transition(
                &format!("{name}_appointment"),
                origin(),
                leg.pos,
                Condition {
                    at_unix_secs: Some(not_before),
                    ..Condition::default()
                },
                &depart,
                &drive,
            );
            leg_places.push(depart);
        }
        let path = self.paths.get(index);
        // Each way of driving the leg (the action beside the drive and its alternatives), each
        // in a place of its own: `L_drive`, then `L_drive_ALT`.
        let during = leg.during.clone().unwrap_or_default();
        let ways = during.strategies();
        let mut drives = Vec::with_capacity(ways.len());
        for way in &ways {
            let suffix = way_suffix(way.name);
            let place = format!("{drive}{suffix}");
            let (modules, params) = self.drive_action(&leg.to, way.modules, leg.pos, path);
            self.place(&place, origin(), leg.pos, modules, params);
            self.drive_exits(index, leg, &place, &suffix, &after_drive);
            self.mark_alternative(way.name, &place);
            self.mark_alternative(way.name, &format!("{name}_arrived{suffix}"));
            self.mark_alternative(way.name, &format!("{name}_blocked{suffix}"));
            leg_places.push(place.clone());
            drives.push(place);
        }
        self.switches(index, &drives, &ways);
        if let Some(deadline) = leg.arrive_by_unix_secs {
            let late = Condition {
                at_unix_secs: Some(deadline),
                ..Condition::default()
            };
            let response = self.response(leg, &Trigger::Late);
            let mut lates = Vec::with_capacity(ways.len());
            for (way, drive) in ways.iter().zip(&drives) {
                let suffix = way_suffix(way.name);
                let target = match &response {
                    Some(Response::Continue) | None => {
                        // Late, the robot drives on the same way.
                        let drive_late = format!("{name}_drive_late{suffix}");
                        let (modules, params) =
                            self.drive_action(&leg.to, way.modules, leg.pos, path);
                        self.place(&drive_late, origin(), leg.pos, modules, params);
                        self.drive_exits(
                            index,
                            leg,
                            &drive_late,
                            &format!("_late{suffix}"),
                            &after_drive,
                        );
                        self.mark_alternative(way.name, &drive_late);
                        self.mark_alternative(way.name, &format!("{name}_arrived_late{suffix}"));
                        self.mark_alternative(way.name, &format!("{name}_blocked_late{suffix}"));
                        leg_places.push(drive_late.clone());
                        lates.push(drive_late.clone());
                        drive_late
                    }
                    Some(response) => self.respond(index, leg, response),
                };
                let transition = format!("{name}_late{suffix}");
                self.transition(&transition, origin(), leg.pos, late.clone(), drive, &target);
                self.mark_alternative(way.name, &transition);
            }
            if lates.len() == ways.len() {
                self.switches(index, &lates, &ways);
            }
        }
        if let Some(arrival) = &leg.arrival {
            let ways = arrival.strategies();
            let mut places = Vec::with_capacity(ways.len());
            for way in &ways {
                let suffix = way_suffix(way.name);
                let place = format!("{name}_arrival{suffix}");
                let (modules, params) = modules_and_params(way.modules);
                self.place(&place, origin(), arrival.pos, modules, params);
                let until = arrival.until.clone();
                let mut done = Condition {
                    event: until.clone(),
                    ..Condition::default()
                };
                if until.is_none() {
                    done.delay_secs = arrival.for_secs;
                }
                let transition = format!("{name}_arrival_done{suffix}");
                self.transition(
                    &transition,
                    origin(),
                    arrival.pos,
                    done,
                    &place,
                    &after_arrival,
                );
                self.mark_alternative(way.name, &transition);
                if let (Some(_), Some(secs)) = (&until, arrival.for_secs) {
                    let transition = format!("{name}_arrival_timeout{suffix}");
                    self.transition(
                        &transition,
                        origin(),
                        arrival.pos,
                        Condition {
                            delay_secs: Some(secs),
                            ..Condition::default()
                        },
                        &place,
                        &after_arrival,
                    );
                    self.mark_alternative(way.name, &transition);
                }
                self.mark_alternative(way.name, &place);
                leg_places.push(place.clone());
                places.push(place);
            }
            self.switches(index, &places, &ways);
        }
        if let Some(wait) = leg.wait_secs {
            let place = format!("{name}_wait");
            self.place(&place, origin(), leg.pos, Vec::new(), Vec::new());
            self.transition(
                &format!("{name}_waited"),
                origin(),
                leg.pos,
                Condition {
                    delay_secs: Some(wait),
                    ..Condition::default()
                },
                &place,
                &after_wait,
            );
            leg_places.push(place);
        }
        // The battery is reported low once, and an event counts only for the transitions
        // enabled when it comes: so it is listened to wherever the robot may be in the leg (the
        // drives listen already), waiting for an appointment, acting on arrival, waiting there
        // or holding for the operator.
        for place in &leg_places {
            if !drives.contains(place) && !place.starts_with(&format!("{name}_drive_late")) {
                self.low_battery(index, leg, place, &format!("{place}_low_battery"));
                self.link_lost(index, leg, place, &format!("{place}_link_lost"));
            }
        }
        for module in self.failure_modules.clone() {
            let trigger = Trigger::Failed {
                module: module.clone(),
            };
            let Some(response) = self.response(leg, &trigger) else {
                continue;
            };
            let target = self.respond(index, leg, &response);
            for place in &leg_places {
                // In a way that has an alternative for this failure, the alternative answers it;
                // the contingency, only once they are all spent.
                if self.switched.contains(&(place.clone(), module.clone())) {
                    continue;
                }
                self.transition(
                    &format!("{place}_{module}_failed"),
                    origin(),
                    leg.pos,
                    Condition {
                        event: Some(format!("module.{module}.failed")),
                        ..Condition::default()
                    },
                    place,
                    &target,
                );
            }
        }
        let hold = format!("{name}_hold");
        if self.trace.contains_key(&hold) {
            self.low_battery(index, leg, &hold, &format!("{hold}_low_battery"));
            self.link_lost(index, leg, &hold, &format!("{hold}_link_lost"));
        }
    }

    /// The switches between the ways of doing a part of a leg, `places[k]` doing `ways[k]`:
    /// from each way, the failure for good of a module that a later way answers leads to the
    /// first such way (`PLACE_MODULE_failed`). A failure that no later way answers is left to
    /// the contingencies.
    fn switches(&mut self, index: usize, places: &[String], ways: &[Strategy<'_>]) {
        for (from, place) in places.iter().enumerate() {
            let mut answered: Vec<&str> = Vec::new();
            for (to, way) in ways.iter().enumerate().skip(from + 1) {
                for module in &way.answers {
                    if answered.contains(&module.as_str()) {
                        continue;
                    }
                    answered.push(module);
                    let transition = format!("{place}_{module}_failed");
                    self.transition(
                        &transition,
                        Origin::Leg(index),
                        way.pos,
                        Condition {
                            event: Some(format!("module.{module}.failed")),
                            ..Condition::default()
                        },
                        place,
                        &places[to],
                    );
                    self.switches.insert(
                        transition.clone(),
                        Switch {
                            leg: index,
                            to: way.name.unwrap_or_default().to_owned(),
                            module: module.clone(),
                        },
                    );
                    self.alternatives.insert(transition);
                    self.switched.insert((place.clone(), module.clone()));
                }
            }
        }
    }

    /// Notes a net element that only an alternative's way (`way`, its name) has.
    fn mark_alternative(&mut self, way: Option<&str>, element: &str) {
        if way.is_some() {
            self.alternatives.insert(element.to_owned());
        }
    }

    /// The arrival and blocked transitions of a drive place (`suffix` tells the late one apart).
    fn drive_exits(&mut self, index: usize, leg: &Leg, drive: &str, suffix: &str, after: &str) {
        let nav = &self.plan.navigation;
        let name = &leg.name;
        self.transition(
            &format!("{name}_arrived{suffix}"),
            Origin::Leg(index),
            leg.pos,
            Condition {
                event: Some(format!("{}.{}", nav.module, nav.reached_event)),
                ..Condition::default()
            },
            drive,
            after,
        );
        let response = self
            .response(leg, &Trigger::Blocked)
            .unwrap_or(Response::Hold);
        let target = self.respond(index, leg, &response);
        self.transition(
            &format!("{name}_blocked{suffix}"),
            Origin::Leg(index),
            leg.pos,
            Condition {
                event: Some(format!("{}.{}", nav.module, nav.blocked_event)),
                ..Condition::default()
            },
            drive,
            &target,
        );
        // A robot that does not know where it is stops driving, when the plan says which
        // localiser to listen to.
        let lost = self
            .plan
            .contingency_on(leg, |trigger| matches!(trigger, Trigger::Lost { .. }))
            .cloned();
        if let Some(contingency) = lost
            && let Trigger::Lost { module } = &contingency.trigger
        {
            let target = self.respond(index, leg, &contingency.response);
            self.transition(
                &format!("{name}_lost{suffix}"),
                Origin::Leg(index),
                contingency.pos,
                Condition {
                    event: Some(format!("{module}.lost")),
                    ..Condition::default()
                },
                drive,
                &target,
            );
        }
        self.low_battery(
            index,
            leg,
            drive,
            &format!("{}_low_battery{suffix}", leg.name),
        );
        self.link_lost(
            index,
            leg,
            drive,
            &format!("{}_link_lost{suffix}", leg.name),
        );
    }

    /// The transition named `name` out of `place` once the robot has not heard its operator
    /// for the contingency's time (the run's `link.lost.SECS`, reported once per outage), when
    /// the plan answers it with something else than going on (and `place` is not where the
    /// answer leads).
    fn link_lost(&mut self, index: usize, leg: &Leg, place: &str, name: &str) {
        let lost = self
            .plan
            .contingency_on(leg, |trigger| matches!(trigger, Trigger::LinkLost { .. }))
            .cloned();
        if let Some(contingency) = lost
            && let Trigger::LinkLost { after_secs } = contingency.trigger
            && contingency.response != Response::Continue
        {
            let event = crate::net::link_lost_event(after_secs);
            self.answer_event(index, leg, place, name, &contingency, event);
        }
    }

    /// The transition named `name` out of `place` on `event`, to where `contingency`'s
    /// response leads (none when `place` is where it leads: an answer does not listen to what
    /// it answers).
    fn answer_event(
        &mut self,
        index: usize,
        leg: &Leg,
        place: &str,
        name: &str,
        contingency: &super::Contingency,
        event: String,
    ) {
        let target = self.respond(index, leg, &contingency.response);
        if target == place {
            return;
        }
        self.transition(
            name,
            Origin::Leg(index),
            contingency.pos,
            Condition {
                event: Some(event),
                ..Condition::default()
            },
            place,
            &target,
        );
    }

    /// The transition named `name` out of `place` on a low battery, when the plan listens for
    /// one (and `place` is not where the answer leads).
    fn low_battery(&mut self, index: usize, leg: &Leg, place: &str, name: &str) {
        let low = self
            .plan
            .contingency_on(leg, |trigger| matches!(trigger, Trigger::LowBattery { .. }))
            .cloned();
        if let Some(contingency) = low
            && let Trigger::LowBattery { module } = &contingency.trigger
        {
            let event = format!("{module}.low_battery");
            self.answer_event(index, leg, place, name, &contingency, event);
        }
    }

    fn response(&self, leg: &Leg, trigger: &Trigger) -> Option<Response> {
        self.plan
            .contingency(leg, trigger)
            .map(|contingency| contingency.response.clone())
    }

    /// The place a response leads to, made on first use.
    fn respond(&mut self, index: usize, leg: &Leg, response: &Response) -> String {
        let name = &leg.name;
        let origin = || Origin::Leg(index);
        match response {
            Response::Skip | Response::Continue => self.entry(index + 1),
            // A repair holds as a hold does: the run applies the repair's default from there.
            Response::Hold | Response::Repair { .. } => {
                let hold = format!("{name}_hold");
                if !self.trace.contains_key(&hold) {
                    self.place(&hold, origin(), leg.pos, Vec::new(), Vec::new());
                    let operator = Condition {
                        operator: true,
                        ..Condition::default()
                    };
                    let drive = format!("{name}_drive");
                    let next = self.entry(index + 1);
                    self.transition(
                        &format!("{name}_retry"),
                        origin(),
                        leg.pos,
                        operator.clone(),
                        &hold,
                        &drive,
                    );
                    self.transition(
                        &format!("{name}_skip"),
                        origin(),
                        leg.pos,
                        operator,
                        &hold,
                        &next,
                    );
                }
                hold
            }
            Response::Return { waypoint } => {
                let drive = format!("{name}_return");
                if !self.trace.contains_key(&drive) {
                    // Where the robot will be when it turns back is not known: no path.
                    let (modules, params) = self.drive_action(waypoint, &[], leg.pos, None);
                    self.place(&drive, origin(), leg.pos, modules, params);
                    let end = format!("returned_{waypoint}");
                    if !self.trace.contains_key(&end) {
                        self.place(
                            &end,
                            Origin::Waypoint(waypoint.clone()),
                            leg.pos,
                            Vec::new(),
                            Vec::new(),
                        );
                        if let Some(place) = self.net.places.last_mut() {
                            place.is_final = true;
                        }
                    }
                    let nav = &self.plan.navigation;
                    let reached = format!("{}.{}", nav.module, nav.reached_event);
                    let blocked = format!("{}.{}", nav.module, nav.blocked_event);
                    self.transition(
                        &format!("{name}_returned"),
                        origin(),
                        leg.pos,
                        Condition {
                            event: Some(reached),
                            ..Condition::default()
                        },
                        &drive,
                        &end,
                    );
                    let hold = format!("{name}_return_hold");
                    self.place(&hold, origin(), leg.pos, Vec::new(), Vec::new());
                    self.transition(
                        &format!("{name}_return_blocked"),
                        origin(),
                        leg.pos,
                        Condition {
                            event: Some(blocked),
                            ..Condition::default()
                        },
                        &drive,
                        &hold,
                    );
                    self.transition(
                        &format!("{name}_return_retry"),
                        origin(),
                        leg.pos,
                        Condition {
                            operator: true,
                            ..Condition::default()
                        },
                        &hold,
                        &drive,
                    );
                }
                drive
            }
        }
    }

    /// The modules and parameters of a drive to `waypoint` (along `path`, when it is known),
    /// with an action beside it.
    fn drive_action(
        &self,
        waypoint: &str,
        beside: &[ActionModule],
        pos: Pos,
        path: Option<&Path>,
    ) -> (Vec<String>, Vec<PlaceParam>) {
        let nav = &self.plan.navigation;
        let mut modules = vec![nav.module.clone()];
        modules.extend(nav.companions.iter().cloned());
        let goal = self.positions.get(waypoint).copied().unwrap_or_default();
        let param = |name: &str, value: String| PlaceParam {
            module: nav.module.clone(),
            name: name.to_owned(),
            value,
            pos,
        };
        let mut params = vec![
            param(&nav.goal_x_param, geo::round_mm(goal.x)),
            param(&nav.goal_y_param, geo::round_mm(goal.y)),
        ];
        if !self.no_go.is_empty() {
            params.push(param(&nav.no_go_param, self.no_go.clone()));
        }
        // The follower replans round what its laser sees on the way: with the margins the
        // plan was checked with, not a default.
        if !self.no_go_margins.is_empty() && !nav.no_go_margins_param.is_empty() {
            params.push(param(&nav.no_go_margins_param, self.no_go_margins.clone()));
        }
        // And for the robot the paths were planned for (the navigation module's defaults are
        // the planner's).
        if self.robot.radius_m != planner::DEFAULT_ROBOT_RADIUS_M
            && !nav.robot_radius_param.is_empty()
        {
            params.push(param(
                &nav.robot_radius_param,
                geo::round_mm(self.robot.radius_m),
            ));
        }
        if self.robot.clearance_m != planner::DEFAULT_CLEARANCE_M && !nav.clearance_param.is_empty()
        {
            params.push(param(
                &nav.clearance_param,
                geo::round_mm(self.robot.clearance_m),
            ));
        }
        if let Some(path) = path
            && !nav.path_param.is_empty()
        {
            params.push(param(&nav.path_param, path.format()));
        }
        let (more_modules, more_params) = modules_and_params(beside);
        modules.extend(more_modules);
        params.extend(more_params);
        (modules, params)
    }

    fn place(
        &mut self,
        name: &str,
        origin: Origin,
        pos: Pos,
        mut modules: Vec<String>,
        mut params: Vec<PlaceParam>,
    ) {
        if let Some(action) = &self.plan.throughout {
            let (more_modules, more_params) = action_parts(action);
            modules.extend(more_modules);
            params.extend(more_params);
        }
        self.trace.insert(name.to_owned(), origin);
        self.net.places.push(Place {
            name: name.to_owned(),
            modules,
            params,
            tokens: 0,
            is_final: false,
            pos,
        });
    }

    fn transition(
        &mut self,
        name: &str,
        origin: Origin,
        pos: Pos,
        condition: Condition,
        from: &str,
        to: &str,
    ) {
        self.trace.insert(name.to_owned(), origin);
        let arc = |place: &str| Arc {
            place: place.to_owned(),
            weight: 1,
            pos,
        };
        self.net.transitions.push(Transition {
            name: name.to_owned(),
            priority: 0,
            condition,
            inputs: vec![arc(from)],
            outputs: vec![arc(to)],
            pos,
        });
    }
}

fn action_parts(action: &Action) -> (Vec<String>, Vec<PlaceParam>) {
    modules_and_params(&action.modules)
}

fn modules_and_params(modules: &[ActionModule]) -> (Vec<String>, Vec<PlaceParam>) {
    let names = modules.iter().map(|m| m.name.clone()).collect();
    let params = modules
        .iter()
        .flat_map(|module| {
            module.params.iter().map(|param| PlaceParam {
                module: module.name.clone(),
                name: param.name.clone(),
                value: param.value.clone(),
                pos: param.pos,
            })
        })
        .collect();
    (names, params)
}

/// What the places of a way are named with after the action's own: `_ALT`, or nothing.
fn way_suffix(name: Option<&str>) -> String {
    name.map_or_else(String::new, |name| format!("_{name}"))
}

#[cfg(test)]
mod tests;
