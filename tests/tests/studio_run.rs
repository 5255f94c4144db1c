//! The studio's Run view driven as an operator would, through egui_kittest: a plan run at
//! accelerated time to its final place; a run paused (the robot holds), resumed, advanced by
//! hand and aborted; a module killed from outside shown crashed, then running again; the robot
//! driven with the arrow keys through the teleop module, and the recording of that drive opened
//! into the same map; an arrow held at ×10 keeping teleop in control, the robot stopped within
//! half a second of wall time once it is let go; a crate only the sim knows of replanned round,
//! the path followed and the one replaced drawn; the robot driven by its camera (the video
//! panel holding the arrow keys) and the recorded video played back in the same panel; the
//! localiser's estimate and the simulator's truth side by side (issue 33): a robot carried away
//! mid-leg shown `localised` then `lost`, held without driving on (judged by the truth) until
//! the operator sets its pose and retries the leg, then completing by the truth; the pose set by a drag on the map (rviz's "2D Pose
//! Estimate"), the tool greyed for a studio attached with an observer's key.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use armor_model::world::Point;
use armor_module_api::types::{LocalisationState, Pose2D};
use armor_protocol::{ModuleState, Request, Role, RoleKey, Status};
use armor_studio::app::View;
use armor_studio::common::palette::Palette;
use armor_studio::files::Home;
use armor_studio::{Options, StudioApp};
use armor_tests::{bin_dir, workspace_root};
use egui::{Key, Modifiers, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};

const PATIENCE: Duration = Duration::from_secs(40);

/// A studio whose palette describes the real module binaries and whose runs work in `dir`.
fn harness(dir: &Path) -> Harness<'static, StudioApp> {
    let mut options = Options::new(Home::new(dir.join("home")));
    options.module_path = vec![bin_dir()];
    let binaries = armor_runtime::probe::list_modules(&[bin_dir()]);
    let descriptions: Vec<_> = armor_runtime::probe::probe_all(&binaries, Duration::from_secs(10))
        .into_iter()
        .filter_map(|(_, description)| description.ok())
        .collect();
    options.palette = Some(Palette::from_descriptions(descriptions));
    let mut app = StudioApp::new(options);
    app.run_mut().working_dir = dir.to_path_buf();
    let mut harness = Harness::builder()
        .with_size([1500.0, 950.0])
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(8)
        .build_ui_state(|ui, app: &mut StudioApp| app.ui(ui), app);
    harness.run_ok();
    harness
}

