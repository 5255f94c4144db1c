//! `armor-studio-bench`: the studio's own timings, printed as JSON lines in `armor-bench`'s
//! format (`bench`, `ours`, `reference`, `unit`, `ratio`), which `armor-bench` runs and relays
//! (the runtime must not depend on egui, so the measuring happens here). A crate of its own, so
//! that the product, `armor-studio`, links neither its renderer (`egui_kittest`) nor its
//! fixtures.
//!
//! - `studio_frame_ms_1000_blocks`: time of one UI frame on one thread (layout, the canvas and
//!   its 1,500 wires, tessellation) in a headless egui context, on a 1,000-block diagram, at the
//!   view the studio opens it with (its fit), at 1:1 around the first blocks (`one_to_one_ms`),
//!   and at the least zoom a fit goes to (`half_scale_ms`, the most blocks drawn as widgets).
//!   Each also `*_rendered_ms`: the same frames laid out and rasterised by the kittest
//!   snapshots' renderer (egui_kittest's wgpu renderer; mesa's lavapipe here) and read back, what
//!   a user waits for. The reference is the goal: a 60 Hz frame budget.
//! - `markers_frame_ms` ([`markers`]): the Run view's frame with 20 modules' markers, 500 each.
//! - `station_frame_ms_20_robots` ([`station`]): the operator station's frame with 20 robots
//!   (issue 41: p99 ≤ 33 ms).
//! - `studio_load_ms_1000_blocks`: opening that file (read, parse into the diagram, check it as
//!   the validation panel does); the reference is the bare parse by `SystemConfig::parse`.
//! - `studio_vs_bare_snarl_1000`: our diagram's frame against a bare egui-snarl viewer on the
//!   same graph, with the same view and zoom (the studio's opening fit, where ours draws every
//!   block as a widget) and the same text (name, type, `pin: Type`), at 100, 500 and 1,000
//!   blocks (1.5 links a block), fitted, at 1:1 and in the overview; `ours` and `reference` are
//!   the fitted view at 1,000 blocks (issue 10: at most 0.5×).
//! - `studio_overview_vs_bare_snarl_1000`: the overview (every block in view, below the zoom
//!   where text reads: boxes, names where they fit) against the bare viewer at that zoom, which
//!   draws every node with its text: what the overview saves, a line of its own.
//! - `map_frame_ms_500_waypoints`: one frame of the Mission view (map tiles from the cache,
//!   500 waypoints and their legs with labels, 40 unit symbols, phase lines and areas, the
//!   inspector and the net beside the map) with the whole plan in view; the reference is the
//!   60 Hz frame budget; `rendered_ms` as above.

mod markers;
mod station;

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_module_api::ModuleDescription;
use armor_module_api::describe::{ParamSpec, ParamType, PortSpec};

use armor_studio::app::{Options, StudioApp};
use armor_studio::common::palette::Palette;
use armor_studio::files::Home;
use armor_studio::system::diagram::{Diagram, Pin, PinSide, PortRef};

pub const FRAME: &str = "studio_frame_ms_1000_blocks";
pub const LOAD: &str = "studio_load_ms_1000_blocks";
pub const MAP: &str = "map_frame_ms_500_waypoints";
pub const LABELS: &str = "label_place_ms_500_waypoints";
pub const VS_SNARL: &str = "studio_vs_bare_snarl_1000";
/// The overview (every block in view, boxes below the zoom where text reads) against the bare
/// viewer at that zoom: a line of its own, as the two do not draw the same text.
pub const VS_SNARL_OVERVIEW: &str = "studio_overview_vs_bare_snarl_1000";
pub const LAYOUT: &str = "layout_ms_200_blocks";
const LAYOUT_GOAL_MS: f64 = 100.0;
/// `armor-studio-bench monitor CONTROL SYSTEM SECS`: the Run view watching a run for
/// `armor-bench`'s `monitor_overhead` (no line printed).
pub const MONITOR: &str = "monitor";
/// The frame rate the monitor is drawn at, as a window would while the robot moves.
const MONITOR_FPS: f64 = 30.0;
const FRAME_BUDGET_MS: f64 = 16.0;
const LABEL_BUDGET_MS: f64 = 5.0;

