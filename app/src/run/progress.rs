//! The leg being driven, in numbers: the distance left, the time to its deadline and the slack,
//! as the run's status carries them (`armor_protocol::LegProgress`, the numbers `armor run`'s
//! live line gives on a terminal). Nothing is worked out here: the studio says what the run says.

use armor_protocol::LegProgress;
use egui::{RichText, Ui};

/// The leg in force and its numbers, in a small grid under the mission's marking. (The line
/// says "from … to" in words: the studio's font has no arrow.)
pub fn progress_ui(ui: &mut Ui, progress: &LegProgress) {
    ui.label(
        RichText::new(format!(
            "Leg {}/{} `{}`, from `{}` to `{}`",
            progress.number, progress.legs, progress.leg, progress.from, progress.to
        ))
        .strong(),
    );
    egui::Grid::new("run-leg-progress")
        .num_columns(2)
        .show(ui, |ui| {
            ui.label("left");
            ui.label(progress.left_m.map_or_else(
                || "not known yet: no position from the robot".to_owned(),
                |left| format!("{left:.1} m"),
            ));
            ui.end_row();
            if let (Some(deadline), Some(time_left)) =
                (progress.deadline_run_secs, progress.time_left_secs)
            {
                timed_row(
                    ui,
                    "deadline",
                    time_left,
                    format!("{time_left:.1} s left (by {deadline:.1} s)"),
                    format!("{:.1} s late (was {deadline:.1} s)", -time_left),
                );
            }
            if let Some(slack) = progress.slack_secs {
                timed_row(
                    ui,
                    "slack",
                    slack,
                    format!("{slack:.1} s early at the plan's speed"),
                    format!("{:.1} s late at the plan's speed", -slack),
                );
            }
        });
}

/// A row of the grid that says `on_time` when `secs` is at or above zero, else `late`, in the
/// warning colour.
fn timed_row(ui: &mut Ui, name: &str, secs: f64, on_time: String, late: String) {
    ui.label(name);
    if secs >= 0.0 {
        ui.label(on_time);
    } else {
        ui.label(RichText::new(late).color(ui.visuals().warn_fg_color));
    }
    ui.end_row();
}
