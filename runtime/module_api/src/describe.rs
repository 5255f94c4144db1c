//! What a module says about itself when run with `--describe`: the contract between module
//! binaries (in any language) and the tools that have never seen them (`armor probe`, the studio).
//!
//! The XML form is documented in `docs/protocol.md`; [`ModuleDescription::to_xml`] writes it and
//! [`ModuleDescription::from_xml`] reads it back, reporting problems with line and column.

use std::fmt;
use std::str::FromStr;

use crate::xml::{self, Element, Located};

/// The type of a parameter value, as written in XML (`bool`, `int`, `float`, `string`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ParamType {
    Bool,
    Int,
    Float,
    String,
}

impl ParamType {
    pub fn as_str(self) -> &'static str {
        match self {
            ParamType::Bool => "bool",
            ParamType::Int => "int",
            ParamType::Float => "float",
            ParamType::String => "string",
        }
    }

    /// Checks that `value` is a valid literal of this type; the error says why in words.
    pub fn check_value(self, value: &str) -> Result<(), ValueError> {
        let ok = match self {
            ParamType::Bool => matches!(value.trim(), "true" | "false"),
            ParamType::Int => value.trim().parse::<i64>().is_ok(),
            ParamType::Float => value.trim().parse::<f64>().is_ok_and(f64::is_finite),
            ParamType::String => true,
        };
        if ok {
            Ok(())
        } else {
            let expected = match self {
                ParamType::Bool => "`true` or `false`",
                ParamType::Int => "a whole number",
                ParamType::Float => "a finite number",
                ParamType::String => "text",
            };
            Err(ValueError::NotOfType {
                value: value.to_owned(),
                expected,
            })
        }
    }
}

/// Why a value does not fit a parameter, in the words a user reads: "`-5` is not greater than
/// 0°".
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ValueError {
    /// Not a literal of the parameter's type (`expected`: "a whole number").
    #[error("`{value}` is not {expected}")]
    NotOfType {
        value: String,
        expected: &'static str,
    },
    /// Of its type, but outside its range, `nonzero` or choices (`allowed`, in words).
    #[error("`{value}` is not {allowed}")]
    NotAllowed { value: String, allowed: String },
}

/// A parameter type's name that is none of ours.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown parameter type `{0}` (expected bool, int, float or string)")]
pub struct UnknownParamType(pub String);

impl fmt::Display for ParamType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for ParamType {
    type Err = UnknownParamType;
    fn from_str(s: &str) -> Result<Self, UnknownParamType> {
        match s {
            "bool" => Ok(ParamType::Bool),
            "int" => Ok(ParamType::Int),
            "float" => Ok(ParamType::Float),
            "string" => Ok(ParamType::String),
            other => Err(UnknownParamType(other.to_owned())),
        }
    }
}

/// An input or an output of a module.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PortSpec {
    pub name: String,
    /// The data type carried, for example `Counter` or `LaserScan`; links must match it exactly.
    pub data_type: String,
    pub doc: String,
}

/// One end of a numeric parameter's range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    pub value: f64,
    /// Whether the value itself is allowed (`min`, `max`) or only values beyond it
    /// (`min_exclusive`, `max_exclusive`).
    pub inclusive: bool,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ParamSpec {
    pub name: String,
    pub param_type: ParamType,
    /// Unit of the value (`s`, `m/s`, ...), empty when the value has none.
    pub unit: String,
    /// The value used when the configuration gives none; `None` makes the parameter required.
    pub default: Option<String>,
    pub doc: String,
    /// The lowest value allowed (`int` and `float` only).
    pub min: Option<Bound>,
    /// The highest value allowed (`int` and `float` only).
    pub max: Option<Bound>,
    /// 0 is refused (`int` and `float` only).
    pub nonzero: bool,
    /// The only values allowed, when not empty (`string` only).
    pub choices: Vec<String>,
    /// The value names a file the module reads (`string` only), bundled under
    /// `assets/FOLDER/` with this folder: the runtime resolves it (next to the system file
    /// first) and hands the module a path it can open, and `armor check` refuses a file it
    /// cannot find or read.
    pub file: Option<String>,
}

impl ParamSpec {
    pub fn new(name: &str, param_type: ParamType, doc: &str) -> Self {
        Self {
            name: name.to_owned(),
            param_type,
            unit: String::new(),
            default: None,
            doc: doc.to_owned(),
            min: None,
            max: None,
            nonzero: false,
            choices: Vec::new(),
            file: None,
        }
    }