/// The module type every block of the bench diagram has.
pub fn relay() -> ModuleDescription {
    let mut relay = ModuleDescription::new("relay", "passes values on");
    for (name, data_type) in [("a", "Counter"), ("b", "Twist")] {
        let port = PortSpec {
            name: name.into(),
            data_type: data_type.into(),
            doc: String::new(),
        };
        relay.inputs.push(PortSpec {
            name: format!("in_{name}"),
            ..port.clone()
        });
        relay.outputs.push(PortSpec {
            name: format!("out_{name}"),
            ..port
        });
    }
    relay
        .params
        .push(ParamSpec::new("gain", ParamType::Float, "gain").default("1"));
    relay
        .params
        .push(ParamSpec::new("rate_hz", ParamType::Float, "rate").unit("Hz"));
    relay
}

/// `blocks` relays in rows of 40; block i feeds i+1 on `a`, and i+2 on `b` until there are
/// `links` links.
pub fn diagram(blocks: usize, links: usize) -> Diagram {
    let relay = relay();
    let catalog = [(relay.module_type.clone(), relay)].into_iter().collect();
    let mut diagram = Diagram::new("bench");
    let ids: Vec<_> = (0..blocks)
        .map(|i| {
            let pos = [(i % 40) as f32 * 260.0, (i / 40) as f32 * 140.0];
            let id = diagram.add_block("relay", pos);
            diagram.set_param(id, "rate_hz", Some("10".into()));
            id
        })
        .collect();
    let pin = |side, block, port: &str| Pin {
        side,
        port: PortRef {
            block,
            port: port.into(),
        },
    };
    let mut count = 0;
    'outer: for (step, port) in [(1, "a"), (2, "b")] {
        for i in 0..blocks.saturating_sub(step) {
            if count >= links {
                break 'outer;
            }
            let from = pin(PinSide::Output, ids[i], &format!("out_{port}"));
            let to = pin(PinSide::Input, ids[i + step], &format!("in_{port}"));
            if diagram.connect(&catalog, &from, &to).is_ok() {
                count += 1;
            }
        }
    }
    diagram
}

/// `blocks` relays and `links` links between them at random (a fixed seed): nine in ten from a
/// block to one of the next twenty, one in ten backwards, each into a free input.
pub fn random_diagram(blocks: usize, links: usize) -> Diagram {
    let relay = relay();
    let catalog = [(relay.module_type.clone(), relay)].into_iter().collect();
    let mut diagram = Diagram::new("bench");
    let ids: Vec<_> = (0..blocks)
        .map(|_| diagram.add_block("relay", [0.0, 0.0]))
        .collect();
    let mut seed = 0x2545_f491_4f6c_dd1d_u64;
    let mut next = move |below: usize| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed % below.max(1) as u64) as usize
    };
    let pin = |side, block, port: String| Pin {
        side,
        port: PortRef { block, port },
    };
    let mut count = 0;
    // Enough tries to find free inputs; the bench checks the count it got.
    for _ in 0..links * 20 {
        if count >= links || blocks < 2 {
            break;
        }
        let from = next(blocks);
        let to = if next(10) == 0 {
            next(from.max(1))
        } else {
            (from + 1 + next(20)).min(blocks - 1)
        };
        let port = if next(2) == 0 { "a" } else { "b" };
        let input = PortRef {
            block: ids[to],
            port: format!("in_{port}"),
        };
        if from == to || diagram.source_of(&input).is_some() {
            continue;
        }
        let from_pin = pin(PinSide::Output, ids[from], format!("out_{port}"));
        let to_pin = pin(PinSide::Input, ids[to], input.port.clone());
        if diagram.connect(&catalog, &from_pin, &to_pin).is_ok() {
            count += 1;
        }
    }
    diagram
}

fn median_ms(mut samples: Vec<Duration>) -> f64 {
    samples.sort();
    samples
        .get(samples.len() / 2)
        .map_or(f64::NAN, |d| d.as_secs_f64() * 1e3)
}

fn round(value: f64) -> f64 {
    (value * 1000.0).round() / 1000.0
}

fn line(bench: &str, ours: f64, reference: f64, extra: serde_json::Value) -> String {
    let mut object = serde_json::json!({
        "bench": bench,
        "ours": round(ours),
        "reference": round(reference),
        "unit": "ms",
        "ratio": round(ours / reference),
    });
    if let (Some(object), serde_json::Value::Object(extra)) = (object.as_object_mut(), extra) {
        object.extend(extra);
    }
    object.to_string()
}

