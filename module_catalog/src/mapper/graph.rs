//! The mapper's pose graph: one node per keyframe (its pose in the map frame), one edge per
//! measured motion between two keyframes (the scan matcher's, from one keyframe to the next,
//! and the loop closures'), and a Gauss–Newton optimisation that moves the nodes to agree best
//! with every edge at once.
//!
//! The normal equations are solved by a Cholesky factorisation in skyline (profile) storage:
//! each row keeps the entries from its first non-zero column to the diagonal, and the factor
//! fills in nowhere else. Keyframes are numbered in the order they were made, so the edges from
//! one to the next keep the profile a narrow band, and each loop closure widens only the rows of
//! the keyframe that closed it. This is why no sparse-matrix crate is used: a 2-D pose graph
//! in this order needs nothing more, in about a hundred lines.

use armor_module_api::types::Pose2D;

use super::between;
use crate::nav::wrap_angle;

/// How strongly the first node is held where it is: the graph's frame is the first keyframe's.
const ANCHOR_INFORMATION: f64 = 1e9;
/// The optimisation stops when no node moves more than this (metres, and radians)...
const CONVERGED: f64 = 1e-6;
/// ... or after this many steps.
const MAX_ITERATIONS: usize = 20;

/// A measured motion from keyframe `from` to keyframe `to`, in `from`'s frame, and how much it
/// is trusted: the inverse of the covariance of its error (x and y in `to`'s frame, and
/// heading), symmetric and positive definite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Edge {
    pub from: usize,
    pub to: usize,
    pub measured: Pose2D,
    pub information: [[f64; 3]; 3],
}

impl Edge {
    /// The edge's error at the given poses: how far `to` is from where the measurement puts it,
    /// in the measurement's frame.
    fn error(&self, from: Pose2D, to: Pose2D) -> [f64; 3] {
        let relative = between(from, to);
        let error = between(self.measured, relative);
        [error.x_m, error.y_m, error.theta_rad]
    }
}

/// What an optimisation did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Optimised {
    pub iterations: usize,
    /// The weighted squared error of all the edges, before and after.
    pub error_before: f64,
    pub error_after: f64,
    /// The most any node moved, in metres.
    pub largest_move_m: f64,
}

/// Keyframe poses and the edges between them.
#[derive(Clone, Debug, Default)]
pub struct PoseGraph {
    poses: Vec<Pose2D>,
    edges: Vec<Edge>,
}

impl PoseGraph {
    pub fn poses(&self) -> &[Pose2D] {
        &self.poses
    }

    pub fn edges(&self) -> &[Edge] {
        &self.edges
    }

    /// Adds a node at `pose` and returns its number.
    pub fn add_node(&mut self, pose: Pose2D) -> usize {
        self.poses.push(pose);
        self.poses.len() - 1
    }

    /// Adds an edge between two nodes already in the graph (refused otherwise, or when it joins
    /// a node to itself or its information is not symmetric and positive definite).
    pub fn add_edge(&mut self, edge: Edge) -> Result<(), String> {
        let nodes = self.poses.len();
        if edge.from >= nodes || edge.to >= nodes || edge.from == edge.to {
            return Err(format!(
                "an edge from node {} to node {} in a graph of {nodes}",
                edge.from, edge.to
            ));
        }
        if !positive_definite(edge.information) {
            return Err(format!(
                "an edge's information must be symmetric and positive definite: {:?}",
                edge.information
            ));
        }
        self.edges.push(edge);
        Ok(())
    }

    /// The weighted squared error of all the edges at the current poses.
    pub fn error(&self) -> f64 {
        self.edges
            .iter()
            .map(|edge| {
                let e = edge.error(self.poses[edge.from], self.poses[edge.to]);
                weighted(edge.information, e, e)
            })
            .sum()
    }

    /// The error of one edge at the current poses: (metres, radians).
    pub fn edge_error(&self, edge: &Edge) -> (f64, f64) {
        let e = edge.error(self.poses[edge.from], self.poses[edge.to]);
        (e[0].hypot(e[1]), e[2].abs())
    }

