//! The plan XML format (see [`super`] and `assets/schema/plan.xsd`): [`Plan::parse`] and
//! [`Plan::to_xml`].

use std::collections::hash_map::Entry;
use std::collections::{BTreeMap, HashMap};
use std::fmt::Write as _;

use armor_module_api::describe::is_identifier;
use armor_module_api::xml::{self as tree, Element, Located, Pos};

use super::{
    Action, ActionModule, ActionParam, Alternative, AreaKind, Basemap, Contingency, Graphic,
    GraphicKind, LatLon, Leg, Navigation, Plan, Response, Trigger, Unit, Waypoint, check_sidc,
};
use crate::fields::{
    Field, NAME_RULE, escape, finish, identifier, is_decimal, no_children, no_text, optional,
    read_identifier, required,
};
use crate::net::{format_date, read_date, read_event};

impl Plan {
    /// Reads a plan, reporting every problem of its form (malformed XML, unknown elements or
    /// attributes, bad numbers, coordinates or dates, names used twice, legs that name missing
    /// waypoints or do not join up), sorted by position. Whether it fits its world and system is
    /// checked by [`super::compile`].
    pub fn parse(text: &str) -> Result<Plan, Vec<Located>> {
        let root = tree::parse_document(text, "plan")?;
        let mut problems = Vec::new();
        let p = &mut problems;
        p.extend(root.unknown_attrs(&["name", "system", "world", "start"]));
        p.extend(root.unknown_children(&[
            "origin",
            "basemap",
            "navigation",
            "throughout",
            "waypoint",
            "leg",
            "objectives",
            "contingency",
            "phase_line",
            "boundary",
            "area",
            "unit",
        ]));
        no_text(&root, p);
        let mut plan = Plan {
            name: identifier(&root, "name", "name", p).unwrap_or_default(),
            system: required(&root, "system", p)
                .map(|field| field.value.to_owned())
                .unwrap_or_default(),
            world: root.attr_value("world").unwrap_or_default().to_owned(),
            start_unix_secs: optional(&root, "start", date("start"), p),
            pos: root.pos,
            ..Plan::default()
        };
        let count = |name: &str| root.children_named(name).count();
        plan.waypoints.reserve_exact(count("waypoint"));
        plan.legs.reserve_exact(count("leg"));
        let mut navigation_seen: Option<Pos> = None;
        for child in &root.children {
            match child.name.as_str() {
                "origin" => {
                    if plan.origin.is_some() {
                        p.push(Located::new(child.pos, "the plan has one <origin> at most"));
                    }
                    p.extend(child.unknown_attrs(&["lat", "lon"]));
                    no_children(child, p);
                    no_text(child, p);
                    plan.origin = lat_lon(child, p);
                }
                "basemap" => {
                    if plan.basemap.is_some() {
                        p.push(Located::new(
                            child.pos,
                            "the plan has one <basemap> at most",
                        ));
                    }
                    p.extend(child.unknown_attrs(&["href"]));
                    no_children(child, p);
                    no_text(child, p);
                    plan.basemap = required(child, "href", p).map(|href| Basemap {
                        href: href.value.to_owned(),
                        pos: href.pos,
                    });
                }
                "navigation" => {
                    if let Some(first) = navigation_seen {
                        p.push(Located::new(
                            child.pos,
                            format!(
                                "the plan has one <navigation> at most (line {})",
                                first.line
                            ),
                        ));
                    }
                    navigation_seen = Some(child.pos);
                    plan.navigation = read_navigation(child, p);
                }
                "throughout" => {
                    if plan.throughout.is_some() {
                        p.push(Located::new(
                            child.pos,
                            "the plan has one <throughout> at most",
                        ));
                    }
                    plan.throughout = Some(read_action(child, p));
                }
                "waypoint" => plan.waypoints.push(read_waypoint(child, p)),
                "leg" => {
                    let index = plan.legs.len();
                    plan.legs.push(read_leg(child, index, p));
                }
                "objectives" => {
                    if plan.objectives.is_some() {
                        p.push(Located::new(
                            child.pos,
                            "the plan has one <objectives> at most",
                        ));
                    }
                    plan.objectives = Some(super::objectives::read(child, plan.start_unix_secs, p));
                }
                "contingency" => plan.contingencies.extend(read_contingency(child, p)),
                "phase_line" | "boundary" | "area" => plan.graphics.push(read_graphic(child, p)),
                "unit" => plan.units.push(read_unit(child, p)),
                _ => {}
            }
        }
        // The tree is no longer needed: its memory serves the checks.
        drop(root);
        resolve_start_returns(&mut plan);
        check_references(&plan, p);
        finish(plan, problems)
    }

