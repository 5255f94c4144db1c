//! The reference the benchmark holds the solver against: nearest neighbour, then 2-opt, as a
//! dispatcher would do it by hand. It serves every task it can in the order it builds, drops
//! (optional) tasks that it cannot fit, and improves the order by reversing segments while the
//! route gets better in the lexicographic order of [`crate::Cost::key`].

use crate::{Problem, Route};

/// Nearest neighbour from the start, then 2-opt; `None` when it finds no feasible route.
pub fn nearest_neighbour_2opt(problem: &Problem) -> Option<Route> {
    let n = problem.tasks.len();
    let mut order: Vec<usize> = Vec::with_capacity(n);
    let mut left: Vec<usize> = (0..n).collect();
    let mut node = 0;
    while !left.is_empty() {
        // The nearest task left that can be appended without breaking a limit on the way.
        let mut candidates: Vec<(i32, usize)> = left
            .iter()
            .filter_map(|&task| Some((problem.travel_ds[node][Problem::node(task)]?, task)))
            .collect();
        candidates.sort_unstable();
        let next = candidates
            .iter()
            .map(|&(_, task)| task)
            .find(|&task| prefix_feasible(problem, &order, task));
        let Some(next) = next else {
            break;
        };
        order.push(next);
        left.retain(|&task| task != next);
        node = Problem::node(next);
    }
    let mut best = problem
        .evaluate(&order)
        .or_else(|| drop_until_feasible(problem, &order))?;
    // 2-opt: reverse every segment while that improves the route.
    let mut improved = true;
    while improved {
        improved = false;
        let len = best.order.len();
        for i in 0..len {
            for j in i + 1..len {
                let mut candidate = best.order.clone();
                candidate[i..=j].reverse();
                if let Some(route) = problem.evaluate(&candidate)
                    && route.cost.key() < best.cost.key()
                {
                    best = route;
                    improved = true;
                }
            }
        }
    }
    Some(best)
}

/// Whether `order` then `task` keeps every window, precedence and endurance on the way (the
/// must-serve tasks not yet served are not held against it).
fn prefix_feasible(problem: &Problem, order: &[usize], task: usize) -> bool {
    let mut relaxed = problem.clone();
    for spec in &mut relaxed.tasks {
        spec.must = false;
    }
    let mut candidate = order.to_vec();
    candidate.push(task);
    relaxed.evaluate(&candidate).is_some()
}

/// Drops optional tasks, least priority first, until the route is feasible.
fn drop_until_feasible(problem: &Problem, order: &[usize]) -> Option<Route> {
    let mut order = order.to_vec();
    let mut optional: Vec<usize> = order
        .iter()
        .copied()
        .filter(|&task| !problem.tasks[task].must)
        .collect();
    optional.sort_by_key(|&task| problem.tasks[task].priority);
    for task in optional {
        order.retain(|&t| t != task);
        if let Some(route) = problem.evaluate(&order) {
            return Some(route);
        }
    }
    None
}
