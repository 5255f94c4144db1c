//! `discovery_ms`: a module process started to its first value delivered to a subscriber that
//! was waiting for it: `armor-mod-counter` (publishing every 0.5 ms) spawned with its agent, to
//! the first sample at this bench's node, whose input is bound to it and which asked the agent
//! before the process existed (the agent tells it when the provider registers). Reference:
//! spawning the same binary with `--describe` until it exits, the floor of any start.

use std::time::{Duration, Instant};

use anyhow::bail;
use armor_module_api::types::Counter;
use armor_module_api::{Event, ModuleSpec};

use crate::Settings;
use crate::harness::{self, LINK_TIMEOUT};
use crate::kill::describe_spawn;
use crate::procs::{ChildGuard, module_binary, module_command};
use armor_bench_report::{Report, median};

pub const NAME: &str = "discovery_ms";
/// After a round's publisher is killed, how long the subscriber is given to see it gone.
const SETTLE: Duration = Duration::from_millis(300);

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let rounds = if settings.quick { 2 } else { 15 };
    let agent = harness::agent()?;
    let spec = ModuleSpec::new("bench", "armor-bench: the discovery probe")
        .input::<Counter>("count", "the started counter's values");
    let mut node = harness::connect(spec, agent, &[("count", "pub.count")])?;
    let count = node.input::<Counter>("count")?;
    let agent = agent.to_string();
    let mut ours = Vec::with_capacity(rounds);
    let mut reference = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let command = module_command(
            "counter",
            &[
                "--name",
                "pub",
                "--agent",
                &agent,
                "--param",
                "period_secs=0.0005",
            ],
        )?;
        let start = Instant::now();
        let mut publisher = ChildGuard::spawn_quiet("armor-mod-counter", command)?;
        let give_up = start + LINK_TIMEOUT;
        loop {
            match node.next_event_until(give_up)? {
                Event::Input(port) if port == count.id() && node.take(&count)?.is_some() => break,
                Event::Timeout => {
                    publisher.check_alive()?;
                    bail!("no value from the started counter within {LINK_TIMEOUT:?}");
                }
                _ => {}
            }
        }
        ours.push(start.elapsed().as_secs_f64() * 1e3);
        drop(publisher);
        // The subscriber sees its provider go and asks the agent again before the next one.
        let settle = Instant::now() + SETTLE;
        while Instant::now() < settle {
            node.next_event_until(settle)?;
            while node.take(&count)?.is_some() {}
        }
        reference.push(describe_spawn(&module_binary("counter")?)?);
    }
    Ok(
        Report::single(NAME, "ms", median(&ours), median(&reference))
            .with("rounds", rounds)
            .with(
                "reference_is",
                "spawning armor-mod-counter --describe until it exits",
            ),
    )
}
