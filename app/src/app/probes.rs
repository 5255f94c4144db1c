//! What tests and the bench read of the window: where the System view drew its blocks, pins,
//! wire ends and routes last frame, and its canvas's view.

use egui::Pos2;

use super::StudioApp;
use crate::system::diagram::PinSide;

impl StudioApp {
    /// Where a block's pin is on screen (as drawn last frame): `side` is input or output.
    pub fn pin_pos(&self, block: &str, port: &str, side: PinSide) -> Option<Pos2> {
        self.system.pin_pos(block, port, side)
    }

    /// Where a block is on screen (its centre, as drawn last frame).
    pub fn block_pos(&self, block: &str) -> Option<Pos2> {
        self.system.block_pos(&self.palette.catalog, block)
    }

    /// Where a block's header is on screen (where a hand grabs it to move it).
    pub fn block_header_pos(&self, block: &str) -> Option<Pos2> {
        self.system.block_header_pos(&self.palette.catalog, block)
    }

    /// The wires' ends marked last frame: the input pin (`block.port`) and where, on screen.
    pub fn wire_ends(&self) -> Vec<(String, Pos2)> {
        self.system.wire_ends()
    }

    /// The links drawn round the blocks (those that run backwards): `from -> to` and the
    /// route's corners on screen, as drawn last frame.
    pub fn routes(&self) -> Vec<(String, Vec<Pos2>)> {
        self.system.routes(&self.palette.catalog)
    }

    /// A block's rectangle on screen (as drawn last frame).
    pub fn block_screen_rect(&self, block: &str) -> Option<egui::Rect> {
        self.system.block_screen_rect(&self.palette.catalog, block)
    }

    /// The blocks whose names the overview drew last frame (none when zoomed in).
    pub fn overview_names(&self) -> &[String] {
        &self.system.canvas.overview_names
    }

    /// Whether the canvas shows the overview (zoomed out: boxes and lines, no widgets).
    pub fn is_overview(&self) -> bool {
        self.system.canvas.is_overview()
    }

    /// The canvas's transform (graph to screen), as drawn last frame.
    pub fn canvas_transform(&self) -> egui::emath::TSTransform {
        self.system.canvas.to_global
    }

    /// The screen rectangle of the canvas.
    pub fn canvas_rect(&self) -> egui::Rect {
        self.system.canvas.rect
    }

    /// Sets the canvas's view (the bench's overview, below the zoom a fit goes to).
    pub fn set_canvas_transform(&mut self, to_global: egui::emath::TSTransform) {
        self.system.canvas.transform_request = Some(to_global);
        self.system.canvas.view_request = None;
    }

    /// Shows the first blocks at about `scale` (the bench's other views).
    pub fn view_at_scale(&mut self, scale: f32) {
        self.system.view_at_scale(scale);
    }
}
