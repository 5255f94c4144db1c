//! The studio's figures: `studio_frame_ms_1000_blocks` (CPU time of one UI frame on a
//! 1,000-block, 1,500-link diagram; goal < 16 ms; `rendered_ms` with the frame rasterised by
//! the kittest snapshots' wgpu renderer) and `studio_load_ms_1000_blocks` (opening
//! that file), and `map_frame_ms_500_waypoints` (one frame of the Mission view with a
//! 500-waypoint plan and its symbols; goal < 16 ms), and `studio_vs_bare_snarl_1000` (our
//! diagram's frame against a bare egui-snarl viewer on the same graph, view, zoom and text; goal
//! ≤ 0.5×) with `studio_overview_vs_bare_snarl_1000` (our overview of boxes against the bare
//! viewer at that zoom), and
//! `layout_ms_200_blocks` (File → Arrange on 200 blocks and 300 links; goal < 100 ms). The runtime must not depend on egui, so `armor-studio-bench` measures them and
//! prints them as report lines; this relays them.

use crate::Settings;
use armor_bench_report::Report;

pub const NAME_FRAME: &str = "studio_frame_ms_1000_blocks";
pub const NAME_LOAD: &str = "studio_load_ms_1000_blocks";
pub const NAME_MAP: &str = "map_frame_ms_500_waypoints";
pub const NAME_LABELS: &str = "label_place_ms_500_waypoints";
pub const NAME_VS_SNARL: &str = "studio_vs_bare_snarl_1000";
pub const NAME_OVERVIEW_VS_SNARL: &str = "studio_overview_vs_bare_snarl_1000";
pub const NAME_LAYOUT: &str = "layout_ms_200_blocks";
pub const NAME_MARKERS: &str = "markers_frame_ms";

pub fn run_frame(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_FRAME, settings)
}

pub fn run_load(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_LOAD, settings)
}

pub fn run_map(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_MAP, settings)
}

pub fn run_labels(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_LABELS, settings)
}

pub fn run_layout(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_LAYOUT, settings)
}

pub fn run_markers(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_MARKERS, settings)
}

pub fn run_vs_snarl(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_VS_SNARL, settings)
}

pub fn run_overview_vs_snarl(settings: &Settings) -> anyhow::Result<Report> {
    relay(NAME_OVERVIEW_VS_SNARL, settings)
}

fn relay(name: &'static str, settings: &Settings) -> anyhow::Result<Report> {
    crate::procs::relay("armor-studio-bench", &[], name, "ms", settings)
}
