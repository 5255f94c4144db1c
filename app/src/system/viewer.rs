//! The canvas: egui-snarl drawing the diagram. The snarl holds only block ids and positions; the
//! [`DiagramViewer`] is a thin adapter that reads the document to draw blocks and pins and turns
//! what the user does into [`Command`]s, applied after the frame. egui-snarl 0.12 keeps its
//! in-progress wire private and has no "may connect?" hook, so the wire's origin is tracked
//! from egui's pointer state (by `system/canvas.rs`) and the pins drawn last frame, which
//! [`Canvas`] keeps.
//!
//! egui-snarl lays out every node it holds each frame, so it is given only the blocks in view;
//! below [`DETAIL_SCALE`] the diagram is painted as an overview of boxes and lines instead.
//! Wires are drawn above the blocks, with an arrowhead at the pin each enters, rather than
//! routed round them: egui-snarl draws its own curves with no hook for a route, and a router
//! would have to follow every drag. Only a link that runs backwards (into an input left of its
//! output) is drawn round, below the blocks between its ends, in a lane of its own.

use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::rc::Rc;

use egui::emath::TSTransform;
use egui::{Color32, Pos2, Rect, RichText, Stroke, Ui, Vec2};
use egui_snarl::ui::{PinInfo, PinWireInfo, SnarlPin, SnarlStyle, SnarlViewer};
use egui_snarl::{InPin, InPinId, NodeId, OutPin, OutPinId, Snarl};

use crate::common::draw::state_colour;
use crate::common::palette::Catalog;
use crate::system::diagram::{BlockId, Diagram, GROUP_TYPE_PREFIX, Link, Pin, PinSide, PortRef};
use crate::system::editor::Command;
use armor_module_api::Category;
use armor_module_api::describe::is_identifier;
use armor_protocol::ModuleState;

/// Pins drawn this frame, in canvas coordinates.
type PinSink = Rc<RefCell<Vec<(Pin, Rect)>>>;

/// Where a wire may land while one is being dragged.
const LEGAL: Color32 = Color32::from_rgb(60, 200, 90);
const ILLEGAL: Color32 = Color32::from_rgb(90, 90, 90);
const SELECTED: Color32 = Color32::from_rgb(255, 200, 60);
const WARNING: Color32 = Color32::from_rgb(230, 90, 70);

/// Below this zoom, text is too small to read: the diagram is painted as an overview of boxes
/// and wires instead of widgets: blocks are selected and moved there, and linked once zoomed in.
pub const DETAIL_SCALE: f32 = 0.5;
/// The least zoom fit chooses: block names (16 points) over 10 pixels high and port labels (at
/// the body's 12.5 points) about 8, read at first sight (below, they are drawn, but small).
/// Low enough that the bundled robot systems fit whole in a 1280×800 window.
pub const FIT_FLOOR: f32 = 0.65;
/// The size of a block's name in its header, at zoom 1 (the body's text is 12).
const HEADER_NAME_SIZE: f32 = 16.0;
/// The height of the header's band in the overview, in canvas points (about a header's).
const OVERVIEW_BAND: f32 = 34.0;
/// The size of a block's name in the overview, in pixels on screen (drawn where it fits).
const OVERVIEW_NAME_PX: f32 = 12.0;
/// The radius of a port's dot in the overview, in pixels on screen.
const OVERVIEW_PORT_PX: f32 = 2.5;

/// The canvas's state across frames.
pub struct Canvas {
    pub snarl: Snarl<BlockId>,
    node_of: HashMap<BlockId, NodeId>,
    /// The editor revision the snarl was built from.
    synced: Option<u64>,
    /// Canvas to screen, as of the last frame.
    pub to_global: TSTransform,
    /// The screen rectangle of the canvas.
    pub rect: Rect,
    /// Pins and blocks as drawn in the last frame, in canvas coordinates.
    pub pins: Vec<(Pin, Rect)>,
    pub node_rects: HashMap<BlockId, Rect>,
    /// The pin a wire is being dragged from.
    pub wire_from: Option<Pin>,
    /// The document as it was when blocks began to move, for one undo step per drag.
    pub move_before: Option<Diagram>,
    /// A canvas rectangle to show whole on the next frame (zoom to fit, find).
    pub view_request: Option<Rect>,
    /// A transform to take as it is on the next frame (the bench's overview, below the zoom a
    /// fit goes to).
    pub transform_request: Option<TSTransform>,
    /// The snarl's own selection as last seen (shift-click and rectangle selection).
    snarl_selection: Vec<NodeId>,
    /// The block dragged in the overview, where egui-snarl holds none.
    pub overview_grab: Option<BlockId>,
    /// The blocks whose names the overview drew last frame.
    pub overview_names: Vec<String>,
    /// The input pins whose wire's end was marked last frame, and where (canvas coordinates).
    pub wire_ends: Vec<(PortRef, Pos2)>,
    /// Links that run backwards (into an input left of their output), and fallback sources:
    /// egui-snarl does not hold them, as its curve would run across the blocks between and it
    /// draws every wire alike; [`Canvas::paint_routes`] draws them round, below the blocks they
    /// pass, the fallbacks dashed.
    pub routed: BTreeSet<Link>,
    /// The frame (egui's count) the canvas was last drawn in, and its transform when that
    /// frame began: the wheel zooms from it in every pass of the frame.
    pub frame_start: Option<(u64, TSTransform)>,
}

impl Default for Canvas {
    fn default() -> Self {
        Canvas {
            snarl: Snarl::new(),
            node_of: HashMap::new(),
            synced: None,
            to_global: TSTransform::IDENTITY,
            rect: Rect::NOTHING,
            pins: Vec::new(),
            node_rects: HashMap::new(),
            wire_from: None,
            move_before: None,
            view_request: None,
            transform_request: None,
            snarl_selection: Vec::new(),
            overview_grab: None,
            overview_names: Vec::new(),
            wire_ends: Vec::new(),
            routed: BTreeSet::new(),
            frame_start: None,
        }
    }
}

