use std::path::Path;

use super::*;
use crate::sim::tour::{BUILDING_LOOP, RING_FLOOR, RING_LOOP, Tour};
use crate::sim::world::World;
use crate::sim::{SimParams, Simulator};
use armor_module_api::testing::{Step, TestBench};
use armor_module_api::types::Twist;

fn pose(x_m: f64, y_m: f64, theta_rad: f64) -> Pose2D {
    Pose2D {
        x_m,
        y_m,
        theta_rad,
    }
}

fn close(a: Pose2D, b: Pose2D) -> bool {
    (a.x_m - b.x_m).abs() < 1e-9
        && (a.y_m - b.y_m).abs() < 1e-9
        && wrap_angle(a.theta_rad - b.theta_rad).abs() < 1e-9
}

fn distance(a: Pose2D, b: Pose2D) -> f64 {
    (a.x_m - b.x_m).hypot(a.y_m - b.y_m)
}

#[test]
fn poses_compose_and_invert() {
    use std::f64::consts::FRAC_PI_2;
    // Facing north at (1, 2), one metre ahead and a quarter turn left: (1, 3) facing west.
    let a = pose(1.0, 2.0, FRAC_PI_2);
    let b = compose(a, pose(1.0, 0.0, FRAC_PI_2));
    assert!(close(b, pose(1.0, 3.0, std::f64::consts::PI)), "{b:?}");
    assert!(close(between(a, b), pose(1.0, 0.0, FRAC_PI_2)));
    // Round trips, across the ±π seam too.
    let c = pose(-4.0, 0.5, 3.1);
    let d = pose(2.0, -1.5, -3.0);
    assert!(close(compose(c, between(c, d)), d));
    assert!(close(compose(d, between(d, c)), c));
    assert!(close(between(c, c), Pose2D::default()));
    assert!(wrap_angle(between(c, d).theta_rad - (std::f64::consts::TAU - 6.1)).abs() < 1e-9);
}

/// A 12 m × 10 m room with a few walls to match against, for quick tests.
const ROOM: &str = "\
name room
origin 0 0
start 3 3 0
boundary 0,0 12,0 12,10 0,10 0,0
wall 6,0 6,4
wall 6,6 6,10
rect 2,7 3,8
circle 9,3 0.5
";

fn room() -> World {
    World::parse(ROOM, "room.world").expect("valid")
}

#[test]
fn the_first_scan_sets_the_map_frame_and_the_grid_centre() {
    let world = room();
    let mut sim = Simulator::new(world, SimParams::default()).expect("fits");
    let report = sim.step();
    let odometry = pose(3.0, 3.0, 0.0);
    let mut mapper = Mapper::new(Settings::default()).expect("settings");
    assert_eq!(mapper.occupancy_grid(), None);
    let corrected = mapper.on_scan(sim.scan(), odometry).expect("scan");
    assert!(report.scanned);
    assert_eq!(corrected, odometry);
    let map = mapper.occupancy_grid().expect("a map");
    assert_eq!((map.width, map.height, map.resolution_m), (600, 600, 0.1));
    assert!((map.origin_x_m + 27.0).abs() < 1e-9 && (map.origin_y_m + 27.0).abs() < 1e-9);
    let cell = |x: f64, y: f64| {
        let col = ((x - map.origin_x_m) / 0.1).floor() as usize;
        let row = ((y - map.origin_y_m) / 0.1).floor() as usize;
        map.cells[row * 600 + col]
    };
    assert!((0..50).contains(&cell(4.05, 3.05)), "free before the wall");
    assert!(
        cell(6.05, 3.05) > 50 || cell(5.95, 3.05) > 50,
        "the wall at x = 6"
    );
    assert_eq!(cell(20.0, 20.0), -1, "out of reach");
    assert_eq!(cell(7.05, 1.05), -1, "behind the wall");
}