    /// Writes the plan in the form [`Plan::parse`] reads (dates in UTC).
    pub fn to_xml(&self) -> String {
        let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        let _ = write!(
            out,
            "<plan name=\"{}\" system=\"{}\"",
            escape(&self.name),
            escape(&self.system)
        );
        if !self.world.is_empty() {
            let _ = write!(out, " world=\"{}\"", escape(&self.world));
        }
        if let Some(start) = self.start_unix_secs {
            let _ = write!(out, " start=\"{}\"", format_date(start));
        }
        out.push_str(">\n");
        if let Some(origin) = self.origin {
            let _ = writeln!(out, "  <origin {}/>", lat_lon_attrs(origin));
        }
        if let Some(basemap) = &self.basemap {
            let _ = writeln!(out, "  <basemap href=\"{}\"/>", escape(&basemap.href));
        }
        let nav = &self.navigation;
        if *nav != Navigation::default() {
            let defaults = Navigation::default();
            out.push_str("  <navigation");
            for (name, value, default) in [
                ("module", &nav.module, &defaults.module),
                ("goal_x", &nav.goal_x_param, &defaults.goal_x_param),
                ("goal_y", &nav.goal_y_param, &defaults.goal_y_param),
                ("no_go", &nav.no_go_param, &defaults.no_go_param),
                (
                    "no_go_margins",
                    &nav.no_go_margins_param,
                    &defaults.no_go_margins_param,
                ),
                (
                    "robot_radius",
                    &nav.robot_radius_param,
                    &defaults.robot_radius_param,
                ),
                ("clearance", &nav.clearance_param, &defaults.clearance_param),
                ("reached", &nav.reached_event, &defaults.reached_event),
                ("blocked", &nav.blocked_event, &defaults.blocked_event),
                ("path", &nav.path_param, &defaults.path_param),
            ] {
                if value != default {
                    let _ = write!(out, " {name}=\"{}\"", escape(value));
                }
            }
            if nav.speed_mps != defaults.speed_mps {
                let _ = write!(out, " speed_mps=\"{}\"", nav.speed_mps);
            }
            if let Some(radius) = nav.robot_radius_m {
                let _ = write!(out, " robot_radius_m=\"{radius}\"");
            }
            if let Some(clearance) = nav.clearance_m {
                let _ = write!(out, " clearance_m=\"{clearance}\"");
            }
            if nav.companions.is_empty() {
                out.push_str("/>\n");
            } else {
                out.push_str(">\n");
                for module in &nav.companions {
                    let _ = writeln!(out, "    <module name=\"{}\"/>", escape(module));
                }
                out.push_str("  </navigation>\n");
            }
        }
        if let Some(action) = &self.throughout {
            write_action(&mut out, "  ", "throughout", action);
        }
        for waypoint in &self.waypoints {
            let _ = write!(
                out,
                "  <waypoint name=\"{}\" {}",
                escape(&waypoint.name),
                lat_lon_attrs(waypoint.position)
            );
            if let Some(symbol) = &waypoint.symbol {
                let _ = write!(out, " symbol=\"{}\"", escape(symbol));
            }
            out.push_str("/>\n");
        }
        for (index, leg) in self.legs.iter().enumerate() {
            let _ = write!(out, "  <leg");
            if leg.name != default_leg_name(index) {
                let _ = write!(out, " name=\"{}\"", escape(&leg.name));
            }
            let _ = write!(
                out,
                " from=\"{}\" to=\"{}\"",
                escape(&leg.from),
                escape(&leg.to)
            );
            if let Some(at) = leg.not_before_unix_secs {
                let _ = write!(out, " not_before=\"{}\"", format_date(at));
            }
            if let Some(at) = leg.arrive_by_unix_secs {
                let _ = write!(out, " arrive_by=\"{}\"", format_date(at));
            }
            if let Some(wait) = leg.wait_secs {
                let _ = write!(out, " wait_secs=\"{wait}\"");
            }
            if leg.during.is_none() && leg.arrival.is_none() && leg.contingencies.is_empty() {
                out.push_str("/>\n");
                continue;
            }
            out.push_str(">\n");
            for (tag, action) in [("during", &leg.during), ("arrival", &leg.arrival)] {
                if let Some(action) = action {
                    write_action(&mut out, "    ", tag, action);
                }
            }
            for contingency in &leg.contingencies {
                write_contingency(&mut out, "    ", contingency);
            }
            out.push_str("  </leg>\n");
        }
        if let Some(objectives) = &self.objectives {
            super::objectives::write(&mut out, objectives);
        }
        for contingency in &self.contingencies {
            write_contingency(&mut out, "  ", contingency);
        }
        for graphic in &self.graphics {
            let tag = graphic_tag(graphic.kind);
            let _ = write!(out, "  <{tag} name=\"{}\"", escape(&graphic.name));
            if let GraphicKind::Area(kind) = graphic.kind {
                let _ = write!(out, " kind=\"{}\"", kind.as_str());
            }
            if let Some(at) = graphic.at_unix_secs {
                let _ = write!(out, " at=\"{}\"", format_date(at));
            }
            if let Some(margin) = graphic.margin_m {
                let _ = write!(out, " margin_m=\"{margin}\"");
            }
            out.push_str(">\n");
            for point in &graphic.points {
                let _ = writeln!(out, "    <point {}/>", lat_lon_attrs(*point));
            }
            let _ = writeln!(out, "  </{tag}>");
        }
        for unit in &self.units {
            let _ = writeln!(
                out,
                "  <unit name=\"{}\" sidc=\"{}\" {}/>",
                escape(&unit.name),
                escape(&unit.sidc),
                lat_lon_attrs(unit.position)
            );
        }
        out.push_str("</plan>\n");
        out
    }
}

/// The name of the leg at `index` (from 0) when the plan gives none.
pub(crate) fn default_leg_name(index: usize) -> String {
    format!("leg{}", index + 1)
}

fn graphic_tag(kind: GraphicKind) -> &'static str {
    match kind {
        GraphicKind::PhaseLine => "phase_line",
        GraphicKind::Boundary => "boundary",
        GraphicKind::Area(_) => "area",
    }
}

/// Seven decimals of a degree: about a centimetre.
pub(super) fn lat_lon_attrs(position: LatLon) -> String {
    format!(
        "lat=\"{}\" lon=\"{}\"",
        degrees(position.lat_deg),
        degrees(position.lon_deg)
    )
}

fn degrees(value: f64) -> String {
    crate::geo::trimmed_decimal(value, 7)
}

pub(super) fn write_action(out: &mut String, indent: &str, tag: &str, action: &Action) {
    let _ = write!(out, "{indent}<{tag}");
    if let Some(until) = &action.until {
        let _ = write!(out, " until=\"{}\"", escape(until));
    }
    if let Some(secs) = action.for_secs {
        let _ = write!(out, " for_secs=\"{secs}\"");
    }
    out.push_str(">\n");
    let inner = format!("{indent}  ");
    write_modules(out, &inner, &action.modules);
    for (index, alternative) in action.alternatives.iter().enumerate() {
        let _ = write!(out, "{inner}<alternative");
        if alternative.name != Alternative::default_name(index) {
            let _ = write!(out, " name=\"{}\"", escape(&alternative.name));
        }
        if !alternative.on.is_empty() {
            let _ = write!(out, " on=\"{}\"", escape(&alternative.on.join(" ")));
        }
        if alternative.modules.is_empty() {
            out.push_str("/>\n");
            continue;
        }
        out.push_str(">\n");
        write_modules(out, &format!("{inner}  "), &alternative.modules);
        let _ = writeln!(out, "{inner}</alternative>");
    }
    let _ = writeln!(out, "{indent}</{tag}>");
}

fn write_modules(out: &mut String, indent: &str, modules: &[ActionModule]) {
    for module in modules {
        let _ = write!(out, "{indent}<module name=\"{}\"", escape(&module.name));
        if module.params.is_empty() {
            out.push_str("/>\n");
            continue;
        }
        out.push_str(">\n");
        for param in &module.params {
            let _ = writeln!(
                out,
                "{indent}  <param name=\"{}\" value=\"{}\"/>",
                escape(&param.name),
                escape(&param.value)
            );
        }
        let _ = writeln!(out, "{indent}</module>");
    }
}

fn write_contingency(out: &mut String, indent: &str, contingency: &Contingency) {
    let on = match &contingency.trigger {
        Trigger::Blocked => "blocked".to_owned(),
        Trigger::Late => "late".to_owned(),
        Trigger::Failed { module } => format!("failed\" module=\"{}", escape(module)),
        Trigger::Lost { module } if module == DEFAULT_LOCALISER => "lost".to_owned(),
        Trigger::Lost { module } => format!("lost\" module=\"{}", escape(module)),
        Trigger::LowBattery { module } if module == DEFAULT_BATTERY => "low_battery".to_owned(),
        Trigger::LowBattery { module } => format!("low_battery\" module=\"{}", escape(module)),
        Trigger::LinkLost { after_secs } if *after_secs == DEFAULT_LINK_LOST_AFTER_SECS => {
            "link_lost".to_owned()
        }
        Trigger::LinkLost { after_secs } => format!("link_lost\" after_secs=\"{after_secs}"),
    };
    let response = match &contingency.response {
        Response::Skip => "skip".to_owned(),
        Response::Hold => "hold".to_owned(),
        Response::Continue => "continue".to_owned(),
        Response::Repair { after_secs: None } => "repair".to_owned(),
        Response::Repair {
            after_secs: Some(after_secs),
        } => format!("repair\" after_secs=\"{after_secs}"),
        Response::Return { waypoint } => format!("return\" waypoint=\"{}", escape(waypoint)),
    };
    let _ = writeln!(out, "{indent}<contingency on=\"{on}\" do=\"{response}\"/>");
}

/// A date attribute reader whose message names the attribute.
fn date(name: &'static str) -> fn(Field<'_>) -> Result<f64, Located> {
    match name {
        "start" => |field| named_date(field, "start"),
        "not_before" => |field| named_date(field, "not_before"),
        "arrive_by" => |field| named_date(field, "arrive_by"),
        _ => |field| named_date(field, "at"),
    }
}

