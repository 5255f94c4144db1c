//! The plan on the map: the walkers widget over the world's tiles, with the tactical graphics,
//! the legs (as the compiled routes go, round no-go areas), the appointment and deadline lines,
//! the waypoints and the unit symbols drawn over it; and the clicks and drags that edit the
//! plan, queued as [`PlanCommand`]s.

use std::collections::HashMap;

use crate::common::draw::draw_route;
use crate::common::labels::{Importance, Label, Placed};
use crate::mission::LegRoute;
use armor_model::plan::{AreaKind, Graphic, GraphicKind, LatLon, Plan};
use armor_model::world::{Point, World};
use egui::{Color32, Pos2, Rect, RichText, Sense, Stroke, Ui, Vec2, pos2, vec2};
use walkers::{Map, MapMemory, Projector, lat_lon};

use super::basemap::BaseTiles;
use super::plan_edit::{Handle, PlanCommand, Selection, unique_name};
use super::symbols::SymbolCache;
use super::tiles::WorldTiles;
use super::{MissionView, Tool};

/// How close (in points) a click must be to a line to pick it.
const PICK_DISTANCE: f32 = 7.0;
const WAYPOINT_RADIUS: f32 = 7.0;
/// The side of a unit symbol, in points.
const SYMBOL_SIZE: f32 = 44.0;

const ROUTE: Color32 = Color32::from_rgb(20, 70, 170);
const SELECTED: Color32 = Color32::from_rgb(240, 140, 0);
const TACTICAL: Color32 = Color32::from_rgb(20, 20, 20);
const NO_GO: Color32 = Color32::from_rgb(200, 30, 30);
const SYNC: Color32 = Color32::from_rgb(120, 40, 140);
const LABEL_BACK: Color32 = Color32::from_rgba_premultiplied(250, 248, 240, 220);

/// The map's own state, kept between frames.
pub struct MapState {
    pub tool: Tool,
    /// The corners of the graphic being drawn.
    pub pending: Vec<LatLon>,
    /// The code a placed unit gets.
    pub unit_sidc: String,
    pub tiles: WorldTiles,
    /// An offline base map (MBTiles or a tile folder) under the world's tiles.
    pub basemap: Option<BaseTiles>,
    ctx: egui::Context,
    /// OpenStreetMap under the world, when the user turns it on (off by default: the machines
    /// the studio runs on are often offline).
    pub online: Option<walkers::HttpTiles>,
    pub memory: MapMemory,
    pub symbols: SymbolCache,
    pub rect: Rect,
    /// What the map's centre starts at (walkers' "my position").
    centre: LatLon,
    /// The area to frame at the next frame (after opening a plan or loading a world).
    pub fit_requested: bool,
    bounds: Option<(LatLon, LatLon)>,
    projector: Option<Projector>,
    /// The labels' boxes drawn at the last frame, and how long placing them took.
    pub label_boxes: Vec<Rect>,
    pub label_time: std::time::Duration,
    /// A handle being dragged and the plan before the drag.
    drag: Option<(Handle, Box<Plan>)>,
    /// What a right-click picked, for its menu.
    context: Selection,
}

impl MapState {
    pub fn new(ctx: &egui::Context) -> MapState {
        MapState {
            tool: Tool::Select,
            pending: Vec::new(),
            unit_sidc: "SFGPUCR----D---".to_owned(),
            tiles: WorldTiles::new(ctx, None, (0.0, 0.0)),
            basemap: None,
            ctx: ctx.clone(),
            online: None,
            memory: MapMemory::default(),
            symbols: SymbolCache::default(),
            rect: Rect::NOTHING,
            centre: LatLon::default(),
            fit_requested: true,
            bounds: None,
            projector: None,
            label_boxes: Vec::new(),
            label_time: std::time::Duration::ZERO,
            drag: None,
            context: Selection::None,
        }
    }

    pub fn set_world(&mut self, world: Option<World>, origin: LatLon) {
        self.bounds = world.as_ref().map(|world| {
            let bounds = world.bounds();
            let corner = |x, y| {
                let (lat, lon) = world.to_lat_lon(Point::new(x, y));
                LatLon::new(lat, lon)
            };
            (
                corner(bounds.min_x, bounds.min_y),
                corner(bounds.max_x, bounds.max_y),
            )
        });
        self.centre = match self.bounds {
            Some((a, b)) => {
                LatLon::new((a.lat_deg + b.lat_deg) / 2.0, (a.lon_deg + b.lon_deg) / 2.0)
            }
            None => origin,
        };
        self.tiles
            .set_world(world, (origin.lat_deg, origin.lon_deg));
        self.fit_requested = true;
    }

    /// Shows `map` under the world's tiles (which are then drawn half seen through), or no
    /// base map.
    pub fn set_basemap(&mut self, map: Option<armor_runtime::basemap::Basemap>) {
        self.basemap = map.map(|map| BaseTiles::new(&self.ctx, map));
    }

    pub fn set_online(&mut self, ctx: &egui::Context, on: bool) {
        self.online =
            on.then(|| walkers::HttpTiles::new(walkers::sources::OpenStreetMap, ctx.clone()));
    }

    /// Where a geographic point is on screen, as drawn last frame.
    pub fn screen_pos(&self, at: LatLon) -> Option<Pos2> {
        self.projector
            .as_ref()
            .map(|projector| projector.project(position(at)).to_pos2())
    }