    /// Moves the nodes to minimise the weighted squared error of the edges (Gauss–Newton), the
    /// first node held where it is. None when the equations are singular (a node without any
    /// edge), in which case the poses are left as they were.
    pub fn optimise(&mut self) -> Option<Optimised> {
        let error_before = self.error();
        let start = self.poses.clone();
        let mut iterations = 0;
        while iterations < MAX_ITERATIONS {
            iterations += 1;
            let Some(step) = self.step() else {
                self.poses = start;
                return None;
            };
            let mut largest = 0.0_f64;
            for (pose, delta) in self.poses.iter_mut().zip(step.chunks_exact(3)) {
                pose.x_m += delta[0];
                pose.y_m += delta[1];
                pose.theta_rad = wrap_angle(pose.theta_rad + delta[2]);
                largest = largest.max(delta[0].hypot(delta[1])).max(delta[2].abs());
            }
            if largest < CONVERGED {
                break;
            }
        }
        let largest_move_m = self
            .poses
            .iter()
            .zip(&start)
            .map(|(a, b)| (a.x_m - b.x_m).hypot(a.y_m - b.y_m))
            .fold(0.0, f64::max);
        Some(Optimised {
            iterations,
            error_before,
            error_after: self.error(),
            largest_move_m,
        })
    }

    /// One Gauss–Newton step: the change of every node's (x, y, heading).
    fn step(&self) -> Option<Vec<f64>> {
        let size = 3 * self.poses.len();
        if size == 0 {
            return Some(Vec::new());
        }
        // Each row's first non-zero column: its own node's first, or the earliest node an edge
        // joins it to.
        let mut first: Vec<usize> = (0..size).map(|i| i - i % 3).collect();
        for edge in &self.edges {
            let (low, high) = (edge.from.min(edge.to), edge.from.max(edge.to));
            for row_first in &mut first[3 * high..3 * high + 3] {
                *row_first = (*row_first).min(3 * low);
            }
        }
        let mut h = Skyline::new(first);
        let mut b = vec![0.0; size];
        for edge in &self.edges {
            let (a, c) = (self.poses[edge.from], self.poses[edge.to]);
            let e = edge.error(a, c);
            let (jacobian_from, jacobian_to) = jacobians(edge.measured, a, c);
            let blocks = [(edge.from, jacobian_from), (edge.to, jacobian_to)];
            let column = |j: [[f64; 3]; 3], c: usize| [j[0][c], j[1][c], j[2][c]];
            for &(node_r, jr) in &blocks {
                for r in 0..3 {
                    let row = 3 * node_r + r;
                    b[row] += weighted(edge.information, column(jr, r), e);
                    for &(node_c, jc) in &blocks {
                        for c in 0..3 {
                            let col = 3 * node_c + c;
                            if col <= row {
                                let value =
                                    weighted(edge.information, column(jr, r), column(jc, c));
                                h.add(row, col, value);
                            }
                        }
                    }
                }
            }
        }
        for k in 0..3 {
            h.add(k, k, ANCHOR_INFORMATION);
        }
        let mut step = h.solve(&b)?;
        for value in &mut step {
            *value = -*value;
        }
        // The anchor leaves the first node a step of the order of 1e-20: none at all keeps it
        // exactly where it was.
        step[..3].fill(0.0);
        Some(step)
    }
}

/// `uᵀ · m · v`.
fn weighted(m: [[f64; 3]; 3], u: [f64; 3], v: [f64; 3]) -> f64 {
    (0..3)
        .map(|r| (0..3).map(|c| u[r] * m[r][c] * v[c]).sum::<f64>())
        .sum()
}

/// Whether a 3 × 3 matrix is finite, symmetric and positive definite (its leading minors
/// positive).
pub fn positive_definite(m: [[f64; 3]; 3]) -> bool {
    let finite = m.iter().flatten().all(|v| v.is_finite());
    let symmetric = (0..3).all(|r| (0..3).all(|c| m[r][c] == m[c][r]));
    let minor2 = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    finite && symmetric && m[0][0] > 0.0 && minor2 > 0.0 && det > 0.0
}

