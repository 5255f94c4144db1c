//! Scan matching against the map built so far, in two stages:
//!
//! 1. A correlative search over a window of poses around the predicted one (headings a step
//!    apart, under which the farthest point moves by a cell; positions a cell apart), coarse to
//!    fine, scoring the scan's points on the grid's likelihood field, with a slight preference
//!    for poses near the prediction. This finds the right basin even when the prediction is
//!    tenths of a metre or several degrees off.
//! 2. A few Gauss–Newton steps of point-to-line ICP from that pose, against the mean echoes
//!    the grid keeps per cell and the surfaces through them: a pose finer than a cell, without
//!    the cell-centre bias of a field sampled on the grid.
//!
//! Only the points that fall on the mapped part of the grid take part: points beyond the edge
//! of what is mapped would otherwise pull the scan back into it, which in a corridor drags the
//! pose backwards at every scan.

use armor_module_api::types::Pose2D;

use super::grid::LogOddsGrid;
use crate::nav::wrap_angle;

/// How far from the predicted pose the matcher looks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SearchWindow {
    /// Each way in x and in y.
    pub linear_m: f64,
    /// Each way in heading.
    pub angular_rad: f64,
}

/// The pose that best explains a scan, and how well it does.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Match {
    pub pose: Pose2D,
    /// The mean likelihood field value at the points used (0: none near a wall … 1: all on
    /// occupied cells).
    pub score: f64,
    /// How many of the scan's points were used: those that fall on the mapped part of the grid.
    pub points: usize,
}

/// Among equally good poses, the one nearest the prediction wins: a pose at the edge of the
/// window in one direction loses this much of its mean score.
const PRIOR_WEIGHT: f64 = 0.1;
/// The refinement's pull towards the correlative pose, per point and per square metre (or square
/// radian): weak, but it holds the pose along a featureless corridor.
const REFINE_PRIOR: f64 = 0.01;
/// Points that land on unknown cells from the predicted pose are left out of the match (they
/// would pull the scan back into the mapped area), unless this close to a wall in the field.
const NEAR_WALL_FIELD: f32 = 0.6;
/// The angular step of the search is the angle under which the farthest point moves by a cell,
/// but no finer than this.
const MIN_ANGULAR_STEP_RAD: f64 = 0.002;
const REFINE_ITERATIONS: usize = 6;
/// A point pairs with a mapped echo at most this many cells away.
const PAIRING_CELLS: f64 = 1.5;
/// Residuals beyond this many cells count less (Huber).
const HUBER_CELLS: f64 = 0.3;
/// At least this many pairs are needed to refine.
const MIN_PAIRS: usize = 10;

/// A cell of the grid and the normal of the surface through it, if it has one.
type CellNormal = (usize, Option<(f64, f64)>);

/// The matcher, with its buffers kept between scans.
#[derive(Clone, Debug, Default)]
pub struct Matcher {
    scores: Vec<f32>,
    usable: Vec<(f64, f64)>,
    /// Per point, the cell it last paired with and that cell's surface normal.
    normals: Vec<Option<CellNormal>>,
}

/// The correlative search's pull towards the predicted pose, in units of mean field score.
#[derive(Clone, Copy, Debug)]
struct Prior {
    predicted: Pose2D,
    /// Per square metre of distance.
    linear: f64,
    /// Per square radian of turn.
    angular: f64,
}

impl Prior {
    fn new(predicted: Pose2D, window: SearchWindow, res: f64, angular_step: f64) -> Self {
        let linear_reach = window.linear_m.max(res);
        let angular_reach = window.angular_rad.max(angular_step);
        Self {
            predicted,
            linear: PRIOR_WEIGHT / (linear_reach * linear_reach),
            angular: PRIOR_WEIGHT / (angular_reach * angular_reach),
        }
    }

    fn offsets(&self, pose: Pose2D) -> [f64; 3] {
        [
            pose.x_m - self.predicted.x_m,
            pose.y_m - self.predicted.y_m,
            wrap_angle(pose.theta_rad - self.predicted.theta_rad),
        ]
    }

    fn penalty(&self, pose: Pose2D) -> f64 {
        let [dx, dy, dtheta] = self.offsets(pose);
        self.linear * (dx * dx + dy * dy) + self.angular * dtheta * dtheta
    }
}