/// The snarl's style: its own selection highlight is hidden, because the editor's selection
/// (which select-all and the problem list can set) is drawn by [`DiagramViewer::node_frame`].
pub fn style() -> SnarlStyle {
    let mut style = SnarlStyle::new();
    style.min_scale = Some(MIN_SCALE);
    style.max_scale = Some(MAX_SCALE);
    style.centering = Some(false);
    style.select_style = Some(egui_snarl::ui::SelectionStyle {
        margin: egui::Margin::ZERO,
        rounding: egui::CornerRadius::ZERO,
        fill: Color32::TRANSPARENT,
        stroke: Stroke::NONE,
    });
    style.pin_size = Some(PIN_SIZE);
    style.wire_width = Some(2.0);
    // Wires above blocks, so that none passes under a block unseen and seems to come out of a
    // pin it does not enter; where each ends is marked over everything by
    // [`Canvas::paint_wire_ends`].
    style.wire_layer = Some(egui_snarl::ui::WireLayer::AboveNodes);
    // Pins on the frame's edge, so that they never cover the end of a label.
    style.pin_placement = Some(egui_snarl::ui::PinPlacement::Edge);
    style
}

impl Canvas {
    /// Keeps the snarl in step with the document and the view. Only the blocks in (or near) the
    /// view are given to egui-snarl, which lays out every node it holds each frame, and every
    /// pin by walking every wire: past a few hundred blocks that is more than a frame's budget.
    /// Below [`DETAIL_SCALE`] no block is given to it: the overview is painted as shapes.
    pub fn sync(&mut self, diagram: &Diagram, catalog: &Catalog, revision: u64) {
        let wanted = self.wanted(diagram, catalog);
        if self.synced != Some(revision) {
            self.synced = Some(revision);
            self.snarl = Snarl::new();
            self.node_of.clear();
            self.routed.clear();
            self.node_rects.retain(|id, _| diagram.block(*id).is_some());
        } else if wanted.len() == self.node_of.len()
            && wanted.iter().all(|id| self.node_of.contains_key(id))
        {
            return;
        }
        let gone: Vec<BlockId> = self
            .node_of
            .keys()
            .filter(|id| !wanted.contains(id))
            .copied()
            .collect();
        for id in gone {
            if let Some(node) = self.node_of.remove(&id) {
                self.snarl.remove_node(node);
            }
        }
        let mut added = BTreeSet::new();
        for id in wanted {
            if self.node_of.contains_key(&id) {
                continue;
            }
            if let Some(block) = diagram.block(id) {
                let node = self
                    .snarl
                    .insert_node(Pos2::new(block.pos[0], block.pos[1]), id);
                self.node_of.insert(id, node);
                added.insert(id);
            }
        }
        for link in diagram.links() {
            if !added.contains(&link.from.block) && !added.contains(&link.to.block) {
                continue;
            }
            let from = self.rect_of(diagram, catalog, link.from.block);
            let to = self.rect_of(diagram, catalog, link.to.block);
            // A fallback is drawn by us too, dashed: egui-snarl draws every wire alike.
            if link.fallback > 0 || to.left() < from.right() + BACK_GAP {
                self.routed.insert(link.clone());
                continue;
            }
            self.routed.remove(link);
            let (Some(from), Some(to)) = (
                self.pin_id(diagram, catalog, &link.from, PinSide::Output),
                self.pin_id(diagram, catalog, &link.to, PinSide::Input),
            ) else {
                continue;
            };
            self.snarl.connect(
                OutPinId {
                    node: from.0,
                    output: from.1,
                },
                InPinId {
                    node: to.0,
                    input: to.1,
                },
            );
        }
    }

    /// Whether the view is zoomed out past the point where blocks are drawn as widgets.
    pub fn is_overview(&self) -> bool {
        self.to_global.scaling < DETAIL_SCALE
    }

    /// The part of the canvas on screen, in canvas coordinates.
    pub fn viewport(&self) -> Rect {
        self.to_global.inverse() * self.rect
    }

    fn wanted(&self, diagram: &Diagram, catalog: &Catalog) -> BTreeSet<BlockId> {
        if self.is_overview() || !self.rect.is_finite() {
            return BTreeSet::new();
        }
        // A margin, so that a block being dragged in from the edge is already there.
        let view = self.viewport().expand(300.0);
        diagram
            .blocks()
            .filter(|(id, _)| view.intersects(self.rect_of(diagram, catalog, *id)))
            .map(|(id, _)| id)
            .collect()
    }

    /// A block's rectangle: as drawn last time, else as it will roughly be.
    pub fn rect_of(&self, diagram: &Diagram, catalog: &Catalog, id: BlockId) -> Rect {
        let Some(block) = diagram.block(id) else {
            return Rect::NOTHING;
        };
        let pos = Pos2::new(block.pos[0], block.pos[1]);
        match self.node_rects.get(&id) {
            Some(rect) => Rect::from_min_size(pos, rect.size()),
            None => {
                let rows = catalog.get(&block.module_type).map_or(0, |description| {
                    description.inputs.len().max(description.outputs.len())
                });
                Rect::from_min_size(pos, Vec2::new(200.0, 44.0 + 20.0 * rows as f32))
            }
        }
    }

    fn pin_id(
        &self,
        diagram: &Diagram,
        catalog: &Catalog,
        port: &PortRef,
        side: PinSide,
    ) -> Option<(NodeId, usize)> {
        let node = *self.node_of.get(&port.block)?;
        let block = diagram.block(port.block)?;
        let description = catalog.get(&block.module_type)?;
        let ports = match side {
            PinSide::Input => &description.inputs,
            PinSide::Output => &description.outputs,
        };
        let index = ports.iter().position(|spec| spec.name == port.port)?;
        Some((node, index))
    }

    /// Screen to canvas coordinates.
    pub fn to_canvas(&self, screen: Pos2) -> Pos2 {
        self.to_global.inverse() * screen
    }

