//! Files from other tools, second round (issue 44), as a user of those tools would bring them:
//! Nav2's TurtleBot map, QGroundControl's own test plans, a GPS tool's GPX, nets as the Model
//! Checking Contest writes them, and ROS maps written by hand from map_server's documented
//! rules. Each test says which item of the issue it holds. The files taken from the tools are
//! under `tests/data/external/` (their sources, commits and licences in its README).
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Output;

use armor_model::geo::Point;
use armor_model::plan::Plan;
use armor_tests::check::{armor, located, output_text};
use armor_tests::mission::armor_run;
use armor_tests::{ctl, workspace_root};

fn external(name: &str) -> PathBuf {
    workspace_root().join("tests/data/external").join(name)
}

fn run(args: &[&str]) -> Output {
    let args: Vec<&std::ffi::OsStr> = args.iter().map(std::ffi::OsStr::new).collect();
    armor(&args)
}

fn text(path: &Path) -> String {
    path.to_str().unwrap().to_owned()
}

fn write(dir: &Path, name: &str, content: &str) -> PathBuf {
    let file = dir.join(name);
    std::fs::write(&file, content).unwrap();
    file
}

/// The simulated robot on `world` with the follower that drives the legs and the avoider that
/// keeps its default radius (0.25 m); the simulator's radius as given.
fn robot_system(dir: &Path, world: &Path, sim_radius_m: &str) -> PathBuf {
    write(
        dir,
        "system.xml",
        &format!(
            r#"<system name="small-robot">
  <module name="sim" type="sim">
    <param name="world" value="{world}"/>
    <param name="robot_radius_m" value="{sim_radius_m}"/>
  </module>
  <module name="follower" type="follower">
    <param name="world" value="{world}"/>
    <param name="goal_x_m" value="0"/>
    <param name="goal_y_m" value="0"/>
  </module>
  <module name="avoider" type="avoider"/>
  <link from="sim.odometry" to="follower.odometry"/>
  <link from="sim.scan" to="follower.scan"/>
  <link from="sim.scan" to="avoider.scan"/>
  <link from="follower.cmd_desired" to="avoider.cmd_desired"/>
  <link from="avoider.cmd_vel" to="sim.cmd_vel"/>
</system>
"#,
            world = world.display()
        ),
    )
}

/// A plan over `system.xml` (its world) through `points` (name, x, y in the world frame).
fn plan_on(
    world: &armor_model::world::World,
    navigation: &str,
    points: &[(&str, f64, f64)],
) -> String {
    let mut out = format!("<plan name=\"p\" system=\"system.xml\">\n{navigation}");
    for (name, x, y) in points {
        let (lat, lon) = world.to_lat_lon(Point::new(*x, *y));
        out.push_str(&format!(
            "  <waypoint name=\"{name}\" lat=\"{lat:.9}\" lon=\"{lon:.9}\"/>\n"
        ));
    }
    for pair in points.windows(2) {
        out.push_str(&format!(
            "  <leg from=\"{}\" to=\"{}\"/>\n",
            pair[0].0, pair[1].0
        ));
    }
    out.push_str("</plan>\n");
    out
}

fn load_world(file: &Path) -> armor_model::world::World {
    armor_model::world_file::load(file, &mut |path| std::fs::read(path)).unwrap()
}

/// Items 1 and 8: on Nav2's TurtleBot map (no `start`, no `geo_origin`), `armor check` says
/// how far the simulated robot starts from where the plan starts, and is quiet when they
/// agree; `armor check map.yaml` checks the map; a GPX export of a plan on a map with no
/// geographic origin is warned.
#[test]
fn on_nav2_s_turtlebot_map_the_check_compares_the_robot_s_start_with_the_plan_s() {
    let map = external("nav2/tb3_sandbox.yaml");
    let checked = run(&["check", &text(&map)]);
    let said = output_text(&checked);
    assert!(checked.status.success(), "{said}");
    assert!(said.contains(": ok (world `"), "{said}");
    assert!(said.contains("the simulated robot starts at ("), "{said}");
    assert!(!said.contains("top-level element"), "{said}");

    let world = load_world(&map);
    let start = world.start();
    let dir = tempfile::tempdir().unwrap();
    robot_system(dir.path(), &map, "0.105");
    // A plan that starts 1 m south of the robot's start, by the TurtleBot world's west side.
    let plan = write(
        dir.path(),
        "plan.xml",
        &plan_on(&world, "", &[("home", -1.7, -1.0), ("north", -1.775, 0.9)]),
    );
    let checked = run(&["check", &text(&plan)]);
    let said = output_text(&checked);
    assert!(checked.status.success(), "{said}");
    let off_m = (start.x_m + 1.7).hypot(start.y_m + 1.0);
    assert!(
        off_m > 0.5,
        "the map's start {start:?} is near the spawn point"
    );
    let warning = located(&checked, &plan)
        .into_iter()
        .find(|(_, _, message)| message.contains("the simulated robot starts at"))
        .unwrap_or_else(|| panic!("no word on the start:\n{said}"));
    assert_eq!(warning.0, 4, "at the first leg: {said}");
    let cm = format!("{:.2}", off_m);
    let cm = cm.trim_end_matches('0').trim_end_matches('.');
    assert!(
        warning.2.contains(&format!("{cm} m from `home`")),
        "{cm}: {said}"
    );
    assert!(warning.2.contains("start: ["), "{said}");

    // A plan that starts where the robot does: not a word.
    let plan = write(
        dir.path(),
        "plan.xml",
        &plan_on(
            &world,
            "",
            &[("home", start.x_m, start.y_m), ("north", -1.775, 0.9)],
        ),
    );
    let checked = run(&["check", &text(&plan)]);
    let said = output_text(&checked);
    assert!(checked.status.success(), "{said}");
    assert!(!said.contains("starts at"), "{said}");

    // The map has no geo_origin: its coordinates are round (0°, 0°), and a GPX says so.
    let gpx = dir.path().join("plan.gpx");
    let exported = run(&["export", "--gpx", &text(&plan), "-o", &text(&gpx)]);
    let said = output_text(&exported);
    assert!(exported.status.success(), "{said}");
    assert!(
        said.contains("(0°, 0°)") && said.contains("geo_origin"),
        "{said}"
    );
}

