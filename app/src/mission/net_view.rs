//! The compiled Petri net beside the map: a layered layout (left to right, in the order the
//! net can fire) and its drawing, with the elements of the selected leg highlighted and a click
//! on an element reported so that the map can select its leg.

use std::collections::{BTreeMap, BTreeSet, VecDeque};

use armor_model::net::{Marking, MissionNet};
use egui::{Color32, Pos2, Rect, Sense, Stroke, Ui, Vec2, pos2, vec2};

/// The least distance between layers and the distance between rows, in points of the layout
/// (at zoom 1); layers are pushed further apart until no label touches another.
const LAYER_STEP: f32 = 48.0;
/// Room left between the canvas's edge and a highlight that does not fit in it.
const HIGHLIGHT_MARGIN: f32 = 12.0;
/// Rows clear a place's name below it and a transition's above the next by more than a name
/// stands off its own node, so that a name in a stack of bars reads as the one below it (a layer
/// holds only places or only transitions).
const ROW_STEP: f32 = 48.0;
const MARGIN: f32 = 12.0;
/// The least room between two labels (or a label and a node) of different layers.
const LABEL_GAP: f32 = 10.0;
const PLACE_RADIUS: f32 = 11.0;
const TRANSITION_SIZE: Vec2 = vec2(7.0, 24.0);
/// The labels' size at zoom 1.
pub const LABEL_FONT_SIZE: f32 = 11.0;
/// One notch of the wheel zooms by this factor.
const ZOOM_STEP: f32 = 1.1;
/// Fit never enlarges a small net past this.
const MAX_FIT_ZOOM: f32 = 1.5;
/// Room left round the whole net at a fit, in screen points.
const FIT_SPARE: f32 = 4.0;
/// What the net's panel takes besides the net: the header's line (Fit, Enlarge, the legend),
/// the space under it and the panel's margins.
pub const HEADER_HEIGHT: f32 = 48.0;
/// The least zoom the view opens at: names at 9 points or more.
pub const READABLE_ZOOM: f32 = 9.0 / LABEL_FONT_SIZE;
const ZOOM_RANGE: std::ops::RangeInclusive<f32> = 0.05..=6.0;

const INK: Color32 = Color32::from_rgb(40, 40, 40);
const PAPER: Color32 = Color32::from_rgb(248, 246, 238);
const HIGHLIGHT: Color32 = Color32::from_rgb(230, 150, 20);
const FINAL: Color32 = Color32::from_rgb(60, 150, 80);
const OPERATOR: Color32 = Color32::from_rgb(40, 110, 200);
const TIMED: Color32 = Color32::from_rgb(150, 70, 170);
const EVENT: Color32 = Color32::from_rgb(20, 140, 130);

/// Where each place and transition goes, in points from the top left of the drawing at zoom 1.
#[derive(Clone, Debug, Default)]
pub struct Layout {
    pub nodes: BTreeMap<String, Node>,
    pub size: Vec2,
}

#[derive(Clone, Debug)]
pub struct Node {
    pub pos: Pos2,
    pub is_place: bool,
    /// Where the name goes: below a place, above a transition, so that the names of a place
    /// and of the transitions beside it (in the next layers, on the rows next to its own) lie
    /// in different bands.
    pub label: Rect,
    /// The name as drawn: shortened (the full name in the tooltip) when it shares its first
    /// word with other nodes, as the elements of one leg do (`advance_arrived`,
    /// `advance_blocked`): only the first of them in reading order is drawn in full.
    pub text: String,
}

/// A node's name and its (layer, row).
type Cell<'a> = (&'a str, (usize, usize));

/// The names as drawn (see [`Node::text`]).
fn short_names<'a>(members: impl Iterator<Item = Cell<'a>>) -> BTreeMap<&'a str, String> {
    let mut groups: BTreeMap<&str, Vec<Cell<'a>>> = BTreeMap::new();
    for (name, at) in members {
        let prefix = name.split_once('_').map_or(name, |(prefix, _)| prefix);
        groups.entry(prefix).or_default().push((name, at));
    }
    let mut shown = BTreeMap::new();
    for (prefix, mut members) in groups {
        members.sort_by_key(|(_, (layer, row))| (*layer, *row));
        for (index, (name, _)) in members.iter().enumerate() {
            let text = match name.strip_prefix(prefix).and_then(|s| s.strip_prefix('_')) {
                Some(rest) if index > 0 && !rest.is_empty() => rest.to_owned(),
                _ => (*name).to_owned(),
            };
            shown.insert(*name, text);
        }
    }
    shown
}

/// The label's rectangle of a node at `pos` whose name measures `text`.
fn label_rect(pos: Pos2, is_place: bool, text: Vec2) -> Rect {
    if is_place {
        Rect::from_min_size(pos2(pos.x - text.x / 2.0, pos.y + PLACE_RADIUS + 2.0), text)
    } else {
        Rect::from_min_size(
            pos2(
                pos.x - text.x / 2.0,
                pos.y - TRANSITION_SIZE.y / 2.0 - 2.0 - text.y,
            ),
            text,
        )
    }
}

