//! The Mission view's editing, driven as an operator would: waypoints clicked, dragged,
//! inserted and deleted on the map; a no-go area drawn corner by corner; a unit placed; undo;
//! a GPX route imported; the net's selection linked to the map's.
#![allow(clippy::unwrap_used)]

mod common;

use armor_model::plan::{AreaKind, GraphicKind};
use armor_studio::StudioApp;
use armor_studio::mission::plan_edit::Selection;
use common::*;
use egui::{Key, Modifiers, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

fn robot(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../missions/robot")
        .join(name)
}

fn studio(options: armor_studio::Options) -> Harness<'static, StudioApp> {
    Harness::builder()
        .with_size(SIZE)
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(60)
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options),
        )
}

/// The studio on a new plan for the yard's robot, in the Mission view.
fn yard(dir: &std::path::Path) -> Harness<'static, StudioApp> {
    yard_with(options(&dir.join("home"), None))
}

fn yard_with(options: armor_studio::Options) -> Harness<'static, StudioApp> {
    let mut harness = studio(options);
    harness.run();
    harness
        .state_mut()
        .set_view(armor_studio::app::View::Mission);
    harness.run();
    let report = harness
        .state_mut()
        .mission_mut()
        .unwrap()
        .new_plan(Some(&robot("system.xml")));
    assert!(report.is_ok(), "{report:?}");
    harness.run();
    harness
}

fn at(harness: &Harness<'_, StudioApp>, x_m: f64, y_m: f64) -> Pos2 {
    let mission = harness.state().mission().unwrap();
    mission.screen_pos_of_local(x_m, y_m).unwrap()
}

/// A click, far enough in time from the last one not to make a double click with it.
fn tap(harness: &mut Harness<'_, StudioApp>, at: Pos2) {
    harness.run_steps(30);
    click(harness, at);
}

/// A route through `points` (world metres), drawn with the waypoint tool.
fn draw_route(harness: &mut Harness<'_, StudioApp>, points: &[(f64, f64)]) {
    harness.key_press(Key::W);
    harness.run();
    for &(x, y) in points {
        let p = at(harness, x, y);
        tap(harness, p);
    }
}

fn local(harness: &Harness<'_, StudioApp>, name: &str) -> (f64, f64) {
    let mission = harness.state().mission().unwrap();
    let plan = mission.plan();
    let p = plan
        .waypoint(name)
        .unwrap()
        .position
        .to_local(mission.surroundings.origin(plan));
    (p.x, p.y)
}

fn route(harness: &Harness<'_, StudioApp>) -> Vec<String> {
    let plan = harness.state().mission().unwrap().plan();
    plan.legs
        .iter()
        .map(|leg| format!("{}>{}", leg.from, leg.to))
        .collect()
}

#[test]
fn waypoints_are_clicked_dragged_inserted_deleted_and_undone() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    harness.key_press(Key::W);
    harness.run();
    assert!(harness.state().status().text.starts_with("waypoint tool"));
    for (x, y) in [(4.0, 4.0), (12.0, 4.0), (12.0, 14.0)] {
        let p = at(&harness, x, y);
        tap(&mut harness, p);
    }
    assert_eq!(route(&harness), ["wp1>wp2", "wp2>wp3"]);

    // Dragged: the waypoint follows the pointer, and one undo puts it back.
    harness.key_press(Key::V);
    harness.run();
    let (from, to) = (at(&harness, 12.0, 4.0), at(&harness, 16.0, 5.0));
    drag(&mut harness, from, to);
    let (x, y) = local(&harness, "wp2");
    assert!(
        (x - 16.0).abs() < 0.2 && (y - 5.0).abs() < 0.2,
        "({x}, {y})"
    );
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    harness.run();
    let (x, y) = local(&harness, "wp2");
    assert!(
        (x - 12.0).abs() < 0.1 && (y - 4.0).abs() < 0.1,
        "({x}, {y})"
    );

    // A right-click on the second leg, then its menu: a waypoint in its middle.
    let middle = at(&harness, 12.0, 9.0);
    harness.run_steps(30);
    harness.hover_at(middle);
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton {
            pos: middle,
            button: egui::PointerButton::Secondary,
            pressed,
            modifiers: Modifiers::NONE,
        });
    }
    harness.run();
    harness.get_by_label("Insert a waypoint").click();
    harness.run();
    assert_eq!(route(&harness), ["wp1>wp2", "wp2>wp4", "wp4>wp3"]);
    let (x, y) = local(&harness, "wp4");
    assert!(
        (x - 12.0).abs() < 0.1 && (y - 9.0).abs() < 0.1,
        "({x}, {y})"
    );

    // Selected on the map and deleted with the key: the route closes up.
    let p = at(&harness, 12.0, 4.0);
    tap(&mut harness, p);
    assert_eq!(
        harness.state().mission().unwrap().editor.selection,
        Selection::Waypoint("wp2".into())
    );
    harness.key_press(Key::Delete);
    harness.run();
    assert_eq!(route(&harness), ["wp1>wp4", "wp4>wp3"]);
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    harness.run();
    assert_eq!(route(&harness), ["wp1>wp2", "wp2>wp4", "wp4>wp3"]);
    assert!(
        harness.state().title().starts_with('*'),
        "{}",
        harness.state().title()
    );
}

