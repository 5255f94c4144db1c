//! The constraint planner behind `armor plan`: a plan's objectives (places to reach, what to do
//! there, time windows, priorities, precedences, the robot's endurance) in, an ordered and
//! timed route out, written as an ordinary plan; or, when the must-serve objectives cannot all
//! be served, a minimal set of the operator's constraints that conflict, in their words.
//!
//! [`instance`] turns a [`Plan`](armor_model::plan::Plan) on its world into a [`Problem`]:
//! integers only (times in deciseconds, distances in decimetres), the travel between every two
//! places measured along the paths the costmap planner finds, as `armor check` plans legs.
//! [`solve`] states it as a constraint model for Pumpkin (a lazy clause generation solver in
//! pure Rust) and optimises it lexicographically: most priority served, then least lateness,
//! then least distance, within a time limit. [`explain`] finds a minimal conflicting set by
//! deletion over the solver's core. [`heuristic`] is the reference the benchmark compares with
//! (nearest neighbour and 2-opt). [`write`] makes the plan file's legs.
//!
//! **Architecture Invariant:** no IO; the only clock is the solver's time limit.

pub mod explain;
pub mod heuristic;
pub mod instance;
pub mod solve;
pub mod write;

#[cfg(test)]
mod tests;

pub use explain::{Conflict, Constraint, explain};
pub use instance::{Instance, instance};
pub use solve::{Outcome, Solved, solve, solve_from};

/// One objective as the solver sees it (times from the plan's start, in deciseconds).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Task {
    /// How long the robot stays once there.
    pub service_ds: i32,
    /// Arrive no earlier.
    pub not_before_ds: Option<i32>,
    /// Arrive by, or count the lateness.
    pub due_ds: Option<i32>,
    /// Arrive no later.
    pub by_ds: Option<i32>,
    pub priority: i32,
    /// Must be served (it may not be dropped).
    pub must: bool,
}

/// A routing problem: leave node 0 (the start) at time 0, serve some of the tasks (nodes 1 to
/// n) and end at node n+1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Problem {
    pub tasks: Vec<Task>,
    /// Travel time between nodes, `None` where there is no way; `(n+2)²`, row = from.
    pub travel_ds: Vec<Vec<Option<i32>>>,
    /// Distance driven between nodes (decimetres), where there is a way.
    pub distance_dm: Vec<Vec<i32>>,
    /// `(first, then)`: task indices (from 0); binds when both are served.
    pub precedences: Vec<(usize, usize)>,
    /// The most the robot may drive.
    pub max_distance_dm: Option<i32>,
    /// The latest the robot may arrive at the end.
    pub max_time_ds: Option<i32>,
    /// The most of the battery the plan may use.
    pub max_charge: Option<ChargeLimit>,
}

/// A limit on the battery's charge used: `per_dm × distance + per_ds × end time ≤ max`, in
/// ten-millionths of a full charge.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ChargeLimit {
    pub per_dm: i32,
    pub per_ds: i32,
    pub max: i32,
}

/// The unit of [`ChargeLimit`]: a full charge.
pub const FULL_CHARGE: f64 = 1e7;

impl ChargeLimit {
    /// The limit of a battery that drains `per_m` of a full charge a metre and `per_hour` an
    /// hour, of which the plan may use `share` (the drains rounded up, the share down, so that
    /// the limit errs on the side of the battery).
    pub fn new(per_m: f64, per_hour: f64, share: f64) -> ChargeLimit {
        let scaled = |value: f64| value.clamp(0.0, f64::from(i32::MAX / 4)) as i32;
        ChargeLimit {
            per_dm: scaled((per_m / 10.0 * FULL_CHARGE).ceil()),
            per_ds: scaled((per_hour / 36_000.0 * FULL_CHARGE).ceil()),
            max: scaled((share * FULL_CHARGE).floor()),
        }
    }

    /// The charge a route of `distance_dm` ending at `end_ds` uses.
    pub fn used(&self, distance_dm: i64, end_ds: i64) -> i64 {
        i64::from(self.per_dm) * distance_dm + i64::from(self.per_ds) * end_ds
    }
}

impl Problem {
    /// The node of task `task`.
    pub fn node(task: usize) -> usize {
        task + 1
    }

    /// The end node.
    pub fn end(&self) -> usize {
        self.tasks.len() + 1
    }

