//! Subsystems, as a user meets them: `armor check` refuses wrong ones with their positions,
//! and `armor run` runs a system that has them (the same modules and links as without) with a
//! mission whose place names a subsystem for all its modules.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::time::Duration;

use armor_tests::check::{armor, assert_refused, line_of, located, output_text};
use armor_tests::mission::run_mission;

const SYSTEM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="grouped">
  <module name="counter" type="counter" activation="explicit">
    <param name="period_secs" value="0.05"/>
    <param name="limit" value="5"/>
  </module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
  <subsystem name="counting">
    <member module="counter"/>
    <subsystem name="checking">
      <member module="checker"/>
    </subsystem>
    <port name="count" of="counter.count"/>
  </subsystem>
</system>
"#;

/// Counts to five with a place that names the subsystem `counting` (the counter and, nested,
/// the checker), then settles with the checker alone.
const MISSION: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<mission name="grouped-count" system="system.xml">
  <place name="counting" tokens="1">
    <module name="counting"/>
  </place>
  <place name="done" final="true"/>
  <transition name="counted" event="counter.done">
    <input place="counting"/>
    <output place="done"/>
  </transition>
</mission>
"#;

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let file = dir.join(name);
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn a_system_with_subsystems_is_checked_clean_and_its_mission_runs_a_subsystem_as_a_whole() {
    let dir = tempfile::tempdir().unwrap();
    let system = write(dir.path(), "system.xml", SYSTEM);
    let mission = write(dir.path(), "mission.xml", MISSION);
    for file in [&system, &mission] {
        let output = armor(&["check".as_ref(), file.as_os_str()]);
        assert!(output.status.success(), "{}", output_text(&output));
    }
    // The place names the subsystem: the counter runs (wanted by the place), counts to five
    // and reports done; the checker, in the nested subsystem, runs wanted too.
    let finished = run_mission(&mission, &[], Duration::from_secs(60));
    assert_eq!(finished.fired_names(), ["counted"]);
    let timeline = finished.report["timeline"].as_array().unwrap();
    let wanted = timeline.iter().any(|entry| {
        entry["kind"] == "demand"
            && entry["running"]["counter"] == "place counting"
            && entry["running"]["checker"] == "place counting"
    });
    assert!(wanted, "{timeline:#?}");
}

#[test]
fn armor_check_refuses_wrong_subsystems_where_they_are() {
    let dir = tempfile::tempdir().unwrap();
    let text = SYSTEM
        .replace(
            r#"    <member module="counter"/>"#,
            r#"    <member module="counter"/>
    <member module="ghost"/>"#,
        )
        .replace(
            r#"      <member module="checker"/>"#,
            r#"      <member module="checker"/>
      <member module="counter"/>"#,
        )
        .replace(
            r#"<port name="count" of="counter.count"/>"#,
            r#"<port name="count" of="counter.nothing"/>
    <port name="outside" of="sink.input"/>"#,
        )
        .replace(
            "</system>",
            r#"  <subsystem name="checker"><member module="checker"/></subsystem>
</system>"#,
        );
    let file = write(dir.path(), "bad.xml", &text);
    let output = armor(&["check".as_ref(), file.as_os_str()]);
    assert_refused(
        &output,
        &file,
        line_of(&text, "ghost"),
        &["no module `ghost`"],
    );
    let nested_counter = text
        .lines()
        .enumerate()
        .filter(|(_, line)| line.contains(r#"<member module="counter"/>"#))
        .map(|(index, _)| index + 1)
        .nth(1)
        .unwrap();
    assert_refused(
        &output,
        &file,
        nested_counter,
        &["module `counter` is already a member of `counting`"],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, "counter.nothing"),
        &["has no port `nothing`"],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, "sink.input"),
        &["module `sink` is not in the subsystem"],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, r#"<subsystem name="checker">"#),
        &["a module has that name"],
    );
    // A syntax error in a subsystem: its line and column.
    let broken = SYSTEM.replace(
        r#"<member module="checker"/>"#,
        r#"<member modul="checker"/>"#,
    );
    let file = write(dir.path(), "broken.xml", &broken);
    let output = armor(&["check".as_ref(), file.as_os_str()]);
    assert_refused(
        &output,
        &file,
        line_of(&broken, "modul="),
        &["<member> needs the attribute `module`"],
    );
    assert!(located(&output, &file).iter().all(|(_, col, _)| *col > 0));
}
