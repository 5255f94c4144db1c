//! Navigation on the map (issue 26), as a user would meet it: real `armor check` and `armor
//! compile` on plan files, real `armor run` of the simulated robot (sim, follower, avoider) at
//! accelerated time, files in a temporary folder.
//!
//! * The warehouse (`missions/robot/plan-warehouse.xml`): a no-go area leaves 1 m between it and
//!   the shelves, too narrow; the plan goes the wide way round and the robot, in truth (the sim's
//!   `pose_truth`, recorded), does too.
//! * An obstacle in the sim only (its `obstacles` parameter, not the world file): the follower's
//!   laser sees it, it replans round it and arrives. Its new path keeps what the plan was
//!   checked with: a no-go area's own margin, and the plan's robot (larger than the sim's).
//! * Seeded random worlds: every leg the planner finds a way for is driven to its end without a
//!   collision; every leg it finds none for is refused by `armor check`, named, with the narrowest
//!   passage or where the way is closed. The robots of these runs have exact odometry (nothing
//!   corrects a drifting one yet: see `missions/robot/system-warehouse.xml`).
//! * Bad places at check time, beyond `plans.rs`: a waypoint inside an obstacle, one too near a
//!   shelf, a start within a no-go area's margin: each a `FILE:LINE:COL:` error, all at once, and
//!   `armor run` refuses the plan before starting anything.
#![allow(clippy::unwrap_used)]

use std::ffi::OsStr;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};

use armor_model::MissionNet;
use armor_model::geo::{self, LatLon};
use armor_model::planner::random::{self, RandomWorld, SplitMix64};
use armor_model::planner::{Costmap, CostmapSettings, PathError, Planner, Robot};
use armor_model::world::{Point, World};
use armor_module_api::Datum as _;
use armor_module_api::types::Pose2D;
use armor_tests::check::{armor, assert_refused, line_of, located, output_text};
use armor_tests::mcap::read_mcap;
use armor_tests::mission::{Finished, armor_run, run_mission};
use armor_tests::workspace_root;

/// How long one robot's run may take in real time: the warehouse round is three minutes of run
/// time, ten seconds at the tests' time scale on an idle machine.
const RUN_DEADLINE: Duration = Duration::from_secs(120);

/// The whole robots of this file run one test at a time (each is half a dozen processes, the
/// machines have two cores, and a starved follower reports `blocked`); the random worlds run a
/// few at a time within their test.
static ROBOTS: Mutex<()> = Mutex::new(());

fn robot_file(name: &str) -> PathBuf {
    workspace_root().join("missions/robot").join(name)
}

fn path_arg(path: &Path) -> &OsStr {
    path.as_os_str()
}

/// The points of a `path` parameter (`X,Y X,Y …`).
fn points(path: &str) -> Vec<Point> {
    armor_model::planner::Path::parse(path).unwrap().points
}

/// The follower's `path` in the place `place` of a compiled mission.
fn compiled_path(net: &MissionNet, place: &str) -> Vec<Point> {
    let place = net
        .place(place)
        .unwrap_or_else(|| panic!("no place `{place}`"));
    let param = place
        .params
        .iter()
        .find(|param| param.module == "follower" && param.name == "path")
        .unwrap_or_else(|| panic!("no path in {place:?}"));
    points(&param.value)
}

/// The sim's true poses a recorder wrote, in time order (the robot's camera, recorded beside
/// them, is skipped).
fn read_truth(file: &Path) -> Vec<Point> {
    let mut truth = Vec::new();
    for ((topic, encoding), messages) in read_mcap(file) {
        if topic == "camera.image" {
            continue;
        }
        assert_eq!(topic, "sim.pose_truth");
        for (log_time, data) in messages {
            let pose = match encoding.as_str() {
                "json" => serde_json::from_slice::<Pose2D>(&data).unwrap(),
                _ => Pose2D::decode(&data).unwrap(),
            };
            truth.push((log_time, Point::new(pose.x_m, pose.y_m)));
        }
    }
    truth.sort_by_key(|(at, _)| *at);
    truth.into_iter().map(|(_, at)| at).collect()
}

