//! Plays a mission net in time, purely: the caller gives the time (run-time seconds, any clock
//! that does not go backwards) and the events, and starts and stops what [`Firing`]s say.
//!
//! Semantics:
//! - a transition is *enabled* when each input place holds at least the arc's weight; its
//!   [`Engine::enabled_since`] is the time it became so, forgotten when it becomes disabled;
//! - an enabled transition *can fire* when every given part of its condition holds: its delay has
//!   elapsed since it became enabled, its date is reached, its event is latched; with no
//!   condition it can fire at once;
//! - an event counts only for the transitions enabled when it is reported; it stays latched for
//!   each of them until that transition fires or becomes disabled;
//! - [`Engine::step`] fires, one at a time and until none can, the transition that can fire with
//!   the highest priority, the first declared among equals;
//! - a firing is atomic: a transition that stays enabled through another's firing keeps its time
//!   and its latched event; the transition that fired starts afresh (its tokens were consumed).

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::sync::Arc as Shared;

use super::{Condition, Marking, MissionNet};
use crate::fields::listing;

/// At most this many firings per [`Engine::step`]: a cycle of transitions without condition
/// would otherwise fire forever. When it is reached, [`Engine::next_deadline`] is the current
/// time, so the caller steps again without waiting.
pub const MAX_FIRINGS_PER_STEP: usize = 10_000;

/// One transition fired.
#[derive(Clone, Debug, PartialEq)]
pub struct Firing {
    pub transition: String,
    pub at_secs: f64,
    pub marking_after: MarkedPlaces,
    /// Modules active after the firing that were not before, sorted.
    pub started: Vec<String>,
    /// Modules active before the firing that are not after, sorted.
    pub stopped: Vec<String>,
}

/// The places that hold tokens, in declaration order, with their tokens: what a [`Firing`]
/// left. Cheap to take at every firing (the names are shared with the engine);
/// [`MarkedPlaces::to_marking`] gives the map.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MarkedPlaces(Vec<(Shared<str>, u32)>);

impl MarkedPlaces {
    /// (place, tokens), in the net's declaration order.
    pub fn iter(&self) -> impl Iterator<Item = (&str, u32)> {
        self.0.iter().map(|(place, tokens)| (&**place, *tokens))
    }

    pub fn to_marking(&self) -> Marking {
        self.iter()
            .map(|(place, tokens)| (place.to_owned(), tokens))
            .collect()
    }
}

impl From<&MarkedPlaces> for Marking {
    fn from(marked: &MarkedPlaces) -> Marking {
        marked.to_marking()
    }
}

impl PartialEq<Marking> for MarkedPlaces {
    fn eq(&self, marking: &Marking) -> bool {
        self.0.len() == marking.len()
            && self
                .iter()
                .all(|(place, tokens)| marking.get(place) == Some(&tokens))
    }
}

#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum EngineError {
    #[error("no transition `{name}` in this mission (transitions: {known})")]
    UnknownTransition { name: String, known: String },
    #[error("transition `{name}` cannot fire: {why}")]
    NotEnabled { name: String, why: String },
    #[error("no place `{name}` in this mission (places: {known})")]
    UnknownPlace { name: String, known: String },
}

#[derive(Debug)]
struct EnginePlace {
    name: Shared<str>,
    tokens: u32,
    /// Indices in [`CompiledNet::modules`], each once.
    modules: Vec<usize>,
    /// (module, parameter, value)
    params: Vec<(String, String, String)>,
    is_final: bool,
}

#[derive(Debug)]
struct EngineTransition {
    name: String,
    condition: Condition,
    /// (place index, weight); `None` for an arc to a place the net does not have, which never
    /// holds a token.
    inputs: Vec<(Option<usize>, u32)>,
    outputs: Vec<(Option<usize>, u32)>,
    /// The transitions whose enabling its firing may change (those with an input place among
    /// its places), itself included.
    affected: Vec<usize>,
    /// Its position in [`CompiledNet::order`].
    rank: usize,
}

/// A mission net as the engine plays it: names resolved to indices once, shared by every
/// [`Engine`] started from it (as a compiled program is by its runs).
#[derive(Debug)]
pub struct CompiledNet {
    places: Vec<EnginePlace>,
    transitions: Vec<EngineTransition>,
    /// Transition indices by decreasing priority, then declaration order.
    order: Vec<usize>,
    /// The modules the places name, sorted: indices order like names.
    modules: Vec<String>,
    place_index: HashMap<Shared<str>, usize>,
    transition_index: HashMap<String, usize>,
}