/// Runs `frames` frames and returns the median time of one.
fn frame_time(ctx: &egui::Context, app: &mut StudioApp, frames: usize) -> f64 {
    frame_times(ctx, app, frames, None).map_or(f64::NAN, |(layout, _)| layout)
}

/// The renderer of the kittest snapshots (`egui_kittest`'s wgpu renderer; on this machine
/// mesa's lavapipe, a software Vulkan), for the `*_rendered_ms` figures: what the user waits
/// for is the frame rasterised, not only laid out and tessellated.
pub struct Renderer {
    renderer: egui_kittest::wgpu::WgpuTestRenderer,
    /// The adapter wgpu chose, as it names it (`llvmpipe (LLVM …)` for lavapipe).
    pub adapter: String,
}

impl Renderer {
    /// The kittest snapshots' renderer, or why there is none (no Vulkan or GL driver).
    pub fn new() -> anyhow::Result<Renderer> {
        let state = std::panic::catch_unwind(|| {
            egui_kittest::wgpu::create_render_state(
                egui_kittest::wgpu::default_wgpu_setup(),
                eframe::egui_wgpu::RendererOptions::PREDICTABLE,
            )
        })
        .map_err(|_| {
            anyhow::anyhow!(
                "no wgpu adapter to render with (install mesa-vulkan-drivers for lavapipe)"
            )
        })?;
        let info = state.adapter.get_info();
        let adapter = format!("{} ({:?})", info.name, info.backend);
        Ok(Renderer {
            renderer: egui_kittest::wgpu::WgpuTestRenderer::from_render_state(state),
            adapter,
        })
    }
}

/// Runs `frames` frames on a 1600 × 1000 screen and returns the median time of one: laid out
/// and tessellated, and, with a renderer, laid out and rendered (the renderer's textures
/// updated, the frame tessellated, rasterised into an image and read back, as a snapshot is).
/// A renderer must see every frame of its context from the first (the font atlas).
fn frame_times(
    ctx: &egui::Context,
    app: &mut StudioApp,
    frames: usize,
    mut renderer: Option<&mut Renderer>,
) -> anyhow::Result<(f64, f64)> {
    use egui_kittest::TestRenderer as _;
    let screen = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1600.0, 1000.0));
    let mut layout = Vec::with_capacity(frames);
    let mut rendered = Vec::with_capacity(frames);
    for _ in 0..frames {
        let input = egui::RawInput {
            screen_rect: Some(screen),
            ..Default::default()
        };
        let start = Instant::now();
        let mut output = ctx.run_ui(input, |ui| app.ui(ui));
        let ui_time = start.elapsed();
        let shapes = match renderer {
            Some(_) => output.shapes.clone(),
            None => std::mem::take(&mut output.shapes),
        };
        let start = Instant::now();
        let primitives = ctx.tessellate(shapes, output.pixels_per_point);
        layout.push(ui_time + start.elapsed());
        std::hint::black_box(primitives);
        match renderer.as_deref_mut() {
            Some(renderer) => {
                let start = Instant::now();
                renderer.renderer.handle_delta(&mut output.textures_delta);
                let image = renderer
                    .renderer
                    .render(ctx, &output)
                    .map_err(|err| anyhow::anyhow!("rendering a frame: {err}"))?;
                rendered.push(ui_time + start.elapsed());
                std::hint::black_box(image);
            }
            // No renderer takes the font atlas's updates here.
            None => output.textures_delta.clear(),
        }
    }
    Ok((median_ms(layout), median_ms(rendered)))
}

