//! The costmap: the world (or an open box) rasterised, inflated by what the robot keeps from
//! obstacles and no-go areas, with a cost that falls off beyond.

use std::fmt;

use armor_module_api::types::OccupancyGrid;

use super::{Blocker, CostmapSettings, Keepout, Robot};
use crate::world::{Bounds, Point, World};

/// The cost of a cell the robot's centre must not enter.
pub const LETHAL: u8 = 255;
/// The cost of a free cell right at the edge of the lethal zone, in percent of a step: a step
/// there costs twice a step in the open.
pub(crate) const MAX_EXTRA: u8 = 100;

/// The most cells on a side of a costmap.
const MAX_SIDE_CELLS: f64 = 65_536.0;

/// Why a costmap cannot be built.
#[derive(Clone, Debug, PartialEq)]
pub struct CostmapError(pub String);

impl fmt::Display for CostmapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CostmapError {}

/// A grid over the map: each cell's cost ([`LETHAL`], or 0 to 100 percent extra per step) and
/// its slack (how much further than needed it is from the nearest obstacle or area, negative
/// when too close). The outermost ring of cells is lethal, so that a search needs no bounds
/// checks. Cell `col`, `row` is at index `row * width + col`; `(0, 0)` has its lower-left corner
/// at [`Costmap::origin`].
#[derive(Clone, Debug)]
pub struct Costmap {
    origin: Point,
    resolution_m: f64,
    width: usize,
    height: usize,
    cost: Vec<u8>,
    slack: Vec<f32>,
    robot: Robot,
    keepouts: Vec<Keepout>,
    world: Option<World>,
    /// Where the robot may be with no world: the box the map was asked to cover.
    extent: Bounds,
    falloff_m: f64,
}

impl Costmap {
    /// The costmap of `world` with its obstacles inflated for `robot` and the `keepouts`.
    pub fn for_world(
        world: &World,
        robot: &Robot,
        keepouts: &[Keepout],
        settings: &CostmapSettings,
    ) -> Result<Costmap, CostmapError> {
        let mut map = Costmap::empty(world.bounds(), robot, keepouts, settings)?;
        map.world = Some(world.clone());
        let occupied = map.rasterise(world);
        map.inflate_obstacles(world, &occupied);
        drop(occupied);
        map.finish();
        Ok(map)
    }

    /// The costmap of the box `extent` with nothing in it but the keepouts (a plan with no
    /// world: a real robot's map is not known). Beyond the box is lethal.
    pub fn open(
        extent: Bounds,
        robot: &Robot,
        keepouts: &[Keepout],
        settings: &CostmapSettings,
    ) -> Result<Costmap, CostmapError> {
        let mut map = Costmap::empty(extent, robot, keepouts, settings)?;
        map.finish();
        Ok(map)
    }

    /// All cells free and far from everything, the border lethal.
    fn empty(
        extent: Bounds,
        robot: &Robot,
        keepouts: &[Keepout],
        settings: &CostmapSettings,
    ) -> Result<Costmap, CostmapError> {
        let finite = [extent.min_x, extent.min_y, extent.max_x, extent.max_y]
            .iter()
            .all(|v| v.is_finite());
        if !finite || extent.width() < 0.0 || extent.height() < 0.0 {
            return Err(CostmapError(format!(
                "the map's extent is not a box: {extent:?}"
            )));
        }
        if !(settings.resolution_m.is_finite() && settings.resolution_m > 0.0) {
            return Err(CostmapError(format!(
                "the cell size must be greater than 0 m, not {}",
                settings.resolution_m
            )));
        }
        if !(robot.radius_m >= 0.0 && robot.clearance_m >= 0.0 && robot.keep_m().is_finite()) {
            return Err(CostmapError(format!(
                "the robot's radius and clearance must be 0 m or more, not {} and {}",
                robot.radius_m, robot.clearance_m
            )));
        }
        let max_cells = settings.max_cells.max(16) as f64;
        let mut resolution_m = settings.resolution_m;
        let cells = |resolution: f64| {
            ((extent.width() / resolution).ceil() + 2.0)
                * ((extent.height() / resolution).ceil() + 2.0)
        };
        // The search packs a cell's column and row in 16 bits each.
        let side = |resolution: f64| {
            (extent.width() / resolution)
                .ceil()
                .max((extent.height() / resolution).ceil())
                + 2.0
        };
        if cells(resolution_m) > max_cells {
            resolution_m = (extent.width() * extent.height() / max_cells).sqrt();
        }
        while cells(resolution_m) > max_cells || side(resolution_m) > MAX_SIDE_CELLS {
            resolution_m *= 1.01;
        }
        let width = (extent.width() / resolution_m).ceil() as usize + 2;
        let height = (extent.height() / resolution_m).ceil() as usize + 2;
        let mut map = Costmap {
            origin: Point::new(extent.min_x - resolution_m, extent.min_y - resolution_m),
            resolution_m,
            width,
            height,
            cost: vec![0; width * height],
            slack: vec![f32::INFINITY; width * height],
            robot: *robot,
            keepouts: keepouts
                .iter()
                .filter(|keepout| keepout.polygon.corners.len() >= 3)
                .cloned()
                .collect(),
            world: None,
            extent,
            falloff_m: settings.falloff_m.max(0.0),
        };
        for col in 0..width {
            map.cost[col] = LETHAL;
            map.cost[(height - 1) * width + col] = LETHAL;
        }
        for row in 0..height {
            map.cost[row * width] = LETHAL;
            map.cost[row * width + width - 1] = LETHAL;
        }
        Ok(map)
    }

