//! The messaging anchors against zenoh (crate `zenoh`, peer mode over TCP on 127.0.0.1,
//! multicast scouting off), built only with `--features zenoh`.
//!
//! Our side is measured by `armor-bench` itself (the same binary and method as its own
//! `latency_64b`, `throughput_64b` and `kill_recover_ms`), run as a child of this one in the
//! same run; zenoh is measured here, between this process and a child of it (this binary
//! re-executed with `--zenoh-peer ROLE ...`), each with its own session:
//!
//! - `latency_64b_vs_zenoh` (and `_1kib_`, `_64kib_`, `_1mib_`): round trip of a message of that
//!   size, one in flight; zenoh: publisher `ping` (express, blocking congestion control) to a
//!   peer whose subscriber callback puts the payload back on `pong`; ours: `armor-bench
//!   latency_64b` (a node to `armor-mod-echo`) and its sizes.
//! - `throughput_64b_vs_zenoh` (and the same sizes): messages per second into another process;
//!   zenoh: a publisher (batching, blocking congestion control) to a counting subscriber; ours:
//!   `armor-bench throughput_64b` (into `armor-mod-sink`) and its sizes. Both sides send the
//!   same number of messages in the same number of rounds (zenoh takes them from our line).
//!
//! zenoh is given its best path, as its own `z_pub_thr`, `z_ping` and their shared-memory twins
//! do: the payload is built once as a `ZBytes` and each message puts a shallow clone of it (a
//! reference count, no copy); the receivers look at the payload where it arrived (`slices()`,
//! never `to_bytes()`). Every zenoh figure is taken twice: over TCP with shared memory off (the
//! same transport as ours, the headline), and with zenoh's shared-memory transport (the payload
//! allocated once in a POSIX shared-memory segment, only its descriptor on the TCP link; the
//! receiver checks that it really came by shared memory), a second reference for processes on
//! one host, which ArMoR does not offer.
//!
//! Run the whole binary under `taskset -c 0` for the figures with both processes on one core:
//! the children inherit the affinity, and every line says which CPUs it was allowed
//! (`cpus_allowed`).
//! - `pull_vs_raw_tcp`: a request for the latest value; ours: `armor-bench pull_latest` (a
//!   pull-mode input on `armor-mod-echo`'s output, answered by its node); the reference is raw
//!   TCP request/reply (1 byte asked, 64 answered, TCP_NODELAY), measured by `armor-bench` in the
//!   same run, and zenoh `get` on a queryable is given beside it.
//! - `discovery_vs_zenoh`: a process started to its first message delivered; zenoh: a child
//!   that opens a session, connects to ours (already subscribed) and publishes; ours: `armor-bench
//!   discovery_ms` (`armor-mod-counter` spawned with its agent, to the first value at a node
//!   that was waiting for it).

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, ExitCode, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context as _, bail, ensure};
use zenoh::Wait as _;
use zenoh::bytes::ZBytes;
use zenoh::qos::CongestionControl;
use zenoh::shm::{PosixShmProviderBackend, ShmProvider, ShmProviderBuilder, ZShm};

use crate::Settings;
use armor_bench_report::{Report, median, percentile};

/// The latency benches: (name, the `armor-bench` bench of our side, message bytes).
pub const LATENCY: [(&str, &str, usize); 4] = [
    ("latency_64b_vs_zenoh", "latency_64b", 64),
    ("latency_1kib_vs_zenoh", "latency_1kib", 1024),
    ("latency_64kib_vs_zenoh", "latency_64kib", 64 * 1024),
    ("latency_1mib_vs_zenoh", "latency_1mib", 1024 * 1024),
];
/// The throughput benches, likewise.
pub const THROUGHPUT: [(&str, &str, usize); 4] = [
    ("throughput_64b_vs_zenoh", "throughput_64b", 64),
    ("throughput_1kib_vs_zenoh", "throughput_1kib", 1024),
    ("throughput_64kib_vs_zenoh", "throughput_64kib", 64 * 1024),
    ("throughput_1mib_vs_zenoh", "throughput_1mib", 1024 * 1024),
];
pub const NAME_PULL: &str = "pull_vs_raw_tcp";
pub const NAME_DISCOVERY: &str = "discovery_vs_zenoh";

