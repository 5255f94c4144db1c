//! Images in Foxglove's message schemas, as JSON: a raw [`Image`] (`rgb8`, `mono8`) as a
//! `foxglove.RawImage`, a JPEG one as a `foxglove.CompressedImage`, with the JSON Schemas
//! Foxglove publishes for them (bytes as base64 strings, the time as seconds and nanoseconds).
//! The recorder writes images so, so that Foxglove and other MCAP viewers show them, and
//! `armor replay` and the studio read them back into images.

use armor_module_api::types::{Image, ImageEncoding};
use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use serde::{Deserialize, Serialize};
use serde_json::json;

pub const RAW_IMAGE: &str = "foxglove.RawImage";
pub const COMPRESSED_IMAGE: &str = "foxglove.CompressedImage";

#[derive(Serialize, Deserialize)]
struct Time {
    sec: u64,
    nsec: u32,
}

#[derive(Serialize, Deserialize)]
struct RawImage {
    timestamp: Time,
    frame_id: String,
    width: u32,
    height: u32,
    encoding: String,
    step: u32,
    data: String,
}

#[derive(Serialize, Deserialize)]
struct CompressedImage {
    timestamp: Time,
    frame_id: String,
    data: String,
    format: String,
}

/// The Foxglove schema an image of this encoding is written with.
pub fn schema_name(encoding: ImageEncoding) -> &'static str {
    match encoding {
        ImageEncoding::Rgb8 | ImageEncoding::Mono8 => RAW_IMAGE,
        ImageEncoding::Jpeg => COMPRESSED_IMAGE,
    }
}

/// The JSON Schema of `schema_name` (either of [`RAW_IMAGE`], [`COMPRESSED_IMAGE`]), as
/// Foxglove's schema repository gives it.
pub fn json_schema(schema_name: &str) -> Option<serde_json::Value> {
    let timestamp = json!({
        "type": "object",
        "title": "time",
        "properties": {
            "sec": {"type": "integer", "minimum": 0},
            "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999},
        },
        "description": "Timestamp of image",
    });
    let frame_id = json!({
        "type": "string",
        "description": "Frame of reference for the image. The origin of the frame is the \
            optical center of the camera. +x points to the right in the image, +y points down, \
            and +z points into the plane of the image.",
    });
    let schema = match schema_name {
        RAW_IMAGE => json!({
            "title": RAW_IMAGE,
            "description": "A raw image",
            "type": "object",
            "properties": {
                "timestamp": timestamp,
                "frame_id": frame_id,
                "width": {"type": "integer", "minimum": 0, "description": "Image width"},
                "height": {"type": "integer", "minimum": 0, "description": "Image height"},
                "encoding": {"type": "string", "description": "Encoding of the raw image data"},
                "step": {"type": "integer", "minimum": 0, "description": "Byte length of a single row"},
                "data": {"type": "string", "contentEncoding": "base64", "description": "Raw image data"},
            },
        }),
        COMPRESSED_IMAGE => json!({
            "title": COMPRESSED_IMAGE,
            "description": "A compressed image",
            "type": "object",
            "properties": {
                "timestamp": timestamp,
                "frame_id": frame_id,
                "data": {"type": "string", "contentEncoding": "base64", "description": "Compressed image data"},
                "format": {"type": "string", "description": "Image format"},
            },
        }),
        _ => return None,
    };
    Some(schema)
}

/// The image as the JSON message of its schema ([`schema_name`]).
pub fn to_json(image: &Image) -> Vec<u8> {
    let timestamp = Time {
        sec: image.stamp_ns / 1_000_000_000,
        nsec: (image.stamp_ns % 1_000_000_000) as u32,
    };
    let data = BASE64.encode(&image.data);
    let frame_id = image.frame_id.clone();
    let result = match image.encoding.bytes_per_pixel() {
        Some(bytes) => serde_json::to_vec(&RawImage {
            timestamp,
            frame_id,
            width: image.width,
            height: image.height,
            encoding: image.encoding.name().to_owned(),
            step: image.width.saturating_mul(bytes as u32),
            data,
        }),
        None => serde_json::to_vec(&CompressedImage {
            timestamp,
            frame_id,
            data,
            format: image.encoding.name().to_owned(),
        }),
    };
    // Strings and integers only: nothing serde_json can refuse.
    result.unwrap_or_default()
}

/// An image from a `foxglove.RawImage` (`rgb8`, `mono8`, rows without padding) or a
/// `foxglove.CompressedImage` (`jpeg`) JSON message; the error says what is wrong.
pub fn from_json(json: &[u8]) -> Result<Image, String> {
    let value: serde_json::Value =
        serde_json::from_slice(json).map_err(|err| format!("not JSON: {err}"))?;
    let image = if value.get("format").is_some() {
        let message: CompressedImage = serde_json::from_value(value)
            .map_err(|err| format!("not a {COMPRESSED_IMAGE}: {err}"))?;
        let encoding = match message.format.as_str() {
            "jpeg" | "jpg" | "image/jpeg" => ImageEncoding::Jpeg,
            other => return Err(format!("format `{other}`: only jpeg is read")),
        };
        let data = decode_data(&message.data)?;
        let (width, height) =
            jpeg_size(&data).ok_or("the data is not a JPEG file with a frame header")?;
        Image {
            width,
            height,
            encoding,
            stamp_ns: stamp_ns(&message.timestamp),
            frame_id: message.frame_id,
            data: data.into(),
        }
    } else {
        let message: RawImage =
            serde_json::from_value(value).map_err(|err| format!("not a {RAW_IMAGE}: {err}"))?;
        let encoding = ImageEncoding::from_name(&message.encoding)
            .filter(|encoding| encoding.bytes_per_pixel().is_some())
            .ok_or_else(|| format!("encoding `{}`: rgb8 or mono8 are read", message.encoding))?;
        let row = u64::from(message.width) * encoding.bytes_per_pixel().unwrap_or(1) as u64;
        if u64::from(message.step) != row {
            return Err(format!(
                "step {} for rows of {row} bytes: padded rows are not read",
                message.step
            ));
        }
        Image {
            width: message.width,
            height: message.height,
            encoding,
            stamp_ns: stamp_ns(&message.timestamp),
            frame_id: message.frame_id,
            data: decode_data(&message.data)?.into(),
        }
    };
    image.check()?;
    Ok(image)
}

