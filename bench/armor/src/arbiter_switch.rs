//! `arbiter_switch_ms`: from a behaviour of higher priority becoming applicable (its first
//! proposal published) to its command coming out of the selector, the winner changed, against
//! the same path through `mux` (today's fixed-priority selector) at its best, publishing at its
//! highest rate (1000 Hz). Both run as their real binaries, standalone on an agent of this
//! process, with the same two inputs: a low-priority candidate proposing all along and a
//! high-priority one that proposes once, goes stale, and proposes again. Samples alternate
//! between the two in blocks, so that a change in the machine's load weighs on both alike.

use std::time::{Duration, Instant};

use anyhow::{Context as _, bail};
use armor_module_api::types::Twist;
use armor_module_api::{Event, Input, ModuleSpec, Node, Output};

use crate::Settings;
use crate::harness::{self, LINK_TIMEOUT, STALL_TIMEOUT};
use crate::procs::{ChildGuard, module_command};
use armor_bench_report::Report;

pub const NAME: &str = "arbiter_switch_ms";
/// A proposal older than this no longer counts (both selectors).
const FRESH_SECS: f64 = 0.03;
/// A switch not seen within this long is counted lost (and left out of the times).
const LOST_AFTER: Duration = Duration::from_secs(1);
/// The low-priority candidate proposes this often.
const LOW_PERIOD: Duration = Duration::from_millis(5);
const LOW: Twist = Twist {
    linear_mps: 0.1,
    angular_radps: 0.0,
};

/// One selector under test, with the bench's node feeding and reading it.
struct Selector {
    node: Node,
    low: Output<Twist>,
    high: Output<Twist>,
    out: Input<Twist>,
    child: ChildGuard,
    /// Distinguishes each high proposal from the previous ones.
    next_id: u32,
}

impl Selector {
    /// `armor-mod-arbiter` (candidate_1 high, candidate_2 low) or `armor-mod-mux` (observe high,
    /// auto low).
    fn start(arbiter: bool) -> anyhow::Result<Selector> {
        let agent = harness::agent()?;
        let spec = ModuleSpec::new("bench", "armor-bench: two competing candidates")
            .output::<Twist>("low", "the low-priority candidate")
            .output::<Twist>("high", "the high-priority candidate")
            .input::<Twist>("out", "the selector's command");
        let node = harness::connect(spec, agent, &[("out", "sel.cmd_vel")])?;
        let fresh = format!("fresh_secs={FRESH_SECS}");
        let agent = agent.to_string();
        let mut args = vec!["--name", "sel", "--agent", &agent, "--param", &fresh];
        let (module_type, extra): (&str, &[&str]) = if arbiter {
            (
                "arbiter",
                &[
                    "--bind",
                    "candidate_1=bench.high",
                    "--bind",
                    "candidate_2=bench.low",
                    "--param",
                    "hold_secs=0",
                ],
            )
        } else {
            (
                "mux",
                &[
                    "--bind",
                    "observe=bench.high",
                    "--bind",
                    "auto=bench.low",
                    "--param",
                    "rate_hz=1000",
                ],
            )
        };
        args.extend_from_slice(extra);
        let child = ChildGuard::spawn(
            &format!("armor-mod-{module_type}"),
            module_command(module_type, &args)?,
        )?;
        let mut node = node;
        let low = node.output::<Twist>("low")?;
        let high = node.output::<Twist>("high")?;
        let out = node.input::<Twist>("out")?;
        let mut selector = Selector {
            node,
            low,
            high,
            out,
            child,
            next_id: 0,
        };
        let give_up = Instant::now() + LINK_TIMEOUT;
        while selector.node.subscriber_count(&selector.low) == 0
            || selector.node.subscriber_count(&selector.high) == 0
            || !selector.node.is_linked(&selector.out)
        {
            selector.node.next_event(Some(LOW_PERIOD))?;
            selector.child.check_alive()?;
            if Instant::now() > give_up {
                return Err(selector
                    .child
                    .failure("did not link within the time allowed"));
            }
        }
        Ok(selector)
    }

    /// Proposes low until the selector's output is low again (high stale), then times one high
    /// proposal to the selector's output (`None`: not seen within [`LOST_AFTER`]).
    fn switch(&mut self) -> anyhow::Result<Option<Duration>> {
        self.wait_for(LOW, true, STALL_TIMEOUT)?;
        self.next_id += 1;
        let high = Twist {
            linear_mps: 0.5,
            angular_radps: f64::from(self.next_id),
        };
        let start = Instant::now();
        self.node.send(&self.high, &high)?;
        self.node.flush()?;
        Ok(self
            .wait_for(high, false, LOST_AFTER)?
            .then(|| start.elapsed()))
    }

    /// Waits until the output is `wanted`, proposing low every [`LOW_PERIOD`] when `with_low`
    /// (otherwise low goes on too, but the wait is what is timed: it is sent only when due).
    /// Whether it was seen within `patience`; [`STALL_TIMEOUT`] is an error.
    fn wait_for(
        &mut self,
        wanted: Twist,
        with_low: bool,
        patience: Duration,
    ) -> anyhow::Result<bool> {
        let give_up = Instant::now() + patience;
        let mut low_due = Instant::now();
        loop {
            if Instant::now() >= low_due {
                self.node.send(&self.low, &LOW)?;
                low_due = Instant::now() + LOW_PERIOD;
            }
            let wait = if with_low {
                low_due.saturating_duration_since(Instant::now())
            } else {
                LOW_PERIOD
            };
            if let Event::Input(_) = self.node.next_event(Some(wait))?
                && let Some(sample) = self.node.take(&self.out)?
                && sample.value == wanted
            {
                return Ok(true);
            }
            if Instant::now() > give_up {
                self.child.check_alive()?;
                if patience >= STALL_TIMEOUT {
                    bail!("the selector never put out {wanted:?}");
                }
                return Ok(false);
            }
        }
    }
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let (block, blocks) = if settings.quick { (10, 2) } else { (100, 5) };
    let mut arbiter = Selector::start(true).context("the arbiter")?;
    let mut mux = Selector::start(false).context("the mux")?;
    // Warm-up: links made, caches warm.
    for _ in 0..3 {
        arbiter.switch()?;
        mux.switch()?;
    }
    // A switch not seen in time is counted, not timed: a best-effort input keeps only the newest
    // sample, so a command can be overtaken before the bench's node reads it.
    let mut ours = Vec::with_capacity(block * blocks);
    let mut reference = Vec::with_capacity(block * blocks);
    let (mut ours_lost, mut reference_lost) = (0, 0);
    for _ in 0..blocks {
        for _ in 0..block {
            match arbiter.switch()? {
                Some(time) => ours.push(time),
                None => ours_lost += 1,
            }
        }
        for _ in 0..block {
            match mux.switch()? {
                Some(time) => reference.push(time),
                None => reference_lost += 1,
            }
        }
    }
    Ok(Report::distribution(NAME, "ms", 1e3, &ours, &reference)
        .with("lost", ours_lost)
        .with("reference_lost", reference_lost))
}
