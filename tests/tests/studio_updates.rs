//! Issue 39 in the studio, with real processes: `armor run` of the yard plan (the bundled robot,
//! simulated) in a terminal of its own; the studio attaches to it (`armor-studio --attach`),
//! the operator drags waypoint `north` on the Mission view's map while the robot drives and
//! presses "Send to robot": the run takes the update, the studio says so, and the plan the run
//! plays (as it sends it) has `north` where it was dragged. Another unit reports an area with
//! `armor ctl area` from elsewhere: the studio's Run view draws it without being asked. The run's
//! report lists both updates, the studio's by the name it gave it.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use armor_model::plan::{AreaKind, GraphicKind, LatLon, Plan};
use armor_protocol::Request;
use armor_studio::app::View;
use armor_studio::common::palette::Palette;
use armor_studio::files::Home;
use armor_studio::{Options, StudioApp};
use armor_tests::{Proc, bin, bin_dir, control_address, ctl, workspace_root};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};

const PATIENCE: Duration = Duration::from_secs(60);

/// The yard plan and its system in `dir`, the world named by its absolute path and the
/// recording written there.
fn yard(dir: &Path) -> PathBuf {
    let robot = workspace_root().join("missions/robot");
    let world = workspace_root().join("assets/worlds/yard.world");
    let system = std::fs::read_to_string(robot.join("system.xml"))
        .unwrap()
        .replace(
            "value=\"yard.world\"",
            &format!("value=\"{}\"", world.display()),
        );
    assert!(system.contains(&world.display().to_string()));
    std::fs::write(dir.join("system.xml"), system).unwrap();
    let plan = std::fs::read_to_string(robot.join("plan-yard.xml"))
        .unwrap()
        .replace(
            "value=\"yard-recon.mcap\"",
            &format!("value=\"{}\"", dir.join("yard-recon.mcap").display()),
        );
    let file = dir.join("plan.xml");
    std::fs::write(&file, plan).unwrap();
    file
}

/// A studio attached at `control` (`armor-studio --attach ADDR`), with no file of the run's:
/// it asks the run for them.
fn studio(dir: &Path, control: std::net::SocketAddr) -> Harness<'static, StudioApp> {
    let mut options = Options::new(Home::new(dir.join("home")));
    options.module_path = vec![bin_dir()];
    options.palette = Some(Palette::from_descriptions(Vec::new()));
    options.attach = Some(control);
    let mut harness = Harness::builder()
        .with_size([1500.0, 950.0])
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(8)
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options),
        );
    harness.run_ok();
    harness
}

fn step_until(harness: &mut Harness<'_, StudioApp>, what: &str, done: impl Fn(&StudioApp) -> bool) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        harness.step();
        if done(harness.state()) {
            harness.step();
            return;
        }
        assert!(
            Instant::now() < deadline,
            "waited {PATIENCE:?} for {what}; status line {:?}; last status: {:#?}",
            harness.state().status().text,
            harness.state().run().status()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn waypoint(plan: &Plan, name: &str) -> LatLon {
    plan.waypoint(name).unwrap().position
}

fn areas(plan: &Plan) -> Vec<String> {
    plan.graphics
        .iter()
        .filter(|graphic| graphic.kind == GraphicKind::Area(AreaKind::NoGo))
        .map(|graphic| graphic.name.clone())
        .collect()
}

#[test]
fn a_plan_edited_in_the_studio_is_sent_to_a_real_run_which_takes_it_and_reports_it() {
    let dir = tempfile::tempdir().unwrap();
    let plan = yard(dir.path());
    let report_file = dir.path().join("report.json");
    // Slow enough for the studio's frames to reach the run while the robot is on its first
    // legs, on a loaded machine; the test aborts the mission once it has seen what it needs.
    let mut run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&plan)
            .args(["--time-scale", "4", "--start-at", "2026-11-23T08:00:00Z"])
            .arg("--report")
            .arg(&report_file)
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir())
            .current_dir(dir.path()),
    );
    let addr = control_address(&run);
    let mut harness = studio(dir.path(), addr.parse().unwrap());
    step_until(&mut harness, "the run's plan in the Mission view", |app| {
        app.mission()
            .is_some_and(|mission| app.run().watches(mission) && mission.checked().net().is_some())
            && app
                .run()
                .status()
                .is_some_and(|status| status.mission.is_some())
    });
    harness.state_mut().set_view(View::Mission);
    harness.run_ok();
    let before = waypoint(harness.state().mission().unwrap().plan(), "north");
    assert!(
        harness
            .get_by_label("⬆ Send to robot")
            .accesskit_node()
            .is_disabled(),
        "the plan shown is the robot's: nothing to send"
    );

    // The operator drags `north` west on the map, and sends the plan.
    let mission = harness.state().mission().unwrap();
    let from = mission.screen_pos(before).unwrap();
    let to = from - egui::vec2(40.0, 0.0);
    harness.hover_at(from);
    harness.step();
    harness.drag_at(from);
    harness.step();
    for i in 1..=12 {
        harness.hover_at(from + (to - from) * (i as f32 / 12.0));
        harness.step();
    }
    harness.drop_at(to);
    harness.run_ok();
    let moved = waypoint(harness.state().mission().unwrap().plan(), "north");
    assert!(moved.lon_deg < before.lon_deg - 1e-6, "{moved:?}");
    harness.get_by_label("⬆ Send to robot").click();
    harness.run_ok();
    step_until(&mut harness, "the run's answer", |app| {
        app.run().updates.answer.is_some()
    });
    let answer = harness.state().run().updates.answer.clone().unwrap();
    assert!(answer.taken, "{}", answer.message);
    assert!(
        answer.message.starts_with("update 1 taken: "),
        "{}",
        answer.message
    );
    harness.get_by_label("✔ Taken by the robot");

    // The plan the run plays now, as it sends it: `north` where it was dragged.
    let files = armor_protocol::request(addr.parse().unwrap(), &Request::Files, None).unwrap();
    let running = Plan::parse(&files.files.unwrap().mission.unwrap().text).unwrap();
    let north = waypoint(&running, "north");
    assert!(
        (north.lon_deg - moved.lon_deg).abs() < 1e-6
            && (north.lat_deg - moved.lat_deg).abs() < 1e-6,
        "the run plays north at {north:?}, dragged to {moved:?}"
    );

    // Another unit reports an area from elsewhere: the Run view draws it, unasked.
    let (taken, said) = ctl(&addr, &["area", "reported", "2,12", "4,12", "4,14", "2,14"]);
    assert!(taken, "{said}");
    step_until(&mut harness, "the area reported drawn", |app| {
        app.mission()
            .is_some_and(|mission| areas(mission.watched_plan()).contains(&"reported".to_owned()))
    });
    harness.state_mut().set_view(View::Run);
    harness.run_ok();
    harness.get_by_label("Plan updates (2)");
    harness.get_by_label("area `reported` reported by the operator");

    // The mission aborted, the run's report lists both updates.
    let (aborted, said) = ctl(&addr, &["abort"]);
    assert!(aborted, "{said}");
    run.wait_exit(PATIENCE);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_file).unwrap()).unwrap();
    let updates: Vec<(u64, String, bool)> = report["updates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|update| {
            (
                update["number"].as_u64().unwrap(),
                update["file"].as_str().unwrap().to_owned(),
                update["taken"] == true,
            )
        })
        .collect();
    assert_eq!(
        updates,
        [
            (1, "plan.xml (sent from the studio)".to_owned(), true),
            (
                2,
                "area `reported` reported by the operator".to_owned(),
                true
            ),
        ]
    );
}
