//! GPX 1.0 and 1.1 (the format GIS tools and GPS receivers exchange) to and from plans.
//!
//! Import: every `<wpt>` becomes a waypoint; the points of each `<rte>` and each `<trk>`
//! become waypoints joined by legs, routes and tracks one after the other in file order (a
//! track's points are thinned to one every [`TRACK_SPACING_M`] metres, since a receiver logs
//! one a second). A route point with the name of a point already read, within [`SAME_POINT_M`]
//! of it, is that point (GPS tools write a route's points as waypoints too, and a round trip
//! ends where it began). A file with waypoints only gets legs between them in file order. Names become
//! identifiers (`Gate 1` → `Gate_1`), made unique with a suffix. A `<sym>` that is a SIDC
//! becomes the waypoint's symbol.
//!
//! Export: the waypoints as `<wpt>` and the legs as one `<rte>`, so that a GIS tool shows
//! both. What GPX cannot hold (actions, time constraints, areas) stays in the plan file.

use std::collections::BTreeSet;
use std::fmt::Write as _;

use armor_module_api::xml::{self as tree, Element, Located, Pos};

use super::{LatLon, Leg, Plan, Waypoint, check_sidc};
use crate::fields::escape;
use crate::world::Point;
use crate::{geo, plan::xml::default_leg_name};

/// Track points closer than this to the last one kept are dropped on import.
pub const TRACK_SPACING_M: f64 = 5.0;

/// A route point this close to a point of the same name already read is that point: GPS tools
/// round coordinates differently in `wpt` and `rtept` (our own export writes 7 decimals, 1 cm).
pub const SAME_POINT_M: f64 = 1.0;

/// Reads a GPX file into a plan called `name` over the system file `system`.
pub fn import(text: &str, name: &str, system: &str) -> Result<Plan, Vec<Located>> {
    let root = tree::parse_document(text, "gpx")?;
    let mut problems = Vec::new();
    let mut names = Names::default();
    let mut plan = Plan {
        name: names.identifier(name, "plan"),
        system: system.to_owned(),
        pos: root.pos,
        ..Plan::default()
    };
    // Sequences of waypoint names to join with legs, one per route or track.
    let mut sequences: Vec<Vec<String>> = Vec::new();
    let mut loose: Vec<String> = Vec::new();
    // The named points so far (`wpt` and `rtept`): (name as written, position, waypoint).
    let mut named: Vec<(String, LatLon, String)> = Vec::new();
    for child in &root.children {
        match local(&child.name) {
            "wpt" => {
                if let Some(waypoint) = point(child, "wpt", &mut names, &mut problems) {
                    if let Some(written) = written_name(child) {
                        named.push((written, waypoint.position, waypoint.name.clone()));
                    }
                    loose.push(waypoint.name.clone());
                    plan.waypoints.push(waypoint);
                }
            }
            "rte" => {
                let mut sequence = Vec::new();
                for rtept in child.children.iter().filter(|c| local(&c.name) == "rtept") {
                    let Some(waypoint) = point(rtept, "rtept", &mut names, &mut problems) else {
                        continue;
                    };
                    // GPS tools (and our export) write a route's points as waypoints too, and
                    // a round trip ends where it began: a point with the name and the place of
                    // one already read is that one, not a copy.
                    let written = written_name(rtept);
                    let same = written.as_ref().and_then(|written| {
                        named.iter().find(|(name, position, _)| {
                            name == written
                                && geo::distance(
                                    waypoint.position.to_local(*position),
                                    Point::default(),
                                ) <= SAME_POINT_M
                        })
                    });
                    match same {
                        Some((_, _, existing)) => {
                            names.forget(&waypoint.name);
                            sequence.push(existing.clone());
                        }
                        None => {
                            if let Some(written) = written {
                                named.push((written, waypoint.position, waypoint.name.clone()));
                            }
                            sequence.push(waypoint.name.clone());
                            plan.waypoints.push(waypoint);
                        }
                    }
                }
                sequences.push(sequence);
            }
            "trk" => {
                let mut sequence = Vec::new();
                let mut last: Option<LatLon> = None;
                let points = child
                    .children
                    .iter()
                    .filter(|c| local(&c.name) == "trkseg")
                    .flat_map(|segment| &segment.children)
                    .filter(|c| local(&c.name) == "trkpt")
                    .collect::<Vec<_>>();
                let count = points.len();
                for (index, trkpt) in points.into_iter().enumerate() {
                    let Some(mut waypoint) = point(trkpt, "trkpt", &mut names, &mut problems)
                    else {
                        continue;
                    };
                    let keep = index + 1 == count
                        || last.is_none_or(|last| {
                            let p = waypoint.position.to_local(last);
                            geo::distance(p, Point::default()) >= TRACK_SPACING_M
                        });
                    if keep {
                        last = Some(waypoint.position);
                        waypoint.pos = trkpt.pos;
                        sequence.push(waypoint.name.clone());
                        plan.waypoints.push(waypoint);
                    } else {
                        names.forget(&waypoint.name);
                    }
                }
                sequences.push(sequence);
            }
            _ => {}
        }
    }
    if !problems.is_empty() {
        return Err(problems);
    }
    if sequences.iter().all(Vec::is_empty) {
        sequences = vec![loose];
    }
    let order: Vec<String> = sequences.into_iter().flatten().collect();
    plan.legs = legs_through(&order, &mut names, root.pos);
    if plan.waypoints.is_empty() {
        return Err(vec![Located::new(
            root.pos,
            "the GPX file has no waypoint, route or track",
        )]);
    }
    if plan.legs.is_empty() {
        return Err(vec![Located::new(
            root.pos,
            "the GPX file has a single point: a plan needs two to make a leg",
        )]);
    }
    Ok(plan)
}

