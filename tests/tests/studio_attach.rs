//! The studio attached to a run started elsewhere (`armor-studio --attach ADDR`, Run →
//! Attach…), driven through egui_kittest: it follows the run through its control interface,
//! pauses and resumes the mission with the same buttons as a run of its own, detaches without
//! stopping it, attaches again through the menu's prompt, and shows a lost connection; drives
//! the robot with the arrow keys through the run's control interface (no port of the teleop
//! module's own), which stops it when the keys are let go and goes on without it once detached;
//! attached without the system file, draws the run's world and robot from the files the run
//! sends (a ROS map's image too), and opens the plan a run plays in its Mission view.
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use armor_protocol::Status;
use armor_studio::app::View;
use armor_studio::common::palette::Palette;
use armor_studio::files::Home;
use armor_studio::{Options, StudioApp};
use armor_tests::{
    PATIENCE, Proc, bin_dir, ctl_status, driven_system, process_alive, run_with_control,
};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};

/// A mission that waits for the operator: it runs until the test is done with it.
const MISSION: &str = r#"<mission name="waits" system="system.xml">
  <place name="counting" tokens="1">
    <module name="counter"/>
    <module name="checker"/>
  </place>
  <place name="done" final="true"/>
  <transition name="finish" operator="true">
    <input place="counting"/>
    <output place="done"/>
  </transition>
</mission>
"#;

const SYSTEM: &str = r#"<system name="demo">
  <module name="counter" type="counter">
    <param name="period_secs" value="0.1"/>
  </module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

/// `armor run` of the waiting mission in a terminal of its own, and its control address.
fn run_elsewhere(dir: &std::path::Path) -> (Proc, std::net::SocketAddr) {
    std::fs::write(dir.join("system.xml"), SYSTEM).unwrap();
    std::fs::write(dir.join("mission.xml"), MISSION).unwrap();
    run_file_elsewhere(&dir.join("mission.xml"))
}

fn harness(dir: &std::path::Path, attach: std::net::SocketAddr) -> Harness<'static, StudioApp> {
    harness_with(dir, attach, None)
}

/// The studio attached at `attach`, with the run's system `file` open when given
/// (`armor-studio --attach ADDR FILE`).
fn harness_with(
    dir: &std::path::Path,
    attach: std::net::SocketAddr,
    file: Option<std::path::PathBuf>,
) -> Harness<'static, StudioApp> {
    let mut options = Options::new(Home::new(dir.join("home")));
    options.module_path = vec![bin_dir()];
    // With a file, the modules' descriptions pick the live views' sources, as the probed
    // palette of the window does.
    let descriptions = if file.is_some() {
        let binaries = armor_runtime::probe::list_modules(&[bin_dir()]);
        armor_runtime::probe::probe_all(&binaries, Duration::from_secs(10))
            .into_iter()
            .filter_map(|(_, description)| description.ok())
            .collect()
    } else {
        Vec::new()
    };
    options.palette = Some(Palette::from_descriptions(descriptions));
    options.attach = Some(attach);
    options.file = file;
    harness_of(StudioApp::new(options))
}

/// The studio's window around `app`, its first frames drawn (an `--attach` attaches there).
fn harness_of(app: StudioApp) -> Harness<'static, StudioApp> {
    let mut harness = Harness::builder()
        .with_size([1500.0, 950.0])
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(8)
        .build_ui_state(|ui, app: &mut StudioApp| app.ui(ui), app);
    harness.run_ok();
    harness
}

