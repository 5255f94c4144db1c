//! Pictures of the main view, rendered in software (Mesa's lavapipe): the diagram as a user
//! sees it, and a wire being dragged with its legal targets lit. A changed pixel fails the test
//! and writes a diff image beside the snapshot.
#![allow(clippy::unwrap_used)]

mod common;

use armor_studio::StudioApp;
use armor_studio::diagram::PinSide;
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

#[test]
fn the_diagram_exports_as_a_png_picture() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = rendering_harness(dir.path());
    let picture = dir.path().join("diagram.png");
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label("Export PNG…").click();
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
    let bytes = std::fs::read(&picture).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    // The canvas, not the window: narrower than the 1280-point window, at least 400 wide.
    let width = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let height = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    assert!(
        (400..1280).contains(&width) && height >= 300,
        "{width}x{height}"
    );
    harness.get_by_label_contains("exported");
}
