//! `follower`: drives towards a goal with a proportional heading controller.
//!
//! Each pose received on `odometry` gives one command on `cmd_desired`: turn towards the goal
//! in proportion to the heading error, and move forward at a speed that drops as the heading
//! error grows (nothing beyond 90°, so the robot turns first when the goal is behind it) and as
//! the goal gets close. Within `tolerance_m` of the goal it commands zero and reports
//! `goal_reached`, once per goal: a new goal (a live change of `goal_x_m` or `goal_y_m`, as the
//! mission sets each leg) or a new activation re-arms it (the mission controller starts the
//! follower afresh at each leg, even when the goal is the previous leg's). When the distance to
//! the goal has not shrunk for `blocked_after_secs` of run time since the first pose after a
//! (re)start, it reports `blocked`, once until progress resumes.
//!
//! Areas given in `no_go` (as a mission compiled from a plan gives them) are kept out of: at
//! every pose the follower takes the shortest way round them to the goal
//! ([`armor_model::geo::route`], [`CLEARANCE_M`] away from them) and heads for its first corner.
//! With no way round it stops, and `blocked` follows.
//!
//! When a `path` is given (as a compiled plan gives each leg the path planned at plan time, which
//! already keeps out of the no-go areas), the follower drives along it instead, with regulated
//! pure pursuit ([`super::pursuit`]), and progress is the length of path left to the goal.
//! When it replans, it keeps each no-go area's own margin (`no_go_margins_m`, as the plan was
//! checked with), not one for all.
//!
//! With a mapper's live `map` linked (a robot with no `world`), the path left is checked
//! against the map's walls at a leg's start and at each map taken (one per [`MAP_EVERY_M`]
//! driven); when it comes nearer one than the robot keeps, the leg is planned again on the map,
//! every wall seen so far at once, and that plan does not count among `max_replans`. The laser's
//! raw hits are then left to the map.
//!
//! With a localiser's `estimate` linked, the follower also keeps the pose's uncertainty from
//! the no-go areas: while its body is closer to one than [`UNCERTAINTY_SIGMAS`] standard
//! deviations of the position (on its worst axis), it stops rather than guess, until the
//! estimate is sure enough again (or `blocked` follows). It also reports `goal_reached` only
//! once the goal is within `tolerance_m` less that uncertainty (but at least half the
//! tolerance), so that the robot is truly there, not only by its estimate. It never drives on
//! an estimate that is not proven (after a search of the map, a suspected kidnap, or lost): it
//! turns in place, so that the localiser can prove the place by the turn, and after
//! [`PROOF_SECS`] without a proof it stops and reports `blocked`.

use armor_model::geo::{self, Polygon};
use armor_model::planner::{self, Keepout, Path, Robot};
use armor_model::world::Point;
use armor_module_api::types::{
    Frame, LaserScan, LocalisationState, Marker, Markers, OccupancyGrid, Odometry, Pose2D,
    PoseEstimate, Shape, Text, Twist,
};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use super::pursuit::{Limits, Pursuit};
use super::replan::{self, LiveMap, WorldMap};
use super::wrap_angle;
use crate::BodyError;

pub const TYPE: &str = "follower";

