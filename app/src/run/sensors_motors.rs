//! Sensors and motors at a glance: every laser of the robot, as the points it sees around the
//! robot and as a range plot, and every velocity command of the run — each candidate's
//! proposal, the arbiter's winner starred, the command that reaches the robot — with its latest
//! value and its recent past plotted. It reads the inspector's store of every output
//! ([`Outputs`]), so it shows a recording as it shows a run.

use armor_module_api::types::LaserScan;
use armor_protocol::Status;
use egui::{RichText, Ui};
use egui_plot::{Legend, Line, Plot, Points};

use super::inspector::{Outputs, scan_range_ui};

/// The panel. `status` names the arbiters' winners (none for a recording).
pub fn panel_ui(ui: &mut Ui, outputs: &Outputs, status: Option<&Status>) {
    let scans: Vec<(&String, &LaserScan)> = outputs
        .by_name
        .iter()
        .filter_map(|(name, output)| Some((name, output.scan.as_deref()?)))
        .collect();
    if scans.is_empty() {
        ui.label(RichText::new("no laser scan yet").weak());
    }
    for (name, scan) in scans {
        ui.label(RichText::new(name.as_str()).strong());
        hits_ui(ui, name, scan);
        scan_range_ui(ui, ("sensors-range", name), scan);
    }
    let winners: Vec<&str> = status
        .map(|status| {
            status
                .modules
                .iter()
                .filter_map(|m| m.winner.as_deref())
                .collect()
        })
        .unwrap_or_default();
    let commands: Vec<(&String, &super::inspector::Output)> = outputs
        .by_name
        .iter()
        .filter(|(_, output)| output.data_type == "Twist")
        .collect();
    if commands.is_empty() {
        ui.label(RichText::new("no motor command yet").weak());
        return;
    }
    egui::Grid::new("motors").striped(true).show(ui, |ui| {
        ui.label(RichText::new("command").strong());
        ui.label(RichText::new("m/s").strong());
        ui.label(RichText::new("rad/s").strong());
        ui.end_row();
        for (name, output) in &commands {
            let module = name.split_once('.').map_or(name.as_str(), |(m, _)| m);
            let text = if winners.contains(&module) {
                format!("★ {name}")
            } else {
                name.to_string()
            };
            ui.label(text);
            let latest = output
                .numbers
                .back()
                .map(|(_, v)| v.as_slice())
                .unwrap_or(&[]);
            for value in latest.iter().take(2) {
                ui.label(format!("{value:+.2}"));
            }
            ui.end_row();
        }
    });
    Plot::new("motors-linear")
        .height(110.0)
        .legend(Legend::default())
        .allow_scroll(false)
        .show(ui, |plot| {
            for (name, output) in &commands {
                let points: Vec<[f64; 2]> = output
                    .numbers
                    .iter()
                    .filter_map(|(n, v)| Some([*n as f64, *v.first()?]))
                    .collect();
                plot.line(Line::new(format!("{name} m/s"), points));
            }
        });
}

/// The scan's echoes around the robot (robot frame, x ahead), as a plot of points.
fn hits_ui(ui: &mut Ui, name: &str, scan: &LaserScan) {
    let hits: Vec<[f64; 2]> = scan
        .ranges_m
        .iter()
        .enumerate()
        .filter(|(_, r)| r.is_finite() && f64::from(**r) < scan.range_max_m && **r > 0.0)
        .map(|(i, r)| {
            let angle = scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
            let r = f64::from(*r);
            // Drawn with x ahead pointing up: the plot's x is the robot's left-right.
            [-r * angle.sin(), r * angle.cos()]
        })
        .collect();
    Plot::new(("sensors-hits", name))
        .height(160.0)
        .data_aspect(1.0)
        .allow_scroll(false)
        .show(ui, |plot| {
            plot.points(Points::new("echoes (robot ahead is up)", hits).radius(1.5));
            plot.points(Points::new("robot", vec![[0.0, 0.0]]).radius(4.0));
        });
}
