//! The overview (the canvas zoomed out below half size, boxes and lines, drawn by `viewer.rs`):
//! egui-snarl then holds no block, so dragging one is done here.

use egui::Ui;

use super::SystemView;
use crate::common::palette::Catalog;
use crate::system::diagram::BlockId;

impl SystemView {
    /// In the overview, the block under the pointer (or the one being dragged) takes drags, on
    /// top of the canvas's own panning: the blocks it moves this frame, with their new places.
    pub(super) fn overview_drag(
        &mut self,
        ui: &mut Ui,
        catalog: &Catalog,
    ) -> Vec<(BlockId, [f32; 2])> {
        let diagram = &self.editor.diagram;
        let under_pointer = || {
            let pointer = ui.ctx().pointer_hover_pos()?;
            self.canvas.block_at(diagram, catalog, pointer)
        };
        let Some(block) = self
            .canvas
            .overview_grab
            .filter(|block| diagram.block(*block).is_some())
            .or_else(under_pointer)
        else {
            return Vec::new();
        };
        let rect = self.canvas.to_global * self.canvas.rect_of(diagram, catalog, block);
        // Over egui-snarl's layer (a sublayer of this one, which takes drags to pan).
        let layer = egui::LayerId::new(ui.layer_id().order, egui::Id::new("overview drag"));
        ui.ctx().set_sublayer(ui.layer_id(), layer);
        let drag_ui = ui.new_child(
            egui::UiBuilder::new()
                .layer_id(layer)
                .max_rect(self.canvas.rect),
        );
        let response = drag_ui.interact(
            rect.intersect(self.canvas.rect),
            egui::Id::new(("overview block", block)),
            egui::Sense::drag(),
        );
        if response.drag_started() {
            self.canvas.overview_grab = Some(block);
        }
        if !response.dragged() {
            self.canvas.overview_grab = None;
        }
        let delta = response.drag_delta() / self.canvas.to_global.scaling;
        if delta == egui::Vec2::ZERO {
            return Vec::new();
        }
        self.group_moved(block, [delta.x, delta.y]).collect()
    }
}
