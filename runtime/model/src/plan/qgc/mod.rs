//! QGroundControl plan files (`.plan`: JSON, as QGC's developer guide documents it under
//! "Plan File Format") to and from plans, for the ground stations that read them.
//!
//! Export: the route as the mission's items, its first waypoint as `plannedHomePosition`; each
//! leg's destination is a `MAV_CMD_NAV_WAYPOINT` (16) whose hold time (param1) is the leg's
//! `wait_secs`; an appointment (`not_before`) is a `MAV_CMD_NAV_DELAY` (93) until its time of
//! day (UTC) before the leg; no-go areas are exclusion polygons of the geofence, wound
//! clockwise; the waypoints a `return` contingency names are rally points. The robot is
//! written as a ground rover (`MAV_TYPE` 10) of a generic autopilot (`MAV_AUTOPILOT` 0), at
//! 0 m above home (frame 3, global with relative altitude). What the format cannot carry is
//! listed in [`Exported::dropped`].
//!
//! Import: `plannedHomePosition` is the start (`home`); waypoint items (16, and 82 spline
//! waypoints, 19 timed loiters, which hold) become waypoints `wp1`, `wp2`, … joined by legs;
//! a delay (93) of seconds lengthens the wait where the robot is, a delay until a time of day
//! is the next leg's `not_before` on the day of the plan's start (when one is given); exclusion
//! polygons become no-go areas, exclusion circles no-go polygons round them, inclusion fences
//! named areas, rally points waypoints. Everything else (complex items such as surveys, other
//! commands, altitudes) is skipped with a warning. Problems and warnings say `LINE:COL` and the
//! JSON path of the value.

mod export;
mod fence;
mod import;
#[cfg(test)]
mod tests;

pub use export::{Exported, export};
pub use import::{Failed, Imported, import, import_all};

pub const MAV_CMD_NAV_WAYPOINT: u64 = 16;
pub const MAV_CMD_NAV_LOITER_TIME: u64 = 19;
pub const MAV_CMD_NAV_SPLINE_WAYPOINT: u64 = 82;
pub const MAV_CMD_NAV_DELAY: u64 = 93;
/// `MAV_FRAME_MISSION`: a command without coordinates.
pub const MAV_FRAME_MISSION: u64 = 2;
pub const MAV_FRAME_GLOBAL_RELATIVE_ALT: u64 = 3;
pub const MAV_TYPE_GROUND_ROVER: u64 = 10;
const MAV_TYPE_SURFACE_BOAT: u64 = 11;
pub const MAV_AUTOPILOT_GENERIC: u64 = 0;
/// QGC's `AltitudeModeRelative` (its `AltMode` enum: mixed, relative, absolute, …).
pub const ALTITUDE_MODE_RELATIVE: u64 = 1;
/// The frames whose coordinates are latitude and longitude: global, relative, terrain, and
/// their `_INT` forms.
const GLOBAL_FRAMES: [u64; 6] = [0, 3, 5, 6, 10, 11];
/// Corners of the polygon an exclusion circle is imported as.
pub const CIRCLE_CORNERS: usize = 32;
const SECS_PER_DAY: f64 = 86_400.0;