#[test]
fn a_no_go_area_drawn_on_the_map_sends_the_route_round_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    draw_route(&mut harness, &[(4.0, 4.0), (16.0, 4.0)]);
    let straight = harness
        .state()
        .mission()
        .unwrap()
        .checked()
        .compiled
        .as_ref()
        .unwrap()
        .routes[0]
        .len();
    assert_eq!(straight, 2);

    // Four corners across the leg, then Enter.
    harness.key_press(Key::N);
    harness.run();
    for (x, y) in [(9.0, 2.5), (11.0, 2.5), (11.0, 5.5), (9.0, 5.5)] {
        let p = at(&harness, x, y);
        tap(&mut harness, p);
    }
    harness.key_press(Key::Enter);
    harness.run();
    let mission = harness.state().mission().unwrap();
    let area = &mission.plan().graphics[0];
    assert_eq!(area.kind, GraphicKind::Area(AreaKind::NoGo));
    assert_eq!(area.points.len(), 4);
    assert_eq!(area.name, "nogo1");
    let routes = &mission.checked().compiled.as_ref().unwrap().routes;
    assert!(
        routes[0].len() > 2,
        "the leg goes round the area: {:?}",
        routes[0]
    );

    // A unit symbol placed with the unit tool, its code described in the inspector.
    harness.key_press(Key::U);
    harness.run();
    let p = at(&harness, 20.0, 20.0);
    tap(&mut harness, p);
    let mission = harness.state().mission().unwrap();
    assert_eq!(mission.plan().units[0].sidc, "SFGPUCR----D---");
    assert_eq!(mission.editor.selection, Selection::Unit(0));
    harness.get_by_label_contains("friend");
}

#[test]
fn a_gpx_route_imports_and_the_net_selects_its_leg_on_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label("Import GPX…").click();
    harness.run();
    harness
        .get_by_label("Path:")
        .type_text(&robot("yard-route.gpx").display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    harness.get_by_label_contains("imported");
    let plan = harness.state().mission().unwrap().plan().clone();
    assert!(plan.legs.len() >= 3, "{:?}", plan.legs);
    let checked = harness.state().mission().unwrap().checked();
    assert!(checked.errors.is_empty(), "{:?}", checked.errors);

    // A click on a transition of the second leg in the net selects that leg.
    let transition = checked
        .net()
        .unwrap()
        .transitions
        .iter()
        .find(|t| t.name.starts_with(&format!("{}_", plan.legs[1].name)))
        .unwrap()
        .name
        .clone();
    harness.get_by_label(&transition).click();
    harness.run();
    assert_eq!(
        harness.state().mission().unwrap().editor.selection,
        Selection::Leg(1)
    );
    harness.get_by_label_contains(&format!("Leg {}", plan.legs[1].name));
}

