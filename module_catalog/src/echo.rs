//! `echo`: republishes every value it receives, unchanged and at once.

use armor_module_api::types::Blob;
use armor_module_api::{BodyResult, Event, ModuleSpec, Node};

pub const TYPE: &str = "echo";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Republishes every value it receives, unchanged and at once.",
    )
    .category(armor_module_api::Category::Other)
    .version(env!("CARGO_PKG_VERSION"))
    .input::<Blob>("input", "the values to send back (every one, in order)")
    .output::<Blob>("output", "the same values")
}

pub fn body(node: &mut Node) -> BodyResult {
    let input = node.reliable_input::<Blob>("input")?;
    let output = node.output::<Blob>("output")?;
    loop {
        match node.next_event(None)? {
            Event::Input(port) if port == input.id() => {
                while let Some(sample) = node.take(&input)? {
                    node.send(&output, &sample.value)?;
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

    #[test]
    fn sends_back_the_same_bytes_in_order() {
        let values = [
            Blob(b"hello".to_vec()),
            Blob(Vec::new()),
            Blob((0..=255).collect()),
        ];
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        // Declared reliable before anything arrives: `TestBench::push` to a not-yet-reliable input
        // keeps only the newest value, and `reliable_input` then drops it.
        bench.node().reliable_input::<Blob>("input").expect("input");
        for value in &values {
            bench.push("input", value).expect("push");
        }
        body(bench.node()).expect("body");
        assert_eq!(bench.sent::<Blob>("output").expect("sent"), values);
    }
}
