//! Pictures of the canvas or the map (File, Export PNG…): asked of the renderer as a
//! screenshot, cropped and written by `crate::export`.

use std::path::PathBuf;
use std::sync::Arc;

use super::{StudioApp, View};

/// A picture requested from the renderer: the part under `crop` (the canvas or the map) is
/// written to `path`.
#[derive(Clone, Debug)]
struct ExportRequest {
    path: PathBuf,
    crop: egui::Rect,
}

impl StudioApp {
    pub(super) fn export_png(&mut self, ctx: &egui::Context, path: PathBuf, view: View) {
        // Deselect and frame everything so the picture shows the whole document as drawn; the
        // screenshot waits two frames, for the new view and for the path dialog to be gone.
        if view == View::System {
            self.system.frame_for_picture();
        } else if let Some(mission) = &mut self.mission {
            mission.request_fit();
        }
        self.export_after = Some((path, view, 2));
        self.set_status("exporting the picture…".to_owned(), false);
        ctx.request_repaint();
    }

    pub(super) fn request_screenshot(&mut self, ctx: &egui::Context) {
        match self.export_after.take() {
            Some((path, view, 0)) => {
                let crop = match (view, &self.mission) {
                    (View::Mission, Some(mission)) => mission.map_rect(),
                    _ => self.system.canvas.rect,
                };
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(egui::UserData::new(
                    ExportRequest { path, crop },
                )));
                ctx.request_repaint();
            }
            Some((path, view, frames)) => {
                self.export_after = Some((path, view, frames - 1));
                ctx.request_repaint();
            }
            None => {}
        }
    }

    pub(super) fn handle_screenshots(&mut self, ctx: &egui::Context) {
        let shots: Vec<(Arc<egui::ColorImage>, ExportRequest)> = ctx.input(|input| {
            input
                .events
                .iter()
                .filter_map(|event| match event {
                    egui::Event::Screenshot {
                        image, user_data, ..
                    } => {
                        let request = user_data.data.as_ref()?.downcast_ref::<ExportRequest>()?;
                        Some((image.clone(), request.clone()))
                    }
                    _ => None,
                })
                .collect()
        });
        for (image, ExportRequest { path, crop }) in shots {
            let scale = ctx.pixels_per_point();
            match crate::export::write_png(&image, crop, scale, &path) {
                Ok(()) => self.set_status(format!("exported {}", path.display()), false),
                Err(err) => self.set_status(format!("{err:#}"), true),
            }
        }
    }
}
