//! The menu bar: the command table's menus for the view shown (each entry with its keys), the
//! views' switch and the title.

use egui::{RichText, Ui};

use super::StudioApp;
use crate::command::{self, MenuItem, UiCommand, View};

impl StudioApp {
    pub(super) fn menu_ui(&mut self, ui: &mut Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            for menu in command::menus(self.view) {
                ui.menu_button(menu.title, |ui| {
                    for item in menu.items {
                        match *item {
                            MenuItem::Separator => {
                                ui.separator();
                            }
                            MenuItem::Recent => self.recent_menu_ui(ui),
                            MenuItem::Examples => self.examples_menu_ui(ui),
                            MenuItem::Note(text) => {
                                ui.weak(text);
                            }
                            MenuItem::Command(command) => {
                                let keys = command.keys_text();
                                let label = command.label(self.view);
                                let button = egui::Button::new(label).shortcut_text(keys.as_str());
                                let enabled = match command {
                                    UiCommand::Run => !self.run.is_running(),
                                    UiCommand::Stop => self.run.is_running(),
                                    _ => true,
                                };
                                let response = ui.add_enabled(enabled, button);
                                name_menu_item(&response, label, &keys, enabled);
                                if response.clicked() {
                                    self.execute(command, ui.ctx(), true);
                                }
                            }
                        }
                    }
                });
            }
            ui.separator();
            let mut view = self.view;
            ui.selectable_value(&mut view, View::System, "System");
            ui.selectable_value(&mut view, View::Mission, "Mission");
            ui.selectable_value(&mut view, View::Run, "Run");
            if view != self.view {
                self.set_view(view);
            }
            ui.separator();
            ui.label(RichText::new(&self.title).weak());
        });
    }
}

/// Gives a menu entry its own name for screen readers and tests: egui names a button with a
/// shortcut by both texts run together ("SaveCtrl+S"), which neither a screen reader nor a test
/// looking for "Save" should have to read. The keys go where AccessKit keeps them, in the
/// entry's keyboard shortcut, which screen readers announce after the name.
fn name_menu_item(response: &egui::Response, label: &str, keys: &str, enabled: bool) {
    response.widget_info(|| egui::WidgetInfo::labeled(egui::WidgetType::Button, enabled, label));
    if !keys.is_empty() {
        response.ctx.accesskit_node_builder(response.id, |node| {
            node.set_keyboard_shortcut(keys);
        });
    }
}
