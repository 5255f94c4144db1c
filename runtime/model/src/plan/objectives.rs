//! A plan's objectives (`<objectives>`): what the operator wants done rather than the route to
//! do it, for `armor plan` to order and time (the constraint planner, `armor_autoplan`).
//!
//! ```xml
//! <objectives from="home" to="home" max_distance_m="400" max_secs="900">
//!   <objective name="gate_look" at="gate" priority="3" not_before="2026-11-23T08:01:00Z"
//!              by="2026-11-23T08:04:00Z">
//!     <arrival for_secs="30"><module name="observer"/></arrival>
//!   </objective>
//!   <objective name="north_post" lat="43.5616439" lon="1.4693909" optional="true"
//!              due="2026-11-23T08:06:00Z" wait_secs="5"/>
//!   <precedence first="gate_look" then="north_post"/>
//! </objectives>
//! ```
//!
//! An objective is a place (a waypoint it names with `at`, or its own `lat`/`lon`) and what to
//! do there (an `<arrival>` action, as a leg's, whose `for_secs` bounds how long it takes, and
//! `wait_secs` to stay after it). Its window: `not_before` (arrive no earlier), `by` (arrive
//! no later: a hard limit) and `due` (arrive by, or count the lateness: a soft one). Its
//! `priority` (1 by default) weighs it when not everything fits; an `optional` one may be
//! dropped, the others must be served. A `<precedence>` says which of two is served first when
//! both are. The robot leaves `from` at the plan's start and ends at `to` (when given), and may
//! drive at most `max_distance_m`, take at most `max_secs` and use at most `max_charge` of its
//! battery (its endurance).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use armor_module_api::xml::{Element, Located, Pos};

use super::{Action, LatLon};
use crate::fields::{Field, escape, identifier, is_decimal, optional};
use crate::net::format_date;

/// What the operator wants done, and the robot's limits in doing it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Objectives {
    /// The waypoint the robot starts at.
    pub from: String,
    /// The waypoint the robot ends at; `None`: wherever its last objective is.
    pub to: Option<String>,
    /// The most the robot may drive (its endurance in distance).
    pub max_distance_m: Option<f64>,
    /// The longest the whole plan may take (its endurance in time).
    pub max_secs: Option<f64>,
    /// The share of the battery's charge the plan may use (its endurance in charge, from 0 to
    /// 1), by the battery's drain with distance and time (the simulator's model).
    pub max_charge: Option<f64>,
    pub objectives: Vec<Objective>,
    pub precedences: Vec<Precedence>,
    pub pos: Pos,
}

/// One place to reach and what to do there.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Objective {
    pub name: String,
    pub place: Place,
    /// Runs on arrival (as a leg's `<arrival>`); its `for_secs` is how long it may take.
    pub arrival: Option<Action>,
    /// Seconds to stay after the arrival action.
    pub wait_secs: Option<f64>,
    /// Arrive no earlier (Unix seconds).
    pub not_before_unix_secs: Option<f64>,
    /// Arrive by, or count the lateness (Unix seconds): a soft limit.
    pub due_unix_secs: Option<f64>,
    /// Arrive no later (Unix seconds): a hard limit.
    pub by_unix_secs: Option<f64>,
    /// How much serving it weighs when not everything can be served (1 or more).
    pub priority: u32,
    /// Whether it may be dropped; when not, it must be served.
    pub optional: bool,
    pub pos: Pos,
}

impl Objective {
    /// The longest it keeps the robot at its place: its arrival action's `for_secs` and its
    /// wait.
    pub fn service_secs(&self) -> f64 {
        self.arrival
            .as_ref()
            .and_then(|action| action.for_secs)
            .unwrap_or(0.0)
            + self.wait_secs.unwrap_or(0.0)
    }

    /// The waypoint a written plan reaches it at: the one it names, else one of its own name.
    pub fn waypoint(&self) -> &str {
        match &self.place {
            Place::Waypoint(name) => name,
            Place::At(_) | Place::Area(_) => &self.name,
        }
    }
}

