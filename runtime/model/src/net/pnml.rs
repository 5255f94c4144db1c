//! PNML (ISO/IEC 15909-2, version 2009) place/transition nets, to exchange missions with other
//! Petri net tools.
//!
//! [`to_pnml`] writes one net on one page: places with their `<name>` and `<initialMarking>`,
//! transitions with their `<name>`, arcs with their `<inscription>`. Node ids are the mission's
//! names. What PNML has no words for (the modules and parameters of places, final places,
//! priorities and conditions of transitions, the mission's name and system) goes in
//! `<toolspecific tool="ArMoR" version="1">` elements, which other tools ignore:
//!
//! ```xml
//! <place id="leg1">
//!   <name><text>leg1</text></name>
//!   <initialMarking><text>1</text></initialMarking>
//!   <toolspecific tool="ArMoR" version="1">
//!     <module name="nav"/>
//!     <param module="nav" name="goal_x" value="10"/>
//!     <final/>
//!   </toolspecific>
//! </place>
//! <transition id="arrive">
//!   <name><text>arrive</text></name>
//!   <toolspecific tool="ArMoR" version="1">
//!     <condition priority="1" event="nav.goal_reached" delay_secs="2" at="2026-11-22T20:00:00Z"/>
//!   </toolspecific>
//! </transition>
//! ```
//!
//! [`from_pnml`] reads that back without loss, and reads standard place/transition nets from
//! other tools (without ArMoR's data: no modules, no conditions), taking node ids as names
//! (`<name>` labels are only shown by tools). It refuses what a place/transition mission cannot
//! be: other net types (symmetric, high-level), high-level labels (`<hlinscription>`,
//! `<hlinitialMarking>`, `<structure>`, `<type>`, `<condition>`), `<declaration>`s, reference
//! nodes, and arcs between two places or two transitions.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use armor_module_api::xml::{self as tree, Element, Located, Pos};

use super::{
    Arc, Condition, MissionNet, Place, PlaceParam, Transition, check_structure, read_date,
    read_delay, read_event, read_operator, read_priority, read_tokens, read_weight,
    write_condition_attrs,
};
use crate::fields::{
    Field, escape, finish, identifier, no_children, no_text, optional, read_identifier, required,
};

/// The namespace of PNML 2009 documents.
pub const PNML_NAMESPACE: &str = "http://www.pnml.org/version-2009/grammar/pnml";
/// The type of place/transition nets.
pub const PTNET_TYPE: &str = "http://www.pnml.org/version-2009/grammar/ptnet";
/// The PNML core model's type, which pm4py and ProM write for place/transition nets (with
/// markings and inscriptions the core model does not define).
pub const CORE_MODEL_TYPE: &str = "http://www.pnml.org/version-2009/grammar/pnmlcoremodel";

const TOOL: &str = "ArMoR";
const TOOL_VERSION: &str = "1";

/// Writes the mission as a PNML place/transition net (see the module documentation).
pub fn to_pnml(net: &MissionNet) -> String {
    let mut used: std::collections::BTreeSet<String> = net
        .places
        .iter()
        .map(|place| place.name.clone())
        .chain(net.transitions.iter().map(|t| t.name.clone()))
        .collect();
    let net_id = fresh(
        if net.name.is_empty() {
            "net"
        } else {
            &net.name
        },
        &mut used,
    );
    let page_id = fresh("page", &mut used);
    let tool = format!("<toolspecific tool=\"{TOOL}\" version=\"{TOOL_VERSION}\">");
    let e = |text: &str| escape(text);
    let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    let _ = writeln!(out, "<pnml xmlns=\"{PNML_NAMESPACE}\">");
    let _ = writeln!(out, "  <net id=\"{}\" type=\"{PTNET_TYPE}\">", e(&net_id));
    let _ = writeln!(out, "    <name><text>{}</text></name>", e(&net.name));
    let _ = write!(out, "    {tool}\n      <mission name=\"{}\"", e(&net.name));
    if !net.system.is_empty() {
        let _ = write!(out, " system=\"{}\"", e(&net.system));
    }
    out.push_str("/>\n    </toolspecific>\n");
    let _ = writeln!(out, "    <page id=\"{}\">", e(&page_id));
    for place in &net.places {
        let _ = writeln!(out, "      <place id=\"{}\">", e(&place.name));
        let _ = writeln!(out, "        <name><text>{}</text></name>", e(&place.name));
        if place.tokens > 0 {
            let _ = writeln!(
                out,
                "        <initialMarking><text>{}</text></initialMarking>",
                place.tokens
            );
        }
        if !place.modules.is_empty() || !place.params.is_empty() || place.is_final {
            let _ = writeln!(out, "        {tool}");
            for module in &place.modules {
                let _ = writeln!(out, "          <module name=\"{}\"/>", e(module));
            }
            for param in &place.params {
                let _ = writeln!(
                    out,
                    "          <param module=\"{}\" name=\"{}\" value=\"{}\"/>",
                    e(&param.module),
                    e(&param.name),
                    e(&param.value)
                );
            }
            if place.is_final {
                out.push_str("          <final/>\n");
            }
            out.push_str("        </toolspecific>\n");
        }
        out.push_str("      </place>\n");
    }
    for transition in &net.transitions {
        let _ = writeln!(out, "      <transition id=\"{}\">", e(&transition.name));
        let _ = writeln!(
            out,
            "        <name><text>{}</text></name>",
            e(&transition.name)
        );
        let condition = &transition.condition;
        if transition.priority != 0 || !condition.is_empty() {
            let _ = write!(out, "        {tool}\n          <condition");
            write_condition_attrs(&mut out, transition.priority, condition);
            out.push_str("/>\n        </toolspecific>\n");
        }
        out.push_str("      </transition>\n");
    }
    for transition in &net.transitions {
        let arcs = transition
            .inputs
            .iter()
            .map(|arc| (arc, &arc.place, &transition.name))
            .chain(
                transition
                    .outputs
                    .iter()
                    .map(|arc| (arc, &transition.name, &arc.place)),
            );
        for (arc, source, target) in arcs {
            let id = fresh(&format!("{source}-{target}"), &mut used);
            let _ = writeln!(
                out,
                "      <arc id=\"{}\" source=\"{}\" target=\"{}\">",
                e(&id),
                e(source),
                e(target)
            );
            let _ = writeln!(
                out,
                "        <inscription><text>{}</text></inscription>",
                arc.weight
            );
            out.push_str("      </arc>\n");
        }
    }
    out.push_str("    </page>\n  </net>\n</pnml>\n");
    out
}