    /// The cell size.
    pub fn resolution_m(&self) -> f64 {
        self.resolution_m
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// The lower-left corner of cell (0, 0), in the world frame.
    pub fn origin(&self) -> Point {
        self.origin
    }

    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    pub fn keepouts(&self) -> &[Keepout] {
        &self.keepouts
    }

    pub fn world(&self) -> Option<&World> {
        self.world.as_ref()
    }

    /// Every cell's cost, row after row.
    pub fn costs(&self) -> &[u8] {
        &self.cost
    }

    /// The cell holding `p`, if it is on the map.
    pub fn cell_of(&self, p: Point) -> Option<usize> {
        let col = ((p.x - self.origin.x) / self.resolution_m).floor();
        let row = ((p.y - self.origin.y) / self.resolution_m).floor();
        let inside =
            col >= 0.0 && row >= 0.0 && (col as usize) < self.width && (row as usize) < self.height;
        inside.then(|| row as usize * self.width + col as usize)
    }

    /// The centre of a cell.
    pub fn centre(&self, cell: usize) -> Point {
        let (col, row) = (cell % self.width, cell / self.width);
        Point::new(
            self.origin.x + (col as f64 + 0.5) * self.resolution_m,
            self.origin.y + (row as f64 + 0.5) * self.resolution_m,
        )
    }

    /// Whether the robot's centre may not be in the cell holding `p` (off the map included).
    pub fn is_lethal_at(&self, p: Point) -> bool {
        self.cell_of(p).is_none_or(|cell| self.cost[cell] == LETHAL)
    }

    pub(crate) fn slack(&self, cell: usize) -> f32 {
        self.slack[cell]
    }

    /// Half a cell's diagonal: how far a point of a cell can be from its centre.
    pub(crate) fn half_diagonal(&self) -> f64 {
        self.resolution_m * std::f64::consts::FRAC_1_SQRT_2
    }

    /// The map as an occupancy grid to draw: lethal cells 100, the others their cost scaled to
    /// 0–99.
    pub fn to_occupancy_grid(&self) -> OccupancyGrid {
        OccupancyGrid {
            resolution_m: self.resolution_m,
            width: self.width as u32,
            height: self.height as u32,
            origin_x_m: self.origin.x,
            origin_y_m: self.origin.y,
            cells: self
                .cost
                .iter()
                .map(|&cost| {
                    if cost == LETHAL {
                        100
                    } else {
                        (u32::from(cost) * 99 / u32::from(MAX_EXTRA)) as i8
                    }
                })
                .collect(),
        }
    }

    /// Why the robot cannot be at `p`, measured on the geometry (not the cells): outside the
    /// world, in or too near an obstacle, in or too near a no-go area.
    pub fn blocker_at(&self, p: Point) -> Option<Blocker> {
        if !p.is_finite() || self.cell_of(p).is_none() {
            return Some(Blocker::OutsideWorld);
        }
        if self.world.is_none() && !self.extent.contains(p) {
            return Some(Blocker::OutsideWorld);
        }
        super::blocker_at(self.world.as_ref(), &self.robot, &self.keepouts, p)
    }

    /// Whether the robot can drive straight from `a` to `b`, measured on the geometry: both
    /// ends where it may be, and the segment keeping its distance from every obstacle and area.
    pub fn segment_clear(&self, a: Point, b: Point) -> bool {
        if !a.is_finite() || !b.is_finite() {
            return false;
        }
        let keep = self.robot.keep_m();
        match &self.world {
            Some(world) => {
                if !world.is_free(a)
                    || !world.is_free(b)
                    || world.segment_clearance(a, b, keep) < keep
                {
                    return false;
                }
            }
            None => {
                if !self.extent.contains(a) || !self.extent.contains(b) {
                    return false;
                }
            }
        }
        super::clear_of_keepouts(&self.robot, &self.keepouts, a, b)
    }

    /// Visits the cells that segment `a`–`b` passes through, in order, with the length of the
    /// segment inside each (in metres), until `visit` says stop. Where the segment passes exactly
    /// through a corner, only the cells it enters are visited: the corner belongs to them too.
    /// Returns false when stopped or when the segment leaves the map.
    pub(crate) fn walk(
        &self,
        a: Point,
        b: Point,
        mut visit: impl FnMut(usize, f64) -> bool,
    ) -> bool {
        let res = self.resolution_m;
        let (ax, ay) = ((a.x - self.origin.x) / res, (a.y - self.origin.y) / res);
        let (bx, by) = ((b.x - self.origin.x) / res, (b.y - self.origin.y) / res);
        if !(ax.is_finite() && ay.is_finite() && bx.is_finite() && by.is_finite()) {
            return false;
        }
        let length_m = a.distance(b);
        let (mut cx, mut cy) = (ax.floor() as i64, ay.floor() as i64);
        let (ex, ey) = (bx.floor() as i64, by.floor() as i64);
        let (dx, dy) = (bx - ax, by - ay);
        let step_x: i64 = if dx > 0.0 {
            1
        } else if dx < 0.0 {
            -1
        } else {
            0
        };
        let step_y: i64 = if dy > 0.0 {
            1
        } else if dy < 0.0 {
            -1
        } else {
            0
        };
        let delta_x = if dx == 0.0 {
            f64::INFINITY
        } else {
            1.0 / dx.abs()
        };
        let delta_y = if dy == 0.0 {
            f64::INFINITY
        } else {
            1.0 / dy.abs()
        };
        let mut next_x = match step_x {
            1 => ((cx + 1) as f64 - ax) / dx,
            -1 => (cx as f64 - ax) / dx,
            _ => f64::INFINITY,
        };
        let mut next_y = match step_y {
            1 => ((cy + 1) as f64 - ay) / dy,
            -1 => (cy as f64 - ay) / dy,
            _ => f64::INFINITY,
        };
        let (width, height) = (self.width as i64, self.height as i64);
        let index = |cx: i64, cy: i64| {
            (cx >= 0 && cy >= 0 && cx < width && cy < height).then(|| (cy * width + cx) as usize)
        };
        let steps = (ex - cx).abs() + (ey - cy).abs() + 1;
        let mut t = 0.0_f64;
        for _ in 0..=steps {
            let Some(cell) = index(cx, cy) else {
                return false;
            };
            let at_end = cx == ex && cy == ey;
            let t_next = if at_end {
                1.0
            } else {
                next_x.min(next_y).min(1.0)
            };
            if !visit(cell, (t_next - t).max(0.0) * length_m) {
                return false;
            }
            if at_end {
                return true;
            }
            if t_next >= 1.0 {
                // Rounding left the end cell unvisited: it holds `b`, so it is visited too.
                return index(ex, ey).is_some_and(|cell| visit(cell, 0.0));
            }
            if (next_x - next_y).abs() <= 1e-12 {
                cx += step_x;
                cy += step_y;
                next_x += delta_x;
                next_y += delta_y;
            } else if next_x < next_y {
                cx += step_x;
                next_x += delta_x;
            } else {
                cy += step_y;
                next_y += delta_y;
            }
            t = t_next;
        }
        index(ex, ey).is_some_and(|cell| visit(cell, 0.0))
    }

    /// For each row of the map, the columns whose cell centres lie inside `polygon` (even-odd
    /// rule, as [`crate::geo::inside`]), as spans `from..to`.
    fn spans(&self, polygon: &[Point], mut span: impl FnMut(usize, usize, usize)) {
        if polygon.len() < 3 {
            return;
        }
        let res = self.resolution_m;
        let (min_y, max_y) = polygon
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.y), hi.max(p.y))
            });
        let first = ((min_y - self.origin.y) / res - 0.5).ceil().max(0.0) as usize;
        let last = (((max_y - self.origin.y) / res - 0.5).floor().max(-1.0) + 1.0) as usize;
        let last = last.min(self.height);
        let mut crossings: Vec<f64> = Vec::new();
        let n = polygon.len();
        for row in first..last {
            let y = self.origin.y + (row as f64 + 0.5) * res;
            crossings.clear();
            for i in 0..n {
                let (a, b) = (polygon[i], polygon[(i + 1) % n]);
                if (a.y > y) != (b.y > y) {
                    crossings.push(a.x + (y - a.y) / (b.y - a.y) * (b.x - a.x));
                }
            }
            crossings.sort_by(f64::total_cmp);
            for pair in crossings.chunks_exact(2) {
                let column = |x: f64| {
                    ((x - self.origin.x) / res - 0.5)
                        .ceil()
                        .clamp(0.0, self.width as f64) as usize
                };
                let (from, to) = (column(pair[0]), column(pair[1]));
                if from < to {
                    span(row, from, to);
                }
            }
        }
    }

    /// The occupied cells of the world: outside the boundary, inside an obstacle (by the
    /// cell's centre), or touched by any edge or wall.
    fn rasterise(&self, world: &World) -> Vec<bool> {
        let width = self.width;
        let mut occupied = vec![true; width * self.height];
        self.spans(&world.boundary().points, |row, from, to| {
            occupied[row * width + from..row * width + to].fill(false);
        });
        for shape in world.shapes().iter().skip(1) {
            if shape.kind == crate::world::ShapeKind::Obstacle {
                self.spans(&shape.points, |row, from, to| {
                    occupied[row * width + from..row * width + to].fill(true);
                });
            }
        }
        for (a, b) in world.segments() {
            self.walk(a, b, |cell, _| {
                occupied[cell] = true;
                true
            });
        }
        occupied
    }

    /// Lethal cells and slack from the world's obstacles: a distance transform of the occupied
    /// cells, with the cells it cannot decide measured against the geometry.
    fn inflate_obstacles(&mut self, world: &World, occupied: &[bool]) {
        let squared = distance_transform(occupied, self.width, self.height);
        let res = self.resolution_m;
        let keep = self.robot.keep_m();
        let half = self.half_diagonal();
        // A cell is lethal when its centre is closer than `lethal` to the geometry: then every
        // point of the cell is at least `keep` away. The transform measures to the centres of
        // occupied cells, within `half` of the geometry either way.
        let lethal = keep + half;
        for (cell, &squared) in squared.iter().enumerate() {
            let distance = f64::from(squared).sqrt() * res;
            self.slack[cell] = (distance - keep) as f32;
            if self.cost[cell] == LETHAL {
                continue;
            }
            let is_lethal = if distance + half < lethal {
                true
            } else if distance - half >= lethal {
                false
            } else {
                world.wall_distance(self.centre(cell), lethal) < lethal
            };
            if is_lethal {
                self.cost[cell] = LETHAL;
            }
        }
    }

    /// Keepouts, then the costs of the free cells from their slack.
    fn finish(&mut self) {
        let res = self.resolution_m;
        let half = self.half_diagonal();
        let keepouts = std::mem::take(&mut self.keepouts);
        for keepout in &keepouts {
            let keep = keepout.keep_m(&self.robot);
            let reach = keep + half + self.falloff_m + res;
            let (lo, hi) = keepout.polygon.corners.iter().fold(
                (
                    Point::new(f64::INFINITY, f64::INFINITY),
                    Point::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
                ),
                |(lo, hi), p| {
                    (
                        Point::new(lo.x.min(p.x), lo.y.min(p.y)),
                        Point::new(hi.x.max(p.x), hi.y.max(p.y)),
                    )
                },
            );
            let col = |x: f64| {
                ((x - self.origin.x) / res)
                    .floor()
                    .clamp(0.0, (self.width - 1) as f64) as usize
            };
            let row = |y: f64| {
                ((y - self.origin.y) / res)
                    .floor()
                    .clamp(0.0, (self.height - 1) as f64) as usize
            };
            let (c0, c1) = (col(lo.x - reach), col(hi.x + reach));
            let (r0, r1) = (row(lo.y - reach), row(hi.y + reach));
            let mut inside = vec![false; (c1 - c0 + 1) * (r1 - r0 + 1)];
            let span_width = c1 - c0 + 1;
            self.spans(&keepout.polygon.corners, |r, from, to| {
                if (r0..=r1).contains(&r) {
                    for c in from.max(c0)..to.min(c1 + 1) {
                        inside[(r - r0) * span_width + (c - c0)] = true;
                    }
                }
            });
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let cell = r * self.width + c;
                    let (slack, is_lethal) = if inside[(r - r0) * span_width + (c - c0)] {
                        (-keep, true)
                    } else {
                        let distance = keepout.polygon.distance_to_outline(self.centre(cell));
                        (distance - keep, distance < keep + half)
                    };
                    self.slack[cell] = self.slack[cell].min(slack as f32);
                    if is_lethal {
                        self.cost[cell] = LETHAL;
                    }
                }
            }
        }
        self.keepouts = keepouts;
        let falloff = self.falloff_m;
        for (cost, &slack) in self.cost.iter_mut().zip(&self.slack) {
            if *cost == LETHAL {
                continue;
            }
            let beyond = f64::from(slack) - half;
            *cost = if beyond >= falloff {
                0
            } else if beyond <= 0.0 {
                MAX_EXTRA
            } else {
                (f64::from(MAX_EXTRA) * (1.0 - beyond / falloff)).round() as u8
            };
        }
    }
}

