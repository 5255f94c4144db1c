//! `firings_vs_libpetri`: firings per second of our mission engine (`armor_model::net::Engine`)
//! against the `libpetri` crate (a coloured time Petri-net engine) on the same two nets:
//!
//! - a chain of 100 transitions passing one token along (100 firings a run);
//! - a 10-branch mission net: a start transition forks into 10 parallel legs of 4 transitions
//!   each, and a join transition waits for all ten (42 firings a run).
//!
//! One run = start an engine in the initial marking and fire until nothing can fire. Both sides
//! compile the net once, outside the timed loop, as the controller does once per mission: ours
//! `CompiledNet::new` then, each run, `Engine::start_compiled` and `step(0.0)`, which fires every
//! transition without condition and returns the firings, each with its marking and the modules
//! started and stopped (what the controller needs); libpetri `OwnedPrecompiledNet::compile` then
//! `run_sync` (its `PrecompiledNetExecutor`), with unit tokens and built-in synchronous actions
//! (`fork`, and `transform` for joins). Beside them, each side compiling the net in every run:
//! ours `Engine::new` + `step`, libpetri's `BitmapNetExecutor::new` + `run_sync`. The reference
//! is the faster of libpetri's two. Each side's final marking is checked.

use std::collections::HashMap;
use std::hint::black_box;
use std::sync::Arc as Shared;
use std::time::{Duration, Instant};

use anyhow::{bail, ensure};
use armor_model::net::{Arc, CompiledNet, Engine, MissionNet, Place, Transition};
use serde_json::json;

use crate::Settings;
use armor_bench_report::{Report, median};

pub const NAME: &str = "firings_vs_libpetri";

/// The chain: `c0 → t0 → c1 → … → t99 → c100`, one token in `c0`.
pub fn chain(length: usize) -> MissionNet {
    let mut net = MissionNet {
        name: format!("chain{length}"),
        ..MissionNet::default()
    };
    for i in 0..=length {
        net.places.push(place(format!("c{i}"), u32::from(i == 0)));
    }
    for i in 0..length {
        net.transitions.push(transition(
            format!("t{i}"),
            &[format!("c{i}")],
            &[format!("c{}", i + 1)],
        ));
    }
    net
}

/// A mission of `branches` parallel legs of `legs` transitions each, between a fork and a join.
pub fn branches(branches: usize, legs: usize) -> MissionNet {
    let mut net = MissionNet {
        name: format!("branches{branches}"),
        ..MissionNet::default()
    };
    net.places.push(place("start".to_owned(), 1));
    net.places.push(place("done".to_owned(), 0));
    let mut firsts = Vec::new();
    let mut lasts = Vec::new();
    for b in 0..branches {
        for j in 0..=legs {
            net.places.push(place(format!("b{b}_{j}"), 0));
        }
        for j in 0..legs {
            net.transitions.push(transition(
                format!("leg{b}_{j}"),
                &[format!("b{b}_{j}")],
                &[format!("b{b}_{}", j + 1)],
            ));
        }
        firsts.push(format!("b{b}_0"));
        lasts.push(format!("b{b}_{legs}"));
    }
    net.transitions.push(transition(
        "fork".to_owned(),
        &["start".to_owned()],
        &firsts,
    ));
    net.transitions
        .push(transition("join".to_owned(), &lasts, &["done".to_owned()]));
    net
}

fn place(name: String, tokens: u32) -> Place {
    Place {
        name,
        tokens,
        ..Place::default()
    }
}

fn transition(name: String, inputs: &[String], outputs: &[String]) -> Transition {
    let arcs = |places: &[String]| {
        places
            .iter()
            .map(|place| Arc {
                place: place.clone(),
                weight: 1,
                ..Arc::default()
            })
            .collect()
    };
    Transition {
        name,
        inputs: arcs(inputs),
        outputs: arcs(outputs),
        ..Transition::default()
    }
}

/// Our engine on a net compiled beforehand: one run, returning the firings.
fn ours_once(net: &Shared<CompiledNet>) -> usize {
    let mut engine = Engine::start_compiled(net, 0.0);
    engine.step(0.0).len()
}

/// The same net for libpetri, with the places to seed and to check.
struct Peer {
    net: libpetri::PetriNet,
    places: HashMap<String, libpetri::Place<()>>,
    initial: Vec<(String, u32)>,
}

impl Peer {
    fn new(net: &MissionNet) -> anyhow::Result<Peer> {
        let places: HashMap<String, libpetri::Place<()>> = net
            .places
            .iter()
            .map(|place| {
                (
                    place.name.clone(),
                    libpetri::Place::new(place.name.as_str()),
                )
            })
            .collect();
        let get = |name: &str| match places.get(name) {
            Some(place) => Ok(place),
            None => bail!("an arc to no place `{name}`"),
        };
        let mut builder = libpetri::PetriNet::builder(net.name.as_str());
        for transition in &net.transitions {
            let mut t = libpetri::Transition::builder(transition.name.as_str());
            for arc in &transition.inputs {
                ensure!(arc.weight == 1, "weights other than 1 are not translated");
                t = t.input(libpetri::one(get(&arc.place)?));
            }
            let mut outputs = Vec::new();
            for arc in &transition.outputs {
                ensure!(arc.weight == 1, "weights other than 1 are not translated");
                outputs.push(libpetri::out_place(get(&arc.place)?));
            }
            match outputs.len() {
                0 => {}
                1 => t = t.output(outputs.remove(0)),
                _ => t = t.output(libpetri::and(outputs)),
            }
            let action = if transition.inputs.len() == 1 {
                libpetri::fork()
            } else {
                libpetri::transform(|_| Shared::new(()))
            };
            builder = builder.transition(t.action(action).build());
        }
        Ok(Peer {
            net: builder.build(),
            initial: net
                .places
                .iter()
                .filter(|place| place.tokens > 0)
                .map(|place| (place.name.clone(), place.tokens))
                .collect(),
            places,
        })
    }

