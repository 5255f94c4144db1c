//! PNML written by another tool: pm4py (the most used Python process-mining and Petri-net
//! library, `pip install pm4py`, installed by `scripts/test`) writes P/T nets as the PNML core model
//! (`pnmlcoremodel`) with markings, inscriptions and a `<finalmarkings>` element. `armor import`
//! reads them with a warning; the mission it writes has the same places, initial marking, arcs
//! and weights as pm4py's own net, its final marking as final places, and passes `armor check`'s
//! analysis (the net's structure).
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::process::Command;

use armor_model::MissionNet;
use armor_tests::bin;
use serde_json::Value;

/// Writes two nets with pm4py into `argv[1]` (a folder): `hand.pnml`, built by hand with a
/// weighted arc and a silent transition, and `discovered.pnml`, discovered by the inductive
/// miner from a small event log (transition ids are UUIDs there). Prints JSON: for each, the
/// places (name -> initial tokens), the final places, and the arcs as
/// `[source label, target label, weight]`, with transitions by label (or name if silent).
const PM4PY: &str = r#"
import json, sys, os
import pandas as pd
import pm4py
from pm4py.objects.petri_net.obj import PetriNet, Marking
from pm4py.objects.petri_net.utils import petri_utils

folder = sys.argv[1]

def describe(net, im, fm):
    label = lambda node: node.name if isinstance(node, PetriNet.Place) else (node.label or node.name)
    return {
        "places": {p.name: im[p] for p in net.places},
        "final": sorted(p.name for p in fm),
        "arcs": sorted([label(a.source), label(a.target), a.weight] for a in net.arcs),
        "transitions": len(net.transitions),
    }

net = PetriNet("order flow")
source, waiting, sink = PetriNet.Place("source"), PetriNet.Place("waiting"), PetriNet.Place("sink")
for p in (source, waiting, sink):
    net.places.add(p)
register = PetriNet.Transition("t1", "register request")
silent = PetriNet.Transition("tau_1", None)
net.transitions.update([register, silent])
petri_utils.add_arc_from_to(source, register, net)
petri_utils.add_arc_from_to(register, waiting, net, weight=2)
petri_utils.add_arc_from_to(waiting, silent, net, weight=2)
petri_utils.add_arc_from_to(silent, sink, net)
im, fm = Marking(), Marking()
im[source] = 2
fm[sink] = 1
pm4py.write_pnml(net, im, fm, os.path.join(folder, "hand.pnml"))

log = pd.DataFrame({
    "case:concept:name": ["1", "1", "1", "2", "2", "2", "3", "3"],
    "concept:name": ["check", "pack", "ship", "check", "ship", "pack", "check", "cancel"],
    "time:timestamp": pd.to_datetime([
        "2026-01-01 10:00", "2026-01-01 11:00", "2026-01-01 12:00",
        "2026-01-02 10:00", "2026-01-02 11:00", "2026-01-02 12:00",
        "2026-01-03 10:00", "2026-01-03 11:00",
    ]),
})
dnet, dim, dfm = pm4py.discover_petri_net_inductive(log)
pm4py.write_pnml(dnet, dim, dfm, os.path.join(folder, "discovered.pnml"))

print(json.dumps({"hand": describe(net, im, fm), "discovered": describe(dnet, dim, dfm)}))
"#;

/// A net as the test compares it: places with their initial tokens, final places, and arcs as
/// (from, to, weight).
type Described = (
    BTreeMap<String, u32>,
    Vec<String>,
    Vec<(String, String, u32)>,
);

/// The same description of the mission `armor import` wrote, with each transition by the label
/// pm4py gave it: the name ArMoR made of it, so compared after the same making.
fn described(net: &MissionNet) -> Described {
    let places = net
        .places
        .iter()
        .map(|place| (place.name.clone(), place.tokens))
        .collect();
    let finals = net
        .places
        .iter()
        .filter(|place| place.is_final)
        .map(|place| place.name.clone())
        .collect();
    let mut arcs = Vec::new();
    for transition in &net.transitions {
        for arc in &transition.inputs {
            arcs.push((arc.place.clone(), transition.name.clone(), arc.weight));
        }
        for arc in &transition.outputs {
            arcs.push((transition.name.clone(), arc.place.clone(), arc.weight));
        }
    }
    arcs.sort();
    (places, finals, arcs)
}