    /// Frames `a`–`b` (opposite corners) in the map's rectangle.
    fn fit(&mut self, a: LatLon, b: LatLon, size: Vec2) {
        let centre = LatLon::new((a.lat_deg + b.lat_deg) / 2.0, (a.lon_deg + b.lon_deg) / 2.0);
        let span = a.to_local(b);
        let extent_m = span
            .x
            .abs()
            .max(span.y.abs() * f64::from(size.x / size.y.max(1.0)))
            .max(5.0);
        // Metres per point at zoom z: 156,543 · cos(latitude) / 2^z (256-point tiles).
        let metres_per_point = extent_m * 1.15 / f64::from(size.x.max(100.0));
        let zoom = (156_543.03 * centre.lat_deg.to_radians().cos() / metres_per_point).log2();
        let _ = self.memory.set_zoom(zoom.clamp(2.0, 25.5));
        self.memory.center_at(position(centre));
    }
}

/// A map position, built the one way (x is the longitude).
pub fn position(at: LatLon) -> walkers::Position {
    lat_lon(at.lat_deg, at.lon_deg)
}

fn lat_lon_of(position: walkers::Position) -> LatLon {
    LatLon::new(position.y(), position.x())
}

/// Everything the drawing needs, in screen points.
struct Scene {
    waypoints: Vec<(String, Pos2)>,
    /// Each leg's route as drawn.
    routes: Vec<Vec<Pos2>>,
    /// Per leg: `Some` when the robot has no way through, with where it is cut (if known).
    cut: Vec<Option<Option<Pos2>>>,
}

impl MissionView {
    /// The map and what is drawn on it, for editing.
    pub fn map_ui(&mut self, ui: &mut Ui) {
        let selection = self.editor.selection.clone();
        let (scene, projector, response) =
            self.show_map(ui, &selection, None, Box::new(|_, _, _, _, _, _| {}));
        let mut out = Vec::new();
        self.handles_ui(ui, &scene, &projector, &mut out);
        self.clicks_ui(ui, &response, &scene, &projector, &mut out);
        self.pending_ui(ui, &response, &projector);
        self.commands.extend(out);
    }

    /// Frames the plan's world at the next frame the map is drawn.
    pub fn request_fit(&mut self) {
        self.map.fit_requested = true;
    }

    /// The system the plan names, as read when it was opened or last changed.
    pub fn plan_system(&self) -> Option<&armor_model::SystemConfig> {
        self.surroundings.system.as_ref()
    }

    /// Centres the map on `point` of the world frame (metres), keeping the zoom: to follow
    /// the robot.
    pub fn centre_on(&mut self, point: Point) {
        let origin = self.surroundings.origin(&self.editor.plan);
        let at = LatLon::from_local(point, origin);
        if at.lat_deg.is_finite() && at.lon_deg.is_finite() {
            self.map.memory.center_at(position(at));
        }
    }

    /// The boxes of the labels drawn at the last frame (none overlaps another).
    pub fn label_boxes(&self) -> &[Rect] {
        &self.map.label_boxes
    }

    /// What placing the labels took at the last frame (`armor-studio-bench`'s
    /// `label_place_ms_500_waypoints`).
    pub fn label_time(&self) -> std::time::Duration {
        self.map.label_time
    }

    /// Where `point` of the world frame (metres) was drawn at the last frame, and the map's
    /// area then: for tests that look for the robot.
    pub fn last_screen_of(&self, point: Point) -> Option<(Pos2, Rect)> {
        let projector = self.map.projector.as_ref()?;
        let origin = self.surroundings.origin(&self.editor.plan);
        let at = projector.project(position(LatLon::from_local(point, origin)));
        Some((at.to_pos2(), self.map.rect))
    }

    /// The world-frame point (metres) under `pos` on the map drawn at the last frame: where
    /// the operator pressed, for the Run view's set-pose tool.
    pub fn world_at(&self, pos: Pos2) -> Option<Point> {
        let projector = self.map.projector.as_ref()?;
        let origin = self.surroundings.origin(&self.editor.plan);
        let point = lat_lon_of(projector.unproject(pos.to_vec2())).to_local(origin);
        (point.x.is_finite() && point.y.is_finite()).then_some(point)
    }

    /// The map for watching a run: the run's plan ([`MissionView::watch_plan`], else the plan
    /// edited) with `current` (a leg) highlighted and no editing; `overlay` paints over it,
    /// given where a point of the world frame (metres) is on screen. The plan's labels keep off
    /// what `keep_clear` returns (the robot) and stay inside the world; they are drawn over
    /// the overlay's shapes (a laser's hits do not cross them), its own texts keeping off them.
    pub fn watch_ui(
        &mut self,
        ui: &mut Ui,
        current: Option<usize>,
        keep_clear: &KeepClear<'_>,
        overlay: Box<Overlay<'_>>,
    ) -> egui::Response {
        let selection = current.map_or(Selection::None, Selection::Leg);
        let (_, _, response) = self.show_map(ui, &selection, Some(keep_clear), overlay);
        response
    }

