//! Issue 39 in the studio, driven as an operator would: the yard plan a run plays, attached to
//! (Run → Attach…), is edited in the Mission view while the run goes on, then sent with "Send
//! to robot"; the run's answer (taken, refused) stays until dismissed, a refused update keeps
//! the edits, and the Run view draws only what the robot has taken. An update the run takes
//! from elsewhere (an area reported) is drawn in the Run view, and followed by the Mission view
//! unless the operator has edits of their own. An observer's key sees "Send to robot" greyed,
//! with the reason. A repair the mission proposes (a leg cut) is shown with each option's
//! costs; the operator applies one, and the Run view draws the plan the run made of it; an
//! observer sees the options' buttons greyed.
//!
//! The run is a stand-in on the real control interface (`armor_runtime::control::serve`, the
//! studio's real session and link): it answers as `armor run` does, taking an update unless it
//! removes the leg in force. The real run's own rules are `tests/tests/plan_updates.rs`'s, and
//! `tests/tests/studio_updates.rs` sends an update from the studio to a real `armor run`.
#![allow(clippy::unwrap_used)]

mod common;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant};

use armor_model::plan::{AreaKind, Graphic, GraphicKind, LatLon, Plan};
use armor_module_api::auth::{Role, RoleKey, Secret};
use armor_protocol::{
    FileText, MissionStatus, ParamFile, Repair, RepairKind, RepairOption, Reply, Request, RunFiles,
    Status, UpdateRecord,
};
use armor_studio::StudioApp;
use armor_studio::app::View;
use common::*;
use egui::{Key, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};

const PATIENCE: Duration = Duration::from_secs(30);
const SEND: &str = "⬆ Send to robot";

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// What the stand-in run plays and has been asked.
struct Run {
    plan: String,
    updates: Vec<UpdateRecord>,
    /// The repair proposed, if any.
    repair: Option<Repair>,
}

impl Run {
    /// Takes `text` as update of the plan unless it removes leg `advance`, which is in force
    /// (the words are `armor run`'s).
    fn update(&mut self, file: &str, text: &str) -> (bool, String) {
        self.repair = None;
        let number = self.updates.len() as u32 + 1;
        let keeps_the_leg =
            Plan::parse(text).is_ok_and(|plan| plan.legs.iter().any(|leg| leg.name == "advance"));
        let (taken, message) = if keeps_the_leg {
            self.plan = text.to_owned();
            (
                true,
                "leg `advance` in force goes on unchanged in `advance_drive`".to_owned(),
            )
        } else {
            (
                false,
                "the update removes leg `advance`, which is in force (in `advance_drive`): keep \
                 a leg of that name, or abort the mission"
                    .to_owned(),
            )
        };
        self.updates.push(UpdateRecord {
            number,
            run_secs: 10.0 + f64::from(number),
            file: file.to_owned(),
            taken,
            message: message.clone(),
        });
        let word = if taken { "taken" } else { "refused" };
        (taken, format!("update {number} {word}: {message}"))
    }

    fn status(&self) -> Status {
        Status {
            system: "/robot/missions/system.xml".to_owned(),
            run_secs: 12.0,
            time_scale: 1.0,
            mission: Some(MissionStatus {
                name: "yard-recon".to_owned(),
                marking: [("advance_drive".to_owned(), 1)].into(),
                updates: self.updates.clone(),
                repair: self.repair.clone(),
                ..MissionStatus::default()
            }),
            ..Status::default()
        }
    }

    fn files(&self) -> RunFiles {
        let read = |path: &str| std::fs::read_to_string(workspace().join(path)).unwrap();
        RunFiles {
            system: FileText {
                path: "/robot/missions/system.xml".to_owned(),
                text: read("missions/robot/system.xml"),
            },
            mission: Some(FileText {
                path: "/robot/missions/plan-yard.xml".to_owned(),
                text: self.plan.clone(),
            }),
            params: vec![ParamFile {
                module: "sim".to_owned(),
                param: "world".to_owned(),
                file: FileText {
                    path: "/robot/missions/yard.world".to_owned(),
                    text: read("assets/worlds/yard.world"),
                },
                beside: Vec::new(),
            }],
            descriptions: Vec::new(),
        }
    }
}

