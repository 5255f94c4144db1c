//! A QGC plan file read into a plan (see [`super`]).

use armor_module_api::xml::{Located, Pos};
use serde_json::{Map, Value};

use super::{
    GLOBAL_FRAMES, MAV_CMD_NAV_DELAY, MAV_CMD_NAV_LOITER_TIME, MAV_CMD_NAV_SPLINE_WAYPOINT,
    MAV_CMD_NAV_WAYPOINT, MAV_TYPE_GROUND_ROVER, MAV_TYPE_SURFACE_BOAT, SECS_PER_DAY,
};
use crate::json_positions::{JsonPositions, index_path, key_path};
use crate::plan::xml::default_leg_name;
use crate::plan::{LatLon, Leg, Plan, Waypoint};

/// A plan read from a QGC plan file, with what was dropped or changed on the way.
#[derive(Debug)]
pub struct Imported {
    pub plan: Plan,
    pub warnings: Vec<Located>,
}

/// A QGC plan file that cannot be imported: its problems, and the warnings about what was
/// skipped on the way (often the reason: a survey skipped leaves no waypoint).
#[derive(Debug)]
pub struct Failed {
    pub problems: Vec<Located>,
    pub warnings: Vec<Located>,
}

/// Reads a QGC plan file into a plan called `name` over the system file `system`. A delay
/// until a time of day becomes an appointment on the day of `start_unix_secs` (the plan's
/// start), or the next day when that time has passed; without a start it is dropped.
pub fn import(
    text: &str,
    name: &str,
    system: &str,
    start_unix_secs: Option<f64>,
) -> Result<Imported, Vec<Located>> {
    import_all(text, name, system, start_unix_secs).map_err(|failed| failed.problems)
}

/// [`import`], with the warnings also when the file is refused.
pub fn import_all(
    text: &str,
    name: &str,
    system: &str,
    start_unix_secs: Option<f64>,
) -> Result<Imported, Failed> {
    let root: Value = serde_json::from_str(text).map_err(|err| Failed {
        problems: vec![json_error(&err)],
        warnings: Vec::new(),
    })?;
    let mut reader = Reader {
        positions: JsonPositions::of(text),
        problems: Vec::new(),
        warnings: Vec::new(),
    };
    let plan = reader.plan(&root, name, system, start_unix_secs);
    let Reader {
        mut problems,
        mut warnings,
        ..
    } = reader;
    warnings.sort_by_key(|warning| warning.pos);
    match plan {
        Some(plan) if problems.is_empty() => Ok(Imported { plan, warnings }),
        _ => {
            problems.sort_by_key(|problem| problem.pos);
            Err(Failed { problems, warnings })
        }
    }
}

/// serde_json's syntax error at its line and column, its message without them.
fn json_error(err: &serde_json::Error) -> Located {
    let message = err.to_string();
    let message = message
        .rsplit_once(" at line ")
        .map_or(message.as_str(), |(message, _)| message);
    Located::new(
        Pos {
            line: u32::try_from(err.line().max(1)).unwrap_or(u32::MAX),
            col: u32::try_from(err.column().max(1)).unwrap_or(u32::MAX),
        },
        format!("not a QGC plan (JSON): {message}"),
    )
}

pub(super) struct Reader<'a> {
    positions: JsonPositions<'a>,
    problems: Vec<Located>,
    warnings: Vec<Located>,
}

/// What the items read so far leave for the legs that follow.
#[derive(Default)]
struct Route {
    waypoints: Vec<Waypoint>,
    legs: Vec<Leg>,
    /// A time-of-day delay waiting for the next leg: its date and where it was written.
    not_before: Option<(f64, String)>,
    /// The latest appointment so far, after which the next time of day falls.
    last_time: Option<f64>,
}

