//! Why no route serves every must-serve task: a minimal set of the operator's constraints that
//! cannot all hold, found by deletion over the solver's core.
//!
//! Every constraint is posted under a selector literal ([`crate::solve`]); solving under the
//! assumption that all selectors hold fails with a *core*, a subset of them that already
//! fails. Deletion then tries the core without each of its members in turn: a member whose
//! removal leaves the rest failing is left out for good. What remains is minimal: removing any
//! one of its constraints makes the others satisfiable (unless a check ran out of time, which
//! [`Conflict::minimal`] says).

use std::time::{Duration, Instant};

use pumpkin_conflict_resolvers::resolvers::ResolutionResolver;
use pumpkin_core::predicates::Predicate;
use pumpkin_core::results::SatisfactionResultUnderAssumptions;
use pumpkin_core::termination::TimeBudget;
use pumpkin_core::variables::Literal;

use crate::Problem;
use crate::solve::{Bounds, Model, Selectors};

/// One of the operator's constraints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Constraint {
    /// Task `i` is served (it is not optional).
    Must(usize),
    /// Task `i` is reached no earlier than its `not_before`.
    NotBefore(usize),
    /// Task `i` is reached no later than its `by`.
    By(usize),
    /// The precedence at this index holds.
    Precedence(usize),
    /// The robot drives no more than its endurance.
    MaxDistance,
    /// The plan takes no longer than its endurance.
    MaxTime,
    /// The plan uses no more of the battery than its share.
    MaxCharge,
}

impl Constraint {
    /// The task it concerns, if one.
    pub fn task(&self) -> Option<usize> {
        match *self {
            Constraint::Must(task) | Constraint::NotBefore(task) | Constraint::By(task) => {
                Some(task)
            }
            _ => None,
        }
    }
}

/// A set of constraints that cannot all hold.
#[derive(Clone, Debug, PartialEq)]
pub struct Conflict {
    pub constraints: Vec<Constraint>,
    /// Every deletion check finished: removing any one constraint makes the rest feasible.
    pub minimal: bool,
}

/// Whether the must-serve tasks can all be served within every limit: `Ok(())` when they can,
/// else a minimal conflicting set; `Err(None)` when `limit` passed before an answer.
pub fn explain(problem: &Problem, limit: Duration) -> Result<(), Option<Conflict>> {
    let started = Instant::now();
    let mut model = Model::build(problem, Selectors::Assumed, Bounds::default());
    let selectors = model.selectors.clone();
    let all: Vec<usize> = (0..selectors.len()).collect();
    let mut core = match check(&mut model, problem, &selectors, &all, limit) {
        Check::Feasible => return Ok(()),
        Check::Unknown => return Err(None),
        Check::Core(core) => core,
    };
    let mut minimal = true;
    let mut index = 0;
    while index < core.len() {
        let without: Vec<usize> = core
            .iter()
            .enumerate()
            .filter(|&(at, _)| at != index)
            .map(|(_, &selector)| selector)
            .collect();
        let left = limit.saturating_sub(started.elapsed());
        match check(&mut model, problem, &selectors, &without, left) {
            // Still failing without it: it is not needed; the new core may be smaller still.
            Check::Core(smaller) => {
                core = smaller
                    .into_iter()
                    .filter(|selector| without.contains(selector))
                    .collect();
                core.sort_unstable();
                // The members before `index` were each found needed; keep checking from the
                // first one not yet checked in the smaller core.
                index = index.min(core.len());
            }
            Check::Feasible => index += 1,
            Check::Unknown => {
                minimal = false;
                index += 1;
            }
        }
    }
    let mut constraints: Vec<Constraint> = core.iter().map(|&at| selectors[at].0).collect();
    constraints.sort_unstable();
    Err(Some(Conflict {
        constraints,
        minimal,
    }))
}

enum Check {
    Feasible,
    /// The indices (into the selectors) of a failing subset.
    Core(Vec<usize>),
    Unknown,
}

/// Solves under the assumption that the selectors at `on` hold (the others are free).
fn check(
    model: &mut Model,
    problem: &Problem,
    selectors: &[(Constraint, Literal)],
    on: &[usize],
    limit: Duration,
) -> Check {
    let assumptions: Vec<Predicate> = on
        .iter()
        .map(|&at| selectors[at].1.get_true_predicate())
        .collect();
    let mut brancher = model.brancher(problem, None);
    let mut resolver = ResolutionResolver::default();
    let mut termination = TimeBudget::starting_now(limit);
    match model.solver.satisfy_under_assumptions(
        &mut brancher,
        &mut termination,
        &mut resolver,
        &assumptions,
    ) {
        SatisfactionResultUnderAssumptions::Satisfiable(_) => Check::Feasible,
        SatisfactionResultUnderAssumptions::UnsatisfiableUnderAssumptions(mut unsatisfiable) => {
            let core = unsatisfiable.extract_core();
            let mut indices: Vec<usize> = on
                .iter()
                .copied()
                .filter(|&at| core.contains(&selectors[at].1.get_true_predicate()))
                .collect();
            indices.sort_unstable();
            Check::Core(indices)
        }
        // Unsatisfiable with no assumption at all: nothing the operator gave is to blame, and
        // the model is built so that this cannot be; the empty core says so.
        SatisfactionResultUnderAssumptions::Unsatisfiable(_) => Check::Core(Vec::new()),
        SatisfactionResultUnderAssumptions::Unknown(_) => Check::Unknown,
    }
}
