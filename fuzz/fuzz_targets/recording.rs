//! Recordings (MCAP files) as the studio opens them: `replay::read_recording_bytes` with a
//! budget, the messages sorted by time, each sample of a type the Run view draws checked and,
//! for a grid, pictured (`app/src/run/untrusted.rs`). Nothing panics, what is read stays within
//! the budget, and the play head stays within the recording.
#![no_main]

use armor_fuzz::untrusted::{self, Timeline};
use armor_module_api::Datum;
use armor_module_api::types::{LaserScan, OccupancyGrid, Odometry, Pose2D};
use armor_runtime::replay::read_recording_bytes;
use libfuzzer_sys::fuzz_target;

/// What the messages of one input may take: far below libFuzzer's memory limit.
const BUDGET_BYTES: usize = 64 * 1024 * 1024;

fuzz_target!(|data: &[u8]| {
    let Ok(mut messages) = read_recording_bytes("fuzz.mcap", data, BUDGET_BYTES) else {
        return;
    };
    let used: usize = messages
        .iter()
        .map(|message| message.size_in_memory())
        .sum();
    assert!(used <= BUDGET_BYTES);
    messages.sort_by_key(|message| message.log_time_ns);
    let Some(span) = Timeline::of(messages.iter().map(|message| message.log_time_ns)) else {
        return;
    };
    for at_secs in [
        0.0,
        span.duration_secs() / 2.0,
        span.duration_secs(),
        f64::NAN,
    ] {
        let until = span.until_ns(at_secs);
        assert!(span.first_ns <= until && until <= span.last_ns);
    }
    for message in &messages {
        let payload = message.payload.as_slice();
        match message.data_type.as_str() {
            "Pose2D" => {
                if let Ok(pose) = Pose2D::decode(payload) {
                    let _ = untrusted::check_pose(&pose);
                }
            }
            "Odometry" => {
                if let Ok(odometry) = Odometry::decode(payload) {
                    let _ = untrusted::check_pose(&odometry.pose_in_odom);
                }
            }
            "LaserScan" => {
                if let Ok(scan) = LaserScan::decode(payload)
                    && untrusted::check_scan(&scan).is_ok()
                {
                    let pose = Pose2D::default();
                    assert!(
                        untrusted::scan_hits(&scan, &pose)
                            .all(|(x, y)| x.is_finite() && y.is_finite())
                    );
                }
            }
            "OccupancyGrid" => {
                if let Ok(grid) = OccupancyGrid::decode(payload)
                    && let Ok(picture) = untrusted::grid_picture(&grid, 2048)
                {
                    assert_eq!(picture.rgba.len(), 4 * picture.size[0] * picture.size[1]);
                }
            }
            _ => {}
        }
    }
});
