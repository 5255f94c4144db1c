//! Plan updates sent to a running mission (issue 39, item 1): `armor ctl update PLAN.xml`
//! moves the mission to the new plan between two firings, with no restart of the mission nor
//! of the follower, or refuses it with the reason and goes on unchanged.
//!
//! * The yard reconnaissance, rehearsed with the bundled system (its default noise, its
//!   localiser) and a run secret, updated while it drives: the waypoint `north` moved ahead of
//!   the robot, the appointment at the gate moved later, a no-go area reported across the leg
//!   after the one driven. An update that removes the leg being driven, one that does not check
//!   and one sent with an observer's key are refused. The simulator's truth, read back from the
//!   recording, judges: the robot arrived truly at the moved waypoint, its footprint never met
//!   a no-go area, the gate was left at the new time; the follower kept its process; the
//!   report, the summary and `armor ctl status` list the updates with their times.
//! * The refusal rules the run itself applies (beyond those of `armor_model::plan::migrate`,
//!   unit tested there), through `armor_runtime::update::prepare` on files: a mission net
//!   rather than a plan, another system, and a leg in force replaced with no way from where the
//!   robot is; a leg replaced gets its path from where the robot is, and keeps it through an
//!   update that leaves it unchanged. A run that plays a net, not a plan, refuses any update.
//! * Areas reported from outside (item 3): `armor ctl area` across the leg being driven, and
//!   the observer's `area` message while it looks round at the gate, each taken as an update:
//!   the robot goes round the south of the minefield and its true footprint never meets the
//!   area after the report. Bad areas (two corners, an outline that crosses itself, a name the
//!   plan has, an observer's key, a corner that is not `X,Y`) are refused and the run goes on.
//!   An area over the robot, across the gap it drives through, leaves it no way: the update is
//!   taken and the leg held on `blocked`, its reason naming the area, its repair nothing but
//!   waiting; once the area is lifted the operator's retry drives from where the robot is.
//! * Repair (item 2): a ring of mines sighted round `north` cuts the legs to and from it; with
//!   `do="repair"` the area is taken at once with the best option (skip `north`), without it
//!   the repair is proposed and `armor ctl repair 1` takes it (an observer's key refused);
//!   either way the robot completes at `rally` and its true footprint never meets the ring;
//!   the proposal and the update are in the run's MCAP recording (`armor-run.updates`). With
//!   `after_secs`, the default waits that long for the operator's choice. A leg made late (a
//!   tight `arrive_by`) holds and proposes its deadline pushed back or dropped, or the skip;
//!   the operator drops it and the mission completes. An obstacle only the simulator has, in
//!   the gap `cross` drives through, truly blocks the follower (it does not replan here): the
//!   repair's way round through `rally` is chosen, and the robot completes without touching
//!   it by the truth. With `do="repair" after_secs="30"` and nobody choosing, the run holds
//!   what stopped the follower as a no-go area across its way, the default drives on round it,
//!   south of the minefield, and the truth says the robot never met the obstacle nor the area,
//!   with the default taken not before its time and within a bound after it.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Mutex, PoisonError};
use std::time::Duration;

use armor_model::geo::LatLon;
use armor_model::net::Marking;
use armor_model::plan::{self, Plan};
use armor_model::world::{Point, World};
use armor_runtime::update::{Now, Running, check, prepare};
use armor_tests::truth::{footprint_gap_m, recorded_truth};
use armor_tests::{
    Proc, bin, bin_dir, control_address, ctl, role_key, secret_file, workspace_root,
};

/// Slower than the other mission tests' 20: the updates are sent while given legs are driven,
/// and a leg of a few metres must last long enough in real time for `armor ctl` to reach it on
/// a loaded machine.
const TIME_SCALE: &str = "10";

/// How long the whole run may take in real time: about 25 s on an idle machine.
const RUN_DEADLINE: Duration = Duration::from_secs(240);

/// The follower's default tolerance, plus the slack a rehearsal allows.
const ALLOWED_M: f64 = 0.3 + 0.1;

/// The runs take turns with each other: each starts a whole simulated robot.
static ONE_ROBOT_AT_A_TIME: Mutex<()> = Mutex::new(());

/// The yard plan and its system copied into a temporary folder, with the world and the
/// recording named by absolute paths, so that the plan and its updates can be written there.
struct Yard {
    dir: tempfile::TempDir,
    world: World,
    plan_text: String,
    recording: PathBuf,
}

impl Yard {
    fn new() -> Yard {
        let dir = tempfile::tempdir().unwrap();
        let robot = workspace_root().join("missions/robot");
        let world_file = workspace_root().join("assets/worlds/yard.world");
        let system = std::fs::read_to_string(robot.join("system.xml"))
            .unwrap()
            .replace(
                "value=\"yard.world\"",
                &format!("value=\"{}\"", world_file.display()),
            );
        assert!(system.contains(&world_file.display().to_string()));
        std::fs::write(dir.path().join("system.xml"), system).unwrap();
        let recording = dir.path().join("yard-recon.mcap");
        let plan_text = std::fs::read_to_string(robot.join("plan-yard.xml"))
            .unwrap()
            .replace(
                "<param name=\"file\" value=\"yard-recon.mcap\"/>",
                &format!(
                    "<param name=\"file\" value=\"{}\"/><param name=\"compression\" value=\"none\"/>",
                    recording.display()
                ),
            );
        assert!(plan_text.contains("compression"));
        let world = World::parse(
            &std::fs::read_to_string(&world_file).unwrap(),
            &world_file.display().to_string(),
        )
        .unwrap();
        Yard {
            dir,
            world,
            plan_text,
            recording,
        }
    }

    /// Writes `text` as the plan file `name` in the folder.
    fn write(&self, name: &str, text: &str) -> PathBuf {
        let file = self.dir.path().join(name);
        std::fs::write(&file, text).unwrap();
        file
    }

    /// `lat="…" lon="…"` of the world point (x, y), as a plan writes it.
    fn lat_lon(&self, x: f64, y: f64) -> String {
        let (lat, lon) = self.world.origin_lat_lon();
        let at = LatLon::from_local(Point::new(x, y), LatLon::new(lat, lon));
        format!("lat=\"{:.9}\" lon=\"{:.9}\"", at.lat_deg, at.lon_deg)
    }

    /// A no-go area `name`, the rectangle from (x0, y0) to (x1, y1), as a plan writes it.
    fn area(&self, name: &str, (x0, y0): (f64, f64), (x1, y1): (f64, f64)) -> String {
        let corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
            .iter()
            .map(|&(x, y)| format!("<point {}/>", self.lat_lon(x, y)))
            .collect::<String>();
        format!("<area name=\"{name}\" kind=\"no-go\">{corners}</area>\n  ")
    }

    /// The plan `text` compiled on the yard for the bundled robot, as `armor check` would.
    fn compiled(&self, text: &str) -> plan::Compiled {
        let plan = Plan::parse(text).unwrap();
        let robot = plan::robot(&plan, None, &Default::default());
        plan::compile_for(&plan, Some(&self.world), &robot).unwrap()
    }
}

/// `armor run PLAN` in the yard's folder on the plan's day at `time_scale`, with a run secret
/// and a report.
fn yard_run(yard: &Yard, plan: &Path, report_file: &Path, secret: &Path, time_scale: &str) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(plan)
            .args([
                "--time-scale",
                time_scale,
                "--start-at",
                "2026-11-23T08:00:00Z",
            ])
            .arg("--report")
            .arg(report_file)
            .arg("--secret")
            .arg(secret)
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(yard.dir.path()),
    )
}

/// `text` with `from` replaced by `to`, which it must hold.
fn edited(text: &str, from: &str, to: &str) -> String {
    assert!(text.contains(from), "no `{from}` in the plan");
    text.replacen(from, to, 1)
}

/// The run's status as `armor ctl --secret SECRET status --json` prints it.
fn status(addr: &str, secret: &Path) -> serde_json::Value {
    let (ok, text) = ctl(
        addr,
        &["--secret", secret.to_str().unwrap(), "status", "--json"],
    );
    assert!(ok, "{text}");
    let json = text.find('{').map_or("", |start| &text[start..]);
    serde_json::from_str(json).unwrap_or_else(|err| panic!("{err}: {text}"))
}

