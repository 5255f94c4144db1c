//! Moving a running mission to an updated plan (`armor ctl update`): where the robot stands in
//! the net of the plan it runs (the marked place, and the leg it comes from), and where that
//! puts it in the net of the new plan, or why the update cannot be taken.
//!
//! Legs are matched **by name**, never by position: the legs done (those before the leg in
//! force, in the running plan's order) must be, by name and in the same order, the first legs
//! of the new plan, and the leg in force must follow them there. So the legs done and the leg in
//! force keep their positions, and a leg with no name of its own (`legN`, after its position)
//! is matched as safely as a named one; the legs after it are free (added, removed, reordered,
//! changed). The marked place keeps its name in the new net, but for two that the new plan
//! may no longer have: `LEG_depart` (the appointment was removed) becomes `LEG_drive`, and
//! `LEG_drive_late` always becomes `LEG_drive` so that the leg's deadline is judged again
//! against the run's clock by the new net's own `LEG_late`. Pure: the caller plays the result
//! ([`crate::net::Engine::resume`]).

use std::collections::{BTreeMap, BTreeSet};

use crate::net::{Marking, MissionNet, Place};

use super::{Compiled, Origin, Plan};

/// Where a running mission goes in the net of an updated plan.
#[derive(Clone, Debug, PartialEq)]
pub struct Migration {
    /// The marking of the new net to resume in.
    pub marking: Marking,
    /// The legs done (or skipped), by name, in order: the first legs of both plans.
    pub done: Vec<String>,
    /// The leg in force: its name, its index in the new plan, the place marked before and
    /// after.
    pub leg: String,
    pub index: usize,
    pub place_before: String,
    pub place_after: String,
    /// Whether the marked place runs other modules or parameters in the new net (a path
    /// planned again, a goal moved): the leg is then replaced at once, and the events latched
    /// under the old one no longer count.
    pub changed: bool,
}

/// Why an update cannot be taken; the running mission goes on unchanged. Every rule is listed
/// in `docs/plans.md` (section "Updates to a running mission").
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Refusal {
    /// No marked place comes from a leg: the mission has ended, or returns to a waypoint after
    /// its last leg.
    #[error("the mission is in no leg ({marking}): there is nothing left to update")]
    NotInALeg { marking: String },
    /// Marked places come from several legs (a net drawn by hand): which leg is in force is
    /// ambiguous.
    #[error(
        "the marking ({marking}) is in several legs at once: which one is in force is ambiguous"
    )]
    SeveralLegs { marking: String },
    /// The new plan has no leg of the name of the leg in force.
    #[error(
        "the update removes leg `{leg}`, which is in force (in `{place}`): keep a leg of that name, or abort the mission"
    )]
    LegInForceRemoved { leg: String, place: String },
    /// The legs done are not the first legs of the new plan, by name and in order.
    #[error(
        "the legs done ({done}) must be, by name and in this order, the first legs of the update, followed by `{leg}` in force; the update has {found} before it"
    )]
    DoneLegsDiffer {
        done: String,
        leg: String,
        found: String,
    },
    /// The new net has no counterpart of the marked place.
    #[error(
        "leg `{leg}` is in `{place}`, which the update does not have ({why}): the leg cannot go on from there"
    )]
    PlaceGone {
        leg: String,
        place: String,
        why: String,
    },
}

