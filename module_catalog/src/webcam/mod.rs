//! `webcam`: a V4L2 camera of a real robot, through the `linuxvideo` crate ([`device`]), published as
//! `Image`s: a camera's Motion-JPEG frames as they come (`jpeg`), or its YUYV frames converted
//! to `rgb8`. Device, size, pixel format and rate are parameters.
//!
//! A camera that is not there (no such device, not a video capture device, no format the
//! module reads) is a clear error in the log, and the module then ends normally: restarting it
//! would fail the same way, so the supervisor (whose default policy restarts only modules that
//! fail) leaves it ended instead of restarting it in a loop. A camera that fails while
//! streaming (unplugged) is a failure: the module exits with an error and is restarted, and
//! finds the device again if it came back.
//!
//! The loop ([`capture`]) reads any [`FrameSource`], so that it is tested with a fake camera.

pub mod device;

use std::time::Duration;

use armor_module_api::types::{Image, ImageEncoding};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;

pub const TYPE: &str = "webcam";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "A V4L2 camera (a webcam, a robot's camera) published as images: Motion-JPEG frames as \
         they come, or YUYV frames as rgb8.",
    )
    .category(armor_module_api::Category::Sensor)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .output::<Image>(
        "image",
        "each frame, stamped with the run time it was read at",
    )
    .param(
        ParamSpec::new("device", ParamType::String, "the camera's device file")
            .default("/dev/video0"),
    )
    .param(
        ParamSpec::new(
            "width",
            ParamType::Int,
            "image width asked of the camera (it may choose the nearest it has)",
        )
        .min(16.0)
        .max(8192.0)
        .unit("px")
        .default("640"),
    )
    .param(
        ParamSpec::new("height", ParamType::Int, "image height asked of the camera")
            .min(16.0)
            .max(8192.0)
            .unit("px")
            .default("480"),
    )
    .param(
        ParamSpec::new(
            "rate_hz",
            ParamType::Float,
            "frames per second asked of the camera",
        )
        .min(1.0)
        .max(240.0)
        .unit("Hz")
        .default("15"),
    )
    .param(
        ParamSpec::new(
            "format",
            ParamType::String,
            "pixel format asked of the camera: `mjpeg` (published as jpeg, no conversion) or \
             `yuyv` (converted to rgb8)",
        )
        .choices(&["mjpeg", "yuyv"])
        .default("mjpeg"),
    )
    .param(crate::camera::frame_id_param())
}

/// The pixel formats the module reads from a camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PixelFormat {
    /// Motion-JPEG: each frame a JPEG file.
    Mjpeg,
    /// YUYV 4:2:2: two pixels in four bytes (Y0 U Y1 V).
    Yuyv,
}

impl PixelFormat {
    pub fn name(self) -> &'static str {
        match self {
            Self::Mjpeg => "mjpeg",
            Self::Yuyv => "yuyv",
        }
    }

    /// The V4L2 four-character code.
    pub fn fourcc(self) -> &'static [u8; 4] {
        match self {
            Self::Mjpeg => b"MJPG",
            Self::Yuyv => b"YUYV",
        }
    }

    pub fn from_fourcc(code: &[u8; 4]) -> Option<Self> {
        [Self::Mjpeg, Self::Yuyv]
            .into_iter()
            .find(|format| format.fourcc() == code)
    }
}

/// The module's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub device: String,
    pub width: u32,
    pub height: u32,
    pub rate_hz: f64,
    pub format: PixelFormat,
    pub frame_id: String,
}

impl Settings {
    pub fn from_node(node: &Node) -> Result<Self, BodyError> {
        let format: String = node.param("format")?;
        Ok(Self {
            device: node.param("device")?,
            width: node.param("width")?,
            height: node.param("height")?,
            rate_hz: node.param("rate_hz")?,
            format: match format.as_str() {
                "yuyv" => PixelFormat::Yuyv,
                _ => PixelFormat::Mjpeg,
            },
            frame_id: node.param("frame_id")?,
        })
    }
}