/// Steps frames until `done` holds, at most `patience`.
fn step_until(
    harness: &mut Harness<'_, StudioApp>,
    what: &str,
    patience: Duration,
    mut done: impl FnMut(&StudioApp) -> bool,
) {
    let deadline = Instant::now() + patience;
    loop {
        harness.step();
        if done(harness.state()) {
            return;
        }
        let status = harness.state().run().status();
        assert!(
            Instant::now() < deadline,
            "waited {patience:?} for {what}; last status: {status:#?}; run ended: {:?}",
            harness.state().run().ended()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn status(app: &StudioApp) -> Status {
    app.run().status().unwrap_or_default()
}

fn module_state(app: &StudioApp, name: &str) -> Option<ModuleState> {
    status(app)
        .modules
        .iter()
        .find(|module| module.name == name)
        .map(|module| module.state)
}

/// The robot system of `missions/robot`, its world and recording given as absolute paths so
/// that the run works from `dir`.
fn robot_system(dir: &Path) -> PathBuf {
    robot_system_with(dir, "")
}

/// [`robot_system`] with `sim_params` (`<param …/>` elements) given to the sim.
fn robot_system_with(dir: &Path, sim_params: &str) -> PathBuf {
    let world = workspace_root().join("assets/worlds/yard.world");
    let text = std::fs::read_to_string(workspace_root().join("missions/robot/system.xml"))
        .unwrap()
        .replace(
            r#"value="yard.world""#,
            &format!(r#"value="{}""#, world.display()),
        )
        .replace(
            r#"value="truth.mcap""#,
            &format!(r#"value="{}""#, dir.join("truth.mcap").display()),
        )
        .replace(
            r#"<module name="sim" type="sim">"#,
            &format!(r#"<module name="sim" type="sim">{sim_params}"#),
        );
    assert!(text.contains(&world.display().to_string()));
    assert!(text.contains(sim_params));
    let file = dir.join("system.xml");
    std::fs::write(&file, text).unwrap();
    file
}

/// A plan in the yard: from `home` east to the gate (12 m), then `legs` more.
fn plan(dir: &Path, legs: &str) -> PathBuf {
    robot_system(dir);
    let file = dir.join("plan.xml");
    std::fs::write(
        &file,
        format!(
            r#"<plan name="short" system="system.xml">
  <navigation module="follower" speed_mps="0.5"/>
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
  <leg name="advance" from="home" to="gate"/>
  {legs}
</plan>"#
        ),
    )
    .unwrap();
    file
}

fn open_and_run(harness: &mut Harness<'_, StudioApp>, file: &Path, time_scale: f64) {
    if file.ends_with("plan.xml") {
        harness.state_mut().set_view(View::Mission);
        harness.run_ok();
        harness.state_mut().open_plan(file);
    } else {
        harness.state_mut().open(file);
    }
    harness.run_ok();
    harness.state_mut().set_view(View::Run);
    harness.state_mut().run_mut().time_scale = time_scale;
    harness.run_ok();
    // Before the run, the title names what a Run would start (not an empty System view's
    // "untitled").
    let name = file.file_name().unwrap().to_string_lossy();
    assert_eq!(harness.state().title(), format!("{name} — ArMoR Studio"));
    // The button says what it runs: the document of the view left last.
    let run = if file.ends_with("plan.xml") {
        "▶ Run plan"
    } else {
        "▶ Run system"
    };
    harness.get_by_label(run).click();
    harness.run_ok();
    assert!(
        harness.state().run().is_running(),
        "{:?}",
        harness.state().status()
    );
}

/// In a plain system run the follower and the observer drive too: stops them by hand, for the
/// operator to drive alone.
fn stop_the_drivers(harness: &mut Harness<'_, StudioApp>) {
    for module in ["follower", "observer"] {
        harness.state_mut().run_mut().request(Request::StopModule {
            module: module.to_owned(),
        });
    }
    step_until(harness, "follower and observer stopped", PATIENCE, |app| {
        module_state(app, "follower") == Some(ModuleState::Stopped)
            && module_state(app, "observer") == Some(ModuleState::Stopped)
    });
}

/// The robot system running at `time_scale` in a studio, every module up, the follower and
/// the observer stopped: the operator drives alone, with the pad on screen.
fn ready_to_drive(dir: &Path, time_scale: f64) -> Harness<'static, StudioApp> {
    let system = robot_system(dir);
    let mut harness = harness(dir);
    open_and_run(&mut harness, &system, time_scale);
    step_until(&mut harness, "every module running", PATIENCE, |app| {
        app.run().live().truth.is_some()
            && status(app)
                .modules
                .iter()
                .all(|module| module.state == ModuleState::Running)
    });
    stop_the_drivers(&mut harness);
    harness.run_ok();
    harness.get_by_label("forward");
    harness
}

fn truth_x(app: &StudioApp) -> Option<f64> {
    app.run().live().truth.map(|pose| pose.x_m)
}

/// Waits for the run to end after Shift+F5.
fn stop_with_shift_f5(harness: &mut Harness<'_, StudioApp>) {
    harness.key_press_modifiers(Modifiers::SHIFT, Key::F5);
    step_until(harness, "the run stopped", PATIENCE, |app| {
        !app.run().is_running()
    });
}

/// The time scale F5's prompt offers, which says what it runs in `words`: the number box just
/// below those words.
fn prompt_scale(harness: &Harness<'_, StudioApp>, words: &str) -> f64 {
    let said = harness
        .get_by_label(&format!("Run the {words} with armor run"))
        .rect();
    harness
        .query_all_by_role(egui::accesskit::Role::SpinButton)
        .find(|node| {
            let rect = node.rect();
            rect.min.y > said.min.y && rect.min.y < said.max.y + 60.0
        })
        .and_then(|node| node.accesskit_node().numeric_value())
        .expect("the prompt's time scale")
}

/// Issue 37, defects 2 and 8: F5 runs the document of the view shown (the system in the System
/// view even with a plan open in the Mission view, the plan in the Mission view), the menu and
/// F5's prompt say which, and the prompt asks the time scale, offering the last one asked,
/// in this session and the next (F5 never falls back to ×1).
#[test]
fn f5_runs_the_document_of_the_view_shown_at_the_time_scale_asked_and_remembered() {
    let dir = tempfile::tempdir().unwrap();
    let plan_file = plan(dir.path(), "");
    let system_file = dir.path().join("system.xml");
    let mut harness = harness(dir.path());
    // A plan opened in the Mission view first, then the system in the System view.
    harness.state_mut().set_view(View::Mission);
    harness.run_ok();
    harness.state_mut().open_plan(&plan_file);
    harness.run_ok();
    harness.state_mut().set_view(View::System);
    harness.run_ok();
    harness.state_mut().open(&system_file);
    harness.run_ok();

    harness.key_press(Key::F5);
    harness.run_ok();
    assert!(
        !harness.state().run().is_running(),
        "F5 runs at once, without asking the time scale: {:?}",
        harness.state().run().session_target()
    );
    assert_eq!(prompt_scale(&harness, "system `system.xml`"), 1.0);
    // The time scale is typed into the prompt, and Enter runs.
    harness
        .get_by_role(egui::accesskit::Role::SpinButton)
        .click();
    harness.run_ok();
    harness.key_press_modifiers(Modifiers::COMMAND, Key::A);
    harness
        .get_by_role(egui::accesskit::Role::SpinButton)
        .type_text("5");
    harness.run_ok();
    harness.key_press(Key::Enter);
    harness.run_ok();
    assert!(
        harness.state().run().is_running(),
        "{:?}",
        harness.state().status()
    );
    assert_eq!(harness.state().view(), View::Run);
    assert_eq!(
        harness.state().run().session_target(),
        Some(system_file.as_path())
    );
    step_until(&mut harness, "the run's status", PATIENCE, |app| {
        app.run().status().is_some()
    });
    assert_eq!(status(harness.state()).time_scale, 5.0);
    // The Run view's button says what it runs (greyed during the run).
    harness.get_by_label("▶ Run system");
    stop_with_shift_f5(&mut harness);

    // In the Mission view, the File menu and F5 run the plan, at the scale asked last.
    harness.state_mut().set_view(View::Mission);
    harness.run_ok();
    harness.get_by_label("File").click();
    harness.run_ok();
    harness.get_by_label("Run plan…");
    harness.key_press(Key::Escape);
    harness.run_ok();
    harness.key_press(Key::F5);
    harness.run_ok();
    assert_eq!(prompt_scale(&harness, "plan `plan.xml`"), 5.0);
    harness.key_press(Key::Enter);
    harness.run_ok();
    assert_eq!(
        harness.state().run().session_target(),
        Some(plan_file.as_path())
    );
    harness.get_by_label("▶ Run plan");
    stop_with_shift_f5(&mut harness);
    drop(harness);

    // A new session offers the scale asked last; Escape runs nothing.
    let mut harness = self::harness(dir.path());
    harness.state_mut().open(&system_file);
    harness.run_ok();
    harness.get_by_label("File").click();
    harness.run_ok();
    harness.get_by_label("Run system…");
    harness.key_press(Key::Escape);
    harness.run_ok();
    harness.key_press(Key::F5);
    harness.run_ok();
    assert_eq!(prompt_scale(&harness, "system `system.xml`"), 5.0);
    harness.key_press(Key::Escape);
    harness.run_ok();
    assert!(harness.query_by_label_contains("with armor run").is_none());
    assert!(!harness.state().run().is_running());
}

#[test]
fn a_plan_run_from_the_run_view_reaches_its_final_place() {
    let dir = tempfile::tempdir().unwrap();
    let file = plan(dir.path(), "");
    let mut harness = harness(dir.path());
    // The map left far from the yard in the Mission view: the run must bring the robot back.
    harness.state_mut().set_view(View::Mission);
    harness.run_ok();
    harness.state_mut().open_plan(&file);
    harness.run_ok();
    harness
        .state_mut()
        .mission_mut()
        .unwrap()
        .centre_on(Point::new(5_000.0, 5_000.0));
    harness.run_ok();
    open_and_run(&mut harness, &file, 10.0);
    // The title is read in the frame the robot first shows: at ten times real time on a loaded
    // machine, the short run may have ended a few frames later.
    let mut title = String::new();
    step_until(&mut harness, "the robot on the live map", PATIENCE, |app| {
        title = app.title().to_owned();
        truth_x(app).is_some()
    });
    assert_eq!(title, "plan.xml (running) — ArMoR Studio");
    harness.run_ok();
    // The plan names the follower only: the avoider its commands pass through runs with it,
    // and its row says why.
    step_until(&mut harness, "the avoider running", PATIENCE, |app| {
        module_state(app, "avoider") == Some(ModuleState::Running)
    });
    harness.run_ok();
    harness.get_by_label("carries follower.cmd_desired");
    let truth = harness.state().run().live().truth.unwrap();
    let (robot, map) = harness
        .state()
        .mission()
        .unwrap()
        .last_screen_of(Point::new(truth.x_m, truth.y_m))
        .unwrap();
    assert!(
        map.shrink(12.0).contains(robot),
        "the run frames the robot: it is drawn at {robot:?}, the map is {map:?}"
    );
    // The net follows the mission: its marked places are in the net's view.
    step_until(
        &mut harness,
        "the marked places in the net's view",
        PATIENCE,
        |app| {
            let (Some(mission), Some(run)) = (app.mission(), status(app).mission) else {
                return false;
            };
            let (view, Some(layout)) = (mission.net_view(), mission.net_layout()) else {
                return false;
            };
            run.marking.keys().all(|place| {
                layout
                    .nodes
                    .get(place)
                    .is_some_and(|node| view.canvas.contains(view.screen_from_layout(node.pos)))
            })
        },
    );
    step_until(&mut harness, "the run to end", PATIENCE, |app| {
        app.run().ended().is_some()
    });
    harness.run_ok();
    assert_eq!(
        harness.state().title(),
        "plan.xml (run ended) — ArMoR Studio"
    );
    let status = status(harness.state());
    // Once the run is over no module reads "running".
    for module in &status.modules {
        assert!(
            matches!(module.state, ModuleState::Ended | ModuleState::Exited),
            "{} reads {:?} after the run",
            module.name,
            module.state
        );
    }
    let mission = status.mission.unwrap();
    assert_eq!(mission.outcome.as_deref(), Some("complete"));
    assert_eq!(
        mission.marking.keys().collect::<Vec<_>>(),
        ["done"],
        "the final place"
    );
    assert!(
        mission
            .firings
            .iter()
            .any(|firing| firing.transition.starts_with("advance")),
        "{:?}",
        mission.firings
    );
    harness.run_ok();
    harness.get_by_label_contains("`short` (complete)");
    let x = truth_x(harness.state()).unwrap();
    assert!(x > 8.0, "the robot drove east to the gate, at x = {x}");
}

#[test]
fn pause_holds_the_robot_and_the_operator_fires_and_aborts() {
    let dir = tempfile::tempdir().unwrap();
    let file = plan(
        dir.path(),
        r#"<leg name="back" from="gate" to="home" wait_secs="600"/>"#,
    );
    let mut harness = harness(dir.path());
    // At 1.5 times real time the robot takes about seven seconds of wall time to reach the gate:
    // time enough for the pause to reach it through a loaded machine's studio frames.
    open_and_run(&mut harness, &file, 1.5);
    // The robot starts at `home`, 4 m east of the world's origin: driving is moving from there.
    step_until(&mut harness, "the robot's true pose", PATIENCE, |app| {
        truth_x(app).is_some()
    });
    let start_x = truth_x(harness.state()).unwrap();
    step_until(
        &mut harness,
        "the robot to start driving",
        PATIENCE,
        |app| truth_x(app).is_some_and(|x| x > start_x + 0.3),
    );
    // The robot's data can come before the first status that has the mission (and its Pause).
    step_until(&mut harness, "the mission in the status", PATIENCE, |app| {
        status(app).mission.is_some()
    });
    harness.run_ok();
    harness.get_by_label("⏸ Pause").click();
    step_until(&mut harness, "the mission to pause", PATIENCE, |app| {
        status(app).mission.is_some_and(|mission| mission.paused)
    });
    // The modules hold: after the robot has come to rest, it stays where it is. Rest and the
    // while after it are measured on the run's clock and in fresh samples of the robot's, not
    // on the wall clock: on a busy machine a wall-clock second may bring neither, and a
    // robot not seen to move because no sample came would prove nothing.
    let reading = |app: &StudioApp| {
        (
            status(app).run_secs,
            app.run().live().samples,
            truth_x(app).unwrap_or(f64::NAN),
        )
    };
    let mut last = reading(harness.state());
    step_until(&mut harness, "the robot to come to rest", PATIENCE, |app| {
        let now = reading(app);
        if now.0 < last.0 + 1.0 || now.1 < last.1 + 20 {
            return false;
        }
        let resting = (now.2 - last.2).abs() < 0.01;
        last = now;
        resting
    });
    let (rested_secs, rested_samples, held_at) = last;
    step_until(&mut harness, "a while paused", PATIENCE, |app| {
        let (secs, samples, _) = reading(app);
        secs >= rested_secs + 4.0 && samples >= rested_samples + 40
    });
    let now_at = truth_x(harness.state()).unwrap();
    assert!(
        (now_at - held_at).abs() < 0.05,
        "paused, the robot moved from {held_at} to {now_at}"
    );
    assert!(now_at < 11.0, "paused before the gate, at {now_at}");

    harness.get_by_label("⏵ Resume").click();
    step_until(&mut harness, "the robot to move again", PATIENCE, |app| {
        truth_x(app).is_some_and(|x| x > now_at + 0.3)
    });
    // The leg's arrival waits for the follower; the operator declares it by hand.
    let enabled = status(harness.state()).mission.unwrap().enabled;
    let arrival = enabled
        .iter()
        .find(|enabled| enabled.transition.starts_with("advance"))
        .unwrap_or_else(|| panic!("no transition of the first leg enabled: {enabled:?}"))
        .transition
        .clone();
    harness.get_by_label(&format!("⏭ {arrival}")).click();
    step_until(&mut harness, "the firing by hand", PATIENCE, |app| {
        status(app).mission.is_some_and(|mission| {
            mission
                .firings
                .iter()
                .any(|firing| firing.by_hand && firing.transition == arrival)
        })
    });
    harness.get_by_label("⏹ Abort").click();
    step_until(&mut harness, "the run to end", PATIENCE, |app| {
        app.run().ended().is_some()
    });
    assert_eq!(
        status(harness.state()).mission.unwrap().outcome.as_deref(),
        Some("aborted")
    );
}

#[test]
fn a_module_killed_from_outside_shows_crashed_then_running_again() {
    let dir = tempfile::tempdir().unwrap();
    let system = dir.path().join("system.xml");
    std::fs::copy(workspace_root().join("missions/demo/system.xml"), &system).unwrap();
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &system, 1.0);
    step_until(&mut harness, "the counter running", PATIENCE, |app| {
        module_state(app, "counter") == Some(ModuleState::Running)
    });
    // The diagram shows it too.
    assert_eq!(
        harness.state().run().module_states().get("counter"),
        Some(&ModuleState::Running)
    );
    let pid = status(harness.state())
        .modules
        .iter()
        .find(|module| module.name == "counter")
        .and_then(|module| module.pid)
        .unwrap();
    armor_tests::signal(pid as i32, 9);
    step_until(
        &mut harness,
        "the counter restarted and running",
        PATIENCE,
        |app| {
            status(app).modules.iter().any(|module| {
                module.name == "counter"
                    && module.restarts == 1
                    && module.state == ModuleState::Running
                    && module.pid != Some(pid)
            })
        },
    );
    harness.run_ok();
    harness.get_by_label("1 restart");
    harness.get_by_label_contains("crashed: it was killed by signal 9");
    // Its log says so too, and the filter finds it.
    harness.state_mut().run_mut().log_filter = "restarting in".to_owned();
    harness.run_ok();
    harness.get_by_label_contains("restarting in");
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
}

#[test]
fn the_robot_is_driven_with_the_keys_and_its_recording_replays() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = ready_to_drive(dir.path(), 1.0);
    let rest = Instant::now() + Duration::from_millis(800);
    step_until(&mut harness, "the robot at rest", PATIENCE, |_| {
        Instant::now() > rest
    });
    let start = harness.state().run().live().truth.unwrap();
    harness.key_down(Key::ArrowUp);
    step_until(&mut harness, "the robot to move forward", PATIENCE, |app| {
        app.run()
            .live()
            .truth
            .is_some_and(|now| (now.x_m - start.x_m).hypot(now.y_m - start.y_m) > 0.3)
    });
    harness.key_up(Key::ArrowUp);
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
    let recording = dir.path().join("truth.mcap");
    assert!(recording.is_file(), "the recorder wrote {recording:?}");
    harness.state_mut().run_mut().open_recording(&recording);
    harness.run_ok();
    let live = harness.state().run().live();
    assert!(live.truth.is_some(), "the recording's last pose is shown");
    assert!(live.trail.len() >= 2, "with the path driven");
    harness.get_by_label_contains("Recording truth.mcap");
}

/// The robot's true pose as a triple, so that a turn on the spot counts as a move.
fn truth_pose(app: &StudioApp) -> Option<(f64, f64, f64)> {
    app.run()
        .live()
        .truth
        .map(|pose| (pose.x_m, pose.y_m, pose.theta_rad))
}

/// The mux's "in control: …" lines so far, in the studio's log of the run.
fn mux_switches(app: &StudioApp) -> Vec<String> {
    app.run()
        .log_of("mux")
        .into_iter()
        .filter(|line| line.contains("in control: "))
        .collect()
}

/// Issue 37: at ×10 the teleop's dead-man (half a second of run time, 50 ms of wall time)
/// expired between two of the studio's commands (ten a second of wall time), and the mux
/// switched between teleop and the others 21 times in 2 s. Held for 3 s of wall time, the
/// arrow must keep teleop in control throughout, and the robot must stand still within half
/// a second of wall time once it is let go.
#[test]
fn at_ten_times_real_time_a_held_arrow_keeps_teleop_in_control_and_release_stops_the_robot() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = ready_to_drive(dir.path(), 10.0);
    let start = truth_pose(harness.state()).unwrap();

    // Left turns on the spot: the yard's walls cannot stop the robot in the operator's stead.
    harness.key_down(Key::ArrowLeft);
    step_until(&mut harness, "teleop in control", PATIENCE, |app| {
        mux_switches(app)
            .last()
            .is_some_and(|line| line.ends_with("in control: teleop"))
    });
    let taken_over = mux_switches(harness.state()).len();
    let held_until = Instant::now() + Duration::from_secs(3);
    // The angle turned, summed over the poses seen (the heading wraps round).
    let mut heading = start.2;
    let mut turned_rad = 0.0;
    step_until(&mut harness, "3 s of the arrow held", PATIENCE, |app| {
        let now = truth_pose(app).unwrap().2;
        turned_rad += armor_module_catalog::wrap_angle(now - heading).abs();
        heading = now;
        Instant::now() >= held_until
    });
    let while_held = mux_switches(harness.state());
    assert_eq!(
        while_held.len(),
        taken_over,
        "the mux switched while the arrow was held: {:?}",
        &while_held[taken_over - 1..]
    );
    assert!(
        turned_rad > 1.0,
        "the robot turned only {turned_rad} rad in 3 s at ×10"
    );
    let turned = truth_pose(harness.state()).unwrap();

    harness.key_up(Key::ArrowLeft);
    let released = Instant::now();
    let mut last = turned;
    let mut last_move = released;
    step_until(
        &mut harness,
        "the robot still for a second",
        PATIENCE,
        |app| {
            let now = truth_pose(app).unwrap();
            if now != last {
                last = now;
                last_move = Instant::now();
            }
            last_move.elapsed() > Duration::from_secs(1)
        },
    );
    let stopped_after = last_move.saturating_duration_since(released);
    eprintln!(
        "held 3 s at ×10 with {} switches of the mux; still {stopped_after:?} after release",
        while_held.len() - taken_over
    );
    assert!(
        stopped_after <= Duration::from_millis(500),
        "the robot still moved {stopped_after:?} of wall time after the arrow was let go"
    );
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
}

#[test]
fn the_mappers_grid_and_corrected_pose_are_shown_on_the_live_map() {
    let dir = tempfile::tempdir().unwrap();
    let system = robot_system(dir.path());
    let text = std::fs::read_to_string(&system).unwrap().replace(
        "</system>",
        r#"  <module name="mapper" type="mapper"/>
  <link from="sim.scan" to="mapper.scan"/>
  <link from="sim.odometry" to="mapper.odometry"/>
</system>"#,
    );
    std::fs::write(&system, text).unwrap();
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &system, 1.0);
    let sources = harness.state().run().sources().unwrap();
    assert_eq!(sources.grid.as_deref(), Some("mapper.map"));
    assert_eq!(
        sources.estimated.as_deref(),
        Some("localiser.pose"),
        "the estimated pose is the one the follower drives by, not the mapper's beside it"
    );
    step_until(
        &mut harness,
        "the grid drawn on the live map",
        PATIENCE,
        |app| app.run().grid_picture_size().is_some() && app.run().live().estimated.is_some(),
    );
    let live = harness.state().run().live();
    let grid = live.grid.unwrap();
    assert_eq!(
        harness.state().run().grid_picture_size(),
        Some([grid.width as usize, grid.height as usize]),
        "one pixel a cell"
    );
    let occupied = grid.cells.iter().filter(|&&cell| cell > 50).count();
    let free = grid
        .cells
        .iter()
        .filter(|&&cell| (0..50).contains(&cell))
        .count();
    assert!(
        occupied > 10 && free > 100,
        "the yard's walls seen: {occupied} occupied and {free} free cells"
    );
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
}

#[test]
fn a_replan_round_what_only_the_sim_knows_is_drawn_on_the_live_map() {
    let dir = tempfile::tempdir().unwrap();
    let file = plan(dir.path(), "");
    // A crate on the way from home (4, 4) to the gate (16, 4) that the world file, and so the
    // plan, does not hold: the follower's laser finds it and the follower plans round it.
    let crate_at = Point::new(10.0, 4.0);
    let system = dir.path().join("system.xml");
    let text = std::fs::read_to_string(&system).unwrap().replace(
        r#"<module name="sim" type="sim">"#,
        r#"<module name="sim" type="sim">
    <param name="obstacles" value="circle 10,4 0.5"/>"#,
    );
    assert!(text.contains("circle 10,4"));
    std::fs::write(&system, text).unwrap();
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &file, 5.0);
    step_until(&mut harness, "a replan drawn", PATIENCE, |app| {
        app.run().followed().replans() >= 1
    });
    harness.run_ok();
    let followed = harness.state().run().followed().clone();
    assert_eq!(followed.max_replans, Some(3), "the follower's default");
    let (now, before) = followed.paths.split_last().unwrap();
    assert!(!now.replaced && now.replan.is_some(), "{followed:#?}");
    assert!(
        !before.is_empty() && before.iter().all(|path| path.replaced),
        "the path replaced stays drawn: {followed:#?}"
    );
    let clearance_m = now
        .points
        .windows(2)
        .map(|pair| distance_to_segment(crate_at, pair[0], pair[1]))
        .fold(f64::INFINITY, f64::min);
    assert!(
        clearance_m > 0.5 + 0.25,
        "the path followed goes round the crate, {clearance_m} m from its centre: {now:?}"
    );
    let goal = now.points.last().unwrap();
    assert!(
        (goal.x - 16.0).abs() < 0.1 && (goal.y - 4.0).abs() < 0.1,
        "{goal:?}"
    );
    // Said in words too: on the map and in the mission panel.
    harness.get_by_label_contains("Path: following replan");
    step_until(&mut harness, "the run to end", PATIENCE, |app| {
        app.run().ended().is_some()
    });
    let mission = status(harness.state()).mission.unwrap();
    assert_eq!(mission.outcome.as_deref(), Some("complete"));
}

