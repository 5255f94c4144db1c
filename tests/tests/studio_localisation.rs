//! The Run view shows where the robot believes it is and where it truly is (issue 33, item 6),
//! driven as an operator would through egui_kittest, on the bundled yard robot (sim, localiser,
//! follower):
//!
//! * A robot carried away mid-leg (the sim's `kidnap`): the panel says `localised`, then `lost`;
//!   the follower still "arrives", and the run ends with the rehearsal's verdict in words, the
//!   leg's true error in the legs table, never a bare "complete".
//! * The set-pose tool (rviz's "2D Pose Estimate"): a press on the map, a drag for the heading,
//!   a release; the localiser's estimate is then there. A studio attached with an observer's
//!   key shows the tool greyed.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use armor_model::world::Point;
use armor_module_api::types::LocalisationState;
use armor_runtime::control::{ModuleState, Request, Role, RoleKey};
use armor_studio::app::View;
use armor_studio::files::Home;
use armor_studio::palette::Palette;
use armor_studio::{Options, StudioApp};
use armor_tests::{bin_dir, workspace_root};
use egui::{Modifiers, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

const PATIENCE: Duration = Duration::from_secs(60);

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

/// Steps frames until `done` holds, at most [`PATIENCE`].
fn step_until(
    harness: &mut Harness<'_, StudioApp>,
    what: &str,
    mut done: impl FnMut(&StudioApp) -> bool,
) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        harness.step();
        if done(harness.state()) {
            // One more frame, drawn with what the condition saw.
            harness.step();
            return;
        }
        assert!(
            Instant::now() < deadline,
            "waited {PATIENCE:?} for {what}; run ended: {:?}; status line: {:?}",
            harness.state().run().ended(),
            harness.state().status().text
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn state(app: &StudioApp) -> Option<LocalisationState> {
    app.run().live().estimate.map(|estimate| estimate.state)
}

fn module_state(app: &StudioApp, name: &str) -> Option<ModuleState> {
    app.run()
        .status()?
        .modules
        .iter()
        .find(|module| module.name == name)
        .map(|module| module.state)
}

/// The bundled yard robot (`missions/robot/system.xml`), its world and recording given as
/// absolute paths so that the run works from `dir`, with `sim_params` added to the sim.
fn robot_system(dir: &Path, sim_params: &str) -> PathBuf {
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

/// Opens `file` (a plan when it is `plan.xml`) and runs it from the Run view.
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
    harness.get_by_label("▶ Run").click();
    harness.run_ok();
    assert!(harness.state().run().is_running());
}

fn shown(harness: &Harness<'_, StudioApp>, text: &str) -> usize {
    harness.query_all_by_label_contains(text).count()
}

#[test]
fn a_kidnapped_robot_is_shown_lost_and_its_rehearsal_fails_in_words() {
    let dir = tempfile::tempdir().unwrap();
    // Carried 10 m north of the line it drives at 14 s of simulated time (some metres into the
    // leg, localised by then), where the laser sees another yard: its odometry does not see it,
    // so the follower "arrives" 10 m or so from the gate by the truth.
    robot_system(dir.path(), r#"<param name="kidnap" value="14 8 14 0"/>"#);
    let file = dir.path().join("plan.xml");
    std::fs::write(
        &file,
        r#"<plan name="short" system="system.xml">
  <navigation module="follower" speed_mps="0.5"/>
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
  <leg name="advance" from="home" to="gate"/>
</plan>"#,
    )
    .unwrap();
    let mut harness = harness(dir.path());
    open_and_run(&mut harness, &file, 2.0);
    step_until(&mut harness, "the localiser localised", |app| {
        state(app) == Some(LocalisationState::Localised)
    });
    // In the panel and on the map's status line, with the estimate's spread; the estimate and
    // the truth both known, each drawn.
    assert!(shown(&harness, "localised") >= 2, "the state in words");
    assert!(shown(&harness, "scan fit") >= 1, "the estimate's details");
    let live = harness.state().run().live();
    assert!(live.estimated.is_some() && live.truth.is_some());
    step_until(&mut harness, "the localiser lost", |app| {
        state(app) == Some(LocalisationState::Lost)
    });
    assert!(shown(&harness, "lost") >= 2, "lost, in words");
    step_until(&mut harness, "the run to end", |app| {
        app.run().ended().is_some()
    });
    harness.run_ok();
    let ended = harness.state().run().ended().unwrap();
    assert_eq!(
        ended,
        "ended: mission complete, rehearsal FAILED by the simulator's truth"
    );
    // The toolbar says so, never a bare "complete".
    let words = format!("the run {ended}");
    assert!(shown(&harness, &words) >= 1, "{words}");
    assert_eq!(
        shown(&harness, "the run ended: mission complete"),
        shown(&harness, &words),
        "never a bare `complete`"
    );
    let verdict = harness.state().run().rehearsal().unwrap();
    assert!(!verdict.passed);
    let error = verdict.arrivals[0].true_error_m.unwrap();
    assert!(error > 9.0, "the leg truly ended {error} m off");
    // Above the map and in the panel, the reason in words.
    let reason = format!(
        "leg `advance` arrived {error:.2} m from its waypoint `gate` by the simulator's truth"
    );
    assert!(shown(&harness, &reason) >= 2, "{reason}: {verdict:#?}");
    harness.get_by_label(" FAILED by the simulator's truth ");
    // The legs table: the leg, its way, and its true error marked as the simulator's.
    harness.get_by_label("home to gate");
    harness.get_by_label(&format!("{error:.2} m (simulator) FAILED"));
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
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let system = robot_system(dir.path(), "");
    let secret_file = dir.path().join("secret");
    std::fs::write(&secret_file, "thirty-two bytes of shared secret").unwrap();
    std::fs::set_permissions(&secret_file, std::fs::Permissions::from_mode(0o600)).unwrap();
    let mut harness = harness(dir.path());
    harness.state_mut().run_mut().secret_file = secret_file.display().to_string();
    open_and_run(&mut harness, &system, 1.0);
    // The robot held still: only the operator moves it.
    for module in ["follower", "observer"] {
        harness.state_mut().run_mut().request(Request::StopModule {
            module: module.to_owned(),
        });
    }
    step_until(&mut harness, "the drivers stopped and localised", |app| {
        module_state(app, "follower") == Some(ModuleState::Stopped)
            && module_state(app, "observer") == Some(ModuleState::Stopped)
            && state(app) == Some(LocalisationState::Localised)
    });
    let truth = harness.state().run().live().truth.unwrap();

    // An observer's key: the same tool, greyed.
    let observer_key = dir.path().join("observer.key");
    let secret = armor_module_api::auth::Secret::load(&secret_file).unwrap();
    let key = RoleKey {
        role: Role::Observer,
        key: secret.role_key(Role::Observer),
    };
    std::fs::write(&observer_key, key.to_line()).unwrap();
    std::fs::set_permissions(&observer_key, std::fs::Permissions::from_mode(0o600)).unwrap();
    let control = harness
        .state()
        .run()
        .session
        .as_ref()
        .unwrap()
        .shared()
        .control_addr
        .unwrap();
    let mut observer = self::harness(&dir.path().join("observer"));
    observer.state_mut().set_view(View::Run);
    observer.state_mut().run_mut().secret_file = observer_key.display().to_string();
    let ctx = observer.ctx.clone();
    observer.state_mut().run_mut().attach_bare(control, &ctx);
    step_until(&mut observer, "the observer attached", |app| {
        app.run().has_localiser() && !app.run().may_command()
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
    step_until(&mut harness, "the localiser's answer", |app| {
        !app.status().is_error && app.status().text.starts_with("`localiser`: pose set to")
    });
    assert!(!harness.state().run().set_pose_tool, "one pose per use");
    step_until(&mut harness, "the estimate where it was set", |app| {
        app.run().live().estimated.is_some_and(|pose| {
            (pose.x_m - target.x).hypot(pose.y_m - target.y) < 0.5
                && (pose.theta_rad - std::f64::consts::FRAC_PI_2).abs() < 0.3
        })
    });
    harness.get_by_label("■ Stop").click();
    step_until(&mut harness, "the run to stop", |app| {
        !app.run().is_running()
    });
}
