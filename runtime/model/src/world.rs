//! The simulated world: a plane of walls and obstacles read from the text of a `.world` file,
//! with the queries a simulator, a map display, a plan compiler or a mapper's test needs (ray
//! casting, collision, an occupancy grid, latitude and longitude).
//!
//! # The `.world` format
//!
//! One statement per line; `#` starts a comment; blank lines are ignored. Lengths are metres in
//! the world frame (x east, y north), angles degrees. A vertex is written `X,Y` (no space).
//!
//! ```text
//! name     Open yard                  # any text
//! origin   48.8566 2.3522             # latitude and longitude (degrees) of the point (0, 0)
//! start    5 5 90                     # start pose: x y heading (degrees, counter-clockwise from east)
//! boundary 0,0 40,0 40,30 0,30 0,0    # the outer wall: a closed polygon
//! wall     10,0 10,8                  # a wall: a polyline, closed if it ends where it starts
//! obstacle 20,10 22,10 21,13 20,10    # a solid obstacle: a closed polygon
//! rect     30,20 31.5,21              # a solid rectangle, by two opposite corners
//! circle   12,20 0.4                  # a solid disc (a 16-sided polygon), by centre and radius
//! ```
//!
//! `name`, `origin`, `start` and `boundary` are required, once each. Closed polygons repeat their
//! first vertex at the end; they need at least 3 corners and must not cross themselves. The start
//! pose must lie inside the boundary, outside every obstacle and off every wall. Every problem is
//! reported as `FILE:LINE:COL: message` ([`WorldError`]).

use std::fmt;

use armor_module_api::types::{OccupancyGrid, Pose2D};

use crate::geo::LatLon;
pub use crate::geo::Point;

/// Sides of the polygon that stands for a `circle`.
const CIRCLE_SIDES: usize = 16;
/// Collinearity tolerance of the polygon checks (cross products, in square metres).
const GEOMETRY_EPS: f64 = 1e-9;
/// Occupancy grids larger than this many cells are refused.
const MAX_GRID_CELLS: usize = 50_000_000;

fn cross(a: Point, b: Point) -> f64 {
    a.x * b.y - a.y * b.x
}

/// An axis-aligned box of the world frame, in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min_x: f64,
    pub min_y: f64,
    pub max_x: f64,
    pub max_y: f64,
}

impl Bounds {
    fn around(points: impl IntoIterator<Item = Point>) -> Self {
        let mut bounds = Bounds {
            min_x: f64::INFINITY,
            min_y: f64::INFINITY,
            max_x: f64::NEG_INFINITY,
            max_y: f64::NEG_INFINITY,
        };
        for p in points {
            bounds.min_x = bounds.min_x.min(p.x);
            bounds.min_y = bounds.min_y.min(p.y);
            bounds.max_x = bounds.max_x.max(p.x);
            bounds.max_y = bounds.max_y.max(p.y);
        }
        bounds
    }

    pub fn width(&self) -> f64 {
        self.max_x - self.min_x
    }

    pub fn height(&self) -> f64 {
        self.max_y - self.min_y
    }

    pub fn contains(&self, p: Point) -> bool {
        (self.min_x..=self.max_x).contains(&p.x) && (self.min_y..=self.max_y).contains(&p.y)
    }
}

/// What a shape of the world file is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeKind {
    /// The outer wall; the robot lives inside it.
    Boundary,
    /// A thin wall: an open polyline or a closed (hollow) one.
    Wall,
    /// A solid polygon (also from `rect` and `circle`).
    Obstacle,
}

impl ShapeKind {
    pub fn noun(self) -> &'static str {
        match self {
            ShapeKind::Boundary => "boundary",
            ShapeKind::Wall => "wall",
            ShapeKind::Obstacle => "obstacle",
        }
    }
}

/// A boundary, wall or obstacle as read from the world file.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    pub kind: ShapeKind,
    /// The vertices in order. A closed shape does not repeat its first vertex at the end.
    pub points: Vec<Point>,
    /// Whether the last vertex joins the first (always for boundaries and obstacles).
    pub closed: bool,
    /// The line of the world file that defines it.
    pub line: usize,
}

impl Shape {
    /// A solid obstacle from its corners (not repeating the first), which must not cross.
    pub fn obstacle(points: Vec<Point>) -> Shape {
        Shape {
            kind: ShapeKind::Obstacle,
            points,
            closed: true,
            line: 0,
        }
    }

    /// The shape's edges, including the closing one of a closed shape.
    pub fn edges(&self) -> impl Iterator<Item = (Point, Point)> + '_ {
        let n = self.points.len();
        let count = if self.closed { n } else { n.saturating_sub(1) };
        (0..count).map(move |i| (self.points[i], self.points[(i + 1) % n]))
    }

    /// Whether a point lies inside this shape's outline (even-odd rule; only meaningful for a
    /// closed shape).
    pub fn contains(&self, p: Point) -> bool {
        crate::geo::inside(self.edges(), p)
    }
}

/// A problem with a world file: `FILE:LINE:COL: message`, or `FILE: message` when it concerns
/// the whole file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct WorldError {
    pub file: String,
    /// 1-based; 0 when the problem has no single place (a missing statement, an unreadable file).
    pub line: usize,
    /// 1-based, in characters.
    pub col: usize,
    pub message: String,
}

impl fmt::Display for WorldError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(
                f,
                "{}:{}:{}: {}",
                self.file, self.line, self.col, self.message
            )
        }
    }
}

impl std::error::Error for WorldError {}

/// One edge of a wall, obstacle or the boundary.
#[derive(Clone, Copy, Debug)]
struct Segment {
    a: Point,
    b: Point,
    /// Index in `World::shapes`.
    shape: usize,
}

