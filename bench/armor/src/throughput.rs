//! `throughput_64b`, `throughput_1kib`, `throughput_64kib` and `throughput_1mib`: messages streamed from a node in this process to an
//! `armor-mod-sink` process, timed from the first send until the sink's count reaches the total,
//! against the same bytes streamed over raw TCP to a child that answers one byte at the end.
//!
//! Each side runs a few rounds, interleaved; the reported rates are the medians.

use std::io::{BufWriter, Read as _, Write as _};
use std::time::{Duration, Instant};

use anyhow::bail;
use armor_module_api::types::{Blob, Counter};
use armor_module_api::{Event, Input, ModuleSpec, Node, Output, PortId};

use crate::Settings;
use crate::harness::{LINK_TIMEOUT, STALL_TIMEOUT, Security};
use crate::procs::{ChildGuard, module_command};
use crate::raw;
use armor_bench_report::{Report, median};

pub const NAME_1MIB: &str = "throughput_1mib";
pub const NAME_64B: &str = "throughput_64b";
pub const NAME_1KIB: &str = "throughput_1kib";
pub const NAME_64KIB: &str = "throughput_64kib";
pub const NAME_FANOUT: &str = "fanout_64b";
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

/// `fanout_64b`: what one more subscriber costs. 64-byte messages streamed to one
/// `armor-mod-sink` and to four: the time per message grows by `(t4 - t1) / 3` for each extra
/// subscriber (the publisher's work and the extra sink's, on the same two cores). Reference: the
/// same measure for raw TCP at its best, one publisher streaming the same bytes through a 64 KiB
/// buffer per subscriber to one raw sink process and to four. A difference that comes out
/// negative (noise on a loaded machine) is reported as measured, not clamped. Goal: ratio <= 1.
pub fn run_fanout(settings: &Settings) -> anyhow::Result<Report> {
    const MORE: usize = 4;
    let (count, every, rounds) = if settings.quick {
        (10_000, 1_000, 1)
    } else {
        (500_000, 10_000, 3)
    };
    let plan = Plan {
        name: NAME_FANOUT,
        size: 64,
        count,
        every,
        rounds,
    };
    let mut one = ArmorSide::start(&plan, 1, &Security::Plain)?;
    let mut more = ArmorSide::start(&plan, MORE, &Security::Plain)?;
    let (mut rate_one, mut rate_more) = (Vec::new(), Vec::new());
    let (mut raw_one, mut raw_more) = (Vec::new(), Vec::new());
    for _ in 0..plan.rounds {
        rate_one.push(one.round(&plan)?);
        rate_more.push(more.round(&plan)?);
        raw_one.push(raw_fanout_round(&plan, 1)?);
        raw_more.push(raw_fanout_round(&plan, MORE)?);
    }
    let extra = |one: &[f64], more: &[f64]| {
        let (t_one, t_more) = (1e9 / median(one), 1e9 / median(more));
        (t_more - t_one) / (MORE - 1) as f64
    };
    Ok(Report::single(
        plan.name,
        "ns/msg",
        extra(&rate_one, &rate_more),
        extra(&raw_one, &raw_more),
    )
    .with("bytes", plan.size)
    .with("msg_per_s_1_subscriber", median(&rate_one).round())
    .with(
        format!("msg_per_s_{MORE}_subscribers").as_str(),
        median(&rate_more).round(),
    )
    .with("raw_msg_per_s_1_subscriber", median(&raw_one).round())
    .with(
        format!("raw_msg_per_s_{MORE}_subscribers").as_str(),
        median(&raw_more).round(),
    )
    .with("goal", "<= 1x what one more subscriber costs raw TCP")
    .with(
        "reference_is",
        "the extra time per message of one more subscriber for raw TCP: one publisher streaming \
         the same bytes through a 64 KiB buffer per subscriber, to 1 and to 4 sink processes",
    ))
}

/// Messages per second of one raw publisher streaming `plan.count` messages to each of
/// `subscribers` raw sink processes, through a buffer per sink; timed until every sink has
/// answered that it has all the bytes.
fn raw_fanout_round(plan: &Plan, subscribers: usize) -> anyhow::Result<f64> {
    let total = plan.size as u64 * plan.count;
    let mut peers = (0..subscribers)
        .map(|_| raw::start_peer("--raw-sink", &total.to_string()))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let message = vec![0xA5; plan.size];
    let start = Instant::now();
    let streamed = (|| {
        let mut writers: Vec<_> = peers
            .iter()
            .map(|peer| BufWriter::with_capacity(RAW_BUFFER, &peer.stream))
            .collect();
        for _ in 0..plan.count {
            for writer in &mut writers {
                writer.write_all(&message)?;
            }
        }
        for writer in &mut writers {
            writer.flush()?;
        }
        drop(writers);
        let mut answer = [0; 1];
        for peer in &mut peers {
            peer.stream.read_exact(&mut answer)?;
        }
        std::io::Result::Ok(())
    })();
    let elapsed = start.elapsed();
    if let Err(err) = streamed {
        for peer in &mut peers {
            peer.child.check_alive()?;
        }
        return Err(err.into());
    }
    for peer in &mut peers {
        peer.child.wait_exit(Duration::from_secs(5))?;
    }
    Ok(plan.count as f64 / elapsed.as_secs_f64())
}