#[test]
fn an_unsaved_plan_is_offered_back_after_a_crash_and_its_net_exports_as_pnml() {
    let dir = tempfile::tempdir().unwrap();
    let home = dir.path().join("home");
    let mut first = options(&home, None);
    first.autosave_every = std::time::Duration::ZERO;
    let mut harness = yard_with(first);
    draw_route(&mut harness, &[(4.0, 4.0), (12.0, 4.0)]);
    assert!(home.join("recovery-plan.xml").exists());
    // The studio "crashes": it is dropped without on_exit.
    drop(harness);

    let mut harness = studio(options(&home, None));
    harness.run();
    harness.get_by_label_contains("an unsaved plan");
    harness.get_by_label("Restore").click();
    harness.run();
    assert_eq!(harness.state().view(), armor_studio::app::View::Mission);
    assert_eq!(route(&harness), ["wp1>wp2"]);
    assert!(harness.state().mission().unwrap().is_dirty());

    let pnml = dir.path().join("net.pnml");
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label("Export PNML…").click();
    harness.run();
    harness
        .get_by_label("Path:")
        .type_text(&pnml.display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    let text = std::fs::read_to_string(&pnml).unwrap();
    let net = armor_model::net::from_pnml(&text).unwrap();
    let compiled = harness
        .state()
        .mission()
        .unwrap()
        .checked()
        .net()
        .unwrap()
        .clone();
    assert_eq!(net.places.len(), compiled.places.len());
    assert_eq!(net.transitions.len(), compiled.transitions.len());
}

#[test]
fn a_new_plan_names_only_its_follower() {
    use armor_module_api::ModuleDescription;
    let dir = tempfile::tempdir().unwrap();
    let mut options = options(&dir.path().join("home"), None);
    let described = |module_type: &str, controllable: bool| {
        let mut description = ModuleDescription::new(module_type, "test");
        description.controllable = controllable;
        description
    };
    options.palette = Some(armor_studio::common::palette::Palette::from_descriptions([
        described("sim", false),
        described("follower", true),
        described("avoider", true),
        described("observer", true),
        described("teleop", false),
        described("mux", false),
        described("recorder", true),
    ]));
    let harness = yard_with(options);
    // The yard's system: follower → avoider → mux → sim. The avoider runs with the follower on
    // demand: the plan need not name it.
    let plan = harness.state().mission().unwrap().plan();
    assert!(plan.navigation.companions.is_empty());
}

#[test]
fn a_changed_plan_is_not_replaced_without_asking() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    draw_route(&mut harness, &[(4.0, 4.0), (12.0, 4.0)]);
    assert_eq!(route(&harness), ["wp1>wp2"]);
    let new_plan = |harness: &mut Harness<'_, StudioApp>| {
        harness.get_by_label("File").click();
        harness.run();
        harness.get_by_label("New plan").click();
        harness.run();
    };
    new_plan(&mut harness);
    harness.get_by_label("the new plan has unsaved changes, lost if not saved.");
    harness.get_by_label("Cancel").click();
    harness.run();
    assert_eq!(route(&harness), ["wp1>wp2"], "kept");
    new_plan(&mut harness);
    harness.get_by_label("Don't save").click();
    harness.run();
    assert!(route(&harness).is_empty(), "replaced by a new plan");
    assert!(!harness.state().mission().unwrap().is_dirty());
}

#[test]
fn the_bundled_plans_labels_never_overlap_at_the_first_frame() {
    for name in [
        "plan-yard.xml",
        "plan-yard-route.xml",
        "plan-building.xml",
        "plan-field.xml",
        "plan-warehouse.xml",
    ] {
        let dir = tempfile::tempdir().unwrap();
        let mut harness = studio(options(&dir.path().join("home"), Some(robot(name))));
        harness.run();
        let mission = harness.state().mission().unwrap();
        let boxes = mission.label_boxes();
        let plan = mission.plan();
        assert!(
            boxes.len() >= plan.waypoints.len(),
            "{name}: {} labels for {} waypoints",
            boxes.len(),
            plan.waypoints.len()
        );
        for (i, a) in boxes.iter().enumerate() {
            for b in &boxes[i + 1..] {
                assert!(
                    !a.intersects(*b),
                    "{name}: labels at {a:?} and {b:?} overlap"
                );
            }
        }
    }
}

