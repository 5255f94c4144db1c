//! `latency_64b_cross_ns`: round trips of 64 bytes, one in flight, between a node in this
//! process and an `armor-mod-echo` in another network namespace (joined to this one by a veth
//! pair, as two computers of a robot on a cable), against TCP ping-pong with a peer in the same
//! namespace over the same pair. Needs root and iproute2, as `remote_start_ms`.

use std::net::SocketAddr;
use std::process::Command;

use anyhow::Context as _;
use armor_module_api::{Node, Standalone};

use crate::Settings;
use crate::latency::{self, ArmorPingPong, RawPingPong};
use crate::procs::{ChildGuard, module_binary};
use crate::raw;
use crate::remote::{FAR, FarSide, NEAR};
use armor_bench_report::Report;

pub const NAME: &str = "latency_64b_cross_ns";
const SIZE: usize = 64;

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let far = FarSide::make()?;
    let counts = latency::counts(SIZE, settings);
    let echo_binary = module_binary("echo")?;
    let ours = || -> anyhow::Result<ArmorPingPong> {
        let agent = armor_runtime::agent::spawn(SocketAddr::new(
            NEAR.parse().context("the near address")?,
            0,
        ))
        .context("cannot start an agent")?;
        let node = Node::connect(
            latency::spec(),
            Standalone {
                name: Some(crate::harness::NODE_NAME.to_owned()),
                agent: Some(agent.to_string()),
                binds: vec![("pong".to_owned(), "echo.output".to_owned())],
                host: Some(NEAR.to_owned()),
                ..Standalone::default()
            },
        )?;
        ArmorPingPong::link(
            node,
            SIZE,
            |agent| {
                let mut command = Command::new("ip");
                command
                    .args(["netns", "exec", &far.ns])
                    .arg(&echo_binary)
                    .args(["--name", "echo", "--agent", agent, "--host", FAR])
                    .args(["--bind", "input=bench.ping"]);
                ChildGuard::spawn("armor-mod-echo (far)", command)
            },
            agent,
        )
    };
    let reference = || {
        RawPingPong::over(
            raw::start_peer_on(NEAR, Some(&far.ns), "--raw-echo", &SIZE.to_string())?,
            SIZE,
        )
    };
    let (ours, theirs) = latency::in_turn(&counts, ours, reference)?;
    Ok(Report::distribution(NAME, "ns", 1e9, &ours, &theirs)
        .with("bytes", SIZE)
        .with(
            "reference_is",
            "TCP ping-pong with a peer in the other namespace, over the same veth pair; each \
             side with fresh processes of its own in turn",
        ))
}