/// How often, in run time, the follower checks for lack of progress when no pose arrives.
const TICK_SECS: f64 = 0.1;
/// How often, in run time, the path followed is published again while active: a subscriber
/// that comes late (the studio's Run view, after the first leg started) still gets it.
const PATH_AGAIN_SECS: f64 = 1.0;
/// The distance to the goal must shrink by this much to count as progress.
const PROGRESS_M: f64 = 0.05;
/// Turning speed per radian of heading error (before clamping to `max_turn_radps`).
const TURN_GAIN: f64 = 2.0;
/// Closer than this to the goal, the forward speed drops in proportion to the distance.
const SLOW_DOWN_M: f64 = 1.0;
/// A way round no-go areas is given up for a shorter one only when that one is this much shorter.
const SWITCH_M: f64 = 1.0;
/// Closer than this to a corner of the way round, the follower heads for the next one.
const VIA_REACHED_M: f64 = 0.4;
/// How far the way round a no-go area keeps from it (what plans are compiled with).
pub const CLEARANCE_M: f64 = armor_model::plan::CLEARANCE_M;
/// A new live map is taken once the robot has moved this far since the last one taken (or at
/// a leg's start): the map grows as the laser sees more, which it does as the robot moves, and
/// a mapper's grid is large (decoding 60 m at 0.1 m took 24 ms in a debug build, which at
/// twenty times real time and a map a second of run time left the follower's commands late).
const MAP_EVERY_M: f64 = 2.0;
/// How many standard deviations of the estimated position the robot's body keeps from the
/// no-go areas (two: about 95 % along the worst axis).
pub const UNCERTAINTY_SIGMAS: f64 = 2.0;
/// While the estimate is not proven, the follower turns in place at most this fast: the
/// localiser pairs each scan with the odometry of about its time, and turning fast, a few
/// milliseconds between them move the far beams' ends by tens of centimetres, so that the
/// scans disagree with the map and the turn proves nothing (measured on Nav2's depot map: 20 s
/// of turning at 1.2 rad/s proved nothing).
const PROOF_TURN_RADPS: f64 = 0.5;
/// How long the follower turns in place for a proof before it stops and reports `blocked`:
/// three full turns at [`PROOF_TURN_RADPS`].
pub const PROOF_SECS: f64 = 40.0;

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Drives towards a goal position: turns towards it, moves forward when roughly facing it, \
         slows down near it, and reports goal_reached within tolerance (once per goal).",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .input::<Odometry>(
        "odometry",
        "the robot's pose (the odometry pose, or a corrected pose in the same frame as the goal)",
    )
    .input::<PoseEstimate>(
        "estimate",
        "the localiser's estimate (optional): its uncertainty is kept from the no-go areas \
         (closer than two standard deviations of the position, the follower stops until the \
         estimate is sure enough); while it is not proven, the follower turns in place instead \
         of driving (at most 0.5 rad/s), and reports blocked after 40 s without a proof",
    )
    .input::<LaserScan>(
        "scan",
        "the laser scan (optional): with a path, what it sees on the way is gone round when \
         replanning",
    )
    .input::<OccupancyGrid>(
        "map",
        "a mapper's live map, in the frame of the pose (optional; for a robot with no `world`): \
         with a path, every wall it holds is planned round at once, whenever the path left \
         comes near one (at the leg's start and at each new map)",
    )
    .output::<Text>(
        "path",
        "the path being followed, `X,Y X,Y ...` in metres: the planned one at each activation, \
         each new one after a replan, and the same again every second of run time while \
         active (for a display that subscribes late)",
    )
    .output::<Markers>(
        "markers",
        "what it follows, for the Run view's map: the path ahead (or the line to the goal or \
         the next corner round a no-go area) and the goal, ten times a second of run time",
    )
    .output::<Twist>(
        "cmd_desired",
        "the velocity that would take the robot to the goal (one per pose received; zero at the \
         goal, and once when the module is stopped)",
    )
    .param(
        ParamSpec::new(
            "goal_x_m",
            ParamType::Float,
            "goal x, in the frame of the odometry pose (tunable live: a new goal re-arms \
             goal_reached)",
        )
        .unit("m"),
    )
    .param(
        ParamSpec::new(
            "goal_y_m",
            ParamType::Float,
            "goal y, in the frame of the odometry pose (tunable live)",
        )
        .unit("m"),
    )
    .param(
        ParamSpec::new(
            "tolerance_m",
            ParamType::Float,
            "the goal is reached within this distance (greater than 0)",
        )
        .above(0.0)
        .unit("m")
        .default("0.3"),
    )
    .param(
        ParamSpec::new(
            "pose_uncertainty_m",
            ParamType::Float,
            "how far the true position may be from the odometry pose when no `estimate` says \
             it (a mapper's corrected pose, say): the goal counts as reached within tolerance_m \
             less this, and no-go areas are kept this much further",
        )
        .min(0.0)
        .unit("m")
        .default("0"),
    )
    .param(
        ParamSpec::new(
            "max_speed_mps",
            ParamType::Float,
            "forward speed far from the goal when facing it (greater than 0)",
        )
        .above(0.0)
        .unit("m/s")
        .default("0.6"),
    )
    .param(
        ParamSpec::new(
            "max_turn_radps",
            ParamType::Float,
            "largest turning speed (greater than 0)",
        )
        .above(0.0)
        .unit("rad/s")
        .default("1.2"),
    )
    .param(
        ParamSpec::new(
            "blocked_after_secs",
            ParamType::Float,
            "report `blocked` when the distance to the goal has not shrunk for this long, in run \
             time (0 or more; 0 reports at the first pose that shows no progress)",
        )
        .min(0.0)
        .unit("s")
        .default("10"),
    )
    .param(
        ParamSpec::new(
            "no_go",
            ParamType::String,
            "areas to keep out of, in the frame of the odometry pose: polygons `X,Y X,Y X,Y` in \
             metres separated by `;` (a plan's no-go areas); the follower drives round them, \
             1 m away, and stops when there is no way round (tunable live)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "no_go_margins_m",
            ParamType::String,
            "how far the robot's body keeps from each area of no_go when replanning: metres \
             separated by `;`, one per area in no_go's order (a compiled plan gives them when one \
             is not the default); empty: 0.75 m from each (tunable live)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "path",
            ParamType::String,
            "the path planned for this leg at plan time, in the frame of the odometry pose: \
             points `X,Y X,Y ...` in metres from the leg's start to the goal (a compiled plan \
             gives it); when given, the follower drives along it (regulated pure pursuit) \
             instead of heading for the goal, and no_go is left to the path (tunable live)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "world",
            ParamType::String,
            "the world file replanning starts from (found as the sim finds its own; empty: \
             replan on what the laser sees alone)",
        )
        .default("")
        .file("worlds"),
    )
    .param(
        ParamSpec::new(
            "robot_radius_m",
            ParamType::Float,
            "the robot's radius, for replanning (greater than 0; a compiled plan gives its own \
             when it is not the default)",
        )
        .above(0.0)
        .unit("m")
        .default("0.25"),
    )
    .param(
        ParamSpec::new(
            "clearance_m",
            ParamType::Float,
            "how far the robot's body keeps from obstacles when replanning (0 or more; a \
             compiled plan gives its own when it is not the default)",
        )
        .min(0.0)
        .unit("m")
        .default("0.1"),
    )
    .param(
        ParamSpec::new(
            "replan_after_secs",
            ParamType::Float,
            "with a path: plan again from where the robot is when it has made no progress along \
             the path for this long, or at once when the laser sees the path blocked ahead \
             (greater than 0)",
        )
        .above(0.0)
        .unit("s")
        .default("3"),
    )
    .param(
        ParamSpec::new(
            "max_replans",
            ParamType::Int,
            "with a path: the most replans per leg (0 to 100); beyond them, no progress for \
             blocked_after_secs reports `blocked`, and so does a replan that finds no way",
        )
        .min(0.0)
        .max(100.0)
        .default("3"),
    )
    .event(
        "goal_reached",
        "the robot is within tolerance_m of the goal (once per goal or activation)",
    )
    .event(
        "blocked",
        "no progress towards the goal for blocked_after_secs (once, until progress resumes)",
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let odometry = node.input::<Odometry>("odometry")?;
    let scan = node.input::<LaserScan>("scan")?;
    let estimate = node.input::<PoseEstimate>("estimate")?;
    let map = node.input::<OccupancyGrid>("map")?;
    let path_output = node.output::<Text>("path")?;
    let output = node.output::<Twist>("cmd_desired")?;
    let markers_output = node.output::<Markers>("markers")?;
    let settings = Settings::read(node)?;
    let world = load_world(&settings.world)?;
    tracing::info!(
        "goal ({}, {}), {} no-go area(s)",
        settings.goal_x_m,
        settings.goal_y_m,
        settings.no_go.len()
    );
    let mut follower = Follower::new(settings, node.timestamp());
    follower.world = world;
    let mut next_tick = node.timestamp() + TICK_SECS;
    let mut path_sent = f64::NEG_INFINITY;
    let mut applicable = true;
    let mut map_waiting = false;
    loop {
        let event = if node.is_active() {
            let deadline = node.clock().instant_at(next_tick);
            node.next_event_until(deadline)?
        } else {
            node.next_event(None)?
        };
        match event {
            Event::Input(port) if port == odometry.id() => {
                let Some(sample) = node.take(&odometry)? else {
                    continue;
                };
                if map_waiting && follower.wants_map() {
                    map_waiting = false;
                    if let Some(sample) = node.take(&map)? {
                        follower.on_map(sample.value);
                    }
                }
                if node.is_active() {
                    let control = follower.on_pose(sample.value.pose_in_odom, node.timestamp());
                    if control.new_path {
                        send_path(node, &path_output, &follower)?;
                        path_sent = node.timestamp();
                    }
                    // A behaviour proposes only while it applies (until the goal is reached),
                    // and says so; its last proposal is the zero of arrival.
                    let applied = applicable;
                    applicable = !follower.reached;
                    node.set_applicable(applicable);
                    if applicable || applied {
                        node.send(&output, &control.twist)?;
                    }
                    if let Some(event) = control.report {
                        node.report(event)?;
                    }
                }
            }
            Event::Input(port) if port == scan.id() => {
                if let Some(sample) = node.take(&scan)? {
                    follower.on_scan(&sample.value);
                }
            }
            // The newest map waits in its input until the follower wants one (see MAP_EVERY_M).
            Event::Input(port) if port == map.id() => map_waiting = true,
            Event::Input(port) if port == estimate.id() => {
                if let Some(sample) = node.take(&estimate)? {
                    follower.on_estimate(&sample.value);
                }
            }
            Event::Timeout if node.is_active() => {
                let now = node.timestamp();
                next_tick = now + TICK_SECS;
                if now - path_sent >= PATH_AGAIN_SECS {
                    send_path(node, &path_output, &follower)?;
                    path_sent = now;
                }
                if let Some(event) = follower.on_tick(now) {
                    node.report(event)?;
                }
                node.send(&markers_output, &follower.markers())?;
            }
            Event::Start => {
                tracing::info!("active: heading for the goal");
                follower.restart(node.timestamp());
                applicable = true;
                next_tick = node.timestamp() + TICK_SECS;
                send_path(node, &path_output, &follower)?;
                path_sent = node.timestamp();
            }
            Event::Stop => {
                tracing::info!("inactive: stopping");
                node.send(&output, &Twist::default())?;
            }
            Event::ParamsChanged(_) => match Settings::read(node) {
                Ok(settings) => {
                    if settings.world != follower.settings.world {
                        match load_world(&settings.world) {
                            Ok(world) => follower.world = world,
                            Err(err) => tracing::error!("{err}; keeping the previous world"),
                        }
                    }
                    follower.retune(settings, node.timestamp());
                }
                Err(err) => tracing::error!("{err}; keeping the previous settings"),
            },
            Event::ProviderFailed(port) if port == odometry.id() => {
                // The run moves the input to its fallback, if it has one; poses go on from it.
                tracing::warn!("the provider of `odometry` failed");
            }
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

/// The path being followed, on the `path` output (nothing without one).
fn send_path(
    node: &mut Node,
    output: &armor_module_api::Output<Text>,
    follower: &Follower,
) -> Result<(), BodyError> {
    if let Some(pursuit) = &follower.pursuit {
        node.send(output, &Text(Path::new(pursuit.points().to_vec()).format()))?;
    }
    Ok(())
}

/// The world named by the `world` parameter, found as the sim finds its own.
fn load_world(name: &str) -> Result<Option<WorldMap>, BodyError> {
    let name = name.trim();
    if name.is_empty() {
        return Ok(None);
    }
    let path = crate::sim::find_world(name).map_err(|err| format!("parameter `world`: {err}"))?;
    let world = crate::sim::load_world_file(&path)
        .map(WorldMap::new)
        .map_err(|err| format!("parameter `world`: {err}"))?;
    tracing::info!("replanning on the world `{}`", world.file_name);
    Ok(Some(world))
}

/// The follower's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub goal_x_m: f64,
    pub goal_y_m: f64,
    pub tolerance_m: f64,
    pub max_speed_mps: f64,
    pub max_turn_radps: f64,
    pub blocked_after_secs: f64,
    pub no_go: Vec<Polygon>,
    /// How far the robot's body keeps from each area of `no_go` (as many, or none: the
    /// default for each).
    pub no_go_margins_m: Vec<f64>,
    /// The path planned for the leg (empty: none, head for the goal).
    pub path: Path,
    pub world: String,
    pub robot_radius_m: f64,
    pub clearance_m: f64,
    pub replan_after_secs: f64,
    pub max_replans: u32,
    /// How uncertain the pose is when no estimate says it.
    pub pose_uncertainty_m: f64,
}

impl Settings {
    fn read(node: &Node) -> Result<Self, BodyError> {
        let settings = Self {
            goal_x_m: node.param::<f64>("goal_x_m")?,
            goal_y_m: node.param::<f64>("goal_y_m")?,
            tolerance_m: node.param::<f64>("tolerance_m")?,
            max_speed_mps: node.param::<f64>("max_speed_mps")?,
            max_turn_radps: node.param::<f64>("max_turn_radps")?,
            blocked_after_secs: node.param::<f64>("blocked_after_secs")?,
            no_go: geo::parse_polygons(&node.param::<String>("no_go")?)
                .map_err(|why| format!("parameter `no_go`: {why}"))?,
            no_go_margins_m: parse_margins(&node.param::<String>("no_go_margins_m")?)?,
            path: Path::parse(&node.param::<String>("path")?)
                .map_err(|why| format!("parameter `path`: {why}"))?,
            world: node.param::<String>("world")?,
            robot_radius_m: node.param::<f64>("robot_radius_m")?,
            clearance_m: node.param::<f64>("clearance_m")?,
            replan_after_secs: node.param::<f64>("replan_after_secs")?,
            max_replans: node.param::<u32>("max_replans")?,
            pose_uncertainty_m: node.param::<f64>("pose_uncertainty_m")?,
        };
        let margins = settings.no_go_margins_m.len();
        if margins != 0 && margins != settings.no_go.len() {
            return Err(format!(
                "parameter `no_go_margins_m`: {margins} margin(s) for {} no-go area(s)",
                settings.no_go.len()
            )
            .into());
        }
        Ok(settings)
    }

    /// The no-go areas as the planner keeps out of them, each with its margin.
    fn keepouts(&self) -> Vec<Keepout> {
        self.no_go
            .iter()
            .enumerate()
            .map(|(i, polygon)| {
                Keepout::new(
                    format!("no-go area {}", i + 1),
                    polygon.clone(),
                    self.no_go_margins_m
                        .get(i)
                        .copied()
                        .unwrap_or(planner::DEFAULT_AREA_MARGIN_M),
                )
            })
            .collect()
    }

    fn same_goal(&self, other: &Settings) -> bool {
        self.goal_x_m == other.goal_x_m
            && self.goal_y_m == other.goal_y_m
            && self.path == other.path
    }

    fn goal(&self) -> Point {
        Point::new(self.goal_x_m, self.goal_y_m)
    }

    fn limits(&self) -> Limits {
        Limits {
            max_speed_mps: self.max_speed_mps,
            max_turn_radps: self.max_turn_radps,
        }
    }

    /// The path to pursue, when one is given: the planned points, ending at the goal (added
    /// when the path does not end there, as after a live change of the goal alone).
    fn pursuit(&self) -> Option<Pursuit> {
        if self.path.points.is_empty() {
            return None;
        }
        let mut points = self.path.points.clone();
        let goal = self.goal();
        if points
            .last()
            .is_some_and(|last| geo::distance(*last, goal) > 1e-3)
        {
            points.push(goal);
        }
        Some(Pursuit::new(points))
    }
}

/// The `no_go_margins_m` parameter: metres, `;` between areas (empty: none given).
fn parse_margins(text: &str) -> Result<Vec<f64>, BodyError> {
    if text.trim().is_empty() {
        return Ok(Vec::new());
    }
    text.split(';')
        .map(|margin| {
            margin
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|m| m.is_finite() && *m >= 0.0)
                .ok_or_else(|| {
                    format!(
                        "parameter `no_go_margins_m`: `{}` is not a distance in metres (0 or more)",
                        margin.trim()
                    )
                    .into()
                })
        })
        .collect()
}

/// The command for one pose, and the event to report, if any.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Control {
    pub(crate) twist: Twist,
    pub(crate) report: Option<&'static str>,
    /// A new path is being followed (to publish).
    new_path: bool,
}