/// The places marked, by name.
fn marked(status: &serde_json::Value) -> Vec<String> {
    status["mission"]["marking"]
        .as_object()
        .map(|marking| marking.keys().cloned().collect())
        .unwrap_or_default()
}

/// The follower's process id and restarts.
fn follower(status: &serde_json::Value) -> (u64, u64) {
    let module = status["modules"]
        .as_array()
        .unwrap()
        .iter()
        .find(|module| module["name"] == "follower")
        .unwrap();
    (
        module["pid"].as_u64().unwrap(),
        module["restarts"].as_u64().unwrap(),
    )
}

/// `armor ctl --secret SECRET update FILE`: whether it was taken, and what it said.
fn update(addr: &str, secret: &Path, file: &Path) -> (bool, String) {
    ctl(
        addr,
        &[
            "--secret",
            secret.to_str().unwrap(),
            "update",
            file.to_str().unwrap(),
        ],
    )
}

/// The run time the transition `name` fired at, by the report's timeline.
fn fired_at(report: &serde_json::Value, name: &str) -> f64 {
    report["timeline"]
        .as_array()
        .unwrap()
        .iter()
        .find(|entry| entry["kind"] == "fired" && entry["transition"] == name)
        .and_then(|entry| entry["at_secs"].as_f64())
        .unwrap_or_else(|| panic!("`{name}` never fired"))
}

