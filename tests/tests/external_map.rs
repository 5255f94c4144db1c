//! A plan on a map nobody here drew: Nav2's `depot` map (`tests/data/external/nav2_depot/`, its
//! source, commit and licence in the README there), driven by the whole robot (sim, localiser,
//! follower, avoider, recorder) with the simulator's default odometry noise. The simulator's
//! recorded truth judges: every leg arrives within the follower's tolerance plus 0.1 m, the
//! robot's footprint never meets the no-go area, and nothing is hit.

// A test that cannot read what it made has failed: unwrapping says where.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::time::Duration;

use armor_model::geo::{self, LatLon, Polygon};
use armor_model::world::Point;
use armor_module_api::Datum as _;
use armor_module_api::types::{LocalisationState, Odometry, Pose2D, PoseEstimate};
use armor_tests::mcap::read_mcap;
use armor_tests::mission::{armor_run, run_mission};
use armor_tests::{
    PATIENCE, control_address, ctl, loaded, process_alive, run_with_control, try_ctl_status,
    wait_until, wait_until_loaded, workspace_root,
};

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

/// The robot's system; `recover` turns the localiser's search of the map on when lost, and the
/// recorder keeps `topics` (the truth first).
fn system(map: &Path, record: &Path, kidnap: &str, recover: bool, topics: &str) -> String {
    let map = map.display();
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="robot-depot">
  <module name="sim" type="sim">
    <param name="world" value="{map}"/>
    <param name="kidnap" value="{kidnap}"/>
  </module>
  <module name="localiser" type="localiser">
    <param name="world" value="{map}"/>
    <param name="recover" value="{recover}"/>
  </module>
  <module name="follower" type="follower">
    <param name="world" value="{map}"/>
    <param name="goal_x_m" value="10"/>
    <param name="goal_y_m" value="2"/>
    <param name="blocked_after_secs" value="20"/>
  </module>
  <module name="avoider" type="avoider"/>
  <module name="mux" type="mux"/>
  <module name="recorder" type="recorder">
    <param name="record" value="{topics}"/>
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
    plan_of(system, &PLACES)
}

