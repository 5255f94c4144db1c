//! Missions as Petri nets: the model, its XML form, the checks against a system, an engine that
//! plays the net in time, a state-space analysis and the PNML (ISO/IEC 15909-2) exchange format.
//!
//! A **place** is an action: the modules that run while it holds a token and the parameter values
//! they get while it does. A **transition** moves tokens from its input places to its output
//! places when its inputs hold enough tokens (it is *enabled*) and its condition holds: a delay
//! since it became enabled, an absolute date, an event reported by a module, or all of those that
//! are given. Among transitions that can fire at once, the highest priority goes first, then the
//! one declared first.
//!
//! ```xml
//! <mission name="patrol" system="system.xml">
//!   <place name="leg1" tokens="1">
//!     <module name="nav"/>
//!     <param module="nav" name="goal_x" value="10"/>
//!   </place>
//!   <place name="done" final="true"/>
//!   <transition name="arrive" priority="0" event="nav.goal_reached" delay_secs="2">
//!     <input place="leg1"/>
//!     <output place="done" weight="1"/>
//!   </transition>
//! </mission>
//! ```
//!
//! Places and transitions share one set of names (as in PNML, where they are ids). Events are
//! `MODULE.EVENT`, or `module.ID.failed`, which the runtime reports when module `ID` dies for good.
//! A transition marked `operator="true"` waits for an operator to fire it by hand.
//! The schema is `assets/schema/mission.xsd`.
//!
//! Everything here is pure: texts in, values and problems out; time is always a parameter.

use std::collections::{BTreeMap, BTreeSet};

use armor_module_api::describe::is_identifier;
use armor_module_api::xml::{Located, Pos};

use crate::fields::{Field, is_decimal, listing};

pub mod analysis;
mod check;
mod date;
pub mod engine;
pub mod pnml;
pub(crate) mod xml;

pub use analysis::{Analysis, analyse, dining_philosophers};
pub use check::check_names;
pub use date::{format_rfc3339, parse_rfc3339};
pub use engine::{CompiledNet, Engine, EngineError, Firing, MAX_FIRINGS_PER_STEP, MarkedPlaces};
pub use pnml::{CORE_MODEL_TYPE, PNML_NAMESPACE, PTNET_TYPE, from_pnml, read_pnml, to_pnml};

/// Tokens per place, naming only the places that hold some.
pub type Marking = BTreeMap<String, u32>;

/// A marking as the command line and the studio show it: `{a, b×2}` (a place with one token
/// by its name alone).
pub fn marking_text(marking: &Marking) -> String {
    let places: Vec<String> = marking
        .iter()
        .map(|(place, tokens)| match tokens {
            1 => place.clone(),
            _ => format!("{place}×{tokens}"),
        })
        .collect();
    format!("{{{}}}", places.join(", "))
}

/// A whole mission: a Petri net whose places run modules.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MissionNet {
    pub name: String,
    /// Path of the system file, relative to the mission file; empty when the mission names none.
    pub system: String,
    pub places: Vec<Place>,
    pub transitions: Vec<Transition>,
    /// The `<mission>` (or PNML `<net>`) element.
    pub pos: Pos,
}

/// An action: the modules that run while the place holds a token.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Place {
    pub name: String,
    /// Module instances (names in the system) that run while the place is marked.
    pub modules: Vec<String>,
    /// Parameter values the modules get while the place is marked.
    pub params: Vec<PlaceParam>,
    /// Tokens in the initial marking.
    pub tokens: u32,
    /// A marking that marks a final place ends the mission successfully.
    pub is_final: bool,
    pub pos: Pos,
}

/// A parameter value a place gives to one of its modules.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlaceParam {
    pub module: String,
    pub name: String,
    pub value: String,
    pub pos: Pos,
}

#[derive(Clone, Debug, Default, PartialEq)]
pub struct Transition {
    pub name: String,
    /// Among transitions that can fire at the same time, the highest priority fires first.
    pub priority: i32,
    pub condition: Condition,
    pub inputs: Vec<Arc>,
    pub outputs: Vec<Arc>,
    pub pos: Pos,
}

/// When an enabled transition fires: every part given must hold; with none, it fires at once.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Condition {
    /// Seconds since the transition became enabled.
    pub delay_secs: Option<f64>,
    /// An absolute date, in seconds since 1970-01-01T00:00:00Z.
    pub at_unix_secs: Option<f64>,
    /// `MODULE.EVENT` or `module.ID.failed`, reported while the transition is enabled.
    pub event: Option<String>,
    /// Only an operator fires the transition (by hand, `armor ctl fire NAME`): a choice left to
    /// a person, such as resuming a leg after the robot was held.
    pub operator: bool,
}

