use super::*;
use crate::net::analyse;
use crate::planner::Robot;

/// A 40 m × 30 m world with a block in the middle, anchored at (43.5615, 1.469).
const WORLD: &str = "name Test yard
origin 43.5615 1.469
start 4 4 0
boundary 0,0 40,0 40,30 0,30 0,0
rect 18,8 22,12
";

fn world() -> World {
    World::parse(WORLD, "test.world").unwrap_or_else(|err| panic!("{err}"))
}

fn origin() -> LatLon {
    LatLon::new(43.5615, 1.469)
}

/// `<waypoint>` at world point (x, y).
fn waypoint(name: &str, x: f64, y: f64) -> String {
    let at = LatLon::from_local(Point::new(x, y), origin());
    format!(
        "<waypoint name=\"{name}\" lat=\"{:.8}\" lon=\"{:.8}\"/>",
        at.lat_deg, at.lon_deg
    )
}

fn plan(body: &str) -> Plan {
    let text = format!(
        "<plan name=\"p\" system=\"system.xml\" start=\"2026-11-23T08:00:00Z\">\n\
         <navigation><module name=\"avoider\"/></navigation>\n{}\n{body}\n</plan>",
        [
            waypoint("home", 4.0, 4.0),
            waypoint("gate", 34.0, 4.0),
            waypoint("hill", 34.0, 24.0)
        ]
        .join("\n")
    );
    Plan::parse(&text).unwrap_or_else(|problems| panic!("{problems:?}"))
}

fn compiled(body: &str) -> Compiled {
    compile(&plan(body), Some(&world())).unwrap_or_else(|problems| panic!("{problems:?}"))
}

fn errors(body: &str) -> Vec<String> {
    match compile(&plan(body), Some(&world())) {
        Ok(_) => Vec::new(),
        Err(problems) => problems.iter().map(|p| p.message.clone()).collect(),
    }
}

/// `name: input -> output [condition]`, one line per transition, and the places with their
/// modules and tokens: a readable picture of a net to compare.
fn picture(net: &MissionNet) -> String {
    let mut lines = Vec::new();
    for place in &net.places {
        let mut line = format!("place {}", place.name);
        if place.tokens > 0 {
            line.push_str(" (1)");
        }
        if place.is_final {
            line.push_str(" final");
        }
        if !place.modules.is_empty() {
            line.push_str(&format!(" [{}]", place.modules.join(" ")));
        }
        lines.push(line);
    }
    for t in &net.transitions {
        let c = &t.condition;
        let mut why = Vec::new();
        if let Some(event) = &c.event {
            why.push(event.clone());
        }
        if let Some(delay) = c.delay_secs {
            why.push(format!("{delay} s"));
        }
        if let Some(at) = c.at_unix_secs {
            why.push(format_date(at));
        }
        if c.operator {
            why.push("operator".into());
        }
        lines.push(format!(
            "{}: {} -> {} {}",
            t.name,
            t.inputs[0].place,
            t.outputs[0].place,
            why.join(", ")
        ));
    }
    lines.join("\n")
}

