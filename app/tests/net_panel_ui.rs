//! Issue 37, defect 9: the net panel's net is seen whole at first sight, not cut at the
//! panel's edges.
#![allow(clippy::unwrap_used)]

mod common;

use armor_studio::StudioApp;
use common::{robot_file as robot, studio_on as studio};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

/// At 1280×800 the yard's net opens whole in its panel, at a zoom its names can be read at:
/// it was cut at the panel's bottom (the rows of `lost`, `retry` and `skip` half seen).
#[test]
fn the_net_is_seen_whole_and_readable_at_first_sight() {
    let dir = tempfile::tempdir().unwrap();
    let harness = studio(&dir.path().join("home"), robot("plan-yard.xml"));
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

/// Enlarge makes the map small: it is framed again, its world whole, so that its labels are
/// the world's and not piled at the edge of a corner of it; Shrink frames it again.
#[test]
fn enlarge_frames_the_map_again_so_its_world_stays_whole() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = studio(&dir.path().join("home"), robot("plan-yard.xml"));
    let world = |harness: &Harness<'_, StudioApp>| {
        let mission = harness.state().mission().unwrap();
        let text = std::fs::read_to_string(
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/worlds/yard.world"),
        )
        .unwrap();
        let bounds = armor_model::world::World::parse(&text, "yard.world")
            .unwrap()
            .bounds();
        let corner = |x: f64, y: f64| {
            mission
                .last_screen_of(armor_model::world::Point::new(x, y))
                .unwrap()
        };
        let (a, map) = corner(bounds.min_x, bounds.min_y);
        let (b, _) = corner(bounds.max_x, bounds.max_y);
        (egui::Rect::from_two_pos(a, b), map)
    };
    let (before, map_before) = world(&harness);
    assert!(
        map_before.expand(1.0).contains_rect(before),
        "{before:?} in {map_before:?}"
    );
    harness.get_by_label("Enlarge").click();
    for _ in 0..3 {
        harness.run();
    }
    let (enlarged, map) = world(&harness);
    assert!(
        map.height() < map_before.height() * 0.6,
        "{map_before:?} → {map:?}"
    );
    assert!(
        map.expand(1.0).contains_rect(enlarged),
        "the world {enlarged:?} cut by the small map {map:?}"
    );
    let boxes = harness.state().mission().unwrap().label_boxes().to_vec();
    assert!(
        boxes.iter().all(|label| map.contains_rect(*label)),
        "{boxes:?}"
    );
    harness.get_by_label("Shrink").click();
    for _ in 0..3 {
        harness.run();
    }
    let (after, map_after) = world(&harness);
    assert!(
        map_after.expand(1.0).contains_rect(after),
        "{after:?} in {map_after:?}"
    );
}
