//! QGC plan files: seeded random plans through export and import, seeded random .plan files
//! (items of every kind, broken values) through import, and the rules of delays.

use armor_module_api::xml::Located;
use serde_json::{Value, json};

use super::{export, import};
use crate::plan::{
    AreaKind, Contingency, Graphic, GraphicKind, LatLon, Leg, Plan, Response, Trigger, Waypoint,
};
use crate::planner::random::SplitMix64;
use crate::world::Point;

/// A plan of 2 to 12 stops within a kilometre of a random place on Earth, with random waits,
/// appointments (rising, less than a day apart), convex no-go areas and a `return`.
fn random_plan(rng: &mut SplitMix64) -> Plan {
    let origin = LatLon::new(rng.uniform(-80.0, 80.0), rng.uniform(-179.0, 179.0));
    let start = rng.uniform(946_684_800.0, 1_893_456_000.0).floor() + rng.uniform(0.0, 1.0);
    let count = 2 + (rng.next_u64() % 11) as usize;
    let waypoints: Vec<Waypoint> = (0..count)
        .map(|i| Waypoint {
            name: format!("w{i}"),
            position: LatLon::from_local(
                Point::new(rng.uniform(-1000.0, 1000.0), rng.uniform(-1000.0, 1000.0)),
                origin,
            ),
            ..Waypoint::default()
        })
        .collect();
    let mut time = start;
    let legs: Vec<Leg> = (1..count)
        .map(|i| {
            let wait_secs = (rng.next_u64().is_multiple_of(3)).then(|| rng.uniform(0.5, 600.0));
            let not_before_unix_secs = (rng.next_u64().is_multiple_of(3)).then(|| {
                time += rng.uniform(1.0, 80_000.0);
                time
            });
            Leg {
                name: format!("leg{i}"),
                from: format!("w{}", i - 1),
                to: format!("w{i}"),
                wait_secs,
                not_before_unix_secs,
                ..Leg::default()
            }
        })
        .collect();
    let areas = (0..rng.next_u64() % 4)
        .map(|i| {
            let centre = Point::new(rng.uniform(-1000.0, 1000.0), rng.uniform(-1000.0, 1000.0));
            let corners = 3 + (rng.next_u64() % 6) as usize;
            let mut angles: Vec<f64> = (0..corners)
                .map(|_| rng.uniform(0.0, std::f64::consts::TAU))
                .collect();
            angles.sort_by(f64::total_cmp);
            if rng.next_u64().is_multiple_of(2) {
                angles.reverse();
            }
            let radius = rng.uniform(2.0, 50.0);
            Graphic {
                kind: GraphicKind::Area(AreaKind::NoGo),
                name: format!("area{i}"),
                points: angles
                    .iter()
                    .map(|a| {
                        let p =
                            Point::new(centre.x + radius * a.cos(), centre.y + radius * a.sin());
                        LatLon::from_local(p, origin)
                    })
                    .collect(),
                ..Graphic::default()
            }
        })
        .collect();
    Plan {
        name: "random".into(),
        system: "system.xml".into(),
        start_unix_secs: Some(start),
        contingencies: vec![Contingency {
            trigger: Trigger::Blocked,
            response: Response::Return {
                waypoint: "w0".into(),
            },
            pos: Default::default(),
        }],
        waypoints,
        legs,
        graphics: areas,
        ..Plan::default()
    }
}

#[test]
fn seeded_random_plans_come_back_with_their_route_delays_and_no_go_areas() {
    for seed in 0..300 {
        let mut rng = SplitMix64(seed);
        let plan = random_plan(&mut rng);
        Plan::parse(&plan.to_xml()).unwrap_or_else(|p| panic!("seed {seed}: {p:?}"));
        let written = export(&plan).text;
        let back = import(&written, "random", "system.xml", plan.start_unix_secs)
            .unwrap_or_else(|p| panic!("seed {seed}: {p:?}\n{written}"));
        // A rally point is where the plan's `return` goes: read back as that waypoint, with a
        // warning that no contingency returns there; nothing else is lost.
        assert!(
            back.warnings.iter().all(|w| w
                .message
                .starts_with("rally points kept as waypoints (home)")),
            "seed {seed}: {:?}",
            back.warnings
        );
        let again = back.plan;
        assert_eq!(again.waypoints.len(), plan.waypoints.len(), "seed {seed}");
        for (got, want) in again.waypoints.iter().zip(&plan.waypoints) {
            // Doubles, exactly.
            assert_eq!(got.position, want.position, "seed {seed}");
        }
        for (got, want) in again.legs.iter().zip(&plan.legs) {
            assert_eq!(got.wait_secs, want.wait_secs, "seed {seed}");
            match (got.not_before_unix_secs, want.not_before_unix_secs) {
                (Some(got), Some(want)) => {
                    assert!(
                        (got - want).abs() < 1e-6,
                        "seed {seed}: {got} against {want}"
                    )
                }
                (got, want) => assert_eq!(got, want, "seed {seed}"),
            }
        }
        let areas: Vec<&Graphic> = again.no_go_areas().collect();
        assert_eq!(areas.len(), plan.graphics.len(), "seed {seed}");
        for (got, want) in areas.iter().zip(&plan.graphics) {
            // Clockwise: the same corners, maybe the other way round.
            let mut corners = got.points.clone();
            if corners != want.points {
                corners.reverse();
            }
            assert_eq!(corners, want.points, "seed {seed}");
        }
        // And what comes back is a plan the plan reader takes as it is.
        let xml = again.to_xml();
        Plan::parse(&xml).unwrap_or_else(|p| panic!("seed {seed}: {p:?}\n{xml}"));
    }
}

