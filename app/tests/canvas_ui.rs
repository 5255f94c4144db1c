//! The diagram canvas as a newcomer meets it: block headers coloured by the module's category
//! (from its describe output), one way to zoom and pan (the plain wheel about the pointer, a
//! drag on empty space, Fit and Home), every wire's end marked at the pin it enters, and menu
//! entries that show their keys while keeping their names.
#![allow(clippy::unwrap_used)]

mod common;

use std::collections::BTreeMap;
use std::path::PathBuf;

use armor_module_api::{Category, ModuleDescription};
use armor_studio::StudioApp;
use armor_studio::common::palette::Palette;
use armor_studio::system::diagram::PinSide;
use armor_studio::system::viewer::{self, FIT_FLOOR, ZOOM_STEP};
use common::*;
use egui::{Color32, Key, Modifiers, Pos2, Vec2};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};

fn robot_system() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../missions/robot/system.xml")
}

/// The bundled modules, as their binaries describe themselves (through the describe XML).
fn bundled_palette() -> Palette {
    use armor_module_catalog as catalog;
    let specs = [
        catalog::sim::spec(),
        catalog::localiser::spec(),
        catalog::nav::follower::spec(),
        catalog::nav::avoider::spec(),
        catalog::observer::spec(),
        catalog::teleop::spec(),
        catalog::mux::spec(),
        catalog::recorder::spec(),
        catalog::mapper::spec(),
    ];
    Palette::from_descriptions(
        specs
            .iter()
            .map(|spec| ModuleDescription::from_xml(&spec.description().to_xml()).unwrap()),
    )
}

fn robot_harness(dir: &std::path::Path) -> Harness<'static, StudioApp> {
    let mut options = options(&dir.join("home"), Some(robot_system()));
    options.palette = Some(bundled_palette());
    harness(options)
}

fn wheel(harness: &mut Harness<'_, StudioApp>, at: Pos2, notches: f32) {
    harness.hover_at(at);
    harness.step();
    harness.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Line,
        delta: Vec2::new(0.0, notches),
        phase: egui::TouchPhase::Move,
        modifiers: Modifiers::NONE,
    });
    // Frames, not `run`: a tooltip under the pointer (a pin's) keeps asking for more.
    harness.run_steps(6);
}

/// A point of the canvas with no block under it (the canvas's left edge, half way down, is
/// left of every block once fitted).
fn empty_point(harness: &Harness<'_, StudioApp>) -> Pos2 {
    let rect = harness.state().canvas_rect();
    let point = Pos2::new(rect.left() + 12.0, rect.top() + 30.0);
    let blocks: Vec<String> = harness
        .state()
        .editor()
        .diagram
        .blocks()
        .map(|(_, block)| block.name.clone())
        .collect();
    for name in blocks {
        let block = harness.state().block_screen_rect(&name).unwrap();
        assert!(!block.contains(point), "{name} is under {point:?}");
    }
    point
}

#[test]
fn bundled_modules_say_their_category_and_the_palette_groups_them() {
    let palette = bundled_palette();
    let category = |module: &str| palette.catalog[module].category;
    assert_eq!(category("sim"), Category::Sensor);
    assert_eq!(category("follower"), Category::Navigation);
    assert_eq!(category("avoider"), Category::Navigation);
    assert_eq!(category("mapper"), Category::Mapping);
    assert_eq!(category("teleop"), Category::Operator);
    assert_eq!(category("recorder"), Category::Recording);

    let dir = tempfile::tempdir().unwrap();
    let robot = robot_harness(dir.path());
    // The palette's groups are named, in the colours of the headers.
    for group in [
        "sensors & sim",
        "navigation",
        "mapping",
        "operator",
        "recording",
    ] {
        robot.get_by_label(group);
    }
    // A module that says no category (as one written before categories) is "other".
    let plain = harness(options(&dir.path().join("plain-home"), None));
    assert_eq!(
        plain.state().palette().catalog["checker"].category,
        Category::Other
    );
    plain.get_by_label("other");
    assert!(plain.query_by_label("mapping").is_none());
}

