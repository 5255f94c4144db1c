//! Mission plans (issue 5), as a user would use them: the four example plans of
//! `missions/robot/` run headless by `armor run PLAN` at accelerated time, checked against the
//! recorded ground truth (the robot visited the legs' destinations in order, waited where told,
//! left no earlier than each appointment, never entered a no-go area); `armor compile`, GPX
//! import and export (read back by gpxpy, an independent GPX library), and bad input through
//! the command line.
//!
//! The waypoints and areas are placed in the world frame by `armor_model` (the plan's own
//! coordinates, the world's origin), the same way the compiler does, and the robot's true pose
//! is what the sim publishes as `sim.pose_truth`, recorded by the plans' `recorder` throughout.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};
use std::time::Duration;

use armor_model::MissionNet;
use armor_model::SystemConfig;
use armor_model::geo::{self, LatLon, Polygon};
use armor_model::plan::{self, Compiled, Plan};
use armor_model::world::{Point, World};
use armor_module_api::Datum as _;
use armor_module_api::types::Pose2D;
use armor_tests::check::{armor, assert_refused, line_of, located, output_text};
use armor_tests::mcap::{read_mcap, recorder_segments};
use armor_tests::mission::{Finished, run_mission};
use armor_tests::workspace_root;

/// How close the robot must truly come to a waypoint: the follower's `tolerance_m` (0.3 m) plus
/// 0.1 m. The follower drives on the localiser's pose (Monte Carlo localisation on the plan's
/// map, `docs/localisation.md`), with the simulator's default odometry noise; on odometry alone
/// the robot ended metres away.
const TOLERANCE_M: f64 = 0.4;

/// How far a robot told to stay put (waiting, or before an appointment) may move: it may still
/// be slowing down when the transition fires, or turn on the spot to look around (it moves by
/// a centimetre or so).
const STILL_M: f64 = 0.1;

/// Slack on the run time of things the controller starts and stops (a module's first and last
/// samples): a few tens of milliseconds of real time at the accelerated clock.
const SLACK_SECS: f64 = 1.5;

/// The farthest the robot may be seen to move from one truth sample to the next: the sim's step
/// at its top speed is 2 cm (1 m/s at 50 Hz), so a longer jump means samples are missing, and a
/// quarter of a metre is well inside a no-go area's margin (0.75 m), so no crossing can hide
/// in one.
const MAX_JUMP_M: f64 = 0.25;

/// How long a plan's run may take in real time: the longest (plan-field, three minutes of run
/// time with its appointment) takes about ten seconds at the time scale on an idle machine.
const PLAN_DEADLINE: Duration = Duration::from_secs(120);

/// The plans run one at a time: each starts a whole simulated robot (eight processes), and
/// the machines have two cores; the follower's `blocked` would fire on a starved robot.
static ONE_ROBOT_AT_A_TIME: Mutex<()> = Mutex::new(());

fn robot_file(name: &str) -> PathBuf {
    workspace_root().join("missions/robot").join(name)
}

/// The value of attribute `name` in the first tag that has it.
fn attribute<'a>(text: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let start = text.find(&key)? + key.len();
    Some(&text[start..start + text[start..].find('"')?])
}

/// An example plan, with what `armor_model` makes of it on its world.
struct Example {
    file: PathBuf,
    text: String,
    plan: Plan,
    world: World,
    origin: LatLon,
    compiled: Compiled,
}

impl Example {
    fn load(name: &str) -> Example {
        Example::load_file(robot_file(name))
    }

    /// A plan anywhere (one `armor plan` wrote), its system named from its folder.
    fn load_file(file: PathBuf) -> Example {
        let name = file.display().to_string();
        let text = std::fs::read_to_string(&file).unwrap();
        let plan = Plan::parse(&text).unwrap_or_else(|err| panic!("{name}: {err:?}"));
        let system_text =
            std::fs::read_to_string(file.parent().unwrap().join(&plan.system)).unwrap();
        let system = SystemConfig::parse(&system_text).unwrap();
        let world_name = if plan.world.is_empty() {
            system
                .modules
                .iter()
                .find_map(|module| module.param("world"))
                .map(|param| param.value.clone())
                .expect("the plan's system runs a sim with a world")
        } else {
            plan.world.clone()
        };
        let world_file = workspace_root().join("assets/worlds").join(&world_name);
        let world = World::parse(
            &std::fs::read_to_string(&world_file).unwrap(),
            &world_file.display().to_string(),
        )
        .unwrap();
        let (lat, lon) = world.origin_lat_lon();
        let compiled = plan::compile(&plan, Some(&world))
            .unwrap_or_else(|problems| panic!("{name} does not compile: {problems:?}"));
        Example {
            file,
            text,
            plan,
            world,
            origin: LatLon::new(lat, lon),
            compiled,
        }
    }

    fn position(&self, waypoint: &str) -> Point {
        self.compiled.positions[waypoint]
    }

    /// The no-go areas in the world frame, with their names.
    fn no_go(&self) -> Vec<(String, Polygon)> {
        self.plan
            .no_go_areas()
            .map(|area| {
                let corners = area
                    .points
                    .iter()
                    .map(|p| p.to_local(self.origin))
                    .collect();
                (area.name.clone(), Polygon::new(corners))
            })
            .collect()
    }

    /// The run time of a date of the plan: seconds since its `start`.
    fn run_secs(&self, unix_secs: f64) -> f64 {
        unix_secs
            - self
                .plan
                .start_unix_secs
                .expect("a plan with dates has a start")
    }

    /// The plan's text for a run in `dir`: its system an absolute path, every recorder `file`
    /// in `dir` and written without compression (for our MCAP reader), so that a run writes
    /// nothing into the repository.
    fn copy_into(&self, dir: &Path) -> PathBuf {
        assert!(
            !self.text.contains("name=\"compression\""),
            "{}: the test adds the recorders' compression itself",
            self.file.display()
        );
        let system = self.file.parent().unwrap().join(&self.plan.system);
        let mut text = self.text.replacen(
            &format!("system=\"{}\"", self.plan.system),
            &format!("system=\"{}\"", system.display()),
            1,
        );
        let key = "<param name=\"file\" value=\"";
        let mut from = 0;
        while let Some(found) = text[from..].find(key) {
            let start = from + found + key.len();
            let end = start + text[start..].find("\"/>").unwrap();
            let value = text[start..end].to_owned();
            let replacement = format!(
                "{}\"/><param name=\"compression\" value=\"none",
                dir.join(&value).display()
            );
            text.replace_range(start..end, &replacement);
            from = start + replacement.len();
        }
        let copy = dir.join(self.file.file_name().unwrap());
        std::fs::write(&copy, &text).unwrap();
        // The copy is the same plan but for the paths and the recorders' compression.
        let copied = Plan::parse(&text).unwrap();
        assert_eq!(copied.waypoints, self.plan.waypoints);
        assert_eq!(copied.legs.len(), self.plan.legs.len());
        copy
    }

    /// The file a module's action writes (its `file` parameter), in `dir`.
    fn action_file(&self, action: &plan::Action, module: &str, dir: &Path) -> PathBuf {
        let file = action
            .modules
            .iter()
            .filter(|m| m.name == module)
            .flat_map(|m| &m.params)
            .find(|param| param.name == "file")
            .unwrap_or_else(|| panic!("module `{module}` has no `file` in {action:?}"));
        dir.join(&file.value)
    }
}

/// The robot's true position at run time `secs`.
#[derive(Clone, Copy, Debug)]
struct Sample {
    secs: f64,
    at: Point,
}

/// A finished run of an example plan.
struct PlanRun {
    example: Example,
    run: Finished,
    dir: tempfile::TempDir,
    /// The recorded ground truth, in time order.
    truth: Vec<Sample>,
}

/// Runs an example plan to its end, headless at accelerated time, from a copy in a temporary
/// folder; it must end in `done` with the robot never touching anything nor being blocked.
fn run_example(name: &str) -> PlanRun {
    run_plan(Example::load(name))
}

/// [`run_example`] of a loaded plan.
fn run_plan(example: Example) -> PlanRun {
    run_plan_to(example, "done")
}

