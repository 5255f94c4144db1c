//! What the studio's UI tests share: a harness around the real [`StudioApp`], a palette of
//! module types like the bundled ones, and pointer gestures.
#![allow(dead_code, clippy::unwrap_used)]

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use armor_module_api::ModuleDescription;
use armor_module_api::describe::{ParamSpec, ParamType, PortSpec};
use armor_studio::common::palette::Palette;
use armor_studio::files::Home;
use armor_studio::{Options, StudioApp};
use egui::{Modifiers, Pos2};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

pub const SIZE: [f32; 2] = [1280.0, 800.0];

fn port(name: &str, data_type: &str) -> PortSpec {
    PortSpec {
        name: name.into(),
        data_type: data_type.into(),
        doc: format!("the {name}"),
    }
}

/// Module types shaped like the bundled `counter` (a sensor), `checker` (no category, as a
/// module written before categories) and `follower` (navigation).
pub fn descriptions() -> Vec<ModuleDescription> {
    let mut counter = ModuleDescription::new("counter", "Publishes 1, 2, 3, ... every period.");
    counter.category = armor_module_api::Category::Sensor;
    counter.outputs.push(port("count", "Counter"));
    counter.params.push(
        ParamSpec::new("period_secs", ParamType::Float, "time between two values")
            .unit("s")
            .default("0.1")
            .above(0.0),
    );
    let mut checker =
        ModuleDescription::new("checker", "Checks that counter values arrive in order.");
    checker.inputs.push(port("input", "Counter"));
    checker.outputs.push(port("received", "Counter"));
    checker.params.push(
        ParamSpec::new("report_every", ParamType::Int, "log every this many values").default("10"),
    );
    let mut follower = ModuleDescription::new("follower", "Drives towards a goal position.");
    follower.category = armor_module_api::Category::Navigation;
    follower.inputs.push(port("odometry", "Odometry"));
    follower.outputs.push(port("cmd_desired", "Twist"));
    follower
        .params
        .push(ParamSpec::new("goal_x_m", ParamType::Float, "goal x").unit("m"));
    follower
        .params
        .push(ParamSpec::new("goal_y_m", ParamType::Float, "goal y").unit("m"));
    vec![counter, checker, follower]
}

pub fn options(home: &Path, file: Option<PathBuf>) -> Options {
    let mut options = Options::new(Home::new(home));
    options.palette = Some(Palette::from_descriptions(descriptions()));
    options.file = file;
    options
}

pub fn harness(options: Options) -> Harness<'static, StudioApp> {
    let mut harness = Harness::builder()
        .with_size(SIZE)
        // Frames as a screen has them: a double click is two clicks within 0.3 s.
        .with_step_dt(1.0 / 60.0)
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options),
        );
    harness.run();
    harness
}

/// Presses at `from`, moves to `to` in small steps (one frame each, as a hand would), releases.
pub fn drag(harness: &mut Harness<'_, StudioApp>, from: Pos2, to: Pos2) {
    drag_holding(harness, from, to);
    harness.event(egui::Event::PointerButton {
        pos: to,
        button: egui::PointerButton::Primary,
        pressed: false,
        modifiers: Modifiers::NONE,
    });
    harness.run();
}

/// The first half of [`drag`]: the button stays down at `to`.
pub fn drag_holding(harness: &mut Harness<'_, StudioApp>, from: Pos2, to: Pos2) {
    harness.hover_at(from);
    harness.step();
    harness.drag_at(from);
    harness.step();
    for i in 1..=12 {
        harness.hover_at(from + (to - from) * (i as f32 / 12.0));
        harness.step();
    }
}

pub fn click(harness: &mut Harness<'_, StudioApp>, at: Pos2) {
    harness.hover_at(at);
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton {
            pos: at,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: Modifiers::NONE,
        });
    }
    harness.run();
}

pub fn double_click(harness: &mut Harness<'_, StudioApp>, at: Pos2) {
    // Let the last click age, so that these two are not taken for a triple click with it.
    harness.run_steps(60);
    harness.hover_at(at);
    for _ in 0..2 {
        for pressed in [true, false] {
            harness.event(egui::Event::PointerButton {
                pos: at,
                button: egui::PointerButton::Primary,
                pressed,
                modifiers: Modifiers::NONE,
            });
        }
    }
    harness.run();
}

/// Drags a module type from the palette to a point of the canvas.
pub fn drop_module(harness: &mut Harness<'_, StudioApp>, module_type: &str, at: Pos2) {
    let from = harness
        .get_all_by_label(module_type)
        .next()
        .expect("the palette lists the module type")
        .rect()
        .center();
    drag(harness, from, at);
}

pub fn pin(
    harness: &Harness<'_, StudioApp>,
    block: &str,
    port: &str,
    side: armor_studio::system::diagram::PinSide,
) -> Pos2 {
    harness
        .state()
        .pin_pos(block, port, side)
        .unwrap_or_else(|| panic!("pin {block}.{port} is drawn"))
}

/// Runs frames until `done` holds, for at most `deadline` (background work: probing).
pub fn run_until(
    harness: &mut Harness<'_, StudioApp>,
    deadline: Duration,
    done: impl Fn(&StudioApp) -> bool,
) {
    let start = std::time::Instant::now();
    while !done(harness.state()) {
        assert!(start.elapsed() < deadline, "timed out");
        harness.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    harness.run();
}

/// A bundled example of `missions/robot/` (a plan or a system).
pub fn robot_file(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../missions/robot")
        .join(name)
}

/// The studio on `file` (a plan opens in the Mission view), its first frames drawn.
pub fn studio_on(home: &Path, file: PathBuf) -> Harness<'static, StudioApp> {
    let mut harness = Harness::builder()
        .with_size(SIZE)
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(60)
        .build_ui_state(
            |ui, app: &mut StudioApp| app.ui(ui),
            StudioApp::new(options(home, Some(file))),
        );
    for _ in 0..3 {
        harness.run();
    }
    harness
}

/// The stand-in run on a real control interface: it answers every request with the status in
/// the mutex (and sends no files: the studio watches such a run without them).
pub fn stand_in_run(
    first: armor_protocol::Status,
) -> (SocketAddr, Arc<Mutex<armor_protocol::Status>>) {
    let shared = Arc::new(Mutex::new(first));
    let (incoming, requests) = mpsc::channel::<armor_runtime::control::Incoming>();
    let addr = armor_runtime::control::serve(SocketAddr::from(([127, 0, 0, 1], 0)), incoming, None)
        .unwrap();
    let status = Arc::clone(&shared);
    std::thread::spawn(move || {
        for (_, reply) in requests {
            let _ = reply.send(armor_protocol::Reply {
                ok: true,
                message: "ok".to_owned(),
                status: Some(status.lock().unwrap().clone()),
                files: None,
            });
        }
    });
    (addr, shared)
}
