//! The constraint model and its lexicographic optimisation.
//!
//! The model is a single-vehicle routing problem with time windows in successor form: every
//! node but the end has a successor (`succ[k]`, the end's node or a task's), all different; a
//! task that is its own successor is dropped. A served task's arrival `time[j]` is at least
//! its predecessor's arrival, service and travel (`[succ[k] = j] → time[j] ≥ time[k] +
//! service[k] + travel[k][j]`), and its rank is one more than its predecessor's, so that the
//! served tasks form one path from the start to the end and no detached cycle. The priority
//! served, the lateness and the distance are sums over these literals.
//!
//! Lexicographic optimisation is three solves of a fresh model: the most priority; then, with
//! that much priority required, the least lateness; then, with both, the least distance. Each
//! stops at the time left; a phase stopped early keeps the best it found and the next one
//! requires that much.
//!
//! Every constraint the operator gave (each window limit, each must-serve, each precedence,
//! each endurance) is posted under a *selector* literal: true in the plain model, and an
//! assumption when looking for a conflict ([`crate::explain`]).

use std::cell::Cell;
use std::time::{Duration, Instant};

use pumpkin_conflict_resolvers::resolvers::ResolutionResolver;
use pumpkin_core::Solver;
use pumpkin_core::branching::branchers::dynamic_brancher::DynamicBrancher;
use pumpkin_core::branching::branchers::warm_start::WarmStart;
use pumpkin_core::branching::{Brancher, BrancherEvent, SelectionContext};
use pumpkin_core::optimisation::OptimisationDirection;
use pumpkin_core::optimisation::linear_sat_unsat::LinearSatUnsat;
use pumpkin_core::predicate;
use pumpkin_core::predicates::Predicate;
use pumpkin_core::results::{OptimisationResult, ProblemSolution, SolutionReference};
use pumpkin_core::termination::TerminationCondition;
use pumpkin_core::variables::{AffineView, DomainId, Literal, TransformableVariable};

use crate::explain::Constraint;
use crate::{Problem, Route};

/// How solving ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// The best route found, and whether it is proven best.
    Solved(Solved),
    /// No route serves every must-serve task within the limits (proven).
    Infeasible,
    /// The time limit passed before any route was found.
    Unknown,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Solved {
    pub route: Route,
    /// Each phase finished with a proof that nothing better exists.
    pub optimal: bool,
    /// When the first route was found, from the start of solving.
    pub first_found: Duration,
}

/// The model's variables.
pub(crate) struct Model {
    pub solver: Solver,
    /// Successor of node k (0: the start, 1..=n: the tasks).
    succ: Vec<DomainId>,
    pub priority: DomainId,
    pub lateness: DomainId,
    pub distance: DomainId,
    /// The selector of each of the operator's constraints, with what it is.
    pub selectors: Vec<(Constraint, Literal)>,
}

/// Which operator constraints are posted under fresh selector literals (the others hold).
#[derive(Clone, Copy, PartialEq)]
pub(crate) enum Selectors {
    Hold,
    Assumed,
}

/// Bounds added by the earlier phases of the lexicographic order.
#[derive(Clone, Copy, Default)]
pub(crate) struct Bounds {
    pub min_priority: Option<i32>,
    pub max_lateness: Option<i32>,
    pub max_distance: Option<i32>,
}

