//! Pictures of the main view, rendered in software (Mesa's lavapipe): the diagram as a user
//! sees it, and a wire being dragged with its legal targets lit. A changed pixel fails the test
//! and writes a diff image beside the snapshot.
#![allow(clippy::unwrap_used)]

mod common;

use armor_studio::StudioApp;
use armor_studio::system::diagram::PinSide;
use common::*;
use egui::Pos2;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

const SYSTEM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="demo">
  <module name="counter" type="counter">
    <param name="period_secs" value="0.5"/>
  </module>
  <module name="checker" type="checker"/>
  <module name="second" type="checker"/>
  <module name="follower" type="follower"/>
  <link from="counter.count" to="checker.input"/>
</system>
<!-- armor-studio layout: counter=0,0 checker=260,-60 second=260,80 follower=0,160 -->
"#;

fn rendering_harness(dir: &std::path::Path) -> Harness<'static, StudioApp> {
    let file = dir.join("demo.xml");
    std::fs::write(&file, SYSTEM).unwrap();
    let mut harness = Harness::builder()
        .with_size(SIZE)
        .with_step_dt(1.0 / 60.0)
        .wgpu()
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options(&dir.join("home"), Some(file))),
        );
    harness.run();
    harness
}

/// The status line names the temporary folder: hide it from the picture.
fn mask_status(harness: &mut Harness<'_, StudioApp>) {
    // The whole line: the width of the random folder name varies with its letters.
    let label = harness.get_by_label_contains("opened").rect();
    let rect = egui::Rect::from_min_max(label.min, egui::pos2(SIZE[0], label.max.y));
    harness.mask(rect);
}

#[test]
fn main_view() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = rendering_harness(dir.path());
    mask_status(&mut harness);
    harness.snapshot("main_view");
}

#[test]
fn dragging_a_wire_lights_its_legal_targets() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = rendering_harness(dir.path());
    let from = pin(&harness, "counter", "count", PinSide::Output);
    drag_holding(&mut harness, from, Pos2::new(from.x + 90.0, from.y + 60.0));
    harness.run();
    mask_status(&mut harness);
    harness.snapshot("wire_drag");
}

/// Exports a picture through the File menu item `item` into `picture`; its width and height.
fn export_picture(
    harness: &mut Harness<'_, StudioApp>,
    item: &str,
    picture: &std::path::Path,
) -> (u32, u32) {
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label(item).click();
    harness.run();
    harness.get_by_label("Path:").click();
    harness.run();
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness
        .get_by_label("Path:")
        .type_text(&picture.display().to_string());
    harness.run();
    harness.key_press(egui::Key::Enter);
    harness.run();
    harness.run();
    assert!(picture.exists(), "{}", harness.state().status().text);
    let bytes = std::fs::read(picture).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    let width = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let height = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    (width, height)
}

#[test]
fn the_diagram_exports_as_a_png_picture() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = rendering_harness(dir.path());
    let picture = dir.path().join("diagram.png");
    let (width, height) = export_picture(&mut harness, "Export PNG…", &picture);
    // The canvas, not the window: narrower than the 1280-point window, at least 400 wide.
    assert!(
        (400..1280).contains(&width) && height >= 300,
        "{width}x{height}"
    );
    harness.get_by_label_contains("exported");
}

/// The yard's reconnaissance plan in the Mission view: the map rendered from the world, the
/// route with its appointment and deadline lines, the phase line, the minefield, the symbols,
/// and the net below.
fn plan_harness(dir: &std::path::Path) -> Harness<'static, StudioApp> {
    let plan =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../missions/robot/plan-yard.xml");
    let mut harness = Harness::builder()
        .with_size(SIZE)
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(60)
        .wgpu()
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options(&dir.join("home"), Some(plan))),
        );
    harness.run();
    harness
}

#[test]
fn mission_map_with_a_plan() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = plan_harness(dir.path());
    let mission = harness.state().mission().unwrap();
    assert_eq!(mission.plan().name, "yard-recon");
    assert!(mission.checked().net().is_some());
    mask_status(&mut harness);
    harness.snapshot("mission_map");
}

#[test]
fn the_map_exports_as_a_png_for_a_briefing() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = plan_harness(dir.path());
    let picture = dir.path().join("briefing.png");
    let (width, height) = export_picture(&mut harness, "Export map PNG…", &picture);
    // The map alone: the window less the inspector on the right and the net below.
    let map = harness.state().mission().unwrap().map_rect();
    assert_eq!(
        (width, height),
        (map.width().round() as u32, map.height().round() as u32)
    );
    assert!(width < 1100 && height < 700, "{width}x{height}");
}