#[test]
fn a_waypoint_is_placed_by_typing_metres_or_degrees_in_the_inspector() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    harness.key_press(Key::W);
    harness.run();
    let p = at(&harness, 4.0, 4.0);
    tap(&mut harness, p);
    harness.key_press(Key::V);
    harness.run();
    let p = at(&harness, 4.0, 4.0);
    tap(&mut harness, p);
    harness.get_by_label("Waypoint wp1");
    // Metres east and north of the world's origin.
    let east = harness.get_by_label("East (m)");
    east.click();
    harness.run();
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness.get_by_label("East (m)").type_text("10.5");
    harness.run();
    let (x, y) = local(&harness, "wp1");
    assert!(
        (x - 10.5).abs() < 1e-6 && (y - 4.0).abs() < 0.2,
        "({x}, {y})"
    );
    // A number out of range is refused, and said so.
    harness.get_by_label("Latitude (°)").click();
    harness.run();
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness.get_by_label("Latitude (°)").type_text("123");
    harness.run();
    harness.get_by_label("latitude: a number from -90 to 90");
    let (x2, _) = local(&harness, "wp1");
    assert!((x2 - 10.5).abs() < 1e-6);
}

/// Draws a no-go area corner by corner (metres), as the N tool does.
fn no_go_area(harness: &mut Harness<'_, StudioApp>, corners: &[(f64, f64)]) {
    harness.key_press(Key::N);
    harness.run();
    for &(x, y) in corners {
        let p = at(harness, x, y);
        tap(harness, p);
    }
    harness.key_press(Key::Enter);
    harness.run();
}

/// Issue 37, defect 9: with a route on the map whose leg is blocked, the net panel never says
/// "No net yet: draw a route…": it names the leg and what blocks it.
#[test]
fn with_a_blocked_leg_the_net_panel_says_what_is_blocked_not_to_draw_a_route() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    draw_route(&mut harness, &[(4.0, 4.0), (16.0, 4.0), (16.0, 14.0)]);
    assert!(harness.state().mission().unwrap().checked().net().is_some());
    // A no-go area right round the last waypoint: the second leg cannot reach it.
    no_go_area(
        &mut harness,
        &[(14.0, 12.0), (18.0, 12.0), (18.0, 16.0), (14.0, 16.0)],
    );
    let mission = harness.state().mission().unwrap();
    assert!(
        mission.checked().net().is_none(),
        "the plan still compiles: {:?}",
        mission.checked().legs
    );
    assert!(
        harness.query_by_label_contains("draw a route").is_none(),
        "the net panel asks for a route with three waypoints on the map"
    );
    harness.get_by_label_contains("No net: the plan does not compile");
    let leg = &harness.state().mission().unwrap().plan().legs[1];
    let said = format!(
        "leg `{}` ({} → {}) is blocked: ",
        leg.name, leg.from, leg.to
    );
    assert!(
        harness.query_by_label_contains(&said).is_some(),
        "`{said}` not shown; legs {:?}, errors {:?}",
        harness.state().mission().unwrap().checked().legs,
        harness.state().mission().unwrap().checked().errors
    );
}