/// A uniform grid over the world listing the segments that cross each cell, so that a ray or a
/// disc only looks at the walls near it.
#[derive(Clone, Debug)]
struct Grid {
    min: Point,
    cell: f64,
    cols: usize,
    rows: usize,
    /// Cell `c`'s segments are `items[starts[c]..starts[c + 1]]`.
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl Grid {
    /// Cells are about a metre wide, fewer for very large worlds.
    fn build(bounds: &Bounds, segments: &[Segment]) -> Self {
        const MAX_SIDE_CELLS: f64 = 512.0;
        let pad = 1e-6 * (1.0 + bounds.width().max(bounds.height()));
        let min = Point::new(bounds.min_x - pad, bounds.min_y - pad);
        let width = bounds.width() + 2.0 * pad;
        let height = bounds.height() + 2.0 * pad;
        let cell = (width.max(height) / MAX_SIDE_CELLS).max(1.0);
        let cols = ((width / cell).ceil() as usize).max(1);
        let rows = ((height / cell).ceil() as usize).max(1);
        let mut grid = Grid {
            min,
            cell,
            cols,
            rows,
            starts: Vec::new(),
            items: Vec::new(),
        };
        let mut pairs: Vec<(usize, u32)> = Vec::new();
        let margin = cell * 1e-6;
        for (index, segment) in segments.iter().enumerate() {
            let (c0, c1) =
                grid.col_range(segment.a.x.min(segment.b.x), segment.a.x.max(segment.b.x));
            let (r0, r1) =
                grid.row_range(segment.a.y.min(segment.b.y), segment.a.y.max(segment.b.y));
            for row in r0..=r1 {
                for col in c0..=c1 {
                    let lo = Point::new(
                        min.x + col as f64 * cell - margin,
                        min.y + row as f64 * cell - margin,
                    );
                    let hi = Point::new(lo.x + cell + 2.0 * margin, lo.y + cell + 2.0 * margin);
                    if segment_meets_box(segment.a, segment.b, lo, hi) {
                        pairs.push((row * cols + col, index as u32));
                    }
                }
            }
        }
        pairs.sort_unstable();
        grid.starts = vec![0; cols * rows + 1];
        for &(cell_index, _) in &pairs {
            grid.starts[cell_index + 1] += 1;
        }
        for i in 0..cols * rows {
            grid.starts[i + 1] += grid.starts[i];
        }
        grid.items = pairs.into_iter().map(|(_, segment)| segment).collect();
        grid
    }

    fn index_of(&self, value: f64, origin: f64, count: usize) -> usize {
        let cell = ((value - origin) / self.cell).floor();
        if cell <= 0.0 {
            0
        } else {
            (cell as usize).min(count - 1)
        }
    }

    fn col_range(&self, lo: f64, hi: f64) -> (usize, usize) {
        (
            self.index_of(lo, self.min.x, self.cols),
            self.index_of(hi, self.min.x, self.cols),
        )
    }

    fn row_range(&self, lo: f64, hi: f64) -> (usize, usize) {
        (
            self.index_of(lo, self.min.y, self.rows),
            self.index_of(hi, self.min.y, self.rows),
        )
    }

    fn cell_items(&self, col: usize, row: usize) -> &[u32] {
        let cell = row * self.cols + col;
        &self.items[self.starts[cell] as usize..self.starts[cell + 1] as usize]
    }

    fn max(&self) -> Point {
        Point::new(
            self.min.x + self.cols as f64 * self.cell,
            self.min.y + self.rows as f64 * self.cell,
        )
    }
}

/// Whether segment `a`–`b` meets the box `lo`–`hi` (Liang–Barsky clipping).
fn segment_meets_box(a: Point, b: Point, lo: Point, hi: Point) -> bool {
    let d = b.sub(a);
    let mut t0: f64 = 0.0;
    let mut t1: f64 = 1.0;
    for (p, q) in [
        (-d.x, a.x - lo.x),
        (d.x, hi.x - a.x),
        (-d.y, a.y - lo.y),
        (d.y, hi.y - a.y),
    ] {
        if p == 0.0 {
            if q < 0.0 {
                return false;
            }
        } else {
            let r = q / p;
            if p < 0.0 {
                if r > t1 {
                    return false;
                }
                t0 = t0.max(r);
            } else {
                if r < t0 {
                    return false;
                }
                t1 = t1.min(r);
            }
        }
    }
    true
}

/// Where the ray `origin + t·dir` (t ≥ 0) meets segment `a`–`b`, if it does.
fn ray_meets_segment(origin: Point, dir: Point, a: Point, b: Point) -> Option<f64> {
    let edge = b.sub(a);
    let denom = cross(dir, edge);
    if denom.abs() < 1e-12 {
        return None;
    }
    let to_a = a.sub(origin);
    let t = cross(to_a, edge) / denom;
    let u = cross(to_a, dir) / denom;
    (t >= 0.0 && (0.0..=1.0).contains(&u)).then_some(t)
}

/// The distance between segments `p1`–`p2` and `q1`–`q2` (0 when they meet).
pub(crate) fn segment_segment_distance(p1: Point, p2: Point, q1: Point, q2: Point) -> f64 {
    if segments_meet(p1, p2, q1, q2) {
        return 0.0;
    }
    crate::geo::segment_distance(p1, q1, q2)
        .min(crate::geo::segment_distance(p2, q1, q2))
        .min(crate::geo::segment_distance(q1, p1, p2))
        .min(crate::geo::segment_distance(q2, p1, p2))
}

/// The sign of the turn `a` → `b` → `c`: positive counter-clockwise, 0 when (nearly) collinear.
fn orientation(a: Point, b: Point, c: Point) -> f64 {
    let turn = cross(b.sub(a), c.sub(a));
    if turn.abs() <= GEOMETRY_EPS {
        0.0
    } else {
        turn
    }
}

/// Whether `p`, known collinear with `a`–`b`, lies within it.
fn within(a: Point, b: Point, p: Point) -> bool {
    p.x >= a.x.min(b.x) - GEOMETRY_EPS
        && p.x <= a.x.max(b.x) + GEOMETRY_EPS
        && p.y >= a.y.min(b.y) - GEOMETRY_EPS
        && p.y <= a.y.max(b.y) + GEOMETRY_EPS
}

/// Whether two segments share at least one point.
fn segments_meet(p1: Point, p2: Point, q1: Point, q2: Point) -> bool {
    let d1 = orientation(q1, q2, p1);
    let d2 = orientation(q1, q2, p2);
    let d3 = orientation(p1, p2, q1);
    let d4 = orientation(p1, p2, q2);
    if d1 * d2 < 0.0 && d3 * d4 < 0.0 {
        return true;
    }
    (d1 == 0.0 && within(q1, q2, p1))
        || (d2 == 0.0 && within(q1, q2, p2))
        || (d3 == 0.0 && within(p1, p2, q1))
        || (d4 == 0.0 && within(p1, p2, q2))
}

/// What a ray met first ([`World::raycast_hit`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayHit {
    pub distance_m: f64,
    /// Index in [`World::shapes`].
    pub shape: usize,
    /// The edge of that shape that was met.
    pub edge: (Point, Point),
}

/// The planar world of the simulator: boundary, walls and obstacles, start pose and geographic
/// origin. Cheap to share (`Clone`) and safe to query from several threads.
#[derive(Clone, Debug)]
pub struct World {
    name: String,
    file_name: String,
    origin_lat_lon: (f64, f64),
    start: Pose2D,
    /// Where the `start` statement is (line, column of its first value).
    start_at: (usize, usize),
    /// The boundary first, then walls and obstacles in file order.
    shapes: Vec<Shape>,
    segments: Vec<Segment>,
    /// Bounding box and index in `shapes` of each obstacle.
    obstacles: Vec<(Bounds, usize)>,
    bounds: Bounds,
    grid: Grid,
}

impl World {
    /// Reads and checks the text of a world file; `file_name` is only used in error messages.
    pub fn parse(text: &str, file_name: &str) -> Result<World, WorldError> {
        let mut parser = Parser {
            file: file_name,
            name: None,
            origin: None,
            start: None,
            boundary: None,
            shapes: Vec::new(),
        };
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        for (index, line) in text.lines().enumerate() {
            parser.statement(index + 1, line)?;
        }
        parser.finish()
    }

    /// The world's name, from its `name` statement.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The file it was read from, as given to [`World::parse`].
    pub fn file_name(&self) -> &str {
        &self.file_name
    }

    /// Latitude and longitude in degrees of the world's point (0, 0).
    pub fn origin_lat_lon(&self) -> (f64, f64) {
        self.origin_lat_lon
    }

    /// Latitude and longitude in degrees of a world point (x east, y north; a local
    /// equirectangular projection, accurate to centimetres over a few kilometres).
    pub fn to_lat_lon(&self, p: Point) -> (f64, f64) {
        let at = LatLon::from_local(p, self.origin());
        (at.lat_deg, at.lon_deg)
    }

    /// The world point at a latitude and longitude in degrees (inverse of [`World::to_lat_lon`]).
    pub fn from_lat_lon(&self, lat: f64, lon: f64) -> Point {
        LatLon::new(lat, lon).to_local(self.origin())
    }

    fn origin(&self) -> LatLon {
        LatLon::new(self.origin_lat_lon.0, self.origin_lat_lon.1)
    }

    /// The start pose in the world frame.
    pub fn start(&self) -> Pose2D {
        self.start
    }

    /// The box around every shape of the world.
    pub fn bounds(&self) -> Bounds {
        self.bounds
    }

    /// The outer boundary.
    pub fn boundary(&self) -> &Shape {
        &self.shapes[0]
    }

    /// Every shape: the boundary first, then walls and obstacles in file order.
    pub fn shapes(&self) -> &[Shape] {
        &self.shapes
    }

