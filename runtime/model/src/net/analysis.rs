//! What can happen in a mission, whatever the times and events: the analysis of the *untimed*
//! net, where every condition may hold at any moment and priorities are ignored. That covers
//! every run of the timed net (a deadlock found here may need a particular timing to happen).
//!
//! - Reachability: breadth-first, so each dead marking comes with a shortest firing sequence.
//!   Markings are packed 1, 2, 4, 8, 16 or 32 bits per place (the narrowest that holds every
//!   count seen: the search starts over wider when a count outgrows it; a safe net takes one
//!   bit per place) into 64-bit words stored back to back in one arena, and found again
//!   through an open-addressing hash table of 8-byte slots (a 32-bit hash tag and the
//!   marking's index), with the parent of each marking for the sequences.
//! - When the reachable markings exceed the limit, Karp–Miller coverability (markings with ω)
//!   tells which places are unbounded, which transitions can never fire and which places are
//!   never marked; deadlocks are then only searched among the markings explored.

use std::collections::HashSet;
use std::fmt::Write as _;

use armor_module_api::xml::{Located, Pos};

use super::{Arc, Marking, MissionNet, Place, Transition};

/// At most this many dead markings are kept with their sequence (the first found, so the
/// shortest); [`Analysis::dead_count`] counts them all.
pub const MAX_DEAD_MARKINGS: usize = 100;

/// What the analysis found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Analysis {
    /// Reachable markings explored.
    pub states: usize,
    /// Markings where no transition is enabled and no final place is marked, each with a
    /// shortest firing sequence from the initial marking (at most [`MAX_DEAD_MARKINGS`]).
    pub dead_markings: Vec<(Marking, Vec<String>)>,
    /// All the dead markings found.
    pub dead_count: usize,
    /// Transitions enabled in no reachable marking.
    pub never_fired: Vec<String>,
    /// Places that hold a token in no reachable marking.
    pub never_marked: Vec<String>,
    /// Places whose tokens can grow without limit.
    pub unbounded: Vec<String>,
    /// The reachable markings are more than the limit: other dead markings may exist.
    pub truncated: bool,
    /// With `truncated`, the coverability analysis stopped at the limit too: `never_fired` and
    /// `never_marked` are then left empty, and `unbounded` may miss places.
    pub coverability_truncated: bool,
}

/// Analyses the untimed net, exploring at most `limit_states` markings (and as many nodes of
/// the coverability tree when the markings are more).
pub fn analyse(net: &MissionNet, limit_states: usize) -> Analysis {
    let compiled = Compiled::new(net);
    let limit = limit_states.clamp(1, u32::MAX as usize - 1);
    single_token_state_machine(&compiled, limit)
        .unwrap_or_else(|| analyse_by_exploration(&compiled, limit))
}

/// The general analysis: the reachable markings packed as bit fields, explored breadth-first,
/// then the coverability tree when they are too many.
fn analyse_by_exploration(compiled: &Compiled, limit: usize) -> Analysis {
    // The narrowest fields that hold the initial counts, wider when a count outgrows them.
    let widest = u64::from(compiled.initial.iter().copied().max().unwrap_or(0));
    let explored = [1, 2, 4, 8, 16]
        .into_iter()
        .filter(|&bits| widest < 1 << bits)
        .find_map(|bits| match bits {
            1 => explore::<1>(compiled, limit),
            2 => explore::<2>(compiled, limit),
            4 => explore::<4>(compiled, limit),
            8 => explore::<8>(compiled, limit),
            _ => explore::<16>(compiled, limit),
        })
        .or_else(|| explore::<32>(compiled, limit));
    let Some(explored) = explored else {
        // Unreachable: 32 bits hold any count.
        return Analysis::default();
    };
    let mut analysis = Analysis {
        states: explored.states,
        dead_count: explored.dead.len(),
        truncated: explored.truncated,
        ..Analysis::default()
    };
    for &state in explored.dead.iter().take(MAX_DEAD_MARKINGS) {
        let counts = explored.decode(state);
        let marking = compiled.marking(&counts);
        let sequence = explored
            .sequence(state)
            .into_iter()
            .map(|t| compiled.transition_names[t].to_owned())
            .collect();
        analysis.dead_markings.push((marking, sequence));
    }
    let (fired, marked) = if explored.truncated {
        let coverability = karp_miller(compiled, limit);
        analysis.unbounded = names(&compiled.place_names, &coverability.unbounded, true);
        analysis.coverability_truncated = !coverability.complete;
        if coverability.complete {
            (coverability.fired, coverability.marked)
        } else {
            return analysis;
        }
    } else {
        (explored.fired, explored.marked)
    };
    analysis.never_fired = names(&compiled.transition_names, &fired, false);
    analysis.never_marked = names(&compiled.place_names, &marked, false);
    analysis
}

