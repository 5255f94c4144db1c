//! `image_640x480_latency_ms` and `image_640x480_fps`: camera frames of 640×480 `rgb8` (921,600
//! bytes of pixels) through one ArMoR link, between two nodes on two threads of this process
//! (the publisher sends from the image's own buffer; the subscriber, reliable, decodes each into
//! an `Image`), against raw TCP moving the same bytes between two threads in the same run
//! (`TCP_NODELAY`, blocking writes of whole frames, reads into one reused buffer).
//!
//! Latency: one frame in flight, from the send to the subscriber holding the whole frame
//! (p50, p99 in milliseconds; goal ratio <= 1.2). Rate: frames sent back to back, from the
//! first send to the last frame received (the median of a few rounds, frames a second; goal
//! ratio >= 0.8). Blocks of each side alternate, so that the machine's load weighs on both.

use std::io::{Read as _, Write as _};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, RecvTimeoutError, Sender, channel};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use armor_module_api::types::{Image, ImageEncoding};
use armor_module_api::{Event, ModuleSpec, Node, Output, Standalone};

use crate::Settings;
use crate::harness::{LINK_TIMEOUT, STALL_TIMEOUT, agent, connect};
use armor_bench_report::{Report, median};

pub const NAME_LATENCY: &str = "image_640x480_latency_ms";
pub const NAME_FPS: &str = "image_640x480_fps";
const WIDTH: u32 = 640;
const HEIGHT: u32 = 480;
const PIXEL_BYTES: usize = (WIDTH * HEIGHT * 3) as usize;

/// A frame's number and when the receiving side held it whole.
type Arrival = (u64, Instant);

pub fn run_latency(settings: &Settings) -> anyhow::Result<Report> {
    let (block, blocks) = if settings.quick { (5, 2) } else { (40, 10) };
    let mut armor = ArmorLink::start()?;
    let mut raw = RawLink::start()?;
    armor.latencies(10)?;
    raw.latencies(10)?;
    let (mut ours, mut reference) = (Vec::new(), Vec::new());
    for _ in 0..blocks {
        ours.extend(armor.latencies(block)?);
        reference.extend(raw.latencies(block)?);
    }
    armor.finish()?;
    raw.finish()?;
    Ok(
        Report::distribution(NAME_LATENCY, "ms", 1e3, &ours, &reference)
            .with("bytes", PIXEL_BYTES)
            .with("goal_ratio_at_most", 1.2),
    )
}

pub fn run_fps(settings: &Settings) -> anyhow::Result<Report> {
    let (frames, rounds) = if settings.quick { (20, 1) } else { (400, 5) };
    let mut armor = ArmorLink::start()?;
    let mut raw = RawLink::start()?;
    armor.rate(frames / 4)?;
    raw.rate(frames / 4)?;
    let (mut ours, mut reference) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        ours.push(armor.rate(frames)?);
        reference.push(raw.rate(frames)?);
    }
    armor.finish()?;
    raw.finish()?;
    Ok(
        Report::single(NAME_FPS, "frames/s", median(&ours), median(&reference))
            .with("bytes", PIXEL_BYTES)
            .with("frames", frames)
            .with("goal_ratio_at_least", 0.8),
    )
}

/// Waits for the arrival of frame `number`, skipping earlier ones.
fn arrival_of(arrivals: &Receiver<Arrival>, number: u64) -> anyhow::Result<Instant> {
    loop {
        match arrivals.recv_timeout(STALL_TIMEOUT) {
            Ok((got, at)) if got == number => return Ok(at),
            Ok(_) => {}
            Err(RecvTimeoutError::Timeout) => bail!("frame {number} never arrived"),
            Err(RecvTimeoutError::Disconnected) => bail!("the receiving side ended"),
        }
    }
}

/// The bench's node publishing `bench.image`, and a viewer node on a thread of its own.
struct ArmorLink {
    node: Node,
    output: Output<Image>,
    image: Image,
    number: u64,
    arrivals: Receiver<Arrival>,
    stop: Arc<AtomicBool>,
    viewer: Option<JoinHandle<anyhow::Result<()>>>,
}