fn stamp_ns(time: &Time) -> u64 {
    time.sec
        .saturating_mul(1_000_000_000)
        .saturating_add(u64::from(time.nsec))
}

fn decode_data(base64: &str) -> Result<Vec<u8>, String> {
    BASE64
        .decode(base64)
        .map_err(|err| format!("`data` is not base64: {err}"))
}

/// Width and height from a JPEG file's frame header (the first SOF marker).
pub fn jpeg_size(jpeg: &[u8]) -> Option<(u32, u32)> {
    if !jpeg.starts_with(&[0xFF, 0xD8]) {
        return None;
    }
    let mut at = 2;
    while at + 4 <= jpeg.len() {
        if jpeg[at] != 0xFF {
            return None;
        }
        let marker = jpeg[at + 1];
        if marker == 0xFF {
            // Fill bytes before a marker.
            at += 1;
            continue;
        }
        let length = usize::from(u16::from_be_bytes([jpeg[at + 2], jpeg[at + 3]]));
        // SOF0 to SOF15, except DHT (C4), JPG (C8) and DAC (CC).
        if (0xC0..=0xCF).contains(&marker) && !matches!(marker, 0xC4 | 0xC8 | 0xCC) {
            let header = jpeg.get(at + 4..at + 9)?;
            let height = u32::from(u16::from_be_bytes([header[1], header[2]]));
            let width = u32::from(u16::from_be_bytes([header[3], header[4]]));
            return (width > 0 && height > 0).then_some((width, height));
        }
        if length < 2 {
            return None;
        }
        at += 2 + length;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(encoding: ImageEncoding, data: Vec<u8>) -> Image {
        Image {
            width: 3,
            height: 2,
            encoding,
            stamp_ns: 12_345_678_901,
            frame_id: "camera".into(),
            data: data.into(),
        }
    }

    #[test]
    fn raw_images_are_raw_images_of_foxglove_and_come_back_equal() {
        let rgb = image(ImageEncoding::Rgb8, (0..18).collect());
        let json = to_json(&rgb);
        let value: serde_json::Value = serde_json::from_slice(&json).expect("json");
        assert_eq!(value["timestamp"], json!({"sec": 12, "nsec": 345_678_901}));
        assert_eq!(value["step"], 9);
        assert_eq!(value["encoding"], "rgb8");
        assert_eq!(value["data"], BASE64.encode((0..18).collect::<Vec<u8>>()));
        assert_eq!(from_json(&json), Ok(rgb));
        let mono = image(ImageEncoding::Mono8, vec![7; 6]);
        assert_eq!(from_json(&to_json(&mono)), Ok(mono));
        assert_eq!(schema_name(ImageEncoding::Mono8), RAW_IMAGE);
    }

    #[test]
    fn a_jpeg_is_a_compressed_image_whose_size_comes_from_its_frame_header() {
        // The smallest parts of a JPEG file: SOI, an APP0 segment, SOF0 of 640 × 480.
        let mut jpeg = vec![0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x04, 0x00, 0x00];
        jpeg.extend([0xFF, 0xC0, 0x00, 0x11, 0x08, 0x01, 0xE0, 0x02, 0x80, 0x03]);
        jpeg.extend([0; 9]);
        let value = Image {
            width: 640,
            height: 480,
            ..image(ImageEncoding::Jpeg, jpeg.clone())
        };
        let json = to_json(&value);
        let fields: serde_json::Value = serde_json::from_slice(&json).expect("json");
        assert_eq!(fields["format"], "jpeg");
        assert!(fields.get("width").is_none(), "CompressedImage has no size");
        assert_eq!(from_json(&json), Ok(value));
        assert_eq!(jpeg_size(&jpeg[..12]), None, "cut in the frame header");
        assert_eq!(jpeg_size(b"GIF89a"), None);
    }

    #[test]
    fn what_is_not_an_image_is_refused_in_words() {
        let bad = |json: serde_json::Value| {
            from_json(&serde_json::to_vec(&json).expect("json")).expect_err("refused")
        };
        let time = json!({"sec": 1, "nsec": 0});
        let raw = |encoding: &str, step: u32, data: &str| {
            json!({"timestamp": time, "frame_id": "", "width": 2, "height": 1,
                   "encoding": encoding, "step": step, "data": data})
        };
        assert!(bad(raw("bgr8", 6, "AAAAAAAA")).contains("encoding `bgr8`"));
        assert!(bad(raw("mono8", 4, "AAA=")).contains("padded rows"));
        assert!(bad(raw("mono8", 2, "AAAA")).contains("3 bytes of mono8"));
        assert!(bad(raw("mono8", 2, "!!")).contains("not base64"));
        let png = json!({"timestamp": time, "frame_id": "", "data": "", "format": "png"});
        assert!(bad(png).contains("format `png`"));
        assert!(from_json(b"{").expect_err("cut").contains("not JSON"));
    }
}
