//! The start page: what an empty studio shows instead of a blank canvas — the recent files,
//! the bundled examples, and the ways to begin (a new system, a new plan, a file to open).

use std::path::{Path, PathBuf};

use egui::{RichText, Ui};

/// What the user chose on the start page.
#[derive(Clone, Debug, PartialEq)]
pub enum StartChoice {
    NewSystem,
    NewPlan,
    Open,
    /// A system or a plan (the studio tells them apart by their root element).
    File(PathBuf),
}

/// The bundled examples' folder, `missions/`, found from the current folder or the folders above
/// the studio's executable (a checkout's `target/debug/`), the first found.
pub fn missions_folder() -> Option<PathBuf> {
    let mut roots: Vec<PathBuf> = Vec::new();
    if let Ok(dir) = std::env::current_dir() {
        roots.extend(dir.ancestors().map(Path::to_path_buf));
    }
    if let Ok(exe) = std::env::current_exe() {
        roots.extend(exe.ancestors().skip(1).map(Path::to_path_buf));
    }
    roots
        .into_iter()
        .map(|root| root.join("missions"))
        .find(|dir| dir.is_dir())
}

/// The bundled examples: the system and plan files of `missions/*/` ([`missions_folder`]).
pub fn examples() -> Vec<PathBuf> {
    let Some(missions) = missions_folder() else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&missions)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|entry| entry.path().is_dir())
        .flat_map(|dir| {
            std::fs::read_dir(dir.path())
                .into_iter()
                .flatten()
                .flatten()
        })
        .map(|entry| entry.path())
        .filter(|path| {
            path.extension().is_some_and(|ext| ext == "xml")
                && path.file_name().is_some_and(|name| {
                    let name = name.to_string_lossy();
                    name.starts_with("system") || name.starts_with("plan")
                })
        })
        .collect();
    files.sort();
    files
}

/// A file's name with its folder's: `demo/system.xml` and `robot/system.xml` differ.
pub fn short_name(file: &Path) -> String {
    let parts: Vec<_> = file.iter().rev().take(2).collect();
    parts
        .into_iter()
        .rev()
        .map(|part| part.to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// Shows the start page in `ui`; the choice once made.
pub fn start_ui(ui: &mut Ui, recent: &[PathBuf], examples: &[PathBuf]) -> Option<StartChoice> {
    let mut choice = None;
    ui.vertical_centered(|ui| {
        ui.add_space(ui.available_height() * 0.08);
        ui.heading("ArMoR Studio");
        ui.label(
            "Build a robot's modules as a block diagram, plan its mission on a map, and run it.",
        );
        ui.add_space(12.0);
        ui.horizontal(|ui| {
            ui.add_space((ui.available_width() - 380.0).max(0.0) / 2.0);
            if ui.button("New system").clicked() {
                choice = Some(StartChoice::NewSystem);
            }
            if ui.button("New plan").clicked() {
                choice = Some(StartChoice::NewPlan);
            }
            if ui.button("Open…").clicked() {
                choice = Some(StartChoice::Open);
            }
        });
    });
    ui.add_space(16.0);
    ui.columns(2, |columns| {
        let mut list = |ui: &mut Ui, title: &str, files: &[PathBuf], empty: &str| {
            ui.label(RichText::new(title).strong());
            if files.is_empty() {
                ui.label(RichText::new(empty).weak());
            }
            for file in files {
                if ui
                    .link(short_name(file))
                    .on_hover_text(file.display().to_string())
                    .clicked()
                {
                    choice = Some(StartChoice::File(file.clone()));
                }
            }
        };
        list(&mut columns[0], "Recent files", recent, "none yet");
        list(
            &mut columns[1],
            "Examples",
            examples,
            "no missions/ folder found here",
        );
    });
    choice
}