fn shape_rect(pos: Pos2, is_place: bool) -> Rect {
    if is_place {
        Rect::from_center_size(pos, Vec2::splat(PLACE_RADIUS * 2.0))
    } else {
        Rect::from_center_size(pos, TRANSITION_SIZE)
    }
}

/// Lays `net` out in layers by breadth-first distance from the initially marked places (or,
/// without any, from the places no transition feeds), each node in the row of the first
/// node that reached it where it is free, so that a chain of legs reads as one line and a
/// contingency branches off below it. What the search never reaches goes in two last layers
/// (places, then transitions). `measure` gives the size of a name at zoom 1: each layer stands
/// as far from the ones before as its names need, so that no two names touch.
pub fn layout(net: &MissionNet, measure: &dyn Fn(&str) -> Vec2) -> Layout {
    let mut successors: BTreeMap<&str, Vec<&str>> = BTreeMap::new();
    let mut fed: BTreeSet<&str> = BTreeSet::new();
    for transition in &net.transitions {
        for arc in &transition.inputs {
            successors
                .entry(arc.place.as_str())
                .or_default()
                .push(&transition.name);
        }
        for arc in &transition.outputs {
            successors
                .entry(transition.name.as_str())
                .or_default()
                .push(&arc.place);
            fed.insert(&arc.place);
        }
    }
    let mut roots: Vec<&str> = net
        .places
        .iter()
        .filter(|place| place.tokens > 0)
        .map(|place| place.name.as_str())
        .collect();
    if roots.is_empty() {
        roots = net
            .places
            .iter()
            .filter(|place| !fed.contains(place.name.as_str()))
            .map(|place| place.name.as_str())
            .collect();
    }
    let mut layer_of: BTreeMap<&str, (usize, usize)> = BTreeMap::new();
    let mut taken: BTreeSet<(usize, usize)> = BTreeSet::new();
    let mut queue = VecDeque::new();
    for (row, root) in roots.iter().enumerate() {
        layer_of.insert(root, (0, row));
        taken.insert((0, row));
        queue.push_back(*root);
    }
    while let Some(node) = queue.pop_front() {
        let (layer, row) = layer_of[node];
        for next in successors.get(node).into_iter().flatten() {
            if layer_of.contains_key(next) {
                continue;
            }
            let mut free = row;
            while taken.contains(&(layer + 1, free)) {
                free += 1;
            }
            taken.insert((layer + 1, free));
            layer_of.insert(next, (layer + 1, free));
            queue.push_back(next);
        }
    }
    let last = layer_of
        .values()
        .map(|(layer, _)| layer + 1)
        .max()
        .unwrap_or(0);
    // Layers hold places or transitions only (the net is bipartite), so that one kind of
    // label band per layer suffices; the unreached keep that too.
    let mut unreached_rows = [0, 0];
    let mut layers: BTreeMap<usize, Vec<(&str, bool, usize)>> = BTreeMap::new();
    let all = net
        .places
        .iter()
        .map(|p| (p.name.as_str(), true))
        .chain(net.transitions.iter().map(|t| (t.name.as_str(), false)));
    for (name, is_place) in all {
        let (layer, row) = layer_of.get(name).copied().unwrap_or_else(|| {
            let kind = usize::from(!is_place);
            unreached_rows[kind] += 1;
            (last + kind, unreached_rows[kind] - 1)
        });
        layers.entry(layer).or_default().push((name, is_place, row));
    }
    let shown = short_names(layers.iter().flat_map(|(layer, members)| {
        members
            .iter()
            .map(move |&(name, _, row)| (name, (*layer, row)))
    }));
    let mut nodes: BTreeMap<String, Node> = BTreeMap::new();
    let mut placed: Vec<Rect> = Vec::new();
    let mut previous_x: Option<f32> = None;
    for members in layers.values() {
        let measured: Vec<(&str, bool, f32, Rect, Rect)> = members
            .iter()
            .map(|&(name, is_place, row)| {
                let y = row as f32 * ROW_STEP;
                let at = pos2(0.0, y);
                let label = label_rect(at, is_place, measure(&shown[name]));
                (name, is_place, y, label, shape_rect(at, is_place))
            })
            .collect();
        let mut x = previous_x.map_or(0.0, |x| x + LAYER_STEP);
        for (_, _, _, label, shape) in &measured {
            let footprint = label.union(*shape);
            for other in &placed {
                if other
                    .y_range()
                    .intersects(footprint.expand2(vec2(0.0, 2.0)).y_range())
                {
                    x = x.max(other.max.x + LABEL_GAP - footprint.min.x);
                }
            }
        }
        for (name, is_place, y, label, shape) in measured {
            let shift = vec2(x, 0.0);
            placed.push(label.union(shape).translate(shift));
            nodes.insert(
                name.to_owned(),
                Node {
                    pos: pos2(x, y),
                    is_place,
                    label: label.translate(shift),
                    text: shown[name].clone(),
                },
            );
        }
        previous_x = Some(x);
    }
    let mut bounds = placed.iter().fold(Rect::NOTHING, |a, b| a.union(*b));
    // Room for the arcs going back, which loop below the lower of their ends.
    let lowest = nodes
        .values()
        .map(|node| node.pos.y)
        .fold(f32::MIN, f32::max);
    bounds.max.y = bounds.max.y.max(lowest + ROW_STEP * 0.45 + 2.0);
    if !bounds.is_positive() {
        return Layout::default();
    }
    let shift = Vec2::splat(MARGIN) - bounds.min.to_vec2();
    for node in nodes.values_mut() {
        node.pos += shift;
        node.label = node.label.translate(shift);
    }
    Layout {
        nodes,
        size: bounds.size() + Vec2::splat(2.0 * MARGIN),
    }
}