/// Item 2: QGroundControl's own ArduRover test plan says `cruiseSpeed` 15 (QGC's default for
/// every vehicle); the robot drives at most 0.6 m/s (the follower's default), and a 5-minute
/// deadline on its first leg (2.1 km) is checked at the robot's speed, with a word on the
/// plan's.
#[test]
fn a_qgc_cruise_speed_the_robot_cannot_drive_is_said_and_the_times_use_the_robot_s() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "system.xml",
        r#"<system name="rover">
  <module name="follower" type="follower">
    <param name="goal_x_m" value="0"/>
    <param name="goal_y_m" value="0"/>
  </module>
</system>
"#,
    );
    let plan = dir.path().join("rover.xml");
    let imported = run(&[
        "import",
        &text(&external("qgc/ArduPilotSITL-ArduRover.plan")),
        "-o",
        &text(&plan),
        "--start",
        "2026-11-23T08:00:00Z",
    ]);
    assert!(imported.status.success(), "{}", output_text(&imported));
    let written = std::fs::read_to_string(&plan).unwrap();
    assert_eq!(Plan::parse(&written).unwrap().navigation.speed_mps, 15.0);
    // No world (a real rover): the plan's origin places it; the first leg is due in 5 minutes.
    let header_end = written.find("<plan").unwrap();
    let header_end = header_end + written[header_end..].find(">\n").unwrap() + 2;
    let mut edited = written.clone();
    edited.insert_str(
        header_end,
        "  <origin lat=\"-35.363261\" lon=\"149.16523\"/>\n",
    );
    let edited = edited.replacen("<leg ", "<leg arrive_by=\"2026-11-23T08:05:00Z\" ", 1);
    std::fs::write(&plan, &edited).unwrap();
    let checked = run(&["check", &text(&plan)]);
    let said = output_text(&checked);
    assert!(checked.status.success(), "{said}");
    assert!(
        said.contains(
            "the plan's speed, 15 m/s, is more than the robot drives (0.6 m/s: module \
             `follower`'s default max_speed_mps)"
        ),
        "{said}"
    );
    let deadline = located(&checked, &plan)
        .into_iter()
        .find(|(_, _, message)| message.contains("the deadline"))
        .unwrap_or_else(|| panic!("the deadline passes:\n{said}"));
    assert!(deadline.2.contains("at 0.6 m/s"), "{said}");
}

/// A P/T net in the Model Checking Contest's PNML: `count` places in a row, the first marked
/// when `marked`, each transition moving the token on; the last place ends the net.
fn mcc_net(id: &str, count: usize, marked: bool) -> String {
    let mut out = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnml\">\n  <net id=\"{id}\" type=\"http://www.pnml.org/version-2009/grammar/ptnet\">\n    <name><text>{id}</text></name>\n    <page id=\"page0\">\n"
    );
    for i in 0..count {
        let marking = if marked && i == 0 {
            "<initialMarking><text>1</text></initialMarking>"
        } else {
            ""
        };
        out.push_str(&format!(
            "      <place id=\"p{i}\"><name><text>p{i}</text></name>{marking}</place>\n"
        ));
    }
    for i in 0..count - 1 {
        out.push_str(&format!(
            "      <transition id=\"t{i}\"><name><text>t{i}</text></name></transition>\n      <arc id=\"a{i}\" source=\"p{i}\" target=\"t{i}\"/>\n      <arc id=\"b{i}\" source=\"t{i}\" target=\"p{}\"/>\n",
            i + 1
        ));
    }
    out.push_str("    </page>\n  </net>\n</pnml>\n");
    out
}

