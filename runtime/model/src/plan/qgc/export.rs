//! A plan as a QGC plan file (see [`super`]).

use serde_json::{Value, json};

use super::{
    ALTITUDE_MODE_RELATIVE, MAV_AUTOPILOT_GENERIC, MAV_CMD_NAV_DELAY, MAV_CMD_NAV_WAYPOINT,
    MAV_FRAME_GLOBAL_RELATIVE_ALT, MAV_FRAME_MISSION, MAV_TYPE_GROUND_ROVER, SECS_PER_DAY,
};
use crate::plan::{AreaKind, GraphicKind, LatLon, Leg, Plan, Response, Waypoint};

/// A plan written as a QGC plan file.
#[derive(Debug)]
pub struct Exported {
    pub text: String,
    /// What the plan has that the file does not carry, one line per kind.
    pub dropped: Vec<String>,
}

/// The plan as a QGC plan file.
pub fn export(plan: &Plan) -> Exported {
    let stops = route_stops(plan);
    let home = stops.first().map(|waypoint| waypoint.position);
    let mut items = Vec::new();
    let mut push = |mut item: Value| {
        item["doJumpId"] = json!(items.len() + 1);
        items.push(item);
    };
    if plan.legs.is_empty() {
        for waypoint in stops.iter().skip(1) {
            push(waypoint_item(waypoint.position, 0.0));
        }
    }
    for (leg, to) in plan.legs.iter().zip(stops.iter().skip(1)) {
        if let Some(at) = leg.not_before_unix_secs {
            push(delay_until_item(at));
        }
        push(waypoint_item(to.position, leg.wait_secs.unwrap_or(0.0)));
    }
    let polygons: Vec<Value> = plan
        .no_go_areas()
        .map(|area| {
            let corners: Vec<Value> = clockwise(&area.points)
                .iter()
                .map(|corner| json!([corner.lat_deg, corner.lon_deg]))
                .collect();
            json!({"inclusion": false, "polygon": corners, "version": 1})
        })
        .collect();
    let rally: Vec<Value> = rally_waypoints(plan)
        .iter()
        .map(|waypoint| json!([waypoint.position.lat_deg, waypoint.position.lon_deg, 0.0]))
        .collect();
    let home = home.map_or(Value::Null, |home| json!([home.lat_deg, home.lon_deg, 0.0]));
    let document = json!({
        "fileType": "Plan",
        "groundStation": "ArMoR",
        "version": 1,
        "mission": {
            "version": 2,
            "firmwareType": MAV_AUTOPILOT_GENERIC,
            "vehicleType": MAV_TYPE_GROUND_ROVER,
            "cruiseSpeed": plan.navigation.speed_mps,
            "hoverSpeed": plan.navigation.speed_mps,
            "globalPlanAltitudeMode": ALTITUDE_MODE_RELATIVE,
            "plannedHomePosition": home,
            "items": items,
        },
        "geoFence": {"version": 2, "polygons": polygons, "circles": []},
        "rallyPoints": {"version": 2, "points": rally},
    });
    let mut text = serde_json::to_string_pretty(&document).unwrap_or_default();
    text.push('\n');
    Exported {
        text,
        dropped: dropped(plan),
    }
}

/// The waypoints the route passes, in order: the first leg's start and each leg's end; a plan
/// without legs, its waypoints.
fn route_stops(plan: &Plan) -> Vec<&Waypoint> {
    if plan.legs.is_empty() {
        plan.waypoints.iter().collect()
    } else {
        plan.route()
    }
}

/// The waypoints some `return` contingency names, once each, in the plan's order.
fn rally_waypoints(plan: &Plan) -> Vec<&Waypoint> {
    let returns: Vec<&str> = plan
        .every_contingency()
        .filter_map(|contingency| match &contingency.response {
            Response::Return { waypoint } => Some(waypoint.as_str()),
            _ => None,
        })
        .collect();
    plan.waypoints
        .iter()
        .filter(|waypoint| returns.contains(&waypoint.name.as_str()))
        .collect()
}

fn waypoint_item(position: LatLon, hold_secs: f64) -> Value {
    json!({
        "type": "SimpleItem",
        "command": MAV_CMD_NAV_WAYPOINT,
        "frame": MAV_FRAME_GLOBAL_RELATIVE_ALT,
        // Hold, acceptance radius, pass radius, yaw (NaN, which QGC writes as null: keep the
        // heading), latitude, longitude, altitude.
        "params": [hold_secs, 0.0, 0.0, null, position.lat_deg, position.lon_deg, 0.0],
        "autoContinue": true,
        "AMSLAltAboveTerrain": null,
        "Altitude": 0.0,
        "AltitudeMode": ALTITUDE_MODE_RELATIVE,
    })
}

