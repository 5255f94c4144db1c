//! `arbiter`: chooses among competing behaviours, as JDE's sibling motor schemas compete for
//! the actuators.
//!
//! Each of up to [`CANDIDATES`] inputs (`candidate_1` …) carries one behaviour's proposed
//! command; its priority is the parameter `priority_N` of the system file. A behaviour proposes
//! only while its preconditions hold (`Node::set_applicable`), so a candidate counts while its
//! latest proposal is *fresh* (received within `fresh_secs` of run time). The winner is the
//! fresh candidate of highest priority (the lower number on a tie), with hysteresis: a winner
//! that is still fresh keeps control for at least `hold_secs` before another takes over, so
//! that two behaviours whose preconditions flicker do not chatter.
//!
//! The winner's command is published as soon as it arrives (no tick in between: a behaviour
//! that becomes applicable reaches the robot at once), and zero `rate_hz` times a second while
//! no candidate is fresh. Each change of winner is logged, reported as `winner_changed`, and told
//! to the supervisor (`Node::set_winner`), which shows the winner's module as `winner` and the
//! other applicable ones as `ready`. Put the avoider's safety layer after it: no winner can
//! then override the safety stop. Not controllable, like `mux`: it is the robot's only source.

use armor_module_api::types::Twist;
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;
use crate::nav::sanitized;

pub const TYPE: &str = "arbiter";

/// How many candidate inputs the arbiter has (unlinked ones never win).
pub const CANDIDATES: usize = 6;
/// Fastest rate of the zero command published while no candidate is fresh (run time).
const MAX_RATE_HZ: f64 = 1000.0;

fn input_name(index: usize) -> String {
    format!("candidate_{}", index + 1)
}

fn priority_name(index: usize) -> String {
    format!("priority_{}", index + 1)
}

