//! `mux`: the one source of the robot's `cmd_vel`, chosen among three by priority.
//!
//! The module keeps the latest command of each input and when it arrived (run time). At a fixed
//! rate (`rate_hz` of run time) it publishes the command of the highest-priority *fresh* input
//! (received within `fresh_secs`):
//!
//! 1. `teleop`, when fresh and non-zero: an operator who touches the controls takes over, and the
//!    teleop module's idle zeros do not hold the robot still;
//! 2. `observe`, when fresh (the observer turning on the spot, or its zero once done);
//! 3. `auto`, when fresh (navigation: the avoider's safe command);
//! 4. otherwise zero: with no fresh command the robot stands still.
//!
//! It logs which source is in control each time that changes. Non-finite components of a
//! command are read as 0. It is the robot's last safety link, so the mission controller never
//! stops it.

use armor_module_api::types::Twist;
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;
use crate::nav::sanitized;

pub const TYPE: &str = "mux";

/// Fastest publishing rate accepted (run time).
const MAX_RATE_HZ: f64 = 1000.0;

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Chooses the robot's velocity command by priority: teleop when fresh and non-zero, else \
         observe when fresh, else auto when fresh, else zero; publishes it at a fixed rate and \
         logs which source is in control when that changes.",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .input::<Twist>(
        "auto",
        "the navigation command (from the avoider): lowest priority",
    )
    .input::<Twist>("observe", "the observer's command: before auto when fresh")
    .input::<Twist>(
        "teleop",
        "the operator's command: first when fresh and non-zero (a zero from an idle operator \
         interface does not take over)",
    )
    .output::<Twist>(
        "cmd_vel",
        "the command of the source in control (zero when none is fresh), rate_hz times per \
         second of run time; never NaN",
    )
    .param(
        ParamSpec::new(
            "fresh_secs",
            ParamType::Float,
            "a command received longer ago than this (run time) no longer counts (greater than \
             0; tunable live)",
        )
        .above(0.0)
        .unit("s")
        .default("0.3"),
    )
    .param(
        ParamSpec::new(
            "rate_hz",
            ParamType::Float,
            "commands published per second of run time (greater than 0, at most 1000; tunable \
             live)",
        )
        .above(0.0)
        .max(MAX_RATE_HZ)
        .unit("Hz")
        .default("20"),
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let inputs = [
        node.input::<Twist>("teleop")?,
        node.input::<Twist>("observe")?,
        node.input::<Twist>("auto")?,
    ];
    let output = node.output::<Twist>("cmd_vel")?;
    let mut settings = Settings::read(node)?;
    let mut mux = Mux::default();
    let mut next_tick = node.timestamp();
    loop {
        let deadline = node.clock().instant_at(next_tick);
        match node.next_event_until(deadline)? {
            Event::Input(port) => {
                let Some(index) = inputs.iter().position(|input| input.id() == port) else {
                    continue;
                };
                if let Some(sample) = node.take(&inputs[index])? {
                    mux.receive(Source::ALL[index], sample.value, node.timestamp());
                }
            }
            Event::Timeout => {
                let now = node.timestamp();
                next_tick = next_tick_after(next_tick, now, settings.period_secs());
                let (source, twist) = mux.select(now, settings.fresh_secs);
                if mux.in_control != Some(source) {
                    tracing::info!("in control: {}", source.describe());
                    mux.in_control = Some(source);
                }
                node.send(&output, &twist)?;
            }
            Event::ParamsChanged(_) => match Settings::read(node) {
                Ok(new) => {
                    tracing::info!(
                        "fresh_secs = {} s, rate_hz = {} Hz",
                        new.fresh_secs,
                        new.rate_hz
                    );
                    settings = new;
                }
                Err(err) => tracing::error!("{err}; keeping the previous settings"),
            },
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

/// When to publish next: one period on, or a period from now after falling a period behind
/// (no burst to catch up).
fn next_tick_after(tick: f64, now: f64, period_secs: f64) -> f64 {
    let next = tick + period_secs;
    if next <= now { now + period_secs } else { next }
}

/// The mux's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub fresh_secs: f64,
    pub rate_hz: f64,
}

impl Settings {
    fn read(node: &Node) -> Result<Self, BodyError> {
        Ok(Self {
            fresh_secs: node.param::<f64>("fresh_secs")?,
            rate_hz: node.param::<f64>("rate_hz")?,
        })
    }

    fn period_secs(&self) -> f64 {
        1.0 / self.rate_hz
    }
}

/// Who is in control of the robot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    Teleop,
    Observe,
    Auto,
    /// No fresh command: zero.
    None,
}

impl Source {
    /// The inputs, highest priority first (the order of [`Mux::latest`]).
    const ALL: [Source; 3] = [Source::Teleop, Source::Observe, Source::Auto];

    fn describe(self) -> &'static str {
        match self {
            Source::Teleop => "teleop",
            Source::Observe => "observe",
            Source::Auto => "auto",
            Source::None => "none (no fresh command: zero)",
        }
    }
}