/// Items 3 and 8: a net from another tool is imported with `--system` and checked without
/// editing; a net that ends fails the check (its last marking is dead) and still says how many
/// markings it has; a net with no initial marking is warned on import.
#[test]
fn an_imported_pnml_net_is_checked_with_its_system_and_its_markings_are_counted() {
    let dir = tempfile::tempdir().unwrap();
    let pnml = write(dir.path(), "Sequence.pnml", &mcc_net("Sequence", 5, true));
    let mission = dir.path().join("sequence.xml");
    let demo_system = workspace_root().join("missions/demo/system.xml");

    // Without --system: a word on what is missing, and the check says how to give it.
    let imported = run(&["import", &text(&pnml), "-o", &text(&mission)]);
    let said = output_text(&imported);
    assert!(imported.status.success(), "{said}");
    assert!(said.contains("--system FILE"), "{said}");
    let checked = run(&["check", &text(&mission)]);
    assert!(
        output_text(&checked).contains("--system FILE"),
        "{}",
        output_text(&checked)
    );

    let imported = run(&[
        "import",
        &text(&pnml),
        "-o",
        &text(&mission),
        "--system",
        &text(&demo_system),
    ]);
    let said = output_text(&imported);
    assert!(imported.status.success(), "{said}");
    assert!(!said.contains("warning"), "{said}");
    let checked = run(&["check", &text(&mission)]);
    let said = output_text(&checked);
    // The net ends in p4, which is not final: a deadlock, and its five markings.
    assert_eq!(checked.status.code(), Some(1), "{said}");
    assert!(
        said.contains("5 markings reachable (counted although the check failed)"),
        "{said}"
    );

    let unmarked = write(dir.path(), "Unmarked.pnml", &mcc_net("Unmarked", 3, false));
    let imported = run(&["import", &text(&unmarked), "-o", &text(&mission)]);
    let said = output_text(&imported);
    assert!(imported.status.success(), "{said}");
    assert!(
        said.contains("warning: the net has no initial marking"),
        "{said}"
    );
}

/// The number that follows `after` in `text`.
fn number_in(text: &str, after: &str) -> f64 {
    let at = text
        .find(after)
        .unwrap_or_else(|| panic!("no `{after}` in {text}"));
    text[at + after.len()..]
        .split_whitespace()
        .next()
        .and_then(|word| word.parse().ok())
        .unwrap_or_else(|| panic!("no number after `{after}` in {text}"))
}

/// A ROS map_server map written from its documented rules: `width` × 80 cells of 5 cm, walled
/// round, with a wall across at x = 4 m that has a door `door_cells` cells wide.
fn door_map(dir: &Path, width: usize, door_cells: usize) -> PathBuf {
    let height = 80;
    let mut pgm = format!("P5\n{width} {height}\n255\n").into_bytes();
    // PGM rows run from the top (north) down; the door is round y = 2 m.
    let door = (40 - door_cells / 2)..(40 - door_cells / 2 + door_cells);
    for row in 0..height {
        for col in 0..width {
            let border = row == 0 || col == 0 || row == height - 1 || col == width - 1;
            let wall = (80..82).contains(&col) && !door.contains(&row);
            pgm.push(if border || wall { 0 } else { 254 });
        }
    }
    std::fs::write(dir.join("door.pgm"), pgm).unwrap();
    write(
        dir,
        "door.yaml",
        "image: door.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\nstart: [1.0, 2.0, 0]\ngeo_origin: [43.5615, 1.469]\n",
    )
}

