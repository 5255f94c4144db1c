//! `sink`: counts the values it receives and publishes the count every `every` values.

use armor_module_api::types::{Blob, Counter};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

pub const TYPE: &str = "sink";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Counts the values it receives and publishes the count every `every` values.",
    )
    .category(armor_module_api::Category::Other)
    .version(env!("CARGO_PKG_VERSION"))
    .input::<Blob>("input", "the values to count (every one)")
    .output::<Counter>("count", "how many values were received so far")
    .param(
        ParamSpec::new(
            "every",
            ParamType::Int,
            "publish the count every this many values (1 or more)",
        )
        .min(1.0)
        .default("1"),
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let input = node.reliable_input::<Blob>("input")?;
    let output = node.output::<Counter>("count")?;
    let every = node.param::<u64>("every")?;
    let mut received: u64 = 0;
    loop {
        match node.next_event(None)? {
            Event::Input(port) if port == input.id() => {
                while node.take(&input)?.is_some() {
                    received += 1;
                    if received.is_multiple_of(every) {
                        node.send(&output, &Counter(received))?;
                    }
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
    use armor_module_api::testing::TestBench;

    fn run_with(params: &[(&str, &str)], values: usize) -> TestBench {
        let mut bench = TestBench::new(&spec(), params).expect("bench");
        // Declared reliable before anything arrives: `TestBench::push` to a not-yet-reliable input
        // keeps only the newest value, and `reliable_input` then drops it.
        bench.node().reliable_input::<Blob>("input").expect("input");
        for index in 0..values {
            bench.push("input", &Blob(vec![0; index])).expect("push");
        }
        body(bench.node()).expect("body");
        bench
    }

    #[test]
    fn publishes_the_count_every_n_values() {
        let bench = run_with(&[("every", "3")], 10);
        assert_eq!(
            bench.sent::<Counter>("count").expect("sent"),
            [Counter(3), Counter(6), Counter(9)]
        );
    }

    #[test]
    fn publishes_every_value_by_default() {
        let bench = run_with(&[], 3);
        assert_eq!(
            bench.sent::<Counter>("count").expect("sent"),
            [Counter(1), Counter(2), Counter(3)]
        );
    }

    #[test]
    fn refuses_every_below_one() {
        let mut bench = TestBench::new(&spec(), &[("every", "0")]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse");
        assert!(err.to_string().contains("`every`"), "{err}");
    }
}
