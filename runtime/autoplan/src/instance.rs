//! From a plan's `<objectives>` on its world to a [`Problem`]: every place placed as `armor
//! check` places waypoints, the way between every two planned on one costmap (the paths the
//! plan's legs would get), and every time and distance rounded to the solver's integers.

use armor_model::geo::{LatLon, Point, Polygon};
use armor_model::plan::objectives::{Objectives, Place};
use armor_model::plan::{self, Plan, Waypoint};
use armor_model::planner::{self, Costmap, CostmapSettings, Keepout, PathError, Planner, Robot};
use armor_model::world::World;
use armor_module_api::xml::Located;

use crate::{Problem, Task};

/// A problem with what is needed to read its answers in the operator's words.
#[derive(Clone, Debug)]
pub struct Instance {
    pub problem: Problem,
    /// The plan's objectives, in the order of the problem's tasks.
    pub objectives: Objectives,
    /// The waypoint each node is at: the start, each task's, the end's (`None`: the robot ends
    /// wherever its last task is).
    pub start: String,
    pub end: Option<String>,
    /// Where each node is in the world frame (start, tasks, end).
    pub points: Vec<Point>,
    /// The way between every two nodes (`[from][to]`), in metres; `None`: none.
    pub length_m: Vec<Vec<Option<f64>>>,
    /// Why there is no way, where there is none (`[from][to]`).
    pub cut: Vec<Vec<Option<String>>>,
    /// The plan's start (Unix seconds): the problem's time 0.
    pub start_unix_secs: Option<f64>,
    pub speed_mps: f64,
    /// The fastest the robot may drive (its modules' least `max_speed_mps`), at least
    /// `speed_mps`: a leg that waits for a window leaves as late as this speed allows, so that
    /// the robot never arrives before the window opens (driving slower, it arrives later than
    /// planned). The planner's own times are at `speed_mps`.
    pub fastest_mps: f64,
    /// How near its destination the navigation reports a leg arrived (the follower's
    /// `tolerance_m`): a leg that waits for a window leaves late enough for that too.
    pub arrival_tolerance_m: f64,
    pub keepouts: Vec<Keepout>,
}

impl Instance {
    /// The way from node `from` to node `to` (0: the start, then the tasks, then the end), in
    /// metres; 0 to an end that is wherever the robot is.
    pub fn length(&self, from: usize, to: usize) -> Option<f64> {
        match (self.points.get(from), self.points.get(to)) {
            (Some(_), Some(_)) => self.length_m[from][to],
            _ => Some(0.0),
        }
    }
}

/// The waypoints of the objectives with a place of their own, named after them and at their
/// line: what a written plan adds to the plan's waypoints.
pub fn own_waypoints(objectives: &Objectives) -> impl Iterator<Item = Waypoint> + '_ {
    objectives
        .objectives
        .iter()
        .filter_map(|objective| match objective.place {
            Place::At(position) => Some(Waypoint {
                name: objective.name.clone(),
                position,
                symbol: None,
                pos: objective.pos,
            }),
            Place::Waypoint(_) | Place::Area(_) => None,
        })
}