/// Legs through the waypoints named in `order`, one after the other (a point repeated at once
/// makes no leg), as an imported route is read.
pub(super) fn legs_through(order: &[String], names: &mut Names, pos: Pos) -> Vec<Leg> {
    order
        .windows(2)
        .filter(|pair| pair[0] != pair[1])
        .enumerate()
        .map(|(index, pair)| Leg {
            // Not the default name as such: a point may be called `leg1` (found by fuzzing).
            name: names.identifier(&default_leg_name(index), "leg"),
            from: pair[0].clone(),
            to: pair[1].clone(),
            pos,
            ..Leg::default()
        })
        .collect()
}

/// The name a point is given in the file, if any.
fn written_name(element: &Element) -> Option<String> {
    element
        .children
        .iter()
        .find(|child| local(&child.name) == "name")
        .map(|child| child.text.trim().to_owned())
        .filter(|text| !text.is_empty())
}

/// A `wpt`, `rtept` or `trkpt` as a waypoint.
fn point(
    element: &Element,
    kind: &str,
    names: &mut Names,
    problems: &mut Vec<Located>,
) -> Option<Waypoint> {
    let mut coordinate = |attr: &str, limit: f64| -> Option<f64> {
        let Some(field) = element.attr(attr) else {
            problems.push(Located::new(
                element.pos,
                format!("<{}> needs the attribute `{attr}`", element.name),
            ));
            return None;
        };
        match field.value.trim().parse::<f64>() {
            Ok(value) if value.is_finite() && value.abs() <= limit => Some(value),
            _ => {
                problems.push(Located::new(
                    field.pos,
                    format!(
                        "`{attr}` must be degrees between -{limit} and {limit}, not `{}`",
                        field.value
                    ),
                ));
                None
            }
        }
    };
    let lat = coordinate("lat", 90.0);
    let lon = coordinate("lon", 180.0);
    let text_of = |tag: &str| {
        element
            .children
            .iter()
            .find(|child| local(&child.name) == tag)
            .map(|child| child.text.trim().to_owned())
            .filter(|text| !text.is_empty())
    };
    let name = text_of("name").unwrap_or_else(|| kind.to_owned());
    let symbol = text_of("sym").filter(|sym| check_sidc(sym).is_ok());
    Some(Waypoint {
        name: names.identifier(&name, kind),
        position: LatLon::new(lat?, lon?),
        symbol,
        pos: element.pos,
    })
}