/// The size of a name at zoom 1, as the net view draws it.
pub fn measure_ui(ui: &Ui) -> impl Fn(&str) -> Vec2 + '_ {
    move |text: &str| {
        ui.painter()
            .layout_no_wrap(
                text.to_owned(),
                egui::FontId::proportional(LABEL_FONT_SIZE),
                INK,
            )
            .size()
    }
}

/// What the net view keeps between frames: how it is zoomed and panned, and whether it is
/// enlarged.
#[derive(Clone, Debug)]
pub struct NetViewState {
    /// Screen points per point of the layout.
    pub zoom: f32,
    /// Where the layout's origin is, from the top left of the canvas.
    pub offset: Vec2,
    /// Fit at the next frame (the net changed, or Fit was asked).
    pub fit_pending: bool,
    /// The next fit shows the whole net (asked for with Fit or Home), readable or not.
    pub fit_whole: bool,
    /// The user has not moved the view since the last fit: it fits again when the canvas
    /// changes size (enlarged, or the panel dragged).
    fitted: bool,
    /// The pointer was over the canvas at the last frame (Home then fits the net, not the map).
    pub pointer_over: bool,
    /// The net's panel takes most of the window.
    pub enlarged: bool,
    /// The canvas of the last frame, on the screen.
    pub canvas: Rect,
    /// The names' rectangles of the last frame, on the screen.
    pub label_boxes: Vec<Rect>,
    /// The whole panel below the header: the canvas, and the overview's column beside it when
    /// the net is too large to be read whole.
    pub panel: Rect,
    /// Where the overview of the whole net was drawn at the last frame, and its scale (screen
    /// points per point of the layout): drawn only when part of the net is out of view.
    pub overview: Option<(Rect, f32)>,
    /// The hints drawn at the canvas's edges beyond which part of the net lies ("7 more →"),
    /// with their boxes, at the last frame.
    pub hints: Vec<(String, Rect)>,
}

impl Default for NetViewState {
    fn default() -> Self {
        NetViewState {
            zoom: 1.0,
            offset: Vec2::ZERO,
            fit_pending: true,
            fit_whole: false,
            fitted: true,
            pointer_over: false,
            enlarged: false,
            canvas: Rect::NOTHING,
            panel: Rect::NOTHING,
            label_boxes: Vec::new(),
            overview: None,
            hints: Vec::new(),
        }
    }
}

impl NetViewState {
    pub fn screen_from_layout(&self, p: Pos2) -> Pos2 {
        self.canvas.min + self.offset + p.to_vec2() * self.zoom
    }

    pub fn layout_from_screen(&self, p: Pos2) -> Pos2 {
        ((p - self.canvas.min - self.offset) / self.zoom).to_pos2()
    }

    /// Fits the net in view: the whole of it when asked (Fit, Home), else never below the
    /// zoom at which names can be read, its start (the left) in view.
    fn fit(&mut self, size: Vec2) {
        let whole = std::mem::take(&mut self.fit_whole);
        let room = self.canvas.size();
        if size.x <= 0.0 || size.y <= 0.0 || room.x <= 0.0 || room.y <= 0.0 {
            return;
        }
        // A few points to spare: text does not scale quite as the zoom does (a name drawn at
        // a small size can stand a point or two beyond where the layout measured it).
        let inner = (room - Vec2::splat(2.0 * FIT_SPARE)).max(Vec2::splat(1.0));
        let zoom = (inner.x / size.x).min(inner.y / size.y).min(MAX_FIT_ZOOM);
        self.zoom = if whole { zoom } else { zoom.max(READABLE_ZOOM) };
        let spare = room - size * self.zoom;
        self.offset = vec2(
            if spare.x >= 0.0 { spare.x / 2.0 } else { 8.0 },
            if spare.y >= 0.0 { spare.y / 2.0 } else { 8.0 },
        );
        self.fitted = true;
    }

    /// Zooms by `factor` keeping the point under `about` (on the screen) where it is.
    fn zoom_about(&mut self, factor: f32, about: Pos2) {
        let fixed = self.layout_from_screen(about);
        self.zoom = (self.zoom * factor).clamp(*ZOOM_RANGE.start(), *ZOOM_RANGE.end());
        self.offset = about - self.canvas.min - fixed.to_vec2() * self.zoom;
        self.fitted = false;
    }
}