/// The analysis of a net that moves one token around: a single token at the start and every
/// transition taking one token from one place and putting one in one place (what a plan
/// compiles to, whatever its size). Its markings are its places, so the reachable markings are
/// the places a breadth-first search reaches, in the order the general exploration finds them,
/// which gives the same results in time linear in the net. `None` for any other net, or when
/// the places reached are more than `limit`.
fn single_token_state_machine(net: &Compiled, limit: usize) -> Option<Analysis> {
    let places = net.place_names.len();
    let mut start = None;
    for (p, &tokens) in net.initial.iter().enumerate() {
        match tokens {
            0 => {}
            1 if start.is_none() => start = Some(p),
            _ => return None,
        }
    }
    let start = start?;
    // Each transition's (input, output) place.
    let mut moves = Vec::with_capacity(net.transitions());
    for t in 0..net.transitions() {
        let [(from, 1)] = net.pre(t) else {
            return None;
        };
        let to = match net.effect(t) {
            [] => *from,
            [(a, -1), (b, 1)] if a == from => *b,
            [(b, 1), (a, -1)] if a == from => *b,
            _ => return None,
        };
        moves.push((*from, to));
    }
    let mut parent = vec![usize::MAX; places];
    let mut via = vec![usize::MAX; places];
    let mut reached = vec![false; places];
    let mut order = vec![start];
    reached[start] = true;
    let mut fired = vec![false; net.transitions()];
    let mut dead = Vec::new();
    let mut next = 0;
    while next < order.len() {
        let p = order[next];
        next += 1;
        let mut any = false;
        for &t in &net.consumers[p] {
            let t = t as usize;
            any = true;
            fired[t] = true;
            let q = moves[t].1;
            if !reached[q] {
                if order.len() >= limit {
                    return None;
                }
                reached[q] = true;
                parent[q] = p;
                via[q] = t;
                order.push(q);
            }
        }
        if !any && !net.finals.contains(&p) {
            dead.push(p);
        }
    }
    let mut analysis = Analysis {
        states: order.len(),
        dead_count: dead.len(),
        ..Analysis::default()
    };
    for &p in dead.iter().take(MAX_DEAD_MARKINGS) {
        let mut sequence = Vec::new();
        let mut at = p;
        while at != start {
            sequence.push(net.transition_names[via[at]].to_owned());
            at = parent[at];
        }
        sequence.reverse();
        let marking = Marking::from([(net.place_names[p].to_owned(), 1)]);
        analysis.dead_markings.push((marking, sequence));
    }
    analysis.never_fired = names(&net.transition_names, &fired, false);
    analysis.never_marked = names(&net.place_names, &reached, false);
    Some(analysis)
}

/// The names whose flag is `wanted`.
fn names(names: &[&str], flags: &[bool], wanted: bool) -> Vec<String> {
    names
        .iter()
        .zip(flags)
        .filter(|(_, flag)| **flag == wanted)
        .map(|(name, _)| (*name).to_owned())
        .collect()
}

/// At most this many transitions of a firing sequence are written in a message.
const SHOWN_FIRINGS: usize = 20;

impl Analysis {
    /// The findings as problems at the elements concerned, sorted by position: a deadlock at
    /// the first place it marks, a dead transition or a never-marked or unbounded place at its
    /// element, the limit reached at the mission.
    pub fn problems(&self, net: &MissionNet) -> Vec<Located> {
        let mut problems = Vec::new();
        let place_pos = |name: &str| net.place(name).map_or(net.pos, |place| place.pos);
        for (marking, sequence) in &self.dead_markings {
            let pos = net
                .places
                .iter()
                .find(|place| marking.contains_key(&place.name))
                .map_or(net.pos, |place| place.pos);
            let shown = render_marking(marking);
            let message = if sequence.is_empty() {
                format!("the net can deadlock in its initial marking {shown} (not a final marking)")
            } else {
                let mut firings = sequence
                    .iter()
                    .take(SHOWN_FIRINGS)
                    .map(String::as_str)
                    .collect::<Vec<_>>()
                    .join(", ");
                if sequence.len() > SHOWN_FIRINGS {
                    let _ = write!(firings, ", ... ({} firings in all)", sequence.len());
                }
                format!(
                    "the net can deadlock in marking {shown} after firing {firings} (not a final marking)"
                )
            };
            problems.push(Located::new(pos, message));
        }
        if self.dead_count > self.dead_markings.len() {
            problems.push(Located::new(
                net.pos,
                format!(
                    "the net can deadlock in {} other markings",
                    self.dead_count - self.dead_markings.len()
                ),
            ));
        }
        for name in &self.never_fired {
            let pos = net.transition(name).map_or(net.pos, |t| t.pos);
            problems.push(Located::new(
                pos,
                format!("transition `{name}` can never fire"),
            ));
        }
        for name in &self.never_marked {
            problems.push(Located::new(
                place_pos(name),
                format!("place `{name}` is never marked"),
            ));
        }
        for name in &self.unbounded {
            problems.push(Located::new(
                place_pos(name),
                format!("place `{name}` is unbounded: its tokens can grow without limit"),
            ));
        }
        if self.truncated {
            let mut message = format!(
                "the analysis stopped at its limit of {} markings: the net may deadlock in \
                 markings not explored",
                self.states
            );
            if self.coverability_truncated {
                message.push_str(
                    "; transitions that can never fire and places never marked were not \
                     searched, and more places may be unbounded",
                );
            }
            problems.push(Located::new(net.pos, message));
        }
        problems.sort_by_key(|problem| problem.pos);
        problems
    }
}

/// `{a: 1, b: 2}`.
fn render_marking(marking: &Marking) -> String {
    let parts: Vec<String> = marking
        .iter()
        .map(|(place, tokens)| format!("{place}: {tokens}"))
        .collect();
    format!("{{{}}}", parts.join(", "))
}