pub(super) fn named_date(field: Field<'_>, name: &str) -> Result<f64, Located> {
    read_date(field).map_err(|err| {
        Located::new(
            err.pos,
            err.message.replacen("`at`", &format!("`{name}`"), 1),
        )
    })
}

/// A number of seconds, 0 or more, or a speed above 0: finite decimals only.
pub(super) fn seconds(field: Field<'_>) -> Result<f64, Located> {
    match field.value.trim().parse::<f64>() {
        Ok(value) if value.is_finite() && value >= 0.0 && is_decimal(field.value) => Ok(value),
        _ => Err(Located::new(
            field.pos,
            format!(
                "expected a number of seconds, 0 or more (like 10 or 2.5), not `{}`",
                field.value
            ),
        )),
    }
}

fn speed(field: Field<'_>) -> Result<f64, Located> {
    match field.value.trim().parse::<f64>() {
        Ok(value) if value.is_finite() && value > 0.0 && is_decimal(field.value) => Ok(value),
        _ => Err(Located::new(
            field.pos,
            format!(
                "`speed_mps` must be a speed in m/s above 0 (like 0.5), not `{}`",
                field.value
            ),
        )),
    }
}

/// A distance in metres, 0 or more, named `name` in the message.
fn metres(name: &'static str) -> fn(Field<'_>) -> Result<f64, Located> {
    fn read(field: Field<'_>, name: &str) -> Result<f64, Located> {
        match field.value.trim().parse::<f64>() {
            Ok(value) if value.is_finite() && value >= 0.0 && is_decimal(field.value) => Ok(value),
            _ => Err(Located::new(
                field.pos,
                format!(
                    "`{name}` must be a distance in metres, 0 or more (like 0.25), not `{}`",
                    field.value
                ),
            )),
        }
    }
    match name {
        "robot_radius_m" => |field| read(field, "robot_radius_m"),
        "clearance_m" => |field| read(field, "clearance_m"),
        _ => |field| read(field, "margin_m"),
    }
}

pub(super) fn lat_lon(element: &Element, problems: &mut Vec<Located>) -> Option<LatLon> {
    let mut read = |name: &str, limit: f64, what: &str| -> Option<f64> {
        let field = required(element, name, problems)?;
        match field.value.trim().parse::<f64>() {
            Ok(value) if is_decimal(field.value) && value.abs() <= limit => Some(value),
            _ => {
                problems.push(Located::new(
                    field.pos,
                    format!(
                        "`{name}` must be a {what} in degrees between -{limit} and {limit} (like 43.5615), not `{}`",
                        field.value
                    ),
                ));
                None
            }
        }
    };
    let lat = read("lat", 90.0, "latitude");
    let lon = read("lon", 180.0, "longitude");
    Some(LatLon {
        lat_deg: lat?,
        lon_deg: lon?,
    })
}

fn read_navigation(element: &Element, p: &mut Vec<Located>) -> Navigation {
    p.extend(element.unknown_attrs(&[
        "module",
        "goal_x",
        "goal_y",
        "no_go",
        "no_go_margins",
        "robot_radius",
        "clearance",
        "reached",
        "blocked",
        "path",
        "speed_mps",
        "robot_radius_m",
        "clearance_m",
    ]));
    p.extend(element.unknown_children(&["module"]));
    no_text(element, p);
    let mut navigation = Navigation {
        pos: element.pos,
        ..Navigation::default()
    };
    for (attr, slot) in [
        ("module", &mut navigation.module),
        ("goal_x", &mut navigation.goal_x_param),
        ("goal_y", &mut navigation.goal_y_param),
        ("no_go", &mut navigation.no_go_param),
        ("no_go_margins", &mut navigation.no_go_margins_param),
        ("robot_radius", &mut navigation.robot_radius_param),
        ("clearance", &mut navigation.clearance_param),
        ("reached", &mut navigation.reached_event),
        ("blocked", &mut navigation.blocked_event),
        ("path", &mut navigation.path_param),
    ] {
        if let Some(value) = element.attr(attr) {
            // An empty `path` (`no_go_margins`, …) passes no path (no margins, …) on.
            if matches!(
                attr,
                "path" | "no_go_margins" | "robot_radius" | "clearance"
            ) && value.value.trim().is_empty()
            {
                *slot = String::new();
                continue;
            }
            match read_identifier(Field::new(&value.value, value.pos), attr, "<navigation>") {
                Ok(name) => *slot = name,
                Err(err) => p.push(err),
            }
        }
    }
    if let Some(speed) = optional(element, "speed_mps", speed, p) {
        navigation.speed_mps = speed;
    }
    navigation.robot_radius_m = optional(element, "robot_radius_m", metres("robot_radius_m"), p);
    navigation.clearance_m = optional(element, "clearance_m", metres("clearance_m"), p);
    for child in element.children_named("module") {
        p.extend(child.unknown_attrs(&["name"]));
        no_children(child, p);
        no_text(child, p);
        if let Some(name) = identifier(child, "name", "module name", p) {
            if name == navigation.module || navigation.companions.contains(&name) {
                p.push(Located::new(
                    child.pos,
                    format!("<navigation> already runs module `{name}`"),
                ));
            } else {
                navigation.companions.push(name);
            }
        }
    }
    navigation
}

fn read_waypoint(element: &Element, p: &mut Vec<Located>) -> Waypoint {
    p.extend(element.unknown_attrs(&["name", "lat", "lon", "symbol"]));
    no_children(element, p);
    no_text(element, p);
    Waypoint {
        name: identifier(element, "name", "name", p).unwrap_or_default(),
        position: lat_lon(element, p).unwrap_or_default(),
        symbol: symbol(element, "symbol", p),
        pos: element.pos,
    }
}

fn symbol(element: &Element, attr: &str, p: &mut Vec<Located>) -> Option<String> {
    let field = element.attr(attr)?;
    match check_sidc(field.value.trim()) {
        Ok(()) => Some(field.value.trim().to_owned()),
        Err(why) => {
            p.push(Located::new(
                field.pos,
                format!("`{attr}` `{}` is not a symbol code: {why}", field.value),
            ));
            None
        }
    }
}

fn read_leg(element: &Element, index: usize, p: &mut Vec<Located>) -> Leg {
    p.extend(element.unknown_attrs(&[
        "name",
        "from",
        "to",
        "not_before",
        "arrive_by",
        "wait_secs",
    ]));
    p.extend(element.unknown_children(&["during", "arrival", "contingency"]));
    no_text(element, p);
    let name = match element.attr("name") {
        Some(_) => identifier(element, "name", "name", p).unwrap_or_default(),
        None => default_leg_name(index),
    };
    let mut leg = Leg {
        name,
        from: identifier(element, "from", "waypoint name", p).unwrap_or_default(),
        to: identifier(element, "to", "waypoint name", p).unwrap_or_default(),
        not_before_unix_secs: optional(element, "not_before", date("not_before"), p),
        arrive_by_unix_secs: optional(element, "arrive_by", date("arrive_by"), p),
        wait_secs: optional(element, "wait_secs", seconds, p),
        pos: element.pos,
        ..Leg::default()
    };
    for child in &element.children {
        match child.name.as_str() {
            "during" | "arrival" => {
                let slot = if child.name == "during" {
                    &mut leg.during
                } else {
                    &mut leg.arrival
                };
                if slot.is_some() {
                    p.push(Located::new(
                        child.pos,
                        format!("the leg has one <{}> at most", child.name),
                    ));
                }
                *slot = Some(read_action(child, p));
            }
            "contingency" => leg.contingencies.extend(read_contingency(child, p)),
            _ => {}
        }
    }
    leg
}

