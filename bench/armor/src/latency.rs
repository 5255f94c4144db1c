//! `latency_64b` (and `latency_1kib`, `latency_64kib`, `latency_1mib`): round trips of a message
//! of that size, one in flight, between a node in this process and an `armor-mod-echo` process,
//! against TCP ping-pong (TCP_NODELAY) with a child.

use std::io::{Read as _, Write as _};
use std::time::{Duration, Instant};

use anyhow::bail;
use armor_module_api::types::Blob;
use armor_module_api::{Event, Input, ModuleSpec, Node, Output};

use crate::Settings;
use crate::harness::{LINK_TIMEOUT, STALL_TIMEOUT, Security};
use crate::procs::{ChildGuard, spawn_echo};
use crate::{placement, raw};
use armor_bench_report::{Report, round};

/// The benches, by message size.
pub const SIZES: [(&str, usize); 4] = [
    ("latency_64b", 64),
    ("latency_1kib", 1024),
    ("latency_64kib", 64 * 1024),
    ("latency_1mib", 1024 * 1024),
];
/// How long a warm-up ping waits for its pong before another is sent.
const LINK_PROBE: Duration = Duration::from_millis(20);
/// After the first pong, how long stale pongs are drained.
const SETTLE: Duration = Duration::from_millis(50);

pub(crate) struct Counts {
    pub(crate) warm_up: usize,
    /// Timed round trips per block; blocks (or rounds of blocks) alternate between ArMoR and
    /// the reference, so that a change in the machine's load weighs on both alike.
    pub(crate) block: usize,
    pub(crate) blocks: usize,
}

pub fn run_64b(settings: &Settings) -> anyhow::Result<Report> {
    run(SIZES[0], settings)
}

pub fn run_1kib(settings: &Settings) -> anyhow::Result<Report> {
    run(SIZES[1], settings)
}

pub fn run_64kib(settings: &Settings) -> anyhow::Result<Report> {
    run(SIZES[2], settings)
}

pub fn run_1mib(settings: &Settings) -> anyhow::Result<Report> {
    run(SIZES[3], settings)
}

/// `latency_64b_secret`: round trips of 64 bytes on authenticated links, against the same
/// without a secret, in the same run.
pub const NAME_SECRET: &str = "latency_64b_secret";
/// `latency_64b_encrypted`: the same on encrypted links.
pub const NAME_ENCRYPTED: &str = "latency_64b_encrypted";

pub fn run_secret(settings: &Settings) -> anyhow::Result<Report> {
    run_secured(NAME_SECRET, &Security::with_secret(false)?, settings)
}

pub fn run_encrypted(settings: &Settings) -> anyhow::Result<Report> {
    run_secured(NAME_ENCRYPTED, &Security::with_secret(true)?, settings)
}

pub(crate) fn counts(size: usize, settings: &Settings) -> Counts {
    // Fewer round trips for large messages: a 1 MiB one takes about a millisecond.
    let scale = (size / 1024).max(1);
    if settings.quick {
        Counts {
            warm_up: 20,
            block: 100,
            blocks: 2,
        }
    } else {
        Counts {
            warm_up: (2_000 / scale).max(20),
            block: (2_000 / scale).max(100),
            blocks: 10,
        }
    }
}

/// Alternating blocks of round trips on `ours` and `reference`.
pub(crate) fn alternate(
    ours: &mut impl FnMut(usize) -> anyhow::Result<Vec<Duration>>,
    reference: &mut impl FnMut(usize) -> anyhow::Result<Vec<Duration>>,
    counts: &Counts,
) -> anyhow::Result<(Vec<Duration>, Vec<Duration>)> {
    ours(counts.warm_up)?;
    reference(counts.warm_up)?;
    let mut mine = Vec::with_capacity(counts.block * counts.blocks);
    let mut theirs = Vec::with_capacity(counts.block * counts.blocks);
    for _ in 0..counts.blocks {
        mine.extend(ours(counts.block)?);
        theirs.extend(reference(counts.block)?);
    }
    Ok((mine, theirs))
}

