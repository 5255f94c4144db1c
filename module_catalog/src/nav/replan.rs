//! Replanning from what the laser sees: the follower's recovery when its path is blocked.
//!
//! The map is the world file the follower is given (the sim's, found the same way) with every
//! laser hit the world does not explain added as a small obstacle; the planner inflates them by
//! the robot's radius and clearance like any other obstacle. Hits the world explains (within
//! [`EXPLAINED_M`] of one of its walls or outlines) are left out: the odometry the scan is placed
//! with drifts, and a wall seen a little off would otherwise narrow every door on the way.
//! Without a world the map is the open box round the robot, the goal and the hits.
//!
//! A mapper's live map ([`LiveMap`], the follower's `map` input) stands in for the world where
//! there is none: the walls it has seen, placed from its corrected pose, are planned round all
//! at once, where the laser's hits alone show only the walls in view, and a replan round them
//! would meet the next ones one by one.
//!
//! Pure: the world's text comes in as text, the scan as a value.

use armor_model::geo;
use armor_model::planner::{
    Costmap, CostmapSettings, Keepout, Path, PathError, Planner, Robot, open_extent,
};
use armor_model::world::{Point, Shape, World};
use armor_module_api::types::{LaserScan, OccupancyGrid, Pose2D};

/// A hit this close to the world's walls and outlines is the world, not a new obstacle.
pub const EXPLAINED_M: f64 = 0.3;
/// Hits are kept one per square of this side (the costmap's cells are 5 cm; this is coarse
/// enough to keep the map small and fine enough to close every gap the robot cannot use).
const HIT_CELL_M: f64 = 0.1;
/// The radius of the small obstacle each hit becomes.
const HIT_RADIUS_M: f64 = 0.05;
/// How far ahead along the path the laser is watched for obstacles in the way.
pub const AHEAD_M: f64 = 3.0;
/// A live map's cell is a wall from this value on (as a ROS map's `occupied_thresh` of 0.5).
const LIVE_WALL_FROM: i8 = 50;
/// The world made of a live map reaches this far beyond its walls, the robot and the goal.
const LIVE_MARGIN_M: f64 = 2.0;
/// How far round the robot a free place to set off from is sought when its own place is too
/// close to what it sees (the avoider stops it near obstacles).
const SET_OFF_SEARCH_M: f64 = 1.0;

/// The world the follower plans on: its text (to add the hits to) and its parsed form.
#[derive(Clone, Debug)]
pub struct WorldMap {
    pub file_name: String,
    pub world: World,
}

impl WorldMap {
    pub fn new(world: World) -> WorldMap {
        WorldMap {
            file_name: world.file_name().to_owned(),
            world,
        }
    }
}

/// A mapper's occupancy grid as the follower plans on it: its walls (cells of
/// [`LIVE_WALL_FROM`] or more), and every other cell, seen free or not seen yet, open. A
/// building nobody mapped is explored on the hope that what the laser has not seen is open:
/// the laser and the map's next update say when it is not.
#[derive(Clone, Debug)]
pub struct LiveMap {
    grid: OccupancyGrid,
    /// The centres of the wall cells.
    walls: Vec<Point>,
}

impl LiveMap {
    /// The live map of a grid; `None` for a grid whose cells do not match its size or whose
    /// geometry is not finite.
    pub fn new(grid: OccupancyGrid) -> Option<LiveMap> {
        let (width, height) = (grid.width as usize, grid.height as usize);
        let sane = grid.cells.len() == width * height
            && grid.resolution_m.is_finite()
            && grid.resolution_m > 0.0
            && grid.origin_x_m.is_finite()
            && grid.origin_y_m.is_finite();
        if !sane {
            return None;
        }
        let resolution = grid.resolution_m;
        let walls = grid
            .cells
            .iter()
            .enumerate()
            .filter(|(_, value)| **value >= LIVE_WALL_FROM)
            .map(|(index, _)| {
                Point::new(
                    grid.origin_x_m + ((index % width) as f64 + 0.5) * resolution,
                    grid.origin_y_m + ((index / width) as f64 + 0.5) * resolution,
                )
            })
            .collect();
        Some(LiveMap { grid, walls })
    }

