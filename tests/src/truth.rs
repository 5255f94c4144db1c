//! The simulator's truth, as the suites judge a simulated run by it on their own, from the
//! definitions rather than through the run's judge: the true poses a recorder wrote, and the
//! distance of the robot's footprint to a no-go area.

use std::path::Path;

use armor_model::geo::{Point, Polygon};
use armor_module_api::Datum as _;
use armor_module_api::types::Pose2D;

use crate::mcap::read_mcap;

/// The true poses (`sim.pose_truth`) the recorder wrote in `file`, in time order: (run seconds,
/// position). A recording with a thousand or fewer is no evidence of a whole run.
pub fn recorded_truth(file: &Path) -> Vec<(f64, Point)> {
    let mut truth: Vec<(f64, Point)> = read_mcap(file)
        .into_iter()
        .filter(|((topic, _), _)| topic == "sim.pose_truth")
        .flat_map(|((_, encoding), messages)| {
            messages.into_iter().map(move |(log_time, data)| {
                let pose = match encoding.as_str() {
                    "json" => serde_json::from_slice::<Pose2D>(&data).unwrap(),
                    _ => Pose2D::decode(&data).unwrap(),
                };
                (log_time as f64 / 1e9, Point::new(pose.x_m, pose.y_m))
            })
        })
        .collect();
    truth.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert!(truth.len() > 1000, "{} true poses", truth.len());
    truth
}

/// Least distance between a disc of `radius_m` round `at` and `area`, negative inside: what a
/// rehearsal reports, computed here from the definitions.
pub fn footprint_gap_m(area: &Polygon, at: Point, radius_m: f64) -> f64 {
    let outline = area
        .edges()
        .map(|(a, b)| armor_model::geo::segment_distance(at, a, b))
        .fold(f64::INFINITY, f64::min);
    let centre = if area.contains(at) { -outline } else { outline };
    centre - radius_m
}
