//! Paths on the map: a costmap of the world the plan is drawn on, and the shortest way across
//! it that keeps the robot clear of obstacles and no-go areas.
//!
//! The same pure code serves `armor check` and `armor compile` (every leg planned at plan
//! time), the studio (legs drawn as their paths) and the follower (the path driven).
//!
//! ```
//! use armor_model::planner::{Keepout, Planner, Robot, plan_path};
//! use armor_model::world::{Point, World};
//!
//! let world = World::parse(
//!     "name room\norigin 0 0\nstart 1 1 0\nboundary 0,0 10,0 10,10 0,10 0,0\nrect 4,0 5,8\n",
//!     "room.world",
//! ).unwrap();
//! let path = plan_path(Some(&world), &Robot::default(), &[], Point::new(2.0, 2.0), Point::new(8.0, 2.0))
//!     .unwrap();
//! assert!(path.length_m > 12.0); // round the end of the block, at y = 8
//! ```
//!
//! # How
//!
//! * **Costmap** ([`Costmap`]): the world rasterised (5 cm by default): the boundary's outside,
//!   obstacles and every wall or edge occupy cells. A Euclidean distance transform gives each
//!   cell's distance to them; cells closer than the robot's radius plus its clearance are
//!   lethal, and a cost that falls off over [`CostmapSettings::falloff_m`] beyond keeps paths
//!   off walls where there is room. No-go areas are lethal within their own margin (the exact
//!   distance to their outline, cell by cell). The lethal test errs on the safe side by half a
//!   cell's diagonal, and where the distance transform cannot tell, the cell's centre is
//!   measured against the world's geometry itself; so every point of a segment that crosses
//!   only free cells keeps the clearance from the real walls, not just from their pixels.
//! * **Search**: A* on the 8-connected grid, with integer costs and a bucket queue (see
//!   ARCHITECTURE.md for why not the `pathfinding` crate, which the benchmark runs beside it).
//! * **Smoothing**: the grid path is pulled straight (line of sight over free cells), and a
//!   shortcut is taken only when it costs no more than the stretch it replaces, so that a path
//!   that kept off a wall does not get pulled back against it.
//! * **When there is no path** ([`PathError::Cut`]): the widest way (the path that keeps
//!   furthest from everything, a max-min flood over the distances) and its narrowest point: the
//!   place and width of the passage the robot does not fit through.

mod costmap;
#[doc(hidden)]
pub mod random;
mod search;
#[cfg(test)]
mod tests;

use std::fmt;

use crate::geo::{self, Polygon};
use crate::world::{Bounds, Point, World, shape_origin};

pub use costmap::{Costmap, CostmapError, LETHAL};
pub use search::{Planner, heuristic, step_cost};

/// The cell size of a costmap, unless told otherwise.
pub const DEFAULT_RESOLUTION_M: f64 = 0.05;
/// The robot's radius when neither the plan nor its system says (the simulator's default).
pub const DEFAULT_ROBOT_RADIUS_M: f64 = 0.25;
/// How far the robot's body keeps from obstacles beyond its radius, unless told otherwise.
pub const DEFAULT_CLEARANCE_M: f64 = 0.1;
/// How far the robot's body keeps from a no-go area unless the area says: with the default
/// radius, the robot's centre keeps 1 m off, as routes always did.
pub const DEFAULT_AREA_MARGIN_M: f64 = 0.75;
/// How far beyond the clearance the cost of being near a wall falls to nothing.
pub const DEFAULT_FALLOFF_M: f64 = 0.5;
/// The largest costmap built: beyond this many cells, cells are made larger (16 M cells of
/// about 14 bytes: the map and one search).
pub const DEFAULT_MAX_CELLS: usize = 16_000_000;

/// The robot as the planner sees it: a disc, and the room it keeps from obstacles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Robot {
    pub radius_m: f64,
    /// How far the disc keeps from walls and obstacles.
    pub clearance_m: f64,
}

impl Default for Robot {
    fn default() -> Self {
        Self {
            radius_m: DEFAULT_ROBOT_RADIUS_M,
            clearance_m: DEFAULT_CLEARANCE_M,
        }
    }
}

impl Robot {
    /// How far the robot's centre keeps from obstacles: radius plus clearance.
    pub fn keep_m(&self) -> f64 {
        self.radius_m + self.clearance_m
    }
}

/// An area the robot keeps out of (a plan's no-go area), and how far its body stays off it.
#[derive(Clone, Debug, PartialEq)]
pub struct Keepout {
    pub name: String,
    pub polygon: Polygon,
    pub margin_m: f64,
}

impl Keepout {
    pub fn new(name: impl Into<String>, polygon: Polygon, margin_m: f64) -> Self {
        Self {
            name: name.into(),
            polygon,
            margin_m,
        }
    }

    /// How far the robot's centre keeps from the area: its radius plus the area's margin.
    pub fn keep_m(&self, robot: &Robot) -> f64 {
        robot.radius_m + self.margin_m
    }
}

/// How a costmap is built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostmapSettings {
    /// The cell size (made larger when the map would exceed `max_cells`).
    pub resolution_m: f64,
    /// Beyond the clearance, the cost of passing near a wall falls to 0 over this distance.
    pub falloff_m: f64,
    pub max_cells: usize,
}

