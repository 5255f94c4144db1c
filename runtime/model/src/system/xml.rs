//! The system XML format (see [`super`] and `assets/schema/system.xsd`): [`SystemConfig::parse`]
//! and [`SystemConfig::to_xml`].

use armor_module_api::describe::is_identifier;
use armor_module_api::xml::{self, Attr, Element, Located, Pos};

use super::subsystem::{read_subsystem, write_subsystem};
use super::{
    Activation, DEFAULT_HOST_PORT, Endpoint, HostDecl, Link, ModuleInstance, ParamValue,
    RestartPolicy, SystemConfig,
};
use crate::fields::{escape, identifier, no_children, no_text, required};

impl SystemConfig {
    /// Reads a system configuration, reporting every structural problem, sorted by position.
    pub fn parse(text: &str) -> Result<SystemConfig, Vec<Located>> {
        let root = xml::parse_document(text, "system")?;
        let mut problems = Vec::new();
        problems.extend(root.unknown_attrs(&["name", "host"]));
        problems.extend(root.unknown_children(&["host", "module", "link", "subsystem"]));
        no_text(&root, &mut problems);
        let name = identifier(&root, "name", "name", &mut problems).unwrap_or_default();
        let host = host_attr(&root, &mut problems);
        let mut system = SystemConfig {
            name,
            host,
            hosts: Vec::new(),
            modules: Vec::new(),
            links: Vec::new(),
            subsystems: Vec::new(),
        };
        for child in &root.children {
            match child.name.as_str() {
                "host" => {
                    if let Some(host) = read_host(child, &mut problems) {
                        if system.hosts.iter().any(|other| other.name == host.name) {
                            problems.push(Located::new(
                                host.pos,
                                format!("host `{}` is declared twice", host.name),
                            ));
                        } else {
                            system.hosts.push(host);
                        }
                    }
                }
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
                "subsystem" => {
                    if let Some(subsystem) = read_subsystem(child, &mut problems) {
                        system.subsystems.push(subsystem);
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
        let _ = write!(out, "<system name=\"{}\"", escape(&self.name));
        if let Some(host) = &self.host {
            let _ = write!(out, " host=\"{}\"", escape(host));
        }
        out.push_str(">\n");
        for host in &self.hosts {
            let _ = write!(
                out,
                "  <host name=\"{}\" address=\"{}\"",
                escape(&host.name),
                escape(&host.address)
            );
            if host.port != DEFAULT_HOST_PORT {
                let _ = write!(out, " port=\"{}\"", host.port);
            }
            out.push_str("/>\n");
        }
        for module in &self.modules {
            let _ = write!(
                out,
                "  <module name=\"{}\" type=\"{}\" restart=\"{}\"",
                escape(&module.name),
                escape(&module.module_type),
                module.restart
            );
            if module.activation != Activation::default() {
                let _ = write!(out, " activation=\"{}\"", module.activation);
            }
            if let Some(host) = &module.host {
                let _ = write!(out, " host=\"{}\"", escape(host));
            }
            for (attr, list) in [
                ("may_publish", &module.may_publish),
                ("may_subscribe", &module.may_subscribe),
            ] {
                if let Some(list) = list {
                    let _ = write!(out, " {attr}=\"{}\"", escape(&list.join(" ")));
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
                    escape(&param.name),
                    escape(&param.value)
                );
            }
            out.push_str("  </module>\n");
        }
        for link in &self.links {
            let _ = write!(
                out,
                "  <link from=\"{}\" to=\"{}\"",
                escape(&link.from.to_string()),
                escape(&link.to.to_string())
            );
            if link.fallback > 0 {
                let _ = write!(out, " fallback=\"{}\"", link.fallback);
            }
            if let Some(hz) = link.max_rate_hz {
                let _ = write!(out, " max_rate_hz=\"{hz}\"");
            }
            out.push_str("/>\n");
        }
        for subsystem in &self.subsystems {
            write_subsystem(&mut out, subsystem, 1);
        }
        out.push_str("</system>\n");
        out
    }
}

fn read_module(element: &Element, problems: &mut Vec<Located>) -> Option<ModuleInstance> {
    problems.extend(element.unknown_attrs(&[
        "name",
        "type",
        "restart",
        "activation",
        "host",
        "may_publish",
        "may_subscribe",
    ]));
    problems.extend(element.unknown_children(&["param"]));
    no_text(element, problems);
    let name = identifier(element, "name", "name", problems);
    let type_attr = element.attr("type");
    let module_type = identifier(element, "type", "module type", problems);
    let host = host_attr(element, problems);
    let restart = word_attr::<RestartPolicy>(element, "restart", problems);
    let activation = word_attr::<Activation>(element, "activation", problems);
    let params: Vec<ParamValue> = element
        .children_named("param")
        .filter_map(|child| read_param(child, problems))
        .collect();
    Some(ModuleInstance {
        name: name?,
        module_type: module_type?,
        host,
        restart: restart?,
        activation: activation?,
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

/// An attribute that takes one of a few words (its type's `FromStr` says which), or the
/// type's default when absent; `None` after reporting a word it does not take.
fn word_attr<T: std::str::FromStr<Err = String> + Default>(
    element: &Element,
    name: &str,
    problems: &mut Vec<Located>,
) -> Option<T> {
    match element.attr(name) {
        None => Some(T::default()),
        Some(attr) => attr
            .value
            .parse()
            .map_err(|err| problems.push(Located::new(attr.pos, err)))
            .ok(),
    }
}

fn read_param(element: &Element, problems: &mut Vec<Located>) -> Option<ParamValue> {
    problems.extend(element.unknown_attrs(&["name", "value"]));
    no_children(element, problems);
    no_text(element, problems);
    let name = identifier(element, "name", "name", problems);
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
    problems.extend(element.unknown_attrs(&["from", "to", "fallback", "max_rate_hz"]));
    no_children(element, problems);
    no_text(element, problems);
    let from = endpoint_attr(element, "from", "MODULE.OUTPUT", problems);
    let to = endpoint_attr(element, "to", "MODULE.INPUT", problems);
    let fallback = match element.attr("fallback") {
        None => Some(0),
        Some(attr) => match attr.value.parse::<u32>() {
            Ok(rank) if rank > 0 => Some(rank),
            _ => {
                problems.push(Located::new(
                    attr.pos,
                    format!(
                        "`fallback` is the fallback's rank, 1, 2, …, not `{}`",
                        attr.value
                    ),
                ));
                None
            }
        },
    };
    let max_rate_hz = match element.attr("max_rate_hz") {
        None => Some(None),
        Some(attr) => match attr.value.trim().parse::<f64>() {
            Ok(hz) if hz.is_finite() && hz > 0.0 => Some(Some(hz)),
            _ => {
                problems.push(Located::new(
                    attr.pos,
                    format!(
                        "`max_rate_hz` is a number of samples a second above 0, not `{}`",
                        attr.value
                    ),
                ));
                None
            }
        },
    };
    let ((from, from_pos), (to, to_pos)) = (from?, to?);
    Some(Link {
        from,
        to,
        fallback: fallback?,
        pos: element.pos,
        from_pos,
        to_pos,
        max_rate_hz: max_rate_hz?,
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

fn read_host(element: &Element, problems: &mut Vec<Located>) -> Option<HostDecl> {
    problems.extend(element.unknown_attrs(&["name", "address", "port"]));
    no_children(element, problems);
    no_text(element, problems);
    let name = identifier(element, "name", "host name", problems);
    let address = required(element, "address", problems).map(|field| field.value.to_owned());
    let port = match element.attr("port") {
        None => Some(DEFAULT_HOST_PORT),
        Some(attr) => match attr.value.trim().parse::<u16>() {
            Ok(port) if port > 0 => Some(port),
            _ => {
                problems.push(Located::new(
                    attr.pos,
                    format!("`port` is a TCP port, 1 to 65535, not `{}`", attr.value),
                ));
                None
            }
        },
    };
    Some(HostDecl {
        name: name?,
        address: address?,
        port: port?,
        pos: element.pos,
    })
}

fn host_attr(element: &Element, problems: &mut Vec<Located>) -> Option<String> {
    element.attr("host")?;
    required(element, "host", problems).map(|field| field.value.to_owned())
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
