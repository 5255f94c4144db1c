//! The video panel of the Run view: the latest frame of one `Image` output of the run (picked
//! from a list of the run's image outputs, or a recording's image channels), with its age, at
//! the rate the frames come. While the panel has the keyboard focus (a click on the picture),
//! the arrow keys drive the robot through the teleop module, as over the map, so that the
//! operator can drive by the camera alone.
//!
//! Frames are kept as they arrive ([`Frames`], shared with the live data) and decoded only
//! when one is shown: a recording played fast or sought through passes thousands of frames
//! that are never drawn.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

use armor_module_api::Datum as _;
use armor_module_api::types::{Image, ImageEncoding};
use egui::{Color32, RichText, Ui};

/// Pixels a frame may have (a 4K camera has 8.3 million): a frame that claims more is not
/// decoded, so a hostile JPEG header cannot make the studio allocate gigabytes.
pub const MAX_PIXELS: u64 = 16 * 1024 * 1024;

/// The latest frame of each image output.
#[derive(Clone, Debug, Default)]
pub struct Frames {
    latest: BTreeMap<String, Frame>,
}

/// One frame as it arrived.
#[derive(Clone, Debug)]
pub struct Frame {
    pub image: Arc<Image>,
    /// When the studio took it (for the age of a live frame).
    pub received: Instant,
    /// Counts the frames of its output, so that a new one is decoded once.
    pub number: u64,
}

impl Frames {
    /// Takes a sample of the image output `data_name`; refuses (with the reason) one that does
    /// not decode or is too large to show.
    pub fn take(&mut self, data_name: &str, payload: &[u8]) -> Result<(), String> {
        let image = Image::decode(payload).map_err(|err| err.to_string())?;
        check_size(image.width, image.height)?;
        let number = self
            .latest
            .get(data_name)
            .map_or(1, |frame| frame.number + 1);
        self.latest.insert(
            data_name.to_owned(),
            Frame {
                image: Arc::new(image),
                received: Instant::now(),
                number,
            },
        );
        Ok(())
    }

    pub fn get(&self, data_name: &str) -> Option<&Frame> {
        self.latest.get(data_name)
    }
}

fn check_size(width: u32, height: u32) -> Result<(), String> {
    if u64::from(width) * u64::from(height) > MAX_PIXELS {
        return Err(format!(
            "an image of {width} × {height} pixels is larger than the {MAX_PIXELS} shown"
        ));
    }
    Ok(())
}

/// The picture of a frame, for the display.
pub fn decode(image: &Image) -> Result<egui::ColorImage, String> {
    let size = [image.width as usize, image.height as usize];
    match image.encoding {
        ImageEncoding::Rgb8 => Ok(egui::ColorImage::from_rgb(size, &image.data)),
        ImageEncoding::Mono8 => Ok(egui::ColorImage::from_gray(size, &image.data)),
        ImageEncoding::Jpeg => {
            // The file's own header says how large it is: checked before decoding.
            let (width, height) = armor_model::foxglove::jpeg_size(&image.data)
                .ok_or("the JPEG file has no frame header")?;
            check_size(width, height)?;
            let decoded =
                image::load_from_memory_with_format(&image.data, image::ImageFormat::Jpeg)
                    .map_err(|err| format!("cannot decode the JPEG: {err}"))?
                    .to_rgb8();
            let size = [decoded.width() as usize, decoded.height() as usize];
            Ok(egui::ColorImage::from_rgb(size, decoded.as_raw()))
        }
    }
}

/// What the panel keeps between frames.
#[derive(Default)]
pub struct VideoPanel {
    /// The output shown (the first of the list when none was picked, or the one picked is not
    /// in the list).
    pub picked: Option<String>,
    /// The frame last decoded (its output and number), shown unless it failed.
    decoded: Option<(String, u64)>,
    texture: Option<egui::TextureHandle>,
    /// Why the frame shown could not be decoded.
    problem: Option<String>,
}

/// The panel's widget id: the arrow keys drive while it has the focus.
fn picture_id() -> egui::Id {
    egui::Id::new("run-video-picture")
}

/// Whether the picture has the keyboard focus, so that the arrow keys are the robot's.
pub fn has_focus(ctx: &egui::Context) -> bool {
    ctx.memory(|memory| memory.has_focus(picture_id()))
}