fn run_secured(
    name: &'static str,
    security: &Security,
    settings: &Settings,
) -> anyhow::Result<Report> {
    let size = 64;
    let counts = counts(size, settings);
    // Each side in turn on fresh processes, as `latency_64b`: with both echoes alive at once,
    // the bench's thread shares a vCPU with only one of them, and which one decided the ratio.
    let (ours, reference) = in_turn(
        &counts,
        || ArmorPingPong::start(size, security),
        || ArmorPingPong::start(size, &Security::Plain),
    )?;
    Ok(Report::distribution(name, "us", 1e6, &ours, &reference)
        .with("bytes", size)
        .with("reference_is", "the same round trip without a secret")
        .with(
            "placement_is",
            "ours and reference: each side in turn with fresh processes of its own, where the \
             scheduler puts them",
        ))
}

fn run((name, size): (&'static str, usize), settings: &Settings) -> anyhow::Result<Report> {
    let counts = counts(size, settings);
    let (ours, reference) = in_turn(
        &counts,
        || ArmorPingPong::start(size, &Security::Plain),
        || RawPingPong::start(size),
    )?;
    let mut report = Report::distribution(name, "us", 1e6, &ours, &reference)
        .with("bytes", size)
        // armor-bench-peers times as many zenoh round trips.
        .with("round_trips", ours.len());
    let mut armor = ArmorPingPong::start(size, &Security::Plain)?;
    let mut raw = RawPingPong::start(size)?;
    let me = placement::own_thread()?;
    let allowed = placement::allowed_cpus();
    if let [first, second, ..] = allowed[..] {
        // Both pairs on one vCPU, then both split over two, each side alike.
        let placed = Counts {
            warm_up: counts.warm_up,
            block: counts.block,
            blocks: (counts.blocks / 2).max(1),
        };
        let peers = [armor.echo.id(), raw.peer.child.id()];
        let mut measure = |peer_cpu: usize| -> anyhow::Result<(f64, f64)> {
            placement::set(me, &[first], false)?;
            for peer in peers {
                placement::set(peer, &[peer_cpu], true)?;
            }
            let (ours, reference) = alternate(
                &mut |n| armor.round_trips(n),
                &mut |n| raw.round_trips(n),
                &placed,
            )?;
            Ok((p50_us(&ours), p50_us(&reference)))
        };
        let same = measure(first);
        let split = measure(second);
        placement::set(me, &allowed, false)?;
        for peer in peers {
            placement::set(peer, &allowed, true)?;
        }
        let ((same, same_reference), (split, split_reference)) = (same?, split?);
        report = report
            .with("same_cpu_p50", round(same))
            .with("same_cpu_reference_p50", round(same_reference))
            .with("same_cpu_ratio", round(same / same_reference))
            .with("split_p50", round(split))
            .with("split_reference_p50", round(split_reference))
            .with("split_ratio", round(split / split_reference))
            .with(
                "placement_is",
                "ours and reference: each side in turn with fresh processes of its own, where \
                 the scheduler puts them; same_cpu_* and split_* place both pairs alike: the \
                 bench's thread and both peers on one vCPU, then the peers on the other vCPU",
            );
    }
    raw.finish()?;
    Ok(report)
}

/// Rounds of fresh processes each side gets in [`in_turn`].
const FRESH_ROUNDS: usize = 5;

/// One side of a round-trip comparison, on processes of its own.
pub(crate) trait Timed {
    /// Times `count` round trips.
    fn timed(&mut self, count: usize) -> anyhow::Result<Vec<Duration>>;
    /// Ends the side's processes, checking that they end well.
    fn end(self) -> anyhow::Result<()>
    where
        Self: Sized,
    {
        Ok(())
    }
}

/// Round trips of both sides, each in turn with fresh processes of its own, never both peers
/// alive: with both, the bench's thread shares a vCPU with only one of them, and that side is
/// the fast one (see `placement`). [`FRESH_ROUNDS`] rounds alternate, so that a change in the
/// machine's load weighs on both alike; each side warms up at every start.
pub(crate) fn in_turn<O: Timed, R: Timed>(
    counts: &Counts,
    mut ours: impl FnMut() -> anyhow::Result<O>,
    mut reference: impl FnMut() -> anyhow::Result<R>,
) -> anyhow::Result<(Vec<Duration>, Vec<Duration>)> {
    fn blocks(
        side: &mut impl Timed,
        counts: &Counts,
        rounds: usize,
    ) -> anyhow::Result<Vec<Duration>> {
        side.timed(counts.warm_up)?;
        let mut samples = Vec::new();
        for _ in 0..counts.blocks / rounds {
            samples.extend(side.timed(counts.block)?);
        }
        Ok(samples)
    }
    let rounds = FRESH_ROUNDS.min(counts.blocks).max(1);
    let (mut mine, mut theirs) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        let mut side = ours()?;
        mine.extend(blocks(&mut side, counts, rounds)?);
        side.end()?;
        let mut side = reference()?;
        theirs.extend(blocks(&mut side, counts, rounds)?);
        side.end()?;
    }
    Ok((mine, theirs))
}

