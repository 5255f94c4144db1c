//! The map's image: PGM (binary `P5` or plain `P2`), read here, or PNG, with the `png` crate.

use super::{Image, error};
use crate::world::WorldError;

/// Images larger than this many pixels are refused.
const MAX_PIXELS: usize = 50_000_000;

/// Decodes a PGM (binary `P5` or plain `P2`) or PNG image.
pub fn decode_image(bytes: &[u8], file: &str) -> Result<Image, WorldError> {
    if bytes.starts_with(b"P5") || bytes.starts_with(b"P2") {
        decode_pgm(bytes, file)
    } else if bytes.starts_with(b"\x89PNG") {
        decode_png(bytes, file)
    } else {
        Err(error(
            file,
            0,
            0,
            "not a PGM (P5 or P2) or PNG image, the formats map_server maps are saved in",
        ))
    }
}

/// PGM is a header of whitespace-separated numbers (`#` comments allowed) and then the
/// pixels: four numbers need no library, and reading them here gives the line of a bad one.
fn decode_pgm(bytes: &[u8], file: &str) -> Result<Image, WorldError> {
    let plain = bytes.starts_with(b"P2");
    let mut at = 2;
    let mut line = 1;
    // The next number of the header (or of a plain file's pixels).
    let mut next = |what: &str| -> Result<usize, WorldError> {
        loop {
            match bytes.get(at) {
                Some(b'#') => {
                    while bytes.get(at).is_some_and(|&byte| byte != b'\n') {
                        at += 1;
                    }
                }
                Some(b'\n') => {
                    line += 1;
                    at += 1;
                }
                Some(byte) if byte.is_ascii_whitespace() => at += 1,
                _ => break,
            }
        }
        let start = at;
        while bytes.get(at).is_some_and(u8::is_ascii_digit) {
            at += 1;
        }
        std::str::from_utf8(&bytes[start..at])
            .ok()
            .and_then(|digits| digits.parse::<usize>().ok())
            .ok_or_else(|| error(file, line, 0, format!("the PGM's {what} is not a number")))
    };
    let width = next("width")?;
    let height = next("height")?;
    let max_value = next("largest value")?;
    if width == 0 || height == 0 || width.saturating_mul(height) > MAX_PIXELS {
        return Err(error(
            file,
            0,
            0,
            format!(
                "a {width} × {height} image is empty or too large (at most {MAX_PIXELS} pixels)"
            ),
        ));
    }
    if !(1..=65535).contains(&max_value) {
        return Err(error(
            file,
            0,
            0,
            format!("the PGM's largest value must be 1 to 65535, not {max_value}"),
        ));
    }
    let scale = |value: usize| ((value.min(max_value) * 255 + max_value / 2) / max_value) as u8;
    let count = width * height;
    let mut grey = Vec::with_capacity(count);
    if plain {
        for _ in 0..count {
            grey.push(scale(next("pixel")?));
        }
    } else {
        // One whitespace byte ends the header; the pixels follow it (none if the file ends).
        let bytes_per_pixel = if max_value > 255 { 2 } else { 1 };
        let data = bytes.get(at + 1..).unwrap_or_default();
        if data.len() < count * bytes_per_pixel {
            return Err(error(
                file,
                0,
                0,
                format!(
                    "the PGM is cut short: {width} × {height} pixels need {} bytes, found {}",
                    count * bytes_per_pixel,
                    bytes.len().saturating_sub(at + 1)
                ),
            ));
        }
        grey.extend(data.chunks_exact(bytes_per_pixel).take(count).map(|pixel| {
            let value = pixel
                .iter()
                .fold(0_usize, |sum, &byte| (sum << 8) | byte as usize);
            scale(value)
        }));
    }
    Ok(Image {
        width,
        height,
        grey,
        opaque: None,
    })
}

fn decode_png(bytes: &[u8], file: &str) -> Result<Image, WorldError> {
    let fail =
        |err: png::DecodingError| error(file, 0, 0, format!("the PNG does not decode: {err}"));
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().map_err(fail)?;
    let (width, height) = (reader.info().width as usize, reader.info().height as usize);
    if width.saturating_mul(height) > MAX_PIXELS {
        return Err(error(
            file,
            0,
            0,
            format!("a {width} × {height} image is too large (at most {MAX_PIXELS} pixels)"),
        ));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| error(file, 0, 0, "the PNG is too large"))?;
    let mut buffer = vec![0; size];
    let frame = reader.next_frame(&mut buffer).map_err(fail)?;
    let channels = frame.color_type.samples();
    let has_alpha = matches!(
        frame.color_type,
        png::ColorType::GrayscaleAlpha | png::ColorType::Rgba
    );
    let colours = if has_alpha { channels - 1 } else { channels };
    let mut grey = Vec::with_capacity(width * height);
    let mut opaque = Vec::with_capacity(if has_alpha { width * height } else { 0 });
    for row in buffer[..frame.buffer_size()].chunks_exact(frame.line_size) {
        for pixel in row.chunks_exact(channels).take(width) {
            let sum: usize = pixel[..colours].iter().map(|&value| value as usize).sum();
            grey.push((sum / colours) as u8);
            if has_alpha {
                opaque.push(pixel[colours] == 255);
            }
        }
    }
    Ok(Image {
        width,
        height,
        grey,
        opaque: has_alpha.then_some(opaque),
    })
}