/// [`run_plan`] of a plan that must end in the place `end` (a contingency's `returned_W`).
fn run_plan_to(example: Example, end: &str) -> PlanRun {
    let dir = tempfile::tempdir().unwrap();
    let copy = example.copy_into(dir.path());
    let plan_tag = &example.text[example.text.find("<plan ").unwrap()..];
    let plan_tag = &plan_tag[..plan_tag.find('>').unwrap()];
    // A plan made for a day that has passed is rehearsed on that day by `armor run` itself (the
    // README's first command relies on it); one made for a day to come is given its day.
    let start = attribute(plan_tag, "start");
    let past = start.is_some_and(|start| {
        armor_model::net::parse_rfc3339(start).unwrap()
            < std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_secs_f64()
    });
    let extra = match start {
        Some(start) if !past => vec!["--start-at", start],
        _ => Vec::new(),
    };
    let run = {
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        run_mission(&copy, &extra, PLAN_DEADLINE)
    };
    if past {
        assert!(
            run.any_line(|line| line.contains("which has passed: rehearsed as if starting then")),
            "{}",
            run.lines.join("\n")
        );
    }
    assert_eq!(
        run.final_marking(),
        serde_json::Value::Object([(end.to_owned(), 1.into())].into_iter().collect()),
        "{:?}",
        run.fired()
    );
    run.assert_clean();

    let recording = example.action_file(
        example.plan.throughout.as_ref().expect("the plan records"),
        "recorder",
        dir.path(),
    );
    let truth = read_truth(&recording);
    PlanRun {
        example,
        run,
        dir,
        truth,
    }
}

/// The `sim.pose_truth` samples a recorder wrote in `file`, in time order. The plan's
/// `<throughout>` recorder runs in every place alike, so it records the whole mission in that one
/// file (a restart would have started `NAME-2.mcap`). The recorder stores a sample as JSON when
/// JSON gives it back exactly, else as its postcard bytes on a second channel of the same topic:
/// both are read. The robot's camera is recorded beside it (as JSON images).
fn read_truth(file: &Path) -> Vec<Sample> {
    assert_eq!(
        recorder_segments(file),
        [file],
        "one recording for the whole mission"
    );
    let mut truth = Vec::new();
    let mut frames = 0;
    for ((topic, encoding), messages) in read_mcap(file) {
        if topic == "camera.image" {
            assert_eq!(encoding, "json", "{}", file.display());
            frames += messages.len();
            continue;
        }
        assert_eq!(topic, "sim.pose_truth", "{}", file.display());
        for (log_time, data) in messages {
            let pose = match encoding.as_str() {
                "json" => serde_json::from_slice::<Pose2D>(&data).unwrap(),
                "postcard" => Pose2D::decode(&data).unwrap(),
                other => panic!("{}: encoding {other}", file.display()),
            };
            truth.push(Sample {
                secs: log_time as f64 / 1e9,
                at: Point::new(pose.x_m, pose.y_m),
            });
        }
    }
    truth.sort_by(|a, b| a.secs.total_cmp(&b.secs));
    assert!(truth.len() > 100, "{} samples of the truth", truth.len());
    assert!(frames > 0, "the camera's video is in {}", file.display());
    truth
}

impl PlanRun {
    /// What the run did, for a failure's message: the firings and the lines of the controller
    /// and the follower.
    fn context(&self) -> String {
        let lines: Vec<&str> = self
            .run
            .lines
            .iter()
            .filter(|line| !line.starts_with('[') || line.starts_with("[follower]"))
            .map(String::as_str)
            .collect();
        format!("fired: {:?}\n{}", self.run.fired(), lines.join("\n"))
    }

    /// The truth sample nearest in time to `secs`.
    fn at(&self, secs: f64) -> Sample {
        *self
            .truth
            .iter()
            .min_by(|a, b| (a.secs - secs).abs().total_cmp(&(b.secs - secs).abs()))
            .unwrap()
    }

    fn samples_between(&self, from: f64, to: f64) -> impl Iterator<Item = &Sample> {
        self.truth
            .iter()
            .filter(move |sample| sample.secs >= from && sample.secs <= to)
    }

    /// When leg `index` arrived (its `LEG_arrived`, or `LEG_arrived_late` after its deadline).
    fn arrival(&self, index: usize) -> f64 {
        let leg = &self.example.plan.legs[index];
        self.run
            .fired_at(&format!("{}_arrived", leg.name))
            .or_else(|| self.run.fired_at(&format!("{}_arrived_late", leg.name)))
            .unwrap_or_else(|| panic!("leg `{}` never arrived: {:?}", leg.name, self.run.fired()))
    }

    /// The recording covers the whole run, without holes: the checks below see every moment.
    fn check_the_truth_covers_the_run(&self) {
        let end = self.run.fired().last().unwrap().1;
        let last = self.truth[self.truth.len() - 1].secs;
        // The start is judged in space too: the recorder starts with the other modules, and on
        // a busy machine its first sample can come seconds of run time after the run began. What
        // matters is that the robot had not yet gone farther than one step may jump.
        let start = self.example.position(&self.example.plan.legs[0].from);
        let moved = geo::distance(self.truth[0].at, start);
        assert!(
            moved <= MAX_JUMP_M,
            "the truth starts at {} s with the robot already {moved:.2} m from its start: the \
             first stretch of its path is missing",
            self.truth[0].secs
        );
        assert!(
            last >= end - SLACK_SECS,
            "the truth ends at {last} s, the mission at {end} s"
        );
        // A hole is judged in space, not in time: on a busy machine the sim may run late and
        // catch up (or skip ahead, the world standing still), so its samples' run times can be
        // far apart while the robot moved by a step between them. What the checks need is
        // that no stretch of the path is missing.
        let (jump, at) = self
            .truth
            .windows(2)
            .map(|pair| (geo::distance(pair[0].at, pair[1].at), pair[0].secs))
            .fold(
                (0.0, 0.0),
                |worst, jump| if jump.0 > worst.0 { jump } else { worst },
            );
        assert!(
            jump <= MAX_JUMP_M,
            "the truth jumps {jump:.2} m after {at} s: samples of the path are missing"
        );
    }

    /// The robot started at the first leg's origin and was at each leg's destination when the
    /// leg arrived, the legs in order; the truth alone shows the visits in the same order.
    fn check_visits_in_order(&self) {
        let plan = &self.example.plan;
        let start = self.example.position(&plan.legs[0].from);
        let d = geo::distance(self.truth[0].at, start);
        assert!(
            d <= TOLERANCE_M,
            "the robot started {d:.2} m from `{}`",
            plan.legs[0].from
        );
        let mut previous = 0.0;
        for (index, leg) in plan.legs.iter().enumerate() {
            let arrived = self.arrival(index);
            assert!(
                arrived > previous,
                "leg `{}` arrived at {arrived} s",
                leg.name
            );
            previous = arrived;
            let goal = self.example.position(&leg.to);
            let sample = self.at(arrived);
            let d = geo::distance(sample.at, goal);
            let tolerance = TOLERANCE_M;
            assert!(
                d <= tolerance,
                "leg `{}` arrived at {arrived} s with the robot at {} m, {d:.2} m from `{}` at \
                 {goal} m (more than {tolerance:.2} m)\n{}",
                leg.name,
                sample.at,
                leg.to,
                self.context()
            );
        }
        let mut next = 0;
        for sample in &self.truth {
            if let Some(leg) = plan.legs.get(next)
                && geo::distance(sample.at, self.example.position(&leg.to)) <= TOLERANCE_M
            {
                next += 1;
            }
        }
        assert_eq!(
            next,
            plan.legs.len(),
            "the truth shows the robot at the destinations of the first {next} legs only"
        );
    }