/// The go-to-goal controller and its once-only events, on run time.
#[derive(Clone, Debug)]
pub(crate) struct Follower {
    settings: Settings,
    /// The path being followed, when there is one.
    pursuit: Option<Pursuit>,
    /// The corner of the way round the no-go areas headed for (without a path).
    via: Option<Point>,
    /// The world replanning starts from.
    pub(crate) world: Option<WorldMap>,
    /// The latest pose, and the laser's hits the world does not explain, seen from it.
    pose: Option<Pose2D>,
    seen: Vec<Point>,
    /// A mapper's live map, and whether the path left comes near one of its walls (checked at
    /// the first pose of a leg and at each new map).
    live_map: Option<LiveMap>,
    /// Where the robot was when the live map was taken.
    map_taken_at: Option<Point>,
    map_in_the_way: bool,
    map_checked: bool,
    /// Replans since the last (re)start, and when the last one was.
    replans: u32,
    last_replan: f64,
    pub(crate) reached: bool,
    blocked: bool,
    /// The shortest way left to the goal so far (along the path when there is one), and when
    /// it was last shortened.
    best_distance_m: f64,
    last_progress: f64,
    /// How far the true position may be from the pose ([`UNCERTAINTY_SIGMAS`] standard
    /// deviations of the latest estimate; `None` until one comes, and then `pose_uncertainty_m`
    /// says it).
    estimated_uncertainty_m: Option<f64>,
    /// The robot is stopped by a no-go area within its uncertainty.
    guarded: bool,
    /// Whether the latest estimate is proven (true until one says otherwise, and without a
    /// localiser), since when the follower turns in place for want of a proven one, and whether
    /// it gave up waiting (see [`Follower::turn_for_proof`]).
    estimate_proven: bool,
    unproven_since: Option<f64>,
    proof_given_up: bool,
}

impl Follower {
    pub(crate) fn new(settings: Settings, now: f64) -> Self {
        let mut follower = Self {
            settings,
            pursuit: None,
            via: None,
            world: None,
            pose: None,
            seen: Vec::new(),
            live_map: None,
            map_taken_at: None,
            map_in_the_way: false,
            map_checked: false,
            replans: 0,
            last_replan: f64::NEG_INFINITY,
            reached: false,
            blocked: false,
            best_distance_m: f64::INFINITY,
            last_progress: now,
            estimated_uncertainty_m: None,
            guarded: false,
            estimate_proven: true,
            unproven_since: None,
            proof_given_up: false,
        };
        follower.restart(now);
        follower
    }

    /// A new goal or a new activation: `goal_reached` and `blocked` are re-armed, and progress
    /// is counted from the next pose.
    fn restart(&mut self, now: f64) {
        self.pursuit = self.settings.pursuit();
        if let Some(pursuit) = &self.pursuit {
            tracing::info!(
                "following the planned path: {} points, {} m",
                pursuit.points().len(),
                geo::round_mm(geo::path_length(pursuit.points()))
            );
        }
        self.via = None;
        self.seen.clear();
        self.map_in_the_way = false;
        self.map_checked = false;
        self.replans = 0;
        self.last_replan = f64::NEG_INFINITY;
        self.reached = false;
        self.blocked = false;
        self.best_distance_m = f64::INFINITY;
        self.last_progress = now;
        self.unproven_since = None;
        self.proof_given_up = false;
    }