/// `text` with its `system` attribute made absolute (it names a file in `missions/robot/`) and
/// its recorders writing uncompressed into `dir`.
fn relocated_plan(text: &str, dir: &Path) -> String {
    let system = text
        .split("system=\"")
        .nth(1)
        .and_then(|rest| rest.split('"').next())
        .unwrap();
    let mut text = text.replacen(
        &format!("system=\"{system}\""),
        &format!("system=\"{}\"", robot_file(system).display()),
        1,
    );
    let key = "<param name=\"file\" value=\"";
    if let Some(found) = text.find(key) {
        let start = found + key.len();
        let end = start + text[start..].find("\"/>").unwrap();
        let file = dir.join(&text[start..end]);
        text.replace_range(
            start..end,
            &format!(
                "{}\"/><param name=\"compression\" value=\"none",
                file.display()
            ),
        );
    }
    text
}

/// Runs `plan` to its end (it must complete within [`RUN_DEADLINE`], the robot never touching
/// anything nor being blocked), one robot at a time.
fn run_plan(plan: &Path) -> Finished {
    let run = {
        let _one = ROBOTS.lock().unwrap_or_else(PoisonError::into_inner);
        run_mission(plan, &[], RUN_DEADLINE)
    };
    assert_eq!(
        run.final_marking(),
        serde_json::json!({ "done": 1 }),
        "{:?}",
        run.fired()
    );
    run.assert_clean();
    run
}

// The warehouse (assets/worlds/warehouse.world): the spill is fenced off at x 14 to 20, y 15 to
// 17.5; the north row of shelving ends at y 14, the north wall is at y 20.
const SPILL: (f64, f64, f64, f64) = (14.0, 20.0, 15.0, 17.5);

#[test]
fn the_warehouse_round_goes_the_wide_way_round_the_spill() {
    let started = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(robot_file("plan-warehouse.xml")).unwrap();
    let plan = dir.path().join("plan-warehouse.xml");
    std::fs::write(&plan, relocated_plan(&text, dir.path())).unwrap();

    let output = armor(&["check".as_ref(), path_arg(&plan)]);
    assert!(output.status.success(), "{}", output_text(&output));

    // The plan: the third leg's path passes the spill on its north side, with its margin.
    let mission = dir.path().join("mission.xml");
    let output = armor(&[
        "compile".as_ref(),
        path_arg(&plan),
        "-o".as_ref(),
        path_arg(&mission),
    ]);
    assert!(output.status.success(), "{}", output_text(&output));
    let net = MissionNet::parse(&std::fs::read_to_string(&mission).unwrap()).unwrap();
    let path = compiled_path(&net, "back_west_drive");
    let (x0, x1, _, north) = SPILL;
    let mut beside = 0;
    for pair in path.windows(2) {
        for step in 0..=100 {
            let t = f64::from(step) / 100.0;
            let p = Point::new(
                pair[0].x + (pair[1].x - pair[0].x) * t,
                pair[0].y + (pair[1].y - pair[0].y) * t,
            );
            if (x0..=x1).contains(&p.x) {
                beside += 1;
                // The area's margin (0.5 m) and the robot's radius (0.25 m) north of it.
                assert!(p.y >= north + 0.75 - 0.01, "{p} on {path:?}");
            }
        }
    }
    assert!(beside > 0, "{path:?}");

    // The run: four legs, arrived in order, and in truth the robot passed north of the spill.
    let run = run_plan(&plan);
    assert_eq!(
        run.fired_names(),
        [
            "main_aisle_arrived",
            "through_arrived",
            "back_west_arrived",
            "return_arrived"
        ]
    );
    let truth = read_truth(&dir.path().join("warehouse-round.mcap"));
    let passing: Vec<Point> = truth
        .iter()
        .copied()
        .filter(|p| (x0..=x1).contains(&p.x) && p.y > 14.0)
        .collect();
    assert!(
        passing.len() > 10,
        "the robot never passed the spill: {}",
        passing.len()
    );
    let lowest = passing.iter().map(|p| p.y).fold(f64::INFINITY, f64::min);
    // The robot's footprint (0.25 m round its centre), not only its centre, stays out.
    assert!(
        lowest - 0.25 > north,
        "the robot came down to y = {lowest} beside the spill (its north edge is at {north})"
    );
    // With the simulator's default noise, driving on the localiser's pose, the truth came
    // within the follower's tolerance plus 0.1 m of every leg's goal, in order, and ended there.
    let goals: Vec<Point> = ["main_aisle", "through", "back_west", "return"]
        .iter()
        .map(|leg| {
            let place = net.place(&format!("{leg}_drive")).unwrap();
            let param = |name: &str| -> f64 {
                place
                    .params
                    .iter()
                    .find(|p| p.module == "follower" && p.name == name)
                    .unwrap()
                    .value
                    .parse()
                    .unwrap()
            };
            Point::new(param("goal_x_m"), param("goal_y_m"))
        })
        .collect();
    let mut next = 0;
    let mut closest = f64::INFINITY;
    for p in &truth {
        if let Some(goal) = goals.get(next) {
            closest = closest.min(geo::distance(*p, *goal));
            if geo::distance(*p, *goal) <= 0.4 {
                next += 1;
                closest = f64::INFINITY;
            }
        }
    }
    assert_eq!(
        next,
        goals.len(),
        "the truth came within 0.4 m of the first {next} goals only ({closest:.2} m from the next)"
    );
    let end = truth.last().unwrap();
    let last = geo::distance(*end, goals[3]);
    assert!(last <= 0.4, "the robot ended {last:.2} m from home");
    eprintln!(
        "warehouse: passed the spill at y {lowest:.2} at the lowest; {:.1} s",
        started.elapsed().as_secs_f64()
    );
}