#[test]
fn each_leg_shows_its_path_and_a_leg_with_no_way_through_is_drawn_and_said_so() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    draw_route(&mut harness, &[(4.0, 4.0), (16.0, 4.0)]);
    // A no-go area across the yard from its west boundary to its east one, between the two
    // waypoints... once moved north of it: the leg cannot get through.
    no_go_area(
        &mut harness,
        &[(0.2, 8.0), (39.8, 8.0), (39.8, 9.0), (0.2, 9.0)],
    );
    let mission = harness.state().mission().unwrap();
    assert!(
        matches!(&mission.checked().legs[0], armor_studio::mission::LegRoute::Path { length_m, .. } if (length_m - 12.0).abs() < 0.5),
        "{:?}",
        mission.checked().legs
    );
    // The leg selected: its path's length and time in the inspector.
    harness.state_mut().mission_mut().unwrap().editor.selection = Selection::Leg(0);
    harness.run();
    harness.get_by_label_contains("path: 12.0 m, about 24 s");
    // The second waypoint moved north of the area (typed in the inspector).
    harness.state_mut().mission_mut().unwrap().editor.selection = Selection::Waypoint("wp2".into());
    harness.run();
    harness.get_by_label("North (m)").click();
    harness.run();
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness.get_by_label("North (m)").type_text("14");
    harness.run();
    let mission = harness.state().mission().unwrap();
    assert!(
        matches!(
            &mission.checked().legs[0],
            armor_studio::mission::LegRoute::Cut { .. }
        ),
        "{:?}",
        mission.checked().legs
    );
    assert!(
        mission
            .checked()
            .errors
            .iter()
            .any(|e| e.message.contains("no way from `wp1` to `wp2`")),
        "{:?}",
        mission.checked().errors
    );
    harness.state_mut().mission_mut().unwrap().editor.selection = Selection::Leg(0);
    harness.run();
    // Said twice: in the inspector of the selected leg and in the net panel, which names every
    // blocked leg and what blocks it.
    assert_eq!(
        harness
            .query_all_by_label_contains("no way through: the narrowest passage")
            .count(),
        2
    );
}

/// The studio on a bundled plan, in the Mission view, its net fitted.
fn bundled(dir: &std::path::Path, name: &str) -> Harness<'static, StudioApp> {
    let mut harness = studio(options(&dir.join("home"), Some(robot(name))));
    harness.run();
    harness
}

#[test]
fn the_wheel_zooms_the_net_about_the_pointer_and_home_fits_it_again() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = bundled(dir.path(), "plan-yard.xml");
    let before = harness.state().mission().unwrap().net_view().clone();
    assert!(before.canvas.is_positive());
    // Off the centre, so that a zoom about the centre would be told apart.
    let pointer = before.canvas.lerp_inside(egui::vec2(0.3, 0.6));
    let under = before.layout_from_screen(pointer);
    harness.hover_at(pointer);
    harness.run();
    harness.event(egui::Event::MouseWheel {
        unit: egui::MouseWheelUnit::Line,
        delta: egui::vec2(0.0, 2.0),
        phase: egui::TouchPhase::Move,
        modifiers: Modifiers::NONE,
    });
    harness.run();
    let after = harness.state().mission().unwrap().net_view().clone();
    let ratio = after.zoom / before.zoom;
    assert!((ratio - 1.21).abs() < 1e-3, "two notches zoom by {ratio}");
    let still = after.layout_from_screen(pointer);
    assert!(
        (still - under).length() < 0.5,
        "{under:?} moved to {still:?}"
    );
    harness.key_press(Key::Home);
    harness.run();
    let fitted = harness.state().mission().unwrap().net_view().clone();
    // Home shows the whole net: no larger than the view opened at (which keeps names
    // readable), and smaller than the zoom the wheel reached.
    assert!(
        fitted.zoom <= before.zoom + 1e-4 && fitted.zoom < after.zoom,
        "{} then {} then {}",
        before.zoom,
        after.zoom,
        fitted.zoom
    );
}

#[test]
fn the_net_opens_readable_and_its_names_never_overlap_nor_leave_the_view_at_fit() {
    for name in [
        "plan-yard.xml",
        "plan-yard-route.xml",
        "plan-building.xml",
        "plan-field.xml",
        "plan-warehouse.xml",
    ] {
        let dir = tempfile::tempdir().unwrap();
        let mut harness = bundled(dir.path(), name);
        // At the first frame the names can be read.
        let first = harness.state().mission().unwrap().net_view().clone();
        assert!(
            first.zoom >= armor_studio::mission::net_view::READABLE_ZOOM - 1e-3,
            "{name}: opens at zoom {}",
            first.zoom
        );
        // Home, with the pointer over the net, shows the whole net.
        harness.hover_at(first.canvas.center());
        harness.run();
        harness.key_press(Key::Home);
        harness.run();
        let mission = harness.state().mission().unwrap();
        let net = mission.checked().net().unwrap();
        let view = mission.net_view();
        let boxes = &view.label_boxes;
        assert_eq!(
            boxes.len(),
            net.places.len() + net.transitions.len(),
            "{name}: every name drawn"
        );
        for (i, a) in boxes.iter().enumerate() {
            assert!(view.canvas.contains_rect(*a), "{name}: {a:?} clipped");
            for b in &boxes[i + 1..] {
                assert!(
                    !a.intersects(*b),
                    "{name}: names at {a:?} and {b:?} overlap"
                );
            }
        }
    }
}

