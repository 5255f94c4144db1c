//! The geofence and rally points of a QGC plan file (see [`super`]): exclusion polygons and
//! circles as no-go areas, inclusion fences as named areas, rally points as waypoints.

use std::f64::consts::PI;

use serde_json::{Map, Value};

use super::CIRCLE_CORNERS;
use super::import::Reader;
use crate::json_positions::{index_path, key_path};
use crate::plan::{AreaKind, Graphic, GraphicKind, LatLon, Plan, Waypoint};
use crate::world::Point;

impl Reader<'_> {
    pub(super) fn fence(&mut self, fence: &Value, plan: &mut Plan) {
        let Some(fence) = fence.as_object() else {
            self.problem("geoFence", "`geoFence` is a JSON object");
            return;
        };
        if fence.get("version").and_then(Value::as_u64) != Some(2) {
            self.warn(
                "geoFence",
                "a geofence of another version than 2 (QGC's own since 2017) is not read: skipped",
            );
            return;
        }
        // Each fence: inclusion or not, its corners, its path.
        let mut fences: Vec<(bool, Vec<LatLon>, String)> = Vec::new();
        for (index, polygon) in list(fence, "polygons").iter().enumerate() {
            let path = index_path("geoFence.polygons", index);
            let inclusion = self.inclusion(polygon, &path);
            let corners_path = key_path(&path, "polygon");
            let corners: Vec<LatLon> = list_of(polygon, "polygon")
                .iter()
                .enumerate()
                .filter_map(|(i, corner)| self.lat_lon(corner, &index_path(&corners_path, i)))
                .collect();
            if corners.len() < 3 {
                self.warn(
                    &path,
                    format!(
                        "a fence polygon of {} corners encloses nothing: skipped",
                        corners.len()
                    ),
                );
                continue;
            }
            fences.push((inclusion, corners, path));
        }
        for (index, circle) in list(fence, "circles").iter().enumerate() {
            let path = index_path("geoFence.circles", index);
            let inclusion = self.inclusion(circle, &path);
            let centre = circle.get("circle").and_then(|c| c.get("center"));
            let radius = circle
                .get("circle")
                .and_then(|c| c.get("radius"))
                .and_then(Value::as_f64)
                .filter(|radius| radius.is_finite() && *radius > 0.0);
            let (Some(centre), Some(radius)) = (centre, radius) else {
                self.problem(
                    &path,
                    "a fence circle needs `circle` with its `center` [latitude, longitude] and a \
                     `radius` in metres above 0",
                );
                continue;
            };
            let Some(centre) = self.lat_lon(centre, &key_path(&path, "circle.center")) else {
                continue;
            };
            let corners = circle_polygon(centre, radius);
            let on_earth = |c: &LatLon| c.lat_deg.abs() <= 90.0 && c.lon_deg.abs() <= 180.0;
            if radius > MAX_CIRCLE_RADIUS_M || !corners.iter().all(on_earth) {
                self.problem(
                    &key_path(&path, "circle.radius"),
                    format!(
                        "a fence circle of {radius} m round ({}, {}) does not fit on the map: at \
                         most {} km, away from the poles and the date line",
                        centre.lat_deg,
                        centre.lon_deg,
                        MAX_CIRCLE_RADIUS_M / 1000.0
                    ),
                );
                continue;
            }
            self.warn(
                &path,
                format!(
                    "a fence circle ({radius} m) is kept as a polygon of {CIRCLE_CORNERS} \
                     corners round it"
                ),
            );
            fences.push((inclusion, corners, path));
        }
        let (mut no_go, mut kept) = (0, 0);
        for (inclusion, points, path) in fences {
            let (kind, name) = if inclusion {
                kept += 1;
                let name = format!("fence_{kept}");
                self.warn(
                    &path,
                    format!(
                        "an inclusion fence is kept as the named area `{name}`: the robot is not \
                         held inside it"
                    ),
                );
                (AreaKind::Named, name)
            } else {
                no_go += 1;
                (AreaKind::NoGo, format!("no_go_{no_go}"))
            };
            // No position: the plan is written out, and read again from there.
            plan.graphics.push(Graphic {
                kind: GraphicKind::Area(kind),
                name,
                points,
                ..Graphic::default()
            });
        }
    }

    fn inclusion(&mut self, fence: &Value, path: &str) -> bool {
        match fence.get("inclusion") {
            Some(Value::Bool(inclusion)) => *inclusion,
            _ => {
                self.warn(path, "no `inclusion`: read as an inclusion fence");
                true
            }
        }
    }

    pub(super) fn rally(&mut self, rally: &Value, plan: &mut Plan) {
        let mut names = Vec::new();
        let mut added = 0;
        for (index, point) in list_of(rally, "points").iter().enumerate() {
            let Some(position) = self.lat_lon(point, &index_path("rallyPoints.points", index))
            else {
                continue;
            };
            let same = |w: &&Waypoint| {
                (w.position.lat_deg - position.lat_deg).abs() < 1e-9
                    && (w.position.lon_deg - position.lon_deg).abs() < 1e-9
            };
            if let Some(existing) = plan.waypoints.iter().find(same) {
                names.push(existing.name.clone());
                continue;
            }
            added += 1;
            let name = match added {
                1 => "rally".to_owned(),
                n => format!("rally_{n}"),
            };
            names.push(name.clone());
            plan.waypoints.push(Waypoint {
                name,
                position,
                ..Waypoint::default()
            });
        }
        if !names.is_empty() {
            self.warn(
                "rallyPoints",
                format!(
                    "rally points kept as waypoints ({}): no contingency returns there",
                    names.join(", ")
                ),
            );
        }
    }
}

/// `object[key]` as a list, empty when it is not one.
fn list<'a>(object: &'a Map<String, Value>, key: &str) -> &'a [Value] {
    object
        .get(key)
        .and_then(Value::as_array)
        .map_or(&[], Vec::as_slice)
}

fn list_of<'a>(value: &'a Value, key: &str) -> &'a [Value] {
    value.as_object().map_or(&[], |object| list(object, key))
}

/// The largest fence circle read: a local plane is no good beyond.
const MAX_CIRCLE_RADIUS_M: f64 = 100_000.0;

/// A polygon that holds the circle: its corners on a circle larger by 1 / cos(π / n), so
/// that its edges touch the circle from outside.
fn circle_polygon(centre: LatLon, radius_m: f64) -> Vec<LatLon> {
    let outer = radius_m / (PI / CIRCLE_CORNERS as f64).cos();
    (0..CIRCLE_CORNERS)
        .map(|i| {
            // Clockwise from north, as QGC winds fences.
            let bearing = 2.0 * PI * i as f64 / CIRCLE_CORNERS as f64;
            LatLon::from_local(
                Point::new(outer * bearing.sin(), outer * bearing.cos()),
                centre,
            )
        })
        .collect()
}
