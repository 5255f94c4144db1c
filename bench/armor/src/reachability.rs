//! `reachability_states_per_s`: the mission analysis (`armor_model::net::analyse`, what
//! `armor check` and `armor run` do before anything runs) on ten dining philosophers (6,726
//! reachable markings), against a straightforward breadth-first exploration of the same net
//! written here: markings as `Vec<u32>` in a `HashSet`, successors by checking each transition's
//! input weights. Both must find the same number of states.
//!
//! The analysis does more than count (it keeps each marking's parent for the deadlock
//! sequences, finds dead markings, transitions never enabled and places never marked), so the
//! comparison is, if anything, unfair to it. Both sides include turning the net's names into
//! indices.

use std::collections::{HashSet, VecDeque};
use std::hint::black_box;
use std::time::{Duration, Instant};

use anyhow::{bail, ensure};
use armor_model::net::{MissionNet, analyse, dining_philosophers};
use armor_runtime::mission::ANALYSIS_LIMIT_STATES;

use crate::Settings;
use armor_bench_report::{Report, median};

pub const NAME: &str = "reachability_states_per_s";

struct Counts {
    philosophers: usize,
    /// Rounds alternate between the analysis and the reference, so that a change in the
    /// machine's load weighs on both alike; the medians are reported.
    rounds: usize,
    /// Each round of each side repeats the exploration for at least this long.
    round_time: Duration,
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let counts = if settings.quick {
        Counts {
            philosophers: 5,
            rounds: 1,
            round_time: Duration::from_millis(20),
        }
    } else {
        Counts {
            philosophers: 10,
            rounds: 7,
            round_time: Duration::from_millis(300),
        }
    };
    let net = dining_philosophers(counts.philosophers);
    let analysis = analyse(&net, ANALYSIS_LIMIT_STATES);
    ensure!(
        !analysis.truncated,
        "the analysis stopped at its limit of {ANALYSIS_LIMIT_STATES} markings"
    );
    let states = analysis.states;
    let reference_states = breadth_first(&net)?;
    if reference_states != states {
        bail!(
            "{} dining philosophers: the analysis found {states} reachable markings, the \
             reference breadth-first exploration {reference_states}",
            counts.philosophers
        );
    }
    let mut ours = Vec::with_capacity(counts.rounds);
    let mut reference = Vec::with_capacity(counts.rounds);
    for _ in 0..counts.rounds {
        ours.push(rate(counts.round_time, || {
            Ok(analyse(black_box(&net), ANALYSIS_LIMIT_STATES).states)
        })?);
        reference.push(rate(counts.round_time, || breadth_first(black_box(&net)))?);
    }
    Ok(Report::single(NAME, "states/s", median(&ours), median(&reference)).with_states(states))
}

/// States per second of `explore`, repeated for at least `time`.
fn rate(time: Duration, mut explore: impl FnMut() -> anyhow::Result<usize>) -> anyhow::Result<f64> {
    let start = Instant::now();
    let mut states = 0;
    loop {
        states += black_box(explore()?);
        let elapsed = start.elapsed();
        if elapsed >= time {
            return Ok(states as f64 / elapsed.as_secs_f64());
        }
    }
}

/// The reachable markings of `net`, counted the plain way.
fn breadth_first(net: &MissionNet) -> anyhow::Result<usize> {
    let index = |name: &str| -> anyhow::Result<usize> {
        match net.places.iter().position(|place| place.name == name) {
            Some(place) => Ok(place),
            None => bail!("an arc to no place `{name}`"),
        }
    };
    let mut transitions = Vec::with_capacity(net.transitions.len());
    for transition in &net.transitions {
        let arcs = |arcs: &[armor_model::net::Arc]| -> anyhow::Result<Vec<(usize, u32)>> {
            arcs.iter()
                .map(|arc| Ok((index(&arc.place)?, arc.weight)))
                .collect()
        };
        transitions.push((arcs(&transition.inputs)?, arcs(&transition.outputs)?));
    }
    let initial: Vec<u32> = net.places.iter().map(|place| place.tokens).collect();
    let mut seen: HashSet<Vec<u32>> = HashSet::new();
    let mut queue = VecDeque::new();
    seen.insert(initial.clone());
    queue.push_back(initial);
    while let Some(marking) = queue.pop_front() {
        for (inputs, outputs) in &transitions {
            if !inputs
                .iter()
                .all(|&(place, weight)| marking[place] >= weight)
            {
                continue;
            }
            let mut next = marking.clone();
            for &(place, weight) in inputs {
                next[place] -= weight;
            }
            for &(place, weight) in outputs {
                next[place] = next[place]
                    .checked_add(weight)
                    .ok_or_else(|| anyhow::anyhow!("more than {} tokens in a place", u32::MAX))?;
            }
            if !seen.contains(&next) {
                if seen.len() >= ANALYSIS_LIMIT_STATES {
                    bail!("more than {ANALYSIS_LIMIT_STATES} reachable markings");
                }
                seen.insert(next.clone());
                queue.push_back(next);
            }
        }
    }
    Ok(seen.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_reference_counts_the_companion_pell_numbers() {
        for (n, states) in [(2, 6), (3, 14), (5, 82), (10, 6726)] {
            assert_eq!(breadth_first(&dining_philosophers(n)).ok(), Some(states));
        }
    }
}