/// A pm4py label as `armor import` names it (see `as_name` in `net/pnml.rs`).
fn as_name(label: &str) -> String {
    let name: String = label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if name.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
        name
    } else {
        format!("t_{name}")
    }
}

#[test]
fn nets_written_by_pm4py_import_with_their_markings_weights_and_final_places() {
    let dir = tempfile::tempdir().unwrap();
    let output = armor_tests::tools::python3(&["pm4py"])
        .arg("-c")
        .arg(PM4PY)
        .arg(dir.path())
        .output()
        .unwrap_or_else(|err| panic!("cannot run python3: {err}"));
    assert!(
        output.status.success(),
        "pm4py could not write the nets:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    // pm4py prints a banner on stdout before our line.
    let stdout = String::from_utf8_lossy(&output.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|line| line.starts_with('{'))
        .unwrap();
    let expected: Value = serde_json::from_str(line).unwrap();

    for name in ["hand", "discovered"] {
        let pnml = dir.path().join(format!("{name}.pnml"));
        let mission = dir.path().join(format!("{name}.xml"));
        let import = Command::new(bin("armor"))
            .arg("import")
            .arg(&pnml)
            .arg("-o")
            .arg(&mission)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&import.stderr);
        assert!(import.status.success(), "{name}: {stderr}");
        assert!(
            stderr.contains(&format!("{}:3:", pnml.display()))
                && stderr
                    .contains("warning: a `pnmlcoremodel` net, read as a place/transition net"),
            "{name}: {stderr}"
        );
        let net = MissionNet::parse(&std::fs::read_to_string(&mission).unwrap()).unwrap();
        let (places, finals, arcs) = described(&net);

        let want = &expected[name];
        let want_places: BTreeMap<String, u32> = want["places"]
            .as_object()
            .unwrap()
            .iter()
            .map(|(place, tokens)| (as_name(place), tokens.as_u64().unwrap() as u32))
            .collect();
        assert_eq!(places, want_places, "{name}: places and initial marking");
        let want_finals: Vec<String> = want["final"]
            .as_array()
            .unwrap()
            .iter()
            .map(|place| as_name(place.as_str().unwrap()))
            .collect();
        assert_eq!(finals, want_finals, "{name}: final places");
        assert_eq!(
            net.transitions.len() as u64,
            want["transitions"].as_u64().unwrap(),
            "{name}: transitions"
        );
        // Transitions with the same label get `-2`, `-3`...: compare without the suffix.
        let base = |name: &str| {
            name.rsplit_once('-')
                .filter(|(_, n)| n.parse::<u32>().is_ok())
                .map_or(name.to_owned(), |(base, _)| base.to_owned())
        };
        let mut got: Vec<(String, String, u32)> = arcs
            .into_iter()
            .map(|(from, to, weight)| (base(&from), base(&to), weight))
            .collect();
        got.sort();
        let mut want_arcs: Vec<(String, String, u32)> = want["arcs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|arc| {
                (
                    as_name(arc[0].as_str().unwrap()),
                    as_name(arc[1].as_str().unwrap()),
                    arc[2].as_u64().unwrap() as u32,
                )
            })
            .collect();
        want_arcs.sort();
        assert_eq!(got, want_arcs, "{name}: arcs and weights");

        // The net itself is sound enough for the analysis: `armor check` says only that it
        // names no system.
        let check = Command::new(bin("armor"))
            .arg("check")
            .arg(&mission)
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&check.stderr).into_owned()
            + &String::from_utf8_lossy(&check.stdout);
        let problems: Vec<&str> = said
            .lines()
            .filter(|line| line.starts_with(&mission.display().to_string()))
            .collect();
        assert_eq!(problems.len(), 1, "{name}: {said}");
        assert!(
            problems[0].contains("names no system file"),
            "{name}: {said}"
        );
    }
}