#[test]
fn an_obstacle_the_map_does_not_have_is_seen_and_driven_round() {
    let started = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    // The warehouse robot, with a pallet left in the middle of the main aisle, 1.5 m from the
    // shelves on either side: the sim has it, the world file (and so the plan) does not.
    let system = std::fs::read_to_string(robot_file("system-warehouse.xml")).unwrap();
    let pallet = "rect 19,9 21,11";
    let system = system.replacen(
        "<param name=\"world\" value=\"warehouse.world\"/>",
        &format!(
            "<param name=\"world\" value=\"warehouse.world\"/>\n    \
             <param name=\"obstacles\" value=\"{pallet}\"/>"
        ),
        1,
    );
    assert!(system.contains(pallet));
    let system_file = dir.path().join("system.xml");
    std::fs::write(&system_file, system).unwrap();
    let origin = LatLon::new(43.6045, 1.4425);
    let waypoint = |name: &str, x: f64, y: f64| {
        let at = LatLon::from_local(Point::new(x, y), origin);
        format!(
            "  <waypoint name=\"{name}\" lat=\"{:.8}\" lon=\"{:.8}\"/>\n",
            at.lat_deg, at.lon_deg
        )
    };
    let plan = dir.path().join("pallet.xml");
    std::fs::write(
        &plan,
        format!(
            "<plan name=\"pallet\" system=\"{}\">\n  <navigation><module name=\"avoider\"/></navigation>\n\
             <throughout><module name=\"recorder\"><param name=\"file\" value=\"{}\"/>\
             <param name=\"compression\" value=\"none\"/></module></throughout>\n{}{}\
             \x20 <leg name=\"down_the_aisle\" from=\"home\" to=\"east\"/>\n</plan>\n",
            system_file.display(),
            dir.path().join("truth.mcap").display(),
            waypoint("home", 3.0, 10.0),
            waypoint("east", 40.0, 10.0),
        ),
    )
    .unwrap();

    // The plan knows nothing of the pallet: its path is the straight line along the aisle.
    let output = armor(&["check".as_ref(), path_arg(&plan)]);
    assert!(output.status.success(), "{}", output_text(&output));

    let run = run_plan(&plan);
    assert_eq!(run.fired_names(), ["down_the_aisle_arrived"]);
    assert!(
        run.any_line(|line| line.starts_with("[follower]") && line.contains("replanned:")),
        "the follower never replanned:\n{}",
        run.lines.join("\n")
    );
    // In truth the robot went past the pallet on one side or the other, and on to the end.
    let truth = read_truth(&dir.path().join("truth.mcap"));
    let beside: Vec<Point> = truth
        .iter()
        .copied()
        .filter(|p| (19.0..=21.0).contains(&p.x))
        .collect();
    assert!(!beside.is_empty(), "never passed x 19 to 21");
    for p in &beside {
        assert!(
            p.y < 9.0 - 0.25 || p.y > 11.0 + 0.25,
            "at {p}, the robot's disc overlaps the pallet"
        );
    }
    assert!(truth.last().unwrap().x > 38.0, "{:?}", truth.last());
    eprintln!(
        "pallet: passed it at y {:.2}; {:.1} s",
        beside[0].y,
        started.elapsed().as_secs_f64()
    );
}