/// A label of another tool made into a name: characters other than letters, digits, `_` and
/// `-` become `_`, and a name that would start with a digit or `-` gets the kind's first letter
/// (`p` or `t`) in front.
fn as_name(label: &str, kind: &str) -> String {
    let mut name: String = label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if !name.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_') {
        name.insert(0, '_');
        name.insert(0, kind.chars().next().unwrap_or('n'));
    }
    name
}

/// `base`, or `base-2`, `base-3`... whichever is not in `used`; then it is.
fn fresh(base: &str, used: &mut std::collections::BTreeSet<String>) -> String {
    let mut id = base.to_owned();
    let mut n = 1;
    while used.contains(&id) {
        n += 1;
        id = format!("{base}-{n}");
    }
    used.insert(id.clone());
    id
}

/// Why an element of high-level or other PNML nets is refused.
fn unsupported(name: &str) -> Option<&'static str> {
    Some(match name {
        "declaration" | "declarations" => {
            "declarations belong to coloured and high-level nets; ArMoR reads place/transition nets"
        }
        "hlinscription" => {
            "high-level inscriptions belong to coloured nets; an arc of a place/transition net \
             has an <inscription> with a number of tokens"
        }
        "hlinitialMarking" => {
            "high-level markings belong to coloured nets; a place of a place/transition net has \
             an <initialMarking> with a number of tokens"
        }
        "structure" => "high-level terms belong to coloured nets; ArMoR reads the <text> of labels",
        "type" => {
            "sorts of places and types of arcs (inhibitor, reset, read arcs) are not part of \
             place/transition nets"
        }
        "condition" => {
            "guards belong to high-level nets; ArMoR conditions go in <toolspecific tool=\"ArMoR\">"
        }
        "referencePlace" | "referenceTransition" => {
            "reference nodes are not supported; put the nodes themselves on the pages"
        }
        _ => return None,
    })
}

/// Problems for every child not in `allowed`, saying why when it is a known unsupported one.
fn check_children(element: &Element, allowed: &[&str], problems: &mut Vec<Located>) {
    for child in &element.children {
        if allowed.contains(&child.name.as_str()) {
            continue;
        }
        let message = match unsupported(&child.name) {
            Some(why) => format!(
                "<{}> inside <{}> is not supported: {why}",
                child.name, element.name
            ),
            None => format!(
                "unknown element <{}> inside <{}> (expected one of: {})",
                child.name,
                element.name,
                allowed.join(", ")
            ),
        };
        problems.push(Located::new(child.pos, message));
    }
}

/// A node of the net, by id.
#[derive(Clone, Copy)]
enum Node {
    Place(usize),
    Transition(usize),
}

/// What the walk through the pages collects.
struct Reader<'a> {
    net: MissionNet,
    problems: Vec<Located>,
    /// Every id -> where it is defined.
    ids: BTreeMap<String, Pos>,
    nodes: BTreeMap<String, Node>,
    /// Ids of nodes refused (already reported): arcs to them say nothing more.
    refused: std::collections::BTreeSet<String>,
    /// A `pnmlcoremodel` net of another tool: names are made from labels, not taken from ids.
    core_model: bool,
    /// The names given so far (core model).
    names: std::collections::BTreeSet<String>,
    warnings: Vec<Located>,
    arcs: Vec<&'a Element<'a>>,
}

/// Reads a PNML document holding one place/transition net, reporting every problem found,
/// sorted by position (see the module documentation for what is refused).
pub fn from_pnml(text: &str) -> Result<MissionNet, Vec<Located>> {
    read_pnml(text).map(|(net, _)| net)
}