    /// The least time from the start to each node by any chain of ways (windows and services
    /// aside): a bound on when a node can be reached that holds whatever the ways are (a way
    /// may be longer than going through another place: each is the path planned for its
    /// leg). `None` where there is no way.
    pub fn earliest_ds(&self) -> Vec<Option<i32>> {
        let count = self.travel_ds.len();
        let mut earliest: Vec<Option<i32>> = vec![None; count];
        let mut done = vec![false; count];
        if count > 0 {
            earliest[0] = Some(0);
        }
        while let Some(node) = (0..count)
            .filter(|&node| !done[node])
            .filter_map(|node| Some((earliest[node]?, node)))
            .min()
            .map(|(_, node)| node)
        {
            done[node] = true;
            let Some(at) = earliest[node] else { break };
            for (next, travel) in self.travel_ds[node].iter().enumerate() {
                if let Some(travel) = travel {
                    let through = at.saturating_add(*travel);
                    if earliest[next].is_none_or(|known| through < known) {
                        earliest[next] = Some(through);
                    }
                }
            }
        }
        earliest
    }

    /// A time no route can need: every window's end, every service and the longest way out of
    /// every node, added up.
    pub fn horizon_ds(&self) -> i32 {
        let windows = self
            .tasks
            .iter()
            .flat_map(|task| [task.not_before_ds, task.due_ds, task.by_ds])
            .flatten()
            .chain(self.max_time_ds)
            .max()
            .unwrap_or(0);
        let services: i64 = self
            .tasks
            .iter()
            .map(|task| i64::from(task.service_ds))
            .sum();
        let ways: i64 = self
            .travel_ds
            .iter()
            .map(|row| i64::from(row.iter().flatten().copied().max().unwrap_or(0)))
            .sum();
        i32::try_from(i64::from(windows) + services + ways + 1).unwrap_or(i32::MAX / 4)
    }

    /// The earliest schedule of the tasks in `order` (task indices), waiting only where a
    /// window opens later; `None` when a way is missing or a hard limit is broken (a window's
    /// `by`, a precedence, must-serve, the endurance).
    pub fn evaluate(&self, order: &[usize]) -> Option<Route> {
        let mut served = vec![false; self.tasks.len()];
        let mut at_ds = vec![0; self.tasks.len()];
        let mut time = 0i64;
        let mut distance = 0i64;
        let mut lateness = 0i64;
        let mut priority = 0i64;
        let mut node = 0;
        for &task in order {
            let next = Self::node(task);
            if served.get(task).copied().unwrap_or(true) {
                return None;
            }
            time += i64::from(self.travel_ds[node][next]?);
            distance += i64::from(self.distance_dm[node][next]);
            let spec = &self.tasks[task];
            if let Some(not_before) = spec.not_before_ds {
                time = time.max(i64::from(not_before));
            }
            if spec.by_ds.is_some_and(|by| time > i64::from(by)) {
                return None;
            }
            if let Some(due) = spec.due_ds {
                lateness += (time - i64::from(due)).max(0);
            }
            at_ds[task] = i32::try_from(time).ok()?;
            served[task] = true;
            priority += i64::from(spec.priority);
            time += i64::from(spec.service_ds);
            node = next;
        }
        time += i64::from(self.travel_ds[node][self.end()]?);
        distance += i64::from(self.distance_dm[node][self.end()]);
        if self
            .tasks
            .iter()
            .zip(&served)
            .any(|(task, served)| task.must && !served)
        {
            return None;
        }
        let position = |task: usize| order.iter().position(|&t| t == task);
        for &(first, then) in &self.precedences {
            if let (Some(a), Some(b)) = (position(first), position(then))
                && a > b
            {
                return None;
            }
        }
        if self
            .max_distance_dm
            .is_some_and(|max| distance > i64::from(max))
            || self.max_time_ds.is_some_and(|max| time > i64::from(max))
            || self
                .max_charge
                .is_some_and(|limit| limit.used(distance, time) > i64::from(limit.max))
        {
            return None;
        }
        Some(Route {
            order: order.to_vec(),
            arrival_ds: order.iter().map(|&task| at_ds[task]).collect(),
            end_ds: i32::try_from(time).ok()?,
            cost: Cost {
                priority: i32::try_from(priority).ok()?,
                lateness_ds: i32::try_from(lateness).ok()?,
                distance_dm: i32::try_from(distance).ok()?,
            },
        })
    }
}

/// A route: the tasks served in order, when the robot arrives at each, and what it costs.
#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    pub order: Vec<usize>,
    /// The arrival at each task of `order`.
    pub arrival_ds: Vec<i32>,
    /// The arrival at the end.
    pub end_ds: i32,
    pub cost: Cost,
}

/// What a route achieves, in the lexicographic order it is judged by.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Cost {
    /// The priority of the tasks served, added up (more is better).
    pub priority: i32,
    /// The lateness past each task's `due`, added up.
    pub lateness_ds: i32,
    pub distance_dm: i32,
}

impl Cost {
    /// The key to sort by, best first: most priority, then least lateness, then least
    /// distance.
    pub fn key(&self) -> (i32, i32, i32) {
        (-self.priority, self.lateness_ds, self.distance_dm)
    }
}