/// How far `p` is from the segment `a`–`b`.
fn distance_to_segment(p: Point, a: Point, b: Point) -> f64 {
    let (dx, dy) = (b.x - a.x, b.y - a.y);
    let length_sq = dx * dx + dy * dy;
    let t = if length_sq > 0.0 {
        (((p.x - a.x) * dx + (p.y - a.y) * dy) / length_sq).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (p.x - a.x - t * dx).hypot(p.y - a.y - t * dy)
}

#[test]
fn a_system_with_access_lists_is_watched_all_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let system = robot_system(dir.path());
    // One list is enough for the agent to serve the system's modules only; the studio's node
    // is let in as an observer.
    let text = std::fs::read_to_string(&system).unwrap().replace(
        r#"<module name="sim" type="sim">"#,
        r#"<module name="sim" type="sim" may_publish="sim.*">"#,
    );
    assert!(text.contains("may_publish"));
    std::fs::write(&system, text).unwrap();
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &system, 1.0);
    step_until(
        &mut harness,
        "the scan and the pose on the live map",
        PATIENCE,
        |app| app.run().live().scan.is_some() && app.run().live().estimated.is_some(),
    );
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
}

/// Writes `text` to `file`, readable by its owner only (as secrets and keys must be).
fn private_file(file: &Path, text: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::write(file, text).unwrap();
    std::fs::set_permissions(file, std::fs::Permissions::from_mode(0o600)).unwrap();
    file.to_path_buf()
}