#[test]
fn a_placed_scan_updates_the_grid_as_a_matched_one_would() {
    // The first scan is never matched: placing it at the same pose gives the same map.
    let mut sim = Simulator::new(room(), SimParams::default()).expect("fits");
    sim.step();
    let at = pose(3.0, 3.0, 0.0);
    let mut matched = Mapper::new(Settings::default()).expect("settings");
    let mut placed = Mapper::new(Settings::default()).expect("settings");
    matched.on_scan(sim.scan(), at).expect("scan");
    placed.place_scan(sim.scan(), at).expect("scan");
    assert_eq!(placed.occupancy_grid(), matched.occupancy_grid());
    assert_eq!((placed.pose(), placed.stats().scans), (None, 0));
    let bad = pose(f64::NAN, 0.0, 0.0);
    assert!(placed.place_scan(sim.scan(), bad).is_err());
}

#[test]
fn scans_with_bad_geometry_are_refused() {
    let mut mapper = Mapper::new(Settings::default()).expect("settings");
    let scan = LaserScan {
        angle_min_rad: f64::NAN,
        angle_increment_rad: 0.1,
        range_max_m: 8.0,
        ranges_m: vec![1.0; 10],
    };
    let err = mapper
        .on_scan(&scan, Pose2D::default())
        .expect_err("refused");
    assert!(err.contains("not finite"), "{err}");
    assert_eq!(mapper.stats().scans, 0);
    let bad = Settings {
        size_m: 0.01,
        ..Settings::default()
    };
    assert!(Mapper::new(bad).is_err());
}

#[test]
fn corrects_a_biased_odometry_in_a_room() {
    // The robot drives a slow circle; its odometry overestimates every turn by 10 %. The
    // mapper's pose stays on the truth.
    let world = room();
    let params = SimParams {
        odom_noise: crate::sim::robot::OdometryNoise::default(),
        ..SimParams::default()
    };
    let mut sim = Simulator::new(world, params).expect("fits");
    let mut mapper = Mapper::new(Settings::default()).expect("settings");
    let mut biased = sim.truth();
    let mut previous = sim.truth();
    let mut worst = 0.0_f64;
    for _ in 0..400 {
        let _ = sim.command(Twist {
            linear_mps: 0.4,
            angular_radps: 0.3,
        });
        let report = sim.step();
        let mut increment = between(previous, report.truth);
        increment.theta_rad *= 1.1;
        biased = compose(biased, increment);
        previous = report.truth;
        if report.scanned {
            let corrected = mapper.on_scan(sim.scan(), biased).expect("scan");
            worst = worst.max(distance(corrected, report.truth));
        }
    }
    let odometry_error = distance(biased, sim.truth());
    assert!(odometry_error > 0.3, "{odometry_error}");
    assert!(worst < 0.05, "worst corrected error {worst} m");
    let stats = mapper.stats();
    assert_eq!(stats.scans, 80);
    assert!(stats.matched >= 75, "{stats:?}");
}

fn bench(params: &[(&str, &str)]) -> TestBench {
    TestBench::new(&spec(), params).expect("bench")
}

fn push<T: armor_module_api::types::Datum>(input: &str, value: &T) -> Step {
    Step::push(input, value).expect("encode")
}

#[test]
fn the_module_publishes_a_pose_per_scan_and_per_odometry_sample_and_the_map_on_time() {
    let mut sim = Simulator::new(room(), SimParams::default()).expect("fits");
    let mut script = vec![push("scan", &sim.scan().clone())];
    let mut truths = Vec::new();
    for _ in 0..3 {
        let mut report = sim.step();
        let _ = sim.command(Twist {
            linear_mps: 0.5,
            angular_radps: 0.0,
        });
        while !report.scanned {
            report = sim.step();
        }
        truths.push(report.truth);
        script.push(push("odometry", &report.odometry));
        script.push(push("scan", &sim.scan().clone()));
    }
    script.push(Step::Timeouts(2));
    // A 200 × 200 grid: the bench loses frames over 64 KiB.
    let mut bench = bench(&[("size_m", "20")]);
    bench.script(script);
    body(bench.node()).expect("body");
    // The scan before any odometry is ignored; each later one gives a pose, and so does each
    // odometry sample once a scan has given the correction: scan, odometry, scan, odometry,
    // scan.
    let poses = bench.sent::<Odometry>("pose").expect("sent");
    let shown = bench.sent::<Pose2D>("pose_map").expect("sent");
    assert_eq!(poses.len(), 5);
    assert_eq!(shown.len(), 3);
    let per_scan = poses.iter().step_by(2);
    for ((sent, shown), truth) in per_scan.zip(&shown).zip(&truths) {
        assert_eq!(sent.pose_in_odom, *shown);
        assert!(distance(*shown, *truth) < 0.05, "{shown:?} {truth:?}");
    }
    // Between scans, the odometry sample corrected as the scan before was: at the next scan's
    // place, give or take the odometry's drift over one scan period.
    for (between, truth) in poses.iter().skip(1).step_by(2).zip(&truths[1..]) {
        assert!(
            distance(between.pose_in_odom, *truth) < 0.05,
            "{between:?} {truth:?}"
        );
    }
    assert!((poses[4].twist.linear_mps - 0.5).abs() < 0.1);
    let maps = bench.sent::<OccupancyGrid>("map").expect("sent");
    assert_eq!(maps.len(), 2, "one per timeout");
    assert_eq!(maps[0].cells.len(), 200 * 200);
    assert!(maps[1].cells.iter().any(|&c| c > 50));
    assert!(bench.reported().is_empty());
}

