//! The mission XML format (see the module documentation of [`super`] and
//! `assets/schema/mission.xsd`): [`MissionNet::parse`] and [`MissionNet::to_xml`].

use std::collections::BTreeMap;
use std::fmt::Write as _;

use armor_module_api::xml::{self as tree, Element, Located, Pos};

use super::{
    Arc, Condition, MissionNet, Place, PlaceParam, Transition, check_structure, read_date,
    read_delay, read_event, read_final, read_operator, read_priority, read_tokens, read_weight,
    write_condition_attrs,
};
use crate::fields::{escape, finish, identifier, no_children, no_text, optional, required};

impl MissionNet {
    /// Reads a mission, reporting every problem found (malformed XML, unknown elements or
    /// attributes, bad numbers or dates, names used twice, arcs to unknown places, transitions
    /// without input), sorted by position. Whether the modules and events exist is checked
    /// against a system by [`super::check_names`].
    pub fn parse(text: &str) -> Result<MissionNet, Vec<Located>> {
        let root = tree::parse_document(text, "mission")?;
        let mut problems = Vec::new();
        problems.extend(root.unknown_attrs(&["name", "system"]));
        problems.extend(root.unknown_children(&["place", "transition"]));
        no_text(&root, &mut problems);
        let mut net = MissionNet {
            name: identifier(&root, "name", "name", &mut problems).unwrap_or_default(),
            system: match root.attr("system") {
                Some(_) => required(&root, "system", &mut problems)
                    .map(|field| field.value.to_owned())
                    .unwrap_or_default(),
                None => String::new(),
            },
            places: Vec::new(),
            transitions: Vec::new(),
            pos: root.pos,
        };
        for child in &root.children {
            match child.name.as_str() {
                "place" => net.places.push(read_place(child, &mut problems)),
                "transition" => net.transitions.push(read_transition(child, &mut problems)),
                _ => {}
            }
        }
        check_structure(&net, &mut problems);
        finish(net, problems)
    }

    /// Writes the mission in the format [`MissionNet::parse`] reads (dates in UTC).
    pub fn to_xml(&self) -> String {
        let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        let _ = write!(out, "<mission name=\"{}\"", escape(&self.name));
        if !self.system.is_empty() {
            let _ = write!(out, " system=\"{}\"", escape(&self.system));
        }
        out.push_str(">\n");
        for place in &self.places {
            let _ = write!(out, "  <place name=\"{}\"", escape(&place.name));
            if place.tokens > 0 {
                let _ = write!(out, " tokens=\"{}\"", place.tokens);
            }
            if place.is_final {
                out.push_str(" final=\"true\"");
            }
            if place.modules.is_empty() && place.params.is_empty() {
                out.push_str("/>\n");
                continue;
            }
            out.push_str(">\n");
            for module in &place.modules {
                let _ = writeln!(out, "    <module name=\"{}\"/>", escape(module));
            }
            for param in &place.params {
                let _ = writeln!(
                    out,
                    "    <param module=\"{}\" name=\"{}\" value=\"{}\"/>",
                    escape(&param.module),
                    escape(&param.name),
                    escape(&param.value)
                );
            }
            out.push_str("  </place>\n");
        }
        for transition in &self.transitions {
            let _ = write!(out, "  <transition name=\"{}\"", escape(&transition.name));
            write_condition_attrs(&mut out, transition.priority, &transition.condition);
            out.push_str(">\n");
            for (tag, arcs) in [
                ("input", &transition.inputs),
                ("output", &transition.outputs),
            ] {
                for arc in arcs {
                    let _ = write!(out, "    <{tag} place=\"{}\"", escape(&arc.place));
                    if arc.weight != 1 {
                        let _ = write!(out, " weight=\"{}\"", arc.weight);
                    }
                    out.push_str("/>\n");
                }
            }
            out.push_str("  </transition>\n");
        }
        out.push_str("</mission>\n");
        out
    }
}

