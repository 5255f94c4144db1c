//! `monitor`: logs every report of the run's health stream (`armor.health`), one line each, in
//! the order the run sent them, and publishes how many it received.

use armor_module_api::types::{Counter, Health};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node};

pub const TYPE: &str = "monitor";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Logs every report of the run's health stream (link `armor.health` to its `health`): \
         a module failed, stalled, restarting, recovered or given up, an input switched source.",
    )
    .category(armor_module_api::Category::Operator)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .input::<Health>(
        "health",
        "the run's health stream, `armor.health` (every report)",
    )
    .output::<Counter>("count", "how many reports were received so far")
}

/// The log line of one report, heard at `heard_ns` (run clock, as the report's stamp; with
/// `--time-scale` the lag is in run time too): `health #3 at 12.400 s (heard 0.210 ms later):
/// mapper failed (its connection closed)`.
pub fn line(seq: u64, health: &Health, heard_ns: u64) -> String {
    format!(
        "health #{seq} at {:.3} s (heard {:.3} ms later): {} {} ({})",
        health.at_ns as f64 / 1e9,
        heard_ns.saturating_sub(health.at_ns) as f64 / 1e6,
        health.module,
        health.kind,
        health.reason
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let input = node.reliable_input::<Health>("health")?;
    let output = node.output::<Counter>("count")?;
    let mut received: u64 = 0;
    loop {
        match node.next_event(None)? {
            Event::Input(port) if port == input.id() => {
                while let Some(sample) = node.take(&input)? {
                    let heard_ns = node.clock().now_ns();
                    received += 1;
                    tracing::info!("{}", line(sample.seq, &sample.value, heard_ns));
                    node.send(&output, &Counter(received))?;
                }
            }
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_report_reads_as_one_line() {
        let health = Health {
            module: "mapper".into(),
            kind: "failed".into(),
            reason: "its connection closed".into(),
            at_ns: 12_400_000_000,
        };
        assert_eq!(
            line(3, &health, 12_400_210_000),
            "health #3 at 12.400 s (heard 0.210 ms later): mapper failed (its connection closed)"
        );
    }
}