impl Matcher {
    /// Matches `points` (in the sensor's frame) against `grid` around `predicted`. Only the
    /// points that land on the mapped part of the grid from the predicted pose are used; None
    /// when there are none.
    pub fn match_scan(
        &mut self,
        grid: &LogOddsGrid,
        points: &[(f64, f64)],
        predicted: Pose2D,
        window: SearchWindow,
    ) -> Option<Match> {
        let mut usable = std::mem::take(&mut self.usable);
        usable.clear();
        let sin_cos = predicted.theta_rad.sin_cos();
        usable.extend(points.iter().copied().filter(|&p| {
            let (x, y) = transform(predicted, sin_cos, p);
            grid.cell_of(x, y).is_some_and(|(col, row)| {
                grid.is_known(col, row) || grid.cell_field(col, row) >= NEAR_WALL_FIELD
            })
        }));
        let found = self.match_usable(grid, &usable, predicted, window);
        self.usable = usable;
        found
    }

    fn match_usable(
        &mut self,
        grid: &LogOddsGrid,
        points: &[(f64, f64)],
        predicted: Pose2D,
        window: SearchWindow,
    ) -> Option<Match> {
        if points.is_empty() {
            return None;
        }
        let res = grid.resolution_m();
        let step = angular_step(grid, points);
        let prior = Prior::new(predicted, window, res, step);
        let coarse = self.correlative(grid, points, prior, window, step);
        // The refinement stays within a search step or two of the correlative pose.
        let pose = refine(grid, points, coarse, &mut self.normals)
            .filter(|refined| {
                let moved = (refined.x_m - coarse.x_m).hypot(refined.y_m - coarse.y_m);
                let turned = wrap_angle(refined.theta_rad - coarse.theta_rad).abs();
                moved <= 2.0 * res && turned <= 2.0 * step
            })
            .unwrap_or(coarse);
        Some(Match {
            pose,
            score: mean_field(grid, points, pose),
            points: points.len(),
        })
    }

    /// The best pose on a lattice of the window (headings a step apart, positions a cell apart),
    /// coarse to fine: every other heading and every other position first (the field is smooth
    /// over a cell, so the best of those is next to the best of all), then the lattice poses
    /// around the best coarse one.
    fn correlative(
        &mut self,
        grid: &LogOddsGrid,
        points: &[(f64, f64)],
        prior: Prior,
        window: SearchWindow,
        step: f64,
    ) -> Pose2D {
        let res = grid.resolution_m();
        let cells = (window.linear_m.max(0.0) / res).ceil() as i64;
        let turns = (window.angular_rad.max(0.0) / step).ceil() as i64;
        let step = if turns > 0 {
            window.angular_rad / turns as f64
        } else {
            0.0
        };
        let lattice = Lattice {
            predicted: prior.predicted,
            res,
            step,
        };
        let coarse_cells = Stride {
            first: -(cells / 2) * 2,
            count: (cells / 2) as usize * 2 + 1,
            by: 2,
        }
        .thin();
        let mut best = (f64::NEG_INFINITY, 0, 0, 0);
        for turn in (-(turns / 2)..=turns / 2).map(|t| 2 * t) {
            let found = self.best_translation(
                grid,
                points,
                prior,
                lattice,
                turn,
                coarse_cells,
                coarse_cells,
            );
            if found.0 > best.0 {
                best = found;
            }
        }
        let (_, turn0, x0, y0) = best;
        let around = |centre: i64, limit: i64| {
            let first = (centre - 1).max(-limit);
            Stride {
                first,
                count: ((centre + 1).min(limit) - first + 1) as usize,
                by: 1,
            }
        };
        for turn in (turn0 - 1).max(-turns)..=(turn0 + 1).min(turns) {
            let found = self.best_translation(
                grid,
                points,
                prior,
                lattice,
                turn,
                around(x0, cells),
                around(y0, cells),
            );
            if found.0 > best.0 {
                best = found;
            }
        }
        lattice.pose(best.1, best.2, best.3)
    }

