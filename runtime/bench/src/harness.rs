//! The ArMoR side of a benchmark: an agent and a node hosted in this process.

use std::net::{Ipv4Addr, SocketAddr};
use std::time::Duration;

use anyhow::Context as _;
use armor_module_api::{ModuleSpec, Node, Standalone};

/// The bench's node name: its outputs are `bench.OUTPUT`.
pub const NODE_NAME: &str = "bench";
/// How long modules have to link up before a benchmark gives up.
pub const LINK_TIMEOUT: Duration = Duration::from_secs(20);
/// No single wait of a timed loop lasts longer than this (a dead peer fails the bench).
pub const STALL_TIMEOUT: Duration = Duration::from_secs(10);

/// A fresh agent on a thread of this process, on a free port (one per benchmark, so that no
/// registration outlives the benchmark that made it).
pub fn agent() -> anyhow::Result<SocketAddr> {
    armor_runtime::agent::spawn(SocketAddr::from((Ipv4Addr::LOCALHOST, 0)))
        .context("cannot start an agent")
}

/// Hosts a module named [`NODE_NAME`] in this process, its inputs bound as `binds` says
/// (`input`, `module.output`).
pub fn connect(
    spec: ModuleSpec,
    agent: SocketAddr,
    binds: &[(&str, &str)],
) -> anyhow::Result<Node> {
    Node::connect(
        spec,
        Standalone {
            name: Some(NODE_NAME.to_owned()),
            agent: Some(agent.to_string()),
            binds: binds
                .iter()
                .map(|&(input, source)| (input.to_owned(), source.to_owned()))
                .collect(),
            ..Standalone::default()
        },
    )
    .context("cannot connect the bench's node")
}
