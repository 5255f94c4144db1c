//! The studio driven as a user would: pointer drags from the palette, wires between pins, the
//! parameters dialog, keyboard shortcuts, files typed into the path field.
#![allow(clippy::unwrap_used)]

mod common;

use std::time::Duration;

use armor_studio::system::diagram::{Diagram, PinSide};
use common::*;
use egui::{Key, Modifiers, Pos2};
use egui_kittest::kittest::Queryable as _;

fn type_into(
    harness: &mut egui_kittest::Harness<'_, armor_studio::StudioApp>,
    label: &str,
    text: &str,
) {
    harness.get_by_label(label).click();
    harness.run();
    harness.get_by_label(label).type_text(text);
    harness.run();
}

#[test]
fn build_link_set_parameters_save_and_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(&dir.path().join("home"), None));

    // Three modules dragged from the palette.
    drop_module(&mut harness, "counter", Pos2::new(450.0, 200.0));
    drop_module(&mut harness, "checker", Pos2::new(750.0, 200.0));
    drop_module(&mut harness, "follower", Pos2::new(450.0, 450.0));
    let names: Vec<String> = harness
        .state()
        .editor()
        .diagram
        .blocks()
        .map(|(_, b)| b.name.clone())
        .collect();
    assert_eq!(names, ["counter", "checker", "follower"]);
    assert!(
        harness.state().title().starts_with('*'),
        "{}",
        harness.state().title()
    );

    // A compatible link: counter.count (Counter) → checker.input (Counter).
    let from = pin(&harness, "counter", "count", PinSide::Output);
    let to = pin(&harness, "checker", "input", PinSide::Input);
    drag(&mut harness, from, to);
    assert_eq!(harness.state().editor().diagram.links().count(), 1);

    // An incompatible one is refused, with the reason on screen.
    let to = pin(&harness, "follower", "odometry", PinSide::Input);
    drag(&mut harness, from, to);
    assert_eq!(harness.state().editor().diagram.links().count(), 1);
    harness.get_by_label_contains(
        "`follower.odometry` expects Odometry but `counter.count` is Counter",
    );

    // Input to input too.
    let from = pin(&harness, "checker", "input", PinSide::Input);
    drag(&mut harness, from, to);
    assert_eq!(harness.state().editor().diagram.links().count(), 1);
    harness.get_by_label_contains("cannot link two inputs");

    // The follower has two required parameters unset: saving writes a draft and names them,
    // and `armor check` refuses the draft with the reasons.
    harness.get_by_label("2 required unset");
    let file = dir.path().join("robot.xml");
    harness.key_press_modifiers(Modifiers::COMMAND, Key::S);
    harness.run();
    type_into(&mut harness, "Path:", &file.display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    harness.get_by_label_contains(
        "as a draft: required parameters unset: follower.goal_x_m, follower.goal_y_m",
    );
    let draft = armor_model::SystemConfig::parse(&std::fs::read_to_string(&file).unwrap()).unwrap();
    let draft_problems = armor_model::check(
        &draft,
        &armor_studio::common::palette::Palette::from_descriptions(descriptions()).catalog,
    );
    assert!(
        draft_problems
            .iter()
            .any(|problem| problem.message.contains("goal_x_m")),
        "{draft_problems:?}"
    );

    // Double-click the follower: its parameters, checked as they are typed.
    let at = harness.state().block_pos("follower").unwrap();
    double_click(&mut harness, at);
    harness.get_by_label("Block follower");
    type_into(&mut harness, "goal_x_m", "abc");
    harness.get_by_label("`abc` is not a finite number");
    assert!(
        harness
            .state()
            .editor()
            .diagram
            .missing_required(
                &harness.state().palette().catalog,
                harness
                    .state()
                    .editor()
                    .diagram
                    .block_named("follower")
                    .unwrap()
            )
            .len()
            == 2
    );
    for _ in 0..3 {
        harness.key_press(Key::Backspace);
    }
    harness.get_by_label("goal_x_m").type_text("1.5");
    harness.run();
    harness.get_by_label("1 required unset");
    type_into(&mut harness, "goal_y_m", "-2");
    assert!(harness.query_by_label("1 required unset").is_none());
    // The draft's warning is gone with its cause.
    assert!(
        !harness.state().status().text.contains("draft"),
        "{}",
        harness.state().status().text
    );
    // And a new name, unique.
    let name = harness.get_by_label("Name");
    name.click();
    harness.run();
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness.get_by_label("Name").type_text("counter");
    harness.run();
    harness.get_by_label("another block has this name");
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness.get_by_label("Name").type_text("nav");
    harness.run();
    harness.get_by_label("Close").click();
    harness.run();

    // Save again, to the draft's file: now complete, what `armor check` accepts.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::S);
    harness.run();
    assert!(
        harness.query_by_label("Path:").is_none(),
        "the file is known"
    );
    assert_eq!(
        harness.state().status().text,
        format!("saved {}", file.display())
    );
    assert_eq!(harness.state().title(), "robot.xml — ArMoR Studio");
    let text = std::fs::read_to_string(&file).unwrap();
    let system = armor_model::SystemConfig::parse(&text).unwrap();
    let catalog = armor_studio::common::palette::Palette::from_descriptions(descriptions()).catalog;
    assert_eq!(armor_model::check(&system, &catalog), []);
    assert!(
        text.contains(r#"<param name="goal_x_m" value="1.5"/>"#),
        "{text}"
    );
    assert!(
        text.contains(r#"<link from="counter.count" to="checker.input"/>"#),
        "{text}"
    );
    assert!(
        text.contains(r#"<module name="nav" type="follower""#),
        "{text}"
    );
    let saved = harness.state().editor().diagram.clone();

    // Reopen in a fresh studio: the same document, and it is in the recent files.
    let mut again = common::harness(options(&dir.path().join("home"), Some(file.clone())));
    assert_eq!(
        again.state().editor().diagram,
        Diagram::from_xml(&text).unwrap()
    );
    assert_eq!(again.state().editor().diagram.to_xml(), saved.to_xml());
    assert!(!again.state().is_dirty());
    again.get_by_label("File").click();
    again.run();
    again.get_by_label_contains("Open recent").hover();
    again.run();
    again.get_by_label(&std::path::absolute(&file).unwrap().display().to_string());
}

#[test]
fn undo_back_to_empty_and_redo() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(dir.path(), None));
    harness.get_by_label("add counter").click();
    harness.run();
    harness.get_by_label("add checker").click();
    harness.run();
    let from = pin(&harness, "counter", "count", PinSide::Output);
    let to = pin(&harness, "checker", "input", PinSide::Input);
    drag(&mut harness, from, to);
    assert_eq!(harness.state().editor().diagram.links().count(), 1);
    // Select all, duplicate, delete: every step undoable.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness.key_press_modifiers(Modifiers::COMMAND, Key::D);
    harness.run();
    assert_eq!(harness.state().editor().diagram.len(), 4);
    assert_eq!(harness.state().editor().diagram.links().count(), 2);
    harness.key_press(Key::Delete);
    harness.run();
    assert_eq!(harness.state().editor().diagram.len(), 2);

    let mut steps = 0;
    while harness.state().editor().history.can_undo() {
        harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
        harness.run();
        steps += 1;
        assert!(steps < 20, "undo does not end");
    }
    assert!(harness.state().editor().diagram.is_empty());
    assert!(!harness.state().title().starts_with('*'));
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Y);
    harness.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::Z);
    harness.run();
    assert_eq!(harness.state().editor().diagram.len(), 2);
}