/// `throughput_1mib_secret`: 1 MiB messages on an authenticated link, against the same without
/// a secret, in the same run.
pub const NAME_1MIB_SECRET: &str = "throughput_1mib_secret";
/// `throughput_1mib_encrypted`: the same on an encrypted link.
pub const NAME_1MIB_ENCRYPTED: &str = "throughput_1mib_encrypted";

pub fn run_1mib_secret(settings: &Settings) -> anyhow::Result<Report> {
    run_secured(NAME_1MIB_SECRET, &Security::with_secret(false)?, settings)
}

pub fn run_1mib_encrypted(settings: &Settings) -> anyhow::Result<Report> {
    run_secured(NAME_1MIB_ENCRYPTED, &Security::with_secret(true)?, settings)
}

fn run_secured(
    name: &'static str,
    security: &Security,
    settings: &Settings,
) -> anyhow::Result<Report> {
    let (count, every, rounds) = if settings.quick {
        (20, 2, 1)
    } else {
        (2_000, 10, 3)
    };
    let plan = Plan {
        name,
        size: 1024 * 1024,
        count,
        every,
        rounds,
    };
    let mut secured = ArmorSide::start(&plan, 1, security)?;
    let mut plain = ArmorSide::start(&plan, 1, &Security::Plain)?;
    let mut ours = Vec::with_capacity(plan.rounds);
    let mut reference = Vec::with_capacity(plan.rounds);
    for _ in 0..plan.rounds {
        ours.push(secured.round(&plan)?);
        reference.push(plain.round(&plan)?);
    }
    Ok(
        Report::single(plan.name, "msg/s", median(&ours), median(&reference))
            .with("bytes", plan.size)
            .with("reference_is", "the same stream without a secret"),
    )
}

fn run(plan: &Plan) -> anyhow::Result<Report> {
    let mut armor = ArmorSide::start(plan, 1, &Security::Plain)?;
    let mut ours = Vec::with_capacity(plan.rounds);
    let mut reference = Vec::with_capacity(plan.rounds);
    for _ in 0..plan.rounds {
        ours.push(armor.round(plan)?);
        reference.push(raw_round(plan, RAW_BUFFER)?);
    }
    Ok(
        Report::single(plan.name, "msg/s", median(&ours), median(&reference))
            .with("bytes", plan.size)
            // armor-bench-peers sends zenoh the same number of messages in as many rounds.
            .with("messages_per_round", plan.count)
            .with("rounds", plan.rounds),
    )
}

/// The bench's node (output `data`, inputs `count0`, `count1`, … bound to `sink0.count`, …) and
/// the sink processes.
struct ArmorSide {
    node: Node,
    data: Output<Blob>,
    counts: Vec<Input<Counter>>,
    sinks: Vec<ChildGuard>,
    payload: Blob,
    /// Each sink's count as last heard: exactly what it has received, once quiet.
    received: Vec<u64>,
}

impl ArmorSide {
    /// Connects both ways to `sinks` sinks and learns their exact counts.
    fn start(plan: &Plan, sinks: usize, security: &Security) -> anyhow::Result<Self> {
        let agent = security.agent()?;
        let names: Vec<(String, String)> = (0..sinks)
            .map(|i| (format!("count{i}"), format!("sink{i}")))
            .collect();
        let mut spec = ModuleSpec::new("bench", "armor-bench: the throughput source")
            .output::<Blob>("data", "the messages to count");
        for (input, _) in &names {
            spec = spec.input::<Counter>(input, "how many a sink has received");
        }
        let sources: Vec<(String, String)> = names
            .iter()
            .map(|(input, sink)| (input.clone(), format!("{sink}.count")))
            .collect();
        let binds: Vec<(&str, &str)> = sources
            .iter()
            .map(|(input, source)| (input.as_str(), source.as_str()))
            .collect();
        let mut node = security.connect(spec, agent, &binds)?;
        let data = node.output::<Blob>("data")?;
        let counts = names
            .iter()
            .map(|(input, _)| node.input::<Counter>(input))
            .collect::<Result<Vec<_>, _>>()?;
        let agent = agent.to_string();
        let every = format!("every={}", plan.every);
        let sinks = names
            .iter()
            .map(|(_, sink)| {
                let mut command = module_command(
                    "sink",
                    &[
                        "--name",
                        sink,
                        "--agent",
                        &agent,
                        "--param",
                        &every,
                        "--bind",
                        "input=bench.data",
                    ],
                )?;
                security.module_env(&mut command, sink)?;
                ChildGuard::spawn("armor-mod-sink", command)
            })
            .collect::<anyhow::Result<Vec<_>>>()?;
        let mut side = Self {
            node,
            data,
            received: vec![0; counts.len()],
            counts,
            sinks,
            payload: Blob(vec![0xA5; plan.size]),
        };
        side.link(plan)?;
        Ok(side)
    }