/// Where an objective is.
#[derive(Clone, Debug, PartialEq)]
pub enum Place {
    /// A waypoint of the plan, by name.
    Waypoint(String),
    /// A place of its own.
    At(LatLon),
    /// An area to reach or observe: the planner places the objective in it (its centroid when
    /// the objective acts there, else the point of it the robot reaches first from the start).
    Area(Area),
}

/// An objective's area, written as a no-go area's outline is: three `<point>`s or more.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Area {
    pub points: Vec<LatLon>,
    pub pos: Pos,
}

impl Default for Place {
    fn default() -> Self {
        Place::Waypoint(String::new())
    }
}

/// `first` is served before `then` when both are.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Precedence {
    pub first: String,
    pub then: String,
    pub pos: Pos,
}

/// Reads `<objectives>`; `start_unix_secs` is the plan's start, which windows need.
pub(crate) fn read(
    element: &Element,
    start_unix_secs: Option<f64>,
    p: &mut Vec<Located>,
) -> Objectives {
    p.extend(element.unknown_attrs(&["from", "to", "max_distance_m", "max_secs", "max_charge"]));
    p.extend(element.unknown_children(&["objective", "precedence"]));
    crate::fields::no_text(element, p);
    let mut objectives = Objectives {
        from: identifier(element, "from", "waypoint name", p).unwrap_or_default(),
        to: element
            .attr("to")
            .and_then(|_| identifier(element, "to", "waypoint name", p)),
        max_distance_m: optional(element, "max_distance_m", positive("max_distance_m"), p),
        max_secs: optional(element, "max_secs", positive("max_secs"), p),
        max_charge: optional(element, "max_charge", charge, p),
        pos: element.pos,
        ..Objectives::default()
    };
    for child in &element.children {
        match child.name.as_str() {
            "objective" => objectives
                .objectives
                .push(read_objective(child, start_unix_secs, p)),
            "precedence" => {
                p.extend(child.unknown_attrs(&["first", "then"]));
                crate::fields::no_children(child, p);
                crate::fields::no_text(child, p);
                objectives.precedences.push(Precedence {
                    first: identifier(child, "first", "objective name", p).unwrap_or_default(),
                    then: identifier(child, "then", "objective name", p).unwrap_or_default(),
                    pos: child.pos,
                });
            }
            _ => {}
        }
    }
    if objectives.objectives.is_empty() {
        p.push(Located::new(
            element.pos,
            "<objectives> has no <objective>: nothing to plan",
        ));
    }
    objectives
}

fn read_objective(
    element: &Element,
    start_unix_secs: Option<f64>,
    p: &mut Vec<Located>,
) -> Objective {
    p.extend(element.unknown_attrs(&[
        "name",
        "at",
        "lat",
        "lon",
        "wait_secs",
        "not_before",
        "due",
        "by",
        "priority",
        "optional",
    ]));
    p.extend(element.unknown_children(&["arrival", "area"]));
    crate::fields::no_text(element, p);
    let name = identifier(element, "name", "objective name", p).unwrap_or_default();
    let areas: Vec<&Element> = element.children_named("area").collect();
    for extra in areas.iter().skip(1) {
        p.push(Located::new(
            extra.pos,
            format!("objective `{name}` has one <area> at most"),
        ));
    }
    let place = match (
        element.attr("at"),
        element.attr("lat").or(element.attr("lon")),
        areas.first(),
    ) {
        (Some(_), None, None) => {
            Place::Waypoint(identifier(element, "at", "waypoint name", p).unwrap_or_default())
        }
        (None, Some(_), None) => Place::At(super::xml::lat_lon(element, p).unwrap_or_default()),
        (None, None, Some(area)) => Place::Area(read_area(area, &name, p)),
        (None, None, None) => {
            p.push(Located::new(
                element.pos,
                format!(
                    "objective `{name}` has no place: give `at` (a waypoint), `lat` and `lon`, \
                     or an <area>"
                ),
            ));
            Place::default()
        }
        _ => {
            p.push(Located::new(
                element.pos,
                format!(
                    "objective `{name}`: give its place one way: as a waypoint (`at`), as `lat` \
                     and `lon`, or as an <area>"
                ),
            ));
            Place::default()
        }
    };
    let date = |attr: &str, p: &mut Vec<Located>| -> Option<f64> {
        let field = element.attr(attr)?;
        super::xml::named_date(Field::new(&field.value, field.pos), attr)
            .map_err(|err| p.push(err))
            .ok()
    };
    let mut objective = Objective {
        name,
        place,
        wait_secs: optional(element, "wait_secs", super::xml::seconds, p),
        not_before_unix_secs: date("not_before", p),
        due_unix_secs: date("due", p),
        by_unix_secs: date("by", p),
        priority: optional(element, "priority", priority, p).unwrap_or(1),
        optional: optional(element, "optional", boolean, p).unwrap_or(false),
        pos: element.pos,
        ..Objective::default()
    };
    for child in element.children_named("arrival") {
        if objective.arrival.is_some() {
            p.push(Located::new(
                child.pos,
                "the objective has one <arrival> at most",
            ));
        }
        let action = super::xml::read_action(child, p);
        if action.for_secs.is_none() {
            p.push(Located::new(
                child.pos,
                format!(
                    "objective `{}`: its <arrival> needs `for_secs`, the longest it may take, \
                     for the planner to know how long the robot stays",
                    objective.name
                ),
            ));
        }
        objective.arrival = Some(action);
    }
    check_window(&objective, start_unix_secs, p);
    objective
}

