//! Loop closure: keyframes, each kept with its scan, matched against earlier ones to find where
//! the robot truly is when it comes back to a place it has mapped, and a [`PoseGraph`] that
//! spreads the correction over the way there.
//!
//! A keyframe is made every `keyframe_m` metres or `keyframe_deg` degrees of the corrected
//! pose, a node of the graph joined to the previous keyframe by two edges: the motion the scan
//! matcher found between them, trusted in the directions its scan's walls pin down, and the
//! odometry's, trusted as wheel odometry is. Along a corridor, whose walls say nothing of where
//! along it the robot is, the odometry's is then what counts: the scan matcher can slip there,
//! and the graph puts a loop's correction there rather than spreading it evenly.
//!
//! Each new keyframe then looks for earlier ones it could have seen the same walls as: made at
//! least [`LOOP_MIN_PATH_M`] of path before it (closer ones are what the scan matcher already
//! matches against), and near it within the uncertainty of their relative position, which
//! grows with the length of the shortest way between them through the graph
//! ([`LOOP_DRIFT_PER_M`] of it, as the mapper drifts). The nearest such keyframe and its
//! neighbours along the old path are drawn into a small grid of their own, and the new scan is
//! matched there with the mapper's [`Matcher`], searching as far as that uncertainty. A match
//! that scores well on enough of the scan becomes an edge of the graph, trusted in the
//! directions its walls pin down, and the graph is optimised when that edge disagrees with it;
//! the mapper then draws its grid again from the keyframes at their corrected poses.
//!
//! Every keyframe is kept (about 12 kB each, one a metre) and every optimisation and redrawing
//! takes them all: fine for a building, not for a city.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use armor_module_api::types::Pose2D;

use super::between;
use super::graph::{Edge, PoseGraph, diagonal};
use super::grid::LogOddsGrid;
use super::matcher::{self, Matcher, SearchWindow};

/// Earlier keyframes are looked at only this far back along the path: nearer ones are part of
/// the map the scan matcher already uses.
pub const LOOP_MIN_PATH_M: f64 = 10.0;
/// The uncertainty of the position of two keyframes relative to each other: this much ...
pub const LOOP_BASE_M: f64 = 0.1;
/// ... plus this much per metre of the shortest way between them through the graph (the
/// mapper's drift without loop closure is about 1 % of the way with the simulator's default
/// noise; twice that leaves a margin) ...
pub const LOOP_DRIFT_PER_M: f64 = 0.02;
/// ... at most this much (the scan matcher's own limit, and the cost of a search grows with
/// its square).
pub const LOOP_MAX_SEARCH_M: f64 = 2.0;
/// The same for headings: this much, plus this much per metre, at most this much.
pub const LOOP_BASE_RAD: f64 = 0.05;
pub const LOOP_DRIFT_RAD_PER_M: f64 = 0.003;
pub const LOOP_MAX_SEARCH_RAD: f64 = 0.35;
/// A keyframe this much farther than the uncertainty still saw much of what the new one sees.
pub const LOOP_OVERLAP_M: f64 = 2.0;
/// The old path drawn for a match: this many keyframes each side of the nearest one.
const SUBMAP_KEYFRAMES: usize = 10;
/// A loop match must score at least this (the mean likelihood field at its points; the scan
/// matcher's own threshold is 0.1, but a false loop closure bends the whole map) ...
pub const LOOP_MIN_SCORE: f64 = 0.6;
/// ... on at least this share of the scan's points (those that fall where the old keyframes
/// saw; the others are what the robot sees of the place that it did not see then). A match
/// along a corridor, where the walls say nothing of where along it the robot is, is taken for
/// what it says across it only (see the edges' information).
pub const LOOP_MIN_SHARE: f64 = 0.3;
/// A loop edge that the graph already agrees with to within this does not start an
/// optimisation (metres, radians).
const AGREES_M: f64 = 0.03;
const AGREES_RAD: f64 = 0.01;
/// How far off a point of a scan is trusted to be from the wall it pairs with, for the motion
/// from one keyframe to the next (the scan matcher's, over a dozen scans) and for a loop match.
/// A direction is pinned down by as many points as face it, and one that no wall faces (along a
/// corridor) not at all (see [`matcher::information_per_point`]).
const STEP_POINT_SIGMA_M: f64 = 0.05;
const LOOP_POINT_SIGMA_M: f64 = 0.05;
/// Where the scan says nothing, the scan matcher's motion from one keyframe to the next is
/// trusted to this much only: it is then only the odometry's prediction, or worse, a slip
/// along a corridor.
const STEP_PRIOR_SIGMA_M: f64 = 1.0;
const STEP_PRIOR_SIGMA_RAD: f64 = 0.5;
/// The odometry's motion from one keyframe to the next is trusted to within this much, plus
/// this much per metre travelled and per radian turned: an ordinary wheel odometry (the
/// simulator's default noise is 2 % of the way), which in a corridor says where along it the
/// robot went better than the walls do.
const ODOMETRY_SIGMA_M: f64 = 0.02;
const ODOMETRY_SIGMA_PER_M: f64 = 0.05;
const ODOMETRY_SIGMA_RAD: f64 = 0.01;
const ODOMETRY_SIGMA_RAD_PER_M: f64 = 0.02;
const ODOMETRY_SIGMA_RAD_PER_RAD: f64 = 0.05;
/// A loop match is trusted to within this where its scan says nothing: it then only repeats
/// the prediction it started from.
const LOOP_PRIOR_SIGMA_M: f64 = 2.0;
const LOOP_PRIOR_SIGMA_RAD: f64 = 0.5;