/// The control address of the run the studio started.
fn control_addr(app: &StudioApp) -> std::net::SocketAddr {
    let session = app.run().session.as_ref().unwrap();
    session.shared().control_addr.unwrap()
}

/// The robot system run from the studio with a shared secret in `dir`; the secret's file.
fn run_with_a_secret(dir: &Path) -> (Harness<'static, StudioApp>, PathBuf) {
    let system = robot_system(dir);
    let secret_file = private_file(&dir.join("secret"), "thirty-two bytes of shared secret");
    let mut harness = harness(dir);
    harness.state_mut().run_mut().secret_file = secret_file.display().to_string();
    open_and_run(&mut harness, &system, 1.0);
    (harness, secret_file)
}

#[test]
fn a_run_with_a_shared_secret_is_started_and_watched_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let (mut harness, secret_file) = run_with_a_secret(dir.path());
    // The module monitor and the live map both come through connections that prove it.
    step_until(
        &mut harness,
        "the modules running and the pose on the live map",
        PATIENCE,
        |app| {
            module_state(app, "sim") == Some(ModuleState::Running)
                && app.run().live().estimated.is_some()
        },
    );
    // The run requires it: its control interface refuses a client without it.
    let control = control_addr(harness.state());
    // It sends such a client not a byte: the client says what that means.
    let refused =
        armor_protocol::request(control, &Request::Status, None).map_err(|err| format!("{err:#}"));
    assert!(
        refused
            .as_ref()
            .is_err_and(|err| err.contains("requires the shared secret")),
        "{refused:?}"
    );
    let secret = armor_module_api::auth::Secret::load(&secret_file).unwrap();
    armor_protocol::request(control, &Request::Status, Some(&secret)).unwrap();
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
}