    /// The centres of the wall cells.
    pub fn walls(&self) -> &[Point] {
        &self.walls
    }

    /// The world to plan on from `from` to `goal`: the box round the walls, `from` and `goal`
    /// with [`LIVE_MARGIN_M`] to spare, each run of wall cells an obstacle (as a ROS map
    /// becomes a world), the rest open.
    pub fn world(&self, from: Point, goal: Point) -> Option<WorldMap> {
        let g = &self.grid;
        let resolution = g.resolution_m;
        let (mut min_x, mut min_y) = (from.x.min(goal.x), from.y.min(goal.y));
        let (mut max_x, mut max_y) = (from.x.max(goal.x), from.y.max(goal.y));
        for wall in &self.walls {
            min_x = min_x.min(wall.x);
            min_y = min_y.min(wall.y);
            max_x = max_x.max(wall.x);
            max_y = max_y.max(wall.y);
        }
        let (min_x, min_y) = (min_x - LIVE_MARGIN_M, min_y - LIVE_MARGIN_M);
        let (max_x, max_y) = (max_x + LIVE_MARGIN_M, max_y + LIVE_MARGIN_M);
        if ![min_x, min_y, max_x, max_y].iter().all(|v| v.is_finite()) {
            return None;
        }
        // The box on the grid's own cells, so that each wall cell stays where it was.
        let first_col = ((min_x - g.origin_x_m) / resolution).floor() as i64;
        let first_row = ((min_y - g.origin_y_m) / resolution).floor() as i64;
        let width = (((max_x - g.origin_x_m) / resolution).ceil() as i64 - first_col).max(1);
        let height = (((max_y - g.origin_y_m) / resolution).ceil() as i64 - first_row).max(1);
        if width * height > 4_000_000 {
            return None;
        }
        let (source_width, source_height) = (g.width as i64, g.height as i64);
        let mut cells = vec![0_i8; (width * height) as usize];
        for row in 0..height {
            for col in 0..width {
                let (c, r) = (first_col + col, first_row + row);
                if (0..source_width).contains(&c)
                    && (0..source_height).contains(&r)
                    && g.cells[(r * source_width + c) as usize] >= LIVE_WALL_FROM
                {
                    cells[(row * width + col) as usize] = 100;
                }
            }
        }
        let crop = OccupancyGrid {
            resolution_m: resolution,
            width: width as u32,
            height: height as u32,
            origin_x_m: g.origin_x_m + first_col as f64 * resolution,
            origin_y_m: g.origin_y_m + first_row as f64 * resolution,
            cells,
        };
        let start = Pose2D {
            x_m: from.x,
            y_m: from.y,
            theta_rad: 0.0,
        };
        armor_model::ros_map::world_of_grid(
            &crop,
            "live map",
            "the mapper's map",
            (0.0, 0.0),
            Some(start),
        )
        .map_err(|err| tracing::warn!("the live map as a world: {err}"))
        .ok()
        .map(WorldMap::new)
    }
}

/// The laser's hits in the odometry frame, from the pose the robot had when it scanned: beams
/// with an echo within range, one per [`HIT_CELL_M`] square.
pub fn scan_hits(pose: Pose2D, scan: &LaserScan) -> Vec<Point> {
    let mut hits: Vec<Point> = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for (i, range) in scan.ranges_m.iter().enumerate() {
        let range = f64::from(*range);
        if !range.is_finite() || range <= 0.0 || range >= scan.range_max_m * 0.99 {
            continue;
        }
        let angle = pose.theta_rad + scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
        let hit = Point::new(
            pose.x_m + range * angle.cos(),
            pose.y_m + range * angle.sin(),
        );
        if !hit.is_finite() {
            continue;
        }
        let key = (
            (hit.x / HIT_CELL_M).floor() as i64,
            (hit.y / HIT_CELL_M).floor() as i64,
        );
        if seen.insert(key) {
            hits.push(hit);
        }
    }
    hits
}