#[test]
fn a_plan_with_every_kind_of_step_becomes_a_sound_net() {
    let compiled = compiled(
        r#"<leg from="home" to="gate" arrive_by="2026-11-23T08:10:00Z" wait_secs="5">
  <during><module name="recorder"/></during>
  <arrival until="observer.observation_done" for_secs="60">
    <module name="observer"><param name="sector_deg" value="180"/></module>
  </arrival>
</leg>
<leg from="gate" to="hill" not_before="2026-11-23T08:20:00Z">
  <contingency on="blocked" do="return" waypoint="home"/>
</leg>
<contingency on="failed" module="mapper" do="skip"/>"#,
    );
    assert_eq!(
        picture(&compiled.net),
        "place leg1_drive (1) [follower avoider recorder]
place leg1_hold
place leg1_drive_late [follower avoider recorder]
place leg1_arrival [observer]
place leg1_wait
place leg2_depart
place leg2_drive [follower avoider]
place leg2_return [follower avoider]
place returned_home final
place leg2_return_hold
place done final
leg1_arrived: leg1_drive -> leg1_arrival follower.goal_reached
leg1_retry: leg1_hold -> leg1_drive operator
leg1_skip: leg1_hold -> leg2_depart operator
leg1_blocked: leg1_drive -> leg1_hold follower.blocked
leg1_arrived_late: leg1_drive_late -> leg1_arrival follower.goal_reached
leg1_blocked_late: leg1_drive_late -> leg1_hold follower.blocked
leg1_late: leg1_drive -> leg1_drive_late 2026-11-23T08:10:00Z
leg1_arrival_done: leg1_arrival -> leg1_wait observer.observation_done
leg1_arrival_timeout: leg1_arrival -> leg1_wait 60 s
leg1_waited: leg1_wait -> leg2_depart 5 s
leg1_drive_mapper_failed: leg1_drive -> leg2_depart module.mapper.failed
leg1_drive_late_mapper_failed: leg1_drive_late -> leg2_depart module.mapper.failed
leg1_arrival_mapper_failed: leg1_arrival -> leg2_depart module.mapper.failed
leg1_wait_mapper_failed: leg1_wait -> leg2_depart module.mapper.failed
leg2_appointment: leg2_depart -> leg2_drive 2026-11-23T08:20:00Z
leg2_arrived: leg2_drive -> done follower.goal_reached
leg2_returned: leg2_return -> returned_home follower.goal_reached
leg2_return_blocked: leg2_return -> leg2_return_hold follower.blocked
leg2_return_retry: leg2_return_hold -> leg2_return operator
leg2_blocked: leg2_drive -> leg2_return follower.blocked
leg2_depart_mapper_failed: leg2_depart -> done module.mapper.failed
leg2_drive_mapper_failed: leg2_drive -> done module.mapper.failed"
    );
    // Goals are the destinations in the world frame, to the millimetre, and the path is the
    // planned one (straight here: nothing is in the way).
    let drive = compiled.net.place("leg1_drive").expect("drive");
    let goal: Vec<(&str, &str)> = drive
        .params
        .iter()
        .map(|p| (p.name.as_str(), p.value.as_str()))
        .collect();
    assert_eq!(
        goal,
        [("goal_x_m", "34"), ("goal_y_m", "4"), ("path", "4,4 34,4")]
    );
    // A return drive has no path: where the robot turns back is not known.
    let back = compiled.net.place("leg2_return").expect("return");
    assert!(back.params.iter().all(|p| p.name != "path"), "{back:?}");
    let observer = &compiled.net.place("leg1_arrival").expect("arrival").params[0];
    assert_eq!(
        (observer.name.as_str(), observer.value.as_str()),
        ("sector_deg", "180")
    );
    // The net reads back, has no deadlock, no dead transition and stays bounded.
    let again = MissionNet::parse(&compiled.net.to_xml()).expect("reads back");
    assert_eq!(again.without_positions(), compiled.net.without_positions());
    let analysis = analyse(&compiled.net, 100_000);
    assert_eq!(analysis.problems(&compiled.net), []);
    // Every element traces back to its leg, the ends to the plan and the return waypoint.
    assert_eq!(compiled.trace["leg1_arrival_timeout"], Origin::Leg(0));
    assert_eq!(compiled.trace["leg2_return_retry"], Origin::Leg(1));
    assert_eq!(
        compiled.trace["returned_home"],
        Origin::Waypoint("home".into())
    );
    assert_eq!(compiled.trace["done"], Origin::Plan);
    assert_eq!(
        compiled.trace.len(),
        compiled.net.places.len() + compiled.net.transitions.len()
    );
}

#[test]
fn compiling_is_deterministic() {
    let body = r#"<leg from="home" to="gate" wait_secs="3"/><leg from="gate" to="hill"/>"#;
    assert_eq!(compiled(body).net.to_xml(), compiled(body).net.to_xml());
}

#[test]
fn legs_go_around_no_go_areas_and_the_navigation_learns_them() {
    // A no-go strip across the straight line from home to gate.
    let corners = [(12.0, 1.0), (14.0, 1.0), (14.0, 7.0), (12.0, 7.0)]
        .map(|(x, y)| {
            let at = LatLon::from_local(Point::new(x, y), origin());
            format!(
                "<point lat=\"{:.8}\" lon=\"{:.8}\"/>",
                at.lat_deg, at.lon_deg
            )
        })
        .join("");
    let compiled = compiled(&format!(
        "<leg from=\"home\" to=\"gate\"/><area name=\"mines\" kind=\"no-go\">{corners}</area>"
    ));
    let route = &compiled.routes[0];
    assert!(route.len() > 2, "{route:?}");
    let area = Polygon::new(vec![
        Point::new(12.0, 1.0),
        Point::new(14.0, 1.0),
        Point::new(14.0, 7.0),
        Point::new(12.0, 7.0),
    ]);
    for pair in route.windows(2) {
        assert!(
            !area.blocks(pair[0], pair[1], CLEARANCE_M * 0.99),
            "{route:?}"
        );
    }
    let drive = compiled.net.place("leg1_drive").expect("drive");
    let no_go = drive
        .params
        .iter()
        .find(|p| p.name == "no_go")
        .expect("no_go");
    let polygons = geo::parse_polygons(&no_go.value).expect("polygons");
    assert_eq!(polygons.len(), 1);
    for (got, want) in polygons[0].corners.iter().zip(&area.corners) {
        assert!((got.x - want.x).abs() < 0.01 && (got.y - want.y).abs() < 0.01);
    }
    // The default margin is not passed on; another one is, so that the follower's replans
    // keep what the plan was checked with.
    assert!(!drive.params.iter().any(|p| p.name == "no_go_margins_m"));
    let two = format!(
        "<leg from=\"home\" to=\"gate\"/><area name=\"mines\" kind=\"no-go\">{corners}</area>\
         <area name=\"pit\" kind=\"no-go\" margin_m=\"1.5\">{}</area>",
        [(30.0, 20.0), (32.0, 20.0), (32.0, 22.0)]
            .map(|(x, y)| {
                let at = LatLon::from_local(Point::new(x, y), origin());
                format!(
                    "<point lat=\"{:.8}\" lon=\"{:.8}\"/>",
                    at.lat_deg, at.lon_deg
                )
            })
            .join("")
    );
    let compiled = self::compiled(&two);
    let drive = compiled.net.place("leg1_drive").expect("drive");
    let margins = drive
        .params
        .iter()
        .find(|p| p.name == "no_go_margins_m")
        .expect("no_go_margins_m");
    assert_eq!(margins.value, "0.75;1.5");
}

