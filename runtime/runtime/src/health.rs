//! The run's health stream (`armor.health`): what happens to each module — `failed`, `stalled`,
//! `restarting`, `recovered`, `gave_up` — and the inputs that switch source because of it
//! (`switched`), told to every module as it happens.
//!
//! The config server keeps the book ([`HealthBook`]) and sends each report to every connected
//! module on the connection it already holds (`FromSupervisor::Health`): no lookup, no new
//! socket, so a report reaches every module within one write each. Which sources are down
//! decides which source each input with fallbacks is bound to ([`HealthBook::source_for`]).
//!
//! Detection: a module whose process dies is `failed` as soon as its connection to the config
//! server closes (the kernel closes it with the process); one that is stopped or stuck is
//! `stalled` once it has sent nothing for a lease, found within a sixteenth of a lease after
//! (the heartbeat's check period), so at most 1.0625 leases after its last answer.

use std::collections::{BTreeMap, BTreeSet};

use armor_model::{Endpoint, SystemConfig};
use armor_module_api::Clock;
use armor_module_api::types::Health;

/// The kinds after which a module's outputs are not to be relied on until it has `recovered`.
const DOWN_KINDS: [&str; 3] = ["failed", "stalled", "gave_up"];

pub struct HealthBook {
    clock: Clock,
    seq: u64,
    /// Modules down, with the kind that put them there.
    down: BTreeMap<String, String>,
    /// Modules told to shut down: their connection closing is no failure.
    leaving: BTreeSet<String>,
}

impl HealthBook {
    pub fn new(clock: Clock) -> Self {
        Self {
            clock,
            seq: 0,
            down: BTreeMap::new(),
            leaving: BTreeSet::new(),
        }
    }

    /// Notes a report and returns it with its sequence number (1 for the first).
    pub fn report(&mut self, module: &str, kind: &str, reason: &str) -> (u64, Health) {
        if DOWN_KINDS.contains(&kind) {
            self.down.insert(module.to_owned(), kind.to_owned());
        } else if kind == "recovered" {
            self.down.remove(module);
        }
        self.seq += 1;
        let health = Health {
            module: module.to_owned(),
            kind: kind.to_owned(),
            reason: reason.to_owned(),
            at_ns: self.clock.now_ns(),
        };
        tracing::info!("health: `{module}` {kind} ({reason})");
        (self.seq, health)
    }

    /// Whether `module`'s failure was reported since it last recovered.
    pub fn failure_reported(&self, module: &str) -> bool {
        self.down.get(module).is_some_and(|kind| kind == "failed")
    }

    pub fn is_down(&self, module: &str) -> bool {
        self.down.contains_key(module)
    }

    /// The module was told to shut down: its connection closing says nothing of its health.
    pub fn leaving(&mut self, module: &str) {
        self.leaving.insert(module.to_owned());
    }

    /// Whether a closed connection of `module` is a failure (not a shutdown asked for).
    pub fn closed_is_failure(&mut self, module: &str) -> bool {
        !self.leaving.remove(module)
    }

    /// A new process of the module said hello: a later shutdown of it is again asked for anew.
    pub fn connected(&mut self, module: &str) {
        self.leaving.remove(module);
    }

    /// The data name that feeds `input` now: its source, or while that is down its first
    /// fallback whose provider is up (the source if all are down, so that the input comes back
    /// with the first of them that does).
    pub fn source_for(&self, system: &SystemConfig, input: &Endpoint, primary: &str) -> String {
        let sources = system.sources(input);
        if sources.len() < 2 {
            return primary.to_owned();
        }
        sources
            .iter()
            .find(|link| {
                link.from.to_string() == armor_module_api::protocol::HEALTH
                    || !self.is_down(&link.from.module)
            })
            .map_or_else(|| primary.to_owned(), |link| link.from.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_input_takes_its_first_source_that_is_up() {
        let system = SystemConfig::parse(
            r#"<system name="s">
  <module name="mapper" type="mapper"/><module name="sim" type="sim"/>
  <module name="gps" type="gps"/><module name="follower" type="follower"/>
  <link from="mapper.pose" to="follower.odometry"/>
  <link from="gps.pose" to="follower.odometry" fallback="2"/>
  <link from="sim.odometry" to="follower.odometry" fallback="1"/>
</system>"#,
        )
        .expect("parses");
        let input = Endpoint::new("follower", "odometry");
        let mut book = HealthBook::new(Clock::real_time());
        let source = |book: &HealthBook| book.source_for(&system, &input, "mapper.pose");
        assert_eq!(source(&book), "mapper.pose");
        assert_eq!(book.report("mapper", "stalled", "no answer").0, 1);
        assert_eq!(source(&book), "sim.odometry");
        book.report("sim", "failed", "its connection closed");
        assert_eq!(source(&book), "gps.pose");
        book.report("gps", "gave_up", "5 crashes");
        assert_eq!(source(&book), "mapper.pose", "all down: the source");
        book.report("sim", "restarting", "in 100 ms");
        assert_eq!(source(&book), "mapper.pose", "restarting is not up yet");
        let (seq, health) = book.report("sim", "recovered", "configured again");
        assert_eq!((seq, health.kind.as_str()), (5, "recovered"));
        assert_eq!(source(&book), "sim.odometry");
        book.report("mapper", "recovered", "configured again");
        assert_eq!(source(&book), "mapper.pose", "back to the source");
    }

    #[test]
    fn a_failure_is_reported_once_until_recovered() {
        let mut book = HealthBook::new(Clock::real_time());
        assert!(!book.failure_reported("mapper"));
        book.report("mapper", "stalled", "no answer");
        assert!(!book.failure_reported("mapper"), "stalled is not failed");
        book.report("mapper", "failed", "its connection closed");
        assert!(book.failure_reported("mapper"));
        book.report("mapper", "restarting", "in 100 ms");
        assert!(
            book.failure_reported("mapper"),
            "still down while restarting"
        );
        book.report("mapper", "recovered", "configured again");
        assert!(!book.failure_reported("mapper"));
    }

    #[test]
    fn a_shutdown_asked_for_is_no_failure() {
        let mut book = HealthBook::new(Clock::real_time());
        assert!(book.closed_is_failure("sim"));
        book.leaving("sim");
        assert!(!book.closed_is_failure("sim"));
        assert!(book.closed_is_failure("sim"), "only once");
    }
}