/// A number from `lo` to `hi`, or now and then a value of the kinds a broken or unusual file
/// holds where a number is expected.
fn sometimes_broken(rng: &mut SplitMix64, lo: f64, hi: f64) -> Value {
    let good = rng.uniform(lo, hi);
    match rng.next_u64() % 60 {
        0 => Value::Null,
        1 => json!("12"),
        2 => json!(1e300),
        3 => json!([]),
        4 => json!(rng.uniform(-200.0, 200.0)),
        _ => json!(good),
    }
}

/// A .plan file with random items of every kind this reader knows and some it does not.
fn random_file(rng: &mut SplitMix64) -> String {
    let items: Vec<Value> = (0..rng.next_u64() % 8)
        .map(|i| {
            let command = [16, 16, 16, 19, 82, 93, 93, 20, 178, 22][(rng.next_u64() % 10) as usize];
            let params: Vec<Value> = (0..7 - u64::from(rng.next_u64().is_multiple_of(20)))
                .map(|p| match (command, p) {
                    (93, 0) => json!([-1, 5, 0][(rng.next_u64() % 3) as usize]),
                    (93, 1..=3) => json!((rng.next_u64() % 24) as f64),
                    (_, 4) => sometimes_broken(rng, -89.0, 89.0),
                    (_, 5) => sometimes_broken(rng, -179.0, 179.0),
                    _ => sometimes_broken(rng, -10.0, 60.0),
                })
                .collect();
            match rng.next_u64() % 30 {
                0 => json!({"type": "ComplexItem", "complexItemType": "survey", "polygon": []}),
                1 => json!({"type": "SimpleItem", "command": command}),
                2 => json!(i),
                _ => json!({
                    "type": "SimpleItem",
                    "command": command,
                    "frame": ([3, 3, 3, 2, 1][(rng.next_u64() % 5) as usize]),
                    "params": params,
                    "autoContinue": true,
                    "doJumpId": i + 1,
                }),
            }
        })
        .collect();
    let point = |rng: &mut SplitMix64| {
        json!([
            sometimes_broken(rng, -89.0, 89.0),
            sometimes_broken(rng, -179.0, 179.0),
            0
        ])
    };
    let corners: Vec<Value> = (0..rng.next_u64() % 6).map(|_| point(rng)).collect();
    let (home, centre, rally) = (point(rng), point(rng), point(rng));
    let mut doc = json!({
        "fileType": "Plan",
        "version": 1,
        "groundStation": "QGroundControl",
        "mission": {
            "version": 2,
            "vehicleType": ([10, 2, 1][(rng.next_u64() % 3) as usize]),
            "cruiseSpeed": sometimes_broken(rng, 0.1, 20.0),
            "plannedHomePosition": home,
            "items": items,
        },
        "geoFence": {
            "version": 2,
            "polygons": [{"inclusion": rng.next_u64().is_multiple_of(2), "polygon": corners, "version": 1}],
            "circles": [{
                "inclusion": false,
                "circle": {"center": centre, "radius": sometimes_broken(rng, 0.0, 100.0)},
                "version": 1
            }],
        },
        "rallyPoints": {"version": 2, "points": [rally]},
    });
    if rng.next_u64().is_multiple_of(4) {
        doc["mission"]
            .as_object_mut()
            .map(|m| m.remove("plannedHomePosition"));
    }
    let text = serde_json::to_string_pretty(&doc).unwrap_or_default();
    if rng.next_u64().is_multiple_of(5) {
        // Cut anywhere (on a character boundary).
        let mut cut = (rng.next_u64() as usize) % text.len().max(1);
        while !text.is_char_boundary(cut) {
            cut -= 1;
        }
        return text[..cut].to_owned();
    }
    text
}