impl Model {
    pub(crate) fn build(problem: &Problem, selectors: Selectors, bounds: Bounds) -> Model {
        let mut solver = Solver::default();
        let n = problem.tasks.len();
        let end = n + 1;
        let horizon = problem.horizon_ds();
        let tag = solver.new_constraint_tag();
        let mut chosen: Vec<(Constraint, Literal)> = Vec::new();
        let mut selector = |solver: &mut Solver, constraint: Constraint| -> Literal {
            match selectors {
                Selectors::Hold => solver.get_true_literal(),
                Selectors::Assumed => {
                    let literal = solver.new_literal();
                    chosen.push((constraint, literal));
                    literal
                }
            }
        };
        // Successors: the start's and every task's; a task may be its own (dropped).
        let succ: Vec<DomainId> = (0..=n)
            .map(|k| {
                let values: Vec<i32> = (1..=end)
                    .filter(|&j| j == k || problem.travel_ds[k][j].is_some())
                    .map(|j| j as i32)
                    .collect();
                solver.new_sparse_integer(values)
            })
            .collect();
        solver
            .add_constraint(pumpkin_constraints::all_different(succ.clone(), tag))
            .post();
        let time: Vec<DomainId> = (0..=end)
            .map(|k| {
                if k == 0 {
                    solver.new_bounded_integer(0, 0)
                } else {
                    solver.new_bounded_integer(0, horizon)
                }
            })
            .collect();
        let rank: Vec<DomainId> = (0..=end)
            .map(|k| {
                if k == 0 {
                    solver.new_bounded_integer(0, 0)
                } else {
                    solver.new_bounded_integer(1, end as i32)
                }
            })
            .collect();
        // Whether each task is served.
        let served: Vec<Literal> = (1..=n)
            .map(|k| {
                let node = succ[k];
                solver.new_literal_for_predicate(predicate![node != k as i32], tag)
            })
            .collect();
        // Each node's way out, as an element of its row of distances: its lower bound is the
        // shortest way the successors left allow, which bounds the total far better than a sum
        // over the successor literals would.
        // Predecessors, channelled with the successors: they bound each node's way in and its
        // arrival from the earliest of the nodes it may come from.
        let pred: Vec<DomainId> = (0..=end)
            .map(|j| {
                if j == 0 {
                    return solver.new_bounded_integer(0, 0);
                }
                let values: Vec<i32> = (0..=n)
                    .filter(|&k| k == j || problem.travel_ds[k][j].is_some())
                    .map(|k| k as i32)
                    .collect();
                solver.new_sparse_integer(values)
            })
            .collect();
        solver
            .add_constraint(pumpkin_constraints::all_different(pred[1..].to_vec(), tag))
            .post();
        for task in 1..=n {
            // Dropped: its own successor and its own predecessor.
            let (out, into) = (succ[task], pred[task]);
            let dropped = solver.new_literal_for_predicate(predicate![out == task as i32], tag);
            let alone = solver.new_literal_for_predicate(predicate![into == task as i32], tag);
            solver.add_clause(
                [dropped.get_false_predicate(), alone.get_true_predicate()],
                tag,
            );
            solver.add_clause(
                [alone.get_false_predicate(), dropped.get_true_predicate()],
                tag,
            );
        }
        let mut distance_in_terms: Vec<AffineView<DomainId>> = Vec::new();
        for j in 1..=end {
            let column: Vec<DomainId> = (0..=n)
                .map(|k| {
                    let metres = if k == j || problem.travel_ds[k][j].is_none() {
                        0
                    } else {
                        problem.distance_dm[k][j]
                    };
                    solver.new_bounded_integer(metres, metres)
                })
                .collect();
            let longest = (0..=n)
                .map(|k| problem.distance_dm[k][j])
                .max()
                .unwrap_or(0)
                .max(0);
            let into = solver.new_bounded_integer(0, longest);
            solver
                .add_constraint(pumpkin_constraints::element(pred[j], column, into, tag))
                .post();
            distance_in_terms.push(into.scaled(1));
            // The arrival is no earlier than leaving the predecessor (whichever it is) and
            // driving from there; a dropped task is its own predecessor, which says nothing.
            let ready: Vec<AffineView<DomainId>> = (0..=n)
                .map(|k| {
                    if k == j {
                        time[j].offset(0)
                    } else {
                        let service = if k == 0 {
                            0
                        } else {
                            problem.tasks[k - 1].service_ds
                        };
                        time[k].offset(service + problem.travel_ds[k][j].unwrap_or(0))
                    }
                })
                .collect();
            let earliest = solver.new_bounded_integer(0, horizon.saturating_mul(2));
            solver
                .add_constraint(pumpkin_constraints::element(pred[j], ready, earliest, tag))
                .post();
            solver
                .add_constraint(pumpkin_constraints::less_than_or_equals(
                    vec![earliest.scaled(1), time[j].scaled(-1)],
                    0,
                    tag,
                ))
                .post();
        }
        let mut distance_terms: Vec<AffineView<DomainId>> = Vec::new();
        for (k, &next) in succ.iter().enumerate() {
            let row: Vec<DomainId> = (0..=end)
                .map(|j| {
                    let metres = if j == k || problem.travel_ds[k][j].is_none() {
                        0
                    } else {
                        problem.distance_dm[k][j]
                    };
                    solver.new_bounded_integer(metres, metres)
                })
                .collect();
            let longest = row_max(&problem.distance_dm[k]);
            let out = solver.new_bounded_integer(0, longest);
            solver
                .add_constraint(pumpkin_constraints::element(next, row, out, tag))
                .post();
            distance_terms.push(out.scaled(1));
        }
        for k in 0..=n {
            let service = if k == 0 {
                0
            } else {
                problem.tasks[k - 1].service_ds
            };
            for j in 1..=end {
                if j == k {
                    continue;
                }
                let Some(travel) = problem.travel_ds[k][j] else {
                    continue;
                };
                let node = succ[k];
                let next = solver.new_literal_for_predicate(predicate![node == j as i32], tag);
                let from = pred[j];
                let back = solver.new_literal_for_predicate(predicate![from == k as i32], tag);
                solver.add_clause([next.get_false_predicate(), back.get_true_predicate()], tag);
                solver.add_clause([back.get_false_predicate(), next.get_true_predicate()], tag);
                // time[k] - time[j] <= -(service + travel)
                solver
                    .add_constraint(pumpkin_constraints::less_than_or_equals(
                        vec![time[k].scaled(1), time[j].scaled(-1)],
                        -(service + travel),
                        tag,
                    ))
                    .implied_by(next);
                solver
                    .add_constraint(pumpkin_constraints::less_than_or_equals(
                        vec![rank[k].scaled(1), rank[j].scaled(-1)],
                        -1,
                        tag,
                    ))
                    .implied_by(next);
            }
        }
        let max_distance: i32 = problem.distance_dm.iter().map(|row| row_max(row)).sum();
        let distance = solver.new_bounded_integer(0, max_distance.max(0));
        for mut terms in [distance_terms, distance_in_terms] {
            terms.push(distance.scaled(-1));
            solver
                .add_constraint(pumpkin_constraints::equals(terms, 0, tag))
                .post();
        }
        // A served task is reached no sooner than by the quickest chain of ways from the start
        // (`Problem::earliest_ds`: a way may be longer than going through another place), and
        // this bound is what lets the solver prove the least lateness without trying every
        // order.
        let earliest = problem.earliest_ds();
        for task in 0..n {
            if let Some(direct) = earliest[task + 1] {
                solver
                    .add_constraint(pumpkin_constraints::greater_than_or_equals(
                        vec![time[task + 1]],
                        direct,
                        tag,
                    ))
                    .implied_by(served[task]);
            }
        }
        // The operator's constraints.
        let mut lateness_terms: Vec<AffineView<DomainId>> = Vec::new();
        let mut priority_terms: Vec<AffineView<DomainId>> = Vec::new();
        let mut max_priority = 0;
        for (task, spec) in problem.tasks.iter().enumerate() {
            let node = task + 1;
            let at = time[node];
            if let Some(not_before) = spec.not_before_ds {
                let on = selector(&mut solver, Constraint::NotBefore(task));
                solver
                    .add_constraint(pumpkin_constraints::greater_than_or_equals(
                        vec![at],
                        not_before,
                        tag,
                    ))
                    .implied_by(on);
            }
            if let Some(by) = spec.by_ds {
                let on = selector(&mut solver, Constraint::By(task));
                solver
                    .add_constraint(pumpkin_constraints::less_than_or_equals(vec![at], by, tag))
                    .implied_by(on);
            }
            if spec.must {
                let on = selector(&mut solver, Constraint::Must(task));
                solver.add_clause(
                    [on.get_false_predicate(), served[task].get_true_predicate()],
                    tag,
                );
            }
            if let Some(due) = spec.due_ds {
                let late = solver.new_bounded_integer(0, horizon);
                solver
                    .add_constraint(pumpkin_constraints::less_than_or_equals(
                        vec![at.scaled(1), late.scaled(-1)],
                        due,
                        tag,
                    ))
                    .implied_by(served[task]);
                lateness_terms.push(late.scaled(1));
            }
            priority_terms.push(served[task].get_integer_variable().scaled(spec.priority));
            max_priority += spec.priority;
        }
        for (index, &(first, then)) in problem.precedences.iter().enumerate() {
            let on = selector(&mut solver, Constraint::Precedence(index));
            // Binds when both are served (and the precedence is in force).
            let both = solver.new_literal();
            solver.add_clause(
                [
                    on.get_false_predicate(),
                    served[first].get_false_predicate(),
                    served[then].get_false_predicate(),
                    both.get_true_predicate(),
                ],
                tag,
            );
            solver
                .add_constraint(pumpkin_constraints::less_than_or_equals(
                    vec![time[first + 1].scaled(1), time[then + 1].scaled(-1)],
                    -problem.tasks[first].service_ds,
                    tag,
                ))
                .implied_by(both);
        }
        if let Some(max) = problem.max_distance_dm {
            let on = selector(&mut solver, Constraint::MaxDistance);
            solver
                .add_constraint(pumpkin_constraints::less_than_or_equals(
                    vec![distance],
                    max,
                    tag,
                ))
                .implied_by(on);
        }
        if let Some(max) = problem.max_time_ds {
            let on = selector(&mut solver, Constraint::MaxTime);
            solver
                .add_constraint(pumpkin_constraints::less_than_or_equals(
                    vec![time[end]],
                    max,
                    tag,
                ))
                .implied_by(on);
        }
        if let Some(limit) = problem.max_charge {
            let on = selector(&mut solver, Constraint::MaxCharge);
            solver
                .add_constraint(pumpkin_constraints::less_than_or_equals(
                    vec![
                        distance.scaled(limit.per_dm),
                        time[end].scaled(limit.per_ds),
                    ],
                    limit.max,
                    tag,
                ))
                .implied_by(on);
        }
        let priority = solver.new_bounded_integer(0, max_priority);
        priority_terms.push(priority.scaled(-1));
        solver
            .add_constraint(pumpkin_constraints::equals(priority_terms, 0, tag))
            .post();
        let lateness = solver.new_bounded_integer(0, horizon.saturating_mul(n as i32 + 1));
        lateness_terms.push(lateness.scaled(-1));
        solver
            .add_constraint(pumpkin_constraints::equals(lateness_terms, 0, tag))
            .post();
        if let Some(min) = bounds.min_priority {
            solver
                .add_constraint(pumpkin_constraints::greater_than_or_equals(
                    vec![priority],
                    min,
                    tag,
                ))
                .post();
        }
        if let Some(max) = bounds.max_lateness {
            solver
                .add_constraint(pumpkin_constraints::less_than_or_equals(
                    vec![lateness],
                    max,
                    tag,
                ))
                .post();
        }
        if let Some(max) = bounds.max_distance {
            solver
                .add_constraint(pumpkin_constraints::less_than_or_equals(
                    vec![distance],
                    max,
                    tag,
                ))
                .post();
        }
        Model {
            solver,
            succ,
            priority,
            lateness,
            distance,
            selectors: chosen,
        }
    }

