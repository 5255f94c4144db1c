//! The canvas's input: egui-snarl drawn through [`DiagramViewer`], then what it does not do
//! itself: the wire's origin and a refused wire's reason, drops from the palette, moves (with
//! the selected group), clicks that select, double clicks in the overview, and the clipboard.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use armor_protocol::ModuleState;
use egui::{Key, Ui};
use egui_snarl::ui::SnarlWidget;

use super::SystemView;
use crate::command::UiCommand;
use crate::common::palette::Catalog;
use crate::system::diagram::{BlockId, Diagram, GROUP_TYPE_PREFIX, border_of};
use crate::system::editor::Command;
use crate::system::viewer::{self, CanvasEvents, DiagramViewer};

/// Where the level's diagram of `real` draws the block `id` (a group's border block).
fn real_view_pos(
    real: &Diagram,
    level: Option<BlockId>,
    id: BlockId,
    catalog: &Catalog,
) -> Option<[f32; 2]> {
    real.at_level(level, catalog)
        .0
        .block(id)
        .map(|block| block.pos)
}

/// The canvas's id: tests and the selection lookup name it.
const CANVAS_ID: &str = "diagram";

/// What the palette hands the canvas during a drag.
#[derive(Clone, Debug)]
pub(super) struct PaletteDrag(pub String);