/// Where a mission of `old_plan` (compiled as `old`) in `marking` goes in `new_plan` (compiled
/// as `new`), or why it cannot.
pub fn migrate(
    old_plan: &Plan,
    old: &Compiled,
    marking: &Marking,
    new_plan: &Plan,
    new: &Compiled,
) -> Result<Migration, Refusal> {
    let marking_text = || crate::net::marking_text(marking);
    let legs: BTreeSet<usize> = marking
        .iter()
        .filter(|(_, tokens)| **tokens > 0)
        .filter_map(|(place, _)| match old.trace.get(place) {
            Some(Origin::Leg(index)) => Some(*index),
            _ => None,
        })
        .collect();
    let in_final = marking
        .keys()
        .any(|place| old.net.place(place).is_some_and(|place| place.is_final));
    let index_before = match (legs.len(), in_final) {
        (1, false) => legs.first().copied().unwrap_or_default(),
        (0, _) | (_, true) => {
            return Err(Refusal::NotInALeg {
                marking: marking_text(),
            });
        }
        _ => {
            return Err(Refusal::SeveralLegs {
                marking: marking_text(),
            });
        }
    };
    let Some(leg) = old_plan.legs.get(index_before) else {
        return Err(Refusal::NotInALeg {
            marking: marking_text(),
        });
    };
    let place_before = marking
        .keys()
        .find(|place| old.trace.get(*place) == Some(&Origin::Leg(index_before)))
        .cloned()
        .unwrap_or_default();
    let Some(index) = new_plan.legs.iter().position(|new| new.name == leg.name) else {
        return Err(Refusal::LegInForceRemoved {
            leg: leg.name.clone(),
            place: place_before,
        });
    };
    let done: Vec<String> = old_plan.legs[..index_before]
        .iter()
        .map(|leg| leg.name.clone())
        .collect();
    let before_in_new: Vec<String> = new_plan.legs[..index]
        .iter()
        .map(|leg| leg.name.clone())
        .collect();
    if done != before_in_new {
        let names = |names: &[String]| {
            if names.is_empty() {
                "none".to_owned()
            } else {
                names
                    .iter()
                    .map(|name| format!("`{name}`"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        };
        return Err(Refusal::DoneLegsDiffer {
            done: names(&done),
            leg: leg.name.clone(),
            found: names(&before_in_new),
        });
    }
    let place_after =
        counterpart(&leg.name, &place_before, index, new).ok_or_else(|| Refusal::PlaceGone {
            leg: leg.name.clone(),
            place: place_before.clone(),
            why: gone_why(&leg.name, &place_before),
        })?;
    let changed = match (old.net.place(&place_before), new.net.place(&place_after)) {
        (Some(before), Some(after)) => !same_work(before, after),
        _ => true,
    };
    let tokens = marking.get(&place_before).copied().unwrap_or(1);
    Ok(Migration {
        marking: [(place_after.clone(), tokens)].into(),
        done,
        leg: leg.name.clone(),
        index,
        place_before,
        place_after,
        changed,
    })
}

/// The place of the new net that stands for `place` of leg `leg` (at `index` in the new plan):
/// the same name, from the same leg; `LEG_drive_late` is taken back to `LEG_drive` (the new
/// net's `LEG_late` judges the deadline again), `LEG_depart` goes on to `LEG_drive` when the
/// appointment is gone.
fn counterpart(leg: &str, place: &str, index: usize, new: &Compiled) -> Option<String> {
    let of_leg = |name: &str| {
        (new.trace.get(name) == Some(&Origin::Leg(index)) && new.net.place(name).is_some())
            .then(|| name.to_owned())
    };
    let drive = format!("{leg}_drive");
    if place == format!("{leg}_drive_late") {
        return of_leg(&drive).or_else(|| of_leg(place));
    }
    of_leg(place).or_else(|| (place == format!("{leg}_depart")).then(|| of_leg(&drive))?)
}

/// Why the new plan has no counterpart of `place`, in words.
fn gone_why(leg: &str, place: &str) -> String {
    let part = place.strip_prefix(leg).unwrap_or(place);
    match part {
        "_hold" => "the leg no longer holds for the operator on that contingency".to_owned(),
        "_wait" => "the leg no longer waits at its destination".to_owned(),
        "_return" => "the leg no longer returns on that contingency".to_owned(),
        part if part.starts_with("_arrival") => {
            "the leg's arrival action, or that way of doing it, is gone".to_owned()
        }
        part if part.starts_with("_drive") => {
            "that alternative way of driving the leg is gone".to_owned()
        }
        _ => "no place of that name comes from the leg".to_owned(),
    }
}

/// Whether two places run the same modules with the same parameters.
fn same_work(a: &Place, b: &Place) -> bool {
    fn modules(place: &Place) -> BTreeSet<&String> {
        place.modules.iter().collect()
    }
    fn params(place: &Place) -> BTreeSet<(&String, &String, &String)> {
        place
            .params
            .iter()
            .map(|param| (&param.module, &param.name, &param.value))
            .collect()
    }
    modules(a) == modules(b) && params(a) == params(b)
}

/// Sets `module`'s `param` in every place of `net` that comes from leg `index` (by `trace`)
/// and sets it, to what `value` gives for the place's name (nothing: left as it is). A leg's
/// drive places, late or by an alternative way, give the navigation module its `path`: this is
/// how a leg replaced under way gets the path planned from where the robot is, and how a leg
/// that goes on unchanged keeps the path the run gave it.
pub fn set_leg_param(
    net: &mut MissionNet,
    trace: &BTreeMap<String, Origin>,
    index: usize,
    (module, param): (&str, &str),
    value: impl Fn(&str) -> Option<String>,
) {
    for place in &mut net.places {
        if trace.get(&place.name) != Some(&Origin::Leg(index)) {
            continue;
        }
        let Some(value) = value(&place.name) else {
            continue;
        };
        for given in &mut place.params {
            if given.module == module && given.name == param {
                given.value.clone_from(&value);
            }
        }
    }
}

/// The value of `module`'s `param` in the place `place` of `net`, if it sets one.
pub fn param_of(net: &MissionNet, place: &str, (module, param): (&str, &str)) -> Option<String> {
    net.place(place)?
        .params
        .iter()
        .find(|given| given.module == module && given.name == param)
        .map(|given| given.value.clone())
}

#[cfg(test)]
mod tests;