/// [`from_pnml`], with the warnings of a net read leniently: a `pnmlcoremodel` net written by
/// another tool (pm4py, ProM) that carries P/T markings and inscriptions is read as a
/// place/transition net; its nodes are named after their `<name>` labels (or ids) made into
/// names, and the places of its `<finalmarkings>` become final places.
pub fn read_pnml(text: &str) -> Result<(MissionNet, Vec<Located>), Vec<Located>> {
    let root = tree::parse_document(text, "pnml")?;
    if let Some(namespace) = root.attr("xmlns")
        && namespace.value != PNML_NAMESPACE
    {
        return Err(vec![Located::new(
            namespace.pos,
            format!(
                "namespace `{}` is not the one of PNML 2009 (`{PNML_NAMESPACE}`)",
                namespace.value
            ),
        )]);
    }
    let mut problems = root.unknown_attrs(&[]);
    check_children(&root, &["net"], &mut problems);
    no_text(&root, &mut problems);
    let mut nets = root.children_named("net");
    let Some(net_element) = nets.next() else {
        problems.push(Located::new(root.pos, "the document holds no <net>"));
        return finish((MissionNet::default(), Vec::new()), problems);
    };
    for other in nets {
        problems.push(Located::new(
            other.pos,
            "a second <net>: a mission is one net, give one net per document",
        ));
    }
    match net_element.attr("type") {
        None => {
            problems.push(Located::new(
                net_element.pos,
                format!(
                    "<net> needs the attribute `type` (`{PTNET_TYPE}` for place/transition nets)"
                ),
            ));
            return finish((MissionNet::default(), Vec::new()), problems);
        }
        Some(attr) if attr.value == CORE_MODEL_TYPE => {}
        Some(attr) if attr.value != PTNET_TYPE => {
            let kind = match attr.value.rsplit('/').next().unwrap_or_default() {
                "symmetricnet" => " (a symmetric net)",
                "highlevelnet" => " (a high-level net)",
                "pt-hlpng" => " (a place/transition net in high-level notation)",
                _ => "",
            };
            return Err(vec![Located::new(
                attr.pos,
                format!(
                    "net type `{}`{kind} is not supported: ArMoR reads place/transition nets (`{PTNET_TYPE}`)",
                    attr.value
                ),
            )]);
        }
        Some(_) => {}
    }
    let core_model = net_element.attr_value("type") == Some(CORE_MODEL_TYPE);
    let mut reader = Reader {
        net: MissionNet {
            pos: net_element.pos,
            ..MissionNet::default()
        },
        problems,
        core_model,
        names: std::collections::BTreeSet::new(),
        warnings: Vec::new(),
        ids: BTreeMap::new(),
        nodes: BTreeMap::new(),
        refused: std::collections::BTreeSet::new(),
        arcs: Vec::new(),
    };
    reader.read_net(net_element);
    reader.resolve_arcs();
    if core_model {
        reader.read_final_markings(net_element);
        reader.warnings.push(Located::new(
            net_element
                .attr("type")
                .map_or(net_element.pos, |attr| attr.pos),
            format!(
                "a `pnmlcoremodel` net, read as a place/transition net ({}, {} with tokens; nodes \
                 named after their labels)",
                crate::plural(reader.net.places.len(), "place"),
                crate::plural(
                    reader
                        .net
                        .places
                        .iter()
                        .filter(|place| place.tokens > 0)
                        .count(),
                    "place"
                )
            ),
        ));
    }
    let Reader {
        net,
        mut problems,
        warnings,
        ..
    } = reader;
    check_structure(&net, &mut problems);
    finish((net, warnings), problems)
}

impl<'a> Reader<'a> {
    /// The element's id, registered; `None` if missing or already used (reported).
    fn id(&mut self, element: &Element) -> Option<String> {
        let field = required(element, "id", &mut self.problems)?;
        if let Some(first) = self.ids.get(field.value) {
            self.problems.push(Located::new(
                field.pos,
                format!(
                    "id `{}` is already used at line {}",
                    field.value, first.line
                ),
            ));
            return None;
        }
        self.ids.insert(field.value.to_owned(), element.pos);
        Some(field.value.to_owned())
    }

    /// The node's id and its mission name: the id itself, or in a core-model net of another tool
    /// its `<name>` label (or id) made into a name, unique in the net.
    fn node_name(&mut self, element: &Element) -> Option<(String, String)> {
        let id = self.id(element)?;
        if self.core_model {
            let label = element
                .children_named("name")
                .flat_map(|name| name.children_named("text"))
                .map(|text| text.text.trim())
                .find(|text| !text.is_empty())
                .unwrap_or(&id);
            let name = fresh(&as_name(label, &element.name), &mut self.names);
            return Some((id, name));
        }
        let pos = element.attr("id").map_or(element.pos, |attr| attr.pos);
        match read_identifier(
            Field::new(&id, pos),
            "id",
            &format!("<{}>, which ArMoR uses as its name,", element.name),
        ) {
            Ok(name) => Some((id, name)),
            Err(err) => {
                self.problems.push(err);
                self.refused.insert(id);
                None
            }
        }
    }

    /// The places a core-model net's `<finalmarkings>` mark (pm4py's form: `<marking>` of
    /// `<place idref="…"><text>1</text></place>`) become final places.
    fn read_final_markings(&mut self, net_element: &Element) {
        for marking in net_element
            .children_named("finalmarkings")
            .flat_map(|markings| markings.children_named("marking"))
        {
            for place in marking.children_named("place") {
                let Some(idref) = place.attr("idref") else {
                    self.problems.push(Located::new(
                        place.pos,
                        "final marking: <place> needs the attribute `idref`",
                    ));
                    continue;
                };
                let marked = place
                    .children_named("text")
                    .any(|text| text.text.trim().parse::<u32>().is_ok_and(|n| n > 0));
                match self.nodes.get(idref.value.as_str()) {
                    Some(Node::Place(index)) if marked => self.net.places[*index].is_final = true,
                    Some(_) if !marked => {}
                    _ => self.problems.push(Located::new(
                        idref.pos,
                        format!("final marking: no place `{}`", idref.value),
                    )),
                }
            }
        }
    }

    fn read_net(&mut self, element: &'a Element<'a>) {
        self.problems.extend(element.unknown_attrs(&["id", "type"]));
        let allowed: &[&str] = if self.core_model {
            &["name", "page", "toolspecific", "finalmarkings"]
        } else {
            &["name", "page", "toolspecific"]
        };
        check_children(element, allowed, &mut self.problems);
        no_text(element, &mut self.problems);
        let id = self.id(element);
        let mut name = None;
        for child in &element.children {
            match child.name.as_str() {
                "name" => {
                    self.read_label(child, false);
                }
                "page" => self.read_page(child),
                "toolspecific" => {
                    for data in self.ours(child, &["mission"]) {
                        self.problems
                            .extend(data.unknown_attrs(&["name", "system"]));
                        no_children(data, &mut self.problems);
                        no_text(data, &mut self.problems);
                        name = identifier(data, "name", "mission name", &mut self.problems);
                        if data.attr("system").is_some()
                            && let Some(system) = required(data, "system", &mut self.problems)
                        {
                            self.net.system = system.value.to_owned();
                        }
                    }
                }
                _ => {}
            }
        }
        self.net.name = match (name, id) {
            (Some(name), _) => name,
            (None, Some(id)) if self.core_model => as_name(&id, "net"),
            (None, Some(id)) => {
                let pos = element.attr("id").map_or(element.pos, |attr| attr.pos);
                read_identifier(
                    Field::new(&id, pos),
                    "id",
                    "<net>, which ArMoR uses as the mission's name,",
                )
                .map_err(|err| self.problems.push(err))
                .unwrap_or_default()
            }
            (None, None) => String::new(),
        };
        if !element.children.iter().any(|child| child.name == "page") {
            self.problems.push(Located::new(
                element.pos,
                "<net> has no <page>: places, transitions and arcs go on a page",
            ));
        }
    }

