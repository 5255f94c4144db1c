//! `markers_frame_ms`: one frame of the Run view with 20 modules publishing 500 markers each at
//! 10 Hz (a recording of them played: points, polylines, polygons, arrows and texts, in the
//! world's frame and the robot's), every layer shown. As in a run, the samples are decoded and
//! checked between frames (by the studio's node thread in a run; by the play head here), so a
//! frame is what the window pays: the layers' switches and the inspector's list, and painting
//! 10,000 markers on the map. The reference is the 60 Hz frame budget; `hidden_ms` is the same
//! frame with every layer switched off.

use std::path::Path;

use anyhow::Context as _;
use armor_module_api::Datum;
use armor_module_api::types::{Frame, Marker, Markers, Pose2D, Shape};
use armor_runtime::replay::Recorded;

use super::{FRAME_BUDGET_MS, frame_time, line, round};
use armor_studio::app::{Options, StudioApp, View};
use armor_studio::files::Home;
use armor_studio::run::live::Recording;

pub const NAME: &str = "markers_frame_ms";
const MODULES: usize = 20;
const MARKERS: usize = 500;
const RATE_HZ: f64 = 10.0;
const SECONDS: usize = 3;
const FRAME_SECS: f64 = 1.0 / 60.0;

/// A robot in a 50 m × 20 m world, which the Run view's map frames: every marker is in view.
const SYSTEM: &str = r#"<system name="bench-markers">
  <module name="sim" type="sim"><param name="world" value="bench-markers.world"/></module>
</system>
"#;
const WORLD: &str = "name Bench\norigin 43.5 1.4\nstart 10 5 0\nboundary 0,0 50,0 50,20 0,20 0,0\n";

/// One module's markers at step `step`: a mix of every shape, half in the robot's frame.
fn markers(module: usize, step: usize) -> Markers {
    let shapes = [
        Shape::Points,
        Shape::Polyline,
        Shape::Polygon,
        Shape::Arrows,
        Shape::Text,
    ];
    let markers = (0..MARKERS)
        .map(|i| {
            let shape = shapes[i % shapes.len()];
            let frame = if i % 2 == 0 {
                Frame::World
            } else {
                Frame::Robot
            };
            let (x, y) = (
                (module * 2) as f64 + (i % 25) as f64 * 0.1,
                (i / 25) as f64 * 0.5 + step as f64 * 0.01,
            );
            // Robot-frame markers stay within a few metres of the robot.
            let (x, y) = match frame {
                Frame::World => (x, y),
                Frame::Robot => (x * 0.1, y * 0.3),
            };
            let points = [(x, y), (x + 0.3, y), (x + 0.3, y + 0.2), (x, y + 0.2)];
            Marker::new(shape, frame, [200, 60, (module * 12) as u8, 200], points).with_text("m")
        })
        .collect();
    Markers { markers }
}

fn recording(file: &Path) -> anyhow::Result<Recording> {
    let mut messages = Vec::new();
    let steps = (SECONDS as f64 * RATE_HZ) as usize;
    for step in 0..steps {
        let at_ns = (step as f64 / RATE_HZ * 1e9) as u64;
        let mut pose = Vec::new();
        Pose2D {
            x_m: 10.0,
            y_m: 5.0,
            theta_rad: 0.3,
        }
        .encode(&mut pose)?;
        messages.push(Recorded {
            log_time_ns: at_ns,
            data_name: "sim.pose_truth".into(),
            data_type: "Pose2D".into(),
            payload: pose,
        });
        for module in 0..MODULES {
            let mut payload = Vec::new();
            markers(module, step).encode(&mut payload)?;
            messages.push(Recorded {
                log_time_ns: at_ns + module as u64,
                data_name: format!("m{module}.markers"),
                data_type: Markers::TYPE.into(),
                payload,
            });
        }
    }
    Recording::of(file, messages)
}

/// The median frame while the play head moves on by a 60 Hz frame between frames.
fn frames(ctx: &egui::Context, app: &mut StudioApp, count: usize) -> f64 {
    let mut samples = Vec::with_capacity(count);
    for _ in 0..count {
        if let Some(recording) = &mut app.run_mut().recording {
            let next = (recording.at_secs + FRAME_SECS) % recording.duration_secs;
            recording.seek(next);
        }
        samples.push(frame_time(ctx, app, 1));
    }
    samples.sort_by(f64::total_cmp);
    samples[samples.len() / 2]
}

pub fn run(dir: &Path, rounds: usize) -> anyhow::Result<String> {
    let system = dir.join("bench-markers.xml");
    std::fs::write(&system, SYSTEM)
        .with_context(|| format!("cannot write {}", system.display()))?;
    let world = dir.join("bench-markers.world");
    std::fs::write(&world, WORLD).with_context(|| format!("cannot write {}", world.display()))?;
    let mut options = Options::new(Home::new(dir.join("home")));
    options.file = Some(system.clone());
    let mut app = StudioApp::new(options);
    app.set_view(View::Run);
    let mut recording = recording(&dir.join("markers.mcap"))?;
    recording.seek(0.0);
    app.run_mut().recording = Some(recording);
    app.run_mut().request_fit();
    let ctx = egui::Context::default();
    frames(&ctx, &mut app, 5);
    let shown = frames(&ctx, &mut app, rounds);
    let drawn: usize = app.run().markers_drawn.values().sum();
    anyhow::ensure!(
        drawn == MODULES * MARKERS,
        "{drawn} markers drawn, not {}",
        MODULES * MARKERS
    );
    app.run_mut().hidden_markers = (0..MODULES).map(|m| format!("m{m}")).collect();
    frames(&ctx, &mut app, 3);
    let hidden = frames(&ctx, &mut app, rounds);
    Ok(line(
        NAME,
        shown,
        FRAME_BUDGET_MS,
        serde_json::json!({
            "goal": "< 16",
            "reference_is": "a 60 Hz frame budget",
            "hidden_ms": round(hidden),
            "modules": MODULES,
            "markers_each": MARKERS,
            "rate_hz": RATE_HZ,
        }),
    ))
}