/// The size of the pull and discovery messages.
const SIZE: usize = 64;
const KEY_PING: &str = "armor/bench/ping";
const KEY_PONG: &str = "armor/bench/pong";
const KEY_DATA: &str = "armor/bench/data";
const KEY_DONE: &str = "armor/bench/done";
const KEY_LATEST: &str = "armor/bench/latest";
const KEY_DISCOVERY: &str = "armor/bench/discovery";
const TIMEOUT: Duration = Duration::from_secs(10);

fn zerr(err: zenoh::Error) -> anyhow::Error {
    anyhow::anyhow!("zenoh: {err}")
}

/// How zenoh carries the payload between the two processes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Transport {
    /// TCP with shared memory off: the payload's bytes go through the socket, as ours do.
    Tcp,
    /// zenoh's shared-memory transport: the payload is allocated in a POSIX shared-memory
    /// segment and only its descriptor goes through the TCP link.
    Shm,
}

impl Transport {
    fn arg(self) -> &'static str {
        match self {
            Transport::Tcp => "tcp",
            Transport::Shm => "shm",
        }
    }

    fn parse(text: &str) -> anyhow::Result<Self> {
        match text {
            "tcp" => Ok(Transport::Tcp),
            "shm" => Ok(Transport::Shm),
            other => bail!("--zenoh-peer: unknown transport `{other}` (tcp or shm)"),
        }
    }
}

/// A payload built once, sent as shallow clones of its `ZBytes` (a reference count each, no
/// copy), as zenoh's `z_pub_thr` and `z_pub_shm_thr` do. The shared-memory provider is kept as
/// long as the payload.
struct Payload {
    bytes: ZBytes,
    _provider: Option<ShmProvider<PosixShmProviderBackend>>,
}

impl Payload {
    /// `size` bytes of `fill`, the first one `first`, in the heap or in shared memory.
    fn new(size: usize, first: u8, fill: u8, transport: Transport) -> anyhow::Result<Self> {
        let mut data = vec![fill; size];
        if let Some(byte) = data.first_mut() {
            *byte = first;
        }
        match transport {
            Transport::Tcp => Ok(Payload {
                bytes: ZBytes::from(data),
                _provider: None,
            }),
            Transport::Shm => {
                // Room for the buffer and the allocator's own layout.
                let provider = ShmProviderBuilder::default_backend(size * 2 + 64 * 1024)
                    .wait()
                    .map_err(zerr)?;
                let mut buffer = provider
                    .alloc(size)
                    .wait()
                    .map_err(|err| anyhow::anyhow!("zenoh shared memory: {err:?}"))?;
                buffer.copy_from_slice(&data);
                let buffer: ZShm = buffer.into();
                Ok(Payload {
                    bytes: ZBytes::from(buffer),
                    _provider: Some(provider),
                })
            }
        }
    }

    fn put(&self) -> ZBytes {
        self.bytes.clone()
    }
}

/// The first byte of a payload, read where it arrived (no copy of the payload).
fn first_byte(payload: &ZBytes) -> Option<u8> {
    payload
        .slices()
        .find(|slice| !slice.is_empty())
        .map(|slice| slice[0])
}