#[test]
fn copy_paste_find_and_help() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(dir.path(), None));
    harness.get_by_label("add checker").click();
    harness.run();
    // The new block is selected: copy, paste twice.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::C);
    harness.key_press_modifiers(Modifiers::COMMAND, Key::V);
    harness.key_press_modifiers(Modifiers::COMMAND, Key::V);
    harness.run();
    let names: Vec<String> = harness
        .state()
        .editor()
        .diagram
        .blocks()
        .map(|(_, b)| b.name.clone())
        .collect();
    assert_eq!(names, ["checker", "checker_2", "checker_3"]);

    // Find a block by name: it becomes the selection.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::F);
    harness.run();
    harness.get_by_label("Find:").type_text("checker_2");
    harness.run();
    harness.key_press(Key::Enter);
    harness.run();
    let selected = &harness.state().editor().selection;
    let id = harness
        .state()
        .editor()
        .diagram
        .block_named("checker_2")
        .unwrap();
    assert_eq!(selected.iter().collect::<Vec<_>>(), [&id]);

    // A click on a block selects it; a click on empty canvas clears the selection.
    // (Block labels are drawn on the canvas's zoomed layer: the app says where they are.)
    let at = harness.state().block_pos("checker_3").unwrap();
    click(&mut harness, at);
    let id3 = harness
        .state()
        .editor()
        .diagram
        .block_named("checker_3")
        .unwrap();
    assert_eq!(
        harness
            .state()
            .editor()
            .selection
            .iter()
            .collect::<Vec<_>>(),
        [&id3]
    );
    let empty = harness.state().canvas_rect().left_bottom() + egui::vec2(20.0, -20.0);
    click(&mut harness, empty);
    assert!(harness.state().editor().selection.is_empty());

    // The shortcuts sheet.
    harness.key_press(Key::F1);
    harness.run();
    harness.get_by_label("Keyboard shortcuts");
    harness.get_by_label("Ctrl+Y, Ctrl+Shift+Z");
}

