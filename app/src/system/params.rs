//! A block's dialog: its name and its parameters, each checked as typed against the module's
//! description; a value reaches the document only once it is valid.

use std::collections::BTreeMap;

use egui::{RichText, Ui};

use super::{ERROR, OK, SystemView};
use crate::common::palette::Catalog;
use crate::system::diagram::BlockId;
use crate::system::editor::Command;

/// The parameters dialog of one block, with what the user is typing.
pub(super) struct ParamsDialog {
    block: BlockId,
    name: String,
    values: BTreeMap<String, String>,
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
                            if edit.changed() {
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
