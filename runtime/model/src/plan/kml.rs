//! KML 2.2 (OGC 07-147r2: what Google Earth and ATAK open) to and from plans.
//!
//! Export: the route as a line, the waypoints as placemarks with their times, the areas as
//! polygons, phase lines and boundaries as lines, the units as placemarks with their SIDC, each
//! kind in a folder of its own. Coordinates are `longitude,latitude,altitude` (KML's order), on
//! the ground.
//!
//! Import, of every placemark however deep in documents and folders: a point is a waypoint, its
//! `sidc` data its symbol (a unit when it is styled `#unit`, as ours are); a polygon an area (no-go unless its
//! `kind` data or its style says otherwise, with its `margin_m`); a line the route when it is
//! styled `#route` or is the first line with no `kind` (a path drawn in Google Earth), else a
//! phase line or a boundary. Each point of the route is the waypoint within [`SAME_POINT_M`] of
//! it, else a new one; without a route, the waypoints are joined in file order, as GPX's are.
//!
//! Written by hand, as GPX is ([`super::gpx`]): the handful of elements needs no library.
//! What KML cannot carry as such (actions, contingencies, the navigation, the system) stays in
//! the plan file; times and margins go in each placemark's `ExtendedData`, and a waypoint's
//! deadline (or appointment) in its `TimeStamp`, which Google Earth's time slider shows.

use std::collections::HashMap;
use std::fmt::Write as _;

use armor_module_api::xml::{self as tree, Element, Located};

use super::gpx::{Names, SAME_POINT_M, legs_through};
use super::{AreaKind, Graphic, GraphicKind, LatLon, Leg, Plan, Unit, Waypoint, check_sidc};
use crate::fields::escape;
use crate::geo;
use crate::net::format_date;
use crate::world::Point;

/// The KML namespace.
pub const KML_NAMESPACE: &str = "http://www.opengis.net/kml/2.2";

/// The plan as a KML document.
pub fn export(plan: &Plan) -> String {
    let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(out, "<kml xmlns=\"{KML_NAMESPACE}\">\n<Document>");
    let _ = writeln!(out, "  <name>{}</name>", escape(&plan.name));
    if let Some(start) = plan.start_unix_secs {
        let _ = writeln!(
            out,
            "  <description>Plan `{}`, starting {}</description>",
            escape(&plan.name),
            format_date(start)
        );
    }
    out.push_str(STYLES);
    route(&mut out, plan);
    waypoints(&mut out, plan);
    let areas: Vec<&Graphic> = plan
        .graphics
        .iter()
        .filter(|g| matches!(g.kind, GraphicKind::Area(_)))
        .collect();
    if !areas.is_empty() {
        out.push_str("  <Folder>\n    <name>Areas</name>\n");
        for area in areas {
            area_placemark(&mut out, area);
        }
        out.push_str("  </Folder>\n");
    }
    let lines: Vec<&Graphic> = plan
        .graphics
        .iter()
        .filter(|g| !matches!(g.kind, GraphicKind::Area(_)))
        .collect();
    if !lines.is_empty() {
        out.push_str("  <Folder>\n    <name>Lines</name>\n");
        for line in lines {
            line_placemark(&mut out, line);
        }
        out.push_str("  </Folder>\n");
    }
    if !plan.units.is_empty() {
        out.push_str("  <Folder>\n    <name>Units</name>\n");
        for unit in &plan.units {
            let _ = writeln!(
                out,
                "    <Placemark>\n      <name>{}</name>\n      <styleUrl>#unit</styleUrl>",
                escape(&unit.name)
            );
            extended_data(&mut out, &[("sidc", unit.sidc.clone())]);
            point(&mut out, unit.position);
            out.push_str("    </Placemark>\n");
        }
        out.push_str("  </Folder>\n");
    }
    out.push_str("</Document>\n</kml>\n");
    out
}

