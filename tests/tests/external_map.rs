//! A plan on a map nobody here drew: Nav2's `depot` map (`tests/data/external/nav2_depot/`, its
//! source, commit and licence in the README there), driven by the whole robot (sim, localiser,
//! follower, avoider, recorder) with the simulator's default odometry noise. The simulator's
//! recorded truth judges: every leg arrives within the follower's tolerance plus 0.1 m, the
//! robot's footprint never meets the no-go area, and nothing is hit.

use std::path::Path;
use std::time::Duration;

use armor_model::geo::{self, LatLon, Polygon};
use armor_model::world::Point;
use armor_module_api::Datum as _;
use armor_module_api::types::Pose2D;
use armor_tests::mcap::read_mcap;
use armor_tests::mission::run_mission;
use armor_tests::workspace_root;

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

fn system(map: &Path, record: &Path) -> String {
    let map = map.display();
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="robot-depot">
  <module name="sim" type="sim"><param name="world" value="{map}"/></module>
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

#[test]
fn a_plan_on_nav2_s_depot_map_arrives_by_the_truth_with_default_noise() {
    let map = workspace_root().join("tests/data/external/nav2_depot/depot-armor.yaml");
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("truth.mcap");
    let system_file = dir.path().join("system.xml");
    std::fs::write(&system_file, system(&map, &record)).unwrap();
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

    let mut truth: Vec<(f64, Point)> = Vec::new();
    for ((topic, encoding), messages) in read_mcap(&record) {
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
    let area = Polygon::new(NO_GO.iter().map(|&(x, y)| Point::new(x, y)).collect());
    let closest = truth
        .iter()
        .map(|(_, p)| {
            if area.contains(*p) {
                -1.0
            } else {
                area.distance_to_outline(*p) - RADIUS_M
            }
        })
        .fold(f64::INFINITY, f64::min);
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