/// An objective's `<area>`: its points, three or more, whose outline neither crosses itself
/// nor encloses nothing (measured in degrees, which keeps both properties over an area the
/// size of a plan's).
fn read_area(element: &Element, name: &str, p: &mut Vec<Located>) -> Area {
    p.extend(element.unknown_attrs(&[]));
    p.extend(element.unknown_children(&["point"]));
    crate::fields::no_text(element, p);
    let points: Vec<LatLon> = element
        .children_named("point")
        .filter_map(|point| {
            p.extend(point.unknown_attrs(&["lat", "lon"]));
            crate::fields::no_children(point, p);
            crate::fields::no_text(point, p);
            super::xml::lat_lon(point, p)
        })
        .collect();
    let count = element.children_named("point").count();
    if count < 3 {
        p.push(Located::new(
            element.pos,
            format!("objective `{name}`: its <area> needs 3 <point>s or more, it has {count}"),
        ));
    } else if points.len() == count {
        let outline = crate::geo::Polygon::new(
            points
                .iter()
                .map(|point| crate::geo::Point::new(point.lon_deg, point.lat_deg))
                .collect(),
        );
        if outline.crosses_itself() {
            p.push(Located::new(
                element.pos,
                format!(
                    "objective `{name}`: its area's outline crosses itself, so it has no clear \
                     inside"
                ),
            ));
        } else if outline.area() < 1e-12 {
            // A square degree is some 9,000 km² at the latitudes plans are drawn at: this is
            // about a hundredth of a square metre.
            p.push(Located::new(
                element.pos,
                format!(
                    "objective `{name}`: its area encloses nothing (its points are on one line \
                     or at one place)"
                ),
            ));
        }
    }
    Area {
        points,
        pos: element.pos,
    }
}

/// A window that ends before it starts, or that needs the plan's start to be read.
fn check_window(objective: &Objective, start_unix_secs: Option<f64>, p: &mut Vec<Located>) {
    let name = &objective.name;
    let limits = [
        ("not_before", objective.not_before_unix_secs),
        ("due", objective.due_unix_secs),
        ("by", objective.by_unix_secs),
    ];
    match start_unix_secs {
        None if limits.iter().any(|(_, at)| at.is_some()) => p.push(Located::new(
            objective.pos,
            format!(
                "objective `{name}` has a time window but the plan has no `start`: give \
                 <plan start=\"DATE\"> for the planner to know when the robot leaves"
            ),
        )),
        Some(start) => {
            for (attr, at) in &limits[1..] {
                if let Some(at) = at
                    && *at <= start
                {
                    p.push(Located::new(
                        objective.pos,
                        format!(
                            "objective `{name}`: `{attr}` {} is not after the plan's start ({})",
                            format_date(*at),
                            format_date(start)
                        ),
                    ));
                }
            }
        }
        None => {}
    }
    if let Some(not_before) = objective.not_before_unix_secs {
        for (attr, at) in &limits[1..] {
            if let Some(at) = at
                && *at < not_before
            {
                p.push(Located::new(
                    objective.pos,
                    format!(
                        "objective `{name}`: its window ends ({attr} {}) before it starts \
                         (not_before {})",
                        format_date(*at),
                        format_date(not_before)
                    ),
                ));
            }
        }
    }
    if let (Some(due), Some(by)) = (objective.due_unix_secs, objective.by_unix_secs)
        && by < due
    {
        p.push(Located::new(
            objective.pos,
            format!(
                "objective `{name}`: `due` ({}) is after `by` ({}), which is the hard limit; \
                 give `due` no later than `by`",
                format_date(due),
                format_date(by)
            ),
        ));
    }
}

