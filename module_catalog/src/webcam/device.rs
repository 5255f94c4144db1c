//! A V4L2 capture device through the `linuxvideo` crate (pure Rust: its kernel structures are
//! written out in the crate, so building it needs no libclang and no kernel headers): opened,
//! checked to capture video, set to the size, pixel format and rate asked (the driver may choose
//! the nearest it has), and read from memory-mapped buffers. A frame is taken only when the
//! device's descriptor is readable (waited on with mio for at most a tenth of a second), so that
//! the module's loop keeps answering its supervisor while the camera is slow.

use std::os::fd::AsRawFd as _;
use std::time::Duration;

use linuxvideo::format::{PixFormat, PixelFormat as V4l2PixelFormat};
use linuxvideo::stream::ReadStream;
use linuxvideo::{CapabilityFlags, Device, Fract};
use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token};

use super::{FrameSource, PixelFormat, Settings};

/// How long one wait for a frame lasts.
const WAIT: Duration = Duration::from_millis(100);

/// An open camera, streaming.
pub struct V4l2Source {
    stream: ReadStream,
    /// Readiness of the device's descriptor.
    poll: Poll,
    events: Events,
    format: PixelFormat,
    width: u32,
    height: u32,
}

impl V4l2Source {
    /// Opens `settings.device` and starts streaming; the error says what is missing, in words.
    pub fn open(settings: &Settings) -> Result<Self, String> {
        let path = &settings.device;
        // `Device::open` asks the driver for its capabilities at once, so a file that is not a
        // V4L2 device fails there, with the ioctl refused (ENOTTY).
        let device = Device::open(path).map_err(|err| {
            if err.raw_os_error() == Some(libc::ENOTTY) {
                format!("{path} is not a V4L2 device: {err}")
            } else {
                format!("no camera at {path}: {err}")
            }
        })?;
        let caps = device
            .capabilities()
            .map_err(|err| format!("{path} is not a V4L2 device: {err}"))?;
        if !caps
            .device_capabilities()
            .contains(CapabilityFlags::VIDEO_CAPTURE | CapabilityFlags::STREAMING)
        {
            return Err(format!(
                "{path} ({}, driver {}) cannot stream video captures",
                caps.card(),
                caps.driver()
            ));
        }
        let asked = PixFormat::new(
            settings.width,
            settings.height,
            V4l2PixelFormat::from_fourcc(*settings.format.fourcc()),
        );
        let capture = device
            .video_capture(asked)
            .map_err(|err| format!("{path}: cannot set {}: {err}", settings.format.name()))?;
        let chosen = capture.format();
        let fourcc = chosen.pixel_format().as_fourcc();
        let pixel_format = PixelFormat::from_fourcc(&fourcc).ok_or_else(|| {
            format!(
                "{path} offers {} instead of {}; `format` takes mjpeg or yuyv",
                chosen.pixel_format(),
                settings.format.name()
            )
        })?;
        let (width, height) = (chosen.width(), chosen.height());
        let fps = settings.rate_hz.round().max(1.0) as u32;
        if let Err(err) = capture.set_frame_interval(Fract::new(1, fps)) {
            tracing::warn!("{path}: cannot ask for {fps} frames a second ({err}): taking its rate");
        }
        let stream = capture
            .into_stream()
            .map_err(|err| format!("{path}: cannot map capture buffers: {err}"))?;
        let poll = Poll::new().map_err(|err| format!("cannot watch {path}: {err}"))?;
        poll.registry()
            .register(
                &mut SourceFd(&stream.as_raw_fd()),
                Token(0),
                Interest::READABLE,
            )
            .map_err(|err| format!("cannot watch {path}: {err}"))?;
        tracing::info!(
            "capturing from {path} ({}): {width}×{height} {}",
            caps.card(),
            pixel_format.name()
        );
        Ok(Self {
            stream,
            poll,
            events: Events::with_capacity(4),
            format: pixel_format,
            width,
            height,
        })
    }
}

impl FrameSource for V4l2Source {
    fn format(&self) -> (PixelFormat, u32, u32) {
        (self.format, self.width, self.height)
    }

    fn next_frame(&mut self, frame: &mut Vec<u8>) -> std::io::Result<bool> {
        // The stream is on and its buffers queued from the start, so the descriptor turns
        // readable as soon as the driver has filled one.
        self.poll.poll(&mut self.events, Some(WAIT))?;
        if self.events.is_empty() {
            return Ok(false);
        }
        self.stream.dequeue(|buffer| {
            frame.clear();
            frame.extend_from_slice(&buffer);
            Ok(())
        })?;
        Ok(true)
    }
}