    /// What the follower follows, drawn: the path ahead of the robot (or the line to the
    /// corner round a no-go area it heads for, then to the goal) and the goal.
    fn markers(&self) -> Markers {
        const PATH_RGBA: [u8; 4] = [30, 140, 60, 230];
        const GOAL_RGBA: [u8; 4] = [30, 140, 60, 255];
        let goal = self.settings.goal();
        let mut markers = vec![
            Marker::new(Shape::Points, Frame::World, GOAL_RGBA, [(goal.x, goal.y)]),
            Marker::new(Shape::Text, Frame::World, GOAL_RGBA, [(goal.x, goal.y)]).with_text(
                if self.reached {
                    "goal (reached)"
                } else {
                    "goal"
                },
            ),
        ];
        if let Some(pose) = self.pose.filter(|_| !self.reached) {
            let here = Point::new(pose.x_m, pose.y_m);
            let ahead = match &self.pursuit {
                Some(pursuit) => pursuit.ahead(here),
                None => [Some(here), self.via, Some(goal)]
                    .into_iter()
                    .flatten()
                    .collect(),
            };
            let mut line = Marker::new(
                Shape::Polyline,
                Frame::World,
                PATH_RGBA,
                ahead.iter().map(|p| (p.x, p.y)),
            )
            .with_text("path ahead");
            line.size_px = 3.0;
            markers.push(line);
        }
        Markers { markers }
    }

    fn retune(&mut self, settings: Settings, now: f64) {
        if !settings.same_goal(&self.settings) {
            tracing::info!("new goal ({}, {})", settings.goal_x_m, settings.goal_y_m);
            self.settings = settings;
            self.restart(now);
        } else {
            self.settings = settings;
        }
    }

    /// The command from `pose`, the straight distance to the goal and the way left to it
    /// (along the path when there is one).
    fn steer(&mut self, pose: Pose2D) -> Option<(Twist, f64, f64)> {
        match &mut self.pursuit {
            Some(pursuit) => {
                let steer = pursuit.steer(pose, self.settings.limits())?;
                let distance_m =
                    geo::distance(Point::new(pose.x_m, pose.y_m), self.settings.goal());
                Some((steer.twist, distance_m, steer.remaining_m))
            }
            None => steer_round(&self.settings, pose, &mut self.via)
                .map(|(twist, distance_m)| (twist, distance_m, distance_m)),
        }
    }

    pub(crate) fn on_pose(&mut self, pose: Pose2D, now: f64) -> Control {
        let Some((twist, distance_m, remaining_m)) = self.steer(pose) else {
            tracing::warn!("ignoring a non-finite pose {pose:?}");
            return Control {
                twist: Twist::default(),
                report: self.on_tick(now),
                new_path: false,
            };
        };
        if self.reached {
            return Control {
                twist: Twist::default(),
                report: None,
                new_path: false,
            };
        }
        // Neither arrival nor a step on the way is judged by an estimate that is not proven.
        if !self.estimate_proven {
            self.pose = Some(pose);
            return self.turn_for_proof(now);
        }
        if self.unproven_since.take().is_some() {
            tracing::info!("the estimate is proven: driving on");
            // The time spent turning was no lack of progress.
            self.last_progress = now;
        }
        if distance_m <= self.arrival_radius_m() {
            self.reached = true;
            return Control {
                twist: Twist::default(),
                report: Some("goal_reached"),
                new_path: false,
            };
        }
        self.pose = Some(pose);
        let too_close = self.too_close(pose);
        if too_close.is_some() != self.guarded {
            self.guarded = too_close.is_some();
            match too_close {
                Some(area) => tracing::warn!(
                    "stopping: no-go area {} may be within the pose's uncertainty ({:.2} m)",
                    area + 1,
                    self.uncertainty_m()
                ),
                None => tracing::info!("the pose is sure enough again: driving on"),
            }
        }
        if self.guarded {
            return Control {
                twist: Twist::default(),
                report: self.on_tick(now),
                new_path: false,
            };
        }
        if !self.map_checked {
            self.check_map();
        }
        let progress = remaining_m < self.best_distance_m - PROGRESS_M;
        if let Some(control) = self.replan_if_stuck(pose, progress, now) {
            return control;
        }
        let report = if progress {
            self.best_distance_m = remaining_m;
            self.last_progress = now;
            self.blocked = false;
            None
        } else {
            self.on_tick(now)
        };
        Control {
            twist,
            report,
            new_path: false,
        }
    }

    /// While the estimate is not proven (a localiser that searched the map, or suspects the
    /// robot was carried elsewhere, or is lost): the robot does not drive on it, it turns in
    /// place, so that the localiser sees all round and can prove the place by the turn (as
    /// Nav2's spin recovery lets AMCL converge). With no proof after [`PROOF_SECS`] of turning,
    /// it stops and reports `blocked` (once): the mission holds, as for any blocked robot.
    fn turn_for_proof(&mut self, now: f64) -> Control {
        let since = match self.unproven_since {
            Some(since) => since,
            None => {
                tracing::warn!(
                    "the localiser's estimate is not proven: turning in place until it is, for at \
                     most {PROOF_SECS} s"
                );
                self.unproven_since = Some(now);
                now
            }
        };
        if now - since < PROOF_SECS {
            return Control {
                twist: Twist {
                    linear_mps: 0.0,
                    angular_radps: self.settings.max_turn_radps.min(PROOF_TURN_RADPS),
                },
                report: None,
                new_path: false,
            };
        }
        let report = if self.proof_given_up || self.blocked {
            None
        } else {
            tracing::warn!(
                "the localiser's estimate was not proven after {:.1} s of turning in place: \
                 stopping",
                now - since
            );
            self.blocked = true;
            Some("blocked")
        };
        self.proof_given_up = true;
        Control {
            twist: Twist::default(),
            report,
            new_path: false,
        }
    }

    /// A localiser's estimate: how uncertain the pose is (a lost localiser's estimate counts
    /// as uncertain without bound), and whether it is proven.
    pub(crate) fn on_estimate(&mut self, estimate: &PoseEstimate) {
        self.estimate_proven = estimate.proven;
        self.estimated_uncertainty_m = Some(if estimate.state == LocalisationState::Lost {
            f64::INFINITY
        } else {
            UNCERTAINTY_SIGMAS * estimate.position_sigma_m()
        });
    }

    /// How far the true position may be from the pose: the latest estimate's, or what the
    /// system says of a pose source without one.
    fn uncertainty_m(&self) -> f64 {
        self.estimated_uncertainty_m
            .unwrap_or(self.settings.pose_uncertainty_m)
    }

    /// How close to the goal the pose must come to report it reached: `tolerance_m` less the
    /// pose's uncertainty, so that the true position, not only the estimate, is within the
    /// tolerance (a rehearsal judges arrivals by the truth). Never less than half the tolerance:
    /// a robot whose estimate is that unsure would circle the goal for ever, and a lost
    /// localiser holds the mission anyway.
    fn arrival_radius_m(&self) -> f64 {
        let tolerance_m = self.settings.tolerance_m;
        (tolerance_m - self.uncertainty_m()).max(tolerance_m / 2.0)
    }

    /// The no-go area the robot's body may be in or touching, given the pose's uncertainty.
    fn too_close(&self, pose: Pose2D) -> Option<usize> {
        let uncertainty_m = self.uncertainty_m();
        if uncertainty_m <= 0.0 {
            return None;
        }
        let here = Point::new(pose.x_m, pose.y_m);
        let reach = self.settings.robot_radius_m + uncertainty_m;
        self.settings
            .no_go
            .iter()
            .position(|area| area.contains(here) || area.distance_to_outline(here) < reach)
    }

    /// The laser's hits that the world does not explain, placed from the latest pose. With a
    /// live map they are left to the map: the mapper places each scan where its matcher puts
    /// it, where the follower would place it from the pose it has when the scan arrives, which
    /// may be late (on a busy machine, at a high time scale, a scan taken while the robot
    /// turns was placed askew across a doorway it then replanned round, 20 m the long way).
    pub(crate) fn on_scan(&mut self, scan: &LaserScan) {
        if self.pursuit.is_none() || self.live_map.is_some() {
            self.seen.clear();
            return;
        }
        if let Some(pose) = self.pose {
            let world = self.world.as_ref().map(|world| &world.world);
            self.seen = replan::unexplained(world, &replan::scan_hits(pose, scan));
        }
    }

    /// Whether a newer live map is wanted: none yet, a leg not checked against one yet, or
    /// the robot [`MAP_EVERY_M`] from where the last was taken.
    pub(crate) fn wants_map(&self) -> bool {
        let moved = match (self.map_taken_at, self.pose) {
            (Some(at), Some(pose)) => geo::distance(at, Point::new(pose.x_m, pose.y_m)),
            _ => f64::INFINITY,
        };
        self.live_map.is_none()
            || (self.pursuit.is_some() && !self.map_checked)
            || moved >= MAP_EVERY_M
    }