/// What the net drawing shows besides the net.
pub struct NetStyle<'a> {
    /// Elements drawn highlighted (the selected leg's).
    pub highlighted: &'a BTreeSet<String>,
    /// A marking to draw as tokens; without one, the initial marking.
    pub marking: Option<&'a Marking>,
    /// Bring the highlighted elements into view (once, after the selection changed).
    pub scroll_to_highlight: bool,
    /// The elements of the actions' alternative ways and the switches to them: their places
    /// and arcs are drawn dashed.
    pub alternatives: &'a BTreeSet<String>,
}

/// The kinds of transition, each drawn in its colour (as the legend says).
fn transition_colour(condition: &armor_model::net::Condition) -> Color32 {
    if condition.operator {
        OPERATOR
    } else if condition.event.is_some() {
        EVENT
    } else if condition.delay_secs.is_some() || condition.at_unix_secs.is_some() {
        TIMED
    } else {
        INK
    }
}

/// The Fit and Enlarge buttons and the legend, on one line above the net.
fn header_ui(ui: &mut Ui, state: &mut NetViewState) {
    ui.horizontal(|ui| {
        if ui
            .button("Fit")
            .on_hover_text(
                "Show the whole net (Home, with the pointer over the net).\n\
                 The wheel zooms, a drag pans, a click selects.",
            )
            .clicked()
        {
            state.fit_pending = true;
            state.fit_whole = true;
        }
        let text = if state.enlarged { "Shrink" } else { "Enlarge" };
        if ui
            .selectable_label(state.enlarged, text)
            .on_hover_text("Give the net most of the window's height, or back")
            .clicked()
        {
            state.enlarged = !state.enlarged;
        }
        // Only where it leaves the legend its room (not in the Run view's narrower column).
        if ui.available_width() > 900.0 {
            ui.weak("wheel: zoom · drag: pan · click: select");
        }
        ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
            // Right to left: the last item is drawn first, so the list is reversed.
            let items: [(&str, Glyph); 7] = [
                ("alternative", Glyph::Alternative),
                ("operator-fired", Glyph::Bar(OPERATOR)),
                ("timed", Glyph::Bar(TIMED)),
                ("event", Glyph::Bar(EVENT)),
                ("immediate", Glyph::Bar(INK)),
                ("marked place", Glyph::Marked),
                ("final place", Glyph::Final),
            ];
            for (text, glyph) in items.iter().rev() {
                // What does not fit beside the buttons is left out, the last entries first.
                let width = ui
                    .painter()
                    .layout_no_wrap(
                        (*text).to_owned(),
                        egui::TextStyle::Body.resolve(ui.style()),
                        Color32::WHITE,
                    )
                    .size()
                    .x;
                if ui.available_width() < width + 16.0 + 2.0 * ui.spacing().item_spacing.x {
                    break;
                }
                ui.label(*text);
                let (rect, _) = ui.allocate_exact_size(vec2(16.0, 16.0), Sense::hover());
                glyph.paint(ui.painter(), rect.center());
            }
        });
    });
}

enum Glyph {
    Bar(Color32),
    Marked,
    Final,
    Alternative,
}

/// A place's outline drawn dashed: a place of an alternative way.
fn dashed_circle(painter: &egui::Painter, at: Pos2, radius: f32, stroke: Stroke) {
    let points: Vec<Pos2> = (0..=32)
        .map(|i| {
            let angle = i as f32 / 32.0 * std::f32::consts::TAU;
            at + vec2(angle.cos(), angle.sin()) * radius
        })
        .collect();
    let dash = (radius * 0.4).max(1.5);
    painter.extend(egui::Shape::dashed_line(&points, stroke, dash, dash * 0.7));
}

impl Glyph {
    fn paint(&self, painter: &egui::Painter, at: Pos2) {
        // On the net's paper, so that the ink reads as it does in the net in a dark theme.
        painter.rect_filled(Rect::from_center_size(at, Vec2::splat(16.0)), 3.0, PAPER);
        match self {
            Glyph::Bar(colour) => {
                painter.rect_filled(Rect::from_center_size(at, vec2(5.0, 14.0)), 1.0, *colour);
            }
            Glyph::Marked => {
                painter.circle(at, 6.5, Color32::WHITE, Stroke::new(1.5, INK));
                painter.circle_filled(at, 2.5, INK);
            }
            Glyph::Final => {
                painter.circle(at, 6.5, Color32::WHITE, Stroke::new(1.5, FINAL));
                painter.circle_stroke(at, 4.0, Stroke::new(1.0, FINAL));
            }
            Glyph::Alternative => {
                painter.circle_filled(at, 6.5, Color32::WHITE);
                dashed_circle(painter, at, 6.5, Stroke::new(1.5, INK));
            }
        }
    }
}