    /// Whether `other` has the same shapes in the same box: what a path planned on one holds
    /// on the other (its name, origin and start may differ).
    pub fn same_geometry(&self, other: &World) -> bool {
        self.bounds == other.bounds && self.shapes == other.shapes
    }

    /// Every edge of the boundary, walls and obstacles (for drawing).
    pub fn segments(&self) -> impl Iterator<Item = (Point, Point)> + '_ {
        self.segments.iter().map(|segment| (segment.a, segment.b))
    }

    /// The distance from `origin` along the direction `angle_rad` (counter-clockwise from the x
    /// axis) to the first wall, obstacle or boundary edge, or `max_range` if there is none closer.
    pub fn raycast(&self, origin: Point, angle_rad: f64, max_range: f64) -> f64 {
        self.cast(origin, angle_rad, max_range).0
    }

    /// What a ray from `origin` along `angle_rad` meets first within `max_range`: the distance,
    /// the shape and the edge (for a camera, which shades each shape and each face apart).
    pub fn raycast_hit(&self, origin: Point, angle_rad: f64, max_range: f64) -> Option<RayHit> {
        let (distance_m, segment) = self.cast(origin, angle_rad, max_range);
        let segment = &self.segments[segment? as usize];
        Some(RayHit {
            distance_m,
            shape: segment.shape,
            edge: (segment.a, segment.b),
        })
    }

    /// The distance to the first edge met and that edge's index in `segments`, or `max_range`
    /// and `None`.
    fn cast(&self, origin: Point, angle_rad: f64, max_range: f64) -> (f64, Option<u32>) {
        let max_range = if max_range.is_nan() {
            0.0
        } else {
            max_range.max(0.0)
        };
        if !origin.is_finite() || !angle_rad.is_finite() || max_range == 0.0 {
            return (max_range, None);
        }
        let dir = Point::new(angle_rad.cos(), angle_rad.sin());
        let grid = &self.grid;
        // The part of the ray inside the grid, [t_enter, t_exit].
        let (mut t_enter, mut t_exit) = (0.0_f64, max_range);
        let grid_max = grid.max();
        for (o, d, lo, hi) in [
            (origin.x, dir.x, grid.min.x, grid_max.x),
            (origin.y, dir.y, grid.min.y, grid_max.y),
        ] {
            if d == 0.0 {
                if o < lo || o > hi {
                    return (max_range, None);
                }
            } else {
                let (t0, t1) = ((lo - o) / d, (hi - o) / d);
                t_enter = t_enter.max(t0.min(t1));
                t_exit = t_exit.min(t0.max(t1));
            }
        }
        if t_enter > t_exit {
            return (max_range, None);
        }
        let entry = Point::new(origin.x + dir.x * t_enter, origin.y + dir.y * t_enter);
        let mut col = grid.index_of(entry.x, grid.min.x, grid.cols);
        let mut row = grid.index_of(entry.y, grid.min.y, grid.rows);
        // Run length along the ray to the next column / row boundary, and between boundaries.
        let next_boundary = |index: usize, o: f64, d: f64, lo: f64| {
            if d > 0.0 {
                (lo + (index + 1) as f64 * grid.cell - o) / d
            } else if d < 0.0 {
                (lo + index as f64 * grid.cell - o) / d
            } else {
                f64::INFINITY
            }
        };
        let mut t_next_col = next_boundary(col, origin.x, dir.x, grid.min.x);
        let mut t_next_row = next_boundary(row, origin.y, dir.y, grid.min.y);
        let t_step_col = if dir.x == 0.0 {
            f64::INFINITY
        } else {
            grid.cell / dir.x.abs()
        };
        let t_step_row = if dir.y == 0.0 {
            f64::INFINITY
        } else {
            grid.cell / dir.y.abs()
        };
        let mut best = (max_range, None);
        loop {
            for &index in grid.cell_items(col, row) {
                let segment = &self.segments[index as usize];
                if let Some(t) = ray_meets_segment(origin, dir, segment.a, segment.b)
                    && t < best.0
                {
                    best = (t, Some(index));
                }
            }
            let t_leave = t_next_col.min(t_next_row);
            if best.0 <= t_leave || t_leave >= t_exit {
                return best;
            }
            if t_next_col < t_next_row {
                match (dir.x > 0.0, col) {
                    (true, c) if c + 1 < grid.cols => col += 1,
                    (false, c) if c > 0 => col -= 1,
                    _ => return best,
                }
                t_next_col += t_step_col;
            } else {
                match (dir.y > 0.0, row) {
                    (true, r) if r + 1 < grid.rows => row += 1,
                    (false, r) if r > 0 => row -= 1,
                    _ => return best,
                }
                t_next_row += t_step_row;
            }
        }
    }

    /// Whether a disc of `radius` centred on (`x`, `y`) touches a wall, an obstacle or the
    /// boundary, or lies (partly) outside the boundary.
    pub fn collides(&self, x: f64, y: f64, radius: f64) -> bool {
        self.contact(Point::new(x, y), radius).is_some()
    }

    /// The distance from `p` to the nearest wall, obstacle edge or boundary edge, or `max` if
    /// none is closer.
    pub fn wall_distance(&self, p: Point, max: f64) -> f64 {
        self.nearest_segment(p, max)
            .map_or(max, |(distance, _)| distance)
    }

    /// The shape nearest to `p` within `max` (inclusive) and its distance: the boundary, a wall
    /// or an obstacle's outline (0 inside an obstacle only on its outline: see
    /// [`World::obstacle_at`]).
    pub fn nearest_shape(&self, p: Point, max: f64) -> Option<(f64, &Shape)> {
        self.nearest_segment(p, max)
            .map(|(distance, segment)| (distance, &self.shapes[self.segments[segment].shape]))
    }

    /// The obstacle whose inside holds `p`, if any.
    pub fn obstacle_at(&self, p: Point) -> Option<&Shape> {
        self.obstacle_index_at(p).map(|shape| &self.shapes[shape])
    }

    /// The distance from segment `a`–`b` to the nearest wall, obstacle edge or boundary edge,
    /// or `max` if none is closer (0 where it crosses one). Whether the segment lies inside an
    /// obstacle or outside the boundary is the caller's to check, at its ends
    /// ([`World::is_free`]): a segment that crosses no edge stays on one side of all of them.
    pub fn segment_clearance(&self, a: Point, b: Point, max: f64) -> f64 {
        if !a.is_finite() || !b.is_finite() || max.is_nan() || max <= 0.0 {
            return 0.0;
        }
        let grid = &self.grid;
        let (c0, c1) = grid.col_range(a.x.min(b.x) - max, a.x.max(b.x) + max);
        let (r0, r1) = grid.row_range(a.y.min(b.y) - max, a.y.max(b.y) + max);
        let mut best = max;
        for row in r0..=r1 {
            for col in c0..=c1 {
                // Only cells near the segment: the box of the cell widened by `best`.
                let lo = Point::new(
                    grid.min.x + col as f64 * grid.cell - best,
                    grid.min.y + row as f64 * grid.cell - best,
                );
                let hi = Point::new(lo.x + grid.cell + 2.0 * best, lo.y + grid.cell + 2.0 * best);
                if !segment_meets_box(a, b, lo, hi) {
                    continue;
                }
                for &index in grid.cell_items(col, row) {
                    let segment = &self.segments[index as usize];
                    let distance = segment_segment_distance(a, b, segment.a, segment.b);
                    if distance < best {
                        best = distance;
                        if best == 0.0 {
                            return 0.0;
                        }
                    }
                }
            }
        }
        best
    }

    /// Whether `p` is inside the boundary and outside every obstacle.
    pub fn is_free(&self, p: Point) -> bool {
        p.is_finite() && self.boundary().contains(p) && self.obstacle_index_at(p).is_none()
    }

    /// The shape a disc of `radius` at `p` runs into, if any.
    fn contact(&self, p: Point, radius: f64) -> Option<usize> {
        if !p.is_finite() || !self.boundary().contains(p) {
            return Some(0);
        }
        if let Some(shape) = self.obstacle_index_at(p) {
            return Some(shape);
        }
        self.nearest_segment(p, radius)
            .map(|(_, segment)| self.segments[segment].shape)
    }

    fn obstacle_index_at(&self, p: Point) -> Option<usize> {
        self.obstacles
            .iter()
            .find(|(bounds, shape)| bounds.contains(p) && self.shapes[*shape].contains(p))
            .map(|(_, shape)| *shape)
    }

    /// The nearest segment within `max` of `p` (inclusive), and its distance.
    fn nearest_segment(&self, p: Point, max: f64) -> Option<(f64, usize)> {
        if !p.is_finite() || max.is_nan() || max < 0.0 {
            return None;
        }
        let grid = &self.grid;
        let (c0, c1) = grid.col_range(p.x - max, p.x + max);
        let (r0, r1) = grid.row_range(p.y - max, p.y + max);
        let mut best: Option<(f64, usize)> = None;
        for row in r0..=r1 {
            for col in c0..=c1 {
                for &index in grid.cell_items(col, row) {
                    let segment = &self.segments[index as usize];
                    let distance = crate::geo::segment_distance(p, segment.a, segment.b);
                    if distance <= max && best.is_none_or(|(d, _)| distance < d) {
                        best = Some((distance, index as usize));
                    }
                }
            }
        }
        best
    }

    /// Checks that a robot of `radius` fits at the start pose: inside the boundary, outside every
    /// obstacle, touching no wall. The error points at the `start` statement. (Loading checks
    /// this with radius 0; the simulator again with its robot's radius.)
    pub fn check_start(&self, radius: f64) -> Result<(), WorldError> {
        let p = Point::new(self.start.x_m, self.start.y_m);
        let Some(shape_index) = self.contact(p, radius) else {
            return Ok(());
        };
        let shape = &self.shapes[shape_index];
        let subject = if radius > 0.0 {
            format!(
                "the robot (radius {} m) at the start pose {p}",
                crate::geo::round_mm(radius)
            )
        } else {
            format!("the start pose {p}")
        };
        let on_line = |shape: &Shape| shape_origin(shape.line);
        let problem = if shape.kind == ShapeKind::Boundary && !self.boundary().contains(p) {
            match shape.line {
                0 => "is outside the map".to_owned(),
                line => format!("is outside the boundary (line {line})"),
            }
        } else if shape.kind == ShapeKind::Obstacle && shape.contains(p) {
            format!("is inside the obstacle{}", on_line(shape))
        } else if radius > 0.0 {
            format!("overlaps the {}{}", shape.kind.noun(), on_line(shape))
        } else {
            format!("lies on the {}{}", shape.kind.noun(), on_line(shape))
        };
        Err(WorldError {
            file: self.file_name.clone(),
            line: self.start_at.0,
            col: self.start_at.1,
            message: format!("{subject} {problem}"),
        })
    }

    /// The world rasterised: cells crossed by a wall or edge, or inside an obstacle, are 100;
    /// other cells whose centre is inside the boundary 0; the rest -1 (unknown: out of reach).
    /// The grid covers [`World::bounds`] with its origin at the lower-left corner.
    pub fn occupancy_grid(&self, resolution_m: f64) -> Result<OccupancyGrid, String> {
        if !(resolution_m.is_finite() && resolution_m > 0.0) {
            return Err(format!(
                "the grid resolution must be greater than 0 m, not {resolution_m}"
            ));
        }
        let bounds = self.bounds;
        let width = ((bounds.width() / resolution_m).ceil() as usize).max(1);
        let height = ((bounds.height() / resolution_m).ceil() as usize).max(1);
        if width.saturating_mul(height) > MAX_GRID_CELLS {
            return Err(format!(
                "a {width} × {height} grid at {resolution_m} m is too large (at most {MAX_GRID_CELLS} cells)"
            ));
        }
        let cell_box = |col: usize, row: usize| {
            let lo = Point::new(
                bounds.min_x + col as f64 * resolution_m,
                bounds.min_y + row as f64 * resolution_m,
            );
            (lo, Point::new(lo.x + resolution_m, lo.y + resolution_m))
        };
        let index_of = |value: f64, origin: f64, count: usize| {
            (((value - origin) / resolution_m).floor().max(0.0) as usize).min(count - 1)
        };
        let mut cells = vec![0_i8; width * height];
        for row in 0..height {
            for col in 0..width {
                let (lo, hi) = cell_box(col, row);
                let centre = Point::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0);
                if !self.boundary().contains(centre) {
                    cells[row * width + col] = -1;
                }
            }
        }
        for &(obstacle_bounds, shape) in &self.obstacles {
            let (c0, c1) = (
                index_of(obstacle_bounds.min_x, bounds.min_x, width),
                index_of(obstacle_bounds.max_x, bounds.min_x, width),
            );
            let (r0, r1) = (
                index_of(obstacle_bounds.min_y, bounds.min_y, height),
                index_of(obstacle_bounds.max_y, bounds.min_y, height),
            );
            for row in r0..=r1 {
                for col in c0..=c1 {
                    let (lo, hi) = cell_box(col, row);
                    let centre = Point::new((lo.x + hi.x) / 2.0, (lo.y + hi.y) / 2.0);
                    if self.shapes[shape].contains(centre) {
                        cells[row * width + col] = 100;
                    }
                }
            }
        }
        for segment in &self.segments {
            let (a, b) = (segment.a, segment.b);
            let (c0, c1) = (
                index_of(a.x.min(b.x), bounds.min_x, width),
                index_of(a.x.max(b.x), bounds.min_x, width),
            );
            let (r0, r1) = (
                index_of(a.y.min(b.y), bounds.min_y, height),
                index_of(a.y.max(b.y), bounds.min_y, height),
            );
            for row in r0..=r1 {
                for col in c0..=c1 {
                    let (lo, hi) = cell_box(col, row);
                    if segment_meets_box(a, b, lo, hi) {
                        cells[row * width + col] = 100;
                    }
                }
            }
        }
        Ok(OccupancyGrid {
            resolution_m,
            width: width as u32,
            height: height as u32,
            origin_x_m: bounds.min_x,
            origin_y_m: bounds.min_y,
            cells,
        })
    }
}