/// A scan kept with its node of the graph.
#[derive(Clone, Debug)]
pub struct Keyframe {
    /// Beams as the grid integrates them: (angle, length, ends on an echo).
    pub beams: Vec<(f64, f64, bool)>,
    /// The echoes' points, as the matcher takes them.
    points: Vec<(f64, f64)>,
    /// The path length travelled when it was made.
    travelled_m: f64,
    /// The odometry's pose then (None when the odometry restarted since the keyframe before,
    /// in another frame).
    odometry: Option<Pose2D>,
}

/// When and how to make keyframes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeyframeSpacing {
    pub linear_m: f64,
    pub angular_rad: f64,
}

/// What the graph's optimisation changed, for the mapper to redraw its grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closed {
    /// The corrected pose of the scan that closed the loop.
    pub pose: Pose2D,
    /// The most any keyframe moved, in metres.
    pub largest_move_m: f64,
}

/// Keyframes, the graph of their poses, and the search for loops.
#[derive(Clone, Debug, Default)]
pub struct LoopCloser {
    graph: PoseGraph,
    keyframes: Vec<Keyframe>,
    matcher: Matcher,
    travelled_m: f64,
    last_pose: Option<Pose2D>,
    /// Loop edges added, and optimisations run.
    closures: u64,
    optimisations: u64,
    /// The shortest way through the graph from the newest keyframe to the first (the map
    /// frame's origin, where the pose is known exactly): what its error grew over.
    origin_way_m: f64,
}

impl LoopCloser {
    pub fn keyframes(&self) -> impl Iterator<Item = (Pose2D, &Keyframe)> {
        self.graph.poses().iter().copied().zip(&self.keyframes)
    }

    pub fn graph(&self) -> &PoseGraph {
        &self.graph
    }

    /// The odometry restarted: the next keyframe is joined to the one before by the scan
    /// matcher alone.
    pub fn forget_odometry(&mut self) {
        if let Some(last) = self.keyframes.last_mut() {
            last.odometry = None;
        }
    }

    /// The way the pose's error grew over: the shortest way through the graph from the first
    /// keyframe to the newest (a loop edge costs nothing: a place seen again is as sure as it
    /// was then), and the way travelled since the newest. Before any keyframe, the way
    /// travelled.
    pub fn way_from_origin_m(&self) -> f64 {
        match self.keyframes.last() {
            Some(newest) => self.origin_way_m + (self.travelled_m - newest.travelled_m),
            None => self.travelled_m,
        }
    }

    /// Loop edges added so far, and the optimisations they caused.
    pub fn closures(&self) -> (u64, u64) {
        (self.closures, self.optimisations)
    }

