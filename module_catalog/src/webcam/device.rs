//! A V4L2 capture device through the `v4l` crate: opened, checked to capture video, set to the
//! size, pixel format and rate asked (the driver may choose the nearest it has), and read from
//! memory-mapped buffers. Once streaming, a frame is taken only when the device's descriptor is
//! readable (waited on with mio for at most a tenth of a second), so that the module's loop
//! keeps answering its supervisor while the camera is slow; the `v4l` stream's own timeout is
//! not used, as a timed-out read leaves its buffer queue in a state the next read fails on.

use std::time::Duration;

use mio::unix::SourceFd;
use mio::{Events, Interest, Poll, Token};

use v4l::buffer::Type;
use v4l::capability::Flags;
use v4l::io::mmap::Stream;
use v4l::io::traits::CaptureStream as _;
use v4l::video::Capture as _;
use v4l::{Device, FourCC};

use super::{FrameSource, PixelFormat, Settings};

/// Buffers the driver fills in turn.
const BUFFERS: u32 = 4;

/// How long one wait for a frame lasts.
const WAIT: Duration = Duration::from_millis(100);

/// An open camera, streaming.
pub struct V4l2Source {
    stream: Stream<'static>,
    /// Readiness of the device's descriptor, once the first frame came.
    poll: Poll,
    events: Events,
    started: bool,
    format: PixelFormat,
    width: u32,
    height: u32,
}

impl V4l2Source {
    /// Opens `settings.device` and starts streaming; the error says what is missing, in words.
    pub fn open(settings: &Settings) -> Result<Self, String> {
        let path = &settings.device;
        let device =
            Device::with_path(path).map_err(|err| format!("no camera at {path}: {err}"))?;
        let caps = device
            .query_caps()
            .map_err(|err| format!("{path} is not a V4L2 device: {err}"))?;
        if !caps
            .capabilities
            .contains(Flags::VIDEO_CAPTURE | Flags::STREAMING)
        {
            return Err(format!(
                "{path} ({}, driver {}) cannot stream video captures",
                caps.card, caps.driver
            ));
        }
        let mut format = device
            .format()
            .map_err(|err| format!("{path}: cannot read its format: {err}"))?;
        format.width = settings.width;
        format.height = settings.height;
        format.fourcc = FourCC::new(settings.format.fourcc());
        let format = device
            .set_format(&format)
            .map_err(|err| format!("{path}: cannot set {}: {err}", settings.format.name()))?;
        let pixel_format = PixelFormat::from_fourcc(&format.fourcc.repr).ok_or_else(|| {
            format!(
                "{path} offers {} instead of {}; `format` takes mjpeg or yuyv",
                format.fourcc,
                settings.format.name()
            )
        })?;
        let fps = settings.rate_hz.round().max(1.0) as u32;
        if let Err(err) = device.set_params(&v4l::video::capture::Parameters::with_fps(fps)) {
            tracing::warn!("{path}: cannot ask for {fps} frames a second ({err}): taking its rate");
        }
        // The stream borrows the device for its whole life, which is the module's.
        let device: &'static Device = Box::leak(Box::new(device));
        let stream = Stream::with_buffers(device, Type::VideoCapture, BUFFERS)
            .map_err(|err| format!("{path}: cannot map capture buffers: {err}"))?;
        let poll = Poll::new().map_err(|err| format!("cannot watch {path}: {err}"))?;
        let fd = device.handle().fd();
        poll.registry()
            .register(&mut SourceFd(&fd), Token(0), Interest::READABLE)
            .map_err(|err| format!("cannot watch {path}: {err}"))?;
        tracing::info!(
            "capturing from {path} ({}): {}×{} {}",
            caps.card,
            format.width,
            format.height,
            pixel_format.name()
        );
        Ok(Self {
            stream,
            poll,
            events: Events::with_capacity(4),
            started: false,
            format: pixel_format,
            width: format.width,
            height: format.height,
        })
    }
}

impl FrameSource for V4l2Source {
    fn format(&self) -> (PixelFormat, u32, u32) {
        (self.format, self.width, self.height)
    }

    fn next_frame(&mut self, frame: &mut Vec<u8>) -> std::io::Result<bool> {
        // Before the first read no buffer is queued, so the descriptor cannot be ready: the
        // first read starts the stream and waits for its frame.
        if self.started {
            self.poll.poll(&mut self.events, Some(WAIT))?;
            if self.events.is_empty() {
                return Ok(false);
            }
        }
        let (buffer, meta) = self.stream.next()?;
        self.started = true;
        let used = (meta.bytesused as usize).min(buffer.len());
        frame.clear();
        frame.extend_from_slice(&buffer[..used]);
        Ok(true)
    }
}