#[test]
fn the_yard_run_takes_three_updates_while_driving_and_refuses_the_wrong_ones() {
    let yard = Yard::new();
    let original = yard.write("plan-yard.xml", &yard.plan_text);
    // 1. `north`, where `climb` goes, moved 2.5 m west (ahead of the robot: it is about to
    // drive the first leg).
    let moved_north = (29.0, 16.0);
    let north_before = "<waypoint name=\"north\" lat=\"43.5616439\" lon=\"1.4693909\"/>";
    let text1 = edited(
        &yard.plan_text,
        north_before,
        &format!(
            "<waypoint name=\"north\" {}/>",
            yard.lat_lon(moved_north.0, moved_north.1)
        ),
    );
    let update1 = yard.write("plan-north-moved.xml", &text1);
    // 2. The appointment at the gate moved 20 s later.
    let text2 = edited(
        &text1,
        "not_before=\"2026-11-23T08:01:30Z\"",
        "not_before=\"2026-11-23T08:01:50Z\"",
    );
    let update2 = yard.write("plan-appointment-later.xml", &text2);
    // 3. Another unit reports a minefield across `climb`, north of the container: the way
    // from `east` to `north` must go round it, by the gap along the low wall.
    let reported = ((29.5, 12.0), (31.5, 13.0));
    let text3 = edited(
        &text2,
        "<phase_line",
        &format!(
            "{}<phase_line",
            yard.area("reported", reported.0, reported.1)
        ),
    );
    let update3 = yard.write("plan-reported-area.xml", &text3);
    // Refused: the leg being driven (`cross`) taken out.
    let without_cross = edited(
        &edited(
            &text2,
            "<leg name=\"cross\" from=\"gate\" to=\"east\" not_before=\"2026-11-23T08:01:50Z\" wait_secs=\"5\"/>",
            "",
        ),
        "<leg name=\"climb\" from=\"east\"",
        "<leg name=\"climb\" from=\"gate\"",
    );
    let removal = yard.write("plan-without-cross.xml", &without_cross);
    // Refused: a leg to a waypoint the plan does not have.
    let broken_text = edited(&text1, "to=\"rally\"", "to=\"nowhere\"");
    let broken = yard.write("plan-broken.xml", &broken_text);
    let broken_line = broken_text
        .lines()
        .position(|line| line.contains("to=\"nowhere\""))
        .unwrap()
        + 1;
    let secret = secret_file(yard.dir.path());
    let observer = role_key(&secret, "observer");
    let report_file = yard.dir.path().join("report.json");

    let _one = ONE_ROBOT_AT_A_TIME
        .lock()
        .unwrap_or_else(PoisonError::into_inner);
    let mut run = yard_run(&yard, &original, &report_file, &secret, TIME_SCALE);
    let addr = control_address(&run);
    let first = status(&addr, &secret);
    assert!(
        marked(&first)
            .iter()
            .all(|place| place.starts_with("advance_"))
    );

    let (taken, said) = update(&addr, &secret, &update1);
    assert!(taken, "{said}");
    assert!(
        said.starts_with("update 1 taken: leg `advance` in force goes on unchanged in `advance_"),
        "{said}"
    );
    let (taken, said) = update(&addr, &secret, &update2);
    assert!(taken, "{said}");
    assert!(
        said.starts_with("update 2 taken:") && said.contains("leg `cross` leaves at 08:01:50"),
        "{said}"
    );
    // A plan that does not check: refused with its place and reason, the run unchanged.
    let (taken, said) = update(&addr, &secret, &broken);
    assert!(!taken, "{said}");
    assert!(
        said.starts_with(&format!(
            "update 3 refused: the update does not check: {}:{broken_line}:",
            broken.display()
        )) && said.contains("`to` names waypoint `nowhere`, which the plan does not define"),
        "{said}"
    );
    // An observer reads the run; it does not update it.
    let (taken, said) = ctl(
        &addr,
        &[
            "--key",
            observer.to_str().unwrap(),
            "update",
            update3.to_str().unwrap(),
        ],
    );
    assert!(!taken && said.contains("observer"), "{said}");

    // While `cross` is driven: taking it out is refused, and the run goes on; the area across
    // the next leg is taken.
    // The run says each firing in its log: no need to ask for its status again and again.
    run.wait_for("`cross` set off", RUN_DEADLINE, |line| {
        line.contains("fired `cross_appointment`")
    });
    let (taken, said) = update(&addr, &secret, &removal);
    assert!(!taken, "{said}");
    assert!(
        said.starts_with("update 4 refused: the update removes leg `cross`, which is in force"),
        "{said}"
    );
    let (taken, said) = update(&addr, &secret, &update3);
    assert!(taken, "{said}");
    assert!(
        said.starts_with("update 5 taken:") && said.contains("no-go areas added: `reported`"),
        "{said}"
    );
    let last = status(&addr, &secret);
    let updates = last["mission"]["updates"].as_array().unwrap();
    assert_eq!(
        updates
            .iter()
            .map(|update| (update["number"].as_u64().unwrap(), update["taken"] == true))
            .collect::<Vec<_>>(),
        [(1, true), (2, true), (3, false), (4, false), (5, true)]
    );
    // The follower kept its process through the updates.
    assert_eq!(follower(&first), follower(&last));
    assert_eq!(follower(&last).1, 0);

    let exit = run.wait_exit(RUN_DEADLINE);
    let lines = run.lines();
    let text = lines.join("\n");
    assert!(exit.success(), "{exit}:\n{text}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_file).unwrap()).unwrap();
    assert_eq!(report["outcome"], "complete", "{text}");
    assert_eq!(report["rehearsal"]["verdict"], "passed", "{text}");
    let timeline = report["timeline"].as_array().unwrap();
    // One mission from start to end: started once, each leg's transitions in order.
    assert_eq!(
        timeline
            .iter()
            .filter(|entry| entry["kind"] == "started")
            .count(),
        1
    );
    let fired: Vec<&str> = timeline
        .iter()
        .filter(|entry| entry["kind"] == "fired")
        .map(|entry| entry["transition"].as_str().unwrap())
        .collect();
    assert_eq!(fired, armor_tests::mission::YARD_FIRINGS);
    // The gate was left at the new appointment, 110 s after the start, not at the old one.
    assert!(fired_at(&report, "cross_appointment") >= 110.0);
    // The report lists the updates with their times, in the timeline too.
    let listed = report["updates"].as_array().unwrap();
    assert_eq!(listed.len(), 5);
    let in_timeline: Vec<(u64, f64)> = timeline
        .iter()
        .filter(|entry| entry["kind"] == "update")
        .map(|entry| {
            (
                entry["number"].as_u64().unwrap(),
                entry["run_secs"].as_f64().unwrap(),
            )
        })
        .collect();
    assert_eq!(in_timeline.len(), 5);
    for (update, (number, run_secs)) in listed.iter().zip(&in_timeline) {
        assert_eq!(update["number"].as_u64(), Some(*number));
        assert_eq!(update["run_secs"].as_f64(), Some(*run_secs));
    }
    // Updates 4 and 5 came while `cross` was driven: after the appointment, before `climb`.
    assert!(in_timeline[3].1 >= fired_at(&report, "cross_appointment"));
    assert!(in_timeline[4].1 <= fired_at(&report, "climb_arrived"));
    for number in 1..=5 {
        assert!(
            lines
                .iter()
                .any(|line| line.starts_with(&format!("update {number} at "))),
            "no summary line for update {number}:\n{text}"
        );
    }

    // The truth, from the recording: the robot arrived at the moved `north`, and its footprint
    // kept out of both no-go areas.
    let truth = recorded_truth(&yard.recording);
    let climbed = fired_at(&report, "climb_arrived");
    let (_, at_arrival) = truth
        .iter()
        .min_by(|a, b| (a.0 - climbed).abs().total_cmp(&(b.0 - climbed).abs()))
        .copied()
        .unwrap();
    let compiled = yard.compiled(&text3);
    let north = compiled.positions["north"];
    assert!(
        north.distance(Point::new(moved_north.0, moved_north.1)) < 0.01,
        "{north:?}"
    );
    let error = at_arrival.distance(north);
    assert!(
        error <= ALLOWED_M,
        "`climb` arrived {error} m from the moved `north`"
    );
    let radius_m = report["rehearsal"]["robot_radius_m"].as_f64().unwrap();
    assert_eq!(compiled.keepouts.len(), 2);
    for keepout in &compiled.keepouts {
        let least = truth
            .iter()
            .map(|(_, at)| footprint_gap_m(&keepout.polygon, *at, radius_m))
            .fold(f64::INFINITY, f64::min);
        assert!(
            least > 0.0,
            "the footprint came {least} m from `{}`",
            keepout.name
        );
    }
    // The area reported lies across the straight way from `east` to the moved `north`: the
    // robot went round it, which the truth shows east of the area while passing it.
    let (x0, y0) = reported.0;
    let (x1, y1) = reported.1;
    assert!(
        truth
            .iter()
            .filter(|(_, at)| at.y > y0 && at.y < y1)
            .all(|(_, at)| at.x < x0 || at.x > x1),
        "the robot crossed the reported area's band inside it"
    );
}

/// The running yard plan, loaded as `armor run` loads it, for `prepare`.
fn running(yard: &Yard) -> (Running, PathBuf) {
    let file = yard.write("plan-yard.xml", &yard.plan_text);
    let loaded = armor_runtime::mission::load_mission(&file, &[bin_dir()]).unwrap();
    (
        Running {
            file: file.clone(),
            system_file: loaded.system_file.clone(),
            plan: loaded.plan.clone().unwrap(),
            compiled: loaded.compiled.clone().unwrap(),
            memory: Default::default(),
        },
        file,
    )
}

#[test]
fn the_run_refuses_what_it_cannot_take_and_plans_a_leg_replaced_from_the_robot() {
    let yard = Yard::new();
    let (mut running, _) = running(&yard);
    let driving_cross: Marking = [("cross_drive".to_owned(), 1)].into();
    let now = Now {
        robot_at: Some(Point::new(20.0, 7.0)),
        unix_secs: armor_model::net::parse_rfc3339("2026-11-23T08:01:40Z").unwrap(),
    };
    let mut refused = |file: &str, text: &str, marking: &Marking, now: Now| {
        check(&mut running, file, text, &[bin_dir()])
            .and_then(|checked| {
                prepare(
                    &running,
                    checked,
                    &[bin_dir()],
                    (&running.compiled.net, marking),
                    now,
                )
            })
            .map(|prepared| prepared.message)
            .expect_err("refused")
            .to_string()
    };
    // A mission net is not a plan.
    // (`system="system.xml"`, found beside the running plan: the same system.)
    let net = std::fs::read_to_string(workspace_root().join("missions/robot/yard.xml")).unwrap();
    let why = refused("net.xml", &net, &driving_cross, now);
    assert_eq!(
        why,
        "the update is a mission net, not a plan: a running plan is updated with a plan"
    );
    // Another system: the copy of the same file is another file.
    std::fs::copy(
        yard.dir.path().join("system.xml"),
        yard.dir.path().join("other.xml"),
    )
    .unwrap();
    let other = edited(
        &yard.plan_text,
        "system=\"system.xml\"",
        "system=\"other.xml\"",
    );
    let why = refused("other-system.xml", &other, &driving_cross, now);
    assert!(
        why.starts_with("the update is over the system `")
            && why.contains("cannot change the system"),
        "{why}"
    );
    // An area over where the robot is, across the leg in force: no way from there.
    let boxed = edited(
        &yard.plan_text,
        "<phase_line",
        &format!(
            "{}<phase_line",
            yard.area("reported", (19.0, 6.0), (21.0, 8.0))
        ),
    );
    let why = refused("boxed.xml", &boxed, &driving_cross, now);
    assert!(
        why.starts_with(
            "leg `cross` in force changed, and there is no way from where the robot is, (20, 7), \
             to `east`"
        ),
        "{why}"
    );
    // The same area taken while the robot is elsewhere on the leg: its path starts there.
    let elsewhere = Now {
        robot_at: Some(Point::new(17.0, 4.5)),
        ..now
    };
    let checked = check(&mut running, "boxed.xml", &boxed, &[bin_dir()]).unwrap();
    let prepared = prepare(
        &running,
        checked,
        &[bin_dir()],
        (&running.compiled.net, &driving_cross),
        elsewhere,
    )
    .unwrap();
    assert!(prepared.migration.changed);
    let path =
        armor_model::plan::migrate::param_of(&prepared.net, "cross_drive", ("follower", "path"))
            .unwrap();
    let start = armor_model::planner::Path::parse(&path).unwrap().points[0];
    assert!(start.distance(Point::new(17.0, 4.5)) < 0.05, "{path}");
    assert!(
        prepared
            .message
            .contains("its path planned again from where the robot is, (17, 4.5)"),
        "{}",
        prepared.message
    );
    // Taken, then the same plan sent again: the leg goes on unchanged, on the path the run gave
    // it from where the robot was, not back on the plan's from `gate`.
    let mut taken = Running {
        plan: prepared.plan.clone(),
        compiled: prepared.compiled.clone(),
        ..running.clone()
    };
    let checked = check(&mut taken, "boxed.xml", &boxed, &[bin_dir()]).unwrap();
    let again = prepare(
        &taken,
        checked,
        &[bin_dir()],
        (&prepared.net, &driving_cross),
        Now {
            robot_at: Some(Point::new(19.0, 3.0)),
            ..now
        },
    )
    .unwrap();
    assert!(!again.migration.changed);
    assert!(
        again
            .message
            .starts_with("leg `cross` in force goes on unchanged in `cross_drive`"),
        "{}",
        again.message
    );
    // What `armor check` warns of comes with the answer, a line each, at the operator's file.
    let hurried = edited(
        &yard.plan_text,
        "arrive_by=\"2026-11-23T08:06:00Z\"",
        "arrive_by=\"2026-11-23T08:02:00Z\"",
    );
    let checked = check(&mut running, "hurried.xml", &hurried, &[bin_dir()]).unwrap();
    let warned = prepare(
        &running,
        checked,
        &[bin_dir()],
        (&running.compiled.net, &driving_cross),
        now,
    )
    .unwrap();
    let mut lines = warned.message.lines();
    assert!(
        lines
            .next()
            .unwrap()
            .starts_with("leg `cross` in force goes on unchanged")
    );
    let warning = lines.next().unwrap_or_default();
    assert!(
        warning.starts_with("hurried.xml:")
            && warning.contains(": warning: ")
            && warning.contains("regroup"),
        "{}",
        warned.message
    );
    let follower_path = |net: &armor_model::net::MissionNet| {
        armor_model::plan::migrate::param_of(net, "cross_drive", ("follower", "path"))
    };
    assert_eq!(follower_path(&again.net), Some(path));
    assert_ne!(
        follower_path(&again.net),
        follower_path(&again.compiled.net)
    );
    // An area added across `cross` while the robot waits at the gate: the leg goes on in
    // `cross_depart`, and its drive takes the new route round the area, not the one the run
    // had given it through the gap.
    let waiting: Marking = [("cross_depart".to_owned(), 1)].into();
    let gap = edited(
        &yard.plan_text,
        "<phase_line",
        &format!("{}<phase_line", yard.area("gap", (23.0, 5.3), (25.0, 8.2))),
    );
    let checked = check(&mut running, "gap.xml", &gap, &[bin_dir()]).unwrap();
    let rerouted = prepare(
        &running,
        checked,
        &[bin_dir()],
        (&running.compiled.net, &waiting),
        now,
    )
    .unwrap();
    assert!(!rerouted.migration.changed);
    assert_eq!(
        follower_path(&rerouted.net),
        follower_path(&rerouted.compiled.net)
    );
    assert_ne!(
        follower_path(&rerouted.net),
        follower_path(&running.compiled.net)
    );
}

#[test]
fn a_run_that_plays_a_net_refuses_updates_and_numbers_them() {
    let yard = Yard::new();
    // The net's folder is its own: the yard's plan sent is over another system file.
    let net_dir = tempfile::tempdir().unwrap();
    let mission = armor_tests::waiting_mission(net_dir.path());
    let plan = yard.write("plan-yard.xml", &yard.plan_text);
    let (mut run, addr) = armor_tests::run_with_control(&mission);
    let (taken, said) = ctl(&addr, &["update", plan.to_str().unwrap()]);
    assert!(!taken, "{said}");
    assert!(
        said.starts_with(
            "update 1 refused: this run plays a mission net, not a plan: only a plan is updated"
        ),
        "{said}"
    );
    let status = armor_tests::ctl_status(&addr);
    assert_eq!(status["mission"]["updates"][0]["number"], 1);
    assert_eq!(status["mission"]["updates"][0]["taken"], false);
    // The run goes on in its place.
    assert_eq!(marked(&status), ["counting"]);
    let (aborted, said) = ctl(&addr, &["abort"]);
    assert!(aborted, "{said}");
    run.wait_exit(RUN_DEADLINE);
}

/// Areas reported from outside (issue 39, item 3): `armor ctl area` and a module's `area`
/// message add a no-go area to the running plan, taken as an update.
mod reported {
    use super::*;

    /// The northern gap between the minefield and the container, where `cross` drives: an
    /// area there sends the leg south of the minefield (the only other way).
    const GAP: [(f64, f64); 4] = [(23.0, 5.3), (25.0, 5.3), (25.0, 8.2), (23.0, 8.2)];

    /// `X,Y` arguments of `armor ctl area`.
    fn corners(points: &[(f64, f64)]) -> Vec<String> {
        points.iter().map(|(x, y)| format!("{x},{y}")).collect()
    }

    /// The yard plan `text` where the observer, looking round at the gate, sights the area
    /// `name` at `points` and reports it.
    fn sighting(text: &str, name: &str, points: &[(f64, f64)]) -> String {
        let sighted = format!(
            "<param name=\"sector_deg\" value=\"360\"/>\n        <param name=\"sighted\" value=\"{name} {}\"/>",
            corners(points).join(" ")
        );
        edited(text, "<param name=\"sector_deg\" value=\"360\"/>", &sighted)
    }

    /// `armor ctl --secret SECRET area NAME CORNER…`: whether it was taken, and what it said.
    fn area(addr: &str, secret: &Path, name: &str, points: &[(f64, f64)]) -> (bool, String) {
        let corners = corners(points);
        let mut args = vec!["--secret", secret.to_str().unwrap(), "area", name];
        args.extend(corners.iter().map(String::as_str));
        ctl(addr, &args)
    }

    /// The yard plan (as `text`) run at `time_scale` with a secret and a report.
    struct Run {
        proc: Proc,
        addr: String,
        secret: PathBuf,
        report_file: PathBuf,
    }

    fn start(yard: &Yard, text: &str, time_scale: &str) -> Run {
        let plan = yard.write("plan-yard.xml", text);
        let secret = secret_file(yard.dir.path());
        let report_file = yard.dir.path().join("report.json");
        let proc = yard_run(yard, &plan, &report_file, &secret, time_scale);
        let addr = control_address(&proc);
        Run {
            proc,
            addr,
            secret,
            report_file,
        }
    }

    impl Run {
        /// Waits for the run to end, and reads its report.
        fn finish(&mut self) -> (std::process::ExitStatus, serde_json::Value, String) {
            let exit = self.proc.wait_exit(RUN_DEADLINE);
            let text = self.proc.lines().join("\n");
            let report = std::fs::read_to_string(&self.report_file)
                .unwrap_or_else(|err| panic!("no report: {err}\n{text}"));
            (exit, serde_json::from_str(&report).unwrap(), text)
        }
    }

    /// The truth after `from_secs` never brought the robot's footprint onto `corners`, and it
    /// went round by the south of the minefield.
    fn kept_out(yard: &Yard, report: &serde_json::Value, corners: &[(f64, f64)], from_secs: f64) {
        let after = never_met(yard, report, corners, from_secs);
        // It went round by the south of the minefield: the way through the gap was closed.
        assert!(
            after
                .iter()
                .any(|at| at.y < 2.0 && at.x > 22.0 && at.x < 26.0),
            "the robot did not go round the south of the minefield"
        );
    }

    /// The true poses after `from_secs`, none of which brought the robot's footprint onto
    /// `corners`.
    fn never_met(
        yard: &Yard,
        report: &serde_json::Value,
        corners: &[(f64, f64)],
        from_secs: f64,
    ) -> Vec<Point> {
        let polygon = armor_model::geo::Polygon::new(
            corners.iter().map(|&(x, y)| Point::new(x, y)).collect(),
        );
        let radius_m = report["rehearsal"]["robot_radius_m"].as_f64().unwrap();
        let truth = recorded_truth(&yard.recording);
        let after: Vec<Point> = truth
            .iter()
            .filter(|(at_secs, _)| *at_secs >= from_secs)
            .map(|(_, at)| *at)
            .collect();
        assert!(
            after.len() > 100,
            "{} true poses after the report",
            after.len()
        );
        let least = after
            .iter()
            .map(|at| footprint_gap_m(&polygon, *at, radius_m))
            .fold(f64::INFINITY, f64::min);
        assert!(least > 0.0, "the footprint came {least} m into the area");
        after
    }

    /// The update entries of the report: (number, file, taken, message).
    fn updates(report: &serde_json::Value) -> Vec<(u64, String, bool, String)> {
        report["updates"]
            .as_array()
            .unwrap()
            .iter()
            .map(|update| {
                (
                    update["number"].as_u64().unwrap(),
                    update["file"].as_str().unwrap().to_owned(),
                    update["taken"] == true,
                    update["message"].as_str().unwrap().to_owned(),
                )
            })
            .collect()
    }

    #[test]
    fn an_area_reported_by_the_operator_across_the_leg_driven_is_driven_round() {
        let yard = Yard::new();
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        // Slower than the other runs: the robot must still be short of the gap when the area
        // reaches the run, on a loaded machine.
        let mut run = start(&yard, &yard.plan_text, "5");
        let observer = role_key(&run.secret, "observer");
        // Bad input, refused with the reason, the run unchanged.
        let (taken, said) = area(&run.addr, &run.secret, "short", &[(1.0, 1.0), (2.0, 1.0)]);
        assert!(!taken, "{said}");
        assert!(
            said.starts_with(
                "update 1 refused: area `short` has 2 corners: an area needs at least 3"
            ),
            "{said}"
        );
        let knot = [(1.0, 1.0), (3.0, 3.0), (3.0, 1.0), (1.0, 3.0)];
        let (taken, said) = area(&run.addr, &run.secret, "knot", &knot);
        assert!(!taken, "{said}");
        assert!(
            said.starts_with("update 2 refused: area `knot`: its outline crosses itself"),
            "{said}"
        );
        let (taken, said) = area(&run.addr, &run.secret, "minefield", &GAP);
        assert!(!taken, "{said}");
        assert!(
            said.starts_with("update 3 refused: the plan has an element named `minefield` already"),
            "{said}"
        );
        let (taken, said) = ctl(
            &run.addr,
            &[
                "--key",
                observer.to_str().unwrap(),
                "area",
                "seen",
                "1,1",
                "2,1",
                "2,2",
            ],
        );
        assert!(!taken && said.contains("observer"), "{said}");
        // A corner that is not `X,Y` never leaves `armor ctl`: it says which.
        let output = Command::new(bin("armor"))
            .args(["ctl", "--addr", &run.addr, "--secret"])
            .arg(&run.secret)
            .args(["area", "bad", "1,1", "2;1", "2,2"])
            .output()
            .unwrap();
        let said = String::from_utf8_lossy(&output.stderr);
        assert!(
            !output.status.success()
                && said.contains("corner 2 of the area, `2;1`: expected X,Y in metres"),
            "{said}"
        );

        // Across `cross`, as soon as it sets off from the gate.
        run.proc.wait_for("`cross` set off", RUN_DEADLINE, |line| {
            line.contains("fired `cross_appointment`")
        });
        let (taken, said) = area(&run.addr, &run.secret, "reported", &GAP);
        assert!(taken, "{said}");
        assert!(
            said.starts_with("update 4 taken: leg `cross` in force replaced at once in `cross_drive`, its path planned again from where the robot is")
                && said.contains("no-go areas added: `reported`"),
            "{said}"
        );
        let status = status(&run.addr, &run.secret);
        assert!(
            status["mission"]["updates"][3]["file"]
                .as_str()
                .is_some_and(|file| file == "area `reported` reported by the operator"),
            "{status}"
        );

        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        assert_eq!(report["outcome"], "complete", "{text}");
        assert_eq!(report["rehearsal"]["verdict"], "passed", "{text}");
        let listed = updates(&report);
        assert_eq!(
            listed
                .iter()
                .map(|(number, _, taken, _)| (*number, *taken))
                .collect::<Vec<_>>(),
            [(1, false), (2, false), (3, false), (4, true)]
        );
        let reported_at = report["updates"][3]["run_secs"].as_f64().unwrap();
        kept_out(&yard, &report, &GAP, reported_at);
    }

    #[test]
    fn an_area_reported_by_a_module_is_taken_and_driven_round() {
        let yard = Yard::new();
        // The observer, looking round at the gate, sights a minefield in the gap.
        let text = sighting(&yard.plan_text, "mines", &GAP);
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let mut run = start(&yard, &text, TIME_SCALE);
        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        assert_eq!(report["outcome"], "complete", "{text}");
        assert_eq!(report["rehearsal"]["verdict"], "passed", "{text}");
        let listed = updates(&report);
        assert_eq!(listed.len(), 1, "{listed:?}");
        let (number, file, taken, message) = &listed[0];
        assert_eq!(
            (*number, file.as_str(), *taken),
            (1, "area `mines` reported by module `observer`", true),
            "{message}"
        );
        // `cross`, not driven yet, is routed anew round the area at once: no repair, nothing
        // for the operator to choose (issue 39: an area across a later leg is not a block).
        assert!(
            message.contains("no-go areas added: `mines`")
                && message.contains("legs routed anew: `cross`"),
            "{message}"
        );
        assert!(
            !report["timeline"]
                .as_array()
                .unwrap()
                .iter()
                .any(|entry| entry["kind"] == "repair"),
            "a repair was proposed:\n{text}"
        );
        assert!(
            text.lines()
                .any(|line| line.starts_with("update 1 at ") && line.contains("`mines`")),
            "{text}"
        );
        // Reported during the arrival at the gate, before `cross` set off.
        let reported_at = report["updates"][0]["run_secs"].as_f64().unwrap();
        assert!(reported_at <= fired_at(&report, "cross_appointment"));
        kept_out(&yard, &report, &GAP, reported_at);
    }

    /// Where the robot believed it was when an update replaced its leg, from the answer.
    fn robot_at(said: &str) -> (f64, f64) {
        let from = "from where the robot is, (";
        let start = said.find(from).map(|at| at + from.len()).unwrap();
        let inside = &said[start..start + said[start..].find(')').unwrap()];
        let (x, y) = inside.split_once(", ").unwrap();
        (x.parse().unwrap(), y.parse().unwrap())
    }

    #[test]
    fn an_area_that_closes_every_way_from_the_robot_blocks_the_leg() {
        let yard = Yard::new();
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let mut run = start(&yard, &yard.plan_text, "2");
        run.proc.wait_for("`cross` set off", RUN_DEADLINE, |line| {
            line.contains("fired `cross_appointment`")
        });
        // Small areas far from the route tell where the robot is (each update's answer says),
        // until it is past the gate, heading for the gap.
        let mut probes = 0;
        let (x, _) = loop {
            probes += 1;
            assert!(probes < 200, "the robot never left the gate");
            let corner = (0.5 + 0.1 * f64::from(probes), 28.0);
            let probe = [corner, (corner.0 + 0.05, 28.0), (corner.0, 28.05)];
            let (taken, said) = area(&run.addr, &run.secret, &format!("probe{probes}"), &probe);
            assert!(taken, "{said}");
            let at = robot_at(&said);
            if at.0 >= 19.0 {
                break at;
            }
        };
        // An area over the robot, across the gap: nothing left from where it is (the leg's
        // own way from the gate, south of the minefield, is still open).
        let wall = [
            (x - 1.0, 4.5),
            (x + 3.0, 4.5),
            (x + 3.0, 8.2),
            (x - 1.0, 8.2),
        ];
        let (taken, said) = area(&run.addr, &run.secret, "wall", &wall);
        assert!(taken, "{said}");
        let stopped_at = robot_at(&said);
        assert!(
            said.contains("leg `cross` in force blocked: with the no-go area `wall` there is no way from where the robot is")
                && said.contains("the plan's contingency on `blocked` applies"),
            "{said}"
        );
        let held = status(&run.addr, &run.secret);
        assert_eq!(marked(&held), ["cross_hold"], "{held}");
        let last = held["mission"]["updates"]
            .as_array()
            .unwrap()
            .last()
            .unwrap()
            .clone();
        assert_eq!(last["taken"], true);
        assert!(
            last["message"].as_str().unwrap().contains("`wall`"),
            "{last}"
        );
        // The repair has nothing but waiting to offer: every way from inside the area is cut.
        let proposed = &held["mission"]["repair"];
        assert_eq!(proposed["leg"], "cross", "{held}");
        assert_eq!(proposed["options"].as_array().unwrap().len(), 1, "{held}");
        assert_eq!(proposed["options"][0]["kind"], "wait", "{held}");
        let secret = run.secret.to_str().unwrap().to_owned();
        let (taken, said) = ctl(&run.addr, &["--secret", &secret, "repair", "1"]);
        assert!(!taken && said.contains("option 1 is to wait"), "{said}");
        // The area is lifted (the plan as it was, without the probes nor the wall), and the
        // operator retries: the leg drives again from where the robot is, not from the gate.
        let lifted = yard.write("plan-lifted.xml", &yard.plan_text);
        let (taken, said) = update(&run.addr, &run.secret, &lifted);
        assert!(taken, "{said}");
        assert!(said.contains("no-go areas removed: `probe1`"), "{said}");
        let (retried, said) = ctl(&run.addr, &["--secret", &secret, "fire", "cross_retry"]);
        assert!(retried, "{said}");
        // From where it stopped when the wall came (it has held since), not from the gate.
        let from = robot_at(&said);
        assert!(
            said.starts_with(
                "fired `cross_retry`: leg `cross` drives again from where the robot is"
            ) && (from.0 - stopped_at.0).hypot(from.1 - stopped_at.1) < 1.0,
            "{said} (stopped at {stopped_at:?})"
        );
        assert_eq!(marked(&status(&run.addr, &run.secret)), ["cross_drive"]);
        // The operator decides: here, the mission ends.
        let (aborted, said) = ctl(
            &run.addr,
            &["--secret", run.secret.to_str().unwrap(), "abort"],
        );
        assert!(aborted, "{said}");
        let (exit, report, text) = run.finish();
        assert!(!exit.success(), "{text}");
        assert_eq!(report["outcome"], "aborted", "{text}");
        fired_at(&report, "cross_blocked");
    }

    /// A ring round the waypoint `north` (2 m clear of it all round inside), open by a slit of
    /// 0.1 m that no robot passes: `north` stays a place the robot can be, but no way leads
    /// there, so the legs `climb` (to it) and `regroup` (from it) are cut.
    const RING: [(f64, f64); 12] = [
        (28.5, 13.0),
        (34.5, 13.0),
        (34.5, 19.0),
        (28.5, 19.0),
        (28.5, 16.05),
        (29.5, 16.05),
        (29.5, 18.0),
        (33.5, 18.0),
        (33.5, 14.0),
        (29.5, 14.0),
        (29.5, 15.95),
        (28.5, 15.95),
    ];

    /// The run ended complete, its rehearsal passed, `climb` arrived at `rally` by the truth,
    /// and the robot never met the ring after `from_secs`.
    fn completed_round_the_ring(
        yard: &Yard,
        report: &serde_json::Value,
        text: &str,
        from_secs: f64,
    ) {
        assert_eq!(report["outcome"], "complete", "{text}");
        assert_eq!(report["rehearsal"]["verdict"], "passed", "{text}");
        let arrivals = report["rehearsal"]["arrivals"].as_array().unwrap();
        let climb = arrivals
            .iter()
            .find(|arrival| arrival["leg"] == "climb")
            .unwrap_or_else(|| panic!("no arrival of `climb`: {arrivals:?}"));
        assert_eq!(climb["waypoint"], "rally", "{climb}");
        assert!(
            !arrivals.iter().any(|arrival| arrival["leg"] == "regroup"),
            "{arrivals:?}"
        );
        never_met(yard, report, &RING, from_secs);
    }

    /// The yard plan where the observer, looking round at the gate, sights the ring of mines
    /// round `north`, and the plan answers `blocked` with `contingency`.
    fn ring_sighted(yard: &Yard, contingency: &str) -> String {
        edited(
            &sighting(&yard.plan_text, "ring", &RING),
            "<contingency on=\"blocked\" do=\"hold\"/>",
            contingency,
        )
    }

    #[test]
    fn an_area_that_cuts_a_later_leg_is_repaired_by_the_plans_default_and_driven_round() {
        let yard = Yard::new();
        // The plan repairs by itself.
        let text = ring_sighted(&yard, "<contingency on=\"blocked\" do=\"repair\"/>");
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let mut run = start(&yard, &text, TIME_SCALE);
        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        let listed = updates(&report);
        assert_eq!(listed.len(), 1, "{listed:?}");
        let (number, file, taken, message) = &listed[0];
        assert_eq!(
            (*number, file.as_str(), *taken),
            (
                1,
                "area `ring` reported by module `observer`, repair option 1: skip `north`: leg \
                 `climb` drives on to `rally`, in place of leg `regroup`",
                true
            ),
            "{message}"
        );
        assert!(
            message.contains("no-go areas added: `ring`")
                && message.contains("legs removed: `regroup`"),
            "{message}"
        );
        // The proposal is in the timeline: the skip first, and the plan's default.
        let proposed = report["timeline"]
            .as_array()
            .unwrap()
            .iter()
            .find(|entry| entry["kind"] == "repair")
            .unwrap_or_else(|| panic!("no repair in the timeline:\n{text}"));
        assert_eq!(proposed["leg"], "climb", "{proposed}");
        assert_eq!(proposed["default_option"], 1, "{proposed}");
        assert_eq!(proposed["options"][0]["kind"], "skip", "{proposed}");
        assert!(
            proposed["options"][0]["distance_m"].as_f64().unwrap() > 10.0,
            "{proposed}"
        );
        let reported_at = report["updates"][0]["run_secs"].as_f64().unwrap();
        completed_round_the_ring(&yard, &report, &text, reported_at);
        // The recording has them too, on the run's own channel: the proposal, then the update
        // that took it, with the same numbers and words as the report.
        let recorded: Vec<serde_json::Value> = armor_tests::mcap::read_mcap(&yard.recording)
            .into_iter()
            .filter(|((topic, _), _)| topic == "armor-run.updates")
            .flat_map(|((_, encoding), messages)| {
                assert_eq!(encoding, "json");
                messages.into_iter().map(|(_, data)| {
                    let text: serde_json::Value = serde_json::from_slice(&data).unwrap();
                    serde_json::from_str(text["text"].as_str().unwrap()).unwrap()
                })
            })
            .collect();
        let kinds: Vec<&str> = recorded
            .iter()
            .map(|entry| entry["kind"].as_str().unwrap())
            .collect();
        assert_eq!(kinds, ["repair", "update"], "{recorded:?}");
        assert_eq!(recorded[0]["options"], proposed["options"], "{recorded:?}");
        assert_eq!(
            (
                &recorded[1]["number"],
                &recorded[1]["taken"],
                &recorded[1]["file"]
            ),
            (
                &report["updates"][0]["number"],
                &serde_json::Value::Bool(true),
                &report["updates"][0]["file"]
            ),
            "{recorded:?}"
        );
    }

    #[test]
    fn the_operator_chooses_a_repair_with_armor_ctl_repair_and_an_observer_cannot() {
        let yard = Yard::new();
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let mut run = start(&yard, &yard.plan_text, TIME_SCALE);
        let observer = role_key(&run.secret, "observer");
        let secret = run.secret.to_str().unwrap().to_owned();
        // Nothing to repair yet.
        let (taken, said) = ctl(&run.addr, &["--secret", &secret, "repair", "1"]);
        assert!(!taken, "{said}");
        assert!(said.starts_with("no repair is proposed"), "{said}");
        // The ring cuts `climb` and `regroup`: the area is refused as it stands (the plan
        // holds on `blocked`, it names no default), and a repair is proposed.
        let (taken, said) = area(&run.addr, &run.secret, "ring", &RING);
        assert!(!taken, "{said}");
        assert!(
            said.contains("a repair is proposed for leg `climb`"),
            "{said}"
        );
        let proposed = status(&run.addr, &run.secret)["mission"]["repair"].clone();
        assert_eq!(proposed["leg"], "climb", "{proposed}");
        assert!(proposed["default_option"].is_null(), "{proposed}");
        let options = proposed["options"].as_array().unwrap();
        let kinds: Vec<&str> = options
            .iter()
            .map(|option| option["kind"].as_str().unwrap())
            .collect();
        assert_eq!(kinds, ["skip", "return", "wait"], "{proposed}");
        // `armor ctl status` prints them numbered, with their costs.
        let (ok, printed) = ctl(&run.addr, &["--secret", &secret, "status"]);
        assert!(ok, "{printed}");
        assert!(
            printed.contains("repair proposed at ")
                && printed.contains("  1. skip `north`: leg `climb` drives on to `rally`")
                && printed.contains("3. wait where the robot is"),
            "{printed}"
        );
        // An observer reads, it does not choose.
        let (taken, said) = ctl(
            &run.addr,
            &["--key", observer.to_str().unwrap(), "repair", "1"],
        );
        assert!(!taken && said.contains("observer"), "{said}");
        let (taken, said) = ctl(&run.addr, &["--secret", &secret, "repair", "7"]);
        assert!(!taken, "{said}");
        assert!(said.contains("has options 1 to 3, not 7"), "{said}");
        let (taken, said) = ctl(&run.addr, &["--secret", &secret, "repair", "1"]);
        assert!(taken, "{said}");
        assert!(
            said.starts_with("update 2 taken: leg `advance` in force")
                && said.contains("no-go areas added: `ring`"),
            "{said}"
        );
        let after = status(&run.addr, &run.secret);
        assert!(after["mission"]["repair"].is_null(), "{after}");
        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        let listed = updates(&report);
        assert_eq!(
            listed
                .iter()
                .map(|(number, file, taken, _)| (*number, file.as_str(), *taken))
                .collect::<Vec<_>>(),
            [
                (1, "area `ring` reported by the operator", false),
                (
                    2,
                    "area `ring` reported by the operator, repair option 1: skip `north`: leg \
                     `climb` drives on to `rally`, in place of leg `regroup`",
                    true
                ),
            ]
        );
        let chosen_at = report["updates"][1]["run_secs"].as_f64().unwrap();
        completed_round_the_ring(&yard, &report, &text, chosen_at);
    }

    /// The run's status once `pred` holds of it, polled until `RUN_DEADLINE`. A status the run
    /// did not answer in time (busy checking an update on a loaded machine) is asked again.
    fn status_when(
        run: &Run,
        what: &str,
        pred: impl Fn(&serde_json::Value) -> bool,
    ) -> serde_json::Value {
        let give_up = std::time::Instant::now() + RUN_DEADLINE;
        let secret = run.secret.to_str().unwrap();
        loop {
            let (ok, text) = ctl(&run.addr, &["--secret", secret, "status", "--json"]);
            let json = text.find('{').map_or("", |start| &text[start..]);
            if let (true, Ok(now)) = (ok, serde_json::from_str::<serde_json::Value>(json))
                && pred(&now)
            {
                return now;
            }
            assert!(
                std::time::Instant::now() < give_up,
                "{what} never came: {text}\n{}",
                run.proc.lines().join("\n")
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// The kinds of a proposed repair's options, in order.
    fn kinds(proposed: &serde_json::Value) -> Vec<String> {
        proposed["options"]
            .as_array()
            .unwrap()
            .iter()
            .map(|option| option["kind"].as_str().unwrap().to_owned())
            .collect()
    }

    /// The run ended complete, its rehearsal passed by the truth, and `leg` arrived at
    /// `waypoint` by it.
    fn completed(report: &serde_json::Value, text: &str, leg: &str, waypoint: &str) {
        assert_eq!(report["outcome"], "complete", "{text}");
        assert_eq!(report["rehearsal"]["verdict"], "passed", "{text}");
        let arrivals = report["rehearsal"]["arrivals"].as_array().unwrap();
        assert!(
            arrivals
                .iter()
                .any(|arrival| arrival["leg"] == leg && arrival["waypoint"] == waypoint),
            "no arrival of `{leg}` at `{waypoint}`: {arrivals:?}"
        );
    }

    /// The yard plan with `advance` due 20 s after the start (it takes about 25 s to drive)
    /// and `contingency` on it.
    fn late_advance(yard: &Yard, contingency: &str) -> String {
        edited(
            &edited(
                &yard.plan_text,
                "arrive_by=\"2026-11-23T08:01:00Z\"",
                "arrive_by=\"2026-11-23T08:00:20Z\"",
            ),
            "    </arrival>\n  </leg>",
            &format!("    </arrival>\n    {contingency}\n  </leg>"),
        )
    }

    #[test]
    fn a_late_leg_raises_a_repair_and_the_operators_choice_drives_it_on() {
        let yard = Yard::new();
        let text = late_advance(&yard, "<contingency on=\"late\" do=\"hold\"/>");
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let mut run = start(&yard, &text, TIME_SCALE);
        let secret = run.secret.to_str().unwrap().to_owned();
        // The robot sets off 12 m from the gate, 24 s at the plan's speed, due in 20 s: it is
        // forecast late as soon as it drives, before the deadline passes; the leg holds and its
        // repair is proposed, none applied by the plan.
        let held = status_when(&run, "the late leg's repair", |now| {
            now["mission"]["repair"]["leg"] == "advance"
        });
        assert_eq!(marked(&held), ["advance_hold"], "{held}");
        let proposed = &held["mission"]["repair"];
        assert_eq!(
            proposed["why"],
            "leg `advance` is late (due by 08:00:20): at the plan's speed it would arrive after \
             its deadline, it holds in `advance_hold`",
            "{proposed}"
        );
        assert!(
            proposed["run_secs"].as_f64().is_some_and(|at| at < 20.0),
            "forecast late before its deadline: {proposed}"
        );
        assert!(proposed["default_option"].is_null(), "{proposed}");
        assert_eq!(
            kinds(proposed),
            ["push_back", "drop_deadline", "skip", "wait"],
            "{proposed}"
        );
        let pushed = proposed["options"][0]["summary"].as_str().unwrap();
        assert!(
            pushed.starts_with("push the deadline back to 08:00:")
                && pushed.contains("when the robot is now expected at `gate`"),
            "{pushed}"
        );
        let (ok, printed) = ctl(&run.addr, &["--secret", &secret, "status"]);
        assert!(ok, "{printed}");
        assert!(
            printed.contains("2. drop the deadline: leg `advance` drives on to `gate` with none"),
            "{printed}"
        );
        // The operator drops the deadline: taken as an update, and the leg drives on from
        // where the robot is.
        let (taken, said) = ctl(&run.addr, &["--secret", &secret, "repair", "2"]);
        assert!(taken, "{said}");
        assert!(
            said.starts_with("update 1 taken: leg `advance` in force")
                && said.contains("fired `advance_retry`"),
            "{said}"
        );
        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        completed(&report, &text, "advance", "gate");
        completed(&report, &text, "regroup", "rally");
        // The deadline fired the hold; the option taken fired the retry.
        fired_at(&report, "advance_late");
        assert!(
            report["timeline"]
                .as_array()
                .unwrap()
                .iter()
                .any(|entry| entry["kind"] == "repair_applied"
                    && entry["fired"] == "advance_retry"
                    && entry["ok"] == true),
            "{text}"
        );
        let listed = updates(&report);
        assert_eq!(
            listed
                .iter()
                .map(|(number, file, taken, _)| (*number, file.as_str(), *taken))
                .collect::<Vec<_>>(),
            [(
                1,
                "repair option 2: drop the deadline: leg `advance` drives on to `gate` with none",
                true
            )]
        );
    }

    /// `text` run (one robot at a time: the guard holds the turn) until it proposes a repair
    /// for `leg`, whose option 1 the plan applies `after_secs` after the proposal: the run, the
    /// proposal, and when the default is due (run seconds).
    fn proposing_a_default(
        yard: &Yard,
        text: &str,
        leg: &str,
        after_secs: f64,
    ) -> (
        std::sync::MutexGuard<'static, ()>,
        Run,
        serde_json::Value,
        f64,
    ) {
        let one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let run = start(yard, text, TIME_SCALE);
        let proposed = status_when(&run, &format!("`{leg}`'s repair"), |now| {
            now["mission"]["repair"]["leg"] == leg
        })["mission"]["repair"]
            .clone();
        assert_eq!(proposed["default_option"], 1, "{proposed}");
        let proposed_at = proposed["run_secs"].as_f64().unwrap();
        let default_at = proposed["default_at_run_secs"].as_f64().unwrap();
        assert!(
            (default_at - proposed_at - after_secs).abs() < 1e-6,
            "{proposed}"
        );
        (one, run, proposed, default_at)
    }

    #[test]
    fn a_repairs_default_is_applied_after_the_time_the_plan_gives() {
        let yard = Yard::new();
        // The plan repairs by itself, 15 s (run time) after proposing, unless the operator
        // chooses first.
        let text = ring_sighted(
            &yard,
            "<contingency on=\"blocked\" do=\"repair\" after_secs=\"15\"/>",
        );
        let (_one, mut run, _, default_at) = proposing_a_default(&yard, &text, "climb", 15.0);
        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        let listed = updates(&report);
        assert_eq!(
            listed
                .iter()
                .map(|(number, file, taken, _)| (*number, file.as_str(), *taken))
                .collect::<Vec<_>>(),
            [
                (1, "area `ring` reported by module `observer`", false),
                (
                    2,
                    "area `ring` reported by module `observer`, repair option 1: skip `north`: leg \
                     `climb` drives on to `rally`, in place of leg `regroup`",
                    true
                ),
            ],
            "{text}"
        );
        // Not at once: when the plan said (its check and compilation take their time after
        // that, in run seconds at ten times real time).
        let taken_at = report["updates"][1]["run_secs"].as_f64().unwrap();
        assert!(
            taken_at >= default_at,
            "taken at {taken_at} s, due at {default_at} s:\n{}",
            text.lines()
                .filter(|line| line.contains("update") || line.contains("repair"))
                .collect::<Vec<_>>()
                .join("\n")
        );
        assert!(
            text.contains("no option chosen in time, the plan's default (option 1) is applied"),
            "{text}"
        );
        completed_round_the_ring(&yard, &report, &text, taken_at);
    }

    /// Across the northern gap where `cross` drives, in the simulator's world only: an obstacle
    /// neither the plan's map nor the follower's has.
    const UNMAPPED: [(f64, f64); 4] = [(23.3, 5.6), (24.7, 5.6), (24.7, 7.9), (23.3, 7.9)];

    /// The yard where the simulator's world has the obstacle `UNMAPPED` in the gap `cross`
    /// drives through, and the plan, the follower and the localiser have the yard as mapped;
    /// the follower does not replan by itself, so that it stops in front of the obstacle and
    /// reports `blocked`. Writes the system, and returns the plan with `contingency` on
    /// `blocked` in place of its `hold`.
    fn truly_blocked(yard: &Yard, contingency: &str) -> String {
        let mapped = workspace_root().join("assets/worlds/yard.world");
        let truth = format!(
            "{}\nrect {},{} {},{}\n",
            std::fs::read_to_string(&mapped).unwrap(),
            UNMAPPED[0].0,
            UNMAPPED[0].1,
            UNMAPPED[2].0,
            UNMAPPED[2].1
        );
        let truth_file = yard.write("yard-truth.world", &truth);
        let system_file = yard.dir.path().join("system.xml");
        let system = edited(
            &edited(
                &std::fs::read_to_string(&system_file).unwrap(),
                &format!(
                    "<module name=\"sim\" type=\"sim\">\n    <param name=\"world\" value=\"{}\"/>",
                    mapped.display()
                ),
                &format!(
                    "<module name=\"sim\" type=\"sim\">\n    <param name=\"world\" value=\"{}\"/>",
                    truth_file.display()
                ),
            ),
            "<param name=\"blocked_after_secs\" value=\"20\"/>",
            "<param name=\"blocked_after_secs\" value=\"20\"/>\n    <param name=\"max_replans\" value=\"0\"/>",
        );
        std::fs::write(&system_file, system).unwrap();
        edited(
            &edited(
                &yard.plan_text,
                "system=\"system.xml\"",
                &format!("system=\"system.xml\" world=\"{}\"", mapped.display()),
            ),
            "<contingency on=\"blocked\" do=\"hold\"/>",
            contingency,
        )
    }

    #[test]
    fn a_leg_truly_blocked_is_repaired_by_a_way_round_and_completed() {
        let yard = Yard::new();
        let text = truly_blocked(&yard, "<contingency on=\"blocked\" do=\"hold\"/>");
        let _one = ONE_ROBOT_AT_A_TIME
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        let mut run = start(&yard, &text, TIME_SCALE);
        let secret = run.secret.to_str().unwrap().to_owned();
        let held = status_when(&run, "`cross` blocked", |now| {
            now["mission"]["repair"]["leg"] == "cross"
        });
        assert_eq!(marked(&held), ["cross_hold"], "{held}");
        let proposed = &held["mission"]["repair"];
        // Round through `rally`, north-west of the container, keeps off the gap both ways.
        let (number, option) = proposed["options"]
            .as_array()
            .unwrap()
            .iter()
            .find(|option| option["kind"] == "way_round" && option["via"][0] == "rally")
            .map(|option| (option["number"].as_u64().unwrap(), option.clone()))
            .unwrap_or_else(|| panic!("no way round through `rally`: {proposed}"));
        let (taken, said) = ctl(
            &run.addr,
            &["--secret", &secret, "repair", &number.to_string()],
        );
        assert!(taken, "{said}");
        assert!(
            said.contains("legs added: `cross_via_rally`") && said.contains("fired `cross_retry`"),
            "{said} ({option})"
        );
        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        fired_at(&report, "cross_blocked");
        completed(&report, &text, "cross", "rally");
        completed(&report, &text, "cross_via_rally", "east");
        completed(&report, &text, "regroup", "rally");
        // By the truth, the robot's body never met the obstacle.
        never_met(&yard, &report, &UNMAPPED, 0.0);
    }

    /// How late, in run seconds, the plan's default may be taken after the time it gave: the
    /// run decides at the first turn of its loop after that time (every 20 ms of real time)
    /// and takes the option it checked when it proposed it (about a second of real time in a
    /// debug build: the 30 s the plan gives are 3 s here); at ten times real time, on a loaded
    /// machine, its migration and the path from where the robot is take a few tenths of a
    /// second of real time.
    const DEFAULT_LATE_SECS: f64 = 10.0;

    /// Issue 39's test of a repair: what stopped the follower in the gap (the obstacle only
    /// the simulator has) is held as a no-go area across its way, the repair proposed with
    /// the plan's default after 30 s, nobody chooses, and the default, driving on round it,
    /// takes the robot south of the minefield to `east` and on to the end. The truth judges:
    /// the robot never met the obstacle nor the area, and went the other way.
    #[test]
    fn a_leg_truly_blocked_is_driven_round_by_the_plans_default_with_nobody_choosing() {
        let yard = Yard::new();
        let text = truly_blocked(
            &yard,
            "<contingency on=\"blocked\" do=\"repair\" after_secs=\"30\"/>",
        );
        let (_one, mut run, proposed, default_at) =
            proposing_a_default(&yard, &text, "cross", 30.0);
        assert!(
            proposed["why"].as_str().is_some_and(|why| why.contains(
                "stopped before something the plan's map does not have (held as the no-go area \
                 `cross_blocked` across its way ahead)"
            )),
            "{proposed}"
        );
        let first = &proposed["options"][0];
        assert_eq!(first["kind"], "way_round", "{proposed}");
        // No waypoint on the way: the leg itself, round the area (an empty `via` is left out).
        assert!(
            first["via"].as_array().is_none_or(Vec::is_empty),
            "{proposed}"
        );
        let label = "repair option 1: drive on to `east` round what stopped the robot (no-go \
                     area `cross_blocked`)";
        assert_eq!(
            first["summary"]
                .as_str()
                .map(|summary| format!("repair option 1: {summary}")),
            Some(label.to_owned()),
            "{proposed}"
        );

        let (exit, report, text) = run.finish();
        assert!(exit.success(), "{exit}:\n{text}");
        fired_at(&report, "cross_blocked");
        completed(&report, &text, "cross", "east");
        completed(&report, &text, "regroup", "rally");
        let listed = updates(&report);
        assert_eq!(
            listed
                .iter()
                .map(|(number, file, taken, _)| (*number, file.as_str(), *taken))
                .collect::<Vec<_>>(),
            [(1, label, true)],
            "{text}"
        );
        // Not before the time the plan gave, and within the bound after it.
        let taken_at = report["updates"][0]["run_secs"].as_f64().unwrap();
        assert!(
            taken_at >= default_at && taken_at <= default_at + DEFAULT_LATE_SECS,
            "taken at {taken_at} s, due at {default_at} s"
        );
        // By the truth: the body never met the obstacle, nor the area after it was taken, and
        // the robot went round the south of the minefield.
        never_met(&yard, &report, &UNMAPPED, 0.0);
        let area = report["rehearsal"]["no_go_areas"]
            .as_array()
            .unwrap()
            .iter()
            .find(|area| area["area"] == "cross_blocked")
            .unwrap_or_else(|| panic!("`cross_blocked` not judged: {}", report["rehearsal"]));
        assert!(
            area["least_distance_m"]
                .as_f64()
                .is_some_and(|gap| gap > 0.0),
            "{area}"
        );
        let after = never_met(&yard, &report, &UNMAPPED, taken_at);
        assert!(
            after
                .iter()
                .any(|at| at.y < 2.0 && at.x > 22.0 && at.x < 26.0),
            "the robot did not go round the south of the minefield"
        );
    }
}
