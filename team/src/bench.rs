//! `armor-team bench [NAME…] [--quick]`: the team's figures as `armor-bench` report lines,
//! which `armor-bench` runs and relays (it links no zenoh, as nothing but this crate does).
//!
//! - `team_status_latency_ms`: from a robot's bridge taking its run's status to a station
//!   opening it, over zenoh on loopback, sealed; against a bare zenoh put and subscribe of a
//!   sample of the same size between the same two sessions, in the same run.
//! - `team_bandwidth_kbps_per_robot`: what each of 20 stand-in robots costs one station, with
//!   the default budget (status and pose; no outputs); against the budget, 50 kbit/s.

use std::net::TcpListener;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use anyhow::Context as _;
use armor_bench_report::Report;
use armor_module_api::auth::{Role, RoleKey, Secret};
use zenoh::Wait as _;

use crate::net::z;
use crate::robot::{Budget, Shared};
use crate::stand_in::{StandIn, bridge};
use crate::station::{OnStatus, Station};

pub const NAME_LATENCY: &str = "team_status_latency_ms";
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
    if wants(NAME_BANDWIDTH) {
        known = true;
        print(&bandwidth(options.quick)?);
    }
    anyhow::ensure!(
        known,
        "unknown benchmark (known: {NAME_LATENCY}, {NAME_BANDWIDTH})"
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
    let on_status: OnStatus = {
        let seen = Arc::clone(&seen);
        let sizes = Arc::clone(&sizes);
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
    };
    let _station = Station::start(
        &station_side,
        &operator(&secret),
        &robot_side_names,
        2.0,
        Some(on_status),
    );
    wait_for(&seen, samples, Duration::from_secs(60))?;
    let ours = take(&seen);
    let size = take(&sizes)
        .iter()
        .copied()
        .max()
        .unwrap_or(400)
        // The seal's nonce and tag, and the `Up`'s tag.
        + 24
        + 20;

    // The reference: a bare put and subscribe of a sample of that size, between a session
    // that connects and one that listens, at the same rate.
    let robot_side = crate::net::open(&[], &[endpoint])?;
    let bare: Arc<Mutex<Vec<Duration>>> = Arc::default();
    let _subscriber = {
        let bare = Arc::clone(&bare);
        z(station_side
            .declare_subscriber("bench/bare")
            .callback(move |sample| {
                let bytes = sample.payload().to_bytes();
                if bytes.len() >= 8 {
                    let mut sent = [0; 8];
                    sent.copy_from_slice(&bytes[..8]);
                    let sent_secs = f64::from_be_bytes(sent);
                    bare.lock().unwrap_or_else(PoisonError::into_inner).push(
                        Duration::from_secs_f64(
                            (epoch.elapsed().as_secs_f64() - sent_secs).max(0.0),
                        ),
                    );
                }
            })
            .wait())?
    };
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
