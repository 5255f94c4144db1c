//! [`Image`]: a camera frame. Its encoding is postcard's for the struct (so a module in another
//! language writes it from docs/protocol.md alone), and the pixels come last, as a byte
//! sequence: a large image is sent from the module's own buffer, and a received one keeps the
//! frame's buffer as its pixels, where they arrived ([`Pixels`]: moving them to the front of
//! the buffer, past the few bytes of head, would copy the whole frame once more).

use std::ops::Deref;

use serde::{Deserialize, Serialize};

use super::{CodecError, Datum, postcard_encode};

const TYPE: &str = "Image";

/// How an [`Image`]'s `data` holds its pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ImageEncoding {
    /// Three bytes a pixel (red, green, blue), rows top to bottom, no padding.
    Rgb8,
    /// One byte a pixel (grey level), rows top to bottom, no padding.
    Mono8,
    /// A JPEG file (JFIF), whose own header gives its size.
    Jpeg,
}

impl ImageEncoding {
    pub const ALL: [ImageEncoding; 3] = [Self::Rgb8, Self::Mono8, Self::Jpeg];

    /// The name on the wire (and in Foxglove's and ROS's image messages).
    pub fn name(self) -> &'static str {
        match self {
            Self::Rgb8 => "rgb8",
            Self::Mono8 => "mono8",
            Self::Jpeg => "jpeg",
        }
    }

    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|encoding| encoding.name() == name)
    }

    /// Bytes a pixel of a raw encoding; `None` for a compressed one.
    pub fn bytes_per_pixel(self) -> Option<usize> {
        match self {
            Self::Rgb8 => Some(3),
            Self::Mono8 => Some(1),
            Self::Jpeg => None,
        }
    }
}

/// A camera frame: `width` × `height` pixels, taken at `stamp_ns` (run time) by the camera
/// whose frame of reference is `frame_id`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub encoding: ImageEncoding,
    /// Run time of the capture, in nanoseconds (the sample's own stamp is when it was sent).
    pub stamp_ns: u64,
    pub frame_id: String,
    /// `width × height × bytes a pixel` bytes for a raw encoding, a whole file for JPEG.
    pub data: Pixels,
}

/// An image's bytes, in a buffer that may hold something before them (the rest of the frame
/// they arrived in). Reads as a byte slice; [`Pixels::as_mut_vec`] gives a vector to fill.
#[derive(Clone, Default)]
pub struct Pixels {
    buf: Vec<u8>,
    start: usize,
}

impl Pixels {
    /// The bytes as a vector to fill or replace (what the buffer held before them is dropped
    /// first: a move, once).
    pub fn as_mut_vec(&mut self) -> &mut Vec<u8> {
        if self.start > 0 {
            self.buf.drain(..self.start);
            self.start = 0;
        }
        &mut self.buf
    }

    pub fn into_vec(mut self) -> Vec<u8> {
        std::mem::take(self.as_mut_vec())
    }
}

impl Deref for Pixels {
    type Target = [u8];
    fn deref(&self) -> &[u8] {
        &self.buf[self.start..]
    }
}

impl AsRef<[u8]> for Pixels {
    fn as_ref(&self) -> &[u8] {
        self
    }
}

impl From<Vec<u8>> for Pixels {
    fn from(buf: Vec<u8>) -> Self {
        Self { buf, start: 0 }
    }
}

impl FromIterator<u8> for Pixels {
    fn from_iter<I: IntoIterator<Item = u8>>(bytes: I) -> Self {
        Vec::from_iter(bytes).into()
    }
}

impl PartialEq for Pixels {
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl Eq for Pixels {}

impl PartialEq<[u8]> for Pixels {
    fn eq(&self, other: &[u8]) -> bool {
        **self == *other
    }
}

impl PartialEq<Vec<u8>> for Pixels {
    fn eq(&self, other: &Vec<u8>) -> bool {
        **self == **other
    }
}

impl std::fmt::Debug for Pixels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} bytes", self.len())
    }
}

/// Everything before the pixels, as postcard writes it: the pixels' length is the varint
/// postcard puts before a byte sequence.
#[derive(Serialize, Deserialize)]
struct Head<'a> {
    width: u32,
    height: u32,
    encoding: &'a str,
    stamp_ns: u64,
    frame_id: &'a str,
    data_len: u64,
}

impl Image {
    /// Checks that `data` holds what the encoding and size say.
    pub fn check(&self) -> Result<(), String> {
        let (width, height) = (self.width as usize, self.height as usize);
        if width == 0 || height == 0 {
            return Err(format!("{}×{} pixels: the image is empty", width, height));
        }
        match self.encoding.bytes_per_pixel() {
            Some(bytes) => {
                let expected = width.saturating_mul(height).saturating_mul(bytes);
                if self.data.len() != expected {
                    return Err(format!(
                        "{} bytes of {} pixels for {width}×{height}, not {expected}",
                        self.data.len(),
                        self.encoding.name()
                    ));
                }
            }
            None if self.data.is_empty() => {
                return Err(format!("no bytes of {}", self.encoding.name()));
            }
            None => {}
        }
        Ok(())
    }