/// Draws the net with its header; returns the element clicked, if any. The wheel zooms about
/// the pointer, a drag on empty space pans, Fit and Home show the whole net.
pub fn net_ui(
    ui: &mut Ui,
    net: &MissionNet,
    layout: &Layout,
    style: &NetStyle,
    state: &mut NetViewState,
) -> Option<String> {
    header_ui(ui, state);
    let (panel, response) = ui.allocate_exact_size(
        ui.available_size().max(vec2(40.0, 40.0)),
        Sense::click_and_drag(),
    );
    // A net too large to be read whole in the panel leaves a column at its right to the
    // overview of the whole net, beside the net rather than over it.
    let needs = layout.size * READABLE_ZOOM + Vec2::splat(2.0 * FIT_SPARE);
    let canvas = if needs.x > panel.width() || needs.y > panel.height() {
        let column = (panel.width() * OVERVIEW_SHARE).clamp(OVERVIEW_MIN_WIDTH, OVERVIEW_MAX_WIDTH);
        Rect::from_min_max(panel.min, pos2(panel.max.x - column, panel.max.y))
    } else {
        panel
    };
    state.panel = panel;
    if canvas != state.canvas {
        state.canvas = canvas;
        if state.fitted {
            state.fit_pending = true;
        }
    }
    let pointer_in = ui.rect_contains_pointer(canvas);
    state.pointer_over = pointer_in;
    if pointer_in {
        // In the Mission view the window takes Home (as Zoom to fit) and hands it here when
        // the pointer is over the net; in the Run view it comes through.
        let (notches, home) = ui.input(|input| {
            let notches: f32 = input
                .events
                .iter()
                .map(|event| match event {
                    egui::Event::MouseWheel { unit, delta, .. } => match unit {
                        egui::MouseWheelUnit::Line => delta.y,
                        egui::MouseWheelUnit::Point => delta.y / 50.0,
                        egui::MouseWheelUnit::Page => delta.y * 10.0,
                    },
                    _ => 0.0,
                })
                .sum();
            (notches, input.key_pressed(egui::Key::Home))
        });
        if notches != 0.0
            && let Some(pointer) = ui.input(|input| input.pointer.hover_pos())
        {
            state.zoom_about(ZOOM_STEP.powf(notches), pointer);
        }
        if home {
            state.fit_pending = true;
            state.fit_whole = true;
        }
    }
    if response.dragged() {
        state.offset += response.drag_delta();
        state.fitted = false;
    }
    if std::mem::take(&mut state.fit_pending) {
        state.fit(layout.size);
    }
    if style.scroll_to_highlight {
        let lit = style
            .highlighted
            .iter()
            .filter_map(|name| layout.nodes.get(name))
            .fold(Rect::NOTHING, |rect, node| {
                rect.union(node.label.union(shape_rect(node.pos, node.is_place)))
            });
        if lit.is_positive() {
            let on_screen = Rect::from_two_pos(
                state.screen_from_layout(lit.min),
                state.screen_from_layout(lit.max),
            );
            if !canvas.contains_rect(on_screen) {
                // Centred where it fits; where it does not, its start (the leg's first place,
                // where the marking enters it) at the canvas's edge rather than both ends cut.
                let along = |lit: (f32, f32), room: (f32, f32)| {
                    if lit.1 - lit.0 <= room.1 - room.0 {
                        (room.0 + room.1 - lit.0 - lit.1) / 2.0
                    } else {
                        room.0 + HIGHLIGHT_MARGIN - lit.0
                    }
                };
                state.offset += vec2(
                    along(
                        (on_screen.min.x, on_screen.max.x),
                        (canvas.min.x, canvas.max.x),
                    ),
                    along(
                        (on_screen.min.y, on_screen.max.y),
                        (canvas.min.y, canvas.max.y),
                    ),
                );
                state.fitted = false;
            }
            // A run's marked places, the tokens the operator watches, are never left out.
            let marked = style
                .marking
                .into_iter()
                .flat_map(|marking| marking.keys())
                .filter_map(|name| layout.nodes.get(name.as_str()))
                .fold(Rect::NOTHING, |rect, node| {
                    rect.union(node.label.union(shape_rect(node.pos, node.is_place)))
                });
            if marked.is_positive() {
                let on_screen = Rect::from_two_pos(
                    state.screen_from_layout(marked.min),
                    state.screen_from_layout(marked.max),
                );
                if !canvas.contains_rect(on_screen) {
                    state.offset += canvas.center() - on_screen.center();
                }
            }
        }
    }

    let painter = ui.painter_at(canvas);
    // Paper, as the map: the net's ink reads the same in a dark or a light theme.
    painter.rect_filled(canvas, 0.0, PAPER);
    let zoom = state.zoom;
    let visible = canvas.expand(LAYER_STEP * zoom);
    let at = |name: &str| {
        layout
            .nodes
            .get(name)
            .map(|node| state.screen_from_layout(node.pos))
    };
    for transition in &net.transitions {
        let Some(t) = at(&transition.name) else {
            continue;
        };
        let lit = style.highlighted.contains(&transition.name);
        let colour = if lit { HIGHLIGHT } else { Color32::GRAY };
        let dashed = style.alternatives.contains(&transition.name);
        for arc in &transition.inputs {
            if let Some(p) = at(&arc.place) {
                arrow(&painter, p, t, colour, visible, zoom, dashed);
            }
        }
        for arc in &transition.outputs {
            if let Some(p) = at(&arc.place) {
                arrow(&painter, t, p, colour, visible, zoom, dashed);
            }
        }
    }
    let marking = style
        .marking
        .cloned()
        .unwrap_or_else(|| net.initial_marking());
    let shown = |name: &str| {
        layout
            .nodes
            .get(name)
            .map_or_else(|| name.to_owned(), |node| node.text.clone())
    };
    let font = egui::FontId::proportional(LABEL_FONT_SIZE * zoom);
    let mut label_boxes = Vec::new();
    let mut clicked = None;
    for place in &net.places {
        let Some(p) = at(&place.name).filter(|p| visible.contains(*p)) else {
            continue;
        };
        let lit = style.highlighted.contains(&place.name);
        let outline = match (lit, place.is_final) {
            (true, _) => HIGHLIGHT,
            (false, true) => FINAL,
            (false, false) => INK,
        };
        let radius = PLACE_RADIUS * zoom;
        let stroke = Stroke::new(2.0 * zoom.min(1.0), outline);
        if style.alternatives.contains(&place.name) {
            painter.circle_filled(p, radius, Color32::WHITE);
            dashed_circle(&painter, p, radius, stroke);
        } else {
            painter.circle(p, radius, Color32::WHITE, stroke);
        }
        if place.is_final {
            painter.circle_stroke(p, radius * 0.72, Stroke::new(1.0, FINAL));
        }
        match marking.get(&place.name).copied().unwrap_or(0) {
            0 => {}
            1 => {
                painter.circle_filled(p, 4.0 * zoom, INK);
            }
            n => {
                painter.text(
                    p,
                    egui::Align2::CENTER_CENTER,
                    n.to_string(),
                    font.clone(),
                    INK,
                );
            }
        }
        label_boxes.push(painter.text(
            p + vec2(0.0, radius + 2.0 * zoom),
            egui::Align2::CENTER_TOP,
            shown(&place.name),
            font.clone(),
            INK,
        ));
        let response = ui.interact(
            Rect::from_center_size(p, Vec2::splat(radius * 2.0).max(Vec2::splat(8.0))),
            ui.id().with(("place", &place.name)),
            Sense::click(),
        );
        // Named for screen readers (and the UI tests), as the text is painted.
        response
            .widget_info(|| egui::WidgetInfo::labeled(egui::WidgetType::Button, true, &place.name));
        if response.on_hover_text(place_tooltip(place)).clicked() {
            clicked = Some(place.name.clone());
        }
    }
    for transition in &net.transitions {
        let Some(t) = at(&transition.name).filter(|t| visible.contains(*t)) else {
            continue;
        };
        let lit = style.highlighted.contains(&transition.name);
        let fill = if lit {
            HIGHLIGHT
        } else {
            transition_colour(&transition.condition)
        };
        let bar = Rect::from_center_size(t, TRANSITION_SIZE * zoom);
        painter.rect_filled(bar, 1.0, fill);
        label_boxes.push(painter.text(
            t - vec2(0.0, (TRANSITION_SIZE.y / 2.0 + 2.0) * zoom),
            egui::Align2::CENTER_BOTTOM,
            shown(&transition.name),
            font.clone(),
            INK,
        ));
        let response = ui.interact(
            bar.expand(4.0),
            ui.id().with(("transition", &transition.name)),
            Sense::click(),
        );
        response.widget_info(|| {
            egui::WidgetInfo::labeled(egui::WidgetType::Button, true, &transition.name)
        });
        if response
            .on_hover_text(transition_tooltip(transition))
            .clicked()
        {
            clicked = Some(transition.name.clone());
        }
    }
    state.label_boxes = label_boxes;
    out_of_view_ui(ui, net, layout, state);
    clicked
}

