//! First sight of a system: a file without saved positions is laid out in layers by data flow,
//! fitted at a zoom where every block's name is drawn, and File → Arrange is one undo step.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::PathBuf;

use armor_studio::system::diagram::Diagram;
use armor_studio::system::viewer::DETAIL_SCALE;
use common::*;
use egui::{Key, Modifiers};
use egui_kittest::kittest::Queryable as _;

fn robot_system() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../missions/robot/system.xml")
}

#[test]
fn robot_system_opens_in_layers_with_every_name_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let harness = harness(options(&dir.path().join("home"), Some(robot_system())));
    let diagram = &harness.state().editor().diagram;
    // sim, localiser, camera, follower, avoider, observer, teleop, mux, recorder.
    assert_eq!(diagram.len(), 9);

    // Sources left of their sinks, for every link but the one that closes the loop through
    // the robot (mux → sim), which the layout turns round, and the avoider's command to the
    // mux, laid out under the follower so that the whole opens at a readable zoom.
    let x = |id| diagram.block(id).unwrap().pos[0];
    let backwards: Vec<String> = diagram
        .links()
        .filter(|link| x(link.from.block) >= x(link.to.block))
        .map(|link| {
            format!(
                "{} -> {}",
                diagram.port_label(&link.from),
                diagram.port_label(&link.to)
            )
        })
        .collect();
    assert_eq!(
        backwards,
        [
            "`avoider.cmd_vel` -> `mux.auto`",
            "`mux.cmd_vel` -> `sim.cmd_vel`"
        ]
    );

    // Fitted no smaller than the zoom at which names are drawn, and every name is drawn.
    let scale = harness.state().canvas_transform().scaling;
    assert!(scale >= DETAIL_SCALE, "fitted at {scale}");
    for (_, block) in diagram.blocks() {
        assert!(
            harness.query_all_by_label(&block.name).next().is_some(),
            "`{}` is not drawn",
            block.name
        );
    }
}

/// The modules of the behaviours' system, as their binaries describe themselves.
fn behaviours_palette() -> armor_studio::common::palette::Palette {
    use armor_module_catalog as catalog;
    let specs = [
        catalog::sim::spec(),
        catalog::localiser::spec(),
        catalog::nav::follower::spec(),
        catalog::nav::vff::spec(),
        catalog::nav::stop::spec(),
        catalog::arbiter::spec(),
        catalog::nav::avoider::spec(),
        catalog::teleop::spec(),
        catalog::mux::spec(),
    ];
    armor_studio::common::palette::Palette::from_descriptions(specs.iter().map(|spec| {
        armor_module_api::describe::ModuleDescription::from_xml(&spec.description().to_xml())
            .unwrap()
    }))
}

/// A system of competing behaviours saved without positions or subsystems (as another tool
/// writes one) opens
/// whole: its loop through sensors, behaviours, arbiter and motors is seven layers long, too
/// long for one row at a readable zoom, so the layout folds it into bands, and every block and
/// every link routed round them is on the canvas at the first frames, blocks apart.
#[test]
fn a_long_loop_opens_whole_folded_into_bands() {
    let dir = tempfile::tempdir().unwrap();
    let file =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../missions/robot/system-behaviours.xml");
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(
        !text.contains("armor-studio layout"),
        "saved without positions"
    );
    // Its modules and links alone, as a tool that knows nothing of subsystems writes them.
    let (before, rest) = text.split_once("  <subsystem").unwrap();
    let (_, after) = rest.rsplit_once("</subsystem>").unwrap();
    let file = dir.path().join("flat.xml");
    std::fs::write(&file, format!("{before}{after}")).unwrap();
    let mut options = options(&dir.path().join("home"), Some(file));
    options.palette = Some(behaviours_palette());
    let harness = harness(options);
    let app = harness.state();
    let names: Vec<String> = app
        .editor()
        .diagram
        .blocks()
        .map(|(_, block)| block.name.clone())
        .collect();
    assert_eq!(names.len(), 9, "{names:?}");
    let scale = app.canvas_transform().scaling;
    assert!(scale >= DETAIL_SCALE, "fitted at {scale}");
    let canvas = app.canvas_rect();
    let rects: Vec<(String, egui::Rect)> = names
        .iter()
        .map(|name| (name.clone(), app.block_screen_rect(name).unwrap()))
        .collect();
    for (i, (name, rect)) in rects.iter().enumerate() {
        assert!(
            canvas.contains_rect(*rect),
            "`{name}` at {rect:?} is cut off by {canvas:?}"
        );
        for (other, other_rect) in &rects[i + 1..] {
            assert!(!rect.intersects(*other_rect), "`{name}` overlaps `{other}`");
        }
    }
    let routes = app.routes();
    assert!(!routes.is_empty(), "the loop back to the sim is routed");
    for (link, points) in routes {
        for point in points {
            assert!(
                canvas.contains(point),
                "{link} runs out of the canvas at {point:?}"
            );
        }
    }
}

#[test]
fn arrange_is_one_undo_step() {
    let dir = tempfile::tempdir().unwrap();
    // The robot system with positions saved, scattered as a user dragging blocks might leave it.
    let mut scattered =
        Diagram::from_xml(&std::fs::read_to_string(robot_system()).unwrap()).unwrap();
    let ids: Vec<_> = scattered.blocks().map(|(id, _)| id).collect();
    for (index, id) in ids.into_iter().enumerate() {
        scattered.move_block(id, [index as f32 * 37.0, 600.0 - index as f32 * 80.0]);
    }
    let file = dir.path().join("scattered.xml");
    std::fs::write(&file, scattered.to_xml()).unwrap();
    let mut harness = harness(options(&dir.path().join("home"), Some(file)));
    let opened = harness.state().editor().diagram.clone();
    let positions = |diagram: &Diagram| diagram.blocks().map(|(_, b)| b.pos).collect::<Vec<_>>();
    assert_eq!(
        positions(&opened),
        positions(&scattered),
        "saved positions are kept"
    );

    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label("Arrange").click();
    harness.run();
    let arranged = harness.state().editor().diagram.clone();
    assert_ne!(positions(&arranged), positions(&opened));
    harness.get_by_label("arranged by data flow");

    harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    harness.run();
    assert_eq!(harness.state().editor().diagram, opened);
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Y);
    harness.run();
    assert_eq!(harness.state().editor().diagram, arranged);
}