/// The stand-in run on a real control interface (with `secret`, roles proven); every update
/// asked of it is also sent on the receiver.
fn stand_in_run(secret: Option<Secret>) -> (SocketAddr, Arc<Mutex<Run>>, mpsc::Receiver<String>) {
    let run = Arc::new(Mutex::new(Run {
        plan: std::fs::read_to_string(workspace().join("missions/robot/plan-yard.xml")).unwrap(),
        updates: Vec::new(),
        repair: None,
    }));
    let (incoming, requests) = mpsc::channel::<armor_runtime::control::Incoming>();
    let addr =
        armor_runtime::control::serve(SocketAddr::from(([127, 0, 0, 1], 0)), incoming, secret)
            .unwrap();
    let (asked, updates) = mpsc::channel();
    let shared = Arc::clone(&run);
    std::thread::spawn(move || {
        for (request, reply) in requests {
            let mut run = shared.lock().unwrap();
            let answer = match request {
                Request::Files => Reply {
                    ok: true,
                    message: "the run's files".to_owned(),
                    status: None,
                    files: Some(run.files()),
                },
                Request::Update { file, text } => {
                    let _ = asked.send(text.clone());
                    let (ok, message) = run.update(&file, &text);
                    Reply {
                        ok,
                        message,
                        status: Some(run.status()),
                        files: None,
                    }
                }
                // Option 2 skips leg `climb`, as the repair below proposes it.
                Request::Repair { option } => {
                    let _ = asked.send(format!("repair {option}"));
                    let (ok, message) = match (&run.repair, option) {
                        (Some(_), 2) => {
                            let text = without_climb(&run.plan);
                            run.update("repair option 2", &text)
                        }
                        _ => (false, format!("no option {option}")),
                    };
                    Reply {
                        ok,
                        message,
                        status: Some(run.status()),
                        files: None,
                    }
                }
                _ => Reply {
                    ok: true,
                    message: "ok".to_owned(),
                    status: Some(run.status()),
                    files: None,
                },
            };
            let _ = reply.send(answer);
        }
    });
    (addr, run, updates)
}

/// A studio attached to the run at `control` (with the key in `key_file`), shown the run's
/// plan in the Mission view once the run has sent it.
fn attached(
    dir: &Path,
    control: SocketAddr,
    key_file: Option<&Path>,
) -> Harness<'static, StudioApp> {
    let mut harness = harness(options(&dir.join("home"), None));
    harness.state_mut().set_view(View::Run);
    if let Some(key) = key_file {
        harness.state_mut().run_mut().secret_file = key.display().to_string();
    }
    let ctx = harness.ctx.clone();
    harness.state_mut().run_mut().attach_bare(control, &ctx);
    shows_the_runs_plan(&mut harness);
    harness
}

/// Steps until the Mission view shows the plan the run plays (its copy, watched, compiled) and
/// the run's status came, then shows the Mission view.
fn shows_the_runs_plan(harness: &mut Harness<'_, StudioApp>) {
    step_until(harness, "the run's plan in the Mission view", |app| {
        app.mission()
            .is_some_and(|mission| app.run().watches(mission) && mission.checked().net().is_some())
            && app.run().status().is_some()
    });
    harness.state_mut().set_view(View::Mission);
    harness.run();
}