/// A robot system on the world file `world`, written in `dir` (its file): sim, follower and
/// avoider, the sim's odometry exact (this robot knows where it is: what is tested is the
/// planning, the following and the replanning, not the dead reckoning) and its noise seeded by
/// `seed`, with `sim_params` (`<param …/>` lines) added to the sim.
fn robot_system(dir: &Path, world: &Path, seed: u64, sim_params: &str) -> PathBuf {
    let system = dir.join("system.xml");
    std::fs::write(
        &system,
        format!(
            r#"<system name="robot">
  <module name="sim" type="sim">
    <param name="world" value="{world}"/>
    <param name="seed" value="{seed}"/>
    <param name="odom_noise_dist" value="0"/>
    <param name="odom_noise_rot" value="0"/>
    <param name="odom_noise_drift" value="0"/>
    {sim_params}
  </module>
  <module name="follower" type="follower">
    <param name="world" value="{world}"/>
    <param name="goal_x_m" value="0"/>
    <param name="goal_y_m" value="0"/>
    <param name="blocked_after_secs" value="20"/>
  </module>
  <module name="avoider" type="avoider"/>
  <module name="recorder" type="recorder">
    <param name="record" value="sim.pose_truth"/>
    <param name="file" value="{truth}"/>
    <param name="compression" value="none"/>
  </module>
  <link from="sim.odometry" to="follower.odometry"/>
  <link from="sim.scan" to="avoider.scan"/>
  <link from="sim.scan" to="follower.scan"/>
  <link from="follower.cmd_desired" to="avoider.cmd_desired"/>
  <link from="avoider.cmd_vel" to="sim.cmd_vel"/>
</system>
"#,
            world = world.display(),
            truth = dir.join("truth.mcap").display(),
        ),
    )
    .unwrap();
    system
}