    /// Takes the corrected pose of a scan just integrated, with its beams and points. Makes a
    /// keyframe of it when it is far enough from the last one and looks for a loop from there;
    /// returns the new poses when the graph was optimised.
    #[allow(clippy::too_many_arguments)]
    pub fn on_scan(
        &mut self,
        grid: &LogOddsGrid,
        pose: Pose2D,
        odometry: Pose2D,
        beams: &[(f64, f64, bool)],
        points: &[(f64, f64)],
        spacing: KeyframeSpacing,
        resolution_m: f64,
    ) -> Option<Closed> {
        if let Some(last) = self.last_pose {
            self.travelled_m += (pose.x_m - last.x_m).hypot(pose.y_m - last.y_m);
        }
        self.last_pose = Some(pose);
        let previous = self.graph.poses().last().copied();
        if let Some(previous) = previous {
            let step = between(previous, pose);
            if step.x_m.hypot(step.y_m) < spacing.linear_m
                && step.theta_rad.abs() < spacing.angular_rad
            {
                return None;
            }
        }
        // What the scan says of the keyframe's pose, on the map it was just matched against.
        let seen = matcher::information_per_point(grid, points, pose);
        let node = self.graph.add_node(pose);
        self.keyframes.push(Keyframe {
            beams: beams.to_vec(),
            points: points.to_vec(),
            travelled_m: self.travelled_m,
            odometry: Some(odometry),
        });
        if let Some(previous) = previous {
            let measured = between(previous, pose);
            let scan_information = information(
                seen,
                pose,
                STEP_POINT_SIGMA_M,
                STEP_PRIOR_SIGMA_M,
                STEP_PRIOR_SIGMA_RAD,
            );
            // The nodes exist and the information is positive definite: these cannot be
            // refused.
            let _ = self.graph.add_edge(Edge {
                from: node - 1,
                to: node,
                measured,
                information: scan_information,
            });
            if let Some(before) = self.keyframes[node - 1].odometry {
                let moved = between(before, odometry);
                let length = moved.x_m.hypot(moved.y_m);
                let sigma_m = ODOMETRY_SIGMA_M + ODOMETRY_SIGMA_PER_M * length;
                let sigma_rad = ODOMETRY_SIGMA_RAD
                    + ODOMETRY_SIGMA_RAD_PER_M * length
                    + ODOMETRY_SIGMA_RAD_PER_RAD * moved.theta_rad.abs();
                let _ = self.graph.add_edge(Edge {
                    from: node - 1,
                    to: node,
                    measured: moved,
                    information: information(None, pose, 1.0, sigma_m, sigma_rad),
                });
            }
        }
        let closed = self.close_loop(node, resolution_m);
        self.origin_way_m = self.shortest_ways(node)[0];
        closed
    }