fn read_place(element: &Element, problems: &mut Vec<Located>) -> Place {
    problems.extend(element.unknown_attrs(&["name", "tokens", "final"]));
    problems.extend(element.unknown_children(&["module", "param"]));
    no_text(element, problems);
    let mut place = Place {
        name: identifier(element, "name", "name", problems).unwrap_or_default(),
        tokens: optional(element, "tokens", read_tokens, problems).unwrap_or(0),
        is_final: optional(element, "final", read_final, problems).unwrap_or(false),
        pos: element.pos,
        ..Place::default()
    };
    let mut modules: BTreeMap<String, Pos> = BTreeMap::new();
    for child in &element.children {
        match child.name.as_str() {
            "module" => {
                problems.extend(child.unknown_attrs(&["name"]));
                no_children(child, problems);
                no_text(child, problems);
                let Some(module) = identifier(child, "name", "module name", problems) else {
                    continue;
                };
                if let Some(first) = modules.get(&module) {
                    problems.push(Located::new(
                        child.pos,
                        format!(
                            "place `{}` already runs module `{module}` (line {})",
                            place.name, first.line
                        ),
                    ));
                    continue;
                }
                modules.insert(module.clone(), child.pos);
                place.modules.push(module);
            }
            "param" => {
                problems.extend(child.unknown_attrs(&["module", "name", "value"]));
                no_children(child, problems);
                no_text(child, problems);
                let module = identifier(child, "module", "module name", problems);
                let name = identifier(child, "name", "parameter name", problems);
                // An empty value is allowed: it is a valid `string` parameter.
                let value = child.attr("value");
                if value.is_none() {
                    problems.push(Located::new(
                        child.pos,
                        "<param> needs the attribute `value`",
                    ));
                }
                place.params.push(PlaceParam {
                    module: module.unwrap_or_default(),
                    name: name.unwrap_or_default(),
                    value: value
                        .map(|attr| attr.value.as_str().to_owned())
                        .unwrap_or_default(),
                    pos: child.pos,
                });
            }
            _ => {}
        }
    }
    place
}

fn read_transition(element: &Element, problems: &mut Vec<Located>) -> Transition {
    problems.extend(element.unknown_attrs(&[
        "name",
        "priority",
        "event",
        "delay_secs",
        "at",
        "operator",
    ]));
    problems.extend(element.unknown_children(&["input", "output"]));
    no_text(element, problems);
    let mut transition = Transition {
        name: identifier(element, "name", "name", problems).unwrap_or_default(),
        priority: optional(element, "priority", read_priority, problems).unwrap_or(0),
        condition: Condition {
            delay_secs: optional(element, "delay_secs", read_delay, problems),
            at_unix_secs: optional(element, "at", read_date, problems),
            event: optional(element, "event", read_event, problems),
            operator: optional(element, "operator", read_operator, problems).unwrap_or(false),
        },
        pos: element.pos,
        ..Transition::default()
    };
    for child in &element.children {
        let arcs = match child.name.as_str() {
            "input" => &mut transition.inputs,
            "output" => &mut transition.outputs,
            _ => continue,
        };
        problems.extend(child.unknown_attrs(&["place", "weight"]));
        no_children(child, problems);
        no_text(child, problems);
        arcs.push(Arc {
            place: identifier(child, "place", "place name", problems).unwrap_or_default(),
            weight: optional(child, "weight", read_weight, problems).unwrap_or(1),
            pos: child.pos,
        });
    }
    transition
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) const PATROL: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<mission name="patrol" system="system.xml">
  <place name="leg1" tokens="1">
    <module name="nav"/>
    <module name="sim"/>
    <param module="nav" name="goal_x" value="10"/>
  </place>
  <place name="done" final="true"/>
  <transition name="arrive" priority="0" event="nav.goal_reached" delay_secs="2" at="2026-11-22T20:00:00Z">
    <input place="leg1" weight="1"/>
    <output place="done"/>
  </transition>