/// A peer-mode configuration: listening on `listen` or connecting to `connect`, no multicast
/// scouting, shared memory on or off as `transport` says (off, zenoh would also move payloads
/// of 3 KiB and more through shared memory on its own).
fn config(
    listen: Option<&str>,
    connect: Option<&str>,
    transport: Transport,
) -> anyhow::Result<zenoh::Config> {
    let mut config = zenoh::Config::default();
    config.insert_json5("mode", r#""peer""#).map_err(zerr)?;
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .map_err(zerr)?;
    config
        .insert_json5(
            "transport/shared_memory/enabled",
            if transport == Transport::Shm {
                "true"
            } else {
                "false"
            },
        )
        .map_err(zerr)?;
    let endpoints = |endpoint: Option<&str>| match endpoint {
        Some(endpoint) => format!(r#"["{endpoint}"]"#),
        None => "[]".to_owned(),
    };
    config
        .insert_json5("listen/endpoints", &endpoints(listen))
        .map_err(zerr)?;
    config
        .insert_json5("connect/endpoints", &endpoints(connect))
        .map_err(zerr)?;
    Ok(config)
}

/// A free TCP port on 127.0.0.1 as a zenoh endpoint.
fn free_endpoint() -> anyhow::Result<String> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    Ok(format!("tcp/127.0.0.1:{}", listener.local_addr()?.port()))
}

/// A child process killed when dropped.
struct Peer(Child);

impl Drop for Peer {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts this binary as a zenoh peer in `role` and waits for its `ready` line.
fn start_peer(args: &[&str]) -> anyhow::Result<Peer> {
    let mut child = Command::new(std::env::current_exe()?)
        .arg("--zenoh-peer")
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .context("starting the zenoh peer")?;
    let stdout = child.stdout.take().context("peer stdout")?;
    let peer = Peer(child);
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line)?;
    ensure!(
        line.trim() == "ready",
        "the zenoh peer said `{}`",
        line.trim()
    );
    Ok(peer)
}

/// The `armor-bench` binary: `$ARMOR_BENCH`, else the workspace's `target/release`.
fn armor_bench() -> PathBuf {
    std::env::var_os("ARMOR_BENCH").map_or_else(
        || PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/release/armor-bench"),
        PathBuf::from,
    )
}

/// Runs one `armor-bench` benchmark and returns its JSON line.
fn ours(name: &str, settings: &Settings) -> anyhow::Result<serde_json::Value> {
    let bench = armor_bench();
    let mut command = Command::new(&bench);
    command.arg(name).stderr(Stdio::inherit());
    if settings.quick {
        command.arg("--quick");
    }
    let output = command
        .output()
        .with_context(|| format!("running {} (build it first)", bench.display()))?;
    ensure!(output.status.success(), "armor-bench {name} failed");
    let text = String::from_utf8_lossy(&output.stdout);
    let line = text.lines().last().context("armor-bench printed nothing")?;
    Ok(serde_json::from_str(line)?)
}

/// The CPUs this process may run on, as Linux lists them (`0-1`, `0`), from /proc/self/status.
pub fn cpus_allowed() -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|status| {
            status.lines().find_map(|line| {
                line.strip_prefix("Cpus_allowed_list:")
                    .map(|list| list.trim().to_owned())
            })
        })
        .unwrap_or_else(|| "unknown".to_owned())
}

fn field(value: &serde_json::Value, key: &str) -> anyhow::Result<f64> {
    value
        .get(key)
        .and_then(serde_json::Value::as_f64)
        .with_context(|| format!("no `{key}` in armor-bench's line"))
}

/// Round trips of `size` bytes through a zenoh peer, in µs.
fn zenoh_round_trips(size: usize, count: usize, transport: Transport) -> anyhow::Result<Vec<f64>> {
    let endpoint = free_endpoint()?;
    let session = zenoh::open(config(Some(&endpoint), None, transport)?)
        .wait()
        .map_err(zerr)?;
    let publisher = session
        .declare_publisher(KEY_PING)
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(zerr)?;
    let subscriber = session.declare_subscriber(KEY_PONG).wait().map_err(zerr)?;
    let _peer = start_peer(&["pong", &endpoint, transport.arg()])?;
    let payload = Payload::new(size, 7, 7, transport)?;
    // Until the routes are known both ways, pings are dropped: ping until a pong comes.
    let deadline = Instant::now() + TIMEOUT;
    loop {
        ensure!(Instant::now() < deadline, "no pong from the zenoh peer");
        publisher.put(payload.put()).wait().map_err(zerr)?;
        if let Some(pong) = subscriber
            .recv_timeout(Duration::from_millis(20))
            .map_err(zerr)?
        {
            ensure!(
                transport == Transport::Tcp || pong.payload().as_shm().is_some(),
                "zenoh did not carry the pong through shared memory"
            );
            break;
        }
    }
    while subscriber
        .recv_timeout(Duration::from_millis(50))
        .map_err(zerr)?
        .is_some()
    {}
    let mut times = Vec::with_capacity(count);
    for _ in 0..count {
        let start = Instant::now();
        publisher.put(payload.put()).wait().map_err(zerr)?;
        let sample = subscriber
            .recv_timeout(TIMEOUT)
            .map_err(zerr)?
            .context("a pong never came")?;
        times.push(start.elapsed().as_secs_f64() * 1e6);
        ensure!(sample.payload().len() == size, "a pong of the wrong size");
    }
    Ok(times)
}