    /// The pin drawn under a screen position last frame.
    pub fn pin_at(&self, screen: Pos2) -> Option<&Pin> {
        let pos = self.to_canvas(screen);
        self.pins
            .iter()
            .find(|(_, rect)| rect.expand(3.0).contains(pos))
            .map(|(pin, _)| pin)
    }

    /// The screen position of a pin, as drawn last frame.
    pub fn pin_screen_pos(&self, pin: &Pin) -> Option<Pos2> {
        self.pins
            .iter()
            .find(|(drawn, _)| drawn == pin)
            .map(|(_, rect)| self.to_global * rect.center())
    }

    /// The block under a screen position (the top one).
    pub fn block_at(&self, diagram: &Diagram, catalog: &Catalog, screen: Pos2) -> Option<BlockId> {
        let pos = self.to_canvas(screen);
        diagram
            .blocks()
            .filter(|(id, _)| self.rect_of(diagram, catalog, *id).contains(pos))
            .map(|(id, _)| id)
            .max()
    }

    /// The bounding box of the blocks (and of the links routed round them, for the whole diagram),
    /// in canvas coordinates.
    pub fn bounds(&self, diagram: &Diagram, only: Option<&BTreeSet<BlockId>>) -> Option<Rect> {
        let mut bounds = Rect::NOTHING;
        for (id, block) in diagram.blocks() {
            if only.is_some_and(|only| !only.contains(&id)) {
                continue;
            }
            // Where the document puts the block (it may have just moved: Arrange, undo), as
            // large as it was last drawn.
            let size = self
                .node_rects
                .get(&id)
                .map_or(Vec2::new(200.0, 100.0), |rect| rect.size());
            let rect = Rect::from_min_size(Pos2::new(block.pos[0], block.pos[1]), size);
            bounds = bounds.union(rect);
        }
        if only.is_none() && !self.routed.is_empty() {
            // The routed links run round the blocks, each in its lane: the whole diagram is
            // theirs too.
            let reach =
                ROUTE_STUB + ROUTE_LANE * self.routed.len() as f32 + ARROW_LENGTH + PIN_SIZE;
            bounds = Rect::from_min_max(
                bounds.min - Vec2::new(reach, 0.0),
                bounds.max + Vec2::splat(reach),
            );
        }
        bounds.is_finite().then_some(bounds)
    }

    /// Blocks moved by the user this frame: their new positions.
    pub fn moved_blocks(&self, diagram: &Diagram) -> Vec<(BlockId, [f32; 2])> {
        self.snarl
            .nodes_pos_ids()
            .filter_map(|(_, pos, id)| {
                let block = diagram.block(*id)?;
                (block.pos != [pos.x, pos.y]).then_some((*id, [pos.x, pos.y]))
            })
            .collect()
    }

    /// Puts the snarl's nodes of `blocks` at the given positions (those on screen; the others
    /// are drawn from the document when they come into view).
    pub fn place_nodes(&mut self, blocks: &[(BlockId, [f32; 2])]) {
        for (id, pos) in blocks {
            if let Some(node) = self.node_of.get(id)
                && let Some(info) = self.snarl.get_node_info_mut(*node)
            {
                info.pos = Pos2::new(pos[0], pos[1]);
            }
        }
    }

    /// Marks where each wire ends, over the blocks and the wires: an arrowhead in the wire's
    /// colour, outlined, pointing into the input pin the wire enters. Wires are drawn above
    /// blocks (egui-snarl's `WireLayer::AboveNodes`), so a wire that crosses a block is seen
    /// crossing it; the arrowhead says which pin it ends at, so that a wire passing close to
    /// another pin cannot be taken for entering it. Only the pins egui-snarl drew this frame
    /// (the blocks in view) are marked. `painter` paints on the canvas's layer, in canvas
    /// coordinates.
    pub fn paint_wire_ends(
        &mut self,
        diagram: &Diagram,
        catalog: &Catalog,
        painter: &egui::Painter,
    ) {
        self.wire_ends.clear();
        if self.is_overview() {
            return;
        }
        let drawn: HashMap<(BlockId, &str), Rect> = self
            .pins
            .iter()
            .filter(|(pin, _)| pin.side == PinSide::Input)
            .map(|(pin, rect)| ((pin.port.block, pin.port.port.as_str()), *rect))
            .collect();
        for link in diagram.links() {
            let Some(rect) = drawn.get(&(link.to.block, link.to.port.as_str())) else {
                continue;
            };
            let colour = diagram
                .block(link.from.block)
                .and_then(|block| catalog.get(&block.module_type))
                .and_then(|description| description.output(&link.from.port))
                .map_or(Color32::GRAY, |spec| type_colour(&spec.data_type));
            let tip = Pos2::new(rect.left(), rect.center().y);
            paint_arrowhead(painter, tip, colour);
            self.wire_ends.push((link.to.clone(), tip));
        }
    }