#[test]
fn no_map_before_the_first_scan_and_live_tuning() {
    let mut bench = bench(&[("map_rate_hz", "5")]);
    bench.script([
        Step::Timeouts(2),
        Step::param("match_search_m", "-1"),
        Step::param("match_search_deg", "5"),
        Step::Timeouts(1),
    ]);
    body(bench.node()).expect("a bad live value does not end the module");
    assert!(bench.sent::<OccupancyGrid>("map").expect("sent").is_empty());
}

#[test]
fn refuses_bad_parameters() {
    let refusal = |params: &[(&str, &str)]| {
        let mut bench = bench(params);
        body(bench.node()).expect_err("must refuse").to_string()
    };
    assert_eq!(
        refusal(&[("resolution_m", "0")]),
        "parameter `resolution_m` must be greater than 0 m, not 0"
    );
    assert_eq!(
        refusal(&[("match_search_deg", "90")]),
        "parameter `match_search_deg` must be between 0° and 45°, not 90"
    );
    assert_eq!(
        refusal(&[("map_rate_hz", "0")]),
        "parameter `map_rate_hz` must be greater than 0 Hz and at most 100 Hz, not 0"
    );
    assert_eq!(
        refusal(&[("max_range_m", "500")]),
        "parameter `max_range_m` must be greater than 0 m and at most 100 m, not 500"
    );
    assert_eq!(
        refusal(&[("keyframe_m", "0")]),
        "parameter `keyframe_m` must be greater than 0 m and at most 10 m, not 0"
    );
    let err = refusal(&[("size_m", "1000"), ("resolution_m", "0.01")]);
    assert!(err.contains("100000 cells a side (1 to 4000)"), "{err}");
}

/// The intersection over union of the occupied cells (over 50 %) of the mapper's grid and the
/// true one, whose cells are aligned at the same resolution; and the same over the cells the
/// mapper has observed only.
fn occupied_iou(map: &OccupancyGrid, truth: &OccupancyGrid) -> (f64, f64) {
    let res = truth.resolution_m;
    let (tw, th) = (truth.width as i64, truth.height as i64);
    let truth_occupied = truth.cells.iter().filter(|&&c| c > 50).count();
    let (mut both, mut mapped, mut mapped_known, mut truth_known) =
        (0usize, 0usize, 0usize, 0usize);
    for (index, &cell) in map.cells.iter().enumerate() {
        let (col, row) = (index % map.width as usize, index / map.width as usize);
        let x = map.origin_x_m + (col as f64 + 0.5) * map.resolution_m;
        let y = map.origin_y_m + (row as f64 + 0.5) * map.resolution_m;
        let tc = ((x - truth.origin_x_m) / res).floor() as i64;
        let tr = ((y - truth.origin_y_m) / res).floor() as i64;
        let occupied = cell > 50;
        mapped += usize::from(occupied);
        if tc < 0 || tr < 0 || tc >= tw || tr >= th {
            continue;
        }
        let truly_occupied = truth.cells[(tr * tw + tc) as usize] > 50;
        both += usize::from(occupied && truly_occupied);
        if cell >= 0 {
            mapped_known += usize::from(occupied);
            truth_known += usize::from(truly_occupied);
        }
    }
    let iou = both as f64 / (mapped + truth_occupied - both) as f64;
    let known_iou = both as f64 / (mapped_known + truth_known - both) as f64;
    (iou, known_iou)
}