impl SystemView {
    /// Where the blocks moving with `grabbed` go when it moves by `delta`: itself, and the rest
    /// of the editor's selection if it is part of it.
    pub(super) fn group_moved(
        &self,
        grabbed: BlockId,
        delta: [f32; 2],
    ) -> impl Iterator<Item = (BlockId, [f32; 2])> + '_ {
        let selection = &self.editor.selection;
        let group: Vec<BlockId> = if selection.contains(&grabbed) {
            selection.iter().copied().collect()
        } else {
            vec![grabbed]
        };
        group.into_iter().filter_map(move |id| {
            let pos = self.editor.diagram.block(id)?.pos;
            Some((id, [pos[0] + delta[0], pos[1] + delta[1]]))
        })
    }

    /// The canvas. With subsystems, it draws one level (see `diagram/groups.rs`): the
    /// document is swapped for the level's diagram for the frame, so that everything the
    /// canvas does reads what it draws, and what moved is copied back after.
    pub(super) fn canvas_ui(
        &mut self,
        ui: &mut Ui,
        catalog: &Catalog,
        started: bool,
        live: &BTreeMap<String, ModuleState>,
    ) {
        let level = self.editor.level;
        if level.is_none() && self.editor.diagram.groups().next().is_none() {
            self.canvas_body(ui, catalog, started, live);
            return;
        }
        let (view, view_catalog) = self.editor.diagram.at_level(level, catalog);
        let real = std::mem::replace(&mut self.editor.diagram, view);
        let had_before = self.canvas.move_before.is_some();
        let queued = self.commands.len();
        self.drawing_level = true;
        self.canvas_body(ui, &view_catalog, started, live);
        self.drawing_level = false;
        let view = std::mem::replace(&mut self.editor.diagram, real.clone());
        for (id, block) in view.blocks() {
            if border_of(id).is_some() {
                let group = border_of(id).and_then(|(group, outputs)| {
                    Some(self.editor.diagram.group(group)?.border[usize::from(outputs)])
                });
                // Drawn where it was computed until moved: a move is a change from that.
                let before = real_view_pos(&real, level, id, catalog);
                if group.is_some() && before != Some(block.pos) {
                    self.editor.diagram.move_border(id, block.pos);
                }
                continue;
            }
            let moved = match self.editor.diagram.block(id) {
                Some(real) => real.pos != block.pos,
                None => self
                    .editor
                    .diagram
                    .group(id)
                    .is_some_and(|group| group.pos != block.pos),
            };
            if moved {
                self.editor.diagram.move_block(id, block.pos);
            }
        }
        // An undo step of a move restores the document, not the level's diagram.
        if !had_before && self.canvas.move_before.is_some() {
            self.canvas.move_before = Some(real.clone());
        }
        for command in &mut self.commands[queued..] {
            if let Command::Moved { before } = command
                && !had_before
            {
                **before = real.clone();
            }
        }
        // A double click on a group (or its menu's Parameters) opens it.
        if let Some(block) = self.opened_group.take() {
            self.commands.push(Command::Open(Some(block)));
        }
    }

    fn canvas_body(
        &mut self,
        ui: &mut Ui,
        catalog: &Catalog,
        started: bool,
        live: &BTreeMap<String, ModuleState>,
    ) {
        let ctx = ui.ctx().clone();
        self.canvas
            .sync(&self.editor.diagram, catalog, self.editor.revision());
        self.canvas.rect = ui.available_rect_before_wrap();
        if !started && self.canvas.view_request.is_none() {
            self.zoom_to_fit();
        }
        let (pressed, released, press_origin, latest, double_click, modifiers) =
            ctx.input(|input| {
                (
                    input.pointer.primary_pressed(),
                    input.pointer.primary_released(),
                    input.pointer.press_origin(),
                    input.pointer.latest_pos(),
                    input
                        .pointer
                        .button_double_clicked(egui::PointerButton::Primary)
                        .then(|| input.pointer.interact_pos())
                        .flatten(),
                    input.modifiers,
                )
            });
        // The wire's origin: the pin under the pointer when the button went down.
        if pressed {
            self.canvas.wire_from = press_origin
                .filter(|pos| self.canvas.rect.contains(*pos))
                .and_then(|pos| self.canvas.pin_at(pos).cloned());
        }

        let wheel = self.wheel_zoom(&ctx);

        let pins = std::rc::Rc::new(std::cell::RefCell::new(Vec::new()));
        let mut events = CanvasEvents::default();
        let mut node_rects = HashMap::new();
        let mut to_global = self.canvas.to_global;
        let view_request = self.canvas.view_request.take();
        let transform_request = self.canvas.transform_request.take();
        let wire_from = self.canvas.wire_from.clone();
        // The viewer reads the canvas while egui-snarl edits the snarl: hold them apart.
        let mut canvas = std::mem::take(&mut self.canvas);
        let mut snarl = std::mem::take(&mut canvas.snarl);
        let mut viewer = DiagramViewer {
            diagram: &self.editor.diagram,
            catalog,
            selection: &self.editor.selection,
            flagged: &self.flagged,
            commands: &mut self.commands,
            events: &mut events,
            wire_from: wire_from.as_ref(),
            pins: pins.clone(),
            node_rects: &mut node_rects,
            to_global: &mut to_global,
            view_request,
            transform_request,
            screen_rect: canvas.rect,
            double_click: double_click.filter(|pos| canvas.rect.contains(*pos)),
            canvas: &canvas,
            live,
            wheel,
            shift: ctx.input(|input| input.modifiers.shift),
        };
        // The id given, not a salt, so that its layer is known: the wires' ends are painted on it.
        let snarl_id = ui.id().with(CANVAS_ID);
        let widget = SnarlWidget::new().id(snarl_id).style(viewer::style());
        widget.show(&mut snarl, &mut viewer, ui);
        drop(viewer);
        self.canvas = canvas;
        self.canvas.snarl = snarl;
        self.canvas.node_rects.extend(node_rects);
        self.canvas.to_global = to_global;
        self.canvas.pins = pins.take();
        // Drawn on egui-snarl's own layer (whose id is the widget's), after its blocks and
        // wires, and in canvas coordinates, as that layer is transformed.
        let snarl_layer = egui::LayerId::new(ui.layer_id().order, snarl_id);
        // Its clip set, not intersected with the layer's default (the screen, which is not in
        // canvas coordinates).
        let mut painter = ctx.layer_painter(snarl_layer);
        painter.set_clip_rect(self.canvas.viewport());
        self.canvas
            .paint_routes(&self.editor.diagram, catalog, &painter);
        self.canvas
            .paint_wire_ends(&self.editor.diagram, catalog, &painter);

        self.canvas_tools_ui(&ctx);
        if self.fit_again > 0 {
            self.fit_again -= 1;
            self.canvas.view_request = self.canvas.bounds(&self.editor.diagram, None);
        }

        // In the overview, a double click zooms in on the block (its pins and parameters are
        // there).
        if self.canvas.is_overview()
            && let Some(pos) = double_click.filter(|pos| self.canvas.rect.contains(*pos))
            && let Some(block) = self.canvas.block_at(&self.editor.diagram, catalog, pos)
        {
            self.show_block(block);
        }
        self.canvas.overview_names = std::mem::take(&mut events.overview_names);
        if let Some(block) = events.open_params {
            let group = self
                .editor
                .diagram
                .block(block)
                .is_some_and(|b| b.module_type.starts_with(GROUP_TYPE_PREFIX));
            if group {
                self.opened_group = Some(block);
            } else if border_of(block).is_some() {
                // A subsystem's border has no parameters.
            } else {
                self.open_params(block);
            }
        }

        // A wire dropped on a pin of the same side: egui-snarl ignores it silently; say why.
        if released {
            if let (Some(from), Some(to)) = (
                self.canvas.wire_from.take(),
                latest.and_then(|pos| self.canvas.pin_at(pos).cloned()),
            ) && from.side == to.side
                && from != to
                && let Err(reason) = self.editor.diagram.link_between(catalog, &from, &to)
            {
                self.set_status(format!("refused: {reason}"), true);
            }
            self.canvas.wire_from = None;
        }

        // A module type dropped from the palette.
        if let Some(pos) = latest.filter(|pos| self.canvas.rect.contains(*pos))
            && released
            && let Some(payload) = egui::DragAndDrop::take_payload::<PaletteDrag>(&ctx)
        {
            let at = self.canvas.to_canvas(pos);
            self.commands.push(Command::AddBlock {
                module_type: payload.0.clone(),
                pos: [at.x - 60.0, at.y - 20.0],
            });
        }

        // Moves: the snarl moved its nodes; copy them into the document, one undo step a drag.
        let mut moved = self.canvas.moved_blocks(&self.editor.diagram);
        // A block of a group selected in the editor (select all, find, a paste) carries the rest
        // of the group along; egui-snarl moves only its own selection.
        if let [(grabbed, to)] = moved[..]
            && let Some(from) = self.editor.diagram.block(grabbed).map(|block| block.pos)
        {
            let delta = [to[0] - from[0], to[1] - from[1]];
            moved.extend(
                self.group_moved(grabbed, delta)
                    .filter(|(id, _)| *id != grabbed),
            );
            self.canvas.place_nodes(&moved);
        }
        // In the overview egui-snarl holds no block: the block under the pointer is dragged here.
        if self.canvas.is_overview() {
            moved.extend(self.overview_drag(ui, catalog));
        }
        if !moved.is_empty() {
            if self.canvas.move_before.is_none() {
                self.canvas.move_before = Some(self.editor.diagram.clone());
            }
            for (id, pos) in moved {
                self.editor.diagram.move_block(id, pos);
            }
        }
        let pointer_down = ctx.input(|input| input.pointer.any_down());
        if !pointer_down && let Some(before) = self.canvas.move_before.take() {
            self.commands.push(Command::Moved {
                before: Box::new(before),
            });
        }

        // Selection: a click on a block selects it (egui-snarl selects only with Shift), a click
        // on empty canvas clears it; Shift-click and rectangle selection are egui-snarl's own.
        let snarl_selected = widget.get_selected_nodes(ui);
        if let Some(selected) = self.canvas.snarl_selection_change(snarl_selected) {
            self.commands.push(Command::Select(selected));
        } else if released
            && !modifiers.shift
            && !modifiers.command
            && let Some(pos) = latest.filter(|pos| self.canvas.rect.contains(*pos))
            && !ctx.input(|input| input.pointer.is_decidedly_dragging())
            && ctx
                .layer_id_at(pos)
                .is_some_and(|layer| layer.order == egui::Order::Background)
        {
            match self.canvas.block_at(&self.editor.diagram, catalog, pos) {
                Some(block) => self.commands.push(Command::Select([block].into())),
                None => self.commands.push(Command::Select(BTreeSet::new())),
            }
        }
    }

    /// The canvas's corner, as the map's and the net's toolbars: Fit, and how to zoom and pan.
    /// Over the canvas (egui-snarl's layer covers the panel it is in), in the bottom right
    /// corner, where Node-RED has its zoom buttons.
    fn canvas_tools_ui(&mut self, ctx: &egui::Context) {
        let rect = self.canvas.rect;
        if !rect.is_positive() {
            return;
        }
        egui::Area::new(egui::Id::new("canvas-tools"))
            .order(egui::Order::Middle)
            .pivot(egui::Align2::RIGHT_BOTTOM)
            .fixed_pos(rect.right_bottom() - egui::vec2(10.0, 10.0))
            .constrain_to(rect)
            .show(ctx, |ui| {
                egui::Frame::popup(ui.style()).show(ui, |ui| {
                    ui.horizontal(|ui| {
                        ui.weak("wheel: zoom · drag: pan");
                        if ui
                            .button("Fit")
                            .on_hover_text("show every block (Home)")
                            .clicked()
                        {
                            self.zoom_to_fit();
                        }
                    });
                });
            });
    }

    /// The wheel's zoom this frame, when the pointer is over the canvas (and no window or menu
    /// over it): the factor and the point it zooms about, on screen.
    ///
    /// egui-snarl pans on the plain wheel and zooms on Ctrl+wheel, through egui's `Scene`, in
    /// steps that follow egui's smoothed scroll and scroll-zoom speed. Every other canvas of the
    /// studio (the map, the net) zooms on the plain wheel about the pointer, one notch a fine
    /// step, and pans by dragging: so the diagram does too. The wheel's pan is taken out of
    /// egui's input before egui-snarl reads it, and the transform egui-snarl computes is
    /// replaced by ours in [`DiagramViewer`]'s `current_transform` for the frames the wheel
    /// moves (egui's smoothed Ctrl+wheel zoom cannot be taken out of its input).
    fn wheel_zoom(&mut self, ctx: &egui::Context) -> Option<viewer::WheelZoom> {
        let pointer = ctx.input(|input| input.pointer.hover_pos())?;
        let over_canvas = self.canvas.rect.contains(pointer)
            && ctx
                .layer_id_at(pointer)
                .is_some_and(|layer| layer.order == egui::Order::Background);
        if !over_canvas {
            return None;
        }
        let (notches, pinch, wheeling) = ctx.input_mut(|input| {
            let mut notches = 0.0;
            let mut pinch = 1.0;
            for event in &input.events {
                match event {
                    egui::Event::MouseWheel { unit, delta, .. } => {
                        notches += viewer::wheel_notches(*unit, *delta);
                    }
                    egui::Event::Zoom(factor) => pinch *= factor,
                    _ => {}
                }
            }
            // egui spreads a notch's scroll over the next frames: taken out, those frames do
            // not pan. Its Ctrl+wheel zoom, spread likewise, cannot be taken out: in those
            // frames egui-snarl's transform is replaced by last frame's.
            let wheeling = input.zoom_delta() != 1.0;
            input.smooth_scroll_delta = egui::Vec2::ZERO;
            (notches, pinch, wheeling)
        });
        // egui may run a frame's UI twice (a discarded first pass) with the same input: the
        // zoom is taken from the transform the frame began with, so that it is applied once.
        let frame = ctx.cumulative_frame_nr();
        let from = match self.canvas.frame_start {
            Some((seen, transform)) if seen == frame => transform,
            _ => self.canvas.to_global,
        };
        self.canvas.frame_start = Some((frame, from));
        (notches != 0.0 || pinch != 1.0 || wheeling).then(|| viewer::WheelZoom {
            factor: viewer::ZOOM_STEP.powf(notches) * pinch,
            about: pointer,
            from,
        })
    }

    /// Cut, copy and paste. The platform turns Ctrl+C / Ctrl+X / Ctrl+V into copy, cut and
    /// paste events, the last with the system clipboard's text (and a headless harness sends
    /// plain keys): take both.
    pub fn clipboard_input(&mut self, ctx: &egui::Context) {
        let key_of = |command: UiCommand| command.shortcuts().first().map(|s| s.logical_key);
        let shortcut = |event: &egui::Event, wanted: Option<Key>| matches!(event, egui::Event::Key { key, pressed: true, modifiers, .. } if Some(*key) == wanted && modifiers.command);
        let commands = ctx.input(|input| {
            let mut commands = Vec::new();
            for event in &input.events {
                match event {
                    egui::Event::Copy => commands.push(Command::Copy),
                    egui::Event::Cut => commands.push(Command::Cut),
                    egui::Event::Paste(text) if self.copied_text.as_ref() == Some(text) => {
                        commands.push(Command::Paste);
                    }
                    egui::Event::Paste(text) => commands.push(Command::PasteText(text.clone())),
                    event if shortcut(event, key_of(UiCommand::Copy)) => {
                        commands.push(Command::Copy);
                    }
                    event if shortcut(event, key_of(UiCommand::Cut)) => {
                        commands.push(Command::Cut);
                    }
                    event if shortcut(event, key_of(UiCommand::Paste)) => {
                        commands.push(Command::Paste);
                    }
                    _ => {}
                }
            }
            commands
        });
        self.commands.extend(commands);
    }
}