/// Where frames come from: a V4L2 device ([`device::V4l2Source`]) or a test's fake camera.
pub trait FrameSource {
    /// The pixel format, width and height of the frames.
    fn format(&self) -> (PixelFormat, u32, u32);
    /// Waits a short while (a tenth of a second at most, once streaming) for the next frame
    /// and puts its bytes in `frame`; `false` if none came in that time.
    fn next_frame(&mut self, frame: &mut Vec<u8>) -> std::io::Result<bool>;
}

pub fn body(node: &mut Node) -> BodyResult {
    let settings = Settings::from_node(node)?;
    let mut source = match device::V4l2Source::open(&settings) {
        Ok(source) => source,
        Err(why) => {
            tracing::error!(
                "{why}: nothing to capture, so the module ends (it is not restarted; fix \
                 `device` or plug the camera in, then start it again)"
            );
            return Ok(());
        }
    };
    capture(node, &mut source, &settings)
}

/// Publishes every frame of `source` until shutdown.
pub fn capture(node: &mut Node, source: &mut impl FrameSource, settings: &Settings) -> BodyResult {
    let output = node.output::<Image>("image")?;
    let (format, width, height) = source.format();
    let mut raw = Vec::new();
    let mut image = Image {
        width,
        height,
        encoding: match format {
            PixelFormat::Mjpeg => ImageEncoding::Jpeg,
            PixelFormat::Yuyv => ImageEncoding::Rgb8,
        },
        stamp_ns: 0,
        frame_id: settings.frame_id.clone(),
        data: Default::default(),
    };
    let mut refused = 0_u64;
    loop {
        // What the supervisor sent since the last frame, without waiting.
        loop {
            match node.next_event(Some(Duration::ZERO))? {
                Event::Shutdown => return Ok(()),
                Event::Timeout => break,
                Event::ParamsChanged(names) => tracing::warn!(
                    "new values of {} are taken when the module restarts",
                    names.join(", ")
                ),
                _ => {}
            }
        }
        if !source.next_frame(&mut raw)? {
            continue;
        }
        image.stamp_ns = (node.timestamp().max(0.0) * 1e9) as u64;
        let taken = match format {
            PixelFormat::Mjpeg => {
                std::mem::swap(image.data.as_mut_vec(), &mut raw);
                image.check()
            }
            PixelFormat::Yuyv => yuyv_to_rgb(&raw, width, height, image.data.as_mut_vec()),
        };
        match taken {
            Ok(()) => node.send(&output, &image)?,
            Err(why) => {
                refused += 1;
                if refused.is_power_of_two() {
                    tracing::warn!("a frame was not published ({refused} so far): {why}");
                }
            }
        }
    }
}