fn positive(name: &'static str) -> fn(Field<'_>) -> Result<f64, Located> {
    fn read(field: Field<'_>, name: &str, unit: &str) -> Result<f64, Located> {
        match field.value.trim().parse::<f64>() {
            Ok(value) if value.is_finite() && value > 0.0 && is_decimal(field.value) => Ok(value),
            _ => Err(Located::new(
                field.pos,
                format!(
                    "`{name}` must be a number of {unit} above 0 (like 300), not `{}`",
                    field.value
                ),
            )),
        }
    }
    match name {
        "max_distance_m" => |field| read(field, "max_distance_m", "metres"),
        _ => |field| read(field, "max_secs", "seconds"),
    }
}

fn charge(field: Field<'_>) -> Result<f64, Located> {
    match field.value.trim().parse::<f64>() {
        Ok(value) if value > 0.0 && value <= 1.0 && is_decimal(field.value) => Ok(value),
        _ => Err(Located::new(
            field.pos,
            format!(
                "`max_charge` must be the share of the battery the plan may use, above 0 and at \
                 most 1 (like 0.3), not `{}`",
                field.value
            ),
        )),
    }
}

fn priority(field: Field<'_>) -> Result<u32, Located> {
    match field.value.trim().parse::<u32>() {
        Ok(value) if (1..=1000).contains(&value) => Ok(value),
        _ => Err(Located::new(
            field.pos,
            format!(
                "`priority` must be a whole number from 1 to 1000, not `{}`",
                field.value
            ),
        )),
    }
}

fn boolean(field: Field<'_>) -> Result<bool, Located> {
    match field.value.trim() {
        "true" => Ok(true),
        "false" => Ok(false),
        other => Err(Located::new(
            field.pos,
            format!("`optional` must be `true` or `false`, not `{other}`"),
        )),
    }
}

/// Objectives and precedences that name what does not exist, names used twice, and cycles of
/// precedences; `waypoints` are the plan's (an objective of its own place takes its name as a
/// waypoint's, so it may not be one).
pub(crate) fn check_references(
    objectives: &Objectives,
    waypoints: &BTreeMap<&str, Pos>,
    p: &mut Vec<Located>,
) {
    let listing = || crate::fields::listing(waypoints.keys().copied());
    for (attr, name) in std::iter::once(("from", Some(&objectives.from)))
        .chain(std::iter::once(("to", objectives.to.as_ref())))
    {
        if let Some(name) = name
            && !name.is_empty()
            && !waypoints.contains_key(name.as_str())
        {
            p.push(Located::new(
                objectives.pos,
                format!(
                    "<objectives>: `{attr}` names waypoint `{name}`, which the plan does not \
                     define (waypoints: {})",
                    listing()
                ),
            ));
        }
    }
    let mut names: BTreeMap<&str, Pos> = BTreeMap::new();
    for objective in &objectives.objectives {
        if objective.name.is_empty() {
            continue;
        }
        if let Some(first) = names.get(objective.name.as_str()) {
            p.push(Located::new(
                objective.pos,
                format!(
                    "objective `{}`: the name is already used by the objective at line {}",
                    objective.name, first.line
                ),
            ));
        } else {
            names.insert(&objective.name, objective.pos);
        }
        match &objective.place {
            Place::Waypoint(at) if !at.is_empty() && !waypoints.contains_key(at.as_str()) => {
                p.push(Located::new(
                    objective.pos,
                    format!(
                        "objective `{}`: `at` names waypoint `{at}`, which the plan does not \
                         define (waypoints: {})",
                        objective.name,
                        listing()
                    ),
                ));
            }
            Place::At(_) | Place::Area(_) => {
                if let Some(waypoint) = waypoints.get(objective.name.as_str()) {
                    p.push(Located::new(
                        objective.pos,
                        format!(
                            "objective `{}` has a place of its own, which the written plan \
                             names after it, but the waypoint at line {} has that name",
                            objective.name, waypoint.line
                        ),
                    ));
                }
            }
            Place::Waypoint(_) => {}
        }
    }
    let mut after: BTreeMap<&str, Vec<(&str, Pos)>> = BTreeMap::new();
    for precedence in &objectives.precedences {
        for name in [&precedence.first, &precedence.then] {
            if !name.is_empty() && !names.contains_key(name.as_str()) {
                p.push(Located::new(
                    precedence.pos,
                    format!(
                        "<precedence> names objective `{name}`, which is not one (objectives: \
                         {})",
                        crate::fields::listing(names.keys().copied())
                    ),
                ));
            }
        }
        if precedence.first == precedence.then && !precedence.first.is_empty() {
            p.push(Located::new(
                precedence.pos,
                format!("<precedence> puts `{}` before itself", precedence.first),
            ));
            continue;
        }
        after
            .entry(&precedence.first)
            .or_default()
            .push((&precedence.then, precedence.pos));
    }
    if let Some((cycle, pos)) = precedence_cycle(&after) {
        p.push(Located::new(
            pos,
            format!(
                "the precedences make a cycle, so no order serves them all: {}",
                cycle
                    .iter()
                    .map(|name| format!("`{name}`"))
                    .collect::<Vec<_>>()
                    .join(" before ")
            ),
        ));
    }
}