    pub fn unit(mut self, unit: &str) -> Self {
        self.unit = unit.to_owned();
        self
    }

    pub fn default(mut self, value: &str) -> Self {
        self.default = Some(value.to_owned());
        self
    }

    /// `value` or more.
    pub fn min(mut self, value: f64) -> Self {
        self.min = Some(Bound {
            value,
            inclusive: true,
        });
        self
    }

    /// Strictly greater than `value`.
    pub fn above(mut self, value: f64) -> Self {
        self.min = Some(Bound {
            value,
            inclusive: false,
        });
        self
    }

    /// `value` or less.
    pub fn max(mut self, value: f64) -> Self {
        self.max = Some(Bound {
            value,
            inclusive: true,
        });
        self
    }

    /// Strictly less than `value`.
    pub fn below(mut self, value: f64) -> Self {
        self.max = Some(Bound {
            value,
            inclusive: false,
        });
        self
    }

    /// 0 is refused.
    pub fn nonzero(mut self) -> Self {
        self.nonzero = true;
        self
    }

    /// The only values allowed.
    pub fn choices(mut self, choices: &[&str]) -> Self {
        self.choices = choices.iter().map(|&choice| choice.to_owned()).collect();
        self
    }

    /// The value names a file the module reads, bundled under `assets/FOLDER/`.
    pub fn file(mut self, assets_folder: &str) -> Self {
        self.file = Some(assets_folder.to_owned());
        self
    }

    pub fn is_required(&self) -> bool {
        self.default.is_none()
    }

    /// Whether a range, `nonzero` or choices limit the values beyond their type.
    pub fn is_limited(&self) -> bool {
        self.min.is_some() || self.max.is_some() || self.nonzero || !self.choices.is_empty()
    }

    /// Checks that `value` is a valid literal of the parameter's type and within its range,
    /// `nonzero` and choices; the error says why in words: "`-5` is not greater than 0°".
    pub fn check_value(&self, value: &str) -> Result<(), ValueError> {
        self.param_type.check_value(value)?;
        match self.param_type {
            ParamType::Int | ParamType::Float => {
                let Ok(number) = value.trim().parse::<f64>() else {
                    return Ok(());
                };
                let low = self.min.is_none_or(|bound| {
                    number > bound.value || (bound.inclusive && number == bound.value)
                });
                let high = self.max.is_none_or(|bound| {
                    number < bound.value || (bound.inclusive && number == bound.value)
                });
                if low && high && !(self.nonzero && number == 0.0) {
                    Ok(())
                } else {
                    Err(ValueError::NotAllowed {
                        value: value.trim().to_owned(),
                        allowed: self.range_text(),
                    })
                }
            }
            ParamType::String if !self.choices.is_empty() => {
                if self.choices.iter().any(|choice| choice == value) {
                    Ok(())
                } else {
                    Err(ValueError::NotAllowed {
                        value: value.to_owned(),
                        allowed: self.range_text(),
                    })
                }
            }
            ParamType::Bool | ParamType::String => Ok(()),
        }
    }

    /// The values allowed in words: `greater than 0 Hz and at most 1000 Hz`, `between 0° and
    /// 45°`, `non-zero`, `one of: sorted, random`; `any TYPE` when nothing limits them.
    pub fn range_text(&self) -> String {
        let quantity = |value: f64| match self.unit.as_str() {
            "" => format!("{value}"),
            "°" | "deg" => format!("{value}°"),
            unit => format!("{value} {unit}"),
        };
        if !self.choices.is_empty() {
            return format!("one of: {}", self.choices.join(", "));
        }
        let mut parts = Vec::new();
        match (self.min, self.max) {
            (Some(low), Some(high)) if low.inclusive && high.inclusive => parts.push(format!(
                "between {} and {}",
                quantity(low.value),
                quantity(high.value)
            )),
            (low, high) => {
                if let Some(low) = low {
                    parts.push(if low.inclusive {
                        format!("{} or more", quantity(low.value))
                    } else {
                        format!("greater than {}", quantity(low.value))
                    });
                }
                if let Some(high) = high {
                    parts.push(if high.inclusive {
                        format!("at most {}", quantity(high.value))
                    } else {
                        format!("less than {}", quantity(high.value))
                    });
                }
            }
        }
        if self.nonzero {
            parts.push("non-zero".to_owned());
        }
        if parts.is_empty() {
            format!("any {}", self.param_type)
        } else {
            parts.join(" and ")
        }
    }
}

