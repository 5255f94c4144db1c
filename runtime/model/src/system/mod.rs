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
//! Modules may be grouped into named subsystems (`<subsystem name="…"><member module="…"/>…`),
//! which nest and expose ports on their border; they change nothing at run time (see
//! [`subsystem`]).
//!
//! A module may be limited to what it publishes and subscribes to: `may_publish` and
//! `may_subscribe` list data names (`module.output`, `module.*` or `*`), separated by spaces or
//! commas. The agent refuses registrations and lookups outside the lists; without a list, a
//! module may publish its own outputs (`its_name.*`) and subscribe to anything. A `may_publish`
//! naming another module's names grants them (a data name has one publisher, which `check`
//! holds to).
//!
//! [`SystemConfig::parse`] reports structural problems (the XML alone), [`check`] reports the
//! problems found against the module descriptions, both with line and column. The schema is
//! `assets/schema/system.xsd`.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use armor_module_api::describe::{ModuleDescription, is_identifier};
use armor_module_api::xml::Pos;

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

/// When a controllable module runs (the `activation` attribute; a module that is not
/// controllable runs whenever its process does).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Activation {
    /// When a place or the operator wants it, and also when a module that runs needs what it
    /// publishes, or when it carries the commands of a wanted module on (see [`demand`]).
    #[default]
    OnDemand,
    /// All the time, mission or not.
    Always,
    /// Only when a place or the operator names it: never pulled in by another's needs (a
    /// source that the mission starts and stops on purpose).
    Explicit,
}

impl Activation {
    pub fn as_str(self) -> &'static str {
        match self {
            Activation::OnDemand => "on-demand",
            Activation::Always => "always",
            Activation::Explicit => "explicit",
        }
    }
}

impl fmt::Display for Activation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Activation {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "on-demand" => Ok(Activation::OnDemand),
            "always" => Ok(Activation::Always),
            "explicit" => Ok(Activation::Explicit),
            other => Err(format!(
                "unknown activation `{other}` (expected on-demand, always or explicit)"
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
    /// When it runs, if it is controllable.
    pub activation: Activation,
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

/// Data flowing from an output of a module to an input of a module.
#[derive(Clone, Debug, PartialEq)]
pub struct Link {
    pub from: Endpoint,
    pub to: Endpoint,
    /// 0 for an input's source; 1, 2, … for its fallbacks, taken in that order while the
    /// sources before them are down (`fallback="1"`).
    pub fallback: u32,
    /// The `<link>` element.
    pub pos: Pos,
    /// The `from` attribute.
    pub from_pos: Pos,
    /// The `to` attribute.
    pub to_pos: Pos,
    /// At most this many samples a second cross the link (`max_rate_hz="10"`): the provider
    /// skips the samples that come sooner, for a link over a slow or lossy network. `None`:
    /// every sample.
    pub max_rate_hz: Option<f64>,
}

/// A computer of the robot (`<host name="robot1" address="10.0.0.2"/>`), where an `armor host`
/// daemon starts the modules placed on it (`<module … host="robot1">`).
#[derive(Clone, Debug, PartialEq)]
pub struct HostDecl {
    pub name: String,
    /// The address its modules bind to, and the daemon's host (its port: `port`).
    pub address: String,
    /// The daemon's port ([`DEFAULT_HOST_PORT`] when absent).
    pub port: u16,
    /// The `<host>` element.
    pub pos: Pos,
}

/// The port `armor host` listens on when neither its command line nor the system says another.
pub const DEFAULT_HOST_PORT: u16 = 7410;

impl HostDecl {
    /// `address:port`, bracketed for IPv6.
    pub fn daemon_addr(&self) -> String {
        if self.address.contains(':') {
            format!("[{}]:{}", self.address, self.port)
        } else {
            format!("{}:{}", self.address, self.port)
        }
    }
}

/// A whole system configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemConfig {
    pub name: String,
    /// The address the agent and the config server listen on; `None` for [`DEFAULT_HOST`].
    pub host: Option<String>,
    /// The other computers of the robot, each with an `armor host` daemon.
    pub hosts: Vec<HostDecl>,
    pub modules: Vec<ModuleInstance>,
    pub links: Vec<Link>,
    /// Named groups of its modules (see [`subsystem`]); empty for a flat system.
    pub subsystems: Vec<Subsystem>,
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

impl SystemConfig {
    /// The module instance called `name` (the first one, if it is defined twice).
    pub fn module(&self, name: &str) -> Option<&ModuleInstance> {
        self.modules.iter().find(|module| module.name == name)
    }

    /// The sources of the input `to`, best first: its source, then its fallbacks by rank.
    pub fn sources(&self, to: &Endpoint) -> Vec<&Link> {
        let mut sources: Vec<&Link> = self.links.iter().filter(|link| link.to == *to).collect();
        sources.sort_by_key(|link| link.fallback);
        sources
    }

    /// The host the agent and config server listen on: the configured one or [`DEFAULT_HOST`].
    pub fn host_or_default(&self) -> &str {
        self.host.as_deref().unwrap_or(DEFAULT_HOST)
    }

    /// The declared host called `name`.
    pub fn host_decl(&self, name: &str) -> Option<&HostDecl> {
        self.hosts.iter().find(|host| host.name == name)
    }

    /// The declared host a module is placed on (its `host` names one), or `None` when it runs
    /// on the supervisor's machine.
    pub fn placement(&self, module: &ModuleInstance) -> Option<&HostDecl> {
        self.host_decl(module.host.as_deref()?)
    }

    /// The address a module binds its data port to: its host's address when it is placed on a
    /// declared host, else its `host` attribute taken as an address, else the system's.
    pub fn bind_address(&self, module: &ModuleInstance) -> String {
        match (self.placement(module), &module.host) {
            (Some(host), _) => host.address.clone(),
            (None, Some(address)) => address.clone(),
            (None, None) => self.host_or_default().to_owned(),
        }
    }

    /// The links' rate limits by the input they feed: `module` → input → Hz.
    pub fn input_rates(&self, module: &str) -> BTreeMap<String, f64> {
        self.links
            .iter()
            .filter(|link| link.to.module == module && link.fallback == 0)
            .filter_map(|link| Some((link.to.port.clone(), link.max_rate_hz?)))
            .collect()
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
            if link.to.module == module && link.fallback == 0 {
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

mod check;
pub mod demand;
pub mod subsystem;
mod xml;

pub use check::check;
pub use demand::{Reason, demand};
pub use subsystem::{ExposedPort, Member, Subsystem};

#[cfg(test)]
mod tests;
