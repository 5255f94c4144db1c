//! KML 2.2 (OGC 07-147r2: what Google Earth and ATAK open) from plans: the route as a line,
//! the waypoints as placemarks with their times, the areas as polygons, phase lines and
//! boundaries as lines, the units as placemarks with their SIDC, each kind in a folder of its
//! own. Coordinates are `longitude,latitude,altitude` (KML's order), on the ground.
//!
//! Written by hand, as GPX is ([`super::gpx`]): the handful of elements needs no library.
//! What KML cannot carry as such (actions, contingencies, the navigation, the system) stays in
//! the plan file; times and margins go in each placemark's `ExtendedData`, and a waypoint's
//! deadline (or appointment) in its `TimeStamp`, which Google Earth's time slider shows.

use std::collections::HashMap;
use std::fmt::Write as _;

use super::{AreaKind, Graphic, GraphicKind, LatLon, Leg, Plan};
use crate::fields::escape;
use crate::net::format_date;

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