/// A cycle in the precedence graph, as the names along it (the first again at the end), and
/// the precedence that closes it.
fn precedence_cycle<'a>(
    after: &BTreeMap<&'a str, Vec<(&'a str, Pos)>>,
) -> Option<(Vec<&'a str>, Pos)> {
    // Depth-first search with colours: a name on the current path reached again closes a cycle.
    #[derive(Clone, Copy, PartialEq)]
    enum Colour {
        OnPath,
        Done,
    }
    fn visit<'a>(
        name: &'a str,
        after: &BTreeMap<&'a str, Vec<(&'a str, Pos)>>,
        colour: &mut BTreeMap<&'a str, Colour>,
        path: &mut Vec<&'a str>,
    ) -> Option<(Vec<&'a str>, Pos)> {
        colour.insert(name, Colour::OnPath);
        path.push(name);
        for &(next, pos) in after.get(name).map_or(&[][..], Vec::as_slice) {
            match colour.get(next) {
                Some(Colour::OnPath) => {
                    let from = path.iter().position(|&on| on == next).unwrap_or(0);
                    let mut cycle = path[from..].to_vec();
                    cycle.push(next);
                    return Some((cycle, pos));
                }
                Some(Colour::Done) => {}
                None => {
                    if let Some(found) = visit(next, after, colour, path) {
                        return Some(found);
                    }
                }
            }
        }
        path.pop();
        colour.insert(name, Colour::Done);
        None
    }
    let mut colour = BTreeMap::new();
    for &name in after.keys() {
        if !colour.contains_key(name) {
            let mut path = Vec::new();
            if let Some(found) = visit(name, after, &mut colour, &mut path) {
                return Some(found);
            }
        }
    }
    None
}

