//! `armor-bench-peers`: ArMoR measured against its best peers in the same run (issue 10): the
//! Spin model checker, the `libpetri` crate, roxmltree and xml-rs, plain process spawns, and
//! (with `--features zenoh`) zenoh.
//!
//! It prints one JSON line per benchmark in `armor-bench`'s format: `bench`, `ours`,
//! `reference`, `unit`, `ratio` (= ours / reference), plus what each benchmark says of its
//! figures (`goal`, `reference_is`, details per size or per net). The crate is excluded from the
//! root workspace, so `cargo build/test --workspace` never builds its dependencies:
//!
//! ```sh
//! CARGO_TARGET_DIR=target/peers cargo build --release --manifest-path bench/peers/Cargo.toml
//! target/peers/release/armor-bench-peers [NAME...] [--quick] [--list]
//! ```

mod firings;
mod probe_cold;
mod spin;
mod xml_load;
#[cfg(feature = "zenoh")]
mod zenoh_bench;

use std::process::ExitCode;

use clap::Parser;

use armor_bench_report::{Bench, run_benches};

#[derive(Parser)]
#[command(
    name = "armor-bench-peers",
    version,
    about = "Measures ArMoR against its best peers (Spin, libpetri, xml-rs, zenoh), one JSON \
             line per benchmark"
)]
struct Cli {
    /// Benchmarks to run, in this order (default: all; see --list).
    names: Vec<String>,
    /// Tiny iteration counts: checks that everything runs, measures nothing worth keeping.
    #[arg(long)]
    quick: bool,
    /// Print the benchmark names and exit.
    #[arg(long)]
    list: bool,
    /// Hidden peer process of the zenoh benchmarks.
    #[cfg(feature = "zenoh")]
    #[arg(long, hide = true, num_args = 1.., value_name = "ARGS")]
    zenoh_peer: Option<Vec<String>>,
}

pub use armor_bench_report::Settings;

const BENCHES: &[Bench] = &[
    Bench {
        name: spin::NAME,
        about: "reachable markings per second of dining philosophers (10, 12, 14) vs Spin on the \
                same net in Promela (states/s, identical counts)",
        run: spin::run,
    },
    Bench {
        name: firings::NAME,
        about: "firings per second of our mission engine vs libpetri on a 100-transition chain \
                and a 10-branch mission (firings/s)",
        run: firings::run,
    },
    Bench {
        name: xml_load::NAME,
        about: "load of a 5,000-module system and a 10,000-waypoint plan vs roxmltree, the \
                fastest reader, parsing the same bytes (and xml-rs beside it) (ms; goal ratio <= 2)",
        run: xml_load::run,
    },
    Bench {
        name: probe_cold::NAME,
        about: "50 module binaries probed without cache vs 50 spawns of /bin/true, and served \
                warm from the probe cache (ms)",
        run: probe_cold::run,
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::LATENCY[0].0,
        about: "round trip of 64 bytes through armor-mod-echo vs zenoh peers (us)",
        run: |settings| zenoh_bench::run_latency(0, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::LATENCY[1].0,
        about: "round trip of 1 KiB through armor-mod-echo vs zenoh peers (us)",
        run: |settings| zenoh_bench::run_latency(1, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::LATENCY[2].0,
        about: "round trip of 64 KiB through armor-mod-echo vs zenoh peers (us)",
        run: |settings| zenoh_bench::run_latency(2, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::LATENCY[3].0,
        about: "round trip of 1 MiB through armor-mod-echo vs zenoh peers (us)",
        run: |settings| zenoh_bench::run_latency(3, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::THROUGHPUT[0].0,
        about: "64-byte messages per second into armor-mod-sink vs a zenoh subscriber (msg/s)",
        run: |settings| zenoh_bench::run_throughput(0, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::THROUGHPUT[1].0,
        about: "1 KiB messages per second into armor-mod-sink vs a zenoh subscriber (msg/s)",
        run: |settings| zenoh_bench::run_throughput(1, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::THROUGHPUT[2].0,
        about: "64 KiB messages per second into armor-mod-sink vs a zenoh subscriber (msg/s)",
        run: |settings| zenoh_bench::run_throughput(2, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::THROUGHPUT[3].0,
        about: "1 MiB messages per second into armor-mod-sink vs a zenoh subscriber (msg/s)",
        run: |settings| zenoh_bench::run_throughput(3, settings),
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::NAME_PULL,
        about: "request for the latest value vs raw TCP request/reply and zenoh get (us)",
        run: zenoh_bench::run_pull,
    },
    #[cfg(feature = "zenoh")]
    Bench {
        name: zenoh_bench::NAME_DISCOVERY,
        about: "module start to first delivered message vs zenoh session open to first \
                sample (ms)",
        run: zenoh_bench::run_discovery,
    },
];

fn main() -> ExitCode {
    let cli = Cli::parse();
    #[cfg(feature = "zenoh")]
    if let Some(args) = &cli.zenoh_peer {
        return zenoh_bench::peer_main(args);
    }
    run_benches(BENCHES, &[], &cli.names, Settings { quick: cli.quick }, cli.list)
}

/// Four significant digits, for the figures inside a report's details.
pub fn round4(value: f64) -> f64 {
    if !value.is_finite() || value == 0.0 {
        return value;
    }
    let magnitude = value.abs().log10().floor() as i32;
    let factor = 10f64.powi(3 - magnitude);
    (value * factor).round() / factor
}
