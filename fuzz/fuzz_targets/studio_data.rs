//! What the studio's Run view draws from a peer's samples (`app/src/run/untrusted.rs`): the
//! first byte picks a pose, a scan, a grid, a recording's times or a followed path (text); the
//! second, for a grid, the
//! largest texture side (1 to 8192). Nothing panics; a grid that passes the checks has a
//! picture of its size (shrunk to the side), made without allocating more than four bytes a
//! cell; a scan's points are finite and near; the play head stays within the recording; a path
//! is bounded, near, and one too long is refused before anything is allocated for it.
#![no_main]

use armor_fuzz::counting::{Counting, measure};
use armor_fuzz::untrusted::{self, MAX_COORDINATE_M, MAX_PATH_POINTS, Refused, Timeline};
use armor_module_api::Datum;
use armor_module_api::types::{LaserScan, OccupancyGrid, Pose2D};
use libfuzzer_sys::fuzz_target;

#[global_allocator]
static ALLOCATOR: Counting = Counting;

fn grid(max_side: usize, payload: &[u8]) {
    let Ok(grid) = OccupancyGrid::decode(payload) else {
        return;
    };
    let checked = untrusted::check_grid(&grid);
    let (picture, largest) = measure(|| untrusted::grid_picture(&grid, max_side));
    assert_eq!(
        checked.is_ok(),
        picture.is_ok(),
        "check and picture disagree"
    );
    let Ok(picture) = picture else {
        assert_eq!(largest, 0, "a refused grid allocated {largest} bytes");
        return;
    };
    assert!(
        largest <= 4 * grid.cells.len(),
        "{largest} bytes for {} cells",
        grid.cells.len()
    );
    let [columns, rows] = picture.size;
    assert_eq!(picture.rgba.len(), 4 * columns * rows);
    assert!(
        columns <= max_side && rows <= max_side,
        "{columns} × {rows} over {max_side}"
    );
    assert!(columns * rows <= grid.cells.len());
    assert!(columns > 0 && rows > 0);
}

fn scan(payload: &[u8]) {
    let Some((pose, rest)) = payload.split_at_checked(24) else {
        return;
    };
    let (Ok(pose), Ok(scan)) = (Pose2D::decode(pose), LaserScan::decode(rest)) else {
        return;
    };
    if untrusted::check_pose(&pose).is_err() {
        return;
    }
    if untrusted::check_scan(&scan).is_ok() {
        assert!(scan.ranges_m.len() <= untrusted::MAX_SCAN_RANGES);
    }
    for (x_m, y_m) in untrusted::scan_hits(&scan, &pose) {
        assert!(x_m.abs() <= MAX_COORDINATE_M && y_m.abs() <= MAX_COORDINATE_M);
    }
}

fn pose(payload: &[u8]) {
    if let Ok(pose) = Pose2D::decode(payload)
        && untrusted::check_pose(&pose).is_ok()
    {
        assert!(pose.x_m.is_finite() && pose.y_m.is_finite() && pose.theta_rad.is_finite());
    }
}

/// Times (8 bytes each) until 8 bytes are left, then the play head's seconds (an f64).
fn timeline(payload: &[u8]) {
    let Some((times, at)) = payload.split_last_chunk::<8>() else {
        return;
    };
    let at_secs = f64::from_le_bytes(*at);
    let times = times
        .chunks_exact(8)
        .map(|time| u64::from_le_bytes(time.try_into().expect("8 bytes")));
    let Some(span) = Timeline::of(times) else {
        return;
    };
    assert!(span.first_ns <= span.last_ns);
    let duration = span.duration_secs();
    assert!(duration.is_finite() && duration >= 0.0);
    let until = span.until_ns(at_secs);
    assert!(span.first_ns <= until && until <= span.last_ns);
    let clamped = span.clamp_secs(at_secs);
    assert!((0.0..=duration).contains(&clamped));
    assert_eq!(span.until_ns(duration), span.last_ns);
}

/// The follower's `path` output as the Run view reads it.
fn path(payload: &[u8]) {
    let Ok(text) = std::str::from_utf8(payload) else {
        return;
    };
    let (parsed, largest) = measure(|| untrusted::parse_path(text));
    match parsed {
        Ok(points) => {
            assert!(points.len() <= MAX_PATH_POINTS);
            for (x_m, y_m) in points {
                assert!(x_m.abs() <= MAX_COORDINATE_M && y_m.abs() <= MAX_COORDINATE_M);
            }
        }
        Err(Refused::PathTooLong { .. }) => {
            assert_eq!(
                largest, 0,
                "a path refused for its length allocated {largest} bytes"
            );
        }
        Err(_) => {}
    }
}

fuzz_target!(|data: &[u8]| {
    let [which, side, payload @ ..] = data else {
        return;
    };
    match which % 5 {
        0 => pose(payload),
        1 => scan(payload),
        2 => grid(1 << (side % 14), payload),
        3 => timeline(payload),
        _ => path(payload),
    }
});