/// Writes `<objectives>` in the form [`read`] reads.
pub(crate) fn write(out: &mut String, objectives: &Objectives) {
    let _ = write!(out, "  <objectives from=\"{}\"", escape(&objectives.from));
    if let Some(to) = &objectives.to {
        let _ = write!(out, " to=\"{}\"", escape(to));
    }
    if let Some(metres) = objectives.max_distance_m {
        let _ = write!(out, " max_distance_m=\"{metres}\"");
    }
    if let Some(secs) = objectives.max_secs {
        let _ = write!(out, " max_secs=\"{secs}\"");
    }
    if let Some(charge) = objectives.max_charge {
        let _ = write!(out, " max_charge=\"{charge}\"");
    }
    out.push_str(">\n");
    for objective in &objectives.objectives {
        let _ = write!(out, "    <objective name=\"{}\"", escape(&objective.name));
        match &objective.place {
            Place::Waypoint(at) => {
                let _ = write!(out, " at=\"{}\"", escape(at));
            }
            Place::At(position) => {
                let _ = write!(out, " {}", super::xml::lat_lon_attrs(*position));
            }
            Place::Area(_) => {}
        }
        if let Some(wait) = objective.wait_secs {
            let _ = write!(out, " wait_secs=\"{wait}\"");
        }
        for (attr, at) in [
            ("not_before", objective.not_before_unix_secs),
            ("due", objective.due_unix_secs),
            ("by", objective.by_unix_secs),
        ] {
            if let Some(at) = at {
                let _ = write!(out, " {attr}=\"{}\"", format_date(at));
            }
        }
        if objective.priority != 1 {
            let _ = write!(out, " priority=\"{}\"", objective.priority);
        }
        if objective.optional {
            out.push_str(" optional=\"true\"");
        }
        let area = match &objective.place {
            Place::Area(area) => Some(area),
            _ => None,
        };
        if area.is_none() && objective.arrival.is_none() {
            out.push_str("/>\n");
            continue;
        }
        out.push_str(">\n");
        if let Some(area) = area {
            out.push_str("      <area>\n");
            for point in &area.points {
                let _ = writeln!(
                    out,
                    "        <point {}/>",
                    super::xml::lat_lon_attrs(*point)
                );
            }
            out.push_str("      </area>\n");
        }
        if let Some(action) = &objective.arrival {
            super::xml::write_action(out, "      ", "arrival", action);
        }
        out.push_str("    </objective>\n");
    }
    for precedence in &objectives.precedences {
        let _ = writeln!(
            out,
            "    <precedence first=\"{}\" then=\"{}\"/>",
            escape(&precedence.first),
            escape(&precedence.then)
        );
    }
    out.push_str("  </objectives>\n");
}

#[cfg(test)]
mod tests {
    use crate::plan::Plan;

    /// A plan of objectives around `body` (the objectives' children), starting at 08:00.
    fn plan(body: &str) -> String {
        format!(
            r#"<plan name="p" system="system.xml" start="2026-11-23T08:00:00Z">
  <waypoint name="home" lat="43.5615360" lon="1.4690496"/>
  <waypoint name="gate" lat="43.5615360" lon="1.4691986"/>
  <objectives from="home" to="home" max_distance_m="300">
{body}
  </objectives>
</plan>
"#
        )
    }

    fn problems(text: &str) -> Vec<String> {
        match Plan::parse(text) {
            Ok(_) => Vec::new(),
            Err(problems) => problems.iter().map(ToString::to_string).collect(),
        }
    }