/// Steps frames until `done` holds, for at most [`PATIENCE`].
fn step_until(harness: &mut Harness<'_, StudioApp>, what: &str, done: impl Fn(&StudioApp) -> bool) {
    let deadline = Instant::now() + PATIENCE;
    while !done(harness.state()) {
        assert!(
            Instant::now() < deadline,
            "waited {PATIENCE:?} for {what}; status line: {:?}",
            harness.state().status().text
        );
        harness.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    harness.run();
}

fn waypoint(plan: &Plan, name: &str) -> LatLon {
    plan.waypoint(name).unwrap().position
}

/// Where waypoint `name` of the plan edited is on screen.
fn on_screen(harness: &Harness<'_, StudioApp>, name: &str) -> Pos2 {
    let mission = harness.state().mission().unwrap();
    mission.screen_pos(waypoint(mission.plan(), name)).unwrap()
}

fn send_is_greyed(harness: &Harness<'_, StudioApp>) -> bool {
    harness.get_by_label(SEND).accesskit_node().is_disabled()
}

#[test]
fn an_edit_sent_while_the_plan_runs_is_taken_or_refused_and_nothing_is_lost() {
    let dir = tempfile::tempdir().unwrap();
    let (control, _run, asked) = stand_in_run(None);
    let mut harness = attached(dir.path(), control, None);
    assert!(
        send_is_greyed(&harness),
        "nothing to send: the plan shown is the robot's"
    );
    harness.get_by_label("The plan shown is the one the robot runs.");
    let before = waypoint(harness.state().mission().unwrap().plan(), "north");

    // `north` dragged 40 points west on the map: an edit, not yet the robot's.
    let from = on_screen(&harness, "north");
    drag(&mut harness, from, from - egui::vec2(40.0, 0.0));
    let mission = harness.state().mission().unwrap();
    let moved = waypoint(mission.plan(), "north");
    assert!(moved.lon_deg < before.lon_deg, "{moved:?} from {before:?}");
    assert_eq!(
        waypoint(mission.watched_plan(), "north"),
        before,
        "the Run view draws the robot's plan, not an edit it has not taken"
    );
    assert!(!send_is_greyed(&harness));
    harness.get_by_label_contains("Edited: the robot runs the plan without these edits");

    // Sent: the run takes it, and says so until dismissed.
    harness.get_by_label(SEND).click();
    // The spinner repaints while the answer is awaited: frames, not `run`.
    harness.step();
    let sent = asked.recv_timeout(PATIENCE).unwrap();
    assert_eq!(waypoint(&Plan::parse(&sent).unwrap(), "north").lon_deg, {
        let text = harness.state().mission().unwrap().plan().to_xml();
        waypoint(&Plan::parse(&text).unwrap(), "north").lon_deg
    });
    step_until(&mut harness, "the run's answer", |app| {
        app.run().updates.answer.is_some()
    });
    harness.get_by_label("✔ Taken by the robot");
    // In the answer (and on the status line).
    assert!(
        harness
            .query_all_by_label_contains("update 1 taken: leg `advance` in force goes on unchanged")
            .count()
            >= 1
    );
    let mission = harness.state().mission().unwrap();
    assert!(
        (waypoint(mission.watched_plan(), "north").lon_deg - moved.lon_deg).abs() < 1e-7,
        "the Run view draws the plan taken"
    );
    assert!(send_is_greyed(&harness), "the robot runs the plan shown");
    // It stays, frames later, until dismissed.
    harness.run_steps(120);
    harness.get_by_label("✔ Taken by the robot");
    harness.get_by_label("Dismiss").click();
    harness.run();
    assert!(harness.query_by_label("✔ Taken by the robot").is_none());

    // The first waypoint deleted: leg `advance`, the one in force, goes. The run refuses.
    let home = on_screen(&harness, "home");
    harness.run_steps(30);
    click(&mut harness, home);
    harness.key_press(Key::Delete);
    harness.run();
    let edited = legs(harness.state().mission().unwrap().plan());
    assert!(!edited.contains(&"advance".to_owned()), "{edited:?}");
    harness.get_by_label(SEND).click();
    // The spinner repaints while the answer is awaited: frames, not `run`.
    harness.step();
    asked.recv_timeout(PATIENCE).unwrap();
    step_until(&mut harness, "the refusal", |app| {
        app.run()
            .updates
            .answer
            .as_ref()
            .is_some_and(|answer| !answer.taken)
    });
    harness.get_by_label("✖ Not taken");
    assert!(
        harness
            .query_all_by_label_contains("update 2 refused: the update removes leg `advance`")
            .count()
            >= 1
    );
    harness.get_by_label("Your edits are kept in the Mission view; the run goes on with its plan.");
    let mission = harness.state().mission().unwrap();
    assert_eq!(legs(mission.plan()), edited, "nothing of the edit is lost");
    assert!(
        legs(mission.watched_plan()).contains(&"advance".to_owned()),
        "the run goes on with the plan it had"
    );
    assert!(!send_is_greyed(&harness), "the edit can be sent again");

    // The Run view lists both, with the answer still shown there.
    harness.state_mut().set_view(View::Run);
    harness.run();
    harness.get_by_label("Plan updates (2)");
    harness.get_by_label("✖ Not taken");
    assert_eq!(harness.query_all_by_label("taken").count(), 1);
    assert_eq!(harness.query_all_by_label("refused").count(), 1);
}

/// The plan `text` with a no-go area `name` added, as a run adds an area reported.
fn with_area(text: &str, name: &str) -> String {
    let mut plan = Plan::parse(text).unwrap();
    let corner = |lat_deg: f64, lon_deg: f64| LatLon::new(lat_deg, lon_deg);
    plan.graphics.push(Graphic {
        kind: GraphicKind::Area(AreaKind::NoGo),
        name: name.to_owned(),
        points: vec![
            corner(43.56163, 1.46915),
            corner(43.56163, 1.46917),
            corner(43.56165, 1.46917),
            corner(43.56165, 1.46915),
        ],
        ..Default::default()
    });
    plan.to_xml()
}

fn area_names(plan: &Plan) -> Vec<String> {
    plan.graphics
        .iter()
        .filter(|graphic| matches!(graphic.kind, GraphicKind::Area(AreaKind::NoGo)))
        .map(|graphic| graphic.name.clone())
        .collect()
}

#[test]
fn an_update_taken_from_elsewhere_is_drawn_and_followed_unless_the_operator_has_edits() {
    let dir = tempfile::tempdir().unwrap();
    let (control, run, _asked) = stand_in_run(None);
    let mut harness = attached(dir.path(), control, None);

    // Another unit reports a minefield: the run takes it (`armor ctl area`).
    {
        let mut run = run.lock().unwrap();
        let text = with_area(&run.plan, "reported");
        run.update("area `reported` reported by the operator", &text);
    }
    step_until(&mut harness, "the run's new plan drawn", |app| {
        app.mission()
            .is_some_and(|mission| area_names(mission.watched_plan()).contains(&"reported".into()))
    });
    let mission = harness.state().mission().unwrap();
    assert!(
        mission.watched_checked().compiled.is_some(),
        "{:?}",
        mission.watched_checked().errors
    );
    // No edits of the operator's: the Mission view follows, and nothing is left to send.
    assert!(area_names(mission.plan()).contains(&"reported".into()));
    assert!(send_is_greyed(&harness));

    // With an edit of the operator's, a second report is drawn in the Run view but the edit
    // stays, and the Mission view says that sending it replaces the robot's plan.
    let from = on_screen(&harness, "rally");
    drag(&mut harness, from, from + egui::vec2(30.0, 0.0));
    {
        let mut run = run.lock().unwrap();
        let text = with_area(&run.plan, "second");
        run.update("area `second` reported by module `observer`", &text);
    }
    step_until(&mut harness, "the second report drawn", |app| {
        app.mission()
            .is_some_and(|mission| area_names(mission.watched_plan()).contains(&"second".into()))
    });
    let mission = harness.state().mission().unwrap();
    assert!(!area_names(mission.plan()).contains(&"second".into()));
    harness.get_by_label_contains("The robot's plan changed while you edited (update 2");
    // Taking the robot's plan back drops the edit (and Undo would bring it back).
    harness.get_by_label("↺ Take the robot's plan").click();
    harness.run();
    let mission = harness.state().mission().unwrap();
    assert!(area_names(mission.plan()).contains(&"second".into()));
    assert!(send_is_greyed(&harness));

    // The Run view lists both, by whom they were reported.
    harness.state_mut().set_view(View::Run);
    harness.run();
    harness.get_by_label("Plan updates (2)");
    harness.get_by_label("area `second` reported by module `observer`");
}

#[test]
fn an_observer_sees_send_greyed_with_the_reason_and_sends_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let secret_file = dir.path().join("secret");
    {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::write(&secret_file, "a secret of thirty-two bytes, ok").unwrap();
        std::fs::set_permissions(&secret_file, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    let secret = Secret::load(&secret_file).unwrap();
    let key = RoleKey {
        role: Role::Observer,
        key: secret.role_key(Role::Observer),
    };
    let key_file = dir.path().join("observer.key");
    {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::write(&key_file, key.to_line()).unwrap();
        std::fs::set_permissions(&key_file, std::fs::Permissions::from_mode(0o600)).unwrap();
    }
    let (control, run, asked) = stand_in_run(Some(secret));
    run.lock().unwrap().repair = Some(climb_cut());
    let mut harness = attached(dir.path(), control, Some(&key_file));
    let from = on_screen(&harness, "north");
    drag(&mut harness, from, from - egui::vec2(40.0, 0.0));
    assert!(send_is_greyed(&harness), "an observer may not send");
    // The reason, on hover.
    let button = harness.get_by_label(SEND).rect().center();
    harness.hover_at(button);
    harness.run_steps(90);
    harness.get_by_label_contains("attached with an observer's key");
    // Clicked all the same, it sends nothing.
    click(&mut harness, button);
    harness.run_steps(30);
    assert!(asked.recv_timeout(Duration::from_millis(500)).is_err());
    assert!(harness.state().run().updates.answer.is_none());

    // The repair's options, shown, their buttons greyed.
    harness.state_mut().set_view(View::Run);
    harness.run();
    harness.get_by_label("Leg `climb` cannot be completed");
    for apply in ["Apply 1", "Apply 2"] {
        assert!(
            harness.get_by_label(apply).accesskit_node().is_disabled(),
            "{apply} for an observer"
        );
    }
    let apply = harness.get_by_label("Apply 2").rect().center();
    click(&mut harness, apply);
    harness.run_steps(30);
    assert!(asked.recv_timeout(Duration::from_millis(500)).is_err());
}

fn legs(plan: &Plan) -> Vec<String> {
    plan.legs.iter().map(|leg| leg.name.clone()).collect()
}

/// The plan `text` without leg `climb`: `regroup` leaves from `east` (the repair's skip).
fn without_climb(text: &str) -> String {
    let mut plan = Plan::parse(text).unwrap();
    plan.legs.retain(|leg| leg.name != "climb");
    for leg in &mut plan.legs {
        if leg.name == "regroup" {
            leg.from = "east".to_owned();
        }
    }
    plan.to_xml()
}

/// What `armor run` proposes when a no-go area reported cuts leg `climb`.
fn climb_cut() -> Repair {
    Repair {
        run_secs: 11.0,
        leg: "climb".to_owned(),
        why: "no-go area `cut` cuts leg `climb`".to_owned(),
        options: vec![
            RepairOption {
                number: 1,
                kind: RepairKind::WayRound,
                summary: "round through `rally`, then `north`".to_owned(),
                via: vec!["rally".to_owned()],
                distance_m: 61.0,
                duration_secs: Some(150.0),
                deadlines_missed: vec![
                    "leg `regroup` due by 08:06:00, arrives 08:06:40".to_owned(),
                ],
                ..RepairOption::default()
            },
            RepairOption {
                number: 2,
                kind: RepairKind::Skip,
                summary: "skip `north`: from `east` on to `rally`".to_owned(),
                legs_dropped: vec!["climb".to_owned()],
                distance_m: 34.0,
                duration_secs: Some(75.0),
                ..RepairOption::default()
            },
        ],
        default_option: None,
        default_at_run_secs: None,
    }
}

#[test]
fn a_repair_proposed_is_shown_with_its_costs_and_the_option_applied_is_drawn() {
    let dir = tempfile::tempdir().unwrap();
    let (control, run, asked) = stand_in_run(None);
    run.lock().unwrap().repair = Some(climb_cut());
    let mut harness = attached(dir.path(), control, None);
    // The Mission view's bar points to the Run view.
    harness
        .get_by_label_contains("Leg `climb` cannot be completed: the Run view lists the repairs");
    harness.state_mut().set_view(View::Run);
    harness.run();
    harness.get_by_label("Leg `climb` cannot be completed");
    harness.get_by_label("no-go area `cut` cuts leg `climb`");
    harness.get_by_label("The mission holds until you choose an option (or send a plan).");
    harness.get_by_label("way round: round through `rally`, then `north`");
    harness.get_by_label(
        "61 m left to drive · 2 min 30 s · misses: leg `regroup` due by 08:06:00, arrives 08:06:40",
    );
    harness
        .get_by_label("34 m left to drive · 1 min 15 s · gives up `climb` · meets every deadline");

    harness.get_by_label("Apply 2").click();
    // The spinner repaints while the answer is awaited: frames, not `run`.
    harness.step();
    assert_eq!(asked.recv_timeout(PATIENCE).unwrap(), "repair 2");
    step_until(&mut harness, "the repaired plan drawn", |app| {
        app.mission()
            .is_some_and(|mission| !legs(mission.watched_plan()).contains(&"climb".to_owned()))
    });
    harness.get_by_label("✔ Taken by the robot");
    assert!(
        harness
            .query_by_label("Leg `climb` cannot be completed")
            .is_none(),
        "the repair is no longer proposed"
    );
    // The Mission view had no edits: it follows the plan the run made.
    let mission = harness.state().mission().unwrap();
    assert_eq!(legs(mission.plan()), ["advance", "cross", "regroup"]);
    harness.get_by_label("Plan updates (1)");
}

/// Issue 39's Send bar when the operator attaches with the robot's system file already open
/// (Run → Attach… from the System view): the run is asked for its files all the same, the plan
/// it plays is opened in the Mission view, and an edit of it is sent and taken. Before, the
/// studio watched the system alone and never showed the bar.
#[test]
fn attached_with_the_system_open_the_plan_the_run_plays_is_edited_and_sent() {
    let dir = tempfile::tempdir().unwrap();
    let (control, _run, asked) = stand_in_run(None);
    let system = workspace().join("missions/robot/system.xml");
    let mut harness = harness(options(&dir.path().join("home"), Some(system.clone())));
    assert_eq!(
        harness.state().path(),
        Some(system.as_path()),
        "the system is open"
    );
    let ctx = harness.ctx.clone();
    harness.state_mut().attach_run(control, &ctx);
    shows_the_runs_plan(&mut harness);
    harness.get_by_label("The plan shown is the one the robot runs.");
    assert!(send_is_greyed(&harness), "nothing edited yet");

    let from = on_screen(&harness, "north");
    drag(&mut harness, from, from - egui::vec2(40.0, 0.0));
    assert!(!send_is_greyed(&harness), "an edit to send");
    harness.get_by_label(SEND).click();
    harness.step();
    let sent = asked.recv_timeout(PATIENCE).unwrap();
    let edited = harness.state().mission().unwrap().plan().clone();
    assert_eq!(
        waypoint(&Plan::parse(&sent).unwrap(), "north"),
        waypoint(&Plan::parse(&edited.to_xml()).unwrap(), "north")
    );
    step_until(&mut harness, "the run's answer", |app| {
        app.run().updates.answer.is_some()
    });
    harness.get_by_label("✔ Taken by the robot");
}