    /// The links egui-snarl does not hold because they run backwards (`routed`), as drawn: out
    /// of the output to the right, down below every block between the two ends, left, and up
    /// into the input from its left, so that no part runs under or across a block between.
    /// Only those whose both pins were drawn this frame (the others are the overview's lines);
    /// points in canvas coordinates.
    pub fn routes(&self, diagram: &Diagram, catalog: &Catalog) -> Vec<(Link, Vec<Pos2>)> {
        if self.is_overview() || self.routed.is_empty() {
            return Vec::new();
        }
        let drawn: HashMap<(PinSide, &PortRef), Pos2> = self
            .pins
            .iter()
            .map(|(pin, rect)| ((pin.side, &pin.port), rect.center()))
            .collect();
        let pin = |port: &PortRef, side: PinSide| drawn.get(&(side, port)).copied();
        // Measured once for every route (a large diagram has many blocks to pass below).
        let blocks: Vec<Rect> = diagram
            .blocks()
            .map(|(id, _)| self.rect_of(diagram, catalog, id))
            .collect();
        let mut ends: Vec<(&Link, Pos2, Pos2)> = self
            .routed
            .iter()
            .filter_map(|link| {
                let from = pin(&link.from, PinSide::Output)?;
                let to = pin(&link.to, PinSide::Input)?;
                Some((link, from, to))
            })
            .collect();
        // Each route in a lane of its own, so that two never share a line: the lowest input
        // innermost, so that the routes into one block nest without crossing.
        ends.sort_by(|a, b| b.2.y.total_cmp(&a.2.y));
        let mut routes = Vec::new();
        for (lane, (link, from, to)) in ends.into_iter().enumerate() {
            let offset = ROUTE_LANE * lane as f32;
            let right = from.x + ROUTE_STUB + offset;
            // Clear of the arrowhead, whose tip is at the pin's edge (half the pin's size in).
            let left = to.x - PIN_SIZE / 2.0 - ARROW_LENGTH - ROUTE_STUB / 2.0 - offset;
            let (low, high) = (left.min(right), left.max(right));
            let below = blocks
                .iter()
                .filter(|rect| rect.right() >= low && rect.left() <= high)
                .map(|rect| rect.bottom())
                .fold(from.y.max(to.y), f32::max)
                + ROUTE_STUB
                + offset;
            let points = vec![
                from,
                Pos2::new(right, from.y),
                Pos2::new(right, below),
                Pos2::new(left, below),
                Pos2::new(left, to.y),
                to,
            ];
            routes.push((link.clone(), points));
        }
        routes
    }

    /// Draws [`Canvas::routes`] in their wires' colours, fallback sources dashed.
    pub fn paint_routes(&self, diagram: &Diagram, catalog: &Catalog, painter: &egui::Painter) {
        for (link, points) in self.routes(diagram, catalog) {
            let colour = diagram
                .block(link.from.block)
                .and_then(|block| catalog.get(&block.module_type))
                .and_then(|description| description.output(&link.from.port))
                .map_or(Color32::GRAY, |spec| type_colour(&spec.data_type));
            let stroke = Stroke::new(2.0, colour);
            if link.fallback > 0 {
                painter.extend(egui::Shape::dashed_line(&points, stroke, 8.0, 5.0));
            } else {
                painter.add(egui::Shape::line(points, stroke));
            }
        }
    }

    /// The blocks of the snarl's own selection, when it changed since last asked.
    pub fn snarl_selection_change(&mut self, selected: Vec<NodeId>) -> Option<BTreeSet<BlockId>> {
        if selected == self.snarl_selection {
            return None;
        }
        self.snarl_selection = selected;
        Some(
            self.snarl_selection
                .iter()
                .filter_map(|node| self.snarl.get_node(*node).copied())
                .collect(),
        )
    }
}

/// What a frame of the canvas reports back besides commands.
#[derive(Default)]
pub struct CanvasEvents {
    /// A block was double-clicked (or "Parameters…" chosen in its menu).
    pub open_params: Option<BlockId>,
    /// The blocks whose names the overview drew this frame.
    pub overview_names: Vec<String>,
}

/// The adapter egui-snarl calls to draw and edit the diagram.
pub struct DiagramViewer<'a> {
    pub diagram: &'a Diagram,
    pub catalog: &'a Catalog,
    pub selection: &'a BTreeSet<BlockId>,
    /// Blocks that have a problem in the validation panel.
    pub flagged: &'a BTreeSet<BlockId>,
    pub commands: &'a mut Vec<Command>,
    pub events: &'a mut CanvasEvents,
    pub wire_from: Option<&'a Pin>,
    pub pins: PinSink,
    pub node_rects: &'a mut HashMap<BlockId, Rect>,
    /// The canvas transform: read by snarl, overridden to show `view_request`.
    pub to_global: &'a mut TSTransform,
    pub view_request: Option<Rect>,
    pub transform_request: Option<TSTransform>,
    pub screen_rect: Rect,
    /// Where a double click happened this frame, on screen.
    pub double_click: Option<Pos2>,
    /// The canvas's state: which blocks egui-snarl holds, where the others are.
    pub canvas: &'a Canvas,
    /// During a run, each module's state: blocks and the links they feed are coloured by it.
    pub live: &'a BTreeMap<String, ModuleState>,
    /// The wheel's zoom this frame, which replaces egui-snarl's own handling of the wheel.
    pub wheel: Option<WheelZoom>,
    /// Shift is held: a wire dropped into an input that has a source becomes a fallback.
    pub shift: bool,
}

/// A zoom by the wheel: `factor` about the screen point `about`, from the transform `from` of
/// the last frame.
#[derive(Clone, Copy, Debug)]
pub struct WheelZoom {
    pub factor: f32,
    pub about: Pos2,
    pub from: TSTransform,
}

impl WheelZoom {
    /// The transform after the zoom: the canvas point under `about` stays under it, and the
    /// zoom stays within the canvas's range.
    pub fn apply(&self) -> TSTransform {
        let scale = (self.from.scaling * self.factor).clamp(MIN_SCALE, MAX_SCALE);
        let under = self.from.inverse() * self.about;
        TSTransform::new(self.about.to_vec2() - under.to_vec2() * scale, scale)
    }
}

/// One notch of the wheel zooms by this factor (as in the net view).
pub const ZOOM_STEP: f32 = 1.1;
/// The canvas's zoom range.
const MIN_SCALE: f32 = 0.05;
const MAX_SCALE: f32 = 2.0;

/// How many notches a wheel event turns, up positive (zoom in).
pub fn wheel_notches(unit: egui::MouseWheelUnit, delta: Vec2) -> f32 {
    match unit {
        egui::MouseWheelUnit::Line => delta.y,
        egui::MouseWheelUnit::Point => delta.y / 50.0,
        egui::MouseWheelUnit::Page => delta.y * 10.0,
    }
}