/// One style per kind of feature (colours are `aabbggrr`).
const STYLES: &str = r##"  <Style id="route">
    <LineStyle><color>ffff7f00</color><width>3</width></LineStyle>
  </Style>
  <Style id="waypoint">
    <IconStyle><scale>0.8</scale></IconStyle>
  </Style>
  <Style id="no-go">
    <LineStyle><color>ff0000ff</color><width>2</width></LineStyle>
    <PolyStyle><color>550000ff</color></PolyStyle>
  </Style>
  <Style id="area">
    <LineStyle><color>ff00aa00</color><width>2</width></LineStyle>
    <PolyStyle><color>3300aa00</color></PolyStyle>
  </Style>
  <Style id="phase-line">
    <LineStyle><color>ff000000</color><width>2</width></LineStyle>
  </Style>
  <Style id="boundary">
    <LineStyle><color>ff000000</color><width>3</width></LineStyle>
  </Style>
  <Style id="unit">
    <IconStyle><scale>1.0</scale></IconStyle>
  </Style>
"##;

/// The legs as one line, start to end.
fn route(out: &mut String, plan: &Plan) {
    if plan.legs.is_empty() {
        return;
    }
    let stops: Vec<LatLon> = plan.route().iter().map(|w| w.position).collect();
    let _ = writeln!(
        out,
        "  <Folder>\n    <name>Route</name>\n    <Placemark>\n      <name>{} route</name>\n      \
         <styleUrl>#route</styleUrl>\n      <LineString>\n        <tessellate>1</tessellate>\n        \
         <coordinates>{}</coordinates>\n      </LineString>\n    </Placemark>\n  </Folder>",
        escape(&plan.name),
        coordinates(&stops)
    );
}

/// Each waypoint, with the times of the legs that arrive there and leave from there.
fn waypoints<'a>(out: &mut String, plan: &'a Plan) {
    if plan.waypoints.is_empty() {
        return;
    }
    // The legs that arrive at and leave from each waypoint, by name.
    let mut arriving: HashMap<&str, Vec<&Leg>> = HashMap::new();
    let mut leaving: HashMap<&str, Vec<&Leg>> = HashMap::new();
    for leg in &plan.legs {
        arriving.entry(leg.to.as_str()).or_default().push(leg);
        leaving.entry(leg.from.as_str()).or_default().push(leg);
    }
    let legs_of = |map: &HashMap<&str, Vec<&'a Leg>>, name: &str| -> Vec<&'a Leg> {
        map.get(name).cloned().unwrap_or_default()
    };
    out.push_str("  <Folder>\n    <name>Waypoints</name>\n");
    for waypoint in &plan.waypoints {
        let mut data: Vec<(&str, String)> = Vec::new();
        let mut notes: Vec<String> = Vec::new();
        let mut when: Option<f64> = None;
        let is_start = plan
            .legs
            .first()
            .is_some_and(|leg| leg.from == waypoint.name);
        if let (true, Some(start)) = (is_start, plan.start_unix_secs) {
            data.push(("start", format_date(start)));
            notes.push(format!("start {}", format_date(start)));
            when = Some(start);
        }
        for leg in legs_of(&arriving, &waypoint.name) {
            if let Some(at) = leg.arrive_by_unix_secs {
                data.push(("arrive_by", format_date(at)));
                notes.push(format!(
                    "arrive by {} (leg `{}`)",
                    format_date(at),
                    leg.name
                ));
                when = Some(at);
            }
            if let Some(wait) = leg.wait_secs {
                data.push(("wait_secs", wait.to_string()));
                notes.push(format!("wait {wait} s"));
            }
        }
        for leg in legs_of(&leaving, &waypoint.name) {
            if let Some(at) = leg.not_before_unix_secs {
                data.push(("not_before", format_date(at)));
                notes.push(format!(
                    "leave not before {} (leg `{}`)",
                    format_date(at),
                    leg.name
                ));
                when = when.or(Some(at));
            }
        }
        if let Some(symbol) = &waypoint.symbol {
            data.push(("sidc", symbol.clone()));
        }
        let _ = writeln!(
            out,
            "    <Placemark>\n      <name>{}</name>",
            escape(&waypoint.name)
        );
        if !notes.is_empty() {
            let _ = writeln!(
                out,
                "      <description>{}</description>",
                escape(&notes.join("; "))
            );
        }
        if let Some(when) = when {
            let _ = writeln!(
                out,
                "      <TimeStamp><when>{}</when></TimeStamp>",
                format_date(when)
            );
        }
        out.push_str("      <styleUrl>#waypoint</styleUrl>\n");
        extended_data(out, &data);
        point(out, waypoint.position);
        out.push_str("    </Placemark>\n");
    }
    out.push_str("  </Folder>\n");
}

