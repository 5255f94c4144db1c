//! A plan on a map nobody here drew: Nav2's `depot` map (`tests/data/external/nav2_depot/`, its
//! source, commit and licence in the README there), driven by the whole robot (sim, localiser,
//! follower, avoider, recorder) with the simulator's default odometry noise. The simulator's
//! recorded truth judges: every leg arrives within the follower's tolerance plus 0.1 m, the
//! robot's footprint never meets the no-go area, and nothing is hit.

// A test that cannot read what it made has failed: unwrapping says where.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::time::Duration;

use armor_model::geo::{self, LatLon, Polygon};
use armor_model::world::Point;
use armor_module_api::Datum as _;
use armor_module_api::types::Pose2D;
use armor_tests::mcap::read_mcap;
use armor_tests::mission::run_mission;
use armor_tests::{ctl, ctl_status, run_with_control, wait_until, workspace_root};

/// The follower's tolerance plus 0.1 m.
const TOLERANCE_M: f64 = 0.4;
const RADIUS_M: f64 = 0.25;
/// The wrapper's `geo_origin`: where the map's origin is on Earth.
const ORIGIN: (f64, f64) = (43.6, 1.44);
/// Places in the depot's open floor and its aisle between the posts (map frame, metres).
const PLACES: [(&str, f64, f64); 5] = [
    ("start", 2.0, 2.0),
    ("south", 10.0, 2.0),
    ("posts", 20.0, 8.5),
    ("north", 10.0, 13.0),
    ("west", 2.0, 12.0),
];
/// A no-go area on the open floor, between the start and the west place.
const NO_GO: [(f64, f64); 4] = [(3.5, 5.0), (6.0, 5.0), (6.0, 8.0), (3.5, 8.0)];

fn system(map: &Path, record: &Path, kidnap: &str) -> String {
    let map = map.display();
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="robot-depot">
  <module name="sim" type="sim">
    <param name="world" value="{map}"/>
    <param name="kidnap" value="{kidnap}"/>
  </module>
  <module name="localiser" type="localiser"><param name="world" value="{map}"/></module>
  <module name="follower" type="follower">
    <param name="world" value="{map}"/>
    <param name="goal_x_m" value="10"/>
    <param name="goal_y_m" value="2"/>
    <param name="blocked_after_secs" value="20"/>
  </module>
  <module name="avoider" type="avoider"/>
  <module name="mux" type="mux"/>
  <module name="recorder" type="recorder">
    <param name="record" value="sim.pose_truth"/>
    <param name="file" value="{record}"/>
    <param name="compression" value="none"/>
  </module>
  <link from="sim.odometry" to="localiser.odometry"/>
  <link from="sim.scan" to="localiser.scan"/>
  <link from="localiser.pose" to="follower.odometry"/>
  <link from="localiser.estimate" to="follower.estimate"/>
  <link from="sim.scan" to="avoider.scan"/>
  <link from="sim.scan" to="follower.scan"/>
  <link from="follower.cmd_desired" to="avoider.cmd_desired"/>
  <link from="avoider.cmd_vel" to="mux.auto"/>
  <link from="mux.cmd_vel" to="sim.cmd_vel"/>
</system>
"#,
        record = record.display()
    )
}

fn plan(system: &Path) -> String {
    let origin = LatLon::new(ORIGIN.0, ORIGIN.1);
    let at = |x: f64, y: f64| LatLon::from_local(Point::new(x, y), origin);
    let mut text = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<plan name=\"depot-round\" system=\"{}\">\n  \
         <navigation><module name=\"avoider\"/></navigation>\n  <throughout><module \
         name=\"recorder\"/></throughout>\n",
        system.display()
    );
    for (name, x, y) in PLACES {
        let p = at(x, y);
        text.push_str(&format!(
            "  <waypoint name=\"{name}\" lat=\"{:.9}\" lon=\"{:.9}\"/>\n",
            p.lat_deg, p.lon_deg
        ));
    }
    for pair in PLACES.windows(2) {
        text.push_str(&format!(
            "  <leg name=\"to_{}\" from=\"{}\" to=\"{}\"/>\n",
            pair[1].0, pair[0].0, pair[1].0
        ));
    }
    text.push_str(
        "  <contingency on=\"lost\" do=\"hold\"/>\n  <area name=\"pit\" kind=\"no-go\">\n",
    );
    for (x, y) in NO_GO {
        let p = at(x, y);
        text.push_str(&format!(
            "    <point lat=\"{:.9}\" lon=\"{:.9}\"/>\n",
            p.lat_deg, p.lon_deg
        ));
    }
    text.push_str("  </area>\n</plan>\n");
    text
}

/// The sim's true positions a recorder wrote, with their run time, in time order.
fn read_truth(record: &Path) -> Vec<(f64, Point)> {
    let mut truth: Vec<(f64, Point)> = Vec::new();
    for ((topic, encoding), messages) in read_mcap(record) {
        assert_eq!(topic, "sim.pose_truth");
        for (log_time, data) in messages {
            let pose = match encoding.as_str() {
                "json" => serde_json::from_slice::<Pose2D>(&data).unwrap(),
                _ => Pose2D::decode(&data).unwrap(),
            };
            truth.push((log_time as f64 / 1e9, Point::new(pose.x_m, pose.y_m)));
        }
    }
    truth.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert!(truth.len() > 100, "{} true poses recorded", truth.len());
    truth
}

fn no_go_area() -> Polygon {
    Polygon::new(NO_GO.iter().map(|&(x, y)| Point::new(x, y)).collect())
}