    /// Each wait lasted its `wait_secs`, the robot standing at the destination.
    fn check_waits(&self) -> usize {
        let mut waits = 0;
        for leg in &self.example.plan.legs {
            let Some(wait_secs) = leg.wait_secs else {
                continue;
            };
            waits += 1;
            let place = format!("{}_wait", leg.name);
            let (from, _) = self
                .run
                .entered(&place)
                .unwrap_or_else(|| panic!("`{place}` was never entered: {:?}", self.run.fired()));
            let to = self
                .run
                .fired_at(&format!("{}_waited", leg.name))
                .unwrap_or_else(|| panic!("`{}` never waited: {:?}", leg.name, self.run.fired()));
            assert!(
                to - from >= wait_secs - 0.01,
                "leg `{}` waited {} s of {wait_secs} s",
                leg.name,
                to - from
            );
            let here = self.at(from).at;
            let goal = self.example.position(&leg.to);
            for sample in self.samples_between(from, to) {
                assert!(
                    geo::distance(sample.at, here) <= STILL_M,
                    "leg `{}`: the robot moved from {here} m to {} m at {} s while waiting",
                    leg.name,
                    sample.at,
                    sample.secs
                );
                assert!(geo::distance(sample.at, goal) <= TOLERANCE_M);
            }
        }
        waits
    }

    /// No leg with an appointment left before it: its `LEG_appointment` fired no earlier, and
    /// the robot stayed at the leg's origin from its arrival there until then.
    fn check_appointments(&self) -> usize {
        let plan = &self.example.plan;
        let mut appointments = 0;
        for (index, leg) in plan.legs.iter().enumerate() {
            let Some(not_before) = leg.not_before_unix_secs else {
                continue;
            };
            appointments += 1;
            let due = self.example.run_secs(not_before);
            let fired = self
                .run
                .fired_at(&format!("{}_appointment", leg.name))
                .unwrap_or_else(|| panic!("no appointment fired: {:?}", self.run.fired()));
            assert!(
                fired >= due - 0.01,
                "leg `{}` left at {fired} s, its appointment is at {due} s",
                leg.name
            );
            let there = if index == 0 {
                0.0
            } else {
                self.arrival(index - 1)
            };
            assert!(
                there < due,
                "the robot reached `{}` at {there} s, after the appointment at {due} s: the \
                 check would be empty",
                leg.from
            );
            let origin = self.example.position(&leg.from);
            let here = self.at(there).at;
            for sample in self.samples_between(there, due) {
                let d = geo::distance(sample.at, here);
                assert!(
                    d <= STILL_M && geo::distance(sample.at, origin) <= TOLERANCE_M,
                    "leg `{}`: the robot was at {} m at {} s, {d:.2} m from where it stood at \
                     `{}`, before its appointment at {due} s",
                    leg.name,
                    sample.at,
                    sample.secs,
                    leg.from
                );
            }
            // It did leave afterwards.
            let left = self
                .samples_between(due, f64::INFINITY)
                .find(|sample| geo::distance(sample.at, origin) > TOLERANCE_M)
                .unwrap_or_else(|| panic!("the robot never left `{}`", leg.from));
            assert!(left.secs >= fired);
        }
        appointments
    }

    /// Every sample of the truth is outside every no-go area; a leg's route goes round one, so
    /// that this is not true by chance. Returns how close the robot came.
    fn check_no_go(&self) -> f64 {
        let areas = self.example.no_go();
        let mut closest = f64::INFINITY;
        for (name, polygon) in &areas {
            for sample in &self.truth {
                assert!(
                    !polygon.contains(sample.at),
                    "the robot entered the no-go area `{name}`: at {} m at {} s",
                    sample.at,
                    sample.secs
                );
                closest = closest.min(polygon.distance_to_outline(sample.at));
            }
        }
        if !areas.is_empty() {
            let plan = &self.example.plan;
            let detours: Vec<&str> = plan
                .legs
                .iter()
                .filter(|leg| {
                    let (a, b) = (
                        self.example.position(&leg.from),
                        self.example.position(&leg.to),
                    );
                    areas.iter().any(|(_, polygon)| polygon.blocks(a, b, 0.0))
                })
                .map(|leg| leg.name.as_str())
                .collect();
            assert!(
                !detours.is_empty(),
                "no leg of {} would cross a no-go area driven straight: the check proves nothing",
                self.example.file.display()
            );
        }
        closest
    }

    fn check_all(&self) -> (usize, usize) {
        self.check_the_truth_covers_the_run();
        self.check_visits_in_order();
        let waits = self.check_waits();
        let appointments = self.check_appointments();
        self.check_no_go();
        (waits, appointments)
    }
}

#[test]
fn the_yard_plan_waits_for_its_appointment_and_goes_round_the_minefield() {
    let run = run_example("plan-yard.xml");
    assert_eq!((1, 1), run.check_all());
    assert!(run.example.world.name().contains("yard"));
    let names = run.run.fired_names();
    assert_eq!(names, armor_tests::mission::YARD_FIRINGS);
    // The appointment is at 08:01:30, the run starting at 08:00:00.
    assert!(run.run.fired_at("cross_appointment").unwrap() >= 90.0);
    // The run ends with a table of the legs: when each set off and arrived, against its
    // deadline (advance by 08:01:00, 60 s in).
    let lines = &run.run.lines;
    let at = lines
        .iter()
        .position(|line| line == "plan `yard-recon`, complete:")
        .unwrap_or_else(|| panic!("no summary:\n{}", lines.join("\n")));
    let advance = &lines[at + 2];
    assert!(
        advance.starts_with("advance")
            && advance.contains("s early")
            && advance.contains("home → gate"),
        "{advance}"
    );
    let arrived = run.run.fired_at("advance_arrived").unwrap();
    assert!(advance.contains(&format!("{arrived:.1} s")), "{advance}");
    assert!(lines[at + 3].starts_with("cross") && lines[at + 3].contains("no deadline"));
    // Looking around at the gate took a full turn (10.5 s at the observer's 0.6 rad/s).
    let observing = run.run.between("advance_arrived", "advance_arrival_done");
    assert!(observing >= 10.0, "observed for {observing} s");
}

#[test]
fn the_building_plan_looks_into_the_north_room_and_waits_in_both() {
    let run = run_example("plan-building.xml");
    assert_eq!((2, 0), run.check_all());
    let names = run.run.fired_names();
    assert_eq!(
        names,
        [
            "leg1_arrived",
            "enter_north_arrived",
            "enter_north_arrival_done",
            "enter_north_waited",
            "leave_north_arrived",
            "to_south_arrived",
            "enter_south_arrived",
            "enter_south_waited"
        ]
    );
}

/// In a building the robot has no map of, it drives on the mapper's corrected pose (scan
/// matching and loop closure) with the simulator's default odometry noise: every arrival and
/// the no-go area are judged by the simulator's truth, as for the plans on a known map.
#[test]
fn the_explore_plan_drives_on_the_mappers_pose_in_a_building_it_has_no_map_of() {
    let system_text = std::fs::read_to_string(robot_file("system-explore.xml")).unwrap();
    let system = SystemConfig::parse(&system_text).unwrap();
    // Only the simulator and its simulated camera are given a world, and nothing lowers the
    // simulator's noise.
    let with_world: Vec<&str> = system
        .modules
        .iter()
        .filter(|module| module.param("world").is_some())
        .map(|module| module.name.as_str())
        .collect();
    assert_eq!(with_world, ["sim", "camera"]);
    assert!(
        !system_text.contains("odom_noise"),
        "the explore system keeps the simulator's default odometry noise"
    );
    assert!(
        system
            .links
            .iter()
            .any(|link| link.from.to_string() == "mapper.pose"
                && link.to.to_string() == "follower.odometry"),
        "the follower drives on the mapper's pose"
    );
    // ... with the mapper's covariance as its uncertainty and the mapper's live map to plan
    // its legs on; no stated uncertainty, and the default bound of replans.
    for (from, to) in [
        ("mapper.estimate", "follower.estimate"),
        ("mapper.map", "follower.map"),
    ] {
        assert!(
            system
                .links
                .iter()
                .any(|link| link.from.to_string() == from && link.to.to_string() == to),
            "{from} -> {to}"
        );
    }
    assert!(
        !system_text.contains("pose_uncertainty_m") && !system_text.contains("max_replans"),
        "the explore system's follower keeps its defaults"
    );
    let run = run_example("plan-explore.xml");
    assert_eq!((0, 0), run.check_all());
    assert_eq!(
        run.run.fired_names(),
        [
            "leg1_arrived",
            "enter_north_arrived",
            "leave_north_arrived",
            "to_south_arrived",
            "enter_south_arrived",
            "leave_south_arrived",
            "back_arrived"
        ]
    );
    assert!(
        run.run
            .any_line(|line| line.starts_with("rehearsal passed by the simulator's truth")),
        "{}",
        run.run.lines.join("\n")
    );
    // The run's live line (distance left, distance driven) follows the pose the follower
    // drives on, the mapper's, not the odometry.
    assert!(
        run.run
            .any_line(|line| line.contains("subscriber=\"armor-run.mapper.pose\"")),
        "{}",
        run.run.lines.join("\n")
    );
}