fn area_placemark(out: &mut String, area: &Graphic) {
    let GraphicKind::Area(kind) = area.kind else {
        return;
    };
    let style = if kind == AreaKind::NoGo {
        "no-go"
    } else {
        "area"
    };
    let _ = writeln!(
        out,
        "    <Placemark>\n      <name>{}</name>\n      <styleUrl>#{style}</styleUrl>",
        escape(&area.name)
    );
    let mut data = vec![("kind", kind.as_str().to_owned())];
    if let Some(margin) = area.margin_m {
        data.push(("margin_m", margin.to_string()));
    }
    extended_data(out, &data);
    // A linear ring is closed: its first point again at the end.
    let mut ring = area.points.clone();
    if let Some(first) = area.points.first() {
        ring.push(*first);
    }
    let _ = writeln!(
        out,
        "      <Polygon>\n        <tessellate>1</tessellate>\n        <outerBoundaryIs>\n          \
         <LinearRing>\n            <coordinates>{}</coordinates>\n          </LinearRing>\n        \
         </outerBoundaryIs>\n      </Polygon>\n    </Placemark>",
        coordinates(&ring)
    );
}

fn line_placemark(out: &mut String, line: &Graphic) {
    let style = match line.kind {
        GraphicKind::Boundary => "boundary",
        _ => "phase-line",
    };
    let kind = if line.kind == GraphicKind::Boundary {
        "boundary"
    } else {
        "phase line"
    };
    let _ = writeln!(
        out,
        "    <Placemark>\n      <name>{}</name>",
        escape(&line.name)
    );
    let mut data = vec![("kind", kind.to_owned())];
    if let Some(at) = line.at_unix_secs {
        let _ = writeln!(
            out,
            "      <TimeStamp><when>{}</when></TimeStamp>",
            format_date(at)
        );
        data.push(("at", format_date(at)));
    }
    let _ = writeln!(out, "      <styleUrl>#{style}</styleUrl>");
    extended_data(out, &data);
    let _ = writeln!(
        out,
        "      <LineString>\n        <tessellate>1</tessellate>\n        \
         <coordinates>{}</coordinates>\n      </LineString>\n    </Placemark>",
        coordinates(&line.points)
    );
}

fn extended_data(out: &mut String, data: &[(&str, String)]) {
    if data.is_empty() {
        return;
    }
    out.push_str("      <ExtendedData>\n");
    for (name, value) in data {
        let _ = writeln!(
            out,
            "        <Data name=\"{name}\"><value>{}</value></Data>",
            escape(value)
        );
    }
    out.push_str("      </ExtendedData>\n");
}

fn point(out: &mut String, position: LatLon) {
    let _ = writeln!(
        out,
        "      <Point>\n        <coordinates>{}</coordinates>\n      </Point>",
        coordinates(&[position])
    );
}