    /// A mapper's live map: kept for replanning, and the path left checked against it.
    pub(crate) fn on_map(&mut self, grid: OccupancyGrid) {
        match LiveMap::new(grid) {
            Some(live) => {
                self.live_map = Some(live);
                self.map_taken_at = self.pose.map(|pose| Point::new(pose.x_m, pose.y_m));
                self.check_map();
            }
            None => tracing::warn!("ignored a map whose cells do not match its size"),
        }
    }

    /// Whether the path left comes nearer a wall of the live map than the robot keeps (with
    /// half its clearance to spare, as for what the laser sees): then the leg is planned
    /// again on the map at the next pose.
    fn check_map(&mut self) {
        let (Some(live), Some(pursuit), Some(pose)) = (&self.live_map, &self.pursuit, self.pose)
        else {
            return;
        };
        self.map_checked = true;
        let here = Point::new(pose.x_m, pose.y_m);
        let keep_m = self.settings.robot_radius_m + self.settings.clearance_m * 0.5;
        self.map_in_the_way =
            replan::blocked_within(&pursuit.ahead(here), live.walls(), keep_m, f64::INFINITY);
    }

    /// The world replanning is done on: the `world` given, else the live map's round `from`
    /// and the goal, else none (the open box round what the laser sees).
    fn plan_world(&self, from: Point) -> Option<WorldMap> {
        if let Some(world) = &self.world {
            return Some(world.clone());
        }
        self.live_map
            .as_ref()
            .and_then(|live| live.world(from, self.settings.goal()))
    }

    /// With a path: plans again when the robot has made no progress for `replan_after_secs`
    /// or the laser sees the path blocked ahead, at most `max_replans` times per leg. `None`
    /// when nothing was done; a replan that finds no way reports `blocked` and stops.
    fn replan_if_stuck(&mut self, pose: Pose2D, progress: bool, now: f64) -> Option<Control> {
        let settings = &self.settings;
        let pursuit = self.pursuit.as_ref()?;
        if self.blocked {
            return None;
        }
        let here = Point::new(pose.x_m, pose.y_m);
        // Replans for lack of progress or what the laser sees are recoveries, bounded by
        // `max_replans`; one for a wall of the live map is the leg planned on what is known,
        // bounded only by `replan_after_secs` between two.
        let recovering = self.replans < settings.max_replans;
        let stuck = recovering
            && !progress
            && self.best_distance_m.is_finite()
            && now - self.last_progress >= settings.replan_after_secs;
        let seen_in_the_way = recovering
            && !self.seen.is_empty()
            && now - self.last_replan >= settings.replan_after_secs
            && replan::blocked_ahead(
                &pursuit.ahead(here),
                &self.seen,
                settings.robot_radius_m + settings.clearance_m * 0.5,
            );
        let map_in_the_way =
            self.map_in_the_way && now - self.last_replan >= settings.replan_after_secs;
        if !stuck && !seen_in_the_way && !map_in_the_way {
            return None;
        }
        let robot = Robot {
            radius_m: settings.robot_radius_m,
            clearance_m: settings.clearance_m,
        };
        let keepouts = settings.keepouts();
        let why = if stuck {
            "no progress"
        } else if seen_in_the_way {
            "the laser sees something in the way"
        } else {
            "the live map has a wall in the way"
        };
        if stuck || seen_in_the_way {
            self.replans += 1;
        }
        self.map_in_the_way = false;
        self.last_replan = now;
        let world = self.plan_world(here);
        let settings = &self.settings;
        match replan::replan(
            world.as_ref(),
            &robot,
            &keepouts,
            &self.seen,
            here,
            settings.goal(),
        ) {
            Ok(path) => {
                tracing::info!(
                    "replanned: {} points, {} m ({why}; replan {} of {})",
                    path.points.len(),
                    geo::round_mm(path.length_m),
                    self.replans,
                    settings.max_replans
                );
                self.pursuit = Some(Pursuit::new(path.points));
                self.best_distance_m = f64::INFINITY;
                self.last_progress = now;
                // The new path is steered on from this pose: a command of zero in between
                // would stop the robot for a step at every replan (the bench's updates saw it).
                let twist = self
                    .steer(pose)
                    .map_or_else(Twist::default, |(twist, _, _)| twist);
                Some(Control {
                    twist,
                    report: None,
                    new_path: true,
                })
            }
            // What the laser sees is placed with the odometry, which drifts: a door's jambs seen
            // a little off close the door. The map alone decides whether there is no way.
            Err(err)
                if !self.seen.is_empty()
                    && replan::replan(
                        world.as_ref(),
                        &robot,
                        &keepouts,
                        &[],
                        here,
                        settings.goal(),
                    )
                    .is_ok() =>
            {
                tracing::warn!(
                    "replanning ({why}) found no way round what the laser sees ({err}); \
                     keeping the path (replan {} of {})",
                    self.replans,
                    settings.max_replans
                );
                None
            }
            // A live map is drawn from scans placed by a pose that drifts too, and a doorway
            // seen from afar may look closed on it: the path planned on what the operator drew
            // is kept, and the laser and the next map decide.
            Err(err) if !stuck && !seen_in_the_way => {
                tracing::warn!("replanning on the live map found no way ({err}); keeping the path");
                None
            }
            Err(err) => {
                tracing::warn!("replanning ({why}) found no way to the goal: {err}");
                self.replans = settings.max_replans;
                self.blocked = true;
                Some(Control {
                    twist: Twist::default(),
                    report: Some("blocked"),
                    new_path: false,
                })
            }
        }
    }

    /// Reports `blocked` (once) when there was no progress for long enough. Progress is timed
    /// from the first pose after a (re)start: without a pose, the follower cannot tell a robot
    /// that does not move from one whose odometry has not arrived yet (modules link up in any
    /// order, and at high time scales that takes seconds of run time).
    fn on_tick(&mut self, now: f64) -> Option<&'static str> {
        let has_pose = self.best_distance_m.is_finite();
        if !has_pose
            || self.reached
            || self.blocked
            || now - self.last_progress < self.settings.blocked_after_secs
        {
            return None;
        }
        self.blocked = true;
        tracing::warn!(
            "no progress towards the goal for {:.1} s",
            now - self.last_progress
        );
        Some("blocked")
    }
}

/// The command from `pose` along the way round the no-go areas, and the straight distance to
/// the goal (`None` if the pose is not finite). Without a way round, the command is to stop.
///
/// `via` is the corner headed for at the previous pose: the follower keeps to it while the way
/// through it is not [`SWITCH_M`] longer than the shortest, so that two nearly equal ways round
/// an area (and the avoider's swerves) do not make it waver between them.
fn steer_round(settings: &Settings, pose: Pose2D, via: &mut Option<Point>) -> Option<(Twist, f64)> {
    let goal = Point::new(settings.goal_x_m, settings.goal_y_m);
    let here = Point::new(pose.x_m, pose.y_m);
    let distance_m = geo::distance(here, goal);
    if settings.no_go.is_empty() || !distance_m.is_finite() {
        *via = None;
        return steer(settings, pose, goal, distance_m).map(|twist| (twist, distance_m));
    }
    let way = |from: Point| geo::route(from, goal, &settings.no_go, CLEARANCE_M, &[], &|_, _| true);
    let Some(route) = way(here) else {
        tracing::debug!("no way round the no-go areas from {here}");
        *via = None;
        return Some((Twist::default(), distance_m));
    };
    let mut target = route[0];
    let mut remaining_m = geo::distance(here, target) + geo::path_length(&route);
    if let Some(previous) = *via
        && previous != target
        && geo::distance(here, previous) > VIA_REACHED_M
        && !settings
            .no_go
            .iter()
            .any(|area| area.blocks(here, previous, CLEARANCE_M * 0.9))
        && let Some(rest) = way(previous)
    {
        let through_m = geo::distance(here, previous)
            + geo::distance(previous, rest[0])
            + geo::path_length(&rest);
        if through_m <= remaining_m + SWITCH_M {
            target = previous;
            remaining_m = through_m;
        }
    }
    *via = (target != goal).then_some(target);
    steer(settings, pose, target, remaining_m).map(|twist| (twist, distance_m))
}

