//! `armor-team bench [NAME…] [--quick]`: the team's figures as `armor-bench` report lines,
//! which `armor-bench` runs and relays (it links no zenoh, as nothing but this crate does).
//!
//! - `team_status_latency_ms`: from a robot's bridge taking its run's status to a station
//!   opening it, over zenoh on loopback, sealed; against a bare zenoh put and subscribe of a
//!   sample of the same size between the same two sessions, in the same run.
//! - `team_status_latency_ms_radio`: the same through the radio of the namespace test
//!   ([`crate::radio`]: 10 % loss each way, 256 kbit/s, 300 ms each way), the robot's side a
//!   child in its namespace and the station's another in the station's, against a bare zenoh
//!   put and subscribe over the same radio; as root only (the line says why it was skipped
//!   otherwise).
//! - `team_bandwidth_kbps_per_robot`: what each of 20 stand-in robots costs one station, with
//!   the default budget (status and pose; no outputs); against the budget, 50 kbit/s.

use std::io::{BufRead as _, BufReader, Write as _};
use std::net::TcpListener;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_bench_report::Report;
use armor_module_api::auth::{Role, RoleKey, Secret};
use serde::{Deserialize, Serialize};
use zenoh::Wait as _;

use crate::net::z;
use crate::radio;
use crate::robot::{Budget, Shared};
use crate::stand_in::{StandIn, bridge};
use crate::station::{OnStatus, Station};

pub const NAME_LATENCY: &str = "team_status_latency_ms";
pub const NAME_LATENCY_RADIO: &str = "team_status_latency_ms_radio";
pub const NAME_BANDWIDTH: &str = "team_bandwidth_kbps_per_robot";

#[derive(Clone, Debug, clap::Args)]
pub struct Options {
    /// The benchmarks to run (all when none is named).
    pub names: Vec<String>,
    /// Fewer samples, for a smoke test.
    #[arg(long)]
    pub quick: bool,
}

static STOP_NEVER: AtomicBool = AtomicBool::new(false);

pub fn run(options: &Options) -> anyhow::Result<()> {
    let wants = |name: &str| options.names.is_empty() || options.names.iter().any(|n| n == name);
    let mut known = false;
    if wants(NAME_LATENCY) {
        known = true;
        print(&latency(options.quick)?);
    }
    if wants(NAME_LATENCY_RADIO) {
        known = true;
        print(&latency_radio(options.quick)?);
    }
    if wants(NAME_BANDWIDTH) {
        known = true;
        print(&bandwidth(options.quick)?);
    }
    anyhow::ensure!(
        known,
        "unknown benchmark (known: {NAME_LATENCY}, {NAME_LATENCY_RADIO}, {NAME_BANDWIDTH})"
    );
    Ok(())
}

fn print(report: &Report) {
    if let Ok(line) = serde_json::to_string(report) {
        println!("{line}");
    }
}

