//! The picture export: the canvas as the renderer drew it (so it looks exactly like the
//! screen), cut out of a screenshot and written as PNG with tiny-skia.

use std::path::Path;

use anyhow::Context as _;

/// Writes the part of `image` under `rect` (in points; `scale` pixels a point) as a PNG file.
pub fn write_png(
    image: &egui::ColorImage,
    rect: egui::Rect,
    scale: f32,
    path: &Path,
) -> anyhow::Result<()> {
    let [width, height] = image.size;
    let clamp = |v: f32, max: usize| ((v * scale).round().max(0.0) as usize).min(max);
    let (x0, y0) = (clamp(rect.min.x, width), clamp(rect.min.y, height));
    let (x1, y1) = (clamp(rect.max.x, width), clamp(rect.max.y, height));
    anyhow::ensure!(
        x1 > x0 && y1 > y0,
        "the canvas is not visible: nothing to export"
    );
    let (w, h) = (x1 - x0, y1 - y0);
    let mut pixmap =
        tiny_skia::Pixmap::new(w as u32, h as u32).context("the picture is too large")?;
    let data = pixmap.data_mut();
    for y in 0..h {
        for x in 0..w {
            let colour = image.pixels[(y0 + y) * width + (x0 + x)];
            let at = (y * w + x) * 4;
            // Both are premultiplied RGBA, and a screenshot is opaque.
            data[at..at + 4].copy_from_slice(&colour.to_array());
        }
    }
    let png = pixmap.encode_png().context("cannot encode the picture")?;
    armor_runtime::fs::write_atomically(path, &png)
        .with_context(|| format!("cannot write {}", path.display()))
}