impl Default for CostmapSettings {
    fn default() -> Self {
        Self {
            resolution_m: DEFAULT_RESOLUTION_M,
            falloff_m: DEFAULT_FALLOFF_M,
            max_cells: DEFAULT_MAX_CELLS,
        }
    }
}

/// A planned path: the polyline to drive in the world frame, from the start to the goal.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Path {
    pub points: Vec<Point>,
    pub length_m: f64,
}

impl Path {
    pub fn new(points: Vec<Point>) -> Self {
        let length_m = geo::path_length(&points);
        Self { points, length_m }
    }

    /// `X,Y X,Y …` in metres to the millimetre: the form of the follower's `path` parameter.
    pub fn format(&self) -> String {
        let mut text = String::with_capacity(self.points.len() * 16);
        for (index, point) in self.points.iter().enumerate() {
            if index > 0 {
                text.push(' ');
            }
            geo::push_mm(&mut text, point.x);
            text.push(',');
            geo::push_mm(&mut text, point.y);
        }
        text
    }

    /// Reads [`Path::format`]'s form; an empty text is an empty path.
    pub fn parse(text: &str) -> Result<Path, String> {
        let mut points = Vec::new();
        for pair in text.split_whitespace() {
            let point = pair
                .split_once(',')
                .and_then(|(x, y)| Some(Point::new(x.parse().ok()?, y.parse().ok()?)))
                .filter(|p| p.is_finite())
                .ok_or_else(|| format!("`{pair}` is not a point `X,Y` in metres"))?;
            points.push(point);
        }
        Ok(Path::new(points))
    }
}

/// Which end of a path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    Start,
    Goal,
}

/// Why the robot cannot be at a place.
#[derive(Clone, Debug, PartialEq)]
pub enum Blocker {
    /// Outside the world's boundary (or, with no world, outside the map).
    OutsideWorld,
    /// Inside the obstacle on this line of the world file.
    InObstacle {
        line: usize,
    },
    /// Closer to a wall, obstacle or the boundary than the robot keeps.
    NearObstacle {
        /// `wall`, `obstacle` or `boundary`.
        kind: &'static str,
        line: usize,
        distance_m: f64,
        keep_m: f64,
    },
    InArea {
        name: String,
    },
    NearArea {
        name: String,
        distance_m: f64,
        keep_m: f64,
    },
    /// Far enough from everything, but hemmed in: no free cell to set off from.
    NoRoom,
}

impl fmt::Display for Blocker {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mm = geo::round_mm;
        match self {
            Blocker::OutsideWorld => write!(f, "is outside the world"),
            Blocker::InObstacle { line } => {
                write!(f, "is inside the obstacle{}", shape_origin(*line))
            }
            Blocker::NearObstacle {
                kind,
                line,
                distance_m,
                keep_m,
            } => write!(
                f,
                "{} the {kind}{}; the robot keeps {} m from obstacles",
                geo::is_from(*distance_m),
                shape_origin(*line),
                mm(*keep_m)
            ),
            Blocker::InArea { name } => write!(f, "is in the no-go area `{name}`"),
            Blocker::NearArea {
                name,
                distance_m,
                keep_m,
            } => write!(
                f,
                "is {} m from the no-go area `{name}`; the robot keeps {} m from it",
                mm(*distance_m),
                mm(*keep_m)
            ),
            Blocker::NoRoom => write!(f, "is hemmed in: there is no room to move from there"),
        }
    }
}

/// Where the way is cut: the narrowest point of the widest way from start to goal.
#[derive(Clone, Debug, PartialEq)]
pub struct Bottleneck {
    pub at: Point,
    /// The width of the passage there: twice the distance from its middle to the nearest
    /// obstacle or area (0 when the way is closed).
    pub width_m: f64,
    /// The no-go area that makes it narrow, when one does (rather than an obstacle).
    pub area: Option<String>,
    /// The width the robot needs there, measured the same way: twice what its centre keeps
    /// from the thing that makes it narrow, plus a cell's diagonal (the planner's cells must be
    /// clear at every point, so a passage is narrower on the grid than on the geometry); 0 when
    /// not known (the way is closed).
    pub needed_m: f64,
}

impl fmt::Display for Bottleneck {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // To the centimetre: the cells are 5 cm.
        let cm = |value: f64| geo::round_mm((value * 100.0).round() / 100.0);
        let at = format!("({}, {})", cm(self.at.x), cm(self.at.y));
        if self.width_m <= 0.0 {
            write!(f, "the way is closed at {at}")?;
        } else {
            write!(
                f,
                "the narrowest passage is {} m wide at {at}",
                cm(self.width_m)
            )?;
        }
        if let Some(area) = &self.area {
            write!(f, ", by the no-go area `{area}`")?;
        }
        // Said in the same terms as the width, so that a passage a little wider than twice the
        // robot's keep does not read as a contradiction.
        if self.width_m > 0.0 && self.needed_m > 0.0 {
            write!(
                f,
                "; the robot needs {} m there",
                geo::round_mm((self.needed_m * 100.0).ceil() / 100.0)
            )?;
        }
        Ok(())
    }
}