/// `lon,lat,0 lon,lat,0 …`: longitude first, as KML has it.
fn coordinates(points: &[LatLon]) -> String {
    points
        .iter()
        .map(|p| format!("{},{},0", p.lon_deg, p.lat_deg))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Reads a KML file into a plan called `name` over the system file `system`.
pub fn import(text: &str, name: &str, system: &str) -> Result<Plan, Vec<Located>> {
    let root = tree::parse_document(text, "kml")?;
    let mut placemarks = Vec::new();
    collect_placemarks(&root, &mut placemarks);
    let mut problems = Vec::new();
    let mut names = Names::default();
    let mut plan = Plan {
        name: names.identifier(name, "plan"),
        system: system.to_owned(),
        pos: root.pos,
        ..Plan::default()
    };
    let mut route: Option<Vec<LatLon>> = None;
    for placemark in placemarks {
        let label = child_text(placemark, "name");
        let data = extended(placemark);
        let kind = data
            .iter()
            .find(|(key, _)| key == "kind")
            .map(|(_, v)| v.as_str());
        let style = child_text(placemark, "styleUrl").unwrap_or_default();
        let geometry = ["Point", "LineString", "Polygon"]
            .iter()
            .find_map(|tag| find_descendant(placemark, tag));
        let Some(geometry) = geometry else {
            continue;
        };
        let Some(points) = find_descendant(geometry, "coordinates")
            .map(|coordinates| read_coordinates(coordinates, &mut problems))
        else {
            problems.push(Located::new(
                geometry.pos,
                format!("<{}> has no <coordinates>", geometry.name),
            ));
            continue;
        };
        match &*geometry.name {
            "Point" => {
                let Some(&position) = points.first() else {
                    continue;
                };
                let sidc = data
                    .iter()
                    .find(|(key, _)| key == "sidc")
                    .map(|(_, sidc)| sidc.clone())
                    .filter(|sidc| check_sidc(sidc).is_ok());
                match sidc {
                    Some(sidc) if style == "#unit" => plan.units.push(Unit {
                        name: label.unwrap_or_else(|| "unit".to_owned()),
                        sidc,
                        position,
                        pos: placemark.pos,
                    }),
                    symbol => plan.waypoints.push(Waypoint {
                        name: names.identifier(label.as_deref().unwrap_or("wpt"), "wpt"),
                        position,
                        symbol,
                        pos: placemark.pos,
                    }),
                }
            }
            "LineString" => {
                let is_route = style == "#route" || (kind.is_none() && route.is_none());
                if is_route && route.is_none() {
                    route = Some(points);
                } else {
                    plan.graphics.push(Graphic {
                        kind: if kind == Some("boundary") || style == "#boundary" {
                            GraphicKind::Boundary
                        } else {
                            GraphicKind::PhaseLine
                        },
                        name: label.unwrap_or_else(|| "line".to_owned()),
                        points,
                        at_unix_secs: None,
                        margin_m: None,
                        pos: placemark.pos,
                    });
                }
            }
            _ => {
                // A linear ring repeats its first point at the end; an area does not.
                let mut ring = points;
                if ring.len() > 1 && ring.first() == ring.last() {
                    ring.pop();
                }
                let area = match kind {
                    Some(kind) => AreaKind::ALL
                        .into_iter()
                        .find(|area| area.as_str() == kind)
                        .unwrap_or(AreaKind::Named),
                    None if style == "#area" => AreaKind::Named,
                    None => AreaKind::NoGo,
                };
                let margin_m = data
                    .iter()
                    .find(|(key, _)| key == "margin_m")
                    .and_then(|(_, value)| value.parse::<f64>().ok())
                    .filter(|margin| margin.is_finite() && *margin >= 0.0);
                plan.graphics.push(Graphic {
                    kind: GraphicKind::Area(area),
                    name: label.unwrap_or_else(|| "area".to_owned()),
                    points: ring,
                    at_unix_secs: None,
                    margin_m,
                    pos: placemark.pos,
                });
            }
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    let order: Vec<String> = match route {
        Some(points) => points
            .into_iter()
            .map(|position| {
                let near = plan.waypoints.iter().find(|waypoint| {
                    geo::distance(waypoint.position.to_local(position), Point::default())
                        <= SAME_POINT_M
                });
                match near {
                    Some(waypoint) => waypoint.name.clone(),
                    None => {
                        let name = names.identifier("wp", "wp");
                        plan.waypoints.push(Waypoint {
                            name: name.clone(),
                            position,
                            symbol: None,
                            pos: root.pos,
                        });
                        name
                    }
                }
            })
            .collect(),
        None => plan.waypoints.iter().map(|w| w.name.clone()).collect(),
    };
    plan.legs = legs_through(&order, &mut names, root.pos);
    if plan.legs.is_empty() {
        return Err(vec![Located::new(
            root.pos,
            "the KML file has no route and fewer than two points: a plan needs two to make a leg",
        )]);
    }
    Ok(plan)
}

/// Every placemark under `element`, in document order.
fn collect_placemarks<'e, 'a>(element: &'e Element<'a>, out: &mut Vec<&'e Element<'a>>) {
    for child in &element.children {
        if &*child.name == "Placemark" {
            out.push(child);
        } else {
            collect_placemarks(child, out);
        }
    }
}

/// The first element called `tag` under `element` (itself excluded), depth first.
fn find_descendant<'e, 'a>(element: &'e Element<'a>, tag: &str) -> Option<&'e Element<'a>> {
    element.children.iter().find_map(|child| {
        if &*child.name == tag {
            Some(child)
        } else {
            find_descendant(child, tag)
        }
    })
}

/// The trimmed text of the child called `tag`, when it has some.
fn child_text(element: &Element, tag: &str) -> Option<String> {
    element
        .children
        .iter()
        .find(|child| &*child.name == tag)
        .map(|child| child.text.trim().to_owned())
        .filter(|text| !text.is_empty())
}

/// A placemark's `<ExtendedData><Data name="…"><value>…</value></Data>` pairs.
fn extended(placemark: &Element) -> Vec<(String, String)> {
    placemark
        .children
        .iter()
        .filter(|child| &*child.name == "ExtendedData")
        .flat_map(|data| &data.children)
        .filter(|data| &*data.name == "Data")
        .filter_map(|data| {
            Some((
                data.attr_value("name")?.to_owned(),
                child_text(data, "value").unwrap_or_default(),
            ))
        })
        .collect()
}

/// `lon,lat[,alt]` tuples separated by white space; a wrong one is a problem at the element.
fn read_coordinates(element: &Element, problems: &mut Vec<Located>) -> Vec<LatLon> {
    let mut points = Vec::new();
    for tuple in element.text.split_whitespace() {
        let mut parts = tuple.split(',').map(|part| part.trim().parse::<f64>());
        match (parts.next(), parts.next()) {
            (Some(Ok(lon)), Some(Ok(lat)))
                if lon.is_finite()
                    && lat.is_finite()
                    && lon.abs() <= 180.0
                    && lat.abs() <= 90.0 =>
            {
                points.push(LatLon::new(lat, lon));
            }
            _ => problems.push(Located::new(
                element.pos,
                format!(
                    "`{tuple}` is not `longitude,latitude[,altitude]` in degrees \
                     (longitude within 180, latitude within 90)"
                ),
            )),
        }
    }
    if points.is_empty() && problems.is_empty() {
        problems.push(Located::new(element.pos, "<coordinates> holds no point"));
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A path and two pins drawn in Google Earth Pro and saved as KML (its style maps, the `gx`
    /// namespace, an altitude on every point, a folder round the placemarks), with a polygon.
    const FROM_GOOGLE_EARTH: &str = r##"<?xml version="1.0" encoding="UTF-8"?>
<kml xmlns="http://www.opengis.net/kml/2.2" xmlns:gx="http://www.google.com/kml/ext/2.2" xmlns:kml="http://www.opengis.net/kml/2.2" xmlns:atom="http://www.w3.org/2005/Atom">
<Document>
	<name>Patrol.kml</name>
	<StyleMap id="m_ylw-pushpin"><Pair><key>normal</key><styleUrl>#s_ylw-pushpin</styleUrl></Pair></StyleMap>
	<Folder>
		<name>Patrol</name>
		<open>1</open>
		<Placemark>
			<name>Start</name>
			<styleUrl>#m_ylw-pushpin</styleUrl>
			<Point><gx:drawOrder>1</gx:drawOrder><coordinates>1.46905,43.56154,0</coordinates></Point>
		</Placemark>
		<Placemark>
			<name>East gate</name>
			<styleUrl>#m_ylw-pushpin</styleUrl>
			<Point><coordinates>1.46925,43.56154,0</coordinates></Point>
		</Placemark>
		<Placemark>
			<name>Path</name>
			<styleUrl>#m_ylw-pushpin</styleUrl>
			<LineString>
				<tessellate>1</tessellate>
				<coordinates>
					1.46905,43.56154,0 1.46925,43.56154,0 1.46925,43.56165,0
				</coordinates>
			</LineString>
		</Placemark>
		<Placemark>
			<name>Minefield</name>
			<Polygon><outerBoundaryIs><LinearRing><coordinates>
				1.4691,43.5616,0 1.4692,43.5616,0 1.4692,43.5617,0 1.4691,43.5616,0
			</coordinates></LinearRing></outerBoundaryIs></Polygon>
		</Placemark>
	</Folder>
</Document>
</kml>
"##;

    #[test]
    fn a_path_and_pins_from_google_earth_become_a_route_through_the_pins() {
        let plan = import(FROM_GOOGLE_EARTH, "patrol", "system.xml").expect("imports");
        let names: Vec<&str> = plan.waypoints.iter().map(|w| w.name.as_str()).collect();
        // The path's first two points are the pins; its third is a waypoint of its own.
        assert_eq!(names, ["Start", "East_gate", "wp"]);
        let legs: Vec<(&str, &str)> = plan
            .legs
            .iter()
            .map(|leg| (leg.from.as_str(), leg.to.as_str()))
            .collect();
        assert_eq!(legs, [("Start", "East_gate"), ("East_gate", "wp")]);
        assert_eq!(plan.graphics.len(), 1);
        let area = &plan.graphics[0];
        assert_eq!(area.kind, GraphicKind::Area(AreaKind::NoGo));
        assert_eq!(area.points.len(), 3, "the ring's closing point dropped");
    }

    #[test]
    fn our_export_comes_back_with_its_waypoints_route_areas_lines_and_units() {
        let mut plan = Plan {
            name: "trip".into(),
            system: "system.xml".into(),
            ..Plan::default()
        };
        for (name, lat, lon) in [
            ("home", 43.0, 1.0),
            ("gate", 43.001, 1.0),
            ("far", 43.001, 1.001),
        ] {
            plan.waypoints.push(Waypoint {
                name: name.into(),
                position: LatLon::new(lat, lon),
                symbol: None,
                pos: Default::default(),
            });
        }
        for (from, to) in [("home", "gate"), ("gate", "far")] {
            plan.legs.push(Leg {
                name: format!("{from}_{to}"),
                from: from.into(),
                to: to.into(),
                ..Leg::default()
            });
        }
        plan.graphics.push(Graphic {
            kind: GraphicKind::Area(AreaKind::Objective),
            name: "obj".into(),
            points: vec![
                LatLon::new(43.0005, 1.0),
                LatLon::new(43.0005, 1.0005),
                LatLon::new(43.0008, 1.0005),
            ],
            margin_m: Some(1.5),
            ..Graphic::default()
        });
        plan.graphics.push(Graphic {
            kind: GraphicKind::Boundary,
            name: "left".into(),
            points: vec![LatLon::new(43.0, 0.999), LatLon::new(43.002, 0.999)],
            ..Graphic::default()
        });
        plan.units.push(Unit {
            name: "alpha".into(),
            sidc: "SFGPUCR----K---".into(),
            position: LatLon::new(43.0, 1.0002),
            pos: Default::default(),
        });
        let back = import(&export(&plan), "trip", "system.xml").expect("imports");
        let places = |p: &Plan| -> Vec<(String, String)> {
            p.waypoints
                .iter()
                .map(|w| {
                    (
                        w.name.clone(),
                        format!("{:.7} {:.7}", w.position.lat_deg, w.position.lon_deg),
                    )
                })
                .collect()
        };
        assert_eq!(places(&back), places(&plan));
        let ends = |p: &Plan| -> Vec<(String, String)> {
            p.legs
                .iter()
                .map(|l| (l.from.clone(), l.to.clone()))
                .collect()
        };
        assert_eq!(ends(&back), ends(&plan));
        let kinds: Vec<(GraphicKind, &str, usize, Option<f64>)> = back
            .graphics
            .iter()
            .map(|g| (g.kind, g.name.as_str(), g.points.len(), g.margin_m))
            .collect();
        assert_eq!(
            kinds,
            [
                (GraphicKind::Area(AreaKind::Objective), "obj", 3, Some(1.5)),
                (GraphicKind::Boundary, "left", 2, None),
            ]
        );
        assert_eq!(back.units.len(), 1);
        assert_eq!(back.units[0].sidc, "SFGPUCR----K---");
    }

    #[test]
    fn broken_coordinates_and_other_documents_are_refused_where_they_are() {
        let broken =
            FROM_GOOGLE_EARTH.replace("1.46925,43.56154,0</coordinates>", "east,43</coordinates>");
        let problems = import(&broken, "p", "s.xml").expect_err("refused");
        assert!(
            problems[0].message.contains("`east,43` is not"),
            "{problems:?}"
        );
        assert_eq!(
            problems[0].pos.line, 17,
            "the `East gate` pin's coordinates"
        );
        let gpx = import("<gpx/>", "p", "s.xml").expect_err("refused");
        assert!(gpx[0].message.contains("expected <kml>"), "{gpx:?}");
        let lonely = import(
            "<kml><Placemark><Point><coordinates>1,2</coordinates></Point></Placemark></kml>",
            "p",
            "s.xml",
        )
        .expect_err("refused");
        assert!(lonely[0].message.contains("needs two"), "{lonely:?}");
    }
}