/// The hits the world does not explain (all of them without a world).
pub fn unexplained(world: Option<&World>, hits: &[Point]) -> Vec<Point> {
    hits.iter()
        .copied()
        .filter(|hit| {
            world.is_none_or(|world| world.wall_distance(*hit, EXPLAINED_M) >= EXPLAINED_M)
        })
        .collect()
}

/// Whether one of `hits` lies on the path ahead: within `keep_m` of it, from `here`'s
/// projection up to [`AHEAD_M`] along it.
pub fn blocked_ahead(path_ahead: &[Point], hits: &[Point], keep_m: f64) -> bool {
    blocked_within(path_ahead, hits, keep_m, AHEAD_M)
}

/// Whether one of `hits` lies within `keep_m` of the first `ahead_m` of `path_ahead`.
pub fn blocked_within(path_ahead: &[Point], hits: &[Point], keep_m: f64, ahead_m: f64) -> bool {
    let mut left_m = ahead_m;
    for pair in path_ahead.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let length_m = geo::distance(a, b);
        let b = if length_m > left_m && length_m > 0.0 {
            Point::new(
                a.x + (b.x - a.x) * left_m / length_m,
                a.y + (b.y - a.y) * left_m / length_m,
            )
        } else {
            b
        };
        if hits
            .iter()
            .any(|hit| super::pursuit::project_on_segment(*hit, a, b).1 < keep_m)
        {
            return true;
        }
        left_m -= length_m;
        if left_m <= 0.0 {
            break;
        }
    }
    false
}

/// Plans from `from` to `goal` on `world` (or the open map) with `obstacles` added. When `from`
/// itself is too close to what is seen, the path sets off from the nearest free place within
/// [`SET_OFF_SEARCH_M`] (and starts at `from`).
pub fn replan(
    world: Option<&WorldMap>,
    robot: &Robot,
    keepouts: &[Keepout],
    obstacles: &[Point],
    from: Point,
    goal: Point,
) -> Result<Path, PathError> {
    let settings = CostmapSettings::default();
    let costmap = costmap_with(world, robot, keepouts, obstacles, from, goal, &settings);
    let Some(costmap) = costmap else {
        return armor_model::planner::plan_path(None, robot, keepouts, from, goal);
    };
    let set_off = free_place_near(&costmap, from);
    let mut planner = Planner::new(costmap);
    let path = planner.plan(set_off.unwrap_or(from), goal)?;
    match set_off {
        Some(set_off) if set_off != from => {
            let mut points = vec![from];
            points.extend(path.points);
            Ok(Path::new(points))
        }
        _ => Ok(path),
    }
}

fn costmap_with(
    world: Option<&WorldMap>,
    robot: &Robot,
    keepouts: &[Keepout],
    obstacles: &[Point],
    from: Point,
    goal: Point,
    settings: &CostmapSettings,
) -> Option<Costmap> {
    let hits: Vec<Vec<Point>> = obstacles
        .iter()
        .map(|&hit| armor_model::world::circle(hit, HIT_RADIUS_M))
        .collect();
    let world = match world {
        Some(world) => world
            .world
            .with_shapes(hits.into_iter().map(Shape::obstacle)),
        None => {
            let mut points = vec![from, goal];
            points.extend_from_slice(obstacles);
            let b = open_extent(&points, keepouts, robot, settings);
            let start = Pose2D {
                x_m: from.x,
                y_m: from.y,
                theta_rad: 0.0,
            };
            let corners = vec![
                Point::new(b.min_x, b.min_y),
                Point::new(b.max_x, b.min_y),
                Point::new(b.max_x, b.max_y),
                Point::new(b.min_x, b.max_y),
            ];
            World::from_shapes("seen", "the laser's map", (0.0, 0.0), start, corners, hits)
        }
    }
    .ok()?;
    Costmap::for_world(&world, robot, keepouts, settings).ok()
}

