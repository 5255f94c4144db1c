//! `checker`: checks that a `Counter` stream arrives complete and in order.

use armor_module_api::types::Counter;
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

pub const TYPE: &str = "checker";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Checks that counter values arrive one more than the previous, and logs a summary.",
    )
        .category(armor_module_api::Category::Other)
    .version(env!("CARGO_PKG_VERSION"))
    .input::<Counter>("input", "the values to check (every one, in order)")
    .output::<Counter>("received", "how many values were received so far")
    .param(
        ParamSpec::new(
            "report_every",
            ParamType::Int,
            "log a summary line every this many values (1 or more)",
        ).min(1.0)
        .default("10"),
    )
    .event(
        "out_of_order",
        "a value was not one more than the previous one",
    )
    .event(
        "restarted",
        "values now come over a new link: the provider restarted or the link was re-established (not an error)",
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let input = node.reliable_input::<Counter>("input")?;
    let output = node.output::<Counter>("received")?;
    let report_every = node.param::<u64>("report_every")?;
    let mut tally = Tally::default();
    loop {
        match node.next_event(None)? {
            Event::Input(port) if port == input.id() => {
                while let Some(sample) = node.take(&input)? {
                    match tally.check(sample.value.0, sample.link) {
                        Verdict::InOrder => {}
                        Verdict::Relinked { previous, value } => {
                            tracing::info!("new link to the provider: {value} after {previous}");
                            node.report("restarted")?;
                        }
                        Verdict::OutOfOrder { previous, value } => {
                            tracing::warn!("out of order: {value} after {previous}");
                            node.report("out_of_order")?;
                        }
                    }
                    node.send(&output, &Counter(tally.received))?;
                    if tally.received.is_multiple_of(report_every) {
                        tracing::info!("{}", tally.summary());
                    }
                }
            }
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    InOrder,
    Relinked { previous: u64, value: u64 },
    OutOfOrder { previous: u64, value: u64 },
}

/// What the checker has seen so far.
#[derive(Clone, Debug, Default)]
struct Tally {
    received: u64,
    last: Option<u64>,
    link: u64,
    out_of_order: u64,
}

impl Tally {
    /// Takes a value and the link it came by. The first value of a link may be anything (the
    /// checker may have joined late, or the provider restarted); after it, each value must be
    /// one more than the previous.
    fn check(&mut self, value: u64, link: u64) -> Verdict {
        self.received += 1;
        let verdict = match self.last {
            None => Verdict::InOrder,
            Some(previous) if link != self.link => Verdict::Relinked { previous, value },
            Some(previous) if previous.checked_add(1) == Some(value) => Verdict::InOrder,
            Some(previous) => {
                self.out_of_order += 1;
                Verdict::OutOfOrder { previous, value }
            }
        };
        self.last = Some(value);
        self.link = link;
        verdict
    }

    /// The line end-to-end tests look for: `received N values, last V, in order` or
    /// `received N values, last V, K out of order`.
    fn summary(&self) -> String {
        let last = self.last.unwrap_or(0);
        let order = match self.out_of_order {
            0 => "in order".to_owned(),
            count => format!("{count} out of order"),
        };
        format!("received {} values, last {last}, {order}", self.received)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::TestBench;

    /// Runs the checker on values; `None` stands for the input being relinked.
    fn run_with(values: &[Option<u64>]) -> TestBench {
        let mut bench = TestBench::new(&spec(), &[("report_every", "2")]).expect("bench");
        for value in values {
            match value {
                Some(value) => bench.push("input", &Counter(*value)).expect("push"),
                None => bench.relink("input").expect("relink"),
            }
        }
        body(bench.node()).expect("body");
        bench
    }

    #[test]
    fn in_order_values_are_counted_silently() {
        let bench = run_with(&[Some(5), Some(6), Some(7)]);
        assert!(bench.reported().is_empty());
        assert_eq!(
            bench.sent::<Counter>("received").expect("sent"),
            [Counter(1), Counter(2), Counter(3)]
        );
    }

    #[test]
    fn a_gap_or_a_step_back_on_one_link_is_out_of_order() {
        let bench = run_with(&[Some(1), Some(2), Some(4), Some(1)]);
        assert_eq!(bench.reported(), ["out_of_order", "out_of_order"]);
        assert_eq!(bench.sent::<Counter>("received").expect("sent").len(), 4);
    }

    #[test]
    fn a_new_link_is_a_restart_whatever_its_first_value() {
        let bench = run_with(&[Some(19), Some(20), None, Some(20), Some(21), None, Some(1)]);
        assert_eq!(bench.reported(), ["restarted", "restarted"]);
        assert_eq!(bench.sent::<Counter>("received").expect("sent").len(), 5);
    }

    #[test]
    fn refuses_report_every_below_one() {
        let mut bench = TestBench::new(&spec(), &[("report_every", "0")]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse");
        assert!(err.to_string().contains("`report_every`"), "{err}");
    }

    #[test]
    fn summary_lines() {
        let mut tally = Tally::default();
        for value in [1, 2, 3] {
            tally.check(value, 1);
        }
        assert_eq!(tally.summary(), "received 3 values, last 3, in order");
        for value in [5, 1, 7] {
            tally.check(value, 1);
        }
        assert_eq!(tally.summary(), "received 6 values, last 7, 3 out of order");
    }
}
