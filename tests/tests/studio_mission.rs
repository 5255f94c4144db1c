//! The studio's Mission view driven as an operator would, through egui_kittest: a plan drawn by
//! clicking on the map of the yard, a wait and an appointment typed into the leg's fields, the
//! compiled net checked, the mission exported, and the exported file run headless by
//! `armor run` to its final place.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::time::Duration;

use armor_model::net::{MissionNet, parse_rfc3339};
use armor_studio::app::View;
use armor_studio::common::palette::Palette;
use armor_studio::files::Home;
use armor_studio::mission::plan_edit::Selection;
use armor_studio::{Options, StudioApp};
use armor_tests::mission::run_mission;
use armor_tests::workspace_root;
use egui::{Key, Modifiers, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

const START: &str = "2026-11-23T10:00:00Z";
const APPOINTMENT: &str = "2026-11-23T10:00:40Z";

fn harness(home: &Path) -> Harness<'static, StudioApp> {
    let mut options = Options::new(Home::new(home));
    options.palette = Some(Palette::from_descriptions(Vec::new()));
    let mut harness = Harness::builder()
        .with_size([1400.0, 900.0])
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(60)
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options),
        );
    harness.run();
    harness
}

fn click(harness: &mut Harness<'_, StudioApp>, at: Pos2) {
    // Apart in time, so that two clicks are never one double click.
    harness.run_steps(30);
    harness.hover_at(at);
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton {
            pos: at,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: Modifiers::NONE,
        });
    }
    harness.run();
}

fn type_into(harness: &mut Harness<'_, StudioApp>, label: &str, text: &str) {
    harness.get_by_label(label).click();
    harness.run();
    harness.get_by_label(label).type_text(text);
    harness.run();
}

/// Where a point of the yard (metres, world frame) is on the screen.
fn on_map(harness: &Harness<'_, StudioApp>, x_m: f64, y_m: f64) -> Pos2 {
    let mission = harness.state().mission().unwrap();
    let at = mission.screen_pos_of_local(x_m, y_m).unwrap();
    assert!(
        mission.map_rect().contains(at),
        "({x_m}, {y_m}) is off the map at {at:?}"
    );
    at
}