/// The latency bench `LATENCY[index]`.
pub fn run_latency(index: usize, settings: &Settings) -> anyhow::Result<Report> {
    let (name, ours_name, size) = LATENCY[index];
    let ours = ours(ours_name, settings)?;
    // As many round trips as our side timed.
    let count = field(&ours, "round_trips")? as usize;
    let mut zenoh = zenoh_round_trips(size, count, Transport::Tcp)?;
    zenoh.sort_by(f64::total_cmp);
    let mut shm = zenoh_round_trips(size, count, Transport::Shm)?;
    shm.sort_by(f64::total_cmp);
    let ours_p50 = field(&ours, "p50")?;
    let zenoh_p50 = percentile(&zenoh, 0.5);
    let shm_p50 = percentile(&shm, 0.5);
    let mut report = Report::single(name, "us", ours_p50, zenoh_p50);
    report.p50 = Some(ours_p50);
    report.p99 = Some(field(&ours, "p99")?);
    report.reference_p50 = Some(crate::round4(zenoh_p50));
    report.reference_p99 = Some(crate::round4(percentile(&zenoh, 0.99)));
    Ok(report
        .with("reference_p999", crate::round4(percentile(&zenoh, 0.999)))
        .with("bytes", size)
        .with("round_trips", count)
        .with("cpus_allowed", cpus_allowed())
        .with("zenoh_shm_p50", crate::round4(shm_p50))
        .with("zenoh_shm_p99", crate::round4(percentile(&shm, 0.99)))
        .with("ratio_vs_zenoh_shm", crate::round4(ours_p50 / shm_p50))
        .with("raw_tcp_p50", field(&ours, "reference_p50")?)
        .with("ratio_vs_raw_tcp", field(&ours, "ratio")?)
        .with("goal", "<= 0.5x zenoh, <= 1.3x raw TCP")
        .with(
            "reference_is",
            "zenoh 1.10 peers over TCP (shared memory off), express publisher putting a \
             payload built once, to a callback that puts the received payload back (no copy \
             on either side); zenoh_shm_*: the same through zenoh's shared-memory transport",
        ))
}

/// Messages of `size` bytes per second into a zenoh subscriber in another process.
fn zenoh_throughput(
    size: usize,
    count: u64,
    rounds: usize,
    transport: Transport,
) -> anyhow::Result<Vec<f64>> {
    let endpoint = free_endpoint()?;
    let session = zenoh::open(config(Some(&endpoint), None, transport)?)
        .wait()
        .map_err(zerr)?;
    let publisher = session
        .declare_publisher(KEY_DATA)
        .congestion_control(CongestionControl::Block)
        .wait()
        .map_err(zerr)?;
    let done = session.declare_subscriber(KEY_DONE).wait().map_err(zerr)?;
    let _peer = start_peer(&["sink", &endpoint, &count.to_string(), transport.arg()])?;
    // A hello (first byte 1) is answered at once and not counted: send them until one is. The
    // answer says whether the hello came through shared memory.
    let hello = Payload::new(size, 1, 0, transport)?;
    let deadline = Instant::now() + TIMEOUT;
    loop {
        ensure!(Instant::now() < deadline, "the zenoh sink never answered");
        publisher.put(hello.put()).wait().map_err(zerr)?;
        if let Some(answer) = done.recv_timeout(Duration::from_millis(20)).map_err(zerr)? {
            ensure!(
                transport == Transport::Tcp || first_byte(answer.payload()) == Some(1),
                "zenoh did not carry the messages through shared memory"
            );
            break;
        }
    }
    while done
        .recv_timeout(Duration::from_millis(50))
        .map_err(zerr)?
        .is_some()
    {}
    let payload = Payload::new(size, 0, 0, transport)?;
    let mut rates = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let start = Instant::now();
        for _ in 0..count {
            publisher.put(payload.put()).wait().map_err(zerr)?;
        }
        done.recv_timeout(TIMEOUT * 6)
            .map_err(zerr)?
            .context("the zenoh sink did not get every message")?;
        rates.push(count as f64 / start.elapsed().as_secs_f64());
    }
    Ok(rates)
}

