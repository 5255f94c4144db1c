//! `armor-team`: the team bridge on a robot (`robot`) and an operator's station (`station`).

use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use armor_team::{bench, capture, radio, robot, stand_in, station};
use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "armor-team",
    about = "ArMoR's robots and operator stations over zenoh"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// On a robot, beside its `armor run`: publish its state to the team's stations and take
    /// their commands, under the run's keys and roles.
    Robot(robot::Options),
    /// An operator's station: a line per robot each second; commands on standard input, one a
    /// line: `ROBOT|all status|pause|resume|abort|fire T|update PLAN.xml`.
    Station(station::Options),
    /// What anyone on the team network sees: every sample under a key expression, its key,
    /// size and bytes (hex), for `--for-secs`. The sealed contents stay sealed.
    Capture(capture::Options),
    /// Robots that are only a clock (the real bridge serving a run that drives round a
    /// square), for tests and benchmarks of a station with many robots.
    StandIns(stand_in::Options),
    /// The team's figures as `armor-bench` lines (`team_status_latency_ms`, on loopback and
    /// through the radio, and `team_bandwidth_kbps_per_robot`), which `armor-bench` relays.
    Bench(bench::Options),
    /// A team's radio on this machine, for tests and benchmarks (root only): network
    /// namespaces for a station and its robots, joined by links with loss, a rate and a delay.
    Radio(radio::Options),
    /// One side of `bench team_status_latency_ms_radio`, which the bench starts in its
    /// namespace.
    #[command(hide = true)]
    BenchSide(bench::SideOptions),
}

/// Both ends run until they are stopped (a signal ends the process).
static STOP: AtomicBool = AtomicBool::new(false);

fn main() -> ExitCode {
    armor_module_api::hardening::make_non_dumpable();
    // zenoh's router warns at every start that gossip is off: that is this program's choice.
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| {
                tracing_subscriber::EnvFilter::new("info,zenoh=warn,zenoh::net::routing=error")
            }),
        )
        .with_writer(std::io::stderr)
        .init();
    let result = match Cli::parse().command {
        Command::Robot(options) => robot::run(&options, &STOP),
        Command::Station(options) => station::run(&options, &STOP),
        Command::Capture(options) => capture::run(&options),
        Command::StandIns(options) => stand_in::run(&options, &STOP),
        Command::Bench(options) => bench::run(&options),
        Command::Radio(options) => radio::run(&options),
        Command::BenchSide(options) => bench::side(&options),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("armor-team: {err:#}");
            ExitCode::FAILURE
        }
    }
}