impl DiagramViewer<'_> {
    fn pin(
        &self,
        snarl: &Snarl<BlockId>,
        node: NodeId,
        index: usize,
        side: PinSide,
    ) -> Option<Pin> {
        let id = *snarl.get_node(node)?;
        let block = self.diagram.block(id)?;
        let description = self.catalog.get(&block.module_type)?;
        let ports = match side {
            PinSide::Input => &description.inputs,
            PinSide::Output => &description.outputs,
        };
        Some(Pin {
            side,
            port: PortRef {
                block: id,
                port: ports.get(index)?.name.clone(),
            },
        })
    }

    fn pin_ui(&mut self, pin: Option<Pin>, ui: &mut Ui) -> TrackedPin {
        let Some(pin) = pin else {
            return TrackedPin {
                info: PinInfo::circle(),
                pin: None,
                sink: self.pins.clone(),
            };
        };
        let data_type = self
            .diagram
            .block(pin.port.block)
            .and_then(|block| self.catalog.get(&block.module_type))
            .and_then(|description| match pin.side {
                PinSide::Input => description.input(&pin.port.port),
                PinSide::Output => description.output(&pin.port.port),
            })
            .map(|spec| (spec.data_type.clone(), spec.doc.clone()))
            .unwrap_or_default();
        let live = self
            .diagram
            .block(pin.port.block)
            .and_then(|block| self.live.get(&block.name))
            .filter(|state| pin.side == PinSide::Output && **state != ModuleState::Running);
        let colour = live.map_or_else(|| type_colour(&data_type.0), |state| state_colour(*state));
        let mut info = PinInfo::circle().with_fill(colour).with_wire_color(colour);
        if let Some(from) = self.wire_from
            && from != &pin
        {
            let legal = self.diagram.link_between(self.catalog, from, &pin).is_ok();
            info = info
                .with_fill(if legal { LEGAL } else { ILLEGAL })
                .with_stroke(Stroke::new(
                    if legal { 2.0 } else { 1.0 },
                    if legal { Color32::WHITE } else { ILLEGAL },
                ));
        }
        let text = format!("{}: {}", pin.port.port, data_type.0);
        // At the body's size, not small: at the least zoom fit chooses it is still about 9
        // pixels high.
        ui.add(egui::Label::new(text).extend())
            .on_hover_text(data_type.1);
        TrackedPin {
            info,
            pin: Some(pin),
            sink: self.pins.clone(),
        }
    }
}

impl DiagramViewer<'_> {
    /// Paints what egui-snarl does not hold: the blocks of the overview (each with its name
    /// where it fits and its ports), and the links with an end outside the view (egui-snarl draws
    /// only links between blocks it holds). Returns the names the overview drew.
    fn paint_outside_snarl(
        &self,
        viewport: &Rect,
        style: &egui::Style,
        painter: &egui::Painter,
    ) -> Vec<String> {
        let canvas = self.canvas;
        let held = |id: &BlockId| canvas.node_of.contains_key(id);
        let overview = canvas.is_overview();
        let mut names = Vec::new();
        if overview {
            let visuals = &style.visuals;
            let fill = visuals.widgets.inactive.bg_fill;
            let stroke = visuals.widgets.noninteractive.bg_stroke;
            for (id, _) in self.diagram.blocks() {
                let rect = canvas.rect_of(self.diagram, self.catalog, id);
                if !viewport.intersects(rect) {
                    continue;
                }
                let live = self
                    .diagram
                    .block(id)
                    .and_then(|block| self.live.get(&block.name));
                let stroke = if self.selection.contains(&id) {
                    Stroke::new(3.0 / canvas.to_global.scaling, SELECTED)
                } else if let Some(state) = live {
                    Stroke::new(3.0 / canvas.to_global.scaling, state_colour(*state))
                } else if self.flagged.contains(&id) {
                    Stroke::new(2.0 / canvas.to_global.scaling, WARNING)
                } else {
                    stroke
                };
                painter.rect(rect, 6.0, fill, stroke, egui::StrokeKind::Inside);
                // The header's band in the category's colour, as the block has it zoomed in.
                let category = self.diagram.block(id).map_or(Category::Other, |block| {
                    category_of(self.catalog, &block.module_type)
                });
                let band = Rect::from_min_size(
                    rect.min,
                    Vec2::new(rect.width(), rect.height().min(OVERVIEW_BAND)),
                );
                painter.rect_filled(
                    band.shrink(stroke.width),
                    egui::CornerRadius {
                        nw: 6,
                        ne: 6,
                        sw: 0,
                        se: 0,
                    },
                    category_colour(category),
                );
                if let Some(block) = self.diagram.block(id) {
                    self.paint_overview_block(block, rect, style, painter, &mut names);
                }
            }
        }
        let drawn: HashMap<(BlockId, PinSide, &str), Pos2> = canvas
            .pins
            .iter()
            .map(|(pin, rect)| {
                (
                    (pin.port.block, pin.side, pin.port.port.as_str()),
                    rect.center(),
                )
            })
            .collect();
        let pin_pos = |port: &PortRef, side: PinSide| -> Option<Pos2> {
            if held(&port.block)
                && let Some(pos) = drawn.get(&(port.block, side, port.port.as_str()))
            {
                return Some(*pos);
            }
            let block = self.diagram.block(port.block)?;
            let description = self.catalog.get(&block.module_type)?;
            let ports = match side {
                PinSide::Input => &description.inputs,
                PinSide::Output => &description.outputs,
            };
            let index = ports.iter().position(|spec| spec.name == port.port)?;
            let rect = canvas.rect_of(self.diagram, self.catalog, port.block);
            let x = if side == PinSide::Input {
                rect.left()
            } else {
                rect.right()
            };
            Some(Pos2::new(x, rect.top() + 36.0 + 20.0 * index as f32))
        };
        let width = if overview {
            1.0 / canvas.to_global.scaling
        } else {
            2.0
        };
        for link in self.diagram.links() {
            if held(&link.from.block) && held(&link.to.block) {
                continue;
            }
            let (Some(from), Some(to)) = (
                pin_pos(&link.from, PinSide::Output),
                pin_pos(&link.to, PinSide::Input),
            ) else {
                continue;
            };
            if !viewport.intersects(Rect::from_two_pos(from, to)) {
                continue;
            }
            let colour = self
                .diagram
                .block(link.from.block)
                .and_then(|block| self.catalog.get(&block.module_type))
                .and_then(|description| description.output(&link.from.port))
                .map_or(Color32::GRAY, |spec| type_colour(&spec.data_type));
            painter.line_segment([from, to], Stroke::new(width, colour));
            if !overview {
                paint_arrowhead(painter, to, colour);
            }
        }
        names
    }

    /// A block of the overview: its name in the body where it fits at a readable size on
    /// screen, and a dot for each port, at the edge where its pin is zoomed in.
    fn paint_overview_block(
        &self,
        block: &crate::system::diagram::Block,
        rect: Rect,
        style: &egui::Style,
        painter: &egui::Painter,
        names: &mut Vec<String>,
    ) {
        let scale = self.canvas.to_global.scaling;
        if let Some(description) = self.catalog.get(&block.module_type) {
            let radius = OVERVIEW_PORT_PX / scale;
            for (ports, x) in [
                (&description.inputs, rect.left()),
                (&description.outputs, rect.right()),
            ] {
                for (index, port) in ports.iter().enumerate() {
                    let y = rect.top() + 36.0 + 20.0 * index as f32;
                    if y + radius > rect.bottom() {
                        break;
                    }
                    painter.circle_filled(Pos2::new(x, y), radius, type_colour(&port.data_type));
                }
            }
        }
        let galley = painter.layout_no_wrap(
            block.name.clone(),
            egui::FontId::proportional(OVERVIEW_NAME_PX / scale),
            style.visuals.strong_text_color(),
        );
        let room = rect.shrink(2.0 / scale);
        if galley.size().x <= room.width() && galley.size().y <= room.height() {
            let at = room.center() - galley.size() / 2.0;
            painter.galley(at, galley, style.visuals.strong_text_color());
            names.push(block.name.clone());
        }
    }
}