/// Squared distances, in cells, from each cell's centre to the centre of the nearest occupied
/// cell (Felzenszwalb and Huttenlocher's exact transform: a pass down the columns, then the
/// lower envelope of parabolas along each row). Far from everything the value is huge.
fn distance_transform(occupied: &[bool], width: usize, height: usize) -> Vec<f32> {
    const FAR: f64 = 1e12;
    // Down the columns: the distance to the nearest occupied cell above or below, row by row
    // so that memory is read in order.
    let mut vertical = vec![u32::MAX; width * height];
    let mut above = vec![u32::MAX; width];
    for row in 0..height {
        for (col, above) in above.iter_mut().enumerate() {
            let cell = row * width + col;
            *above = if occupied[cell] {
                0
            } else {
                above.saturating_add(1)
            };
            vertical[cell] = *above;
        }
    }
    let mut below = vec![u32::MAX; width];
    for row in (0..height).rev() {
        for (col, below) in below.iter_mut().enumerate() {
            let cell = row * width + col;
            *below = if occupied[cell] {
                0
            } else {
                below.saturating_add(1)
            };
            vertical[cell] = vertical[cell].min(*below);
        }
    }
    let mut out = vec![0.0_f32; width * height];
    let mut f = vec![0.0_f64; width];
    let mut v = vec![0_usize; width];
    let mut z = vec![0.0_f64; width + 1];
    for row in 0..height {
        let line = &vertical[row * width..(row + 1) * width];
        for (value, &distance) in f.iter_mut().zip(line) {
            *value = if distance == u32::MAX {
                FAR
            } else {
                f64::from(distance) * f64::from(distance)
            };
        }
        // The lower envelope of the parabolas (x - q)² + f(q).
        let mut k = 0;
        v[0] = 0;
        z[0] = f64::NEG_INFINITY;
        z[1] = f64::INFINITY;
        for q in 1..width {
            let fq = f[q] + (q * q) as f64;
            // z[0] is minus infinity, so k never goes below 0.
            let mut s;
            loop {
                let p = v[k];
                s = (fq - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64);
                if s > z[k] {
                    break;
                }
                k -= 1;
            }
            k += 1;
            v[k] = q;
            z[k] = s;
            z[k + 1] = f64::INFINITY;
        }
        k = 0;
        let out_line = &mut out[row * width..(row + 1) * width];
        for (q, value) in out_line.iter_mut().enumerate() {
            while z[k + 1] < q as f64 {
                k += 1;
            }
            let p = v[k];
            let dq = q as f64 - p as f64;
            *value = (dq * dq + f[p]).min(FAR) as f32;
        }
    }
    out
}

#[cfg(test)]
pub(crate) fn distance_transform_for_tests(
    occupied: &[bool],
    width: usize,
    height: usize,
) -> Vec<f32> {
    distance_transform(occupied, width, height)
}