fn step_until(
    harness: &mut Harness<'_, StudioApp>,
    what: &str,
    mut done: impl FnMut(&mut Harness<'_, StudioApp>) -> bool,
) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        harness.step();
        if done(harness) {
            // One more frame, drawn with what the condition saw.
            harness.step();
            return;
        }
        assert!(
            Instant::now() < deadline,
            "waited {PATIENCE:?} for {what}; last status: {:#?}",
            harness.state().run().status()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn status(app: &StudioApp) -> Status {
    app.run().status().unwrap_or_default()
}

fn paused(addr: std::net::SocketAddr) -> bool {
    ctl_status(&addr.to_string())["mission"]["paused"]
        .as_bool()
        .unwrap()
}

/// Run → Attach…: the Run menu (the other "Run" is the view's tab, toggled on), then its
/// Attach item; the prompt for the run's control address is open.
fn open_attach_prompt(harness: &mut Harness<'_, StudioApp>) {
    harness
        .get_all_by_label("Run")
        .find(|node| node.accesskit_node().toggled().is_none())
        .expect("the Run menu")
        .click();
    harness.run_ok();
    harness.get_by_label("Attach…").click();
    harness.run_ok();
    assert!(has_label(harness, "The run's control address"));
}

fn has_label(harness: &Harness<'_, StudioApp>, text: &str) -> bool {
    harness.query_by_label_contains(text).is_some()
}

#[test]
fn the_studio_attaches_pauses_resumes_and_detaches_without_stopping_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let (run, addr) = run_elsewhere(dir.path());
    let mut harness = harness(dir.path(), addr);
    assert_eq!(harness.state().view(), View::Run);
    step_until(&mut harness, "the run's modules and mission", |h| {
        let status = status(h.state());
        status.mission.is_some() && status.modules.len() == 2
    });
    assert!(has_label(&harness, "attached to demo"));
    // The log panel says where the logs are rather than staying blank.
    assert!(has_label(&harness, "its modules' logs stay where it runs"));

    harness.get_by_label("⏸ Pause").click();
    step_until(&mut harness, "the mission paused", |h| {
        status(h.state())
            .mission
            .is_some_and(|mission| mission.paused)
    });
    assert!(paused(addr), "the run itself is paused");
    harness.get_by_label("⏵ Resume").click();
    step_until(&mut harness, "the mission resumed", |h| {
        status(h.state())
            .mission
            .is_some_and(|mission| !mission.paused)
    });
    assert!(!paused(addr));

    // Detach: the studio stops watching, the run goes on.
    harness.get_by_label("⏏ Detach").click();
    step_until(&mut harness, "the studio detached", |h| {
        !h.state().run().is_running()
    });
    assert!(process_alive(run.pid()), "detaching stopped the run");
    let after = ctl_status(&addr.to_string());
    assert_eq!(after["mission"]["outcome"], serde_json::Value::Null);

    // Run → Attach…: the prompt offers the last address; attach again.
    open_attach_prompt(&mut harness);
    harness.get_by_label("Attach").click();
    step_until(&mut harness, "attached again", |h| {
        h.state().run().is_running() && status(h.state()).mission.is_some()
    });

    // The run goes away: the studio says the connection is lost, and keeps asking.
    drop(run);
    step_until(&mut harness, "the lost connection shown", |h| {
        has_label(h, "connection lost")
    });
    assert!(harness.state().run().is_running(), "still trying");
}

/// `armor run FILE` in a terminal of its own, and its control address.
fn run_file_elsewhere(file: &std::path::Path) -> (Proc, std::net::SocketAddr) {
    let (run, addr) = run_with_control(file);
    (run, addr.parse().unwrap())
}

fn truth(app: &StudioApp) -> Option<(f64, f64)> {
    app.run().live().truth.map(|pose| (pose.x_m, pose.y_m))
}

fn distance(a: (f64, f64), b: (f64, f64)) -> f64 {
    (a.0 - b.0).hypot(a.1 - b.1)
}

/// Steps until the robot's pose has not changed for half a second; returns it.
fn at_rest(harness: &mut Harness<'_, StudioApp>, what: &str) -> (f64, f64) {
    let mut last = truth(harness.state()).unwrap();
    let mut still_since = Instant::now();
    step_until(harness, what, |h| {
        let now = truth(h.state()).unwrap();
        if distance(now, last) > 1e-9 {
            last = now;
            still_since = Instant::now();
        }
        still_since.elapsed() > Duration::from_millis(500)
    });
    last
}

#[test]
fn the_attached_studio_drives_through_the_runs_control_interface_and_detaches() {
    let dir = tempfile::tempdir().unwrap();
    let system = driven_system(dir.path());
    let (run, addr) = run_file_elsewhere(&system);
    let mut harness = harness_with(dir.path(), addr, Some(system));
    step_until(&mut harness, "the teleop up and the robot seen", |h| {
        h.state()
            .run()
            .status()
            .is_some_and(|status| armor_studio::run::session::can_drive(&status))
            && truth(h.state()).is_some()
    });
    // The pad shows once the run's teleop module is up.
    harness.get_by_label("forward");
    let start = at_rest(&mut harness, "the robot at rest");
    harness.key_down(egui::Key::ArrowUp);
    step_until(&mut harness, "the robot driven forward", |h| {
        truth(h.state()).is_some_and(|now| distance(now, start) > 0.3)
    });
    harness.key_up(egui::Key::ArrowUp);
    let stopped = at_rest(&mut harness, "the robot stopped once the key is let go");
    assert!(
        distance(start, stopped) < 3.0,
        "the robot drove on after the key was let go: {start:?} → {stopped:?}"
    );

    // Detached: the run goes on, and nothing drives the robot.
    harness.get_by_label("⏏ Detach").click();
    step_until(&mut harness, "the studio detached", |h| {
        !h.state().run().is_running()
    });
    assert!(process_alive(run.pid()), "detaching stopped the run");
    let pad = ctl_status(&addr.to_string())["modules"]
        .as_array()
        .unwrap()
        .iter()
        .find(|module| module["name"] == "pad")
        .cloned()
        .unwrap();
    assert_eq!(pad["state"], "running", "{pad}");
}

#[test]
fn attached_without_its_file_the_studio_draws_the_run_from_the_runs_own_files() {
    let dir = tempfile::tempdir().unwrap();
    let system = driven_system(dir.path());
    let (run, addr) = run_file_elsewhere(&system);
    // No file, and no module descriptions of its own: all from the run.
    let mut harness = harness(dir.path(), addr);
    step_until(
        &mut harness,
        "the world and the robot on the live map",
        |h| {
            truth(h.state()).is_some()
                && h.state()
                    .run()
                    .own_map_view()
                    .is_some_and(|map| map.surroundings.world.is_some())
        },
    );
    let map = harness.state().run().own_map_view().unwrap();
    assert_ne!(
        map.surroundings.system_file, system,
        "the map reads the run's copy of its system, not the file the test wrote"
    );
    assert!(
        map.surroundings.problems.is_empty(),
        "{:?}",
        map.surroundings.problems
    );
    assert!(has_label(&harness, "attached to driven"));
    assert!(
        has_label(&harness, "from the run"),
        "the status line says so"
    );

    harness.get_by_label("⏏ Detach").click();
    step_until(&mut harness, "the studio detached", |h| {
        !h.state().run().is_running()
    });
    assert!(process_alive(run.pid()), "detaching stopped the run");
}

/// The bundled robot system's text, its world and its recording given as absolute paths (the
/// recording in `dir`), so that it runs from any folder.
fn yard_system(dir: &std::path::Path) -> String {
    let world = armor_tests::workspace_root().join("assets/worlds/yard.world");
    std::fs::read_to_string(armor_tests::workspace_root().join("missions/robot/system.xml"))
        .unwrap()
        .replace(
            r#"value="yard.world""#,
            &format!(r#"value="{}""#, world.display()),
        )
        .replace(
            r#"value="truth.mcap""#,
            &format!(r#"value="{}""#, dir.join("truth.mcap").display()),
        )
}

#[test]
fn attached_without_its_file_to_a_plans_run_the_studio_opens_the_runs_plan() {
    let dir = tempfile::tempdir().unwrap();
    let system = yard_system(dir.path());
    std::fs::create_dir(dir.path().join("robot")).unwrap();
    std::fs::create_dir(dir.path().join("plans")).unwrap();
    std::fs::write(dir.path().join("robot/system.xml"), system).unwrap();
    let plan = dir.path().join("plans/gate.xml");
    std::fs::write(
        &plan,
        r#"<plan name="gate" system="../robot/system.xml">
  <navigation module="follower" speed_mps="0.5"/>
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
  <leg name="advance" from="home" to="gate"/>
</plan>"#,
    )
    .unwrap();
    let (run, addr) = run_file_elsewhere(&plan);
    let mut harness = harness(dir.path(), addr);
    step_until(
        &mut harness,
        "the run's plan open and the robot seen",
        |h| {
            truth(h.state()).is_some()
                && h.state()
                    .mission()
                    .and_then(|mission| mission.path())
                    .is_some_and(|path| path.ends_with("plans/gate.xml"))
        },
    );
    let mission = harness.state().mission().unwrap();
    assert_ne!(mission.path(), Some(plan.as_path()), "a copy of the run's");
    assert!(
        mission.surroundings.world.is_some(),
        "the plan finds its system, and its world, as on the run's machine: {:?}",
        mission.surroundings.problems
    );
    assert_eq!(
        harness.state().run().session_target(),
        mission.path(),
        "the Run view runs the plan's map"
    );
    assert!(
        mission.checked().net().is_some(),
        "the plan compiled for the Run view's net, without a visit to the Mission view"
    );
    drop(run);
}

#[test]
fn attached_without_its_file_to_a_run_on_a_ros_map_the_studio_has_the_maps_image_too() {
    let dir = tempfile::tempdir().unwrap();
    let worlds = armor_tests::workspace_root().join("assets/worlds");
    for name in ["yard-map.yaml", "yard-map.pgm"] {
        std::fs::copy(worlds.join(name), dir.path().join(name)).unwrap();
    }
    let system = dir.path().join("mapped.xml");
    std::fs::write(
        &system,
        r#"<system name="mapped">
  <module name="sim" type="sim"><param name="world" value="yard-map.yaml"/></module>
  <module name="pad" type="teleop"/>
  <link from="pad.cmd_vel" to="sim.cmd_vel"/>
</system>
"#,
    )
    .unwrap();
    let (run, addr) = run_file_elsewhere(&system);
    let mut harness = harness(dir.path(), addr);
    step_until(&mut harness, "the map's world and the robot", |h| {
        truth(h.state()).is_some()
            && h.state()
                .run()
                .own_map_view()
                .is_some_and(|map| map.surroundings.world.is_some())
    });
    let map = harness.state().run().own_map_view().unwrap();
    let copy = map.surroundings.system_file.with_file_name("yard-map.pgm");
    assert_eq!(
        std::fs::read(&copy).unwrap(),
        std::fs::read(worlds.join("yard-map.pgm")).unwrap(),
        "the map's image, as the run has it"
    );
    drop(run);
}

/// The studio attached with an observer's key (`armor secret derive --role observer`) reads the
/// run and its live data, says it is an observer, and greys every command it may not give: pause, abort, firing
/// a transition, starting and stopping modules; it offers no driving pad.
#[test]
fn attached_with_an_observers_key_the_studio_reads_and_greys_its_commands() {
    let dir = tempfile::tempdir().unwrap();
    let secret = armor_tests::secret_file(dir.path());
    let key = armor_tests::role_key(&secret, "observer");
    // The waiting mission on the driven robot: the counter and the checker, which the mission
    // starts and stops, beside the sim and the teleop, which always run.
    let driven = std::fs::read_to_string(driven_system(dir.path())).unwrap();
    let modules = SYSTEM.lines().skip(1).collect::<Vec<_>>().join("\n");
    std::fs::write(
        dir.path().join("system.xml"),
        driven.replace("</system>\n", &modules),
    )
    .unwrap();
    let mission = dir.path().join("mission.xml");
    std::fs::write(&mission, MISSION).unwrap();
    let run = Proc::start(
        std::process::Command::new(armor_tests::bin("armor"))
            .arg("run")
            .arg(&mission)
            .arg("--secret")
            .arg(&secret)
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let addr: std::net::SocketAddr = armor_tests::control_address(&run).parse().unwrap();

    let mut options = Options::new(Home::new(dir.path().join("home")));
    options.module_path = vec![bin_dir()];
    options.palette = Some(Palette::from_descriptions(Vec::new()));
    options.attach = Some(addr);
    let mut app = StudioApp::new(options);
    // The key the Run view's field holds (from ARMOR_SECRET_FILE or typed there).
    app.run_mut().secret_file = key.to_string_lossy().into_owned();
    let mut harness = harness_of(app);
    step_until(&mut harness, "the run read with the observer's key", |h| {
        let status = status(h.state());
        status.mission.is_some()
            && status
                .modules
                .iter()
                .any(|module| module.name == "pad" && module.state.as_str() == "running")
            && status.modules.len() == 4
    });
    assert!(!harness.state().run().may_command());
    assert!(has_label(&harness, "attached as an observer: reading only"));
    // It shows the run's live data as an operator's studio does: the robot's pose and its
    // laser scan on the map of the run's world.
    step_until(&mut harness, "the observer's live pose and scan", |h| {
        let live = h.state().run().live();
        live.truth.is_some() && live.scan.is_some()
    });
    for command in ["⏸ Pause", "⏹ Abort", "⏭ finish"] {
        assert!(
            harness.get_by_label(command).accesskit_node().is_disabled(),
            "`{command}` is offered to an observer"
        );
    }
    let switches: Vec<bool> = harness
        .get_all_by_label("on")
        .map(|switch| switch.accesskit_node().is_disabled())
        .collect();
    assert_eq!(switches, [true, true], "the modules' on switches");
    assert!(has_label(&harness, "driving needs an operator's"));
    assert!(harness.query_by_label("forward").is_none(), "a driving pad");
    // A click on the greyed button commands nothing.
    harness.get_by_label("⏹ Abort").click();
    for _ in 0..30 {
        harness.step();
    }
    let after = ctl_status_with(&addr, &secret);
    assert_eq!(
        after["mission"]["outcome"],
        serde_json::Value::Null,
        "{after}"
    );
    assert!(process_alive(run.pid()));
}

/// `armor ctl status --json` with the run's secret.
fn ctl_status_with(addr: &std::net::SocketAddr, secret: &std::path::Path) -> serde_json::Value {
    let output = std::process::Command::new(armor_tests::bin("armor"))
        .args(["ctl", "--addr", &addr.to_string(), "--secret"])
        .arg(secret)
        .args(["status", "--json"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&output.stdout);
    serde_json::Deserializer::from_str(&text)
        .into_iter()
        .next()
        .and_then(Result::ok)
        .unwrap_or_else(|| panic!("no status: {output:?}"))
}

/// The time scale the Run view's toolbar shows: the number box highest in the window.
fn shown_time_scale(harness: &Harness<'_, StudioApp>) -> Option<f64> {
    harness
        .query_all_by_role(egui::accesskit::Role::SpinButton)
        .min_by(|a, b| a.rect().min.y.total_cmp(&b.rect().min.y))
        .and_then(|node| node.accesskit_node().numeric_value())
}

/// Issue 37, defect 6: attached to a plan's run at ×5 without its files, the toolbar shows ×5;
/// once detached, neither the title, the modules, the status line nor the toolbar says the
/// run is still watched, ended, or offers to run the copy of its files; attached again from
/// the menu (Enter answering the prompt), the run's plan is drawn again.
#[test]
fn detached_nothing_on_screen_lies_and_attached_again_from_the_menu_the_plan_is_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let system = yard_system(dir.path());
    std::fs::write(dir.path().join("system.xml"), system).unwrap();
    let plan = dir.path().join("gate.xml");
    // A long leg, so that the run outlives the test.
    std::fs::write(
        &plan,
        r#"<plan name="gate" system="system.xml">
  <navigation module="follower" speed_mps="0.2"/>
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
  <leg name="advance" from="home" to="gate"/>
  <leg name="back" from="gate" to="home"/>
</plan>"#,
    )
    .unwrap();
    let run = Proc::start(
        std::process::Command::new(armor_tests::bin("armor"))
            .arg("run")
            .arg(&plan)
            .arg("--no-run-folder")
            .args(["--time-scale", "5"])
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let addr: std::net::SocketAddr = armor_tests::control_address(&run).parse().unwrap();
    let mut harness = harness(dir.path(), addr);
    let plan_drawn = |h: &mut Harness<'_, StudioApp>| {
        let app = h.state();
        let mission = app.mission().and_then(|mission| mission.path());
        mission.is_some_and(|path| path.ends_with("gate.xml"))
            && app.run().session_target() == mission
            && status(app).mission.is_some()
            && truth(app).is_some()
    };
    step_until(&mut harness, "the run's plan drawn", plan_drawn);
    assert_eq!(shown_time_scale(&harness), Some(5.0), "the run's own scale");
    assert!(!status(harness.state()).modules.is_empty());
    assert!(
        harness
            .query_all_by_label_contains("running")
            .next()
            .is_some()
    );

    harness.get_by_label("⏏ Detach").click();
    step_until(&mut harness, "the studio detached", |h| {
        !h.state().run().is_running()
    });
    harness.run_ok();
    assert!(process_alive(run.pid()), "detaching stopped the run");
    let title = harness.state().title().to_owned();
    assert!(
        title.contains("detached") && !title.contains("ended"),
        "{title}"
    );
    assert!(
        harness.query_all_by_label("running").next().is_none(),
        "no module reads running once the studio stopped watching"
    );
    assert!(has_label(&harness, "Detached: the run goes on"));
    let said = &harness.state().status().text;
    assert!(
        said.starts_with(&format!("detached from the run at {addr}")),
        "{said}"
    );
    // No Run of the copy of the run's files the studio was shown.
    for button in harness
        .query_all_by_role(egui::accesskit::Role::Button)
        .filter(|node| {
            node.accesskit_node()
                .label()
                .is_some_and(|label| label.starts_with("▶ Run"))
        })
    {
        assert!(
            button.accesskit_node().is_disabled(),
            "{:?} offered after detaching",
            button.accesskit_node().label()
        );
    }

    // Run → Attach…, the last address offered, Enter: the plan is drawn again.
    open_attach_prompt(&mut harness);
    harness.key_press(egui::Key::Enter);
    harness.run_ok();
    assert!(
        !has_label(&harness, "The run's control address"),
        "Enter answers the prompt"
    );
    step_until(&mut harness, "the run's plan drawn again", plan_drawn);
    assert_eq!(shown_time_scale(&harness), Some(5.0));
    drop(run);
}
