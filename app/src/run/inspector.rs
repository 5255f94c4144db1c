//! The generic inspector: any output of the run, of any type, picked in a list and shown as
//! its type allows — numbers plotted (counters, velocities, poses, odometry), text listed,
//! scans as a range plot, grids and markers summarised, any other type as its size and first
//! bytes. Every output's samples are kept here as they arrive (decoded once, bounded), so that
//! picking one shows its recent past at once.

use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

use armor_module_api::Datum;
use armor_module_api::types::{Counter, LaserScan, Markers, Odometry, Pose2D, Text, Twist};
use egui::{RichText, Ui};
use egui_plot::{Legend, Line, Plot};

use super::untrusted;

/// Samples of numbers and lines of text kept per output.
const MAX_HISTORY: usize = 300;
const MAX_TEXT_LINES: usize = 20;
/// A text longer than this is cut when kept (in characters).
const MAX_TEXT_CHARS: usize = 400;

/// What the inspector keeps of one output.
#[derive(Clone, Debug, Default)]
pub struct Output {
    pub data_type: String,
    pub samples: u64,
    /// The fields' names and, per sample, their values (numbers only).
    pub fields: Vec<&'static str>,
    pub numbers: VecDeque<(u64, Vec<f64>)>,
    pub texts: VecDeque<String>,
    pub scan: Option<Arc<LaserScan>>,
    /// A short description of the latest sample (grids, markers, other types).
    pub summary: String,
    /// The latest sample could not be read, and why.
    pub unreadable: Option<String>,
}

/// Every output seen, by data name.
#[derive(Clone, Debug, Default)]
pub struct Outputs {
    pub by_name: BTreeMap<String, Output>,
}

impl Outputs {
    pub fn take(&mut self, data_name: &str, data_type: &str, payload: &[u8]) {
        let output = self.by_name.entry(data_name.to_owned()).or_default();
        output.data_type = data_type.to_owned();
        output.samples += 1;
        output.unreadable = None;
        if let Err(err) = output.read(payload) {
            output.unreadable = Some(err);
        }
    }
}