/// Headers in the category's colour, the instance name large and the type only where it
/// differs, in pixels as rendered; and the mark at a wire's end drawn over everything.
#[test]
fn headers_are_coloured_by_category_and_wire_ends_are_drawn_on_top() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("demo.xml");
    std::fs::write(
        &file,
        r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="demo">
  <module name="counter" type="counter"/>
  <module name="check_a" type="checker"/>
  <module name="nav" type="follower"><param name="goal_x_m" value="1"/><param name="goal_y_m" value="1"/></module>
  <link from="counter.count" to="check_a.input"/>
</system>
<!-- armor-studio layout: counter=0,0 check_a=320,0 nav=0,200 -->
"#,
    )
    .unwrap();
    // The common modules, through their describe output (the checker's says no category).
    let described: Vec<ModuleDescription> = descriptions()
        .into_iter()
        .map(|description| ModuleDescription::from_xml(&description.to_xml()).unwrap())
        .collect();
    let mut options = options(&dir.path().join("home"), Some(file));
    options.palette = Some(Palette::from_descriptions(described));
    let mut harness = Harness::builder()
        .with_size(SIZE)
        .with_step_dt(1.0 / 60.0)
        .wgpu()
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options),
        );
    harness.run();
    let image = harness.render().unwrap();
    let pixel = |at: Pos2| {
        let scale = harness.ctx.pixels_per_point();
        let p = image.get_pixel((at.x * scale) as u32, (at.y * scale) as u32);
        Color32::from_rgb(p[0], p[1], p[2])
    };
    let near = |a: Color32, b: Color32| {
        let d = |x: u8, y: u8| (i16::from(x) - i16::from(y)).abs();
        d(a.r(), b.r()) <= 6 && d(a.g(), b.g()) <= 6 && d(a.b(), b.b()) <= 6
    };
    for (block, category) in [
        ("counter", Category::Sensor),
        ("check_a", Category::Other),
        ("nav", Category::Navigation),
    ] {
        let rect = harness.state().block_screen_rect(block).unwrap();
        // The header's top right corner, clear of its text and its rounded corner.
        let at = Pos2::new(rect.right() - 10.0, rect.top() + 5.0);
        let got = pixel(at);
        let want = viewer::category_colour(category);
        assert!(near(got, want), "{block}: {got:?} at {at:?}, not {want:?}");
    }
    // The type is written only under a name that does not say it: "check_a" and "nav" have
    // theirs (besides the palette's entries), "counter" has none.
    assert_eq!(harness.query_all_by_label("checker").count(), 2);
    assert_eq!(harness.query_all_by_label("follower").count(), 2);
    assert_eq!(harness.query_all_by_label("counter").count(), 2);

    // The wire's end: an arrowhead left of the input pin, in the wire's colour, on top.
    let ends = harness.state().wire_ends();
    assert_eq!(
        ends.iter()
            .map(|(port, _)| port.as_str())
            .collect::<Vec<_>>(),
        ["check_a.input"]
    );
    let tip = ends[0].1;
    let pin = harness
        .state()
        .pin_pos("check_a", "input", PinSide::Input)
        .unwrap();
    assert!((tip.y - pin.y).abs() < 1.0 && tip.x < pin.x && pin.x - tip.x < 8.0);
    // Off the wire's line (which enters the pin level), inside the arrowhead.
    let scale = harness.state().canvas_transform().scaling;
    let inside = Pos2::new(tip.x - 9.0 * scale, tip.y + 2.5 * scale);
    let got = pixel(inside);
    let want = viewer::type_colour("Counter");
    assert!(
        near(got, want),
        "arrowhead: {got:?} at {inside:?}, not {want:?}"
    );
}

#[test]
fn header_colours_read_white_text_on_the_dark_theme() {
    // WCAG's contrast ratio of white text on each header, and of each header on the canvas.
    fn luminance(colour: Color32) -> f32 {
        let channel = |c: u8| {
            let c = f32::from(c) / 255.0;
            if c <= 0.039_28 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        };
        0.2126 * channel(colour.r()) + 0.7152 * channel(colour.g()) + 0.0722 * channel(colour.b())
    }
    let contrast = |a: Color32, b: Color32| {
        let (a, b) = (luminance(a), luminance(b));
        (a.max(b) + 0.05) / (a.min(b) + 0.05)
    };
    let canvas = egui::Visuals::dark().extreme_bg_color;
    let mut seen = Vec::new();
    for category in Category::ALL {
        let fill = viewer::category_colour(category);
        for text in [viewer::HEADER_TEXT, viewer::HEADER_TEXT_WEAK] {
            let ratio = contrast(text, fill);
            assert!(ratio >= 4.5, "{category}: text contrast {ratio:.2}");
        }
        let ratio = contrast(fill, canvas);
        assert!(
            ratio >= 2.0,
            "{category}: stands out {ratio:.2} from the canvas"
        );
        assert!(!seen.contains(&fill), "{category} shares a colour");
        seen.push(fill);
    }
}