/// The throughput bench `THROUGHPUT[index]`.
pub fn run_throughput(index: usize, settings: &Settings) -> anyhow::Result<Report> {
    let (name, ours_name, size) = THROUGHPUT[index];
    let ours = ours(ours_name, settings)?;
    // The same number of messages in as many rounds as our side sent.
    let count = field(&ours, "messages_per_round")? as u64;
    let rounds = field(&ours, "rounds")? as usize;
    let ours_rate = field(&ours, "ours")?;
    let zenoh = median(&zenoh_throughput(size, count, rounds, Transport::Tcp)?);
    let shm = median(&zenoh_throughput(size, count, rounds, Transport::Shm)?);
    Ok(Report::single(name, "msg/s", ours_rate, zenoh)
        .with("bytes", size)
        .with("messages_per_round", count)
        .with("rounds", rounds)
        .with("cpus_allowed", cpus_allowed())
        .with("zenoh_shm", shm.round())
        .with("ratio_vs_zenoh_shm", crate::round4(ours_rate / shm))
        .with("raw_tcp", field(&ours, "reference")?)
        .with("ratio_vs_raw_tcp", field(&ours, "ratio")?)
        .with("goal", ">= 1x zenoh at 64 bytes, >= 0.8x raw TCP at 1 MiB")
        .with(
            "reference_is",
            "zenoh 1.10 peers over TCP (shared memory off), batching publisher (blocking \
             congestion control) putting a payload built once, to a subscriber in another \
             process that counts without copying; the same message count and rounds as ours; \
             zenoh_shm: the same through zenoh's shared-memory transport",
        ))
}

/// Raw TCP request/reply with a child: 1 byte asked, 64 answered; µs each.
fn raw_requests(count: usize) -> anyhow::Result<Vec<f64>> {
    let listener = TcpListener::bind("127.0.0.1:0")?;
    let addr = listener.local_addr()?.to_string();
    let _peer = start_peer(&["raw", &addr])?;
    let (mut stream, _) = listener.accept()?;
    stream.set_nodelay(true)?;
    let mut reply = [0u8; SIZE];
    let mut times = Vec::with_capacity(count);
    for i in 0..count + count / 10 {
        let start = Instant::now();
        stream.write_all(&[1])?;
        stream.read_exact(&mut reply)?;
        if i >= count / 10 {
            times.push(start.elapsed().as_secs_f64() * 1e6);
        }
    }
    Ok(times)
}