/// A module's role, which tools show (the studio colours a block's header by it). Optional in
/// the describe format: a module that says none, or one this version does not know, is
/// [`Category::Other`], so modules written before categories existed, and categories added
/// later, are read without complaint.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Category {
    /// Sensors and simulators: where data comes from.
    Sensor,
    Navigation,
    Mapping,
    /// Operator interfaces (teleop and the like).
    Operator,
    Recording,
    #[default]
    Other,
}

impl Category {
    /// Every category, in the order tools list them.
    pub const ALL: [Category; 6] = [
        Category::Sensor,
        Category::Navigation,
        Category::Mapping,
        Category::Operator,
        Category::Recording,
        Category::Other,
    ];

    /// As written in XML.
    pub fn as_str(self) -> &'static str {
        match self {
            Category::Sensor => "sensor",
            Category::Navigation => "navigation",
            Category::Mapping => "mapping",
            Category::Operator => "operator",
            Category::Recording => "recording",
            Category::Other => "other",
        }
    }

    /// As read from XML: an unknown name is `Other`, never an error (see the type's doc).
    pub fn from_name(name: &str) -> Self {
        Category::ALL
            .into_iter()
            .find(|category| category.as_str() == name)
            .unwrap_or_default()
    }
}

impl fmt::Display for Category {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EventSpec {
    pub name: String,
    pub doc: String,
}

/// Everything a tool needs to know about a module type without running it for real.
#[derive(Clone, Debug, PartialEq)]
pub struct ModuleDescription {
    /// The module type; its binary is `armor-mod-<module_type>`.
    pub module_type: String,
    pub version: String,
    /// One line saying what the module does.
    pub doc: String,
    pub inputs: Vec<PortSpec>,
    pub outputs: Vec<PortSpec>,
    pub params: Vec<ParamSpec>,
    pub events: Vec<EventSpec>,
    /// `false` for modules the mission controller must never stop (operator interfaces).
    pub controllable: bool,
    /// Its role (`category="…"`, optional).
    pub category: Category,
}

impl ModuleDescription {
    pub fn new(module_type: &str, doc: &str) -> Self {
        Self {
            module_type: module_type.to_owned(),
            version: "0.0.0".to_owned(),
            doc: doc.to_owned(),
            inputs: Vec::new(),
            outputs: Vec::new(),
            params: Vec::new(),
            events: Vec::new(),
            controllable: true,
            category: Category::Other,
        }
    }

    pub fn input(&self, name: &str) -> Option<&PortSpec> {
        self.inputs.iter().find(|port| port.name == name)
    }

    pub fn output(&self, name: &str) -> Option<&PortSpec> {
        self.outputs.iter().find(|port| port.name == name)
    }

    pub fn param(&self, name: &str) -> Option<&ParamSpec> {
        self.params.iter().find(|param| param.name == name)
    }

    pub fn event(&self, name: &str) -> Option<&EventSpec> {
        self.events.iter().find(|event| event.name == name)
    }