/// One drive round [`BUILDING_LOOP`] with the simulator, feeding the mapper with each scan and
/// the odometry of the same step.
struct LoopRun {
    odometry_error_m: f64,
    mapper_error_m: f64,
    max_mapper_error_m: f64,
    iou: f64,
    known_iou: f64,
    stats: Stats,
    travelled_m: f64,
    /// The true error at each scan over the standard deviation the estimate gave it.
    errors_in_sigmas: Vec<f64>,
    /// The standard deviation at the end.
    sigma_m: f64,
}

fn drive_the_building_loop(seed: u64, odometry_noise_scale: f64, loop_closure: bool) -> LoopRun {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/worlds/building.world");
    let world = crate::sim::load_world_file(path.as_ref()).expect("the building");
    let truth_grid = world.occupancy_grid(0.1).expect("grid");
    let defaults = SimParams::default();
    let noise = defaults.odom_noise;
    let params = SimParams {
        seed,
        odom_noise: crate::sim::robot::OdometryNoise {
            dist: noise.dist * odometry_noise_scale,
            rot: noise.rot * odometry_noise_scale,
            drift: noise.drift * odometry_noise_scale,
        },
        ..defaults
    };
    let mut sim = Simulator::new(world, params).expect("fits");
    let settings = Settings {
        loop_closure,
        ..Settings::default()
    };
    let mut mapper = Mapper::new(settings).expect("settings");
    let mut tour = Tour::new(BUILDING_LOOP, 20_000);
    // At the last scan: the corrected pose, the odometry and the truth.
    let (mut corrected, mut odometry, mut truth_at_scan) = (sim.truth(), sim.truth(), sim.truth());
    let mut max_mapper_error_m = 0.0_f64;
    let mut errors_in_sigmas = Vec::new();
    let mut sigma_m = 0.0;
    while let Some(report) = tour.next_scan(&mut sim) {
        odometry = report.odometry.pose_in_odom;
        truth_at_scan = report.truth;
        corrected = mapper.on_scan(sim.scan(), odometry).expect("scan");
        let error_m = distance(corrected, report.truth);
        max_mapper_error_m = max_mapper_error_m.max(error_m);
        let estimate = mapper.estimate().expect("an estimate after a scan");
        sigma_m = estimate.position_sigma_m();
        errors_in_sigmas.push(error_m / sigma_m);
    }
    assert!(tour.finished(), "the robot got stuck at {:?}", sim.truth());
    assert_eq!(sim.collisions(), 0);
    let map = mapper.occupancy_grid().expect("a map");
    let (iou, known_iou) = occupied_iou(&map, &truth_grid);
    LoopRun {
        odometry_error_m: distance(odometry, truth_at_scan),
        mapper_error_m: distance(corrected, truth_at_scan),
        max_mapper_error_m,
        iou,
        known_iou,
        stats: mapper.stats(),
        travelled_m: tour.travelled_m(),
        errors_in_sigmas,
        sigma_m,
    }
}

/// The mapper's covariance is honest: round the office floor with the simulator's default
/// noise, the corrected pose's true error stays within two of its standard deviations at 95 %
/// of the scans and within three at every one, and the deviation stays small enough for a
/// follower to drive on (under 0.15 m, `localised`, where the loop brings it back).
#[test]
fn the_mappers_covariance_holds_its_true_error() {
    for seed in [1, 2, 3] {
        let run = drive_the_building_loop(seed, 1.0, true);
        let mut sorted = run.errors_in_sigmas.clone();
        sorted.sort_by(f64::total_cmp);
        let p95 = sorted[sorted.len() * 95 / 100];
        let worst = sorted[sorted.len() - 1];
        println!(
            "seed {seed}: {:.1} m, error over sigma: median {:.2}, 95 % {p95:.2}, worst \
             {worst:.2}; sigma at the end {:.3} m; worst error {:.3} m",
            run.travelled_m,
            sorted[sorted.len() / 2],
            run.sigma_m,
            run.max_mapper_error_m
        );
        assert!(
            p95 <= 2.0,
            "seed {seed}: 95 % of errors within {p95:.2} sigma"
        );
        assert!(worst <= 3.0, "seed {seed}: an error of {worst:.2} sigma");
        assert!(
            run.sigma_m <= 0.15,
            "seed {seed}: sigma {:.3} m",
            run.sigma_m
        );
    }
}