/// A hall 40 m × 12 m (start at (2, 3) facing east), a no-go area in it with a margin of 3 m
/// (x 18 to 22, y 5 to 8: the robot's centre keeps 3.25 m off, so south of it below y 1.75),
/// and a pallet only the sim has, across the way the plan takes south of the area (x 14 to 15,
/// y 0 to 2): the follower replans round the pallet, and its new path must keep the area's own
/// margin, not a default one (with 0.75 m, it would pass at 2 to 2.5 m from the area).
#[test]
fn a_replanned_path_keeps_the_no_go_area_s_own_margin() {
    let started = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let world = dir.path().join("hall.world");
    std::fs::write(
        &world,
        "name Hall\norigin 43.6 1.44\nstart 2 3 0\nboundary 0,0 40,0 40,12 0,12 0,0\n",
    )
    .unwrap();
    let system = robot_system(
        dir.path(),
        &world,
        26,
        r#"<param name="obstacles" value="rect 14,0 15,2"/>"#,
    );
    let origin = LatLon::new(43.6, 1.44);
    let at = |x: f64, y: f64| {
        let at = LatLon::from_local(Point::new(x, y), origin);
        format!("lat=\"{:.8}\" lon=\"{:.8}\"", at.lat_deg, at.lon_deg)
    };
    let plan = dir.path().join("hall.xml");
    std::fs::write(
        &plan,
        format!(
            "<plan name=\"hall\" system=\"{}\">\n  <navigation><module name=\"avoider\"/></navigation>\n\
             <throughout><module name=\"recorder\"/></throughout>\n\
             \x20 <waypoint name=\"west\" {}/>\n  <waypoint name=\"east\" {}/>\n\
             \x20 <leg name=\"across\" from=\"west\" to=\"east\"/>\n\
             \x20 <area name=\"pit\" kind=\"no-go\" margin_m=\"3\">\n\
             \x20   <point {}/><point {}/><point {}/><point {}/>\n  </area>\n</plan>\n",
            system.display(),
            at(2.0, 3.0),
            at(36.0, 3.0),
            at(18.0, 5.0),
            at(22.0, 5.0),
            at(22.0, 8.0),
            at(18.0, 8.0),
        ),
    )
    .unwrap();
    let output = armor(&["check".as_ref(), path_arg(&plan)]);
    assert!(output.status.success(), "{}", output_text(&output));

    let run = run_plan(&plan);
    assert_eq!(run.fired_names(), ["across_arrived"]);
    assert!(
        run.any_line(|line| line.starts_with("[follower]") && line.contains("replanned:")),
        "the follower never replanned:\n{}",
        run.lines.join("\n")
    );
    let truth = read_truth(&dir.path().join("truth.mcap"));
    let pit = armor_model::geo::Polygon::new(vec![
        Point::new(18.0, 5.0),
        Point::new(22.0, 5.0),
        Point::new(22.0, 8.0),
        Point::new(18.0, 8.0),
    ]);
    let nearest = truth
        .iter()
        .map(|p| pit.distance_to_outline(*p))
        .fold(f64::INFINITY, f64::min);
    // 3.25 m for the centre, less what pure pursuit cuts off the path's corners.
    assert!(
        nearest > 3.0,
        "the robot came {nearest:.2} m from the area, inside its margin:\n{}",
        run.lines
            .iter()
            .filter(|line| line.starts_with("[follower]"))
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
    eprintln!(
        "margin: the robot kept {nearest:.2} m from the area; {:.1} s",
        started.elapsed().as_secs_f64()
    );
}

/// The robot of a plan that says it is larger than the sim's (carrying a load: a radius of
/// 0.45 m, so it keeps 0.55 m from obstacles), in a hall 40 m × 12 m, from (2, 4) to (36, 4).
/// A block only the sim has stands across the way (x 18 to 19, y 1 to 9): 1 m between it and
/// the south wall, which the plan's robot does not fit through, and 3 m to the north wall. The
/// follower replans for the plan's robot, so it goes north, though south is shorter.
#[test]
fn a_replanned_path_is_for_the_plan_s_robot() {
    let started = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let world = dir.path().join("hall.world");
    std::fs::write(
        &world,
        "name Hall\norigin 43.6 1.44\nstart 2 4 0\nboundary 0,0 40,0 40,12 0,12 0,0\n",
    )
    .unwrap();
    let system = robot_system(
        dir.path(),
        &world,
        45,
        r#"<param name="obstacles" value="rect 18,1 19,9"/>"#,
    );
    let origin = LatLon::new(43.6, 1.44);
    let at = |x: f64, y: f64| {
        let at = LatLon::from_local(Point::new(x, y), origin);
        format!("lat=\"{:.8}\" lon=\"{:.8}\"", at.lat_deg, at.lon_deg)
    };
    let plan = dir.path().join("loaded.xml");
    std::fs::write(
        &plan,
        format!(
            "<plan name=\"loaded\" system=\"{}\">\n  <navigation robot_radius_m=\"0.45\">\
             <module name=\"avoider\"/></navigation>\n\
             <throughout><module name=\"recorder\"/></throughout>\n\
             \x20 <waypoint name=\"west\" {}/>\n  <waypoint name=\"east\" {}/>\n\
             \x20 <leg name=\"across\" from=\"west\" to=\"east\"/>\n</plan>\n",
            system.display(),
            at(2.0, 4.0),
            at(36.0, 4.0),
        ),
    )
    .unwrap();
    let output = armor(&["check".as_ref(), path_arg(&plan)]);
    assert!(output.status.success(), "{}", output_text(&output));

    let run = run_plan(&plan);
    assert_eq!(run.fired_names(), ["across_arrived"]);
    let truth = read_truth(&dir.path().join("truth.mcap"));
    let passing: Vec<Point> = truth
        .iter()
        .copied()
        .filter(|p| (18.0..=19.0).contains(&p.x))
        .collect();
    assert!(!passing.is_empty(), "never passed the block");
    assert!(
        passing.iter().all(|p| p.y > 9.0),
        "the robot went through the 1 m gap, too narrow for the plan's robot: {:?}\n{}",
        passing.first(),
        run.lines
            .iter()
            .filter(|line| line.starts_with("[follower]"))
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
    eprintln!(
        "robot: passed the block at y {:.2}; {:.1} s",
        passing[0].y,
        started.elapsed().as_secs_f64()
    );
}

/// The random worlds' seed: the worlds, their places and the sim's noise follow from it.
const SEED: u64 = 2611;
const WORLDS: usize = 30;
/// Places per world: the start and eleven more, so eleven legs for `armor check`…
const PLACES: usize = 12;
/// … of which the first three (the places among the first four that the start reaches) are
/// driven.
const DRIVEN_PLACES: usize = 4;
/// Robots run side by side (each about half a core at the tests' time scale).
const PARALLEL_RUNS: usize = 3;
const ORIGIN: (f64, f64) = (43.6, 1.44);

/// One random world, its places, and what the planner says of each leg between them.
struct Case {
    index: usize,
    world_text: String,
    places: Vec<Point>,
    /// Whether the planner finds a way for each leg `places[i]` → `places[i + 1]`.
    connected: Vec<bool>,
    /// Whether each place can be reached from the start.
    reachable: Vec<bool>,
}

impl Case {
    fn draw(index: usize) -> Case {
        let mut rng = SplitMix64(SEED.wrapping_add(index as u64));
        let random = RandomWorld {
            origin: ORIGIN,
            ..RandomWorld::default()
        };
        let body = random.obstacles_text(&mut rng);
        let world = World::parse(&random.file_text("random", &body), "random.world").unwrap();
        let costmap =
            Costmap::for_world(&world, &Robot::default(), &[], &CostmapSettings::default())
                .unwrap();
        let mut planner = Planner::new(costmap);
        let places: Vec<Point> = (0..PLACES)
            .map(|_| random::free_place(&mut rng, planner.costmap(), random.side_m))
            .collect();
        let mut way = |a: Point, b: Point| match planner.plan(a, b) {
            Ok(_) => true,
            Err(PathError::Cut(_)) => false,
            Err(other) => panic!("world {index}: {a} to {b}: {other}"),
        };
        let connected = places
            .windows(2)
            .map(|pair| way(pair[0], pair[1]))
            .collect();
        let reachable = places.iter().map(|&p| way(places[0], p)).collect();
        let start = (places[0].x, places[0].y, 0.0);
        let world_text =
            RandomWorld { start, ..random }.file_text(&format!("random {index}"), &body);
        Case {
            index,
            world_text,
            places,
            connected,
            reachable,
        }
    }

    fn name(&self) -> String {
        format!("seed {SEED}, world {}", self.index)
    }

    /// The world, a robot system on it, and a plan through `places` (indices into
    /// `self.places`), written in `dir`; the plan's file and text.
    fn write(&self, dir: &Path, plan_name: &str, places: &[usize]) -> (PathBuf, String) {
        let world = dir.join("random.world");
        std::fs::write(&world, &self.world_text).unwrap();
        let system = robot_system(dir, &world, SEED + self.index as u64, "");
        let origin = LatLon::new(ORIGIN.0, ORIGIN.1);
        let mut text = format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<plan name=\"{plan_name}\" system=\"{}\">\n  \
             <navigation><module name=\"avoider\"/></navigation>\n",
            system.display()
        );
        for &i in places {
            let at = LatLon::from_local(self.places[i], origin);
            text.push_str(&format!(
                "  <waypoint name=\"p{i}\" lat=\"{:.9}\" lon=\"{:.9}\"/>\n",
                at.lat_deg, at.lon_deg
            ));
        }
        for pair in places.windows(2) {
            text.push_str(&format!(
                "  <leg name=\"leg{}_{}\" from=\"p{}\" to=\"p{}\"/>\n",
                pair[0], pair[1], pair[0], pair[1]
            ));
        }
        // A blocked leg is skipped: the run ends, and the report says which.
        text.push_str("  <contingency on=\"blocked\" do=\"skip\"/>\n</plan>\n");
        let file = dir.join(format!("{plan_name}.xml"));
        std::fs::write(&file, &text).unwrap();
        (file, text)
    }

    /// `armor check` of the plan through all the places: it refuses exactly the legs the planner
    /// finds no way for, each at its line with the narrowest passage or where the way is
    /// closed. The number of legs refused.
    fn check(&self, dir: &Path) -> Result<usize, String> {
        let all: Vec<usize> = (0..PLACES).collect();
        let (file, text) = self.write(dir, "all", &all);
        let output = armor(&["check".as_ref(), path_arg(&file)]);
        let problems = located(&output, &file);
        let cut = self.connected.iter().filter(|c| !**c).count();
        let context = || format!("{}:\n{}\n{text}", self.name(), output_text(&output));
        if output.status.success() != (cut == 0) || problems.len() != cut {
            return Err(format!("expected {cut} leg(s) refused; {}", context()));
        }
        for (i, _) in self.connected.iter().enumerate().filter(|(_, c)| !**c) {
            let leg = format!("leg{}_{}", i, i + 1);
            let line = line_of(&text, &format!("name=\"{leg}\""));
            let says = |message: &str| {
                message.starts_with(&format!("leg `{leg}`: no way from `p{i}` to `p{}`", i + 1))
                    && (message.contains("the narrowest passage is")
                        || message.contains("the way is closed at"))
            };
            if !problems
                .iter()
                .any(|(at, col, message)| *at == line && *col > 0 && says(message))
            {
                return Err(format!(
                    "leg `{leg}` not refused at line {line}; {}",
                    context()
                ));
            }
        }
        Ok(cut)
    }

    /// Drives the places reachable from the start, in order: every leg must arrive, with no
    /// collision and no `blocked`. The number of legs driven.
    fn drive(&self, dir: &Path) -> Result<usize, String> {
        let places: Vec<usize> = (0..DRIVEN_PLACES).filter(|&i| self.reachable[i]).collect();
        if places.len() < 2 {
            return Ok(0);
        }
        let (file, text) = self.write(dir, "reachable", &places);
        let report = dir.join("report.json");
        let mut run = armor_run(&file, &report, &[]);
        let status = run.wait_exit(RUN_DEADLINE);
        let lines = run.lines();
        if !status.success() {
            return Err(format!(
                "armor run: {status}; {}:\n{}\n{text}",
                self.name(),
                lines.join("\n")
            ));
        }
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
        let run = Finished { lines, report };
        let context = || format!("{}:\n{}\n{text}", self.name(), run.lines.join("\n"));
        let arrived: Vec<String> = places
            .windows(2)
            .map(|pair| format!("leg{}_{}_arrived", pair[0], pair[1]))
            .collect();
        if run.fired_names() != arrived {
            return Err(format!(
                "fired {:?}, expected {arrived:?}; {}",
                run.fired_names(),
                context()
            ));
        }
        if run.any_line(|line| line.contains("event sim.collision")) {
            return Err(format!("a collision; {}", context()));
        }
        Ok(places.len() - 1)
    }
}

#[test]
fn random_worlds_seed_2611_are_driven_where_there_is_a_way_and_refused_where_not() {
    let started = Instant::now();
    let next = AtomicUsize::new(0);
    let totals = Mutex::new((0, 0, Vec::<String>::new()));
    let _robots = ROBOTS.lock().unwrap_or_else(PoisonError::into_inner);
    std::thread::scope(|scope| {
        for _ in 0..PARALLEL_RUNS {
            scope.spawn(|| {
                loop {
                    let index = next.fetch_add(1, Ordering::Relaxed);
                    if index >= WORLDS {
                        return;
                    }
                    let case = Case::draw(index);
                    let places: Vec<String> = case.places.iter().map(ToString::to_string).collect();
                    let cut: Vec<usize> = (0..PLACES - 1).filter(|&i| !case.connected[i]).collect();
                    eprintln!(
                        "{}: places {}; legs with no way (from place i to i + 1): {cut:?}",
                        case.name(),
                        places.join(" "),
                    );
                    let dir = tempfile::tempdir().unwrap();
                    let outcome = catch_unwind(AssertUnwindSafe(|| {
                        let cut = case.check(dir.path())?;
                        let driven = case.drive(dir.path())?;
                        Ok::<_, String>((driven, cut))
                    }))
                    .unwrap_or_else(|panic| {
                        Err(format!(
                            "{}: {}",
                            case.name(),
                            panic
                                .downcast_ref::<String>()
                                .cloned()
                                .or_else(|| panic.downcast_ref::<&str>().map(|s| (*s).to_owned()))
                                .unwrap_or_default()
                        ))
                    });
                    let mut totals = totals.lock().unwrap_or_else(PoisonError::into_inner);
                    match outcome {
                        Ok((driven, cut)) => {
                            totals.0 += driven;
                            totals.1 += cut;
                        }
                        Err(failure) => totals.2.push(failure),
                    }
                }
            });
        }
    });
    let (driven, cut, failures) = totals.into_inner().unwrap();
    eprintln!(
        "random worlds (seed {SEED}): {driven} legs driven to the goal, {cut} legs with no way \
         refused by armor check, {} failures; {:.1} s",
        failures.len(),
        started.elapsed().as_secs_f64()
    );
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
    // Both kinds happen, so that both checks prove something.
    assert!(driven >= WORLDS && cut > 0, "{driven} driven, {cut} cut");
}

#[test]
fn bad_places_in_the_warehouse_are_refused_at_check_time_all_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let origin = LatLon::new(43.6045, 1.4425);
    let waypoint = |name: &str, x: f64, y: f64| {
        let at = LatLon::from_local(Point::new(x, y), origin);
        format!(
            "  <waypoint name=\"{name}\" lat=\"{:.8}\" lon=\"{:.8}\"/>\n",
            at.lat_deg, at.lon_deg
        )
    };
    let corner = |x: f64, y: f64| {
        let at = LatLon::from_local(Point::new(x, y), origin);
        format!(
            "    <point lat=\"{:.8}\" lon=\"{:.8}\"/>\n",
            at.lat_deg, at.lon_deg
        )
    };
    // The start (3, 10) is 0.5 m west of a no-go area whose margin is 1 m; a waypoint on a
    // column (a circle of radius 0.3 at (24, 1)); one 0.2 m north of the north row of shelves
    // (y 14); and a goal out through the east wall.
    let text = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<plan name=\"bad\" system=\"{}\">\n{}{}{}{}{}\
         \x20 <leg name=\"to_the_column\" from=\"home\" to=\"column\"/>\n\
         \x20 <leg name=\"to_the_shelf\" from=\"column\" to=\"shelf\"/>\n\
         \x20 <leg name=\"out\" from=\"shelf\" to=\"yard\"/>\n\
         \x20 <area name=\"wet_floor\" kind=\"no-go\" margin_m=\"1\">\n{}{}{}{}  </area>\n</plan>\n",
        robot_file("system-warehouse.xml").display(),
        waypoint("home", 3.0, 10.0),
        waypoint("column", 24.1, 1.0),
        waypoint("shelf", 10.0, 14.2),
        waypoint("yard", 53.0, 10.0),
        "",
        corner(3.5, 9.0),
        corner(5.0, 9.0),
        corner(5.0, 11.0),
        corner(3.5, 11.0),
    );
    let file = dir.path().join("bad.xml");
    std::fs::write(&file, &text).unwrap();
    let output = armor(&["check".as_ref(), path_arg(&file)]);
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"home\""),
        &[
            "waypoint `home` at (3, 10) m is 0.5 m from the no-go area `wet_floor`",
            "the robot keeps 1.25 m from it (radius 0.25 m and margin 1 m)",
        ],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"column\""),
        &[
            "waypoint `column` at (24.1, 1) m is inside the obstacle on line 19 of the world `Warehouse`",
        ],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"shelf\""),
        &[
            "waypoint `shelf` at (10, 14.2) m is 0.2 m from the obstacle on line 14 of the world `Warehouse`",
            "the robot keeps 0.35 m from obstacles",
        ],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"yard\""),
        &[
            "waypoint `yard` is outside the world `Warehouse`",
            "0 to 50 m east",
        ],
    );
    // Those four and nothing else: the legs whose ends are misplaced are not planned.
    assert_eq!(located(&output, &file).len(), 4, "{}", output_text(&output));
    // `armor run` refuses it the same way, before starting anything.
    let output = armor(&["run".as_ref(), path_arg(&file)]);
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"column\""),
        &["inside the obstacle"],
    );
    assert!(
        !output_text(&output).contains("[sim]"),
        "{}",
        output_text(&output)
    );
}