#[test]
fn the_field_plan_logs_the_laser_on_one_leg_and_keeps_out_of_the_contaminated_area() {
    let run = run_example("plan-field.xml");
    assert_eq!((0, 1), run.check_all());

    // The laser log holds the scans of the leg `pass_area` only.
    let leg = run
        .example
        .plan
        .legs
        .iter()
        .find(|leg| leg.name == "pass_area")
        .unwrap();
    let file = run
        .example
        .action_file(leg.during.as_ref().unwrap(), "scan_log", run.dir.path());
    assert!(file.exists(), "{} was not written", file.display());
    let (began, _) = run.run.entered("pass_area_drive").unwrap();
    let ended = run.run.fired_at("pass_area_arrived").unwrap();
    let mut times = Vec::new();
    for segment in recorder_segments(&file) {
        for ((topic, _), messages) in read_mcap(&segment) {
            assert_eq!(topic, "sim.scan", "{}", segment.display());
            times.extend(messages.iter().map(|(log_time, _)| *log_time as f64 / 1e9));
        }
    }
    times.sort_by(f64::total_cmp);
    let (first, last) = (times[0], times[times.len() - 1]);
    assert!(
        first >= began - SLACK_SECS && last <= ended + SLACK_SECS,
        "scans from {first} s to {last} s, the leg from {began} s to {ended} s"
    );
    assert!(
        first <= began + SLACK_SECS && last >= ended - SLACK_SECS,
        "scans from {first} s to {last} s do not cover the leg ({began} s to {ended} s)"
    );
    // The sim scans at 10 Hz of run time.
    let expected = (ended - began) * 10.0;
    assert!(
        times.len() as f64 >= expected * 0.8,
        "{} scans in {} s",
        times.len(),
        ended - began
    );
    // The log was started once, on that leg: one file.
    assert_eq!(recorder_segments(&file).len(), 1);
}

#[test]
fn the_plan_imported_from_gpx_drives_the_route() {
    let run = run_example("plan-yard-route.xml");
    assert_eq!((0, 0), run.check_all());
    assert_eq!(
        run.run.fired_names(),
        ["leg1_arrived", "leg2_arrived", "leg3_arrived"]
    );
}

#[test]
fn a_gpx_route_imports_as_the_example_plan() {
    let dir = tempfile::tempdir().unwrap();
    let imported = dir.path().join("plan.xml");
    let output = armor(&[
        "import".as_ref(),
        robot_file("yard-route.gpx").as_os_str(),
        "-o".as_ref(),
        imported.as_os_str(),
        "--system".as_ref(),
        "system.xml".as_ref(),
    ]);
    assert!(output.status.success(), "{}", output_text(&output));
    assert!(
        output_text(&output).contains("5 waypoints, 3 legs"),
        "{}",
        output_text(&output)
    );
    let imported = Plan::parse(&std::fs::read_to_string(&imported).unwrap()).unwrap();
    let example = Example::load("plan-yard-route.xml").plan;
    assert_eq!(imported.system, "system.xml");
    let waypoints = |plan: &Plan| -> Vec<(String, f64, f64)> {
        plan.waypoints
            .iter()
            .map(|w| (w.name.clone(), w.position.lat_deg, w.position.lon_deg))
            .collect()
    };
    let (got, want) = (waypoints(&imported), waypoints(&example));
    assert_eq!(got.len(), want.len(), "{got:?}");
    for (got, want) in got.iter().zip(&want) {
        assert_eq!(got.0, want.0);
        assert!(
            (got.1 - want.1).abs() < 1e-9 && (got.2 - want.2).abs() < 1e-9,
            "{got:?} against {want:?}"
        );
    }
    let legs = |plan: &Plan| -> Vec<(String, String, String)> {
        plan.legs
            .iter()
            .map(|leg| (leg.name.clone(), leg.from.clone(), leg.to.clone()))
            .collect()
    };
    assert_eq!(legs(&imported), legs(&example));
}

#[test]
fn an_exported_plan_is_read_by_gpxpy_with_its_waypoints_and_route() {
    let dir = tempfile::tempdir().unwrap();
    let gpx = dir.path().join("x.gpx");
    let output = armor(&[
        "export".as_ref(),
        "--gpx".as_ref(),
        robot_file("plan-yard.xml").as_os_str(),
        "-o".as_ref(),
        gpx.as_os_str(),
    ]);
    assert!(output.status.success(), "{}", output_text(&output));
    let script = r#"
import json, sys
import gpxpy
with open(sys.argv[1]) as f:
    gpx = gpxpy.parse(f)
point = lambda p: [p.name, p.latitude, p.longitude, p.symbol]
print(json.dumps({
    "waypoints": [point(p) for p in gpx.waypoints],
    "routes": [[point(p) for p in r.points] for r in gpx.routes],
    "tracks": len(gpx.tracks),
}))
"#;
    let read = armor_tests::tools::python3(&["gpxpy"])
        .args(["-c", script])
        .arg(&gpx)
        .output()
        .unwrap_or_else(|err| panic!("cannot run python3: {err}"));
    assert!(read.status.success(), "{}", output_text(&read));
    let read: serde_json::Value = serde_json::from_slice(&read.stdout).unwrap();

    let plan = Example::load("plan-yard.xml").plan;
    let same = |got: &serde_json::Value, want: &plan::Waypoint| {
        assert_eq!(got[0], want.name.as_str(), "{got}");
        let (lat, lon) = (got[1].as_f64().unwrap(), got[2].as_f64().unwrap());
        assert!(
            (lat - want.position.lat_deg).abs() < 1e-8
                && (lon - want.position.lon_deg).abs() < 1e-8,
            "{got} against {want:?}"
        );
        assert_eq!(got[3].as_str(), want.symbol.as_deref(), "{got}");
    };
    let waypoints = read["waypoints"].as_array().unwrap();
    assert_eq!(waypoints.len(), plan.waypoints.len(), "{read}");
    for (got, want) in waypoints.iter().zip(&plan.waypoints) {
        same(got, want);
    }
    let routes = read["routes"].as_array().unwrap();
    assert_eq!(routes.len(), 1, "{read}");
    let stops: Vec<&str> = std::iter::once(plan.legs[0].from.as_str())
        .chain(plan.legs.iter().map(|leg| leg.to.as_str()))
        .collect();
    assert_eq!(stops, ["home", "gate", "east", "north", "rally"]);
    let points = routes[0].as_array().unwrap();
    assert_eq!(points.len(), stops.len(), "{read}");
    for (got, stop) in points.iter().zip(&stops) {
        same(got, plan.waypoint(stop).unwrap());
    }
    assert_eq!(read["tracks"], 0);
}