#[test]
fn problems_are_those_of_armor_check_and_select_their_block() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.xml");
    std::fs::write(
        &file,
        r#"<system name="bad">
  <module name="c" type="counter"/>
  <module name="f" type="follower">
    <param name="goal_x_m" value="1"/>
  </module>
  <link from="c.count" to="f.odometry"/>
</system>
"#,
    )
    .unwrap();
    let mut harness = harness(options(&dir.path().join("home"), Some(file.clone())));
    let problems = harness.state().problems().to_vec();
    // The same messages as the checker gives for the same file.
    let system =
        armor_model::SystemConfig::parse(&std::fs::read_to_string(&file).unwrap()).unwrap();
    let catalog = armor_studio::common::palette::Palette::from_descriptions(descriptions()).catalog;
    let mut expected: Vec<String> = armor_model::check(&system, &catalog)
        .into_iter()
        .map(|p| p.message)
        .collect();
    let mut shown: Vec<String> = problems.iter().map(|p| p.message.clone()).collect();
    expected.sort();
    shown.sort();
    assert_eq!(shown, expected);
    assert!(shown.len() >= 2, "{shown:?}");

    let problem = problems
        .iter()
        .find(|p| p.message.contains("goal_y_m"))
        .expect("the missing parameter is a problem");
    let label = format!("{}: {}", problem.pos, problem.message);
    harness.get_by_label(&label).click();
    harness.run();
    let f = harness.state().editor().diagram.block_named("f").unwrap();
    assert_eq!(
        harness
            .state()
            .editor()
            .selection
            .iter()
            .collect::<Vec<_>>(),
        [&f]
    );
}

#[test]
fn autosave_is_offered_back_after_a_crash() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = options(dir.path(), None);
    first.autosave_every = Duration::ZERO;
    let mut harness = harness(first);
    harness.get_by_label("add counter").click();
    harness.run();
    assert!(dir.path().join("recovery.xml").exists());
    // The studio "crashes": it is dropped without on_exit.
    drop(harness);

    let mut harness = common::harness(options(dir.path(), None));
    harness.get_by_label("Restore unsaved work?");
    harness.get_by_label("Restore").click();
    harness.run();
    assert_eq!(harness.state().editor().diagram.len(), 1);
    assert!(harness.state().is_dirty());
}