#[test]
fn the_net_has_a_legend_and_enlarges_to_most_of_the_window() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = bundled(dir.path(), "plan-yard.xml");
    for kind in [
        "operator-fired",
        "timed",
        "event",
        "immediate",
        "marked place",
        "final place",
    ] {
        harness.get_by_label(kind);
    }
    let small = harness.state().mission().unwrap().net_view().canvas;
    harness.get_by_label("Enlarge").click();
    harness.run();
    let large = harness.state().mission().unwrap().net_view().canvas;
    assert!(large.height() > 0.55 * SIZE[1], "{small:?} → {large:?}");
    // Still fitted: the whole net shows, larger.
    assert!(
        harness
            .state()
            .mission()
            .unwrap()
            .net_view()
            .label_boxes
            .iter()
            .all(|b| large.contains_rect(*b))
    );
    harness.get_by_label("Shrink").click();
    harness.run();
    let back = harness.state().mission().unwrap().net_view().canvas;
    assert!(
        (back.height() - small.height()).abs() < 1.0,
        "{small:?} → {back:?}"
    );
}

/// The centre of the `index`th widget labelled `label`, in the order they are drawn.
fn nth(harness: &Harness<'_, StudioApp>, label: &str, index: usize) -> egui::Pos2 {
    harness
        .get_all_by_label(label)
        .nth(index)
        .unwrap_or_else(|| panic!("no {index}th `{label}`"))
        .rect()
        .center()
}

/// The centre of the `index`th "add a module…" list (a combo box: its text is its value).
fn add_module(harness: &Harness<'_, StudioApp>, index: usize) -> egui::Pos2 {
    harness
        .get_all(egui_kittest::kittest::by().value("add a module…"))
        .nth(index)
        .unwrap_or_else(|| panic!("no {index}th module list"))
        .rect()
        .center()
}

fn during(harness: &Harness<'_, StudioApp>) -> armor_model::plan::Action {
    let plan = harness.state().mission().unwrap().plan();
    plan.legs[0].during.clone().unwrap_or_default()
}

#[test]
fn an_action_s_alternatives_are_added_ordered_given_modules_removed_and_drawn_in_the_net() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    draw_route(&mut harness, &[(4.0, 4.0), (16.0, 4.0)]);
    harness.state_mut().mission_mut().unwrap().editor.selection = Selection::Leg(0);
    harness.run();
    // The recorder beside the drive, picked from the system's modules.
    let add = add_module(&harness, 0);
    tap(&mut harness, add);
    harness.run();
    harness.get_by_label("recorder").click();
    harness.run();
    assert_eq!(during(&harness).modules[0].name, "recorder");
    // An alternative: at first it runs none of the action's modules, so it answers the
    // recorder's failure.
    harness.get_by_label("add an alternative").click();
    harness.run();
    let action = during(&harness);
    assert_eq!(action.alternatives.len(), 1);
    assert_eq!(action.alternatives[0].name, "alt1");
    harness.get_by_label_contains("taken when `recorder` fails for good");
    // Given the observer, and the camera's failure to answer.
    let add = add_module(&harness, 1);
    tap(&mut harness, add);
    harness.run();
    harness.get_by_label("observer").click();
    harness.run();
    harness.get_by_label("On failure of").click();
    harness.run();
    harness.get_by_label("On failure of").type_text("camera");
    harness.run();
    let action = during(&harness);
    assert_eq!(action.alternatives[0].modules[0].name, "observer");
    assert_eq!(action.alternatives[0].on, ["camera"]);
    // A second one, moved before the first.
    harness.get_by_label("add an alternative").click();
    harness.run();
    let earlier = nth(&harness, "earlier", 1);
    tap(&mut harness, earlier);
    harness.run();
    let names: Vec<String> = during(&harness)
        .alternatives
        .iter()
        .map(|a| a.name.clone())
        .collect();
    assert_eq!(names, ["alt2", "alt1"]);
    // The net has a branch for each, its places and switches known as the alternatives'.
    let mission = harness.state().mission().unwrap();
    let compiled = mission.checked().compiled.as_ref().expect("compiled");
    let leg = &mission.plan().legs[0].name;
    for way in ["alt1", "alt2", "camera_failed", "recorder_failed"] {
        let name = format!("{leg}_drive_{way}");
        assert!(
            compiled.alternatives.contains(&name),
            "{name} in {:?}",
            compiled.alternatives
        );
        assert!(
            mission
                .net_layout()
                .is_some_and(|l| l.nodes.contains_key(&name)),
            "{name} laid out"
        );
    }
    // The first alternative removed (the remove after the recorder's): one is left.
    let remove = nth(&harness, "remove", 1);
    tap(&mut harness, remove);
    harness.run();
    let names: Vec<String> = during(&harness)
        .alternatives
        .iter()
        .map(|a| a.name.clone())
        .collect();
    assert_eq!(names, ["alt1"]);
    // What the inspector made is a plan that reads back as written.
    let plan = harness.state().mission().unwrap().plan().clone();
    let again = armor_model::plan::Plan::parse(&plan.to_xml()).expect("reads back");
    assert_eq!(again.to_xml(), plan.to_xml());
    assert!(
        plan.to_xml().contains("<alternative on=\"camera\">"),
        "{}",
        plan.to_xml()
    );
}