    fn read_page(&mut self, element: &'a Element<'a>) {
        self.problems.extend(element.unknown_attrs(&["id"]));
        check_children(
            element,
            &[
                "name",
                "page",
                "place",
                "transition",
                "arc",
                "toolspecific",
                "graphics",
            ],
            &mut self.problems,
        );
        no_text(element, &mut self.problems);
        self.id(element);
        for child in &element.children {
            match child.name.as_str() {
                "name" => {
                    self.read_label(child, false);
                }
                "page" => self.read_page(child),
                "place" => self.read_place(child),
                "transition" => self.read_transition(child),
                "arc" => {
                    self.problems
                        .extend(child.unknown_attrs(&["id", "source", "target"]));
                    check_children(
                        child,
                        &["name", "inscription", "graphics", "toolspecific"],
                        &mut self.problems,
                    );
                    no_text(child, &mut self.problems);
                    if self.id(child).is_some() {
                        self.arcs.push(child);
                    }
                }
                "toolspecific" => {
                    self.ours(child, &[]);
                }
                _ => {}
            }
        }
    }

    fn read_place(&mut self, element: &Element) {
        self.problems.extend(element.unknown_attrs(&["id"]));
        check_children(
            element,
            &["name", "initialMarking", "graphics", "toolspecific"],
            &mut self.problems,
        );
        no_text(element, &mut self.problems);
        let named = self.node_name(element);
        let mut place = Place {
            name: named
                .as_ref()
                .map(|(_, name)| name.clone())
                .unwrap_or_default(),
            pos: element.pos,
            ..Place::default()
        };
        let mut modules: BTreeMap<String, Pos> = BTreeMap::new();
        for child in &element.children {
            match child.name.as_str() {
                "name" => {
                    self.read_label(child, false);
                }
                "initialMarking" => {
                    if let Some(field) = self.read_label(child, true) {
                        place.tokens = read_tokens(field)
                            .map_err(|err| self.problems.push(err))
                            .unwrap_or(0);
                    }
                }
                "toolspecific" => {
                    for data in self.ours(child, &["module", "param", "final"]) {
                        match data.name.as_str() {
                            "module" => {
                                self.problems.extend(data.unknown_attrs(&["name"]));
                                no_children(data, &mut self.problems);
                                no_text(data, &mut self.problems);
                                let Some(module) =
                                    identifier(data, "name", "module name", &mut self.problems)
                                else {
                                    continue;
                                };
                                if let Some(first) = modules.get(&module) {
                                    self.problems.push(Located::new(
                                        data.pos,
                                        format!(
                                            "place `{}` already runs module `{module}` (line {})",
                                            place.name, first.line
                                        ),
                                    ));
                                    continue;
                                }
                                modules.insert(module.clone(), data.pos);
                                place.modules.push(module);
                            }
                            "param" => {
                                self.problems
                                    .extend(data.unknown_attrs(&["module", "name", "value"]));
                                no_children(data, &mut self.problems);
                                no_text(data, &mut self.problems);
                                let module =
                                    identifier(data, "module", "module name", &mut self.problems);
                                let name =
                                    identifier(data, "name", "parameter name", &mut self.problems);
                                let value = data.attr("value");
                                if value.is_none() {
                                    self.problems.push(Located::new(
                                        data.pos,
                                        "<param> needs the attribute `value`",
                                    ));
                                }
                                place.params.push(PlaceParam {
                                    module: module.unwrap_or_default(),
                                    name: name.unwrap_or_default(),
                                    value: value
                                        .map(|attr| attr.value.as_str().to_owned())
                                        .unwrap_or_default(),
                                    pos: data.pos,
                                });
                            }
                            _ => {
                                self.problems.extend(data.unknown_attrs(&[]));
                                no_children(data, &mut self.problems);
                                no_text(data, &mut self.problems);
                                place.is_final = true;
                            }
                        }
                    }
                }
                _ => {}
            }
        }
        if let Some((id, _)) = named {
            self.nodes.insert(id, Node::Place(self.net.places.len()));
            self.net.places.push(place);
        }
    }

    fn read_transition(&mut self, element: &Element) {
        self.problems.extend(element.unknown_attrs(&["id"]));
        check_children(
            element,
            &["name", "graphics", "toolspecific"],
            &mut self.problems,
        );
        no_text(element, &mut self.problems);
        let named = self.node_name(element);
        let mut transition = Transition {
            name: named
                .as_ref()
                .map(|(_, name)| name.clone())
                .unwrap_or_default(),
            pos: element.pos,
            ..Transition::default()
        };
        for child in &element.children {
            match child.name.as_str() {
                "name" => {
                    self.read_label(child, false);
                }
                "toolspecific" => {
                    for data in self.ours(child, &["condition"]) {
                        let problems = &mut self.problems;
                        problems.extend(data.unknown_attrs(&[
                            "priority",
                            "event",
                            "delay_secs",
                            "at",
                            "operator",
                        ]));
                        no_children(data, problems);
                        no_text(data, problems);
                        transition.priority =
                            optional(data, "priority", read_priority, problems).unwrap_or(0);
                        transition.condition = Condition {
                            delay_secs: optional(data, "delay_secs", read_delay, problems),
                            at_unix_secs: optional(data, "at", read_date, problems),
                            event: optional(data, "event", read_event, problems),
                            operator: optional(data, "operator", read_operator, problems)
                                .unwrap_or(false),
                        };
                    }
                }
                _ => {}
            }
        }
        if let Some((id, _)) = named {
            self.nodes
                .insert(id, Node::Transition(self.net.transitions.len()));
            self.net.transitions.push(transition);
        }
    }

