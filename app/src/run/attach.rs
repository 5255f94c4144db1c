//! Run → Attach…: the small window that asks for the control address of a run started
//! elsewhere (`armor run` prints it: `armor run control interface at ADDR`), which the Run view
//! then follows with the same controls as `armor ctl`. Detaching (the Stop button, Shift+F5)
//! leaves the run going.

use std::net::SocketAddr;

/// The prompt's state: the address typed so far, and why the last one was refused.
#[derive(Clone, Debug, Default)]
pub struct AttachPrompt {
    pub addr: String,
    pub error: Option<String>,
}

/// What the prompt asks of the window this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    Attach(SocketAddr),
    Cancel,
}

impl AttachPrompt {
    pub fn new(addr: &str) -> AttachPrompt {
        AttachPrompt {
            addr: addr.to_owned(),
            error: None,
        }
    }

    /// Draws the prompt; returns the operator's answer once given.
    pub fn ui(&mut self, ctx: &egui::Context) -> Option<Answer> {
        let mut answer = None;
        egui::Window::new("Attach to a run")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .show(ctx, |ui| {
                ui.label("The run's control address, as armor run prints it:");
                let field = ui.add(
                    egui::TextEdit::singleline(&mut self.addr)
                        .desired_width(260.0)
                        .hint_text("10.0.0.2:7420"),
                );
                field.request_focus();
                let enter =
                    field.lost_focus() && ui.input(|input| input.key_pressed(egui::Key::Enter));
                if let Some(error) = &self.error {
                    ui.colored_label(ui.visuals().error_fg_color, error);
                }
                ui.horizontal(|ui| {
                    if ui.button("Attach").clicked() || enter {
                        match self.addr.trim().parse::<SocketAddr>() {
                            Ok(addr) => answer = Some(Answer::Attach(addr)),
                            Err(_) => {
                                self.error = Some(format!(
                                    "`{}` is not an address (IP:PORT)",
                                    self.addr.trim()
                                ));
                            }
                        }
                    }
                    if ui.button("Cancel").clicked()
                        || ui.input(|input| input.key_pressed(egui::Key::Escape))
                    {
                        answer = Some(Answer::Cancel);
                    }
                });
            });
        answer
    }
}