/// zenoh `get` on a queryable in another process; µs each.
fn zenoh_gets(count: usize) -> anyhow::Result<Vec<f64>> {
    let endpoint = free_endpoint()?;
    let session = zenoh::open(config(Some(&endpoint), None, Transport::Tcp)?)
        .wait()
        .map_err(zerr)?;
    let _peer = start_peer(&["queryable", &endpoint])?;
    let get = || -> anyhow::Result<usize> {
        let replies = session.get(KEY_LATEST).wait().map_err(zerr)?;
        let mut answers = 0;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                ensure!(sample.payload().len() == SIZE, "a reply of the wrong size");
                answers += 1;
            }
        }
        Ok(answers)
    };
    let deadline = Instant::now() + TIMEOUT;
    while get()? == 0 {
        ensure!(
            Instant::now() < deadline,
            "the zenoh queryable never answered"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let mut times = Vec::with_capacity(count);
    for i in 0..count + count / 10 {
        let start = Instant::now();
        ensure!(get()? == 1, "a get without its one reply");
        if i >= count / 10 {
            times.push(start.elapsed().as_secs_f64() * 1e6);
        }
    }
    Ok(times)
}

pub fn run_pull(settings: &Settings) -> anyhow::Result<Report> {
    let count = if settings.quick { 200 } else { 10_000 };
    let ours = ours("pull_latest", settings)?;
    let mut raw = raw_requests(count)?;
    raw.sort_by(f64::total_cmp);
    let mut zenoh = zenoh_gets(count)?;
    zenoh.sort_by(f64::total_cmp);
    let ours_p50 = field(&ours, "p50")?;
    let raw_p50 = field(&ours, "reference_p50")?;
    let mut report = Report::single(NAME_PULL, "us", ours_p50, raw_p50);
    report.p50 = Some(ours_p50);
    report.p99 = Some(field(&ours, "p99")?);
    report.reference_p50 = Some(raw_p50);
    report.reference_p99 = Some(field(&ours, "reference_p99")?);
    Ok(report
        .with("cpus_allowed", cpus_allowed())
        .with("raw_tcp_here_p50", crate::round4(percentile(&raw, 0.5)))
        .with("zenoh_get_p50", crate::round4(percentile(&zenoh, 0.5)))
        .with("zenoh_get_p99", crate::round4(percentile(&zenoh, 0.99)))
        .with(
            "ratio_vs_zenoh_get",
            crate::round4(ours_p50 / percentile(&zenoh, 0.5)),
        )
        .with("goal", "<= 1.2x raw TCP")
        .with(
            "ours_is",
            "a pull-mode input on armor-mod-echo's output: the request answered by the \
             provider's node from its latest sample (armor-bench pull_latest)",
        )
        .with(
            "reference_is",
            "raw TCP request/reply with a child (1 byte asked, 64 answered, TCP_NODELAY), \
             measured by armor-bench beside ours, in alternate blocks",
        ))
}

/// A zenoh process started to its first sample here, in ms.
fn zenoh_discovery(rounds: usize) -> anyhow::Result<Vec<f64>> {
    let endpoint = free_endpoint()?;
    let session = zenoh::open(config(Some(&endpoint), None, Transport::Tcp)?)
        .wait()
        .map_err(zerr)?;
    let subscriber = session
        .declare_subscriber(KEY_DISCOVERY)
        .wait()
        .map_err(zerr)?;
    let exe = std::env::current_exe()?;
    let mut times = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let start = Instant::now();
        let child = Command::new(&exe)
            .args(["--zenoh-peer", "pub", &endpoint])
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::inherit())
            .spawn()?;
        let child = Peer(child);
        subscriber
            .recv_timeout(TIMEOUT)
            .map_err(zerr)?
            .context("no sample from the started publisher")?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
        drop(child);
        // Let this session see the peer go before the next one comes.
        std::thread::sleep(Duration::from_millis(300));
        while subscriber.try_recv().map_err(zerr)?.is_some() {}
    }
    Ok(times)
}

pub fn run_discovery(settings: &Settings) -> anyhow::Result<Report> {
    let rounds = if settings.quick { 2 } else { 15 };
    let ours = ours("discovery_ms", settings)?;
    let zenoh = median(&zenoh_discovery(rounds)?);
    Ok(
        Report::single(NAME_DISCOVERY, "ms", field(&ours, "ours")?, zenoh)
            .with("cpus_allowed", cpus_allowed())
            .with("process_spawn_ms", field(&ours, "reference")?)
            .with("goal", "<= 0.5x zenoh")
            .with(
                "ours_is",
                "armor-mod-counter spawned with its agent, to its first value at a subscriber \
                 that asked the agent for it before (armor-bench discovery_ms)",
            )
            .with(
                "reference_is",
                "a process spawned that opens a zenoh peer session, connects to ours \
                 (subscribed) and publishes every 0.5 ms (as our counter does), to the first \
                 sample here",
            ),
    )
}

