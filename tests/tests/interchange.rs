//! Mission interchange with ground stations (issue 24, item 4), as a user would use it:
//! `armor export --qgc` of every bundled plan checked field by field against QGroundControl's
//! documented plan file format; `armor import` of the .plan back (waypoints, delays, no-go
//! areas kept, the plan accepted by `armor check` on its world, and the yard's driven by the
//! simulated robot, its appointment kept from QGC's delay); a .plan written the way QGC
//! writes one, with items we do not support (a survey, a speed change, a return to launch),
//! imported with a warning for each at its line and column; broken .plan files refused where
//! they break; and `armor export --kml` read by fastkml (a KML library from PyPI, validating
//! against the OGC KML 2.2 schema it ships).
#![allow(clippy::unwrap_used)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use armor_model::plan::{AreaKind, GraphicKind, LatLon, Plan, Response};
use armor_tests::check::{armor, assert_refused, line_of, located, output_text};
use armor_tests::workspace_root;
use serde_json::Value;

/// Degrees: a .plan carries doubles, the plan file seven decimals (1 cm).
const SAME_DEG: f64 = 1e-7;

fn bundled_plans() -> Vec<PathBuf> {
    let mut plans: Vec<PathBuf> = std::fs::read_dir(workspace_root().join("missions/robot"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| {
            let name = path.file_name().unwrap().to_string_lossy();
            name.starts_with("plan-") && name.ends_with(".xml")
        })
        .collect();
    plans.sort();
    assert!(plans.len() >= 5, "{plans:?}");
    plans
}

fn read_plan(file: &Path) -> Plan {
    Plan::parse(&std::fs::read_to_string(file).unwrap())
        .unwrap_or_else(|problems| panic!("{}: {problems:?}", file.display()))
}

fn export(format: &str, plan: &Path, output: &Path) -> String {
    let out = armor(&[
        "export".as_ref(),
        format.as_ref(),
        plan.as_os_str(),
        "-o".as_ref(),
        output.as_os_str(),
    ]);
    assert!(out.status.success(), "{}", output_text(&out));
    output_text(&out)
}

fn import(file: &Path, output: &Path, extra: &[&str]) -> std::process::Output {
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "import".as_ref(),
        file.as_os_str(),
        "-o".as_ref(),
        output.as_os_str(),
    ];
    args.extend(extra.iter().map(std::ffi::OsStr::new));
    armor(&args)
}

fn keys(value: &Value) -> BTreeSet<&str> {
    value
        .as_object()
        .unwrap_or_else(|| panic!("not an object: {value}"))
        .keys()
        .map(String::as_str)
        .collect()
}

