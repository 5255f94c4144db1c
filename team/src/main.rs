//! `armor-team`: the team bridge on a robot (`robot`) and an operator's station (`station`).

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use armor_team::{robot, station};
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
    Robot {
        /// The robot's name in the team (`armor/team/NAME/…`).
        #[arg(long)]
        name: String,
        /// The run's control address (`armor run` prints it; also $ARMOR_CONTROL).
        #[arg(long, env = "ARMOR_CONTROL")]
        control: SocketAddr,
        /// The run's secret file: stations prove its role keys, the bridge its operator's.
        #[arg(long, env = "ARMOR_SECRET_FILE")]
        secret: PathBuf,
        /// zenoh endpoints to listen at (`tcp/0.0.0.0:7447`).
        #[arg(long)]
        listen: Vec<String>,
        /// zenoh endpoints of peers or routers to connect to.
        #[arg(long)]
        connect: Vec<String>,
        /// The data name of the robot's pose: a `PoseEstimate`, an `Odometry` or a `Pose2D`.
        #[arg(long, default_value = "localiser.estimate")]
        pose: String,
        /// An output to forward (sent when it changed, at --output-hz at most); repeat.
        #[arg(long = "output")]
        outputs: Vec<String>,
        #[arg(long, default_value_t = robot::Budget::default().status_hz)]
        status_hz: f64,
        #[arg(long, default_value_t = robot::Budget::default().pose_hz)]
        pose_hz: f64,
        #[arg(long, default_value_t = robot::Budget::default().output_hz)]
        output_hz: f64,
        /// What the robot may send each station, in kbit/s: outputs wait when it is spent.
        #[arg(long, default_value_t = robot::Budget::default().kbit_per_sec)]
        budget_kbps: f64,
        /// Seconds without an operator's beat before the run is told its link is lost.
        #[arg(long, default_value_t = 2.0)]
        lost_after_secs: f64,
    },
    /// An operator's station: a line per robot each second; commands on standard input, one a
    /// line: `ROBOT|all status|pause|resume|abort|fire T|update PLAN.xml`.
    Station {
        /// A role's key (`armor secret derive --role observer|operator`) or the secret itself.
        #[arg(long)]
        key: PathBuf,
        /// A robot of the team; repeat.
        #[arg(long = "robot", required = true)]
        robots: Vec<String>,
        #[arg(long)]
        listen: Vec<String>,
        #[arg(long)]
        connect: Vec<String>,
        #[arg(long, default_value_t = 2.0)]
        beat_hz: f64,
        #[arg(long, default_value_t = 1.0)]
        print_every_secs: f64,
        /// Send this command (`ROBOT|all COMMAND [ARGS]`) and end, rather than watch; repeat.
        #[arg(long)]
        send: Vec<String>,
    },
    /// What anyone on the team network sees: every sample under a key expression, its key,
    /// size and first bytes (hex), for `--for-secs`. The sealed contents stay sealed.
    Capture {
        #[arg(long)]
        connect: Vec<String>,
        #[arg(long)]
        listen: Vec<String>,
        #[arg(long, default_value = "armor/team/**")]
        key_expr: String,
        #[arg(long, default_value_t = 10.0)]
        for_secs: f64,
    },
}

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
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("armor-team: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<()> {
    // Both ends run until they are stopped (a signal ends the process).
    let stop = AtomicBool::new(false);
    match cli.command {
        Command::Robot {
            name,
            control,
            secret,
            listen,
            connect,
            pose,
            outputs,
            status_hz,
            pose_hz,
            output_hz,
            budget_kbps,
            lost_after_secs,
        } => robot::run(
            &robot::Options {
                name,
                control,
                secret,
                listen,
                connect,
                pose,
                outputs,
                budget: robot::Budget {
                    status_hz,
                    pose_hz,
                    output_hz,
                    kbit_per_sec: budget_kbps,
                },
                lost_after_secs,
            },
            &stop,
        ),
        Command::Station {
            key,
            robots,
            listen,
            connect,
            beat_hz,
            print_every_secs,
            send,
        } => station::run(
            &station::Options {
                key,
                robots,
                listen,
                connect,
                beat_hz,
                print_every_secs,
                send,
            },
            &stop,
        ),
        Command::Capture {
            connect,
            listen,
            key_expr,
            for_secs,
        } => armor_team::capture::run(&listen, &connect, &key_expr, for_secs),
    }
}