pub fn run(args: &[String]) -> anyhow::Result<()> {
    if args.first().map(String::as_str) == Some(MONITOR) {
        return monitor(&args[1..]);
    }
    let quick = args.iter().any(|arg| arg == "--quick");
    let which: Vec<&str> = args
        .iter()
        .map(String::as_str)
        .filter(|arg| !arg.starts_with("--"))
        .collect();
    let wants = |name: &str| which.is_empty() || which.contains(&name);
    let dir = tempfile_dir()?;
    let file = dir.join("bench-1000.xml");
    let diagram = diagram(1000, 1500);
    std::fs::write(&file, diagram.to_xml())
        .with_context(|| format!("cannot write {}", file.display()))?;
    let rounds = if quick { 3 } else { 21 };

    if wants(LOAD) || wants("load") {
        let (ours, reference) = load_times(&file, rounds)?;
        println!(
            "{}",
            line(
                LOAD,
                ours,
                reference,
                serde_json::json!({"reference_is": "SystemConfig::parse of the same file"})
            )
        );
    }
    if wants(FRAME) || wants("frame") {
        let ctx = egui::Context::default();
        let mut renderer = Renderer::new()?;
        let mut options = Options::new(Home::new(dir.join("home")));
        options.palette = Some(Palette::from_descriptions([relay()]));
        options.file = Some(file.clone());
        let mut app = StudioApp::new(options);
        let mut measure = |app: &mut StudioApp, warm_up: usize| {
            frame_times(&ctx, app, warm_up, Some(&mut renderer))?;
            frame_times(&ctx, app, rounds, Some(&mut renderer))
        };
        // The first frames measure the blocks (egui-snarl sizes nodes from their content).
        let fitted = measure(&mut app, 5)?;
        let fitted_scale = app.canvas_transform().scaling;
        app.view_at_scale(1.0);
        let one_to_one = measure(&mut app, 3)?;
        // The most blocks drawn as widgets: the least zoom a fit goes to.
        app.view_at_scale(armor_studio::system::viewer::DETAIL_SCALE + 0.01);
        let most_detail = measure(&mut app, 3)?;
        let least_scale = app.canvas_transform().scaling;
        println!(
            "{}",
            line(
                FRAME,
                fitted.0,
                FRAME_BUDGET_MS,
                serde_json::json!({
                    "goal": "< 16",
                    "reference_is": "a 60 Hz frame budget",
                    "ours_is": "layout and tessellation of one frame (1600 × 1000), the view the studio opens",
                    "scale": round(f64::from(fitted_scale)),
                    "rendered_ms": round(fitted.1),
                    "rendered_ratio": round(fitted.1 / FRAME_BUDGET_MS),
                    "one_to_one_ms": round(one_to_one.0),
                    "one_to_one_rendered_ms": round(one_to_one.1),
                    "half_scale_ms": round(most_detail.0),
                    "half_scale_rendered_ms": round(most_detail.1),
                    "half_scale": round(f64::from(least_scale)),
                    "rendered_is": "the same frames also rasterised by the kittest snapshots' renderer (egui_kittest's wgpu renderer) and read back",
                    "renderer": renderer.adapter,
                    "blocks": app.editor().diagram.len(),
                    "links": app.editor().diagram.links().count(),
                })
            )
        );
    }
    if wants(VS_SNARL) || wants(VS_SNARL_OVERVIEW) || wants("snarl") {
        let mut sizes = serde_json::Map::new();
        let mut headline = (f64::NAN, f64::NAN, f32::NAN);
        let mut overview_line = (f64::NAN, f64::NAN, f32::NAN);
        for blocks in [100, 500, 1000] {
            let file = dir.join(format!("bench-{blocks}.xml"));
            std::fs::write(&file, self::diagram(blocks, blocks * 3 / 2).to_xml())
                .with_context(|| format!("cannot write {}", file.display()))?;
            let mut options = Options::new(Home::new(dir.join("home")));
            options.palette = Some(Palette::from_descriptions([relay()]));
            options.file = Some(file);
            let mut app = StudioApp::new(options);
            let ctx = egui::Context::default();
            let mut bare = Bare::of(&app.editor().diagram);
            let bare_ctx = egui::Context::default();
            let mut both = |app: &mut StudioApp, transform: Option<egui::emath::TSTransform>| {
                frame_time(&ctx, app, 5);
                if let Some(transform) = transform {
                    app.set_canvas_transform(transform);
                    frame_time(&ctx, app, 2);
                }
                let ours = frame_time(&ctx, app, rounds);
                bare.to_global = app.canvas_transform();
                bare_frame_time(&bare_ctx, &mut bare, 3);
                let reference = bare_frame_time(&bare_ctx, &mut bare, rounds);
                (ours, reference, app.canvas_transform().scaling)
            };
            let fitted = both(&mut app, None);
            app.view_at_scale(1.0);
            let one_to_one = both(&mut app, None);
            // Every block in view, below the zoom where ours draws widgets.
            let overview = overview_transform(&app);
            let all_in_view = both(&mut app, Some(overview));
            anyhow::ensure!(
                app.is_overview() && (all_in_view.2 - overview.scaling).abs() < 1e-3,
                "the overview line drew at zoom {} (asked {}): not the overview",
                all_in_view.2,
                overview.scaling
            );
            if blocks == 1000 {
                headline = fitted;
                overview_line = all_in_view;
            }
            sizes.insert(
                blocks.to_string(),
                serde_json::json!({
                    "fitted_scale": round(f64::from(fitted.2)),
                    "fitted_ours_ms": round(fitted.0),
                    "fitted_bare_ms": round(fitted.1),
                    "one_to_one_ours_ms": round(one_to_one.0),
                    "one_to_one_bare_ms": round(one_to_one.1),
                    "overview_scale": round(f64::from(all_in_view.2)),
                    "overview_ours_ms": round(all_in_view.0),
                    "overview_bare_ms": round(all_in_view.1),
                }),
            );
        }
        println!(
            "{}",
            line(
                VS_SNARL,
                headline.0,
                headline.1,
                serde_json::json!({
                    "goal": "<= 0.5 (and < 16 ms at 500 blocks)",
                    "scale": round(f64::from(headline.2)),
                    "reference_is": "a bare egui-snarl viewer on the same graph, the same view and zoom (the studio's opening fit, where ours draws every block as a widget) and the same text: each block's name and its type in the header, each pin's `name: Type`",
                    "sizes": sizes,
                })
            )
        );
        println!(
            "{}",
            line(
                VS_SNARL_OVERVIEW,
                overview_line.0,
                overview_line.1,
                serde_json::json!({
                    "scale": round(f64::from(overview_line.2)),
                    "ours_is": "the studio's overview: every block in view, below the zoom where text reads, painted as boxes with their names where they fit",
                    "reference_is": "the bare egui-snarl viewer at the same zoom, drawing every node as a widget with all its text (not the same text: what the overview saves)",
                })
            )
        );
    }
    if wants(markers::NAME) || wants("markers") {
        println!("{}", markers::run(&dir, rounds.max(15))?);
    }
    if wants(station::NAME) || wants("station") {
        println!("{}", station::run(if quick { 30 } else { 600 })?);
    }
    if wants(LAYOUT) || wants("layout") {
        let relay = relay();
        let catalog: armor_studio::common::palette::Catalog =
            [(relay.module_type.clone(), relay)].into_iter().collect();
        let diagram = random_diagram(200, 300);
        let mut samples = Vec::with_capacity(rounds);
        for _ in 0..rounds {
            let mut arranged = diagram.clone();
            let start = Instant::now();
            arranged.arrange(Some(&catalog));
            samples.push(start.elapsed());
            std::hint::black_box(arranged);
        }
        println!(
            "{}",
            line(
                LAYOUT,
                median_ms(samples),
                LAYOUT_GOAL_MS,
                serde_json::json!({
                    "goal": "< 100",
                    "reference_is": "the goal",
                    "blocks": diagram.len(),
                    "links": diagram.links().count(),
                })
            )
        );
    }
    if wants(MAP) || wants("map") || wants(LABELS) {
        let plan_file = dir.join("plan-500.xml");
        std::fs::write(dir.join("system.xml"), BENCH_SYSTEM)
            .with_context(|| format!("cannot write in {}", dir.display()))?;
        std::fs::write(&plan_file, plan(500, 40).to_xml())
            .with_context(|| format!("cannot write {}", plan_file.display()))?;
        let ctx = egui::Context::default();
        let mut renderer = Renderer::new()?;
        let mut options = Options::new(Home::new(dir.join("home")));
        options.palette = Some(Palette::from_descriptions([]));
        options.file = Some(plan_file);
        let mut app = StudioApp::new(options);
        // The first frames open the plan, fit it in view and render the map's tiles.
        frame_times(&ctx, &mut app, 40, Some(&mut renderer))?;
        let (frame, rendered) = frame_times(&ctx, &mut app, rounds, Some(&mut renderer))?;
        // What placing the labels took in each of those frames (the map fitted to the whole
        // plan, as a user opening it sees it).
        let mut placing = Vec::with_capacity(rounds);
        for _ in 0..rounds {
            frame_time(&ctx, &mut app, 1);
            if let Some(mission) = app.mission() {
                placing.push(mission.label_time());
            }
        }
        let placed = app
            .mission()
            .map_or(0, |mission| mission.label_boxes().len());
        let mission = app.mission().context("the mission view did not open")?;
        let plan = mission.plan();
        anyhow::ensure!(
            plan.waypoints.len() == 500 && mission.checked().net().is_some(),
            "the bench plan did not open and compile: {:?}",
            mission.checked().errors.first()
        );
        println!(
            "{}",
            line(
                MAP,
                frame,
                FRAME_BUDGET_MS,
                serde_json::json!({
                    "goal": "< 16",
                    "reference_is": "a 60 Hz frame budget",
                    "ours_is": "layout and tessellation of one frame (1600 × 1000)",
                    "rendered_ms": round(rendered),
                    "rendered_ratio": round(rendered / FRAME_BUDGET_MS),
                    "rendered_is": "the same frames also rasterised by the kittest snapshots' renderer (egui_kittest's wgpu renderer) and read back",
                    "renderer": renderer.adapter,
                    "waypoints": plan.waypoints.len(),
                    "units": plan.units.len(),
                    "graphics": plan.graphics.len(),
                })
            )
        );
        println!(
            "{}",
            line(
                LABELS,
                median_ms(placing),
                LABEL_BUDGET_MS,
                serde_json::json!({
                    "goal": "< 5",
                    "reference_is": "a budget of 5 ms",
                    "labels_placed": placed,
                    "waypoints": plan.waypoints.len(),
                })
            )
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}

/// A bare egui-snarl viewer: the same graph as a bench diagram, each node its title and its
/// pins' labels, nothing culled.
struct Bare {
    /// Each node's name and module type.
    snarl: egui_snarl::Snarl<(String, String)>,
    to_global: egui::emath::TSTransform,
}

impl Bare {
    fn of(diagram: &Diagram) -> Bare {
        let mut snarl = egui_snarl::Snarl::new();
        let nodes: std::collections::HashMap<_, _> = diagram
            .blocks()
            .map(|(id, block)| {
                let pos = egui::pos2(block.pos[0], block.pos[1]);
                let node = (block.name.clone(), block.module_type.clone());
                (id, snarl.insert_node(pos, node))
            })
            .collect();
        let index = |port: &str| usize::from(port.ends_with('b'));
        for link in diagram.links() {
            snarl.connect(
                egui_snarl::OutPinId {
                    node: nodes[&link.from.block],
                    output: index(&link.from.port),
                },
                egui_snarl::InPinId {
                    node: nodes[&link.to.block],
                    input: index(&link.to.port),
                },
            );
        }
        Bare {
            snarl,
            to_global: egui::emath::TSTransform::IDENTITY,
        }
    }
}

struct BareViewer(egui::emath::TSTransform);

impl egui_snarl::ui::SnarlViewer<(String, String)> for BareViewer {
    fn title(&mut self, node: &(String, String)) -> String {
        node.0.clone()
    }

    /// The same text as ours: the name, and the type small under it.
    fn show_header(
        &mut self,
        node: egui_snarl::NodeId,
        _: &[egui_snarl::InPin],
        _: &[egui_snarl::OutPin],
        ui: &mut egui::Ui,
        snarl: &mut egui_snarl::Snarl<(String, String)>,
    ) {
        let (name, module_type) = &snarl[node];
        ui.vertical(|ui| {
            ui.label(egui::RichText::new(name).strong());
            ui.label(egui::RichText::new(module_type).small());
        });
    }

    fn inputs(&mut self, _: &(String, String)) -> usize {
        2
    }

    fn outputs(&mut self, _: &(String, String)) -> usize {
        2
    }

    fn show_input(
        &mut self,
        pin: &egui_snarl::InPin,
        ui: &mut egui::Ui,
        _: &mut egui_snarl::Snarl<(String, String)>,
    ) -> impl egui_snarl::ui::SnarlPin + 'static {
        ui.label(["in_a: Counter", "in_b: Twist"][pin.id.input.min(1)]);
        egui_snarl::ui::PinInfo::circle()
    }

    fn show_output(
        &mut self,
        pin: &egui_snarl::OutPin,
        ui: &mut egui::Ui,
        _: &mut egui_snarl::Snarl<(String, String)>,
    ) -> impl egui_snarl::ui::SnarlPin + 'static {
        ui.label(["out_a: Counter", "out_b: Twist"][pin.id.output.min(1)]);
        egui_snarl::ui::PinInfo::circle()
    }

    fn current_transform(
        &mut self,
        to_global: &mut egui::emath::TSTransform,
        _: &mut egui_snarl::Snarl<(String, String)>,
    ) {
        *to_global = self.0;
    }
}