#[test]
fn the_navigation_learns_the_robot_the_paths_were_planned_for_unless_it_is_the_default() {
    let has = |compiled: &Compiled, name: &str| {
        compiled
            .net
            .place("leg1_drive")
            .expect("drive")
            .params
            .iter()
            .find(|p| p.name == name)
            .map(|p| p.value.clone())
    };
    let plain = compiled(r#"<leg from="home" to="gate"/>"#);
    assert_eq!(has(&plain, "robot_radius_m"), None);
    assert_eq!(has(&plain, "clearance_m"), None);
    let robot = Robot {
        radius_m: 0.45,
        clearance_m: 0.2,
    };
    let loaded = compile_for(
        &plan(r#"<leg from="home" to="gate"/>"#),
        Some(&world()),
        &robot,
    )
    .unwrap_or_else(|problems| panic!("{problems:?}"));
    assert_eq!(has(&loaded, "robot_radius_m").as_deref(), Some("0.45"));
    assert_eq!(has(&loaded, "clearance_m").as_deref(), Some("0.2"));
}

#[test]
fn places_the_robot_cannot_reach_are_refused() {
    let text = format!(
        "<plan name=\"p\" system=\"s.xml\">{}{}{}<leg from=\"a\" to=\"b\"/><leg from=\"b\" to=\"c\"/></plan>",
        waypoint("a", -5.0, 4.0),
        waypoint("b", 20.0, 10.0),
        waypoint("c", 30.0, 20.0),
    );
    let plan = Plan::parse(&text).expect("reads");
    let found: Vec<String> = compile(&plan, Some(&world()))
        .expect_err("refused")
        .iter()
        .map(|p| p.message.clone())
        .collect();
    assert_eq!(
        found,
        [
            "waypoint `a` is outside the world `Test yard`: it is at (-5, 4) m, the world spans 0 to 40 m east and 0 to 30 m north",
            "waypoint `b` at (20, 10) m is inside the obstacle on line 5 of the world `Test yard`",
        ]
    );
}

#[test]
fn areas_that_cross_themselves_or_close_the_way_are_refused() {
    let at = |x: f64, y: f64| {
        let p = LatLon::from_local(Point::new(x, y), origin());
        format!("<point lat=\"{:.8}\" lon=\"{:.8}\"/>", p.lat_deg, p.lon_deg)
    };
    let bow_tie = format!(
        "{}{}{}{}",
        at(2.0, 20.0),
        at(6.0, 24.0),
        at(6.0, 20.0),
        at(2.0, 24.0)
    );
    // A box around the gate.
    let fence = format!(
        "{}{}{}{}",
        at(30.0, 1.0),
        at(38.0, 1.0),
        at(38.0, 2.0),
        at(30.0, 2.0)
    );
    let wall_w = format!(
        "{}{}{}{}",
        at(30.0, 1.0),
        at(31.0, 1.0),
        at(31.0, 8.0),
        at(30.0, 8.0)
    );
    let wall_e = format!(
        "{}{}{}{}",
        at(37.0, 1.0),
        at(38.0, 1.0),
        at(38.0, 8.0),
        at(37.0, 8.0)
    );
    let wall_n = format!(
        "{}{}{}{}",
        at(30.0, 7.0),
        at(38.0, 7.0),
        at(38.0, 8.0),
        at(30.0, 8.0)
    );
    let found = errors(&format!(
        "<leg from=\"home\" to=\"gate\"/>\
         <area name=\"knot\" kind=\"no-go\">{bow_tie}</area>\
         <area name=\"s\" kind=\"no-go\">{fence}</area>\
         <area name=\"w\" kind=\"no-go\">{wall_w}</area>\
         <area name=\"e\" kind=\"no-go\">{wall_e}</area>\
         <area name=\"n\" kind=\"no-go\">{wall_n}</area>"
    ));
    assert_eq!(
        found,
        [
            "leg `leg1`: no way from `home` to `gate` keeps 0.35 m from obstacles and 1 m from the no-go areas; the way is closed at (30.53, 7.48), by the no-go area `w`",
            "area `knot`: its outline crosses itself, so it has no clear inside",
        ]
    );
    let found = errors(&format!(
        "<leg from=\"home\" to=\"gate\"/><area name=\"on_gate\" kind=\"no-go\">{}{}{}</area>",
        at(33.0, 3.0),
        at(36.0, 3.0),
        at(34.0, 6.0)
    ));
    assert_eq!(
        found,
        ["waypoint `gate` at (34, 4) m is in the no-go area `on_gate`"]
    );
}

#[test]
fn time_constraints_that_cannot_be_met_are_warned_with_the_numbers() {
    // home → gate is 30 m, 60 s at 0.5 m/s, then 20 s of waiting; gate → hill 20 m, 40 s.
    let tight = compiled(
        r#"<leg from="home" to="gate" arrive_by="2026-11-23T08:00:50Z" wait_secs="20"/>
<leg from="gate" to="hill" not_before="2026-11-23T08:01:00Z" arrive_by="2026-11-23T08:01:50Z"/>"#,
    );
    let warnings: Vec<&str> = tight.warnings.iter().map(|w| w.message.as_str()).collect();
    assert_eq!(
        warnings,
        [
            "leg `leg1`: the deadline to reach `gate` at 2026-11-23T08:00:50Z is 10 s before the earliest possible arrival (2026-11-23T08:01:00Z: 30 m at 0.5 m/s from 2026-11-23T08:00:00Z)",
            "leg `leg2`: the appointment to leave `gate` at 2026-11-23T08:01:00Z is 20 s before the earliest possible arrival there (2026-11-23T08:01:20Z: 30 m at 0.5 m/s and 20 s of waiting from 2026-11-23T08:00:00Z)",
            "leg `leg2`: the deadline to reach `hill` at 2026-11-23T08:01:50Z is 10 s before the earliest possible arrival (2026-11-23T08:02:00Z: 50 m at 0.5 m/s and 20 s of waiting from 2026-11-23T08:00:00Z)",
        ]
    );
    // Met constraints say nothing.
    let loose = compiled(
        r#"<leg from="home" to="gate" arrive_by="2026-11-23T08:02:00Z"/>
<leg from="gate" to="hill" not_before="2026-11-23T08:05:00Z" arrive_by="2026-11-23T08:06:00Z"/>"#,
    );
    assert!(loose.warnings.is_empty(), "{:?}", loose.warnings);
}

#[test]
fn without_a_world_the_origin_places_the_plan() {
    let text = format!(
        "<plan name=\"p\" system=\"s.xml\"><origin lat=\"43.5615\" lon=\"1.469\"/>{}{}<leg from=\"a\" to=\"b\"/></plan>",
        waypoint("a", 0.0, 0.0),
        waypoint("b", -100.0, 250.0),
    );
    let plan = Plan::parse(&text).expect("reads");
    let compiled = compile(&plan, None).expect("compiles");
    let b = compiled.positions["b"];
    assert!(
        (b.x + 100.0).abs() < 0.01 && (b.y - 250.0).abs() < 0.01,
        "{b:?}"
    );
    let no_origin = text.replace("<origin lat=\"43.5615\" lon=\"1.469\"/>", "");
    let plan = Plan::parse(&no_origin).expect("reads");
    assert!(compile(&plan, None).is_err());
    // An origin far from the world's is refused.
    let moved = text.replace(
        "lat=\"43.5615\" lon=\"1.469\"",
        "lat=\"43.5625\" lon=\"1.469\"",
    );
    let plan = Plan::parse(&moved).expect("reads");
    let problems = compile(&plan, Some(&world())).expect_err("refused");
    assert!(
        problems[0].message.contains("111.2 m from the origin"),
        "{problems:?}"
    );
}

#[test]
fn legs_are_planned_round_the_world_s_obstacles_and_their_length_counts() {
    // From west of the block to east of it at its height: round it, longer than 20 m.
    let text = format!(
        "<plan name=\"p\" system=\"s.xml\" start=\"2026-11-23T08:00:00Z\">{}{}\
         <leg from=\"w\" to=\"e\" arrive_by=\"2026-11-23T08:00:30Z\"/></plan>",
        waypoint("w", 10.0, 10.0),
        waypoint("e", 30.0, 10.0),
    );
    let plan = Plan::parse(&text).expect("reads");
    let compiled = compile(&plan, Some(&world())).unwrap_or_else(|p| panic!("{p:?}"));
    let route = &compiled.routes[0];
    let length = geo::path_length(route);
    assert!(
        route.len() > 2 && length > 20.5 && length < 24.0,
        "{route:?}"
    );
    let world = world();
    for pair in route.windows(2) {
        assert!(
            world.segment_clearance(pair[0], pair[1], 0.35) >= 0.35 - 1e-9,
            "{route:?}"
        );
    }
    // The deadline is checked along the path, not the straight line.
    let metres = geo::round_mm((length * 10.0).round() / 10.0);
    assert!(
        compiled.warnings[0]
            .message
            .contains(&format!("{metres} m at 0.5 m/s")),
        "{:?}",
        compiled.warnings
    );
    // The follower is given the path.
    let drive = compiled.net.place("leg1_drive").expect("drive");
    let path = drive
        .params
        .iter()
        .find(|p| p.name == "path")
        .expect("path");
    assert_eq!(
        crate::planner::Path::parse(&path.value)
            .expect("a path")
            .points
            .len(),
        route.len()
    );
}

/// A world with a wall across it at x = 20, and a doorway 1 m wide at y 14 to 15.
const WALLED: &str = "name Walled yard
origin 43.5615 1.469
start 4 4 0
boundary 0,0 40,0 40,30 0,30 0,0
wall 20,0 20,14
wall 20,15 20,30
rect 30,20 36,26
wall 29,19 37,19 37,27 29,27 29,19
";

fn walled_errors(navigation: &str, legs: &str, more: &str) -> Vec<String> {
    let world = World::parse(WALLED, "walled.world").expect("world");
    let text = format!(
        "<plan name=\"p\" system=\"s.xml\">{navigation}{}{}{more}{legs}</plan>",
        waypoint("west", 10.0, 14.5),
        waypoint("east", 30.0, 14.5),
    );
    let plan = Plan::parse(&text).unwrap_or_else(|p| panic!("{p:?}"));
    match compile(&plan, Some(&world)) {
        Ok(_) => Vec::new(),
        Err(problems) => problems.iter().map(|p| p.message.clone()).collect(),
    }
}

#[test]
fn a_leg_with_no_way_through_says_where_it_is_cut() {
    let leg = "<leg name=\"through\" from=\"west\" to=\"east\"/>";
    // A 1 m doorway lets a robot of 0.25 m + 0.1 m through...
    assert_eq!(walled_errors("", leg, ""), Vec::<String>::new());
    // ...but not one of 0.4 m + 0.2 m.
    assert_eq!(
        walled_errors(
            "<navigation robot_radius_m=\"0.4\" clearance_m=\"0.2\"/>",
            leg,
            ""
        ),
        [
            "leg `through`: no way from `west` to `east` keeps 0.6 m from obstacles; the narrowest passage is 1 m wide at (20, 14.5); the robot needs 1.28 m there"
        ]
    );
    // A waypoint that the robot cannot get to: the ring of walls round the block is closed.
    let inside = World::parse(WALLED, "walled.world").expect("world");
    assert!(inside.is_free(Point::new(30.0, 19.5)));
    let text_leg = "<leg name=\"in\" from=\"east\" to=\"inner\"/>";
    let found = walled_errors("", text_leg, &waypoint("inner", 29.5, 23.0));
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(
        found[0].starts_with(
            "leg `in`: no way from `east` to `inner` keeps 0.35 m from obstacles; the way is closed at ("
        ),
        "{found:?}"
    );
    // Too near a wall, and the start of a leg in an area.
    let found = walled_errors(
        "",
        "<leg from=\"near\" to=\"west\"/><leg from=\"west\" to=\"east\"/>",
        &format!(
            "{}<area name=\"pond\" kind=\"no-go\" margin_m=\"0.5\">{}{}{}</area>",
            waypoint("near", 10.0, 0.2),
            point(9.0, 13.0),
            point(11.0, 13.0),
            point(10.0, 16.0)
        ),
    );
    assert_eq!(
        found,
        [
            "waypoint `west` at (10, 14.5) m is in the no-go area `pond`",
            "waypoint `near` at (10, 0.2) m is 0.2 m from the boundary on line 4 of the world `Walled yard`; the robot keeps 0.35 m from obstacles (radius 0.25 m and clearance 0.1 m)",
        ]
    );
}

fn point(x: f64, y: f64) -> String {
    let at = LatLon::from_local(Point::new(x, y), origin());
    format!(
        "<point lat=\"{:.8}\" lon=\"{:.8}\"/>",
        at.lat_deg, at.lon_deg
    )
}

#[test]
fn the_robot_comes_from_the_plan_then_the_system() {
    use armor_module_api::{ModuleSpec, ParamSpec, ParamType};
    let plan_with = |navigation: &str| {
        Plan::parse(&format!(
            "<plan name=\"p\" system=\"s.xml\"><origin lat=\"1\" lon=\"2\"/>{navigation}\
             <waypoint name=\"a\" lat=\"1\" lon=\"2\"/><waypoint name=\"b\" lat=\"1\" lon=\"2.001\"/>\
             <leg from=\"a\" to=\"b\"/></plan>"
        ))
        .expect("reads")
    };
    let system = crate::SystemConfig::parse(
        r#"<system name="s">
  <module name="sim" type="sim"><param name="robot_radius_m" value="0.3"/></module>
  <module name="avoider" type="avoider"/>
  <module name="follower" type="follower"/>
</system>"#,
    )
    .expect("parses");
    let describe = |module_type: &str, radius: &str| {
        let spec = ModuleSpec::new(module_type, "test").param(
            ParamSpec::new("robot_radius_m", ParamType::Float, "radius")
                .unit("m")
                .default(radius),
        );
        (module_type.to_owned(), spec.description().clone())
    };
    let descriptions: BTreeMap<_, _> =
        [describe("sim", "0.25"), describe("avoider", "0.35")].into();
    let cases = [
        // (navigation, with the system, radius, clearance)
        ("", false, 0.25, 0.1),
        ("", true, 0.35, 0.1),
        ("<navigation clearance_m=\"0.3\"/>", true, 0.35, 0.3),
        ("<navigation robot_radius_m=\"0.5\"/>", true, 0.5, 0.1),
    ];
    for (navigation, with_system, radius_m, clearance_m) in cases {
        let plan = plan_with(navigation);
        let found = if with_system {
            robot(&plan, Some(&system), &descriptions)
        } else {
            robot(&plan, None, &BTreeMap::new())
        };
        assert_eq!(
            found,
            Robot {
                radius_m,
                clearance_m
            },
            "{navigation} {with_system}"
        );
    }
    // The system's own value beats the module's default: the sim says 0.3 over its 0.25.
    let only_sim: BTreeMap<_, _> = [describe("sim", "0.25")].into();
    assert_eq!(
        robot(&plan_with(""), Some(&system), &only_sim).radius_m,
        0.3
    );
}

#[test]
fn without_a_world_legs_go_round_the_areas_only() {
    let text = format!(
        "<plan name=\"p\" system=\"s.xml\"><origin lat=\"43.5615\" lon=\"1.469\"/>{}{}\
         <leg from=\"a\" to=\"b\"/><area name=\"lake\" kind=\"no-go\">{}{}{}{}</area></plan>",
        waypoint("a", 0.0, 0.0),
        waypoint("b", 100.0, 0.0),
        point(40.0, -10.0),
        point(60.0, -10.0),
        point(60.0, 10.0),
        point(40.0, 10.0),
    );
    let plan = Plan::parse(&text).expect("reads");
    let compiled = compile(&plan, None).unwrap_or_else(|p| panic!("{p:?}"));
    let route = &compiled.routes[0];
    assert!(route.len() > 2, "{route:?}");
    let lake = Polygon::new(vec![
        Point::new(40.0, -10.0),
        Point::new(60.0, -10.0),
        Point::new(60.0, 10.0),
        Point::new(40.0, 10.0),
    ]);
    for pair in route.windows(2) {
        assert!(!lake.blocks(pair[0], pair[1], 0.99), "{route:?}");
    }
}

#[test]
fn alternatives_are_branches_taken_on_failures_then_the_contingency() {
    let compiled = compiled(
        r#"<leg from="home" to="gate" arrive_by="2026-11-23T08:10:00Z">
  <during>
    <module name="mapper"><param name="resolution_m" value="0.05"/></module>
    <module name="recorder"/>
    <alternative name="odometry"><module name="recorder"/></alternative>
    <alternative on="recorder"/>
  </during>
  <arrival for_secs="30">
    <module name="observer"/>
    <alternative on="camera"><module name="observer"/></alternative>
  </arrival>
  <contingency on="failed" module="recorder" do="hold"/>
</leg>"#,
    );
    assert_eq!(
        picture(&compiled.net),
        "place leg1_drive (1) [follower avoider mapper recorder]
place leg1_hold
place leg1_drive_odometry [follower avoider recorder]
place leg1_drive_alt2 [follower avoider]
place leg1_drive_late [follower avoider mapper recorder]
place leg1_drive_late_odometry [follower avoider recorder]
place leg1_drive_late_alt2 [follower avoider]
place leg1_arrival [observer]
place leg1_arrival_alt1 [observer]
place done final
leg1_arrived: leg1_drive -> leg1_arrival follower.goal_reached
leg1_retry: leg1_hold -> leg1_drive operator
leg1_skip: leg1_hold -> done operator
leg1_blocked: leg1_drive -> leg1_hold follower.blocked
leg1_arrived_odometry: leg1_drive_odometry -> leg1_arrival follower.goal_reached
leg1_blocked_odometry: leg1_drive_odometry -> leg1_hold follower.blocked
leg1_arrived_alt2: leg1_drive_alt2 -> leg1_arrival follower.goal_reached
leg1_blocked_alt2: leg1_drive_alt2 -> leg1_hold follower.blocked
leg1_drive_mapper_failed: leg1_drive -> leg1_drive_odometry module.mapper.failed
leg1_drive_recorder_failed: leg1_drive -> leg1_drive_alt2 module.recorder.failed
leg1_drive_odometry_recorder_failed: leg1_drive_odometry -> leg1_drive_alt2 module.recorder.failed
leg1_arrived_late: leg1_drive_late -> leg1_arrival follower.goal_reached
leg1_blocked_late: leg1_drive_late -> leg1_hold follower.blocked
leg1_late: leg1_drive -> leg1_drive_late 2026-11-23T08:10:00Z
leg1_arrived_late_odometry: leg1_drive_late_odometry -> leg1_arrival follower.goal_reached
leg1_blocked_late_odometry: leg1_drive_late_odometry -> leg1_hold follower.blocked
leg1_late_odometry: leg1_drive_odometry -> leg1_drive_late_odometry 2026-11-23T08:10:00Z
leg1_arrived_late_alt2: leg1_drive_late_alt2 -> leg1_arrival follower.goal_reached
leg1_blocked_late_alt2: leg1_drive_late_alt2 -> leg1_hold follower.blocked
leg1_late_alt2: leg1_drive_alt2 -> leg1_drive_late_alt2 2026-11-23T08:10:00Z
leg1_drive_late_mapper_failed: leg1_drive_late -> leg1_drive_late_odometry module.mapper.failed
leg1_drive_late_recorder_failed: leg1_drive_late -> leg1_drive_late_alt2 module.recorder.failed
leg1_drive_late_odometry_recorder_failed: leg1_drive_late_odometry -> leg1_drive_late_alt2 module.recorder.failed
leg1_arrival_done: leg1_arrival -> done 30 s
leg1_arrival_done_alt1: leg1_arrival_alt1 -> done 30 s
leg1_arrival_camera_failed: leg1_arrival -> leg1_arrival_alt1 module.camera.failed
leg1_drive_alt2_recorder_failed: leg1_drive_alt2 -> leg1_hold module.recorder.failed
leg1_drive_late_alt2_recorder_failed: leg1_drive_late_alt2 -> leg1_hold module.recorder.failed
leg1_arrival_recorder_failed: leg1_arrival -> leg1_hold module.recorder.failed
leg1_arrival_alt1_recorder_failed: leg1_arrival_alt1 -> leg1_hold module.recorder.failed"
    );
    // A switch is where its alternative is written (`armor check` points there).
    let switch = compiled
        .net
        .transition("leg1_drive_mapper_failed")
        .expect("switch");
    let leg = compiled.net.transition("leg1_arrived").expect("arrived");
    assert!(
        switch.pos.line > leg.pos.line,
        "{:?} {:?}",
        switch.pos,
        leg.pos
    );
    assert_eq!(
        compiled.switches["leg1_drive_odometry_recorder_failed"],
        Switch {
            leg: 0,
            to: "alt2".to_owned(),
            module: "recorder".to_owned()
        }
    );
    // The alternative ways keep the parameters of the modules they run.
    let mapper = &compiled.net.place("leg1_drive").expect("drive").params;
    assert!(mapper.iter().any(|p| p.module == "mapper"), "{mapper:?}");
    // What only the alternatives have is known, for the studio to draw apart.
    for name in [
        "leg1_drive_odometry",
        "leg1_drive_mapper_failed",
        "leg1_arrived_alt2",
        "leg1_arrival_alt1",
        "leg1_arrival_done_alt1",
    ] {
        assert!(compiled.alternatives.contains(name), "{name}");
    }
    for name in [
        "leg1_drive",
        "leg1_arrived",
        "leg1_hold",
        "leg1_arrival_done",
    ] {
        assert!(!compiled.alternatives.contains(name), "{name}");
    }
    let analysis = analyse(&compiled.net, 100_000);
    assert_eq!(analysis.problems(&compiled.net), []);
    let again = MissionNet::parse(&compiled.net.to_xml()).expect("reads back");
    assert_eq!(again.without_positions(), compiled.net.without_positions());
}

#[test]
fn an_alternative_cannot_run_what_drives_or_runs_throughout() {
    assert_eq!(
        errors(
            r#"<leg from="home" to="gate">
  <during><module name="mapper"/><alternative><module name="avoider"/></alternative></during>
</leg>"#
        ),
        [
            "module `avoider` drives every leg (<navigation>); an action cannot run it with \
             other parameters"
        ]
    );
}

#[test]
fn a_lost_localiser_holds_the_leg_it_drives_or_skips_it_as_the_leg_says() {
    let with = picture(
        &compiled(
            r#"<leg from="home" to="gate"/>
<leg from="gate" to="hill">
  <contingency on="lost" module="amcl" do="skip"/>
</leg>
<contingency on="lost" do="hold"/>"#,
        )
        .net,
    );
    for line in [
        "leg1_lost: leg1_drive -> leg1_hold localiser.lost",
        "leg2_lost: leg2_drive -> done amcl.lost",
    ] {
        assert!(with.lines().any(|l| l == line), "no `{line}` in\n{with}");
    }
    // Without a `lost` contingency nothing listens to a localiser.
    let without = picture(&compiled(r#"<leg from="home" to="gate"/>"#).net);
    assert!(!without.contains(".lost"), "{without}");
}

#[test]
fn a_low_battery_returns_to_the_start_unless_the_plan_says_otherwise() {
    let plan = plan(
        r#"<leg from="home" to="gate" not_before="2026-11-23T08:05:00Z" wait_secs="600">
  <arrival for_secs="60"><module name="observer"/></arrival>
  <contingency on="blocked" do="hold"/>
</leg>
<leg from="gate" to="hill">
  <contingency on="low_battery" module="bms" do="hold"/>
</leg>
<contingency on="low_battery"/>"#,
    );
    // No `do`: return to where the plan starts, written out in full.
    assert!(
        plan.to_xml()
            .contains(r#"<contingency on="low_battery" do="return" waypoint="home"/>"#),
        "{}",
        plan.to_xml()
    );
    let with = picture(
        &compile(&plan, Some(&world()))
            .unwrap_or_else(|problems| panic!("{problems:?}"))
            .net,
    );
    for line in [
        "leg1_low_battery: leg1_drive -> leg1_return sim.low_battery",
        "leg2_low_battery: leg2_drive -> leg2_hold bms.low_battery",
        // Not only while a leg drives: waiting for its appointment, acting on arrival, waiting
        // there, holding for the operator.
        "leg1_depart_low_battery: leg1_depart -> leg1_return sim.low_battery",
        "leg1_arrival_low_battery: leg1_arrival -> leg1_return sim.low_battery",
        "leg1_wait_low_battery: leg1_wait -> leg1_return sim.low_battery",
        "leg1_hold_low_battery: leg1_hold -> leg1_return sim.low_battery",
    ] {
        assert!(with.lines().any(|l| l == line), "no `{line}` in\n{with}");
    }
    // A hold that is itself the answer does not listen to what it answers.
    assert!(!with.contains("leg2_hold_low_battery"), "{with}");
    // Without one nothing listens to the battery.
    let without = picture(&compiled(r#"<leg from="home" to="gate"/>"#).net);
    assert!(!without.contains("low_battery"), "{without}");
}

#[test]
fn a_lost_radio_holds_or_returns_after_its_time_wherever_the_leg_is_and_goes_on_by_default() {
    let plan = plan(
        r#"<leg from="home" to="gate" wait_secs="600">
  <contingency on="link_lost" after_secs="30" do="return" waypoint="home"/>
</leg>
<leg from="gate" to="hill"/>
<leg from="hill" to="home">
  <contingency on="link_lost" do="continue"/>
</leg>
<contingency on="link_lost" do="hold"/>"#,
    );
    // The default time is not written out; another is, and the plan reads back the same.
    let xml = plan.to_xml();
    for written in [
        r#"<contingency on="link_lost" after_secs="30" do="return" waypoint="home"/>"#,
        r#"<contingency on="link_lost" do="hold"/>"#,
        r#"<contingency on="link_lost" do="continue"/>"#,
    ] {
        assert!(xml.contains(written), "no `{written}` in\n{xml}");
    }
    let again = Plan::parse(&xml).unwrap_or_else(|problems| panic!("{problems:?}"));
    assert_eq!(again.to_xml(), xml);
    assert_eq!(
        again.legs[0].contingencies[0].trigger,
        Trigger::LinkLost { after_secs: 30 }
    );
    let with = picture(
        &compile(&plan, Some(&world()))
            .unwrap_or_else(|problems| panic!("{problems:?}"))
            .net,
    );
    for line in [
        "leg1_link_lost: leg1_drive -> leg1_return link.lost.30",
        "leg1_wait_link_lost: leg1_wait -> leg1_return link.lost.30",
        "leg2_link_lost: leg2_drive -> leg2_hold link.lost.10",
    ] {
        assert!(with.lines().any(|l| l == line), "no `{line}` in\n{with}");
    }
    // A hold that is itself the answer does not listen to what it answers, and `continue`
    // (the default without a contingency) changes nothing in the net.
    assert!(!with.contains("leg2_hold_link_lost"), "{with}");
    assert!(!with.contains("leg3_link_lost"), "{with}");
    let without = picture(&compiled(r#"<leg from="home" to="gate"/>"#).net);
    assert!(!without.contains("link"), "{without}");
}

#[test]
fn a_lost_radio_is_refused_with_a_bad_time_a_skip_and_a_time_on_another_trigger() {
    let text = |body: &str| {
        format!(
            "<plan name=\"p\" system=\"system.xml\">\n{}\n{}\n<leg from=\"home\" to=\"gate\"/>\n{body}\n</plan>",
            waypoint("home", 4.0, 4.0),
            waypoint("gate", 34.0, 4.0)
        )
    };
    for (body, expected) in [
        (
            r#"<contingency on="link_lost" after_secs="2.5" do="hold"/>"#,
            "`after_secs` must be a whole number of seconds, 1 or more, not `2.5`",
        ),
        (
            r#"<contingency on="link_lost" after_secs="0" do="hold"/>"#,
            "`after_secs` must be a whole number of seconds, 1 or more, not `0`",
        ),
        (
            r#"<contingency on="link_lost" do="skip"/>"#,
            "`skip` is not for on=\"link_lost\"",
        ),
        (
            r#"<contingency on="blocked" after_secs="5" do="hold"/>"#,
            "`after_secs` is only for on=\"link_lost\"",
        ),
    ] {
        let problems = Plan::parse(&text(body)).expect_err(body);
        assert!(
            problems.iter().any(|p| p.message.contains(expected)),
            "{body}: {problems:?}"
        );
    }
}