impl Condition {
    /// `true` when the condition has no part: the transition fires as soon as it is enabled.
    pub fn is_empty(&self) -> bool {
        self.delay_secs.is_none()
            && self.at_unix_secs.is_none()
            && self.event.is_none()
            && !self.operator
    }
}

/// An arc between a place and a transition (the direction is given by the list holding it).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Arc {
    pub place: String,
    /// Tokens taken (input) or put (output) when the transition fires; 1 or more.
    pub weight: u32,
    pub pos: Pos,
}

/// What an event name designates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EventRef<'a> {
    /// `MODULE.EVENT`: an event the module reports.
    Module { module: &'a str, event: &'a str },
    /// `module.ID.failed`: the runtime reports that module `ID` died for good.
    Failed { module: &'a str },
    /// `link.lost.SECS`: the run reports that the robot has not heard its operator for `SECS`
    /// seconds (the team bridge tells it when the link is lost), once per outage.
    LinkLost { after_secs: u32 },
}

/// The event the run reports once its robot has not heard its operator for `after_secs`.
pub fn link_lost_event(after_secs: u32) -> String {
    format!("link.lost.{after_secs}")
}

impl<'a> EventRef<'a> {
    /// Splits `MODULE.EVENT`, `module.ID.failed` or `link.lost.SECS`; `None` for anything else.
    pub fn parse(name: &'a str) -> Option<EventRef<'a>> {
        let parts: Vec<&str> = name.split('.').collect();
        match parts.as_slice() {
            [module, event] if is_identifier(module) && is_identifier(event) => {
                Some(EventRef::Module { module, event })
            }
            ["module", module, "failed"] if is_identifier(module) => {
                Some(EventRef::Failed { module })
            }
            ["link", "lost", secs] => secs
                .parse()
                .ok()
                .filter(|secs| *secs >= 1 && link_lost_event(*secs) == name)
                .map(|after_secs| EventRef::LinkLost { after_secs }),
            _ => None,
        }
    }
}

impl MissionNet {
    /// The place called `name` (the first one, if it is defined twice).
    pub fn place(&self, name: &str) -> Option<&Place> {
        self.places.iter().find(|place| place.name == name)
    }

    /// The transition called `name` (the first one, if it is defined twice).
    pub fn transition(&self, name: &str) -> Option<&Transition> {
        self.transitions
            .iter()
            .find(|transition| transition.name == name)
    }

    /// The initial marking: the places with tokens.
    pub fn initial_marking(&self) -> Marking {
        let mut marking = Marking::new();
        for place in &self.places {
            if place.tokens > 0 {
                *marking.entry(place.name.clone()).or_default() += place.tokens;
            }
        }
        marking
    }

    /// The same net with every position set to the default (0:0): two nets that differ only by
    /// where they were read from compare equal this way.
    pub fn without_positions(&self) -> MissionNet {
        let zero = Pos::default();
        let mut net = self.clone();
        net.pos = zero;
        for place in &mut net.places {
            place.pos = zero;
            for param in &mut place.params {
                param.pos = zero;
            }
        }
        for transition in &mut net.transitions {
            transition.pos = zero;
            for arc in transition.inputs.iter_mut().chain(&mut transition.outputs) {
                arc.pos = zero;
            }
        }
        net
    }
}

/// A whole number of tokens as XSD's `xs:unsignedInt` writes it (and xmllint reads it): digits
/// only, no sign, no surrounding space.
fn whole_number(text: &str) -> Option<u32> {
    if !text.is_empty() && text.bytes().all(|b| b.is_ascii_digit()) {
        text.parse().ok()
    } else {
        None
    }
}

pub(crate) fn read_tokens(field: Field<'_>) -> Result<u32, Located> {
    whole_number(field.value).ok_or_else(|| {
        Located::new(
            field.pos,
            format!(
                "the number of tokens must be a whole number, 0 or more, not `{}`",
                field.value
            ),
        )
    })
}

pub(crate) fn read_weight(field: Field<'_>) -> Result<u32, Located> {
    match whole_number(field.value) {
        Some(weight) if weight > 0 => Ok(weight),
        _ => Err(Located::new(
            field.pos,
            format!(
                "the weight of an arc must be a whole number of tokens, 1 or more, not `{}`",
                field.value
            ),
        )),
    }
}

/// A priority as XSD's `xs:int` writes it (and xmllint reads it): an optional sign and digits.
pub(crate) fn read_priority(field: Field<'_>) -> Result<i32, Located> {
    let digits = field.value.strip_prefix(['+', '-']).unwrap_or(field.value);
    let valid = !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit());
    valid
        .then(|| field.value.parse::<i32>().ok())
        .flatten()
        .ok_or_else(|| {
            Located::new(
                field.pos,
                format!(
                    "`priority` must be a whole number (higher fires first), not `{}`",
                    field.value
                ),
            )
        })
}

