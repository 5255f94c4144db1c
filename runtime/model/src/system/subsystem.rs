//! Subsystems: named groups of module instances, as Simulink's subsystems, drawn as one block
//! in the studio and named as a whole by a mission place.
//!
//! ```xml
//! <subsystem name="navigation">
//!   <member module="follower"/>
//!   <member module="arbiter"/>
//!   <subsystem name="avoidance">
//!     <member module="vff"/>
//!   </subsystem>
//!   <port name="cmd_vel" of="arbiter.cmd_vel"/>
//! </subsystem>
//! ```
//!
//! A subsystem changes nothing at run time: its modules are modules of the system like any
//! other, and links always join two modules (`armor run` runs the flat system). What it adds is
//! a name for a group (a place that names `navigation` runs every module in it) and the ports
//! it *exposes* on its border, each a port of a module inside it (`of`), which the studio draws
//! on the group's block. Subsystems nest; a module belongs to one subsystem at most.
//! [`check_subsystems`] reports every name that is wrong, with its position.

use std::collections::BTreeMap;

use armor_module_api::describe::ModuleDescription;
use armor_module_api::xml::{Element, Located, Pos};

use super::{Endpoint, ModuleInstance, SystemConfig};
use crate::fields::{escape, identifier, listing, no_children, no_text, required};

/// A named group of module instances (and of nested subsystems).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Subsystem {
    pub name: String,
    /// The modules directly in it (not those of its nested subsystems).
    pub members: Vec<Member>,
    /// Subsystems inside it.
    pub subsystems: Vec<Subsystem>,
    /// The ports it shows on its border.
    pub ports: Vec<ExposedPort>,
    /// The `<subsystem>` element.
    pub pos: Pos,
}

/// `<member module="NAME"/>`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Member {
    pub module: String,
    pub pos: Pos,
}

/// `<port name="NAME" of="MODULE.PORT"/>`: a port of a module inside the subsystem, shown on
/// its border under `name`. It is an input or an output as the module's port is.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExposedPort {
    pub name: String,
    pub of: Endpoint,
    /// The `<port>` element.
    pub pos: Pos,
    /// The `of` attribute.
    pub of_pos: Pos,
}

impl Subsystem {
    pub fn new(name: &str) -> Self {
        Subsystem {
            name: name.to_owned(),
            members: Vec::new(),
            subsystems: Vec::new(),
            ports: Vec::new(),
            pos: Pos::default(),
        }
    }

    /// Every module in it, nested subsystems' too, in the file's order (its own first).
    pub fn modules(&self) -> Vec<&str> {
        let mut modules: Vec<&str> = self.members.iter().map(|m| m.module.as_str()).collect();
        for inner in &self.subsystems {
            modules.extend(inner.modules());
        }
        modules
    }

    /// Whether `module` is in it, at any depth.
    pub fn contains(&self, module: &str) -> bool {
        self.members.iter().any(|member| member.module == module)
            || self.subsystems.iter().any(|inner| inner.contains(module))
    }

    /// It and every subsystem inside it, depth first, each with its path from it (`[self]`,
    /// `[self, inner]`, …).
    pub fn walk(&self) -> Vec<Vec<&Subsystem>> {
        let mut out = vec![vec![self]];
        for inner in &self.subsystems {
            for mut path in inner.walk() {
                path.insert(0, self);
                out.push(path);
            }
        }
        out
    }
}

impl SystemConfig {
    /// Every subsystem, depth first, each with its path from the top (outermost first).
    pub fn all_subsystems(&self) -> Vec<Vec<&Subsystem>> {
        self.subsystems.iter().flat_map(Subsystem::walk).collect()
    }

    /// The subsystem called `name`, at any depth.
    pub fn subsystem(&self, name: &str) -> Option<&Subsystem> {
        self.all_subsystems()
            .into_iter()
            .filter_map(|path| path.last().copied())
            .find(|subsystem| subsystem.name == name)
    }

    /// The subsystems `module` is in, outermost first (empty when it is in none).
    pub fn subsystem_path(&self, module: &str) -> Vec<&str> {
        self.all_subsystems()
            .into_iter()
            .find(|path| {
                path.last()
                    .is_some_and(|inner| inner.members.iter().any(|m| m.module == module))
            })
            .map(|path| path.iter().map(|s| s.name.as_str()).collect())
            .unwrap_or_default()
    }

    /// The modules `name` stands for: the module itself, or every module of the subsystem so
    /// called; `None` when the system has neither.
    pub fn units(&self, name: &str) -> Option<Vec<String>> {
        if self.module(name).is_some() {
            return Some(vec![name.to_owned()]);
        }
        self.subsystem(name)
            .map(|subsystem| subsystem.modules().into_iter().map(str::to_owned).collect())
    }
}

/// Reads a `<subsystem>` element (and those inside it).
pub(super) fn read_subsystem(element: &Element, problems: &mut Vec<Located>) -> Option<Subsystem> {
    problems.extend(element.unknown_attrs(&["name"]));
    problems.extend(element.unknown_children(&["member", "port", "subsystem"]));
    no_text(element, problems);
    let name = identifier(element, "name", "name", problems);
    let mut subsystem = Subsystem::new("");
    subsystem.pos = element.pos;
    for child in &element.children {
        match child.name.as_str() {
            "member" => {
                problems.extend(child.unknown_attrs(&["module"]));
                no_children(child, problems);
                no_text(child, problems);
                if let Some(module) = identifier(child, "module", "module name", problems) {
                    subsystem.members.push(Member {
                        module,
                        pos: child.pos,
                    });
                }
            }
            "port" => {
                problems.extend(child.unknown_attrs(&["name", "of"]));
                no_children(child, problems);
                no_text(child, problems);
                let name = identifier(child, "name", "port name", problems);
                let of = required(child, "of", problems).and_then(|field| {
                    match field.value.parse::<Endpoint>() {
                        Ok(of) => Some((of, field.pos)),
                        Err(()) => {
                            problems.push(Located::new(
                                field.pos,
                                format!(
                                    "`of` must be MODULE.PORT (two names joined by a dot), not `{}`",
                                    field.value
                                ),
                            ));
                            None
                        }
                    }
                });
                if let (Some(name), Some((of, of_pos))) = (name, of) {
                    subsystem.ports.push(ExposedPort {
                        name,
                        of,
                        pos: child.pos,
                        of_pos,
                    });
                }
            }
            "subsystem" => {
                if let Some(inner) = read_subsystem(child, problems) {
                    subsystem.subsystems.push(inner);
                }
            }
            _ => {}
        }
    }
    subsystem.name = name?;
    Some(subsystem)
}

