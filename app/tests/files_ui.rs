//! Issue 37, defect 1: files are picked in the studio's own browser (opened in the document's
//! folder) wherever a path was only typed, errors about files are said in words, and the start
//! page's examples and recent files stay reachable after a failed Open.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;
use std::time::{Duration, Instant};

use armor_module_api::ModuleDescription;
use armor_module_api::describe::{ParamSpec, ParamType};
use armor_studio::StudioApp;
use armor_studio::common::palette::Palette;
use common::{double_click, harness, options};
use egui::{Key, Modifiers};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

fn type_into(harness: &mut Harness<'_, StudioApp>, label: &str, text: &str) {
    harness.get_by_label(label).click();
    harness.run();
    harness.get_by_label(label).type_text(text);
    harness.run();
}

/// Runs frames until a widget whose label contains `text` is shown (the browser reads its
/// folder in the background), failing after a deadline.
fn wait_for_label(harness: &mut Harness<'_, StudioApp>, text: &str) {
    let deadline = Instant::now() + Duration::from_secs(20);
    while harness.query_by_label_contains(text).is_none() {
        assert!(
            Instant::now() < deadline,
            "no `{text}` shown within 20 s; status: {}",
            harness.state().status().text
        );
        harness.step();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Double-clicks the browser's entry whose label contains `name`.
fn double_click_entry(harness: &mut Harness<'_, StudioApp>, name: &str) {
    let at = harness.get_by_label_contains(name).rect().center();
    double_click(harness, at);
    harness.run();
}

#[test]
fn a_failed_open_says_why_in_words_and_keeps_the_start_page_and_its_examples() {
    let dir = tempfile::tempdir().unwrap();
    let mut options = options(&dir.path().join("home"), None);
    options.start_page = true;
    let mut harness = harness(options);
    harness.get_by_label("robot/plan-yard.xml");
    harness.get_by_label("Open…").click();
    harness.run();
    let missing = dir.path().join("nothing-here.xml");
    type_into(&mut harness, "Path:", &missing.display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    let status = harness.state().status().text.clone();
    assert!(
        status.contains("there is no such file") && !status.contains("os error"),
        "{status}"
    );
    // The start page is back, its examples with it.
    harness.get_by_label("robot/plan-yard.xml");
    harness.get_by_label("Recent files");
    // A folder given where a file is wanted: said so, in words.
    harness.get_by_label("Open…").click();
    harness.run();
    type_into(&mut harness, "Path:", &dir.path().display().to_string());
    harness.key_press(Key::Enter);
    harness.run();
    let status = harness.state().status().text.clone();
    assert!(
        status.contains("is a folder, not a file") && !status.contains("os error"),
        "{status}"
    );
    // The File menu lists the examples too; one opens in its view (a plan: the Mission view).
    harness.get_by_label("New system").click();
    harness.run();
    assert!(harness.query_by_label("Recent files").is_none());
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label("Examples ⏵").click();
    harness.run();
    harness.get_by_label("robot/plan-yard.xml").click();
    harness.run();
    harness.run();
    assert_eq!(harness.state().view(), armor_studio::app::View::Mission);
    assert_eq!(harness.state().mission().unwrap().plan().name, "yard-recon");
    // And from the Mission view's File menu, Open recent lists the plan opened.
    harness.get_by_label("File").click();
    harness.run();
    harness.get_by_label("Open recent ⏵").click();
    harness.run();
    let example = armor_studio::start::examples()
        .into_iter()
        .find(|file| file.ends_with("robot/plan-yard.xml"))
        .unwrap();
    let recent = std::path::absolute(&example).unwrap();
    harness.get_by_role_and_label(egui::accesskit::Role::Button, &recent.display().to_string());
}

#[test]
fn open_browses_the_documents_folder_and_opens_the_file_picked() {
    let dir = tempfile::tempdir().unwrap();
    let docs = dir.path().join("docs");
    std::fs::create_dir(&docs).unwrap();
    let system = "<system name=\"s\">\n<module name=\"counter\" type=\"counter\"/>\n</system>\n";
    let first = docs.join("first.xml");
    let second = docs.join("second-system.xml");
    std::fs::write(&first, system).unwrap();
    std::fs::write(&second, system).unwrap();
    let mut harness = harness(options(&dir.path().join("home"), Some(first.clone())));
    assert_eq!(harness.state().path(), Some(first.as_path()));
    harness.key_press_modifiers(Modifiers::COMMAND, Key::O);
    harness.run();
    harness.get_by_label("Browse…").click();
    harness.run();
    // The browser shows the document's folder: its other file is listed, to be picked.
    wait_for_label(&mut harness, "second-system.xml");
    assert!(
        harness.query_by_label("Path:").is_none(),
        "the path field gives way to the browser"
    );
    double_click_entry(&mut harness, "second-system.xml");
    assert_eq!(
        harness.state().path(),
        Some(second.as_path()),
        "status: {}",
        harness.state().status().text
    );
}

#[test]
fn a_file_parameter_is_picked_in_a_browser_and_named_as_armor_run_finds_it() {
    let dir = tempfile::tempdir().unwrap();
    let docs = dir.path().join("robot");
    std::fs::create_dir(&docs).unwrap();
    std::fs::write(docs.join("hall.world"), "# a world\n").unwrap();
    let file = docs.join("system.xml");
    std::fs::write(
        &file,
        "<system name=\"s\">\n<module name=\"sim\" type=\"sim\"/>\n</system>\n",
    )
    .unwrap();
    let mut sim = ModuleDescription::new("sim", "A simulator of a world.");
    sim.params
        .push(ParamSpec::new("world", ParamType::String, "the world file").file("worlds"));
    let mut options = options(&dir.path().join("home"), Some(file.clone()));
    options.palette = Some(Palette::from_descriptions(vec![sim]));
    let mut harness = harness(options);
    harness.run();
    let at = harness.state().block_pos("sim").unwrap();
    double_click(&mut harness, at);
    harness.get_by_label("Block sim");
    harness.get_by_label("Browse…").click();
    harness.run();
    wait_for_label(&mut harness, "hall.world");
    double_click_entry(&mut harness, "hall.world");
    harness.run();
    let diagram = &harness.state().editor().diagram;
    let block = diagram.block(diagram.block_named("sim").unwrap()).unwrap();
    assert_eq!(
        block.params.get("world").map(String::as_str),
        Some("hall.world"),
        "the world beside the system file is named as armor run finds it"
    );
    assert!(Path::new(&docs.join("hall.world")).exists());
}

/// A key held down arrives again as repeats (and a loaded machine that is slow to see a key
/// released repeats it too): Ctrl+O opens its dialog once, and the repeats neither open it
/// again nor throw away what was typed in it.
#[test]
fn a_held_ctrl_o_opens_one_dialog_and_keeps_what_was_typed() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(options(&dir.path().join("home"), None));
    // Pressed and not released: the presses that follow are the keyboard's repeats (egui
    // marks a press of a key already down as a repeat).
    harness.key_down_modifiers(Modifiers::COMMAND, Key::O);
    harness.run();
    type_into(&mut harness, "Path:", "typed-before-the-repeat.xml");
    let typed = harness.get_by_label("Path:").value().unwrap_or_default();
    assert!(typed.ends_with("typed-before-the-repeat.xml"), "{typed:?}");
    for _ in 0..3 {
        harness.key_down_modifiers(Modifiers::COMMAND, Key::O);
        harness.run();
    }
    harness.key_up_modifiers(Modifiers::COMMAND, Key::O);
    harness.run();
    let field = harness.get_by_label("Path:").value().unwrap_or_default();
    assert!(field.ends_with("typed-before-the-repeat.xml"), "{field:?}");
}