#[test]
fn a_compiled_plan_is_a_mission_that_passes_armor_check_with_names_from_the_plan() {
    let dir = tempfile::tempdir().unwrap();
    let mission = dir.path().join("m.xml");
    let compile = || {
        armor(&[
            "compile".as_ref(),
            robot_file("plan-yard.xml").as_os_str(),
            "-o".as_ref(),
            mission.as_os_str(),
        ])
    };
    let output = compile();
    assert!(output.status.success(), "{}", output_text(&output));
    let written = std::fs::read_to_string(&mission).unwrap();
    // Deterministic: compiled again, the same file.
    assert!(compile().status.success());
    assert_eq!(std::fs::read_to_string(&mission).unwrap(), written);

    // The system path is right from where the mission was written.
    let system = attribute(&written, "system").unwrap();
    assert!(Path::new(system).is_relative(), "{system}");
    assert_eq!(
        std::fs::canonicalize(dir.path().join(system)).unwrap(),
        std::fs::canonicalize(robot_file("system.xml")).unwrap()
    );
    let check = armor(&["check".as_ref(), mission.as_os_str()]);
    assert!(check.status.success(), "{}", output_text(&check));
    assert!(
        output_text(&check).contains(": ok (mission `yard-recon`"),
        "{}",
        output_text(&check)
    );

    // Every place and transition traces to a leg of the plan, or is the end.
    let net = MissionNet::parse(&written).unwrap();
    let plan = Example::load("plan-yard.xml").plan;
    let names: Vec<&str> = net
        .places
        .iter()
        .map(|place| place.name.as_str())
        .chain(
            net.transitions
                .iter()
                .map(|transition| transition.name.as_str()),
        )
        .collect();
    for name in [
        "advance_drive",
        "advance_arrived",
        "advance_arrival",
        "advance_arrival_done",
        "advance_arrival_timeout",
        "advance_late",
        "cross_depart",
        "cross_appointment",
        "cross_drive",
        "cross_wait",
        "cross_waited",
        "climb_drive",
        "climb_blocked",
        "climb_hold",
        "climb_retry",
        "climb_skip",
        "regroup_drive_late",
        "regroup_arrived_late",
        "done",
    ] {
        assert!(names.contains(&name), "no `{name}` in {names:?}");
    }
    for name in &names {
        assert!(
            *name == "done"
                || plan
                    .legs
                    .iter()
                    .any(|leg| name.starts_with(&format!("{}_", leg.name))),
            "`{name}` traces to no leg of the plan"
        );
    }
    // The places that drive carry the goal and the no-go areas to the follower.
    let cross = net.places.iter().find(|p| p.name == "cross_drive").unwrap();
    let param = |name: &str| {
        cross
            .params
            .iter()
            .find(|param| param.module == "follower" && param.name == name)
            .unwrap_or_else(|| panic!("no follower `{name}` in {cross:?}"))
            .value
            .clone()
    };
    let example = Example::load("plan-yard.xml");
    let east = example.position("east");
    assert!((param("goal_x_m").parse::<f64>().unwrap() - east.x).abs() < 0.01);
    assert!((param("goal_y_m").parse::<f64>().unwrap() - east.y).abs() < 0.01);
    let no_go = geo::parse_polygons(&param("no_go")).unwrap();
    assert_eq!(no_go.len(), 1);
    let minefield = &example.no_go()[0].1;
    for (got, want) in no_go[0].corners.iter().zip(&minefield.corners) {
        assert!(geo::distance(*got, *want) < 0.01, "{got} against {want}");
    }
}

/// A small yard plan (its system the yard's), with `body` in it after its two waypoints; the
/// file and its text.
fn yard_plan(dir: &Path, name: &str, body: &str) -> (PathBuf, String) {
    let text = format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<plan name="{name}" system="{}" start="2026-11-23T08:00:00Z">
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
{body}
</plan>
"#,
        robot_file("system.xml").display()
    );
    let file = dir.join(format!("{name}.xml"));
    std::fs::write(&file, &text).unwrap();
    (file, text)
}

#[test]
fn a_leg_to_a_missing_waypoint_is_refused_where_it_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let (file, text) = yard_plan(
        dir.path(),
        "missing",
        r#"  <leg from="home" to="gate"/>
  <leg from="gate" to="nowhere"/>"#,
    );
    let line = line_of(&text, "nowhere");
    assert_refused(
        &armor(&["check".as_ref(), file.as_os_str()]),
        &file,
        line,
        &["nowhere"],
    );
    // `armor compile` refuses it the same way, and writes nothing.
    let mission = dir.path().join("m.xml");
    let output = armor(&[
        "compile".as_ref(),
        file.as_os_str(),
        "-o".as_ref(),
        mission.as_os_str(),
    ]);
    assert_refused(&output, &file, line, &["nowhere"]);
    assert!(!mission.exists());
    // So does `armor run`, before starting anything.
    let output = armor(&["run".as_ref(), file.as_os_str()]);
    assert_refused(&output, &file, line, &["nowhere"]);
}

#[test]
fn an_appointment_before_the_earliest_arrival_is_a_warning_with_the_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let (file, text) = yard_plan(
        dir.path(),
        "hurry",
        r#"  <waypoint name="east" lat="43.5615450" lon="1.4693909"/>
  <navigation speed_mps="0.5"/>
  <leg from="home" to="gate"/>
  <leg name="rush" from="gate" to="east" not_before="2026-11-23T08:00:10Z"/>"#,
    );
    // Home to gate, straight (no no-go area): about 12 m, 24 s at 0.5 m/s; the appointment to
    // leave the gate is 10 s after the start.
    let home = LatLon::new(43.5615360, 1.4690496);
    let metres = geo::distance(
        LatLon::new(43.5615360, 1.4691986).to_local(home),
        Point::default(),
    );
    let earliest = (metres / 0.5).round();
    assert!((20.0..30.0).contains(&earliest), "{metres} m");
    let output = armor(&["check".as_ref(), file.as_os_str()]);
    let all = output_text(&output);
    assert_eq!(output.status.code(), Some(0), "a warning only:\n{all}");
    let warnings = located(&output, &file);
    let line = line_of(&text, "name=\"rush\"");
    let warning = warnings
        .iter()
        .find(|(at, _, _)| *at == line)
        .unwrap_or_else(|| panic!("no warning at line {line}:\n{all}"));
    let message = &warning.2;
    for number in [
        "warning:".to_owned(),
        "rush".to_owned(),
        "2026-11-23T08:00:10Z".to_owned(),
        format!("{} s before", earliest - 10.0),
        format!("2026-11-23T08:00:{earliest:02}Z"),
        format!("{} m at", geo::round_mm((metres * 10.0).round() / 10.0)),
        "0.5 m/s".to_owned(),
    ] {
        assert!(message.contains(&number), "no `{number}` in: {message}");
    }
    assert!(all.contains(": ok (mission `hurry`"), "{all}");
}

#[test]
fn a_waypoint_outside_the_world_is_refused_with_the_world_s_extent() {
    let dir = tempfile::tempdir().unwrap();
    let (file, text) = yard_plan(
        dir.path(),
        "abroad",
        r#"  <waypoint name="far" lat="43.5715360" lon="1.4690496"/>
  <leg from="home" to="gate"/>
  <leg from="gate" to="far"/>"#,
    );
    let line = line_of(&text, "name=\"far\"");
    assert_refused(
        &armor(&["check".as_ref(), file.as_os_str()]),
        &file,
        line,
        &["`far`", "outside the world"],
    );
}

#[test]
fn a_waypoint_in_a_no_go_area_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (file, text) = yard_plan(
        dir.path(),
        "mined",
        r#"  <waypoint name="mine" lat="43.5615340" lon="1.4692980"/>
  <leg from="home" to="gate"/>
  <leg from="gate" to="mine"/>
  <area name="minefield" kind="no-go">
    <point lat="43.5615180" lon="1.4692730"/>
    <point lat="43.5615180" lon="1.4693227"/>
    <point lat="43.5615495" lon="1.4693227"/>
    <point lat="43.5615495" lon="1.4692730"/>
  </area>"#,
    );
    let line = line_of(&text, "name=\"mine\"");
    assert_refused(
        &armor(&["check".as_ref(), file.as_os_str()]),
        &file,
        line,
        &["`mine`", "no-go area `minefield`"],
    );
}