    pub fn to_xml(&self) -> String {
        use std::fmt::Write as _;
        let e = |s: &str| xml::escape(s).into_owned();
        let mut out = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
        let _ = write!(
            out,
            "<module type=\"{}\" version=\"{}\" controllable=\"{}\"",
            e(&self.module_type),
            e(&self.version),
            self.controllable
        );
        // Written only when it says something, so that a module without one describes itself
        // exactly as before categories existed.
        if self.category != Category::Other {
            let _ = write!(out, " category=\"{}\"", self.category);
        }
        out.push_str(">\n");
        let _ = writeln!(out, "  <doc>{}</doc>", e(&self.doc));
        for (tag, ports) in [("input", &self.inputs), ("output", &self.outputs)] {
            for port in ports {
                let _ = writeln!(
                    out,
                    "  <{tag} name=\"{}\" type=\"{}\" doc=\"{}\"/>",
                    e(&port.name),
                    e(&port.data_type),
                    e(&port.doc)
                );
            }
        }
        for param in &self.params {
            let _ = write!(
                out,
                "  <param name=\"{}\" type=\"{}\"",
                e(&param.name),
                param.param_type
            );
            if !param.unit.is_empty() {
                let _ = write!(out, " unit=\"{}\"", e(&param.unit));
            }
            match &param.default {
                Some(default) => {
                    let _ = write!(out, " default=\"{}\"", e(default));
                }
                None => out.push_str(" required=\"true\""),
            }
            for (attr, bound, inclusive) in [
                ("min", param.min, true),
                ("min_exclusive", param.min, false),
                ("max", param.max, true),
                ("max_exclusive", param.max, false),
            ] {
                if let Some(bound) = bound.filter(|bound| bound.inclusive == inclusive) {
                    let _ = write!(out, " {attr}=\"{}\"", bound.value);
                }
            }
            if param.nonzero {
                out.push_str(" nonzero=\"true\"");
            }
            if !param.choices.is_empty() {
                let _ = write!(out, " choices=\"{}\"", e(&param.choices.join("|")));
            }
            if let Some(folder) = &param.file {
                let _ = write!(out, " file=\"{}\"", e(folder));
            }
            let _ = writeln!(out, " doc=\"{}\"/>", e(&param.doc));
        }
        for event in &self.events {
            let _ = writeln!(
                out,
                "  <event name=\"{}\" doc=\"{}\"/>",
                e(&event.name),
                e(&event.doc)
            );
        }
        out.push_str("</module>\n");
        out
    }