pub(super) fn read_action(element: &Element, p: &mut Vec<Located>) -> Action {
    let arrival = element.name == "arrival";
    if arrival {
        p.extend(element.unknown_attrs(&["until", "for_secs"]));
    } else {
        p.extend(element.unknown_attrs(&[]));
    }
    // A leg's action may have other ways of doing it; what runs throughout has no leg to
    // switch within.
    let in_leg = element.name != "throughout";
    if in_leg {
        p.extend(element.unknown_children(&["module", "alternative"]));
    } else {
        for child in element.children_named("alternative") {
            p.push(Located::new(
                child.pos,
                "<alternative> is for a leg's <during> or <arrival>: what runs throughout the \
                 mission has no leg to switch within",
            ));
        }
        p.extend(element.unknown_children(&["module", "alternative"]));
    }
    no_text(element, p);
    let mut action = Action {
        until: optional(element, "until", read_event, p),
        for_secs: optional(element, "for_secs", seconds, p),
        pos: element.pos,
        ..Action::default()
    };
    if arrival && action.until.is_none() && action.for_secs.is_none() {
        p.push(Located::new(
            element.pos,
            "<arrival> needs `until` (the event that ends it, like observer.observation_done), \
             `for_secs`, or both",
        ));
    }
    action.modules = read_modules(element, p);
    if action.modules.is_empty() {
        p.push(Located::new(
            element.pos,
            format!(
                "<{}> runs no module (add <module name=\"...\"/>)",
                element.name
            ),
        ));
    }
    if in_leg {
        read_alternatives(element, &mut action, p);
    }
    action
}

/// The `<alternative>`s of an action, after its own modules: each named once, each answering
/// some failure.
fn read_alternatives(element: &Element, action: &mut Action, p: &mut Vec<Located>) {
    for (index, child) in element.children_named("alternative").enumerate() {
        p.extend(child.unknown_attrs(&["name", "on"]));
        p.extend(child.unknown_children(&["module"]));
        no_text(child, p);
        let name = match child.attr("name") {
            Some(_) => identifier(child, "name", "name", p).unwrap_or_default(),
            None => Alternative::default_name(index),
        };
        let mut on: Vec<String> = Vec::new();
        if let Some(field) = child.attr("on") {
            let words: Vec<&str> = field.value.split_whitespace().collect();
            if words.is_empty() {
                p.push(Located::new(
                    field.pos,
                    "`on` names the modules whose failure the alternative answers, like \
                     on=\"mapper\"; leave it out to answer those it does without",
                ));
            }
            for word in words {
                if !is_identifier(word) {
                    p.push(Located::new(
                        field.pos,
                        format!("`on`: module name `{word}` is not valid ({NAME_RULE})"),
                    ));
                } else if on.iter().any(|seen| seen == word) {
                    p.push(Located::new(
                        field.pos,
                        format!("`on` names module `{word}` twice"),
                    ));
                } else {
                    on.push(word.to_owned());
                }
            }
        }
        let alternative = Alternative {
            name,
            on,
            modules: read_modules(child, p),
            pos: child.pos,
        };
        action.alternatives.push(alternative);
    }
    p.extend(action.alternative_problems(&element.name));
}

/// The `<module>`s of an action or an alternative, each with its `<param>`s.
fn read_modules(element: &Element, p: &mut Vec<Located>) -> Vec<ActionModule> {
    let mut modules: Vec<ActionModule> = Vec::new();
    let mut seen: BTreeMap<String, Pos> = BTreeMap::new();
    for child in element.children_named("module") {
        p.extend(child.unknown_attrs(&["name"]));
        p.extend(child.unknown_children(&["param"]));
        no_text(child, p);
        let Some(name) = identifier(child, "name", "module name", p) else {
            continue;
        };
        if let Some(first) = seen.get(&name) {
            p.push(Located::new(
                child.pos,
                format!(
                    "<{}> already runs module `{name}` (line {})",
                    element.name, first.line
                ),
            ));
            continue;
        }
        seen.insert(name.clone(), child.pos);
        let mut module = ActionModule {
            name,
            params: Vec::new(),
            pos: child.pos,
        };
        for param in child.children_named("param") {
            p.extend(param.unknown_attrs(&["name", "value"]));
            no_children(param, p);
            no_text(param, p);
            let name = identifier(param, "name", "parameter name", p);
            let value = param.attr_value("value");
            if value.is_none() {
                p.push(Located::new(
                    param.pos,
                    "<param> needs the attribute `value`",
                ));
            }
            if let Some(name) = &name
                && module.params.iter().any(|other| &other.name == name)
            {
                p.push(Located::new(
                    param.pos,
                    format!(
                        "module `{}` already gets parameter `{name}` here",
                        module.name
                    ),
                ));
            }
            module.params.push(ActionParam {
                name: name.unwrap_or_default(),
                value: value.unwrap_or_default().to_owned(),
                pos: param.pos,
            });
        }
        modules.push(module);
    }
    modules
}

/// The module a `lost` contingency listens to when it names none.
pub const DEFAULT_LOCALISER: &str = "localiser";
/// The module a `low_battery` contingency listens to when it names none: the simulator, which
/// models the battery.
pub const DEFAULT_BATTERY: &str = "sim";

/// How long a robot goes without hearing its operator before a `link_lost` contingency
/// answers, when it says nothing (PX4's data link loss timeout is 10 s too).
pub const DEFAULT_LINK_LOST_AFTER_SECS: u32 = 10;