    /// The search: build the route from the start, each time to the nearest task the domains
    /// still allow (the end last), drop the tasks left, then let the solver's own activity-based
    /// search set the times. The first route is found as a dispatcher would; the clauses learnt
    /// on the way turn the later branches down (kept through the proof, this search proved the
    /// least lateness of seven tasks three times faster than the activity-based one alone).
    pub(crate) fn brancher(&self, problem: &Problem, seed: Option<&Route>) -> DynamicBrancher {
        let mut branchers: Vec<Box<dyn Brancher>> = Vec::new();
        if let Some(seed) = seed {
            // The seed's successors first: its route, then the tasks it drops.
            let mut values = vec![0; self.succ.len()];
            for (node, value) in values.iter_mut().enumerate() {
                *value = node as i32;
            }
            let mut node = 0;
            for &task in &seed.order {
                values[node] = (task + 1) as i32;
                node = task + 1;
            }
            values[node] = self.succ.len() as i32;
            branchers.push(Box::new(WarmStart::new(&self.succ, &values)));
        }
        branchers.extend([
            Box::new(RouteBrancher {
                succ: self.succ.clone(),
                travel_ds: problem.travel_ds.clone(),
            }),
            Box::new(self.solver.default_brancher()) as Box<dyn Brancher>,
        ]);
        DynamicBrancher::new(branchers)
    }