/// RGB of a YUYV 4:2:2 frame (ITU-R BT.601, studio range), rows without padding.
pub fn yuyv_to_rgb(yuyv: &[u8], width: u32, height: u32, rgb: &mut Vec<u8>) -> Result<(), String> {
    let pixels = width as usize * height as usize;
    if !width.is_multiple_of(2) || yuyv.len() < pixels * 2 {
        return Err(format!(
            "{} bytes of YUYV for {width}×{height} pixels, not {}",
            yuyv.len(),
            pixels * 2
        ));
    }
    rgb.clear();
    rgb.reserve(pixels * 3);
    let clamp = |value: i32| value.clamp(0, 255) as u8;
    for quad in yuyv[..pixels * 2].chunks_exact(4) {
        let (u, v) = (i32::from(quad[1]) - 128, i32::from(quad[3]) - 128);
        for y in [quad[0], quad[2]] {
            let c = 298 * (i32::from(y) - 16);
            rgb.push(clamp((c + 409 * v + 128) >> 8));
            rgb.push(clamp((c - 100 * u - 208 * v + 128) >> 8));
            rgb.push(clamp((c + 516 * u + 128) >> 8));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};

    /// A camera that hands out these frames, one per read, then times out.
    struct FakeCamera {
        format: PixelFormat,
        frames: Vec<Vec<u8>>,
    }

    impl FrameSource for FakeCamera {
        fn format(&self) -> (PixelFormat, u32, u32) {
            (self.format, 4, 2)
        }

        fn next_frame(&mut self, frame: &mut Vec<u8>) -> std::io::Result<bool> {
            if self.frames.is_empty() {
                return Ok(false);
            }
            *frame = self.frames.remove(0);
            Ok(true)
        }
    }

    fn settings(format: PixelFormat) -> Settings {
        Settings {
            device: "fake".into(),
            width: 4,
            height: 2,
            rate_hz: 15.0,
            format,
            frame_id: "front".into(),
        }
    }

    #[test]
    fn yuyv_white_black_and_grey_become_rgb() {
        // Y 235 is white and 16 black in studio range; U = V = 128 is no colour.
        let mut rgb = Vec::new();
        yuyv_to_rgb(&[235, 128, 16, 128, 126, 128, 126, 128], 4, 1, &mut rgb).expect("converts");
        assert_eq!(rgb, [255, 255, 255, 0, 0, 0, 128, 128, 128, 128, 128, 128]);
        // Pure red of BT.601: Y 81, U 90, V 240.
        yuyv_to_rgb(&[81, 90, 81, 240], 2, 1, &mut rgb).expect("converts");
        assert!(rgb[0] > 250 && rgb[1] < 5 && rgb[2] < 5, "{rgb:?}");
        let err = yuyv_to_rgb(&[0; 6], 2, 2, &mut rgb).expect_err("short");
        assert!(
            err.contains("6 bytes of YUYV for 2×2 pixels, not 8"),
            "{err}"
        );
    }

    #[test]
    fn the_loop_publishes_each_frame_of_a_fake_camera() {
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        // Three turns of the loop, then shutdown.
        bench.script([Step::Timeouts(3)]);
        let mut camera = FakeCamera {
            format: PixelFormat::Yuyv,
            frames: vec![[235, 128, 235, 128].repeat(4), vec![0; 3]],
        };
        capture(bench.node(), &mut camera, &settings(PixelFormat::Yuyv)).expect("runs");
        let sent = bench.sent::<Image>("image").expect("images");
        assert_eq!(sent.len(), 1, "the short frame is not published");
        assert_eq!(
            (
                sent[0].width,
                sent[0].height,
                sent[0].encoding,
                &*sent[0].frame_id
            ),
            (4, 2, ImageEncoding::Rgb8, "front")
        );
        assert_eq!(*sent[0].data, [255; 24]);
    }

    #[test]
    fn motion_jpeg_frames_go_out_as_they_came() {
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        bench.script([Step::Timeouts(3)]);
        let jpeg = vec![0xFF, 0xD8, 0xFF, 0xD9];
        let mut camera = FakeCamera {
            format: PixelFormat::Mjpeg,
            frames: vec![jpeg.clone(), Vec::new(), jpeg.clone()],
        };
        capture(bench.node(), &mut camera, &settings(PixelFormat::Mjpeg)).expect("runs");
        let sent = bench.sent::<Image>("image").expect("images");
        let data: Vec<_> = sent.iter().map(|image| image.data.to_vec()).collect();
        assert_eq!(data, [jpeg.clone(), jpeg], "the empty frame is dropped");
        assert!(
            sent.iter()
                .all(|image| image.encoding == ImageEncoding::Jpeg)
        );
    }

    #[test]
    fn no_camera_is_a_clear_error_and_a_normal_end() {
        for (device, words) in [
            ("/nonexistent/video7", "no camera at /nonexistent/video7"),
            ("/dev/null", "/dev/null is not a V4L2 device"),
        ] {
            let mut bench = TestBench::new(&spec(), &[("device", device)]).expect("bench");
            let mut settings = settings(PixelFormat::Mjpeg);
            settings.device = device.into();
            let err = device::V4l2Source::open(&settings)
                .err()
                .expect("no camera there");
            assert!(err.starts_with(words), "{err}");
            assert!(body(bench.node()).is_ok(), "{device}: ends normally");
            assert!(bench.sent::<Image>("image").expect("none").is_empty());
        }
    }
}