    /// Reads a description, reporting every problem found (not just the first).
    pub fn from_xml(text: &str) -> Result<Self, Vec<Located>> {
        let root = xml::parse(text).map_err(|err| vec![err])?;
        let mut problems = Vec::new();
        if root.name != "module" {
            return Err(vec![Located::new(
                root.pos,
                format!("expected <module> at the top, found <{}>", root.name),
            )]);
        }
        problems.extend(root.unknown_attrs(&["type", "version", "controllable", "category"]));
        problems.extend(root.unknown_children(&["doc", "input", "output", "param", "event"]));
        let mut description = ModuleDescription::new("", "");
        match root.required_attr("type") {
            Ok(attr) if is_identifier(&attr.value) => {
                description.module_type = attr.value.as_str().to_owned()
            }
            Ok(attr) => problems.push(Located::new(
                attr.pos,
                format!(
                    "module type `{}` must be letters, digits, `_` or `-`",
                    attr.value
                ),
            )),
            Err(err) => problems.push(err),
        }
        description.version = root.attr_value("version").unwrap_or("0.0.0").to_owned();
        if let Some(attr) = root.attr("controllable") {
            match attr.value.as_str() {
                "true" => description.controllable = true,
                "false" => description.controllable = false,
                other => problems.push(Located::new(
                    attr.pos,
                    format!("`controllable` must be `true` or `false`, not `{other}`"),
                )),
            }
        }
        description.category = root
            .attr_value("category")
            .map_or(Category::Other, Category::from_name);
        for child in &root.children {
            let doc = child.attr_value("doc").unwrap_or_default().to_owned();
            match child.name.as_str() {
                "doc" => description.doc = child.text.trim().to_owned(),
                "input" | "output" => {
                    problems.extend(child.unknown_attrs(&["name", "type", "doc"]));
                    let (Some(name), Some(data_type)) = (
                        named(child, &mut problems),
                        attr_or_problem(child, "type", &mut problems),
                    ) else {
                        continue;
                    };
                    let ports = if child.name == "input" {
                        &mut description.inputs
                    } else {
                        &mut description.outputs
                    };
                    if ports.iter().any(|port| port.name == name) {
                        problems.push(Located::new(
                            child.pos,
                            format!("{} `{name}` is declared twice", child.name),
                        ));
                    }
                    ports.push(PortSpec {
                        name,
                        data_type,
                        doc,
                    });
                }
                "param" => {
                    problems.extend(child.unknown_attrs(&[
                        "name",
                        "type",
                        "unit",
                        "default",
                        "required",
                        "min",
                        "min_exclusive",
                        "max",
                        "max_exclusive",
                        "nonzero",
                        "choices",
                        "file",
                        "doc",
                    ]));
                    if let Some(param) = read_param(child, doc, &mut problems) {
                        if description.param(&param.name).is_some() {
                            problems.push(Located::new(
                                child.pos,
                                format!("parameter `{}` is declared twice", param.name),
                            ));
                        }
                        description.params.push(param);
                    }
                }
                "event" => {
                    problems.extend(child.unknown_attrs(&["name", "doc"]));
                    if let Some(name) = named(child, &mut problems) {
                        description.events.push(EventSpec { name, doc });
                    }
                }
                _ => {}
            }
        }
        if problems.is_empty() {
            Ok(description)
        } else {
            problems.sort_by_key(|problem| problem.pos);
            Err(problems)
        }
    }
}

fn read_param(child: &Element, doc: String, problems: &mut Vec<Located>) -> Option<ParamSpec> {
    let name = named(child, problems)?;
    let type_attr = child
        .required_attr("type")
        .map_err(|err| problems.push(err))
        .ok()?;
    let param_type: ParamType = type_attr
        .value
        .parse()
        .map_err(|err: UnknownParamType| {
            problems.push(Located::new(type_attr.pos, err.to_string()))
        })
        .ok()?;
    let default = child.attr("default");
    let required = child.attr("required");
    if let Some(required) = required {
        let expected_required = default.is_none();
        let stated: Option<bool> = required.value.parse().ok();
        if stated != Some(expected_required) {
            problems.push(Located::new(
                required.pos,
                format!(
                    "parameter `{name}`: `required` must be `{expected_required}` when a default is {}",
                    if default.is_some() { "given" } else { "absent" }
                ),
            ));
        }
    }
    let mut spec = ParamSpec::new(&name, param_type, &doc);
    spec.unit = child.attr_value("unit").unwrap_or_default().to_owned();
    read_limits(child, &mut spec, problems);
    if let Some(default) = default {
        if let Err(why) = spec.check_value(&default.value) {
            problems.push(Located::new(
                default.pos,
                format!("default of parameter `{name}` ({param_type}): {why}"),
            ));
        }
        spec.default = Some(default.value.as_str().to_owned());
    }
    Some(spec)
}

/// Reads a parameter's range (`min` or `min_exclusive`, `max` or `max_exclusive`, `nonzero`)
/// and `choices` into `spec`, refusing those its type cannot have and ranges that hold no value.
fn read_limits(child: &Element, spec: &mut ParamSpec, problems: &mut Vec<Located>) {
    let numeric = matches!(spec.param_type, ParamType::Int | ParamType::Float);
    let name = spec.name.clone();
    let bound = |attr: &str, inclusive: bool, problems: &mut Vec<Located>| {
        let found = child.attr(attr)?;
        if !numeric {
            problems.push(Located::new(
                found.pos,
                format!(
                    "parameter `{name}`: `{attr}` applies to `int` and `float` parameters, not `{}`",
                    spec.param_type
                ),
            ));
            return None;
        }
        match found.value.trim().parse::<f64>() {
            Ok(value) if value.is_finite() => Some(Bound { value, inclusive }),
            _ => {
                problems.push(Located::new(
                    found.pos,
                    format!(
                        "parameter `{name}`: `{attr}` must be a finite number, not `{}`",
                        found.value
                    ),
                ));
                None
            }
        }
    };
    for (low, high) in [("min", "min_exclusive"), ("max", "max_exclusive")] {
        let (inclusive, exclusive) = (bound(low, true, problems), bound(high, false, problems));
        if inclusive.is_some() && exclusive.is_some() {
            problems.push(Located::new(
                child.pos,
                format!("parameter `{name}`: give `{low}` or `{high}`, not both"),
            ));
        }
        let found = inclusive.or(exclusive);
        if low == "min" {
            spec.min = found;
        } else {
            spec.max = found;
        }
    }
    if let (Some(low), Some(high)) = (spec.min, spec.max)
        && (low.value > high.value
            || (low.value == high.value && !(low.inclusive && high.inclusive)))
    {
        problems.push(Located::new(
            child.pos,
            format!(
                "parameter `{name}`: its range holds no value ({})",
                spec.range_text()
            ),
        ));
    }
    if let Some(attr) = child.attr("nonzero") {
        match attr.value.as_str() {
            "true" if numeric => spec.nonzero = true,
            "false" => {}
            "true" => problems.push(Located::new(
                attr.pos,
                format!(
                    "parameter `{name}`: `nonzero` applies to `int` and `float` parameters, not `{}`",
                    spec.param_type
                ),
            )),
            other => problems.push(Located::new(
                attr.pos,
                format!("parameter `{name}`: `nonzero` must be `true` or `false`, not `{other}`"),
            )),
        }
    }
    if let Some(attr) = child.attr("choices") {
        if spec.param_type != ParamType::String {
            problems.push(Located::new(
                attr.pos,
                format!(
                    "parameter `{name}`: `choices` applies to `string` parameters, not `{}`",
                    spec.param_type
                ),
            ));
        } else if attr.value.is_empty() {
            problems.push(Located::new(
                attr.pos,
                format!("parameter `{name}`: `choices` lists no value"),
            ));
        } else {
            spec.choices = attr.value.split('|').map(str::to_owned).collect();
        }
    }
    if let Some(attr) = child.attr("file") {
        if spec.param_type != ParamType::String {
            problems.push(Located::new(
                attr.pos,
                format!(
                    "parameter `{name}`: `file` applies to `string` parameters, not `{}`",
                    spec.param_type
                ),
            ));
        } else if !is_identifier(&attr.value) {
            problems.push(Located::new(
                attr.pos,
                format!(
                    "parameter `{name}`: `file` names a folder under assets/ (letters, digits, `_`, `-`), not `{}`",
                    attr.value
                ),
            ));
        } else {
            spec.file = Some(attr.value.as_str().to_owned());
        }
    }
}

fn attr_or_problem(element: &Element, name: &str, problems: &mut Vec<Located>) -> Option<String> {
    element
        .required_attr(name)
        .map(|attr| attr.value.as_str().to_owned())
        .map_err(|err| problems.push(err))
        .ok()
}

fn named(element: &Element, problems: &mut Vec<Located>) -> Option<String> {
    let attr = element
        .required_attr("name")
        .map_err(|err| problems.push(err))
        .ok()?;
    if is_identifier(&attr.value) {
        Some(attr.value.as_str().to_owned())
    } else {
        problems.push(Located::new(
            attr.pos,
            format!(
                "name `{}` of <{}> must be letters, digits, `_` or `-`",
                attr.value, element.name
            ),
        ));
        None
    }
}

/// Names of modules, ports, parameters and events: ASCII letters, digits, `_` and `-`, not
/// starting with a digit or `-`. Dots are reserved to join them (`module.output`).
pub fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    matches!(chars.next(), Some(c) if c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> ModuleDescription {
        let mut description = ModuleDescription::new("counter", "Counts & publishes <numbers>.");
        description.version = "1.2.3".into();
        description.outputs.push(PortSpec {
            name: "count".into(),
            data_type: "Counter".into(),
            doc: "the value".into(),
        });
        description.inputs.push(PortSpec {
            name: "reset".into(),
            data_type: "Counter".into(),
            doc: String::new(),
        });
        description.params.push(
            ParamSpec::new("period_secs", ParamType::Float, "time between values")
                .unit("s")
                .default("0.1"),
        );
        description
            .params
            .push(ParamSpec::new("label", ParamType::String, "a \"name\""));
        description.events.push(EventSpec {
            name: "done".into(),
            doc: "limit reached".into(),
        });
        description.controllable = false;
        description.category = Category::Navigation;
        description
    }

    #[test]
    fn round_trips_through_xml() {
        let description = sample();
        assert_eq!(
            ModuleDescription::from_xml(&description.to_xml()),
            Ok(description)
        );
    }

    #[test]
    fn category_is_optional_and_unknown_ones_are_other() {
        let read = |attr: &str| {
            ModuleDescription::from_xml(&format!("<module type=\"x\"{attr}/>"))
                .map(|description| description.category)
        };
        assert_eq!(read(""), Ok(Category::Other));
        assert_eq!(read(" category=\"mapping\""), Ok(Category::Mapping));
        assert_eq!(read(" category=\"sensor\""), Ok(Category::Sensor));
        assert_eq!(read(" category=\"teleportation\""), Ok(Category::Other));
        // A module without one describes itself as before categories existed.
        let plain = ModuleDescription::new("x", "");
        assert!(!plain.to_xml().contains("category"));
        for category in Category::ALL {
            assert_eq!(Category::from_name(category.as_str()), category);
        }
    }

    fn check_problems(text: &str, expected: &[&str]) {
        let problems = ModuleDescription::from_xml(text).expect_err("should be refused");
        let got: Vec<String> = problems.iter().map(ToString::to_string).collect();
        assert_eq!(got, expected);
    }

    #[test]
    fn ranges_and_choices_round_trip_and_refuse_in_words() {
        let mut description = sample();
        description.params = vec![
            ParamSpec::new("rate_hz", ParamType::Float, "")
                .unit("Hz")
                .default("10")
                .above(0.0)
                .max(1000.0),
            ParamSpec::new("beams", ParamType::Int, "")
                .default("90")
                .min(1.0)
                .below(100_000.0),
            ParamSpec::new("sector", ParamType::Float, "")
                .unit("deg")
                .default("90")
                .min(0.0)
                .max(360.0),
            ParamSpec::new("turn", ParamType::Float, "")
                .default("0.5")
                .nonzero(),
            ParamSpec::new("mode", ParamType::String, "")
                .default("fast")
                .choices(&["fast", "careful"]),
            ParamSpec::new("world", ParamType::String, "").file("worlds"),
        ];
        assert_eq!(
            ModuleDescription::from_xml(&description.to_xml()),
            Ok(description.clone())
        );
        let refusal = |param: usize, value: &str| {
            description.params[param]
                .check_value(value)
                .map_err(|err| err.to_string())
        };
        assert_eq!(refusal(0, "1000"), Ok(()));
        assert_eq!(
            refusal(0, "0"),
            Err("`0` is not greater than 0 Hz and at most 1000 Hz".to_owned())
        );
        assert_eq!(
            refusal(1, "100000"),
            Err("`100000` is not 1 or more and less than 100000".to_owned())
        );
        assert_eq!(
            refusal(2, "-1"),
            Err("`-1` is not between 0° and 360°".to_owned())
        );
        assert_eq!(refusal(3, "0"), Err("`0` is not non-zero".to_owned()));
        assert_eq!(refusal(3, "-0.5"), Ok(()));
        assert_eq!(
            refusal(4, "slow"),
            Err("`slow` is not one of: fast, careful".to_owned())
        );
        assert_eq!(
            refusal(1, "2.5"),
            Err("`2.5` is not a whole number".to_owned())
        );
        check_problems(
            "<module type=\"x\">\n <param name=\"a\" type=\"string\" min=\"1\" nonzero=\"true\"/>\n <param name=\"b\" type=\"int\" min=\"5\" max_exclusive=\"5\" choices=\"x|y\"/>\n <param name=\"c\" type=\"float\" default=\"-1\" min=\"0\" min_exclusive=\"0\" max=\"inf\"/>\n <param name=\"d\" type=\"int\" default=\"1\" file=\"worlds\"/>\n</module>",
            &[
                "2:32: parameter `a`: `min` applies to `int` and `float` parameters, not `string`",
                "2:40: parameter `a`: `nonzero` applies to `int` and `float` parameters, not `string`",
                "3:2: parameter `b`: its range holds no value (5 or more and less than 5)",
                "3:55: parameter `b`: `choices` applies to `string` parameters, not `int`",
                "4:2: parameter `c`: give `min` or `min_exclusive`, not both",
                "4:31: default of parameter `c` (float): `-1` is not 0 or more",
                "4:70: parameter `c`: `max` must be a finite number, not `inf`",
                "5:41: parameter `d`: `file` applies to `string` parameters, not `int`",
            ],
        );
    }

    #[test]
    fn reports_every_problem_with_its_place() {
        check_problems(
            "<module type=\"x\">\n <param name=\"p\" type=\"float\" default=\"fast\"/>\n <output name=\"o\"/>\n <widget/>\n</module>",
            &[
                "2:31: default of parameter `p` (float): `fast` is not a finite number",
                "3:2: <output> needs the attribute `type`",
                "4:2: unknown element <widget> inside <module> (expected one of: doc, input, output, param, event)",
            ],
        );
        check_problems(
            "<module type=\"9lives\" controllable=\"maybe\"/>",
            &[
                "1:9: module type `9lives` must be letters, digits, `_` or `-`",
                "1:23: `controllable` must be `true` or `false`, not `maybe`",
            ],
        );
        check_problems("garbage", &["1:1: text outside the top-level element"]);
    }

    #[test]
    fn parameter_values_are_checked_by_type() {
        assert!(ParamType::Int.check_value("42").is_ok());
        assert_eq!(
            ParamType::Int
                .check_value("4.2")
                .map_err(|err| err.to_string()),
            Err("`4.2` is not a whole number".to_owned())
        );
        assert!(ParamType::Float.check_value("inf").is_err());
        assert!(ParamType::Bool.check_value("yes").is_err());
    }
}