    /// Looks for a loop from the keyframe `node` (the newest), and optimises the graph when one
    /// is found that it does not agree with yet.
    fn close_loop(&mut self, node: usize, resolution_m: f64) -> Option<Closed> {
        let now = self.graph.poses()[node];
        let travelled_m = self.travelled_m;
        let old: Vec<usize> = (0..node)
            .filter(|&k| travelled_m - self.keyframes[k].travelled_m >= LOOP_MIN_PATH_M)
            .collect();
        if old.is_empty() {
            return None;
        }
        let way_m = self.shortest_ways(node);
        let (candidate, search_m) = old
            .iter()
            .filter_map(|&k| {
                let pose = self.graph.poses()[k];
                let apart = (pose.x_m - now.x_m).hypot(pose.y_m - now.y_m);
                let uncertainty =
                    (LOOP_BASE_M + LOOP_DRIFT_PER_M * way_m[k]).min(LOOP_MAX_SEARCH_M);
                (apart <= uncertainty + LOOP_OVERLAP_M).then_some((k, apart, way_m[k]))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(k, _, way)| (k, way))?;
        let window = SearchWindow {
            linear_m: (LOOP_BASE_M + LOOP_DRIFT_PER_M * search_m).min(LOOP_MAX_SEARCH_M),
            angular_rad: (LOOP_BASE_RAD + LOOP_DRIFT_RAD_PER_M * search_m).min(LOOP_MAX_SEARCH_RAD),
        };
        let submap = self.submap(candidate, travelled_m, window, resolution_m)?;
        let points = &self.keyframes[node].points;
        let found = self.matcher.match_scan(&submap, points, now, window)?;
        // Which points fall on what the old keyframes saw depends on where the scan is put:
        // seen from the prediction, which may be metres off, too few may. Matched again from
        // where the search put it, without searching, the score and the share are those of
        // the pose found.
        let settled = SearchWindow {
            linear_m: 0.0,
            angular_rad: 0.0,
        };
        let found = self
            .matcher
            .match_scan(&submap, points, found.pose, settled)?;
        let enough = found.points as f64 >= LOOP_MIN_SHARE * points.len() as f64;
        if !(found.score >= LOOP_MIN_SCORE && enough) {
            tracing::debug!(
                "no loop from keyframe {node} to {candidate}: score {:.2} on {} of {} points",
                found.score,
                found.points,
                points.len()
            );
            return None;
        }
        let seen = matcher::information_per_point(&submap, points, found.pose);
        let edge = Edge {
            from: candidate,
            to: node,
            measured: between(self.graph.poses()[candidate], found.pose),
            information: information(
                seen,
                found.pose,
                LOOP_POINT_SIGMA_M,
                LOOP_PRIOR_SIGMA_M,
                LOOP_PRIOR_SIGMA_RAD,
            ),
        };
        let (off_m, off_rad) = self.graph.edge_error(&edge);
        // The nodes exist and differ, and the information is positive: this cannot be refused.
        let _ = self.graph.add_edge(edge);
        self.closures += 1;
        if off_m < AGREES_M && off_rad < AGREES_RAD {
            return None;
        }
        let optimised = self.graph.optimise()?;
        self.optimisations += 1;
        tracing::info!(
            "loop closed from keyframe {node} to {candidate} ({off_m:.2} m and {:.1}° off, \
             score {:.2}); keyframes moved by up to {:.2} m",
            off_rad.to_degrees(),
            found.score,
            optimised.largest_move_m
        );
        Some(Closed {
            pose: self.graph.poses()[node],
            largest_move_m: optimised.largest_move_m,
        })
    }

    /// The length of the shortest way from `node` to every keyframe through the graph: the
    /// motions between consecutive keyframes count their length, loop edges nothing.
    fn shortest_ways(&self, node: usize) -> Vec<f64> {
        let nodes = self.graph.poses().len();
        let mut neighbours: Vec<Vec<(usize, f64)>> = vec![Vec::new(); nodes];
        for edge in self.graph.edges() {
            let length = if edge.to == edge.from + 1 {
                edge.measured.x_m.hypot(edge.measured.y_m)
            } else {
                0.0
            };
            neighbours[edge.from].push((edge.to, length));
            neighbours[edge.to].push((edge.from, length));
        }
        let mut way = vec![f64::INFINITY; nodes];
        let mut queue = BinaryHeap::new();
        way[node] = 0.0;
        queue.push(Visit(0.0, node));
        while let Some(Visit(length, at)) = queue.pop() {
            if length > way[at] {
                continue;
            }
            for &(next, step) in &neighbours[at] {
                if length + step < way[next] {
                    way[next] = length + step;
                    queue.push(Visit(length + step, next));
                }
            }
        }
        way
    }

    /// A grid of the old path round keyframe `centre`: the keyframes near it in the order they
    /// were made, and at least [`LOOP_MIN_PATH_M`] back from now, drawn at their poses.
    fn submap(
        &self,
        centre: usize,
        travelled_m: f64,
        window: SearchWindow,
        resolution_m: f64,
    ) -> Option<LogOddsGrid> {
        let first = centre.saturating_sub(SUBMAP_KEYFRAMES);
        let last = (centre + SUBMAP_KEYFRAMES).min(self.keyframes.len() - 1);
        let reach_m = self.keyframes[centre]
            .beams
            .iter()
            .map(|beam| beam.1)
            .fold(0.0, f64::max);
        let at = self.graph.poses()[centre];
        let side_m = 2.0 * (reach_m + window.linear_m + LOOP_OVERLAP_M);
        let mut grid = LogOddsGrid::centred(resolution_m, side_m, at.x_m, at.y_m).ok()?;
        for k in first..=last {
            if travelled_m - self.keyframes[k].travelled_m < LOOP_MIN_PATH_M {
                continue;
            }
            let beams = self.keyframes[k].beams.iter().copied();
            grid.integrate(self.graph.poses()[k], beams);
        }
        Some(grid)
    }
}

/// The information of an edge ending at `pose`: what its scan `seen` says (the matcher's
/// information per point in the map frame and the number of points, each point trusted to
/// `point_sigma_m`), turned into the frame of the edge's error (`pose`'s own), plus a floor of
/// `sigma_m` and `sigma_rad` each way.
// Matrix products read best with indices.
#[allow(clippy::needless_range_loop)]
fn information(
    seen: Option<([[f64; 3]; 3], usize)>,
    pose: Pose2D,
    point_sigma_m: f64,
    sigma_m: f64,
    sigma_rad: f64,
) -> [[f64; 3]; 3] {
    let linear = 1.0 / (sigma_m * sigma_m);
    let mut total = diagonal([linear, linear, 1.0 / (sigma_rad * sigma_rad)]);
    if let Some((per_point, pairs)) = seen {
        // The error's x and y are the map frame's turned by the pose's heading: T = diag(R, 1),
        // and the information in the error's frame is Tᵀ · H · T.
        let (sin, cos) = pose.theta_rad.sin_cos();
        let t = [[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]];
        let scale = pairs as f64 / (point_sigma_m * point_sigma_m);
        for r in 0..3 {
            for c in 0..3 {
                let mut sum = 0.0;
                for i in 0..3 {
                    for j in 0..3 {
                        sum += t[i][r] * per_point[i][j] * t[j][c];
                    }
                }
                total[r][c] += scale * sum;
            }
        }
        // Rounding must not make it asymmetric.
        for r in 0..3 {
            for c in 0..r {
                let mean = (total[r][c] + total[c][r]) / 2.0;
                total[r][c] = mean;
                total[c][r] = mean;
            }
        }
    }
    total
}

/// A node to visit at a length of way, shortest first.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Visit(f64, usize);

impl Eq for Visit {}

impl Ord for Visit {
    fn cmp(&self, other: &Self) -> Ordering {
        other.0.total_cmp(&self.0).then(self.1.cmp(&other.1))
    }
}

impl PartialOrd for Visit {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