/// The acceptance test: round the building with twice the default odometry noise, the
/// corrected pose ends at least 3 times closer to the truth than the odometry. Measured (seed 1)
/// before loop closure: odometry 2.27 m off after 91.6 m, the mapper 1 mm (back on the part of
/// the map made at the start), 0.27 m at worst on the way; IoU 0.16 against the whole true grid
/// (which counts obstacles' insides, walls two cells thick where they lie on cell boundaries,
/// and rooms never entered), 0.42 over the cells the mapper observed. Other seeds and up to 5
/// times the default noise gave ratios of 9 to 4000, worst errors of 0.06 to 0.44 m and IoUs of
/// 0.10 to 0.21. With loop closure (the default, run here: this loop comes back through the
/// corridor again and again, and a false or harmful closure would show), 2 mm in the end,
/// 0.18 m at worst, IoU 0.21 and 0.59 over the observed cells.
#[test]
fn the_mapper_beats_odometry_round_the_building() {
    let run = drive_the_building_loop(1, 2.0, true);
    let ratio = run.odometry_error_m / run.mapper_error_m;
    println!(
        "building loop, {:.1} m: final error odometry {:.3} m, mapper {:.3} m (×{ratio:.1} \
         smaller; worst {:.3} m on the way); occupied IoU {:.3} ({:.3} over observed cells); \
         {} scans, {} matched, {:.2} ms per scan",
        run.travelled_m,
        run.odometry_error_m,
        run.mapper_error_m,
        run.max_mapper_error_m,
        run.iou,
        run.known_iou,
        run.stats.scans,
        run.stats.matched,
        run.stats.ms_per_scan()
    );
    assert!(run.travelled_m > 80.0, "{} m", run.travelled_m);
    assert!(
        run.odometry_error_m > 1.0,
        "the odometry must drift meaningfully"
    );
    assert!(ratio >= 3.0, "only ×{ratio:.2}");
    assert!(run.max_mapper_error_m < 0.5, "{} m", run.max_mapper_error_m);
    assert!(
        run.stats.matched * 100 >= run.stats.scans * 95,
        "{:?}",
        run.stats
    );
    assert!(
        run.iou >= 0.12 && run.known_iou >= 0.3,
        "IoU {} / {}",
        run.iou,
        run.known_iou
    );
}

#[test]
fn the_last_scan_placed_is_drawn_from_the_corrected_pose() {
    use armor_module_api::types::{Frame, Shape};
    let scan = LaserScan {
        angle_min_rad: 0.0,
        angle_increment_rad: std::f64::consts::FRAC_PI_2,
        range_max_m: 10.0,
        ranges_m: vec![2.0, 10.0, f32::NAN, 1.0],
    };
    let pose = Pose2D {
        x_m: 1.0,
        y_m: 1.0,
        theta_rad: std::f64::consts::FRAC_PI_2,
    };
    let markers = super::placed_scan(&scan, pose);
    let marker = &markers.markers[0];
    assert_eq!((marker.shape, marker.frame), (Shape::Points, Frame::World));
    // Ahead (north) 2 m, and to the robot's right (east) 1 m; no echo and NaN left out.
    let points: Vec<(f32, f32)> = marker
        .points
        .iter()
        .map(|p| {
            (
                (p.x_m * 100.0).round() / 100.0,
                (p.y_m * 100.0).round() / 100.0,
            )
        })
        .collect();
    assert_eq!(points, [(1.0, 3.0), (2.0, 1.0)]);
}