/// The median of round trips, in microseconds.
fn p50_us(samples: &[Duration]) -> f64 {
    let micros: Vec<f64> = samples.iter().map(|d| d.as_secs_f64() * 1e6).collect();
    armor_bench_report::median(&micros)
}

/// The bench's node (output `ping`, reliable input `pong` bound to `echo.output`) and the echo
/// process (input bound to `bench.ping`).
pub(crate) struct ArmorPingPong {
    node: Node,
    ping: Output<Blob>,
    pong: Input<Blob>,
    echo: ChildGuard,
    message: Blob,
    seq: u64,
}

impl ArmorPingPong {
    /// Connects both ways: keeps sending until a pong comes back.
    fn start(size: usize, security: &Security) -> anyhow::Result<Self> {
        let agent = security.agent()?;
        let node = security.connect(spec(), agent, &[("pong", "echo.output")])?;
        Self::link(node, size, |agent| spawn_echo(agent, security), agent)
    }

    /// The node's ports made, the echo started by `spawn` (given the agent's address), and the
    /// link both ways waited for.
    pub(crate) fn link(
        mut node: Node,
        size: usize,
        spawn: impl FnOnce(&str) -> anyhow::Result<ChildGuard>,
        agent: std::net::SocketAddr,
    ) -> anyhow::Result<Self> {
        let ping = node.output::<Blob>("ping")?;
        let pong = node.reliable_input::<Blob>("pong")?;
        let echo = spawn(&agent.to_string())?;
        let mut side = Self {
            node,
            ping,
            pong,
            echo,
            message: Blob(vec![0xA5; size]),
            seq: 0,
        };
        let give_up = Instant::now() + LINK_TIMEOUT;
        loop {
            side.send_next()?;
            if side.drain(Instant::now() + LINK_PROBE, true)? > 0 {
                break;
            }
            side.echo.check_alive()?;
            if Instant::now() >= give_up {
                return Err(side
                    .echo
                    .failure(&format!("sent no pong back within {LINK_TIMEOUT:?}")));
            }
        }
        side.drain(Instant::now() + SETTLE, false)?;
        Ok(side)
    }

    fn send_next(&mut self) -> anyhow::Result<()> {
        self.seq += 1;
        stamp(&mut self.message, self.seq);
        self.node.send(&self.ping, &self.message)?;
        Ok(())
    }

    /// Times `count` round trips, one message in flight.
    pub(crate) fn round_trips(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        let mut samples = Vec::with_capacity(count);
        for _ in 0..count {
            let start = Instant::now();
            self.send_next()?;
            self.await_pong()?;
            samples.push(start.elapsed());
        }
        Ok(samples)
    }