impl SnarlViewer<BlockId> for DiagramViewer<'_> {
    fn title(&mut self, node: &BlockId) -> String {
        self.diagram
            .block(*node)
            .map(|block| block.name.clone())
            .unwrap_or_default()
    }

    fn show_header(
        &mut self,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<BlockId>,
    ) {
        let Some(block) = self.diagram.block(snarl[node]) else {
            return;
        };
        // egui-snarl sizes a node by its header and clips the pin labels to that width: make
        // the header wide enough for the longest input and output labels side by side.
        if let Some(description) = self.catalog.get(&block.module_type) {
            let longest = |ports: &[armor_module_api::describe::PortSpec]| {
                ports
                    .iter()
                    .map(|p| p.name.len() + p.data_type.len() + 2)
                    .max()
                    .unwrap_or(0)
            };
            let chars = longest(&description.inputs) + longest(&description.outputs);
            ui.set_min_width(chars as f32 * 6.8 + 36.0);
        }
        // The instance's name large; its type small, only where the name does not say it.
        ui.vertical(|ui| {
            ui.spacing_mut().item_spacing.y = 0.0;
            // Never wrapped: the block is as wide as its name.
            ui.add(
                egui::Label::new(
                    RichText::new(&block.name)
                        .size(HEADER_NAME_SIZE)
                        .strong()
                        .color(HEADER_TEXT),
                )
                // A double click on it opens the block, it does not select a word.
                .selectable(false)
                .extend(),
            );
            let module_type = if block.module_type.starts_with(GROUP_TYPE_PREFIX) {
                Some("subsystem · double-click to open")
            } else if block
                .module_type
                .starts_with(crate::system::diagram::BORDER_TYPE_PREFIX)
            {
                Some("the subsystem's border")
            } else {
                (block.module_type != block.name).then_some(block.module_type.as_str())
            };
            if let Some(module_type) = module_type {
                // At the pins' size: small text is unreadable at the zoom a fit chooses.
                ui.add(
                    egui::Label::new(RichText::new(module_type).color(HEADER_TEXT_WEAK)).extend(),
                );
            }
            // During a run, the module's state in its colour, on a dark ground so that it reads
            // on every header colour; at the body's size, as the port labels.
            if let Some(state) = self.live.get(&block.name) {
                ui.label(
                    RichText::new(format!(" {} ", state.as_str()))
                        .color(state_colour(*state))
                        .background_color(Color32::from_black_alpha(190)),
                );
            }
        });
    }

    fn inputs(&mut self, node: &BlockId) -> usize {
        self.diagram
            .block(*node)
            .and_then(|block| self.catalog.get(&block.module_type))
            .map_or(0, |description| description.inputs.len())
    }

    fn outputs(&mut self, node: &BlockId) -> usize {
        self.diagram
            .block(*node)
            .and_then(|block| self.catalog.get(&block.module_type))
            .map_or(0, |description| description.outputs.len())
    }

    fn show_input(
        &mut self,
        pin: &InPin,
        ui: &mut Ui,
        snarl: &mut Snarl<BlockId>,
    ) -> impl SnarlPin + 'static {
        let found = self.pin(snarl, pin.id.node, pin.id.input, PinSide::Input);
        self.pin_ui(found, ui)
    }

    fn show_output(
        &mut self,
        pin: &OutPin,
        ui: &mut Ui,
        snarl: &mut Snarl<BlockId>,
    ) -> impl SnarlPin + 'static {
        let found = self.pin(snarl, pin.id.node, pin.id.output, PinSide::Output);
        self.pin_ui(found, ui)
    }

    fn has_body(&mut self, _node: &BlockId) -> bool {
        true
    }

    fn show_body(
        &mut self,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<BlockId>,
    ) {
        let id = snarl[node];
        let Some(block) = self.diagram.block(id) else {
            return;
        };
        if !self.catalog.contains_key(&block.module_type) {
            ui.colored_label(WARNING, "unknown type");
            return;
        }
        let missing = self.diagram.missing_required(self.catalog, id).len();
        if missing > 0 {
            ui.colored_label(WARNING, format!("{missing} required unset"));
        }
    }

    fn header_frame(
        &mut self,
        default: egui::Frame,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        snarl: &Snarl<BlockId>,
    ) -> egui::Frame {
        let category = self
            .diagram
            .block(snarl[node])
            .map_or(Category::Other, |block| {
                category_of(self.catalog, &block.module_type)
            });
        let radius = default.corner_radius;
        default
            .fill(category_colour(category))
            .stroke(Stroke::NONE)
            .corner_radius(egui::CornerRadius {
                sw: 0,
                se: 0,
                ..radius
            })
    }

    fn node_frame(
        &mut self,
        default: egui::Frame,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        snarl: &Snarl<BlockId>,
    ) -> egui::Frame {
        let id = snarl[node];
        let live = self
            .diagram
            .block(id)
            .and_then(|block| self.live.get(&block.name));
        // Flat, as Node-RED's: a block's shadow would darken the coloured header of a block
        // below it, by an amount that depends on which is drawn first.
        let default = default.shadow(egui::Shadow::NONE);
        if self.selection.contains(&id) {
            default.stroke(Stroke::new(2.5, SELECTED))
        } else if let Some(state) = live {
            default.stroke(Stroke::new(2.5, state_colour(*state)))
        } else if self.flagged.contains(&id) {
            default.stroke(Stroke::new(1.5, WARNING))
        } else {
            default
        }
    }

    fn final_node_rect(
        &mut self,
        node: NodeId,
        rect: Rect,
        ui: &mut Ui,
        snarl: &mut Snarl<BlockId>,
    ) {
        let id = snarl[node];
        self.node_rects.insert(id, rect);
        if let Some(at) = self.double_click
            && rect.contains(self.to_global.inverse() * at)
            && ui.is_enabled()
        {
            self.events.open_params = Some(id);
        }
    }

    fn has_node_menu(&mut self, _node: &BlockId) -> bool {
        true
    }

    fn show_node_menu(
        &mut self,
        node: NodeId,
        _inputs: &[InPin],
        _outputs: &[OutPin],
        ui: &mut Ui,
        snarl: &mut Snarl<BlockId>,
    ) {
        let id = snarl[node];
        if crate::system::diagram::border_of(id).is_some() {
            ui.label("the subsystem's border: its ports, linked inside");
            return;
        }
        let group = self
            .diagram
            .block(id)
            .is_some_and(|block| block.module_type.starts_with(GROUP_TYPE_PREFIX));
        if group {
            if ui.button("Open").clicked() {
                self.commands.push(Command::Open(Some(id)));
                ui.close();
            }
            if ui.button("Ungroup").clicked() {
                self.commands.push(Command::Select([id].into()));
                self.commands.push(Command::Ungroup);
                ui.close();
            }
        } else if ui.button("Parameters…").clicked() {
            self.events.open_params = Some(id);
            ui.close();
        }
        if ui.button("Duplicate").clicked() {
            self.commands.push(Command::Select([id].into()));
            self.commands.push(Command::Duplicate);
            ui.close();
        }
        if ui.button("Delete").clicked() {
            self.commands.push(Command::Select([id].into()));
            self.commands.push(Command::DeleteSelection);
            ui.close();
        }
    }

    fn has_graph_menu(&mut self, _pos: Pos2, _snarl: &mut Snarl<BlockId>) -> bool {
        !self.catalog.is_empty()
    }

    fn show_graph_menu(&mut self, pos: Pos2, ui: &mut Ui, _snarl: &mut Snarl<BlockId>) {
        ui.label("Add a block");
        // Not a group's made-up type (`subsystem NAME`): only module types.
        for module_type in self.catalog.keys().filter(|key| is_identifier(key)) {
            if ui.button(module_type).clicked() {
                self.commands.push(Command::AddBlock {
                    module_type: module_type.clone(),
                    pos: [pos.x, pos.y],
                });
                ui.close();
            }
        }
    }

    fn connect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<BlockId>) {
        // Not connected in the snarl here: the command is checked and applied to the document,
        // and the snarl is rebuilt from it.
        if let (Some(from), Some(to)) = (
            self.pin(snarl, from.id.node, from.id.output, PinSide::Output),
            self.pin(snarl, to.id.node, to.id.input, PinSide::Input),
        ) {
            self.commands.push(Command::Connect {
                from,
                to,
                fallback: self.shift,
            });
        }
    }

    fn disconnect(&mut self, from: &OutPin, to: &InPin, snarl: &mut Snarl<BlockId>) {
        if let (Some(from), Some(to)) = (
            self.pin(snarl, from.id.node, from.id.output, PinSide::Output),
            self.pin(snarl, to.id.node, to.id.input, PinSide::Input),
        ) {
            self.commands
                .push(Command::RemoveLink(crate::system::diagram::Link {
                    from: from.port,
                    to: to.port,
                    fallback: 0,
                }));
        }
    }

    fn drop_outputs(&mut self, pin: &OutPin, snarl: &mut Snarl<BlockId>) {
        if let Some(pin) = self.pin(snarl, pin.id.node, pin.id.output, PinSide::Output) {
            self.commands.push(Command::DisconnectOutput(pin.port));
        }
    }

    fn drop_inputs(&mut self, pin: &InPin, snarl: &mut Snarl<BlockId>) {
        if let Some(pin) = self.pin(snarl, pin.id.node, pin.id.input, PinSide::Input) {
            self.commands.push(Command::DisconnectInput(pin.port));
        }
    }

    fn draw_background(
        &mut self,
        background: Option<&egui_snarl::ui::BackgroundPattern>,
        viewport: &Rect,
        snarl_style: &SnarlStyle,
        style: &egui::Style,
        painter: &egui::Painter,
        _snarl: &Snarl<BlockId>,
    ) {
        if let Some(background) = background {
            background.draw(viewport, snarl_style, style, painter);
        }
        self.events.overview_names = self.paint_outside_snarl(viewport, style, painter);
    }

    fn current_transform(&mut self, to_global: &mut TSTransform, _snarl: &mut Snarl<BlockId>) {
        if let Some(transform) = self.transform_request.take() {
            *to_global = transform;
        } else if let Some(view) = self.view_request.take() {
            *to_global = fit(view, self.screen_rect);
        } else if let Some(wheel) = self.wheel {
            *to_global = wheel.apply();
        }
        *self.to_global = *to_global;
    }
}