fn set(names: &[&'static str]) -> BTreeSet<&'static str> {
    names.iter().copied().collect()
}

fn same_place(got: (f64, f64), want: LatLon) -> bool {
    (got.0 - want.lat_deg).abs() < SAME_DEG && (got.1 - want.lon_deg).abs() < SAME_DEG
}

/// The stops of a plan's route: the first leg's start, then each leg's end.
fn stops(plan: &Plan) -> Vec<LatLon> {
    let route: Vec<LatLon> = plan.route().iter().map(|w| w.position).collect();
    assert_eq!(route.len(), plan.legs.len() + 1);
    route
}

/// Twice the signed area of a ring of [lat, lon] pairs, with x = longitude: negative is
/// clockwise on a north-up map.
fn signed_area(ring: &[(f64, f64)]) -> f64 {
    ring.iter()
        .zip(ring.iter().cycle().skip(1))
        .map(|(a, b)| a.1 * b.0 - b.1 * a.0)
        .sum()
}

/// Two rings are the same polygon: the same corners in the same cyclic order, either way round.
fn same_ring(got: &[LatLon], want: &[LatLon]) -> bool {
    if got.len() != want.len() {
        return false;
    }
    let n = want.len();
    let at = |ring: &[LatLon], i: usize| (ring[i % n].lat_deg, ring[i % n].lon_deg);
    (0..n).any(|shift| {
        let forward = (0..n).all(|i| same_place(at(got, i + shift), want[i]));
        let backward = (0..n).all(|i| same_place(at(got, shift + n - i), want[i]));
        forward || backward
    })
}

/// The keys of every simple item; a waypoint has its altitude's besides.
const ITEM_KEYS: [&str; 6] = [
    "autoContinue",
    "command",
    "doJumpId",
    "frame",
    "params",
    "type",
];

#[test]
fn every_bundled_plan_exports_to_qgc_as_its_documented_format() {
    let dir = tempfile::tempdir().unwrap();
    for file in bundled_plans() {
        let plan = read_plan(&file);
        let output = dir.path().join("out.plan");
        let said = export("--qgc", &file, &output);
        let context = format!("{}", file.display());
        let doc: Value = serde_json::from_str(&std::fs::read_to_string(&output).unwrap()).unwrap();

        // The top level (QGC's "Plan File Format": version 1, fileType "Plan").
        assert_eq!(
            keys(&doc),
            set(&[
                "fileType",
                "geoFence",
                "groundStation",
                "mission",
                "rallyPoints",
                "version"
            ]),
            "{context}"
        );
        assert_eq!(doc["fileType"], "Plan");
        assert_eq!(doc["version"], 1);
        assert!(doc["groundStation"].is_string());

        // The mission object: version 2, and every required value.
        let mission = &doc["mission"];
        assert_eq!(
            keys(mission),
            set(&[
                "cruiseSpeed",
                "firmwareType",
                "globalPlanAltitudeMode",
                "hoverSpeed",
                "items",
                "plannedHomePosition",
                "vehicleType",
                "version"
            ]),
            "{context}"
        );
        assert_eq!(mission["version"], 2);
        assert_eq!(mission["firmwareType"], 0, "MAV_AUTOPILOT_GENERIC");
        assert_eq!(mission["vehicleType"], 10, "MAV_TYPE_GROUND_ROVER");
        assert_eq!(mission["globalPlanAltitudeMode"], 1, "relative");
        assert_eq!(mission["cruiseSpeed"], plan.navigation.speed_mps);
        assert_eq!(mission["hoverSpeed"], plan.navigation.speed_mps);
        let route = stops(&plan);
        let home = mission["plannedHomePosition"].as_array().unwrap();
        assert_eq!(home.len(), 3, "latitude, longitude, altitude");
        assert!(same_place(
            (home[0].as_f64().unwrap(), home[1].as_f64().unwrap()),
            route[0]
        ));

        // The items: a waypoint (16) per leg, a delay (93) before each appointment.
        let items = mission["items"].as_array().unwrap();
        let mut expected = Vec::new();
        for (leg, to) in plan.legs.iter().zip(&route[1..]) {
            if let Some(at) = leg.not_before_unix_secs {
                expected.push((93, at, *to));
            }
            expected.push((16, leg.wait_secs.unwrap_or(0.0), *to));
        }
        assert_eq!(items.len(), expected.len(), "{context}");
        for (index, (item, (command, number, to))) in items.iter().zip(&expected).enumerate() {
            let context = format!("{context}: item {index}: {item}");
            assert_eq!(item["type"], "SimpleItem", "{context}");
            assert_eq!(item["command"], *command, "{context}");
            assert_eq!(item["doJumpId"], index + 1, "{context}");
            assert_eq!(item["autoContinue"], true, "{context}");
            let params = item["params"].as_array().unwrap();
            assert_eq!(params.len(), 7, "{context}");
            if *command == 16 {
                let altitude = ["AMSLAltAboveTerrain", "Altitude", "AltitudeMode"];
                let mut want = set(&ITEM_KEYS);
                want.extend(altitude);
                assert_eq!(keys(item), want, "{context}");
                assert_eq!(item["frame"], 3, "MAV_FRAME_GLOBAL_RELATIVE_ALT: {context}");
                assert_eq!(item["Altitude"], 0.0, "{context}");
                assert_eq!(item["AltitudeMode"], 1, "{context}");
                assert!(item["AMSLAltAboveTerrain"].is_null(), "{context}");
                assert_eq!(params[0].as_f64(), Some(*number), "hold: {context}");
                let (lat, lon) = (params[4].as_f64().unwrap(), params[5].as_f64().unwrap());
                assert!(same_place((lat, lon), *to), "{context}");
                assert_eq!(params[6], 0.0, "{context}");
            } else {
                assert_eq!(keys(item), set(&ITEM_KEYS), "{context}");
                assert_eq!(item["frame"], 2, "MAV_FRAME_MISSION: {context}");
                assert_eq!(params[0], -1.0, "until a time of day: {context}");
                let in_day = params[1].as_f64().unwrap() * 3600.0
                    + params[2].as_f64().unwrap() * 60.0
                    + params[3].as_f64().unwrap();
                assert!(
                    (in_day - number.rem_euclid(86_400.0)).abs() < 1e-6,
                    "{context}"
                );
            }
        }

        // The geofence: version 2, an exclusion polygon (version 1) per no-go area, clockwise.
        let fence = &doc["geoFence"];
        assert_eq!(keys(fence), set(&["circles", "polygons", "version"]));
        assert_eq!(fence["version"], 2);
        assert_eq!(fence["circles"], serde_json::json!([]));
        let polygons = fence["polygons"].as_array().unwrap();
        let no_go: Vec<_> = plan.no_go_areas().collect();
        assert_eq!(polygons.len(), no_go.len(), "{context}");
        for (polygon, area) in polygons.iter().zip(&no_go) {
            assert_eq!(keys(polygon), set(&["inclusion", "polygon", "version"]));
            assert_eq!(polygon["inclusion"], false);
            assert_eq!(polygon["version"], 1);
            let ring: Vec<(f64, f64)> = polygon["polygon"]
                .as_array()
                .unwrap()
                .iter()
                .map(|corner| {
                    let corner = corner.as_array().unwrap();
                    assert_eq!(corner.len(), 2, "[latitude, longitude]");
                    (corner[0].as_f64().unwrap(), corner[1].as_f64().unwrap())
                })
                .collect();
            assert!(signed_area(&ring) < 0.0, "clockwise: {context}: {ring:?}");
            let ring: Vec<LatLon> = ring.iter().map(|(a, b)| LatLon::new(*a, *b)).collect();
            assert!(same_ring(&ring, &area.points), "{context}: {}", area.name);
        }

        // The rally points: the waypoints a `return` contingency names.
        let rally = &doc["rallyPoints"];
        assert_eq!(keys(rally), set(&["points", "version"]));
        assert_eq!(rally["version"], 2);
        let returns: BTreeSet<&str> = plan
            .every_contingency()
            .filter_map(|c| match &c.response {
                Response::Return { waypoint } => Some(waypoint.as_str()),
                _ => None,
            })
            .collect();
        let points = rally["points"].as_array().unwrap();
        assert_eq!(points.len(), returns.len(), "{context}");
        for (point, name) in points.iter().zip(&returns) {
            let point = point.as_array().unwrap();
            assert_eq!(point.len(), 3);
            let want = plan.waypoint(name).unwrap().position;
            assert!(same_place(
                (point[0].as_f64().unwrap(), point[1].as_f64().unwrap()),
                want
            ));
        }

        // What the format cannot carry is said, not silently lost.
        assert!(said.contains("QGC plan written"), "{said}");
        if plan
            .legs
            .iter()
            .any(|leg| leg.arrive_by_unix_secs.is_some())
        {
            assert!(
                said.contains("warning: not carried by a QGC plan: deadlines"),
                "{said}"
            );
        }
    }
}

#[test]
fn every_bundled_plan_comes_back_from_qgc_with_its_route_delays_and_no_go_areas() {
    let dir = tempfile::tempdir().unwrap();
    for file in bundled_plans() {
        let plan = read_plan(&file);
        let context = format!("{}", file.display());
        let qgc = dir.path().join("round.plan");
        export("--qgc", &file, &qgc);
        // Its system named by its full path, so that `armor check` finds it from the copy.
        let back = dir.path().join("round.xml");
        let system = file.with_file_name(&plan.system);
        let system = system.to_str().unwrap();
        let mut args = vec!["--system", system, "--world", &plan.world];
        let start = plan.start_unix_secs.map(armor_model::net::format_rfc3339);
        if let Some(start) = &start {
            args.extend(["--start", start]);
        }
        let out = import(&qgc, &back, &args);
        assert!(out.status.success(), "{context}: {}", output_text(&out));
        // Our own .plan reads without a warning, but for the rally points (where a `return`
        // went), which no contingency uses once read back.
        let text = output_text(&out);
        assert!(
            text.lines()
                .filter(|line| line.contains("warning"))
                .all(|line| line.contains("rally points kept as waypoints")),
            "{context}: {text}"
        );
        let again = read_plan(&back);

        let (want, got) = (stops(&plan), stops(&again));
        assert_eq!(got.len(), want.len(), "{context}");
        for (got, want) in got.iter().zip(&want) {
            assert!(
                same_place((got.lat_deg, got.lon_deg), *want),
                "{context}: {got:?} against {want:?}"
            );
        }
        for (got, want) in again.legs.iter().zip(&plan.legs) {
            assert_eq!(
                got.wait_secs, want.wait_secs,
                "{context}: leg {}",
                want.name
            );
            assert_eq!(
                got.not_before_unix_secs, want.not_before_unix_secs,
                "{context}: leg {}",
                want.name
            );
        }
        let no_go: Vec<_> = plan.no_go_areas().collect();
        let no_go_again: Vec<_> = again.no_go_areas().collect();
        assert_eq!(no_go_again.len(), no_go.len(), "{context}");
        for (got, want) in no_go_again.iter().zip(&no_go) {
            assert!(
                same_ring(&got.points, &want.points),
                "{context}: {}",
                want.name
            );
        }

        // The plan read back is one `armor check` takes on the same world, once given back the
        // no-go areas' own margins, which QGC has no field for (the export says so) and which
        // the operator sets again: with the default margin, the explore plan's spill closes the
        // south room's way in.
        if no_go.iter().any(|area| area.margin_m.is_some()) {
            let mut restored = again.clone();
            let margins: Vec<Option<f64>> = no_go.iter().map(|area| area.margin_m).collect();
            let mut margins = margins.into_iter();
            for graphic in &mut restored.graphics {
                if graphic.kind == GraphicKind::Area(AreaKind::NoGo) {
                    graphic.margin_m = margins.next().flatten();
                }
            }
            std::fs::write(&back, restored.to_xml()).unwrap();
        }
        let checked = armor(&["check".as_ref(), back.as_os_str()]);
        assert!(
            checked.status.success(),
            "{context}: {}",
            output_text(&checked)
        );
    }
}

#[test]
fn a_plan_written_by_qgc_imports_and_what_we_do_not_support_is_warned_where_it_is() {
    let file = workspace_root().join("tests/data/qgc-rover-survey.plan");
    let text = std::fs::read_to_string(&file).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("rover.xml");
    let out = import(&file, &output, &["--start", "2026-11-23T14:00:00Z"]);
    let all = output_text(&out);
    assert!(out.status.success(), "{all}");
    assert!(
        all.contains("plan `rover` written (6 waypoints, 4 legs, 3 areas)"),
        "{all}"
    );

    // Each warning at the line of what it is about.
    let warnings = located(&out, &file);
    let warned_at = |needle: &str, says: &[&str]| {
        let line = line_of(&text, needle);
        assert!(
            warnings.iter().any(|(at, col, message)| *at == line
                && *col > 0
                && message.starts_with("warning:")
                && says.iter().all(|word| message.contains(word))),
            "expected a warning at line {line} ({needle}) saying {says:?}:\n{all}"
        );
    };
    // The survey is warned at its opening brace.
    let survey = text.find("\"TransectStyleComplexItem\"").unwrap();
    let survey_line = text[..=text[..survey].rfind('{').unwrap()].lines().count();
    assert!(
        warnings.iter().any(|(at, _, message)| *at == survey_line
            && message.contains("complex item (`survey`")
            && message.contains("skipped")),
        "the survey is warned at its opening brace, line {survey_line}:\n{all}"
    );
    warned_at("\"command\": 178", &["178", "DO_CHANGE_SPEED", "skipped"]);
    warned_at("\"command\": 20,", &["NAV_RETURN_TO_LAUNCH", "skipped"]);
    assert!(
        warnings
            .iter()
            .any(|(_, _, m)| m.contains("altitude (2 m) is not carried")),
        "{all}"
    );
    assert!(
        warnings
            .iter()
            .any(|(_, _, m)| m.contains("fence circle (6.5 m)")),
        "{all}"
    );
    assert!(
        warnings
            .iter()
            .any(|(_, _, m)| m.contains("inclusion fence is kept as the named area `fence_1`")),
        "{all}"
    );
    assert_eq!(warnings.len(), 7, "{all}");

    // The plan: home, the four waypoints of the route (the survey's own are not taken), and
    // the rally point.
    let plan = read_plan(&output);
    let names: Vec<&str> = plan.waypoints.iter().map(|w| w.name.as_str()).collect();
    assert_eq!(names, ["home", "wp1", "wp2", "wp3", "wp4", "rally"]);
    let at = |name: &str| plan.waypoint(name).unwrap().position;
    assert!(same_place((47.39741302, 8.54435214), at("home")));
    assert!(same_place((47.39770113, 8.54470021), at("wp1")));
    assert!(same_place((47.39805117, 8.54495238), at("wp2")));
    assert!(same_place((47.39742551, 8.54560883), at("wp3")));
    assert!(same_place((47.39725013, 8.54450102), at("wp4")));
    assert!(same_place((47.39735519, 8.54412077), at("rally")));
    let legs: Vec<(&str, &str, Option<f64>)> = plan
        .legs
        .iter()
        .map(|leg| (leg.from.as_str(), leg.to.as_str(), leg.wait_secs))
        .collect();
    assert_eq!(
        legs,
        [
            ("home", "wp1", None),
            // Its hold (15 s) and the delay of 20 s after it.
            ("wp1", "wp2", Some(35.0)),
            ("wp2", "wp3", None),
            // The timed loiter's 30 s.
            ("wp3", "wp4", Some(30.0))
        ]
    );
    // The delay until 14:30 UTC, on the start's day.
    assert_eq!(
        plan.legs[2].not_before_unix_secs,
        Some(armor_model::net::parse_rfc3339("2026-11-23T14:30:00Z").unwrap())
    );
    assert_eq!(plan.navigation.speed_mps, 1.2, "a rover's cruise speed");
    let areas: Vec<(&str, GraphicKind, usize)> = plan
        .graphics
        .iter()
        .map(|g| (g.name.as_str(), g.kind, g.points.len()))
        .collect();
    assert_eq!(
        areas,
        [
            ("no_go_1", GraphicKind::Area(AreaKind::NoGo), 4),
            ("fence_1", GraphicKind::Area(AreaKind::Named), 4),
            ("no_go_2", GraphicKind::Area(AreaKind::NoGo), 32),
        ]
    );
    // The circle's polygon holds the whole circle: every corner at least 6.5 m from the centre.
    let centre = LatLon::new(47.39761228, 8.54524572);
    for corner in &plan.graphics[2].points {
        let d = corner.to_local(centre);
        let r = d.x.hypot(d.y);
        assert!((6.5..6.6).contains(&r), "{r} m");
    }

    // Without a start date, the delay until a time of day cannot be placed: it is dropped,
    // with a warning that says how to keep it.
    let out = import(&file, &dir.path().join("undated.xml"), &[]);
    assert!(out.status.success(), "{}", output_text(&out));
    assert!(
        located(&out, &file)
            .iter()
            .any(|(_, _, m)| m.contains("14:30:00 UTC") && m.contains("--start")),
        "{}",
        output_text(&out)
    );
    let undated = read_plan(&dir.path().join("undated.xml"));
    assert_eq!(undated.legs[2].not_before_unix_secs, None);
}

#[test]
fn broken_qgc_plans_are_refused_where_they_break_and_write_no_plan() {
    let dir = tempfile::tempdir().unwrap();
    let good =
        std::fs::read_to_string(workspace_root().join("tests/data/qgc-rover-survey.plan")).unwrap();
    let refused = |name: &str, text: &str| {
        let file = dir.path().join(format!("{name}.plan"));
        std::fs::write(&file, text).unwrap();
        let plan = dir.path().join(format!("{name}.xml"));
        let out = import(&file, &plan, &[]);
        assert!(
            !plan.exists(),
            "{name}: a plan was written:\n{}",
            output_text(&out)
        );
        (file, out)
    };

    // Cut in the middle: serde_json's line and column.
    let cut = good.find("\"plannedHomePosition\"").unwrap();
    let (file, out) = refused("truncated", &good[..cut]);
    let all = output_text(&out);
    assert_eq!(out.status.code(), Some(1), "{all}");
    assert!(!all.contains("panicked"), "{all}");
    let problems = located(&out, &file);
    assert_eq!(problems.len(), 1, "{all}");
    assert!(problems[0].2.contains("not a QGC plan (JSON)"), "{all}");
    assert_eq!(problems[0].0, good[..cut].lines().count(), "{all}");

    // A latitude beyond the pole, at its own line.
    let broken = good.replacen("47.39805117", "147.39805117", 1);
    let (file, out) = refused("beyond-the-pole", &broken);
    assert_refused(
        &out,
        &file,
        line_of(&broken, "147.39805117"),
        &["latitude", "90", "147.39805117"],
    );

    // A longitude that is text.
    let broken = good.replacen("8.54560883", "\"east\"", 1);
    let (file, out) = refused("not-a-number", &broken);
    assert_refused(
        &out,
        &file,
        line_of(&broken, "\"east\""),
        &["longitude", "must be a number"],
    );

    // A file of another kind, and a mission without items.
    let broken = good.replacen("\"fileType\": \"Plan\"", "\"fileType\": \"GeoFence\"", 1);
    let (file, out) = refused("geofence-file", &broken);
    assert_refused(&out, &file, 2, &["fileType", "\"Plan\""]);
    let (file, out) = refused(
        "no-items",
        "{\"fileType\": \"Plan\", \"version\": 1,\n \"mission\": {\"version\": 2}}",
    );
    assert_refused(&out, &file, 2, &["items"]);

    // Only a home: nothing to drive to.
    let (file, out) = refused(
        "home-only",
        "{\"fileType\": \"Plan\", \"version\": 1, \"mission\": {\"version\": 2,\n\
         \"plannedHomePosition\": [47.4, 8.5, 0], \"items\": []}}",
    );
    assert_refused(&out, &file, 2, &["no waypoint to drive to"]);
}

/// What fastkml reads in a KML file: each folder's placemarks with their geometry, times and
/// extended data. The file is validated against the OGC KML 2.2 schema fastkml ships.
const READ_KML: &str = r#"
import json, sys
from fastkml import KML
kml = KML.parse(sys.argv[1], validate=True)
document = kml.features[0]
def placemark(p):
    g = p.geometry
    kind = type(g).__name__
    if kind == "Polygon":
        coords = [list(c) for c in g.exterior.coords]
    else:
        coords = [list(c) for c in g.coords]
    data = {}
    if p.extended_data is not None:
        data = {d.name: d.value for d in p.extended_data.elements}
    when = p.times.timestamp.dt.isoformat() if p.times is not None else None
    return {"name": p.name, "geometry": kind, "coords": coords, "data": data, "when": when}
print(json.dumps({
    "name": document.name,
    "folders": {f.name: [placemark(p) for p in f.features] for f in document.features},
}))
"#;

fn read_kml(file: &Path) -> Value {
    let read = armor_tests::tools::python3(&["fastkml", "lxml"])
        .args(["-c", READ_KML])
        .arg(file)
        .output()
        .unwrap_or_else(|err| panic!("cannot run python3: {err}"));
    assert!(read.status.success(), "{}", output_text(&read));
    serde_json::from_slice(&read.stdout).unwrap()
}

/// A KML coordinate: longitude first.
fn kml_point(coords: &Value) -> LatLon {
    let c = coords.as_array().unwrap();
    LatLon::new(c[1].as_f64().unwrap(), c[0].as_f64().unwrap())
}

#[test]
fn every_bundled_plan_exports_to_kml_that_fastkml_reads_with_names_coordinates_and_polygons() {
    let dir = tempfile::tempdir().unwrap();
    for file in bundled_plans() {
        let plan = read_plan(&file);
        let context = format!("{}", file.display());
        let kml = dir.path().join("out.kml");
        export("--kml", &file, &kml);
        let read = read_kml(&kml);
        assert_eq!(read["name"], plan.name.as_str(), "{context}");
        let folder = |name: &str| -> Vec<Value> {
            read["folders"][name]
                .as_array()
                .cloned()
                .unwrap_or_default()
        };

        // The route: one line through the stops, longitude first.
        let route = folder("Route");
        assert_eq!(route.len(), 1, "{context}");
        assert_eq!(route[0]["geometry"], "LineString");
        let line: Vec<LatLon> = route[0]["coords"]
            .as_array()
            .unwrap()
            .iter()
            .map(kml_point)
            .collect();
        let want = stops(&plan);
        assert_eq!(line.len(), want.len(), "{context}");
        for (got, want) in line.iter().zip(&want) {
            assert!(same_place((got.lat_deg, got.lon_deg), *want), "{context}");
        }

        // The waypoints, by name, with their SIDC and times.
        let waypoints = folder("Waypoints");
        assert_eq!(waypoints.len(), plan.waypoints.len(), "{context}");
        for (got, want) in waypoints.iter().zip(&plan.waypoints) {
            assert_eq!(got["name"], want.name.as_str(), "{context}");
            assert_eq!(got["geometry"], "Point");
            let at = kml_point(&got["coords"][0]);
            assert!(
                same_place((at.lat_deg, at.lon_deg), want.position),
                "{context}"
            );
            assert_eq!(
                got["data"]["sidc"].as_str(),
                want.symbol.as_deref(),
                "{context}"
            );
            for leg in plan.legs.iter().filter(|leg| leg.to == want.name) {
                if let Some(by) = leg.arrive_by_unix_secs {
                    let by = armor_model::net::format_rfc3339(by);
                    assert_eq!(got["data"]["arrive_by"], by.as_str(), "{context}");
                    // fastkml writes the time stamp back in its own form (+00:00).
                    let when = got["when"].as_str().unwrap();
                    assert_eq!(when.replace("+00:00", "Z"), by, "{context}");
                }
                if let Some(wait) = leg.wait_secs {
                    assert_eq!(got["data"]["wait_secs"], wait.to_string(), "{context}");
                }
            }
            for leg in plan.legs.iter().filter(|leg| leg.from == want.name) {
                if let Some(at) = leg.not_before_unix_secs {
                    let at = armor_model::net::format_rfc3339(at);
                    assert_eq!(got["data"]["not_before"], at.as_str(), "{context}");
                }
            }
        }

        // Every area a closed polygon of its corners; lines as lines; units with their SIDC.
        let areas = folder("Areas");
        let plan_areas: Vec<_> = plan
            .graphics
            .iter()
            .filter(|g| matches!(g.kind, GraphicKind::Area(_)))
            .collect();
        assert_eq!(areas.len(), plan_areas.len(), "{context}");
        for (got, want) in areas.iter().zip(&plan_areas) {
            assert_eq!(got["name"], want.name.as_str());
            assert_eq!(got["geometry"], "Polygon");
            let GraphicKind::Area(kind) = want.kind else {
                unreachable!()
            };
            assert_eq!(got["data"]["kind"], kind.as_str());
            let ring: Vec<LatLon> = got["coords"]
                .as_array()
                .unwrap()
                .iter()
                .map(kml_point)
                .collect();
            assert_eq!(ring.len(), want.points.len() + 1, "closed: {context}");
            let (first, last) = (ring[0], ring[ring.len() - 1]);
            assert!(same_place((first.lat_deg, first.lon_deg), last));
            assert!(
                same_ring(&ring[..ring.len() - 1], &want.points),
                "{context}"
            );
        }
        let lines = folder("Lines");
        let plan_lines: Vec<_> = plan
            .graphics
            .iter()
            .filter(|g| !matches!(g.kind, GraphicKind::Area(_)))
            .collect();
        assert_eq!(lines.len(), plan_lines.len(), "{context}");
        for (got, want) in lines.iter().zip(&plan_lines) {
            assert_eq!(got["name"], want.name.as_str());
            assert_eq!(got["geometry"], "LineString");
            let points: Vec<LatLon> = got["coords"]
                .as_array()
                .unwrap()
                .iter()
                .map(kml_point)
                .collect();
            assert_eq!(points.len(), want.points.len());
            for (got, want) in points.iter().zip(&want.points) {
                assert!(same_place((got.lat_deg, got.lon_deg), *want));
            }
        }
        let units = folder("Units");
        assert_eq!(units.len(), plan.units.len(), "{context}");
        for (got, want) in units.iter().zip(&plan.units) {
            assert_eq!(got["name"], want.name.as_str());
            assert_eq!(got["data"]["sidc"], want.sidc.as_str());
            let at = kml_point(&got["coords"][0]);
            assert!(same_place((at.lat_deg, at.lon_deg), want.position));
        }
    }
}

#[test]
fn the_yard_plan_through_qgc_drives_the_route_and_keeps_its_appointment() {
    let dir = tempfile::tempdir().unwrap();
    let original = workspace_root().join("missions/robot/plan-yard.xml");
    let qgc = dir.path().join("yard.plan");
    export("--qgc", &original, &qgc);
    let imported = dir.path().join("yard-from-qgc.xml");
    let system = workspace_root().join("missions/robot/system.xml");
    let out = import(
        &qgc,
        &imported,
        &[
            "--system",
            system.to_str().unwrap(),
            "--start",
            "2026-11-23T08:00:00Z",
        ],
    );
    assert!(out.status.success(), "{}", output_text(&out));
    // As with a GPX import (README), the navigation is the user's to give: the avoider beside
    // the follower, without which the robot's commands go nowhere.
    let text = std::fs::read_to_string(&imported).unwrap().replacen(
        "start=\"2026-11-23T08:00:00Z\">",
        "start=\"2026-11-23T08:00:00Z\">\n  <navigation><module name=\"avoider\"/></navigation>",
        1,
    );
    std::fs::write(&imported, text).unwrap();

    let run = armor_tests::mission::run_mission(
        &imported,
        &["--start-at", "2026-11-23T08:00:00Z"],
        std::time::Duration::from_secs(120),
    );
    assert_eq!(run.final_marking(), serde_json::json!({ "done": 1 }));
    run.assert_clean();
    let arrived: Vec<String> = run
        .fired_names()
        .into_iter()
        .filter(|name| name.ends_with("_arrived"))
        .collect();
    assert_eq!(
        arrived,
        [
            "leg1_arrived",
            "leg2_arrived",
            "leg3_arrived",
            "leg4_arrived"
        ]
    );
    // The appointment came back from the NAV_DELAY: the second leg left at 08:01:30, 90 s in,
    // and the hold of 5 s at its end was kept.
    let left = run.fired_at("leg2_appointment").unwrap_or_else(|| {
        panic!("no appointment: {:?}", run.fired());
    });
    assert!(left >= 90.0 - 0.5, "left at {left} s");
    assert!(
        run.between("leg2_arrived", "leg2_waited") >= 5.0 - 0.5,
        "{:?}",
        run.fired()
    );
}
