//! A block's dialog: its name and its parameters, each checked as typed against the module's
//! description; a value reaches the document only once it is valid. A parameter that names a
//! file (a world, a map) has a Browse… button: the file is picked, not typed.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use egui::{RichText, Ui};

use super::{ERROR, OK, SystemView};
use crate::browser::{Browser, BrowserAnswer, BrowserRequest};
use crate::common::palette::Catalog;
use crate::system::diagram::BlockId;
use crate::system::editor::Command;

/// The parameters dialog of one block, with what the user is typing.
pub(super) struct ParamsDialog {
    block: BlockId,
    name: String,
    values: BTreeMap<String, String>,
    /// The browser of a file parameter (its name), while it is open.
    browser: Option<(String, Browser)>,
}

impl SystemView {
    pub(super) fn open_params(&mut self, block: BlockId) {
        let Some(found) = self.editor.diagram.block(block) else {
            return;
        };
        self.params = Some(ParamsDialog {
            block,
            name: found.name.clone(),
            values: found.params.clone(),
            browser: None,
        });
    }

    /// The parameters dialog of the block opened, over the window.
    pub fn params_ui(&mut self, ui: &mut Ui, catalog: &Catalog) {
        let ctx = &ui.ctx().clone();
        let Some(dialog) = &mut self.params else {
            return;
        };
        let Some(block) = self.editor.diagram.block(dialog.block) else {
            self.params = None;
            return;
        };
        let description = catalog.get(&block.module_type);
        let system_folder = self
            .path
            .as_deref()
            .and_then(Path::parent)
            .map(Path::to_path_buf);
        // A file picked in a parameter's browser is its value, as if typed.
        let mut picked = None;
        if let Some((param, browser)) = &mut dialog.browser {
            match browser.ui(ctx) {
                None => {}
                Some(BrowserAnswer::Picked(file)) => {
                    let assets = description
                        .and_then(|d| d.param(param))
                        .and_then(|spec| spec.file.clone())
                        .unwrap_or_default();
                    let value = param_value_of(&file, system_folder.as_deref(), &assets);
                    picked = Some((param.clone(), value));
                    dialog.browser = None;
                }
                Some(BrowserAnswer::Cancelled) => dialog.browser = None,
            }
        }
        let mut open = true;
        let mut close = false;
        egui::Window::new(format!("Block {}", block.name))
            .id(egui::Id::new("params"))
            .open(&mut open)
            .collapsible(false)
            .default_width(560.0)
            .show(ctx, |ui| {
                ui.horizontal(|ui| {
                    let label = ui.label("Name");
                    let edit = ui
                        .add(egui::TextEdit::singleline(&mut dialog.name).id_salt("name"))
                        .labelled_by(label.id);
                    let taken = self
                        .editor
                        .diagram
                        .block_named(&dialog.name)
                        .is_some_and(|other| other != dialog.block);
                    let valid = armor_module_api::describe::is_identifier(&dialog.name);
                    if !valid {
                        ui.colored_label(ERROR, "letters, digits and _, starting with a letter");
                    } else if taken {
                        ui.colored_label(ERROR, "another block has this name");
                    } else if edit.changed() {
                        self.commands.push(Command::Rename {
                            block: dialog.block,
                            name: dialog.name.clone(),
                        });
                    }
                });
                ui.label(RichText::new(format!("type {}", block.module_type)).weak());
                let Some(description) = description else {
                    ui.colored_label(ERROR, "this module type is unknown: no parameters to show");
                    return;
                };
                if let Some(doc) = Some(&description.doc).filter(|doc| !doc.is_empty()) {
                    ui.label(RichText::new(doc).small());
                }
                ui.separator();
                if description.params.is_empty() {
                    ui.label("This module has no parameters.");
                }
                // One block of lines per parameter (not a grid): long docs wrap at the
                // window's width instead of widening it, and long lists scroll.
                egui::ScrollArea::vertical()
                    .max_height(460.0)
                    .show(ui, |ui| {
                        for spec in &description.params {
                            let unit = if spec.unit.is_empty() {
                                String::new()
                            } else {
                                format!(" [{}]", spec.unit)
                            };
                            let default = match &spec.default {
                                Some(default) if default.is_empty() => "default: empty".to_owned(),
                                Some(default) => format!("default {default}"),
                                None => "required".to_owned(),
                            };
                            let value = dialog.values.entry(spec.name.clone()).or_default();
                            let picked_here = picked
                                .as_ref()
                                .is_some_and(|(param, _)| *param == spec.name);
                            if let Some((_, file)) = picked.as_ref().filter(|_| picked_here) {
                                value.clone_from(file);
                            }
                            let mut browse = false;
                            let (edit, verdict) = ui
                                .horizontal(|ui| {
                                    let label = ui.label(RichText::new(&spec.name).strong());
                                    ui.label(format!("{}{unit}", spec.param_type.as_str()));
                                    ui.label(RichText::new(&default).weak());
                                    let edit = ui
                                        .add(
                                            egui::TextEdit::singleline(value)
                                                .id_salt(("param", &spec.name))
                                                .hint_text(&default)
                                                .desired_width(140.0),
                                        )
                                        .labelled_by(label.id);
                                    if let Some(assets) = &spec.file {
                                        browse = ui
                                            .button("Browse…")
                                            .on_hover_text(format!(
                                                "Pick the file (found beside the system file, \
                                                 or in assets/{assets}/)"
                                            ))
                                            .clicked();
                                    }
                                    // Checked as typed: the verdict is of this frame's text.
                                    let trimmed = value.trim().to_owned();
                                    let verdict = if trimmed.is_empty() {
                                        if spec.is_required() {
                                            Err("required: set a value".to_owned())
                                        } else {
                                            Ok(None)
                                        }
                                    } else {
                                        spec.check_value(&trimmed)
                                            .map(|()| Some(trimmed))
                                            .map_err(|why| why.to_string())
                                    };
                                    match &verdict {
                                        Ok(_) => ui.colored_label(OK, "ok"),
                                        Err(reason) => ui.colored_label(ERROR, reason),
                                    };
                                    (edit, verdict)
                                })
                                .inner;
                            if spec.is_limited() {
                                ui.label(
                                    RichText::new(format!("allowed: {}", spec.range_text()))
                                        .small(),
                                );
                            }
                            if !spec.doc.is_empty() {
                                ui.add(
                                    egui::Label::new(RichText::new(&spec.doc).small().weak())
                                        .wrap(),
                                );
                            }
                            ui.add_space(6.0);
                            // A value is written to the document only once it is valid, so the
                            // document never holds a value `armor check` would refuse; an emptied
                            // field returns the parameter to its default.
                            if browse && let Some(assets) = &spec.file {
                                let request = BrowserRequest {
                                    title: &format!("Choose the file of `{}`", spec.name),
                                    folder: param_folder(value, system_folder.as_deref(), assets),
                                    document_folder: system_folder.clone(),
                                    filter: ("Any file", &[]),
                                    save_as: None,
                                    folder_wanted: false,
                                };
                                dialog.browser = Some((spec.name.clone(), Browser::open(request)));
                            }
                            if edit.changed() || picked_here {
                                let value = match verdict {
                                    Ok(value) => Some(value),
                                    Err(_) if value.trim().is_empty() => Some(None),
                                    Err(_) => None,
                                };
                                if let Some(value) = value {
                                    self.commands.push(Command::SetParam {
                                        block: dialog.block,
                                        name: spec.name.clone(),
                                        value,
                                    });
                                }
                            }
                        }
                    });
                ui.separator();
                if ui.button("Close").clicked() {
                    close = true;
                }
            });
        if !open || close {
            self.params = None;
        }
    }
}

