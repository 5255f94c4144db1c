//! The palette panel: the module types found on the module path (described by
//! `common::palette` on background threads), dragged or added onto the canvas.

use egui::{RichText, Ui};

use super::canvas::PaletteDrag;
use super::{ERROR, SystemView};
use crate::common::palette::{Entry, Palette};
use crate::system::editor::Command;
use crate::system::viewer;
use armor_module_api::{Category, ModuleDescription};

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
        // Grouped by category, each group headed by its colour and name, and each module type
        // drawn as a chip of that colour, as Node-RED's palette is: the colours are those of
        // the blocks' headers on the canvas, so the palette is also the legend.
        let described: Vec<&ModuleDescription> = palette
            .entries
            .iter()
            .filter_map(|entry| match entry {
                Entry::Described(description) => Some(description),
                Entry::Broken(_) => None,
            })
            .collect();
        egui::ScrollArea::vertical().show(ui, |ui| {
            for category in Category::ALL {
                let group: Vec<&&ModuleDescription> = described
                    .iter()
                    .filter(|description| description.category == category)
                    .collect();
                if group.is_empty() {
                    continue;
                }
                ui.add_space(4.0);
                ui.horizontal(|ui| {
                    let (rect, _) =
                        ui.allocate_exact_size(egui::vec2(12.0, 12.0), egui::Sense::hover());
                    ui.painter()
                        .rect_filled(rect, 3.0, viewer::category_colour(category));
                    ui.label(RichText::new(viewer::category_name(category)).strong());
                });
                for description in group {
                    self.palette_entry_ui(ui, description);
                }
            }
            for entry in &palette.entries {
                if let Entry::Broken(broken) = entry {
                    ui.colored_label(ERROR, format!("{} (broken)", broken.module_type));
                    ui.label(
                        RichText::new(format!("{}: {}", broken.binary, broken.error))
                            .small()
                            .color(ERROR),
                    );
                    ui.add_space(4.0);
                }
            }
        });
    }

    /// A module type: its chip (dragged onto the canvas), its add button, its one-line doc.
    fn palette_entry_ui(&mut self, ui: &mut Ui, description: &ModuleDescription) {
        let module_type = description.module_type.clone();
        ui.horizontal(|ui| {
            ui.dnd_drag_source(
                egui::Id::new(("palette", &module_type)),
                PaletteDrag(module_type.clone()),
                |ui| {
                    egui::Frame::new()
                        .fill(viewer::category_colour(description.category))
                        .corner_radius(4.0)
                        .inner_margin(egui::Margin::symmetric(8, 3))
                        .show(ui, |ui| {
                            ui.add(
                                egui::Label::new(
                                    RichText::new(&module_type)
                                        .strong()
                                        .color(viewer::HEADER_TEXT),
                                )
                                .selectable(false),
                            );
                        });
                },
            )
            .response
            .on_hover_text(&description.doc);
            if ui.small_button(format!("add {module_type}")).clicked() {
                // Cascade, so that blocks added one after the other do not hide each other.
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
        ui.label(RichText::new(&description.doc).small());
        ui.add_space(4.0);
    }
}