/// The transform that shows `view` (canvas) centred in `screen`, whole if it can be at a zoom
/// between [`FIT_FLOOR`] and 1:1. Never below the zoom at which names read: a first sight of
/// nameless boxes, or of names too small to read, tells a newcomer nothing, so a large diagram
/// shows its middle, named, and the rest is a zoom or pan away.
pub fn fit(view: Rect, screen: Rect) -> TSTransform {
    let scale_of = |view: Rect| {
        (screen.width() / view.width())
            .min(screen.height() / view.height())
            .clamp(FIT_FLOOR, 1.0)
    };
    // A margin round the diagram, but not at the price of cutting a block off at the floor.
    let margin = if scale_of(view.expand(40.0)) > FIT_FLOOR {
        40.0
    } else {
        8.0
    };
    let view = view.expand(margin);
    let scale = scale_of(view);
    let scale = if scale.is_finite() { scale } else { 1.0 };
    TSTransform::new(
        screen.center().to_vec2() - view.center().to_vec2() * scale,
        scale,
    )
}

/// The header colour of a block of a module `category`, and the text colour on it. Mid-dark,
/// moderately saturated fills: they stand out from the dark theme's grey canvas and blocks,
/// white text on each has a contrast of at least 4.5:1 (WCAG AA; checked by a test), and the
/// hues are far apart (green, blue, violet, amber, crimson) so that roles are told apart at a
/// glance, as Node-RED colours its palette's groups. Unknown and absent categories are grey.
pub fn category_colour(category: Category) -> Color32 {
    match category {
        Category::Sensor => Color32::from_rgb(34, 118, 84),
        Category::Navigation => Color32::from_rgb(44, 92, 168),
        Category::Mapping => Color32::from_rgb(118, 70, 160),
        Category::Operator => Color32::from_rgb(156, 80, 20),
        Category::Recording => Color32::from_rgb(160, 50, 66),
        Category::Other => Color32::from_rgb(78, 82, 90),
    }
}