</mission>
"#;

    fn rendered(problems: &[Located]) -> Vec<String> {
        problems.iter().map(ToString::to_string).collect()
    }

    /// The problems of `xml` (none expected: `&[]`).
    fn check(xml: &str, expected: &[&str]) {
        let got = match MissionNet::parse(xml) {
            Ok(_) => Vec::new(),
            Err(problems) => rendered(&problems),
        };
        assert_eq!(got, expected, "for:\n{xml}");
    }

    /// A mission of the given lines, one per line from line 2.
    fn mission(lines: &[&str]) -> String {
        let mut out = String::from("<mission name=\"m\">\n");
        for line in lines {
            out.push_str(line);
            out.push('\n');
        }
        out.push_str("</mission>\n");
        out
    }

    #[test]
    fn the_example_parses() {
        let net = MissionNet::parse(PATROL).unwrap_or_else(|p| panic!("{:?}", rendered(&p)));
        assert_eq!(net.name, "patrol");
        assert_eq!(net.system, "system.xml");
        assert_eq!(net.places.len(), 2);
        let leg1 = &net.places[0];
        assert_eq!(leg1.modules, ["nav", "sim"]);
        assert_eq!(leg1.tokens, 1);
        assert!(!leg1.is_final);
        assert_eq!(
            (leg1.params[0].module.as_str(), leg1.params[0].name.as_str()),
            ("nav", "goal_x")
        );
        assert_eq!(leg1.params[0].pos, Pos { line: 6, col: 5 });
        assert!(net.places[1].is_final);
        let arrive = &net.transitions[0];
        assert_eq!(
            arrive.condition,
            Condition {
                delay_secs: Some(2.0),
                at_unix_secs: Some(1_795_377_600.0),
                event: Some("nav.goal_reached".into()),
                operator: false,
            }
        );
        assert_eq!(arrive.inputs[0].weight, 1);
        assert_eq!(arrive.outputs[0].weight, 1);
        assert_eq!(arrive.outputs[0].pos, Pos { line: 11, col: 5 });
        assert_eq!(arrive.pos, Pos { line: 9, col: 3 });
    }

    #[test]
    fn structural_problems() {
        check(PATROL, &[]);
        check("<mission name=\"empty\"/>", &[]);
        check("", &["1:1: document has no element"]);
        check(
            "<mission name=\"m\"><place name=\"a\"></mission>",
            &[
                "1:35: malformed XML: ill-formed document: expected `</place>`, but `</mission>` was found",
            ],
        );
        check(
            "<system name=\"s\"/>",
            &["1:1: expected <mission> at the top, found <system>"],
        );
        // Unknown elements and attributes, text, missing and empty attributes.
        check(
            &mission(&[
                "<place name=\"a\" color=\"red\"><modul name=\"x\"/></place>",
                "<arc/>",
                "<transition name=\"t\" guard=\"x\">hello<input place=\"a\" kind=\"x\"/><inhibitor/></transition>",
                "<place tokens=\"1\"><module/><param name=\"p\"/></place>",
                "<place name=\"\"><module name=\"n\">x</module></place>",
            ]),
            &[
                "2:17: unknown attribute `color` on <place> (expected one of: name, tokens, final)",
                "2:29: unknown element <modul> inside <place> (expected one of: module, param)",
                "3:1: unknown element <arc> inside <mission> (expected one of: place, transition)",
                "4:1: <transition> must not contain text (found `hello`)",
                "4:22: unknown attribute `guard` on <transition> (expected one of: name, priority, event, delay_secs, at, operator)",
                "4:54: unknown attribute `kind` on <input> (expected one of: place, weight)",
                "4:64: unknown element <inhibitor> inside <transition> (expected one of: input, output)",
                "5:1: <place> needs the attribute `name`",
                "5:19: <module> needs the attribute `name`",
                "5:28: <param> needs the attribute `module`",
                "5:28: <param> needs the attribute `value`",
                "6:8: attribute `name` of <place> must not be empty",
                "6:16: <module> must not contain text (found `x`)",
            ],
        );
        check(
            "<mission name=\"m\" system=\" \"/>",
            &["1:19: attribute `system` of <mission> must not be empty"],
        );
        // Names that are not identifiers.
        check(
            &mission(&[
                "<place name=\"leg 1\"><module name=\"nav.x\"/><param module=\"9\" name=\"a b\" value=\"\"/></place>",
                "<transition name=\"t-1.5\"><input place=\"-a\"/></transition>",
            ]),
            &[
                "2:8: name `leg 1` of <place> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "2:29: module name `nav.x` of <module> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "2:50: module name `9` of <param> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "2:61: parameter name `a b` of <param> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "3:13: name `t-1.5` of <transition> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "3:33: place name `-a` of <input> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
            ],
        );
        check(
            "<mission name=\"my mission\"/>",
            &[
                "1:10: name `my mission` of <mission> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
            ],
        );
    }

    #[test]
    fn numbers_dates_and_events() {
        check(
            &mission(&[
                "<place name=\"a\" tokens=\"-1\" final=\"yes\"/>",
                "<place name=\"b\" tokens=\"4294967296\"/>",
                "<place name=\"c\" tokens=\" 3 \" final=\"false\"/>",
                "<transition name=\"t\" priority=\"high\" delay_secs=\"-2\" at=\"tomorrow\" event=\"nav\">",
                "<input place=\"a\" weight=\"0\"/><input place=\"c\" weight=\"1.5\"/><output place=\"b\" weight=\"x\"/>",
                "</transition>",
                "<transition name=\"u\" priority=\"-3\" delay_secs=\"inf\" at=\"2026-02-30T00:00:00Z\" event=\"module.nav.died\">",
                "<input place=\"a\" weight=\"+2\"/>",
                "</transition>",
                "<transition name=\"v\" delay_secs=\"1e3\" at=\"2026-11-22T20:00:00\" event=\"a.b.c\"><input place=\"a\"/></transition>",
                "<transition name=\"w\" delay_secs=\" 0.5\" at=\" 2026-11-22T20:00:00+01:00 \" event=\"module.nav.failed\"><input place=\"a\"/></transition>",
            ]),
            &[
                "2:17: the number of tokens must be a whole number, 0 or more, not `-1`",
                "2:29: `final` must be `true` or `false`, not `yes`",
                "3:17: the number of tokens must be a whole number, 0 or more, not `4294967296`",
                "4:17: the number of tokens must be a whole number, 0 or more, not ` 3 `",
                "5:22: `priority` must be a whole number (higher fires first), not `high`",
                "5:38: `delay_secs` must be a number of seconds, 0 or more (like 2 or 0.5), not `-2`",
                "5:54: `at` must be a date like 2026-11-22T20:00:00Z or 2026-11-22T21:00:00+01:00, not `tomorrow`: expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm",
                "5:68: `event` must be MODULE.EVENT, or module.ID.failed for the failure of module ID, not `nav`",
                "6:18: the weight of an arc must be a whole number of tokens, 1 or more, not `0`",
                "6:47: the weight of an arc must be a whole number of tokens, 1 or more, not `1.5`",
                "6:79: the weight of an arc must be a whole number of tokens, 1 or more, not `x`",
                "8:36: `delay_secs` must be a number of seconds, 0 or more (like 2 or 0.5), not `inf`",
                "8:53: `at` must be a date like 2026-11-22T20:00:00Z or 2026-11-22T21:00:00+01:00, not `2026-02-30T00:00:00Z`: there is no day 30 in 2026-02 (28 days)",
                "8:79: `event` must be MODULE.EVENT, or module.ID.failed for the failure of module ID, not `module.nav.died`",
                "9:18: the weight of an arc must be a whole number of tokens, 1 or more, not `+2`",
                "11:22: `delay_secs` must be a number of seconds, 0 or more (like 2 or 0.5), not `1e3`",
                "11:39: `at` must be a date like 2026-11-22T20:00:00Z or 2026-11-22T21:00:00+01:00, not `2026-11-22T20:00:00`: expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm (the time zone is missing or malformed)",
                "11:64: `event` must be MODULE.EVENT, or module.ID.failed for the failure of module ID, not `a.b.c`",
            ],
        );
    }

    #[test]
    fn problems_between_elements() {
        check(
            &mission(&[
                "<place name=\"a\" tokens=\"1\"><module name=\"nav\"/><module name=\"nav\"/>",
                "  <param module=\"nav\" name=\"x\" value=\"1\"/><param module=\"nav\" name=\"x\" value=\"2\"/>",
                "  <param module=\"sim\" name=\"y\" value=\"1\"/>",
                "</place>",
                "<place name=\"a\"/>",
                "<transition name=\"a\"><input place=\"a\"/></transition>",
                "<transition name=\"t\"><input place=\"a\"/><input place=\"a\" weight=\"2\"/>",
                "  <output place=\"ghost\"/><output place=\"b\"/><output place=\"b\"/></transition>",
                "<transition name=\"t\"><output place=\"a\"/></transition>",
                "<place name=\"b\"/>",
            ]),
            &[
                "2:48: place `a` already runs module `nav` (line 2)",
                "3:43: place `a` already sets parameter `x` of module `nav` (line 3)",
                "4:3: place `a` sets parameter `y` of module `sim`, which it does not run (add <module name=\"sim\"/> to the place)",
                "6:1: place `a`: the name is already used by the place at line 2 (places and transitions need distinct names)",
                "7:1: transition `a`: the name is already used by the place at line 2 (places and transitions need distinct names)",
                "8:40: transition `t` already has an input arc from place `a` (line 8); give one arc with a weight",
                "9:3: transition `t`: no place `ghost` (places: a, b)",
                "9:45: transition `t` already has an output arc to place `b` (line 9); give one arc with a weight",
                "10:1: transition `t`: the name is already used by the transition at line 8 (places and transitions need distinct names)",
                "10:1: transition `t` has no input arc: it would always be enabled and fire forever (give it an <input place=\"...\"/>)",
            ],
        );
    }

    /// `xml` parses, and writing it then reading it back gives the same net.
    fn round_trip(xml: &str) {
        let net = MissionNet::parse(xml).unwrap_or_else(|p| panic!("{:?}", rendered(&p)));
        let written = net.to_xml();
        let again =
            MissionNet::parse(&written).unwrap_or_else(|p| panic!("{written}\n{:?}", rendered(&p)));
        assert_eq!(
            again.without_positions(),
            net.without_positions(),
            "{written}"
        );
    }

    #[test]
    fn round_trips_through_xml() {
        round_trip(PATROL);
        round_trip("<mission name=\"m\"/>");
        round_trip(
            "<mission name=\"m\" system=\"../a &amp; b/système.xml\">\n<place name=\"p\" tokens=\"4294967295\" final=\"false\">\n<param module=\"n\" name=\"text\" value=\"&lt;a &amp; 'b' &quot;c&quot;&gt;&#10;&#9;next&#13;\"/><module name=\"n\"/><param module=\"n\" name=\"empty\" value=\"\"/></place>\n<transition name=\"t\" priority=\"-2147483648\" delay_secs=\"0.1\" at=\"1969-12-31T23:59:59.123Z\"><output place=\"p\" weight=\"4294967295\"/><input place=\"p\" weight=\"3\"/></transition>\n<transition name=\"u\" priority=\"7\" event=\"module.n.failed\" at=\"2026-11-22T21:00:00.5+01:00\"><input place=\"p\"/></transition></mission>",
        );
        // Values set in code, written then read.
        let mut net = MissionNet::parse(PATROL).expect("valid");
        net.places[0].params[0].value = "a\r\nb\t\"c\" <d> & 'e'".into();
        net.transitions[0].condition.delay_secs = Some(1.0 / 3.0);
        net.transitions[0].condition.at_unix_secs = Some(1_795_377_600.0 + 1.0 / 3.0);
        round_trip(&net.to_xml());
        let again = MissionNet::parse(&net.to_xml()).expect("valid");
        assert_eq!(again.places[0].params[0].value, "a\r\nb\t\"c\" <d> & 'e'");
        assert_eq!(again.transitions[0].condition, net.transitions[0].condition);
    }
}