#[test]
fn the_plain_wheel_zooms_about_the_pointer_in_fine_steps() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = robot_harness(dir.path());
    let fitted = harness.state().canvas_transform();
    assert!(fitted.scaling >= FIT_FLOOR);
    // On the observer's header (its pins' labels have tooltips, which keep a frame busy).
    let at = harness.state().block_header_pos("observer").unwrap();
    let under = fitted.inverse() * at;

    // One notch up: one fine step in, the point under the pointer stays under it.
    wheel(&mut harness, at, 1.0);
    let zoomed = harness.state().canvas_transform();
    assert!(
        (zoomed.scaling / fitted.scaling - ZOOM_STEP).abs() < 1e-3,
        "{} -> {}",
        fitted.scaling,
        zoomed.scaling
    );
    assert!((zoomed * under - at).length() < 0.5, "the point moved");
    // The smoothed scroll egui spreads over the next frames does not pan the canvas.
    harness.run_steps(20);
    assert_eq!(harness.state().canvas_transform(), zoomed);

    // Two notches down: two steps out, about the same point.
    wheel(&mut harness, at, -2.0);
    let out = harness.state().canvas_transform();
    assert!((out.scaling / zoomed.scaling - ZOOM_STEP.powi(-2)).abs() < 1e-3);
    assert!((out * under - at).length() < 0.5);

    // A drag on empty space pans, at the same zoom.
    let blocks = harness.state().editor().diagram.len();
    let from = empty_point(&harness);
    drag(&mut harness, from, from + Vec2::new(120.0, 40.0));
    let panned = harness.state().canvas_transform();
    assert!((panned.scaling - out.scaling).abs() < 1e-6);
    assert!(
        (panned.translation - out.translation - Vec2::new(120.0, 40.0)).length() < 2.0,
        "{:?} -> {:?}",
        out.translation,
        panned.translation
    );
    assert_eq!(
        harness.state().editor().diagram.len(),
        blocks,
        "the drag moved nothing else"
    );

    // Home fits again, and so does the canvas's Fit button.
    harness.key_press(Key::Home);
    harness.run();
    assert_eq!(harness.state().canvas_transform(), fitted);
    wheel(&mut harness, at, 3.0);
    assert_ne!(harness.state().canvas_transform(), fitted);
    harness.get_by_label("Fit").click();
    // Frames, not `run`: the button's tooltip keeps asking for more.
    harness.run_steps(6);
    assert_eq!(harness.state().canvas_transform(), fitted);
}

#[test]
fn zoom_and_pan_are_written_in_the_view_menu_and_on_the_sheet() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = robot_harness(dir.path());
    harness.get_by_label("View").click();
    harness.run();
    harness.get_by_label("Wheel: zoom · drag: pan");
    harness.key_press(Key::Escape);
    harness.run();
    harness.key_press(Key::F1);
    harness.run();
    harness.get_by_label("zoom about the pointer (diagram, map, net)");
    harness.get_by_label("pan (diagram, map, net)");
}