    fn head(&self) -> Head<'_> {
        Head {
            width: self.width,
            height: self.height,
            encoding: self.encoding.name(),
            stamp_ns: self.stamp_ns,
            frame_id: &self.frame_id,
            data_len: self.data.len() as u64,
        }
    }

    /// Reads the head; returns the image with empty `data` and where the pixels start.
    fn decode_head(bytes: &[u8]) -> Result<(Image, usize), CodecError> {
        let error = |reason: String| CodecError {
            action: "decode",
            data_type: TYPE,
            reason,
        };
        let (head, rest) =
            postcard::take_from_bytes::<Head>(bytes).map_err(|err| error(err.to_string()))?;
        let encoding = ImageEncoding::from_name(head.encoding).ok_or_else(|| {
            error(format!(
                "unknown encoding `{}` (rgb8, mono8 or jpeg)",
                head.encoding
            ))
        })?;
        if head.data_len != rest.len() as u64 {
            return Err(error(format!(
                "{} bytes of pixels announced, {} there",
                head.data_len,
                rest.len()
            )));
        }
        let image = Image {
            width: head.width,
            height: head.height,
            encoding,
            stamp_ns: head.stamp_ns,
            frame_id: head.frame_id.to_owned(),
            data: Pixels::default(),
        };
        Ok((image, bytes.len() - rest.len()))
    }

    fn checked(self) -> Result<Self, CodecError> {
        self.check().map_err(|reason| CodecError {
            action: "decode",
            data_type: TYPE,
            reason,
        })?;
        Ok(self)
    }
}

impl Datum for Image {
    const TYPE: &'static str = TYPE;

    fn encode(&self, out: &mut Vec<u8>) -> Result<(), CodecError> {
        postcard_encode(&self.head(), out, TYPE)?;
        out.extend_from_slice(&self.data);
        Ok(())
    }

    fn decode(bytes: &[u8]) -> Result<Self, CodecError> {
        let (mut image, start) = Self::decode_head(bytes)?;
        image.data = bytes[start..].to_vec().into();
        image.checked()
    }

    fn decode_owned(bytes: Vec<u8>) -> Result<Self, CodecError> {
        let (mut image, start) = Self::decode_head(&bytes)?;
        // The pixels stay where they came: no copy.
        image.data = Pixels { buf: bytes, start };
        image.checked()
    }

    fn split_encoding(&self, head: &mut Vec<u8>) -> Option<&[u8]> {
        postcard_encode(&self.head(), head, TYPE).ok()?;
        Some(&self.data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(encoding: ImageEncoding, data: Vec<u8>) -> Image {
        Image {
            width: 4,
            height: 2,
            encoding,
            stamp_ns: 1_500_000_000,
            frame_id: "camera".into(),
            data: data.into(),
        }
    }

    #[test]
    fn the_encoding_is_postcard_of_the_fields_in_order() {
        let value = image(ImageEncoding::Mono8, (0..8).collect());
        let mut out = Vec::new();
        value.encode(&mut out).expect("encode");
        let mut expected = vec![4, 2, 5];
        expected.extend(b"mono8");
        expected.extend([0x80, 0xDE, 0xA0, 0xCB, 0x05]); // 1.5e9 as a varint
        expected.push(6);
        expected.extend(b"camera");
        expected.push(8);
        expected.extend(0..8);
        assert_eq!(out, expected);
        assert_eq!(Image::decode(&out).expect("decode"), value);
        assert_eq!(Image::decode_owned(out).expect("decode owned"), value);
    }

    #[test]
    fn the_example_of_the_protocol_document_decodes() {
        let bytes = [
            0x02, 0x01, 0x05, 0x6D, 0x6F, 0x6E, 0x6F, 0x38, 0x80, 0xDE, 0xA0, 0xCB, 0x05, 0x03,
            0x63, 0x61, 0x6D, 0x02, 0x0A, 0x14,
        ];
        let expected = Image {
            width: 2,
            height: 1,
            encoding: ImageEncoding::Mono8,
            stamp_ns: 1_500_000_000,
            frame_id: "cam".into(),
            data: vec![10, 20].into(),
        };
        assert_eq!(Image::decode(&bytes).expect("decode"), expected);
        let owned = Image::decode_owned(bytes.to_vec()).expect("decode owned");
        assert_eq!(owned, expected);
        assert_eq!(owned.data.into_vec(), [10, 20]);
    }

    #[test]
    fn split_encoding_gives_the_head_and_the_pixels_in_place() {
        let value = image(ImageEncoding::Rgb8, vec![9; 24]);
        let mut whole = Vec::new();
        value.encode(&mut whole).expect("encode");
        let mut head = Vec::new();
        let pixels = value.split_encoding(&mut head).expect("split");
        assert!(std::ptr::eq(pixels, &*value.data));
        assert_eq!([head.as_slice(), pixels].concat(), whole);
    }

    #[test]
    fn a_wrong_size_an_unknown_encoding_or_a_cut_is_refused_in_words() {
        let mut out = Vec::new();
        image(ImageEncoding::Rgb8, vec![0; 23])
            .encode(&mut out)
            .expect("encode");
        let err = Image::decode(&out).expect_err("one byte short");
        assert!(err.to_string().contains("23 bytes of rgb8"), "{err}");
        let mut out = Vec::new();
        image(ImageEncoding::Jpeg, vec![0xFF, 0xD8])
            .encode(&mut out)
            .expect("encode");
        assert!(Image::decode(&out[..out.len() - 1]).is_err());
        let at = out.iter().position(|&b| b == b'j').expect("name");
        out[at] = b'p';
        let err = Image::decode(&out).expect_err("unknown");
        assert!(err.to_string().contains("unknown encoding `ppeg`"), "{err}");
        assert!(image(ImageEncoding::Jpeg, Vec::new()).check().is_err());
    }
}
