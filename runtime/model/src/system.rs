//! The system configuration: which module instances run, with which parameters, and the links
//! between their ports.
//!
//! ```xml
//! <system name="demo" host="127.0.0.1">
//!   <module name="counter" type="counter" restart="on-failure">
//!     <param name="period_secs" value="0.05"/>
//!   </module>
//!   <module name="checker" type="checker"/>
//!   <link from="counter.count" to="checker.input"/>
//! </system>
//! ```
//!
//! A module may be limited to what it publishes and subscribes to: `may_publish` and
//! `may_subscribe` list data names (`module.output`, `module.*` or `*`), separated by spaces or
//! commas. The agent refuses registrations and lookups outside the lists; without a list, a
//! module may publish its outputs and subscribe to anything.
//!
//! [`SystemConfig::parse`] reports structural problems (the XML alone), [`check`] reports the
//! problems found against the module descriptions, both with line and column. The schema is
//! `assets/schema/system.xsd`.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use armor_module_api::describe::{ModuleDescription, PortSpec, is_identifier};
use armor_module_api::xml::{self, Attr, Element, Located, Pos};

/// The address the agent and the config server listen on when the system names none.
pub const DEFAULT_HOST: &str = "127.0.0.1";

/// What the agent does when a module process ends.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum RestartPolicy {
    /// Leave it stopped.
    Never,
    /// Start it again when it ended with an error or a signal.
    #[default]
    OnFailure,
    /// Start it again whatever the way it ended.
    Always,
}

impl RestartPolicy {
    pub fn as_str(self) -> &'static str {
        match self {
            RestartPolicy::Never => "never",
            RestartPolicy::OnFailure => "on-failure",
            RestartPolicy::Always => "always",
        }
    }
}

impl fmt::Display for RestartPolicy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for RestartPolicy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "never" => Ok(RestartPolicy::Never),
            "on-failure" => Ok(RestartPolicy::OnFailure),
            "always" => Ok(RestartPolicy::Always),
            other => Err(format!(
                "unknown restart policy `{other}` (expected never, on-failure or always)"
            )),
        }
    }
}

/// One end of a link: a port of a module instance, written `module.port`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Endpoint {
    pub module: String,
    pub port: String,
}

impl Endpoint {
    pub fn new(module: &str, port: &str) -> Self {
        Self {
            module: module.to_owned(),
            port: port.to_owned(),
        }
    }
}

impl fmt::Display for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.module, self.port)
    }
}

impl FromStr for Endpoint {
    type Err = ();
    /// `module.port`, both parts identifiers.
    fn from_str(s: &str) -> Result<Self, ()> {
        match s.split_once('.') {
            Some((module, port)) if is_identifier(module) && is_identifier(port) => {
                Ok(Endpoint::new(module, port))
            }
            _ => Err(()),
        }
    }
}

/// A parameter value given to a module instance.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ParamValue {
    pub name: String,
    pub value: String,
    /// The `<param>` element.
    pub pos: Pos,
    /// The `value` attribute.
    pub value_pos: Pos,
}

/// One module process of the system.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModuleInstance {
    pub name: String,
    pub module_type: String,
    /// Where the module runs; `None` for the system's host.
    pub host: Option<String>,
    pub restart: RestartPolicy,
    pub params: Vec<ParamValue>,
    /// Data name patterns the module may publish (all of its outputs when `None`).
    pub may_publish: Option<Vec<String>>,
    /// Data name patterns the module may subscribe to (any when `None`).
    pub may_subscribe: Option<Vec<String>>,
    /// The `<module>` element.
    pub pos: Pos,
    /// The `type` attribute.
    pub type_pos: Pos,
}

impl ModuleInstance {
    /// The first value given for the parameter `name`.
    pub fn param(&self, name: &str) -> Option<&ParamValue> {
        self.params.iter().find(|param| param.name == name)
    }

    /// Whether the module may publish `data_name`.
    pub fn may_publish(&self, data_name: &str) -> bool {
        allowed(self.may_publish.as_deref(), data_name)
    }

    /// Whether the module may subscribe to `data_name`.
    pub fn may_subscribe(&self, data_name: &str) -> bool {
        allowed(self.may_subscribe.as_deref(), data_name)
    }
}

/// Whether `data_name` matches one of `patterns` (`None`: no limit).
pub fn allowed(patterns: Option<&[String]>, data_name: &str) -> bool {
    patterns.is_none_or(|patterns| {
        patterns
            .iter()
            .any(|pattern| match pattern.strip_suffix('*') {
                Some(prefix) => data_name.starts_with(prefix),
                None => pattern == data_name,
            })
    })
}

/// A list of data name patterns: `module.output`, `module.*` or `*`.
fn read_patterns(attr: &Attr, problems: &mut Vec<Located>) -> Vec<String> {
    let mut patterns = Vec::new();
    for item in attr
        .value
        .split([' ', ',', '\t', '\n'])
        .filter(|s| !s.is_empty())
    {
        let valid = item == "*"
            || match item.split_once('.') {
                Some((module, "*")) => is_identifier(module),
                Some((module, port)) => is_identifier(module) && is_identifier(port),
                None => false,
            };
        if valid {
            patterns.push(item.to_owned());
        } else {
            problems.push(Located::new(
                attr.pos,
                format!(
                    "`{}`: `{item}` is not a data name pattern (expected module.output, module.* or *)",
                    attr.name
                ),
            ));
        }
    }
    patterns
}

