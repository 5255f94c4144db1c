//! `armor-bench`: ArMoR's speed measured against a reference in the same run.
//!
//! Each benchmark prints one JSON line: `{"bench", "ours", "reference", "unit", "ratio"}` (ratio
//! = ours / reference), plus `p50`, `p99`, `reference_p50` and `reference_p99` for
//! distributions (then `ours` and `reference` are medians), and whatever else a benchmark says
//! of its figures (`goal`, `reference_is`: what the reference is when it is no plain TCP or
//! spawn). References are plain TCP or plain
//! process spawns measured on the same machine in the same run, so ratios compare across
//! machines where absolute numbers do not.
//!
//! The raw TCP references need a peer process: the binary re-executes itself in a hidden mode
//! (`--raw-echo ADDR SIZE`, `--raw-sink ADDR BYTES`, `--raw-hop ADDR ROLE ROUNDS`), and the
//! provider `messages_lost_under_kill` kills is one too (`--kill-victim`). Called
//! through a symlink named `armor-mod-benchprobe`, it is the module `event_to_start_ms` runs
//! under `armor run` (see `benchprobe.rs`).

mod arbiter_switch;
mod auto_plan;
mod benchprobe;
mod camera_sim;
mod compile_plan;
mod control_rtt;
mod cross;
mod discovery;
mod event_start;
mod fuzz;
mod handshake;
mod harness;
mod health;
mod image_link;
mod kill;
mod latency;
mod localise;
mod loop_closure;
mod mapper_scan;
mod path_plan;
mod placement;
mod plan_update;
mod procs;
mod pull;
mod qgc_import;
mod raw;
mod reachability;
mod remote;
mod sim_realtime;
mod startup;
mod studio;
mod team;
mod throughput;

use std::process::ExitCode;

use anyhow::Context as _;
use clap::Parser;

use armor_bench_report::{Bench, run_benches};

#[derive(Parser)]
#[command(
    name = "armor-bench",
    version,
    about = "Measures ArMoR against references measured in the same run (raw TCP, plain process spawns, other crates doing the same work), one JSON line per benchmark"
)]
struct Cli {
    /// Benchmarks to run, in this order (default: all but those --list marks as run only when
    /// named).
    names: Vec<String>,
    /// Tiny iteration counts: checks that everything runs, measures nothing worth keeping.
    #[arg(long)]
    quick: bool,
    /// Print the benchmark names and exit.
    #[arg(long)]
    list: bool,
    /// Hidden reference peer: connect to ADDR and echo SIZE-byte messages until closed.
    #[arg(long, hide = true, num_args = 2, value_names = ["ADDR", "SIZE"])]
    raw_echo: Option<Vec<String>>,
    /// Hidden reference peer: connect to ADDR and answer each byte with SIZE bytes until closed.
    #[arg(long, hide = true, num_args = 2, value_names = ["ADDR", "SIZE"])]
    raw_reply: Option<Vec<String>>,
    /// Hidden reference peer: connect to ADDR, read BYTES bytes, answer one byte.
    #[arg(long, hide = true, num_args = 2, value_names = ["ADDR", "BYTES"])]
    raw_sink: Option<Vec<String>>,
    /// Hidden reference peer: connect to ADDR as `a` or `b` and pass a byte back and forth
    /// through the relay ROUNDS times, then print the times.
    #[arg(long, hide = true, num_args = 3, value_names = ["ADDR", "ROLE", "ROUNDS"])]
    raw_hop: Option<Vec<String>>,
    /// Hidden provider of `messages_lost_under_kill`: module `victim` on the agent at AGENT,
    /// publishing GENERATION << 32 | N every PERIOD_US and printing each N once written.
    #[arg(long, hide = true, num_args = 3, value_names = ["AGENT", "GENERATION", "PERIOD_US"])]
    kill_victim: Option<Vec<String>>,
}

pub use armor_bench_report::Settings;