impl CompiledNet {
    pub fn new(net: &MissionNet) -> CompiledNet {
        let mut place_index = HashMap::with_capacity(net.places.len());
        let modules: Vec<String> = net
            .places
            .iter()
            .flat_map(|place| &place.modules)
            .collect::<BTreeSet<_>>()
            .into_iter()
            .cloned()
            .collect();
        let module_index = |name: &String| modules.binary_search(name).ok();
        let places: Vec<EnginePlace> = net
            .places
            .iter()
            .enumerate()
            .map(|(p, place)| {
                let name: Shared<str> = Shared::from(place.name.as_str());
                // The first place of a name wins, as in the other lookups.
                place_index.entry(name.clone()).or_insert(p);
                let mut own: Vec<usize> = place.modules.iter().filter_map(module_index).collect();
                own.sort_unstable();
                own.dedup();
                EnginePlace {
                    name,
                    tokens: place.tokens,
                    modules: own,
                    params: place
                        .params
                        .iter()
                        .map(|param| {
                            (
                                param.module.clone(),
                                param.name.clone(),
                                param.value.clone(),
                            )
                        })
                        .collect(),
                    is_final: place.is_final,
                }
            })
            .collect();
        let arcs = |arcs: &[super::Arc]| -> Vec<(Option<usize>, u32)> {
            arcs.iter()
                .map(|arc| (place_index.get(arc.place.as_str()).copied(), arc.weight))
                .collect()
        };
        let mut transitions: Vec<EngineTransition> = net
            .transitions
            .iter()
            .map(|transition| EngineTransition {
                name: transition.name.clone(),
                condition: transition.condition.clone(),
                inputs: arcs(&transition.inputs),
                outputs: arcs(&transition.outputs),
                affected: Vec::new(),
                rank: 0,
            })
            .collect();
        let mut consumers: Vec<Vec<usize>> = vec![Vec::new(); places.len()];
        for (t, transition) in transitions.iter().enumerate() {
            for &(place, _) in &transition.inputs {
                if let Some(p) = place {
                    consumers[p].push(t);
                }
            }
        }
        for (t, transition) in transitions.iter_mut().enumerate() {
            let mut affected = vec![t];
            for &(place, _) in transition.inputs.iter().chain(&transition.outputs) {
                if let Some(p) = place {
                    affected.extend(&consumers[p]);
                }
            }
            affected.sort_unstable();
            affected.dedup();
            transition.affected = affected;
        }
        let mut order: Vec<usize> = (0..transitions.len()).collect();
        order.sort_by_key(|&t| std::cmp::Reverse(net.transitions[t].priority));
        for (rank, &t) in order.iter().enumerate() {
            transitions[t].rank = rank;
        }
        let mut transition_index = HashMap::with_capacity(transitions.len());
        for (t, transition) in transitions.iter().enumerate() {
            transition_index.entry(transition.name.clone()).or_insert(t);
        }
        CompiledNet {
            places,
            transitions,
            order,
            modules,
            place_index,
            transition_index,
        }
    }
}

/// A set of small indices, one bit each, walked in increasing order.
#[derive(Clone, Debug)]
struct Bits(Vec<u64>);

impl Bits {
    fn new(len: usize) -> Bits {
        Bits(vec![0; len.div_ceil(64)])
    }

    fn set(&mut self, i: usize, on: bool) {
        let (word, bit) = (i / 64, 1u64 << (i % 64));
        if on {
            self.0[word] |= bit;
        } else {
            self.0[word] &= !bit;
        }
    }

    fn len(&self) -> usize {
        self.0.iter().map(|word| word.count_ones() as usize).sum()
    }

    fn iter(&self) -> impl Iterator<Item = usize> + '_ {
        self.0.iter().enumerate().flat_map(|(w, &word)| {
            let mut rest = word;
            std::iter::from_fn(move || {
                (rest != 0).then(|| {
                    let bit = rest.trailing_zeros() as usize;
                    rest &= rest - 1;
                    w * 64 + bit
                })
            })
        })
    }
}

/// The state of a mission being played.
#[derive(Clone, Debug)]
pub struct Engine {
    net: Shared<CompiledNet>,
    marking: Vec<u32>,
    /// The places that hold tokens.
    marked: Bits,
    enabled_since: Vec<Option<f64>>,
    /// The enabled transitions, by rank (their position in [`CompiledNet::order`]).
    enabled: Bits,
    latched: Vec<bool>,
    /// For each module, how many marked places name it: it is active when above 0.
    module_places: Vec<u32>,
    /// The latest time given.
    now: f64,
    /// The Unix time of run-time 0.
    date_origin: f64,
}

impl Engine {
    /// The engine in the initial marking at run-time 0: the transitions enabled there are
    /// enabled since 0. Dates are compared with `now_secs` as if run-time 0 were the Unix epoch;
    /// see [`Engine::with_date_origin`].
    pub fn new(net: &MissionNet) -> Engine {
        Engine::start_at(net, 0.0)
    }

    /// The engine in the initial marking at run-time `now_secs`.
    pub fn start_at(net: &MissionNet, now_secs: f64) -> Engine {
        Engine::start_compiled(&Shared::new(CompiledNet::new(net)), now_secs)
    }

    /// An engine on a net compiled beforehand, in its initial marking at run-time `now_secs`.
    pub fn start_compiled(net: &Shared<CompiledNet>, now_secs: f64) -> Engine {
        let marking: Vec<u32> = net.places.iter().map(|place| place.tokens).collect();
        let mut marked = Bits::new(marking.len());
        let mut module_places = vec![0; net.modules.len()];
        for (p, place) in net.places.iter().enumerate() {
            if marking[p] > 0 {
                marked.set(p, true);
                for &m in &place.modules {
                    module_places[m] += 1;
                }
            }
        }
        let transitions = net.transitions.len();
        let now = if now_secs.is_finite() { now_secs } else { 0.0 };
        let mut engine = Engine {
            net: net.clone(),
            marking,
            marked,
            enabled_since: vec![None; transitions],
            enabled: Bits::new(transitions),
            latched: vec![false; transitions],
            module_places,
            now,
            date_origin: 0.0,
        };
        for t in 0..transitions {
            engine.refresh(t, false, now);
        }
        engine
    }