/// Data flowing from an output of a module to an input of a module.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Link {
    pub from: Endpoint,
    pub to: Endpoint,
    /// The `<link>` element.
    pub pos: Pos,
    /// The `from` attribute.
    pub from_pos: Pos,
    /// The `to` attribute.
    pub to_pos: Pos,
}

/// A whole system configuration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SystemConfig {
    pub name: String,
    /// The address the agent and the config server listen on; `None` for [`DEFAULT_HOST`].
    pub host: Option<String>,
    pub modules: Vec<ModuleInstance>,
    pub links: Vec<Link>,
}

/// What one module instance is told at start: where its data comes from and goes to, and its
/// parameter values.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ModuleBindings {
    pub module_type: String,
    /// Input name -> unique data name (`provider.output`) of the output feeding it.
    pub inputs: BTreeMap<String, String>,
    /// Output name -> unique data name (`module.output`).
    pub outputs: BTreeMap<String, String>,
    /// Parameter name -> value: the configured ones, plus the defaults of the others.
    pub params: BTreeMap<String, String>,
}

const NAME_RULE: &str = "use letters, digits, `_` or `-`, starting with a letter or `_`";

impl SystemConfig {
    /// Reads a system configuration, reporting every structural problem, sorted by position.
    pub fn parse(text: &str) -> Result<SystemConfig, Vec<Located>> {
        let root = xml::parse(text).map_err(|err| vec![err])?;
        if root.name != "system" {
            return Err(vec![Located::new(
                root.pos,
                format!("expected <system> at the top, found <{}>", root.name),
            )]);
        }
        let mut problems = Vec::new();
        problems.extend(root.unknown_attrs(&["name", "host"]));
        problems.extend(root.unknown_children(&["module", "link"]));
        no_text(&root, &mut problems);
        let name = identifier_attr(&root, "name", "name", &mut problems).unwrap_or_default();
        let host = host_attr(&root, &mut problems);
        let mut system = SystemConfig {
            name,
            host,
            modules: Vec::new(),
            links: Vec::new(),
        };
        for child in &root.children {
            match child.name.as_str() {
                "module" => {
                    if let Some(module) = read_module(child, &mut problems) {
                        system.modules.push(module);
                    }
                }
                "link" => {
                    if let Some(link) = read_link(child, &mut problems) {
                        system.links.push(link);
                    }
                }
                _ => {}
            }
        }
        if problems.is_empty() {
            Ok(system)
        } else {
            problems.sort_by_key(|problem| problem.pos);
            Err(problems)
        }
    }

    /// Writes the configuration in the format [`SystemConfig::parse`] reads.
    pub fn to_xml(&self) -> String {
        use std::fmt::Write as _;
        let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        let _ = write!(out, "<system name=\"{}\"", escape_attr(&self.name));
        if let Some(host) = &self.host {
            let _ = write!(out, " host=\"{}\"", escape_attr(host));
        }
        out.push_str(">\n");
        for module in &self.modules {
            let _ = write!(
                out,
                "  <module name=\"{}\" type=\"{}\" restart=\"{}\"",
                escape_attr(&module.name),
                escape_attr(&module.module_type),
                module.restart
            );
            if let Some(host) = &module.host {
                let _ = write!(out, " host=\"{}\"", escape_attr(host));
            }
            for (attr, list) in [
                ("may_publish", &module.may_publish),
                ("may_subscribe", &module.may_subscribe),
            ] {
                if let Some(list) = list {
                    let _ = write!(out, " {attr}=\"{}\"", escape_attr(&list.join(" ")));
                }
            }
            if module.params.is_empty() {
                out.push_str("/>\n");
                continue;
            }
            out.push_str(">\n");
            for param in &module.params {
                let _ = writeln!(
                    out,
                    "    <param name=\"{}\" value=\"{}\"/>",
                    escape_attr(&param.name),
                    escape_attr(&param.value)
                );
            }
            out.push_str("  </module>\n");
        }
        for link in &self.links {
            let _ = writeln!(
                out,
                "  <link from=\"{}\" to=\"{}\"/>",
                escape_attr(&link.from.to_string()),
                escape_attr(&link.to.to_string())
            );
        }
        out.push_str("</system>\n");
        out
    }

    /// The module instance called `name` (the first one, if it is defined twice).
    pub fn module(&self, name: &str) -> Option<&ModuleInstance> {
        self.modules.iter().find(|module| module.name == name)
    }

    /// The host the agent and config server listen on: the configured one or [`DEFAULT_HOST`].
    pub fn host_or_default(&self) -> &str {
        self.host.as_deref().unwrap_or(DEFAULT_HOST)
    }

