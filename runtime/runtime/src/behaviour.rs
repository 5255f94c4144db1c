//! Behaviour states, as JDE's schemas have them: what each behaviour module said of its
//! preconditions (`applicable`), what each arbiter said of its winner, and the module's activity
//! make the state a user sees — `slept`, `checking`, `ready`, `winner` — and a time line of its
//! changes. Pure: the config server feeds it messages and activity, with the time they came.

use std::collections::{BTreeMap, VecDeque};
use std::time::Instant;

use armor_protocol::BehaviourState;

/// The most state changes kept for the time line (the oldest go first).
pub const MAX_CHANGES: usize = 512;

/// One change of a module's behaviour state, at `at`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Change {
    pub at: Instant,
    pub module: String,
    /// `None`: the module is gone (disconnected).
    pub state: Option<BehaviourState>,
}

/// What the modules said, and the states and changes that follow.
#[derive(Clone, Debug, Default)]
pub struct Behaviours {
    applicable: BTreeMap<String, bool>,
    /// Arbiter → the module whose command is in control.
    winners: BTreeMap<String, String>,
    states: BTreeMap<String, BehaviourState>,
    changes: VecDeque<Change>,
}

impl Behaviours {
    pub fn set_applicable(&mut self, module: &str, applicable: bool) {
        self.applicable.insert(module.to_owned(), applicable);
    }

    /// An arbiter's winner, as the module feeding the winning input (`None`: no winner).
    pub fn set_winner(&mut self, arbiter: &str, winner: Option<String>) {
        match winner {
            Some(winner) => self.winners.insert(arbiter.to_owned(), winner),
            None => self.winners.remove(arbiter),
        };
    }

    /// A module went away: it says nothing any more, and wins nothing.
    pub fn forget(&mut self, module: &str) {
        self.applicable.remove(module);
        self.winners.remove(module);
    }

    /// Each arbiter's winner (the module in control).
    pub fn winners(&self) -> &BTreeMap<String, String> {
        &self.winners
    }

    /// The current states.
    pub fn states(&self) -> &BTreeMap<String, BehaviourState> {
        &self.states
    }

    /// The time line, oldest first.
    pub fn changes(&self) -> impl Iterator<Item = &Change> {
        self.changes.iter()
    }

    /// Recomputes every state from what was said and `active` (module → configured active), and
    /// logs those that changed at `at`.
    pub fn update(&mut self, active: &BTreeMap<String, bool>, at: Instant) {
        let states = states(&self.applicable, &self.winners, active);
        for (module, state) in &states {
            if self.states.get(module) != Some(state) {
                self.log(at, module, Some(*state));
            }
        }
        let gone: Vec<String> = self
            .states
            .keys()
            .filter(|module| !states.contains_key(*module))
            .cloned()
            .collect();
        for module in gone {
            self.log(at, &module, None);
        }
        self.states = states;
    }

    fn log(&mut self, at: Instant, module: &str, state: Option<BehaviourState>) {
        if self.changes.len() == MAX_CHANGES {
            self.changes.pop_front();
        }
        self.changes.push_back(Change {
            at,
            module: module.to_owned(),
            state,
        });
    }
}

/// The state of every module that said whether it applies.
fn states(
    applicable: &BTreeMap<String, bool>,
    winners: &BTreeMap<String, String>,
    active: &BTreeMap<String, bool>,
) -> BTreeMap<String, BehaviourState> {
    applicable
        .iter()
        .map(|(module, &applicable)| {
            let state = if !active.get(module).copied().unwrap_or(true) {
                BehaviourState::Slept
            } else if !applicable {
                BehaviourState::Checking
            } else if winners.values().any(|winner| winner == module) {
                BehaviourState::Winner
            } else {
                BehaviourState::Ready
            };
            (module.clone(), state)
        })
        .collect()
}

/// The module that publishes a data name (`module.output`).
pub fn publisher(data_name: &str) -> &str {
    data_name
        .split_once('.')
        .map_or(data_name, |(module, _)| module)
}

#[cfg(test)]
mod tests {
    use super::*;
    use BehaviourState::*;

    fn active(pairs: &[(&str, bool)]) -> BTreeMap<String, bool> {
        pairs.iter().map(|(m, a)| ((*m).to_owned(), *a)).collect()
    }

    #[test]
    fn states_follow_activity_applicability_and_the_winner() {
        let t0 = Instant::now();
        let mut behaviours = Behaviours::default();
        let all_active = active(&[("goal", true), ("avoid", true), ("stop", true)]);
        behaviours.set_applicable("goal", true);
        behaviours.set_applicable("avoid", false);
        behaviours.set_applicable("stop", true);
        behaviours.set_winner("arbiter", Some("goal".into()));
        behaviours.update(&all_active, t0);
        assert_eq!(
            behaviours.states().values().copied().collect::<Vec<_>>(),
            [Checking, Winner, Ready],
            "avoid, goal, stop"
        );
        behaviours.set_applicable("avoid", true);
        behaviours.set_winner("arbiter", Some("avoid".into()));
        behaviours.update(&all_active, t0);
        behaviours.update(&active(&[("stop", false)]), t0);
        let changes: Vec<String> = behaviours
            .changes()
            .map(|change| format!("{} {:?}", change.module, change.state))
            .collect();
        assert_eq!(
            changes[3..],
            ["avoid Some(Winner)", "goal Some(Ready)", "stop Some(Slept)"]
        );
        behaviours.forget("stop");
        behaviours.update(&all_active, t0);
        assert_eq!(
            behaviours.changes().last().map(|c| c.state),
            Some(None),
            "a module gone is logged as gone"
        );
    }

    #[test]
    fn the_time_line_is_bounded() {
        let mut behaviours = Behaviours::default();
        let now = Instant::now();
        for i in 0..MAX_CHANGES + 10 {
            behaviours.set_applicable("a", i % 2 == 0);
            behaviours.update(&BTreeMap::new(), now);
        }
        assert_eq!(behaviours.changes().count(), MAX_CHANGES);
        assert_eq!(publisher("follower.cmd_desired"), "follower");
    }
}
