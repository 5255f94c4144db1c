//! `counter`: publishes 1, 2, 3, … every `period_secs` of run time while active.

use armor_module_api::types::Counter;
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;

pub const TYPE: &str = "counter";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(TYPE, "Publishes 1, 2, 3, ... every period while active.")
        .category(armor_module_api::Category::Sensor)
        .version(env!("CARGO_PKG_VERSION"))
        .output::<Counter>("count", "the values 1, 2, 3, ... in order")
        .param(
            ParamSpec::new(
                "period_secs",
                ParamType::Float,
                "time between two values (run time, greater than 0; tunable live)",
            )
            .above(0.0)
            .unit("s")
            .default("0.1"),
        )
        .param(
            ParamSpec::new(
                "limit",
                ParamType::Int,
                "how many values to publish before reporting `done` (0: no limit)",
            )
            .min(0.0)
            .default("0"),
        )
        .event("done", "`limit` values have been published")
}

pub fn body(node: &mut Node) -> BodyResult {
    let output = node.output::<Counter>("count")?;
    let period_secs = period(node)?;
    let limit = node.param::<u64>("limit")?;
    let mut schedule = Schedule::new(period_secs, node.timestamp());
    let mut next_value: u64 = 1;
    let mut done = false;
    loop {
        let event = if !done && node.is_active() {
            let deadline = node.clock().instant_at(schedule.next_tick);
            node.next_event_until(deadline)?
        } else {
            node.next_event(None)?
        };
        match event {
            Event::Timeout if !done && node.is_active() => {
                node.send(&output, &Counter(next_value))?;
                if limit != 0 && next_value >= limit {
                    done = true;
                    node.report("done")?;
                }
                next_value += 1;
                schedule.advance(node.timestamp());
            }
            Event::Start => {
                tracing::info!("active: counting from {next_value}");
                schedule = Schedule::new(schedule.period_secs, node.timestamp());
            }
            Event::Stop => tracing::info!("inactive: paused before {next_value}"),
            Event::ParamsChanged(names) if names.iter().any(|name| name == "period_secs") => {
                retune(node, &mut schedule);
            }
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

/// Live tuning: takes the new `period_secs` at once, or keeps the current one if it is refused.
fn retune(node: &Node, schedule: &mut Schedule) {
    match period(node) {
        Ok(period_secs) => {
            tracing::info!("period_secs is now {period_secs} s");
            schedule.retune(period_secs, node.timestamp());
        }
        Err(err) => tracing::error!("{err}; keeping period_secs = {} s", schedule.period_secs),
    }
}

/// The `period_secs` parameter, refused unless it is a positive number of seconds.
fn period(node: &Node) -> Result<f64, BodyError> {
    Ok(node.param::<f64>("period_secs")?)
}

/// When the counter publishes, in run time (seconds).
#[derive(Clone, Debug, PartialEq)]
struct Schedule {
    period_secs: f64,
    /// When the previous value was due (or when counting started).
    last_tick: f64,
    next_tick: f64,
}

impl Schedule {
    /// Counting starts at `now`: the first value is due one period later.
    fn new(period_secs: f64, now: f64) -> Self {
        Self {
            period_secs,
            last_tick: now,
            next_tick: now + period_secs,
        }
    }

    /// The value due at `next_tick` was published at `now`. Keeps a steady rhythm, but after
    /// falling a whole period behind it starts afresh rather than publishing a burst.
    fn advance(&mut self, now: f64) {
        self.last_tick = self.next_tick;
        self.next_tick += self.period_secs;
        if self.next_tick <= now {
            self.last_tick = now;
            self.next_tick = now + self.period_secs;
        }
    }

    /// A new period, counted from the previous value (or now, if that moment has passed).
    fn retune(&mut self, period_secs: f64, now: f64) {
        self.period_secs = period_secs;
        self.next_tick = (self.last_tick + period_secs).max(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};

    fn bench(params: &[(&str, &str)]) -> TestBench {
        TestBench::new(&spec(), params).expect("bench")
    }

    #[test]
    fn publishes_up_to_the_limit_then_reports_done_once() {
        let mut bench = bench(&[("limit", "5")]);
        body(bench.node()).expect("body");
        assert_eq!(
            bench.sent::<Counter>("count").expect("sent"),
            (1..=5).map(Counter).collect::<Vec<_>>()
        );
        assert_eq!(bench.reported(), ["done"]);
    }

    #[test]
    fn refuses_a_period_that_is_not_positive() {
        for bad in ["0", "-1"] {
            let mut bench = bench(&[("period_secs", bad), ("limit", "3")]);
            let err = body(bench.node()).expect_err("must refuse");
            let message = err.to_string();
            assert!(
                message.contains("`period_secs` must be greater than 0 s"),
                "{message}"
            );
            assert!(bench.sent::<Counter>("count").expect("sent").is_empty());
        }
    }

    #[test]
    fn refuses_a_negative_limit() {
        let mut bench = bench(&[("limit", "-2")]);
        let err = body(bench.node()).expect_err("must refuse");
        assert!(err.to_string().contains("`limit`"), "{err}");
    }

    #[test]
    fn publishes_nothing_while_stopped_and_resumes_on_start() {
        let mut bench = bench(&[]);
        bench.script([
            Step::Timeouts(2),
            Step::Active(false),
            Step::Timeouts(3),
            Step::Active(true),
            Step::Timeouts(2),
        ]);
        body(bench.node()).expect("body");
        assert_eq!(
            bench.sent::<Counter>("count").expect("sent"),
            (1..=4).map(Counter).collect::<Vec<_>>()
        );
    }

    #[test]
    fn live_period_changes_are_taken_and_bad_ones_refused_while_counting() {
        let mut bench = bench(&[]);
        bench.script([
            Step::Timeouts(1),
            Step::param("period_secs", "-1"),
            Step::Timeouts(1),
            Step::param("period_secs", "0.5"),
            Step::Timeouts(1),
        ]);
        body(bench.node()).expect("a bad live value does not end the module");
        assert_eq!(
            bench.sent::<Counter>("count").expect("sent"),
            [Counter(1), Counter(2), Counter(3)]
        );
        assert_eq!(
            bench.node().param::<f64>("period_secs").expect("param"),
            0.5
        );
    }

    #[test]
    fn a_bad_live_period_is_refused_and_the_old_one_kept() {
        let mut bench = bench(&[]);
        let node = bench.node();
        let now = node.timestamp();
        let mut schedule = Schedule::new(0.1, now);
        bench.set_param("period_secs", "-1");
        retune(bench.node(), &mut schedule);
        assert_eq!(schedule.period_secs, 0.1);
        bench.set_param("period_secs", "2");
        retune(bench.node(), &mut schedule);
        assert_eq!(schedule.period_secs, 2.0);
        assert!(schedule.next_tick >= now + 2.0);
    }

    #[test]
    fn schedule_keeps_its_rhythm_and_skips_rather_than_bursts() {
        let mut schedule = Schedule::new(0.5, 10.0);
        assert_eq!(schedule.next_tick, 10.5);
        schedule.advance(10.52);
        assert_eq!((schedule.last_tick, schedule.next_tick), (10.5, 11.0));
        schedule.advance(13.2);
        assert_eq!((schedule.last_tick, schedule.next_tick), (13.2, 13.7));
    }

    #[test]
    fn retuning_takes_effect_from_the_previous_value() {
        let mut schedule = Schedule::new(10.0, 0.0);
        schedule.retune(1.0, 0.3);
        assert_eq!(schedule.next_tick, 1.0, "no waiting out the old period");
        schedule.retune(0.1, 0.3);
        assert_eq!(schedule.next_tick, 0.3, "already due: at once");
        schedule.retune(5.0, 0.3);
        assert_eq!(schedule.next_tick, 5.0);
    }
}