/// Items 4 and 8: through a 0.75 m door, the robot the system describes needs more; the
/// message says it in the same terms, and which module's radius won (the avoider's default,
/// over the simulator's 0.105 m for a TurtleBot); the plan's own radius lets it through. A
/// waypoint in the wall is "on" it, one outside the map gets the map's extent in round
/// numbers.
#[test]
fn a_door_too_narrow_says_what_the_robot_needs_and_whose_radius_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let map = door_map(dir.path(), 163, 15);
    let world = load_world(&map);
    robot_system(dir.path(), &map, "0.105");
    let through = [("west", 1.0, 2.0), ("east", 7.0, 2.0)];
    let plan = write(dir.path(), "plan.xml", &plan_on(&world, "", &through));
    let checked = run(&["check", &text(&plan)]);
    let said = output_text(&checked);
    assert_eq!(checked.status.code(), Some(1), "{said}");
    let width_m = number_in(&said, "the narrowest passage is ");
    let needed_m = number_in(&said, "the robot needs ");
    assert!((width_m - 0.75).abs() < 0.06, "{said}");
    assert!(needed_m > width_m, "the message contradicts itself: {said}");
    assert!(
        // The follower's default (0.25 m, as the avoider's), not the simulator's 0.105 m.
        said.contains(
            "(the robot's radius, 0.25 m: module `follower`'s default robot_radius_m, the \
             largest of the system's modules (`sim` 0.105 m)"
        ),
        "{said}"
    );

    let small = "  <navigation robot_radius_m=\"0.105\"/>\n";
    let plan = write(dir.path(), "plan.xml", &plan_on(&world, small, &through));
    let checked = run(&["check", &text(&plan)]);
    assert!(checked.status.success(), "{}", output_text(&checked));

    // The same on Nav2's TurtleBot map, between two of its pillars.
    let tb3_dir = tempfile::tempdir().unwrap();
    let tb3_map = external("nav2/tb3_sandbox.yaml");
    let tb3 = load_world(&tb3_map);
    robot_system(tb3_dir.path(), &tb3_map, "0.105");
    let between = [("pillars", -0.6, -0.55), ("west", -1.775, 0.9)];
    let tb3_plan = write(tb3_dir.path(), "plan.xml", &plan_on(&tb3, "", &between));
    let checked = run(&["check", &text(&tb3_plan)]);
    let said = output_text(&checked);
    assert_eq!(checked.status.code(), Some(1), "{said}");
    assert!(
        number_in(&said, "the robot needs ") > number_in(&said, "the narrowest passage is "),
        "{said}"
    );
    let tb3_plan = write(tb3_dir.path(), "plan.xml", &plan_on(&tb3, small, &between));
    let checked = run(&["check", &text(&tb3_plan)]);
    assert!(checked.status.success(), "{}", output_text(&checked));

    let plan = write(
        dir.path(),
        "plan.xml",
        &plan_on(
            &world,
            small,
            &[("west", 1.0, 2.0), ("wall", 4.05, 0.5), ("out", 9.0, 2.0)],
        ),
    );
    let checked = run(&["check", &text(&plan)]);
    let said = output_text(&checked);
    assert_eq!(checked.status.code(), Some(1), "{said}");
    assert!(!said.contains("is 0 m from"), "{said}");
    assert!(
        said.contains("waypoint `wall`") && (said.contains("is on the") || said.contains("inside")),
        "{said}"
    );
    assert!(
        said.contains("spans 0 to 8.15 m east and 0 to 4 m north"),
        "{said}"
    );
}

/// Item 5: QGC's own test plan in its older item format (`coordinate` apart, four `params`)
/// imports, with a word for each command skipped; a plan whose only item is a survey is
/// refused with the warning that says the survey was skipped.
#[test]
fn qgc_s_older_item_format_imports_and_a_refused_plan_keeps_its_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let file = external("qgc/SectionTest.plan");
    let plan = dir.path().join("section.xml");
    let imported = run(&["import", &text(&file), "-o", &text(&plan)]);
    let said = output_text(&imported);
    assert!(imported.status.success(), "{said}");
    assert!(!said.contains("params[4]"), "{said}");
    let read = Plan::parse(&std::fs::read_to_string(&plan).unwrap()).unwrap();
    // Home, then the three waypoints (16); the take-off (22) and the mount control (205) are
    // skipped, each where it is written.
    assert_eq!(read.waypoints.len(), 4, "{said}");
    assert_eq!(read.legs.len(), 3, "{said}");
    let wp1 = read.waypoint("wp1").unwrap().position;
    assert!((wp1.lat_deg - 47.63369112).abs() < 1e-7 && (wp1.lon_deg + 122.08925023).abs() < 1e-7);
    let warnings = located(&imported, &file);
    let source = std::fs::read_to_string(&file).unwrap();
    for (command, name) in [(22, "NAV_TAKEOFF"), (205, "DO_MOUNT_CONTROL")] {
        let line = armor_tests::check::line_of(&source, &format!("\"command\": {command},"));
        assert!(
            warnings
                .iter()
                .any(|(at, _, message)| *at == line && message.contains(name)),
            "{command} at line {line}: {said}"
        );
    }

    let survey = write(
        dir.path(),
        "survey.plan",
        r#"{
    "fileType": "Plan",
    "geoFence": { "circles": [], "polygons": [], "version": 2 },
    "groundStation": "QGroundControl",
    "mission": {
        "cruiseSpeed": 15,
        "firmwareType": 12,
        "hoverSpeed": 5,
        "items": [
            {
                "TransectStyleComplexItem": { "CameraCalc": { "AdjustedFootprintFrontal": 25 } },
                "angle": 0,
                "complexItemType": "survey",
                "entryLocation": 0,
                "flyAlternateTransects": false,
                "polygon": [[47.633, -122.089], [47.634, -122.089], [47.634, -122.087], [47.633, -122.087]],
                "splitConcavePolygons": false,
                "type": "ComplexItem",
                "version": 5
            }
        ],
        "plannedHomePosition": [47.633, -122.090, 20],
        "vehicleType": 10,
        "version": 2
    },
    "rallyPoints": { "points": [], "version": 2 },
    "version": 1
}
"#,
    );
    let imported = run(&["import", &text(&survey), "-o", &text(&plan)]);
    let said = output_text(&imported);
    assert_eq!(imported.status.code(), Some(1), "{said}");
    assert!(said.contains("warning: a complex item (`survey`"), "{said}");
    assert!(said.contains("what it has was skipped"), "{said}");
}