/// The net as the analysis needs it: indices and flat arrays.
struct Compiled<'a> {
    place_names: Vec<&'a str>,
    transition_names: Vec<&'a str>,
    initial: Vec<u32>,
    finals: Vec<usize>,
    /// Transition `t`'s inputs are `pre[pre_start[t]..pre_start[t + 1]]`: (place, weight), one
    /// per place. Transitions that can never be enabled (an input from no place) have a
    /// weight above any count.
    pre_start: Vec<usize>,
    pre: Vec<(usize, u64)>,
    /// Net effect of the firing on each place it changes: (place, tokens added or taken).
    effect_start: Vec<usize>,
    effect: Vec<(usize, i64)>,
    /// The transitions with an input arc from each place, in order: only those can be enabled
    /// by a marking of that place (a mission net marks a handful of its thousands of places).
    consumers: Vec<Vec<u32>>,
    /// Transitions without input arcs (refused by every reader, but the analysis takes any
    /// net): enabled in every marking.
    sourceless: Vec<u32>,
}

impl<'a> Compiled<'a> {
    fn new(net: &'a MissionNet) -> Compiled<'a> {
        let by_name: std::collections::HashMap<&str, usize> = net
            .places
            .iter()
            .enumerate()
            .rev()
            .map(|(p, place)| (place.name.as_str(), p))
            .collect();
        let index = |name: &str| by_name.get(name).copied();
        let mut compiled = Compiled {
            place_names: net.places.iter().map(|place| place.name.as_str()).collect(),
            transition_names: net.transitions.iter().map(|t| t.name.as_str()).collect(),
            initial: net.places.iter().map(|place| place.tokens).collect(),
            finals: (0..net.places.len())
                .filter(|&p| net.places[p].is_final)
                .collect(),
            pre_start: vec![0],
            pre: Vec::new(),
            effect_start: vec![0],
            effect: Vec::new(),
            consumers: vec![Vec::new(); net.places.len()],
            sourceless: Vec::new(),
        };
        for transition in &net.transitions {
            let mut pre: Vec<(usize, u64)> = Vec::new();
            let mut effect: Vec<(usize, i64)> = Vec::new();
            let mut never = false;
            for arc in &transition.inputs {
                match index(&arc.place) {
                    Some(p) => {
                        add(&mut pre, p, u64::from(arc.weight));
                        add(&mut effect, p, -i64::from(arc.weight));
                    }
                    None => never = true,
                }
            }
            for arc in &transition.outputs {
                if let Some(p) = index(&arc.place) {
                    add(&mut effect, p, i64::from(arc.weight));
                }
            }
            if never {
                // An input from no place: never enabled.
                pre.push((usize::MAX, u64::MAX));
            }
            effect.retain(|&(_, delta)| delta != 0);
            let t = compiled.pre_start.len() as u32 - 1;
            if pre.is_empty() {
                compiled.sourceless.push(t);
            }
            for &(p, _) in &pre {
                if let Some(consumers) = compiled.consumers.get_mut(p) {
                    consumers.push(t);
                }
            }
            compiled.pre.extend(pre);
            compiled.pre_start.push(compiled.pre.len());
            compiled.effect.extend(effect);
            compiled.effect_start.push(compiled.effect.len());
        }
        compiled
    }

    fn transitions(&self) -> usize {
        self.transition_names.len()
    }

    fn pre(&self, t: usize) -> &[(usize, u64)] {
        &self.pre[self.pre_start[t]..self.pre_start[t + 1]]
    }

    fn effect(&self, t: usize) -> &[(usize, i64)] {
        &self.effect[self.effect_start[t]..self.effect_start[t + 1]]
    }

    fn enabled(&self, t: usize, marking: &[u32]) -> bool {
        self.pre(t).iter().all(|&(p, weight)| {
            marking
                .get(p)
                .is_some_and(|&tokens| u64::from(tokens) >= weight)
        })
    }

    fn is_final(&self, marking: &[u32]) -> bool {
        self.finals.iter().any(|&p| marking[p] > 0)
    }

    fn marking(&self, counts: &[u32]) -> Marking {
        self.place_names
            .iter()
            .zip(counts)
            .filter(|(_, tokens)| **tokens > 0)
            .map(|(name, tokens)| ((*name).to_owned(), *tokens))
            .collect()
    }
}

/// Adds `amount` to the entry of `place`, or a new entry.
fn add<T: std::ops::AddAssign + Copy>(entries: &mut Vec<(usize, T)>, place: usize, amount: T) {
    match entries.iter_mut().find(|(p, _)| *p == place) {
        Some((_, total)) => *total += amount,
        None => entries.push((place, amount)),
    }
}

/// The largest count a field of `B` bits holds.
const fn field_max<const B: usize>() -> u64 {
    (1u64 << B) - 1
}

/// Reads the count of place `p` from a marking packed `B` bits per place (`B` divides 64, so a
/// field never straddles two words).
#[inline(always)]
fn get<const B: usize>(words: &[u64], p: usize) -> u32 {
    let bit = p * B;
    ((words[bit / 64] >> (bit % 64)) & field_max::<B>()) as u32
}

#[inline(always)]
fn put<const B: usize>(words: &mut [u64], p: usize, value: u32) {
    let bit = p * B;
    let shift = bit % 64;
    let word = &mut words[bit / 64];
    *word = (*word & !(field_max::<B>() << shift)) | (u64::from(value) << shift);
}

/// A 64-bit hash of a packed marking (multiply-rotate word by word, then a final mix).
#[inline]
fn hash_words(words: &[u64]) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut hash = words.len() as u64;
    for &word in words {
        hash = (hash.rotate_left(5) ^ word).wrapping_mul(K);
    }
    hash ^= hash >> 33;
    hash = hash.wrapping_mul(0xFF51_AFD7_ED55_8CCD);
    hash ^ (hash >> 33)
}

/// Markings whose successors are generated, then probed, together.
const BATCH: usize = 64;

