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

use std::collections::BTreeMap;

use armor_module_api::xml::{Located, Pos};

use super::{Action, Leg, Plan, Response, Trigger};
use crate::geo::{self, LatLon, Polygon};
use crate::net::{Arc, Condition, MissionNet, Place, PlaceParam, Transition, format_date};
use crate::world::{Point, ShapeKind, World};

/// How far routes keep from no-go areas, in metres.
pub const CLEARANCE_M: f64 = 1.0;

/// How far a detour around a no-go area keeps from the world's walls, in metres: the robot's
/// radius and some.
const WALL_CLEARANCE_M: f64 = 0.6;

/// Origins of the world frame closer than this are the same.
const ORIGIN_TOLERANCE_M: f64 = 1.0;

/// A compiled plan.
#[derive(Clone, Debug)]
pub struct Compiled {
    pub net: MissionNet,
    /// The plan element each place and transition comes from.
    pub trace: BTreeMap<String, Origin>,
    /// Each leg's route in the world frame: its start, the corners around no-go areas, its end.
    pub routes: Vec<Vec<Point>>,
    /// Each waypoint in the world frame.
    pub positions: BTreeMap<String, Point>,
    /// What may keep the plan from going as drawn without stopping it: time constraints that
    /// cannot all be met, with the numbers.
    pub warnings: Vec<Located>,
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

/// Compiles `plan` drawn on `world` (when the robot runs in one; without, the plan's origin
/// defines the frame). Every problem is reported, at the plan element it concerns.
pub fn compile(plan: &Plan, world: Option<&World>) -> Result<Compiled, Vec<Located>> {
    let mut problems = Vec::new();
    let origin = frame_origin(plan, world, &mut problems);
    let no_go = no_go_polygons(plan, origin, &mut problems);
    let mut positions = BTreeMap::new();
    if let Some(origin) = origin {
        for waypoint in &plan.waypoints {
            let point = waypoint.position.to_local(origin);
            let before = problems.len();
            check_position(
                &waypoint.name,
                point,
                waypoint.pos,
                world,
                &no_go,
                &mut problems,
            );
            // A waypoint the robot cannot be at has no route either: one message is enough.
            if problems.len() == before {
                positions.insert(waypoint.name.clone(), point);
            }
        }
    }
    let world_corners = world.map(corners_around_obstacles).unwrap_or_default();
    let mut routes = Vec::new();
    for leg in &plan.legs {
        let (Some(&from), Some(&to)) = (positions.get(&leg.from), positions.get(&leg.to)) else {
            continue;
        };
        let polygons: Vec<Polygon> = no_go.iter().map(|(_, polygon)| polygon.clone()).collect();
        let detour_ok = |a: Point, b: Point| world.is_none_or(|world| clear_of_walls(world, a, b));
        match geo::route(from, to, &polygons, CLEARANCE_M, &world_corners, &detour_ok) {
            Some(via) => routes.push(std::iter::once(from).chain(via).collect()),
            None => problems.push(Located::new(
                leg.pos,
                format!(
                    "leg `{}`: no way from `{}` to `{}` keeps {CLEARANCE_M} m from the no-go \
                     areas",
                    leg.name, leg.from, leg.to
                ),
            )),
        }
    }
    for contingency in plan
        .contingencies
        .iter()
        .chain(plan.legs.iter().flat_map(|leg| &leg.contingencies))
    {
        if contingency.response == Response::Continue && contingency.trigger != Trigger::Late {
            problems.push(Located::new(
                contingency.pos,
                "`continue` is only for on=\"late\"",
            ));
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
    if !problems.is_empty() {
        problems.sort_by_key(|problem| problem.pos);
        return Err(problems);
    }
    let warnings = time_warnings(plan, &routes);
    let mut builder = Builder::new(plan, &positions, &no_go);
    builder.build();
    Ok(Compiled {
        net: builder.net,
        trace: builder.trace,
        routes,
        positions,
        warnings,
    })
}

/// The geographic origin of the world frame: the world's, which the plan's must match.
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

fn no_go_polygons(
    plan: &Plan,
    origin: Option<LatLon>,
    problems: &mut Vec<Located>,
) -> Vec<(String, Polygon)> {
    let Some(origin) = origin else {
        return Vec::new();
    };
    let mut polygons = Vec::new();
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
        polygons.push((area.name.clone(), polygon));
    }
    polygons
}

fn check_position(
    name: &str,
    point: Point,
    pos: Pos,
    world: Option<&World>,
    no_go: &[(String, Polygon)],
    problems: &mut Vec<Located>,
) {
    if let Some(world) = world {
        let bounds = world.bounds();
        if !world.boundary().contains(point) {
            problems.push(Located::new(
                pos,
                format!(
                    "waypoint `{name}` is outside the world `{}`: it is at {point} m, the world \
                     spans {} to {} m east and {} to {} m north",
                    world.name(),
                    bounds.min_x,
                    bounds.max_x,
                    bounds.min_y,
                    bounds.max_y
                ),
            ));
            return;
        }
        if !world.is_free(point) {
            problems.push(Located::new(
                pos,
                format!(
                    "waypoint `{name}` at {point} m is inside an obstacle of the world `{}`",
                    world.name()
                ),
            ));
            return;
        }
    }
    for (area, polygon) in no_go {
        if polygon.near_box(point, point, CLEARANCE_M)
            && (polygon.contains(point) || polygon.distance_to_outline(point) < CLEARANCE_M)
        {
            problems.push(Located::new(
                pos,
                format!(
                    "waypoint `{name}` is in the no-go area `{area}` or closer than \
                     {CLEARANCE_M} m to it"
                ),
            ));
        }
    }
}

/// Where a detour may turn around the world's obstacles and walls: their corners pushed out by
/// a little more than [`WALL_CLEARANCE_M`] (the ends of a thin wall on four sides), where free.
fn corners_around_obstacles(world: &World) -> Vec<Point> {
    let margin = WALL_CLEARANCE_M * 1.3;
    let mut corners = Vec::new();
    for shape in world.shapes() {
        match shape.kind {
            ShapeKind::Boundary => {}
            ShapeKind::Obstacle => {
                corners.extend(Polygon::new(shape.points.clone()).inflated_corners(margin));
            }
            ShapeKind::Wall => {
                for p in &shape.points {
                    for (dx, dy) in [(1.0, 1.0), (1.0, -1.0), (-1.0, 1.0), (-1.0, -1.0)] {
                        corners.push(Point::new(p.x + dx * margin, p.y + dy * margin));
                    }
                }
            }
        }
    }
    corners.retain(|p| {
        world.is_free(*p) && world.wall_distance(*p, WALL_CLEARANCE_M) >= WALL_CLEARANCE_M
    });
    corners
}

/// Whether the robot can drive straight from `a` to `b` in `world`: both inside and free, the
/// segment crossing no wall and keeping [`WALL_CLEARANCE_M`] from every one.
fn clear_of_walls(world: &World, a: Point, b: Point) -> bool {
    if !world.is_free(a) || !world.is_free(b) {
        return false;
    }
    if world
        .segments()
        .any(|(c, d)| geo::segments_cross(a, b, c, d))
    {
        return false;
    }
    let length = geo::distance(a, b);
    let steps = (length / 0.2).ceil().max(1.0) as usize;
    (0..=steps).all(|i| {
        let t = i as f64 / steps as f64;
        let p = Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t);
        world.wall_distance(p, WALL_CLEARANCE_M) >= WALL_CLEARANCE_M
    })
}

fn action_modules(plan: &Plan) -> Vec<(String, Pos)> {
    plan.legs
        .iter()
        .flat_map(|leg| leg.during.iter().chain(&leg.arrival))
        .flat_map(|action| &action.modules)
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
    no_go: String,
    net: MissionNet,
    /// Also the names made so far (the net's own lookup is a linear search).
    trace: BTreeMap<String, Origin>,
    /// The modules whose failure some contingency handles.
    failure_modules: Vec<String>,
}

impl<'a> Builder<'a> {
    fn new(
        plan: &'a Plan,
        positions: &'a BTreeMap<String, Point>,
        no_go: &[(String, Polygon)],
    ) -> Self {
        let polygons: Vec<Polygon> = no_go.iter().map(|(_, polygon)| polygon.clone()).collect();
        Self {
            plan,
            positions,
            no_go: geo::format_polygons(&polygons),
            net: MissionNet {
                name: plan.name.clone(),
                system: plan.system.clone(),
                pos: plan.pos,
                ..MissionNet::default()
            },
            trace: BTreeMap::new(),
            failure_modules: plan.failure_modules(),
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
        let (modules, params) = self.drive_action(&leg.to, leg.during.as_ref(), leg.pos);
        self.place(&drive, origin(), leg.pos, modules.clone(), params.clone());
        leg_places.push(drive.clone());
        self.drive_exits(index, leg, &drive, "", &after_drive);
        if let Some(deadline) = leg.arrive_by_unix_secs {
            let late = Condition {
                at_unix_secs: Some(deadline),
                ..Condition::default()
            };
            let target = match self.response(leg, &Trigger::Late) {
                Some(Response::Continue) | None => {
                    let drive_late = format!("{name}_drive_late");
                    self.place(&drive_late, origin(), leg.pos, modules, params);
                    self.drive_exits(index, leg, &drive_late, "_late", &after_drive);
                    leg_places.push(drive_late.clone());
                    drive_late
                }
                Some(response) => self.respond(index, leg, &response),
            };
            self.transition(
                &format!("{name}_late"),
                origin(),
                leg.pos,
                late,
                &drive,
                &target,
            );
        }
        if let Some(arrival) = &leg.arrival {
            let place = format!("{name}_arrival");
            let (modules, params) = action_parts(arrival);
            self.place(&place, origin(), arrival.pos, modules, params);
            let until = arrival.until.clone();
            let mut done = Condition {
                event: until.clone(),
                ..Condition::default()
            };
            if until.is_none() {
                done.delay_secs = arrival.for_secs;
            }
            self.transition(
                &format!("{name}_arrival_done"),
                origin(),
                arrival.pos,
                done,
                &place,
                &after_arrival,
            );
            if let (Some(_), Some(secs)) = (&until, arrival.for_secs) {
                self.transition(
                    &format!("{name}_arrival_timeout"),
                    origin(),
                    arrival.pos,
                    Condition {
                        delay_secs: Some(secs),
                        ..Condition::default()
                    },
                    &place,
                    &after_arrival,
                );
            }
            leg_places.push(place);
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
        for module in self.failure_modules.clone() {
            let trigger = Trigger::Failed {
                module: module.clone(),
            };
            let Some(response) = self.response(leg, &trigger) else {
                continue;
            };
            let target = self.respond(index, leg, &response);
            for place in &leg_places {
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
            Response::Hold => {
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
                    let (modules, params) = self.drive_action(waypoint, None, leg.pos);
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

    /// The modules and parameters of a drive to `waypoint`, with an action beside it.
    fn drive_action(
        &self,
        waypoint: &str,
        during: Option<&Action>,
        pos: Pos,
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
        if let Some(action) = during {
            let (more_modules, more_params) = action_parts(action);
            modules.extend(more_modules);
            params.extend(more_params);
        }
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
    let modules = action.modules.iter().map(|m| m.name.clone()).collect();
    let params = action
        .modules
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
    (modules, params)
}

#[cfg(test)]
mod tests;