    /// Draws the map with the plan (the run's when watching a run, that is when `keep_clear`
    /// is given, else the one edited), `selection` highlighted, then `overlay` (given the
    /// boxes of the plan's labels, which its own texts should not cover, and the rectangle
    /// labels stay in).
    fn show_map(
        &mut self,
        ui: &mut Ui,
        selection: &Selection,
        keep_clear: Option<&KeepClear<'_>>,
        overlay: Box<Overlay<'_>>,
    ) -> (Scene, Projector, egui::Response) {
        let watching = keep_clear.is_some();
        let rect = ui.available_rect_before_wrap();
        if self.map.fit_requested && rect.width() > 50.0 {
            self.map.fit_requested = false;
            let plan = if watching {
                self.watched_plan()
            } else {
                &self.editor.plan
            };
            let corners = plan
                .waypoints
                .iter()
                .map(|w| w.position)
                .chain(plan.graphics.iter().flat_map(|g| g.points.iter().copied()));
            let from_plan = corners.fold(None, |bounds: Option<(LatLon, LatLon)>, p| {
                Some(match bounds {
                    None => (p, p),
                    Some((a, b)) => (
                        LatLon::new(a.lat_deg.min(p.lat_deg), a.lon_deg.min(p.lon_deg)),
                        LatLon::new(b.lat_deg.max(p.lat_deg), b.lon_deg.max(p.lon_deg)),
                    ),
                })
            });
            if let Some((a, b)) = self.map.bounds.or(from_plan) {
                self.map.fit(a, b, rect.size());
            } else {
                let centre = self.map.centre;
                self.map.fit(centre, centre, rect.size());
            }
        }
        // Labels stay inside the world while a run is watched.
        let world_bounds = self.map.bounds;
        let origin = self.surroundings.origin(&self.editor.plan);
        let MapState {
            tiles,
            basemap,
            online,
            memory,
            symbols,
            centre,
            ..
        } = &mut self.map;
        let map = match (basemap, online) {
            // The world drawn over the base map or the street map, half seen through.
            (Some(basemap), _) => {
                Map::new(Some(basemap), memory, position(*centre)).with_layer(tiles, 0.55)
            }
            (None, Some(online)) => {
                Map::new(Some(online), memory, position(*centre)).with_layer(tiles, 0.55)
            }
            (None, None) => Map::new(Some(tiles), memory, position(*centre)),
        }
        .zoom_with_ctrl(false)
        .double_click_to_zoom(false);
        let (plan, legs) = match &self.watched {
            Some(watched) if watching => (&watched.plan, &watched.checked.legs),
            _ => (&self.editor.plan, &self.checked.legs),
        };
        let response = map.show(ui, |ui, response, projector, _| {
            let project = |at: LatLon| projector.project(position(at)).to_pos2();
            let scene = Scene {
                waypoints: plan
                    .waypoints
                    .iter()
                    .map(|w| (w.name.clone(), project(w.position)))
                    .collect(),
                routes: plan
                    .legs
                    .iter()
                    .enumerate()
                    .map(|(index, leg)| match legs.get(index) {
                        Some(LegRoute::Path { points, .. }) if points.len() >= 2 => points
                            .iter()
                            .map(|p| project(LatLon::from_local(*p, origin)))
                            .collect(),
                        _ => [&leg.from, &leg.to]
                            .iter()
                            .filter_map(|name| plan.waypoint(name))
                            .map(|w| project(w.position))
                            .collect(),
                    })
                    .collect(),
                cut: plan
                    .legs
                    .iter()
                    .enumerate()
                    .map(|(index, _)| match legs.get(index) {
                        Some(LegRoute::Cut { at, .. }) => {
                            Some(at.map(|p| project(LatLon::from_local(p, origin))))
                        }
                        _ => None,
                    })
                    .collect(),
            };
            let painter = ui.painter().with_clip_rect(response.rect);
            let mut labels = Labels::default();
            draw_graphics(&painter, plan, selection, &project, &mut labels);
            draw_legs(&painter, plan, selection, &scene, &mut labels);
            draw_sync_lines(&painter, plan, &scene, &mut labels);
            draw_waypoints(
                &painter,
                plan,
                selection,
                &scene,
                symbols,
                ui.ctx(),
                &mut labels,
            );
            draw_units(
                &painter,
                plan,
                selection,
                symbols,
                ui.ctx(),
                &project,
                &mut labels,
            );
            let scale = draw_scale(&painter, response.rect, projector, origin);
            labels.obstacles.extend(scale);
            let project_local = |p: Point| project(LatLon::from_local(p, origin));
            let beside = keep_clear.map(|keep_clear| keep_clear(&project_local));
            let bounds = match (&beside, world_bounds) {
                (Some(_), Some((a, b))) => {
                    let world = Rect::from_two_pos(project(a), project(b)).intersect(response.rect);
                    if world.width() >= 120.0 && world.height() >= 40.0 {
                        world
                    } else {
                        response.rect
                    }
                }
                (Some(_), None) => response.rect,
                (None, _) => painter.clip_rect(),
            };
            let mut sizes = HashMap::new();
            if let Some(beside) = beside {
                labels.obstacles.extend(beside.obstacles);
                for (tag, size) in beside.tags {
                    sizes.insert(tag.text.clone(), size);
                    labels.labels.push(tag);
                }
            }
            let (placed, took) = labels.place(&painter, bounds, &sizes);
            let boxes: Vec<Rect> = placed.iter().map(|label| label.rect).collect();
            let leaders: Vec<[Pos2; 2]> = placed.iter().filter_map(|label| label.leader).collect();
            let (tags, placed): (Vec<Placed>, Vec<Placed>) = placed
                .into_iter()
                .partition(|label| label.importance == Importance::Robot);
            // The run's shapes, then the plan's labels over them, then the run's texts.
            overlay(&painter, &project_local, &boxes, &leaders, bounds, tags);
            paint_labels(&painter, placed);
            (scene, projector.clone(), (boxes, took))
        });
        let (scene, projector, (label_boxes, label_time)) = response.inner;
        self.map.label_boxes = label_boxes;
        self.map.label_time = label_time;
        let response = response.response;
        self.map.rect = response.rect;
        self.map.projector = Some(projector.clone());
        (scene, projector, response)
    }