pub fn spec() -> ModuleSpec {
    let mut spec = ModuleSpec::new(
        TYPE,
        "Chooses among competing behaviours: the fresh candidate of highest priority wins (each \
         candidate's priority set in the system file), with hysteresis (a winner keeps control \
         for hold_secs); publishes the winner's command as it arrives, zero when no candidate is \
         fresh, and reports winner_changed.",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable();
    for index in 0..CANDIDATES {
        spec = spec
            .input::<Twist>(
                &input_name(index),
                "a behaviour's proposed command, sent only while it applies",
            )
            .param(
                ParamSpec::new(
                    &priority_name(index),
                    ParamType::Int,
                    &format!(
                        "the priority of candidate_{}: the highest fresh one wins (tunable live)",
                        index + 1
                    ),
                )
                .min(0.0)
                .max(1000.0)
                .default(&(CANDIDATES - index).to_string()),
            );
    }
    spec.output::<Twist>(
        "cmd_vel",
        "the winner's command as it arrives, or zero rate_hz times per second of run time when \
         no candidate is fresh; never NaN",
    )
    .event("winner_changed", "another candidate (or none) took control")
    .param(
        ParamSpec::new(
            "fresh_secs",
            ParamType::Float,
            "a proposal received longer ago than this (run time) no longer counts (greater than \
             0; tunable live)",
        )
        .above(0.0)
        .unit("s")
        .default("0.3"),
    )
    .param(
        ParamSpec::new(
            "hold_secs",
            ParamType::Float,
            "hysteresis: a fresh winner keeps control at least this long (run time; 0: none; \
             tunable live)",
        )
        .min(0.0)
        .unit("s")
        .default("0.3"),
    )
    .param(
        ParamSpec::new(
            "rate_hz",
            ParamType::Float,
            "zero commands per second of run time while no candidate is fresh (greater than 0, \
             at most 1000; tunable live)",
        )
        .above(0.0)
        .max(MAX_RATE_HZ)
        .unit("Hz")
        .default("20"),
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let inputs = (0..CANDIDATES)
        .map(|index| node.input::<Twist>(&input_name(index)))
        .collect::<Result<Vec<_>, _>>()?;
    let output = node.output::<Twist>("cmd_vel")?;
    let mut settings = Settings::read(node)?;
    let mut arbiter = Arbiter::default();
    let mut next_tick = node.timestamp();
    loop {
        let deadline = node.clock().instant_at(next_tick);
        let publish = match node.next_event_until(deadline)? {
            Event::Input(port) => {
                let Some(index) = inputs.iter().position(|input| input.id() == port) else {
                    continue;
                };
                let Some(sample) = node.take(&inputs[index])? else {
                    continue;
                };
                let now = node.timestamp();
                arbiter.receive(index, sample.value, now);
                let winner = arbiter.select(now, &settings);
                changed(node, winner, arbiter.winner_changed)?;
                // Only the winner's own proposals go out as they come.
                winner == Some(index)
            }
            Event::Timeout => {
                let now = node.timestamp();
                next_tick = next_tick_after(next_tick, now, 1.0 / settings.rate_hz);
                let winner = arbiter.select(now, &settings);
                changed(node, winner, arbiter.winner_changed)?;
                winner.is_none() || arbiter.winner_changed
            }
            Event::ParamsChanged(_) => {
                match Settings::read(node) {
                    Ok(new) => settings = new,
                    Err(err) => tracing::error!("{err}; keeping the previous settings"),
                }
                false
            }
            Event::Shutdown => return Ok(()),
            _ => false,
        };
        if publish {
            node.send(&output, &arbiter.command())?;
        }
    }
}

/// Logs, reports and tells the supervisor of a new winner.
fn changed(node: &mut Node, winner: Option<usize>, is_new: bool) -> Result<(), BodyError> {
    if !is_new {
        return Ok(());
    }
    let name = winner.map(input_name);
    tracing::info!("in control: {}", name.as_deref().unwrap_or("none (zero)"));
    node.set_winner(name.as_deref());
    node.report("winner_changed")?;
    Ok(())
}

/// When to publish next: one period on, or a period from now after falling a period behind.
fn next_tick_after(tick: f64, now: f64, period_secs: f64) -> f64 {
    let next = tick + period_secs;
    if next <= now { now + period_secs } else { next }
}

/// The arbiter's parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub priorities: [i64; CANDIDATES],
    pub fresh_secs: f64,
    pub hold_secs: f64,
    pub rate_hz: f64,
}

impl Settings {
    fn read(node: &Node) -> Result<Self, BodyError> {
        let mut priorities = [0; CANDIDATES];
        for (index, priority) in priorities.iter_mut().enumerate() {
            *priority = node.param::<i64>(&priority_name(index))?;
        }
        Ok(Self {
            priorities,
            fresh_secs: node.param::<f64>("fresh_secs")?,
            hold_secs: node.param::<f64>("hold_secs")?,
            rate_hz: node.param::<f64>("rate_hz")?,
        })
    }
}

/// The latest proposal of each candidate, and who holds control since when.
#[derive(Clone, Debug, Default)]
pub struct Arbiter {
    /// Each candidate's latest command and its arrival (run time).
    latest: [Option<(Twist, f64)>; CANDIDATES],
    /// The winner and since when it holds control.
    winner: Option<(usize, f64)>,
    /// Whether the last [`Arbiter::select`] changed the winner.
    pub winner_changed: bool,
}

impl Arbiter {
    pub fn receive(&mut self, index: usize, twist: Twist, now: f64) {
        if let Some(latest) = self.latest.get_mut(index) {
            *latest = Some((sanitized(twist), now));
        }
    }

    fn is_fresh(&self, index: usize, now: f64, settings: &Settings) -> bool {
        self.latest[index].is_some_and(|(_, at)| now - at <= settings.fresh_secs)
    }

    /// The winner at `now`: the fresh candidate of highest priority, unless the current winner
    /// is fresh and has held control for less than `hold_secs`.
    pub fn select(&mut self, now: f64, settings: &Settings) -> Option<usize> {
        let best = (0..CANDIDATES)
            .filter(|&index| self.is_fresh(index, now, settings))
            .max_by_key(|&index| (settings.priorities[index], std::cmp::Reverse(index)));
        let keep = self.winner.filter(|&(index, since)| {
            self.is_fresh(index, now, settings) && now - since < settings.hold_secs
        });
        let chosen = match keep {
            Some((index, _)) => Some(index),
            None => best,
        };
        self.winner_changed = chosen != self.winner.map(|(index, _)| index);
        if self.winner_changed {
            self.winner = chosen.map(|index| (index, now));
        }
        chosen
    }

    /// The winner's latest command, or zero.
    pub fn command(&self) -> Twist {
        self.winner
            .and_then(|(index, _)| self.latest[index])
            .map_or_else(Twist::default, |(twist, _)| twist)
    }
}

#[cfg(test)]
mod tests;
