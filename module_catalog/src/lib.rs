//! The modules bundled with ArMoR, one binary `armor-mod-<type>` each (in `src/bin/`). Each
//! module's [`ModuleSpec`](armor_module_api::ModuleSpec) and body live here so the unit tests drive
//! the very body the binary runs, on a [`TestBench`](armor_module_api::testing::TestBench):
//!
//! - [`arbiter`]: chooses among competing behaviours: the fresh candidate of highest priority
//!   (set per candidate in the system file) wins, with hysteresis; reports `winner_changed`.
//! - [`counter`]: publishes 1, 2, 3, … on `count` every `period_secs` while active, and reports
//!   `done` after `limit` values.
//! - [`checker`]: reads a `Counter` stream reliably, reports `out_of_order` and `restarted`, logs
//!   `received N values, last V, in order` every `report_every` values, and publishes how many it
//!   received.
//! - [`echo`]: republishes every `Blob` it receives, unchanged and at once (latency benchmark).
//! - [`sink`]: counts the `Blob`s it receives and publishes the count every `every` values
//!   (throughput benchmark).
//! - [`sim`]: a simulated differential-drive robot with a laser scanner in a 2-D world file,
//!   on the run clock; its world model is [`armor_model::world`], shared with plans and maps.
//! - [`camera`]: `camera-sim`, a camera over the simulator's world, rendered on the CPU from the
//!   robot's true pose (raw `rgb8`, `mono8` or JPEG images).
//! - [`nav`]: navigation in two modules linked by `cmd_desired`: [`nav::follower`] drives
//!   towards a goal set per leg (`goal_reached`, `blocked`), round the plan's no-go areas,
//!   and [`nav::avoider`] bends that
//!   command away from obstacles seen in the laser scan and stops short of them (`safety_stop`);
//!   [`nav::vff`] (obstacle avoidance) and [`nav::stop`] (always applies, proposes zero) are
//!   behaviours the [`arbiter`] chooses among, beside the follower.
//! - [`mapper`]: an occupancy grid from laser scans and odometry, with the pose corrected by
//!   matching each scan against the map so far (published as `pose`, in place of odometry).
//! - [`localiser`]: Monte Carlo localisation on the plan's map (a `.world` or a ROS map): the
//!   robot's pose in the map frame with its covariance, in place of odometry, and whether it is
//!   `localised`, `uncertain` or `lost`.
//! - [`mux`]: the one source of the robot's `cmd_vel`: teleop when fresh and non-zero, else
//!   observe, else auto, else zero (not controllable).
//! - [`observer`]: turns on the spot through a sector measured on the odometry heading, then
//!   reports `observation_done`.
//! - [`teleop`]: operator velocity commands over a TCP line protocol, clamped and held for a
//!   dead-man time (not controllable).
//! - [`monitor`]: logs every report of the run's health stream (`armor.health`) and counts
//!   them (not controllable).
//! - [`params`]: numeric parameters read with their range, refused in the same words by every
//!   module.
//! - [`webcam`]: a V4L2 camera published as images (Motion-JPEG as it comes, YUYV as rgb8);
//!   no camera is a clear error and a normal end, not a crash loop.
//! - [`recorder`]: records every sample of the data names in `record`, with stamp and type,
//!   into an MCAP file while active (JSON for the built-in types); `armor replay` plays it back.
//! - [`foxglove_bridge`]: `foxglove`, serves the data names in `topics` to Foxglove over its
//!   WebSocket protocol, in Foxglove's schemas, on loopback only (not controllable).

pub mod arbiter;
pub mod camera;
pub mod checker;
pub mod counter;
pub mod echo;
pub mod foxglove_bridge;
pub mod localiser;
pub mod mapper;
pub mod monitor;
pub mod mux;
pub mod nav;
pub mod observer;
pub mod params;
pub mod recorder;
pub mod sim;
pub mod sink;
pub mod teleop;
pub mod webcam;

/// An angle brought into (-π, π].
pub fn wrap_angle(angle_rad: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let wrapped = (angle_rad + PI).rem_euclid(TAU) - PI;
    if wrapped == -PI { PI } else { wrapped }
}

/// The error a module body returns when it refuses its configuration.
pub type BodyError = Box<dyn std::error::Error + Send + Sync>;