/// A diagonal information matrix.
pub fn diagonal(values: [f64; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (k, value) in values.into_iter().enumerate() {
        m[k][k] = value;
    }
    m
}

/// The Jacobians of an edge's error with respect to the (x, y, heading) of its two nodes, rows
/// by error component.
fn jacobians(measured: Pose2D, a: Pose2D, b: Pose2D) -> ([[f64; 3]; 3], [[f64; 3]; 3]) {
    let (sin_a, cos_a) = a.theta_rad.sin_cos();
    let (sin_z, cos_z) = measured.theta_rad.sin_cos();
    let (dx, dy) = (b.x_m - a.x_m, b.y_m - a.y_m);
    // Rᵀ(z)·Rᵀ(a) is the rotation by -(θz + θa).
    let (sin_za, cos_za) = (-(measured.theta_rad + a.theta_rad)).sin_cos();
    let rotation = [[cos_za, -sin_za], [sin_za, cos_za]];
    // d(Rᵀ(a)·d)/dθa, then turned by Rᵀ(z).
    let (ux, uy) = (-sin_a * dx + cos_a * dy, -cos_a * dx - sin_a * dy);
    let (vx, vy) = (cos_z * ux + sin_z * uy, -sin_z * ux + cos_z * uy);
    let from = [
        [-rotation[0][0], -rotation[0][1], vx],
        [-rotation[1][0], -rotation[1][1], vy],
        [0.0, 0.0, -1.0],
    ];
    let to = [
        [rotation[0][0], rotation[0][1], 0.0],
        [rotation[1][0], rotation[1][1], 0.0],
        [0.0, 0.0, 1.0],
    ];
    (from, to)
}

/// A symmetric matrix kept as its lower triangle, each row from its first non-zero column.
struct Skyline {
    first: Vec<usize>,
    rows: Vec<Vec<f64>>,
}

impl Skyline {
    fn new(first: Vec<usize>) -> Self {
        let rows = first
            .iter()
            .enumerate()
            .map(|(i, &f)| vec![0.0; i - f + 1])
            .collect();
        Self { first, rows }
    }

    /// Adds to the entry at (`row`, `col`), `col` ≤ `row` and within the row's profile.
    fn add(&mut self, row: usize, col: usize, value: f64) {
        self.rows[row][col - self.first[row]] += value;
    }

    /// Solves `self · x = b` by Cholesky factorisation in place; None if the matrix is not
    /// positive definite.
    fn solve(mut self, b: &[f64]) -> Option<Vec<f64>> {
        let n = self.rows.len();
        for i in 0..n {
            let fi = self.first[i];
            for j in fi..=i {
                let fj = self.first[j];
                let start = fi.max(fj);
                let mut sum = self.rows[i][j - fi];
                for k in start..j {
                    sum -= self.rows[i][k - fi] * self.rows[j][k - fj];
                }
                if j < i {
                    sum /= self.rows[j][j - fj];
                } else {
                    if !(sum.is_finite() && sum > 0.0) {
                        return None;
                    }
                    sum = sum.sqrt();
                }
                self.rows[i][j - fi] = sum;
            }
        }
        // L·y = b, then Lᵀ·x = y.
        let mut x = b.to_vec();
        for i in 0..n {
            let fi = self.first[i];
            let row = &self.rows[i];
            let known: f64 = row[..i - fi]
                .iter()
                .zip(&x[fi..i])
                .map(|(l, x)| l * x)
                .sum();
            x[i] = (x[i] - known) / row[i - fi];
        }
        for i in (0..n).rev() {
            let fi = self.first[i];
            let row = &self.rows[i];
            x[i] /= row[i - fi];
            let xi = x[i];
            for (xk, l) in x[fi..i].iter_mut().zip(&row[..i - fi]) {
                *xk -= l * xi;
            }
        }
        x.iter().all(|v| v.is_finite()).then_some(x)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapper::compose;

    fn pose(x_m: f64, y_m: f64, theta_rad: f64) -> Pose2D {
        Pose2D {
            x_m,
            y_m,
            theta_rad,
        }
    }

    fn edge(from: usize, to: usize, measured: Pose2D, information: [f64; 3]) -> Edge {
        Edge {
            from,
            to,
            measured,
            information: diagonal(information),
        }
    }

    #[test]
    fn the_jacobians_agree_with_finite_differences() {
        let measured = pose(0.8, -0.3, 0.4);
        let (a, b) = (pose(1.0, 2.0, 2.9), pose(1.5, 2.9, -2.8));
        let e = edge(0, 1, measured, [1.0; 3]);
        let (ja, jb) = jacobians(measured, a, b);
        let h = 1e-6;
        for k in 0..3 {
            let nudge = |p: Pose2D, by: f64| {
                let mut p = p;
                match k {
                    0 => p.x_m += by,
                    1 => p.y_m += by,
                    _ => p.theta_rad += by,
                }
                p
            };
            let (plus, minus) = (e.error(nudge(a, h), b), e.error(nudge(a, -h), b));
            for r in 0..3 {
                let numeric = wrap_angle(plus[r] - minus[r]) / (2.0 * h);
                assert!((numeric - ja[r][k]).abs() < 1e-5, "from {r} {k}");
            }
            let (plus, minus) = (e.error(a, nudge(b, h)), e.error(a, nudge(b, -h)));
            for r in 0..3 {
                let numeric = wrap_angle(plus[r] - minus[r]) / (2.0 * h);
                assert!((numeric - jb[r][k]).abs() < 1e-5, "to {r} {k}");
            }
        }
    }

    /// A square of four sides of 10 m, driven with a heading that drifts by 2° a side: the
    /// last node should be back on the first, and a loop edge that says so brings every corner
    /// near the truth.
    #[test]
    fn a_loop_edge_pulls_a_drifted_square_back_together() {
        let corners = [
            pose(0.0, 0.0, 0.0),
            pose(10.0, 0.0, std::f64::consts::FRAC_PI_2),
            pose(10.0, 10.0, std::f64::consts::PI),
            pose(0.0, 10.0, -std::f64::consts::FRAC_PI_2),
            pose(0.0, 0.0, 0.0),
        ];
        let drift = 2f64.to_radians();
        let mut graph = PoseGraph::default();
        let mut estimate = corners[0];
        graph.add_node(estimate);
        let odometry = [1e2, 1e2, 1e3];
        for (i, pair) in corners.windows(2).enumerate() {
            let mut measured = between(pair[0], pair[1]);
            measured.theta_rad += drift;
            estimate = compose(estimate, measured);
            graph.add_node(estimate);
            graph
                .add_edge(edge(i, i + 1, measured, odometry))
                .expect("valid");
        }
        let off = |graph: &PoseGraph, i: usize| {
            let (p, t) = (graph.poses()[i], corners[i]);
            (p.x_m - t.x_m).hypot(p.y_m - t.y_m)
        };
        assert!(off(&graph, 4) > 0.9, "{}", off(&graph, 4));
        graph
            .add_edge(edge(4, 0, Pose2D::default(), [1e4, 1e4, 1e5]))
            .expect("valid");
        let done = graph.optimise().expect("solvable");
        assert!(done.error_after < done.error_before / 10.0, "{done:?}");
        assert!(off(&graph, 4) < 0.05, "{}", off(&graph, 4));
        for i in 0..5 {
            assert!(off(&graph, i) < 0.6, "corner {i}: {}", off(&graph, i));
        }
        assert_eq!(graph.poses()[0], corners[0], "the first node stays");
    }

    #[test]
    fn refuses_bad_edges_and_a_node_without_one() {
        let mut graph = PoseGraph::default();
        graph.add_node(Pose2D::default());
        graph.add_node(pose(1.0, 0.0, 0.0));
        assert!(
            graph
                .add_edge(edge(0, 2, Pose2D::default(), [1.0; 3]))
                .is_err()
        );
        assert!(
            graph
                .add_edge(edge(1, 1, Pose2D::default(), [1.0; 3]))
                .is_err()
        );
        let zero = edge(0, 1, Pose2D::default(), [1.0, 0.0, 1.0]);
        assert!(graph.add_edge(zero).is_err());
        assert_eq!(graph.optimise(), None, "node 1 has no edge");
        assert_eq!(graph.poses()[1], pose(1.0, 0.0, 0.0));
    }

    #[test]
    fn the_skyline_factorisation_solves_a_banded_system_with_a_long_row() {
        // [[4, 1, 0, 1], [1, 4, 1, 0], [0, 1, 4, 1], [1, 0, 1, 4]] · x = b, row 3 reaching
        // column 0 as a loop closure's does.
        let mut m = Skyline::new(vec![0, 0, 1, 0]);
        for i in 0..4 {
            m.add(i, i, 4.0);
        }
        m.add(1, 0, 1.0);
        m.add(2, 1, 1.0);
        m.add(3, 2, 1.0);
        m.add(3, 0, 1.0);
        let x = m.solve(&[6.0, 6.0, 6.0, 6.0]).expect("positive definite");
        for v in x {
            assert!((v - 1.0).abs() < 1e-12, "{v}");
        }
    }
}