/// Places each objective given as an area (docs/plans.md, "Objectives"): at its centroid when
/// it acts there (an `<arrival>`: it observes the area from its middle), else at the point of
/// it the robot reaches first from the start (the cheapest way's end, on the costmap the ways
/// are planned on); then to the ten-millionth of a degree, as the written plan gives it, so
/// that the ways timed are the legs `armor check` plans. What cannot be is said at the area.
fn place_areas(
    plan: &Plan,
    world: Option<&World>,
    robot: &Robot,
    objectives: &mut Objectives,
    problems: &mut Vec<Located>,
) {
    if !objectives
        .objectives
        .iter()
        .any(|objective| matches!(objective.place, Place::Area(_)))
    {
        return;
    }
    // Without a frame nothing is placed; `plan_legs` says why.
    let Some(origin) = plan::plan_origin(plan, world) else {
        return;
    };
    let mut bare = plan.clone();
    bare.legs.clear();
    let base = plan::plan_legs(&bare, world, robot);
    let start = base.positions.get(&objectives.from).copied();
    let mut planner: Option<Planner> = None;
    for objective in &mut objectives.objectives {
        let Place::Area(area) = &objective.place else {
            continue;
        };
        let name = &objective.name;
        let polygon = Polygon::new(area.points.iter().map(|p| p.to_local(origin)).collect());
        // A degenerate outline is refused when the plan is read.
        if polygon.corners.len() < 3 || polygon.crosses_itself() {
            continue;
        }
        let point = if objective.arrival.is_some() {
            let centroid = polygon.centroid();
            if let Some(why) = planner::blocker_at(world, robot, &base.keepouts, centroid) {
                problems.push(Located::new(
                    area.pos,
                    format!(
                        "objective `{name}` acts on its area from its centroid, at {centroid} m, \
                         which {why}; draw the area so that the robot can be at its middle, or \
                         give the objective a place"
                    ),
                ));
                continue;
            }
            centroid
        } else {
            // A start where the robot cannot be is said at its waypoint.
            let Some(start) = start else {
                continue;
            };
            if planner.is_none() {
                let settings = CostmapSettings::default();
                let costmap = match world {
                    Some(world) => Costmap::for_world(world, robot, &base.keepouts, &settings),
                    None => {
                        let mut points = polygon.corners.clone();
                        points.push(start);
                        let extent =
                            planner::open_extent(&points, &base.keepouts, robot, &settings);
                        Costmap::open(extent, robot, &base.keepouts, &settings)
                    }
                };
                match costmap {
                    Ok(costmap) => planner = Some(Planner::new(costmap)),
                    Err(err) => {
                        problems.push(Located::new(
                            plan.pos,
                            format!("the world cannot be mapped for planning: {err}"),
                        ));
                        return;
                    }
                }
            }
            let Some(planner) = planner.as_mut() else {
                return;
            };
            match planner.nearest_in(start, &polygon) {
                Some(point) => point,
                None => {
                    problems.push(Located::new(
                        area.pos,
                        format!(
                            "objective `{name}`: no part of its area can be reached from `{}`: it \
                             is walled in, or too narrow for the robot, which keeps {} m from \
                             obstacles",
                            objectives.from,
                            armor_model::geo::round_mm(robot.keep_m())
                        ),
                    ));
                    continue;
                }
            }
        };
        objective.place = Place::At(as_written(LatLon::from_local(point, origin)));
    }
}

/// A position as a plan file gives it: to the ten-millionth of a degree.
fn as_written(at: LatLon) -> LatLon {
    let written = |degrees: f64| {
        armor_model::geo::trimmed_decimal(degrees, 7)
            .parse::<f64>()
            .unwrap_or(degrees)
    };
    LatLon::new(written(at.lat_deg), written(at.lon_deg))
}

/// `plan` with every position as the plan `armor plan` writes gives it, so that the ways timed
/// are, to the bit, the legs `armor check` plans from the written file.
fn plan_as_written(plan: &Plan) -> Plan {
    let mut plan = plan.clone();
    let round = |at: &mut LatLon| *at = as_written(*at);
    if let Some(origin) = &mut plan.origin {
        round(origin);
    }
    for waypoint in &mut plan.waypoints {
        round(&mut waypoint.position);
    }
    for graphic in &mut plan.graphics {
        graphic.points.iter_mut().for_each(round);
    }
    for objective in plan
        .objectives
        .iter_mut()
        .flat_map(|objectives| &mut objectives.objectives)
    {
        match &mut objective.place {
            Place::At(at) => round(at),
            Place::Area(area) => area.points.iter_mut().for_each(round),
            Place::Waypoint(_) => {}
        }
    }
    plan
}

/// Deciseconds from seconds, rounded up (a travel time never shorter than it is).
pub fn ds_up(secs: f64) -> i32 {
    (secs * 10.0).ceil().clamp(0.0, f64::from(i32::MAX / 4)) as i32
}