/// A `MAV_CMD_NAV_DELAY` until the time of day of `unix_secs` (UTC): param1 -1 enables the
/// hour, minute and second fields.
fn delay_until_item(unix_secs: f64) -> Value {
    let in_day = unix_secs.rem_euclid(SECS_PER_DAY);
    let hour = (in_day / 3600.0).floor();
    let minute = ((in_day - hour * 3600.0) / 60.0).floor();
    let second = in_day - hour * 3600.0 - minute * 60.0;
    json!({
        "type": "SimpleItem",
        "command": MAV_CMD_NAV_DELAY,
        "frame": MAV_FRAME_MISSION,
        "params": [-1.0, hour, minute, second, 0.0, 0.0, 0.0],
        "autoContinue": true,
    })
}

/// The corners wound clockwise (seen on a map, north up), as QGC's geofence wants them.
fn clockwise(points: &[LatLon]) -> Vec<LatLon> {
    // The shoelace sum with x = longitude, y = latitude: positive is anticlockwise.
    let twice_area: f64 = points
        .iter()
        .zip(points.iter().cycle().skip(1))
        .map(|(a, b)| a.lon_deg * b.lat_deg - b.lon_deg * a.lat_deg)
        .sum();
    let mut corners = points.to_vec();
    if twice_area > 0.0 {
        corners.reverse();
    }
    corners
}

/// What of `plan` a QGC plan cannot carry, one line per kind.
fn dropped(plan: &Plan) -> Vec<String> {
    let mut lines = Vec::new();
    let mut note = |what: String, names: Vec<&str>| {
        if !names.is_empty() {
            lines.push(format!("{what}: {}", quoted(&names)));
        }
    };
    note(
        "waypoint names (read back as home, wp1, wp2, …)".into(),
        plan.waypoints.iter().map(|w| w.name.as_str()).collect(),
    );
    note(
        "waypoint symbols".into(),
        plan.waypoints
            .iter()
            .filter(|w| w.symbol.is_some())
            .map(|w| w.name.as_str())
            .collect(),
    );
    note(
        "deadlines (arrive_by) of legs".into(),
        legs_where(plan, |leg| leg.arrive_by_unix_secs.is_some()),
    );
    note(
        "the day of appointments (not_before; kept as a NAV_DELAY until their time of day, UTC) \
         of legs"
            .into(),
        legs_where(plan, |leg| leg.not_before_unix_secs.is_some()),
    );
    note(
        "actions (during and on arrival) of legs".into(),
        legs_where(plan, |leg| leg.during.is_some() || leg.arrival.is_some()),
    );
    if let Some(action) = &plan.throughout {
        note(
            "the action run throughout".into(),
            action.modules.iter().map(|m| m.name.as_str()).collect(),
        );
    }
    let contingencies: Vec<String> = plan
        .every_contingency()
        .map(|contingency| contingency.trigger.describe())
        .collect();
    note(
        "contingencies (the waypoints a `return` names are rally points)".into(),
        contingencies.iter().map(String::as_str).collect(),
    );
    for (kind, what) in [
        (GraphicKind::PhaseLine, "phase lines"),
        (GraphicKind::Boundary, "boundaries"),
        (
            GraphicKind::Area(AreaKind::Objective),
            "objective areas (only no-go areas are geofences)",
        ),
        (
            GraphicKind::Area(AreaKind::Assembly),
            "assembly areas (only no-go areas are geofences)",
        ),
        (
            GraphicKind::Area(AreaKind::Named),
            "named areas (only no-go areas are geofences)",
        ),
    ] {
        note(
            what.into(),
            plan.graphics
                .iter()
                .filter(|g| g.kind == kind)
                .map(|g| g.name.as_str())
                .collect(),
        );
    }
    note(
        "the margins of no-go areas".into(),
        plan.no_go_areas()
            .filter(|area| area.margin_m.is_some())
            .map(|area| area.name.as_str())
            .collect(),
    );
    note(
        "units".into(),
        plan.units.iter().map(|u| u.name.as_str()).collect(),
    );
    if plan.start_unix_secs.is_some() {
        lines.push("the plan's start date".into());
    }
    lines
}

fn legs_where(plan: &Plan, keep: impl Fn(&Leg) -> bool) -> Vec<&str> {
    plan.legs
        .iter()
        .filter(|leg| keep(leg))
        .map(|leg| leg.name.as_str())
        .collect()
}

fn quoted(names: &[&str]) -> String {
    names
        .iter()
        .map(|name| format!("`{name}`"))
        .collect::<Vec<_>>()
        .join(", ")
}