#[test]
fn the_robot_is_driven_by_its_camera_and_the_video_is_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let system = robot_system(dir.path());
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &system, 1.0);
    let sources = harness.state().run().sources().unwrap();
    assert_eq!(sources.images, ["camera.image"]);
    step_until(&mut harness, "a camera frame", PATIENCE, |app| {
        app.run().live().video.get("camera.image").is_some()
            && status(app)
                .modules
                .iter()
                .all(|module| module.state == ModuleState::Running)
    });
    harness.run_ok();
    harness.get_by_label_contains("320 × 240 jpeg · camera · age");
    stop_the_drivers(&mut harness);
    // The operator clicks the picture and drives by it: left turns the robot.
    harness.get_by_label("Camera view").click();
    harness.run_ok();
    assert!(armor_studio::run::video::has_focus(&harness.ctx));
    let start = harness.state().run().live().truth.unwrap();
    let first_frame = harness
        .state()
        .run()
        .live()
        .video
        .get("camera.image")
        .unwrap()
        .number;
    harness.key_down(Key::ArrowLeft);
    step_until(&mut harness, "the robot to turn left", PATIENCE, |app| {
        app.run()
            .live()
            .truth
            .is_some_and(|now| now.theta_rad - start.theta_rad > 0.3)
    });
    harness.key_up(Key::ArrowLeft);
    assert!(
        armor_studio::run::video::has_focus(&harness.ctx),
        "the arrows stayed the robot's"
    );
    let live = harness.state().run().live();
    assert!(
        live.video.get("camera.image").unwrap().number > first_frame,
        "new frames came while driving"
    );
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
    // The recording plays the video back in the same panel, aged against its play head.
    let recording = dir.path().join("truth.mcap");
    harness.state_mut().run_mut().open_recording(&recording);
    harness.run_ok();
    let recorded = harness.state().run().live();
    let frame = recorded.video.get("camera.image").expect("recorded frames");
    assert_eq!((frame.image.width, frame.image.height), (320, 240));
    harness.get_by_label_contains("320 × 240 jpeg · camera · age");
}