/// A token of a line and its 1-based column.
#[derive(Clone, Copy, Debug)]
struct Token<'a> {
    text: &'a str,
    col: usize,
}

fn tokenize(line: &str) -> Vec<Token<'_>> {
    let mut tokens = Vec::new();
    let mut start: Option<(usize, usize)> = None;
    for (col, (byte, ch)) in line.char_indices().enumerate() {
        if ch.is_whitespace() {
            if let Some((from, col)) = start.take() {
                tokens.push(Token {
                    text: &line[from..byte],
                    col,
                });
            }
        } else if start.is_none() {
            start = Some((byte, col + 1));
        }
    }
    if let Some((from, col)) = start {
        tokens.push(Token {
            text: &line[from..],
            col,
        });
    }
    tokens
}

const STATEMENTS: &str = "name, origin, start, boundary, wall, obstacle, rect or circle";

/// A vertex and the column where it is written.
type Vertex = (Point, usize);

struct Parser<'a> {
    file: &'a str,
    name: Option<(String, usize)>,
    /// Latitude, longitude, line.
    origin: Option<(f64, f64, usize)>,
    /// Pose, line, column.
    start: Option<(Pose2D, usize, usize)>,
    boundary: Option<Shape>,
    shapes: Vec<Shape>,
}

impl Parser<'_> {
    fn error(&self, line: usize, col: usize, message: impl Into<String>) -> WorldError {
        WorldError {
            file: self.file.to_owned(),
            line,
            col,
            message: message.into(),
        }
    }

    fn statement(&mut self, line: usize, text: &str) -> Result<(), WorldError> {
        let text = text.split('#').next().unwrap_or_default();
        let tokens = tokenize(text);
        let Some((keyword, args)) = tokens.split_first() else {
            return Ok(());
        };
        match keyword.text {
            "name" => {
                if let Some((_, first)) = &self.name {
                    return Err(self.error(
                        line,
                        keyword.col,
                        format!("`name` is given twice (first on line {first})"),
                    ));
                }
                let name = args.first().map_or("", |first| {
                    // The rest of the line, spaces inside kept.
                    let from = text
                        .char_indices()
                        .nth(first.col - 1)
                        .map_or(text.len(), |(byte, _)| byte);
                    text[from..].trim()
                });
                if name.is_empty() {
                    return Err(self.error(line, keyword.col, "`name` needs the world's name"));
                }
                self.name = Some((name.to_owned(), line));
            }
            "origin" => {
                if let Some((_, _, first)) = self.origin {
                    return Err(self.error(
                        line,
                        keyword.col,
                        format!("`origin` is given twice (first on line {first})"),
                    ));
                }
                let [lat, lon] = self.values::<2>(
                    line,
                    keyword,
                    args,
                    "`origin LATITUDE LONGITUDE` (degrees, of the world's point (0, 0))",
                    ["the latitude", "the longitude"],
                )?;
                if !(-90.0..=90.0).contains(&lat) {
                    return Err(self.error(
                        line,
                        args[0].col,
                        format!("the latitude must be between -90 and 90 degrees, not {lat}"),
                    ));
                }
                if !(-180.0..=180.0).contains(&lon) {
                    return Err(self.error(
                        line,
                        args[1].col,
                        format!("the longitude must be between -180 and 180 degrees, not {lon}"),
                    ));
                }
                self.origin = Some((lat, lon, line));
            }
            "start" => {
                if let Some((_, first, _)) = self.start {
                    return Err(self.error(
                        line,
                        keyword.col,
                        format!("`start` is given twice (first on line {first})"),
                    ));
                }
                let [x, y, heading] = self.values::<3>(
                    line,
                    keyword,
                    args,
                    "`start X Y HEADING` (metres, metres, degrees)",
                    ["the start x", "the start y", "the start heading"],
                )?;
                let pose = Pose2D {
                    x_m: x,
                    y_m: y,
                    theta_rad: heading.to_radians(),
                };
                self.start = Some((pose, line, args[0].col));
            }
            "boundary" | "obstacle" => {
                let kind = if keyword.text == "boundary" {
                    ShapeKind::Boundary
                } else {
                    ShapeKind::Obstacle
                };
                if kind == ShapeKind::Boundary
                    && let Some(first) = &self.boundary
                {
                    return Err(self.error(
                        line,
                        keyword.col,
                        format!("`boundary` is given twice (first on line {})", first.line),
                    ));
                }
                let vertices = self.vertices(line, args)?;
                let shape = self.polygon(kind, line, keyword, &vertices)?;
                if kind == ShapeKind::Boundary {
                    self.boundary = Some(shape);
                } else {
                    self.shapes.push(shape);
                }
            }
            "wall" => {
                let vertices = self.vertices(line, args)?;
                let shape = self.wall(line, keyword, &vertices)?;
                self.shapes.push(shape);
            }
            "rect" => {
                let vertices = self.vertices(line, args)?;
                let [(a, _), (b, b_col)] = vertices[..] else {
                    return Err(self.error(
                        line,
                        args.get(2).unwrap_or(keyword).col,
                        format!(
                            "`rect` takes two opposite corners `rect X0,Y0 X1,Y1`, found {} vertices",
                            vertices.len()
                        ),
                    ));
                };
                if a.x == b.x || a.y == b.y {
                    return Err(self.error(
                        line,
                        b_col,
                        format!("the rectangle {a}–{b} has no area"),
                    ));
                }
                let (lo, hi) = (
                    Point::new(a.x.min(b.x), a.y.min(b.y)),
                    Point::new(a.x.max(b.x), a.y.max(b.y)),
                );
                self.shapes.push(Shape {
                    kind: ShapeKind::Obstacle,
                    points: vec![lo, Point::new(hi.x, lo.y), hi, Point::new(lo.x, hi.y)],
                    closed: true,
                    line,
                });
            }
            "circle" => {
                const USAGE: &str = "`circle X,Y RADIUS` (centre and radius in metres)";
                let [centre_token, radius_token] = args else {
                    return Err(self.error(
                        line,
                        args.get(2).unwrap_or(keyword).col,
                        format!("`circle` takes {USAGE}, found {} values", args.len()),
                    ));
                };
                let (centre, _) = self.vertex(line, *centre_token)?;
                let radius = self.number(line, *radius_token, "the radius")?;
                if radius <= 0.0 {
                    return Err(self.error(
                        line,
                        radius_token.col,
                        format!("the radius must be greater than 0 m, not {radius}"),
                    ));
                }
                self.shapes.push(Shape {
                    kind: ShapeKind::Obstacle,
                    points: circle(centre, radius),
                    closed: true,
                    line,
                });
            }
            other => {
                return Err(self.error(
                    line,
                    keyword.col,
                    format!("unknown statement `{other}` (expected {STATEMENTS})"),
                ));
            }
        }
        Ok(())
    }

    /// Exactly `N` numbers after the keyword.
    fn values<const N: usize>(
        &self,
        line: usize,
        keyword: &Token<'_>,
        args: &[Token<'_>],
        usage: &str,
        what: [&str; N],
    ) -> Result<[f64; N], WorldError> {
        if args.len() != N {
            let col = args.get(N).unwrap_or(keyword).col;
            return Err(self.error(
                line,
                col,
                format!(
                    "`{}` takes {N} values, found {}: write {usage}",
                    keyword.text,
                    args.len()
                ),
            ));
        }
        let mut values = [0.0; N];
        for (i, token) in args.iter().enumerate() {
            values[i] = self.number(line, *token, what[i])?;
        }
        Ok(values)
    }

    fn number(&self, line: usize, token: Token<'_>, what: &str) -> Result<f64, WorldError> {
        match token.text.parse::<f64>() {
            Ok(value) if value.is_finite() => Ok(value),
            Ok(_) => Err(self.error(
                line,
                token.col,
                format!("{what} must be a finite number, not `{}`", token.text),
            )),
            Err(_) => Err(self.error(
                line,
                token.col,
                format!("{what} must be a number, not `{}`", token.text),
            )),
        }
    }

    fn vertex(&self, line: usize, token: Token<'_>) -> Result<Vertex, WorldError> {
        let Some((x_text, y_text)) = token.text.split_once(',') else {
            return Err(self.error(
                line,
                token.col,
                format!(
                    "expected a vertex `X,Y` (two numbers and a comma, no space), found `{}`",
                    token.text
                ),
            ));
        };
        let x = self.number(
            line,
            Token {
                text: x_text,
                col: token.col,
            },
            "the x coordinate",
        )?;
        let y = self.number(
            line,
            Token {
                text: y_text,
                col: token.col + x_text.chars().count() + 1,
            },
            "the y coordinate",
        )?;
        Ok((Point::new(x, y), token.col))
    }

    /// The vertices of a shape, refusing a vertex written twice in a row.
    fn vertices(&self, line: usize, args: &[Token<'_>]) -> Result<Vec<Vertex>, WorldError> {
        let mut vertices: Vec<Vertex> = Vec::with_capacity(args.len());
        for token in args {
            let (point, col) = self.vertex(line, *token)?;
            if let Some((previous, _)) = vertices.last()
                && *previous == point
            {
                return Err(self.error(
                    line,
                    col,
                    format!("the vertex {point} is repeated: consecutive vertices must differ"),
                ));
            }
            vertices.push((point, col));
        }
        Ok(vertices)
    }

    /// A closed polygon written with its first vertex repeated at the end.
    fn polygon(
        &self,
        kind: ShapeKind,
        line: usize,
        keyword: &Token<'_>,
        vertices: &[Vertex],
    ) -> Result<Shape, WorldError> {
        let noun = kind.noun();
        let (Some((first, _)), Some((last, last_col))) = (vertices.first(), vertices.last()) else {
            return Err(self.error(
                line,
                keyword.col,
                format!(
                    "the {noun} has no vertices: write `{} X,Y X,Y X,Y ... X,Y`, ending where it starts",
                    keyword.text
                ),
            ));
        };
        if first != last {
            return Err(self.error(
                line,
                *last_col,
                format!(
                    "the {noun} is not closed: it starts at {first} but ends at {last} (repeat the first vertex at the end)"
                ),
            ));
        }
        self.closed_shape(kind, line, keyword, &vertices[..vertices.len() - 1])
    }

    /// A closed shape from its corners (first vertex not repeated): at least 3, not crossing
    /// itself, with an area.
    fn closed_shape(
        &self,
        kind: ShapeKind,
        line: usize,
        keyword: &Token<'_>,
        corners: &[Vertex],
    ) -> Result<Shape, WorldError> {
        let noun = kind.noun();
        if corners.len() < 3 {
            return Err(self.error(
                line,
                keyword.col,
                format!(
                    "the {noun} needs at least 3 corners, found {} (a closed shape repeats its first vertex at the end)",
                    corners.len()
                ),
            ));
        }
        let n = corners.len();
        let edge = |i: usize| (corners[i].0, corners[(i + 1) % n].0);
        for (i, &(_, col)) in corners.iter().enumerate() {
            for j in i + 1..n {
                let ((a1, a2), (b1, b2)) = (edge(i), edge(j));
                let crossing = if j == i + 1 {
                    // Share a2 == b1: they fold back if either far end lies on the other.
                    orientation(a1, a2, b2) == 0.0 && within(a1, a2, b2)
                        || orientation(b1, b2, a1) == 0.0 && within(b1, b2, a1)
                } else if i == 0 && j == n - 1 {
                    // Share a1 == b2.
                    orientation(a1, a2, b1) == 0.0 && within(a1, a2, b1)
                        || orientation(b1, b2, a2) == 0.0 && within(b1, b2, a2)
                } else {
                    segments_meet(a1, a2, b1, b2)
                };
                if crossing {
                    return Err(self.error(
                        line,
                        col,
                        format!("the {noun} crosses itself: edge {a1}–{a2} meets edge {b1}–{b2}"),
                    ));
                }
            }
        }
        let doubled_area: f64 = (0..n)
            .map(|i| {
                let (a, b) = edge(i);
                cross(a, b)
            })
            .sum();
        if doubled_area.abs() <= GEOMETRY_EPS {
            return Err(self.error(line, keyword.col, format!("the {noun} has no area")));
        }
        Ok(Shape {
            kind,
            points: corners.iter().map(|(point, _)| *point).collect(),
            closed: true,
            line,
        })
    }

    /// A wall: a polyline of at least 2 vertices, closed (and then a proper polygon) if it ends
    /// where it starts.
    fn wall(
        &self,
        line: usize,
        keyword: &Token<'_>,
        vertices: &[Vertex],
    ) -> Result<Shape, WorldError> {
        if vertices.len() < 2 {
            return Err(self.error(
                line,
                keyword.col,
                format!(
                    "the wall needs at least 2 vertices, found {}: write `wall X,Y X,Y ...`",
                    vertices.len()
                ),
            ));
        }
        if vertices.first().map(|v| v.0) == vertices.last().map(|v| v.0) {
            return self.closed_shape(
                ShapeKind::Wall,
                line,
                keyword,
                &vertices[..vertices.len() - 1],
            );
        }
        Ok(Shape {
            kind: ShapeKind::Wall,
            points: vertices.iter().map(|(point, _)| *point).collect(),
            closed: false,
            line,
        })
    }

    fn finish(self) -> Result<World, WorldError> {
        let missing = |what: &str| self.error(0, 0, what);
        let Some((name, _)) = &self.name else {
            return Err(missing(
                "no `name` line: give the world a name (`name TEXT`)",
            ));
        };
        let Some((lat, lon, _)) = self.origin else {
            return Err(missing(
                "no `origin` line: give the latitude and longitude of (0, 0) (`origin LAT LON`, degrees)",
            ));
        };
        let Some((start, start_line, start_col)) = self.start else {
            return Err(missing(
                "no `start` line: give the start pose (`start X Y HEADING`, metres and degrees)",
            ));
        };
        let Some(boundary) = &self.boundary else {
            return Err(missing(
                "no `boundary` line: give the outer wall as a closed polygon (`boundary X,Y X,Y X,Y ... X,Y`)",
            ));
        };
        let shapes: Vec<Shape> = std::iter::once(boundary.clone())
            .chain(self.shapes.iter().cloned())
            .collect();
        World::assemble(
            name.clone(),
            self.file.to_owned(),
            (lat, lon),
            start,
            (start_line, start_col),
            shapes,
        )
    }
}

/// Where a shape comes from, for messages: ` on line N` of a world file, or what a shape made
/// from a map's cells (line 0) stands for.
pub fn shape_origin(line: usize) -> String {
    match line {
        0 => " (occupied or unknown cells of the map)".to_owned(),
        line => format!(" on line {line}"),
    }
}

/// The polygon that stands for a disc (as the `circle` statement makes it).
pub fn circle(centre: Point, radius: f64) -> Vec<Point> {
    (0..CIRCLE_SIDES)
        .map(|i| {
            let angle = std::f64::consts::TAU * i as f64 / CIRCLE_SIDES as f64;
            Point::new(
                centre.x + radius * angle.cos(),
                centre.y + radius * angle.sin(),
            )
        })
        .collect()
}

impl World {
    /// This world with more walls and obstacles.
    pub fn with_shapes(&self, extra: impl IntoIterator<Item = Shape>) -> Result<World, WorldError> {
        let mut shapes = self.shapes.clone();
        shapes.extend(
            extra
                .into_iter()
                .filter(|shape| shape.kind != ShapeKind::Boundary),
        );
        World::assemble(
            self.name.clone(),
            self.file_name.clone(),
            self.origin_lat_lon,
            self.start,
            self.start_at,
            shapes,
        )
    }

    /// A world made of a boundary and solid obstacles given as corner lists (not repeating the
    /// first), which must not cross themselves (a map's cells, for one); the start pose is
    /// checked as a world file's is. `file_name` names where they came from in messages.
    pub fn from_shapes(
        name: &str,
        file_name: &str,
        origin_lat_lon: (f64, f64),
        start: Pose2D,
        boundary: Vec<Point>,
        obstacles: Vec<Vec<Point>>,
    ) -> Result<World, WorldError> {
        let boundary = Shape {
            kind: ShapeKind::Boundary,
            ..Shape::obstacle(boundary)
        };
        let shapes = std::iter::once(boundary)
            .chain(obstacles.into_iter().map(Shape::obstacle))
            .collect();
        World::assemble(
            name.to_owned(),
            file_name.to_owned(),
            origin_lat_lon,
            start,
            (0, 0),
            shapes,
        )
    }

    /// The world of checked shapes (the boundary first), with its indexes built.
    fn assemble(
        name: String,
        file_name: String,
        origin_lat_lon: (f64, f64),
        start: Pose2D,
        start_at: (usize, usize),
        shapes: Vec<Shape>,
    ) -> Result<World, WorldError> {
        let segments: Vec<Segment> = shapes
            .iter()
            .enumerate()
            .flat_map(|(index, shape)| {
                shape
                    .edges()
                    .map(move |(a, b)| Segment { a, b, shape: index })
            })
            .collect();
        let obstacles = shapes
            .iter()
            .enumerate()
            .filter(|(_, shape)| shape.kind == ShapeKind::Obstacle)
            .map(|(index, shape)| (Bounds::around(shape.points.iter().copied()), index))
            .collect();
        let bounds = Bounds::around(shapes.iter().flat_map(|shape| shape.points.iter().copied()));
        let grid = Grid::build(&bounds, &segments);
        let world = World {
            name,
            file_name,
            origin_lat_lon,
            start,
            start_at,
            shapes,
            segments,
            obstacles,
            bounds,
            grid,
        };
        world.check_start(0.0)?;
        Ok(world)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    const ROOM: &str = "\
name Test room
origin 45.5 -73.6
start 5 5 0
boundary 0,0 10,0 10,10 0,10 0,0
";

    fn room(extra: &str) -> World {
        World::parse(&format!("{ROOM}{extra}"), "room.world").expect("valid world")
    }

    fn error(text: &str) -> String {
        World::parse(text, "bad.world")
            .expect_err("must be refused")
            .to_string()
    }

    /// The room with one more line (line 5).
    fn room_error(line: &str) -> String {
        error(&format!("{ROOM}{line}\n"))
    }

    #[test]
    fn reads_a_world() {
        let world = room(
            "wall 2,2 2,4 # a comment\nobstacle 7,7 8,7 8,8 7,7\nrect 1,8 2,9\ncircle 8,2 0.5\n",
        );
        assert_eq!(world.name(), "Test room");
        assert_eq!(world.origin_lat_lon(), (45.5, -73.6));
        assert_eq!(
            world.start(),
            Pose2D {
                x_m: 5.0,
                y_m: 5.0,
                theta_rad: 0.0
            }
        );
        assert_eq!(world.shapes().len(), 5);
        assert_eq!(world.boundary().points.len(), 4);
        assert_eq!(world.shapes()[1].kind, ShapeKind::Wall);
        assert!(!world.shapes()[1].closed);
        assert_eq!(world.shapes()[2].line, 6);
        assert_eq!(world.segments().count(), 4 + 1 + 3 + 4 + CIRCLE_SIDES);
        let bounds = world.bounds();
        assert_eq!(
            (bounds.min_x, bounds.max_x, bounds.height()),
            (0.0, 10.0, 10.0)
        );
    }

    #[test]
    fn names_keep_their_spaces() {
        let world = World::parse(
            "name   Big   yard  \norigin 0 0\nstart 2 1 0\nboundary 0,0 3,0 3,3 0,0",
            "x",
        )
        .expect("valid");
        assert_eq!(world.name(), "Big   yard");
    }

    #[test]
    fn raycasts_in_a_square_room() {
        let world = room("");
        let centre = Point::new(5.0, 5.0);
        let cases = [
            (centre, 0.0, 5.0),
            (centre, std::f64::consts::FRAC_PI_2, 5.0),
            (centre, std::f64::consts::PI, 5.0),
            (centre, std::f64::consts::FRAC_PI_4, 50f64.sqrt()),
            (Point::new(2.0, 3.0), std::f64::consts::PI, 2.0),
            (Point::new(2.0, 3.0), -std::f64::consts::FRAC_PI_2, 3.0),
            (Point::new(2.0, 3.0), 0.0, 8.0),
            (
                Point::new(9.5, 0.5),
                -std::f64::consts::FRAC_PI_4,
                0.5 * 2f64.sqrt(),
            ),
        ];
        for (origin, angle, expected) in cases {
            let range = world.raycast(origin, angle, 100.0);
            assert!(
                (range - expected).abs() < 1e-9,
                "{origin} at {angle}: {range}"
            );
        }
        assert_eq!(world.raycast(centre, 0.0, 3.0), 3.0, "nothing within range");
        assert_eq!(world.raycast(centre, f64::NAN, 3.0), 3.0);
        // From outside the grid, looking in and looking away.
        let outside = Point::new(-5.0, 5.0);
        assert!((world.raycast(outside, 0.0, 100.0) - 5.0).abs() < 1e-9);
        assert_eq!(world.raycast(outside, std::f64::consts::PI, 100.0), 100.0);
    }

    #[test]
    fn raycasts_hit_the_nearest_of_several_shapes() {
        let world = room("obstacle 7,4 8,4 8,6 7,6 7,4\nwall 6,0 6,4.5\n");
        let range = world.raycast(Point::new(5.0, 5.0), 0.0, 100.0);
        assert!((range - 2.0).abs() < 1e-9, "{range}");
        let range = world.raycast(Point::new(5.0, 4.0), 0.0, 100.0);
        assert!((range - 1.0).abs() < 1e-9, "{range}");
        // Against a brute force over every segment, from many places and directions.
        let world = room("circle 3,3 0.7\ncircle 6.5,7 1.2\nwall 1,9 4,6.5 2,5.5\nrect 7,1 9,2\n");
        for i in 0..40 {
            for j in 0..72 {
                let origin = Point::new(0.25 + 0.24 * i as f64, 0.3 + 0.23 * i as f64);
                let angle = j as f64 * 5f64.to_radians();
                let dir = Point::new(angle.cos(), angle.sin());
                let brute = world
                    .segments()
                    .filter_map(|(a, b)| ray_meets_segment(origin, dir, a, b))
                    .fold(20.0_f64, f64::min);
                let fast = world.raycast(origin, angle, 20.0);
                assert!(
                    (fast - brute).abs() < 1e-9,
                    "{origin} {angle}: {fast} vs {brute}"
                );
            }
        }
    }

    #[test]
    fn collisions_with_walls_obstacles_and_the_boundary() {
        let world = room("obstacle 7,4 8,4 8,6 7,6 7,4\nwall 2,1 2,3\n");
        assert!(!world.collides(5.0, 5.0, 0.25));
        assert!(world.collides(6.8, 5.0, 0.25), "near the obstacle");
        assert!(world.collides(7.5, 5.0, 0.1), "inside the obstacle");
        assert!(world.collides(2.2, 2.0, 0.25), "near the wall");
        assert!(!world.collides(2.3, 2.0, 0.25));
        assert!(world.collides(2.0, 3.2, 0.25), "near the wall's end");
        assert!(world.collides(9.9, 5.0, 0.25), "near the boundary");
        assert!(world.collides(11.0, 5.0, 0.25), "outside the boundary");
        assert!(world.collides(f64::NAN, 5.0, 0.25));
        assert!((world.wall_distance(Point::new(5.0, 5.0), 10.0) - 2.0).abs() < 1e-9);
        assert!(world.is_free(Point::new(1.0, 1.0)));
        assert!(!world.is_free(Point::new(7.5, 5.0)));
    }

    #[test]
    fn converts_to_and_from_latitude_and_longitude() {
        let world = room("");
        let (lat, lon) = world.to_lat_lon(Point::new(0.0, 0.0));
        assert_eq!((lat, lon), (45.5, -73.6));
        let (lat, lon) = world.to_lat_lon(Point::new(1000.0, 2000.0));
        assert!((lat - 45.5 - 2000.0 / 111_195.0).abs() < 1e-6, "{lat}");
        assert!(lon > -73.6);
        let back = world.from_lat_lon(lat, lon);
        assert!(back.distance(Point::new(1000.0, 2000.0)) < 1e-6, "{back}");
    }

    #[test]
    fn rasterises_to_an_occupancy_grid() {
        let world = room("rect 6,6 8,8\n");
        let grid = world.occupancy_grid(0.5).expect("grid");
        assert_eq!((grid.width, grid.height), (20, 20));
        let at = |x: f64, y: f64| {
            grid.cells[(y / 0.5) as usize * grid.width as usize + (x / 0.5) as usize]
        };
        assert_eq!(at(7.1, 7.1), 100, "inside the rectangle");
        assert_eq!(at(6.1, 7.1), 100, "on its edge");
        assert_eq!(at(2.1, 2.1), 0, "free");
        assert_eq!(at(0.1, 5.1), 100, "on the boundary");
        assert!(world.occupancy_grid(0.0).is_err());
        assert!(world.occupancy_grid(1e-5).is_err());
        let triangle = World::parse(
            "name t\norigin 0 0\nstart 1 0.5 0\nboundary 0,0 4,0 0,4 0,0\n",
            "t",
        )
        .expect("valid");
        let grid = triangle.occupancy_grid(1.0).expect("grid");
        assert_eq!(grid.cells[3 * 4 + 3], -1, "outside the boundary");
    }

    #[test]
    fn refuses_open_polygons() {
        assert_eq!(
            room_error("obstacle 7,7 8,7 8,8"),
            "bad.world:5:18: the obstacle is not closed: it starts at (7, 7) but ends at (8, 8) (repeat the first vertex at the end)"
        );
        assert_eq!(
            error("name x\norigin 0 0\nstart 1 1 0\nboundary 0,0 10,0 10,10 0,10\n"),
            "bad.world:4:25: the boundary is not closed: it starts at (0, 0) but ends at (0, 10) (repeat the first vertex at the end)"
        );
    }

    #[test]
    fn refuses_self_intersecting_polygons() {
        assert_eq!(
            room_error("obstacle 1,1 4,4 4,1 1,4 1,1"),
            "bad.world:5:10: the obstacle crosses itself: edge (1, 1)–(4, 4) meets edge (4, 1)–(1, 4)"
        );
        assert_eq!(
            room_error("obstacle 1,1 3,1 2,1 2,2 1,1"),
            "bad.world:5:10: the obstacle crosses itself: edge (1, 1)–(3, 1) meets edge (3, 1)–(2, 1)"
        );
        assert_eq!(
            room_error("wall 1,1 3,1 3,3 2,0 1,1"),
            "bad.world:5:6: the wall crosses itself: edge (1, 1)–(3, 1) meets edge (3, 3)–(2, 0)"
        );
        // An open wall may cross itself; a closed one that does not is fine.
        room("wall 1,1 3,3 3,1 1,3\nwall 1,1 3,1 3,3 1,1\n");
    }

    #[test]
    fn refuses_too_few_vertices() {
        assert_eq!(
            room_error("obstacle 1,1 2,2 1,1"),
            "bad.world:5:1: the obstacle needs at least 3 corners, found 2 (a closed shape repeats its first vertex at the end)"
        );
        assert_eq!(
            room_error("obstacle"),
            "bad.world:5:1: the obstacle has no vertices: write `obstacle X,Y X,Y X,Y ... X,Y`, ending where it starts"
        );
        assert_eq!(
            room_error("wall 1,1"),
            "bad.world:5:1: the wall needs at least 2 vertices, found 1: write `wall X,Y X,Y ...`"
        );
        assert_eq!(
            room_error("obstacle 1,1 2,1 3,1 1,1"),
            "bad.world:5:10: the obstacle crosses itself: edge (1, 1)–(2, 1) meets edge (3, 1)–(1, 1)"
        );
        assert_eq!(
            room_error("obstacle 1,1 2,2 2,2 1,1"),
            "bad.world:5:18: the vertex (2, 2) is repeated: consecutive vertices must differ"
        );
    }

    #[test]
    fn refuses_a_start_pose_in_the_way() {
        let world = |start: &str| {
            error(&format!(
                "name x\norigin 0 0\n{start}\nboundary 0,0 10,0 10,10 0,10 0,0\nobstacle 4,4 6,4 6,6 4,6 4,4\nwall 1,1 1,3\n"
            ))
        };
        assert_eq!(
            world("start 5 5 0"),
            "bad.world:3:7: the start pose (5, 5) is inside the obstacle on line 5"
        );
        assert_eq!(
            world("start 12 5 0"),
            "bad.world:3:7: the start pose (12, 5) is outside the boundary (line 4)"
        );
        assert_eq!(
            world("start 1 2 0"),
            "bad.world:3:7: the start pose (1, 2) lies on the wall on line 6"
        );
        let ok = World::parse(
            "name x\norigin 0 0\nstart 1.2 2 0\nboundary 0,0 10,0 10,10 0,10 0,0\nwall 1,1 1,3\n",
            "ok.world",
        )
        .expect("valid");
        assert_eq!(
            ok.check_start(0.25).expect_err("too close").to_string(),
            "ok.world:3:7: the robot (radius 0.25 m) at the start pose (1.2, 2) overlaps the wall on line 5"
        );
        ok.check_start(0.1).expect("fits");
    }

    #[test]
    fn refuses_bad_numbers() {
        assert_eq!(
            room_error("circle 5,nan 1"),
            "bad.world:5:10: the y coordinate must be a finite number, not `nan`"
        );
        assert_eq!(
            room_error("wall 1,1 2,x"),
            "bad.world:5:12: the y coordinate must be a number, not `x`"
        );
        assert_eq!(
            room_error("wall 1,1 2 3"),
            "bad.world:5:10: expected a vertex `X,Y` (two numbers and a comma, no space), found `2`"
        );
        assert_eq!(
            error("name x\norigin NaN 0\n"),
            "bad.world:2:8: the latitude must be a finite number, not `NaN`"
        );
        assert_eq!(
            error("name x\norigin 91 0\n"),
            "bad.world:2:8: the latitude must be between -90 and 90 degrees, not 91"
        );
        assert_eq!(
            error("name x\nstart 1 2 inf\n"),
            "bad.world:2:11: the start heading must be a finite number, not `inf`"
        );
        assert_eq!(
            error("name x\nstart 1 2\n"),
            "bad.world:2:1: `start` takes 3 values, found 2: write `start X Y HEADING` (metres, metres, degrees)"
        );
        assert_eq!(
            room_error("circle 5,5 -1"),
            "bad.world:5:12: the radius must be greater than 0 m, not -1"
        );
        assert_eq!(
            room_error("rect 1,1 1,3"),
            "bad.world:5:10: the rectangle (1, 1)–(1, 3) has no area"
        );
    }

    #[test]
    fn refuses_unknown_missing_and_repeated_statements() {
        assert_eq!(
            room_error("  tree 1,1"),
            "bad.world:5:3: unknown statement `tree` (expected name, origin, start, boundary, wall, obstacle, rect or circle)"
        );
        assert_eq!(
            room_error("start 1 1 0"),
            "bad.world:5:1: `start` is given twice (first on line 3)"
        );
        assert_eq!(
            room_error("boundary 0,0 1,0 1,1 0,0"),
            "bad.world:5:1: `boundary` is given twice (first on line 4)"
        );
        assert_eq!(
            error("name x\norigin 0 0\nstart 1 1 0\n"),
            "bad.world: no `boundary` line: give the outer wall as a closed polygon (`boundary X,Y X,Y X,Y ... X,Y`)"
        );
        assert_eq!(
            error("# nothing\n"),
            "bad.world: no `name` line: give the world a name (`name TEXT`)"
        );
        assert_eq!(
            error("name\n"),
            "bad.world:1:1: `name` needs the world's name"
        );
    }

    #[test]
    fn the_bundled_worlds_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/worlds");
        for name in [
            "yard.world",
            "building.world",
            "field.world",
            "warehouse.world",
        ] {
            let path = dir.join(name);
            let text = std::fs::read_to_string(&path).unwrap_or_else(|err| panic!("{err}"));
            let world = World::parse(&text, &path.display().to_string())
                .unwrap_or_else(|err| panic!("{err}"));
            world
                .check_start(0.25)
                .unwrap_or_else(|err| panic!("{err}"));
        }
    }
}