/// Packed markings stored back to back, found again through an open-addressing hash table.
struct Store {
    /// Words per marking.
    stride: usize,
    arena: Vec<u64>,
    /// 0: empty; else the low 32 bits of the hash above the marking's index + 1.
    slots: Vec<u64>,
    count: usize,
}

enum Probe {
    Found,
    /// Not stored; the empty slot where it goes.
    Missing(usize),
}

impl Store {
    fn new(stride: usize) -> Store {
        Store {
            stride,
            arena: Vec::new(),
            slots: vec![0; 1024],
            count: 0,
        }
    }

    fn state(&self, index: usize) -> &[u64] {
        &self.arena[index * self.stride..(index + 1) * self.stride]
    }

    #[inline]
    fn probe(&self, key: &[u64], hash: u64) -> Probe {
        let mask = self.slots.len() - 1;
        let tag = hash & 0xFFFF_FFFF;
        let mut slot = hash as usize & mask;
        loop {
            let entry = self.slots[slot];
            if entry == 0 {
                return Probe::Missing(slot);
            }
            if entry >> 32 == tag {
                let index = (entry & 0xFFFF_FFFF) as usize - 1;
                // Markings are a word or a few: a loop beats a call to `memcmp`.
                if self.state(index).iter().zip(key).all(|(a, b)| a == b) {
                    return Probe::Found;
                }
            }
            slot = (slot + 1) & mask;
        }
    }

    /// Stores `key` (probed missing at `slot`); the table must have room (see `reserve`).
    fn insert(&mut self, key: &[u64], hash: u64, slot: usize) {
        self.count += 1;
        self.slots[slot] = ((hash & 0xFFFF_FFFF) << 32) | self.count as u64;
        self.arena.extend_from_slice(key);
    }

    /// Keeps the table at most half full for `more` markings more.
    fn reserve(&mut self, more: usize) {
        let mut len = self.slots.len();
        while (self.count + more) * 2 > len {
            len *= 2;
        }
        if len == self.slots.len() {
            return;
        }
        let mut slots = vec![0u64; len];
        let mask = slots.len() - 1;
        for &entry in self.slots.iter().filter(|&&entry| entry != 0) {
            let mut slot = (entry >> 32) as usize & mask;
            while slots[slot] != 0 {
                slot = (slot + 1) & mask;
            }
            slots[slot] = entry;
        }
        self.slots = slots;
    }
}

/// The reachable markings, explored breadth-first.
struct Explored {
    /// Bits per place.
    bits: usize,
    places: usize,
    states: usize,
    arena: Vec<u64>,
    /// The marking each was first reached from, and by which transition (`u32::MAX` for the
    /// initial marking).
    parent: Vec<u32>,
    via: Vec<u32>,
    dead: Vec<usize>,
    fired: Vec<bool>,
    marked: Vec<bool>,
    truncated: bool,
}

impl Explored {
    fn decode(&self, state: usize) -> Vec<u32> {
        let stride = (self.places * self.bits).div_ceil(64);
        let words = &self.arena[state * stride..(state + 1) * stride];
        let mask = (1u64 << self.bits) - 1;
        (0..self.places)
            .map(|p| {
                let bit = p * self.bits;
                ((words[bit / 64] >> (bit % 64)) & mask) as u32
            })
            .collect()
    }

    /// The transitions fired from the initial marking to `state`.
    fn sequence(&self, mut state: usize) -> Vec<usize> {
        let mut sequence = Vec::new();
        while self.parent[state] != u32::MAX {
            sequence.push(self.via[state] as usize);
            state = self.parent[state] as usize;
        }
        sequence.reverse();
        sequence
    }
}

/// From this many transitions on, the exploration looks only at the transitions fed by the
/// marked places.
const SPARSE_FROM_TRANSITIONS: usize = 128;