/// Item 6: a GPS tool writes a route's points as waypoints too, and a round trip back to its
/// start: each point comes back once, the legs run through the points themselves.
#[test]
fn a_gpx_with_the_same_points_as_waypoints_and_route_imports_each_once() {
    let dir = tempfile::tempdir().unwrap();
    let gpx = write(
        dir.path(),
        "patrol.gpx",
        r#"<?xml version="1.0" encoding="UTF-8"?>
<gpx version="1.1" creator="OsmAnd" xmlns="http://www.topografix.com/GPX/1/1">
  <wpt lat="43.561536" lon="1.469049"><name>Home</name><sym>Flag, Blue</sym></wpt>
  <wpt lat="43.561590" lon="1.469250"><name>Gate</name></wpt>
  <wpt lat="43.561700" lon="1.469300"><name>Tower</name></wpt>
  <rte>
    <name>Patrol</name>
    <rtept lat="43.561536" lon="1.469049"><name>Home</name></rtept>
    <rtept lat="43.56159" lon="1.46925"><name>Gate</name></rtept>
    <rtept lat="43.5617" lon="1.4693"><name>Tower</name></rtept>
    <rtept lat="43.561536" lon="1.469049"><name>Home</name></rtept>
  </rte>
</gpx>
"#,
    );
    let plan = dir.path().join("patrol.xml");
    let imported = run(&["import", &text(&gpx), "-o", &text(&plan)]);
    assert!(imported.status.success(), "{}", output_text(&imported));
    let read = Plan::parse(&std::fs::read_to_string(&plan).unwrap()).unwrap();
    let names: Vec<&str> = read.waypoints.iter().map(|w| w.name.as_str()).collect();
    assert_eq!(names, ["Home", "Gate", "Tower"]);
    let legs: Vec<(&str, &str)> = read
        .legs
        .iter()
        .map(|leg| (leg.from.as_str(), leg.to.as_str()))
        .collect();
    assert_eq!(
        legs,
        [("Home", "Gate"), ("Gate", "Tower"), ("Tower", "Home")]
    );
}

/// The `wpt` and `rtept` of a GPX file in order: (element and name, latitude, longitude).
fn gpx_points(file: &Path) -> Vec<(String, f64, f64)> {
    let gpx = std::fs::read_to_string(file).unwrap();
    let attribute = |line: &str, name: &str| -> f64 {
        let at = line.find(&format!("{name}=\"")).unwrap() + name.len() + 2;
        line[at..at + line[at..].find('"').unwrap()]
            .parse()
            .unwrap()
    };
    let lines: Vec<&str> = gpx.lines().map(str::trim).collect();
    lines
        .iter()
        .enumerate()
        .filter(|(_, line)| line.starts_with("<wpt ") || line.starts_with("<rtept "))
        .map(|(index, line)| {
            let tag = line.split_whitespace().next().unwrap();
            (
                format!("{tag} {}", lines[index + 1]),
                attribute(line, "lat"),
                attribute(line, "lon"),
            )
        })
        .collect()
}

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

