//! The problem list: `armor_model::check`'s problems (through `validation`), each of
//! which selects its block when clicked.

use egui::{RichText, Ui};

use super::{ERROR, OK, SystemView};
use crate::common::palette::Palette;

impl SystemView {
    pub(super) fn problems_ui(&mut self, ui: &mut Ui, palette: &Palette) {
        if self.problems.is_empty() {
            ui.horizontal(|ui| {
                ui.colored_label(OK, "No problems");
                if palette.is_probing() {
                    ui.label(RichText::new("(modules are still being described)").weak());
                }
            });
            return;
        }
        ui.heading(armor_model::plural(self.problems.len(), "problem"));
        ui.label(
            RichText::new("As `armor check` reports them; click one to select its block.")
                .weak()
                .small(),
        );
        let mut clicked = None;
        egui::ScrollArea::vertical().show(ui, |ui| {
            for problem in &self.problems {
                let text = format!("{}: {}", problem.pos, problem.message);
                let response = ui.add(
                    egui::Label::new(RichText::new(text).color(ERROR))
                        .sense(egui::Sense::click())
                        .wrap(),
                );
                if response.clicked()
                    && let Some(block) = problem.block
                {
                    clicked = Some(block);
                }
            }
        });
        if let Some(block) = clicked {
            self.show_block(block);
        }
    }
}