/// The text on a [`category_colour`].
pub const HEADER_TEXT: Color32 = Color32::WHITE;
/// The smaller, secondary text on a [`category_colour`] (the type): still 4.5:1 on each.
pub const HEADER_TEXT_WEAK: Color32 = Color32::from_rgb(236, 236, 236);

/// A category as the palette and the legend name it.
pub fn category_name(category: Category) -> &'static str {
    match category {
        Category::Sensor => "sensors & sim",
        Category::Navigation => "navigation",
        Category::Mapping => "mapping",
        Category::Operator => "operator",
        Category::Recording => "recording",
        Category::Other => "other",
    }
}

/// The category of a block's module type (`Other` when the type is unknown).
fn category_of(catalog: &Catalog, module_type: &str) -> Category {
    catalog
        .get(module_type)
        .map_or(Category::Other, |description| description.category)
}

/// An arrowhead whose tip is at `tip`, pointing right (into an input pin), in `colour` with a
/// dark outline that keeps it visible on a block, on the canvas and on a wire of its colour.
fn paint_arrowhead(painter: &egui::Painter, tip: Pos2, colour: Color32) {
    let points = vec![
        tip,
        tip + Vec2::new(-ARROW_LENGTH, -ARROW_HALF_WIDTH),
        tip + Vec2::new(-ARROW_LENGTH, ARROW_HALF_WIDTH),
    ];
    painter.add(egui::Shape::convex_polygon(
        points,
        colour,
        Stroke::new(1.5, Color32::from_black_alpha(220)),
    ));
}

/// A pin's size, in canvas points.
const PIN_SIZE: f32 = 10.0;
/// How far a routed link runs straight out of its pins and below the blocks, in canvas points.
/// Small enough that a route stays within the margin fit leaves round the blocks.
const ROUTE_STUB: f32 = 16.0;
/// How far apart routed links run beside one another (each in its own lane).
const ROUTE_LANE: f32 = 6.0;
/// A link whose input is left of its output plus this is routed (see [`Canvas::routed`]).
const BACK_GAP: f32 = 40.0;

/// The arrowhead at a wire's end, in canvas points.
const ARROW_LENGTH: f32 = 14.0;
const ARROW_HALF_WIDTH: f32 = 7.0;

/// A colour per data type, so that wires and pins of one type look alike.
pub fn type_colour(data_type: &str) -> Color32 {
    // FNV-1a: stable across runs and platforms, unlike the std hasher.
    let hash = data_type
        .bytes()
        .fold(0xcbf2_9ce4_8422_2325_u64, |hash, byte| {
            (hash ^ u64::from(byte)).wrapping_mul(0x0100_0000_01b3)
        });
    let hue = (hash % 360) as f32 / 360.0;
    egui::ecolor::Hsva::new(hue, 0.55, 0.95, 1.0).into()
}

/// A pin that records where it was drawn, so that the editor knows which pin a drag began on.
struct TrackedPin {
    info: PinInfo,
    pin: Option<Pin>,
    sink: PinSink,
}

impl SnarlPin for TrackedPin {
    fn draw(
        self,
        snarl_style: &SnarlStyle,
        style: &egui::Style,
        rect: Rect,
        painter: &egui::Painter,
    ) -> PinWireInfo {
        if let Some(pin) = self.pin {
            self.sink.borrow_mut().push((pin, rect));
        }
        self.info.draw(snarl_style, style, rect, painter)
    }
}