/// The least distance between the robot's true footprint and `area` (negative: inside).
fn closest_to(area: &Polygon, truth: &[(f64, Point)]) -> f64 {
    truth
        .iter()
        .map(|(_, p)| {
            if area.contains(*p) {
                -1.0
            } else {
                area.distance_to_outline(*p) - RADIUS_M
            }
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn a_plan_on_nav2_s_depot_map_arrives_by_the_truth_with_default_noise() {
    let map = workspace_root().join("tests/data/external/nav2_depot/depot-armor.yaml");
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("truth.mcap");
    let system_file = dir.path().join("system.xml");
    std::fs::write(&system_file, system(&map, &record, "")).unwrap();
    let plan_file = dir.path().join("plan.xml");
    let plan_text = plan(&system_file);
    std::fs::write(&plan_file, &plan_text).unwrap();
    let run = run_mission(&plan_file, &[], Duration::from_secs(300));
    assert_eq!(
        run.final_marking(),
        serde_json::json!({ "done": 1 }),
        "{:?}\n{}",
        run.fired(),
        run.lines.join("\n")
    );
    run.assert_clean();

    let truth = read_truth(&record);
    let closest = closest_to(&no_go_area(), &truth);
    assert!(
        closest > 0.0,
        "the footprint met the no-go area ({closest:.2} m)"
    );
    let mut errors = Vec::new();
    for pair in PLACES.windows(2) {
        let (name, x, y) = pair[1];
        let arrived = run
            .fired_at(&format!("to_{name}_arrived"))
            .unwrap_or_else(|| panic!("`to_{name}` never arrived: {:?}", run.fired()));
        let (_, at) = truth
            .iter()
            .min_by(|a, b| (a.0 - arrived).abs().total_cmp(&(b.0 - arrived).abs()))
            .unwrap();
        let error = geo::distance(*at, Point::new(x, y));
        errors.push(format!("{name} {error:.3} m"));
        assert!(
            error <= TOLERANCE_M,
            "`to_{name}` arrived {error:.3} m from `{name}` by the truth\n{plan_text}"
        );
    }
    eprintln!(
        "depot: true errors at arrival: {}; closest footprint to the no-go area {closest:.2} m",
        errors.join(", ")
    );
}

/// When the sim carries the robot away (12 s of simulated time in, on the first leg) and where
/// to (the depot's north-east, where nothing looks like where it was).
const KIDNAP_SECS: f64 = 12.0;
const KIDNAPPED_TO: (f64, f64) = (20.0, 12.5);

#[test]
fn a_kidnapped_robot_is_lost_the_plan_holds_and_an_operator_sets_the_pose() {
    let map = workspace_root().join("tests/data/external/nav2_depot/depot-armor.yaml");
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("truth.mcap");
    let system_file = dir.path().join("system.xml");
    let kidnap = format!("{KIDNAP_SECS} {} {} 0", KIDNAPPED_TO.0, KIDNAPPED_TO.1);
    std::fs::write(&system_file, system(&map, &record, &kidnap)).unwrap();
    let plan_file = dir.path().join("plan.xml");
    std::fs::write(&plan_file, plan(&system_file)).unwrap();
    let (mut run, addr) = run_with_control(&plan_file);
    let held = |status: &serde_json::Value| {
        status["mission"]["marking"]["to_south_hold"]
            .as_u64()
            .unwrap_or(0)
            > 0
    };
    // In real time: the kidnapping comes 12 s in, the localiser says lost within a second of
    // simulated time (ten scans, as its unit test states), and the leg holds.
    wait_until("the leg held", Duration::from_secs(60), || {
        held(&ctl_status(&addr))
    });
    let lines = run.lines();
    let kidnapped = lines
        .iter()
        .position(|line| line.contains("kidnapped: the robot is carried"));
    let lost = lines
        .iter()
        .position(|line| line.contains("fired `to_south_lost`"));
    assert!(
        kidnapped.is_some() && lost.is_some() && kidnapped < lost,
        "{}",
        lines.join("\n")
    );
    // Held, nothing drives the robot; the operator tells the localiser where it is, and it is
    // localised again, still held until the operator retries.
    let (ok, said) = ctl(
        &addr,
        &[
            "set-pose",
            &KIDNAPPED_TO.0.to_string(),
            &KIDNAPPED_TO.1.to_string(),
            "0",
        ],
    );
    assert!(ok, "{said}");
    let start = run.line_count();
    run.wait_for_from(start, "localised again", Duration::from_secs(30), |line| {
        line.contains("event localiser.localised")
    });
    assert!(held(&ctl_status(&addr)), "the leg is still held");
    let (ok, said) = ctl(&addr, &["abort"]);
    assert!(ok, "{said}");
    run.wait_exit(Duration::from_secs(30));
    let truth = read_truth(&record);
    let closest = closest_to(&no_go_area(), &truth);
    assert!(
        closest > 0.0,
        "the footprint met the no-go area ({closest:.2} m)"
    );
    // From where it was put, the robot moved no more than its stopping distance.
    let put = Point::new(KIDNAPPED_TO.0, KIDNAPPED_TO.1);
    let after: Vec<Point> = truth
        .iter()
        .map(|(_, p)| *p)
        .skip_while(|p| geo::distance(*p, put) > 0.05)
        .collect();
    assert!(!after.is_empty(), "the kidnapping is in the truth");
    let moved = after
        .iter()
        .map(|p| geo::distance(*p, put))
        .fold(0.0, f64::max);
    assert!(moved < 0.5, "the kidnapped robot drove {moved:.2} m");
}