/// The intersection over union of the occupied cells (over 50 %) of the mapper's grid and the
/// true one, each dilated by one cell (to its eight neighbours) first, so that a wall drawn half
/// a cell off, or two cells thick where it lies on a cell boundary, still counts as found. Both
/// are taken on the mapper's cells; the true grid's cells are aligned with them.
fn dilated_iou(map: &OccupancyGrid, truth: &OccupancyGrid) -> f64 {
    let (w, h) = (map.width as usize, map.height as usize);
    let mapped: Vec<bool> = map.cells.iter().map(|&c| c > 50).collect();
    let mut true_cells = vec![false; w * h];
    for (index, &cell) in truth.cells.iter().enumerate() {
        if cell <= 50 {
            continue;
        }
        let (col, row) = (index % truth.width as usize, index / truth.width as usize);
        let x = truth.origin_x_m + (col as f64 + 0.5) * truth.resolution_m;
        let y = truth.origin_y_m + (row as f64 + 0.5) * truth.resolution_m;
        let mc = ((x - map.origin_x_m) / map.resolution_m).floor();
        let mr = ((y - map.origin_y_m) / map.resolution_m).floor();
        assert!(
            mc >= 0.0 && mr >= 0.0 && (mc as usize) < w && (mr as usize) < h,
            "the mapper's grid covers the world"
        );
        true_cells[mr as usize * w + mc as usize] = true;
    }
    let dilate = |cells: &[bool]| {
        let mut out = vec![false; w * h];
        for row in 0..h {
            for col in 0..w {
                if !cells[row * w + col] {
                    continue;
                }
                for r in row.saturating_sub(1)..=(row + 1).min(h - 1) {
                    for c in col.saturating_sub(1)..=(col + 1).min(w - 1) {
                        out[r * w + c] = true;
                    }
                }
            }
        }
        out
    };
    let (mapped, true_cells) = (dilate(&mapped), dilate(&true_cells));
    let both = mapped
        .iter()
        .zip(&true_cells)
        .filter(|(a, b)| **a && **b)
        .count();
    let either = mapped
        .iter()
        .zip(&true_cells)
        .filter(|(a, b)| **a || **b)
        .count();
    both as f64 / either as f64
}

/// One drive round the ring corridor of [`RING_FLOOR`] with the simulator's default noise.
#[derive(Debug)]
struct RingRun {
    /// Back at the start: the mapper's error against the truth, and the odometry's.
    closure_error_m: f64,
    closure_heading_error_rad: f64,
    odometry_error_m: f64,
    /// The worst error of the pose published on the way.
    max_error_m: f64,
    /// The keyframes' poses as the last loop closure left them, against the truth at their
    /// scans: the trajectory as the mapper knows it in the end (none without loop closure).
    keyframe_errors_m: Option<(f64, f64)>,
    iou: f64,
    /// The IoU of a map drawn from the true poses: the best the scans allow.
    truth_iou: f64,
    stats: Stats,
    travelled_m: f64,
}