/// Writes `subsystem` at `depth` (two spaces each).
pub(super) fn write_subsystem(out: &mut String, subsystem: &Subsystem, depth: usize) {
    use std::fmt::Write as _;
    let indent = "  ".repeat(depth);
    let _ = writeln!(
        out,
        "{indent}<subsystem name=\"{}\">",
        escape(&subsystem.name)
    );
    for member in &subsystem.members {
        let _ = writeln!(
            out,
            "{indent}  <member module=\"{}\"/>",
            escape(&member.module)
        );
    }
    for inner in &subsystem.subsystems {
        write_subsystem(out, inner, depth + 1);
    }
    for port in &subsystem.ports {
        let _ = writeln!(
            out,
            "{indent}  <port name=\"{}\" of=\"{}\"/>",
            escape(&port.name),
            escape(&port.of.to_string())
        );
    }
    let _ = writeln!(out, "{indent}</subsystem>");
}

/// Every problem of the subsystems of `system`: duplicate names (among subsystems, or a
/// subsystem named as a module), members that are not modules of the system or that are
/// already in a subsystem, empty subsystems, exposed ports of modules outside the subsystem,
/// ports the module's type does not have (with `descriptions`), and port names given twice.
pub(super) fn check_subsystems(
    system: &SystemConfig,
    modules: &BTreeMap<&str, &ModuleInstance>,
    descriptions: &BTreeMap<String, ModuleDescription>,
    problems: &mut Vec<Located>,
) {
    let mut names: BTreeMap<&str, Pos> = BTreeMap::new();
    let mut placed: BTreeMap<&str, (&str, Pos)> = BTreeMap::new();
    for path in system.all_subsystems() {
        let Some(subsystem) = path.last().copied() else {
            continue;
        };
        let name = subsystem.name.as_str();
        if let Some(module) = modules.get(name) {
            problems.push(Located::new(
                subsystem.pos,
                format!(
                    "subsystem `{name}`: a module has that name (line {}); a place names one or the other",
                    module.pos.line
                ),
            ));
        }
        match names.get(name) {
            Some(first) => problems.push(Located::new(
                subsystem.pos,
                format!(
                    "subsystem `{name}` is already defined at line {}",
                    first.line
                ),
            )),
            None => {
                names.insert(name, subsystem.pos);
            }
        }
        if subsystem.members.is_empty() && subsystem.subsystems.is_empty() {
            problems.push(Located::new(
                subsystem.pos,
                format!("subsystem `{name}` has no member (add <member module=\"…\"/>)"),
            ));
        }
        for member in &subsystem.members {
            let module = member.module.as_str();
            if !modules.contains_key(module) {
                problems.push(Located::new(
                    member.pos,
                    format!(
                        "subsystem `{name}`: no module `{module}` in this system (modules: {})",
                        listing(modules.keys().copied())
                    ),
                ));
                continue;
            }
            match placed.get(module) {
                Some((other, pos)) => problems.push(Located::new(
                    member.pos,
                    format!(
                        "subsystem `{name}`: module `{module}` is already a member of `{other}` \
                         (line {}); a module is in one subsystem at most",
                        pos.line
                    ),
                )),
                None => {
                    placed.insert(module, (name, member.pos));
                }
            }
        }
        let mut ports: BTreeMap<&str, Pos> = BTreeMap::new();
        for port in &subsystem.ports {
            if let Some(first) = ports.get(port.name.as_str()) {
                problems.push(Located::new(
                    port.pos,
                    format!(
                        "subsystem `{name}`: port `{}` is already exposed at line {}",
                        port.name, first.line
                    ),
                ));
            } else {
                ports.insert(&port.name, port.pos);
            }
            let owner = port.of.module.as_str();
            if !subsystem.contains(owner) {
                problems.push(Located::new(
                    port.of_pos,
                    format!(
                        "subsystem `{name}`: port `{}` is of `{}`, but module `{owner}` is not in \
                         the subsystem (members: {})",
                        port.name,
                        port.of,
                        listing(subsystem.modules())
                    ),
                ));
                continue;
            }
            let Some(description) = modules
                .get(owner)
                .and_then(|module| descriptions.get(&module.module_type))
            else {
                continue;
            };
            let exists = description
                .inputs
                .iter()
                .chain(&description.outputs)
                .any(|spec| spec.name == port.of.port);
            if !exists {
                problems.push(Located::new(
                    port.of_pos,
                    format!(
                        "subsystem `{name}`: port `{}` is of `{}`, but module `{owner}` (type `{}`) \
                         has no port `{}` (ports: {})",
                        port.name,
                        port.of,
                        description.module_type,
                        port.of.port,
                        listing(
                            description
                                .inputs
                                .iter()
                                .chain(&description.outputs)
                                .map(|spec| spec.name.as_str())
                        )
                    ),
                ));
            }
        }
    }
}