/// Why there is no path.
#[derive(Clone, Debug, PartialEq)]
pub enum PathError {
    /// The robot cannot be at the start or the goal.
    Blocked { end: End, at: Point, why: Blocker },
    /// Every way is narrower than the robot needs: where the widest one is narrowest.
    Cut(Bottleneck),
}

impl fmt::Display for PathError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PathError::Blocked { end, at, why } => {
                let end = match end {
                    End::Start => "the start",
                    End::Goal => "the goal",
                };
                write!(f, "{end} {at} {why}")
            }
            PathError::Cut(bottleneck) => write!(f, "no way through: {bottleneck}"),
        }
    }
}

impl std::error::Error for PathError {}

/// Plans one path: builds the costmap (of `world`, or with none of the area round the start,
/// the goal and the keepouts) and searches it. To plan several paths on the same map, build a
/// [`Planner`] once.
pub fn plan_path(
    world: Option<&World>,
    robot: &Robot,
    keepouts: &[Keepout],
    start: Point,
    goal: Point,
) -> Result<Path, PathError> {
    let settings = CostmapSettings::default();
    let costmap = match world {
        Some(world) => Costmap::for_world(world, robot, keepouts, &settings),
        None => Costmap::open(
            open_extent(&[start, goal], keepouts, robot, &settings),
            robot,
            keepouts,
            &settings,
        ),
    };
    match costmap {
        Ok(costmap) => Planner::new(costmap).plan(start, goal),
        // Only a world or extent that is not finite gives no map.
        Err(_) => Err(PathError::Blocked {
            end: End::Start,
            at: start,
            why: Blocker::OutsideWorld,
        }),
    }
}

/// With no world, the map is the box round the given points and keepouts, with room to go
/// round the keepouts on every side.
pub fn open_extent(
    points: &[Point],
    keepouts: &[Keepout],
    robot: &Robot,
    settings: &CostmapSettings,
) -> Bounds {
    let mut all: Vec<Point> = points.to_vec();
    let mut pad: f64 = robot.keep_m() + settings.falloff_m;
    for keepout in keepouts {
        all.extend(keepout.polygon.corners.iter().copied());
        pad = pad.max(keepout.keep_m(robot) + settings.falloff_m);
    }
    let pad = pad + 2.0;
    let (mut min_x, mut min_y, mut max_x, mut max_y) = (
        f64::INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::NEG_INFINITY,
    );
    for p in all.iter().filter(|p| p.is_finite()) {
        min_x = min_x.min(p.x);
        min_y = min_y.min(p.y);
        max_x = max_x.max(p.x);
        max_y = max_y.max(p.y);
    }
    Bounds {
        min_x: min_x - pad,
        min_y: min_y - pad,
        max_x: max_x + pad,
        max_y: max_y + pad,
    }
}

/// Why the robot (its centre at `p`) cannot be there, measured on the geometry: outside the
/// world, in or too near an obstacle (`world`, when there is one), in or too near a keepout.
pub fn blocker_at(
    world: Option<&World>,
    robot: &Robot,
    keepouts: &[Keepout],
    p: Point,
) -> Option<Blocker> {
    if !p.is_finite() {
        return Some(Blocker::OutsideWorld);
    }
    if let Some(world) = world {
        let keep = robot.keep_m();
        if !world.boundary().contains(p) {
            return Some(Blocker::OutsideWorld);
        }
        if let Some(shape) = world.obstacle_at(p) {
            return Some(Blocker::InObstacle { line: shape.line });
        }
        if let Some((distance_m, shape)) = world.nearest_shape(p, keep)
            && distance_m < keep
        {
            return Some(Blocker::NearObstacle {
                kind: shape.kind.noun(),
                line: shape.line,
                distance_m,
                keep_m: keep,
            });
        }
    }
    for keepout in keepouts {
        let keep = keepout.keep_m(robot);
        if keepout.polygon.corners.len() < 3 || !keepout.polygon.near_box(p, p, keep) {
            continue;
        }
        if keepout.polygon.contains(p) {
            return Some(Blocker::InArea {
                name: keepout.name.clone(),
            });
        }
        let distance_m = keepout.polygon.distance_to_outline(p);
        if distance_m < keep {
            return Some(Blocker::NearArea {
                name: keepout.name.clone(),
                distance_m,
                keep_m: keep,
            });
        }
    }
    None
}

/// Whether the segment `a`–`b` keeps what the robot keeps from every keepout (with no world,
/// the straight line is then the path).
pub fn clear_of_keepouts(robot: &Robot, keepouts: &[Keepout], a: Point, b: Point) -> bool {
    keepouts.iter().all(|keepout| {
        let keep = keepout.keep_m(robot);
        let polygon = &keepout.polygon;
        polygon.corners.len() < 3
            || !polygon.near_box(a, b, keep)
            || (!polygon.contains(a)
                && !polygon.contains(b)
                && polygon
                    .edges()
                    .all(|(c, d)| crate::world::segment_segment_distance(a, b, c, d) >= keep))
    })
}
