//! Subsystems in the System view, driven as a user would: blocks selected and grouped with
//! Ctrl+G, the group drawn as one block with the crossing link's port on its border, opened
//! by a double click, left by the breadcrumb, saved as `<subsystem>` in the system file and
//! reopened equal; ungrouped again with Ctrl+Shift+G.
#![allow(clippy::unwrap_used)]

mod common;

use armor_model::SystemConfig;
use armor_studio::system::diagram::PinSide;
use common::*;
use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable as _;

const SYSTEM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="counting">
  <module name="counter" type="counter"/>
  <module name="checker" type="checker"/>
  <module name="follower" type="follower">
    <param name="goal_x_m" value="1"/>
    <param name="goal_y_m" value="2"/>
  </module>
  <link from="counter.count" to="checker.input"/>
</system>
<!-- armor-studio layout: counter=40,40 checker=400,40 follower=40,300 -->
"#;

fn descriptions() -> std::collections::BTreeMap<String, armor_module_api::ModuleDescription> {
    common::descriptions()
        .into_iter()
        .map(|description| (description.module_type.clone(), description))
        .collect()
}

#[test]
fn select_group_open_go_up_save_and_reopen_equal() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("counting.xml");
    std::fs::write(&file, SYSTEM).unwrap();
    let mut harness = harness(options(&dir.path().join("home"), Some(file.clone())));
    harness.run();

    // Select the checker and the follower (Shift-clicks), group them.
    for block in ["checker", "follower"] {
        let at = harness.state().block_header_pos(block).unwrap();
        shift_click(&mut harness, at);
    }
    assert_eq!(harness.state().editor().selection.len(), 2);
    harness.key_press_modifiers(Modifiers::COMMAND, Key::G);
    harness.run();
    harness.run_steps(4);
    harness.run();
    {
        let diagram = &harness.state().editor().diagram;
        let groups: Vec<_> = diagram.groups().collect();
        assert_eq!(groups.len(), 1, "one group");
        let (_, group) = groups[0];
        assert_eq!(group.name, "subsystem");
        assert_eq!(group.members.len(), 2);
        let ports: Vec<&str> = group.ports.iter().map(|(name, _)| name.as_str()).collect();
        assert_eq!(
            ports,
            ["input"],
            "the link from outside crosses its border there"
        );
    }
    // The group is one block; its members are not drawn at the top.
    assert!(shown(&harness, "subsystem"), "{} is drawn", "subsystem");
    harness.get_by_label("subsystem · double-click to open");
    assert!(!shown(&harness, "checker"));
    assert!(!shown(&harness, "follower"));
    // The wire from the counter ends on the group's port.
    assert!(
        harness
            .state()
            .pin_pos("subsystem", "input", PinSide::Input)
            .is_some()
    );
    harness.get_by_label_contains("Ctrl+G groups the selection");

    // A double click opens it: its members are drawn, the breadcrumb says where we are.
    let at = harness.state().block_header_pos("subsystem").unwrap();
    open_by_double_click(&mut harness, at);
    assert!(harness.state().editor().level.is_some(), "opened");
    assert!(shown(&harness, "checker"), "{} is drawn", "checker");
    assert!(shown(&harness, "follower"), "{} is drawn", "follower");
    assert!(!shown(&harness, "counter"));
    harness.get_by_label("›");
    harness.get_by_label_contains("ports on its border: input");
    // Its border's input, linked to the member's port it exposes.
    assert!(shown(&harness, "inputs"));
    assert!(
        harness
            .state()
            .pin_pos("subsystem inputs", "input", PinSide::Output)
            .is_some()
    );

    // Up by the breadcrumb.
    // (The view's tab is a button called System too; the breadcrumb's is a link.)
    harness
        .get_by_role_and_label(egui::accesskit::Role::Label, "System")
        .click();
    settle(&mut harness);
    assert!(harness.state().editor().level.is_none(), "back at the top");
    assert!(shown(&harness, "counter"), "{} is drawn", "counter");
    assert!(shown(&harness, "subsystem"), "{} is drawn", "subsystem");

    // Saved: a <subsystem> in the system file, which armor check's checks accept.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::S);
    harness.run();
    let text = std::fs::read_to_string(&file).unwrap();
    let system = SystemConfig::parse(&text).unwrap();
    assert_eq!(system.subsystems.len(), 1, "{text}");
    let subsystem = &system.subsystems[0];
    assert_eq!(subsystem.name, "subsystem");
    assert_eq!(subsystem.modules(), ["checker", "follower"]);
    assert_eq!(subsystem.ports[0].of.to_string(), "checker.input");
    assert!(armor_model::system::check(&system, &descriptions()).is_empty());
    assert!(
        text.contains("subsystem="),
        "its place in the layout: {text}"
    );

    // Reopened: the same document.
    let saved = harness.state().editor().diagram.clone();
    let again = harness_for(&dir, &file);
    assert_eq!(again.state().editor().diagram, saved);
    assert!(shown(&again, "subsystem"));

    // Ungrouped (Ctrl+Shift+G on the selected group): its blocks are back, and undo regroups.
    let at = harness.state().block_header_pos("subsystem").unwrap();
    click(&mut harness, at);
    harness.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::G);
    settle(&mut harness);
    assert_eq!(harness.state().editor().diagram.groups().count(), 0);
    assert!(shown(&harness, "checker"), "{} is drawn", "checker");
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    harness.run();
    assert_eq!(harness.state().editor().diagram.groups().count(), 1);
}