/// The name without a namespace prefix.
fn local(name: &str) -> &str {
    name.rsplit(':').next().unwrap_or(name)
}

/// Identifiers made from free text, each given once.
#[derive(Default)]
pub(super) struct Names {
    used: BTreeSet<String>,
}

impl Names {
    pub(super) fn identifier(&mut self, text: &str, fallback: &str) -> String {
        let mut base: String = text
            .trim()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        if !base.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
            base = format!("{fallback}_{base}");
        }
        let base = base.trim_end_matches('_').to_owned();
        let base = if base.is_empty() {
            fallback.to_owned()
        } else {
            base
        };
        let mut name = base.clone();
        let mut n = 2;
        while self.used.contains(&name) {
            name = format!("{base}_{n}");
            n += 1;
        }
        self.used.insert(name.clone());
        name
    }

    fn forget(&mut self, name: &str) {
        self.used.remove(name);
    }
}

/// The plan's waypoints and its legs as a GPX 1.1 document.
pub fn export(plan: &Plan) -> String {
    let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    out.push_str(
        "<gpx version=\"1.1\" creator=\"ArMoR\" xmlns=\"http://www.topografix.com/GPX/1/1\">\n",
    );
    let _ = writeln!(
        out,
        "  <metadata>\n    <name>{}</name>\n  </metadata>",
        escape(&plan.name)
    );
    let write_point = |out: &mut String, tag: &str, waypoint: &Waypoint, indent: &str| {
        let _ = writeln!(
            out,
            "{indent}<{tag} lat=\"{:.8}\" lon=\"{:.8}\">",
            waypoint.position.lat_deg, waypoint.position.lon_deg
        );
        let _ = writeln!(out, "{indent}  <name>{}</name>", escape(&waypoint.name));
        if let Some(symbol) = &waypoint.symbol {
            let _ = writeln!(out, "{indent}  <sym>{}</sym>", escape(symbol));
        }
        let _ = writeln!(out, "{indent}</{tag}>");
    };
    for waypoint in &plan.waypoints {
        write_point(&mut out, "wpt", waypoint, "  ");
    }
    if !plan.legs.is_empty() {
        let _ = writeln!(out, "  <rte>\n    <name>{}</name>", escape(&plan.name));
        for waypoint in plan.route() {
            write_point(&mut out, "rtept", waypoint, "    ");
        }
        out.push_str("  </rte>\n");
    }
    out.push_str("</gpx>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const FROM_A_GIS: &str = r#"<?xml version="1.0" encoding="UTF-8" standalone="no" ?>
<gpx xmlns="http://www.topografix.com/GPX/1/1" creator="QGIS" version="1.1"
     xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance">
  <metadata><name>Yard</name><time>2026-11-20T10:00:00Z</time></metadata>
  <wpt lat="43.5616" lon="1.4692"><ele>150</ele><name>Rally point</name><sym>Flag, Blue</sym></wpt>
  <rte>
    <name>Patrol</name>
    <rtept lat="43.56154" lon="1.46905"><name>Start</name></rtept>
    <rtept lat="43.56154" lon="1.46925"><name>East gate</name><sym>SFGPUCR----K---</sym></rtept>
    <rtept lat="43.56165" lon="1.46925"><name>East gate</name></rtept>
  </rte>
  <trk><name>Walk</name><trkseg>
    <trkpt lat="43.56165" lon="1.46925"><time>2026-11-20T10:00:00Z</time></trkpt>
    <trkpt lat="43.561651" lon="1.469251"/>
    <trkpt lat="43.56175" lon="1.46925"/>
    <trkpt lat="43.561751" lon="1.46925"/>
  </trkseg></trk>
</gpx>"#;

    #[test]
    fn waypoints_routes_and_tracks_become_waypoints_and_legs() {
        let plan = import(FROM_A_GIS, "from gis", "system.xml").expect("imports");
        assert_eq!(plan.name, "from_gis");
        let names: Vec<&str> = plan.waypoints.iter().map(|w| w.name.as_str()).collect();
        // The second track point is 0.1 m from the first, the fourth is the last: kept.
        assert_eq!(
            names,
            [
                "Rally_point",
                "Start",
                "East_gate",
                "East_gate_2",
                "trkpt",
                "trkpt_2",
                "trkpt_3"
            ]
        );
        assert_eq!(plan.waypoints[2].symbol.as_deref(), Some("SFGPUCR----K---"));
        assert_eq!(plan.waypoints[0].symbol, None);
        let legs: Vec<(&str, &str)> = plan
            .legs
            .iter()
            .map(|leg| (leg.from.as_str(), leg.to.as_str()))
            .collect();
        assert_eq!(
            legs,
            [
                ("Start", "East_gate"),
                ("East_gate", "East_gate_2"),
                ("East_gate_2", "trkpt"),
                ("trkpt", "trkpt_2"),
                ("trkpt_2", "trkpt_3"),
            ]
        );
        // What is imported is a plan the plan reader accepts.
        Plan::parse(&plan.to_xml()).unwrap_or_else(|p| panic!("{p:?}"));
    }

    #[test]
    fn export_then_import_gives_the_same_route() {
        let plan = import(FROM_A_GIS, "p", "system.xml").expect("imports");
        let again = import(&export(&plan), "p", "system.xml").expect("reads our own GPX");
        let route = |plan: &Plan| -> Vec<(String, String)> {
            plan.legs
                .iter()
                .map(|leg| (leg.from.clone(), leg.to.clone()))
                .collect()
        };
        // The export repeats the route's points after the waypoints: they are the same
        // waypoints, not copies.
        assert_eq!(route(&again), route(&plan));
        assert_eq!(again.waypoints.len(), plan.waypoints.len());
        for (a, b) in plan.legs.iter().zip(&again.legs) {
            let pa = plan.waypoint(&a.to).expect("a").position;
            let pb = again.waypoint(&b.to).expect("b").position;
            assert!(
                (pa.lat_deg - pb.lat_deg).abs() < 1e-7 && (pa.lon_deg - pb.lon_deg).abs() < 1e-7
            );
        }
    }

    #[test]
    fn a_point_named_like_a_leg_does_not_take_its_name() {
        // Found by fuzzing (fuzz/fuzz_targets/gpx.rs): the leg was named `leg1` too, and the
        // plan reader refused the imported plan.
        let text = r#"<gpx><rte>
  <rtept lat="43.561536" lon="1.4690496"><name>home</name></rtept>
  <rtept lat="21.561536" lon="1.4691986"><name>leg1</name></rtept>
</rte></gpx>"#;
        let plan = import(text, "p", "system.xml").expect("imports");
        assert_eq!(plan.waypoints[1].name, "leg1");
        assert_eq!(plan.legs[0].name, "leg1_2");
        let again = Plan::parse(&plan.to_xml()).unwrap_or_else(|p| panic!("{p:?}"));
        assert_eq!(again.legs[0].name, "leg1_2");
    }

    #[test]
    fn broken_gpx_is_reported_never_a_panic() {
        let problems = |text: &str| -> Vec<String> {
            import(text, "p", "s.xml")
                .expect_err("refused")
                .iter()
                .map(ToString::to_string)
                .collect()
        };
        assert_eq!(
            problems("<gpx><wpt lat=\"91\" lon=\"1\"/><wpt lon=\"x\"/></gpx>"),
            [
                "1:11: `lat` must be degrees between -90 and 90, not `91`",
                "1:29: <wpt> needs the attribute `lat`",
                "1:34: `lon` must be degrees between -180 and 180, not `x`",
            ]
        );
        assert_eq!(
            problems("<gpx version=\"1.1\"/>"),
            ["1:1: the GPX file has no waypoint, route or track"]
        );
        assert_eq!(
            problems("<gpx><wpt lat=\"1\" lon=\"1\"/></gpx>"),
            ["1:1: the GPX file has a single point: a plan needs two to make a leg"]
        );
        assert_eq!(
            problems("<kml/>"),
            ["1:1: expected <gpx> at the top, found <kml>"]
        );
        assert_eq!(problems("<gpx><wpt lat=\"1\"").len(), 1);
    }
}