/// Deciseconds from seconds, to the nearest.
pub fn ds(secs: f64) -> i32 {
    (secs * 10.0)
        .round()
        .clamp(f64::from(-i32::MAX / 4), f64::from(i32::MAX / 4)) as i32
}

/// Builds the problem of `plan`'s objectives on `world` for `robot` driving at `speed_mps`;
/// every problem at the element it concerns (an objective where the robot cannot be, two
/// objectives at one place, a plan with no objectives).
pub fn instance(
    plan: &Plan,
    world: Option<&World>,
    robot: &Robot,
    speed_mps: f64,
) -> Result<Instance, Vec<Located>> {
    let plan = &plan_as_written(plan);
    let Some(mut objectives) = plan.objectives.clone() else {
        return Err(vec![Located::new(
            plan.pos,
            "the plan has no <objectives>: nothing for `armor plan` to plan (see docs/plans.md)",
        )]);
    };
    let mut problems = Vec::new();
    place_areas(plan, world, robot, &mut objectives, &mut problems);
    // The objectives with a place of their own are placed as waypoints of their name, at the
    // objective's line, so that one in a wall is reported there.
    let mut placed = plan.clone();
    placed.legs.clear();
    placed.waypoints.extend(own_waypoints(&objectives));
    let legs = plan::plan_legs(&placed, world, robot);
    for problem in legs.problems {
        // A waypoint of an objective's own is the objective to the operator.
        let own = objectives.objectives.iter().find(|objective| {
            matches!(objective.place, Place::At(_)) && objective.pos == problem.pos
        });
        problems.push(match own {
            Some(objective) => Located::new(
                problem.pos,
                problem.message.replacen(
                    &format!("waypoint `{}`", objective.name),
                    &format!("objective `{}`", objective.name),
                    1,
                ),
            ),
            None => problem,
        });
    }
    let mut points = Vec::new();
    let mut place = |name: &str, what: String, pos| match legs.positions.get(name) {
        Some(point) => Some(*point),
        None => {
            // Where the robot cannot be is reported at the waypoint; the user of the waypoint
            // hears of it too.
            if plan.waypoints.iter().any(|waypoint| waypoint.name == name) {
                problems.push(Located::new(
                    pos,
                    format!("{what} is at waypoint `{name}`, where the robot cannot be (above)"),
                ));
            }
            None
        }
    };
    points.push(place(
        &objectives.from,
        "the start (<objectives from>)".to_owned(),
        objectives.pos,
    ));
    for objective in &objectives.objectives {
        let what = format!("objective `{}`", objective.name);
        points.push(match &objective.place {
            Place::Waypoint(name) => place(name, what, objective.pos),
            Place::At(_) | Place::Area(_) => legs.positions.get(&objective.name).copied(),
        });
    }
    if let Some(to) = &objectives.to {
        points.push(place(
            to,
            "the end (<objectives to>)".to_owned(),
            objectives.pos,
        ));
    }
    // The planner's legs cannot go from a place to itself: two objectives at one place, or one
    // where the robot starts, are refused (one objective may do both things there).
    let mut at: Vec<(&str, &str)> = vec![(objectives.from.as_str(), "the start")];
    for objective in &objectives.objectives {
        let waypoint = objective.waypoint();
        if let Some((_, other)) = at.iter().find(|(name, _)| *name == waypoint) {
            problems.push(Located::new(
                objective.pos,
                format!(
                    "objective `{}` is at `{waypoint}`, as {other} is: the planner drives \
                     between different places; give it a place of its own, or join the two",
                    objective.name
                ),
            ));
        }
        at.push((waypoint, &objective.name));
    }
    if !problems.is_empty() {
        problems.sort_by_key(|problem| problem.pos);
        problems.dedup();
        return Err(problems);
    }
    let points: Vec<Point> = points.into_iter().flatten().collect();
    let count = points.len();
    // Every way in both directions, as the written plan's legs will be planned (a path and
    // its reverse may differ by a hair): the planner searches once from each place to all the
    // others, and each way is the path `armor check` then plans for that leg, to the bit.
    let mut pairs = Vec::new();
    for i in 0..count {
        for j in 0..count {
            if i != j {
                pairs.push((points[i], points[j]));
            }
        }
    }
    let paths = plan::plan_pairs(world, robot, &legs.keepouts, &pairs).map_err(|err| {
        vec![Located::new(
            plan.pos,
            format!("the world cannot be mapped for planning: {err}"),
        )]
    })?;
    let mut length_m = vec![vec![None; count]; count];
    let mut cut = vec![vec![None; count]; count];
    for ((i, j), path) in (0..count)
        .flat_map(|i| (0..count).filter(move |&j| j != i).map(move |j| (i, j)))
        .zip(paths)
    {
        match path {
            Ok(path) => length_m[i][j] = Some(path.length_m),
            Err(err) => {
                cut[i][j] = Some(match err {
                    PathError::Cut(bottleneck) => bottleneck.to_string(),
                    PathError::Blocked { why, .. } => why.to_string(),
                });
            }
        }
    }
    for (i, row) in length_m.iter_mut().enumerate() {
        row[i] = Some(0.0);
    }
    let n = objectives.objectives.len();
    // Node indices into `points`: the start, the tasks, the end (when placed).
    let ends_at_place = objectives.to.is_some();
    let node_point = |node: usize| -> Option<usize> {
        if node <= n {
            Some(node)
        } else if ends_at_place {
            Some(n + 1)
        } else {
            None
        }
    };
    let mut travel_ds = vec![vec![None; n + 2]; n + 2];
    let mut distance_dm = vec![vec![0; n + 2]; n + 2];
    for from in 0..n + 2 {
        for to in 0..n + 2 {
            if from == n + 1 || to == 0 || from == to {
                continue;
            }
            let length = match (node_point(from), node_point(to)) {
                (Some(a), Some(b)) => length_m[a][b],
                // Without an end place, the robot ends where it is.
                _ => Some(0.0),
            };
            if let Some(length) = length {
                travel_ds[from][to] = Some(ds_up(length / speed_mps));
                distance_dm[from][to] = (length * 10.0).round() as i32;
            }
        }
    }
    let start = plan.start_unix_secs;
    let relative = |at: Option<f64>| -> Option<i32> { Some(ds(at? - start?)) };
    let tasks = objectives
        .objectives
        .iter()
        .map(|objective| Task {
            service_ds: ds_up(objective.service_secs()),
            not_before_ds: relative(objective.not_before_unix_secs),
            due_ds: relative(objective.due_unix_secs),
            by_ds: relative(objective.by_unix_secs),
            priority: objective.priority as i32,
            must: !objective.optional,
        })
        .collect();
    let index = |name: &str| {
        objectives
            .objectives
            .iter()
            .position(|objective| objective.name == name)
    };
    let precedences = objectives
        .precedences
        .iter()
        .filter_map(|precedence| Some((index(&precedence.first)?, index(&precedence.then)?)))
        .collect();
    let problem = Problem {
        tasks,
        travel_ds,
        distance_dm,
        precedences,
        max_distance_dm: objectives
            .max_distance_m
            .map(|metres| (metres * 10.0).floor() as i32),
        max_time_ds: objectives.max_secs.map(|secs| (secs * 10.0).floor() as i32),
        // Set by the caller, who knows the battery (`ChargeLimit::new`).
        max_charge: None,
    };
    Ok(Instance {
        problem,
        start: objectives.from.clone(),
        end: objectives.to.clone(),
        objectives,
        points,
        length_m,
        cut,
        start_unix_secs: start,
        speed_mps,
        fastest_mps: speed_mps,
        arrival_tolerance_m: 0.0,
        keepouts: legs.keepouts,
    })
}