    /// For the heading `turn` steps from the prediction, the best of the translations by the
    /// cells in `xs` and `ys`: (score, turn, x cells, y cells). The points' cells are computed
    /// once; each translation only shifts them, and the scores of all translations are
    /// accumulated point by point.
    #[allow(clippy::too_many_arguments)]
    fn best_translation(
        &mut self,
        grid: &LogOddsGrid,
        points: &[(f64, f64)],
        prior: Prior,
        lattice: Lattice,
        turn: i64,
        xs: Stride,
        ys: Stride,
    ) -> (f64, i64, i64, i64) {
        let (width, height) = (grid.width() as i64, grid.height() as i64);
        let (origin_x, origin_y) = grid.origin();
        let (res, field) = (lattice.res, grid.field());
        let predicted = lattice.predicted;
        let (sin, cos) = (predicted.theta_rad + turn as f64 * lattice.step).sin_cos();
        self.scores.clear();
        self.scores.resize(xs.count * ys.count, 0.0);
        let (x_first, x_last) = (xs.first, xs.last());
        let (y_first, y_last) = (ys.first, ys.last());
        let (x_by, row_by) = (xs.by as usize, ys.by as usize * width as usize);
        for &(px, py) in points {
            let x = predicted.x_m + cos * px - sin * py;
            let y = predicted.y_m + sin * px + cos * py;
            let col = ((x - origin_x) / res).floor() as i64;
            let row = ((y - origin_y) / res).floor() as i64;
            if col + x_first < 0
                || row + y_first < 0
                || col + x_last >= width
                || row + y_last >= height
            {
                continue;
            }
            // Plain index loops: as fast as iterators when optimised, much faster when not.
            let mut start = ((row + y_first) * width + col + x_first) as usize;
            let mut slot = 0;
            for _ in 0..ys.count {
                let mut at = start;
                for _ in 0..xs.count {
                    self.scores[slot] += field[at];
                    slot += 1;
                    at += x_by;
                }
                start += row_by;
            }
        }
        let count = points.len() as f64;
        let mut best = (f64::NEG_INFINITY, turn, 0, 0);
        for (slot, &sum) in self.scores.iter().enumerate() {
            let x_cells = xs.first + (slot % xs.count) as i64 * xs.by;
            let y_cells = ys.first + (slot / xs.count) as i64 * ys.by;
            let score =
                f64::from(sum) / count - prior.penalty(lattice.pose(turn, x_cells, y_cells));
            if score > best.0 {
                best = (score, turn, x_cells, y_cells);
            }
        }
        best
    }
}

/// The poses the correlative search considers: the prediction turned by whole steps and moved
/// by whole cells.
#[derive(Clone, Copy, Debug)]
struct Lattice {
    predicted: Pose2D,
    res: f64,
    step: f64,
}

impl Lattice {
    fn pose(&self, turn: i64, x_cells: i64, y_cells: i64) -> Pose2D {
        Pose2D {
            x_m: self.predicted.x_m + x_cells as f64 * self.res,
            y_m: self.predicted.y_m + y_cells as f64 * self.res,
            theta_rad: wrap_angle(self.predicted.theta_rad + turn as f64 * self.step),
        }
    }
}

/// `count` offsets in cells, from `first`, `by` apart.
#[derive(Clone, Copy, Debug)]
struct Stride {
    first: i64,
    count: usize,
    by: i64,
}

impl Stride {
    fn last(&self) -> i64 {
        self.first + (self.count as i64 - 1) * self.by
    }

    /// A stride of 2 over at most one offset is a stride of 1.
    fn thin(self) -> Self {
        if self.count <= 1 {
            Self { by: 1, ..self }
        } else {
            self
        }
    }
}

/// The heading step under which the farthest point moves by about one cell.
fn angular_step(grid: &LogOddsGrid, points: &[(f64, f64)]) -> f64 {
    let farthest = points
        .iter()
        .map(|&(x, y)| x.hypot(y))
        .fold(grid.resolution_m(), f64::max);
    (grid.resolution_m() / farthest).max(MIN_ANGULAR_STEP_RAD)
}

/// Where a point of the sensor's frame lands with the sensor at `pose`.
fn transform(pose: Pose2D, (sin, cos): (f64, f64), (px, py): (f64, f64)) -> (f64, f64) {
    (
        pose.x_m + cos * px - sin * py,
        pose.y_m + sin * px + cos * py,
    )
}

/// The mean interpolated likelihood field value at the points seen from `pose`.
pub fn mean_field(grid: &LogOddsGrid, points: &[(f64, f64)], pose: Pose2D) -> f64 {
    if points.is_empty() {
        return 0.0;
    }
    let sin_cos = pose.theta_rad.sin_cos();
    let sum: f64 = points
        .iter()
        .map(|&p| {
            let (x, y) = transform(pose, sin_cos, p);
            grid.field_at(x, y)
        })
        .sum();
    sum / points.len() as f64
}