    /// The order of the tasks a solution serves, following the successors from the start.
    pub(crate) fn order(&self, solution: &impl ProblemSolution) -> Vec<usize> {
        let end = self.succ.len();
        let mut order = Vec::new();
        let mut node = 0;
        while order.len() < end {
            let next = solution.get_integer_value(self.succ[node]) as usize;
            if next >= end || next == node {
                break;
            }
            order.push(next - 1);
            node = next;
        }
        order
    }
}

/// The best route within `limit`, in the lexicographic order of [`crate::Cost::key`].
pub fn solve(problem: &Problem, limit: Duration) -> Outcome {
    solve_from(problem, limit, None)
}

/// [`solve`], the search tried first along `seed` (a route found otherwise, such as
/// [`crate::heuristic`]'s), which the answer is never worse than.
pub fn solve_from(problem: &Problem, limit: Duration, seed: Option<&Route>) -> Outcome {
    let started = Instant::now();
    let mut bounds = Bounds::default();
    let mut best: Option<Route> = None;
    let mut first_found: Option<Duration> = None;
    let mut optimal = true;
    for phase in 0..3u32 {
        // Each phase may take its share of what is left (a third, a half, all) once it has a
        // solution: a first phase that cannot prove its best within the limit leaves the
        // others time to improve; one with no solution yet may take all the time left.
        let left = limit.saturating_sub(started.elapsed());
        let share = left / (3 - phase);
        let phase_found = Cell::new(false);
        let mut model = Model::build(problem, Selectors::Hold, bounds);
        let objective = match phase {
            0 => model.priority,
            1 => model.lateness,
            _ => model.distance,
        };
        let direction = if phase == 0 {
            OptimisationDirection::Maximise
        } else {
            OptimisationDirection::Minimise
        };
        let mut brancher = model.brancher(problem, seed);
        let mut resolver = ResolutionResolver::default();
        let mut termination = Share {
            started: Instant::now(),
            share,
            left,
            found: &phase_found,
        };
        let mut found = |_: &Solver, _: SolutionReference, _: &_, _: &_| {
            phase_found.set(true);
            if first_found.is_none() {
                first_found = Some(started.elapsed());
            }
            std::ops::ControlFlow::<()>::Continue(())
        };
        let result = model.solver.optimise(
            &mut brancher,
            &mut termination,
            &mut resolver,
            LinearSatUnsat::new(direction, objective, &mut found),
        );
        let (solution, proven) = match result {
            OptimisationResult::Optimal(solution) => (solution, true),
            OptimisationResult::Satisfiable(solution)
            | OptimisationResult::Stopped(solution, _) => (solution, false),
            OptimisationResult::Unsatisfiable => {
                // Only the first phase can be unsatisfiable: the later ones require what an
                // earlier solution achieved.
                return match best {
                    Some(route) => Outcome::Solved(Solved {
                        route,
                        optimal: false,
                        first_found: first_found.unwrap_or_default(),
                    }),
                    None => Outcome::Infeasible,
                };
            }
            OptimisationResult::Unknown => {
                optimal = false;
                break;
            }
        };
        optimal &= proven;
        let order = model.order(&solution);
        // The earliest schedule of the order found: the solver's times may wait for nothing.
        let route = problem.evaluate(&order);
        let value = solution.get_integer_value(objective);
        match phase {
            0 => bounds.min_priority = Some(value),
            1 => bounds.max_lateness = Some(value),
            _ => bounds.max_distance = Some(value),
        }
        if let Some(route) = route
            && best
                .as_ref()
                .is_none_or(|best| route.cost.key() <= best.cost.key())
        {
            best = Some(route);
        }
    }
    // The seed, when the search found nothing better in its time.
    if let Some(seed) = seed.and_then(|seed| problem.evaluate(&seed.order))
        && best
            .as_ref()
            .is_none_or(|best| seed.cost.key() < best.cost.key())
    {
        optimal = false;
        best = Some(seed);
    }
    match best {
        Some(route) => Outcome::Solved(Solved {
            route,
            optimal,
            first_found: first_found.unwrap_or_default(),
        }),
        None => Outcome::Unknown,
    }
}