    #[test]
    fn objectives_are_read_and_written_back_the_same() {
        let text = plan(
            r#"    <objective name="look" at="gate" priority="3" not_before="2026-11-23T08:01:00Z" due="2026-11-23T08:02:00Z" by="2026-11-23T08:03:00Z">
      <arrival until="observer.observation_done" for_secs="30">
        <module name="observer"/>
      </arrival>
    </objective>
    <objective name="post" lat="43.5616" lon="1.4693" wait_secs="5" optional="true"/>
    <objective name="lot">
      <area>
        <point lat="43.5616" lon="1.4692"/>
        <point lat="43.5617" lon="1.4692"/>
        <point lat="43.5617" lon="1.4693"/>
      </area>
    </objective>
    <precedence first="look" then="post"/>"#,
        );
        let read = Plan::parse(&text).unwrap_or_else(|err| panic!("{err:?}"));
        let objectives = read.objectives.as_ref().expect("objectives read");
        assert_eq!(objectives.objectives.len(), 3);
        assert!(
            matches!(&objectives.objectives[2].place, super::Place::Area(area) if area.points.len() == 3 && area.pos.line == 12),
            "{:?}",
            objectives.objectives[2].place
        );
        assert_eq!(objectives.objectives[0].priority, 3);
        assert_eq!(objectives.objectives[0].service_secs(), 30.0);
        assert!(objectives.objectives[1].optional);
        assert_eq!(objectives.objectives[1].waypoint(), "post");
        assert_eq!(objectives.max_distance_m, Some(300.0));
        // Written and read again, it is written the same (positions aside, the same plan).
        let written = read.to_xml();
        let again = Plan::parse(&written).unwrap_or_else(|err| panic!("{err:?}"));
        assert_eq!(again.to_xml(), written);
        assert!(
            written.contains(r#"<precedence first="look" then="post"/>"#),
            "{written}"
        );
    }

    #[test]
    fn bad_objectives_are_named_at_their_lines() {
        for (body, line, says) in [
            (
                r#"    <objective name="a" at="gate" not_before="2026-11-23T08:05:00Z" by="2026-11-23T08:04:00Z"/>"#,
                5,
                "objective `a`: its window ends (by 2026-11-23T08:04:00Z) before it starts \
                 (not_before 2026-11-23T08:05:00Z)",
            ),
            (
                r#"    <objective name="a" at="gate"/>
    <objective name="b" lat="43.5616" lon="1.4693"/>
    <objective name="c" lat="43.5617" lon="1.4693"/>
    <precedence first="a" then="b"/>
    <precedence first="b" then="c"/>
    <precedence first="c" then="a"/>"#,
                10,
                "the precedences make a cycle, so no order serves them all: `a` before `b` \
                 before `c` before `a`",
            ),
            (
                r#"    <objective name="a" at="nowhere"/>"#,
                5,
                "objective `a`: `at` names waypoint `nowhere`, which the plan does not define",
            ),
            (
                r#"    <objective name="a" at="gate" priority="0"/>"#,
                5,
                "`priority` must be a whole number from 1 to 1000, not `0`",
            ),
            (
                r#"    <objective name="a" at="gate"><arrival until="observer.observation_done"><module name="observer"/></arrival></objective>"#,
                5,
                "its <arrival> needs `for_secs`",
            ),
            (
                r#"    <objective name="gate" lat="43.5616" lon="1.4693"/>"#,
                5,
                "objective `gate` has a place of its own",
            ),
            (
                r#"    <objective name="a" at="gate" lat="43.5616" lon="1.4693"/>"#,
                5,
                "give its place one way: as a waypoint (`at`), as `lat` and `lon`, or as an \
                 <area>",
            ),
            (
                r#"    <objective name="a">
      <area><point lat="43.5616" lon="1.4693"/><point lat="43.5617" lon="1.4693"/></area>
    </objective>"#,
                6,
                "objective `a`: its <area> needs 3 <point>s or more, it has 2",
            ),
            (
                r#"    <objective name="a">
      <area>
        <point lat="43.5616" lon="1.4693"/>
        <point lat="43.5617" lon="1.4694"/>
        <point lat="43.5616" lon="1.4694"/>
        <point lat="43.5617" lon="1.4693"/>
      </area>
    </objective>"#,
                6,
                "objective `a`: its area's outline crosses itself",
            ),
            (
                r#"    <objective name="a">
      <area>
        <point lat="43.5616" lon="1.4693"/>
        <point lat="43.5617" lon="1.4694"/>
        <point lat="43.5618" lon="1.4695"/>
      </area>
    </objective>"#,
                6,
                "objective `a`: its area encloses nothing",
            ),
            (
                r#"    <objective name="a" at="gate">
      <area><point lat="43.5616" lon="1.4693"/><point lat="43.5617" lon="1.4693"/><point lat="43.5617" lon="1.4694"/></area>
    </objective>"#,
                5,
                "objective `a`: give its place one way",
            ),
        ] {
            let found = problems(&plan(body));
            assert!(
                found
                    .iter()
                    .any(|problem| problem.starts_with(&format!("{line}:"))
                        && problem.contains(says)),
                "expected `{says}` at line {line}, got {found:#?}"
            );
        }
    }

    #[test]
    fn a_window_needs_the_plan_s_start() {
        let text = plan(r#"    <objective name="a" at="gate" by="2026-11-23T08:04:00Z"/>"#)
            .replace(r#" start="2026-11-23T08:00:00Z""#, "");
        let found = problems(&text);
        assert!(
            found
                .iter()
                .any(|problem| problem.contains("has a time window but the plan has no `start`")),
            "{found:#?}"
        );
    }
}