    fn marking(&self) -> libpetri::Marking {
        let mut marking = libpetri::Marking::new();
        for (name, tokens) in &self.initial {
            if let Some(place) = self.places.get(name) {
                for _ in 0..*tokens {
                    marking.add(place, libpetri::Token::at((), 0));
                }
            }
        }
        marking
    }
}

struct Net {
    label: &'static str,
    net: MissionNet,
    /// Firings of one run, and the place that must hold the token at the end.
    firings: usize,
    last: &'static str,
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let (rounds, round_time) = if settings.quick {
        (1, Duration::from_millis(20))
    } else {
        (5, Duration::from_millis(300))
    };
    let nets = [
        Net {
            label: "chain_100",
            net: chain(100),
            firings: 100,
            last: "c100",
        },
        Net {
            label: "branches_10",
            net: branches(10, 4),
            firings: 42,
            last: "done",
        },
    ];
    let mut detail = Vec::new();
    let mut ours_all = Vec::new();
    let mut peer_all = Vec::new();
    for net in &nets {
        let peer = Peer::new(&net.net)?;
        let program = libpetri::OwnedPrecompiledNet::compile(&peer.net);
        // Both sides play the whole net.
        let mut engine = Engine::new(&net.net);
        let fired = engine.step(0.0).len();
        ensure!(
            fired == net.firings && engine.tokens(net.last) == 1,
            "{}: our engine fired {fired} transitions",
            net.label
        );
        let end = program.run_sync::<libpetri::NoopEventStore>(peer.marking());
        ensure!(
            end.count(net.last) == 1,
            "{}: libpetri (precompiled) ended without a token in {}",
            net.label,
            net.last
        );
        let mut bitmap = libpetri::BitmapNetExecutor::<libpetri::NoopEventStore>::new(
            &peer.net,
            peer.marking(),
            libpetri::ExecutorOptions::default(),
        );
        ensure!(
            bitmap.run_sync().count(net.last) == 1,
            "{}: libpetri (bitmap) ended without a token in {}",
            net.label,
            net.last
        );
        let compiled = Shared::new(CompiledNet::new(&net.net));
        let (mut ours, mut precompiled, mut bitmap) = (Vec::new(), Vec::new(), Vec::new());
        let (mut ours_compiling, mut ours_compile) = (Vec::new(), Vec::new());
        for _ in 0..rounds {
            ours.push(rate(round_time, net.firings, || {
                black_box(ours_once(black_box(&compiled)));
            }));
            precompiled.push(rate(round_time, net.firings, || {
                black_box(program.run_sync::<libpetri::NoopEventStore>(peer.marking()));
            }));
            // Compiling in every run (`Engine::new`), against libpetri's bitmap executor; and
            // compiling alone (`CompiledNet::new`, in runs per second).
            ours_compiling.push(rate(round_time, net.firings, || {
                black_box(Engine::new(black_box(&net.net)).step(0.0));
            }));
            ours_compile.push(rate(round_time, 1, || {
                black_box(CompiledNet::new(black_box(&net.net)));
            }));
            bitmap.push(rate(round_time, net.firings, || {
                let mut executor = libpetri::BitmapNetExecutor::<libpetri::NoopEventStore>::new(
                    black_box(&peer.net),
                    peer.marking(),
                    libpetri::ExecutorOptions::default(),
                );
                black_box(executor.run_sync());
            }));
        }
        let (ours, precompiled, bitmap) = (median(&ours), median(&precompiled), median(&bitmap));
        let best = precompiled.max(bitmap);
        let (ours_compiling, ours_compile) = (median(&ours_compiling), median(&ours_compile));
        detail.push(json!({
            "net": net.label,
            "firings_per_run": net.firings,
            "ours": crate::round4(ours),
            "ours_compiling_each_run": crate::round4(ours_compiling),
            "ours_compile_us": crate::round4(1e6 / ours_compile),
            "libpetri_precompiled": crate::round4(precompiled),
            "libpetri_bitmap": crate::round4(bitmap),
            "ratio": crate::round4(ours / best),
        }));
        ours_all.push(ours);
        peer_all.push(best);
    }
    // The headline: geometric means over the two nets.
    let geo =
        |values: &[f64]| (values.iter().map(|v| v.ln()).sum::<f64>() / values.len() as f64).exp();
    Ok(
        Report::single(NAME, "firings/s", geo(&ours_all), geo(&peer_all))
            .with("goal", ">= 1x libpetri")
            .with(
                "reference_is",
                "libpetri 11 (crates.io), the faster of its two executors; both sides compile \
                 the net once; geometric mean of the two nets",
            )
            .with("nets", detail),
    )
}

/// Firings per second of `once` (which fires `firings`), repeated for at least `time`.
fn rate(time: Duration, firings: usize, mut once: impl FnMut()) -> f64 {
    let start = Instant::now();
    let mut runs = 0usize;
    loop {
        once();
        runs += 1;
        let elapsed = start.elapsed();
        if elapsed >= time {
            return (runs * firings) as f64 / elapsed.as_secs_f64();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_engines_play_both_nets_to_the_end() {
        for (net, firings, last) in [(chain(100), 100, "c100"), (branches(10, 4), 42, "done")] {
            assert_eq!(ours_once(&Shared::new(CompiledNet::new(&net))), firings);
            let peer = Peer::new(&net).expect("translate");
            let program = libpetri::OwnedPrecompiledNet::compile(&peer.net);
            let end = program.run_sync::<libpetri::NoopEventStore>(peer.marking());
            assert_eq!(end.count(last), 1);
        }
    }
}
