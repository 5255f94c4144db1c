//! `camera_sim_ms_per_frame`: the simulated camera's cost of one 320×240 frame as the bundled
//! camera makes it (drawn on the CPU, then encoded as JPEG at quality 80), against the JPEG
//! encoding of the same pictures alone (the `image` crate's encoder: what any camera module that
//! sends JPEG pays; `ratio` says what drawing adds to it). Both per-frame distributions in
//! milliseconds, on one thread of this process.
//!
//! The views are those of the headless simulator driven once round the office floor of
//! `building.world` (one frame per laser scan, every tenth of a second of simulated time), so
//! walls near and far, corners and open halls all come in. Goal: under 10 ms a frame, so that 15
//! frames a second take well under one core.

use std::time::{Duration, Instant};

use anyhow::anyhow;
use armor_module_api::types::{Image, ImageEncoding, Pose2D};
use armor_module_catalog::camera::render::{Camera, to_jpeg};
use armor_module_catalog::camera::{Settings as CameraSettings, Shooter};
use armor_module_catalog::sim::tour::{BUILDING_LOOP, Tour};
use armor_module_catalog::sim::world::World;
use armor_module_catalog::sim::{SimParams, Simulator};

use crate::Settings;
use armor_bench_report::Report;

pub const NAME: &str = "camera_sim_ms_per_frame";
const BUILDING_WORLD: &str = include_str!("../../../assets/worlds/building.world");
const MAX_STEPS: u64 = 20_000;
const QUALITY: u8 = 80;

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let limit = if settings.quick { 20 } else { 600 };
    let world = World::parse(BUILDING_WORLD, "building.world").map_err(|err| anyhow!("{err}"))?;
    let poses = tour_poses(&world, limit)?;
    // The module's defaults: 320×240, 90° wide.
    let camera = Camera::default();
    let mut shooter = Shooter::new(CameraSettings {
        camera,
        rate_hz: 15.0,
        max_real_hz: 15.0,
        encoding: ImageEncoding::Jpeg,
        jpeg_quality: QUALITY,
        frame_id: "camera".into(),
    });
    let mut image = Image {
        width: 0,
        height: 0,
        encoding: ImageEncoding::Jpeg,
        stamp_ns: 0,
        frame_id: String::new(),
        data: Default::default(),
    };
    let mut ours = Vec::with_capacity(poses.len());
    let mut bytes = 0;
    for pose in &poses {
        let start = Instant::now();
        shooter
            .shoot(&world, *pose, 0, &mut image)
            .map_err(|err| anyhow!("{err}"))?;
        ours.push(start.elapsed());
        bytes += image.data.len();
    }
    let mut rgb = Vec::new();
    let mut jpeg = Vec::new();
    let mut reference: Vec<Duration> = Vec::with_capacity(poses.len());
    let mut render: Vec<Duration> = Vec::with_capacity(poses.len());
    for pose in &poses {
        let start = Instant::now();
        camera.render(&world, *pose, &mut rgb);
        render.push(start.elapsed());
        let start = Instant::now();
        to_jpeg(&rgb, camera.width, camera.height, QUALITY, &mut jpeg)
            .map_err(|err| anyhow!("{err}"))?;
        reference.push(start.elapsed());
    }
    render.sort();
    let render_ms = render[render.len() / 2].as_secs_f64() * 1e3;
    Ok(Report::distribution(NAME, "ms", 1e3, &ours, &reference)
        .with(
            "reference_is",
            "the JPEG encoding of the same pictures alone (image crate, quality 80)",
        )
        .with("render_p50_ms", (render_ms * 1000.0).round() / 1000.0)
        .with("frames", poses.len())
        .with("jpeg_bytes_mean", bytes / poses.len().max(1))
        .with("goal", 10.0))
}

/// The true pose at each scan of a drive round the building loop (at most `limit`).
fn tour_poses(world: &World, limit: usize) -> anyhow::Result<Vec<Pose2D>> {
    let mut sim =
        Simulator::new(world.clone(), SimParams::default()).map_err(|err| anyhow!("{err}"))?;
    let mut tour = Tour::new(BUILDING_LOOP, MAX_STEPS);
    let mut poses = Vec::new();
    while poses.len() < limit
        && let Some(_report) = tour.next_scan(&mut sim)
    {
        poses.push(sim.truth());
    }
    if poses.is_empty() {
        return Err(anyhow!("the simulated robot took no step"));
    }
    Ok(poses)
}