/// The value a parameter naming a file gets for `file` picked in the browser: as `armor run`
/// finds it from the system's folder (`system_folder`, when the system has a file) or under
/// `assets/ASSETS/`: its bare name when that finds this very file, else its path from the
/// system's folder, else (a system never saved) the whole path.
fn param_value_of(file: &Path, system_folder: Option<&Path>, assets: &str) -> String {
    let same = |found: &Path| match (std::fs::canonicalize(found), std::fs::canonicalize(file)) {
        (Ok(found), Ok(file)) => found == file,
        _ => false,
    };
    let folder = system_folder.map_or_else(
        || std::env::current_dir().unwrap_or_default(),
        Path::to_path_buf,
    );
    if let Some(name) = file
        .file_name()
        .map(|name| name.to_string_lossy().into_owned())
        && armor_runtime::paths::resolve(&name, &folder, &[], assets)
            .is_ok_and(|found| same(&found))
    {
        return name;
    }
    match system_folder {
        Some(folder) => armor_runtime::fs::relative_path(file, folder)
            .display()
            .to_string(),
        None => std::path::absolute(file)
            .unwrap_or_else(|_| file.to_path_buf())
            .display()
            .to_string(),
    }
}

/// The folder a parameter's browser opens in: that of the file its value names now, else the
/// system's, else the current folder's `assets/ASSETS/`, else the current folder.
fn param_folder(value: &str, system_folder: Option<&Path>, assets: &str) -> PathBuf {
    let cwd = std::env::current_dir().unwrap_or_default();
    let from = system_folder.unwrap_or(&cwd);
    let current = Some(value.trim())
        .filter(|value| !value.is_empty())
        .and_then(|value| armor_runtime::paths::resolve(value, from, &[], assets).ok())
        .and_then(|found| found.parent().map(Path::to_path_buf));
    let assets_here = Some(cwd.join("assets").join(assets)).filter(|dir| dir.is_dir());
    current
        .or_else(|| system_folder.map(Path::to_path_buf))
        .or(assets_here)
        .unwrap_or(cwd)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn a_picked_file_is_named_as_armor_run_finds_it() {
        let dir = tempfile::tempdir().unwrap();
        let worlds = dir.path().join("assets").join("worlds");
        std::fs::create_dir_all(&worlds).unwrap();
        let yard = worlds.join("yard.world");
        std::fs::write(&yard, "world").unwrap();
        let robot = dir.path().join("robot");
        std::fs::create_dir(&robot).unwrap();
        // Found under assets/worlds/ of a folder above the system's: its bare name.
        assert_eq!(param_value_of(&yard, Some(&robot), "worlds"), "yard.world");
        // Beside the system: its bare name; elsewhere, its path from the system's folder.
        let beside = robot.join("here.world");
        std::fs::write(&beside, "world").unwrap();
        assert_eq!(
            param_value_of(&beside, Some(&robot), "worlds"),
            "here.world"
        );
        let other = dir.path().join("maps");
        std::fs::create_dir(&other).unwrap();
        let far = other.join("far.world");
        std::fs::write(&far, "world").unwrap();
        assert_eq!(
            param_value_of(&far, Some(&robot), "worlds"),
            Path::new("..")
                .join("maps")
                .join("far.world")
                .display()
                .to_string()
        );
        assert_eq!(param_folder("yard.world", Some(&robot), "worlds"), worlds);
        assert_eq!(param_folder("", Some(&robot), "worlds"), robot);
    }
}