/// The latest command of each input, when it arrived, and who was last in control.
#[derive(Clone, Debug, Default)]
struct Mux {
    /// Indexed like [`Source::ALL`]: the command and its arrival in run time.
    latest: [Option<(Twist, f64)>; 3],
    in_control: Option<Source>,
}

impl Mux {
    fn receive(&mut self, source: Source, twist: Twist, now: f64) {
        let clean = sanitized(twist);
        if clean != twist {
            tracing::warn!(
                "{}: non-finite command ({}, {}) read as ({}, {})",
                source.describe(),
                twist.linear_mps,
                twist.angular_radps,
                clean.linear_mps,
                clean.angular_radps
            );
        }
        if let Some(index) = Source::ALL.iter().position(|known| *known == source) {
            self.latest[index] = Some((clean, now));
        }
    }

    /// The source in control at `now` and its command.
    fn select(&self, now: f64, fresh_secs: f64) -> (Source, Twist) {
        for (source, latest) in Source::ALL.into_iter().zip(&self.latest) {
            let Some((twist, at)) = *latest else {
                continue;
            };
            let fresh = now - at <= fresh_secs;
            let counts = source != Source::Teleop || twist != Twist::default();
            if fresh && counts {
                return (source, twist);
            }
        }
        (Source::None, Twist::default())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};

    fn twist(linear_mps: f64, angular_radps: f64) -> Twist {
        Twist {
            linear_mps,
            angular_radps,
        }
    }

    fn push(input: &str, value: Twist) -> Step {
        Step::push(input, &value).expect("step")
    }

    fn run(params: &[(&str, &str)], steps: impl IntoIterator<Item = Step>) -> Vec<Twist> {
        let mut bench = TestBench::new(&spec(), params).expect("bench");
        bench.script(steps);
        body(bench.node()).expect("body");
        assert!(bench.reported().is_empty());
        bench.sent::<Twist>("cmd_vel").expect("sent")
    }

    const AUTO: Twist = Twist {
        linear_mps: 0.5,
        angular_radps: 0.1,
    };
    const OBSERVE: Twist = Twist {
        linear_mps: 0.0,
        angular_radps: 0.6,
    };
    const TELEOP: Twist = Twist {
        linear_mps: -0.2,
        angular_radps: 0.0,
    };

    #[test]
    fn publishes_zero_at_its_rate_without_any_command() {
        let sent = run(&[], [Step::Timeouts(3)]);
        assert_eq!(sent, [Twist::default(); 3]);
    }

    #[test]
    fn follows_the_highest_priority_fresh_input() {
        let sent = run(
            &[],
            [
                push("auto", AUTO),
                Step::Timeouts(1),
                push("observe", OBSERVE),
                Step::Timeouts(1),
                push("teleop", TELEOP),
                Step::Timeouts(1),
            ],
        );
        assert_eq!(sent, [AUTO, OBSERVE, TELEOP]);
    }