/// The issue's case: at a readable zoom of the robot system, `avoider.cmd_vel` seemed to enter
/// `observer.odometry`. Every wire's end is marked at the pin it enters, and only there.
#[test]
fn every_wire_is_marked_at_the_pin_it_enters_and_nowhere_else() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = robot_harness(dir.path());
    // At 1:1 about the observer, as a user reading it would.
    let at = harness.state().block_header_pos("observer").unwrap();
    let notches = (1.0 / harness.state().canvas_transform().scaling).ln() / ZOOM_STEP.ln();
    wheel(&mut harness, at, notches);
    assert!((harness.state().canvas_transform().scaling - 1.0).abs() < 0.01);

    let diagram = &harness.state().editor().diagram;
    let mut entered: BTreeMap<String, usize> = BTreeMap::new();
    for link in diagram.links() {
        let block = &diagram.block(link.to.block).unwrap().name;
        *entered
            .entry(format!("{block}.{}", link.to.port))
            .or_default() += 1;
    }
    let ends = harness.state().wire_ends();
    assert!(!ends.is_empty());
    for (port, tip) in &ends {
        let (block, name) = port.split_once('.').unwrap();
        let pin = harness
            .state()
            .pin_pos(block, name, PinSide::Input)
            .unwrap();
        assert!(
            (tip.y - pin.y).abs() < 1.0 && pin.x - tip.x < 8.0 && tip.x <= pin.x,
            "{port}: marked at {tip:?}, its pin is at {pin:?}"
        );
        assert_eq!(
            entered.get(port),
            Some(&1),
            "{port} is marked but not linked"
        );
    }
    // Every input in view that a wire enters is marked, once.
    let marked: Vec<&str> = ends.iter().map(|(port, _)| port.as_str()).collect();
    for port in [
        "observer.odometry",
        "mux.auto",
        "mux.observe",
        "avoider.cmd_desired",
    ] {
        assert_eq!(
            marked.iter().filter(|m| **m == port).count(),
            1,
            "{port} in {marked:?}"
        );
    }
}

/// A fallback source of an input is drawn dashed, round the blocks like a backward link, and
/// saved as the file had it.
#[test]
fn a_fallback_source_is_drawn_apart_and_kept() {
    let dir = tempfile::tempdir().unwrap();
    let system = dir.path().join("system.xml");
    let robot = std::fs::read_to_string(robot_system()).unwrap();
    let with_fallback = robot.replace(
        r#"<link from="sim.odometry" to="observer.odometry"/>"#,
        r#"<link from="sim.odometry" to="observer.odometry"/>
  <module name="mapper" type="mapper"/>
  <link from="sim.scan" to="mapper.scan"/>
  <link from="mapper.pose" to="observer.odometry" fallback="1"/>"#,
    );
    assert_ne!(with_fallback, robot);
    std::fs::write(&system, &with_fallback).unwrap();
    let mut options = options(&dir.path().join("home"), Some(system));
    options.palette = Some(bundled_palette());
    let harness = harness(options);
    let routes: Vec<String> = harness
        .state()
        .routes()
        .into_iter()
        .map(|(link, _)| link)
        .collect();
    assert!(
        routes.contains(&"mapper.pose -> observer.odometry (fallback 1)".to_owned()),
        "{routes:?}"
    );
    let saved = harness.state().editor().diagram.to_xml();
    assert!(
        saved.contains(r#"<link from="mapper.pose" to="observer.odometry" fallback="1"/>"#),
        "{saved}"
    );
}

/// The robot's loop (the mux commands the sim, which feeds everything) runs right to left:
/// drawn as a curve it would cross every block between. It goes round them, below.
#[test]
fn a_backward_link_goes_round_the_blocks_between() {
    let dir = tempfile::tempdir().unwrap();
    let harness = robot_harness(dir.path());
    let routes = harness.state().routes();
    assert_eq!(
        routes
            .iter()
            .map(|(link, _)| link.as_str())
            .collect::<Vec<_>>(),
        // The robot system's layout keeps the mux under the follower so that the whole
        // diagram opens at a readable zoom: the avoider's command goes back to it, round.
        ["avoider.cmd_vel -> mux.auto", "mux.cmd_vel -> sim.cmd_vel"]
    );
    let points = &routes[1].1;
    let from = harness
        .state()
        .pin_pos("mux", "cmd_vel", PinSide::Output)
        .unwrap();
    let to = harness
        .state()
        .pin_pos("sim", "cmd_vel", PinSide::Input)
        .unwrap();
    assert_eq!((points[0], points[points.len() - 1]), (from, to));
    // Every segment but the stubs out of and into the pins is clear of every block.
    let blocks: Vec<(String, egui::Rect)> = harness
        .state()
        .editor()
        .diagram
        .blocks()
        .map(|(_, block)| {
            let rect = harness.state().block_screen_rect(&block.name).unwrap();
            (block.name.clone(), rect)
        })
        .collect();
    for segment in points[1..points.len() - 1].windows(2) {
        let box_of = egui::Rect::from_two_pos(segment[0], segment[1]).expand(0.5);
        for (name, rect) in &blocks {
            assert!(
                !rect.intersects(box_of),
                "{segment:?} crosses {name} at {rect:?}"
            );
        }
    }
    // Its end is marked at the sim's input, as every wire's.
    assert!(
        harness
            .state()
            .wire_ends()
            .iter()
            .any(|(port, _)| port == "sim.cmd_vel")
    );
}

#[test]
fn menu_entries_show_their_keys_and_keep_their_names() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = robot_harness(dir.path());
    let menus: [(&str, &[(&str, &str)]); 3] = [
        (
            "File",
            &[
                ("Open…", "Ctrl+O"),
                ("Save", "Ctrl+S"),
                ("Save as…", "Ctrl+Shift+S"),
                ("Arrange", ""),
            ],
        ),
        (
            "Edit",
            &[("Undo", "Ctrl+Z"), ("Redo", "Ctrl+Y, Ctrl+Shift+Z")],
        ),
        ("View", &[("Zoom to fit", "Home, Ctrl+0")]),
    ];
    for (menu, entries) in menus {
        harness.get_by_label(menu).click();
        harness.run();
        for (entry, keys) in entries {
            let node = harness.get_by_label(entry);
            let shortcut = node
                .accesskit_node()
                .data()
                .keyboard_shortcut()
                .map(str::to_owned);
            if keys.is_empty() {
                assert_eq!(shortcut, None, "{menu} → {entry}");
                continue;
            }
            assert_eq!(shortcut.as_deref(), Some(*keys), "{menu} → {entry}");
            // Drawn: the entry is as wide as its name and its keys side by side.
            let width = node.rect().width();
            assert!(
                width > 6.0 * (entry.chars().count() + keys.len()) as f32,
                "{entry} is {width} wide"
            );
        }
    }
    harness.key_press(Key::Escape);
    harness.run();

    // The Mission view's menus too.
    harness
        .state_mut()
        .set_view(armor_studio::command::View::Mission);
    harness.run();
    harness.get_by_label("File").click();
    harness.run();
    let save = harness.get_by_label("Save plan");
    assert_eq!(
        save.accesskit_node().data().keyboard_shortcut(),
        Some("Ctrl+S")
    );
}