/// Room left round the overview and between the hints and the canvas's edges.
const OVERVIEW_INSET: f32 = 6.0;
/// The overview's column takes this share of the panel's width, within these bounds.
const OVERVIEW_SHARE: f32 = 0.22;
const OVERVIEW_MIN_WIDTH: f32 = 90.0;
const OVERVIEW_MAX_WIDTH: f32 = 240.0;

/// When part of the net lies beyond the canvas (a net too large to be read whole in its
/// panel), says so at each edge where it is cut ("23 more to the right"), and, in the column
/// left beside the canvas for it, shows the whole net small with the part in view framed: a
/// click or a drag there brings that part into view.
fn out_of_view_ui(ui: &mut Ui, net: &MissionNet, layout: &Layout, state: &mut NetViewState) {
    state.overview = None;
    state.hints.clear();
    let canvas = state.canvas;
    let (mut left, mut right, mut above, mut below) = (0, 0, 0, 0);
    for node in layout.nodes.values() {
        let at = state.screen_from_layout(node.pos);
        left += usize::from(at.x < canvas.min.x);
        right += usize::from(at.x > canvas.max.x);
        above += usize::from(at.y < canvas.min.y);
        below += usize::from(at.y > canvas.max.y);
    }
    let painter = ui.painter_at(state.panel);
    let font = egui::FontId::proportional(LABEL_FONT_SIZE);
    let inset = OVERVIEW_INSET;
    // In words: the font has no arrows pointing up or down.
    let cut = [
        (right, "to the right", egui::Align2::RIGHT_CENTER),
        (left, "to the left", egui::Align2::LEFT_CENTER),
        (below, "below", egui::Align2::CENTER_BOTTOM),
        (above, "above", egui::Align2::CENTER_TOP),
    ];
    let column = Rect::from_min_max(pos2(canvas.max.x, state.panel.min.y), state.panel.max);
    let has_column = column.width() >= 24.0 && layout.size.x > 0.0 && layout.size.y > 0.0;
    let mut hints = Vec::new();
    let mut hint = |text: String, rect: Rect, framed: bool| {
        let galley = painter.layout_no_wrap(text.clone(), font.clone(), INK);
        if framed {
            painter.rect(
                rect,
                3.0,
                PAPER,
                Stroke::new(1.0, INK),
                egui::StrokeKind::Inside,
            );
        }
        painter.galley(rect.min + vec2(3.0, 3.0), galley, INK);
        hints.push((text, rect));
    };
    let measure = |text: &str| {
        painter
            .layout_no_wrap(text.to_owned(), font.clone(), INK)
            .size()
            + Vec2::splat(6.0)
    };
    if !has_column {
        // Zoomed in on a net that fits: the hints stand at the edges where it is cut.
        for (count, side, align) in cut {
            if count == 0 {
                continue;
            }
            let text = format!("{count} more {side}");
            let outward = align.to_sign();
            let at = canvas.center()
                + vec2(
                    outward.x * (canvas.width() / 2.0 - inset),
                    outward.y * (canvas.height() / 2.0 - inset),
                );
            hint(text.clone(), align.anchor_size(at, measure(&text)), true);
        }
        state.hints = hints;
        return;
    }
    // The whole net, small, in the column beside the canvas, the hints under it.
    painter.rect_filled(column, 0.0, PAPER);
    painter.line_segment(
        [column.left_top(), column.left_bottom()],
        Stroke::new(1.0, INK),
    );
    let column = column.shrink(inset);
    let caption = painter.layout_no_wrap("whole net".to_owned(), font.clone(), INK);
    let room = column.size() - vec2(0.0, caption.size().y + 4.0);
    let scale = (room.x / layout.size.x).min(room.y / layout.size.y);
    let rect = Rect::from_min_size(
        column.min + vec2(0.0, caption.size().y + 4.0),
        layout.size * scale,
    );
    painter.galley(column.min, caption, INK);
    painter.rect(
        rect,
        2.0,
        PAPER,
        Stroke::new(1.0, INK),
        egui::StrokeKind::Outside,
    );
    let at = |name: &str| {
        layout
            .nodes
            .get(name)
            .map(|node| rect.min + node.pos.to_vec2() * scale)
    };
    let arc = Stroke::new(0.5, Color32::GRAY);
    for transition in &net.transitions {
        let Some(t) = at(&transition.name) else {
            continue;
        };
        for place in transition.inputs.iter().chain(&transition.outputs) {
            if let Some(p) = at(&place.place) {
                painter.line_segment([p, t], arc);
            }
        }
    }
    for node in layout.nodes.values() {
        let p = rect.min + node.pos.to_vec2() * scale;
        if node.is_place {
            painter.circle_filled(p, 1.5, INK);
        } else {
            painter.rect_filled(Rect::from_center_size(p, vec2(1.0, 3.0)), 0.0, INK);
        }
    }
    let seen = Rect::from_two_pos(
        rect.min + state.layout_from_screen(canvas.min).to_vec2() * scale,
        rect.min + state.layout_from_screen(canvas.max).to_vec2() * scale,
    )
    .intersect(rect);
    if seen.is_positive() {
        painter.rect_stroke(
            seen,
            0.0,
            Stroke::new(1.5, HIGHLIGHT),
            egui::StrokeKind::Inside,
        );
    }
    let mut line_at = pos2(column.min.x, rect.max.y + inset);
    for (count, side, _) in cut {
        if count == 0 {
            continue;
        }
        let text = format!("{count} more {side}");
        let size = measure(&text);
        hint(text, Rect::from_min_size(line_at, size), false);
        line_at.y += size.y;
    }
    state.hints = hints;
    let response = ui
        .interact(rect, ui.id().with("net-overview"), Sense::click_and_drag())
        .on_hover_text("The whole net: click or drag here to see that part of it");
    response.widget_info(|| egui::WidgetInfo::labeled(egui::WidgetType::Button, true, "whole net"));
    if (response.clicked() || response.dragged())
        && let Some(pointer) = response.interact_pointer_pos()
    {
        let wanted = ((pointer - rect.min) / scale).to_pos2();
        state.offset = canvas.center() - canvas.min - wanted.to_vec2() * state.zoom;
        state.fitted = false;
    }
    state.overview = Some((rect, scale));
}