    /// What the module instance `module` is told at start, or `None` if there is no such
    /// instance. Inputs come from the links into it; outputs are those of `description`, or
    /// without a description those that links use; parameters are the configured values plus
    /// the defaults of `description` for the others. A value given twice keeps the first.
    pub fn bindings(
        &self,
        module: &str,
        description: Option<&ModuleDescription>,
    ) -> Option<ModuleBindings> {
        let instance = self.module(module)?;
        let mut bindings = ModuleBindings {
            module_type: instance.module_type.clone(),
            ..ModuleBindings::default()
        };
        for link in &self.links {
            if link.to.module == module {
                bindings
                    .inputs
                    .entry(link.to.port.clone())
                    .or_insert_with(|| link.from.to_string());
            }
        }
        match description {
            Some(description) => {
                for output in &description.outputs {
                    bindings
                        .outputs
                        .insert(output.name.clone(), format!("{module}.{}", output.name));
                }
            }
            None => {
                for link in &self.links {
                    if link.from.module == module {
                        bindings
                            .outputs
                            .insert(link.from.port.clone(), link.from.to_string());
                    }
                }
            }
        }
        for param in &instance.params {
            bindings
                .params
                .entry(param.name.clone())
                .or_insert_with(|| param.value.clone());
        }
        if let Some(description) = description {
            for spec in &description.params {
                if let Some(default) = &spec.default {
                    bindings
                        .params
                        .entry(spec.name.clone())
                        .or_insert_with(|| default.clone());
                }
            }
        }
        Some(bindings)
    }
}

/// Escapes an attribute value so that any XML reader gives it back unchanged (whitespace
/// characters other than the space would otherwise be normalized to spaces).
fn escape_attr(value: &str) -> String {
    xml::escape(value)
        .replace('\t', "&#9;")
        .replace('\n', "&#10;")
        .replace('\r', "&#13;")
}

fn read_module(element: &Element, problems: &mut Vec<Located>) -> Option<ModuleInstance> {
    problems.extend(element.unknown_attrs(&[
        "name",
        "type",
        "restart",
        "host",
        "may_publish",
        "may_subscribe",
    ]));
    problems.extend(element.unknown_children(&["param"]));
    no_text(element, problems);
    let name = identifier_attr(element, "name", "name", problems);
    let type_attr = element.attr("type");
    let module_type = identifier_attr(element, "type", "module type", problems);
    let host = host_attr(element, problems);
    let restart = match element.attr("restart") {
        None => Some(RestartPolicy::default()),
        Some(attr) => attr
            .value
            .parse()
            .map_err(|err| problems.push(Located::new(attr.pos, err)))
            .ok(),
    };
    let params: Vec<ParamValue> = element
        .children_named("param")
        .filter_map(|child| read_param(child, problems))
        .collect();
    Some(ModuleInstance {
        name: name?,
        module_type: module_type?,
        host,
        restart: restart?,
        params,
        may_publish: element
            .attr("may_publish")
            .map(|attr| read_patterns(attr, problems)),
        may_subscribe: element
            .attr("may_subscribe")
            .map(|attr| read_patterns(attr, problems)),
        pos: element.pos,
        type_pos: type_attr.map_or(element.pos, |attr| attr.pos),
    })
}

fn read_param(element: &Element, problems: &mut Vec<Located>) -> Option<ParamValue> {
    problems.extend(element.unknown_attrs(&["name", "value"]));
    no_children(element, problems);
    no_text(element, problems);
    let name = identifier_attr(element, "name", "name", problems);
    // An empty value is allowed: it is a valid `string` parameter.
    let value = element.attr("value");
    if value.is_none() {
        problems.push(Located::new(
            element.pos,
            "<param> needs the attribute `value`",
        ));
    }
    let value = value?;
    Some(ParamValue {
        name: name?,
        value: value.value.as_str().to_owned(),
        pos: element.pos,
        value_pos: value.pos,
    })
}

fn read_link(element: &Element, problems: &mut Vec<Located>) -> Option<Link> {
    problems.extend(element.unknown_attrs(&["from", "to"]));
    no_children(element, problems);
    no_text(element, problems);
    let from = endpoint_attr(element, "from", "MODULE.OUTPUT", problems);
    let to = endpoint_attr(element, "to", "MODULE.INPUT", problems);
    let ((from, from_pos), (to, to_pos)) = (from?, to?);
    Some(Link {
        from,
        to,
        pos: element.pos,
        from_pos,
        to_pos,
    })
}

fn endpoint_attr(
    element: &Element,
    name: &str,
    form: &str,
    problems: &mut Vec<Located>,
) -> Option<(Endpoint, Pos)> {
    let attr = required(element, name, problems)?;
    match attr.value.parse() {
        Ok(endpoint) => Some((endpoint, attr.pos)),
        Err(()) => {
            problems.push(Located::new(
                attr.pos,
                format!(
                    "`{name}` must be {form} (two names joined by a dot), not `{}`",
                    attr.value
                ),
            ));
            None
        }
    }
}

fn required<'a>(
    element: &'a Element<'a>,
    name: &str,
    problems: &mut Vec<Located>,
) -> Option<&'a Attr<'a>> {
    element
        .required_attr(name)
        .map_err(|err| problems.push(err))
        .ok()
}

fn identifier_attr(
    element: &Element,
    name: &str,
    what: &str,
    problems: &mut Vec<Located>,
) -> Option<String> {
    let attr = required(element, name, problems)?;
    if is_identifier(&attr.value) {
        Some(attr.value.as_str().to_owned())
    } else {
        problems.push(Located::new(
            attr.pos,
            format!(
                "{what} `{}` of <{}> is not valid ({NAME_RULE})",
                attr.value, element.name
            ),
        ));
        None
    }
}