fn read_contingency(element: &Element, p: &mut Vec<Located>) -> Option<Contingency> {
    p.extend(element.unknown_attrs(&["on", "module", "do", "waypoint", "after_secs"]));
    no_children(element, p);
    no_text(element, p);
    let on = required(element, "on", p);
    // A low battery returns to the start unless the plan says otherwise.
    let low_battery = on.is_some_and(|field| field.value.trim() == "low_battery");
    let response = if low_battery && element.attr("do").is_none() {
        None
    } else {
        required(element, "do", p)
    };
    let trigger = match on.map(|field| (field.value.trim(), field.pos)) {
        Some(("blocked", _)) => Some(Trigger::Blocked),
        Some(("late", _)) => Some(Trigger::Late),
        Some(("failed", _)) => {
            identifier(element, "module", "module name", p).map(|module| Trigger::Failed { module })
        }
        Some(("lost", _)) => {
            let module = if element.attr("module").is_some() {
                identifier(element, "module", "module name", p)
            } else {
                Some(DEFAULT_LOCALISER.to_owned())
            };
            module.map(|module| Trigger::Lost { module })
        }
        Some(("low_battery", _)) => {
            let module = if element.attr("module").is_some() {
                identifier(element, "module", "module name", p)
            } else {
                Some(DEFAULT_BATTERY.to_owned())
            };
            module.map(|module| Trigger::LowBattery { module })
        }
        Some(("link_lost", _)) => match element.attr("after_secs") {
            None => Some(Trigger::LinkLost {
                after_secs: DEFAULT_LINK_LOST_AFTER_SECS,
            }),
            Some(field) => match field.value.trim().parse::<u32>() {
                Ok(after_secs) if after_secs >= 1 => Some(Trigger::LinkLost { after_secs }),
                _ => {
                    p.push(Located::new(
                        field.pos,
                        format!(
                            "`after_secs` must be a whole number of seconds, 1 or more, not `{}`",
                            field.value
                        ),
                    ));
                    None
                }
            },
        },
        Some((other, pos)) => {
            p.push(Located::new(
                pos,
                format!(
                    "`on` must be `blocked`, `failed`, `late`, `lost`, `low_battery` or \
                     `link_lost`, not `{other}`"
                ),
            ));
            None
        }
        None => None,
    };
    let link_lost = on.is_some_and(|field| field.value.trim() == "link_lost");
    let repair = response.is_some_and(|field| field.value.trim() == "repair");
    if !link_lost
        && !repair
        && let Some(after) = element.attr("after_secs")
    {
        p.push(Located::new(
            after.pos,
            "`after_secs` is only for on=\"link_lost\" (how long without the operator) and \
             do=\"repair\" (how long the operator has to choose before the default)",
        ));
    }
    if trigger.is_some()
        && !matches!(
            trigger,
            Some(Trigger::Failed { .. } | Trigger::Lost { .. } | Trigger::LowBattery { .. })
        )
        && let Some(module) = element.attr("module")
    {
        p.push(Located::new(
            module.pos,
            "`module` is only for on=\"failed\" (the module whose failure it handles), \
             on=\"lost\" (the localiser) and on=\"low_battery\" (what reports it)",
        ));
    }
    let response = match response.map(|field| (field.value.trim(), field.pos)) {
        Some(("skip", pos)) => {
            if link_lost {
                p.push(Located::new(
                    pos,
                    "`skip` is not for on=\"link_lost\": losing the radio says nothing of the leg \
                     (use continue, hold or return)",
                ));
            }
            Some(Response::Skip)
        }
        Some(("hold", _)) => Some(Response::Hold),
        Some(("repair", pos)) => {
            if trigger.is_some() && !matches!(trigger, Some(Trigger::Blocked | Trigger::Late)) {
                p.push(Located::new(
                    pos,
                    "`repair` is only for on=\"blocked\" and on=\"late\": the run repairs a leg \
                     that cannot be completed, or not in time (use skip, hold or return)",
                ));
            }
            let after_secs = match element.attr("after_secs") {
                None => Some(None),
                Some(field) => match field.value.trim().parse::<u32>() {
                    Ok(after_secs) if after_secs >= 1 => Some(Some(after_secs)),
                    _ => {
                        p.push(Located::new(
                            field.pos,
                            format!(
                                "`after_secs` must be a whole number of seconds, 1 or more, \
                                 not `{}`",
                                field.value
                            ),
                        ));
                        None
                    }
                },
            };
            after_secs.map(|after_secs| Response::Repair { after_secs })
        }
        Some(("continue", pos)) => {
            if trigger.is_some()
                && !matches!(trigger, Some(Trigger::Late | Trigger::LinkLost { .. }))
            {
                p.push(Located::new(
                    pos,
                    "`continue` is only for on=\"late\" and on=\"link_lost\": a blocked robot or a \
                     failed module does not go on by itself (use skip, hold or return)",
                ));
            }
            Some(Response::Continue)
        }
        Some(("return", pos)) => {
            if matches!(trigger, Some(Trigger::Lost { .. })) {
                p.push(Located::new(
                    pos,
                    "`return` is not for on=\"lost\": a robot that does not know where it is \
                     cannot drive back (use hold or skip)",
                ));
            }
            if low_battery && element.attr("waypoint").is_none() {
                // Where the plan starts, once its legs are read (`resolve_start_returns`).
                Some(Response::Return {
                    waypoint: String::new(),
                })
            } else {
                identifier(element, "waypoint", "waypoint name", p)
                    .map(|waypoint| Response::Return { waypoint })
            }
        }
        Some((other, pos)) => {
            p.push(Located::new(
                pos,
                format!(
                    "`do` must be `skip`, `hold`, `return`, `continue` or `repair`, not `{other}`"
                ),
            ));
            None
        }
        None if low_battery => Some(Response::Return {
            waypoint: String::new(),
        }),
        None => None,
    };
    if !matches!(response, Some(Response::Return { .. }))
        && let Some(waypoint) = element.attr("waypoint")
    {
        p.push(Located::new(
            waypoint.pos,
            "`waypoint` is only for do=\"return\" (where to return to)",
        ));
    }
    Some(Contingency {
        trigger: trigger?,
        response: response?,
        pos: element.pos,
    })
}

fn read_graphic(element: &Element, p: &mut Vec<Located>) -> Graphic {
    let area = element.name == "area";
    let mut allowed = vec!["name"];
    if area {
        allowed.extend(["kind", "margin_m"]);
    }
    if element.name == "phase_line" {
        allowed.push("at");
    }
    p.extend(element.unknown_attrs(&allowed));
    p.extend(element.unknown_children(&["point"]));
    no_text(element, p);
    let kind = match element.name.as_str() {
        "phase_line" => GraphicKind::PhaseLine,
        "boundary" => GraphicKind::Boundary,
        _ => {
            let kind = match required(element, "kind", p) {
                Some(field) => match AreaKind::ALL
                    .into_iter()
                    .find(|kind| kind.as_str() == field.value.trim())
                {
                    Some(kind) => kind,
                    None => {
                        p.push(Located::new(
                            field.pos,
                            format!(
                                "`kind` must be one of {}, not `{}`",
                                AreaKind::ALL.map(AreaKind::as_str).join(", "),
                                field.value
                            ),
                        ));
                        AreaKind::Named
                    }
                },
                None => AreaKind::Named,
            };
            GraphicKind::Area(kind)
        }
    };
    let points: Vec<LatLon> = element
        .children_named("point")
        .filter_map(|point| {
            p.extend(point.unknown_attrs(&["lat", "lon"]));
            no_children(point, p);
            no_text(point, p);
            lat_lon(point, p)
        })
        .collect();
    let needed = if area { 3 } else { 2 };
    let count = element.children_named("point").count();
    if count < needed {
        p.push(Located::new(
            element.pos,
            format!(
                "<{}> needs {needed} <point>s or more, it has {count}",
                element.name
            ),
        ));
    }
    Graphic {
        kind,
        name: identifier(element, "name", "name", p).unwrap_or_default(),
        points,
        at_unix_secs: optional(element, "at", date("at"), p),
        margin_m: optional(element, "margin_m", metres("margin_m"), p),
        pos: element.pos,
    }
}

fn read_unit(element: &Element, p: &mut Vec<Located>) -> Unit {
    p.extend(element.unknown_attrs(&["name", "sidc", "lat", "lon"]));
    no_children(element, p);
    no_text(element, p);
    if element.attr("sidc").is_none() {
        p.push(Located::new(
            element.pos,
            "<unit> needs the attribute `sidc` (its symbol code, like SHGPUCI----K---)",
        ));
    }
    Unit {
        name: identifier(element, "name", "name", p).unwrap_or_default(),
        sidc: symbol(element, "sidc", p).unwrap_or_default(),
        position: lat_lon(element, p).unwrap_or_default(),
        pos: element.pos,
    }
}