/// The hidden child roles: `pong ENDPOINT TRANSPORT`, `sink ENDPOINT COUNT TRANSPORT`,
/// `queryable ENDPOINT`, `raw ADDR`, `pub ENDPOINT` (TRANSPORT: `tcp` or `shm`). Each prints `ready` when set up and lives until its stdin
/// closes (or it is killed).
pub fn peer_main(args: &[String]) -> ExitCode {
    match peer(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: zenoh peer: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn ready() -> anyhow::Result<()> {
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "ready")?;
    stdout.flush()?;
    Ok(())
}

fn until_stdin_closes() {
    let mut sink = Vec::new();
    let _ = std::io::stdin().read_to_end(&mut sink);
}

fn peer(args: &[String]) -> anyhow::Result<()> {
    let arg = |i: usize| -> anyhow::Result<&str> {
        args.get(i)
            .map(String::as_str)
            .with_context(|| format!("--zenoh-peer: argument {i} missing"))
    };
    match arg(0)? {
        "raw" => {
            let mut stream = TcpStream::connect(arg(1)?)?;
            stream.set_nodelay(true)?;
            ready()?;
            let latest = [9u8; SIZE];
            let mut ask = [0u8; 1];
            while stream.read_exact(&mut ask).is_ok() {
                stream.write_all(&latest)?;
            }
            Ok(())
        }
        "pong" => {
            let transport = Transport::parse(arg(2)?)?;
            let session = zenoh::open(config(None, Some(arg(1)?), transport)?)
                .wait()
                .map_err(zerr)?;
            let publisher = session
                .declare_publisher(KEY_PONG)
                .congestion_control(CongestionControl::Block)
                .express(true)
                .wait()
                .map_err(zerr)?;
            let _subscriber = session
                .declare_subscriber(KEY_PING)
                .callback(move |sample| {
                    let _ = publisher.put(sample.payload().clone()).wait();
                })
                .wait()
                .map_err(zerr)?;
            ready()?;
            until_stdin_closes();
            Ok(())
        }
        "sink" => {
            let count: u64 = arg(2)?.parse()?;
            let transport = Transport::parse(arg(3)?)?;
            let session = zenoh::open(config(None, Some(arg(1)?), transport)?)
                .wait()
                .map_err(zerr)?;
            let done = session
                .declare_publisher(KEY_DONE)
                .congestion_control(CongestionControl::Block)
                .express(true)
                .wait()
                .map_err(zerr)?;
            let received = Arc::new(AtomicU64::new(0));
            let _subscriber = session
                .declare_subscriber(KEY_DATA)
                .callback(move |sample| {
                    // The payload is looked at where it arrived, never copied.
                    let payload = sample.payload();
                    if first_byte(payload) == Some(1) {
                        let by_shm = payload.as_shm().is_some();
                        let _ = done.put(vec![u8::from(by_shm)]).wait();
                    } else if received.fetch_add(1, Ordering::Relaxed) + 1 == count {
                        received.store(0, Ordering::Relaxed);
                        let _ = done.put(vec![0u8]).wait();
                    }
                })
                .wait()
                .map_err(zerr)?;
            ready()?;
            until_stdin_closes();
            Ok(())
        }
        "queryable" => {
            let session = zenoh::open(config(None, Some(arg(1)?), Transport::Tcp)?)
                .wait()
                .map_err(zerr)?;
            let latest = ZBytes::from(vec![9u8; SIZE]);
            let _queryable = session
                .declare_queryable(KEY_LATEST)
                .callback(move |query| {
                    let _ = query.reply(KEY_LATEST, latest.clone()).wait();
                })
                .wait()
                .map_err(zerr)?;
            ready()?;
            until_stdin_closes();
            Ok(())
        }
        "pub" => {
            let session = zenoh::open(config(None, Some(arg(1)?), Transport::Tcp)?)
                .wait()
                .map_err(zerr)?;
            let publisher = session
                .declare_publisher(KEY_DISCOVERY)
                .express(true)
                .wait()
                .map_err(zerr)?;
            // Publishes until killed, every 0.5 ms like our counter in `discovery_ms`: the
            // first sample that finds the subscriber is the figure.
            let payload = ZBytes::from(vec![1u8; SIZE]);
            loop {
                publisher.put(payload.clone()).wait().map_err(zerr)?;
                std::thread::sleep(Duration::from_micros(500));
            }
        }
        other => bail!("--zenoh-peer: unknown role `{other}`"),
    }
}