    /// Checks a label (`<name>`, `<initialMarking>`, `<inscription>`); with `needs_text`, its
    /// `<text>` is returned (a problem if missing).
    fn read_label<'e>(&mut self, element: &'e Element<'e>, needs_text: bool) -> Option<Field<'e>> {
        self.problems.extend(element.unknown_attrs(&[]));
        check_children(
            element,
            &["text", "graphics", "toolspecific"],
            &mut self.problems,
        );
        no_text(element, &mut self.problems);
        let mut text = None;
        for child in &element.children {
            match child.name.as_str() {
                "text" => {
                    self.problems.extend(child.unknown_attrs(&[]));
                    no_children(child, &mut self.problems);
                    // Tools indent the text of labels: only the number counts.
                    text = Some(Field::new(child.text.trim(), child.pos));
                }
                "toolspecific" => {
                    self.ours(child, &[]);
                }
                _ => {}
            }
        }
        if needs_text && text.is_none() {
            self.problems.push(Located::new(
                element.pos,
                format!("<{}> needs a <text> with a number of tokens", element.name),
            ));
        }
        text
    }

    /// The children of a `<toolspecific>` element if it is ArMoR's (checked against
    /// `allowed`); nothing for other tools' data, which is left alone.
    fn ours<'e>(&mut self, element: &'e Element<'e>, allowed: &[&str]) -> Vec<&'e Element<'e>> {
        let Some(tool) = element.attr("tool") else {
            self.problems.push(Located::new(
                element.pos,
                "<toolspecific> needs the attribute `tool`",
            ));
            return Vec::new();
        };
        if tool.value != TOOL {
            return Vec::new();
        }
        self.problems
            .extend(element.unknown_attrs(&["tool", "version"]));
        no_text(element, &mut self.problems);
        match element.attr("version") {
            Some(version) if version.value == TOOL_VERSION => {}
            Some(version) => {
                self.problems.push(Located::new(
                    version.pos,
                    format!(
                        "ArMoR data of version `{}` is not supported (this ArMoR reads version {TOOL_VERSION})",
                        version.value
                    ),
                ));
                return Vec::new();
            }
            None => {
                self.problems.push(Located::new(
                    element.pos,
                    "<toolspecific> needs the attribute `version`",
                ));
                return Vec::new();
            }
        }
        if allowed.is_empty() {
            if !element.children.is_empty() {
                self.problems.push(Located::new(
                    element.pos,
                    "ArMoR keeps no data here: remove this <toolspecific tool=\"ArMoR\">",
                ));
            }
            return Vec::new();
        }
        self.problems.extend(element.unknown_children(allowed));
        element
            .children
            .iter()
            .filter(|child| allowed.contains(&child.name.as_str()))
            .collect()
    }

    /// Makes the arcs into the transitions' inputs and outputs, in document order.
    fn resolve_arcs(&mut self) {
        for element in std::mem::take(&mut self.arcs) {
            let id = element.attr_value("id").unwrap_or_default().to_owned();
            let source = required(element, "source", &mut self.problems);
            let target = required(element, "target", &mut self.problems);
            let mut weight = 1;
            for child in element.children_named("inscription") {
                if let Some(field) = self.read_label(child, true) {
                    weight = read_weight(field)
                        .map_err(|err| self.problems.push(err))
                        .unwrap_or(1);
                }
            }
            for child in &element.children {
                match child.name.as_str() {
                    "name" => {
                        self.read_label(child, false);
                    }
                    "toolspecific" => {
                        self.ours(child, &[]);
                    }
                    _ => {}
                }
            }
            let (Some(source), Some(target)) = (source, target) else {
                continue;
            };
            let (Some(from), Some(to)) = (self.node(&id, source), self.node(&id, target)) else {
                continue;
            };
            let arc = |place: usize, net: &MissionNet| Arc {
                place: net.places[place].name.clone(),
                weight,
                pos: element.pos,
            };
            match (from, to) {
                (Node::Place(place), Node::Transition(transition)) => {
                    let arc = arc(place, &self.net);
                    self.net.transitions[transition].inputs.push(arc);
                }
                (Node::Transition(transition), Node::Place(place)) => {
                    let arc = arc(place, &self.net);
                    self.net.transitions[transition].outputs.push(arc);
                }
                (Node::Place(_), Node::Place(_)) | (Node::Transition(_), Node::Transition(_)) => {
                    let kind = match from {
                        Node::Place(_) => "place",
                        Node::Transition(_) => "transition",
                    };
                    self.problems.push(Located::new(
                        element.pos,
                        format!(
                            "arc `{id}` goes from {kind} `{}` to {kind} `{}`: an arc joins a place and a transition",
                            source.value, target.value
                        ),
                    ));
                }
            }
        }
    }

    fn node(&mut self, arc: &str, end: Field<'_>) -> Option<Node> {
        let node = self.nodes.get(end.value).copied();
        if node.is_none() && !self.refused.contains(end.value) {
            let message = if self.ids.contains_key(end.value) {
                format!(
                    "arc `{arc}`: `{}` is not a place or a transition",
                    end.value
                )
            } else {
                format!("arc `{arc}`: no place or transition `{}`", end.value)
            };
            self.problems.push(Located::new(end.pos, message));
        }
        node
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PATROL: &str = r#"<mission name="patrol" system="system.xml">
  <place name="leg1" tokens="1">
    <module name="nav"/>
    <module name="sim"/>
    <param module="nav" name="goal_x" value="10 &amp; &lt;more&gt;"/>
  </place>
  <place name="leg2"><module name="nav"/></place>
  <place name="done" final="true"/>
  <place name="aborted" final="true"/>
  <transition name="arrive" priority="2" event="nav.goal_reached" delay_secs="2.5" at="2026-11-22T20:00:00.125Z">
    <input place="leg1" weight="1"/>
    <output place="leg2" weight="3"/>
  </transition>
  <transition name="finish"><input place="leg2" weight="3"/><output place="done"/></transition>
  <transition name="fault" priority="-1" event="module.nav.failed"><input place="leg1"/><input place="leg2"/><output place="aborted"/></transition>
</mission>"#;

    fn rendered(problems: &[Located]) -> Vec<String> {
        problems.iter().map(ToString::to_string).collect()
    }

    fn check(pnml: &str, expected: &[&str]) {
        let got = match from_pnml(pnml) {
            Ok(_) => Vec::new(),
            Err(problems) => rendered(&problems),
        };
        assert_eq!(got, expected, "for:\n{pnml}");
    }

    /// A PNML document whose page holds `lines`, one per line from line 4.
    fn document(lines: &[&str]) -> String {
        let mut out = format!(
            "<pnml xmlns=\"{PNML_NAMESPACE}\">\n<net id=\"n\" type=\"{PTNET_TYPE}\">\n<page id=\"pg\">\n"
        );
        for line in lines {
            out.push_str(line);
            out.push('\n');
        }
        out.push_str("</page>\n</net>\n</pnml>\n");
        out
    }

    #[test]
    fn round_trip_is_lossless() {
        for xml in [
            PATROL,
            "<mission name=\"empty\"/>",
            "<mission name=\"x\"><place name=\"x-2\"/><place name=\"page\" tokens=\"2\"/><place name=\"x\"/><transition name=\"t\"><input place=\"x\"/><output place=\"x\"/></transition><transition name=\"x-t\"><input place=\"page\"/></transition></mission>",
        ] {
            let net = MissionNet::parse(xml).unwrap_or_else(|p| panic!("{:?}", rendered(&p)));
            let pnml = to_pnml(&net);
            let again = from_pnml(&pnml).unwrap_or_else(|p| panic!("{pnml}\n{:?}", rendered(&p)));
            assert_eq!(again.without_positions(), net.without_positions(), "{pnml}");
        }
        let philosophers = super::super::dining_philosophers(3);
        let again = from_pnml(&to_pnml(&philosophers)).expect("valid");
        assert_eq!(again.without_positions(), philosophers);
    }

    #[test]
    fn the_export_is_standard_pnml() {
        let net = MissionNet::parse(PATROL).expect("valid");
        let pnml = to_pnml(&net);
        let root = tree::parse(&pnml).expect("well-formed");
        assert_eq!(root.attr_value("xmlns"), Some(PNML_NAMESPACE));
        let net_element = &root.children[0];
        assert_eq!(net_element.attr_value("type"), Some(PTNET_TYPE));
        let pages: Vec<_> = net_element.children_named("page").collect();
        assert_eq!(pages.len(), 1);
        let page = pages[0];
        assert_eq!(page.children_named("place").count(), 4);
        assert_eq!(page.children_named("transition").count(), 3);
        assert_eq!(page.children_named("arc").count(), 7);
        assert!(pnml.contains(
            "<arc id=\"leg2-finish\" source=\"leg2\" target=\"finish\">\n        <inscription><text>3</text></inscription>"
        ));
        assert!(pnml.contains("<initialMarking><text>1</text></initialMarking>"));
        assert!(pnml.contains(
            "<condition priority=\"2\" event=\"nav.goal_reached\" delay_secs=\"2.5\" at=\"2026-11-22T20:00:00.125Z\"/>"
        ));
        // Ids stay unique when names look like generated ids.
        let net = MissionNet::parse(
            "<mission name=\"page\"><place name=\"a\" tokens=\"1\"/><place name=\"a-t\"/><transition name=\"t\"><input place=\"a\"/><output place=\"a-t\"/></transition></mission>",
        )
        .expect("valid");
        let pnml = to_pnml(&net);
        assert!(pnml.contains("<net id=\"page\""));
        assert!(pnml.contains("<page id=\"page-2\">"));
        assert!(pnml.contains("<arc id=\"a-t-2\" source=\"a\" target=\"t\">"));
        assert!(pnml.contains("<arc id=\"t-a-t\" source=\"t\" target=\"a-t\">"));
    }

    #[test]
    fn nets_of_other_tools() {
        // No ArMoR data, several and nested pages, graphics, other tools' data, names.
        let pnml = format!(
            r#"<?xml version="1.0"?>
<pnml xmlns="{PNML_NAMESPACE}">
  <net id="Philosophers-PT-000002" type="{PTNET_TYPE}">
    <name><text>Dining philosophers</text></name>
    <page id="page0">
      <name><text>Main</text></name>
      <place id="fork_0"><name><text>Fork 0</text><graphics><offset x="0" y="0"/></graphics></name>
        <graphics><position x="10" y="10"/></graphics>
        <initialMarking><text> 1 </text></initialMarking>
        <toolspecific tool="Tina" version="3.7"><whatever/></toolspecific></place>
      <transition id="t1"><graphics><position x="1" y="1"/></graphics></transition>
      <page id="inner">
        <place id="p2"/>
        <arc id="a2" source="t1" target="p2"><graphics/></arc>
      </page>
      <arc id="a1" source="fork_0" target="t1"><inscription><text>1</text><graphics/></inscription></arc>
    </page>
    <toolspecific tool="Tina" version="3.7"/>
  </net>
</pnml>"#
        );
        let net = from_pnml(&pnml).unwrap_or_else(|p| panic!("{:?}", rendered(&p)));
        assert_eq!(net.name, "Philosophers-PT-000002");
        assert_eq!(net.system, "");
        let names: Vec<&str> = net.places.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["fork_0", "p2"]);
        assert_eq!(net.places[0].tokens, 1);
        assert_eq!(net.transitions[0].inputs[0].place, "fork_0");
        assert_eq!(net.transitions[0].outputs[0].place, "p2");
        assert!(net.transitions[0].condition.is_empty());
        // As a mission it can be written and read back.
        let again = MissionNet::parse(&net.to_xml()).expect("valid mission");
        assert_eq!(again.without_positions(), net.without_positions());
    }

    #[test]
    fn refused_documents() {
        check("<pnml/>", &["1:1: the document holds no <net>"]);
        check(
            "<mission name=\"m\"/>",
            &["1:1: expected <pnml> at the top, found <mission>"],
        );
        check(
            "<pnml xmlns=\"http://www.pnml.org/version-2009/grammar/pnmlcoremodel\"/>",
            &[
                "1:7: namespace `http://www.pnml.org/version-2009/grammar/pnmlcoremodel` is not the one of PNML 2009 (`http://www.pnml.org/version-2009/grammar/pnml`)",
            ],
        );
        check(
            "<pnml>\n<net id=\"n\" type=\"http://www.pnml.org/version-2009/grammar/symmetricnet\"><page id=\"p\"><place id=\"x\"><type/></place></page></net>\n</pnml>",
            &[
                "2:13: net type `http://www.pnml.org/version-2009/grammar/symmetricnet` (a symmetric net) is not supported: ArMoR reads place/transition nets (`http://www.pnml.org/version-2009/grammar/ptnet`)",
            ],
        );
        check(
            "<pnml><net id=\"n\"/></pnml>",
            &[
                "1:7: <net> needs the attribute `type` (`http://www.pnml.org/version-2009/grammar/ptnet` for place/transition nets)",
            ],
        );
        check(
            &format!(
                "<pnml>\n<net id=\"a\" type=\"{PTNET_TYPE}\"><page id=\"p\"/></net>\n<net id=\"b\" type=\"{PTNET_TYPE}\"/>\n<graphics/>\n</pnml>"
            ),
            &[
                "3:1: a second <net>: a mission is one net, give one net per document",
                "4:1: unknown element <graphics> inside <pnml> (expected one of: net)",
            ],
        );
        check(
            &format!("<pnml><net id=\"9 lives\" type=\"{PTNET_TYPE}\"/></pnml>"),
            &[
                "1:7: <net> has no <page>: places, transitions and arcs go on a page",
                "1:12: id `9 lives` of <net>, which ArMoR uses as the mission's name, is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
            ],
        );
    }

    #[test]
    fn high_level_features_are_refused_by_name() {
        check(
            &document(&[
                "<declaration><structure/></declaration>",
                "<place id=\"p\"><type><text>Dot</text></type><hlinitialMarking/></place>",
                "<transition id=\"t\"><condition/></transition>",
                "<referencePlace id=\"r\" ref=\"p\"/>",
                "<arc id=\"a\" source=\"p\" target=\"t\"><hlinscription/><type value=\"inhibitor\"/></arc>",
                "<place id=\"q\"><initialMarking><structure/></initialMarking></place>",
            ]),
            &[
                "4:1: <declaration> inside <page> is not supported: declarations belong to coloured and high-level nets; ArMoR reads place/transition nets",
                "5:15: <type> inside <place> is not supported: sorts of places and types of arcs (inhibitor, reset, read arcs) are not part of place/transition nets",
                "5:44: <hlinitialMarking> inside <place> is not supported: high-level markings belong to coloured nets; a place of a place/transition net has an <initialMarking> with a number of tokens",
                "6:20: <condition> inside <transition> is not supported: guards belong to high-level nets; ArMoR conditions go in <toolspecific tool=\"ArMoR\">",
                "7:1: <referencePlace> inside <page> is not supported: reference nodes are not supported; put the nodes themselves on the pages",
                "8:35: <hlinscription> inside <arc> is not supported: high-level inscriptions belong to coloured nets; an arc of a place/transition net has an <inscription> with a number of tokens",
                "8:51: <type> inside <arc> is not supported: sorts of places and types of arcs (inhibitor, reset, read arcs) are not part of place/transition nets",
                "9:15: <initialMarking> needs a <text> with a number of tokens",
                "9:31: <structure> inside <initialMarking> is not supported: high-level terms belong to coloured nets; ArMoR reads the <text> of labels",
            ],
        );
    }

    #[test]
    fn arcs_and_labels() {
        check(
            &document(&[
                "<place id=\"p\"><initialMarking><text>-1</text></initialMarking></place><place id=\"q\"/>",
                "<transition id=\"t\"/><transition id=\"u\"/>",
                "<arc id=\"a1\" source=\"p\" target=\"q\"/>",
                "<arc id=\"a2\" source=\"t\" target=\"u\"/>",
                "<arc id=\"a3\" source=\"ghost\" target=\"t\"/>",
                "<arc id=\"a4\" source=\"p\" target=\"t\"><inscription><text>0</text></inscription></arc>",
                "<arc id=\"a5\" source=\"pg\" target=\"t\"/>",
                "<arc id=\"a1\" source=\"q\" target=\"u\"/>",
                "<arc source=\"q\"/>",
                "<place id=\"p.1\"/><place id=\"p\"/>",
                "<arc id=\"a6\" source=\"p.1\" target=\"t\"/>",
            ]),
            &[
                "4:31: the number of tokens must be a whole number, 0 or more, not `-1`",
                "5:21: transition `u` has no input arc: it would always be enabled and fire forever (give it an <input place=\"...\"/>)",
                "6:1: arc `a1` goes from place `p` to place `q`: an arc joins a place and a transition",
                "7:1: arc `a2` goes from transition `t` to transition `u`: an arc joins a place and a transition",
                "8:14: arc `a3`: no place or transition `ghost`",
                "9:49: the weight of an arc must be a whole number of tokens, 1 or more, not `0`",
                "10:14: arc `a5`: `pg` is not a place or a transition",
                "11:6: id `a1` is already used at line 6",
                "12:1: <arc> needs the attribute `id`",
                "13:8: id `p.1` of <place>, which ArMoR uses as its name, is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "13:25: id `p` is already used at line 4",
            ],
        );
    }

    #[test]
    fn armor_data() {
        check(
            &document(&[
                "<place id=\"p\"><toolspecific tool=\"ArMoR\" version=\"1\"><module name=\"nav\"/><module name=\"nav\"/><param module=\"sim\" name=\"x\"/><final/><colour/></toolspecific></place>",
                "<transition id=\"t\"><toolspecific tool=\"ArMoR\" version=\"1\"><condition priority=\"x\" delay_secs=\"-1\" at=\"now\" event=\"e\" guard=\"1\"/></toolspecific></transition>",
                "<arc id=\"a\" source=\"p\" target=\"t\"><toolspecific tool=\"ArMoR\" version=\"1\"><weight/></toolspecific></arc>",
                "<transition id=\"u\"><toolspecific tool=\"ArMoR\" version=\"2\"/><toolspecific version=\"1\"/></transition>",
            ]),
            &[
                "4:74: place `p` already runs module `nav` (line 4)",
                "4:94: <param> needs the attribute `value`",
                "4:94: place `p` sets parameter `x` of module `sim`, which it does not run (add <module name=\"sim\"/> to the place)",
                "4:132: unknown element <colour> inside <toolspecific> (expected one of: module, param, final)",
                "5:70: `priority` must be a whole number (higher fires first), not `x`",
                "5:83: `delay_secs` must be a number of seconds, 0 or more (like 2 or 0.5), not `-1`",
                "5:99: `at` must be a date like 2026-11-22T20:00:00Z or 2026-11-22T21:00:00+01:00, not `now`: expected YYYY-MM-DDTHH:MM:SS, an optional fraction of a second, then `Z` or an offset ±hh:mm",
                "5:108: `event` must be MODULE.EVENT, or module.ID.failed for the failure of module ID, not `e`",
                "5:118: unknown attribute `guard` on <condition> (expected one of: priority, event, delay_secs, at, operator)",
                "6:35: ArMoR keeps no data here: remove this <toolspecific tool=\"ArMoR\">",
                "7:1: transition `u` has no input arc: it would always be enabled and fire forever (give it an <input place=\"...\"/>)",
                "7:47: ArMoR data of version `2` is not supported (this ArMoR reads version 1)",
                "7:60: <toolspecific> needs the attribute `tool`",
            ],
        );
    }

    #[test]
    fn core_model_nets_of_other_tools_are_read_with_names_from_their_labels() {
        let core = |body: &str| {
            format!(
                "<pnml><net id=\"order flow\" type=\"{CORE_MODEL_TYPE}\"><page id=\"n0\">\n{body}\n</page>\n\
                 <finalmarkings><marking><place idref=\"p-end\"><text>1</text></place></marking></finalmarkings>\n\
                 </net></pnml>"
            )
        };
        let text = core(
            "<place id=\"p-start\"><name><text>start</text></name><initialMarking><text>2</text></initialMarking></place>\n\
             <place id=\"p-end\"><name><text>end</text></name></place>\n\
             <transition id=\"3f2a\"><name><text>check order</text></name></transition>\n\
             <transition id=\"9bc0\"><name><text>check order</text></name>\
             <toolspecific tool=\"ProM\" version=\"6.4\" activity=\"$invisible$\"/></transition>\n\
             <arc id=\"a1\" source=\"p-start\" target=\"3f2a\"/>\n\
             <arc id=\"a2\" source=\"3f2a\" target=\"p-end\"><inscription><text>2</text></inscription></arc>\n\
             <arc id=\"a3\" source=\"p-start\" target=\"9bc0\"/>",
        );
        let (net, warnings) = read_pnml(&text).expect("read");
        assert_eq!(net.name, "order_flow");
        let names: Vec<&str> = net.transitions.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, ["check_order", "check_order-2"]);
        assert_eq!(net.places[0].tokens, 2);
        assert!(net.places[1].is_final && !net.places[0].is_final);
        assert_eq!(net.transitions[0].outputs[0].weight, 2);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0]
                .message
                .contains("read as a place/transition net")
        );
        // The same net as our own type refuses the ids it cannot use as names.
        let strict = text.replace(CORE_MODEL_TYPE, PTNET_TYPE);
        assert!(from_pnml(&strict).is_err());
        // A final marking naming nothing, or no place, is a problem.
        let broken = text
            .replace("<place idref=\"p-end\">", "<place idref=\"nowhere\">")
            .replace("</marking>", "<place><text>1</text></place></marking>");
        let problems: Vec<String> = read_pnml(&broken)
            .expect_err("refused")
            .iter()
            .map(|problem| problem.message.clone())
            .collect();
        assert_eq!(
            problems,
            [
                "final marking: no place `nowhere`",
                "final marking: <place> needs the attribute `idref`"
            ]
        );
    }
}
