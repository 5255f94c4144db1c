//! "Find block" (Ctrl+F): blocks whose name or type contains what is typed; the one chosen is
//! selected and brought into view.

use egui::{Key, Ui};

use super::SystemView;
use crate::system::diagram::BlockId;

impl SystemView {
    /// "Find block", over the window, while open.
    pub fn search_ui(&mut self, ui: &mut Ui) {
        let ctx = &ui.ctx().clone();
        let Some(query) = &mut self.search else {
            return;
        };
        let mut open = true;
        let mut chosen = None;
        egui::Window::new("Find block")
            .id(egui::Id::new("search"))
            .open(&mut open)
            .collapsible(false)
            .show(ctx, |ui| {
                let label = ui.label("Find:");
                let edit = ui
                    .add(
                        egui::TextEdit::singleline(query)
                            .id_salt("find")
                            .hint_text("name or type"),
                    )
                    .labelled_by(label.id);
                if !edit.has_focus() && !edit.lost_focus() {
                    edit.request_focus();
                }
                let needle = query.to_lowercase();
                let matches: Vec<(BlockId, String)> = self
                    .editor
                    .diagram
                    .blocks()
                    .filter(|(_, block)| {
                        block.name.to_lowercase().contains(&needle)
                            || block.module_type.to_lowercase().contains(&needle)
                    })
                    .take(50)
                    .map(|(id, block)| (id, format!("{} ({})", block.name, block.module_type)))
                    .collect();
                if edit.lost_focus() && ui.input(|input| input.key_pressed(Key::Enter)) {
                    chosen = matches.first().map(|(id, _)| *id);
                }
                if matches.is_empty() {
                    ui.label("no block matches");
                }
                for (id, label) in matches {
                    if ui.button(label).clicked() {
                        chosen = Some(id);
                    }
                }
            });
        if let Some(block) = chosen {
            self.show_block(block);
            self.search = None;
        } else if !open {
            self.search = None;
        }
    }
}
