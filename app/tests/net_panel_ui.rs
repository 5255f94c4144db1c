//! Issue 37, defect 9: the net panel's net is seen whole at first sight, not cut at the
//! panel's edges.
#![allow(clippy::unwrap_used)]

mod common;

use armor_studio::StudioApp;
use common::{SIZE, options};
use egui_kittest::Harness;

fn robot(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../missions/robot")
        .join(name)
}

fn studio(file: std::path::PathBuf, home: &std::path::Path) -> Harness<'static, StudioApp> {
    let mut harness = Harness::builder()
        .with_size(SIZE)
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(60)
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options(home, Some(file))),
        );
    for _ in 0..3 {
        harness.run();
    }
    harness
}

/// At 1280×800 the yard's net opens whole in its panel, at a zoom its names can be read at:
/// it was cut at the panel's bottom (the rows of `lost`, `retry` and `skip` half seen).
#[test]
fn the_net_is_seen_whole_and_readable_at_first_sight() {
    let dir = tempfile::tempdir().unwrap();
    let harness = studio(robot("plan-yard.xml"), &dir.path().join("home"));
    let mission = harness.state().mission().unwrap();
    let view = mission.net_view();
    let layout = mission.net_layout().unwrap();
    let net = mission.checked().net().unwrap();
    assert!(
        view.zoom >= armor_studio::mission::net_view::READABLE_ZOOM - 1e-3,
        "opens at zoom {}",
        view.zoom
    );
    assert_eq!(
        view.label_boxes.len(),
        net.places.len() + net.transitions.len(),
        "every name drawn"
    );
    let cut: Vec<_> = view
        .label_boxes
        .iter()
        .filter(|label| !view.canvas.contains_rect(**label))
        .collect();
    assert!(
        cut.is_empty(),
        "names cut at the panel's edge {:?}: {cut:?}; the net ({:?} at zoom {}) does not fit",
        view.canvas,
        layout.size,
        view.zoom
    );
    // The map keeps half the height at least.
    let map = mission.map_rect();
    assert!(
        map.height() >= view.canvas.height(),
        "map {map:?}, net {:?}",
        view.canvas
    );
}
