//! `throughput_64b`, `throughput_1kib`, `throughput_64kib` and `throughput_1mib`: messages streamed from a node in this process to an
//! `armor-mod-sink` process, timed from the first send until the sink's count reaches the total,
//! against the same bytes streamed over raw TCP to a child that answers one byte at the end.
//!
//! Each side runs a few rounds, interleaved; the reported rates are the medians.

use std::io::{BufWriter, Read as _, Write as _};
use std::time::{Duration, Instant};

use anyhow::bail;
use armor_module_api::types::{Blob, Counter};
use armor_module_api::{Event, Input, ModuleSpec, Node, Output};

use crate::Settings;
use crate::harness::{self, LINK_TIMEOUT, STALL_TIMEOUT};
use crate::procs::{ChildGuard, module_command};
use crate::raw;
use crate::report::{Report, median};

pub const NAME_1MIB: &str = "throughput_1mib";
pub const NAME_64B: &str = "throughput_64b";
pub const NAME_1KIB: &str = "throughput_1kib";
pub const NAME_64KIB: &str = "throughput_64kib";
/// The raw reference writes through a buffer of this size (what ArMoR batches before writing).
const RAW_BUFFER: usize = 64 * 1024;
/// How long a warm-up burst waits for the sink's count before another is sent.
const BURST_PROBE: Duration = Duration::from_millis(50);
/// After the first count, how long late ones are collected.
const SETTLE: Duration = Duration::from_millis(200);

struct Plan {
    name: &'static str,
    size: usize,
    /// Messages per round.
    count: u64,
    /// The sink publishes its count every this many messages (divides `count`).
    every: u64,
    rounds: usize,
}

pub fn run_1mib(settings: &Settings) -> anyhow::Result<Report> {
    let (count, every, rounds) = if settings.quick {
        (20, 2, 1)
    } else {
        (2_000, 10, 3)
    };
    run(&Plan {
        name: NAME_1MIB,
        size: 1024 * 1024,
        count,
        every,
        rounds,
    })
}

pub fn run_1kib(settings: &Settings) -> anyhow::Result<Report> {
    let (count, every, rounds) = if settings.quick {
        (2_000, 200, 1)
    } else {
        (500_000, 5_000, 3)
    };
    run(&Plan {
        name: NAME_1KIB,
        size: 1024,
        count,
        every,
        rounds,
    })
}

pub fn run_64kib(settings: &Settings) -> anyhow::Result<Report> {
    let (count, every, rounds) = if settings.quick {
        (200, 20, 1)
    } else {
        (20_000, 100, 3)
    };
    run(&Plan {
        name: NAME_64KIB,
        size: 64 * 1024,
        count,
        every,
        rounds,
    })
}

pub fn run_64b(settings: &Settings) -> anyhow::Result<Report> {
    let (count, every, rounds) = if settings.quick {
        (10_000, 1_000, 1)
    } else {
        (1_000_000, 10_000, 3)
    };
    run(&Plan {
        name: NAME_64B,
        size: 64,
        count,
        every,
        rounds,
    })
}

fn run(plan: &Plan) -> anyhow::Result<Report> {
    let mut armor = ArmorSide::start(plan)?;
    let mut ours = Vec::with_capacity(plan.rounds);
    let mut reference = Vec::with_capacity(plan.rounds);
    for _ in 0..plan.rounds {
        ours.push(armor.round(plan)?);
        reference.push(raw_round(plan)?);
    }
    Ok(
        Report::single(plan.name, "msg/s", median(&ours), median(&reference))
            .with("bytes", plan.size),
    )
}

/// The bench's node (output `data`, input `count` bound to `sink.count`) and the sink process.
struct ArmorSide {
    node: Node,
    data: Output<Blob>,
    count: Input<Counter>,
    sink: ChildGuard,
    payload: Blob,
    /// The sink's count as last heard: exactly what it has received, once quiet.
    received: u64,
}