#[test]
fn seeded_random_qgc_files_import_as_valid_plans_or_are_refused_at_a_place_in_them() {
    let mut imported = 0;
    for seed in 0..2000 {
        let mut rng = SplitMix64(seed);
        let text = random_file(&mut rng);
        let lines = text.lines().count().max(1) as u32;
        let within = |problem: &Located| problem.pos.line >= 1 && problem.pos.line <= lines + 1;
        match import(&text, "random", "system.xml", Some(1_800_000_000.0)) {
            Ok(back) => {
                imported += 1;
                assert!(back.warnings.iter().all(within), "seed {seed}");
                let xml = back.plan.to_xml();
                Plan::parse(&xml).unwrap_or_else(|p| panic!("seed {seed}: {p:?}\n{xml}\n{text}"));
                assert!(!back.plan.legs.is_empty(), "seed {seed}");
            }
            Err(problems) => {
                assert!(!problems.is_empty(), "seed {seed}");
                assert!(problems.iter().all(within), "seed {seed}: {problems:?}");
            }
        }
    }
    // The generator is not so broken that nothing ever imports.
    assert!(imported > 100, "{imported}");
}

fn file_with_items(items: Value) -> String {
    json!({
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "mission": {"version": 2, "plannedHomePosition": [47.0, 8.0, 0], "items": items},
    })
    .to_string()
}

fn waypoint(lat: f64, lon: f64) -> Value {
    json!({"type": "SimpleItem", "command": 16, "frame": 3, "autoContinue": true,
           "params": [0, 0, 0, null, lat, lon, 0]})
}

fn delay(params: [f64; 4]) -> Value {
    json!({"type": "SimpleItem", "command": 93, "frame": 2, "autoContinue": true,
           "params": [params[0], params[1], params[2], params[3], 0, 0, 0]})
}

#[test]
fn a_time_of_day_that_has_passed_is_the_next_day() {
    // Start at 22:00 UTC; appointments at 23:00, then 01:30 (the next day), then 01:00 (the
    // day after: times only go forwards).
    let start = crate::net::parse_rfc3339("2026-11-23T22:00:00Z").unwrap_or_default();
    let text = file_with_items(json!([
        delay([-1.0, 23.0, 0.0, 0.0]),
        waypoint(47.001, 8.0),
        delay([-1.0, 1.0, 30.0, 0.0]),
        waypoint(47.002, 8.0),
        delay([-1.0, 1.0, 0.0, 0.0]),
        waypoint(47.003, 8.0),
    ]));
    let plan = import(&text, "p", "s.xml", Some(start)).map(|i| i.plan);
    let times: Vec<String> = plan
        .map(|plan| {
            plan.legs
                .iter()
                .filter_map(|leg| leg.not_before_unix_secs)
                .map(crate::net::format_rfc3339)
                .collect()
        })
        .unwrap_or_default();
    assert_eq!(
        times,
        [
            "2026-11-23T23:00:00Z",
            "2026-11-24T01:30:00Z",
            "2026-11-25T01:00:00Z"
        ]
    );
}

#[test]
fn delays_of_seconds_add_to_the_wait_where_the_robot_is() {
    let text = file_with_items(json!([
        delay([12.0, -1.0, -1.0, -1.0]),
        waypoint(47.001, 8.0),
        delay([10.0, -1.0, -1.0, -1.0]),
        delay([2.5, -1.0, -1.0, -1.0]),
        waypoint(47.002, 8.0),
        // Nothing to hold: not a wait of 0 s (found by fuzzing).
        delay([-0.0, -1.0, -1.0, -1.0]),
        delay([-1.0, 23.0, 0.0, 0.0]),
    ]));
    let imported = import(&text, "p", "s.xml", Some(0.0)).map_err(|p| format!("{p:?}"));
    let Ok(imported) = imported else {
        panic!("{imported:?}");
    };
    let waits: Vec<Option<f64>> = imported.plan.legs.iter().map(|l| l.wait_secs).collect();
    assert_eq!(waits, [Some(12.5), None]);
    let warnings: Vec<String> = imported
        .warnings
        .iter()
        .map(|w| w.message.clone())
        .collect();
    assert_eq!(
        warnings,
        [
            "a delay before the first waypoint cannot be held at the start: dropped",
            "a delay after the last waypoint holds nothing: dropped",
        ]
    );
}