/// A zenoh endpoint on loopback at a port free now.
fn free_endpoint() -> anyhow::Result<String> {
    let port = TcpListener::bind("127.0.0.1:0")
        .and_then(|listener| listener.local_addr())
        .context("no free port on loopback")?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

/// A station's session listening on loopback, and its endpoint for robots to connect to.
fn station_session() -> anyhow::Result<(zenoh::Session, String)> {
    let endpoint = free_endpoint()?;
    Ok((
        crate::net::open(std::slice::from_ref(&endpoint), &[])?,
        endpoint,
    ))
}

fn secret() -> anyhow::Result<Secret> {
    Ok(Secret::from_bytes(&armor_module_api::auth::random_bytes::<
        32,
    >()?))
}

fn operator(secret: &Secret) -> RoleKey {
    RoleKey {
        role: Role::Operator,
        key: secret.role_key(Role::Operator),
    }
}

/// Starts `count` stand-ins with `budget`, each on its own session connected to `endpoint`;
/// their names.
fn stand_ins(
    count: usize,
    endpoint: &str,
    secret: &Secret,
    budget: &Budget,
    epoch: Instant,
) -> anyhow::Result<Vec<String>> {
    let mut names = Vec::new();
    for index in 0..count {
        let name = format!("robot-{}", index + 1);
        let session = crate::net::open(&[], &[endpoint.to_owned()])?;
        let bridge = bridge(&name, secret, budget.clone());
        let run = StandIn::new(&name, index, epoch);
        std::thread::spawn(move || {
            let shared = Arc::new(Mutex::new(Shared::default()));
            if let Err(err) = bridge.serve(&session, Box::new(run), shared, &STOP_NEVER) {
                eprintln!("armor-team bench: a stand-in: {err:#}");
            }
        });
        names.push(name);
    }
    Ok(names)
}

fn default_budget() -> Budget {
    Budget::default()
}

fn latency(quick: bool) -> anyhow::Result<Report> {
    let samples = if quick { 40 } else { 400 };
    let rate_hz = 20.0;
    let (station_side, endpoint) = station_session()?;
    let secret = secret()?;
    let epoch = Instant::now();
    // Status only, at 20 Hz, so that the samples come in a few seconds.
    let budget = Budget {
        status_hz: rate_hz,
        pose_hz: 0.2,
        ..default_budget()
    };
    let robot_side_names = stand_ins(1, &endpoint, &secret, &budget, epoch)?;
    let seen: Arc<Mutex<Vec<Duration>>> = Arc::default();
    let sizes: Arc<Mutex<Vec<usize>>> = Arc::default();
    let on_status = status_latencies(epoch, &seen, &sizes);
    let _station = Station::start(
        &station_side,
        &operator(&secret),
        &robot_side_names,
        2.0,
        Some(on_status),
    );
    wait_for(&seen, samples, Duration::from_secs(60))?;
    let ours = take(&seen);
    let size = sealed_size(&take(&sizes));

    // The reference: a bare put and subscribe of a sample of that size, between a session
    // that connects and one that listens, at the same rate.
    let robot_side = crate::net::open(&[], &[endpoint])?;
    let bare: Arc<Mutex<Vec<Duration>>> = Arc::default();
    let _subscriber = bare_subscriber(&station_side, epoch, &bare)?;
    // The subscription reaches the other side before the first put counts.
    let deadline = Instant::now() + Duration::from_secs(10);
    while take_len(&bare) == 0 && Instant::now() < deadline {
        put_stamped(&robot_side, epoch, size)?;
        std::thread::sleep(Duration::from_millis(50));
    }
    take(&bare);
    for _ in 0..samples {
        put_stamped(&robot_side, epoch, size)?;
        std::thread::sleep(Duration::from_secs_f64(1.0 / rate_hz));
    }
    wait_for(&bare, samples * 9 / 10, Duration::from_secs(10))?;
    let reference = take(&bare);
    Ok(Report::distribution(NAME_LATENCY, "ms", 1e3, &ours, &reference)
        .with(
            "reference_is",
            "a bare zenoh put and subscribe of a sample of the same size between the same two sessions (TCP on loopback)",
        )
        .with("samples", ours.len())
        .with("sample_bytes", size)
        .with("rate_hz", rate_hz))
}

/// A station's callback that keeps the latency of each status (from the `run_secs` it
/// carries, seconds since `epoch`, to now) and its size.
fn status_latencies(
    epoch: Instant,
    seen: &Arc<Mutex<Vec<Duration>>>,
    sizes: &Arc<Mutex<Vec<usize>>>,
) -> OnStatus {
    let seen = Arc::clone(seen);
    let sizes = Arc::clone(sizes);
    Arc::new(move |_, status| {
        let latency = epoch.elapsed().as_secs_f64() - status.run_secs;
        seen.lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(Duration::from_secs_f64(latency.max(0.0)));
        if let Ok(bytes) = serde_json::to_vec(status) {
            sizes
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .push(bytes.len());
        }
    })
}

/// The size of the largest of `sizes` (statuses in JSON) as a sealed sample carries it.
fn sealed_size(sizes: &[usize]) -> usize {
    sizes.iter().copied().max().unwrap_or(400)
        // The seal's nonce and tag, and the `Up`'s tag.
        + 24
        + 20
}

/// Subscribes to `bench/bare` on `session`, keeping the latency of each sample from the
/// stamp it starts with (seconds since `epoch`).
fn bare_subscriber(
    session: &zenoh::Session,
    epoch: Instant,
    bare: &Arc<Mutex<Vec<Duration>>>,
) -> anyhow::Result<zenoh::pubsub::Subscriber<()>> {
    let bare = Arc::clone(bare);
    z(session
        .declare_subscriber("bench/bare")
        .callback(move |sample| {
            let bytes = sample.payload().to_bytes();
            if bytes.len() >= 8 {
                let mut sent = [0; 8];
                sent.copy_from_slice(&bytes[..8]);
                let sent_secs = f64::from_be_bytes(sent);
                bare.lock()
                    .unwrap_or_else(PoisonError::into_inner)
                    .push(Duration::from_secs_f64(
                        (epoch.elapsed().as_secs_f64() - sent_secs).max(0.0),
                    ));
            }
        })
        .wait())
}

fn put_stamped(session: &zenoh::Session, epoch: Instant, size: usize) -> anyhow::Result<()> {
    let mut payload = epoch.elapsed().as_secs_f64().to_be_bytes().to_vec();
    payload.resize(size.max(8), 0);
    z(session
        .put("bench/bare", payload)
        .congestion_control(zenoh::qos::CongestionControl::Drop)
        .wait())
}

fn take_len(samples: &Mutex<Vec<Duration>>) -> usize {
    samples.lock().unwrap_or_else(PoisonError::into_inner).len()
}

fn take<T>(samples: &Mutex<Vec<T>>) -> Vec<T> {
    std::mem::take(&mut *samples.lock().unwrap_or_else(PoisonError::into_inner))
}

fn wait_for(samples: &Mutex<Vec<Duration>>, count: usize, limit: Duration) -> anyhow::Result<()> {
    let deadline = Instant::now() + limit;
    while take_len(samples) < count {
        anyhow::ensure!(
            Instant::now() < deadline,
            "only {} of {count} samples in {} s",
            take_len(samples),
            limit.as_secs()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(())
}

fn bandwidth(quick: bool) -> anyhow::Result<Report> {
    const ROBOTS: usize = 20;
    let measure = Duration::from_secs(if quick { 4 } else { 20 });
    let (station_side, endpoint) = station_session()?;
    let secret = secret()?;
    let budget = default_budget();
    let names = stand_ins(ROBOTS, &endpoint, &secret, &budget, Instant::now())?;
    let station = Station::start(&station_side, &operator(&secret), &names, 2.0, None);
    let deadline = Instant::now() + Duration::from_secs(60);
    while station
        .reports()
        .iter()
        .any(|report| report.report_age_secs.is_none())
    {
        anyhow::ensure!(
            Instant::now() < deadline,
            "not every stand-in reported within 60 s"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    std::thread::sleep(measure);
    let kbit: Vec<f64> = station
        .reports()
        .iter()
        .map(|report| report.kbit_per_sec)
        .collect();
    let mean = kbit.iter().sum::<f64>() / kbit.len() as f64;
    let max = kbit.iter().copied().fold(0.0, f64::max);
    Ok(
        Report::single(NAME_BANDWIDTH, "kbit/s", mean, budget.kbit_per_sec)
            .with("max_kbps", armor_bench_report::round(max))
            .with("robots", ROBOTS)
            .with("measured_secs", measure.as_secs())
            .with(
                "reference_is",
                "the default budget of a robot per station (status 2 Hz, pose 5 Hz, no outputs)",
            ),
    )
}

/// The radio of the namespace test (`tests/tests/team.rs`), for one robot.
fn the_tests_radio() -> radio::Spec {
    radio::Spec {
        robots: 1,
        loss_pct: 10.0,
        delay_ms: 300,
        rate_kbit: Some(256),
    }
}

/// A line that says why its benchmark did not run: no figures, and `skipped` with the reason
/// (`armor-bench` relays it as it is).
fn skipped(name: &'static str, unit: &'static str, why: &str) -> Report {
    Report::single(name, unit, f64::NAN, f64::NAN).with("skipped", why)
}

/// `team_status_latency_ms_radio`: as [`latency`], through the radio. zenoh's sessions share
/// one runtime per process, and each side must be in its own namespace, so each side is a
/// process of its own (`armor-team bench-side`, [`side`]) started in its namespace; both take
/// their stamps on this process's start as CLOCK_MONOTONIC, which every namespace of one
/// machine shares.
fn latency_radio(quick: bool) -> anyhow::Result<Report> {
    if !radio::is_root() {
        return Ok(skipped(NAME_LATENCY_RADIO, "ms", radio::NEEDS_ROOT));
    }
    let samples = if quick { 40 } else { 400 };
    let rate_hz = 20.0;
    let spec = the_tests_radio();
    // Dropped last: the sides first, then the radio with whatever still runs in it.
    let radio = radio::Radio::up(&spec)?;
    let made = radio.made();
    let link = made
        .robots
        .first()
        .context("the radio has no robot's link")?;
    let secret = armor_module_api::auth::random_bytes::<32>()?;
    let epoch_ns = monotonic_ns();
    let sides = SideOptions {
        side: Side::Robot,
        endpoint: link.listen.clone(),
        epoch_ns,
        samples,
        rate_hz,
    };
    let mut robot = SideChild::spawn(&link.namespace, &sides, &secret)?;
    let mut station = SideChild::spawn(
        &made.station,
        &SideOptions {
            side: Side::Station,
            endpoint: link.station_endpoint.clone(),
            ..sides
        },
        &secret,
    )?;
    // Through 300 ms each way the sessions take a few seconds to open; then 20 samples a
    // second each way, and the losses' retransmissions.
    let limit = Duration::from_secs(120) + Duration::from_secs_f64(samples as f64 / rate_hz);
    let ours: SideSaid = station.said(limit)?;
    robot.tell(&format!("bare {}", ours.sample_bytes))?;
    let bare: SideSaid = station.said(limit)?;
    let dropped = radio.dropped_packets()?;
    let durations = |ms: &[f64]| -> Vec<Duration> {
        ms.iter()
            .map(|ms| Duration::from_secs_f64(ms.max(0.0) / 1e3))
            .collect()
    };
    let (ours_samples, reference) = (durations(&ours.ms), durations(&bare.ms));
    Ok(Report::distribution(
        NAME_LATENCY_RADIO,
        "ms",
        1e3,
        &ours_samples,
        &reference,
    )
    .with(
        "reference_is",
        "a bare zenoh put and subscribe of a sample of the same size between the same two sessions, over the same radio",
    )
    .with(
        "link",
        format!(
            "network namespaces joined by a veth pair: {} % loss each way (iptables statistic), {} kbit/s (tbf), {} ms each way (armor-team radio relay)",
            spec.loss_pct,
            spec.rate_kbit.unwrap_or_default(),
            spec.delay_ms
        ),
    )
    .with("packets_lost", dropped)
    .with("samples", ours_samples.len())
    .with("sample_bytes", ours.sample_bytes)
    .with("rate_hz", rate_hz))
}

/// Now on CLOCK_MONOTONIC, in nanoseconds: the same clock in every namespace of a machine.
fn monotonic_ns() -> u64 {
    let now = rustix::time::clock_gettime(rustix::time::ClockId::Monotonic);
    u64::try_from(now.tv_sec).unwrap_or_default() * 1_000_000_000
        + u64::try_from(now.tv_nsec).unwrap_or_default()
}

/// The instant `epoch_ns` (CLOCK_MONOTONIC, which `Instant` reads on Linux).
fn instant_of(epoch_ns: u64) -> Instant {
    let ago = Duration::from_nanos(monotonic_ns().saturating_sub(epoch_ns));
    let now = Instant::now();
    now.checked_sub(ago).unwrap_or(now)
}

/// `armor-team bench-side`: one side of `team_status_latency_ms_radio`, which the bench starts
/// in its namespace. The team's secret comes as the first line of standard input (hex); the
/// end of standard input (the bench gone) ends it.
#[derive(Clone, Debug, clap::Args)]
pub struct SideOptions {
    #[arg(long, value_enum)]
    pub side: Side,
    /// The robot listens there; the station connects there.
    #[arg(long)]
    pub endpoint: String,
    /// The bench's start, CLOCK_MONOTONIC nanoseconds: the stamps are seconds since it.
    #[arg(long)]
    pub epoch_ns: u64,
    /// Samples of each kind (the sealed statuses, then the bare puts).
    #[arg(long)]
    pub samples: usize,
    /// Statuses (and then bare puts) a second.
    #[arg(long)]
    pub rate_hz: f64,
}

#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Side {
    /// A stand-in robot's bridge; told `bare SIZE` on its input, it stops and puts bare samples.
    Robot,
    /// A station: it prints the statuses' latencies, then the bare samples'.
    Station,
}

/// What the station's side prints, a JSON line for each kind of sample.
#[derive(Debug, Default, Serialize, Deserialize)]
struct SideSaid {
    /// The latencies, in milliseconds.
    ms: Vec<f64>,
    /// The size of a sealed status (the bare samples are as large).
    #[serde(default)]
    sample_bytes: usize,
}

/// The robot's name on the radio.
const RADIO_ROBOT: &str = "robot-1";

/// Stops the stand-in robot of the radio's robot side.
static STOP_STAND_IN: AtomicBool = AtomicBool::new(false);

pub fn side(options: &SideOptions) -> anyhow::Result<()> {
    let mut input = std::io::stdin().lock();
    let mut line = String::new();
    input.read_line(&mut line).context("the secret on stdin")?;
    let secret = armor_module_api::auth::unhex::<32>(line.trim())
        .map(|bytes| Secret::from_bytes(&bytes))
        .context("the secret on stdin is not 32 bytes in hex")?;
    // Lines after the secret are for the robot's side; their end is the bench's.
    let (sender, told) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::stdin().lock().lines() {
            let Ok(line) = line else { break };
            if sender.send(line).is_err() {
                break;
            }
        }
        std::process::exit(0);
    });
    drop(input);
    let epoch = instant_of(options.epoch_ns);
    match options.side {
        Side::Robot => robot_side(options, &secret, epoch, &told),
        Side::Station => station_side(options, &secret, epoch),
    }
}

fn robot_side(
    options: &SideOptions,
    secret: &Secret,
    epoch: Instant,
    told: &std::sync::mpsc::Receiver<String>,
) -> anyhow::Result<()> {
    let session = crate::net::open(std::slice::from_ref(&options.endpoint), &[])?;
    let budget = Budget {
        status_hz: options.rate_hz,
        pose_hz: 0.2,
        ..default_budget()
    };
    let bridge = bridge(RADIO_ROBOT, secret, budget);
    let run = StandIn::new(RADIO_ROBOT, 0, epoch);
    let serving = session.clone();
    std::thread::spawn(move || {
        let shared = Arc::new(Mutex::new(Shared::default()));
        if let Err(err) = bridge.serve(&serving, Box::new(run), shared, &STOP_STAND_IN) {
            eprintln!("armor-team bench-side: the stand-in: {err:#}");
        }
    });
    let size = loop {
        let line = told
            .recv()
            .context("the bench ended before the bare samples")?;
        if let Some(size) = line
            .strip_prefix("bare ")
            .and_then(|size| size.parse::<usize>().ok())
        {
            break size;
        }
    };
    // The reference has the radio to itself.
    STOP_STAND_IN.store(true, std::sync::atomic::Ordering::Relaxed);
    // Until the bench has its samples and ends this process (the end of its input).
    loop {
        put_stamped(&session, epoch, size)?;
        std::thread::sleep(Duration::from_secs_f64(1.0 / options.rate_hz));
    }
}

fn station_side(options: &SideOptions, secret: &Secret, epoch: Instant) -> anyhow::Result<()> {
    let session = crate::net::open(&[], std::slice::from_ref(&options.endpoint))?;
    let seen: Arc<Mutex<Vec<Duration>>> = Arc::default();
    let sizes: Arc<Mutex<Vec<usize>>> = Arc::default();
    let station = Station::start(
        &session,
        &operator(secret),
        &[RADIO_ROBOT.to_owned()],
        2.0,
        Some(status_latencies(epoch, &seen, &sizes)),
    );
    let limit = Duration::from_secs(120)
        + Duration::from_secs_f64(options.samples as f64 / options.rate_hz);
    wait_for(&seen, options.samples, limit)?;
    let ours = take(&seen);
    drop(station);
    let bare: Arc<Mutex<Vec<Duration>>> = Arc::default();
    let _subscriber = bare_subscriber(&session, epoch, &bare)?;
    say(&SideSaid {
        ms: millis(&ours),
        sample_bytes: sealed_size(&take(&sizes)),
    })?;
    // The first bare sample came once the subscription had reached the robot; from then on
    // none is held back by it.
    wait_for(&bare, 1, limit)?;
    take(&bare);
    wait_for(&bare, options.samples, limit)?;
    say(&SideSaid {
        ms: millis(&take(&bare)),
        sample_bytes: 0,
    })
}

fn millis(samples: &[Duration]) -> Vec<f64> {
    samples
        .iter()
        .map(|sample| sample.as_secs_f64() * 1e3)
        .collect()
}

fn say(said: &SideSaid) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    writeln!(out, "{}", serde_json::to_string(said)?)?;
    out.flush()?;
    Ok(())
}

/// A side started in its namespace (`ip netns exec NS armor-team bench-side …`), killed when
/// dropped; it ends by itself when this process does (its input closes).
struct SideChild {
    child: Child,
    input: ChildStdin,
    lines: std::sync::mpsc::Receiver<String>,
    what: String,
}

impl SideChild {
    fn spawn(namespace: &str, options: &SideOptions, secret: &[u8; 32]) -> anyhow::Result<Self> {
        let exe = std::env::current_exe().context("cannot locate armor-team")?;
        let what = format!("the bench's {:?} side in {namespace}", options.side);
        let mut child = Command::new("ip")
            .args(["netns", "exec", namespace])
            .arg(exe)
            .arg("bench-side")
            .args([
                "--side",
                match options.side {
                    Side::Robot => "robot",
                    Side::Station => "station",
                },
                "--endpoint",
                &options.endpoint,
                "--epoch-ns",
                &options.epoch_ns.to_string(),
                "--samples",
                &options.samples.to_string(),
                "--rate-hz",
                &options.rate_hz.to_string(),
            ])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .with_context(|| format!("cannot start {what} (`ip` is in Debian's iproute2)"))?;
        let (Some(mut input), Some(output)) = (child.stdin.take(), child.stdout.take()) else {
            let _ = child.kill();
            let _ = child.wait();
            anyhow::bail!("{what}: its input or output was not captured");
        };
        let (sender, lines) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(output).lines() {
                let Ok(line) = line else { break };
                if sender.send(line).is_err() {
                    break;
                }
            }
        });
        let told = writeln!(input, "{}", armor_module_api::auth::hex(secret));
        let side = Self {
            child,
            input,
            lines,
            what,
        };
        told.with_context(|| format!("{}: cannot hand it the secret", side.what))?;
        Ok(side)
    }

    fn tell(&mut self, line: &str) -> anyhow::Result<()> {
        writeln!(self.input, "{line}").with_context(|| format!("{}: it ended", self.what))
    }

    /// Its next line, within `limit`.
    fn said(&mut self, limit: Duration) -> anyhow::Result<SideSaid> {
        let line = self.lines.recv_timeout(limit).map_err(|_| {
            let ended = self.child.try_wait().ok().flatten();
            anyhow::anyhow!(
                "{}: no samples within {} s{}",
                self.what,
                limit.as_secs(),
                ended.map_or(String::new(), |status| format!(" (it ended: {status})"))
            )
        })?;
        serde_json::from_str(&line).with_context(|| format!("{}: said {line:?}", self.what))
    }
}

impl Drop for SideChild {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A line that could not run says why, with no figures that could be taken for some.
    #[test]
    fn a_skipped_line_says_why_and_has_no_figures() {
        let line = serde_json::to_value(skipped(NAME_LATENCY_RADIO, "ms", radio::NEEDS_ROOT))
            .expect("json");
        assert_eq!(line["bench"], NAME_LATENCY_RADIO);
        assert!(
            line["ours"].is_null() && line["reference"].is_null(),
            "{line}"
        );
        assert!(
            line["skipped"]
                .as_str()
                .is_some_and(|why| why.contains("needs root")),
            "{line}"
        );
    }

    /// The sides' clock: an instant from CLOCK_MONOTONIC nanoseconds is the same instant.
    #[test]
    fn an_instant_from_monotonic_nanoseconds() {
        let now = Instant::now();
        let back = instant_of(monotonic_ns());
        let apart = back.max(now) - back.min(now);
        assert!(apart < Duration::from_millis(50), "{apart:?}");
    }
}