const BENCHES: &[Bench] = &[
    Bench {
        name: latency::SIZES[0].0,
        about: "round trip of 64 bytes through armor-mod-echo vs TCP ping-pong (us)",
        run: latency::run_64b,
    },
    Bench {
        name: latency::SIZES[1].0,
        about: "the same with 1 KiB messages (us)",
        run: latency::run_1kib,
    },
    Bench {
        name: latency::SIZES[2].0,
        about: "the same with 64 KiB messages (us)",
        run: latency::run_64kib,
    },
    Bench {
        name: latency::SIZES[3].0,
        about: "the same with 1 MiB messages (us)",
        run: latency::run_1mib,
    },
    Bench {
        name: latency::NAME_SECRET,
        about: "round trip of 64 bytes on authenticated links (--secret) vs the same without a \
                secret (us; goal ratio <= 1.05)",
        run: latency::run_secret,
    },
    Bench {
        name: latency::NAME_ENCRYPTED,
        about: "round trip of 64 bytes on encrypted links (--secret --encrypt) vs the same \
                without a secret (us; goal ratio <= 1.3)",
        run: latency::run_encrypted,
    },
    Bench {
        name: image_link::NAME_LATENCY,
        about: "a 640x480 rgb8 camera frame (921,600 bytes) through one link, one in flight, vs \
                raw TCP moving the same bytes between two threads (ms; goal ratio <= 1.2)",
        run: image_link::run_latency,
    },
    Bench {
        name: image_link::NAME_FPS,
        about: "640x480 rgb8 frames streamed through one link vs raw TCP moving the same bytes \
                (frames/s; goal ratio >= 0.8)",
        run: image_link::run_fps,
    },
    Bench {
        name: camera_sim::NAME,
        about: "one 320x240 frame of the simulated camera, drawn and JPEG-encoded, vs the JPEG \
                encoding alone (ms; goal under 10)",
        run: camera_sim::run,
    },
    Bench {
        name: control_rtt::NAME,
        about: "a status request and its reply on a kept control link, encrypted (a secret) vs \
                plaintext (ms, p50; goal ratio <= 1.2)",
        run: control_rtt::run,
    },
    Bench {
        name: handshake::NAME,
        about: "a connection to the agent opened with the Noise handshake vs with the hello only \
                (us, p50)",
        run: handshake::run,
    },
    Bench {
        name: pull::NAME,
        about: "request for the latest value of armor-mod-echo's output (pull mode), 64 bytes \
                answered, vs raw TCP request/reply (us)",
        run: pull::run,
    },
    Bench {
        name: throughput::NAME_1MIB,
        about: "1 MiB messages into armor-mod-sink vs TCP streaming (msg/s)",
        run: throughput::run_1mib,
    },
    Bench {
        name: throughput::NAME_1MIB_SECRET,
        about: "1 MiB messages on an authenticated link vs the same without a secret (msg/s; \
                goal ratio >= 0.95)",
        run: throughput::run_1mib_secret,
    },
    Bench {
        name: throughput::NAME_1MIB_ENCRYPTED,
        about: "1 MiB messages on an encrypted link vs the same without a secret (msg/s; goal \
                ratio >= 0.5)",
        run: throughput::run_1mib_encrypted,
    },
    Bench {
        name: throughput::NAME_64B,
        about: "64-byte messages into armor-mod-sink vs buffered TCP streaming (msg/s)",
        run: throughput::run_64b,
    },
    Bench {
        name: throughput::NAME_1KIB,
        about: "the same with 1 KiB messages (msg/s)",
        run: throughput::run_1kib,
    },
    Bench {
        name: throughput::NAME_64KIB,
        about: "the same with 64 KiB messages (msg/s)",
        run: throughput::run_64kib,
    },
    Bench {
        name: throughput::NAME_FANOUT,
        about: "what one more subscriber adds to each 64-byte message published (1 vs 4 sinks) \
                vs what one more subscriber costs raw TCP, buffered (ns/msg; goal ratio <= 1)",
        run: throughput::run_fanout,
    },
    Bench {
        name: startup::NAME,
        about: "`armor run` of ten counters until configured vs ten --describe spawns (ms)",
        run: startup::run,
    },
    Bench {
        name: cross::NAME,
        about: "round trip of 64 bytes through armor-mod-echo in another network namespace \
                (a veth pair) vs TCP ping-pong over the same pair (ns; needs root)",
        run: cross::run,
    },
    Bench {
        name: remote::NAME,
        about: "`armor run` of ten counters, half on an `armor host` in another network \
                namespace, until configured vs the same all local (ms; needs root)",
        run: remote::run,
    },
    Bench {
        name: event_start::NAME,
        about: "a module's event report to the next place's module started, through the mission \
                controller, vs two TCP hops through a relay (ms)",
        run: event_start::run,
    },
    Bench {
        name: reachability::NAME,
        about: "mission analysis of 10 dining philosophers vs a plain breadth-first search \
                (states/s)",
        run: reachability::run,
    },
    Bench {
        name: compile_plan::NAME,
        about: "compile and check a 10,000-waypoint plan vs load and check the net it compiles \
                to (ms; goal < 100)",
        run: compile_plan::run,
    },
    Bench {
        name: qgc_import::NAME,
        about: "read a QGroundControl plan file of 10,000 waypoints into a plan vs serde_json \
                reading its text (ms)",
        run: qgc_import::run,
    },
    Bench {
        name: path_plan::NAME,
        about: "a path across a 100 m × 100 m world at 5 cm with 200 obstacles, 50 random \
                pairs, vs the pathfinding crate's A* on the same grid and costs (ms; goal p99 < \
                50, ratio <= 1)",
        run: path_plan::run,
    },
    Bench {
        name: auto_plan::NAME,
        about: "the constraint planner on 20 objectives on that world: the first plan proven \
                feasible, the distance matrix included, vs nearest neighbour + 2-opt (ms; goal \
                p99 < 200), and the best within 2 s",
        run: auto_plan::run,
    },
    Bench {
        name: auto_plan::NAME_QUALITY,
        about: "the constraint planner's plans within 2 s against nearest neighbour + 2-opt on \
                the same instances: better, equal, worse in the lexicographic order, and the \
                distance driven (goal: never worse)",
        run: auto_plan::run_quality,
    },
    Bench {
        name: path_plan::NAME_CHECK,
        about: "compile and check a 100-leg plan on that world, every leg planned, vs the same \
                plan with no world (ms; goal < 1000)",
        run: path_plan::run_check,
    },
    Bench {
        name: plan_update::NAME,
        about: "armor ctl update of a 100-leg plan on the 100 m world while the robot drives, to \
                the new net running, vs compiling that plan from scratch (ms; goal p99 < 200)",
        run: plan_update::run,
    },
    Bench {
        name: discovery::NAME,
        about: "a counter process spawned to its first value at a subscriber waiting for it, vs \
                spawning the binary (ms)",
        run: discovery::run,
    },
    Bench {
        name: kill::NAME_RECOVER,
        about: "SIGKILL of a module to its subscriber's first value from the restarted process, \
                vs spawning the binary (ms)",
        run: kill::run_recover,
    },
    Bench {
        name: kill::NAME_LOST,
        about: "samples written before a SIGKILL of their provider that never arrived, came \
                twice or out of order (across the restart too), on the killed provider's own \
                reliable 1 kHz link, vs what the protocol promises: 0",
        run: kill::run_lost,
    },
    Bench {
        name: health::NAME_SWITCH,
        about: "SIGKILL (and SIGSTOP, in sigstop_p50/p99) of an input's provider to the first \
                value from its fallback, vs SIGKILL to EOF on a TCP connection (and the lease) \
                (ms; goals p99 < 50, SIGSTOP < lease + 10 %)",
        run: health::run_switch,
    },
    Bench {
        name: health::NAME_BROADCAST,
        about: "a module's failure on the health stream to each of 20 subscribers, vs one \
                message written to 20 TCP connections (ms; goal p99 < 5)",
        run: health::run_broadcast,
    },
    Bench {
        name: sim_realtime::NAME,
        about: "simulated seconds per wall second of the robot demo system on one core vs the \
                bare simulator stepped in one thread (goal >= 50)",
        run: sim_realtime::run,
    },
    Bench {
        name: sim_realtime::NAME_MONITOR,
        about: "the robot demo system's simulated seconds per wall second with the studio's Run \
                view watching it, on the same core, vs without (goal ratio >= 0.9)",
        run: sim_realtime::run_monitor,
    },
    Bench {
        name: mapper_scan::NAME,
        about: "one 360-beam scan matched and integrated by the mapper vs the grid update alone \
                (ms)",
        run: mapper_scan::run,
    },
    Bench {
        name: loop_closure::NAME,
        about: "the mapper's error at the closure of a 100 m loop (simulator's default noise) \
                with loop closure vs without (m; goal ratio <= 0.2)",
        run: loop_closure::run,
    },
    Bench {
        name: localise::NAME_MS,
        about: "one Monte Carlo localisation update (1,000 particles, the sim's 360-beam scan) \
                vs the scan period (ms; goal p99 < 2)",
        run: localise::run_ms,
    },
    Bench {
        name: localise::NAME_ERROR,
        about: "the localiser's mean error against the sim's truth on the warehouse round vs \
                odometry alone (m; goal mean <= 0.1, max <= 0.25, >= 10x better)",
        run: localise::run_error,
    },
    Bench {
        name: arbiter_switch::NAME,
        about: "from a higher-priority behaviour's first proposal to its command out of \
                armor-mod-arbiter vs out of armor-mod-mux at 1000 Hz (ms; goal ratio <= 1.1)",
        run: arbiter_switch::run,
    },
    Bench {
        name: studio::NAME_FRAME,
        about: "one UI frame of armor-studio (headless) on a 1,000-block, 1,500-link diagram vs \
                a 60 Hz frame budget (ms; goal < 16; rendered_ms: rasterised too)",
        run: studio::run_frame,
    },
    Bench {
        name: studio::NAME_LOAD,
        about: "armor-studio opening that diagram (parse and check) vs the bare parse (ms)",
        run: studio::run_load,
    },
    Bench {
        name: studio::NAME_MAP,
        about: "one frame of armor-studio's Mission view (headless) with a 500-waypoint plan, \
                40 unit symbols and tactical graphics vs a 60 Hz frame budget (ms; goal < 16)",
        run: studio::run_map,
    },
    Bench {
        name: studio::NAME_LABELS,
        about: "placing the Mission view's labels (no overlaps) of a 500-waypoint plan, in one \
                frame (ms; goal < 5)",
        run: studio::run_labels,
    },
    Bench {
        name: studio::NAME_VS_SNARL,
        about: "one frame of armor-studio's diagram vs a bare egui-snarl viewer on the same \
                1,000-block graph, view, zoom and text (ms; goal ratio <= 0.5; also 100 and 500 \
                blocks)",
        run: studio::run_vs_snarl,
    },
    Bench {
        name: studio::NAME_OVERVIEW_VS_SNARL,
        about: "one frame of armor-studio's overview (all 1,000 blocks in view, boxes) vs the \
                bare egui-snarl viewer at that zoom drawing every node with its text (ms)",
        run: studio::run_overview_vs_snarl,
    },
    Bench {
        name: studio::NAME_LAYOUT,
        about: "armor-studio's File → Arrange (layered layout) on 200 blocks and 300 links wired \
                at random, some backwards (ms; goal < 100)",
        run: studio::run_layout,
    },
    Bench {
        name: studio::NAME_MARKERS,
        about: "one frame of armor-studio's Run view with 20 modules' markers, 500 each, \
                played at 10 Hz, every layer shown, vs a 60 Hz frame budget (ms; goal < 16)",
        run: studio::run_markers,
    },
    Bench {
        name: team::NAME_LATENCY,
        about: "a robot's status from its team bridge to a station (armor-team, zenoh on \
                loopback, sealed), p50/p99, vs a bare zenoh put/subscribe of the same size (ms)",
        run: team::run_latency,
    },
    Bench {
        name: team::NAME_LATENCY_RADIO,
        about: "the same through the namespace test's radio (10 % loss, 256 kbit/s, 300 ms \
                each way), vs a bare zenoh put/subscribe over it (ms; as root, skipped \
                otherwise)",
        run: team::run_latency_radio,
    },
    Bench {
        name: team::NAME_BANDWIDTH,
        about: "what each of 20 stand-in robots costs one station (status 2 Hz, pose 5 Hz), \
                vs the default budget of 50 kbit/s (kbit/s)",
        run: team::run_bandwidth,
    },
    Bench {
        name: team::NAME_STATION_FRAME,
        about: "p99 of one frame of armor-studio's station view with 20 robots, vs a 30 Hz \
                frame (ms; goal p99 <= 33)",
        run: team::run_station_frame,
    },
];