#[test]
fn broken_gpx_is_refused_where_it_breaks_and_writes_no_plan() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(robot_file("yard-route.gpx")).unwrap();
    let import = |name: &str, text: &str| {
        let file = dir.path().join(format!("{name}.gpx"));
        std::fs::write(&file, text).unwrap();
        let plan = dir.path().join(format!("{name}.xml"));
        let output = armor(&[
            "import".as_ref(),
            file.as_os_str(),
            "-o".as_ref(),
            plan.as_os_str(),
        ]);
        assert!(
            !plan.exists(),
            "{name}: a plan was written:\n{}",
            output_text(&output)
        );
        (file, output)
    };

    // Cut in the middle of the route.
    let cut = good.find("East corner").unwrap();
    let (file, output) = import("truncated", &good[..cut]);
    let all = output_text(&output);
    assert_eq!(output.status.code(), Some(1), "{all}");
    assert!(!all.contains("panicked"), "{all}");
    assert!(!located(&output, &file).is_empty(), "{all}");

    // A latitude beyond the pole, and one that is no number.
    for (name, lat) in [
        ("beyond-the-pole", "143.5615450"),
        ("not-a-number", "north"),
    ] {
        let broken = good.replacen("lat=\"43.5615450\"", &format!("lat=\"{lat}\""), 1);
        let (file, output) = import(name, &broken);
        let line = line_of(&broken, lat);
        assert_refused(&output, &file, line, &["`lat`", lat, "90"]);
    }

    // A file of another kind.
    let (file, output) = import("not-gpx", "<gpx><wpt lat=\"1\" lon=\"2\"></gpx>");
    let all = output_text(&output);
    assert_eq!(output.status.code(), Some(1), "{all}");
    assert!(!located(&output, &file).is_empty(), "{all}");
}

/// A world of our own for the planning tests: a doorway 1 m wide in a wall across it, and a
/// room closed on every side.
const ROOMS_WORLD: &str = "name Closed rooms
origin 43.5615 1.469
start 2 2 0
boundary 0,0 30,0 30,20 0,20 0,0
wall 10,0 10,8
wall 10,9 10,20
wall 20,5 28,5 28,15 20,15 20,5
";

/// A plan on [`ROOMS_WORLD`] (written next to it in `dir`) with waypoints at the given world
/// points and `body` after them; the file and its text.
fn rooms_plan(
    dir: &Path,
    name: &str,
    waypoints: &[(&str, f64, f64)],
    body: &str,
) -> (PathBuf, String) {
    std::fs::write(dir.join("rooms.world"), ROOMS_WORLD).unwrap();
    let origin = LatLon::new(43.5615, 1.469);
    let mut text = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<plan name=\"{name}\" system=\"{}\" world=\"rooms.world\">\n",
        robot_file("system.xml").display()
    );
    for (waypoint, x, y) in waypoints {
        let at = LatLon::from_local(Point::new(*x, *y), origin);
        text.push_str(&format!(
            "  <waypoint name=\"{waypoint}\" lat=\"{:.8}\" lon=\"{:.8}\"/>\n",
            at.lat_deg, at.lon_deg
        ));
    }
    text.push_str(body);
    text.push_str("\n</plan>\n");
    let file = dir.join(format!("{name}.xml"));
    std::fs::write(&file, &text).unwrap();
    (file, text)
}

#[test]
fn a_leg_into_a_closed_room_fails_armor_check_where_the_way_is_cut() {
    let dir = tempfile::tempdir().unwrap();
    let (file, text) = rooms_plan(
        dir.path(),
        "shut",
        &[
            ("home", 2.0, 2.0),
            ("hall", 15.0, 10.0),
            ("vault", 24.0, 10.0),
        ],
        "  <leg name=\"through\" from=\"home\" to=\"hall\"/>\n  <leg name=\"in\" from=\"hall\" to=\"vault\"/>",
    );
    let line = line_of(&text, "name=\"in\"");
    let output = armor(&["check".as_ref(), file.as_os_str()]);
    assert_refused(
        &output,
        &file,
        line,
        &[
            "leg `in`: no way from `hall` to `vault` keeps 0.35 m from obstacles",
            "the way is closed at (",
        ],
    );
    // Only that leg: the one through the doorway is fine.
    assert_eq!(located(&output, &file).len(), 1, "{}", output_text(&output));
    // The same plan for a wider robot: the doorway is now too narrow, and says so.
    let (file, text) = rooms_plan(
        dir.path(),
        "wide",
        &[("home", 2.0, 2.0), ("hall", 15.0, 10.0)],
        "  <navigation robot_radius_m=\"0.45\"/>\n  <leg name=\"through\" from=\"home\" to=\"hall\"/>",
    );
    assert_refused(
        &armor(&["check".as_ref(), file.as_os_str()]),
        &file,
        line_of(&text, "name=\"through\""),
        &[
            "leg `through`: no way from `home` to `hall` keeps 0.55 m from obstacles",
            "the narrowest passage is 1 m wide at (10, 8.5)",
        ],
    );
    // `armor compile` refuses the closed room the same way and writes nothing.
    let (file, _) = rooms_plan(
        dir.path(),
        "shut",
        &[
            ("home", 2.0, 2.0),
            ("hall", 15.0, 10.0),
            ("vault", 24.0, 10.0),
        ],
        "  <leg name=\"through\" from=\"home\" to=\"hall\"/>\n  <leg name=\"in\" from=\"hall\" to=\"vault\"/>",
    );
    let mission = dir.path().join("m.xml");
    let output = armor(&[
        "compile".as_ref(),
        file.as_os_str(),
        "-o".as_ref(),
        mission.as_os_str(),
    ]);
    assert_refused(&output, &file, line, &["leg `in`", "closed"]);
    assert!(!mission.exists());
}

#[test]
fn a_compiled_leg_carries_the_path_checked_round_the_wall() {
    let dir = tempfile::tempdir().unwrap();
    let (file, _) = rooms_plan(
        dir.path(),
        "round",
        &[("home", 2.0, 2.0), ("hall", 15.0, 2.0)],
        "  <leg from=\"home\" to=\"hall\"/>",
    );
    let mission = dir.path().join("m.xml");
    let output = armor(&[
        "compile".as_ref(),
        file.as_os_str(),
        "-o".as_ref(),
        mission.as_os_str(),
    ]);
    assert!(output.status.success(), "{}", output_text(&output));
    let net = MissionNet::parse(&std::fs::read_to_string(&mission).unwrap()).unwrap();
    let drive = net.place("leg1_drive").unwrap();
    let path = &drive
        .params
        .iter()
        .find(|p| p.name == "path")
        .unwrap()
        .value;
    let points: Vec<Point> = path
        .split_whitespace()
        .map(|pair| {
            let (x, y) = pair.split_once(',').unwrap();
            Point::new(x.parse().unwrap(), y.parse().unwrap())
        })
        .collect();
    // Through the doorway at y 8 to 9: up the west side of the wall and down the east side.
    assert!(points.len() > 2, "{path}");
    assert!(
        points
            .iter()
            .any(|p| (p.x - 10.0).abs() < 1.0 && p.y > 8.0 && p.y < 9.0),
        "{path}"
    );
    let world = World::parse(ROOMS_WORLD, "rooms.world").unwrap();
    for pair in points.windows(2) {
        assert!(
            world.segment_clearance(pair[0], pair[1], 0.35) >= 0.349,
            "{path}: {} to {} is too near a wall",
            pair[0],
            pair[1]
        );
    }
}

#[test]
fn bad_places_are_refused_at_check_time_with_their_lines() {
    let dir = tempfile::tempdir().unwrap();
    let (file, text) = rooms_plan(
        dir.path(),
        "bad",
        &[
            ("home", 2.0, 2.0),
            ("abroad", 35.0, 10.0),
            ("wall", 10.0, 3.0),
        ],
        "  <leg from=\"home\" to=\"abroad\"/>\n  <leg from=\"abroad\" to=\"wall\"/>\n  \
         <area name=\"pit\" kind=\"no-go\">\n    <point lat=\"43.5614\" lon=\"1.4689\"/>\n    \
         <point lat=\"43.5614\" lon=\"1.4691\"/>\n    <point lat=\"43.5616\" lon=\"1.4691\"/>\n  </area>",
    );
    let output = armor(&["check".as_ref(), file.as_os_str()]);
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"abroad\""),
        &["waypoint `abroad`", "outside the world `Closed rooms`"],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"wall\""),
        &[
            "waypoint `wall` at (10, 3) m is on the wall on line 5 of the world `Closed rooms`",
            "the robot keeps 0.35 m from obstacles",
        ],
    );
    assert_refused(
        &output,
        &file,
        line_of(&text, "name=\"home\""),
        &["waypoint `home` at (2, 2) m is in the no-go area `pit`"],
    );
}