    /// The tools above the map.
    pub fn toolbar_ui(&mut self, ui: &mut Ui) {
        ui.horizontal_wrapped(|ui| {
            for tool in Tool::ALL {
                let selected = self.map.tool == tool;
                if ui
                    .selectable_label(selected, tool.label())
                    .on_hover_text(tool.help())
                    .clicked()
                {
                    self.set_tool(tool);
                }
            }
            if self.map.tool == Tool::Unit {
                let label = ui.label("SIDC");
                ui.add(egui::TextEdit::singleline(&mut self.map.unit_sidc).desired_width(130.0))
                    .labelled_by(label.id);
            }
            ui.separator();
            if ui
                .button("Fit")
                .on_hover_text("frame the world and the plan (Home)")
                .clicked()
            {
                self.map.fit_requested = true;
            }
            let mut online = self.map.online.is_some();
            if ui
                .checkbox(&mut online, "Online map")
                .on_hover_text("OpenStreetMap tiles under the world (needs the internet)")
                .changed()
            {
                self.map.set_online(ui.ctx(), online);
            }
            ui.separator();
            ui.label(RichText::new(self.map.tool.help()).weak());
        });
    }

    /// Waypoints, units and the selected graphic's corners: each can be clicked and dragged.
    fn handles_ui(
        &mut self,
        ui: &mut Ui,
        scene: &Scene,
        projector: &Projector,
        out: &mut Vec<PlanCommand>,
    ) {
        let plan = &self.editor.plan;
        let mut handles: Vec<(Handle, Pos2, Selection)> = scene
            .waypoints
            .iter()
            .map(|(name, p)| {
                (
                    Handle::Waypoint(name.clone()),
                    *p,
                    Selection::Waypoint(name.clone()),
                )
            })
            .collect();
        for (index, unit) in plan.units.iter().enumerate() {
            let p = projector.project(position(unit.position)).to_pos2();
            handles.push((Handle::Unit(index), p, Selection::Unit(index)));
        }
        if let Selection::Graphic(index) = self.editor.selection
            && let Some(graphic) = plan.graphics.get(index)
        {
            for (corner, at) in graphic.points.iter().enumerate() {
                let p = projector.project(position(*at)).to_pos2();
                ui.painter().rect(
                    Rect::from_center_size(p, Vec2::splat(8.0)),
                    1.0,
                    Color32::WHITE,
                    Stroke::new(1.5, SELECTED),
                    egui::StrokeKind::Middle,
                );
                handles.push((Handle::Vertex(index, corner), p, Selection::Graphic(index)));
            }
        }
        let visible = self.map.rect;
        for (handle, p, selection) in handles {
            if !visible.contains(p) {
                continue;
            }
            let size = match handle {
                Handle::Unit(_) => SYMBOL_SIZE * 0.7,
                _ => WAYPOINT_RADIUS * 2.6,
            };
            let response = ui
                .interact(
                    Rect::from_center_size(p, Vec2::splat(size)),
                    ui.id().with(("handle", &handle)),
                    Sense::click_and_drag(),
                )
                .on_hover_cursor(egui::CursorIcon::Grab);
            if response.clicked() || response.drag_started() {
                out.push(PlanCommand::Select(selection.clone()));
            }
            if response.drag_started() {
                self.map.drag = Some((handle.clone(), Box::new(plan.clone())));
            }
            if response.dragged()
                && let Some(pointer) = response.interact_pointer_pos()
            {
                out.push(PlanCommand::Drag(
                    handle.clone(),
                    lat_lon_of(projector.unproject(pointer.to_vec2())),
                ));
            }
            if response.drag_stopped()
                && let Some((_, before)) = self.map.drag.take()
            {
                out.push(PlanCommand::Moved { before });
            }
            if response.secondary_clicked() {
                self.map.context = selection;
            }
            response.context_menu(|ui| {
                if ui.button("Delete").clicked() {
                    out.push(PlanCommand::Select(self.map.context.clone()));
                    out.push(PlanCommand::DeleteSelection);
                    ui.close();
                }
            });
        }
    }

    /// Clicks on the map itself: what they do depends on the tool.
    fn clicks_ui(
        &mut self,
        ui: &mut Ui,
        response: &egui::Response,
        scene: &Scene,
        projector: &Projector,
        out: &mut Vec<PlanCommand>,
    ) {
        // The menu first: while the pointer is over it, it is not over the map.
        if response.secondary_clicked()
            && let Some(pointer) = response.interact_pointer_pos()
        {
            self.map.context = self.pick(pointer, scene, projector);
        }
        let context = self.map.context.clone();
        response.context_menu(|ui| {
            if let Selection::Leg(index) = context
                && ui.button("Insert a waypoint").clicked()
            {
                out.push(PlanCommand::InsertWaypoint(index));
                ui.close();
            }
            if context != Selection::None && ui.button("Delete").clicked() {
                out.push(PlanCommand::Select(context.clone()));
                out.push(PlanCommand::DeleteSelection);
                ui.close();
            }
            if context == Selection::None {
                ui.label("Nothing here: use the tools above the map to draw.");
            }
        });
        let Some(pointer) = response.interact_pointer_pos().or(response.hover_pos()) else {
            return;
        };
        let at = lat_lon_of(projector.unproject(pointer.to_vec2()));
        if response.double_clicked()
            && let Tool::Graphic(kind) = self.map.tool
        {
            // The first click of the double-click added the last corner.
            self.finish_graphic(kind, out);
            return;
        }
        if !response.clicked() {
            return;
        }
        match self.map.tool {
            Tool::Select => out.push(PlanCommand::Select(self.pick(pointer, scene, projector))),
            Tool::Waypoint => out.push(PlanCommand::AddWaypoint(at)),
            Tool::Graphic(_) => self.map.pending.push(at),
            Tool::Unit => out.push(PlanCommand::AddUnit {
                sidc: self.map.unit_sidc.clone(),
                at,
            }),
        }
        let enter = ui.input(|input| input.key_pressed(egui::Key::Enter));
        if enter && let Tool::Graphic(kind) = self.map.tool {
            self.finish_graphic(kind, out);
        }
    }

