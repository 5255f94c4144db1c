//! The team's figures (issue 41), relayed as the studio's are:
//!
//! - `team_status_latency_ms` (on loopback), `team_status_latency_ms_radio` (through the lossy
//!   radio of the namespace test, as root; skipped otherwise, saying why) and
//!   `team_bandwidth_kbps_per_robot` from `armor-team bench`, the
//!   only program that links zenoh (`armor-bench` does not, so that `cargo build` of the rest
//!   builds no zenoh);
//! - `station_frame_ms_20_robots` from `armor-studio-bench` (the station view is egui's).

use armor_bench_report::Report;

use crate::Settings;
use crate::procs::relay;

pub const NAME_LATENCY: &str = "team_status_latency_ms";
pub const NAME_LATENCY_RADIO: &str = "team_status_latency_ms_radio";
pub const NAME_BANDWIDTH: &str = "team_bandwidth_kbps_per_robot";
pub const NAME_STATION_FRAME: &str = "station_frame_ms_20_robots";

pub fn run_latency(settings: &Settings) -> anyhow::Result<Report> {
    relay("armor-team", &["bench"], NAME_LATENCY, "ms", settings)
}

pub fn run_latency_radio(settings: &Settings) -> anyhow::Result<Report> {
    relay("armor-team", &["bench"], NAME_LATENCY_RADIO, "ms", settings)
}

pub fn run_bandwidth(settings: &Settings) -> anyhow::Result<Report> {
    relay("armor-team", &["bench"], NAME_BANDWIDTH, "kbit/s", settings)
}

pub fn run_station_frame(settings: &Settings) -> anyhow::Result<Report> {
    relay(
        "armor-studio-bench",
        &[],
        NAME_STATION_FRAME,
        "ms",
        settings,
    )
}