    /// Waits until every sink's count reaches this node, then sends bursts of `every` messages
    /// until each count has grown. A burst reaches a sink whole or not at all: the node takes a
    /// new subscriber only while it waits for events, never between the sends of a burst, as
    /// long as it has no subscriber yet. So each sink's count is a whole number of bursts.
    fn link(&mut self, plan: &Plan) -> anyhow::Result<()> {
        let give_up = Instant::now() + LINK_TIMEOUT;
        while !self.counts.iter().all(|count| self.node.is_linked(count)) {
            self.node.next_event(Some(BURST_PROBE))?;
            self.check_progress(give_up, "did not serve its count")?;
        }
        let before = self.received.clone();
        while self
            .received
            .iter()
            .zip(&before)
            .any(|(now, then)| now <= then)
        {
            for _ in 0..plan.every {
                self.node.send(&self.data, &self.payload)?;
            }
            self.await_counts(Instant::now() + BURST_PROBE)?;
            self.check_progress(give_up, "counted nothing")?;
        }
        self.await_counts(Instant::now() + SETTLE)?;
        Ok(())
    }

    fn check_progress(&mut self, give_up: Instant, what: &str) -> anyhow::Result<()> {
        for sink in &mut self.sinks {
            sink.check_alive()?;
        }
        if Instant::now() >= give_up {
            return Err(self.sinks[0].failure(&format!("{what} within {LINK_TIMEOUT:?}")));
        }
        Ok(())
    }

    /// Takes counts until `until`.
    fn await_counts(&mut self, until: Instant) -> anyhow::Result<()> {
        loop {
            match self.node.next_event_until(until)? {
                Event::Input(port) => self.take_count(port)?,
                Event::Timeout => return Ok(()),
                _ => {}
            }
        }
    }

    fn take_count(&mut self, port: PortId) -> anyhow::Result<()> {
        if let Some(i) = self.counts.iter().position(|count| count.id() == port)
            && let Some(sample) = self.node.take(&self.counts[i])?
        {
            self.received[i] = self.received[i].max(sample.value.0);
        }
        Ok(())
    }

    /// One timed round: messages per second from the first send to the last sink's last count.
    fn round(&mut self, plan: &Plan) -> anyhow::Result<f64> {
        let target: Vec<u64> = self.received.iter().map(|got| got + plan.count).collect();
        let start = Instant::now();
        for _ in 0..plan.count {
            self.node.send(&self.data, &self.payload)?;
        }
        while self
            .received
            .iter()
            .zip(&target)
            .any(|(got, want)| got < want)
        {
            match self.node.next_event(Some(STALL_TIMEOUT))? {
                Event::Input(port) => self.take_count(port)?,
                Event::Timeout => {
                    self.check_progress(Instant::now() + STALL_TIMEOUT, "")?;
                    bail!(
                        "the sinks' counts stayed at {:?} of {target:?} for {STALL_TIMEOUT:?}",
                        self.received
                    );
                }
                _ => {}
            }
        }
        Ok(plan.count as f64 / start.elapsed().as_secs_f64())
    }
}

/// One raw round: the same bytes through a TCP stream to a fresh peer, written through a buffer
/// of `buffer` bytes (0: one `send` a message).
fn raw_round(plan: &Plan, buffer: usize) -> anyhow::Result<f64> {
    let total = plan.size as u64 * plan.count;
    let mut peer = raw::start_peer("--raw-sink", &total.to_string())?;
    let message = vec![0xA5; plan.size];
    let mut answer = [0; 1];
    let start = Instant::now();
    let streamed = (|| {
        let mut writer = BufWriter::with_capacity(buffer, &peer.stream);
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