    /// An engine on `net` in `marking` (place → tokens; the net's own initial tokens are not
    /// used) at run-time `now_secs`, taking over what `before` (an engine on an earlier version
    /// of the mission) knew of the transitions both have: a transition of the same name enabled
    /// in both keeps the time it became enabled, so a delay goes on where it was, and, with
    /// `keep_events`, its latched event. Its date origin is `before`'s. This is how a running
    /// mission moves to an updated net between two firings. A place `net` does not have is an
    /// error naming it.
    pub fn resume(
        net: &MissionNet,
        marking: &Marking,
        before: &Engine,
        keep_events: bool,
        now_secs: f64,
    ) -> Result<Engine, EngineError> {
        let mut compiled = CompiledNet::new(net);
        for place in &mut compiled.places {
            place.tokens = 0;
        }
        for (name, &tokens) in marking {
            let Some(&p) = compiled.place_index.get(name.as_str()) else {
                return Err(EngineError::UnknownPlace {
                    name: name.clone(),
                    known: listing(compiled.places.iter().map(|place| &*place.name)),
                });
            };
            compiled.places[p].tokens = tokens;
        }
        let now = before
            .now
            .max(if now_secs.is_finite() { now_secs } else { 0.0 });
        let mut engine = Engine::start_compiled(&Shared::new(compiled), now)
            .with_date_origin(before.date_origin);
        for t in 0..engine.net.transitions.len() {
            if engine.enabled_since[t].is_none() {
                continue;
            }
            let name = &engine.net.transitions[t].name;
            if let Some(old) = before.transition_index(name)
                && let Some(since) = before.enabled_since[old]
            {
                engine.enabled_since[t] = Some(since);
                engine.latched[t] = keep_events && before.latched[old];
            }
        }
        Ok(engine)
    }

    /// Sets the Unix time (seconds since 1970-01-01T00:00:00Z) of run-time 0, against which the
    /// dates of the net are compared: a date `at` is reached when `now_secs >= at - origin`.
    pub fn with_date_origin(mut self, unix_secs: f64) -> Engine {
        self.date_origin = if unix_secs.is_finite() {
            unix_secs
        } else {
            0.0
        };
        self
    }

    /// The Unix time of run-time 0 (see [`Engine::with_date_origin`]).
    pub fn date_origin(&self) -> f64 {
        self.date_origin
    }

    /// The latest time given to the engine.
    pub fn now(&self) -> f64 {
        self.now
    }

    /// The places that hold tokens, with their tokens.
    pub fn marking(&self) -> Marking {
        let mut marking = Marking::new();
        for p in self.marked.iter() {
            *marking
                .entry(self.net.places[p].name.to_string())
                .or_default() += self.marking[p];
        }
        marking
    }

    /// Tokens in the place `name` (0 for an unknown place).
    pub fn tokens(&self, place: &str) -> u32 {
        self.net
            .place_index
            .get(place)
            .map_or(0, |&p| self.marking[p])
    }

    /// When the transition `name` became enabled; `None` if it is not enabled (or unknown).
    pub fn enabled_since(&self, transition: &str) -> Option<f64> {
        self.transition_index(transition)
            .and_then(|t| self.enabled_since[t])
    }

    /// The enabled transitions, in declaration order.
    pub fn enabled(&self) -> Vec<String> {
        self.net
            .transitions
            .iter()
            .zip(&self.enabled_since)
            .filter(|(_, since)| since.is_some())
            .map(|(transition, _)| transition.name.clone())
            .collect()
    }

    /// Whether the transition `name` holds its event (reported since it was enabled).
    pub fn event_latched(&self, transition: &str) -> bool {
        self.transition_index(transition)
            .is_some_and(|t| self.latched[t])
    }

    /// Reports the event `name` (`MODULE.EVENT` or `module.ID.failed`) at `now_secs`: it is
    /// latched by each enabled transition waiting for it, whose names are returned (none: the
    /// event is ignored). It fires nothing: call [`Engine::step`].
    pub fn report_event(&mut self, name: &str, now_secs: f64) -> Vec<String> {
        self.advance(now_secs);
        let mut latched = Vec::new();
        for (t, transition) in self.net.transitions.iter().enumerate() {
            if self.enabled_since[t].is_some()
                && transition.condition.event.as_deref() == Some(name)
            {
                self.latched[t] = true;
                latched.push(transition.name.clone());
            }
        }
        latched
    }

    /// Fires every transition that can fire at `now_secs`, one at a time, until none can (or
    /// [`MAX_FIRINGS_PER_STEP`] have fired), and returns the firings in order.
    pub fn step(&mut self, now_secs: f64) -> Vec<Firing> {
        let now = self.advance(now_secs);
        let mut firings = Vec::new();
        while firings.len() < MAX_FIRINGS_PER_STEP {
            let next = self
                .enabled
                .iter()
                .map(|rank| self.net.order[rank])
                .find(|&t| self.can_fire(t, now));
            let Some(t) = next else {
                break;
            };
            firings.push(self.fire(t, now));
        }
        firings
    }

    /// The earliest time at which a transition can fire without a new event, for the caller's
    /// timer: `None` when only events (or nothing) can make one fire. A value equal to
    /// [`Engine::now`] means a transition can fire already: call [`Engine::step`].
    pub fn next_deadline(&self) -> Option<f64> {
        let mut earliest: Option<f64> = None;
        for (t, transition) in self.net.transitions.iter().enumerate() {
            let Some(since) = self.enabled_since[t] else {
                continue;
            };
            let condition = &transition.condition;
            if (condition.event.is_some() && !self.latched[t]) || condition.operator {
                continue;
            }
            let mut due = since;
            if let Some(delay) = condition.delay_secs {
                due = due.max(since + delay);
                if (since + delay).is_nan() {
                    continue;
                }
            }
            if let Some(at) = condition.at_unix_secs {
                if (at - self.date_origin).is_nan() {
                    continue;
                }
                due = due.max(at - self.date_origin);
            }
            let due = due.max(self.now);
            if due.is_finite() && earliest.is_none_or(|earliest| due < earliest) {
                earliest = Some(due);
            }
        }
        earliest
    }