/// The transform that shows every block of the app's diagram in its canvas (below the zoom a
/// fit goes to, so the studio paints its overview).
fn overview_transform(app: &StudioApp) -> egui::emath::TSTransform {
    let mut bounds = egui::Rect::NOTHING;
    for (_, block) in app.editor().diagram.blocks() {
        let min = egui::pos2(block.pos[0], block.pos[1]);
        // A relay block is about 260 × 90 points.
        bounds = bounds.union(egui::Rect::from_min_size(min, egui::vec2(260.0, 90.0)));
    }
    let canvas = app.canvas_rect();
    let scaling = (canvas.width() / bounds.width())
        .min(canvas.height() / bounds.height())
        .min(armor_studio::system::viewer::DETAIL_SCALE * 0.9);
    let translation = canvas.center().to_vec2() - bounds.center().to_vec2() * scaling;
    egui::emath::TSTransform::new(translation, scaling)
}

/// Like [`frame_time`], for the bare viewer.
fn bare_frame_time(ctx: &egui::Context, bare: &mut Bare, frames: usize) -> f64 {
    let screen = egui::Rect::from_min_size(egui::Pos2::ZERO, egui::vec2(1600.0, 1000.0));
    let mut samples = Vec::with_capacity(frames);
    for _ in 0..frames {
        let input = egui::RawInput {
            screen_rect: Some(screen),
            ..Default::default()
        };
        let mut viewer = BareViewer(bare.to_global);
        let start = Instant::now();
        let mut output = ctx.run_ui(input, |ui| {
            egui_snarl::ui::SnarlWidget::new().id_salt("bare").show(
                &mut bare.snarl,
                &mut viewer,
                ui,
            );
        });
        let primitives = ctx.tessellate(output.shapes, output.pixels_per_point);
        samples.push(start.elapsed());
        output.textures_delta.clear();
        std::hint::black_box(primitives);
    }
    median_ms(samples)
}

