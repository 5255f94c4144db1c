//! `pull_latest`: a request for the latest value of another process's output (a pull-mode
//! input, [`Node::pull_latest`]), 64 bytes answered by the provider's node (`armor-mod-echo`,
//! whose module only waits), against raw TCP request/reply with a child (1 byte asked, 64
//! answered, TCP_NODELAY).

use std::io::{Read as _, Write as _};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use armor_module_api::types::Blob;
use armor_module_api::{Input, ModuleSpec, Node, Output};

use crate::Settings;
use crate::harness::{self, LINK_TIMEOUT, STALL_TIMEOUT};
use crate::latency::{self, Timed};
use crate::procs::{ChildGuard, spawn_echo};
use crate::raw;
use armor_bench_report::Report;

pub const NAME: &str = "pull_latest";
const SIZE: usize = 64;
/// How long a first pull waits for the echo's first value before another ping is sent.
const LINK_PROBE: Duration = Duration::from_millis(20);

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let counts = latency::counts(SIZE, settings);
    let (ours, reference) = latency::in_turn(&counts, ArmorPull::start, RawPull::start)?;
    Ok(Report::distribution(NAME, "us", 1e6, &ours, &reference).with("bytes", SIZE))
}

impl Timed for ArmorPull {
    fn timed(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        self.requests(count)
    }
}

impl Timed for RawPull {
    fn timed(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        self.requests(count)
    }
}

/// The bench's node (output `ping`, pull input `latest` bound to `echo.output`) and the echo
/// process, whose output holds the one 64-byte ping it echoed.
struct ArmorPull {
    node: Node,
    latest: Input<Blob>,
    echo: ChildGuard,
}

impl ArmorPull {
    fn start() -> anyhow::Result<Self> {
        let agent = harness::agent()?;
        let spec = ModuleSpec::new("bench", "armor-bench: the pull probe")
            .output::<Blob>("ping", "one message for the echo to hold")
            .input::<Blob>("latest", "the echo's latest message, pulled");
        let mut node = harness::connect(spec, agent, &[("latest", "echo.output")])?;
        let ping: Output<Blob> = node.output::<Blob>("ping")?;
        let latest = node.pull_input::<Blob>("latest")?;
        let agent = agent.to_string();
        let echo = spawn_echo(&agent, &harness::Security::Plain)?;
        let mut side = Self { node, latest, echo };
        let message = Blob(vec![0xA5; SIZE]);
        let give_up = Instant::now() + LINK_TIMEOUT;
        // Ping until a pull is answered: the echo is linked both ways and holds a value.
        loop {
            if !side.node.is_linked(&side.latest) || side.node.subscriber_count(&ping) == 0 {
                side.node.next_event(Some(LINK_PROBE))?;
            } else {
                side.node.send(&ping, &message)?;
                if side.node.pull_latest(&side.latest, LINK_PROBE)?.is_some() {
                    break;
                }
            }
            side.echo.check_alive()?;
            if Instant::now() >= give_up {
                return Err(side
                    .echo
                    .failure(&format!("answered no pull within {LINK_TIMEOUT:?}")));
            }
        }
        Ok(side)
    }

    fn requests(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        let mut samples = Vec::with_capacity(count);
        for _ in 0..count {
            let start = Instant::now();
            let answer = self.node.pull_latest(&self.latest, STALL_TIMEOUT)?;
            samples.push(start.elapsed());
            let Some(sample) = answer else {
                self.echo.check_alive()?;
                bail!("a pull unanswered within {STALL_TIMEOUT:?}");
            };
            if sample.value.0.len() != SIZE {
                bail!("a pull answered {} bytes", sample.value.0.len());
            }
        }
        Ok(samples)
    }
}

/// Raw request/reply with this binary run as `--raw-reply`.
struct RawPull {
    peer: raw::Peer,
    reply: Vec<u8>,
}

impl RawPull {
    fn start() -> anyhow::Result<Self> {
        Ok(Self {
            peer: raw::start_peer("--raw-reply", &SIZE.to_string())?,
            reply: vec![0; SIZE],
        })
    }

    fn requests(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        let mut samples = Vec::with_capacity(count);
        for _ in 0..count {
            let start = Instant::now();
            self.peer.stream.write_all(&[1])?;
            let read = self.peer.stream.read_exact(&mut self.reply);
            samples.push(start.elapsed());
            if read.is_err() {
                self.peer.child.check_alive()?;
                read.context("the raw reply peer stopped answering")?;
            }
        }
        Ok(samples)
    }
}