/// An arc from `a` to `b` with its head at the target's edge; arcs going back (to the left)
/// go down, across below the lower of their ends and up, so they do not run over the nodes
/// between.
#[allow(clippy::too_many_arguments)]
fn arrow(
    painter: &egui::Painter,
    a: Pos2,
    b: Pos2,
    colour: Color32,
    visible: Rect,
    zoom: f32,
    dashed: bool,
) {
    if !visible.intersects(Rect::from_two_pos(a, b)) {
        return;
    }
    let stroke = Stroke::new(1.2, colour);
    let line = |points: &[Pos2]| {
        if dashed {
            painter.extend(egui::Shape::dashed_line(points, stroke, 5.0, 3.0));
        } else {
            painter.line(points.to_vec(), stroke);
        }
    };
    let head_at;
    let direction;
    if b.x >= a.x {
        direction = (b - a).normalized();
        head_at = b - direction * (PLACE_RADIUS + 1.0) * zoom;
        line(&[a, head_at]);
    } else {
        // Level below the lower end, so that the way back reads as a loop and not as one
        // more diagonal through the layers between.
        let bottom = a.y.max(b.y) + ROW_STEP * 0.45 * zoom;
        line(&[a, pos2(a.x, bottom), pos2(b.x, bottom), b]);
        direction = vec2(0.0, -1.0);
        head_at = b + vec2(0.0, (PLACE_RADIUS + 1.0) * zoom);
    }
    let head = zoom.clamp(0.5, 1.5);
    let side = direction.rot90() * 3.5 * head;
    let back = head_at - direction * 7.0 * head;
    painter.add(egui::Shape::convex_polygon(
        vec![head_at, back + side, back - side],
        colour,
        Stroke::NONE,
    ));
}