    /// Takes the pongs that arrive until `until` (or, with `first_only`, until some arrive);
    /// returns how many.
    fn drain(&mut self, until: Instant, first_only: bool) -> anyhow::Result<usize> {
        let mut got = 0;
        loop {
            match self.node.next_event_until(until)? {
                Event::Input(port) if port == self.pong.id() => {
                    while self.node.take(&self.pong)?.is_some() {
                        got += 1;
                    }
                    if first_only && got > 0 {
                        return Ok(got);
                    }
                }
                Event::Timeout => return Ok(got),
                _ => {}
            }
        }
    }

    /// Waits for the pong of the last message sent, skipping stale ones.
    fn await_pong(&mut self) -> anyhow::Result<()> {
        loop {
            match self.node.next_event(Some(STALL_TIMEOUT))? {
                Event::Input(port) if port == self.pong.id() => {
                    while let Some(sample) = self.node.take(&self.pong)? {
                        if seq_of(&sample.value) == Some(self.seq) {
                            return Ok(());
                        }
                    }
                }
                Event::Timeout => {
                    self.echo.check_alive()?;
                    bail!("no pong for message {} within {STALL_TIMEOUT:?}", self.seq);
                }
                _ => {}
            }
        }
    }
}

impl Timed for ArmorPingPong {
    fn timed(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        self.round_trips(count)
    }
}

impl Timed for RawPingPong {
    fn timed(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        self.round_trips(count)
    }

    fn end(self) -> anyhow::Result<()> {
        self.finish()
    }
}

/// TCP ping-pong with this binary run as `--raw-echo`.
pub(crate) struct RawPingPong {
    peer: raw::Peer,
    message: Vec<u8>,
    echoed: Vec<u8>,
    seq: u64,
}

impl RawPingPong {
    fn start(size: usize) -> anyhow::Result<Self> {
        Self::over(raw::start_peer("--raw-echo", &size.to_string())?, size)
    }

    /// Ping-pong with a `--raw-echo` peer already connected.
    pub(crate) fn over(peer: raw::Peer, size: usize) -> anyhow::Result<Self> {
        Ok(Self {
            peer,
            message: vec![0xA5; size],
            echoed: vec![0; size],
            seq: 0,
        })
    }

    pub(crate) fn round_trips(&mut self, count: usize) -> anyhow::Result<Vec<Duration>> {
        let mut samples = Vec::with_capacity(count);
        for _ in 0..count {
            self.seq += 1;
            self.message[..8].copy_from_slice(&self.seq.to_le_bytes());
            let start = Instant::now();
            self.peer.stream.write_all(&self.message)?;
            if let Err(err) = self.peer.stream.read_exact(&mut self.echoed) {
                self.peer.child.check_alive()?;
                return Err(err.into());
            }
            samples.push(start.elapsed());
        }
        if self.echoed != self.message {
            bail!("the raw echo peer sent back different bytes");
        }
        Ok(samples)
    }

    /// Closes the connection and sees the peer exit cleanly.
    pub(crate) fn finish(self) -> anyhow::Result<()> {
        let raw::Peer { stream, mut child } = self.peer;
        drop(stream);
        child.wait_exit(Duration::from_secs(5))?;
        Ok(())
    }
}

/// The bench node's description: output `ping`, input `pong`.
pub(crate) fn spec() -> ModuleSpec {
    ModuleSpec::new("bench", "armor-bench: the latency probe")
        .output::<Blob>("ping", "messages, each stamped with its sequence number")
        .input::<Blob>("pong", "the same messages, echoed")
}

fn stamp(message: &mut Blob, seq: u64) {
    message.0[..8].copy_from_slice(&seq.to_le_bytes());
}

fn seq_of(message: &Blob) -> Option<u64> {
    let bytes = message.0.get(..8)?;
    Some(u64::from_le_bytes(bytes.try_into().ok()?))
}