/// Lines that need more than the README's two commands install; each runs only when named.
const ON_REQUEST: &[Bench] = &[Bench {
    name: fuzz::NAME,
    about: "inputs run through each parser's fuzz target by fuzz/run.sh, with the crashes \
            found (must be 0); needs cargo-fuzz (`cargo install cargo-fuzz --locked`, as .ci/run does)",
    run: fuzz::run,
}];

fn main() -> ExitCode {
    if benchprobe::invoked_as_module() {
        return benchprobe::main();
    }
    let cli = Cli::parse();
    match run(cli) {
        Ok(code) => code,
        Err(err) => {
            eprintln!("error: {err:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    if let Some(args) = &cli.raw_echo {
        return raw::echo_main(&args[0], parse_number(&args[1], "--raw-echo SIZE")?);
    }
    if let Some(args) = &cli.raw_reply {
        return raw::reply_main(&args[0], parse_number(&args[1], "--raw-reply SIZE")?);
    }
    if let Some(args) = &cli.raw_sink {
        return raw::sink_main(&args[0], parse_number(&args[1], "--raw-sink BYTES")?);
    }
    if let Some(args) = &cli.kill_victim {
        return kill::victim_main(
            &args[0],
            parse_number(&args[1], "--kill-victim GENERATION")?,
            parse_number(&args[2], "--kill-victim PERIOD_US")?,
        );
    }
    if let Some(args) = &cli.raw_hop {
        return event_start::hop_main(
            &args[0],
            &args[1],
            parse_number(&args[2], "--raw-hop ROUNDS")?,
        );
    }
    Ok(run_benches(
        BENCHES,
        ON_REQUEST,
        &cli.names,
        Settings { quick: cli.quick },
        cli.list,
    ))
}

fn parse_number<T: std::str::FromStr>(text: &str, what: &str) -> anyhow::Result<T>
where
    T::Err: std::error::Error + Send + Sync + 'static,
{
    text.parse()
        .with_context(|| format!("{what}: `{text}` is not a number"))
}