#[test]
fn the_palette_probes_real_binaries_and_lists_a_broken_one() {
    let dir = tempfile::tempdir().unwrap();
    let modules = dir.path().join("modules");
    std::fs::create_dir(&modules).unwrap();
    let description = descriptions().remove(0).to_xml();
    write_script(
        &modules.join("armor-mod-counter"),
        &format!("#!/bin/sh\ncat <<'END'\n{description}END\n"),
    );
    write_script(
        &modules.join("armor-mod-broken"),
        "#!/bin/sh\necho 'no describe mode here' >&2\nexit 3\n",
    );
    let mut options = options(&dir.path().join("home"), None);
    options.palette = None;
    options.module_path = vec![modules];
    let mut harness = harness(options);
    run_until(&mut harness, Duration::from_secs(30), |app| {
        !app.palette().is_probing()
    });
    harness.get_by_label("counter");
    harness.get_by_label("broken (broken)");
    harness.get_by_label_contains("--describe exited with");
}

fn write_script(path: &std::path::Path, text: &str) {
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::write(path, text).unwrap();
    std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

/// A studio on a diagram of 400 blocks, which opens as the overview.
fn large_diagram(dir: &std::path::Path) -> egui_kittest::Harness<'static, armor_studio::StudioApp> {
    let file = dir.join("large.xml");
    std::fs::write(&file, armor_studio_bench::diagram(400, 600).to_xml()).unwrap();
    let mut options = options(&dir.join("home"), Some(file));
    options.palette = Some(armor_studio::common::palette::Palette::from_descriptions([
        armor_studio_bench::relay(),
    ]));
    harness(options)
}

/// Zooms the canvas out (as Ctrl+wheel or a pinch would) about its centre until it shows the
/// overview.
fn zoom_out_to_overview(harness: &mut egui_kittest::Harness<'_, armor_studio::StudioApp>) {
    let centre = harness.state().canvas_rect().center();
    harness.hover_at(centre);
    for _ in 0..20 {
        if harness.state().is_overview() {
            break;
        }
        harness.event(egui::Event::Zoom(0.8));
        harness.run_steps(2);
    }
    assert!(harness.state().is_overview());
}

#[test]
fn a_large_diagram_opens_named_and_a_double_click_in_the_overview_zooms_in() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = large_diagram(dir.path());
    // Fit stops at the zoom at which names are drawn: the middle of the diagram, named.
    assert!(!harness.state().is_overview());
    zoom_out_to_overview(&mut harness);
    // No block is a widget in the overview: their names are not on screen as text. They are
    // painted, where they fit at a readable size: just below the detail zoom, every block's.
    assert!(harness.query_by_label("relay_221").is_none());
    assert!(
        harness
            .state()
            .overview_names()
            .iter()
            .any(|name| name == "relay_221"),
        "{:?}",
        harness.state().overview_names()
    );
    // Zoomed far out, names that would not fit are left out rather than run together.
    let centre = harness.state().canvas_rect().center();
    harness.hover_at(centre);
    for _ in 0..12 {
        harness.event(egui::Event::Zoom(0.7));
        harness.run_steps(2);
    }
    assert!(harness.state().canvas_transform().scaling < 0.08);
    assert!(harness.state().overview_names().is_empty());
    harness.key_press(Key::Home);
    harness.run_steps(3);
    zoom_out_to_overview(&mut harness);
    let at = harness.state().block_pos("relay_221").unwrap();
    double_click(&mut harness, at);
    harness.run_steps(3);
    assert!(!harness.state().is_overview());
    harness.get_by_label("relay_221");
    // Home fits again, never into the overview.
    zoom_out_to_overview(&mut harness);
    harness.key_press(Key::Home);
    harness.run_steps(3);
    assert!(!harness.state().is_overview());
}

/// Clicks `item` in the File menu.
fn file_menu(harness: &mut egui_kittest::Harness<'_, armor_studio::StudioApp>, item: &str) {
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label(item).click();
    harness.run();
}