fn host_attr(element: &Element, problems: &mut Vec<Located>) -> Option<String> {
    element.attr("host")?;
    required(element, "host", problems).map(|attr| attr.value.as_str().to_owned())
}

fn no_children(element: &Element, problems: &mut Vec<Located>) {
    for child in &element.children {
        problems.push(Located::new(
            child.pos,
            format!(
                "unknown element <{}> inside <{}> (it has no elements)",
                child.name, element.name
            ),
        ));
    }
}

fn no_text(element: &Element, problems: &mut Vec<Located>) {
    let text = element.text.trim();
    if !text.is_empty() {
        let shown: String = text.chars().take(40).collect();
        let more = if shown.len() < text.len() { "..." } else { "" };
        problems.push(Located::new(
            element.pos,
            format!(
                "<{}> must not contain text (found `{shown}{more}`)",
                element.name
            ),
        ));
    }
}

/// Every problem of `system` against the descriptions of the module types (keyed by module
/// type), sorted by position.
pub fn check(
    system: &SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> Vec<Located> {
    let mut problems = Vec::new();
    // First definition of each module name.
    let mut modules: BTreeMap<&str, &ModuleInstance> = BTreeMap::new();
    for module in &system.modules {
        match modules.get(module.name.as_str()) {
            Some(first) => problems.push(Located::new(
                module.pos,
                format!(
                    "module `{}` is already defined at line {}",
                    module.name, first.pos.line
                ),
            )),
            None => {
                modules.insert(&module.name, module);
            }
        }
        match descriptions.get(&module.module_type) {
            Some(description) => {
                check_params(module, description, &mut problems);
                for output in &description.outputs {
                    let data_name = format!("{}.{}", module.name, output.name);
                    if !module.may_publish(&data_name) {
                        problems.push(Located::new(
                            module.pos,
                            format!(
                                "module `{}`: its output `{data_name}` is not in may_publish \
                                 (the agent would refuse its registration); add it or `{}.*`",
                                module.name, module.name
                            ),
                        ));
                    }
                }
            }
            None => problems.push(Located::new(
                module.type_pos,
                format!(
                    "module `{}`: no module type `{}` on the module path (known: {})",
                    module.name,
                    module.module_type,
                    listing(descriptions.keys())
                ),
            )),
        }
    }
    // Input -> the first link feeding it.
    let mut fed: BTreeMap<&Endpoint, &Link> = BTreeMap::new();
    for link in &system.links {
        let from = resolve(
            &link.from,
            link.from_pos,
            Side::From,
            &modules,
            descriptions,
            &mut problems,
        );
        let to = resolve(
            &link.to,
            link.to_pos,
            Side::To,
            &modules,
            descriptions,
            &mut problems,
        );
        if let Some(subscriber) = modules.get(link.to.module.as_str())
            && !subscriber.may_subscribe(&link.from.to_string())
        {
            problems.push(Located::new(
                link.to_pos,
                format!(
                    "module `{}` may not subscribe to `{}` (may_subscribe: {})",
                    link.to.module,
                    link.from,
                    subscriber
                        .may_subscribe
                        .as_deref()
                        .unwrap_or_default()
                        .join(" ")
                ),
            ));
        }
        if let (Some(Some(output)), Some(Some(input))) = (from, to)
            && output.data_type != input.data_type
        {
            problems.push(Located::new(
                link.to_pos,
                format!(
                    "module `{}`: input `{}` expects {} but `{}` is {}",
                    link.to.module, link.to.port, input.data_type, link.from, output.data_type
                ),
            ));
        }
        if to.is_some() {
            match fed.get(&link.to) {
                Some(first) => problems.push(Located::new(
                    link.to_pos,
                    format!(
                        "input `{}` is already fed by `{}` (line {})",
                        link.to, first.from, first.pos.line
                    ),
                )),
                None => {
                    fed.insert(&link.to, link);
                }
            }
        }
    }
    problems.sort_by_key(|problem| problem.pos);
    problems
}

fn check_params(
    module: &ModuleInstance,
    description: &ModuleDescription,
    problems: &mut Vec<Located>,
) {
    let mut seen: BTreeMap<&str, &ParamValue> = BTreeMap::new();
    for param in &module.params {
        if let Some(first) = seen.get(param.name.as_str()) {
            problems.push(Located::new(
                param.pos,
                format!(
                    "module `{}`: parameter `{}` is already set at line {}",
                    module.name, param.name, first.pos.line
                ),
            ));
            continue;
        }
        seen.insert(&param.name, param);
        let Some(spec) = description.param(&param.name) else {
            problems.push(Located::new(
                param.pos,
                format!(
                    "module `{}`: module type `{}` has no parameter `{}` (known: {})",
                    module.name,
                    module.module_type,
                    param.name,
                    listing(description.params.iter().map(|spec| &spec.name))
                ),
            ));
            continue;
        };
        if let Err(why) = spec.param_type.check_value(&param.value) {
            problems.push(Located::new(
                param.value_pos,
                format!(
                    "module `{}`: parameter `{}` ({}): {why}",
                    module.name, param.name, spec.param_type
                ),
            ));
        }
    }
    for spec in &description.params {
        if spec.is_required() && !seen.contains_key(spec.name.as_str()) {
            problems.push(Located::new(
                module.pos,
                format!(
                    "module `{}`: required parameter `{}` is not set",
                    module.name, spec.name
                ),
            ));
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Side {
    From,
    To,
}

/// Resolves one end of a link. `None`: a problem was reported. `Some(None)`: the module exists
/// but its type is unknown (already reported), so its ports cannot be checked. `Some(Some)`: the
/// port, of the right direction.
fn resolve<'a>(
    endpoint: &Endpoint,
    pos: Pos,
    side: Side,
    modules: &BTreeMap<&str, &ModuleInstance>,
    descriptions: &'a BTreeMap<String, ModuleDescription>,
    problems: &mut Vec<Located>,
) -> Option<Option<&'a PortSpec>> {
    let (side_word, wanted, other) = match side {
        Side::From => ("from", "output", "input"),
        Side::To => ("to", "input", "output"),
    };
    let Some(module) = modules.get(endpoint.module.as_str()) else {
        problems.push(Located::new(
            pos,
            format!(
                "link {side_word} `{endpoint}`: no module `{}` in this system",
                endpoint.module
            ),
        ));
        return None;
    };
    let Some(description) = descriptions.get(&module.module_type) else {
        return Some(None);
    };
    let (ports, other_ports) = match side {
        Side::From => (&description.outputs, &description.inputs),
        Side::To => (&description.inputs, &description.outputs),
    };
    if let Some(port) = ports.iter().find(|port| port.name == endpoint.port) {
        return Some(Some(port));
    }
    let message = if other_ports.iter().any(|port| port.name == endpoint.port) {
        format!(
            "link {side_word} `{endpoint}`: `{}` is an {other} of `{}`; a link goes from an output to an input",
            endpoint.port, endpoint.module
        )
    } else {
        format!(
            "link {side_word} `{endpoint}`: module `{}` (type `{}`) has no {wanted} `{}` ({wanted}s: {})",
            endpoint.module,
            module.module_type,
            endpoint.port,
            listing(ports.iter().map(|port| &port.name))
        )
    };
    problems.push(Located::new(pos, message));
    None
}

fn listing<'a>(names: impl Iterator<Item = &'a String>) -> String {
    let names: Vec<&str> = names.map(String::as_str).collect();
    if names.is_empty() {
        "none".to_owned()
    } else {
        names.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::describe::{ParamSpec, ParamType};

    const DEMO: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="demo" host="127.0.0.1">
  <module name="counter" type="counter" restart="on-failure" host="127.0.0.1">
    <param name="period_secs" value="0.05"/>
  </module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

    fn port(name: &str, data_type: &str) -> PortSpec {
        PortSpec {
            name: name.into(),
            data_type: data_type.into(),
            doc: String::new(),
        }
    }

    fn descriptions() -> BTreeMap<String, ModuleDescription> {
        let mut counter = ModuleDescription::new("counter", "counts");
        counter.outputs.push(port("count", "Counter"));
        counter.inputs.push(port("reset", "Counter"));
        counter
            .params
            .push(ParamSpec::new("period_secs", ParamType::Float, "").default("0.1"));
        counter
            .params
            .push(ParamSpec::new("limit", ParamType::Int, "").default("10"));
        let mut checker = ModuleDescription::new("checker", "checks");
        checker.inputs.push(port("input", "Counter"));
        let mut nav = ModuleDescription::new("nav", "navigates");
        nav.inputs.push(port("scan", "LaserScan"));
        nav.inputs.push(port("odom", "Odometry"));
        nav.outputs.push(port("cmd", "Twist"));
        nav.params
            .push(ParamSpec::new("goal_x", ParamType::Float, ""));
        nav.params
            .push(ParamSpec::new("verbose", ParamType::Bool, "").default("false"));
        let mut sim = ModuleDescription::new("sim", "simulates");
        sim.inputs.push(port("cmd", "Twist"));
        sim.outputs.push(port("odometry", "Odometry"));
        sim.outputs.push(port("scan", "LaserScan"));
        [counter, checker, nav, sim]
            .into_iter()
            .map(|description| (description.module_type.clone(), description))
            .collect()
    }

    fn rendered(problems: &[Located]) -> Vec<String> {
        problems.iter().map(ToString::to_string).collect()
    }

    /// Structural problems of `xml` (none expected: `&[]`).
    fn parse_problems(xml: &str, expected: &[&str]) {
        let got = match SystemConfig::parse(xml) {
            Ok(_) => Vec::new(),
            Err(problems) => rendered(&problems),
        };
        assert_eq!(got, expected, "for:\n{xml}");
    }

    /// Problems of `xml` against [`descriptions`]; `xml` must be structurally valid.
    fn check(xml: &str, expected: &[&str]) {
        let system = match SystemConfig::parse(xml) {
            Ok(system) => system,
            Err(problems) => panic!("structural problems: {:?}", rendered(&problems)),
        };
        let got = rendered(&super::check(&system, &descriptions()));
        assert_eq!(got, expected, "for:\n{xml}");
    }

    /// A system of `modules` (`name:type[:param=value,...]`) and `links` (`from>to`), one
    /// element per line starting at line 2.
    fn system(modules: &[&str], links: &[&str]) -> String {
        let mut out = String::from("<system name=\"s\">\n");
        for module in modules {
            let mut parts = module.split(':');
            let name = parts.next().unwrap_or_default();
            let module_type = parts.next().unwrap_or_default();
            out.push_str(&format!("<module name=\"{name}\" type=\"{module_type}\">"));
            for param in parts
                .next()
                .into_iter()
                .flat_map(|params| params.split(','))
            {
                let (param, value) = param.split_once('=').unwrap_or((param, ""));
                out.push_str(&format!("<param name=\"{param}\" value=\"{value}\"/>"));
            }
            out.push_str("</module>\n");
        }
        for link in links {
            let (from, to) = link.split_once('>').unwrap_or((link, ""));
            out.push_str(&format!("<link from=\"{from}\" to=\"{to}\"/>\n"));
        }
        out.push_str("</system>\n");
        out
    }

    #[test]
    fn the_demo_parses() {
        let demo = SystemConfig::parse(DEMO).expect("demo is valid");
        assert_eq!(demo.name, "demo");
        assert_eq!(demo.host_or_default(), "127.0.0.1");
        assert_eq!(demo.modules.len(), 2);
        let counter = &demo.modules[0];
        assert_eq!(counter.restart, RestartPolicy::OnFailure);
        assert_eq!(counter.type_pos, Pos { line: 3, col: 26 });
        assert_eq!(counter.params[0].value_pos, Pos { line: 4, col: 31 });
        assert_eq!(demo.modules[1].host, None);
        assert_eq!(demo.links[0].from.to_string(), "counter.count");
        assert_eq!(demo.links[0].to_pos, Pos { line: 7, col: 30 });
        assert!(super::check(&demo, &descriptions()).is_empty());
    }

    #[test]
    fn the_bundled_demo_is_clean() {
        let demo = SystemConfig::parse(include_str!("../../../missions/demo/system.xml"))
            .unwrap_or_else(|problems| panic!("{:?}", rendered(&problems)));
        assert!(super::check(&demo, &descriptions()).is_empty());
        let counter = demo.bindings("counter", descriptions().get("counter"));
        assert_eq!(
            counter.map(|b| b.params.get("period_secs").cloned()),
            Some(Some("0.1".to_owned()))
        );
    }

    #[test]
    fn restart_policies() {
        for policy in [
            RestartPolicy::Never,
            RestartPolicy::OnFailure,
            RestartPolicy::Always,
        ] {
            assert_eq!(policy.as_str().parse(), Ok(policy));
        }
        assert_eq!(RestartPolicy::default(), RestartPolicy::OnFailure);
    }

    #[test]
    fn structural_problems() {
        // Clean.
        parse_problems(DEMO, &[]);
        parse_problems("<system name=\"empty\"/>", &[]);
        // Truncated and malformed documents.
        parse_problems(
            "<system name=\"s\">\n  <module name=\"a\" type=\"t\">",
            &["2:29: document ends before <module> (line 2) is closed"],
        );
        parse_problems(
            "<system name=\"s\">\n  <module name=\"a\" type=\"t\"></system>",
            &[
                "2:29: malformed XML: ill-formed document: expected `</module>`, but `</system>` was found",
            ],
        );
        parse_problems(
            "<system name=\"s",
            &[
                "1:1: malformed XML: syntax error: tag not closed: `>` not found before end of input",
            ],
        );
        parse_problems("", &["1:1: document has no element"]);
        // Wrong root.
        parse_problems(
            "<module type=\"counter\"/>",
            &["1:1: expected <system> at the top, found <module>"],
        );
        // Unknown elements and attributes, text, all of them sorted.
        parse_problems(
            "<system name=\"s\" color=\"red\">\n  <modul name=\"a\"/>\n  <module name=\"a\" type=\"t\" prio=\"1\">\n    <parameter/>\n    <param name=\"p\" value=\"1\" unit=\"s\"><x/></param>\n  </module>\n  <link from=\"a.b\" to=\"a.c\" via=\"d\">text</link>\n</system>",
            &[
                "1:18: unknown attribute `color` on <system> (expected one of: name, host)",
                "2:3: unknown element <modul> inside <system> (expected one of: module, link)",
                "3:29: unknown attribute `prio` on <module> (expected one of: name, type, restart, host, may_publish, may_subscribe)",
                "4:5: unknown element <parameter> inside <module> (expected one of: param)",
                "5:31: unknown attribute `unit` on <param> (expected one of: name, value)",
                "5:40: unknown element <x> inside <param> (it has no elements)",
                "7:3: <link> must not contain text (found `text`)",
                "7:29: unknown attribute `via` on <link> (expected one of: from, to)",
            ],
        );
        // Missing and empty required attributes.
        parse_problems(
            "<system>\n<module/>\n<module name=\"\" type=\"t\" host=\"\"><param/></module>\n<link/>\n</system>",
            &[
                "1:1: <system> needs the attribute `name`",
                "2:1: <module> needs the attribute `name`",
                "2:1: <module> needs the attribute `type`",
                "3:9: attribute `name` of <module> must not be empty",
                "3:26: attribute `host` of <module> must not be empty",
                "3:34: <param> needs the attribute `name`",
                "3:34: <param> needs the attribute `value`",
                "4:1: <link> needs the attribute `from`",
                "4:1: <link> needs the attribute `to`",
            ],
        );
        // Names that are not identifiers, bad restart policy, bad endpoints.
        parse_problems(
            "<system name=\"my system\">\n<module name=\"9a\" type=\"a.b\" restart=\"sometimes\">\n<param name=\"-p\" value=\"\"/>\n</module>\n<link from=\"counter\" to=\"a.b.c\"/>\n<link from=\".x\" to=\"a.9\"/>\n</system>",
            &[
                "1:9: name `my system` of <system> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "2:9: name `9a` of <module> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "2:19: module type `a.b` of <module> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "2:30: unknown restart policy `sometimes` (expected never, on-failure or always)",
                "3:8: name `-p` of <param> is not valid (use letters, digits, `_` or `-`, starting with a letter or `_`)",
                "5:7: `from` must be MODULE.OUTPUT (two names joined by a dot), not `counter`",
                "5:22: `to` must be MODULE.INPUT (two names joined by a dot), not `a.b.c`",
                "6:7: `from` must be MODULE.OUTPUT (two names joined by a dot), not `.x`",
                "6:17: `to` must be MODULE.INPUT (two names joined by a dot), not `a.9`",
            ],
        );
    }

    #[test]
    fn an_empty_string_parameter_value_is_allowed() {
        let system = SystemConfig::parse(
            "<system name=\"s\"><module name=\"a\" type=\"t\"><param name=\"label\" value=\"\"/></module></system>",
        )
        .expect("valid");
        assert_eq!(system.modules[0].params[0].value, "");
    }

    #[test]
    fn problems_against_descriptions() {
        // Clean: defaults may be left out, a module may feed itself, an output may feed many.
        check(
            &system(
                &[
                    "c:counter:period_secs=0.5,limit=3",
                    "k:checker",
                    "k2:checker",
                ],
                &["c.count>k.input", "c.count>k2.input", "c.count>c.reset"],
            ),
            &[],
        );
        // Duplicate module names and parameters.
        check(
            &system(&["nav:checker", "nav:counter:limit=1,limit=2"], &[]),
            &[
                "3:1: module `nav` is already defined at line 2",
                "3:66: module `nav`: parameter `limit` is already set at line 3",
            ],
        );
        // Unknown module type: no parameter or port checks for it.
        check(
            &system(
                &["nav:navigaton:whatever=1", "k:checker"],
                &["nav.cmd>k.input", "k.nothing>nav.scan"],
            ),
            &[
                "2:20: module `nav`: no module type `navigaton` on the module path (known: checker, counter, nav, sim)",
                "5:7: link from `k.nothing`: module `k` (type `checker`) has no output `nothing` (outputs: none)",
            ],
        );
        // Parameters: unknown, wrong values, missing required.
        check(
            &system(
                &[
                    "c:counter:period_secs=fast,speed=2,limit=1.5",
                    "n:nav:verbose=yes",
                    "k:checker:x=1",
                ],
                &[],
            ),
            &[
                "2:59: module `c`: parameter `period_secs` (float): `fast` is not a finite number",
                "2:73: module `c`: module type `counter` has no parameter `speed` (known: period_secs, limit)",
                "2:124: module `c`: parameter `limit` (int): `1.5` is not a whole number",
                "3:1: module `n`: required parameter `goal_x` is not set",
                "3:51: module `n`: parameter `verbose` (bool): `yes` is not `true` or `false`",
                "4:33: module `k`: module type `checker` has no parameter `x` (known: none)",
            ],
        );
        // Links: unknown modules and ports, wrong directions.
        check(
            &system(
                &["c:counter", "k:checker"],
                &[
                    "ghost.count>k.input",
                    "c.count>ghost.input",
                    "c.cnt>k.inp",
                    "k.input>c.count",
                ],
            ),
            &[
                "4:7: link from `ghost.count`: no module `ghost` in this system",
                "5:22: link to `ghost.input`: no module `ghost` in this system",
                "6:7: link from `c.cnt`: module `c` (type `counter`) has no output `cnt` (outputs: count)",
                "6:20: link to `k.inp`: module `k` (type `checker`) has no input `inp` (inputs: input)",
                "7:7: link from `k.input`: `input` is an input of `k`; a link goes from an output to an input",
                "7:22: link to `c.count`: `count` is an output of `c`; a link goes from an output to an input",
            ],
        );
        // Type mismatches and inputs fed twice.
        check(
            &system(
                &["sim:sim", "nav:nav:goal_x=1", "c:counter", "k:checker"],
                &[
                    "sim.odometry>nav.scan",
                    "sim.scan>nav.scan",
                    "c.count>k.input",
                    "c.count>k.input",
                    "nav.cmd>sim.cmd",
                ],
            ),
            &[
                "6:27: module `nav`: input `scan` expects LaserScan but `sim.odometry` is Odometry",
                "7:23: input `nav.scan` is already fed by `sim.odometry` (line 6)",
                "9:22: input `k.input` is already fed by `c.count` (line 8)",
            ],
        );
    }

    #[test]
    fn a_thousand_modules() {
        let modules: Vec<String> = (0..1000)
            .map(|i| format!("c{i}:counter:period_secs=0.{i}"))
            .chain(std::iter::once("k:checker".to_owned()))
            .collect();
        let links: Vec<String> = (0..1000)
            .map(|i| format!("c{i}.count>c{}.reset", (i + 1) % 1000))
            .collect();
        let modules: Vec<&str> = modules.iter().map(String::as_str).collect();
        let mut links: Vec<&str> = links.iter().map(String::as_str).collect();
        links.push("c0.count>k.input");
        let xml = system(&modules, &links);
        let parsed = SystemConfig::parse(&xml).expect("valid");
        assert_eq!(parsed.modules.len(), 1001);
        assert_eq!(parsed.links.len(), 1001);
        check(&xml, &[]);
    }

    /// The configuration with every position set to zero.
    fn without_positions(mut system: SystemConfig) -> SystemConfig {
        let zero = Pos::default();
        for module in &mut system.modules {
            (module.pos, module.type_pos) = (zero, zero);
            for param in &mut module.params {
                (param.pos, param.value_pos) = (zero, zero);
            }
        }
        for link in &mut system.links {
            (link.pos, link.from_pos, link.to_pos) = (zero, zero, zero);
        }
        system
    }

    /// `xml` parses, and writing it then reading it back gives the same configuration.
    fn round_trip(xml: &str) {
        let system = SystemConfig::parse(xml).expect("valid");
        let written = system.to_xml();
        let again = SystemConfig::parse(&written)
            .unwrap_or_else(|problems| panic!("{written}\n{:?}", rendered(&problems)));
        assert_eq!(
            without_positions(again),
            without_positions(system),
            "{written}"
        );
    }

    #[test]
    fn round_trips_through_xml() {
        round_trip(DEMO);
        round_trip("<system name=\"s\"/>");
        round_trip(
            "<system name=\"s\" host=\"::1\">\n<module name=\"a\" type=\"t\" restart=\"never\"/>\n<module name=\"b\" type=\"t\" restart=\"always\" host=\"robot-2.local\">\n<param name=\"text\" value=\"&lt;a &amp; 'b' &quot;c&quot;&gt;&#10;&#9;next&#13;\"/>\n<param name=\"empty\" value=\"\"/>\n<param name=\"unicode\" value=\"été → 🤖\"/>\n</module>\n<link from=\"a.x\" to=\"b.y\"/>\n<link from=\"b.y\" to=\"b.z\"/>\n</system>",
        );
        // Values set in code, written then read.
        let mut system = SystemConfig::parse(DEMO).expect("valid");
        system.modules[0].params[0].value = "a\r\nb\t\"c\" <d> & 'e'".into();
        system.host = Some("10.0.0.1".into());
        round_trip(&system.to_xml());
        let again = SystemConfig::parse(&system.to_xml()).expect("valid");
        assert_eq!(again.modules[0].params[0].value, "a\r\nb\t\"c\" <d> & 'e'");
    }

    /// The bindings of `module` in `xml`, each map rendered as `key=value` joined by spaces:
    /// `[inputs, outputs, params]`.
    fn bindings(xml: &str, module: &str, with_description: bool, expected: Option<[&str; 3]>) {
        let system = SystemConfig::parse(xml).expect("valid");
        let descriptions = descriptions();
        let description = system
            .module(module)
            .and_then(|instance| descriptions.get(&instance.module_type))
            .filter(|_| with_description);
        let render = |map: &BTreeMap<String, String>| {
            map.iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect::<Vec<_>>()
                .join(" ")
        };
        let got = system.bindings(module, description).map(|b| {
            assert_eq!(
                Some(b.module_type.as_str()),
                system.module(module).map(|m| m.module_type.as_str())
            );
            [render(&b.inputs), render(&b.outputs), render(&b.params)]
        });
        assert_eq!(got, expected.map(|e| e.map(str::to_owned)));
    }

    #[test]
    fn bindings_of_modules() {
        let xml = system(
            &["c:counter:limit=5", "k:checker", "n:nav:goal_x=2", "s:sim"],
            &[
                "c.count>k.input",
                "c.count>c.reset",
                "s.scan>n.scan",
                "s.odometry>n.odom",
                "n.cmd>s.cmd",
            ],
        );
        bindings(
            &xml,
            "c",
            true,
            Some(["reset=c.count", "count=c.count", "limit=5 period_secs=0.1"]),
        );
        bindings(&xml, "k", true, Some(["input=c.count", "", ""]));
        bindings(
            &xml,
            "n",
            true,
            Some([
                "odom=s.odometry scan=s.scan",
                "cmd=n.cmd",
                "goal_x=2 verbose=false",
            ]),
        );
        bindings(
            &xml,
            "s",
            true,
            Some(["cmd=n.cmd", "odometry=s.odometry scan=s.scan", ""]),
        );
        // Without a description: outputs that links use, configured parameters only.
        bindings(
            &xml,
            "c",
            false,
            Some(["reset=c.count", "count=c.count", "limit=5"]),
        );
        bindings(
            &xml,
            "s",
            false,
            Some(["cmd=n.cmd", "odometry=s.odometry scan=s.scan", ""]),
        );
        bindings(&xml, "nobody", true, None);
    }
}
