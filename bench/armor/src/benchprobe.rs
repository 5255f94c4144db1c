//! The `benchprobe` module that `event_to_start_ms` runs under `armor run`: this very binary,
//! called through a symlink named `armor-mod-benchprobe`.
//!
//! Each time it becomes active (active from the start, or `Event::Start`) it prints
//! `benchprobe active N NS` or `benchprobe start N NS` (its N-th activation, seen at NS on the
//! run clock), then reports `tick` and prints `benchprobe report N NS` (NS read just before
//! reporting; the line is printed once the report is on its way, so that printing it delays
//! nothing). The run clock is Unix-time based and shared by every process of the run, so a report
//! of one module and the start of another compare directly.

use std::ffi::OsStr;
use std::io::Write as _;
use std::path::Path;
use std::process::ExitCode;

use armor_module_api::{BodyResult, Event, ModuleSpec, Node};

/// The module type; its binary is `armor-mod-benchprobe`.
pub const MODULE_TYPE: &str = "benchprobe";
/// The file name under which this binary is the probe module.
pub const BINARY_NAME: &str = "armor-mod-benchprobe";
/// The event reported on each activation.
pub const TICK: &str = "tick";
/// The first word of every line the probe prints.
pub const LINE_TAG: &str = "benchprobe";

/// Whether this process was started as `armor-mod-benchprobe` (through the symlink: the
/// executable itself is `armor-bench`, so only `argv[0]` tells).
pub fn invoked_as_module() -> bool {
    std::env::args_os()
        .next()
        .is_some_and(|arg0| Path::new(&arg0).file_name() == Some(OsStr::new(BINARY_NAME)))
}

/// What a probe line says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Active from its start (its configuration said so): not a start command.
    Active,
    /// Started by a start command.
    Start,
    /// About to report `tick`.
    Report,
}

/// A probe line, once `armor run`'s `[module] ` prefix is taken off.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Line {
    pub kind: Kind,
    /// The activation (1 for the first), or the report that followed it.
    pub count: u64,
    /// Run clock, nanoseconds.
    pub ns: u64,
}

impl Line {
    pub fn parse(text: &str) -> Option<Line> {
        let mut words = text.split_ascii_whitespace();
        if words.next()? != LINE_TAG {
            return None;
        }
        let kind = match words.next()? {
            "active" => Kind::Active,
            "start" => Kind::Start,
            "report" => Kind::Report,
            _ => return None,
        };
        let count = words.next()?.parse().ok()?;
        let ns = words.next()?.parse().ok()?;
        words.next().is_none().then_some(Line { kind, count, ns })
    }
}

fn spec() -> ModuleSpec {
    ModuleSpec::new(
        MODULE_TYPE,
        "armor-bench's probe: reports `tick` each time it is started, printing when it saw the \
         start and when it reported",
    )
    .version(env!("CARGO_PKG_VERSION"))
    .event(TICK, "reported at once on each activation")
}

/// The module's `main`.
pub fn main() -> ExitCode {
    armor_module_api::run(spec(), body)
}

fn body(node: &mut Node) -> BodyResult {
    let mut activations = 0;
    if node.is_active() {
        activations += 1;
        let seen = node.clock().now_ns();
        activate(node, "active", activations, seen)?;
    }
    loop {
        match node.next_event(None)? {
            Event::Start => {
                let seen = node.clock().now_ns();
                activations += 1;
                activate(node, "start", activations, seen)?;
            }
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

fn activate(node: &mut Node, how: &str, count: u64, seen_ns: u64) -> BodyResult {
    let mut stdout = std::io::stdout().lock();
    writeln!(stdout, "{LINE_TAG} {how} {count} {seen_ns}")?;
    stdout.flush()?;
    let reported_ns = node.clock().now_ns();
    node.report(TICK)?;
    // On its way now rather than at the next wait for an event.
    node.flush()?;
    writeln!(stdout, "{LINE_TAG} report {count} {reported_ns}")?;
    stdout.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_read_back() {
        assert_eq!(
            Line::parse("benchprobe start 3 1700000000123456789"),
            Some(Line {
                kind: Kind::Start,
                count: 3,
                ns: 1_700_000_000_123_456_789
            })
        );
        assert_eq!(
            Line::parse("benchprobe active 1 5").map(|line| line.kind),
            Some(Kind::Active)
        );
        for bad in [
            "",
            "INFO reporting event event=\"tick\"",
            "benchprobe start 3",
            "benchprobe stop 3 5",
            "benchprobe report x 5",
            "benchprobe report 1 5 6",
        ] {
            assert_eq!(Line::parse(bad), None, "{bad}");
        }
    }
}