#[test]
fn replacing_a_changed_system_asks_first_and_can_save_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("kept.xml");
    let mut harness = harness(options(&dir.path().join("home"), None));
    harness.get_by_label("add counter").click();
    harness.run();
    let blocks = |harness: &egui_kittest::Harness<'_, armor_studio::StudioApp>| {
        harness.state().editor().diagram.blocks().count()
    };
    assert_eq!(blocks(&harness), 1);

    // New, then Cancel: nothing changes.
    file_menu(&mut harness, "New");
    harness.get_by_label("the new system has unsaved changes, lost if not saved.");
    harness.get_by_label("Cancel").click();
    harness.run();
    assert!(harness.query_by_label("Save changes?").is_none());
    assert_eq!(blocks(&harness), 1);
    assert!(harness.state().is_dirty());

    // New, then Save: the document has no file yet, so the path is asked, the system saved
    // there, and then the new document made.
    file_menu(&mut harness, "New");
    harness.get_by_label("Save").click();
    harness.run();
    type_into(&mut harness, "Path:", &file.display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    let saved = std::fs::read_to_string(&file).unwrap();
    assert!(saved.contains(r#"type="counter""#), "{saved}");
    assert_eq!(blocks(&harness), 0, "then the new system");
    assert!(!harness.state().is_dirty());

    // Open the saved file over a changed document and give the changes up.
    harness.get_by_label("add checker").click();
    harness.run();
    file_menu(&mut harness, "Open…");
    type_into(&mut harness, "Path:", &file.display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    harness.get_by_label("Save changes?");
    harness.get_by_label("Don't save").click();
    harness.run();
    assert_eq!(
        harness.state().editor().diagram,
        Diagram::from_xml(&saved).unwrap(),
        "the file as saved"
    );
    assert_eq!(
        std::fs::read_to_string(&file).unwrap(),
        saved,
        "and left alone"
    );
}

#[test]
fn closing_the_window_with_changes_asks_first() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(&dir.path().join("home"), None));
    let close = |harness: &mut egui_kittest::Harness<'_, armor_studio::StudioApp>| {
        let root = harness
            .input_mut()
            .viewports
            .entry(egui::ViewportId::ROOT)
            .or_default();
        root.events.push(egui::ViewportEvent::Close);
        harness.step();
        let root = harness
            .input_mut()
            .viewports
            .entry(egui::ViewportId::ROOT)
            .or_default();
        root.events.clear();
        harness.run();
    };
    // Nothing changed: nothing asked.
    close(&mut harness);
    assert!(harness.query_by_label("Save changes?").is_none());

    harness.get_by_label("add counter").click();
    harness.run();
    close(&mut harness);
    harness.get_by_label("the new system has unsaved changes, lost if not saved.");
    harness.get_by_label("Cancel").click();
    harness.run();
    assert!(harness.query_by_label("Save changes?").is_none());
    assert_eq!(harness.state().editor().diagram.blocks().count(), 1);
}

/// The text the last frame put on the system clipboard.
fn copied_text(harness: &egui_kittest::Harness<'_, armor_studio::StudioApp>) -> Option<String> {
    harness
        .output()
        .platform_output
        .commands
        .iter()
        .find_map(|command| match command {
            egui::OutputCommand::CopyText(text) => Some(text.clone()),
            _ => None,
        })
}

/// The blocks of the document: name, type and parameters, and its links.
fn contents(harness: &egui_kittest::Harness<'_, armor_studio::StudioApp>) -> String {
    let diagram = &harness.state().editor().diagram;
    armor_studio::system::diagram::Diagram::to_system(diagram).to_xml()
}