/// Breadth-first exploration packing `B` bits per place; `None` when a count does not fit.
/// Counts beyond `u32::MAX` (32 bits) end the exploration as truncated.
fn explore<const B: usize>(net: &Compiled, limit: usize) -> Option<Explored> {
    let places = net.place_names.len();
    let max = field_max::<B>() as i64;
    let stride = (places * B).div_ceil(64);
    let mut store = Store::new(stride);
    let mut next = vec![0u64; stride];
    for (p, &tokens) in net.initial.iter().enumerate() {
        if i64::from(tokens) > max {
            return None;
        }
        put::<B>(&mut next, p, tokens);
    }
    let hash = hash_words(&next);
    if let Probe::Missing(slot) = store.probe(&next, hash) {
        store.insert(&next, hash, slot);
    }
    let mut parent = vec![u32::MAX];
    let mut via = vec![u32::MAX];
    let mut dead = Vec::new();
    let mut fired = vec![false; net.transitions()];
    let mut marked = vec![false; places];
    let mut unmarked = places;
    let mut truncated = false;
    let mut current = vec![0u32; places];
    let mut occupied: Vec<usize> = Vec::new();
    let mut candidates: Vec<u32> = Vec::new();
    let mut listed = vec![false; net.transitions()];
    // Large nets mark few of their places at a time (a mission's places are its steps): only
    // the marked places and the transitions they feed are looked at.
    let sparse = net.transitions() > SPARSE_FROM_TRANSITIONS;
    // The successors of a batch of markings: probing them together lets the memory accesses
    // of the hash table overlap instead of waiting for each other.
    let mut batch_words: Vec<u64> = Vec::new();
    let mut batch: Vec<(u64, u32, u32)> = Vec::new(); // (hash, from, transition)
    let mut state = 0;
    while state < store.count {
        let end = store.count.min(state + BATCH);
        for from in state..end {
            let current_words = store.state(from);
            if !sparse {
                // A small net: decoding every place and trying every transition is cheapest.
                for (p, count) in current.iter_mut().enumerate() {
                    *count = get::<B>(current_words, p);
                }
                if unmarked > 0 {
                    for (p, &count) in current.iter().enumerate() {
                        if count > 0 && !marked[p] {
                            marked[p] = true;
                            unmarked -= 1;
                        }
                    }
                }
                candidates.clear();
                candidates.extend(0..net.transitions() as u32);
            } else {
                // Only the marked places are decoded, found word by word; `current` is zero
                // everywhere else (the previous marking's places are cleared first).
                for &p in &occupied {
                    current[p] = 0;
                }
                occupied.clear();
                for (w, &word) in current_words.iter().enumerate() {
                    if word == 0 {
                        continue;
                    }
                    let first = w * 64 / B;
                    let last = (first + 64 / B).min(places);
                    for (p, slot) in current.iter_mut().enumerate().take(last).skip(first) {
                        let count = get::<B>(current_words, p);
                        if count > 0 {
                            *slot = count;
                            occupied.push(p);
                        }
                    }
                }
                if unmarked > 0 {
                    for &p in &occupied {
                        if !marked[p] {
                            marked[p] = true;
                            unmarked -= 1;
                        }
                    }
                }
                // The transitions that may be enabled, in declaration order (which fixes which
                // firing sequence reaches a marking first).
                candidates.clear();
                for &t in &net.sourceless {
                    listed[t as usize] = true;
                    candidates.push(t);
                }
                for &p in &occupied {
                    for &t in &net.consumers[p] {
                        if !listed[t as usize] {
                            listed[t as usize] = true;
                            candidates.push(t);
                        }
                    }
                }
                candidates.sort_unstable();
            }
            let mut any = false;
            for &t in &candidates {
                let t = t as usize;
                listed[t] = false;
                if !net.enabled(t, &current) {
                    continue;
                }
                any = true;
                fired[t] = true;
                let at = batch_words.len();
                batch_words.extend_from_slice(current_words);
                let next = &mut batch_words[at..];
                let mut fits = true;
                for &(p, delta) in net.effect(t) {
                    let value = i64::from(current[p]) + delta;
                    if value > max {
                        fits = false;
                        break;
                    }
                    put::<B>(next, p, value as u32);
                }
                if !fits {
                    if B >= 32 {
                        truncated = true;
                        batch_words.truncate(at);
                        continue;
                    }
                    return None;
                }
                batch.push((hash_words(next), from as u32, t as u32));
            }
            if !any && !net.is_final(&current) {
                dead.push(from);
            }
        }
        store.reserve(batch.len());
        let mask = store.slots.len() - 1;
        let touched = batch.iter().fold(0u64, |sum, &(hash, _, _)| {
            sum ^ store.slots[hash as usize & mask]
        });
        std::hint::black_box(touched);
        for (k, &(hash, from, t)) in batch.iter().enumerate() {
            let next = &batch_words[k * stride..(k + 1) * stride];
            if let Probe::Missing(slot) = store.probe(next, hash) {
                if store.count >= limit {
                    truncated = true;
                } else {
                    store.insert(next, hash, slot);
                    parent.push(from);
                    via.push(t);
                }
            }
        }
        batch.clear();
        batch_words.clear();
        state = end;
    }
    Some(Explored {
        bits: B,
        places,
        states: store.count,
        arena: store.arena,
        parent,
        via,
        dead,
        fired,
        marked,
        truncated,
    })
}

/// ω in a coverability marking: a count that can grow without limit.
const OMEGA: u32 = u32::MAX;

struct Coverability {
    unbounded: Vec<bool>,
    fired: Vec<bool>,
    marked: Vec<bool>,
    complete: bool,
}

/// The Karp–Miller coverability tree, breadth-first, not expanding a marking already in the
/// tree; at most `limit` nodes.
fn karp_miller(net: &Compiled, limit: usize) -> Coverability {
    let places = net.place_names.len();
    let mut nodes: Vec<Vec<u32>> = vec![net.initial.clone()];
    let mut parent: Vec<usize> = vec![usize::MAX];
    let mut seen: HashSet<Vec<u32>> = HashSet::from([net.initial.clone()]);
    let mut result = Coverability {
        unbounded: vec![false; places],
        fired: vec![false; net.transitions()],
        marked: vec![false; places],
        complete: true,
    };
    let mut node = 0;
    while node < nodes.len() {
        for (p, &count) in nodes[node].iter().enumerate() {
            result.marked[p] |= count > 0;
            result.unbounded[p] |= count == OMEGA;
        }
        for t in 0..net.transitions() {
            if !net.enabled(t, &nodes[node]) {
                continue;
            }
            result.fired[t] = true;
            let mut next = nodes[node].clone();
            for &(p, delta) in net.effect(t) {
                if next[p] != OMEGA {
                    let value = i64::from(next[p]) + delta;
                    next[p] = if value >= i64::from(OMEGA) {
                        OMEGA
                    } else {
                        value as u32
                    };
                }
            }
            // Acceleration: a strictly smaller ancestor means the difference can be pumped.
            let mut ancestor = node;
            while ancestor != usize::MAX {
                let older = &nodes[ancestor];
                if older != &next && older.iter().zip(&next).all(|(a, b)| a <= b) {
                    for (count, &before) in next.iter_mut().zip(older) {
                        if *count > before {
                            *count = OMEGA;
                        }
                    }
                }
                ancestor = parent[ancestor];
            }
            if seen.contains(&next) {
                continue;
            }
            if nodes.len() >= limit {
                result.complete = false;
                return result;
            }
            seen.insert(next.clone());
            nodes.push(next);
            parent.push(node);
        }
        node += 1;
    }
    result
}