/// How old the frame shown is.
#[derive(Clone, Copy, Debug)]
pub enum Clock {
    /// A live run: since the studio received it.
    Live,
    /// A recording: from its capture to the play head (run time, nanoseconds).
    PlayHead(u64),
}

impl VideoPanel {
    /// The output shown among `outputs`.
    pub fn shown<'a>(&self, outputs: &'a [String]) -> Option<&'a String> {
        outputs
            .iter()
            .find(|name| Some(*name) == self.picked.as_ref())
            .or(outputs.first())
    }

    /// The panel: the list of `outputs` to pick from, the picture and its age.
    pub fn ui(&mut self, ui: &mut Ui, outputs: &[String], frames: &Frames, clock: Clock) {
        let Some(shown) = self.shown(outputs).cloned() else {
            ui.label("No image output in this run.");
            return;
        };
        egui::ComboBox::new("run-video-output", "Camera")
            .selected_text(&shown)
            .show_ui(ui, |ui| {
                for output in outputs {
                    if ui.selectable_label(*output == shown, output).clicked() {
                        self.picked = Some(output.clone());
                    }
                }
            });
        let Some(frame) = frames.get(&shown) else {
            ui.label(format!("Waiting for a frame of {shown}…"));
            return;
        };
        let age_secs = match clock {
            Clock::Live => frame.received.elapsed().as_secs_f64(),
            Clock::PlayHead(at_ns) => at_ns.saturating_sub(frame.image.stamp_ns) as f64 / 1e9,
        };
        let image = &frame.image;
        ui.label(format!(
            "{} × {} {} · {} · age {}",
            image.width,
            image.height,
            image.encoding.name(),
            image.frame_id,
            age_text(age_secs)
        ));
        self.upload(ui.ctx(), &shown, frame);
        if let Some(problem) = &self.problem {
            ui.label(RichText::new(format!("not shown: {problem}")).color(Color32::RED));
        }
        let Some(texture) = &self.texture else {
            return;
        };
        let size = texture.size_vec2();
        let scale = (ui.available_width() / size.x).min(ui.available_height().max(60.0) / size.y);
        let (rect, _) = ui.allocate_exact_size(size * scale, egui::Sense::hover());
        let response = ui
            .interact(rect, picture_id(), egui::Sense::click())
            .on_hover_text("Click, then drive with the arrow keys");
        response.widget_info(|| {
            egui::WidgetInfo::labeled(egui::WidgetType::Image, true, "Camera view")
        });
        ui.painter().image(
            texture.id(),
            rect,
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            Color32::WHITE,
        );
        if response.clicked() {
            response.request_focus();
        }
        let id = response.id;
        ui.memory_mut(|memory| {
            memory.set_focus_lock_filter(
                id,
                egui::EventFilter {
                    horizontal_arrows: true,
                    vertical_arrows: true,
                    ..egui::EventFilter::default()
                },
            );
        });
        if response.has_focus() {
            ui.painter().rect_stroke(
                rect,
                0.0,
                egui::Stroke::new(2.0, ui.visuals().selection.stroke.color),
                egui::StrokeKind::Inside,
            );
            ui.label("Driving: arrow keys (Esc to let go)");
        }
    }

    /// Makes the texture of `frame` unless it was decoded already.
    fn upload(&mut self, ctx: &egui::Context, output: &str, frame: &Frame) {
        let key = (output.to_owned(), frame.number);
        if self.decoded.as_ref() == Some(&key) {
            return;
        }
        self.decoded = Some(key);
        match decode(&frame.image) {
            Ok(picture) => {
                let options = egui::TextureOptions::LINEAR;
                match &mut self.texture {
                    Some(texture) => texture.set(picture, options),
                    None => self.texture = Some(ctx.load_texture("run-video", picture, options)),
                }
                self.problem = None;
            }
            // The last good picture stays.
            Err(problem) => self.problem = Some(problem),
        }
    }
}

fn age_text(age_secs: f64) -> String {
    if age_secs < 1.0 {
        format!("{:.0} ms", age_secs * 1000.0)
    } else {
        format!("{age_secs:.1} s")
    }
}