#[test]
fn blocks_cut_and_pasted_through_the_system_clipboard_as_system_xml() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("pair.xml");
    std::fs::write(
        &file,
        r#"<system name="pair">
  <module name="counter" type="counter"><param name="period_secs" value="0.5"/></module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#,
    )
    .unwrap();
    let mut studio = harness(options(&dir.path().join("home"), Some(file)));
    let original = contents(&studio);

    // Copy (Ctrl+C, which a window turns into a copy event): the selection goes on the system
    // clipboard as a system file of its own.
    studio.key_press_modifiers(Modifiers::COMMAND, Key::A);
    studio.run();
    studio.event(egui::Event::Copy);
    studio.step();
    let copied = copied_text(&studio).expect("the copy is on the system clipboard");
    let system = armor_model::system::SystemConfig::parse(&copied).expect("a system file");
    assert_eq!(system.modules.len(), 2, "{copied}");
    assert_eq!(system.links.len(), 1, "{copied}");
    assert!(copied.contains(r#"value="0.5""#), "{copied}");

    // Another studio pastes it: the same blocks, link and parameters.
    let mut other = harness(options(&dir.path().join("home2"), None));
    other.event(egui::Event::Paste(copied.clone()));
    other.run();
    assert_eq!(
        contents(&other),
        original.replace(r#"name="pair""#, r#"name="system""#)
    );
    assert_eq!(other.state().status().text, "pasted 2 blocks");

    // Text that is no system is refused, and changes nothing.
    other.event(egui::Event::Paste("checker counter".to_owned()));
    other.run();
    assert!(other.state().status().is_error);
    assert!(
        other
            .state()
            .status()
            .text
            .contains("the clipboard holds no system file (1:1: "),
        "{}",
        other.state().status().text
    );
    assert_eq!(other.state().editor().diagram.len(), 2);

    // Cut: the blocks go, onto the clipboard; pasted back, they return under their names;
    // undo takes the paste and the cut back one at a time.
    studio.event(egui::Event::Cut);
    studio.step();
    let cut = copied_text(&studio).expect("the cut is on the system clipboard");
    assert_eq!(cut, copied);
    studio.run();
    assert!(studio.state().editor().diagram.is_empty());
    assert_eq!(studio.state().status().text, "cut 2 blocks");
    studio.event(egui::Event::Paste(cut));
    studio.run();
    assert_eq!(contents(&studio), original);
    studio.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    studio.run();
    assert!(studio.state().editor().diagram.is_empty());
    studio.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    studio.run();
    assert_eq!(contents(&studio), original);
}

#[test]
fn a_block_dragged_out_of_a_selected_group_moves_the_whole_group() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(dir.path(), None));
    for module in ["counter", "checker", "follower"] {
        harness.get_by_label(&format!("add {module}")).click();
        harness.run();
    }
    let positions = |harness: &egui_kittest::Harness<'_, armor_studio::StudioApp>| {
        let diagram = &harness.state().editor().diagram;
        diagram
            .blocks()
            .map(|(_, block)| (block.name.clone(), block.pos))
            .collect::<Vec<_>>()
    };
    let before = positions(&harness);
    // Select all, then drag one block by its header.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness.run();
    let from = harness.state().block_header_pos("checker").unwrap();
    drag(&mut harness, from, from + egui::vec2(120.0, 60.0));
    let after = positions(&harness);
    let moved: Vec<[f32; 2]> = before
        .iter()
        .zip(&after)
        .map(|((_, a), (_, b))| [b[0] - a[0], b[1] - a[1]])
        .collect();
    assert!(
        moved[1][0] > 10.0 && moved[1][1] > 5.0,
        "{before:?} → {after:?}"
    );
    assert!(
        moved.iter().all(|delta| delta == &moved[1]),
        "every block moved alike: {moved:?}"
    );
    // The move is one step of the history; drawn where the document says.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    harness.run();
    assert_eq!(positions(&harness), before);
}