    /// The graphic being drawn: its corners so far and a rubber band to the pointer; Enter
    /// ends it, Escape drops it.
    fn pending_ui(&mut self, ui: &mut Ui, response: &egui::Response, projector: &Projector) {
        let Tool::Graphic(kind) = self.map.tool else {
            return;
        };
        let (enter, escape) = ui.input(|input| {
            (
                input.key_pressed(egui::Key::Enter),
                input.key_pressed(egui::Key::Escape),
            )
        });
        if escape {
            self.map.pending.clear();
        }
        if enter && !self.map.pending.is_empty() {
            let mut out = Vec::new();
            self.finish_graphic(kind, &mut out);
            self.commands.extend(out);
            return;
        }
        let mut points: Vec<Pos2> = self
            .map
            .pending
            .iter()
            .map(|at| projector.project(position(*at)).to_pos2())
            .collect();
        if let Some(pointer) = response.hover_pos() {
            points.push(pointer);
        }
        let painter = ui.painter().with_clip_rect(response.rect);
        for pair in points.windows(2) {
            painter.extend(egui::Shape::dashed_line(
                &[pair[0], pair[1]],
                Stroke::new(2.0, SELECTED),
                6.0,
                4.0,
            ));
        }
    }

    fn finish_graphic(&mut self, kind: GraphicKind, out: &mut Vec<PlanCommand>) {
        let points = std::mem::take(&mut self.map.pending);
        let needed = if matches!(kind, GraphicKind::Area(_)) {
            3
        } else {
            2
        };
        if points.len() < needed {
            return;
        }
        let prefix = match kind {
            GraphicKind::PhaseLine => "pl",
            GraphicKind::Boundary => "boundary",
            GraphicKind::Area(AreaKind::NoGo) => "nogo",
            GraphicKind::Area(AreaKind::Objective) => "obj",
            GraphicKind::Area(_) => "area",
        };
        out.push(PlanCommand::AddGraphic(Graphic {
            kind,
            name: unique_name(&self.editor.plan, prefix),
            points,
            ..Graphic::default()
        }));
    }

    /// What is under `pointer`: a waypoint, a unit, a leg, a graphic, or nothing.
    fn pick(&self, pointer: Pos2, scene: &Scene, projector: &Projector) -> Selection {
        let plan = &self.editor.plan;
        if let Some((name, _)) = scene
            .waypoints
            .iter()
            .find(|(_, p)| p.distance(pointer) <= WAYPOINT_RADIUS * 1.5)
        {
            return Selection::Waypoint(name.clone());
        }
        if let Some(index) = plan.units.iter().position(|unit| {
            projector
                .project(position(unit.position))
                .to_pos2()
                .distance(pointer)
                <= SYMBOL_SIZE * 0.4
        }) {
            return Selection::Unit(index);
        }
        let near = |points: &[Pos2]| {
            points
                .windows(2)
                .any(|pair| segment_distance(pointer, pair[0], pair[1]) <= PICK_DISTANCE)
        };
        if let Some(index) = scene.routes.iter().position(|route| near(route)) {
            return Selection::Leg(index);
        }
        for (index, graphic) in plan.graphics.iter().enumerate().rev() {
            let mut points: Vec<Pos2> = graphic
                .points
                .iter()
                .map(|at| projector.project(position(*at)).to_pos2())
                .collect();
            let is_area = matches!(graphic.kind, GraphicKind::Area(_));
            if is_area && let Some(first) = points.first().copied() {
                points.push(first);
            }
            if near(&points) || is_area && inside(&points, pointer) {
                return Selection::Graphic(index);
            }
        }
        Selection::None
    }
}

fn segment_distance(p: Pos2, a: Pos2, b: Pos2) -> f32 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_sq().max(1e-6)).clamp(0.0, 1.0);
    p.distance(a + ab * t)
}

fn inside(polygon: &[Pos2], p: Pos2) -> bool {
    let edges = polygon.windows(2).map(|pair| {
        (
            Point::new(f64::from(pair[0].x), f64::from(pair[0].y)),
            Point::new(f64::from(pair[1].x), f64::from(pair[1].y)),
        )
    });
    armor_model::geo::inside(edges, Point::new(f64::from(p.x), f64::from(p.y)))
}