pub(crate) fn read_delay(field: Field<'_>) -> Result<f64, Located> {
    let text = field.value.trim();
    match text.parse::<f64>() {
        Ok(delay) if is_decimal(text) && delay.is_finite() && delay >= 0.0 => Ok(delay),
        _ => Err(Located::new(
            field.pos,
            format!(
                "`delay_secs` must be a number of seconds, 0 or more (like 2 or 0.5), not `{}`",
                field.value
            ),
        )),
    }
}

pub(crate) fn read_date(field: Field<'_>) -> Result<f64, Located> {
    date::parse_rfc3339(field.value.trim()).map_err(|why| {
        Located::new(
            field.pos,
            format!(
                "`at` must be a date like 2026-11-22T20:00:00Z or 2026-11-22T21:00:00+01:00, not `{}`: {why}",
                field.value
            ),
        )
    })
}

pub(crate) fn read_event(field: Field<'_>) -> Result<String, Located> {
    match EventRef::parse(field.value) {
        Some(_) => Ok(field.value.to_owned()),
        None => Err(Located::new(
            field.pos,
            format!(
                "`event` must be MODULE.EVENT, or module.ID.failed for the failure of module ID, not `{}`",
                field.value
            ),
        )),
    }
}

pub(crate) fn read_final(field: Field<'_>) -> Result<bool, Located> {
    read_bool(field, "final")
}

pub(crate) fn read_operator(field: Field<'_>) -> Result<bool, Located> {
    read_bool(field, "operator")
}

fn read_bool(field: Field<'_>, what: &str) -> Result<bool, Located> {
    match field.value.trim() {
        "true" => Ok(true),
        "false" => Ok(false),
        _ => Err(Located::new(
            field.pos,
            format!("`{what}` must be `true` or `false`, not `{}`", field.value),
        )),
    }
}

/// Writes a transition's priority (unless 0) and condition as attributes, each
/// ` name="value"`, in the order both formats give them: the mission XML's `<transition>` and
/// the `<condition>` of PNML's tool-specific data.
pub(crate) fn write_condition_attrs(out: &mut String, priority: i32, condition: &Condition) {
    use std::fmt::Write as _;
    if priority != 0 {
        let _ = write!(out, " priority=\"{priority}\"");
    }
    if let Some(event) = &condition.event {
        let _ = write!(out, " event=\"{}\"", crate::fields::escape(event));
    }
    if let Some(delay) = condition.delay_secs {
        let _ = write!(out, " delay_secs=\"{delay}\"");
    }
    if let Some(at) = condition.at_unix_secs {
        let _ = write!(out, " at=\"{}\"", format_date(at));
    }
    if condition.operator {
        out.push_str(" operator=\"true\"");
    }
}

/// Writes a date in the form [`read_date`] reads, in UTC.
pub(crate) fn format_date(unix_secs: f64) -> String {
    date::format_rfc3339(unix_secs)
}