#[test]
fn blocks_are_dragged_in_the_overview_too() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = large_diagram(dir.path());
    zoom_out_to_overview(&mut harness);
    let position = |harness: &egui_kittest::Harness<'_, armor_studio::StudioApp>, name: &str| {
        let diagram = &harness.state().editor().diagram;
        diagram
            .block(diagram.block_named(name).unwrap())
            .unwrap()
            .pos
    };
    let before = harness.state().editor().diagram.clone();
    let start = position(&harness, "relay_221");
    let from = harness.state().block_pos("relay_221").unwrap();
    drag(&mut harness, from, from + egui::vec2(40.0, 25.0));
    let end = position(&harness, "relay_221");
    // The block followed the pointer, at the overview's scale (far more than 40 units).
    assert!(
        end[0] - start[0] > 60.0 && end[1] - start[1] > 35.0,
        "{start:?} → {end:?}"
    );
    assert_eq!(
        position(&harness, "relay_222"),
        before
            .block(before.block_named("relay_222").unwrap())
            .unwrap()
            .pos
    );
    assert!(
        harness.state().is_overview(),
        "the view did not pan or zoom"
    );
    // One undo step.
    harness.key_press_modifiers(Modifiers::COMMAND, Key::Z);
    harness.run();
    assert!(harness.state().editor().diagram == before);
    // A drag on empty canvas still pans the view, and moves no block.
    let seen = harness.state().block_pos("relay_221").unwrap();
    let empty = harness.state().canvas_rect().left_bottom() + egui::vec2(20.0, -20.0);
    drag(&mut harness, empty, empty + egui::vec2(50.0, -30.0));
    assert!(harness.state().editor().diagram == before);
    let now = harness.state().block_pos("relay_221").unwrap();
    let panned = now - seen;
    assert!(panned.x > 25.0 && panned.y < -15.0, "{seen:?} → {now:?}");
}

#[test]
fn a_path_offered_in_the_dialog_is_replaced_by_what_is_typed() {
    let dir = tempfile::tempdir().unwrap();
    let first = dir.path().join("first.xml");
    std::fs::write(
        &first,
        r#"<system name="s"><module name="counter" type="counter"/></system>"#,
    )
    .unwrap();
    let mut harness = harness(options(&dir.path().join("home"), Some(first.clone())));
    harness.run();
    // Save as: the dialog offers the current path, selected; typing replaces it whole.
    harness.key_press_modifiers(Modifiers::COMMAND | Modifiers::SHIFT, Key::S);
    harness.run();
    let second = dir.path().join("second.xml");
    harness
        .get_by_label("Path:")
        .type_text(&second.display().to_string());
    harness.run();
    harness.key_press(Key::Enter);
    harness.run();
    assert!(
        second.exists(),
        "saved where typed: {}",
        harness.state().status().text
    );
    assert_eq!(harness.state().title(), "second.xml — ArMoR Studio");
}

#[test]
fn an_empty_studio_offers_a_start_page_with_the_examples() {
    let dir = tempfile::tempdir().unwrap();
    let mut options = options(&dir.path().join("home"), None);
    options.start_page = true;
    let mut harness = harness(options);
    harness.run();
    harness.get_by_label("New system");
    harness.get_by_label("New plan");
    harness.get_by_label("Recent files");
    // The bundled examples, from the checkout's missions/ folder; one opens in its view.
    harness.get_by_label("robot/plan-yard.xml").click();
    harness.run();
    harness.run();
    assert_eq!(harness.state().view(), armor_studio::app::View::Mission);
    let mission = harness.state().mission().unwrap();
    assert_eq!(mission.plan().name, "yard-recon");
    assert!(
        harness.query_by_label("New plan").is_none(),
        "the page is gone"
    );
}

#[test]
fn the_parameter_dialog_shows_and_enforces_the_declared_range() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(&dir.path().join("home"), None));
    drop_module(&mut harness, "counter", Pos2::new(450.0, 200.0));
    let at = harness.state().block_pos("counter").unwrap();
    double_click(&mut harness, at);
    harness.get_by_label("Block counter");
    harness.get_by_label("allowed: greater than 0 s");
    type_into(&mut harness, "period_secs", "0");
    harness.get_by_label("`0` is not greater than 0 s");
    harness.key_press(Key::Backspace);
    harness.get_by_label("period_secs").type_text("0.5");
    harness.run();
    assert!(
        harness
            .query_by_label("`0` is not greater than 0 s")
            .is_none()
    );
    assert!(
        harness
            .query_by_label("`0.5` is not greater than 0 s")
            .is_none()
    );
    harness.get_by_label("ok");
}