impl ArmorSide {
    /// Connects both ways and learns the sink's exact count.
    fn start(plan: &Plan) -> anyhow::Result<Self> {
        let agent = harness::agent()?;
        let spec = ModuleSpec::new("bench", "armor-bench: the throughput source")
            .output::<Blob>("data", "the messages to count")
            .input::<Counter>("count", "how many the sink has received");
        let mut node = harness::connect(spec, agent, &[("count", "sink.count")])?;
        let data = node.output::<Blob>("data")?;
        let count = node.input::<Counter>("count")?;
        let agent = agent.to_string();
        let every = format!("every={}", plan.every);
        let sink = ChildGuard::spawn(
            "armor-mod-sink",
            module_command(
                "sink",
                &[
                    "--name",
                    "sink",
                    "--agent",
                    &agent,
                    "--param",
                    &every,
                    "--bind",
                    "input=bench.data",
                ],
            )?,
        )?;
        let mut side = Self {
            node,
            data,
            count,
            sink,
            payload: Blob(vec![0xA5; plan.size]),
            received: 0,
        };
        side.link(plan)?;
        Ok(side)
    }

    /// Waits until the sink's count reaches this node, then sends bursts of `every` messages
    /// until a count comes back. A burst reaches the sink whole or not at all: the node takes a
    /// new subscriber only while it waits for events, never between the sends of a burst, as
    /// long as it has no subscriber yet. So the sink's count is a whole number of bursts.
    fn link(&mut self, plan: &Plan) -> anyhow::Result<()> {
        let give_up = Instant::now() + LINK_TIMEOUT;
        while !self.node.is_linked(&self.count) {
            self.node.next_event(Some(BURST_PROBE))?;
            self.check_progress(give_up, "did not serve its count")?;
        }
        loop {
            for _ in 0..plan.every {
                self.node.send(&self.data, &self.payload)?;
            }
            if self.await_count(Instant::now() + BURST_PROBE, true)? {
                break;
            }
            self.check_progress(give_up, "counted nothing")?;
        }
        self.await_count(Instant::now() + SETTLE, false)?;
        Ok(())
    }

    fn check_progress(&mut self, give_up: Instant, what: &str) -> anyhow::Result<()> {
        self.sink.check_alive()?;
        if Instant::now() >= give_up {
            return Err(self
                .sink
                .failure(&format!("{what} within {LINK_TIMEOUT:?}")));
        }
        Ok(())
    }

    /// Takes counts until `until` (or, with `first_only`, until the count grows). Returns
    /// whether it grew.
    fn await_count(&mut self, until: Instant, first_only: bool) -> anyhow::Result<bool> {
        let before = self.received;
        loop {
            match self.node.next_event_until(until)? {
                Event::Input(port) if port == self.count.id() => {
                    self.take_count()?;
                    if first_only && self.received > before {
                        return Ok(true);
                    }
                }
                Event::Timeout => return Ok(self.received > before),
                _ => {}
            }
        }
    }

    fn take_count(&mut self) -> anyhow::Result<()> {
        if let Some(sample) = self.node.take(&self.count)? {
            self.received = self.received.max(sample.value.0);
        }
        Ok(())
    }

    /// One timed round: messages per second from the first send to the sink's last count.
    fn round(&mut self, plan: &Plan) -> anyhow::Result<f64> {
        let target = self.received + plan.count;
        let start = Instant::now();
        for _ in 0..plan.count {
            self.node.send(&self.data, &self.payload)?;
        }
        while self.received < target {
            match self.node.next_event(Some(STALL_TIMEOUT))? {
                Event::Input(port) if port == self.count.id() => self.take_count()?,
                Event::Timeout => {
                    self.sink.check_alive()?;
                    bail!(
                        "the sink's count stayed at {} of {target} for {STALL_TIMEOUT:?}",
                        self.received
                    );
                }
                _ => {}
            }
        }
        Ok(plan.count as f64 / start.elapsed().as_secs_f64())
    }
}

/// One raw round: the same bytes through a buffered TCP stream to a fresh peer.
fn raw_round(plan: &Plan) -> anyhow::Result<f64> {
    let total = plan.size as u64 * plan.count;
    let mut peer = raw::start_peer("--raw-sink", &total.to_string())?;
    let message = vec![0xA5; plan.size];
    let mut answer = [0; 1];
    let start = Instant::now();
    let streamed = (|| {
        let mut writer = BufWriter::with_capacity(RAW_BUFFER, &peer.stream);
        for _ in 0..plan.count {
            writer.write_all(&message)?;
        }
        writer.flush()?;
        drop(writer);
        peer.stream.read_exact(&mut answer)
    })();
    let elapsed = start.elapsed();
    if let Err(err) = streamed {
        peer.child.check_alive()?;
        return Err(err.into());
    }
    peer.child.wait_exit(Duration::from_secs(5))?;
    Ok(plan.count as f64 / elapsed.as_secs_f64())
}