    #[test]
    fn a_zero_from_teleop_does_not_take_over_but_a_zero_from_the_observer_does() {
        let sent = run(
            &[],
            [
                push("auto", AUTO),
                push("teleop", Twist::default()),
                Step::Timeouts(1),
                push("observe", Twist::default()),
                Step::Timeouts(1),
            ],
        );
        assert_eq!(sent, [AUTO, Twist::default()]);
    }

    #[test]
    fn stale_inputs_give_way_and_nothing_fresh_means_zero() {
        let sent = run(
            &[("fresh_secs", "0.3")],
            [
                push("auto", AUTO),
                push("observe", OBSERVE),
                push("teleop", TELEOP),
                Step::Timeouts(1),
                Step::Advance(0.2),
                push("auto", AUTO),
                Step::Advance(0.2),
                // Teleop and observe are 0.4 s old, auto 0.2 s.
                Step::Timeouts(1),
                Step::Advance(0.2),
                Step::Timeouts(1),
            ],
        );
        assert_eq!(sent, [TELEOP, AUTO, Twist::default()]);
    }

    #[test]
    fn the_latest_value_of_an_input_counts_and_non_finite_values_read_as_zero() {
        let sent = run(
            &[],
            [
                push("auto", AUTO),
                push("auto", twist(0.1, 0.0)),
                Step::Timeouts(1),
                push("auto", twist(f64::NAN, 0.2)),
                Step::Timeouts(1),
                push("teleop", twist(f64::INFINITY, f64::NAN)),
                Step::Timeouts(1),
            ],
        );
        // A teleop command that reads as zero does not take over.
        assert_eq!(sent, [twist(0.1, 0.0), twist(0.0, 0.2), twist(0.0, 0.2)]);
    }

    #[test]
    fn refuses_bad_settings() {
        for (name, value, expected) in [
            ("fresh_secs", "0", "`fresh_secs` must be greater than 0 s"),
            ("fresh_secs", "-1", "`fresh_secs` must be greater than 0 s"),
            ("rate_hz", "0", "`rate_hz` must be greater than 0 Hz"),
            ("rate_hz", "5000", "and at most 1000 Hz"),
        ] {
            let mut bench = TestBench::new(&spec(), &[(name, value)]).expect("bench");
            let err = body(bench.node()).expect_err("must refuse");
            assert!(err.to_string().contains(expected), "{err}");
            assert!(bench.sent::<Twist>("cmd_vel").expect("sent").is_empty());
        }
    }

    #[test]
    fn takes_live_settings_and_keeps_the_old_ones_when_refused() {
        let sent = run(
            &[("fresh_secs", "0.3")],
            [
                push("observe", OBSERVE),
                Step::param("fresh_secs", "-2"),
                Step::Advance(0.4),
                Step::Timeouts(1),
                push("observe", OBSERVE),
                Step::param("fresh_secs", "1"),
                Step::Advance(0.6),
                Step::Timeouts(1),
            ],
        );
        assert_eq!(sent, [Twist::default(), OBSERVE]);
    }

    #[test]
    fn is_not_stopped_by_the_mission() {
        assert!(!spec().description().controllable);
    }

    #[test]
    fn tracks_who_is_in_control() {
        let mut mux = Mux::default();
        assert_eq!(mux.select(0.0, 0.3), (Source::None, Twist::default()));
        mux.receive(Source::Auto, AUTO, 1.0);
        mux.receive(Source::Teleop, TELEOP, 1.0);
        assert_eq!(mux.select(1.1, 0.3), (Source::Teleop, TELEOP));
        assert_eq!(mux.select(1.35, 0.3), (Source::None, Twist::default()));
        mux.receive(Source::Observe, OBSERVE, 1.3);
        assert_eq!(mux.select(1.35, 0.3), (Source::Observe, OBSERVE));
        assert_eq!(mux.select(1.55, 0.3), (Source::Observe, OBSERVE));
        assert_eq!(mux.select(1.65, 0.3), (Source::None, Twist::default()));
    }

    #[test]
    fn keeps_its_rhythm_without_bursts() {
        assert_eq!(next_tick_after(1.0, 1.01, 0.05), 1.05);
        assert_eq!(next_tick_after(1.0, 1.3, 0.05), 1.35);
    }
}