    /// Fires the transition `name` now if it is enabled, whatever its condition (an operator's
    /// decision).
    pub fn fire_by_hand(&mut self, name: &str, now_secs: f64) -> Result<Firing, EngineError> {
        let now = self.advance(now_secs);
        let Some(t) = self.transition_index(name) else {
            return Err(EngineError::UnknownTransition {
                name: name.to_owned(),
                known: listing(self.net.transitions.iter().map(|t| t.name.as_str())),
            });
        };
        if self.enabled_since[t].is_none() {
            return Err(EngineError::NotEnabled {
                name: name.to_owned(),
                why: self.why_disabled(t),
            });
        }
        Ok(self.fire(t, now))
    }

    /// The modules named by the marked places.
    pub fn active_modules(&self) -> BTreeSet<String> {
        self.net
            .modules
            .iter()
            .zip(&self.module_places)
            .filter(|(_, places)| **places > 0)
            .map(|(module, _)| module.clone())
            .collect()
    }

    /// Module -> parameter -> value, set by the marked places. When two marked places set the
    /// same parameter, the place declared first wins.
    pub fn params(&self) -> BTreeMap<String, BTreeMap<String, String>> {
        let mut params: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
        for p in self.marked.iter() {
            for (module, name, value) in &self.net.places[p].params {
                params
                    .entry(module.clone())
                    .or_default()
                    .entry(name.clone())
                    .or_insert_with(|| value.clone());
            }
        }
        params
    }

    /// A final place is marked: the mission is over, successfully.
    pub fn is_final(&self) -> bool {
        self.marked.iter().any(|p| self.net.places[p].is_final)
    }

    /// No transition is enabled and no final place is marked: the mission is stuck.
    pub fn is_dead(&self) -> bool {
        self.enabled.len() == 0 && !self.is_final()
    }

    fn transition_index(&self, name: &str) -> Option<usize> {
        self.net.transition_index.get(name).copied()
    }

    /// Moves the clock to `now_secs` unless it is earlier (or not a number); the clock.
    fn advance(&mut self, now_secs: f64) -> f64 {
        if now_secs > self.now && now_secs.is_finite() {
            self.now = now_secs;
        }
        self.now
    }

    fn inputs_marked(&self, t: usize) -> bool {
        self.net.transitions[t]
            .inputs
            .iter()
            .all(|&(place, weight)| place.is_some_and(|p| self.marking[p] >= weight))
    }

    fn can_fire(&self, t: usize, now: f64) -> bool {
        let Some(since) = self.enabled_since[t] else {
            return false;
        };
        let condition = &self.net.transitions[t].condition;
        condition
            .delay_secs
            .is_none_or(|delay| now >= since + delay)
            && condition
                .at_unix_secs
                .is_none_or(|at| now >= at - self.date_origin)
            && (condition.event.is_none() || self.latched[t])
            && !condition.operator
    }

    fn why_disabled(&self, t: usize) -> String {
        let transition = &self.net.transitions[t];
        for (arc, &(place, weight)) in transition.inputs.iter().enumerate() {
            match place {
                None => return format!("its input arc {} goes to no place", arc + 1),
                Some(p) if self.marking[p] < weight => {
                    return format!(
                        "place `{}` holds {} of the {} it needs",
                        self.net.places[p].name,
                        self.marking[p],
                        crate::plural(weight as usize, "token")
                    );
                }
                Some(_) => {}
            }
        }
        "it is not enabled".to_owned()
    }

    /// Whether `t` is enabled after the marking changed; `fired` (it has just fired) starts
    /// afresh.
    fn refresh(&mut self, t: usize, fired: bool, now: f64) {
        let enabled = self.inputs_marked(t);
        if !enabled {
            self.enabled_since[t] = None;
            self.latched[t] = false;
        } else if self.enabled_since[t].is_none() || fired {
            self.enabled_since[t] = Some(now);
        }
        if fired {
            self.latched[t] = false;
        }
        self.enabled.set(self.net.transitions[t].rank, enabled);
    }

    /// Sets the tokens of place `p`; when it becomes marked or unmarked, its modules' counts
    /// follow and each module whose activity may change is noted in `touched` with whether it
    /// was active before the firing.
    fn set_tokens(&mut self, p: usize, tokens: u32, touched: &mut Vec<(usize, bool)>) {
        let was_marked = self.marking[p] > 0;
        self.marking[p] = tokens;
        if was_marked == (tokens > 0) {
            return;
        }
        self.marked.set(p, tokens > 0);
        for &m in &self.net.places[p].modules {
            if !touched.iter().any(|&(seen, _)| seen == m) {
                touched.push((m, self.module_places[m] > 0));
            }
            if tokens > 0 {
                self.module_places[m] += 1;
            } else {
                self.module_places[m] -= 1;
            }
        }
    }