/// Text on a pale box, so that it reads over any map; returns the box.
fn tag(
    painter: &egui::Painter,
    at: Pos2,
    anchor: egui::Align2,
    text: &str,
    colour: Color32,
) -> Rect {
    let galley = painter.layout_no_wrap(text.to_owned(), LABEL_FONT, colour);
    let rect = anchor.anchor_size(at, galley.size()).expand(2.0);
    painter.rect_filled(rect, 2.0, LABEL_BACK);
    painter.galley(rect.min + vec2(2.0, 2.0), galley, colour);
    rect
}

/// What a watched map's labels are placed with: the boxes they keep off (the robots), and
/// the robots' tags, placed first, each with its size (drawn larger than the map's labels).
#[derive(Default)]
pub struct Beside {
    pub obstacles: Vec<Rect>,
    pub tags: Vec<(Label, egui::Vec2)>,
}

/// What a watched map's labels are placed with ([`Beside`]), given where a point of the world
/// frame (metres) is on screen.
pub type KeepClear<'a> = dyn Fn(&dyn Fn(Point) -> Pos2) -> Beside + 'a;

/// What a watched map's overlay is given: the painter, where a point of the world frame is on
/// screen, every label's box and leader line, the rectangle labels stay in, and the robots'
/// tags placed.
pub type Overlay<'a> = dyn FnOnce(&egui::Painter, &dyn Fn(Point) -> Pos2, &[Rect], &[[Pos2; 2]], Rect, Vec<Placed>)
    + 'a;

const LABEL_FONT: egui::FontId = egui::FontId::proportional(11.0);

/// The labels of a frame, placed together once every shape is drawn (see `labels.rs`), and
/// the symbols they must not cover.
#[derive(Default)]
struct Labels {
    labels: Vec<Label>,
    obstacles: Vec<Rect>,
}

impl Labels {
    fn add(
        &mut self,
        anchors: Vec<Pos2>,
        gap: f32,
        preferred: egui::Align2,
        text: &str,
        colour: Color32,
        importance: Importance,
    ) {
        self.labels.push(Label {
            anchors,
            gap,
            preferred,
            text: text.to_owned(),
            colour,
            importance,
        });
    }

    /// Places the labels inside `bounds`; returns where, and the time the placement took.
    /// `sizes`: the labels drawn otherwise than the map's (the robots' tags), by text.
    fn place(
        self,
        painter: &egui::Painter,
        bounds: Rect,
        sizes: &HashMap<String, egui::Vec2>,
    ) -> (Vec<Placed>, std::time::Duration) {
        let started = std::time::Instant::now();
        let mut measure = |text: &str| {
            sizes.get(text).copied().unwrap_or_else(|| {
                painter
                    .layout_no_wrap(text.to_owned(), LABEL_FONT, Color32::BLACK)
                    .size()
            })
        };
        let placed =
            crate::common::labels::place(self.labels, &self.obstacles, &[], bounds, &mut measure);
        (placed, started.elapsed())
    }
}

/// Draws labels placed by [`Labels::place`].
fn paint_labels(painter: &egui::Painter, placed: Vec<Placed>) {
    for label in placed {
        if let Some(leader) = label.leader {
            painter.line_segment(leader, Stroke::new(1.0, label.colour.gamma_multiply(0.7)));
        }
        let galley = painter.layout_no_wrap(label.text, LABEL_FONT, label.colour);
        painter.rect_filled(label.rect, 2.0, LABEL_BACK);
        painter.galley(label.rect.min + vec2(2.0, 2.0), galley, label.colour);
    }
}

fn draw_graphics(
    painter: &egui::Painter,
    plan: &Plan,
    selection: &Selection,
    project: &dyn Fn(LatLon) -> Pos2,
    labels: &mut Labels,
) {
    for (index, graphic) in plan.graphics.iter().enumerate() {
        let points: Vec<Pos2> = graphic.points.iter().map(|at| project(*at)).collect();
        if points.len() < 2 {
            continue;
        }
        let selected = *selection == Selection::Graphic(index);
        let width = if selected { 3.5 } else { 2.0 };
        match graphic.kind {
            GraphicKind::Area(kind) => {
                let (line, fill, prefix) = match kind {
                    AreaKind::NoGo => (
                        NO_GO,
                        Color32::from_rgba_unmultiplied(200, 30, 30, 45),
                        "NO-GO",
                    ),
                    AreaKind::Objective => (TACTICAL, Color32::TRANSPARENT, "OBJ"),
                    AreaKind::Assembly => (TACTICAL, Color32::TRANSPARENT, "AA"),
                    AreaKind::Named => (TACTICAL, Color32::TRANSPARENT, ""),
                };
                let line = if selected { SELECTED } else { line };
                painter.add(egui::Shape::convex_polygon(
                    points.clone(),
                    fill,
                    Stroke::NONE,
                ));
                let mut closed = points.clone();
                closed.push(points[0]);
                painter.add(egui::Shape::line(closed.clone(), Stroke::new(width, line)));
                if kind == AreaKind::NoGo {
                    // Ticks inward along the outline, as an obstacle is drawn.
                    for pair in closed.windows(2) {
                        let along = pair[1] - pair[0];
                        let ticks = (along.length() / 10.0).floor() as usize;
                        let normal = along.normalized().rot90() * 5.0;
                        for k in 1..ticks {
                            let p = pair[0] + along * (k as f32 / ticks as f32);
                            painter.line_segment([p, p + normal], Stroke::new(1.2, line));
                        }
                    }
                }
                let centre = points.iter().fold(Vec2::ZERO, |sum, p| sum + p.to_vec2())
                    / points.len() as f32;
                let text = format!("{prefix} {}", graphic.name).trim().to_owned();
                labels.add(
                    vec![centre.to_pos2()],
                    0.0,
                    egui::Align2::CENTER_CENTER,
                    &text,
                    line,
                    Importance::Graphic,
                );
            }
            GraphicKind::PhaseLine | GraphicKind::Boundary => {
                let colour = if selected { SELECTED } else { TACTICAL };
                let stroke = Stroke::new(width, colour);
                if graphic.kind == GraphicKind::Boundary {
                    painter.extend(egui::Shape::dashed_line(&points, stroke, 14.0, 5.0));
                } else {
                    painter.add(egui::Shape::line(points.clone(), stroke));
                }
                let mut text = match graphic.kind {
                    GraphicKind::PhaseLine => {
                        let name = graphic.name.to_uppercase();
                        let name = name.strip_prefix("PL_").unwrap_or(&name);
                        format!("PL {name}")
                    }
                    _ => graphic.name.clone(),
                };
                if let Some(at) = graphic.at_unix_secs {
                    text += &format!("  {}", clock(at));
                }
                // Once, at whichever end has room.
                labels.add(
                    vec![points[0], points[points.len() - 1]],
                    4.0,
                    egui::Align2::CENTER_BOTTOM,
                    &text,
                    colour,
                    Importance::Graphic,
                );
            }
        }
    }
}