fn drive_the_ring(seed: u64, loop_closure: bool) -> RingRun {
    let world = World::parse(RING_FLOOR, "ring.world").expect("valid");
    let truth_grid = world.occupancy_grid(0.1).expect("grid");
    let params = SimParams {
        seed,
        ..SimParams::default()
    };
    let mut sim = Simulator::new(world, params).expect("fits");
    let settings = Settings {
        loop_closure,
        ..Settings::default()
    };
    let mut mapper = Mapper::new(settings).expect("settings");
    let mut placed = Mapper::new(settings).expect("settings");
    let mut tour = Tour::new(RING_LOOP, 20_000);
    let (mut corrected, mut odometry, mut truth) = (sim.truth(), sim.truth(), sim.truth());
    let mut max_error_m = 0.0_f64;
    let mut key_truths = Vec::new();
    while let Some(report) = tour.next_scan(&mut sim) {
        odometry = report.odometry.pose_in_odom;
        truth = report.truth;
        placed.place_scan(sim.scan(), truth).expect("scan");
        let before = mapper.stats().keyframes;
        corrected = mapper.on_scan(sim.scan(), odometry).expect("scan");
        if mapper.stats().keyframes > before {
            key_truths.push(truth);
        }
        max_error_m = max_error_m.max(distance(corrected, truth));
    }
    assert!(tour.finished(), "the robot got stuck at {:?}", sim.truth());
    assert_eq!(sim.collisions(), 0);
    let keyframe_poses = mapper.keyframe_poses();
    assert_eq!(keyframe_poses.len(), key_truths.len());
    let keyframe_errors: Vec<f64> = keyframe_poses
        .iter()
        .zip(&key_truths)
        .map(|(&pose, &truth)| distance(pose, truth))
        .collect();
    let map = mapper.occupancy_grid().expect("a map");
    RingRun {
        closure_error_m: distance(corrected, truth),
        closure_heading_error_rad: wrap_angle(corrected.theta_rad - truth.theta_rad).abs(),
        odometry_error_m: distance(odometry, truth),
        max_error_m,
        keyframe_errors_m: (!keyframe_errors.is_empty()).then(|| {
            let mean = keyframe_errors.iter().sum::<f64>() / keyframe_errors.len() as f64;
            (mean, keyframe_errors.iter().copied().fold(0.0, f64::max))
        }),
        iou: dilated_iou(&map, &truth_grid),
        truth_iou: dilated_iou(&placed.occupancy_grid().expect("a map"), &truth_grid),
        stats: mapper.stats(),
        travelled_m: tour.travelled_m(),
    }
}

/// The loop closure test: once round a 100 m ring corridor with the simulator's default
/// noise. The scan matcher alone slips along the corridor where its walls say nothing of where
/// along it the robot is, and comes back to the start off by that slip, the part of the map
/// made since drawn that much aside; with loop closure, the loop closes near the start, the
/// pose comes back onto the truth, the graph puts the correction where the walls said nothing
/// (the odometry's edges are then what counts), and the map is drawn again from the corrected
/// keyframes. Measured (seed 1): 0.509 m off at the closure without, 0.004 m with (×127);
/// keyframes 0.05 m off on average and 0.11 m at worst in the end; IoU 0.496 without, 0.695
/// with (0.637 for a map of every scan at its true pose: the keyframes' map has fewer stray
/// cells).
#[test]
fn closing_the_loop_round_a_ring_corridor_corrects_the_pose_and_the_map_seed_1() {
    let off = drive_the_ring(1, false);
    let on = drive_the_ring(1, true);
    for (name, run) in [("without loop closure", &off), ("with loop closure", &on)] {
        println!(
            "ring, {:.1} m, {name}: error at the closure {:.3} m and {:.2}° (odometry {:.3} m), \
             worst on the way {:.3} m; keyframes in the end (mean, max) {:.3?} m; occupied IoU \
             (dilated) {:.3} (from the true poses {:.3}); {:?}",
            run.travelled_m,
            run.closure_error_m,
            run.closure_heading_error_rad.to_degrees(),
            run.odometry_error_m,
            run.max_error_m,
            run.keyframe_errors_m,
            run.iou,
            run.truth_iou,
            run.stats
        );
    }
    assert!(off.travelled_m > 95.0, "{} m", off.travelled_m);
    assert_eq!(off.stats.keyframes, 0, "no keyframes without loop closure");
    assert!(
        off.closure_error_m > 0.2,
        "the mapper alone must drift for the test to mean anything: {} m",
        off.closure_error_m
    );
    assert!(
        on.stats.loop_closures >= 1 && on.stats.optimisations >= 1,
        "{:?}",
        on.stats
    );
    assert!(
        on.closure_error_m * 5.0 < off.closure_error_m && on.closure_error_m < 0.05,
        "{} m with loop closure, {} m without",
        on.closure_error_m,
        off.closure_error_m
    );
    let (_, keyframe_max_error_m) = on.keyframe_errors_m.expect("keyframes");
    assert!(
        keyframe_max_error_m < 0.25,
        "the corrected trajectory is {keyframe_max_error_m} m off at worst"
    );
    assert!(
        on.iou > off.iou + 0.1,
        "IoU {} with loop closure, {} without",
        on.iou,
        off.iou
    );
}