/// The classic dining philosophers, `n` of them around a table with `n` forks: philosopher `i`
/// takes fork `i` (on the left), then fork `i + 1 mod n` (on the right), eats, and puts both
/// back. Places `think_i` (1 token), `has_left_i`, `eat_i` and `fork_i` (1 token); transitions
/// `take_left_i`, `take_right_i`, `release_i`: 4n places, 3n transitions.
///
/// For n ≥ 2 it has Q(n) = (1 + √2)ⁿ + (1 − √2)ⁿ reachable markings, the companion Pell numbers
/// 6, 14, 34, 82, 198, ... for n = 2, 3, 4, 5, 6 (each philosopher thinks, holds his left fork
/// or eats, except that philosopher i cannot hold fork i while philosopher i − 1 eats with it),
/// and exactly one dead marking: everyone holds his left fork.
pub fn dining_philosophers(n: usize) -> MissionNet {
    let place = |name: String, tokens: u32| Place {
        name,
        tokens,
        ..Place::default()
    };
    let arc = |place: String| Arc {
        place,
        weight: 1,
        pos: Pos::default(),
    };
    let transition = |name: String, inputs: Vec<Arc>, outputs: Vec<Arc>| Transition {
        name,
        inputs,
        outputs,
        ..Transition::default()
    };
    let mut net = MissionNet {
        name: "philosophers".to_owned(),
        ..MissionNet::default()
    };
    for i in 0..n {
        net.places.push(place(format!("think_{i}"), 1));
        net.places.push(place(format!("has_left_{i}"), 0));
        net.places.push(place(format!("eat_{i}"), 0));
        net.places.push(place(format!("fork_{i}"), 1));
    }
    for i in 0..n {
        let right = (i + 1) % n;
        net.transitions.push(transition(
            format!("take_left_{i}"),
            vec![arc(format!("think_{i}")), arc(format!("fork_{i}"))],
            vec![arc(format!("has_left_{i}"))],
        ));
        net.transitions.push(transition(
            format!("take_right_{i}"),
            vec![arc(format!("has_left_{i}")), arc(format!("fork_{right}"))],
            vec![arc(format!("eat_{i}"))],
        ));
        net.transitions.push(transition(
            format!("release_{i}"),
            vec![arc(format!("eat_{i}"))],
            vec![
                arc(format!("think_{i}")),
                arc(format!("fork_{i}")),
                arc(format!("fork_{right}")),
            ],
        ));
    }
    net
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::net::test_net as net;

    /// The problems the analysis of the mission of `lines` reports.
    fn check(lines: &[&str], limit: usize, expected: &[&str]) {
        let net = net(lines);
        same_by_both_ways(&net, limit);
        let got: Vec<String> = analyse(&net, limit)
            .problems(&net)
            .iter()
            .map(ToString::to_string)
            .collect();
        assert_eq!(got, expected, "for {lines:#?}");
    }

    /// When the one-token shortcut applies, it finds what the general exploration finds.
    fn same_by_both_ways(net: &MissionNet, limit: usize) -> bool {
        let compiled = Compiled::new(net);
        let limit = limit.clamp(1, u32::MAX as usize - 1);
        match single_token_state_machine(&compiled, limit) {
            Some(fast) => {
                assert_eq!(fast, analyse_by_exploration(&compiled, limit));
                true
            }
            None => false,
        }
    }

    #[test]
    fn one_token_nets_take_the_shortcut_with_the_same_findings() {
        let lines = [
            "<place name=\"a\" tokens=\"1\"/><place name=\"b\"/><place name=\"c\"/>",
            "<place name=\"stuck\"/><place name=\"island\"/><place name=\"done\" final=\"true\"/>",
            "<transition name=\"ab\"><input place=\"a\"/><output place=\"b\"/></transition>",
            "<transition name=\"bb\"><input place=\"b\"/><output place=\"b\"/></transition>",
            "<transition name=\"bc\"><input place=\"b\"/><output place=\"c\"/></transition>",
            "<transition name=\"cs\"><input place=\"c\"/><output place=\"stuck\"/></transition>",
            "<transition name=\"cd\"><input place=\"c\"/><output place=\"done\"/></transition>",
            "<transition name=\"back\"><input place=\"done\"/><output place=\"a\"/></transition>",
            "<transition name=\"never\"><input place=\"island\"/><output place=\"a\"/></transition>",
        ];
        let net = net(&lines);
        assert!(same_by_both_ways(&net, 1000));
        let analysis = analyse(&net, 1000);
        assert_eq!(analysis.states, 5);
        assert_eq!(analysis.dead_count, 1);
        assert_eq!(
            analysis.dead_markings[0],
            (
                Marking::from([("stuck".to_owned(), 1)]),
                vec!["ab".into(), "bc".into(), "cs".into()]
            )
        );
        assert_eq!(analysis.never_fired, ["never"]);
        assert_eq!(analysis.never_marked, ["island"]);
        // Too many places for the limit, two tokens, or a token that vanishes: the general way.
        assert!(!same_by_both_ways(&net, 3));
        let mut two = net.clone();
        two.places[1].tokens = 1;
        assert!(!same_by_both_ways(&two, 1000));
        let mut sink = net.clone();
        sink.transitions[3].outputs.clear();
        assert!(!same_by_both_ways(&sink, 1000));
    }

    #[test]
    fn a_clean_mission_chain() {
        let lines = [
            "<place name=\"start\" tokens=\"1\"><module name=\"nav\"/></place>",
            "<place name=\"leg1\"/><place name=\"leg2\"/><place name=\"done\" final=\"true\"/>",
            "<transition name=\"go\"><input place=\"start\"/><output place=\"leg1\"/></transition>",
            "<transition name=\"arrive\" event=\"nav.goal_reached\"><input place=\"leg1\"/><output place=\"leg2\"/></transition>",
            "<transition name=\"timeout\" delay_secs=\"60\"><input place=\"leg1\"/><output place=\"leg2\"/></transition>",
            "<transition name=\"finish\"><input place=\"leg2\"/><output place=\"done\"/></transition>",
        ];
        check(&lines, 1000, &[]);
        let analysis = analyse(&net(&lines), 1000);
        assert_eq!(analysis.states, 4);
        assert!(!analysis.truncated);
    }

    #[test]
    fn a_deadlock_with_its_sequence() {
        check(
            &[
                "<place name=\"start\" tokens=\"1\"/><place name=\"leg1\"/><place name=\"leg2\"/>",
                "<place name=\"done\" final=\"true\"/>",
                "<transition name=\"go\"><input place=\"start\"/><output place=\"leg1\"/></transition>",
                "<transition name=\"arrive\"><input place=\"leg1\"/><output place=\"leg2\"/></transition>",
                "<transition name=\"shortcut\"><input place=\"leg1\"/><output place=\"done\"/></transition>",
            ],
            1000,
            &[
                "2:53: the net can deadlock in marking {leg2: 1} after firing go, arrive (not a final marking)",
            ],
        );
        // Dead at once, and dead with no token left.
        check(
            &[
                "<place name=\"a\" tokens=\"1\"/><place name=\"b\" tokens=\"2\"/>",
                "<transition name=\"t\"><input place=\"a\" weight=\"2\"/><output place=\"b\"/></transition>",
            ],
            1000,
            &[
                "2:1: the net can deadlock in its initial marking {a: 1, b: 2} (not a final marking)",
                "3:1: transition `t` can never fire",
            ],
        );
        check(
            &[
                "<place name=\"a\" tokens=\"1\"/>",
                "<transition name=\"eat\"><input place=\"a\"/></transition>",
            ],
            1000,
            &["1:1: the net can deadlock in marking {} after firing eat (not a final marking)"],
        );
    }

    #[test]
    fn dead_transitions_and_places_never_marked() {
        check(
            &[
                "<place name=\"a\" tokens=\"1\"/><place name=\"b\"/><place name=\"orphan\"/>",
                "<place name=\"done\" final=\"true\"/>",
                "<transition name=\"t\"><input place=\"a\"/><output place=\"done\"/></transition>",
                "<transition name=\"never\"><input place=\"orphan\"/><output place=\"b\"/></transition>",
                "<transition name=\"also_never\"><input place=\"a\"/><input place=\"b\"/><output place=\"done\"/></transition>",
            ],
            1000,
            &[
                "2:29: place `b` is never marked",
                "2:46: place `orphan` is never marked",
                "5:1: transition `never` can never fire",
                "6:1: transition `also_never` can never fire",
            ],
        );
    }

    #[test]
    fn unbounded_places() {
        let lines = [
            "<place name=\"loop\" tokens=\"1\"/><place name=\"pile\"/><place name=\"pile2\"/>",
            "<place name=\"bounded\"/><place name=\"unused\"/>",
            "<transition name=\"produce\" event=\"a.b\"><input place=\"loop\"/><output place=\"loop\"/><output place=\"pile\" weight=\"2\"/></transition>",
            "<transition name=\"move\"><input place=\"pile\" weight=\"3\"/><output place=\"pile2\"/></transition>",
            "<transition name=\"flip\"><input place=\"loop\"/><output place=\"bounded\"/></transition>",
            "<transition name=\"flop\"><input place=\"bounded\"/><output place=\"loop\"/></transition>",
            "<transition name=\"dead\"><input place=\"unused\"/><output place=\"loop\"/></transition>",
        ];
        check(
            &lines,
            100,
            &[
                "1:1: the analysis stopped at its limit of 100 markings: the net may deadlock in markings not explored",
                "2:32: place `pile` is unbounded: its tokens can grow without limit",
                "2:52: place `pile2` is unbounded: its tokens can grow without limit",
                "3:24: place `unused` is never marked",
                "8:1: transition `dead` can never fire",
            ],
        );
        let analysis = analyse(&net(&lines), 100);
        assert_eq!(analysis.states, 100);
        assert!(analysis.truncated && !analysis.coverability_truncated);
        // With a coverability tree larger than the limit too, only what is certain is said.
        let analysis = analyse(&net(&lines), 3);
        assert!(analysis.truncated && analysis.coverability_truncated);
        assert!(analysis.never_fired.is_empty() && analysis.never_marked.is_empty());
        assert_eq!(
            analysis.problems(&net(&lines)).first().map(ToString::to_string),
            Some(
                "1:1: the analysis stopped at its limit of 3 markings: the net may deadlock in markings not explored; transitions that can never fire and places never marked were not searched, and more places may be unbounded"
                    .to_owned()
            )
        );
    }

    #[test]
    fn a_bounded_net_larger_than_the_limit() {
        // The coverability tree of a bounded net holds every reachable marking: it stops at
        // the limit too, and only what is certain is said.
        let analysis = analyse(&dining_philosophers(6), 50);
        assert!(analysis.truncated && analysis.coverability_truncated);
        assert!(analysis.unbounded.is_empty());
        assert!(analysis.never_fired.is_empty() && analysis.never_marked.is_empty());
        assert_eq!(analysis.dead_count, 0, "the deadlock is deeper");
    }

    #[test]
    fn counts_outgrowing_a_byte_and_two() {
        // 300 and then 70000 tokens: the exploration widens its storage and starts over.
        for (tokens, weight) in [
            (300u32, 100u32),
            (70_000, 10_000),
            (4_000_000_000, 1_000_000_000),
        ] {
            let lines = [
                format!(
                    "<place name=\"a\" tokens=\"{tokens}\"/><place name=\"b\" final=\"true\"/>"
                ),
                format!(
                    "<transition name=\"t\"><input place=\"a\" weight=\"{weight}\"/><output place=\"b\" weight=\"{weight}\"/></transition>"
                ),
            ];
            let lines: Vec<&str> = lines.iter().map(String::as_str).collect();
            let analysis = analyse(&net(&lines), 1000);
            assert_eq!(analysis.states as u32, tokens / weight + 1, "{tokens}");
            assert!(analysis.problems(&net(&lines)).is_empty());
        }
        // From 200 to 300 while exploring.
        let analysis = analyse(
            &net(&[
                "<place name=\"a\" tokens=\"200\"/><place name=\"b\" final=\"true\"/>",
                "<transition name=\"t\"><input place=\"a\" weight=\"100\"/><output place=\"b\" weight=\"150\"/></transition>",
            ]),
            1000,
        );
        assert_eq!(analysis.states, 3);
        // Beyond 4 bytes: the exploration stops, coverability calls it unbounded.
        let analysis = analyse(
            &net(&[
                "<place name=\"a\" tokens=\"4000000000\"/>",
                "<transition name=\"t\"><input place=\"a\"/><output place=\"a\" weight=\"1000000000\"/></transition>",
            ]),
            1000,
        );
        assert!(analysis.truncated);
        assert_eq!(analysis.unbounded, ["a"]);
    }

    #[test]
    fn dining_philosophers_state_counts() {
        // Companion Pell numbers; 2 philosophers by hand: TT TL LT LL TE ET.
        for (n, states) in [(2, 6), (3, 14), (4, 34), (5, 82), (10, 6726)] {
            let net = dining_philosophers(n);
            assert_eq!(net.places.len(), 4 * n);
            assert_eq!(net.transitions.len(), 3 * n);
            let analysis = analyse(&net, 1_000_000);
            assert_eq!(analysis.states, states, "{n} philosophers");
            let closed_form =
                (1.0 + 2f64.sqrt()).powi(n as i32) + (1.0 - 2f64.sqrt()).powi(n as i32);
            assert_eq!(closed_form.round() as usize, states);
            assert!(!analysis.truncated);
            assert!(analysis.never_fired.is_empty() && analysis.never_marked.is_empty());
            assert!(analysis.unbounded.is_empty());
            // The one deadlock: everyone holds the left fork.
            assert_eq!(analysis.dead_count, 1);
            let (marking, sequence) = &analysis.dead_markings[0];
            let expected: Marking = (0..n).map(|i| (format!("has_left_{i}"), 1)).collect();
            assert_eq!(marking, &expected);
            let expected: Vec<String> = (0..n).map(|i| format!("take_left_{i}")).collect();
            assert_eq!(sequence, &expected);
        }
        // The generated net is a valid mission.
        let net = dining_philosophers(3);
        let again = MissionNet::parse(&net.to_xml()).expect("valid");
        assert_eq!(again.without_positions(), net);
        assert_eq!(
            analyse(&net, 1000)
                .problems(&net)
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>(),
            [
                "0:0: the net can deadlock in marking {has_left_0: 1, has_left_1: 1, has_left_2: 1} after firing take_left_0, take_left_1, take_left_2 (not a final marking)"
            ]
        );
    }

    #[test]
    fn the_limit_cuts_the_exploration() {
        let analysis = analyse(&dining_philosophers(5), 10);
        assert_eq!(analysis.states, 10);
        assert!(analysis.truncated);
        let analysis = analyse(&dining_philosophers(5), 0);
        assert_eq!(analysis.states, 1);
    }

    #[test]
    fn odd_nets_do_not_panic() {
        let empty = MissionNet::default();
        let analysis = analyse(&empty, 10);
        assert_eq!(analysis.states, 1);
        assert_eq!(analysis.dead_count, 1);
        assert_eq!(
            analysis.problems(&empty)[0].to_string(),
            "0:0: the net can deadlock in its initial marking {} (not a final marking)"
        );
        // Arcs to unknown places, a transition without inputs, no places at all.
        let mut odd = dining_philosophers(2);
        odd.transitions[0].inputs[0].place = "nowhere".into();
        odd.transitions[1].outputs[0].place = "nowhere".into();
        odd.transitions[2].inputs.clear();
        let analysis = analyse(&odd, 1000);
        assert!(analysis.never_fired.contains(&"take_left_0".to_owned()));
        assert!(analysis.truncated, "release_0 without inputs pumps forks");
        let mut no_places = MissionNet::default();
        no_places.transitions.push(Transition {
            name: "t".into(),
            inputs: vec![Arc {
                place: "x".into(),
                weight: 1,
                pos: Pos::default(),
            }],
            ..Transition::default()
        });
        assert_eq!(analyse(&no_places, 10).never_fired, ["t"]);
    }
}