/// The response chosen in the combo box `when lost (module `localiser`)`, as it shows (the
/// leg's or the plan's, whichever the inspector shows).
fn lost_choice(harness: &Harness<'_, StudioApp>) -> String {
    let combo = harness.get_by_label("when lost (module `localiser`)");
    combo.value().unwrap_or_default()
}

#[test]
fn the_inspector_offers_the_lost_contingency_and_the_plan_file_keeps_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = yard(dir.path());
    draw_route(&mut harness, &[(4.0, 4.0), (16.0, 4.0)]);
    // The plan as a whole: skip the rest of a leg when the localiser is lost.
    harness.state_mut().mission_mut().unwrap().editor.selection = Selection::None;
    harness.run();
    assert_eq!(lost_choice(&harness), "drive on regardless");
    harness
        .get_by_label("when lost (module `localiser`)")
        .click();
    harness.run();
    // Hold or skip only: a robot that does not know where it is cannot drive back anywhere.
    assert!(
        harness.query_by_label_contains("return to").is_none(),
        "no `return` for lost"
    );
    harness.get_by_label("skip the rest of the leg").click();
    harness.run();
    // The leg: hold for the operator, whatever the plan says.
    harness.state_mut().mission_mut().unwrap().editor.selection = Selection::Leg(0);
    harness.run();
    assert_eq!(lost_choice(&harness), "as the plan says");
    harness
        .get_by_label("when lost (module `localiser`)")
        .click();
    harness.run();
    harness.get_by_label("hold for the operator").click();
    harness.run();
    let file = dir.path().join("lost.xml");
    let saved = harness.state_mut().mission_mut().unwrap().save(Some(&file));
    assert!(saved.is_ok(), "{saved:?}");
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(
        text.contains(r#"<contingency on="lost" do="skip"/>"#),
        "{text}"
    );
    assert!(
        text.contains(r#"<contingency on="lost" do="hold"/>"#),
        "{text}"
    );
    // Read back: the inspector shows what was chosen.
    let mut again = yard(dir.path());
    let opened = again.state_mut().mission_mut().unwrap().open(&file);
    assert!(opened.is_ok(), "{opened:?}");
    again.state_mut().mission_mut().unwrap().editor.selection = Selection::Leg(0);
    again.run();
    assert_eq!(lost_choice(&again), "hold for the operator");
    again.state_mut().mission_mut().unwrap().editor.selection = Selection::None;
    again.run();
    assert_eq!(lost_choice(&again), "skip the rest of the leg");
    let plan = again.state().mission().unwrap().plan().clone();
    assert_eq!(plan.to_xml(), text, "read back as written");
}