/// The problems of a net read from any format that its fields alone do not show: names used
/// twice, arcs to unknown places or given twice, transitions without input, parameters of
/// modules the place does not run. Every reader runs it on the net it built.
pub(crate) fn check_structure(net: &MissionNet, problems: &mut Vec<Located>) {
    // Places and transitions share one set of names: PNML ids and SNAKES need it.
    let mut names: BTreeMap<&str, (&str, Pos)> = BTreeMap::new();
    let nodes = net
        .places
        .iter()
        .map(|place| ("place", place.name.as_str(), place.pos))
        .chain(
            net.transitions
                .iter()
                .map(|transition| ("transition", transition.name.as_str(), transition.pos)),
        );
    for (kind, name, pos) in nodes {
        if name.is_empty() {
            continue;
        }
        match names.get(name) {
            Some((first_kind, first_pos)) => problems.push(Located::new(
                pos,
                format!(
                    "{kind} `{name}`: the name is already used by the {first_kind} at line {} \
                     (places and transitions need distinct names)",
                    first_pos.line
                ),
            )),
            None => {
                names.insert(name, (kind, pos));
            }
        }
    }
    let places: BTreeSet<&str> = net.places.iter().map(|place| place.name.as_str()).collect();
    for place in &net.places {
        let mut params: BTreeMap<(&str, &str), Pos> = BTreeMap::new();
        for param in &place.params {
            if !param.module.is_empty() && !place.modules.contains(&param.module) {
                problems.push(Located::new(
                    param.pos,
                    format!(
                        "place `{}` sets parameter `{}` of module `{}`, which it does not run \
                         (add <module name=\"{}\"/> to the place)",
                        place.name, param.name, param.module, param.module
                    ),
                ));
            }
            match params.get(&(param.module.as_str(), param.name.as_str())) {
                Some(first) => problems.push(Located::new(
                    param.pos,
                    format!(
                        "place `{}` already sets parameter `{}` of module `{}` (line {})",
                        place.name, param.name, param.module, first.line
                    ),
                )),
                None => {
                    params.insert((&param.module, &param.name), param.pos);
                }
            }
        }
    }
    for transition in &net.transitions {
        if transition.inputs.is_empty() {
            problems.push(Located::new(
                transition.pos,
                format!(
                    "transition `{}` has no input arc: it would always be enabled and fire \
                     forever (give it an <input place=\"...\"/>)",
                    transition.name
                ),
            ));
        }
        for (arcs, direction) in [
            (&transition.inputs, "an input arc from"),
            (&transition.outputs, "an output arc to"),
        ] {
            let mut seen: BTreeMap<&str, Pos> = BTreeMap::new();
            for arc in arcs {
                if arc.place.is_empty() {
                    continue;
                }
                if !places.contains(arc.place.as_str()) {
                    problems.push(Located::new(
                        arc.pos,
                        format!(
                            "transition `{}`: no place `{}` (places: {})",
                            transition.name,
                            arc.place,
                            listing(places.iter().copied())
                        ),
                    ));
                }
                match seen.get(arc.place.as_str()) {
                    Some(first) => problems.push(Located::new(
                        arc.pos,
                        format!(
                            "transition `{}` already has {direction} place `{}` (line {}); \
                             give one arc with a weight",
                            transition.name, arc.place, first.line
                        ),
                    )),
                    None => {
                        seen.insert(&arc.place, arc.pos);
                    }
                }
            }
        }
    }
}

/// A mission named `m` made of the given lines of XML, for tests; panics with the problems.
#[cfg(test)]
pub(crate) fn test_net(lines: &[&str]) -> MissionNet {
    let mut xml = String::from("<mission name=\"m\">\n");
    for line in lines {
        xml.push_str(line);
        xml.push('\n');
    }
    xml.push_str("</mission>");
    MissionNet::parse(&xml).unwrap_or_else(|problems| {
        panic!(
            "{:?}",
            problems.iter().map(ToString::to_string).collect::<Vec<_>>()
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn event_names() {
        assert_eq!(
            EventRef::parse("nav.goal_reached"),
            Some(EventRef::Module {
                module: "nav",
                event: "goal_reached"
            })
        );
        assert_eq!(
            EventRef::parse("module.nav.failed"),
            Some(EventRef::Failed { module: "nav" })
        );
        // A module called `module` reporting `failed` is an ordinary event.
        assert_eq!(
            EventRef::parse("module.failed"),
            Some(EventRef::Module {
                module: "module",
                event: "failed"
            })
        );
        for bad in [
            "",
            "nav",
            "nav.",
            ".x",
            "a.b.c",
            "module.nav.died",
            "module.9.failed",
            "a b.c",
        ] {
            assert_eq!(EventRef::parse(bad), None, "{bad}");
        }
    }

    #[test]
    fn decimals() {
        for good in ["0", "2", "0.5", ".5", "5.", "+1", "-0", "007.250"] {
            assert!(is_decimal(good), "{good}");
        }
        for bad in ["", ".", "+", "1e3", "inf", "NaN", "1.2.3", "0x10", " 1"] {
            assert!(!is_decimal(bad), "{bad}");
        }
    }
}