#[test]
fn a_plan_clicked_on_the_map_compiles_exports_and_runs_headless() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(&dir.path().join("home"));
    harness.state_mut().set_view(View::Mission);
    harness.run();
    let system = workspace_root().join("missions/robot/system.xml");
    let report = harness
        .state_mut()
        .mission_mut()
        .unwrap()
        .new_plan(Some(&system));
    assert!(report.is_ok(), "{report:?}");
    harness.run();
    let mission = harness.state().mission().unwrap();
    assert!(
        mission.surroundings.world.is_some(),
        "{:?}",
        mission.surroundings.problems
    );

    // The waypoint tool, and three clicks in the yard (the robot starts at 4, 4).
    harness.key_press(Key::W);
    harness.run();
    for (x, y) in [(4.0, 4.0), (12.0, 4.0), (12.0, 14.0)] {
        let at = on_map(&harness, x, y);
        click(&mut harness, at);
    }
    let plan = harness.state().mission().unwrap().plan().clone();
    let names: Vec<&str> = plan.waypoints.iter().map(|w| w.name.as_str()).collect();
    assert_eq!(names, ["wp1", "wp2", "wp3"]);
    let route: Vec<(&str, &str)> = plan
        .legs
        .iter()
        .map(|l| (l.from.as_str(), l.to.as_str()))
        .collect();
    assert_eq!(route, [("wp1", "wp2"), ("wp2", "wp3")]);
    // The clicks landed where they were made, to a few centimetres.
    let origin = harness
        .state()
        .mission()
        .unwrap()
        .surroundings
        .origin(&plan);
    let second = plan.waypoints[1].position.to_local(origin);
    assert!(
        (second.x - 12.0).abs() < 0.1 && (second.y - 4.0).abs() < 0.1,
        "{second:?}"
    );

    // The plan's start, with nothing selected (the select tool, Escape).
    harness.key_press(Key::V);
    harness.key_press(Key::Escape);
    harness.run();
    type_into(&mut harness, "Start", START);
    // The system's commands go through the avoider: it drives with the follower.
    type_into(&mut harness, "Drives with", "avoider");
    assert_eq!(
        harness
            .state()
            .mission()
            .unwrap()
            .plan()
            .navigation
            .companions,
        ["avoider"]
    );

    // The second leg, picked on the map: a wait at its end and an appointment at its start.
    let middle = on_map(&harness, 12.0, 9.0);
    click(&mut harness, middle);
    assert_eq!(
        harness.state().mission().unwrap().editor.selection,
        Selection::Leg(1)
    );
    type_into(&mut harness, "Wait (s)", "3");
    type_into(&mut harness, "Not before", APPOINTMENT);
    let leg = &harness.state().mission().unwrap().plan().legs[1];
    assert_eq!(leg.wait_secs, Some(3.0));
    assert_eq!(
        leg.not_before_unix_secs,
        Some(parse_rfc3339(APPOINTMENT).unwrap())
    );

    // The net: compiled as the plan was drawn, verified, the leg's elements lit.
    let checked = harness.state().mission().unwrap().checked();
    assert!(checked.errors.is_empty(), "{:?}", checked.errors);
    let net = checked.net().unwrap().clone();
    let places: Vec<&str> = net.places.iter().map(|p| p.name.as_str()).collect();
    for expected in ["leg1_drive", "leg2_drive", "done"] {
        assert!(places.contains(&expected), "{places:?}");
    }
    let appointment = net
        .transitions
        .iter()
        .find(|t| t.condition.at_unix_secs == Some(parse_rfc3339(APPOINTMENT).unwrap()))
        .expect("a transition waits for the appointment");
    assert!(appointment.name.starts_with("leg2"), "{}", appointment.name);
    assert!(
        net.transitions
            .iter()
            .any(|t| t.condition.delay_secs == Some(3.0)),
        "the wait is a delay"
    );
    harness.get_by_label_contains("no deadlock");
    harness.get_by_label_contains("every transition can fire");
    let lit = harness.state().mission().unwrap().highlighted();
    assert!(
        lit.iter().all(|name| name.starts_with("leg2")) && !lit.is_empty(),
        "{lit:?}"
    );

    // Export, through the menu and the path field, then save the plan beside it.
    let exported = dir.path().join("clicked.mission.xml");
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label("Export mission XML…").click();
    harness.run();
    harness
        .get_by_label("Path:")
        .type_text(&exported.display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    harness.get_by_label_contains("exported the mission");
    let text = std::fs::read_to_string(&exported).unwrap();
    assert_eq!(
        MissionNet::parse(&text).unwrap().places.len(),
        net.places.len()
    );
    let plan_file = dir.path().join("clicked.plan.xml");
    harness.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::S);
    harness.run();
    harness
        .get_by_label("Path:")
        .type_text(&plan_file.display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    assert!(!harness.state().mission().unwrap().is_dirty());
    let saved =
        armor_model::plan::Plan::parse(&std::fs::read_to_string(&plan_file).unwrap()).unwrap();
    assert_eq!(saved.legs[1].wait_secs, Some(3.0));
    drop(harness);

    // The exported mission runs headless to its final place, keeping the appointment.
    let run = run_mission(&exported, &["--start-at", START], Duration::from_secs(90));
    assert_eq!(
        run.final_marking(),
        serde_json::json!({ "done": 1 }),
        "{:?}",
        run.fired()
    );
    let kept = run
        .fired_at(&appointment.name)
        .expect("the appointment fired");
    assert!(kept >= 40.0 - 0.5, "{kept}: {:?}", run.fired());
}
