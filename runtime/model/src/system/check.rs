//! The checks of a system against the descriptions of its module types: [`check`].

use std::collections::BTreeMap;

use armor_module_api::describe::{ModuleDescription, PortSpec};
use armor_module_api::protocol::HEALTH;
use armor_module_api::xml::{Located, Pos};

use super::{Endpoint, Link, ModuleInstance, ParamValue, SystemConfig};
use crate::fields::listing;

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
                    listing(descriptions.keys().map(String::as_str))
                ),
            )),
        }
    }
    // A data name has one publisher: a module's own names are its own, and a `may_publish`
    // that grants another module's output to a second one would let either take it (the agent
    // gives it to the grantee, and the owner's registration is refused).
    for grantee in &system.modules {
        let Some(patterns) = grantee.may_publish.as_deref() else {
            continue;
        };
        for module in system.modules.iter().filter(|m| m.name != grantee.name) {
            let Some(description) = descriptions.get(&module.module_type) else {
                continue;
            };
            for output in &description.outputs {
                let data_name = format!("{}.{}", module.name, output.name);
                if super::allowed(Some(patterns), &data_name) {
                    problems.push(Located::new(
                        grantee.pos,
                        format!(
                            "module `{}`: its may_publish covers `{data_name}`, an output of \
                             module `{}`; a data name has one publisher",
                            grantee.name, module.name
                        ),
                    ));
                }
            }
        }
    }
    // The run's health stream is an output of the runtime, not of a module.
    let health = PortSpec {
        name: "health".to_owned(),
        data_type: "Health".to_owned(),
        doc: String::new(),
    };
    // (Input, fallback rank) -> the first link feeding it so.
    let mut fed: BTreeMap<(&Endpoint, u32), &Link> = BTreeMap::new();
    for link in &system.links {
        let from = if link.from.to_string() == HEALTH {
            Some(Some(&health))
        } else {
            resolve(
                &link.from,
                link.from_pos,
                Side::From,
                &modules,
                descriptions,
                &mut problems,
            )
        };
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
            match fed.get(&(&link.to, link.fallback)) {
                Some(first) if link.fallback == 0 => problems.push(Located::new(
                    link.to_pos,
                    format!(
                        "input `{}` is already fed by `{}` (line {}); another source is a \
                         fallback (fallback=\"1\", \"2\", …)",
                        link.to, first.from, first.pos.line
                    ),
                )),
                Some(first) => problems.push(Located::new(
                    link.pos,
                    format!(
                        "input `{}` already has `{}` as fallback {} (line {})",
                        link.to, first.from, link.fallback, first.pos.line
                    ),
                )),
                None => {
                    fed.insert((&link.to, link.fallback), link);
                }
            }
        }
    }
    for ((input, rank), link) in &fed {
        if *rank > 0 && !fed.contains_key(&(*input, 0)) {
            problems.push(Located::new(
                link.pos,
                format!(
                    "input `{input}` has a fallback but no source: one of its links needs no \
                     `fallback`"
                ),
            ));
        }
    }
    super::subsystem::check_subsystems(system, &modules, descriptions, &mut problems);
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
                    listing(description.params.iter().map(|spec| spec.name.as_str()))
                ),
            ));
            continue;
        };
        if let Err(why) = spec.check_value(&param.value) {
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
            listing(ports.iter().map(|port| port.name.as_str()))
        )
    };
    problems.push(Located::new(pos, message));
    None
}