impl Output {
    fn numbers(&mut self, fields: &[&'static str], values: Vec<f64>) {
        self.fields = fields.to_vec();
        if self.numbers.len() == MAX_HISTORY {
            self.numbers.pop_front();
        }
        self.numbers.push_back((self.samples, values));
    }

    fn read(&mut self, payload: &[u8]) -> Result<(), String> {
        let err = |err: armor_module_api::types::CodecError| err.to_string();
        match self.data_type.as_str() {
            "Counter" => {
                let Counter(value) = Counter::decode(payload).map_err(err)?;
                self.numbers(&["value"], vec![value as f64]);
            }
            "Twist" => {
                let twist = Twist::decode(payload).map_err(err)?;
                self.numbers(
                    &["linear m/s", "angular rad/s"],
                    vec![twist.linear_mps, twist.angular_radps],
                );
            }
            "Pose2D" => {
                let pose = Pose2D::decode(payload).map_err(err)?;
                self.numbers(
                    &["x m", "y m", "θ rad"],
                    vec![pose.x_m, pose.y_m, pose.theta_rad],
                );
            }
            "Odometry" => {
                let odometry = Odometry::decode(payload).map_err(err)?;
                let (pose, twist) = (odometry.pose_in_odom, odometry.twist);
                self.numbers(
                    &["x m", "y m", "θ rad", "linear m/s", "angular rad/s"],
                    vec![
                        pose.x_m,
                        pose.y_m,
                        pose.theta_rad,
                        twist.linear_mps,
                        twist.angular_radps,
                    ],
                );
            }
            "Text" => {
                let Text(text) = Text::decode(payload).map_err(err)?;
                if self.texts.len() == MAX_TEXT_LINES {
                    self.texts.pop_front();
                }
                let mut line: String = text.chars().take(MAX_TEXT_CHARS).collect();
                if line.len() < text.len() {
                    line.push('…');
                }
                self.texts.push_back(line);
            }
            "LaserScan" => {
                let scan = LaserScan::decode(payload).map_err(err)?;
                untrusted::check_scan(&scan).map_err(|refused| refused.to_string())?;
                self.summary = format!(
                    "{} beams, nearest {:.2} m",
                    scan.ranges_m.len(),
                    scan.ranges_m
                        .iter()
                        .copied()
                        .filter(|r| r.is_finite())
                        .fold(f32::INFINITY, f32::min)
                );
                self.scan = Some(Arc::new(scan));
            }
            "OccupancyGrid" => self.summary = grid_summary(payload)?,
            "Markers" => {
                let markers = Markers::decode(payload).map_err(err)?;
                let mut shapes: BTreeMap<String, usize> = BTreeMap::new();
                for marker in &markers.markers {
                    *shapes.entry(format!("{:?}", marker.shape)).or_default() += 1;
                }
                let list: Vec<String> = shapes.iter().map(|(s, n)| format!("{n} {s}")).collect();
                self.summary = format!("{} markers: {}", markers.markers.len(), list.join(", "));
            }
            _ => {
                let head: Vec<String> = payload
                    .iter()
                    .take(16)
                    .map(|b| format!("{b:02x}"))
                    .collect();
                self.summary = format!("{} bytes: {}", payload.len(), head.join(" "));
            }
        }
        Ok(())
    }
}

/// A grid's size and resolution from its first fields, without decoding its cells.
fn grid_summary(payload: &[u8]) -> Result<String, String> {
    let resolution = payload
        .get(..8)
        .and_then(|bytes| bytes.try_into().ok())
        .map(f64::from_le_bytes)
        .ok_or("a grid shorter than its resolution")?;
    let mut rest = &payload[8..];
    let mut varint = || -> Result<u64, String> {
        let mut value = 0u64;
        for shift in (0..35).step_by(7) {
            let (&byte, tail) = rest.split_first().ok_or("a grid cut short")?;
            rest = tail;
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err("a grid's size is not a u32".to_owned())
    };
    let (width, height) = (varint()?, varint()?);
    Ok(format!(
        "{width} × {height} cells of {:.3} m ({:.1} m × {:.1} m)",
        resolution,
        width as f64 * resolution,
        height as f64 * resolution
    ))
}

/// The list of outputs and the picked one, shown.
pub fn inspector_ui(ui: &mut Ui, outputs: &Outputs, picked: &mut Option<String>) {
    let text = picked.as_deref().unwrap_or("pick an output");
    egui::ComboBox::from_label("output")
        .selected_text(text)
        .width(220.0)
        .show_ui(ui, |ui| {
            for (name, output) in &outputs.by_name {
                let label = format!("{name} ({})", output.data_type);
                ui.selectable_value(picked, Some(name.clone()), label);
            }
        });
    let Some(output) = picked.as_ref().and_then(|name| outputs.by_name.get(name)) else {
        if outputs.by_name.is_empty() {
            ui.label(RichText::new("no output has published yet").weak());
        }
        return;
    };
    ui.label(format!("{}: {} samples", output.data_type, output.samples));
    if let Some(reason) = &output.unreadable {
        ui.label(RichText::new(format!("unreadable: {reason}")).color(egui::Color32::RED));
    }
    if !output.numbers.is_empty() {
        if let Some((_, latest)) = output.numbers.back() {
            let values: Vec<String> = output
                .fields
                .iter()
                .zip(latest)
                .map(|(field, value)| format!("{field} {value:.3}"))
                .collect();
            ui.label(values.join(" · "));
        }
        Plot::new(("inspect-numbers", picked.as_deref()))
            .height(140.0)
            .legend(Legend::default())
            .allow_scroll(false)
            .show(ui, |plot| {
                for (index, field) in output.fields.iter().enumerate() {
                    let points: Vec<[f64; 2]> = output
                        .numbers
                        .iter()
                        .filter_map(|(n, values)| Some([*n as f64, *values.get(index)?]))
                        .collect();
                    plot.line(Line::new(*field, points));
                }
            });
    }
    for line in output.texts.iter().rev() {
        ui.label(RichText::new(line).monospace().small());
    }
    if let Some(scan) = &output.scan {
        scan_range_ui(ui, ("inspect-scan", picked.as_deref()), scan);
    }
    if !output.summary.is_empty() {
        ui.label(&output.summary);
    }
}

/// A scan's ranges by beam angle.
pub fn scan_range_ui(ui: &mut Ui, id: impl std::hash::Hash + std::fmt::Debug, scan: &LaserScan) {
    Plot::new(id)
        .height(120.0)
        .allow_scroll(false)
        .include_y(0.0)
        .show(ui, |plot| {
            let points: Vec<[f64; 2]> = scan
                .ranges_m
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    let angle = scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
                    [angle.to_degrees(), f64::from(*r).min(scan.range_max_m)]
                })
                .collect();
            plot.line(Line::new("range m by angle °", points));
        });
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::types::OccupancyGrid;

    fn encoded<T: Datum>(value: &T) -> Vec<u8> {
        let mut out = Vec::new();
        value.encode(&mut out).expect("encodes");
        out
    }

    #[test]
    fn every_type_is_shown_as_it_allows() {
        let mut outputs = Outputs::default();
        let twist = Twist {
            linear_mps: 0.5,
            angular_radps: -0.25,
        };
        outputs.take("arbiter.cmd_vel", "Twist", &encoded(&twist));
        outputs.take("follower.path", "Text", &encoded(&Text("0,0 1,1".into())));
        let grid = OccupancyGrid {
            resolution_m: 0.05,
            width: 300,
            height: 200,
            cells: vec![0; 60_000],
            ..OccupancyGrid::default()
        };
        outputs.take("mapper.map", "OccupancyGrid", &encoded(&grid));
        outputs.take("x.blob", "Blob", &[1, 2, 255]);
        outputs.take("sim.pose_truth", "Pose2D", &[1, 2]);
        let by = |name: &str| &outputs.by_name[name];
        assert_eq!(by("arbiter.cmd_vel").numbers[0].1, [0.5, -0.25]);
        assert_eq!(by("follower.path").texts, ["0,0 1,1"]);
        assert_eq!(
            by("mapper.map").summary,
            "300 × 200 cells of 0.050 m (15.0 m × 10.0 m)"
        );
        assert_eq!(by("x.blob").summary, "3 bytes: 01 02 ff");
        assert!(by("sim.pose_truth").unreadable.is_some());
        for _ in 0..MAX_HISTORY + 5 {
            outputs.take("arbiter.cmd_vel", "Twist", &encoded(&twist));
        }
        assert_eq!(
            outputs.by_name["arbiter.cmd_vel"].numbers.len(),
            MAX_HISTORY
        );
    }
}
