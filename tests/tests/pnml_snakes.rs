//! The PNML export is standard: SNAKES, a Python Petri net library that has never seen ArMoR
//! (`pip install snakes`), loads it with `snakes.pnml.loads` (place/transition nets need no
//! plugin; it skips our `<toolspecific>` data) and finds the same initial marking, the same
//! enabled transitions, the same markings after the same firings, and for the dining
//! philosophers the same number of reachable markings.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;

use armor_model::{Engine, MissionNet, analyse, dining_philosophers, from_pnml, to_pnml};
use serde_json::{Value, json};

/// Loads the PNML file `argv[1]`, fires the transitions `argv[2]` (comma-separated, may be
/// empty) and prints JSON: the net's name, then for the initial marking and after each firing
/// the marking (places with tokens) and the enabled transitions; with `argv[3]`, the number of
/// reachable markings.
const SNAKES: &str = r#"
import json, sys
import snakes.pnml
from snakes.nets import StateGraph

net = snakes.pnml.loads(open(sys.argv[1]).read())

def state():
    marking = {place: len(tokens) for place, tokens in net.get_marking().items()}
    enabled = sorted(t.name for t in net.transition() if t.modes())
    return {"marking": marking, "enabled": enabled}

result = {"name": net.name, "states": [state()]}
for name in filter(None, sys.argv[2].split(",")):
    transition = net.transition(name)
    transition.fire(transition.modes()[0])
    result["states"].append(state())
if len(sys.argv) > 3:
    graph = StateGraph(net)
    graph.build()
    result["reachable"] = len(graph)
print(json.dumps(result))
"#;

fn snakes(pnml: &str, firings: &[&str], count_reachable: bool) -> Value {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("net.pnml");
    std::fs::write(&path, pnml).unwrap();
    let mut command = armor_tests::tools::python3(&["snakes.pnml"]);
    command
        .arg("-c")
        .arg(SNAKES)
        .arg(&path)
        .arg(firings.join(","));
    if count_reachable {
        command.arg("count");
    }
    let output = command
        .output()
        .unwrap_or_else(|err| panic!("cannot run python3: {err}"));
    assert!(
        output.status.success(),
        "SNAKES could not read the export:\n{}\n{pnml}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    let last = stdout.lines().last().unwrap_or_default();
    serde_json::from_str(last).unwrap_or_else(|err| panic!("{err}: {stdout}"))
}

/// The marking and enabled transitions as the Python side prints them.
fn state(engine: &Engine) -> Value {
    let marking: BTreeMap<String, u32> = engine.marking();
    let mut enabled = engine.enabled();
    enabled.sort();
    json!({ "marking": marking, "enabled": enabled })
}

const MISSION: &str = r#"<mission name="delivery" system="system.xml">
  <place name="ready" tokens="1">
    <module name="nav"/>
    <param module="nav" name="goal_x" value="3 &amp; &lt;4&gt;"/>
  </place>
  <place name="batteries" tokens="2"/>
  <place name="moving"><module name="nav"/><module name="sim"/></place>
  <place name="aborted" final="true"/>
  <place name="done" final="true"/>
  <transition name="go" priority="1" event="nav.start">
    <input place="ready"/>
    <input place="batteries" weight="2"/>
    <output place="moving"/>
  </transition>
  <transition name="abort" at="2026-11-22T20:00:00Z">
    <input place="ready"/>
    <output place="aborted"/>
  </transition>
  <transition name="arrive" delay_secs="2.5">
    <input place="moving"/>
    <output place="done"/>
    <output place="batteries" weight="3"/>
  </transition>
</mission>"#;

#[test]
fn snakes_reads_the_export_of_a_mission_with_a_conflict() {
    let net = MissionNet::parse(MISSION).unwrap();
    let pnml = to_pnml(&net);
    let firings = ["go", "arrive"];
    let got = snakes(&pnml, &firings, false);

    let mut engine = Engine::new(&net);
    let mut expected = vec![state(&engine)];
    // `go` and `abort` compete for the token of `ready`.
    assert_eq!(expected[0]["enabled"], json!(["abort", "go"]));
    for transition in firings {
        engine.fire_by_hand(transition, 0.0).unwrap();
        expected.push(state(&engine));
    }
    assert_eq!(got, json!({ "name": "delivery", "states": expected }));
    assert_eq!(
        got["states"][2]["marking"],
        json!({ "batteries": 3, "done": 1 })
    );
    // And what SNAKES ignores comes back from our own reader.
    assert_eq!(
        from_pnml(&pnml).unwrap().without_positions(),
        net.without_positions()
    );
}

#[test]
fn snakes_counts_the_same_reachable_markings() {
    for n in [3, 5] {
        let net = dining_philosophers(n);
        let got = snakes(&to_pnml(&net), &["take_left_0", "take_left_1"], true);
        let analysis = analyse(&net, 100_000);
        assert_eq!(got["reachable"], json!(analysis.states), "{n} philosophers");
        let mut engine = Engine::new(&net);
        assert_eq!(got["states"][0], state(&engine));
        engine.fire_by_hand("take_left_0", 0.0).unwrap();
        engine.fire_by_hand("take_left_1", 0.0).unwrap();
        assert_eq!(got["states"][2], state(&engine));
    }
}