/// Point-to-line ICP against the mapped echoes, by Gauss–Newton: each point pairs with the
/// mean echo of the nearest occupied cell, and its residual is its distance to the surface
/// through that echo, with a Huber weight. Points paired with a cell whose surface has no clear
/// direction (a corner, a lone echo) are left out: pulling them onto the echo itself would drag
/// the scan along sparse walls. A weak pull towards `anchor` holds the directions the scan does
/// not constrain. None when too few points pair.
fn refine(
    grid: &LogOddsGrid,
    points: &[(f64, f64)],
    anchor: Pose2D,
    normals: &mut Vec<Option<CellNormal>>,
) -> Option<Pose2D> {
    normals.clear();
    normals.resize(points.len(), None);
    let mut pose = anchor;
    for _ in 0..REFINE_ITERATIONS {
        let (mut h, mut b, pairs) = normal_equations(grid, points, pose, normals);
        if pairs < MIN_PAIRS {
            return None;
        }
        let offsets = [
            pose.x_m - anchor.x_m,
            pose.y_m - anchor.y_m,
            wrap_angle(pose.theta_rad - anchor.theta_rad),
        ];
        let weight = REFINE_PRIOR * pairs as f64;
        for (i, offset) in offsets.into_iter().enumerate() {
            h[i][i] += weight;
            b[i] -= weight * offset;
        }
        let delta = solve3(h, b)?;
        pose = Pose2D {
            x_m: pose.x_m + delta[0],
            y_m: pose.y_m + delta[1],
            theta_rad: wrap_angle(pose.theta_rad + delta[2]),
        };
        if delta[0].hypot(delta[1]) < 1e-4 && delta[2].abs() < 1e-5 {
            break;
        }
    }
    Some(pose)
}

/// How well the scan's points seen from `pose` pin each direction of the pose down: the
/// Gauss–Newton matrix of [`refine`]'s point-to-line residuals there (in the map frame, for x,
/// y and heading), divided by the number of points that paired, and that number. A corridor's
/// straight walls give it nothing along the corridor: there the scan says nothing of where the
/// robot is, and loop closure must not take it as saying so. None when too few points pair.
pub fn information_per_point(
    grid: &LogOddsGrid,
    points: &[(f64, f64)],
    pose: Pose2D,
) -> Option<([[f64; 3]; 3], usize)> {
    let mut normals = vec![None; points.len()];
    let (mut h, _, pairs) = normal_equations(grid, points, pose, &mut normals);
    if pairs < MIN_PAIRS {
        return None;
    }
    for row in &mut h {
        for value in row {
            *value /= pairs as f64;
        }
    }
    Some((h, pairs))
}

/// The Gauss–Newton matrix and vector of the point-to-line residuals at `pose`, and how many
/// points paired; `normals` keeps each point's last cell and its normal between calls.
fn normal_equations(
    grid: &LogOddsGrid,
    points: &[(f64, f64)],
    pose: Pose2D,
    normals: &mut [Option<CellNormal>],
) -> ([[f64; 3]; 3], [f64; 3], usize) {
    let res = grid.resolution_m();
    let (pairing, huber) = (PAIRING_CELLS * res, HUBER_CELLS * res);
    let (sin, cos) = pose.theta_rad.sin_cos();
    let mut h = [[0.0_f64; 3]; 3];
    let mut b = [0.0_f64; 3];
    let mut pairs = 0;
    for (&p, known) in points.iter().zip(normals.iter_mut()) {
        let (x, y) = transform(pose, (sin, cos), p);
        let Some((cell, (ex, ey))) = grid.nearest_echo(x, y) else {
            continue;
        };
        let (dx, dy) = (x - ex, y - ey);
        if dx.hypot(dy) > pairing {
            continue;
        }
        let normal = match *known {
            Some((known_cell, normal)) if known_cell == cell => normal,
            _ => {
                let normal = grid.normal(cell);
                *known = Some((cell, normal));
                normal
            }
        };
        let Some((nx, ny)) = normal else {
            continue;
        };
        pairs += 1;
        let (px, py) = p;
        // How the point moves as the heading turns.
        let (tx, ty) = (-sin * px - cos * py, cos * px - sin * py);
        let j = [nx, ny, nx * tx + ny * ty];
        let residual = nx * dx + ny * dy;
        let weight = if residual.abs() <= huber {
            1.0
        } else {
            huber / residual.abs()
        };
        for r in 0..3 {
            b[r] -= weight * j[r] * residual;
            for c in 0..3 {
                h[r][c] += weight * j[r] * j[c];
            }
        }
    }
    (h, b, pairs)
}