fn draw_legs(
    painter: &egui::Painter,
    plan: &Plan,
    selection: &Selection,
    scene: &Scene,
    labels: &mut Labels,
) {
    for (index, (leg, route)) in plan.legs.iter().zip(&scene.routes).enumerate() {
        if route.len() < 2 {
            continue;
        }
        let selected = *selection == Selection::Leg(index);
        let (colour, width) = if selected {
            (SELECTED, 5.0)
        } else {
            (ROUTE, 3.0)
        };
        if let Some(Some(cut)) = scene.cut.get(index) {
            // No way through: the leg dashed in red, a cross where the way is cut.
            painter.extend(egui::Shape::dashed_line(
                route,
                Stroke::new(width, NO_GO),
                10.0,
                6.0,
            ));
            if let Some(at) = cut {
                let stroke = Stroke::new(3.0, NO_GO);
                for (a, b) in [
                    (vec2(-7.0, -7.0), vec2(7.0, 7.0)),
                    (vec2(-7.0, 7.0), vec2(7.0, -7.0)),
                ] {
                    painter.line_segment([*at + a, *at + b], stroke);
                }
                labels
                    .obstacles
                    .push(Rect::from_center_size(*at, Vec2::splat(16.0)));
            }
            labels.add(
                vec![route[0] + (route[route.len() - 1] - route[0]) * 0.5],
                8.0,
                egui::Align2::CENTER_BOTTOM,
                &format!("{}: no way through", leg.name),
                NO_GO,
                Importance::Constraint,
            );
            continue;
        }
        if let Some(middle) = draw_route(painter, route, Stroke::new(width, colour), false) {
            labels.add(
                vec![middle],
                8.0,
                egui::Align2::CENTER_BOTTOM,
                &leg.name,
                colour,
                Importance::Detail,
            );
        }
    }
}

/// Appointments and deadlines the way a plan's synchronisation matrix puts them on the map:
/// a line across the route where it applies, with "NET" (not earlier than) at the departure and
/// "NLT" (not later than) at the arrival; a wait as a label at the waypoint.
fn draw_sync_lines(painter: &egui::Painter, plan: &Plan, scene: &Scene, labels: &mut Labels) {
    let stroke = Stroke::new(2.5, SYNC);
    for (leg, route) in plan.legs.iter().zip(&scene.routes) {
        if route.len() < 2 {
            continue;
        }
        let start_dir = (route[1] - route[0]).normalized();
        let end_dir = (route[route.len() - 1] - route[route.len() - 2]).normalized();
        let mut across = |at: Pos2, direction: Vec2, text: String| {
            let side = direction.rot90() * 14.0;
            painter.line_segment([at - side, at + side], stroke);
            labels.add(
                vec![at + side],
                2.0,
                egui::Align2::CENTER_TOP,
                &text,
                SYNC,
                Importance::Constraint,
            );
        };
        if let Some(at) = leg.not_before_unix_secs {
            across(
                route[0] + start_dir * 16.0,
                start_dir,
                format!("NET {}", clock(at)),
            );
        }
        if let Some(at) = leg.arrive_by_unix_secs {
            let end = route[route.len() - 1];
            across(end - end_dir * 16.0, end_dir, format!("NLT {}", clock(at)));
        }
        if let Some(wait) = leg.wait_secs
            && let Some((_, p)) = scene.waypoints.iter().find(|(name, _)| name == &leg.to)
        {
            labels.add(
                vec![*p],
                10.0,
                egui::Align2::LEFT_TOP,
                &format!("wait {wait} s"),
                SYNC,
                Importance::Constraint,
            );
        }
        if let Some(action) = &leg.arrival
            && let Some((_, p)) = scene.waypoints.iter().find(|(name, _)| name == &leg.to)
        {
            let modules: Vec<&str> = action.modules.iter().map(|m| m.name.as_str()).collect();
            labels.add(
                vec![*p],
                10.0,
                egui::Align2::LEFT_BOTTOM,
                &modules.join(", "),
                ROUTE,
                Importance::Detail,
            );
        }
    }
}