    fn fire(&mut self, t: usize, now: f64) -> Firing {
        let net = self.net.clone();
        let transition = &net.transitions[t];
        let mut touched = Vec::new();
        for &(place, weight) in &transition.inputs {
            if let Some(p) = place {
                self.set_tokens(p, self.marking[p].saturating_sub(weight), &mut touched);
            }
        }
        for &(place, weight) in &transition.outputs {
            if let Some(p) = place {
                self.set_tokens(p, self.marking[p].saturating_add(weight), &mut touched);
            }
        }
        for &other in &transition.affected {
            self.refresh(other, other == t, now);
        }
        touched.sort_unstable();
        let (mut started, mut stopped) = (Vec::new(), Vec::new());
        for (m, was_active) in touched {
            match (was_active, self.module_places[m] > 0) {
                (false, true) => started.push(net.modules[m].clone()),
                (true, false) => stopped.push(net.modules[m].clone()),
                _ => {}
            }
        }
        let mut marked = Vec::with_capacity(self.marked.len());
        marked.extend(
            self.marked
                .iter()
                .map(|p| (net.places[p].name.clone(), self.marking[p])),
        );
        Firing {
            transition: transition.name.clone(),
            at_secs: now,
            marking_after: MarkedPlaces(marked),
            started,
            stopped,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::net::test_net as net;

    /// `transition@time` for each firing.
    fn fired(firings: &[Firing]) -> Vec<String> {
        firings
            .iter()
            .map(|firing| format!("{}@{}", firing.transition, firing.at_secs))
            .collect()
    }

    fn marking(engine: &Engine) -> String {
        engine
            .marking()
            .iter()
            .map(|(place, tokens)| format!("{place}={tokens}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    #[test]
    fn transitions_without_condition_fire_at_once_and_modules_follow() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"1\"><module name=\"nav\"/><module name=\"sim\"/></place>",
            "<place name=\"b\"><module name=\"sim\"/><module name=\"arm\"/></place>",
            "<place name=\"c\" final=\"true\"/>",
            "<transition name=\"t1\"><input place=\"a\"/><output place=\"b\"/></transition>",
            "<transition name=\"t2\" delay_secs=\"1\"><input place=\"b\"/><output place=\"c\"/></transition>",
        ]));
        assert_eq!(engine.active_modules().len(), 2);
        let firings = engine.step(0.0);
        assert_eq!(
            firings,
            [Firing {
                transition: "t1".into(),
                at_secs: 0.0,
                marking_after: MarkedPlaces(vec![("b".into(), 1)]),
                started: vec!["arm".into()],
                stopped: vec!["nav".into()],
            }]
        );
        assert_eq!(engine.next_deadline(), Some(1.0));
        let firings = engine.step(1.5);
        assert_eq!(fired(&firings), ["t2@1.5"]);
        assert_eq!(firings[0].stopped, ["arm", "sim"]);
        assert!(engine.is_final());
        assert!(!engine.is_dead());
        assert_eq!(engine.next_deadline(), None);
        assert!(engine.step(100.0).is_empty());
    }

    #[test]
    fn a_resumed_engine_keeps_the_timers_of_the_transitions_both_nets_have() {
        let before_net = net(&[
            "<place name=\"wait\" tokens=\"1\"/><place name=\"done\" final=\"true\"/>",
            "<transition name=\"waited\" delay_secs=\"10\"><input place=\"wait\"/><output place=\"done\"/></transition>",
            "<transition name=\"seen\" event=\"eye.seen\"><input place=\"wait\"/><output place=\"done\"/></transition>",
        ]);
        let mut before = Engine::start_at(&before_net, 2.0).with_date_origin(100.0);
        assert_eq!(before.report_event("eye.seen", 4.0), ["seen"]);
        // The update waits longer, sees the same event, and adds a way out by a date.
        let after_net = net(&[
            "<place name=\"wait\"/><place name=\"done\" final=\"true\"/>",
            "<transition name=\"waited\" delay_secs=\"20\"><input place=\"wait\"/><output place=\"done\"/></transition>",
            "<transition name=\"seen\" event=\"eye.seen\"><input place=\"wait\"/><output place=\"done\"/></transition>",
            "<transition name=\"dated\" at=\"1970-01-01T00:02:30Z\"><input place=\"wait\"/><output place=\"done\"/></transition>",
        ]);
        let marking: Marking = [("wait".to_owned(), 1)].into();
        let resumed = Engine::resume(&after_net, &marking, &before, false, 5.0).unwrap();
        // The delay counts from 2 s, when `waited` became enabled, with its new length; the
        // event latched before is dropped; the date is the date (150 s, 50 s of run time).
        assert_eq!(resumed.enabled_since("waited"), Some(2.0));
        assert!(!resumed.event_latched("seen"));
        assert_eq!(resumed.enabled_since("dated"), Some(5.0));
        assert_eq!(resumed.date_origin(), 100.0);
        assert_eq!(resumed.next_deadline(), Some(22.0));
        let mut kept = Engine::resume(&after_net, &marking, &before, true, 5.0).unwrap();
        assert!(kept.event_latched("seen"));
        assert_eq!(fired(&kept.step(5.0)), ["seen@5"]);
        // A marking in a place the new net does not have is refused.
        let gone: Marking = [("elsewhere".to_owned(), 1)].into();
        let err = Engine::resume(&after_net, &gone, &before, false, 5.0).unwrap_err();
        assert_eq!(
            err.to_string(),
            "no place `elsewhere` in this mission (places: wait, done)"
        );
    }

    #[test]
    fn delays_count_from_when_the_transition_became_enabled() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"1\"/><place name=\"b\"/><place name=\"done\"/>",
            "<transition name=\"leave\" event=\"x.go\"><input place=\"a\"/><output place=\"b\"/></transition>",
            "<transition name=\"back\" event=\"x.back\"><input place=\"b\"/><output place=\"a\"/></transition>",
            "<transition name=\"timeout\" delay_secs=\"5\"><input place=\"a\"/><output place=\"done\"/></transition>",
        ]));
        assert_eq!(engine.enabled_since("timeout"), Some(0.0));
        assert_eq!(engine.next_deadline(), Some(5.0));
        assert!(engine.step(3.0).is_empty());
        assert_eq!(engine.report_event("x.go", 3.0), ["leave"]);
        assert_eq!(engine.next_deadline(), Some(3.0));
        assert_eq!(fired(&engine.step(3.0)), ["leave@3"]);
        assert_eq!(engine.enabled_since("timeout"), None);
        assert_eq!(engine.next_deadline(), None);
        engine.report_event("x.back", 4.0);
        assert_eq!(fired(&engine.step(4.0)), ["back@4"]);
        // Enabled again at 4: the delay starts over.
        assert_eq!(engine.enabled_since("timeout"), Some(4.0));
        assert_eq!(engine.next_deadline(), Some(9.0));
        assert!(engine.step(8.99).is_empty());
        assert_eq!(fired(&engine.step(9.0)), ["timeout@9"]);
        assert_eq!(marking(&engine), "done=1");
        assert!(engine.is_dead());
    }

    #[test]
    fn dates_are_absolute() {
        // 2026-11-22T20:00:00Z is 1_795_377_600; the run starts 10 s before.
        let mission = net(&[
            "<place name=\"a\" tokens=\"1\"/><place name=\"b\"/>",
            "<transition name=\"t\" at=\"2026-11-22T21:00:00+01:00\"><input place=\"a\"/><output place=\"b\"/></transition>",
        ]);
        let mut engine = Engine::new(&mission).with_date_origin(1_795_377_590.0);
        assert_eq!(engine.next_deadline(), Some(10.0));
        assert!(engine.step(9.9).is_empty());
        assert_eq!(fired(&engine.step(10.0)), ["t@10"]);
        // A date in the past at the start: fires at once.
        let mut engine = Engine::new(&mission).with_date_origin(1_795_377_700.0);
        assert_eq!(engine.next_deadline(), Some(0.0));
        assert_eq!(fired(&engine.step(0.0)), ["t@0"]);
        // The caller's clock may be the Unix time itself.
        let mut engine = Engine::start_at(&mission, 1_795_377_000.0);
        assert_eq!(engine.next_deadline(), Some(1_795_377_600.0));
        assert_eq!(fired(&engine.step(1_795_377_600.0)), ["t@1795377600"]);
    }

    #[test]
    fn delay_date_and_event_must_all_hold() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"1\"/><place name=\"b\"/>",
            "<transition name=\"t\" delay_secs=\"2\" at=\"1970-01-01T00:00:05Z\" event=\"nav.done\"><input place=\"a\"/><output place=\"b\"/></transition>",
        ]));
        assert_eq!(engine.next_deadline(), None, "waits for the event");
        assert_eq!(engine.report_event("nav.done", 1.0), ["t"]);
        assert!(engine.event_latched("t"));
        assert_eq!(engine.next_deadline(), Some(5.0));
        assert!(
            engine.step(2.0).is_empty(),
            "delay elapsed, date not reached"
        );
        assert_eq!(fired(&engine.step(5.0)), ["t@5"]);
        assert!(!engine.event_latched("t"));
    }

    #[test]
    fn events_count_only_for_transitions_enabled_when_reported() {
        let mission = net(&[
            "<place name=\"a\" tokens=\"1\"/><place name=\"b\"/><place name=\"c\"/><place name=\"d\"/>",
            "<transition name=\"t1\" delay_secs=\"1\"><input place=\"a\"/><output place=\"b\"/></transition>",
            "<transition name=\"t2\" event=\"nav.done\"><input place=\"b\"/><output place=\"c\"/></transition>",
            "<transition name=\"t3\" delay_secs=\"3\"><input place=\"b\"/><output place=\"d\"/></transition>",
            "<transition name=\"t4\" event=\"nav.done\"><input place=\"d\"/><output place=\"b\"/></transition>",
        ]);
        let mut engine = Engine::new(&mission);
        // Too early: t2 is not enabled, the event is lost.
        assert!(engine.report_event("nav.done", 0.5).is_empty());
        assert_eq!(fired(&engine.step(1.0)), ["t1@1"]);
        assert!(engine.step(2.0).is_empty());
        assert_eq!(
            engine.next_deadline(),
            Some(4.0),
            "only t3's delay is pending"
        );
        // Other events do nothing.
        assert!(engine.report_event("nav.blocked", 2.5).is_empty());
        assert_eq!(engine.report_event("nav.done", 3.0), ["t2"]);
        assert_eq!(fired(&engine.step(3.0)), ["t2@3"]);
        assert_eq!(marking(&engine), "c=1");

        // Latched but not stepped at once: at 4 both t2 and t3 can fire, t2 is declared first.
        let mut engine = Engine::new(&mission);
        engine.step(1.0);
        engine.report_event("nav.done", 1.0);
        assert!(engine.event_latched("t2"));
        assert_eq!(fired(&engine.step(4.0)), ["t2@4"]);

        // An event latched by a transition that is then disabled is forgotten.
        let mut engine = Engine::new(&net(&[
            "<place name=\"b\" tokens=\"1\"/><place name=\"c\"/><place name=\"d\"/>",
            "<transition name=\"t2\" event=\"nav.done\" delay_secs=\"10\"><input place=\"b\"/><output place=\"c\"/></transition>",
            "<transition name=\"t3\" delay_secs=\"3\"><input place=\"b\"/><output place=\"d\"/></transition>",
            "<transition name=\"t4\" event=\"nav.done\"><input place=\"d\"/><output place=\"b\"/></transition>",
        ]));
        assert_eq!(engine.report_event("nav.done", 1.0), ["t2"]);
        assert_eq!(fired(&engine.step(3.0)), ["t3@3"]);
        assert!(!engine.event_latched("t2"));
        assert_eq!(engine.report_event("nav.done", 5.0), ["t4"]);
        assert_eq!(fired(&engine.step(5.0)), ["t4@5"]);
        // Back in b at 5: t2 needs a new event, t3 fires again 3 s later.
        assert!(!engine.event_latched("t2"));
        assert_eq!(engine.next_deadline(), Some(8.0));
        assert_eq!(fired(&engine.step(20.0)), ["t3@20"]);
    }

    #[test]
    fn priorities_then_declaration_order_settle_conflicts() {
        let mission = net(&[
            "<place name=\"a\" tokens=\"1\"/><place name=\"low\"/><place name=\"high\"/><place name=\"first\"/><place name=\"second\"/>",
            "<transition name=\"t_low\"><input place=\"a\"/><output place=\"low\"/></transition>",
            "<transition name=\"t_high\" priority=\"5\" event=\"x.e\"><input place=\"a\"/><output place=\"high\"/></transition>",
            "<transition name=\"t_first\" priority=\"-1\"><input place=\"low\"/><output place=\"first\"/></transition>",
            "<transition name=\"t_second\" priority=\"-1\"><input place=\"low\"/><output place=\"second\"/></transition>",
        ]);
        // t_high waits for its event: t_low fires, then the first declared of two equals.
        let mut engine = Engine::new(&mission);
        assert_eq!(fired(&engine.step(0.0)), ["t_low@0", "t_first@0"]);
        assert_eq!(marking(&engine), "first=1");
        // With the event, the higher priority wins.
        let mut engine = Engine::new(&mission);
        engine.report_event("x.e", 0.0);
        assert_eq!(fired(&engine.step(0.0)), ["t_high@0"]);
        assert_eq!(marking(&engine), "high=1");
    }

    #[test]
    fn weights() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"5\"/><place name=\"b\"/>",
            "<transition name=\"t\"><input place=\"a\" weight=\"2\"/><output place=\"b\" weight=\"3\"/></transition>",
            "<transition name=\"u\" delay_secs=\"1\"><input place=\"b\" weight=\"7\"/><output place=\"a\"/></transition>",
        ]));
        assert_eq!(fired(&engine.step(0.0)), ["t@0", "t@0"]);
        assert_eq!(marking(&engine), "a=1 b=6");
        assert_eq!(engine.enabled(), Vec::<String>::new());
        assert!(engine.is_dead());
        assert_eq!(
            engine.fire_by_hand("u", 1.0),
            Err(EngineError::NotEnabled {
                name: "u".into(),
                why: "place `b` holds 6 of the 7 tokens it needs".into()
            })
        );
    }

    #[test]
    fn a_transition_that_stays_enabled_after_firing_starts_afresh() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"3\"/><place name=\"b\"/>",
            "<transition name=\"t\" delay_secs=\"2\"><input place=\"a\"/><output place=\"b\"/></transition>",
        ]));
        assert_eq!(fired(&engine.step(2.0)), ["t@2"]);
        assert_eq!(engine.enabled_since("t"), Some(2.0));
        assert_eq!(fired(&engine.step(10.0)), ["t@10"]);
        assert_eq!(fired(&engine.step(12.0)), ["t@12"]);
        assert_eq!(marking(&engine), "b=3");
    }

    #[test]
    fn by_hand() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"1\"/><place name=\"b\"><module name=\"nav\"/></place>",
            "<transition name=\"go\" event=\"op.go\" delay_secs=\"100\"><input place=\"a\"/><output place=\"b\"/></transition>",
            "<transition name=\"back\"><input place=\"b\" weight=\"2\"/><output place=\"a\"/></transition>",
        ]));
        assert_eq!(
            engine.fire_by_hand("nope", 0.0),
            Err(EngineError::UnknownTransition {
                name: "nope".into(),
                known: "go, back".into()
            })
        );
        assert_eq!(
            engine
                .fire_by_hand("back", 0.0)
                .map_err(|err| err.to_string()),
            Err("transition `back` cannot fire: place `b` holds 0 of the 2 tokens it needs".into())
        );
        // Enabled, condition not met: by hand it fires anyway.
        let firing = engine.fire_by_hand("go", 1.0).expect("enabled");
        assert_eq!(firing.started, ["nav"]);
        assert_eq!(firing.at_secs, 1.0);
        assert!(engine.fire_by_hand("go", 2.0).is_err());
    }

    #[test]
    fn operator_transitions_wait_for_a_person() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"held\" tokens=\"1\"/><place name=\"leg\"/>",
            "<transition name=\"resume\" operator=\"true\"><input place=\"held\"/><output place=\"leg\"/></transition>",
        ]));
        assert!(engine.step(1e9).is_empty());
        assert_eq!(engine.next_deadline(), None);
        assert_eq!(engine.enabled(), ["resume"]);
        let firing = engine.fire_by_hand("resume", 1e9 + 1.0).expect("enabled");
        assert_eq!(firing.transition, "resume");
        assert_eq!(marking(&engine), "leg=1");
    }

    #[test]
    fn a_cycle_without_condition_is_cut_and_resumed() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"1\"/><place name=\"b\"/>",
            "<transition name=\"ab\"><input place=\"a\"/><output place=\"b\"/></transition>",
            "<transition name=\"ba\"><input place=\"b\"/><output place=\"a\"/></transition>",
        ]));
        assert_eq!(engine.step(0.0).len(), MAX_FIRINGS_PER_STEP);
        assert_eq!(engine.next_deadline(), Some(0.0));
        assert_eq!(engine.step(0.0).len(), MAX_FIRINGS_PER_STEP);
    }

    #[test]
    fn parameters_of_the_marked_places() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"1\"><module name=\"nav\"/><param module=\"nav\" name=\"goal_x\" value=\"1\"/></place>",
            "<place name=\"b\" tokens=\"1\"><module name=\"nav\"/><module name=\"sim\"/><param module=\"nav\" name=\"goal_x\" value=\"2\"/><param module=\"nav\" name=\"speed\" value=\"3\"/><param module=\"sim\" name=\"rate\" value=\"4\"/></place>",
            "<place name=\"c\"/>",
            "<transition name=\"t\" event=\"x.y\"><input place=\"a\"/><output place=\"c\"/></transition>",
        ]));
        let params = |engine: &Engine| format!("{:?}", engine.params());
        assert_eq!(
            params(&engine),
            r#"{"nav": {"goal_x": "1", "speed": "3"}, "sim": {"rate": "4"}}"#
        );
        engine.report_event("x.y", 1.0);
        let firing = &engine.step(1.0)[0];
        assert!(firing.started.is_empty() && firing.stopped.is_empty());
        assert_eq!(
            params(&engine),
            r#"{"nav": {"goal_x": "2", "speed": "3"}, "sim": {"rate": "4"}}"#
        );
    }

    #[test]
    fn time_never_goes_backwards_and_odd_nets_do_not_panic() {
        let mut engine = Engine::new(&net(&[
            "<place name=\"a\" tokens=\"1\"/>",
            "<transition name=\"t\" delay_secs=\"5\"><input place=\"a\"/><output place=\"a\"/></transition>",
        ]));
        assert!(engine.step(4.0).is_empty());
        assert!(engine.step(1.0).is_empty());
        assert!(engine.step(f64::NAN).is_empty());
        assert_eq!(engine.now(), 4.0);
        assert_eq!(fired(&engine.step(5.0)), ["t@5"]);
        // A net built in code with arcs to unknown places, odd numbers and no inputs.
        let mut odd = MissionNet::default();
        odd.places.push(super::super::Place {
            name: "p".into(),
            tokens: u32::MAX,
            ..Default::default()
        });
        odd.transitions.push(super::super::Transition {
            name: "ghost".into(),
            inputs: vec![super::super::Arc {
                place: "nowhere".into(),
                weight: 1,
                pos: Default::default(),
            }],
            ..Default::default()
        });
        odd.transitions.push(super::super::Transition {
            name: "source".into(),
            condition: Condition {
                delay_secs: Some(f64::NAN),
                ..Condition::default()
            },
            outputs: vec![super::super::Arc {
                place: "p".into(),
                weight: u32::MAX,
                pos: Default::default(),
            }],
            ..Default::default()
        });
        let mut engine = Engine::start_at(&odd, f64::NAN);
        assert_eq!(engine.enabled(), ["source"]);
        assert_eq!(engine.next_deadline(), None);
        assert!(engine.step(1.0).is_empty());
        assert!(engine.fire_by_hand("ghost", 1.0).is_err());
        assert!(engine.fire_by_hand("source", 1.0).is_ok());
        assert_eq!(engine.tokens("p"), u32::MAX);
    }

    /// The engine keeps its enabled transitions, marked places and active modules up to date
    /// from what each firing touched; on random nets (shared places, several tokens, weights,
    /// modules in several places, self-loops) they must always equal their definitions,
    /// recomputed from the marking.
    #[test]
    fn what_is_kept_up_to_date_matches_its_definition() {
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move |below: usize| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % below as u64) as usize
        };
        for _ in 0..100 {
            let (places, transitions) = (2 + next(8), 1 + next(10));
            let mut net = MissionNet::default();
            for p in 0..places {
                net.places.push(super::super::Place {
                    name: format!("p{p}"),
                    tokens: next(3) as u32,
                    modules: (0..next(3)).map(|_| format!("m{}", next(4))).collect(),
                    ..Default::default()
                });
            }
            let arcs = |next: &mut dyn FnMut(usize) -> usize| {
                (0..next(3))
                    .map(|_| super::super::Arc {
                        place: format!("p{}", next(places)),
                        weight: 1 + next(2) as u32,
                        pos: Default::default(),
                    })
                    .collect()
            };
            for t in 0..transitions {
                net.transitions.push(super::super::Transition {
                    name: format!("t{t}"),
                    priority: next(3) as i32,
                    inputs: arcs(&mut next),
                    outputs: arcs(&mut next),
                    ..Default::default()
                });
            }
            let mut engine = Engine::new(&net);
            let mut active = engine.active_modules();
            for round in 0..20 {
                // `step` fires until nothing can: 10,000 firings on a net with a cycle.
                let firings = if round % 10 == 0 {
                    engine.step(round as f64)
                } else {
                    let enabled = engine.enabled();
                    if enabled.is_empty() {
                        break;
                    }
                    let pick = &enabled[next(enabled.len())];
                    vec![
                        engine
                            .fire_by_hand(pick, round as f64)
                            .expect("an enabled transition fires by hand"),
                    ]
                };
                for firing in &firings {
                    let after: BTreeSet<String> = active
                        .iter()
                        .filter(|module| !firing.stopped.contains(module))
                        .chain(&firing.started)
                        .cloned()
                        .collect();
                    active = after;
                }
                let tokens = |place: &str| engine.tokens(place);
                let expected: Vec<String> = net
                    .transitions
                    .iter()
                    .filter(|t| t.inputs.iter().all(|arc| tokens(&arc.place) >= arc.weight))
                    .map(|t| t.name.clone())
                    .collect();
                assert_eq!(engine.enabled(), expected, "{net:?}");
                assert_eq!(engine.is_dead(), expected.is_empty(), "{net:?}");
                let modules: BTreeSet<String> = net
                    .places
                    .iter()
                    .filter(|place| tokens(&place.name) > 0)
                    .flat_map(|place| place.modules.iter().cloned())
                    .collect();
                assert_eq!(engine.active_modules(), modules, "{net:?}");
                assert_eq!(active, modules, "started and stopped: {net:?}");
                if let Some(last) = firings.last() {
                    assert_eq!(last.marking_after, engine.marking(), "{net:?}");
                }
            }
        }
    }
}
