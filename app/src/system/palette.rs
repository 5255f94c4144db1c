//! The palette panel: the module types found on the module path (described by `crate::palette`
//! on background threads), dragged or added onto the canvas.

use egui::{RichText, Ui};

use super::canvas::PaletteDrag;
use super::{ERROR, SystemView};
use crate::editor::Command;
use crate::palette::{Entry, Palette};

impl SystemView {
    pub(super) fn palette_ui(&mut self, ui: &mut Ui, palette: &Palette) {
        ui.heading("Modules");
        if palette.is_probing() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(format!("describing {} of {}", palette.done, palette.total));
            });
            ui.add(
                egui::ProgressBar::new(palette.done as f32 / palette.total.max(1) as f32)
                    .desired_height(4.0),
            );
        } else if palette.entries.is_empty() {
            ui.label("No module binaries (armor-mod-*) found on the module path.");
        }
        ui.label(
            RichText::new("Drag a module onto the canvas.")
                .weak()
                .small(),
        );
        egui::ScrollArea::vertical().show(ui, |ui| {
            for entry in &palette.entries {
                match entry {
                    Entry::Described(description) => {
                        let module_type = description.module_type.clone();
                        ui.horizontal(|ui| {
                            ui.dnd_drag_source(
                                egui::Id::new(("palette", &module_type)),
                                PaletteDrag(module_type.clone()),
                                |ui| {
                                    ui.add(
                                        egui::Label::new(RichText::new(&module_type).strong())
                                            .selectable(false),
                                    );
                                },
                            )
                            .response
                            .on_hover_text(&description.doc);
                            if ui.small_button(format!("add {module_type}")).clicked() {
                                // Cascade, so that blocks added one after the other do not hide
                                // each other.
                                let n = self.editor.diagram.len();
                                let at = self.canvas.to_canvas(self.canvas.rect.center())
                                    + egui::vec2(
                                        (n % 3) as f32 * 240.0 - 240.0,
                                        (n / 3 % 4) as f32 * 120.0 - 120.0,
                                    );
                                self.commands.push(Command::AddBlock {
                                    module_type: module_type.clone(),
                                    pos: [at.x - 80.0, at.y - 40.0],
                                });
                            }
                        });
                        ui.label(RichText::new(&description.doc).small().weak());
                        ui.add_space(4.0);
                    }
                    Entry::Broken(broken) => {
                        ui.colored_label(ERROR, format!("{} (broken)", broken.module_type));
                        ui.label(
                            RichText::new(format!("{}: {}", broken.binary, broken.error))
                                .small()
                                .color(ERROR),
                        );
                        ui.add_space(4.0);
                    }
                }
            }
        });
    }
}