/// The bundled system of competing behaviours (`missions/robot/system-behaviours.xml`), its
/// world given by its full path since the run works in `dir`.
fn behaviours_system(dir: &Path) -> PathBuf {
    let world = workspace_root().join("assets/worlds/yard.world");
    let text =
        std::fs::read_to_string(workspace_root().join("missions/robot/system-behaviours.xml"))
            .unwrap()
            .replace(
                r#"value="yard.world""#,
                &format!(r#"value="{}""#, world.display()),
            );
    let file = dir.join("system.xml");
    std::fs::write(&file, text).unwrap();
    file
}

#[test]
fn behaviours_take_and_give_up_control_in_the_oscilloscope_and_markers_are_switched_per_module() {
    use armor_protocol::BehaviourState;
    let dir = tempfile::tempdir().unwrap();
    let system = behaviours_system(dir.path());
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &system, 2.0);

    // The crate makes vff win, and the follower wins again once past it: the time line says so.
    step_until(
        &mut harness,
        "vff to win and give control back to the follower",
        Duration::from_secs(90),
        |app| {
            let changes = status(app).behaviour_changes;
            changes
                .iter()
                .position(|c| c.module == "vff" && c.state == Some(BehaviourState::Winner))
                .is_some_and(|won| {
                    changes[won..]
                        .iter()
                        .any(|c| c.module == "follower" && c.state == Some(BehaviourState::Winner))
                })
        },
    );
    // The tree: the arbiter with who is in control, its behaviours coloured by state.
    harness.run_ok();
    harness.get_by_label_contains("⚖ arbiter — in control: ");
    // Under the subsystem the system file groups them in.
    harness.get_by_label_contains("▣ navigation — in control: ");
    assert!(
        harness.query_all_by_label_contains("★ ").count() <= 1,
        "one winner highlighted at most"
    );
    harness.get_by_label("State changes");
    for module in ["vff", "stop"] {
        assert!(
            harness
                .query_all_by_label_contains(&format!("{module}: "))
                .next()
                .is_some(),
            "{module}'s state shown"
        );
    }

    // Each module's markers in its layer; switching one off hides that module's only.
    step_until(
        &mut harness,
        "vff's and the follower's markers drawn",
        PATIENCE,
        |app| {
            let drawn = &app.run().markers_drawn;
            drawn.get("vff").is_some_and(|n| *n > 0)
                && drawn.get("follower").is_some_and(|n| *n > 0)
        },
    );
    harness.get_by_label_contains("vff (").click();
    harness.run_ok();
    step_until(&mut harness, "vff's markers hidden", PATIENCE, |app| {
        !app.run().markers_drawn.contains_key("vff")
            && app.run().markers_drawn.contains_key("follower")
    });
    assert!(harness.state().run().hidden_markers.contains("vff"));
    harness.get_by_label_contains("vff (").click();
    step_until(&mut harness, "vff's markers shown again", PATIENCE, |app| {
        app.run().markers_drawn.contains_key("vff")
    });

    // Any output inspected: the arbiter's command, picked in the list, plotted.
    harness.get_by_label("output").click();
    harness.run_ok();
    harness.get_by_label("arbiter.cmd_vel (Twist)").click();
    harness.run_ok();
    assert_eq!(
        harness.state().run().inspected.as_deref(),
        Some("arbiter.cmd_vel")
    );
    harness.get_by_label_contains("Twist: ");
    harness.get_by_label_contains("linear m/s ");

    // Sensors and motors: the laser, and every command — each candidate's, the one in control
    // starred, the robot's.
    harness.get_by_label("Sensors and motors").click();
    harness.run_ok();
    assert!(harness.query_all_by_label("sim.scan").next().is_some());
    for command in ["vff.cmd_vel", "stop.cmd_vel", "mux.cmd_vel"] {
        assert!(
            harness
                .query_all_by_label_contains(command)
                .next()
                .is_some(),
            "{command} listed"
        );
    }

    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
}