/// Watches the run whose control interface is at `args[0]` (a run of the system file
/// `args[1]`) from the Run view for `args[2]` seconds: the status polled, the studio's node
/// subscribed to the robot's data, every frame drawn (headless, tessellated) at 30 Hz.
fn monitor(args: &[String]) -> anyhow::Result<()> {
    let [control, system, secs] = args else {
        anyhow::bail!("usage: armor-studio-bench monitor CONTROL_ADDR SYSTEM_FILE SECONDS");
    };
    let control: std::net::SocketAddr = control.parse().context("the control address")?;
    let secs: f64 = secs.parse().context("the seconds")?;
    let system = Path::new(system);
    let ctx = egui::Context::default();
    let mut options = Options::new(Home::new(tempfile_dir()?.join("home")));
    let binaries = armor_runtime::probe::list_modules(&options.module_path);
    let descriptions = armor_runtime::probe::probe_all(&binaries, Duration::from_secs(10))
        .into_iter()
        .filter_map(|(_, description)| description.ok());
    options.palette = Some(Palette::from_descriptions(descriptions));
    options.file = Some(system.to_path_buf());
    let mut app = StudioApp::new(options);
    app.set_view(armor_studio::app::View::Run);
    frame_time(&ctx, &mut app, 1);
    app.attach_run(control, &ctx);
    let end = Instant::now() + Duration::from_secs_f64(secs);
    let period = Duration::from_secs_f64(1.0 / MONITOR_FPS);
    let mut next = Instant::now();
    while Instant::now() < end {
        frame_time(&ctx, &mut app, 1);
        next += period;
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
    anyhow::ensure!(
        app.run().status().is_some(),
        "the run view never had the run's status"
    );
    Ok(())
}

/// The system the bench plan names: a robot without a simulated world (the map is the grid).
const BENCH_SYSTEM: &str = r#"<system name="bench">
  <module name="follower" type="follower"/>
</system>
"#;

/// A survey plan: `waypoints` in a lawnmower pattern 400 m × 300 m, a unit symbol every few
/// legs (`units` of them, of several affiliations and functions), two phase lines timed, a
/// no-go area and an objective.
pub fn plan(waypoints: usize, units: usize) -> armor_model::plan::Plan {
    use armor_model::plan::{AreaKind, Graphic, GraphicKind, LatLon, Leg, Plan, Unit, Waypoint};
    use armor_model::world::Point;
    let origin = LatLon::new(52.0, 4.37);
    let at = |x: f64, y: f64| LatLon::from_local(Point::new(x, y), origin);
    let columns = 25;
    let mut plan = Plan {
        name: "survey".into(),
        system: "system.xml".into(),
        origin: Some(origin),
        start_unix_secs: Some(1_795_428_000.0),
        ..Plan::default()
    };
    for i in 0..waypoints {
        let (row, column) = (i / columns, i % columns);
        let column = if row % 2 == 0 {
            column
        } else {
            columns - 1 - column
        };
        plan.waypoints.push(Waypoint {
            name: format!("w{i}"),
            position: at(column as f64 * 16.0, row as f64 * 15.0),
            ..Waypoint::default()
        });
        if i > 0 {
            plan.legs.push(Leg {
                name: format!("leg{i}"),
                from: format!("w{}", i - 1),
                to: format!("w{i}"),
                wait_secs: (i % 10 == 0).then_some(5.0),
                ..Leg::default()
            });
        }
    }
    let codes = [
        "SFGPUCR----D---",
        "SHGPUCI----E---",
        "SNGPUCA--------",
        "SUGPUCF----C---",
    ];
    for k in 0..units {
        plan.units.push(Unit {
            name: format!("u{k}"),
            sidc: codes[k % codes.len()].into(),
            position: at((k % 8) as f64 * 50.0 + 8.0, (k / 8) as f64 * 60.0 + 7.0),
            ..Unit::default()
        });
    }
    let line = |name: &str, y: f64, at_secs: f64| Graphic {
        kind: GraphicKind::PhaseLine,
        name: name.into(),
        points: vec![at(-20.0, y), at(420.0, y)],
        at_unix_secs: Some(1_795_428_000.0 + at_secs),
        ..Graphic::default()
    };
    plan.graphics.push(line("amber", 100.0, 600.0));
    plan.graphics.push(line("blue", 200.0, 1200.0));
    let area = |name: &str, kind, x: f64, y: f64| Graphic {
        kind: GraphicKind::Area(kind),
        name: name.into(),
        points: vec![
            at(x, y),
            at(x + 30.0, y),
            at(x + 30.0, y + 20.0),
            at(x, y + 20.0),
        ],
        ..Graphic::default()
    };
    plan.graphics
        .push(area("objective", AreaKind::Objective, 380.0, 310.0));
    plan.graphics
        .push(area("pond", AreaKind::NoGo, -80.0, 100.0));
    plan
}

fn load_times(file: &Path, rounds: usize) -> anyhow::Result<(f64, f64)> {
    let catalog = Palette::from_descriptions([relay()]).catalog;
    let mut ours = Vec::new();
    let mut reference = Vec::new();
    for _ in 0..rounds {
        let start = Instant::now();
        let diagram = armor_studio::system::file::open(file)?;
        let problems = armor_studio::system::validation::validate(&diagram, &catalog, &[]);
        ours.push(start.elapsed());
        anyhow::ensure!(
            problems.is_empty(),
            "the bench diagram has problems: {problems:?}"
        );
        let start = Instant::now();
        let text = std::fs::read_to_string(file)?;
        let parsed = armor_model::SystemConfig::parse(&text);
        reference.push(start.elapsed());
        anyhow::ensure!(parsed.is_ok(), "the bench file does not parse");
    }
    Ok((median_ms(ours), median_ms(reference)))
}

fn tempfile_dir() -> anyhow::Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("armor-studio-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(dir)
}