/// The command towards `target` from `pose`, slowing down when `remaining_m` (the way left to
/// the goal) is short; `None` if the pose is not finite.
fn steer(settings: &Settings, pose: Pose2D, target: Point, remaining_m: f64) -> Option<Twist> {
    let dx = target.x - pose.x_m;
    let dy = target.y - pose.y_m;
    let heading_error = wrap_angle(dy.atan2(dx) - pose.theta_rad);
    if !remaining_m.is_finite() || !heading_error.is_finite() {
        return None;
    }
    let angular_radps =
        (TURN_GAIN * heading_error).clamp(-settings.max_turn_radps, settings.max_turn_radps);
    // Full speed when facing the goal, nothing from 90° off (turn on the spot first).
    let facing = heading_error.cos().max(0.0);
    let near = (remaining_m / SLOW_DOWN_M).min(1.0);
    Some(Twist {
        linear_mps: settings.max_speed_mps * facing * near,
        angular_radps,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};
    use std::f64::consts::PI;

    fn settings_with(no_go: &str) -> Settings {
        Settings {
            goal_x_m: 10.0,
            no_go: geo::parse_polygons(no_go).expect("polygons"),
            ..settings()
        }
    }

    #[test]
    fn no_go_areas_are_driven_round() {
        let facing_goal = Pose2D {
            x_m: 0.0,
            y_m: 0.0,
            theta_rad: 0.0,
        };
        // Straight on without areas.
        let (twist, distance) =
            steer_round(&settings_with(""), facing_goal, &mut None).expect("finite");
        assert_eq!(distance, 10.0);
        assert_eq!(twist.angular_radps, 0.0);
        assert!(twist.linear_mps > 0.5);
        // A box across the line, longer to the north: the way round is south, so it turns right.
        let (twist, distance) =
            steer_round(&settings_with("4,-2 6,-2 6,3 4,3"), facing_goal, &mut None)
                .expect("finite");
        assert_eq!(distance, 10.0);
        assert!(twist.angular_radps < -0.1, "{twist:?}");
        // Walled in: no way round, so it stops (and `blocked` will follow).
        let (twist, _) = steer_round(
            &settings_with("-3,-3 -2,-3 -2,3 -3,3; 2,-3 3,-3 3,3 2,3; -3,2 3,2 3,3 -3,3; -3,-3 3,-3 3,-2 -3,-2"),
            facing_goal,
            &mut None,
        )
        .expect("finite");
        assert_eq!(twist, Twist::default());
    }

    #[test]
    fn a_path_is_driven_instead_of_the_way_round_the_no_go_areas() {
        // The straight way round the box is south (see above); the planned path goes north,
        // so the follower turns left, and the areas are left to the path.
        let mut bench = bench(&[
            ("goal_x_m", "10"),
            ("no_go", "4,-2 6,-2 6,3 4,3"),
            ("path", "0,0 2,4 8,4 10,0"),
        ]);
        bench.script([at(0.0, 0.0, 1.1), at(5.0, 4.0, 0.0), at(9.9, 0.1, -1.1)]);
        body(bench.node()).expect("body");
        let sent = sent(&bench);
        assert!(
            sent[0].linear_mps > 0.3,
            "along the first stretch: {sent:?}"
        );
        assert!(
            sent[1].angular_radps.abs() < 1e-6,
            "north of the box: {sent:?}"
        );
        assert!(sent[1].linear_mps > 0.5, "{sent:?}");
        assert_eq!(sent[2], Twist::default());
        assert_eq!(bench.reported(), ["goal_reached"]);
        let err = body(bench_with(&[("path", "0,0 x")]).node()).expect_err("refused");
        assert!(err.to_string().contains("parameter `path`"), "{err}");
    }

    fn follower_on(path: &str, goal_x_m: f64) -> Follower {
        Follower::new(
            Settings {
                goal_x_m,
                goal_y_m: 5.0,
                path: Path::parse(path).expect("path"),
                ..settings()
            },
            0.0,
        )
    }

    /// The pose at `x_m` on the line y = 5, facing east.
    fn east_at(x_m: f64) -> Pose2D {
        Pose2D {
            x_m,
            y_m: 5.0,
            theta_rad: 0.0,
        }
    }

    #[test]
    fn a_path_seen_blocked_ahead_is_planned_again_round_what_is_seen() {
        let mut follower = follower_on("0,5 15,5", 15.0);
        assert!(!follower.on_pose(east_at(1.0), 1.0).new_path);
        // A wall across the way 2 m ahead, from y 0 to 7 (no world: the laser alone).
        follower.seen = (0..=70)
            .map(|i| Point::new(3.0, f64::from(i) * 0.1))
            .collect();
        let control = follower.on_pose(east_at(1.0), 1.1);
        assert!(control.new_path, "{control:?}");
        // It steers on the new path at once: no command of zero for the replan.
        assert!(
            control.twist.linear_mps != 0.0 || control.twist.angular_radps != 0.0,
            "{control:?}"
        );
        let points = follower.pursuit.as_ref().expect("path").points().to_vec();
        assert!(
            points.iter().any(|p| p.y > 7.0),
            "round the north end: {points:?}"
        );
        assert_eq!(follower.replans, 1);
        // Walled in all round: no way, `blocked` at once.
        follower.seen = (0..200)
            .map(|i| {
                let angle = std::f64::consts::TAU * f64::from(i) / 200.0;
                Point::new(1.0 + 1.5 * angle.cos(), 5.0 + 1.5 * angle.sin())
            })
            .collect();
        follower.last_replan = f64::NEG_INFINITY;
        follower.pursuit = follower.settings.pursuit();
        // Walled in by what the laser sees, but not on the map: the laser may be placed off
        // (odometry drifts), so the path is kept and the avoider keeps the robot safe.
        let control = follower.on_pose(east_at(1.0), 5.0);
        assert_eq!(control.report, None);
        assert!(!control.new_path);
        assert_eq!(follower.replans, 2);
        // The goal in a no-go area: the map alone has no way, `blocked` at once.
        follower.settings.no_go = geo::parse_polygons("14,4 16,4 16,6 14,6").expect("polygon");
        follower.last_replan = f64::NEG_INFINITY;
        let control = follower.on_pose(east_at(1.0), 9.0);
        assert_eq!(control.report, Some("blocked"));
        assert_eq!(control.twist, Twist::default());
    }

    /// A mapper's grid of the box 0..20 × 0..10 at 0.1 m, unknown but for the cells given as
    /// walls (100) and the row y = 5 seen free.
    fn live_grid(walls: impl Fn(f64, f64) -> bool) -> OccupancyGrid {
        let (width, height) = (200_u32, 100_u32);
        let mut cells = vec![-1_i8; (width * height) as usize];
        for row in 0..height {
            for col in 0..width {
                let (x, y) = (f64::from(col) * 0.1 + 0.05, f64::from(row) * 0.1 + 0.05);
                let index = (row * width + col) as usize;
                if walls(x, y) {
                    cells[index] = 100;
                } else if (y - 5.0).abs() < 0.1 {
                    cells[index] = 0;
                }
            }
        }
        OccupancyGrid {
            resolution_m: 0.1,
            width,
            height,
            origin_x_m: 0.0,
            origin_y_m: 0.0,
            cells,
        }
    }

    #[test]
    fn a_leg_is_planned_on_the_live_map_at_once_without_using_up_replans() {
        let mut follower = follower_on("1,5 15,5", 15.0);
        // Two walls the mapper has seen across the way: at x = 4 from y 0 to 7, at x = 8
        // from y 3 to 10. The laser in view of neither: nothing seen in the way.
        follower.on_map(live_grid(|x, y| {
            ((x - 4.0).abs() < 0.1 && y < 7.0) || ((x - 8.0).abs() < 0.1 && y > 3.0)
        }));
        let control = follower.on_pose(east_at(1.0), 1.0);
        assert!(control.new_path, "{control:?}");
        assert_eq!(
            follower.replans, 0,
            "a leg planned on the map is not a recovery"
        );
        let points = follower.pursuit.as_ref().expect("path").points().to_vec();
        // Round both walls at once (the way round the second, still unseen beyond the map's
        // walls, is taken as open): every point of the path as far from every wall as the
        // robot keeps, but for the cells' half width.
        let walls = follower.live_map.as_ref().expect("a map").walls().to_vec();
        let samples = points.windows(2).flat_map(|pair| {
            let (a, b) = (pair[0], pair[1]);
            let steps = (geo::distance(a, b) / 0.05).ceil().max(1.0) as usize;
            (0..=steps).map(move |i| {
                let t = i as f64 / steps as f64;
                Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t)
            })
        });
        let nearest = samples
            .flat_map(|p| walls.iter().map(move |w| geo::distance(p, *w)))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest >= 0.35 - 0.05, "{nearest} m: {points:?}");
        // The same map again: the path keeps clear of it, nothing to plan.
        follower.on_map(live_grid(|x, y| {
            ((x - 4.0).abs() < 0.1 && y < 7.0) || ((x - 8.0).abs() < 0.1 && y > 3.0)
        }));
        assert!(!follower.on_pose(east_at(1.05), 10.0).new_path);
        // What the laser sees is left to the map.
        follower.seen = vec![Point::new(4.0, 6.0)];
        let scan = LaserScan {
            angle_min_rad: 0.0,
            angle_increment_rad: 0.1,
            range_max_m: 8.0,
            ranges_m: vec![3.0],
        };
        follower.on_scan(&scan);
        assert!(follower.seen.is_empty(), "{:?}", follower.seen);
    }

    #[test]
    fn no_progress_replans_a_bounded_number_of_times_then_blocked() {
        let mut follower = follower_on("0,5 5,5", 5.0);
        let still = Pose2D {
            x_m: 1.0,
            y_m: 5.0,
            theta_rad: 0.0,
        };
        let mut replans = 0;
        let mut reports = Vec::new();
        for step in 0..400 {
            let control = follower.on_pose(still, f64::from(step) * 0.25);
            replans += usize::from(control.new_path);
            reports.extend(control.report);
        }
        assert_eq!(replans, 3, "max_replans");
        assert_eq!(
            reports,
            ["blocked"],
            "after the replans, blocked_after_secs"
        );
    }

    fn bench_with(params: &[(&str, &str)]) -> TestBench {
        bench(params)
    }

    #[test]
    fn replans_keep_each_area_s_own_margin() {
        let mut settings = settings_with("4,-2 6,-2 6,3 4,3; 8,1 9,1 9,2");
        assert_eq!(
            settings
                .keepouts()
                .iter()
                .map(|keepout| keepout.margin_m)
                .collect::<Vec<_>>(),
            [planner::DEFAULT_AREA_MARGIN_M; 2]
        );
        settings.no_go_margins_m = parse_margins(" 2 ;0.5").expect("margins");
        let keepouts = settings.keepouts();
        assert_eq!(keepouts[0].margin_m, 2.0);
        assert_eq!(keepouts[1].margin_m, 0.5);
        for (margins, says) in [
            ("1;wide", "`wide` is not a distance"),
            ("-1", "`-1` is not a distance"),
            ("1", "1 margin(s) for 2 no-go area(s)"),
        ] {
            let mut bench = bench(&[
                ("no_go", "4,-2 6,-2 6,3 4,3; 8,1 9,1 9,2"),
                ("no_go_margins_m", margins),
            ]);
            let err = body(bench.node()).expect_err("refused");
            assert!(
                err.to_string().contains("parameter `no_go_margins_m`")
                    && err.to_string().contains(says),
                "{margins}: {err}"
            );
        }
    }

    #[test]
    fn bad_no_go_text_is_refused_in_words() {
        let mut bench = TestBench::new(
            &spec(),
            &[("goal_x_m", "2"), ("goal_y_m", "0"), ("no_go", "0,0 1,0")],
        )
        .expect("bench");
        let err = body(bench.node()).expect_err("refused");
        assert!(
            err.to_string()
                .contains("parameter `no_go`: polygon 1 has 2 corners"),
            "{err}"
        );
    }

    fn bench(params: &[(&str, &str)]) -> TestBench {
        let mut all = vec![("goal_x_m", "2"), ("goal_y_m", "0")];
        all.extend_from_slice(params);
        TestBench::new(&spec(), &all).expect("bench")
    }

    fn odometry(x_m: f64, y_m: f64, theta_rad: f64) -> Odometry {
        Odometry {
            pose_in_odom: Pose2D {
                x_m,
                y_m,
                theta_rad,
            },
            twist: Twist::default(),
        }
    }

    fn at(x_m: f64, y_m: f64, theta_rad: f64) -> Step {
        Step::push("odometry", &odometry(x_m, y_m, theta_rad)).expect("step")
    }

    fn sent(bench: &TestBench) -> Vec<Twist> {
        bench.sent::<Twist>("cmd_desired").expect("sent")
    }

    /// The defaults, with the goal 5 m ahead.
    fn settings() -> Settings {
        Settings {
            goal_x_m: 5.0,
            goal_y_m: 0.0,
            tolerance_m: 0.3,
            max_speed_mps: 0.6,
            max_turn_radps: 1.2,
            blocked_after_secs: 10.0,
            no_go: Vec::new(),
            no_go_margins_m: Vec::new(),
            path: Path::default(),
            world: String::new(),
            robot_radius_m: 0.25,
            clearance_m: 0.1,
            replan_after_secs: 3.0,
            max_replans: 3,
            pose_uncertainty_m: 0.0,
        }
    }

    #[test]
    fn requires_a_goal_and_refuses_bad_settings() {
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        let err = body(bench.node()).expect_err("no goal");
        assert!(err.to_string().contains("goal_x_m"), "{err}");
        let mut bench = bench_with_bad_tolerance();
        let err = body(bench.node()).expect_err("bad tolerance");
        assert!(err.to_string().contains("`tolerance_m` must be"), "{err}");
    }

    fn bench_with_bad_tolerance() -> TestBench {
        bench(&[("tolerance_m", "0")])
    }

    #[test]
    fn drives_towards_the_goal_and_reports_it_reached_once() {
        let mut bench = bench(&[]);
        bench.script([
            at(0.0, 0.0, 0.0),
            at(1.5, 0.0, 0.0),
            at(1.8, 0.05, 0.0),
            at(1.85, 0.0, 0.0),
            at(1.9, 0.0, 0.0),
        ]);
        body(bench.node()).expect("body");
        let sent = sent(&bench);
        assert_eq!(sent.len(), 3, "nothing proposed once the goal is reached");
        assert!((sent[0].linear_mps - 0.6).abs() < 1e-9, "{:?}", sent[0]);
        assert!(sent[0].angular_radps.abs() < 1e-9);
        assert!(
            sent[1].linear_mps > 0.0 && sent[1].linear_mps < sent[0].linear_mps,
            "slows down near the goal: {sent:?}"
        );
        assert_eq!(sent[2], Twist::default());
        assert_eq!(bench.reported(), ["goal_reached"]);
        assert_eq!(bench.behaviour(), ["applicable", "not applicable"]);
    }

    #[test]
    fn steers_towards_a_goal_off_to_the_side() {
        let mut bench = bench(&[]);
        bench.script([at(2.0, -3.0, 0.0), at(2.0, 3.0, 0.0)]);
        body(bench.node()).expect("body");
        let sent = sent(&bench);
        assert!(sent[0].angular_radps > 0.0, "goal on the left: {sent:?}");
        assert!(sent[1].angular_radps < 0.0, "goal on the right: {sent:?}");
        for twist in &sent {
            assert!(twist.angular_radps.abs() <= 1.2 + 1e-12);
            assert!(twist.linear_mps.abs() < 1e-9, "90° off: turn first");
        }
    }

    #[test]
    fn turns_first_when_the_goal_is_behind() {
        let mut bench = bench(&[]);
        bench.script([at(0.0, 0.0, PI), at(0.0, 0.0, PI - 0.3), at(0.0, 0.0, 0.1)]);
        body(bench.node()).expect("body");
        let sent = sent(&bench);
        for twist in &sent[..2] {
            assert_eq!(twist.linear_mps, 0.0, "{sent:?}");
            assert_eq!(twist.angular_radps.abs(), 1.2, "turns as fast as allowed");
        }
        assert!(sent[1].angular_radps < 0.0, "the short way round: {sent:?}");
        assert!(sent[2].linear_mps > 0.5, "facing it again: {sent:?}");
    }

    #[test]
    fn a_new_goal_re_arms_goal_reached() {
        let mut bench = bench(&[]);
        bench.script([
            at(1.9, 0.0, 0.0),
            at(1.9, 0.0, 0.0),
            Step::param("goal_x_m", "5"),
            at(1.9, 0.0, 0.0),
            at(4.8, 0.1, 0.0),
        ]);
        body(bench.node()).expect("body");
        let sent = sent(&bench);
        // Arrived at once: one zero, then nothing proposed until the new goal.
        assert_eq!(sent[0], Twist::default());
        assert!(sent[1].linear_mps > 0.5, "drives to the new goal: {sent:?}");
        assert_eq!(sent[2..], [Twist::default()]);
        assert_eq!(bench.reported(), ["goal_reached", "goal_reached"]);
    }

    #[test]
    fn a_bad_live_goal_is_refused_and_the_old_one_kept() {
        let mut bench = bench(&[]);
        bench.script([
            at(1.9, 0.0, 0.0),
            Step::param("goal_x_m", "far"),
            at(1.9, 0.0, 0.0),
        ]);
        body(bench.node()).expect("a bad value does not end the module");
        assert_eq!(sent(&bench), [Twist::default()], "nothing once arrived");
        assert_eq!(bench.reported(), ["goal_reached"]);
    }

    #[test]
    fn reports_blocked_once_when_odometry_stops_changing() {
        let mut bench = bench(&[]);
        bench.script([
            at(0.0, 0.0, 0.0),
            at(0.5, 0.0, 0.0),
            // From now on, no progress is tolerated for any time at all.
            Step::param("blocked_after_secs", "0"),
            at(0.5, 0.0, 0.0),
            at(0.5, 0.0, 0.0),
            Step::Timeouts(2),
            // Progress re-arms it.
            at(1.0, 0.0, 0.0),
            at(1.0, 0.0, 0.0),
        ]);
        body(bench.node()).expect("body");
        assert_eq!(bench.reported(), ["blocked", "blocked"]);
        assert!(
            sent(&bench).iter().all(|twist| twist.linear_mps > 0.0),
            "it keeps trying"
        );
    }

    #[test]
    fn the_body_reports_blocked_only_after_blocked_after_secs_of_run_time() {
        // `blocked_after_secs` is 10: the run clock jumps without any progress.
        for (jump_secs, expected) in [(9.0, &[][..]), (10.5, &["blocked"][..])] {
            let mut bench = bench(&[]);
            bench.script([
                at(0.0, 0.0, 0.0),
                Step::Advance(jump_secs),
                at(0.0, 0.0, 0.0),
                Step::Timeouts(1),
            ]);
            body(bench.node()).expect("body");
            assert_eq!(bench.reported(), expected, "after {jump_secs} s");
        }
    }

    #[test]
    fn no_blocked_before_the_first_pose() {
        // Twice `blocked_after_secs` without odometry (the sim not linked yet): nothing to time.
        // Then the first pose starts the clock, and only no progress after it counts.
        for (after_pose_secs, expected) in [(9.0, &[][..]), (10.5, &["blocked"][..])] {
            let mut bench = bench(&[]);
            bench.script([
                Step::Timeouts(1),
                Step::Advance(20.0),
                Step::Timeouts(2),
                at(0.0, 0.0, 0.0),
                Step::Advance(after_pose_secs),
                Step::Timeouts(1),
            ]);
            body(bench.node()).expect("body");
            assert_eq!(bench.reported(), expected, "{after_pose_secs} s after");
        }

        // The same after a restart: progress is timed from the next pose.
        let mut follower = Follower::new(settings(), 0.0);
        assert_eq!(follower.on_tick(50.0), None, "no pose yet");
        assert_eq!(follower.on_pose(Pose2D::default(), 50.0).report, None);
        assert_eq!(follower.on_tick(59.0), None);
        assert_eq!(follower.on_tick(60.0), Some("blocked"));
        follower.restart(70.0);
        assert_eq!(follower.on_tick(100.0), None, "no pose since the restart");
    }

    #[test]
    fn the_goal_is_reached_only_when_the_uncertain_pose_is_truly_within_tolerance() {
        let on_axis = |x_m| Pose2D {
            x_m,
            y_m: 0.0,
            theta_rad: 0.0,
        };
        let estimate = |sigma_m: f64, state| PoseEstimate {
            pose_in_map: Pose2D::default(),
            covariance: PoseEstimate::diagonal_covariance(sigma_m, 0.1),
            fit: 0.9,
            state,
            proven: true,
        };
        // Without an estimate, the tolerance alone (0.3 m).
        let mut follower = Follower::new(settings(), 0.0);
        assert_eq!(
            follower.on_pose(on_axis(4.75), 1.0).report,
            Some("goal_reached")
        );

        // Two standard deviations of 0.05 m: 0.25 m from the goal is not yet sure to be within
        // 0.3 m of it, 0.19 m is.
        let mut follower = Follower::new(settings(), 0.0);
        follower.on_estimate(&estimate(0.05, LocalisationState::Localised));
        let control = follower.on_pose(on_axis(4.75), 1.0);
        assert_eq!(control.report, None);
        assert!(control.twist.linear_mps > 0.0, "drives on: {control:?}");
        assert_eq!(
            follower.on_pose(on_axis(4.81), 2.0).report,
            Some("goal_reached")
        );

        // A pose source without an estimate, with the uncertainty its system states.
        let mut follower = Follower::new(
            Settings {
                pose_uncertainty_m: 0.15,
                ..settings()
            },
            0.0,
        );
        assert_eq!(follower.on_pose(on_axis(4.8), 1.0).report, None);
        assert_eq!(
            follower.on_pose(on_axis(4.86), 2.0).report,
            Some("goal_reached")
        );

        // An estimate too unsure for that still arrives within half the tolerance.
        let mut follower = Follower::new(settings(), 0.0);
        follower.on_estimate(&estimate(1.0, LocalisationState::Uncertain));
        assert_eq!(follower.on_pose(on_axis(4.8), 1.0).report, None);
        assert_eq!(
            follower.on_pose(on_axis(4.86), 2.0).report,
            Some("goal_reached")
        );
    }

    #[test]
    fn blocked_waits_for_blocked_after_secs_of_run_time() {
        let pose = Pose2D::default();
        let mut follower = Follower::new(settings(), 100.0);
        assert_eq!(follower.on_pose(pose, 100.0).report, None);
        assert_eq!(follower.on_pose(pose, 109.0).report, None);
        assert_eq!(follower.on_tick(109.9), None);
        assert_eq!(follower.on_tick(110.0), Some("blocked"));
        assert_eq!(follower.on_pose(pose, 115.0).report, None, "once");
        let closer = Pose2D { x_m: 1.0, ..pose };
        assert_eq!(follower.on_pose(closer, 116.0).report, None);
        assert_eq!(follower.on_tick(125.0), None);
        assert_eq!(follower.on_tick(126.0), Some("blocked"));
        follower.restart(130.0);
        assert_eq!(follower.on_tick(139.0), None, "activation re-arms it");
    }

    #[test]
    fn commands_nothing_when_stopped_and_re_arms_on_start() {
        let mut bench = bench(&[]);
        bench.script([
            at(1.9, 0.0, 0.0),
            Step::Active(false),
            at(0.0, 0.0, 0.0),
            Step::Timeouts(3),
            at(0.0, 0.0, 0.0),
            Step::Active(true),
            at(1.9, 0.0, 0.0),
        ]);
        body(bench.node()).expect("body");
        assert_eq!(
            sent(&bench),
            [Twist::default(); 3],
            "at the goal, one zero when stopped, nothing while inactive, at the goal again"
        );
        assert_eq!(bench.reported(), ["goal_reached", "goal_reached"]);
    }

    #[test]
    fn a_non_finite_pose_commands_zero() {
        let mut bench = bench(&[]);
        bench.script([at(f64::NAN, 0.0, 0.0), at(0.0, 0.0, f64::INFINITY)]);
        body(bench.node()).expect("body");
        assert_eq!(sent(&bench), [Twist::default(); 2]);
    }
}