fn place_tooltip(place: &armor_model::net::Place) -> String {
    let mut text = format!("place {}", place.name);
    if !place.modules.is_empty() {
        text += &format!("\nruns: {}", place.modules.join(", "));
    }
    for param in &place.params {
        text += &format!("\n{}.{} = {}", param.module, param.name, param.value);
    }
    if place.is_final {
        text += "\nfinal: the mission ends here";
    }
    text
}

pub fn transition_tooltip(transition: &armor_model::net::Transition) -> String {
    let mut text = format!("transition {}", transition.name);
    let condition = &transition.condition;
    if let Some(event) = &condition.event {
        text += &format!("\nwaits for the event {event}");
    }
    if let Some(delay) = condition.delay_secs {
        text += &format!("\nfires {delay} s after it is enabled");
    }
    if let Some(at) = condition.at_unix_secs {
        text += &format!("\nnot before {}", armor_model::net::format_rfc3339(at));
    }
    if condition.operator {
        text += "\nfired by the operator";
    }
    if condition.is_empty() {
        text += "\nfires as soon as it is enabled";
    }
    text
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_reads_left_to_right_on_one_row_and_a_branch_goes_below() {
        let net = MissionNet::parse(
            r#"<mission name="m" system="s.xml">
                 <place name="a" tokens="1"/><place name="b"/><place name="c" final="true"/>
                 <place name="held"/><place name="orphan"/>
                 <transition name="t1"><input place="a"/><output place="b"/></transition>
                 <transition name="t2"><input place="b"/><output place="c"/></transition>
                 <transition name="stuck"><input place="b"/><output place="held"/></transition>
                 <transition name="retry"><input place="held"/><output place="b"/></transition>
               </mission>"#,
        )
        .unwrap();
        let layout = layout(&net, &|text| vec2(text.len() as f32 * 6.0, 13.0));
        let pos = |name: &str| layout.nodes[name].pos;
        let xs: Vec<f32> = ["a", "t1", "b", "t2", "c"]
            .iter()
            .map(|n| pos(n).x)
            .collect();
        assert!(xs.windows(2).all(|w| w[0] < w[1]), "{xs:?}");
        assert!(
            ["t1", "b", "t2", "c"]
                .iter()
                .all(|n| pos(n).y == pos("a").y)
        );
        assert_eq!(pos("stuck").x, pos("t2").x);
        assert!(pos("stuck").y > pos("t2").y);
        // Nothing reaches it: it still has a place, in the last layer, apart from the others.
        assert!(pos("orphan").x > pos("c").x);
        let distinct: BTreeSet<(i32, i32)> = layout
            .nodes
            .values()
            .map(|n| (n.pos.x as i32, n.pos.y as i32))
            .collect();
        assert_eq!(distinct.len(), layout.nodes.len(), "two nodes at one spot");
        assert!(
            layout
                .nodes
                .values()
                .all(|n| n.pos.x < layout.size.x && n.pos.y < layout.size.y)
        );
    }

    #[test]
    fn the_elements_of_a_leg_show_their_leg_once() {
        let shown = short_names(
            [
                ("advance_drive", (0, 0)),
                ("advance_blocked", (1, 1)),
                ("advance_arrived", (1, 0)),
                ("home", (2, 0)),
                ("cross_", (3, 0)),
                ("cross_hold", (4, 0)),
            ]
            .into_iter(),
        );
        assert_eq!(shown["advance_drive"], "advance_drive");
        assert_eq!(shown["advance_arrived"], "arrived");
        assert_eq!(shown["advance_blocked"], "blocked");
        assert_eq!(shown["home"], "home");
        assert_eq!(shown["cross_"], "cross_");
        assert_eq!(shown["cross_hold"], "hold");
    }
}