/// A plan of legs through `places`, in order, holding when lost, round the no-go area.
fn plan_of(system: &Path, places: &[(&str, f64, f64)]) -> String {
    let origin = LatLon::new(ORIGIN.0, ORIGIN.1);
    let at = |x: f64, y: f64| LatLon::from_local(Point::new(x, y), origin);
    let mut text = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<plan name=\"depot-round\" system=\"{}\">\n  \
         <navigation><module name=\"avoider\"/></navigation>\n  <throughout><module \
         name=\"recorder\"/></throughout>\n",
        system.display()
    );
    for &(name, x, y) in places {
        let p = at(x, y);
        text.push_str(&format!(
            "  <waypoint name=\"{name}\" lat=\"{:.9}\" lon=\"{:.9}\"/>\n",
            p.lat_deg, p.lon_deg
        ));
    }
    for pair in places.windows(2) {
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

/// The messages on `topic` a recorder wrote, with their run time (in time order) and their
/// encoding.
fn read_topic(record: &Path, topic: &str) -> Vec<(f64, String, Vec<u8>)> {
    let mut messages: Vec<(f64, String, Vec<u8>)> = read_mcap(record)
        .into_iter()
        .filter(|((recorded, _), _)| recorded == topic)
        .flat_map(|((_, encoding), messages)| {
            messages
                .into_iter()
                .map(move |(log_time, data)| (log_time as f64 / 1e9, encoding.clone(), data))
        })
        .collect();
    messages.sort_by(|a, b| a.0.total_cmp(&b.0));
    messages
}

/// The sim's true positions a recorder wrote, with their run time, in time order.
fn read_truth(record: &Path) -> Vec<(f64, Point)> {
    let truth: Vec<(f64, Point)> = read_topic(record, "sim.pose_truth")
        .into_iter()
        .map(|(at, encoding, data)| {
            let pose = match encoding.as_str() {
                "json" => serde_json::from_slice::<Pose2D>(&data).unwrap(),
                _ => Pose2D::decode(&data).unwrap(),
            };
            (at, Point::new(pose.x_m, pose.y_m))
        })
        .collect();
    assert!(truth.len() > 100, "{} true poses recorded", truth.len());
    truth
}

/// The localiser's estimates a recorder wrote, with their run time, in time order.
fn read_estimates(record: &Path) -> Vec<(f64, PoseEstimate)> {
    read_topic(record, "localiser.estimate")
        .into_iter()
        .map(|(at, encoding, data)| match encoding.as_str() {
            "json" => (at, serde_json::from_slice(&data).unwrap()),
            _ => (at, PoseEstimate::decode(&data).unwrap()),
        })
        .collect()
}

/// The last true position recorded at or before `time` (the first one, before any).
fn true_position_at(truth: &[(f64, Point)], time: f64) -> Point {
    truth
        .iter()
        .rev()
        .find(|(at, _)| *at <= time)
        .or(truth.first())
        .map(|(_, p)| *p)
        .unwrap()
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
    std::fs::write(
        &system_file,
        system(&map, &record, "", false, "sim.pose_truth"),
    )
    .unwrap();
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

/// The depot's system with the kidnap of [`KIDNAPPED_TO`] written in `dir`, the localiser's
/// `recover` as given and the recorder keeping `topics`: the system file and the recording.
fn kidnapped_system(dir: &Path, recover: bool, topics: &str) -> (PathBuf, PathBuf) {
    let map = workspace_root().join("tests/data/external/nav2_depot/depot-armor.yaml");
    let record = dir.join("truth.mcap");
    let system_file = dir.join("system.xml");
    let kidnap = format!("{KIDNAP_SECS} {} {} 0", KIDNAPPED_TO.0, KIDNAPPED_TO.1);
    std::fs::write(
        &system_file,
        system(&map, &record, &kidnap, recover, topics),
    )
    .unwrap();
    (system_file, record)
}

#[test]
fn a_kidnapped_robot_is_lost_the_plan_holds_and_an_operator_sets_the_pose() {
    let dir = tempfile::tempdir().unwrap();
    let (system_file, record) = kidnapped_system(dir.path(), false, "sim.pose_truth");
    let plan_file = dir.path().join("plan.xml");
    std::fs::write(&plan_file, plan(&system_file)).unwrap();
    let (mut run, addr) = run_with_control(&plan_file);
    let held = |status: &serde_json::Value| {
        status["mission"]["marking"]["to_south_hold"]
            .as_u64()
            .unwrap_or(0)
            > 0
    };
    // A status the run did not answer in time (a loaded machine) is asked again: every wait
    // below is on a condition, its deadline stretched by the machine's load.
    let held_now = || try_ctl_status(&addr).is_some_and(|status| held(&status));
    // In real time: the kidnapping comes 12 s in, the localiser says lost within a second of
    // simulated time (ten scans, as its unit test states), and the leg holds.
    wait_until_loaded("the leg held", Duration::from_secs(60), held_now);
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
    // localised again, still held until the operator retries. A request without an answer is
    // sent again: the same pose twice is taken once.
    let start = run.line_count();
    let set_pose = [
        "set-pose",
        &KIDNAPPED_TO.0.to_string(),
        &KIDNAPPED_TO.1.to_string(),
        "0",
    ];
    wait_until_loaded("the pose set", PATIENCE, || ctl(&addr, &set_pose).0);
    wait_until_loaded("localised again", Duration::from_secs(30), || {
        run.lines()
            .iter()
            .skip(start)
            .any(|line| line.contains("event localiser.localised"))
    });
    let mut status = None;
    wait_until_loaded("an answer to `ctl status`", PATIENCE, || {
        status = try_ctl_status(&addr);
        status.is_some()
    });
    assert!(
        status.is_some_and(|status| held(&status)),
        "the leg is still held"
    );
    // Aborted; an abort whose answer was lost ends the run all the same.
    wait_until_loaded("the abort taken", PATIENCE, || {
        !process_alive(run.pid()) || ctl(&addr, &["abort"]).0
    });
    run.wait_exit(loaded(Duration::from_secs(30)));
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

/// How far the pose a follower drives on may be from the truth before it counts as wrong, and
/// how far the robot may drive on a wrong one: the restart test's bounds.
const WRONG_M: f64 = 0.3;
const DRIVEN_WRONG_M: f64 = 0.1;

/// A localiser killed mid-run (as the supervisor's heartbeat kills one that stalls under load)
/// is restarted by the supervisor, and the new process starts where the robot is: from its
/// previous process's correction of odometry, which the run kept for it (`docs/protocol.md`,
/// `keep`), not from the world's start. Judged by the simulator's truth, from the recording:
/// the new process's estimates are within 0.3 m of the truth from its first one and through
/// its first 2 s of run time (the worst to the end is printed: that is the localiser's accuracy
/// on a loaded machine, not the restart's); the robot
/// never drives more than 0.1 m while the pose the follower drives on is more than 0.3 m off;
/// and the plan completes, its last leg arriving after the kill. Before, the new process began
/// at the world's start, 4 m behind the robot here, until the kidnap detector noticed.
#[test]
fn a_localiser_killed_mid_run_comes_back_where_the_robot_is() {
    let dir = tempfile::tempdir().unwrap();
    let map = workspace_root().join("tests/data/external/nav2_depot/depot-armor.yaml");
    let record = dir.path().join("truth.mcap");
    let system_file = dir.path().join("system.xml");
    let topics = "sim.pose_truth,localiser.estimate,localiser.pose";
    std::fs::write(&system_file, system(&map, &record, "", false, topics)).unwrap();
    let plan_file = dir.path().join("plan.xml");
    std::fs::write(&plan_file, plan_of(&system_file, &PLACES[..3])).unwrap();
    let report = dir.path().join("report.json");
    // Twice real time: the two legs (about 21 m at 0.5 m/s) take some 25 s.
    let mut run = armor_tests::Proc::start(
        std::process::Command::new(armor_tests::bin("armor"))
            .arg("run")
            .arg(&plan_file)
            .args(["--no-run-folder", "--time-scale", "2", "--report"])
            .arg(&report)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir()),
    );
    let addr = control_address(&run);
    let localiser = |status: &serde_json::Value| {
        status["modules"]
            .as_array()
            .and_then(|modules| modules.iter().find(|module| module["name"] == "localiser"))
            .cloned()
    };
    // Killed once it has published 100 estimates (10 s of scans, the robot on its first leg),
    // at a run time between `killed_at` and `killed_by`.
    let mut killed_at = 0.0;
    wait_until_loaded("100 estimates", Duration::from_secs(60), || {
        let Some(status) = try_ctl_status(&addr) else {
            return false;
        };
        let Some(module) = localiser(&status) else {
            return false;
        };
        let estimates = module["stats"]["sent"]["localiser.estimate"]
            .as_u64()
            .unwrap_or(0);
        let (true, Some(pid)) = (estimates >= 100, module["pid"].as_i64()) else {
            return false;
        };
        killed_at = status["run_secs"].as_f64().unwrap_or(0.0);
        armor_tests::signal(i32::try_from(pid).unwrap(), libc::SIGKILL);
        true
    });
    let mut killed_by = 0.0;
    wait_until_loaded("the run's time after the kill", PATIENCE, || {
        try_ctl_status(&addr)
            .and_then(|status| status["run_secs"].as_f64())
            .inspect(|&run_secs| killed_by = run_secs)
            .is_some()
    });
    wait_until_loaded("the localiser restarted", Duration::from_secs(30), || {
        try_ctl_status(&addr)
            .and_then(|status| localiser(&status))
            .is_some_and(|module| module["restarts"].as_u64().unwrap_or(0) >= 1)
            || !process_alive(run.pid())
    });
    let status = run.wait_exit(loaded(Duration::from_secs(120)));
    let lines = run.lines();
    assert!(status.success(), "{status}:\n{}", lines.join("\n"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(report["outcome"], "complete", "{report:#}");
    let arrived = report["timeline"]
        .as_array()
        .unwrap()
        .iter()
        .find(|entry| entry["kind"] == "fired" && entry["transition"] == "to_posts_arrived")
        .and_then(|entry| entry["at_secs"].as_f64())
        .unwrap_or_else(|| panic!("the last leg never arrived: {report:#}"));
    assert!(
        arrived > killed_at,
        "the plan was done ({arrived:.1} s) before the kill ({killed_at:.1} s)"
    );

    let truth = read_truth(&record);
    let truth_at = |time: f64| true_position_at(&truth, time);
    let estimates = read_estimates(&record);
    // The new process's estimates: those after the silence that followed the old one's last
    // (the restart takes a process's start and the map's loading, well over 0.5 s of run time).
    let silence = estimates
        .windows(2)
        .position(|pair| {
            pair[0].0 >= killed_at - 1.0 && pair[0].0 <= killed_by && pair[1].0 - pair[0].0 > 0.5
        })
        .unwrap_or_else(|| {
            panic!("no silence in the estimates at the kill ({killed_at:.1} to {killed_by:.1} s)")
        });
    let resumed = &estimates[silence + 1..];
    let off: Vec<(f64, f64)> = resumed
        .iter()
        .map(|(at, estimate)| {
            let p = estimate.pose_in_map;
            (*at, geo::distance(Point::new(p.x_m, p.y_m), truth_at(*at)))
        })
        .collect();
    // Back within 0.3 m from its first estimate, and over its first 2 s of run time.
    let first_secs = resumed.first().map_or(0.0, |(at, _)| *at);
    let early: Vec<f64> = off
        .iter()
        .filter(|(at, _)| *at <= first_secs + 2.0)
        .map(|(_, error)| *error)
        .collect();
    assert!(
        early.len() >= 5,
        "{} estimates in the restart's first 2 s",
        early.len()
    );
    let early_worst = early.iter().copied().fold(0.0, f64::max);
    assert!(
        early_worst <= WRONG_M,
        "after the restart at {first_secs:.1} s (killed between {killed_at:.1} and \
         {killed_by:.1} s) the estimate was {early_worst:.2} m from the truth (first {:.2} m)",
        early[0]
    );
    let worst = off.iter().map(|(_, error)| *error).fold(0.0, f64::max);
    // What the follower drove on: the latest pose at each true pose, the robot's true travel
    // counted while it was more than 0.3 m off.
    let poses: Vec<(f64, Point)> = read_topic(&record, "localiser.pose")
        .into_iter()
        .map(|(at, encoding, data)| {
            let odometry = match encoding.as_str() {
                "json" => serde_json::from_slice::<Odometry>(&data).unwrap(),
                _ => Odometry::decode(&data).unwrap(),
            };
            let p = odometry.pose_in_odom;
            (at, Point::new(p.x_m, p.y_m))
        })
        .collect();
    let mut driven_wrong = 0.0;
    for pair in truth.windows(2) {
        let (at, here) = pair[0];
        let believed = poses.iter().rev().find(|(when, _)| *when <= at);
        if believed.is_some_and(|(_, pose)| geo::distance(*pose, here) > WRONG_M) {
            driven_wrong += geo::distance(here, pair[1].1);
        }
    }
    assert!(
        driven_wrong <= DRIVEN_WRONG_M,
        "the robot drove {driven_wrong:.2} m on a pose more than {WRONG_M} m off"
    );
    eprintln!(
        "killed at {killed_at:.1} to {killed_by:.1} s; the new process's first estimate at \
         {first_secs:.1} s, {:.3} m off, {early_worst:.3} m at worst in its first 2 s, \
         {worst:.3} m at worst to the end; driven on a pose more than {WRONG_M} m off: \
         {driven_wrong:.3} m",
        early[0]
    );
}

/// Kidnapped with the localiser's `recover` on: lost, the leg holds, and the localiser searches
/// the map while the robot stands. The operator retries the leg: the follower does not drive on
/// the estimate the search found (not proven yet), it turns in place until the localiser proves
/// it by the turn, and only then drives the leg to its end. A search that settled on a place the
/// beams contradict searches again, lost, and the leg holds again: the operator retries each
/// time it holds, three times at most (the headless test of the same carrying,
/// `a_robot_searched_for_on_the_depot_map_is_proven_where_it_is_by_turning_in_place`, shows the
/// place the robot was put is told apart from its look-alikes among the posts), then aborts.
/// Judged by the simulator's truth: from each retry until the estimate is proven and
/// `localised`, the robot moves less than 0.1 m; then either the mission completes, arriving by
/// the truth, clear of the no-go area, or it held a fourth time for a reason the run states
/// (the leg's `lost` or `blocked` fired last, and the last estimate is lost or not proven).
/// Both outcomes are what a user should see: a loaded machine delays the scans (more than a
/// second, and the localiser goes on on odometry alone), and a search may then not finish.
#[test]
fn a_kidnapped_robot_retried_with_recovery_turns_in_place_until_its_place_is_proven() {
    let dir = tempfile::tempdir().unwrap();
    let (system_file, record) =
        kidnapped_system(dir.path(), true, "sim.pose_truth,localiser.estimate");
    let plan_file = dir.path().join("plan.xml");
    std::fs::write(&plan_file, plan_of(&system_file, &PLACES[..2])).unwrap();
    let report = dir.path().join("report.json");
    let mut run = armor_run(&plan_file, &report, &["--no-run-folder"]);
    let addr = control_address(&run);
    // Whether the leg is held; false once the run has ended (nothing answers).
    let held = || {
        let (ok, text) = ctl(&addr, &["status", "--json"]);
        let json = text.find('{').map_or("", |start| &text[start..]);
        ok && serde_json::from_str::<serde_json::Value>(json).is_ok_and(|status| {
            status["mission"]["marking"]["to_south_hold"]
                .as_u64()
                .unwrap_or(0)
                > 0
        })
    };
    let mut retries = 0;
    while process_alive(run.pid()) {
        wait_until(
            "the leg held, or the run ended",
            Duration::from_secs(300),
            || held() || !process_alive(run.pid()),
        );
        if !process_alive(run.pid()) {
            break;
        }
        if retries == 3 {
            // Held a fourth time: the operator gives up and ends the mission.
            let (ok, said) = ctl(&addr, &["abort"]);
            assert!(ok, "{said}");
            break;
        }
        retries += 1;
        let (ok, said) = ctl(&addr, &["fire", "to_south_retry"]);
        assert!(ok, "{said}");
        wait_until("the retry taken", Duration::from_secs(60), || {
            !held() || !process_alive(run.pid())
        });
    }
    let status = run.wait_exit(Duration::from_secs(60));
    let lines = run.lines();
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let fired: Vec<(String, f64)> = report["timeline"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|entry| entry["kind"] == "fired")
        .filter_map(|entry| {
            Some((
                entry["transition"].as_str()?.to_owned(),
                entry["run_secs"].as_f64()?,
            ))
        })
        .collect();
    let retried: Vec<f64> = fired
        .iter()
        .filter(|(name, _)| name == "to_south_retry")
        .map(|(_, at)| *at)
        .collect();
    assert!(!retried.is_empty(), "never retried: {report:#}");
    let estimates = read_estimates(&record);
    let truth = read_truth(&record);
    let truth_at = |time: f64| true_position_at(&truth, time);
    let end_secs = truth.last().map_or(0.0, |(at, _)| *at);
    // From each retry until the estimate is proven and localised (or the next retry, or the
    // end), the robot turns in place at most.
    let mut proven_after = Vec::new();
    for (i, &at_retry) in retried.iter().enumerate() {
        let until = retried.get(i + 1).copied().unwrap_or(end_secs);
        let proven_at = estimates
            .iter()
            .find(|(at, estimate)| {
                *at >= at_retry
                    && *at < until
                    && estimate.state == LocalisationState::Localised
                    && estimate.proven
            })
            .map(|(at, _)| *at);
        let from = truth_at(at_retry);
        let window: Vec<Point> = truth
            .iter()
            .filter(|(at, _)| *at >= at_retry && *at <= proven_at.unwrap_or(until))
            .map(|(_, p)| *p)
            .collect();
        assert!(
            window.len() > 10,
            "{} true poses recorded after retry {} ({at_retry:.1} s; the truth runs from {:.1} \
             to {end_secs:.1} s)",
            window.len(),
            i + 1,
            truth[0].0
        );
        let moved = window
            .iter()
            .map(|p| geo::distance(*p, from))
            .fold(0.0, f64::max);
        eprintln!(
            "retry {} at {at_retry:.1} s: proven and localised {} having moved {moved:.3} m \
             ({} true poses)",
            i + 1,
            proven_at.map_or("never after it".to_owned(), |at| format!(
                "{:.1} s later",
                at - at_retry
            )),
            window.len()
        );
        assert!(
            moved < 0.1,
            "after retry {} the robot moved {moved:.3} m on an unproven estimate",
            i + 1
        );
        proven_after.push(proven_at);
    }
    let closest = closest_to(&no_go_area(), &truth);
    assert!(
        closest > 0.0,
        "the footprint met the no-go area ({closest:.2} m)"
    );
    if report["outcome"] == "complete" {
        assert!(status.success(), "{status}:\n{}", lines.join("\n"));
        let (_, arrived) = fired
            .iter()
            .rev()
            .find(|(name, _)| name == "to_south_arrived")
            .unwrap_or_else(|| panic!("`to_south_arrived` never fired: {report:#}"));
        let (_, at_arrival) = truth
            .iter()
            .min_by(|a, b| (a.0 - arrived).abs().total_cmp(&(b.0 - arrived).abs()))
            .unwrap();
        let error = geo::distance(*at_arrival, Point::new(PLACES[1].1, PLACES[1].2));
        eprintln!(
            "completed after {} retry(ies): arrived {error:.3} m from `south`; closest footprint \
             to the no-go area {closest:.2} m",
            retried.len()
        );
        assert!(
            proven_after.last().is_some_and(Option::is_some),
            "completed without a proven estimate after the last retry"
        );
        assert!(error <= TOLERANCE_M, "arrived {error:.3} m from `south`");
    } else {
        // Held a fourth time and aborted: the run says why it held (the leg's `lost` or
        // `blocked` fired last), and the localiser agrees (lost, or not proven).
        assert_eq!(report["outcome"], "aborted", "{report:#}");
        let (why, _) = fired
            .iter()
            .rev()
            .find(|(name, _)| name.starts_with("to_south_") && name != "to_south_retry")
            .unwrap_or_else(|| panic!("no reason fired for the hold: {report:#}"));
        let (_, last) = estimates.last().expect("estimates recorded");
        eprintln!(
            "held a fourth time ({why}) and aborted; the last estimate {:?}, proven {}",
            last.state, last.proven
        );
        assert!(
            why == "to_south_lost" || why == "to_south_blocked",
            "held after `{why}`"
        );
        assert!(
            last.state == LocalisationState::Lost || !last.proven,
            "held with a proven estimate: {last:?}"
        );
    }
}