/// A `low_battery` contingency that says nowhere to return to returns to where the plan starts:
/// its first leg's origin, or its objectives' start.
fn resolve_start_returns(plan: &mut Plan) {
    let start = plan
        .legs
        .first()
        .map(|leg| leg.from.clone())
        .or_else(|| plan.objectives.as_ref().map(|o| o.from.clone()))
        .unwrap_or_default();
    for contingency in plan.contingencies_mut() {
        if let Response::Return { waypoint } = &mut contingency.response
            && waypoint.is_empty()
        {
            waypoint.clone_from(&start);
        }
    }
}

/// Names used twice, legs that name missing waypoints or do not join up, contingencies that
/// return to missing waypoints.
fn check_references(plan: &Plan, p: &mut Vec<Located>) {
    // The first user of each name; waypoints come first, so a name is a defined waypoint when
    // its first user is one.
    // foldhash: several times faster than std's SipHash on short names, and seeded at random.
    let mut names: HashMap<&str, (&str, Pos), foldhash::fast::RandomState> =
        HashMap::with_capacity_and_hasher(
            plan.waypoints.len() + plan.legs.len() + plan.graphics.len() + plan.units.len(),
            foldhash::fast::RandomState::default(),
        );
    let named = plan
        .waypoints
        .iter()
        .map(|w| ("waypoint", w.name.as_str(), w.pos))
        .chain(plan.legs.iter().map(|l| ("leg", l.name.as_str(), l.pos)))
        .chain(
            plan.graphics
                .iter()
                .map(|g| (graphic_tag(g.kind), g.name.as_str(), g.pos)),
        )
        .chain(plan.units.iter().map(|u| ("unit", u.name.as_str(), u.pos)));
    for (kind, name, pos) in named {
        if name.is_empty() {
            continue;
        }
        match names.entry(name) {
            Entry::Occupied(first) => {
                let (first_kind, first) = first.get();
                p.push(Located::new(
                    pos,
                    format!(
                        "{kind} `{name}`: the name is already used by the {first_kind} at line {}",
                        first.line
                    ),
                ));
            }
            Entry::Vacant(slot) => {
                slot.insert((kind, pos));
            }
        }
    }
    let defined = |name: &str| names.get(name).is_some_and(|&(kind, _)| kind == "waypoint");
    if let Some(objectives) = &plan.objectives {
        let waypoints: BTreeMap<&str, Pos> = plan
            .waypoints
            .iter()
            .map(|waypoint| (waypoint.name.as_str(), waypoint.pos))
            .collect();
        super::objectives::check_references(objectives, &waypoints, p);
    }
    let waypoint_names = || {
        let names: Vec<&str> = plan.waypoints.iter().map(|w| w.name.as_str()).collect();
        if names.is_empty() {
            "none".to_owned()
        } else {
            names.join(", ")
        }
    };
    for (index, leg) in plan.legs.iter().enumerate() {
        for (end, name) in [("from", &leg.from), ("to", &leg.to)] {
            if !name.is_empty() && !defined(name) {
                p.push(Located::new(
                    leg.pos,
                    format!(
                        "leg `{}`: `{end}` names waypoint `{name}`, which the plan does not \
                         define (waypoints: {})",
                        leg.name,
                        waypoint_names()
                    ),
                ));
            }
        }
        if !leg.from.is_empty() && leg.from == leg.to {
            p.push(Located::new(
                leg.pos,
                format!(
                    "leg `{}` goes from `{}` to itself; to stay there, give the previous leg \
                     wait_secs",
                    leg.name, leg.from
                ),
            ));
        }
        if index > 0 {
            let previous = &plan.legs[index - 1];
            if !leg.from.is_empty() && !previous.to.is_empty() && leg.from != previous.to {
                p.push(Located::new(
                    leg.pos,
                    format!(
                        "leg `{}` starts at `{}` but the leg before it (`{}`) ends at `{}`: \
                         legs are driven one after the other",
                        leg.name, leg.from, previous.name, previous.to
                    ),
                ));
            }
        }
        if let (Some(leave), Some(arrive)) = (leg.not_before_unix_secs, leg.arrive_by_unix_secs)
            && arrive <= leave
        {
            p.push(Located::new(
                leg.pos,
                format!(
                    "leg `{}` must not leave before {} yet arrive by {}: the constraints \
                     contradict each other",
                    leg.name,
                    format_date(leave),
                    format_date(arrive)
                ),
            ));
        }
    }
    let contingencies = plan
        .contingencies
        .iter()
        .chain(plan.legs.iter().flat_map(|leg| &leg.contingencies));
    for contingency in contingencies {
        if let Response::Return { waypoint } = &contingency.response
            && !defined(waypoint)
        {
            p.push(Located::new(
                contingency.pos,
                format!(
                    "the contingency returns to waypoint `{waypoint}`, which the plan does not \
                     define (waypoints: {})",
                    waypoint_names()
                ),
            ));
        }
    }
    let mut seen: BTreeMap<(usize, Trigger), Pos> = BTreeMap::new();
    let scoped = plan.contingencies.iter().map(|c| (usize::MAX, c)).chain(
        plan.legs
            .iter()
            .enumerate()
            .flat_map(|(i, leg)| leg.contingencies.iter().map(move |c| (i, c))),
    );
    for (scope, contingency) in scoped {
        let key = (scope, contingency.trigger.clone());
        if let Some(first) = seen.get(&key) {
            p.push(Located::new(
                contingency.pos,
                format!(
                    "a contingency for `{}` is already given at line {}",
                    contingency.trigger.describe(),
                    first.line
                ),
            ));
        } else {
            seen.insert(key, contingency.pos);
        }
    }
    // A plan of objectives gets its legs from `armor plan`.
    if plan.legs.is_empty() && plan.objectives.is_none() {
        p.push(Located::new(
            plan.pos,
            "the plan has no leg: add <leg from=\"...\" to=\"...\"/> (or <objectives> for \
             `armor plan` to make them)",
        ));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) const RECON: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<plan name="recon" system="system.xml" world="yard.world" start="2026-11-23T08:00:00Z">
  <navigation speed_mps="0.4" robot_radius_m="0.3" clearance_m="0.15">
    <module name="avoider"/>
  </navigation>
  <throughout>
    <module name="recorder">
      <param name="record" value="sim.pose_truth"/>
      <param name="file" value="recon.mcap"/>
    </module>
  </throughout>
  <waypoint name="home" lat="43.561536" lon="1.469049"/>
  <waypoint name="gate" lat="43.56159" lon="1.46925" symbol="SFGPUCR----K---"/>
  <leg from="home" to="gate" arrive_by="2026-11-23T08:05:00Z" wait_secs="10">
    <arrival until="observer.observation_done" for_secs="60">
      <module name="observer">
        <param name="sector_deg" value="360"/>
      </module>
    </arrival>
    <contingency on="late" do="continue"/>
  </leg>
  <leg name="back" from="gate" to="home" not_before="2026-11-23T08:10:00Z"/>
  <contingency on="blocked" do="hold"/>
  <contingency on="failed" module="mapper" do="return" waypoint="home"/>
  <phase_line name="PL_RED" at="2026-11-23T08:04:00Z">
    <point lat="43.5615" lon="1.4691"/>
    <point lat="43.5617" lon="1.4691"/>
  </phase_line>
  <area name="minefield" kind="no-go" margin_m="1.5">
    <point lat="43.56156" lon="1.46912"/>
    <point lat="43.56156" lon="1.46916"/>
    <point lat="43.56160" lon="1.46916"/>
  </area>
  <unit name="enemy" sidc="SHGPUCI----K---" lat="43.5618" lon="1.4695"/>
</plan>
"#;

    fn problems(text: &str) -> Vec<String> {
        match Plan::parse(text) {
            Ok(_) => Vec::new(),
            Err(problems) => problems.iter().map(ToString::to_string).collect(),
        }
    }

    #[test]
    fn reads_every_part_and_writes_it_back_the_same() {
        let plan = Plan::parse(RECON).unwrap_or_else(|p| panic!("{p:?}"));
        assert_eq!(plan.waypoints.len(), 2);
        assert_eq!(plan.legs[0].name, "leg1");
        assert_eq!(plan.legs[1].name, "back");
        assert_eq!(plan.navigation.companions, ["avoider"]);
        assert_eq!(plan.navigation.speed_mps, 0.4);
        assert_eq!(plan.navigation.robot_radius_m, Some(0.3));
        assert_eq!(plan.navigation.clearance_m, Some(0.15));
        assert_eq!(plan.navigation.path_param, "path");
        assert_eq!(plan.navigation.no_go_margins_param, "no_go_margins_m");
        assert_eq!(plan.navigation.robot_radius_param, "robot_radius_m");
        assert_eq!(plan.navigation.clearance_param, "clearance_m");
        // Other names, and none, are written back and read again.
        for name in ["keep_m", ""] {
            let mut renamed = plan.clone();
            renamed.navigation.no_go_margins_param = name.to_owned();
            renamed.navigation.robot_radius_param = format!("{name}r");
            renamed.navigation.clearance_param = name.to_owned();
            let again = Plan::parse(&renamed.to_xml()).unwrap_or_else(|p| panic!("{p:?}"));
            assert_eq!(again.navigation, renamed.navigation);
        }
        assert_eq!(plan.graphics[1].margin_m, Some(1.5));
        assert_eq!(plan.legs[0].wait_secs, Some(10.0));
        let arrival = plan.legs[0].arrival.as_ref().expect("arrival");
        assert_eq!(arrival.until.as_deref(), Some("observer.observation_done"));
        assert_eq!(arrival.modules[0].params[0].value, "360");
        assert_eq!(plan.contingencies.len(), 2);
        assert_eq!(plan.no_go_areas().count(), 1);
        assert_eq!(plan.failure_modules(), ["mapper"]);
        assert_eq!(plan.units[0].sidc, "SHGPUCI----K---");
        assert_eq!(
            plan.throughout.as_ref().expect("throughout").modules[0]
                .params
                .len(),
            2
        );
        let again = Plan::parse(&plan.to_xml()).unwrap_or_else(|p| panic!("{p:?}"));
        assert_eq!(strip(again), strip(plan.clone()));
        assert_eq!(
            plan.to_xml(),
            Plan::parse(&plan.to_xml()).expect("ok").to_xml()
        );
    }

    fn strip(mut plan: Plan) -> Plan {
        let zero = Pos::default();
        plan.pos = zero;
        plan.navigation.pos = zero;
        plan.waypoints.iter_mut().for_each(|w| w.pos = zero);
        plan.graphics.iter_mut().for_each(|g| g.pos = zero);
        plan.units.iter_mut().for_each(|u| u.pos = zero);
        plan.contingencies.iter_mut().for_each(|c| c.pos = zero);
        for leg in &mut plan.legs {
            leg.pos = zero;
            leg.contingencies.iter_mut().for_each(|c| c.pos = zero);
            for action in leg.during.iter_mut().chain(leg.arrival.iter_mut()) {
                strip_action(action);
            }
        }
        if let Some(action) = &mut plan.throughout {
            strip_action(action);
        }
        plan
    }

    fn strip_action(action: &mut Action) {
        let zero = Pos::default();
        action.pos = zero;
        let alternatives = action.alternatives.iter_mut().flat_map(|alternative| {
            alternative.pos = zero;
            &mut alternative.modules
        });
        for module in action.modules.iter_mut().chain(alternatives) {
            module.pos = zero;
            module.params.iter_mut().for_each(|p| p.pos = zero);
        }
    }

    #[test]
    fn alternatives_are_read_and_written_back_the_same() {
        let text = r#"<plan name="p" system="s.xml">
  <waypoint name="a" lat="1" lon="2"/>
  <waypoint name="b" lat="1" lon="2.001"/>
  <leg from="a" to="b">
    <during>
      <module name="mapper"/>
      <module name="recorder"><param name="file" value="a.mcap"/></module>
      <alternative name="odometry">
        <module name="recorder"><param name="file" value="b.mcap"/></module>
      </alternative>
      <alternative on="sim camera"/>
    </during>
    <arrival for_secs="5">
      <module name="observer"/>
      <alternative name="alt1" on="camera"><module name="observer"/></alternative>
    </arrival>
  </leg>
</plan>"#;
        let plan = Plan::parse(text).unwrap_or_else(|p| panic!("{p:?}"));
        let during = plan.legs[0].during.as_ref().expect("during");
        assert_eq!(during.alternatives.len(), 2);
        assert_eq!(during.alternatives[0].name, "odometry");
        assert_eq!(during.alternatives[0].answers(&during.modules), ["mapper"]);
        assert_eq!(during.alternatives[0].modules[0].params[0].value, "b.mcap");
        assert_eq!(during.alternatives[1].name, "alt2");
        assert_eq!(during.alternatives[1].on, ["sim", "camera"]);
        let ways: Vec<(Option<&str>, Vec<String>)> = during
            .strategies()
            .into_iter()
            .map(|way| (way.name, way.answers))
            .collect();
        assert_eq!(
            ways,
            [
                (None, vec![]),
                (Some("odometry"), vec!["mapper".to_owned()]),
                (Some("alt2"), vec!["sim".to_owned(), "camera".to_owned()]),
            ]
        );
        let written = plan.to_xml();
        // A default name is not written; a given one is, even when it is the default's.
        assert!(
            written.contains("<alternative on=\"sim camera\"/>"),
            "{written}"
        );
        assert!(written.contains("<alternative on=\"camera\">"), "{written}");
        let again = Plan::parse(&written).unwrap_or_else(|p| panic!("{p:?}"));
        assert_eq!(strip(again.clone()), strip(plan));
        assert_eq!(again.to_xml(), written);
    }

    #[test]
    fn bad_alternatives_are_named_with_their_lines() {
        let text = r#"<plan name="p" system="s.xml">
  <throughout>
    <module name="recorder"/>
    <alternative on="sim"/>
  </throughout>
  <waypoint name="a" lat="1" lon="2"/>
  <waypoint name="b" lat="1" lon="2.001"/>
  <leg from="a" to="b">
    <during>
      <module name="mapper"/>
      <alternative><module name="mapper"/></alternative>
      <alternative name="x" on="9lives mapper mapper" when="now"/>
      <alternative name="x" on=" "><module name="a"/><module name="a"/><bogus/></alternative>
      <alternative name="late" on="mapper"/>
    </during>
  </leg>
</plan>"#;
        assert_eq!(
            problems(text),
            [
                "4:5: <alternative> is for a leg's <during> or <arrival>: what runs throughout \
                 the mission has no leg to switch within",
                "11:7: alternative `alt1` answers no failure: it runs every module the way \
                 before it runs; say which failures lead to it with on=\"MODULE\" (a provider \
                 such as the mapper), or leave out the module it does without",
                "12:29: `on`: module name `9lives` is not valid (use letters, digits, `_` or \
                 `-`, starting with a letter or `_`)",
                "12:29: `on` names module `mapper` twice",
                "12:55: unknown attribute `when` on <alternative> (expected one of: name, on)",
                "13:7: <during> already has an alternative named `x` (line 12)",
                "13:7: alternative `x` answers no failure: it runs every module the way before \
                 it runs; say which failures lead to it with on=\"MODULE\" (a provider such as \
                 the mapper), or leave out the module it does without",
                "13:29: `on` names the modules whose failure the alternative answers, like \
                 on=\"mapper\"; leave it out to answer those it does without",
                "13:54: <alternative> already runs module `a` (line 13)",
                "13:72: unknown element <bogus> inside <alternative> (expected one of: module)",
                "14:7: alternative `late`: its places would take the names of the leg's own \
                 (`late`, `done`, `timeout` and names ending in `_failed` are taken); choose \
                 another name",
            ]
        );
    }

    #[test]
    fn references_are_checked_with_their_lines() {
        let text = r#"<plan name="p" system="s.xml">
  <waypoint name="a" lat="1" lon="2"/>
  <waypoint name="b" lat="1" lon="2.001"/>
  <leg from="a" to="nowhere"/>
  <leg from="b" to="a" not_before="2026-11-23T08:10:00Z" arrive_by="2026-11-23T08:00:00Z"/>
  <leg from="a" to="a"/>
  <contingency on="blocked" do="return" waypoint="base"/>
  <contingency on="blocked" do="skip"/>
  <unit name="a" sidc="SFGPUCI----K---" lat="1" lon="2"/>
</plan>"#;
        assert_eq!(
            problems(text),
            [
                "4:3: leg `leg1`: `to` names waypoint `nowhere`, which the plan does not define (waypoints: a, b)",
                "5:3: leg `leg2` starts at `b` but the leg before it (`leg1`) ends at `nowhere`: legs are driven one after the other",
                "5:3: leg `leg2` must not leave before 2026-11-23T08:10:00Z yet arrive by 2026-11-23T08:00:00Z: the constraints contradict each other",
                "6:3: leg `leg3` goes from `a` to itself; to stay there, give the previous leg wait_secs",
                "7:3: the contingency returns to waypoint `base`, which the plan does not define (waypoints: a, b)",
                "8:3: a contingency for `blocked` is already given at line 7",
                "9:3: unit `a`: the name is already used by the waypoint at line 2",
            ]
        );
    }

    #[test]
    fn bad_values_are_named() {
        let text = r#"<plan name="p" system="s.xml" start="soon">
  <navigation speed_mps="-1" module="9x" robot_radius_m="-0.2" path=""/>
  <waypoint name="a" lat="95" lon="east"/>
  <waypoint name="b" lat="1" lon="2" symbol="XX"/>
  <leg from="a" to="b" wait_secs="NaN">
    <arrival><module name="observer"/></arrival>
    <during/>
    <contingency on="tired" do="panic"/>
  </leg>
  <area name="z" kind="swamp" margin_m="wide"><point lat="1" lon="2"/></area>
  <bogus/>
</plan>"#;
        let found = problems(text);
        let expected = [
            "1:31: `start` must be a date like",
            "2:30: module `9x` of <navigation> is not valid",
            "2:15: `speed_mps` must be a speed in m/s above 0",
            "2:42: `robot_radius_m` must be a distance in metres, 0 or more (like 0.25), not `-0.2`",
            "3:22: `lat` must be a latitude in degrees between -90 and 90",
            "3:31: `lon` must be a longitude",
            "4:38: `symbol` `XX` is not a symbol code: a SIDC has 15 characters",
            "5:24: expected a number of seconds, 0 or more",
            "6:5: <arrival> needs `until`",
            "7:5: <during> runs no module",
            "8:18: `on` must be `blocked`, `failed`, `late`, `lost`, `low_battery` or `link_lost`, not `tired`",
            "8:29: `do` must be `skip`, `hold`, `return`, `continue` or `repair`, not `panic`",
            "10:18: `kind` must be one of no-go, objective, assembly, named, not `swamp`",
            "10:31: `margin_m` must be a distance in metres",
            "10:3: <area> needs 3 <point>s or more, it has 1",
            "11:3: unknown element <bogus>",
        ];
        for start in expected {
            assert!(
                found.iter().any(|problem| problem.starts_with(start)),
                "missing `{start}` in {found:#?}"
            );
        }
        assert_eq!(found.len(), expected.len(), "{found:#?}");
    }

    #[test]
    fn repair_is_read_and_written_back_for_blocked_and_late_only() {
        let plan = |contingencies: &str| {
            format!(
                r#"<plan name="p" system="s.xml">
  <waypoint name="a" lat="1" lon="2"/>
  <waypoint name="b" lat="1" lon="2.001"/>
  <leg from="a" to="b"/>
  {contingencies}
</plan>"#
            )
        };
        for contingency in [
            r#"<contingency on="blocked" do="repair"/>"#,
            r#"<contingency on="late" do="repair" after_secs="30"/>"#,
        ] {
            let read = Plan::parse(&plan(contingency)).expect("a plan that repairs");
            assert!(
                matches!(read.contingencies[0].response, Response::Repair { .. }),
                "{contingency}"
            );
            assert!(read.to_xml().contains(contingency), "{}", read.to_xml());
            let again = Plan::parse(&read.to_xml()).expect("written back, read again");
            assert_eq!(
                again.contingencies[0].response,
                read.contingencies[0].response
            );
        }
        let read = Plan::parse(&plan(
            r#"<contingency on="late" do="repair" after_secs="30"/>"#,
        ))
        .expect("a plan that repairs when late");
        assert_eq!(
            read.contingencies[0].response,
            Response::Repair {
                after_secs: Some(30)
            }
        );
        assert_eq!(
            problems(&plan(
                r#"<contingency on="failed" module="m" do="repair"/>"#
            )),
            [
                "5:39: `repair` is only for on=\"blocked\" and on=\"late\": the run repairs a leg \
                 that cannot be completed, or not in time (use skip, hold or return)"
            ]
        );
        assert_eq!(
            problems(&plan(
                r#"<contingency on="blocked" do="repair" after_secs="0"/>"#
            )),
            ["5:41: `after_secs` must be a whole number of seconds, 1 or more, not `0`"]
        );
        assert_eq!(
            problems(&plan(
                r#"<contingency on="blocked" do="hold" after_secs="5"/>"#
            )),
            [
                "5:39: `after_secs` is only for on=\"link_lost\" (how long without the operator) \
                 and do=\"repair\" (how long the operator has to choose before the default)"
            ]
        );
    }

    #[test]
    fn broken_xml_and_other_documents() {
        assert_eq!(
            problems("<mission name=\"m\"/>"),
            ["1:1: expected <plan> at the top, found <mission>"]
        );
        assert_eq!(problems("<plan name=\"p\"").len(), 1);
        assert_eq!(
            problems("<plan name=\"p\" system=\"s\"/>"),
            [
                "1:1: the plan has no leg: add <leg from=\"...\" to=\"...\"/> (or \
                 <objectives> for `armor plan` to make them)"
            ]
        );
    }
}
