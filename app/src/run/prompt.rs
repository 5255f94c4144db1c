//! F5's prompt: what is about to run, named, and the time scale to run it at, remembered from
//! the last run. Enter runs, Escape cancels.

use super::Target;

/// The prompt's state: the run asked for, and its time scale as typed so far.
#[derive(Clone, Debug)]
pub struct RunPrompt {
    pub target: Target,
    pub time_scale: f64,
}

/// What the prompt asks of the window this frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Answer {
    /// Run the target at this time scale.
    Run(f64),
    Cancel,
}

impl RunPrompt {
    pub fn new(target: Target, time_scale: f64) -> RunPrompt {
        RunPrompt { target, time_scale }
    }

    /// What is about to run, in words: "plan `plan-yard.xml`", "system `robot.xml`".
    pub fn what(&self) -> String {
        target_words(&self.target)
    }

    /// Draws the prompt; returns the operator's answer once given.
    pub fn ui(&mut self, ctx: &egui::Context) -> Option<Answer> {
        let mut answer = None;
        egui::Window::new("Run")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .show(ctx, |ui| {
                ui.label(format!("Run the {} with armor run", self.what()));
                ui.label(egui::RichText::new(self.target.path().display().to_string()).weak());
                ui.horizontal(|ui| {
                    ui.label("time scale ×");
                    ui.add(
                        egui::DragValue::new(&mut self.time_scale)
                            .range(0.1..=200.0)
                            .speed(0.1),
                    )
                    .on_hover_text("run time passes this many times faster than wall time");
                });
                ui.horizontal(|ui| {
                    // Read before the buttons: a drag value being typed in gives up the focus
                    // on Enter, and the press must still run.
                    let enter = ui.input(|input| input.key_pressed(egui::Key::Enter));
                    if ui.button("▶ Run").clicked() || enter {
                        answer = Some(Answer::Run(self.time_scale));
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

/// A target in words: "plan `plan-yard.xml`", "system `robot.xml`".
pub fn target_words(target: &Target) -> String {
    let name = target.path().file_name().map_or_else(
        || target.path().display().to_string(),
        |name| name.to_string_lossy().into_owned(),
    );
    match target {
        Target::Plan(_) => format!("plan `{name}`"),
        Target::System(_) => format!("system `{name}`"),
    }
}