/// `armor plan` on the yard's objectives (issue 40): the plan it writes passes `armor check`,
/// runs to completion in the simulator with the rehearsal passed by the simulator's truth, and
/// every objective is truly reached within its window.
#[test]
fn a_plan_made_from_objectives_runs_to_completion_and_meets_its_windows() {
    let said = plan_objectives_and_run("objectives-yard.xml", 4);
    assert!(said.contains("proven the best"), "{said}");
}

/// Every bundled world that has a plan has objectives too (the warehouse's, with an area to
/// reach, and the office floor's, with an area to observe): each is planned, run in the
/// simulator with its default noise, and meets every window by the simulator's truth.
#[test]
fn the_warehouse_objectives_are_planned_and_met_in_the_simulator() {
    plan_objectives_and_run("objectives-warehouse.xml", 4);
}

#[test]
fn the_office_objectives_are_planned_and_met_in_the_simulator() {
    plan_objectives_and_run("objectives-building.xml", 3);
}

/// `armor plan` on the bundled objectives `name`, which must serve all `count` of them; the
/// plan it writes passes `armor check` and runs to completion in the simulator, the rehearsal
/// passed by the truth, every objective truly reached (`check_all`) within its window and in
/// the order of the precedences. What `armor plan` said is returned.
fn plan_objectives_and_run(name: &str, count: usize) -> String {
    let dir = tempfile::tempdir().unwrap();
    // `armor plan` names the system from where it writes the plan.
    let planned = dir.path().join(name.replacen("objectives-", "planned-", 1));
    let output = armor(&[
        "plan".as_ref(),
        robot_file(name).as_os_str(),
        "-o".as_ref(),
        planned.as_os_str(),
    ]);
    let said = output_text(&output);
    assert!(output.status.success(), "{said}");
    assert!(
        said.contains(&format!("{count} of {count} objectives served")),
        "{said}"
    );
    let check = armor(&["check".as_ref(), planned.as_os_str()]);
    assert!(check.status.success(), "{}", output_text(&check));

    let objectives = Plan::parse(&std::fs::read_to_string(robot_file(name)).unwrap())
        .unwrap()
        .objectives
        .unwrap();
    let run = run_plan(Example::load_file(planned));
    run.check_all();
    assert_eq!(
        run.run.report["rehearsal"]["verdict"], "passed",
        "{:#}",
        run.run.report["rehearsal"]
    );
    let legs = &run.example.plan.legs;
    for objective in &objectives.objectives {
        let index = legs
            .iter()
            .position(|leg| leg.name == format!("to_{}", objective.name))
            .unwrap_or_else(|| panic!("{name}: no leg to `{}`", objective.name));
        let arrived = run.arrival(index);
        // The truth agrees (check_visits_in_order): the robot was there when it arrived.
        if let Some(not_before) = objective.not_before_unix_secs {
            let opens = run.example.run_secs(not_before);
            assert!(
                arrived >= opens,
                "{name}: `{}` reached at {arrived} s, before its window opens at {opens} s",
                objective.name
            );
        }
        for limit in [objective.by_unix_secs, objective.due_unix_secs]
            .into_iter()
            .flatten()
        {
            let closes = run.example.run_secs(limit);
            assert!(
                arrived <= closes,
                "{name}: `{}` reached at {arrived} s, after its window closed at {closes} s",
                objective.name
            );
        }
    }
    let position = |name: &str| legs.iter().position(|leg| leg.name == format!("to_{name}"));
    for precedence in &objectives.precedences {
        assert!(
            position(&precedence.first) < position(&precedence.then),
            "{name}: `{}` before `{}`",
            precedence.first,
            precedence.then
        );
    }
    said
}

/// A low battery is acted on while the robot waits, not only while it drives (issue 40): the
/// yard's robot, its simulated battery started low enough to run down during a long wait at
/// the gate, turns back home from the wait and never drives the next leg; by the simulator's
/// truth it waited at the gate until the battery was reported low, and ended at home.
#[test]
fn a_battery_that_runs_low_during_a_wait_takes_the_robot_home() {
    let dir = tempfile::tempdir().unwrap();
    let worlds = workspace_root().join("assets/worlds");
    // The yard's system with its worlds named in full (the copy is outside the workspace), and
    // a battery that starts at 0.3 and drains 0.9 an hour besides 0.002 a metre: about 0.27 on
    // arrival at the gate, below 0.2 some 270 s into the wait.
    let system = std::fs::read_to_string(robot_file("system.xml"))
        .unwrap()
        .replace(
            "value=\"yard.world\"",
            &format!("value=\"{}\"", worlds.join("yard.world").display()),
        )
        .replacen(
            "<module name=\"sim\" type=\"sim\">",
            "<module name=\"sim\" type=\"sim\">\n    \
             <param name=\"battery_start\" value=\"0.3\"/>\n    \
             <param name=\"battery_drain_per_hour\" value=\"0.9\"/>",
            1,
        );
    std::fs::write(dir.path().join("system.xml"), system).unwrap();
    let file = dir.path().join("plan-battery.xml");
    std::fs::write(
        &file,
        r#"<plan name="battery" system="system.xml" start="2026-11-23T08:00:00Z">
  <navigation module="follower" speed_mps="0.5"/>
  <throughout>
    <module name="recorder"><param name="file" value="battery.mcap"/></module>
  </throughout>
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
  <waypoint name="east" lat="43.5615450" lon="1.4693909"/>
  <leg name="out" from="home" to="gate" wait_secs="1200"/>
  <leg name="on" from="gate" to="east"/>
  <contingency on="low_battery"/>
</plan>
"#,
    )
    .unwrap();
    let run = run_plan_to(Example::load_file(file), "returned_home");
    let context = run.context();
    let arrived = run.arrival(0);
    let low = run
        .run
        .fired_at("out_wait_low_battery")
        .unwrap_or_else(|| panic!("the wait did not answer the low battery: {context}"));
    assert!(
        low > arrived + 60.0 && low < arrived + 1200.0,
        "arrived at {arrived} s, the battery low at {low} s: {context}"
    );
    assert!(
        !run.run
            .fired()
            .iter()
            .any(|(name, _)| name.starts_with("on_")),
        "the next leg was driven: {context}"
    );
    // By the truth: at the gate all through the wait, at home at the end.
    let (gate, home) = (run.example.position("gate"), run.example.position("home"));
    for sample in run.samples_between(arrived + 2.0, low) {
        assert!(
            sample.at.distance(gate) < 0.5,
            "at {} s the robot was truly at {}, not waiting at the gate {gate}: {context}",
            sample.secs,
            sample.at
        );
    }
    let end = run.truth.last().unwrap();
    assert!(
        end.at.distance(home) < 0.5,
        "the robot truly ended at {}, not home {home}: {context}",
        end.at
    );
}