fn draw_waypoints(
    painter: &egui::Painter,
    plan: &Plan,
    selection: &Selection,
    scene: &Scene,
    symbols: &mut SymbolCache,
    ctx: &egui::Context,
    labels: &mut Labels,
) {
    let start = plan.legs.first().map(|leg| leg.from.as_str());
    for (waypoint, (name, p)) in plan.waypoints.iter().zip(&scene.waypoints) {
        if !painter.clip_rect().expand(SYMBOL_SIZE).contains(*p) {
            continue;
        }
        let selected = *selection == Selection::Waypoint(name.clone());
        let ring = if selected { SELECTED } else { TACTICAL };
        if let Some(sidc) = &waypoint.symbol {
            draw_symbol(painter, symbols, ctx, sidc, *p);
        }
        labels.obstacles.push(Rect::from_center_size(
            *p,
            Vec2::splat(2.0 * WAYPOINT_RADIUS + 4.0),
        ));
        if Some(name.as_str()) == start {
            let r = WAYPOINT_RADIUS + 2.0;
            let triangle = vec![
                *p + vec2(0.0, -r),
                *p + vec2(r, r * 0.8),
                *p + vec2(-r, r * 0.8),
            ];
            painter.add(egui::Shape::convex_polygon(
                triangle,
                Color32::WHITE,
                Stroke::new(2.5, ring),
            ));
        } else {
            painter.circle(*p, WAYPOINT_RADIUS, Color32::WHITE, Stroke::new(2.5, ring));
            painter.circle_filled(*p, 2.0, ring);
        }
        labels.add(
            vec![*p],
            WAYPOINT_RADIUS + 3.0,
            egui::Align2::CENTER_BOTTOM,
            name,
            ring,
            Importance::Waypoint,
        );
    }
}

fn draw_units(
    painter: &egui::Painter,
    plan: &Plan,
    selection: &Selection,
    symbols: &mut SymbolCache,
    ctx: &egui::Context,
    project: &dyn Fn(LatLon) -> Pos2,
    labels: &mut Labels,
) {
    for (index, unit) in plan.units.iter().enumerate() {
        let p = project(unit.position);
        if !painter.clip_rect().expand(SYMBOL_SIZE).contains(p) {
            continue;
        }
        draw_symbol(painter, symbols, ctx, &unit.sidc, p);
        let colour = if *selection == Selection::Unit(index) {
            SELECTED
        } else {
            TACTICAL
        };
        labels
            .obstacles
            .push(Rect::from_center_size(p, Vec2::splat(SYMBOL_SIZE * 0.8)));
        labels.add(
            vec![p],
            SYMBOL_SIZE * 0.42,
            egui::Align2::CENTER_TOP,
            &unit.name,
            colour,
            Importance::Constraint,
        );
    }
}

fn draw_symbol(
    painter: &egui::Painter,
    symbols: &mut SymbolCache,
    ctx: &egui::Context,
    sidc: &str,
    at: Pos2,
) {
    let pixels = (SYMBOL_SIZE * ctx.pixels_per_point()).round() as u32;
    let rect = Rect::from_center_size(at, Vec2::splat(SYMBOL_SIZE));
    match symbols.texture(ctx, sidc, pixels) {
        Ok(texture) => {
            painter.image(
                texture.id(),
                rect,
                Rect::from_min_max(pos2(0.0, 0.0), pos2(1.0, 1.0)),
                Color32::WHITE,
            );
        }
        Err(_) => {
            painter.rect_stroke(
                rect.shrink(8.0),
                0.0,
                Stroke::new(2.0, NO_GO),
                egui::StrokeKind::Middle,
            );
        }
    }
}

/// A scale bar in the lower left corner: a round length that takes 60 to 150 points; returns
/// the area it takes, which labels keep off.
fn draw_scale(
    painter: &egui::Painter,
    rect: Rect,
    projector: &Projector,
    origin: LatLon,
) -> Option<Rect> {
    let centre = lat_lon_of(projector.unproject(rect.center().to_vec2()));
    let east = LatLon::from_local(
        Point::new(centre.to_local(origin).x + 1.0, centre.to_local(origin).y),
        origin,
    );
    let points_per_metre =
        projector.project(position(east)).x - projector.project(position(centre)).x;
    if !(points_per_metre.is_finite() && points_per_metre > 0.0) {
        return None;
    }
    let metres = [
        0.5, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0, 5000.0,
    ]
    .into_iter()
    .find(|m| m * points_per_metre >= 60.0)?;
    let length = metres * points_per_metre;
    let left = rect.left_bottom() + vec2(16.0, -18.0);
    let stroke = Stroke::new(2.0, TACTICAL);
    painter.line_segment([left, left + vec2(length, 0.0)], stroke);
    for x in [0.0, length] {
        painter.line_segment([left + vec2(x, -5.0), left + vec2(x, 5.0)], stroke);
    }
    let text = tag(
        painter,
        left + vec2(length / 2.0, -4.0),
        egui::Align2::CENTER_BOTTOM,
        &format!("{metres} m"),
        TACTICAL,
    );
    Some(text.union(Rect::from_two_pos(
        left - vec2(2.0, 6.0),
        left + vec2(length + 2.0, 6.0),
    )))
}

/// `HH:MM:SSZ` of a date, as the map shows times.
pub fn clock(unix_secs: f64) -> String {
    let text = armor_model::net::format_rfc3339(unix_secs);
    text.get(11..).map_or(text.clone(), str::to_owned)
}