/// A phase's time: its share once it has a solution, all that is left until then.
struct Share<'a> {
    started: Instant,
    share: Duration,
    left: Duration,
    found: &'a Cell<bool>,
}

impl TerminationCondition for Share<'_> {
    fn should_stop(&mut self) -> bool {
        let elapsed = self.started.elapsed();
        elapsed >= self.left || (self.found.get() && elapsed >= self.share)
    }
}

fn row_max(row: &[i32]) -> i32 {
    row.iter().copied().max().unwrap_or(0).max(0)
}

/// Nearest-neighbour branching over the successors ([`Model::brancher`]).
#[derive(Debug)]
struct RouteBrancher {
    succ: Vec<DomainId>,
    travel_ds: Vec<Vec<Option<i32>>>,
}

impl Brancher for RouteBrancher {
    fn next_decision(&mut self, context: &mut SelectionContext) -> Option<Predicate> {
        let end = self.succ.len();
        let mut node = 0;
        let mut visited = 0;
        // Follow the route as far as it is decided.
        while visited < end && context.is_integer_fixed(self.succ[node]) {
            let next = context.lower_bound(self.succ[node]) as usize;
            if next >= end || next == node {
                break;
            }
            node = next;
            visited += 1;
        }
        if visited < end && !context.is_integer_fixed(self.succ[node]) {
            let var = self.succ[node];
            let nearest = (1..=end)
                .filter(|&next| next != node && context.contains(var, next as i32))
                .min_by_key(|&next| (next == end, self.travel_ds[node][next].unwrap_or(i32::MAX)));
            if let Some(next) = nearest {
                return Some(predicate![var == next as i32]);
            }
        }
        // The route is decided: the tasks off it are dropped.
        (1..end)
            .map(|task| (task, self.succ[task]))
            .find(|&(task, var)| {
                !context.is_integer_fixed(var) && context.contains(var, task as i32)
            })
            .map(|(task, var)| predicate![var == task as i32])
    }

    fn subscribe_to_events(&self) -> Vec<BrancherEvent> {
        Vec::new()
    }
}