/// Bad objectives are refused at their line by `armor plan` and `armor check`, and no plan is
/// written: an objective in a wall (the yard's container), a window that ends before it
/// starts, a precedence cycle, an area walled in (inside the container), one that encloses
/// nothing, and one observed from a centroid in the container.
#[test]
fn bad_objectives_are_refused_where_they_are_written() {
    let dir = tempfile::tempdir().unwrap();
    for (name, body, needle, says) in [
        (
            "in-a-wall",
            r#"  <objectives from="home">
    <objective name="inside" lat="43.5615828" lon="1.4692976"/>
  </objectives>"#,
            "inside",
            &["objective `inside`"][..],
        ),
        (
            "window",
            r#"  <objectives from="home">
    <objective name="late" at="gate" not_before="2026-11-23T08:05:00Z" by="2026-11-23T08:04:00Z"/>
  </objectives>"#,
            "late",
            &["its window ends", "before it starts"][..],
        ),
        (
            "cycle",
            r#"  <objectives from="home">
    <objective name="a" at="gate"/>
    <objective name="b" lat="43.5616" lon="1.4693"/>
    <precedence first="a" then="b"/>
    <precedence first="b" then="a"/>
  </objectives>"#,
            r#"first="b""#,
            &["cycle", "`a` before `b` before `a`"][..],
        ),
        (
            "walled-in-area",
            r#"  <objectives from="home">
    <objective name="in_container">
      <area><point lat="43.5615773" lon="1.4692730"/><point lat="43.5615773" lon="1.4693227"/><point lat="43.5615881" lon="1.4693227"/><point lat="43.5615881" lon="1.4692730"/></area>
    </objective>
  </objectives>"#,
            "<area>",
            &["objective `in_container`: no part of its area can be reached from `home`"][..],
        ),
        (
            "flat-area",
            r#"  <objectives from="home">
    <objective name="flat">
      <area><point lat="43.5616079" lon="1.4690248"/><point lat="43.5616079" lon="1.4690745"/><point lat="43.5616079" lon="1.4691241"/></area>
    </objective>
  </objectives>"#,
            "<area>",
            &["objective `flat`: its area encloses nothing"][..],
        ),
        (
            "centroid-in-a-wall",
            r#"  <objectives from="home">
    <objective name="over_container">
      <area><point lat="43.5615540" lon="1.4692482"/><point lat="43.5615540" lon="1.4693475"/><point lat="43.5616079" lon="1.4693475"/><point lat="43.5616079" lon="1.4692482"/></area>
      <arrival for_secs="10"><module name="observer"/></arrival>
    </objective>
  </objectives>"#,
            "<area>",
            &[
                "objective `over_container` acts on its area from its centroid",
                "inside the obstacle",
            ][..],
        ),
    ] {
        let (file, text) = yard_plan(dir.path(), name, body);
        let line = line_of(&text, needle);
        let written = dir.path().join(format!("{name}-planned.xml"));
        let output = armor(&[
            "plan".as_ref(),
            file.as_os_str(),
            "-o".as_ref(),
            written.as_os_str(),
        ]);
        assert_refused(&output, &file, line, says);
        assert!(!written.exists(), "{name}: a plan was written");
        assert_refused(
            &armor(&["check".as_ref(), file.as_os_str()]),
            &file,
            line,
            says,
        );
    }
}

/// Objectives that cannot all be served: `armor plan` names the conflicting constraints in the
/// operator's words with the numbers behind them, says what it dropped, and writes the plan of
/// what fits; the exit status says that not everything asked is done.
#[test]
fn conflicting_objectives_are_explained_and_what_was_dropped_is_said() {
    let dir = tempfile::tempdir().unwrap();
    // The gate by 08:00:40 and the post by 08:01:05: each can be reached in time alone (the
    // gate in 24 s, the post in 62 s), not both: the 27 m between them take 54 s.
    let (file, _) = yard_plan(
        dir.path(),
        "conflict",
        r#"  <objectives from="home">
    <objective name="gate_look" at="gate" by="2026-11-23T08:00:40Z" priority="2"/>
    <objective name="post" lat="43.5616439" lon="1.4693909" by="2026-11-23T08:01:05Z"/>
    <objective name="spare" lat="43.5616799" lon="1.4692482" optional="true"/>
  </objectives>"#,
    );
    let written = dir.path().join("conflict-planned.xml");
    let output = armor(&[
        "plan".as_ref(),
        file.as_os_str(),
        "-o".as_ref(),
        written.as_os_str(),
    ]);
    let said = output_text(&output);
    assert_eq!(output.status.code(), Some(1), "{said}");
    let conflict = said
        .lines()
        .find(|line| line.starts_with("cannot serve every objective: "))
        .unwrap_or_else(|| panic!("no conflict said:\n{said}"));
    for words in [
        "`gate_look` must be served",
        "`post` must be served",
        "`gate_look` by 08:00:40",
        "`post` by 08:01:05",
        "`gate_look` is reached at 08:00:24.1 at the earliest, then the",
        "m from `gate_look` to `post` take",
        "the windows leave",
    ] {
        assert!(conflict.contains(words), "`{words}` not in: {conflict}");
    }
    assert!(
        said.contains("to make a plan, `post` may be dropped"),
        "{said}"
    );
    assert!(said.contains("not served: `post`"), "{said}");
    // The plan of what fits is an ordinary plan that passes `armor check`.
    let check = armor(&["check".as_ref(), written.as_os_str()]);
    assert!(check.status.success(), "{}", output_text(&check));
    let plan = Plan::parse(&std::fs::read_to_string(&written).unwrap()).unwrap();
    let legs: Vec<&str> = plan.legs.iter().map(|leg| leg.name.as_str()).collect();
    assert_eq!(legs, ["to_gate_look", "to_spare"]);
}

/// Issue 37, defect 8: while a leg is driven, the run's status (`armor ctl status --json`, which
/// the studio's Run view shows) gives the numbers of `armor run`'s live line: the leg, the
/// distance left on its planned path, the time to its deadline and the slack against it, and
/// they follow the robot as it drives.
#[test]
fn the_status_gives_the_leg_driven_its_distance_left_and_its_slack() {
    use armor_tests::{Proc, bin, bin_dir, control_address, ctl, ctl_status, wait_until};

    let example = Example::load("plan-yard.xml");
    let dir = tempfile::tempdir().unwrap();
    let copy = example.copy_into(dir.path());
    let _one = ONE_ROBOT_AT_A_TIME
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    // A slower clock than the plans' runs, so that the first leg lasts several polls.
    let mut run = Proc::start(
        std::process::Command::new(bin("armor"))
            .arg("run")
            .arg(&copy)
            .args(["--time-scale", "4", "--no-run-folder"])
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(workspace_root()),
    );
    let addr = control_address(&run);
    let progress = || ctl_status(&addr)["mission"]["progress"].clone();
    let mut first = serde_json::Value::Null;
    wait_until(
        "the first leg's numbers in the status",
        PLAN_DEADLINE,
        || {
            first = progress();
            first["left_m"].is_f64()
        },
    );
    assert_eq!(first["leg"], "advance", "{first}");
    assert_eq!(
        (first["number"].as_u64(), first["legs"].as_u64()),
        (Some(1), Some(4))
    );
    assert_eq!(
        (first["from"].as_str(), first["to"].as_str()),
        (Some("home"), Some("gate"))
    );
    // `arrive_by` 08:01:00, a minute after the plan's start: the run rehearses it on its day.
    let deadline = example.run_secs(example.plan.legs[0].arrive_by_unix_secs.unwrap());
    assert!(
        (first["deadline_run_secs"].as_f64().unwrap() - deadline).abs() < 1e-6,
        "{first}"
    );
    let left_m = first["left_m"].as_f64().unwrap();
    let route_m = geo::path_length(&example.compiled.routes[0]);
    assert!(
        left_m > 0.0 && left_m <= route_m + TOLERANCE_M,
        "{left_m} of {route_m} m"
    );
    let time_left = first["time_left_secs"].as_f64().unwrap();
    assert!(time_left > 0.0 && time_left <= deadline, "{first}");
    // The slack is the time left less the distance left at the plan's speed.
    let slack = first["slack_secs"].as_f64().unwrap();
    let expected = time_left - left_m / example.plan.navigation.speed_mps;
    assert!(
        (slack - expected).abs() < 1e-6,
        "{slack} against {expected}"
    );
    // The numbers follow the robot: a metre further on, the distance left is a metre less.
    wait_until("the distance left to shrink", PLAN_DEADLINE, || {
        progress()["left_m"]
            .as_f64()
            .is_some_and(|left| left < left_m - 1.0)
    });
    let (aborted, said) = ctl(&addr, &["abort"]);
    assert!(aborted, "{said}");
    run.wait_exit(PLAN_DEADLINE);
}