fn state(app: &StudioApp) -> Option<LocalisationState> {
    app.run().live().estimate.map(|estimate| estimate.state)
}

fn shown(harness: &Harness<'_, StudioApp>, text: &str) -> usize {
    harness.query_all_by_label_contains(text).count()
}

/// The number of tokens on `place` in the running mission's marking.
fn tokens(app: &StudioApp, place: &str) -> u32 {
    status(app)
        .mission
        .and_then(|mission| mission.marking.get(place).copied())
        .unwrap_or(0)
}

/// The greatest distance of the simulator's true position from `from`, updated each frame by
/// [`step_until_watching`].
fn moved_from(from: Pose2D, truth: Option<Pose2D>, moved: &mut f64) {
    if let Some(truth) = truth {
        *moved = moved.max((truth.x_m - from.x_m).hypot(truth.y_m - from.y_m));
    }
}

/// [`step_until`], keeping in `moved` how far the truth came from `from` at any frame.
fn step_until_watching(
    harness: &mut Harness<'_, StudioApp>,
    what: &str,
    from: Pose2D,
    moved: &mut f64,
    mut done: impl FnMut(&StudioApp) -> bool,
) {
    step_until(harness, what, PATIENCE, |app| {
        moved_from(from, app.run().live().truth, moved);
        done(app)
    });
}

#[test]
fn a_kidnapped_robot_is_shown_lost_holds_without_driving_and_completes_once_its_pose_is_set() {
    let dir = tempfile::tempdir().unwrap();
    // Carried 10 m north of the line it drives at 14 s of simulated time (some metres into the
    // leg, localised by then), where the laser sees another yard: its odometry does not see it.
    robot_system_with(dir.path(), r#"<param name="kidnap" value="14 8 14 0"/>"#);
    let file = dir.path().join("plan.xml");
    std::fs::write(
        &file,
        r#"<plan name="short" system="system.xml">
  <navigation module="follower" speed_mps="0.5"/>
  <contingency on="lost" do="hold"/>
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
  <leg name="advance" from="home" to="gate"/>
</plan>"#,
    )
    .unwrap();
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &file, 2.0);
    step_until(&mut harness, "the localiser localised", PATIENCE, |app| {
        state(app) == Some(LocalisationState::Localised)
    });
    harness.step();
    // In the panel and on the map's status line, with the estimate's spread; the estimate and
    // the truth both known, each drawn.
    assert!(shown(&harness, "localised") >= 2, "the state in words");
    assert!(shown(&harness, "scan fit") >= 1, "the estimate's details");
    let live = harness.state().run().live();
    assert!(live.estimated.is_some() && live.truth.is_some());
    step_until(&mut harness, "the localiser lost", PATIENCE, |app| {
        state(app) == Some(LocalisationState::Lost)
    });
    // From here the robot does not know where it is: judged by the simulator's truth, it does
    // not drive on (the follower never translates on an estimate that is not proven, and the
    // plan holds when lost).
    let lost_at = harness.state().run().live().truth.unwrap();
    let mut moved = 0.0;
    step_until_watching(&mut harness, "the leg held", lost_at, &mut moved, |app| {
        tokens(app, "advance_hold") > 0
    });
    harness.run_ok();
    assert!(shown(&harness, "lost") >= 2, "lost, in words");
    // What the mission waits for, and what the operator may do: retry the leg or skip it.
    assert!(
        shown(&harness, "advance_hold") >= 1,
        "the place it holds in"
    );
    harness.get_by_label("⏭ advance_retry");
    harness.get_by_label("⏭ advance_skip");
    // It stays held, and lost, while nobody answers (5 s of simulated time).
    let held_since = status(harness.state()).run_secs;
    step_until_watching(&mut harness, "5 s held", lost_at, &mut moved, |app| {
        status(app).run_secs >= held_since + 5.0
    });
    assert_eq!(tokens(harness.state(), "advance_hold"), 1, "still held");
    assert_eq!(state(harness.state()), Some(LocalisationState::Lost));
    assert!(harness.state().run().ended().is_none(), "the run goes on");
    assert!(
        moved < 0.1,
        "the robot moved {moved:.3} m by the truth while lost"
    );

    // The operator tells the localiser where the robot is (the truth, as someone who sees the
    // robot would), and retries the leg: it drives to the gate from where it was put.
    let truth = harness.state().run().live().truth.unwrap();
    harness.state_mut().run_mut().request(Request::SetPose {
        x_m: truth.x_m,
        y_m: truth.y_m,
        heading_deg: truth.theta_rad.to_degrees(),
        module: None,
    });
    step_until(&mut harness, "localised again", PATIENCE, |app| {
        state(app) == Some(LocalisationState::Localised)
    });
    harness.get_by_label("⏭ advance_retry").click();
    run_to_its_end(&mut harness, "passed");
    let verdict = harness.state().run().rehearsal().unwrap();
    assert!(verdict.passed, "{verdict:#?}");
    let error = verdict.arrivals[0].true_error_m.unwrap();
    eprintln!(
        "while lost the robot moved {moved:.3} m by the truth; after the retry the leg arrived \
         {error:.3} m from its waypoint by the truth"
    );
    assert!(error <= 0.4, "the leg truly ended {error} m off");
}

/// Steps until the plan's run ends, complete, and checks that the studio says so with the
/// rehearsal's `verdict` (`passed`, `FAILED`) by the simulator's truth, in the words shown.
fn run_to_its_end(harness: &mut Harness<'_, StudioApp>, verdict: &str) {
    step_until(harness, "the run to end", Duration::from_secs(90), |app| {
        app.run().ended().is_some()
    });
    harness.run_ok();
    let ended = harness.state().run().ended().unwrap();
    assert_eq!(
        ended,
        format!("ended: mission complete, rehearsal {verdict} by the simulator's truth")
    );
    let words = format!("the run {ended}");
    assert!(shown(harness, &words) >= 1, "{words}");
}