/// KML both ways on every bundled plan: out and in gives the same waypoints (names and places),
/// the same legs, the same areas (kind, name, corners, margin), lines and units; the plan read
/// back writes the same KML again. (That fastkml reads our KML is `interchange.rs`'s test; a
/// path drawn in Google Earth is `armor_model::plan::kml`'s.)
#[test]
fn every_bundled_plan_goes_through_kml_and_back() {
    let dir = tempfile::tempdir().unwrap();
    for plan_file in bundled_plans() {
        let plan = Plan::parse(&std::fs::read_to_string(&plan_file).unwrap()).unwrap();
        let kml = dir.path().join("out.kml");
        let exported = run(&["export", "--kml", &text(&plan_file), "-o", &text(&kml)]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let back = dir.path().join("back.xml");
        let imported = run(&["import", &text(&kml), "-o", &text(&back)]);
        assert!(imported.status.success(), "{}", output_text(&imported));
        let again = Plan::parse(&std::fs::read_to_string(&back).unwrap()).unwrap();
        let places = |plan: &Plan| -> Vec<(String, String)> {
            plan.waypoints
                .iter()
                .map(|w| {
                    let at = format!("{:.6} {:.6}", w.position.lat_deg, w.position.lon_deg);
                    (w.name.clone(), at)
                })
                .collect()
        };
        assert_eq!(places(&again), places(&plan), "{}", plan_file.display());
        let legs = |plan: &Plan| -> Vec<(String, String)> {
            plan.legs
                .iter()
                .map(|leg| (leg.from.clone(), leg.to.clone()))
                .collect()
        };
        assert_eq!(legs(&again), legs(&plan), "{}", plan_file.display());
        let graphics = |plan: &Plan| -> Vec<String> {
            plan.graphics
                .iter()
                .map(|g| {
                    format!(
                        "{:?} {} {} {:?}",
                        g.kind,
                        g.name,
                        g.points.len(),
                        g.margin_m
                    )
                })
                .collect()
        };
        assert_eq!(graphics(&again), graphics(&plan), "{}", plan_file.display());
        let units = |plan: &Plan| -> Vec<(String, String)> {
            plan.units
                .iter()
                .map(|u| (u.name.clone(), u.sidc.clone()))
                .collect()
        };
        assert_eq!(units(&again), units(&plan), "{}", plan_file.display());
        let kml_again = dir.path().join("again.kml");
        let exported = run(&["export", "--kml", &text(&back), "-o", &text(&kml_again)]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let placemarks = |path: &std::path::Path| {
            std::fs::read_to_string(path)
                .unwrap()
                .matches("<Placemark>")
                .count()
        };
        assert_eq!(
            placemarks(&kml_again),
            placemarks(&kml),
            "{}",
            plan_file.display()
        );
    }
}

/// The round trips, both ways, on every bundled plan: GPX out and in gives the same waypoints
/// (no copies) and the same legs, and that plan out again gives the same GPX; PNML out and in
/// gives a net with the same places, transitions and reachable markings (`armor check`).
#[test]
fn every_bundled_plan_goes_through_gpx_and_pnml_and_back_unchanged() {
    let dir = tempfile::tempdir().unwrap();
    for plan_file in bundled_plans() {
        let plan = Plan::parse(&std::fs::read_to_string(&plan_file).unwrap()).unwrap();
        let gpx = dir.path().join("out.gpx");
        let exported = run(&["export", "--gpx", &text(&plan_file), "-o", &text(&gpx)]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let back = dir.path().join("back.xml");
        let imported = run(&["import", &text(&gpx), "-o", &text(&back)]);
        assert!(imported.status.success(), "{}", output_text(&imported));
        let again = Plan::parse(&std::fs::read_to_string(&back).unwrap()).unwrap();
        let names = |plan: &Plan| -> Vec<String> {
            plan.waypoints.iter().map(|w| w.name.clone()).collect()
        };
        assert_eq!(names(&again), names(&plan), "{}", plan_file.display());
        let legs = |plan: &Plan| -> Vec<(String, String)> {
            plan.legs
                .iter()
                .map(|leg| (leg.from.clone(), leg.to.clone()))
                .collect()
        };
        assert_eq!(legs(&again), legs(&plan), "{}", plan_file.display());
        for (a, b) in plan.waypoints.iter().zip(&again.waypoints) {
            assert!(
                (a.position.lat_deg - b.position.lat_deg).abs() < 1e-7
                    && (a.position.lon_deg - b.position.lon_deg).abs() < 1e-7,
                "{}: {a:?} {b:?}",
                plan_file.display()
            );
        }
        // And the other way: the plan read back writes the same GPX.
        let gpx_again = dir.path().join("again.gpx");
        let exported = run(&["export", "--gpx", &text(&back), "-o", &text(&gpx_again)]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let (first, second) = (gpx_points(&gpx), gpx_points(&gpx_again));
        assert_eq!(first.len(), second.len(), "{}", plan_file.display());
        for (a, b) in first.iter().zip(&second) {
            // The plan file keeps 7 decimals (1 cm): the second GPX has the plan's precision.
            assert!(
                a.0 == b.0 && (a.1 - b.1).abs() < 1e-7 && (a.2 - b.2).abs() < 1e-7,
                "{}: {a:?} {b:?}",
                plan_file.display()
            );
        }

        let pnml = dir.path().join("out.pnml");
        let exported = run(&["export", "--pnml", &text(&plan_file), "-o", &text(&pnml)]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let mission = dir.path().join("mission.xml");
        let system = plan_file.parent().unwrap().join(&plan.system);
        let imported = run(&[
            "import",
            &text(&pnml),
            "-o",
            &text(&mission),
            "--system",
            &text(&system),
        ]);
        assert!(imported.status.success(), "{}", output_text(&imported));
        let reachable = |file: &Path| {
            let checked = run(&["check", &text(file)]);
            let said = output_text(&checked);
            assert!(checked.status.success(), "{}: {said}", file.display());
            let summary = said
                .lines()
                .find(|line| line.contains(": ok (mission"))
                .unwrap()
                .to_owned();
            // The counts, after the net's name.
            summary[summary.find("`:").unwrap()..].to_owned()
        };
        assert_eq!(
            reachable(&mission),
            reachable(&plan_file),
            "{}",
            plan_file.display()
        );
        // And back out: the imported mission writes the same PNML.
        let pnml_again = dir.path().join("again.pnml");
        let exported = run(&[
            "export",
            "--pnml",
            &text(&mission),
            "-o",
            &text(&pnml_again),
        ]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let net = |file: &Path| {
            let net = armor_model::net::read_pnml(&std::fs::read_to_string(file).unwrap())
                .unwrap()
                .0;
            let places: Vec<(String, u32, bool)> = net
                .places
                .iter()
                .map(|place| (place.name.clone(), place.tokens, place.is_final))
                .collect();
            let transitions: Vec<String> = net
                .transitions
                .iter()
                .map(|transition| transition.name.clone())
                .collect();
            (places, transitions)
        };
        assert_eq!(net(&pnml_again), net(&pnml), "{}", plan_file.display());
    }
}

/// Item 7: a leg blocked under the default contingency (`hold`) in a run nobody attends: the
/// run says what it waits for (the operator, and the transitions that would take it on), and
/// ends after `--hold-timeout` with the outcome `unattended`; with an operator, the default
/// (300 s) is said, and firing the skip finishes the mission.
#[test]
fn a_headless_run_held_on_a_blocked_leg_says_what_it_waits_for_and_ends() {
    let dir = tempfile::tempdir().unwrap();
    let world = |name: &str, extra: &str| {
        write(
            dir.path(),
            name,
            &format!(
                "name Hall\norigin 43.56150 1.46900\nstart 2 5 0\nboundary 0,0 20,0 20,10 0,10 0,0\n{extra}"
            ),
        )
    };
    // The plan is drawn on the open hall; the robot drives in the same hall walled across.
    let open = world("open.world", "");
    let walled = world("walled.world", "wall 10,0 10,10\n");
    write(
        dir.path(),
        "system.xml",
        &format!(
            r#"<system name="hall">
  <module name="sim" type="sim"><param name="world" value="{walled}"/></module>
  <module name="follower" type="follower">
    <param name="world" value="{walled}"/>
    <param name="goal_x_m" value="2"/>
    <param name="goal_y_m" value="5"/>
    <param name="blocked_after_secs" value="20"/>
  </module>
  <link from="sim.odometry" to="follower.odometry"/>
  <link from="sim.scan" to="follower.scan"/>
  <link from="follower.cmd_desired" to="sim.cmd_vel"/>
</system>
"#,
            walled = walled.display()
        ),
    );
    let open_world = load_world(&open);
    let plan = write(
        dir.path(),
        "plan.xml",
        &plan_on(&open_world, "", &[("west", 2.0, 5.0), ("east", 18.0, 5.0)]).replace(
            "system=\"system.xml\"",
            "system=\"system.xml\" world=\"open.world\"",
        ),
    );
    let checked = run(&["check", &text(&plan)]);
    assert!(checked.status.success(), "{}", output_text(&checked));

    let report = dir.path().join("report.json");
    let mut unattended = armor_run(&plan, &report, &["--hold-timeout", "2", "--no-run-folder"]);
    let status = unattended.wait_exit(armor_tests::mission::MISSION_DEADLINE);
    let lines = unattended.lines().join("\n");
    assert!(!status.success(), "{lines}");
    assert!(
        lines.contains("waits for the operator in {leg1_hold}")
            && lines.contains("`armor ctl fire leg1_retry`")
            && lines.contains("`armor ctl fire leg1_skip`")
            && lines.contains("the run ends in 2 s (--hold-timeout)"),
        "{lines}"
    );
    assert!(lines.contains("nobody answered"), "{lines}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["outcome"], "unattended", "{report:#}");

    // Attended: the default is said, and the operator's skip ends the mission.
    let report = dir.path().join("attended.json");
    let mut attended = armor_run(&plan, &report, &["--no-run-folder"]);
    let addr = armor_tests::control_address(&attended);
    attended.wait_for(
        "the wait for the operator",
        armor_tests::mission::MISSION_DEADLINE,
        |line| line.contains("waits for the operator") && line.contains("ends in 300 s"),
    );
    let (ok, said) = ctl(&addr, &["fire", "leg1_skip"]);
    assert!(ok, "{said}");
    let status = attended.wait_exit(armor_tests::mission::MISSION_DEADLINE);
    assert!(status.success(), "{}", attended.lines().join("\n"));
}

/// Item 8: a plan whose waypoints lie thousands of kilometres apart checks with a word on the
/// flat frame's limits, and the figures.
#[test]
fn a_plan_over_thousands_of_kilometres_is_warned_about_the_local_frame() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "system.xml",
        r#"<system name="rover">
  <module name="follower" type="follower">
    <param name="goal_x_m" value="0"/>
    <param name="goal_y_m" value="0"/>
  </module>
</system>
"#,
    );
    // Toulouse to Reykjavik and on to Montreal, from an origin in Toulouse.
    let plan = write(
        dir.path(),
        "plan.xml",
        r#"<plan name="far" system="system.xml">
  <origin lat="43.6045" lon="1.444"/>
  <waypoint name="toulouse" lat="43.6045" lon="1.444"/>
  <waypoint name="reykjavik" lat="64.1466" lon="-21.9426"/>
  <waypoint name="montreal" lat="45.5019" lon="-73.5674"/>
  <leg from="toulouse" to="reykjavik"/>
  <leg from="reykjavik" to="montreal"/>
</plan>
"#,
    );
    let checked = run(&["check", &text(&plan)]);
    let said = output_text(&checked);
    assert!(checked.status.success(), "{said}");
    let warning = located(&checked, &plan)
        .into_iter()
        .find(|(_, _, message)| message.contains("flat (local) projection"))
        .unwrap_or_else(|| panic!("no word on the frame:\n{said}"));
    assert_eq!(warning.0, 5, "at Montreal, the furthest off: {said}");
    assert!(warning.2.contains("km from the origin"), "{said}");

    // A plan of a few hundred metres: not a word.
    let near = std::fs::read_to_string(&plan)
        .unwrap()
        .replace("64.1466\" lon=\"-21.9426", "43.6055\" lon=\"1.445")
        .replace("45.5019\" lon=\"-73.5674", "43.6065\" lon=\"1.446");
    std::fs::write(&plan, near).unwrap();
    let checked = run(&["check", &text(&plan)]);
    let said = output_text(&checked);
    assert!(checked.status.success(), "{said}");
    assert!(!said.contains("projection"), "{said}");
}

/// The QGC round trip the other way, on every bundled plan: the plan read back from its .plan
/// writes the same mission items, fence and rally points again (the plan to .plan to plan way
/// is `interchange.rs`'s).
#[test]
fn every_bundled_plan_s_qgc_file_comes_back_the_same_through_a_plan() {
    let dir = tempfile::tempdir().unwrap();
    for plan_file in bundled_plans() {
        let first = dir.path().join("first.plan");
        let exported = run(&["export", "--qgc", &text(&plan_file), "-o", &text(&first)]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let back = dir.path().join("back.xml");
        let imported = run(&[
            "import",
            &text(&first),
            "-o",
            &text(&back),
            "--start",
            "2026-11-23T00:00:00Z",
        ]);
        assert!(imported.status.success(), "{}", output_text(&imported));
        let second = dir.path().join("second.plan");
        let exported = run(&["export", "--qgc", &text(&back), "-o", &text(&second)]);
        assert!(exported.status.success(), "{}", output_text(&exported));
        let read = |file: &Path| -> serde_json::Value {
            serde_json::from_str(&std::fs::read_to_string(file).unwrap()).unwrap()
        };
        let (a, b) = (read(&first), read(&second));
        let points = |items: &serde_json::Value| -> Vec<(u64, Vec<f64>)> {
            items
                .as_array()
                .unwrap()
                .iter()
                .map(|item| {
                    (
                        item["command"].as_u64().unwrap(),
                        item["params"]
                            .as_array()
                            .unwrap()
                            .iter()
                            .map(|value| value.as_f64().unwrap_or(f64::NAN))
                            .collect(),
                    )
                })
                .collect()
        };
        let (items_a, items_b) = (
            points(&a["mission"]["items"]),
            points(&b["mission"]["items"]),
        );
        assert_eq!(items_a.len(), items_b.len(), "{}", plan_file.display());
        for ((command_a, params_a), (command_b, params_b)) in items_a.iter().zip(&items_b) {
            assert_eq!(command_a, command_b, "{}", plan_file.display());
            for (x, y) in params_a.iter().zip(params_b) {
                // Coordinates through the plan file's 7 decimals.
                assert!(
                    (x.is_nan() && y.is_nan()) || (x - y).abs() < 1e-7,
                    "{}: {params_a:?} {params_b:?}",
                    plan_file.display()
                );
            }
        }
        assert_eq!(
            a["geoFence"]["polygons"].as_array().map(Vec::len),
            b["geoFence"]["polygons"].as_array().map(Vec::len),
            "{}",
            plan_file.display()
        );
        // Rally points (the waypoints a `return` goes to) come back as waypoints only, as
        // docs/interchange.md says: no contingency uses them, so the second file has none.
        let plan = Plan::parse(&std::fs::read_to_string(&back).unwrap()).unwrap();
        for rally in a["rallyPoints"]["points"].as_array().unwrap() {
            let (lat, lon) = (rally[0].as_f64().unwrap(), rally[1].as_f64().unwrap());
            assert!(
                plan.waypoints
                    .iter()
                    .any(|w| (w.position.lat_deg - lat).abs() < 1e-7
                        && (w.position.lon_deg - lon).abs() < 1e-7),
                "{}: rally point {rally} lost",
                plan_file.display()
            );
        }
    }
}