impl Route {
    /// A leg from the last stop to `position`, holding `hold_secs` there.
    /// The first is the start, `home`.
    fn drive_to(&mut self, position: LatLon, hold_secs: f64) {
        let name = match self.waypoints.len() {
            0 => "home".to_owned(),
            n => format!("wp{n}"),
        };
        let from = self.waypoints.last().map(|w| w.name.clone());
        self.waypoints.push(Waypoint {
            name: name.clone(),
            position,
            ..Waypoint::default()
        });
        if let Some(from) = from {
            let index = self.legs.len();
            self.legs.push(Leg {
                name: default_leg_name(index),
                from,
                to: name,
                wait_secs: (hold_secs > 0.0).then_some(hold_secs),
                not_before_unix_secs: self.not_before.take().map(|(at, _)| at),
                ..Leg::default()
            });
        }
    }
}

impl Reader<'_> {
    fn at(&self, path: &str) -> Pos {
        self.positions.at(path)
    }

    pub(super) fn problem(&mut self, path: &str, message: impl std::fmt::Display) {
        let pos = self.at(path);
        self.problems.push(Located::new(pos, message.to_string()));
    }

    pub(super) fn warn(&mut self, path: &str, message: impl std::fmt::Display) {
        let pos = self.at(path);
        self.warnings.push(Located::new(pos, message.to_string()));
    }

    fn plan(
        &mut self,
        root: &Value,
        name: &str,
        system: &str,
        start_unix_secs: Option<f64>,
    ) -> Option<Plan> {
        let Some(root) = root.as_object() else {
            self.problem(
                "",
                "a QGC plan is a JSON object with `\"fileType\": \"Plan\"`",
            );
            return None;
        };
        match root.get("fileType") {
            Some(Value::String(kind)) if kind == "Plan" => {}
            Some(other) => {
                self.problem(
                    "fileType",
                    format!("`fileType` is {other}: a QGC plan file says \"Plan\""),
                );
                return None;
            }
            None => {
                self.problem(
                    "",
                    "no `fileType`: a QGC plan file says `\"fileType\": \"Plan\"`",
                );
                return None;
            }
        }
        self.expect_version(root, "", 1, "the file");
        let Some(mission) = root.get("mission").and_then(Value::as_object) else {
            self.problem(
                if root.contains_key("mission") {
                    "mission"
                } else {
                    ""
                },
                "a QGC plan needs a `mission` object",
            );
            return None;
        };
        self.expect_version(mission, "mission", 2, "the mission");
        let mut plan = Plan {
            name: crate::plan::gpx::Names::default().identifier(name, "plan"),
            system: system.to_owned(),
            start_unix_secs,
            ..Plan::default()
        };
        self.vehicle(mission, &mut plan);
        let mut route = Route {
            last_time: start_unix_secs,
            ..Route::default()
        };
        match mission.get("plannedHomePosition") {
            Some(home) => {
                if let Some(home) = self.lat_lon(home, "mission.plannedHomePosition") {
                    route.drive_to(home, 0.0);
                }
            }
            None => self.warn(
                "mission",
                "no `plannedHomePosition`: the route starts at the first waypoint",
            ),
        }
        match mission.get("items") {
            Some(Value::Array(items)) => {
                for (index, item) in items.iter().enumerate() {
                    self.item(item, &index_path("mission.items", index), &mut route);
                }
            }
            _ => self.problem("mission", "the mission needs `items`, a list"),
        }
        if let Some((_, path)) = route.not_before.take() {
            self.warn(
                &path,
                "a delay after the last waypoint holds nothing: dropped",
            );
        }
        plan.waypoints = route.waypoints;
        plan.legs = route.legs;
        if let Some(fence) = root.get("geoFence") {
            self.fence(fence, &mut plan);
        }
        if let Some(rally) = root.get("rallyPoints") {
            self.rally(rally, &mut plan);
        }
        if self.problems.is_empty() && plan.legs.is_empty() {
            let skipped = self.warnings.len();
            self.problem(
                "mission.items",
                if skipped == 0 {
                    "the QGC plan has no waypoint to drive to: a plan needs two points to make a \
                     leg"
                    .to_owned()
                } else {
                    format!(
                        "the QGC plan has no waypoint to drive to: a plan needs two points to \
                         make a leg, and what it has was skipped ({}, each warned where it is)",
                        crate::plural(skipped, "warning")
                    )
                },
            );
        }
        Some(plan)
    }

    fn expect_version(&mut self, object: &Map<String, Value>, path: &str, want: u64, what: &str) {
        let version_path = key_path(path, "version");
        match object.get("version") {
            Some(version) if version.as_u64() == Some(want) => {}
            Some(version) => self.warn(
                &version_path,
                format!("{what} is version {version}, read as version {want}"),
            ),
            None => self.warn(
                path,
                format!("{what} has no `version`, read as version {want}"),
            ),
        }
    }

    /// The vehicle the plan was made for: a ground robot's speed is taken.
    fn vehicle(&mut self, mission: &Map<String, Value>, plan: &mut Plan) {
        let vehicle = mission.get("vehicleType").and_then(Value::as_u64);
        match vehicle {
            Some(MAV_TYPE_GROUND_ROVER | MAV_TYPE_SURFACE_BOAT) => {
                if let Some(speed) = mission
                    .get("cruiseSpeed")
                    .and_then(Value::as_f64)
                    .filter(|speed| speed.is_finite() && *speed > 0.0)
                {
                    // The plan's own speed, as QGC's time estimates use it; `armor check`
                    // times the legs at the robot's speed when that is slower.
                    plan.navigation.speed_mps = speed;
                }
            }
            Some(other) => self.warn(
                "mission.vehicleType",
                format!(
                    "the plan was made for a vehicle of MAV_TYPE {other}, not a ground rover \
                     (10): its route is read for the robot, its speeds are not"
                ),
            ),
            None => {}
        }
    }

    fn item(&mut self, item: &Value, path: &str, route: &mut Route) {
        let Some(object) = item.as_object() else {
            self.problem(path, "a mission item is a JSON object");
            return;
        };
        match object.get("type").and_then(Value::as_str) {
            Some("SimpleItem") => self.simple_item(object, path, route),
            Some("ComplexItem") => {
                let kind = object
                    .get("complexItemType")
                    .and_then(Value::as_str)
                    .unwrap_or("unknown");
                self.warn(
                    path,
                    format!(
                        "a complex item (`{kind}`, a pattern QGC expands into waypoints of its \
                         own) is not supported: skipped"
                    ),
                );
            }
            Some(other) => self.warn(
                &key_path(path, "type"),
                format!("an item of type `{other}` is not supported: skipped"),
            ),
            None => self.problem(path, "a mission item needs its `type` (\"SimpleItem\")"),
        }
    }

    fn simple_item(&mut self, item: &Map<String, Value>, path: &str, route: &mut Route) {
        let Some(command) = item.get("command").and_then(Value::as_u64) else {
            self.problem(path, "a simple item needs its `command`, a MAV_CMD number");
            return;
        };
        let params_path = key_path(path, "params");
        let Some(params) = item.get("params").and_then(Value::as_array) else {
            self.problem(path, "a simple item needs its `params`, a list of seven");
            return;
        };
        // QGC's older item format (which it still loads): four `params` and the position
        // apart, `coordinate` [latitude, longitude, altitude], as params 5 to 7.
        let coordinate_path = key_path(path, "coordinate");
        let coordinate = item
            .get("coordinate")
            .filter(|_| params.len() == 4)
            .map(|value| (value, coordinate_path.as_str()));
        // QGC writes a NaN parameter (unused) as null.
        let param = |index: usize| params.get(index).and_then(Value::as_f64);
        match command {
            MAV_CMD_NAV_WAYPOINT | MAV_CMD_NAV_SPLINE_WAYPOINT | MAV_CMD_NAV_LOITER_TIME => {
                let frame = item.get("frame").and_then(Value::as_u64);
                if !frame.is_some_and(|frame| GLOBAL_FRAMES.contains(&frame)) {
                    self.warn(
                        &key_path(path, "frame"),
                        format!(
                            "a waypoint in MAV_FRAME {}, not latitude and longitude: skipped",
                            frame.map_or("(none)".into(), |f| f.to_string())
                        ),
                    );
                    return;
                }
                let (position, altitude, altitude_path) = match coordinate {
                    Some((coordinate, coordinate_path)) => {
                        let Some(position) = self.lat_lon(coordinate, coordinate_path) else {
                            return;
                        };
                        let altitude = coordinate.get(2).and_then(Value::as_f64);
                        (position, altitude, index_path(coordinate_path, 2))
                    }
                    None => {
                        let lat = self.param_number(params, &params_path, 4, "the latitude");
                        let lon = self.param_number(params, &params_path, 5, "the longitude");
                        let (Some(lat), Some(lon)) = (lat, lon) else {
                            return;
                        };
                        let Some(position) = self.check_lat_lon(
                            (lat, &index_path(&params_path, 4)),
                            (lon, &index_path(&params_path, 5)),
                        ) else {
                            return;
                        };
                        (position, param(6), index_path(&params_path, 6))
                    }
                };
                if command == MAV_CMD_NAV_SPLINE_WAYPOINT {
                    self.warn(path, "a spline waypoint is driven to in a straight line");
                }
                let altitude = altitude.unwrap_or(0.0);
                if altitude != 0.0 {
                    self.warn(
                        &altitude_path,
                        format!("the altitude ({altitude} m) is not carried: a ground robot"),
                    );
                }
                let hold = param(0).filter(|hold| hold.is_finite() && *hold > 0.0);
                if route.waypoints.is_empty() {
                    // No home: the first waypoint is the start.
                    route.drive_to(position, 0.0);
                    if hold.is_some() {
                        self.warn(
                            &index_path(&params_path, 0),
                            "a hold at the start holds nothing: dropped",
                        );
                    }
                } else {
                    route.drive_to(position, hold.unwrap_or(0.0));
                }
            }
            MAV_CMD_NAV_DELAY => self.delay(params, &params_path, route),
            other => self.warn(
                &key_path(path, "command"),
                format!(
                    "command {other} ({}) is not supported: skipped",
                    command_name(other)
                ),
            ),
        }
    }

    /// A delay of seconds (param1 ≥ 0) or until a time of day (param1 = -1, then hour, minute,
    /// second in UTC).
    fn delay(&mut self, params: &[Value], params_path: &str, route: &mut Route) {
        let Some(delay) = self.param_number(params, params_path, 0, "the delay") else {
            return;
        };
        if delay == 0.0 {
            // Nothing to hold (-0 too: found by fuzzing, it came back as a wait of 0 s).
            return;
        }
        if delay > 0.0 {
            match route.legs.last_mut() {
                Some(leg) => leg.wait_secs = Some(leg.wait_secs.unwrap_or(0.0) + delay),
                None => self.warn(
                    params_path,
                    "a delay before the first waypoint cannot be held at the start: dropped",
                ),
            }
            return;
        }
        let mut field = |index: usize, what: &str, limit: f64| -> Option<f64> {
            let value = self.param_number(params, params_path, index, what)?;
            if (0.0..limit).contains(&value) {
                Some(value)
            } else {
                self.problem(
                    &index_path(params_path, index),
                    format!("{what} must be from 0 to {limit} (excluded), not {value}"),
                );
                None
            }
        };
        let (hour, minute, second) = (
            field(1, "the hour", 24.0),
            field(2, "the minute", 60.0),
            field(3, "the second", 60.0),
        );
        let (Some(hour), Some(minute), Some(second)) = (hour, minute, second) else {
            return;
        };
        let in_day = hour * 3600.0 + minute * 60.0 + second;
        let Some(after) = route.last_time else {
            self.warn(
                params_path,
                format!(
                    "a delay until {:02}:{:02}:{second:02} UTC needs the plan's start date \
                     (`--start`): dropped",
                    hour as u32, minute as u32
                ),
            );
            return;
        };
        let mut at = (after / SECS_PER_DAY).floor() * SECS_PER_DAY + in_day;
        if at < after {
            at += SECS_PER_DAY;
        }
        route.last_time = Some(at);
        if let Some((earlier, _)) = route.not_before {
            at = at.max(earlier);
        }
        route.not_before = Some((at, params_path.to_owned()));
    }

    fn param_number(
        &mut self,
        params: &[Value],
        params_path: &str,
        index: usize,
        what: &str,
    ) -> Option<f64> {
        let path = index_path(params_path, index);
        match params.get(index) {
            Some(value) => match value.as_f64().filter(|v| v.is_finite()) {
                Some(number) => Some(number),
                None => {
                    self.problem(&path, format!("{what} must be a number, not {value}"));
                    None
                }
            },
            None => {
                self.problem(
                    params_path,
                    format!("{what} (params[{index}]) is missing: a simple item has seven"),
                );
                None
            }
        }
    }

    /// A `[latitude, longitude, …]` point.
    pub(super) fn lat_lon(&mut self, value: &Value, path: &str) -> Option<LatLon> {
        let numbers = value.as_array().filter(|point| point.len() >= 2);
        let Some(point) = numbers else {
            self.problem(
                path,
                format!("a point is a list [latitude, longitude, …], not {value}"),
            );
            return None;
        };
        let lat = self.param_number(point, path, 0, "the latitude");
        let lon = self.param_number(point, path, 1, "the longitude");
        self.check_lat_lon((lat?, &index_path(path, 0)), (lon?, &index_path(path, 1)))
    }

    /// Each value with its path.
    fn check_lat_lon(
        &mut self,
        (lat, lat_path): (f64, &str),
        (lon, lon_path): (f64, &str),
    ) -> Option<LatLon> {
        if lat.abs() > 90.0 {
            self.problem(
                lat_path,
                format!("the latitude must be degrees between -90 and 90, not {lat}"),
            );
            return None;
        }
        if lon.abs() > 180.0 {
            self.problem(
                lon_path,
                format!("the longitude must be degrees between -180 and 180, not {lon}"),
            );
            return None;
        }
        Some(LatLon::new(lat, lon))
    }
}

/// The MAVLink name of the commands QGC plans use most, for warnings.
fn command_name(command: u64) -> &'static str {
    match command {
        17 => "NAV_LOITER_UNLIM",
        18 => "NAV_LOITER_TURNS",
        20 => "NAV_RETURN_TO_LAUNCH",
        21 => "NAV_LAND",
        22 => "NAV_TAKEOFF",
        31 => "NAV_LOITER_TO_ALT",
        84 => "NAV_VTOL_TAKEOFF",
        85 => "NAV_VTOL_LAND",
        112 => "CONDITION_DELAY",
        177 => "DO_JUMP",
        178 => "DO_CHANGE_SPEED",
        183 => "DO_SET_SERVO",
        189 => "DO_LAND_START",
        201 => "DO_SET_ROI",
        203 => "DO_DIGICAM_CONTROL",
        205 => "DO_MOUNT_CONTROL",
        206 => "DO_SET_CAM_TRIGG_DIST",
        530 => "SET_CAMERA_MODE",
        2000 => "IMAGE_START_CAPTURE",
        2001 => "IMAGE_STOP_CAPTURE",
        2500 => "VIDEO_START_CAPTURE",
        3000 => "DO_VTOL_TRANSITION",
        _ => "a MAV_CMD",
    }
}
