//! `station_frame_ms_20_robots`: one frame of the operator station's view with 20 robots, each
//! with its status, pose, a five-point route and its link, as `armor-team station --json`
//! reports them. Every frame takes a fresh report of every robot first (the program sends one
//! each half second; a report a frame is the worst case), then lays the table and the map out
//! and tessellates them. The reference is the goal, a 30 Hz frame (issue 41: p99 ≤ 33 ms);
//! `rendered_ms` is the frame also rasterised, as the other lines have it.

use std::time::{Duration, Instant};

use armor_protocol::team::{LinkQuality, RobotReport, RobotStatus, RoutePoint, StationEvent};
use armor_studio::station::{FromStation, Link, StationView};

use super::{Renderer, line, median_ms, round};

pub const NAME: &str = "station_frame_ms_20_robots";
const ROBOTS: usize = 20;
const GOAL_MS: f64 = 33.0;

fn report(index: usize, frame: usize) -> RobotReport {
    let robot = format!("robot-{}", index + 1);
    let (x0, y0) = ((index % 5) as f64 * 12.0, (index / 5) as f64 * 12.0);
    let route = [(0.0, 0.0), (8.0, 0.0), (8.0, 8.0), (0.0, 8.0), (0.0, 0.0)]
        .iter()
        .enumerate()
        .map(|(i, (x, y))| RoutePoint {
            name: format!("wp{}", i % 4 + 1),
            x_m: x0 + x,
            y_m: y0 + y,
        })
        .collect();
    let along = (frame as f64 * 0.05 + index as f64) % 8.0;
    RobotReport {
        robot: robot.clone(),
        session: true,
        refusal: None,
        status: Some(RobotStatus {
            robot,
            run_secs: frame as f64 / 30.0,
            state: "running".into(),
            leg: Some("leg1".into()),
            places: vec!["leg1_drive".into()],
            localisation: Some("localised".into()),
            operator_heard_secs_ago: Some(0.2),
            firings_total: frame / 10,
            last_firing: Some("leg1_depart".into()),
            ..RobotStatus::default()
        }),
        pose: Some([x0 + along, y0, 0.0]),
        route,
        // A few are not heard from: drawn grey with their last known state.
        report_age_secs: Some(if index % 7 == 6 { 4.5 } else { 0.3 }),
        kbit_per_sec: 8.1,
        link: LinkQuality {
            received: 68,
            sent: 70,
        },
        camera: None,
    }
}

pub fn run(rounds: usize) -> anyhow::Result<String> {
    let (link, events, _commands) = Link::pair();
    let mut view = StationView::new(link);
    events.send(FromStation::Event(StationEvent::Station {
        role: "operator".into(),
        robots: (1..=ROBOTS).map(|i| format!("robot-{i}")).collect(),
    }))?;
    let ctx = egui::Context::default();
    let screen = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1280.0, 800.0));
    let mut frame =
        |number: usize, renderer: Option<&mut Renderer>| -> anyhow::Result<(Duration, Duration)> {
            for index in 0..ROBOTS {
                events.send(FromStation::Event(StationEvent::Robot(Box::new(report(
                    index, number,
                )))))?;
            }
            let input = egui::RawInput {
                screen_rect: Some(screen),
                ..Default::default()
            };
            let start = Instant::now();
            let mut output = ctx.run_ui(input, |ui| view.ui(ui));
            let shapes = std::mem::take(&mut output.shapes);
            let primitives = ctx.tessellate(shapes.clone(), output.pixels_per_point);
            let laid_out = start.elapsed();
            std::hint::black_box(primitives);
            let rendered = match renderer {
                Some(renderer) => {
                    use egui_kittest::TestRenderer as _;
                    output.shapes = shapes;
                    renderer.renderer.handle_delta(&mut output.textures_delta);
                    let image = renderer
                        .renderer
                        .render(&ctx, &output)
                        .map_err(|err| anyhow::anyhow!("rendering a frame: {err}"))?;
                    std::hint::black_box(image);
                    start.elapsed()
                }
                None => {
                    output.textures_delta.clear();
                    laid_out
                }
            };
            Ok((laid_out, rendered))
        };
    // The first frames lay the fonts out.
    for number in 0..10 {
        frame(number, None)?;
    }
    let mut laid_out = Vec::with_capacity(rounds);
    for number in 0..rounds {
        laid_out.push(frame(10 + number, None)?.0);
    }
    let mut renderer = Renderer::new()?;
    let adapter = renderer.adapter.clone();
    let mut rendered = Vec::new();
    for number in 0..rounds.min(30) {
        rendered.push(frame(10 + rounds + number, Some(&mut renderer))?.1);
    }
    let mut sorted: Vec<f64> = laid_out.iter().map(|d| d.as_secs_f64() * 1e3).collect();
    sorted.sort_by(f64::total_cmp);
    let p99 = sorted[((sorted.len() - 1) as f64 * 0.99).round() as usize];
    Ok(line(
        NAME,
        p99,
        GOAL_MS,
        serde_json::json!({
            "ours_is": "p99 of the station view's frame (laid out and tessellated) with 20 robots, a report of each taken first",
            "p50": round(median_ms(laid_out.clone())),
            "p99": round(p99),
            "frames": laid_out.len(),
            "rendered_ms": round(median_ms(rendered)),
            "adapter": adapter,
            "goal": "p99 <= 33",
            "reference_is": "the goal: a 30 Hz frame",
        }),
    ))
}