/// A double click, then the frames the canvas takes to show and fit the level opened.
fn open_by_double_click(
    harness: &mut egui_kittest::Harness<'_, armor_studio::StudioApp>,
    at: egui::Pos2,
) {
    harness.run_steps(60);
    harness.hover_at(at);
    for _ in 0..2 {
        for pressed in [true, false] {
            harness.event(egui::Event::PointerButton {
                pos: at,
                button: egui::PointerButton::Primary,
                pressed,
                modifiers: Modifiers::NONE,
            });
        }
    }
    settle(harness);
}

/// The frames the canvas takes to show a level and fit it; then nothing moves any more.
fn settle(harness: &mut egui_kittest::Harness<'_, armor_studio::StudioApp>) {
    harness.run_steps(10);
    harness.run();
}

fn shift_click(harness: &mut egui_kittest::Harness<'_, armor_studio::StudioApp>, at: egui::Pos2) {
    harness.hover_at(at);
    harness.event(egui::Event::ModifiersChanged(Modifiers::SHIFT));
    harness.step();
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton {
            pos: at,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: Modifiers::SHIFT,
        });
        harness.step();
    }
    harness.event(egui::Event::ModifiersChanged(Modifiers::NONE));
    harness.run();
}

/// Whether a block of that name is drawn (the palette lists the module types of
/// [`common::descriptions`] under their names too).
fn shown(harness: &egui_kittest::Harness<'_, armor_studio::StudioApp>, name: &str) -> bool {
    let in_palette = usize::from(["counter", "checker", "follower"].contains(&name));
    harness.query_all_by_label(name).count() > in_palette
}

fn harness_for(
    dir: &tempfile::TempDir,
    file: &std::path::Path,
) -> egui_kittest::Harness<'static, armor_studio::StudioApp> {
    let mut harness = harness(options(&dir.path().join("home2"), Some(file.to_path_buf())));
    harness.run();
    harness
}

#[test]
fn the_bundled_behaviours_open_as_one_navigation_block() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let file = root.join("missions/robot/system-behaviours.xml");
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(dir.path(), Some(file)));
    harness.run();
    assert!(shown(&harness, "navigation"), "{} is drawn", "navigation");
    assert!(!shown(&harness, "vff"));
    let at = harness.state().block_header_pos("navigation").unwrap();
    open_by_double_click(&mut harness, at);
    for member in ["follower", "vff", "stop", "arbiter"] {
        assert!(shown(&harness, member), "{} is drawn", member);
    }
    harness.key_press_modifiers(Modifiers::ALT, Key::ArrowUp);
    settle(&mut harness);
    assert!(harness.state().editor().level.is_none());
}