/// A press at `from`, a drag to `to` in small steps, a release there.
fn drag(harness: &mut Harness<'_, StudioApp>, from: Pos2, to: Pos2) {
    harness.hover_at(from);
    harness.step();
    harness.drag_at(from);
    harness.step();
    for i in 1..=12 {
        harness.hover_at(from + (to - from) * (i as f32 / 12.0));
        harness.step();
    }
    harness.event(egui::Event::PointerButton {
        pos: to,
        button: egui::PointerButton::Primary,
        pressed: false,
        modifiers: Modifiers::NONE,
    });
    harness.step();
}

#[test]
fn the_pose_is_set_by_a_drag_on_the_map_and_an_observer_sees_the_tool_greyed() {
    let dir = tempfile::tempdir().unwrap();
    let (mut harness, secret_file) = run_with_a_secret(dir.path());
    // The robot held still: only the operator moves it.
    for module in ["follower", "observer"] {
        harness.state_mut().run_mut().request(Request::StopModule {
            module: module.to_owned(),
        });
    }
    // Whatever the localiser says by then (a loaded machine can starve it into `lost` while the
    // follower still drove), the pose set by hand below is what it takes.
    step_until(
        &mut harness,
        "the drivers stopped and an estimate shown",
        PATIENCE,
        |app| {
            module_state(app, "follower") == Some(ModuleState::Stopped)
                && module_state(app, "observer") == Some(ModuleState::Stopped)
                && state(app).is_some()
        },
    );
    let truth = harness.state().run().live().truth.unwrap();

    // An observer's key: the same tool, greyed.
    let secret = armor_module_api::auth::Secret::load(&secret_file).unwrap();
    let key = RoleKey {
        role: Role::Observer,
        key: secret.role_key(Role::Observer),
    };
    let observer_key = private_file(&dir.path().join("observer.key"), &key.to_line());
    let control = control_addr(harness.state());
    let mut observer = self::harness(&dir.path().join("observer"));
    observer.state_mut().set_view(View::Run);
    observer.state_mut().run_mut().secret_file = observer_key.display().to_string();
    let ctx = observer.ctx.clone();
    observer.state_mut().run_mut().attach_bare(control, &ctx);
    // Attached again with the run's files (its sources known), the observer's role proven.
    step_until(&mut observer, "the observer attached", PATIENCE, |app| {
        app.run().has_localiser()
            && app.run().sources().is_some_and(|s| s.estimate.is_some())
            && !app.run().may_command()
    });
    // Clicked, it does nothing: no tool to press on the map with.
    let greyed = observer.get_by_label("📍 Set pose").rect().center();
    observer.hover_at(greyed);
    for pressed in [true, false] {
        observer.event(egui::Event::PointerButton {
            pos: greyed,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: Modifiers::NONE,
        });
    }
    observer.run_ok();
    assert!(
        !observer.state().run().set_pose_tool,
        "the tool is greyed for an observer"
    );
    drop(observer);

    // The operator: the tool, then a press 2 m east and 1.5 m north of the robot, dragged
    // north (up the screen) for a heading of 90°.
    harness.get_by_label("📍 Set pose").click();
    harness.run_ok();
    assert!(harness.state().run().set_pose_tool);
    let target = Point::new(truth.x_m + 2.0, truth.y_m + 1.5);
    let (from, map) = harness
        .state()
        .run()
        .own_map_view()
        .unwrap()
        .last_screen_of(target)
        .unwrap();
    assert!(map.contains(from), "{from:?} on the map {map:?}");
    drag(&mut harness, from, from - egui::vec2(0.0, 60.0));
    step_until(&mut harness, "the localiser's answer", PATIENCE, |app| {
        !app.status().is_error && app.status().text.starts_with("`localiser`: pose set to")
    });
    assert!(!harness.state().run().set_pose_tool, "one pose per use");
    step_until(
        &mut harness,
        "the estimate where it was set",
        PATIENCE,
        |app| {
            app.run().live().estimated.is_some_and(|pose| {
                (pose.x_m - target.x).hypot(pose.y_m - target.y) < 0.5
                    && (pose.theta_rad - std::f64::consts::FRAC_PI_2).abs() < 0.3
            })
        },
    );
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", PATIENCE, |app| {
        !app.run().is_running()
    });
}

/// A rehearsal the simulator's truth contradicts, as the operator reads it in the Run view: the
/// leg across the yard whose follower drives by odometry that lies by a metre
/// (`armor_tests::rehearsal::yard_leg`, the plan `tests/tests/rehearsal.rs` runs from the
/// command line). The mission completes as the robot believes, and the studio says the
/// rehearsal FAILED by the simulator's truth, with each reason: the arrival a metre off, the
/// footprint on the no-go area, and the leg's true error marked FAILED.
#[test]
fn a_rehearsal_the_truth_contradicts_reads_failed_in_the_run_view() {
    let dir = tempfile::tempdir().unwrap();
    let plan_file = armor_tests::rehearsal::yard_leg(dir.path(), true);
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &plan_file, 5.0);
    run_to_its_end(&mut harness, "FAILED");
    // The rehearsal's own panel: the verdict, then each reason in the judge's words.
    harness.get_by_label(" FAILED by the simulator's truth ");
    let verdict = harness.state().run().rehearsal().unwrap();
    assert!(!verdict.passed, "{verdict:#?}");
    let error = verdict.arrivals[0].true_error_m.unwrap();
    // About a metre (the lie), more when a loaded machine drives the two simulators apart:
    // beyond the 0.40 m allowed either way.
    assert!(error > 0.4, "{error}");
    let arrival = format!(
        "leg `advance` arrived {error:.2} m from its waypoint `gate` by the simulator's truth \
         (allowed 0.40 m)"
    );
    assert!(shown(&harness, &arrival) >= 1, "{arrival}");
    let footprint = "the robot's footprint met the no-go area `ditch` by the simulator's truth";
    assert!(shown(&harness, footprint) >= 1, "{footprint}");
    let cell = format!("{error:.2} m (simulator) FAILED");
    assert!(shown(&harness, &cell) >= 1, "{cell}");
    assert!(
        shown(&harness, "passed by the simulator's truth") == 0,
        "nothing says it passed"
    );
}