/// Solves `a · x = b` for a 3 × 3 system by Cramer's rule; None if it is singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !(d.is_finite() && d.abs() > 1e-18) {
        return None;
    }
    let mut x = [0.0; 3];
    for (i, xi) in x.iter_mut().enumerate() {
        let mut m = a;
        for (row, &bi) in m.iter_mut().zip(&b) {
            row[i] = bi;
        }
        *xi = det(m) / d;
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 10 m × 8 m room with an L-shaped inner wall, integrated from a few known poses with a
    /// synthetic scan, and the scan's points from `pose` (360 beams, ranges by ray casting).
    fn room() -> crate::sim::world::World {
        crate::sim::world::World::parse(
            "name room\norigin 0 0\nstart 5 4 0\nboundary 0,0 10,0 10,8 0,8 0,0\n\
             wall 3,2 3,5 6,5\nrect 7,1 8,2\n",
            "room.world",
        )
        .expect("valid")
    }

    fn synthetic_scan(world: &crate::sim::world::World, pose: Pose2D) -> Vec<(f64, f64, bool)> {
        let origin = crate::sim::world::Point::new(pose.x_m, pose.y_m);
        (0..360)
            .map(|i| {
                let angle = -std::f64::consts::PI + f64::from(i).to_radians();
                let range = world.raycast(origin, pose.theta_rad + angle, 8.0);
                (angle, range.min(7.5), range < 7.5)
            })
            .collect()
    }

    fn points(beams: &[(f64, f64, bool)]) -> Vec<(f64, f64)> {
        beams
            .iter()
            .filter(|beam| beam.2)
            .map(|&(a, r, _)| (r * a.cos(), r * a.sin()))
            .collect()
    }

    fn pose(x_m: f64, y_m: f64, theta_rad: f64) -> Pose2D {
        Pose2D {
            x_m,
            y_m,
            theta_rad,
        }
    }

    fn mapped_room() -> (crate::sim::world::World, LogOddsGrid) {
        let world = room();
        let mut grid = LogOddsGrid::centred(0.1, 20.0, 5.0, 4.0).expect("grid");
        for at in [
            pose(5.0, 4.0, 0.0),
            pose(2.0, 6.5, 1.0),
            pose(8.5, 6.0, -2.0),
        ] {
            for _ in 0..3 {
                grid.integrate(at, synthetic_scan(&world, at).into_iter());
            }
        }
        (world, grid)
    }

    #[test]
    fn recovers_a_known_offset_of_a_synthetic_scan() {
        let (world, grid) = mapped_room();
        let mut matcher = Matcher::default();
        let window = SearchWindow {
            linear_m: 0.3,
            angular_rad: 10f64.to_radians(),
        };
        for (truth, offset) in [
            (pose(4.3, 3.1, 0.3), (0.2, -0.15, 0.1)),
            (pose(6.2, 6.0, -1.2), (-0.25, 0.22, -0.15)),
            (pose(1.5, 1.2, 2.5), (0.07, 0.28, 0.05)),
        ] {
            let scan = points(&synthetic_scan(&world, truth));
            // The prediction is off by the offset; the match must come back to the truth.
            let predicted = pose(
                truth.x_m + offset.0,
                truth.y_m + offset.1,
                truth.theta_rad + offset.2,
            );
            let found = matcher
                .match_scan(&grid, &scan, predicted, window)
                .expect("points");
            let error = (found.pose.x_m - truth.x_m).hypot(found.pose.y_m - truth.y_m);
            let turn = wrap_angle(found.pose.theta_rad - truth.theta_rad).abs();
            assert!(
                error < 0.03 && turn < 0.01,
                "{truth:?} found at {:?}: {error} m, {turn} rad",
                found.pose
            );
            assert!(found.score > 0.7, "{}", found.score);
            let before = mean_field(&grid, &scan, predicted);
            assert!(found.score > before + 0.3, "{before} → {}", found.score);
        }
    }

    #[test]
    fn a_zero_window_refines_only_and_no_points_is_no_match() {
        let (world, grid) = mapped_room();
        let mut matcher = Matcher::default();
        let truth = pose(5.0, 3.0, 0.4);
        let scan = points(&synthetic_scan(&world, truth));
        let predicted = pose(5.04, 2.97, 0.41);
        let none = SearchWindow {
            linear_m: 0.0,
            angular_rad: 0.0,
        };
        let found = matcher
            .match_scan(&grid, &scan, predicted, none)
            .expect("points");
        let error = (found.pose.x_m - truth.x_m).hypot(found.pose.y_m - truth.y_m);
        assert!(error < 0.03, "{:?}", found.pose);
        assert_eq!(matcher.match_scan(&grid, &[], predicted, none), None);
    }

    #[test]
    fn solves_small_linear_systems() {
        let x = solve3(
            [[2.0, 0.0, 1.0], [0.0, 3.0, 0.0], [1.0, 0.0, 2.0]],
            [3.0, 6.0, 3.0],
        )
        .expect("regular");
        for (got, want) in x.iter().zip([1.0, 2.0, 1.0]) {
            assert!((got - want).abs() < 1e-12, "{x:?}");
        }
        assert_eq!(
            solve3(
                [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]],
                [1.0; 3]
            ),
            None
        );
    }
}