/// A wire dropped with Shift held into an input that has a source is added as its fallback,
/// drawn dashed and written with its rank; without Shift it would replace the source.
#[test]
fn a_wire_dropped_with_shift_adds_a_fallback_source() {
    let dir = tempfile::tempdir().unwrap();
    let system = dir.path().join("system.xml");
    let robot = std::fs::read_to_string(robot_system()).unwrap();
    let with_mapper = robot.replace(
        r#"<link from="sim.odometry" to="observer.odometry"/>"#,
        r#"<link from="sim.odometry" to="observer.odometry"/>
  <module name="mapper" type="mapper"/>
  <link from="sim.scan" to="mapper.scan"/>"#,
    );
    assert_ne!(with_mapper, robot);
    std::fs::write(&system, &with_mapper).unwrap();
    let mut options = options(&dir.path().join("home"), Some(system));
    options.palette = Some(bundled_palette());
    let mut harness = harness(options);
    let from = pin(&harness, "mapper", "pose", PinSide::Output);
    let to = pin(&harness, "observer", "odometry", PinSide::Input);
    harness.event(egui::Event::ModifiersChanged(Modifiers::SHIFT));
    drag(&mut harness, from, to);
    harness.event(egui::Event::ModifiersChanged(Modifiers::NONE));
    harness.run();
    let saved = harness.state().editor().diagram.to_xml();
    assert!(
        saved.contains(r#"<link from="sim.odometry" to="observer.odometry"/>"#),
        "{saved}"
    );
    assert!(
        saved.contains(r#"<link from="mapper.pose" to="observer.odometry" fallback="1"/>"#),
        "{saved}"
    );
    let routes: Vec<String> = harness
        .state()
        .routes()
        .into_iter()
        .map(|(link, _)| link)
        .collect();
    assert!(
        routes.contains(&"mapper.pose -> observer.odometry (fallback 1)".to_owned()),
        "{routes:?}"
    );
    harness.get_by_label_contains("linked as fallback 1");
}