/// `p` when it is free on the costmap, else the nearest free place found on rings round it.
fn free_place_near(costmap: &Costmap, p: Point) -> Option<Point> {
    if !costmap.is_lethal_at(p) {
        return Some(p);
    }
    let step_m = costmap.resolution_m().max(0.02);
    let mut radius_m = step_m;
    while radius_m <= SET_OFF_SEARCH_M {
        let around = ((std::f64::consts::TAU * radius_m / step_m).ceil() as usize).max(8);
        for k in 0..around {
            let angle = std::f64::consts::TAU * k as f64 / around as f64;
            let q = Point::new(p.x + radius_m * angle.cos(), p.y + radius_m * angle.sin());
            if !costmap.is_lethal_at(q) {
                return Some(q);
            }
        }
        radius_m += step_m;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROOM: &str = "name room\norigin 0 0\nstart 1 5 0\nboundary 0,0 20,0 20,10 0,10 0,0\n";

    fn room() -> WorldMap {
        WorldMap::new(World::parse(ROOM, "room.world").expect("world"))
    }

    /// A scan from (x, 5) facing east that sees a wall across the room 2 m ahead, from y 0 to 7.
    fn scan_of_a_wall(x: f64) -> (Pose2D, LaserScan) {
        let pose = Pose2D {
            x_m: x,
            y_m: 5.0,
            theta_rad: 0.0,
        };
        let beams = 360;
        let increment = std::f64::consts::TAU / beams as f64;
        let ranges = (0..beams)
            .map(|i| {
                let angle = -std::f64::consts::PI + i as f64 * increment;
                let (c, s) = (angle.cos(), angle.sin());
                // The wall at x + 2, from y 0 to 7.
                if c > 1e-6 {
                    let range = 2.0 / c;
                    let y = 5.0 + range * s;
                    if (0.0..=7.0).contains(&y) && range < 8.0 {
                        return range as f32;
                    }
                }
                8.0
            })
            .collect();
        (
            pose,
            LaserScan {
                angle_min_rad: -std::f64::consts::PI,
                angle_increment_rad: increment,
                range_max_m: 8.0,
                ranges_m: ranges,
            },
        )
    }

    #[test]
    fn a_wall_seen_across_the_way_is_gone_round() {
        let world = room();
        let (pose, scan) = scan_of_a_wall(5.0);
        let hits = unexplained(Some(&world.world), &scan_hits(pose, &scan));
        assert!(hits.len() > 20, "{}", hits.len());
        let straight = [Point::new(5.0, 5.0), Point::new(15.0, 5.0)];
        assert!(blocked_ahead(&straight, &hits, 0.3));
        let path = replan(
            Some(&world),
            &Robot::default(),
            &[],
            &hits,
            Point::new(5.0, 5.0),
            Point::new(15.0, 5.0),
        )
        .expect("a way round the north end");
        assert!(path.length_m > 11.0, "{path:?}");
        assert!(
            path.points.iter().any(|p| p.y > 7.0),
            "round the north end: {path:?}"
        );
    }

    #[test]
    fn the_world_s_own_walls_are_not_new_obstacles_and_a_closed_way_is_an_error() {
        let world = room();
        let boundary_hits = [Point::new(10.0, 10.0), Point::new(10.0, 0.02)];
        assert!(unexplained(Some(&world.world), &boundary_hits).is_empty());
        assert_eq!(unexplained(None, &boundary_hits).len(), 2);
        // A wall right across: no way.
        let wall: Vec<Point> = (0..=100)
            .map(|i| Point::new(8.0, f64::from(i) * 0.1))
            .collect();
        let err = replan(
            Some(&world),
            &Robot::default(),
            &[],
            &wall,
            Point::new(5.0, 5.0),
            Point::new(15.0, 5.0),
        )
        .expect_err("closed");
        assert!(matches!(err, PathError::Cut(_)), "{err}");
    }

    #[test]
    fn sets_off_from_a_free_place_when_held_close_to_an_obstacle() {
        // The robot stands 0.3 m before the seen wall (closer than it keeps), with no world.
        let (pose, scan) = scan_of_a_wall(5.0);
        let hits = scan_hits(pose, &scan);
        let from = Point::new(6.7, 5.0);
        let path = replan(
            None,
            &Robot::default(),
            &[],
            &hits,
            from,
            Point::new(15.0, 5.0),
        )
        .expect("a way round");
        assert_eq!(path.points[0], from);
        assert!(path.points.iter().any(|p| p.y > 7.0), "{path:?}");
    }
}