impl ArmorLink {
    fn start() -> anyhow::Result<Self> {
        let agent = agent()?;
        let spec = ModuleSpec::new("bench", "armor-bench: the camera")
            .output::<Image>("image", "640×480 rgb8 frames, numbered by their stamp");
        let node = connect(spec, agent, &[])?;
        let output = node.output::<Image>("image")?;
        let (arrived, arrivals) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let viewer = {
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || view(agent, &arrived, &stop))
        };
        let mut link = Self {
            node,
            output,
            image: Image {
                width: WIDTH,
                height: HEIGHT,
                encoding: ImageEncoding::Rgb8,
                stamp_ns: 0,
                frame_id: "bench".into(),
                data: (0..PIXEL_BYTES).map(|i| (i % 251) as u8).collect(),
            },
            number: 0,
            arrivals,
            stop,
            viewer: Some(viewer),
        };
        let give_up = Instant::now() + LINK_TIMEOUT;
        while link.node.subscriber_count(&link.output) == 0 {
            if Instant::now() >= give_up {
                bail!("the viewer did not subscribe within {LINK_TIMEOUT:?}");
            }
            link.node.next_event(Some(Duration::from_millis(10)))?;
        }
        Ok(link)
    }

    fn send(&mut self) -> anyhow::Result<u64> {
        self.number += 1;
        self.image.stamp_ns = self.number;
        self.node.send(&self.output, &self.image)?;
        self.node.flush()?;
        Ok(self.number)
    }

    /// Waits for frame `number` on the viewer's channel, as the reference waits on its reader's,
    /// and serves the node between waits (it writes what the socket did not take at once, if
    /// anything). Waiting in the node's poll instead (as until 2026-11-24) noticed an arrival
    /// only when the poll timed out, a millisecond later (epoll counts in milliseconds), so the
    /// next frame went out from colder caches than the reference's.
    fn await_arrival(&mut self, number: u64) -> anyhow::Result<Instant> {
        let give_up = Instant::now() + STALL_TIMEOUT;
        loop {
            match self.arrivals.recv_timeout(Duration::from_millis(1)) {
                Ok((got, at)) if got == number => return Ok(at),
                Ok(_) => continue,
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => bail!("the viewer ended"),
            }
            if Instant::now() >= give_up {
                bail!("frame {number} never arrived");
            }
            self.node.next_event(Some(Duration::ZERO))?;
        }
    }

    fn latencies(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        let mut samples = Vec::with_capacity(count);
        for _ in 0..count {
            let start = Instant::now();
            let number = self.send()?;
            samples.push(self.await_arrival(number)? - start);
        }
        Ok(samples)
    }

    fn rate(&mut self, frames: usize) -> anyhow::Result<f64> {
        let start = Instant::now();
        let mut last = 0;
        for _ in 0..frames {
            last = self.send()?;
        }
        let end = self.await_arrival(last)?;
        Ok(frames as f64 / (end - start).as_secs_f64())
    }

    fn finish(mut self) -> anyhow::Result<()> {
        self.stop.store(true, Ordering::Relaxed);
        match self.viewer.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => bail!("the viewer's thread panicked"),
            None => Ok(()),
        }
    }
}

/// The viewer: a node with a reliable input bound to `bench.image`; says when each frame is
/// held, decoded, until `stop`.
fn view(
    agent: std::net::SocketAddr,
    arrived: &Sender<Arrival>,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let spec =
        ModuleSpec::new("viewer", "armor-bench: the viewer").input::<Image>("image", "frames");
    let mut node = Node::connect(
        spec,
        Standalone {
            name: Some("viewer".to_owned()),
            agent: Some(agent.to_string()),
            binds: vec![("image".to_owned(), "bench.image".to_owned())],
            ..Standalone::default()
        },
    )
    .context("cannot connect the viewer")?;
    let input = node.reliable_input::<Image>("image")?;
    while !stop.load(Ordering::Relaxed) {
        if let Event::Input(_) = node.next_event(Some(Duration::from_millis(20)))? {
            while let Some(sample) = node.take(&input)? {
                let at = Instant::now();
                if sample.value.data.len() != PIXEL_BYTES {
                    bail!("a frame of {} bytes came", sample.value.data.len());
                }
                let _ = arrived.send((sample.value.stamp_ns, at));
            }
        }
    }
    Ok(())
}

/// Raw TCP between this thread and a reader thread: frames of an 8-byte number and the pixels.
struct RawLink {
    stream: TcpStream,
    frame: Vec<u8>,
    number: u64,
    arrivals: Receiver<Arrival>,
    reader: Option<JoinHandle<anyhow::Result<()>>>,
}

impl RawLink {
    fn start() -> anyhow::Result<Self> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        let addr = listener.local_addr()?;
        let (arrived, arrivals) = channel();
        let reader = std::thread::spawn(move || -> anyhow::Result<()> {
            let (mut stream, _) = listener.accept()?;
            stream.set_nodelay(true)?;
            let mut frame = vec![0; 8 + PIXEL_BYTES];
            while stream.read_exact(&mut frame).is_ok() {
                let at = Instant::now();
                let number = u64::from_le_bytes(frame[..8].try_into()?);
                let _ = arrived.send((number, at));
            }
            Ok(())
        });
        let stream = TcpStream::connect(addr)?;
        stream.set_nodelay(true)?;
        let mut frame = vec![0; 8];
        frame.extend((0..PIXEL_BYTES).map(|i| (i % 251) as u8));
        Ok(Self {
            stream,
            frame,
            number: 0,
            arrivals,
            reader: Some(reader),
        })
    }

    fn send(&mut self) -> anyhow::Result<u64> {
        self.number += 1;
        self.frame[..8].copy_from_slice(&self.number.to_le_bytes());
        self.stream.write_all(&self.frame)?;
        Ok(self.number)
    }

    fn latencies(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        let mut samples = Vec::with_capacity(count);
        for _ in 0..count {
            let start = Instant::now();
            let number = self.send()?;
            samples.push(arrival_of(&self.arrivals, number)? - start);
        }
        Ok(samples)
    }

    fn rate(&mut self, frames: usize) -> anyhow::Result<f64> {
        let start = Instant::now();
        let mut last = 0;
        for _ in 0..frames {
            last = self.send()?;
        }
        let end = arrival_of(&self.arrivals, last)?;
        Ok(frames as f64 / (end - start).as_secs_f64())
    }

    fn finish(mut self) -> anyhow::Result<()> {
        self.stream.shutdown(std::net::Shutdown::Both)?;
        match self.reader.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => bail!("the reader's thread panicked"),
            None => Ok(()),
        }
    }
}
