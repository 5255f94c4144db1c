//! A test transport: run a module's logic with no network, no agent and no supervisor.
//!
//! ```
//! use armor_module_api::{testing::TestBench, types::Counter, ModuleSpec, Event};
//!
//! let spec = ModuleSpec::new("doubler", "doubles").input::<Counter>("input", "").output::<Counter>("output", "");
//! let mut bench = TestBench::new(&spec, &[]).unwrap();
//! bench.push("input", &Counter(21)).unwrap();
//! let node = bench.node();
//! let (input, output) = (node.input::<Counter>("input").unwrap(), node.output::<Counter>("output").unwrap());
//! while let Event::Input(_) = node.next_event(None).unwrap() {
//!     let value = node.take(&input).unwrap().unwrap().value;
//!     node.send(&output, &Counter(value.0 * 2)).unwrap();
//! }
//! assert_eq!(bench.sent::<Counter>("output").unwrap(), [Counter(42)]);
//! ```
//!
//! When no event is queued, the bench plays the next step of its script ([`TestBench::script`]):
//! timeouts, a parameter change, a start or stop, a value on an input, a jump of the run clock. Without a script, waiting
//! with a deadline returns [`Event::Timeout`] at once and waiting without one returns
//! [`Event::Shutdown`]; once a script is played out, waiting returns [`Event::Shutdown`]. Either
//! way a module body run on a bench ends by itself.

use std::collections::VecDeque;

use crate::clock::Clock;
use crate::core::{ApiError, Core};
use crate::module::{ModuleSpec, default_config};
use crate::node::{Node, Transport};
use crate::protocol::ToSupervisor;
pub use crate::test_transport::Step;
use crate::test_transport::TestTransport;
use crate::types::Datum;

/// A module's node with a test transport, and the controls to feed and observe it.
pub struct TestBench {
    node: Node,
}

impl TestBench {
    /// A node named after the module type, with parameter defaults overridden by `params`.
    pub fn new(spec: &ModuleSpec, params: &[(&str, &str)]) -> Result<Self, ApiError> {
        let description = spec.description().clone();
        let name = description.module_type.clone();
        let mut config = default_config(&name, &description);
        for (param, value) in params {
            let declared = description
                .param(param)
                .ok_or_else(|| ApiError::UnknownParam((*param).to_owned()))?;
            // Only the type is checked here: a value out of its declared range reaches the
            // module, which refuses it where it reads it (as a reloaded configuration would).
            declared
                .param_type
                .check_value(value)
                .map_err(|reason| ApiError::BadParam {
                    name: (*param).to_owned(),
                    value: (*value).to_owned(),
                    reason: reason.to_string(),
                })?;
            config
                .params
                .insert((*param).to_owned(), (*value).to_owned());
        }
        let core = Core::new(name, description, config, Clock::real_time());
        Ok(Self {
            node: Node::from_parts(core, Transport::Test(TestTransport::default())),
        })
    }

    pub fn node(&mut self) -> &mut Node {
        &mut self.node
    }

    fn transport(&mut self) -> (&mut TestTransport, &mut Core) {
        match &mut self.node.transport {
            Transport::Test(test) => (test, &mut self.node.core),
            Transport::Net(_) => unreachable!("a bench node always has the test transport"),
        }
    }

    /// A value arrives on an input when the body next waits (appended to the script).
    pub fn push<T: Datum>(&mut self, input: &str, value: &T) -> Result<(), ApiError> {
        self.node.input::<T>(input)?;
        let step = Step::push(input, value)?;
        self.script([step]);
        Ok(())
    }

    /// The input loses its provider and links again, at this point of the script.
    pub fn relink(&mut self, input: &str) -> Result<(), ApiError> {
        if !self.node.core.inputs.iter().any(|slot| slot.name == input) {
            return Err(ApiError::UnknownPort {
                module: self.node.core.name.clone(),
                kind: "input",
                port: input.to_owned(),
            });
        }
        self.script([Step::Relink(input.to_owned())]);
        Ok(())
    }

    /// Steps played in order whenever the body waits with no event queued; after the last one,
    /// waiting returns [`Event::Shutdown`]. [`TestBench::push`] and [`TestBench::relink`] append
    /// to the same script.
    pub fn script(&mut self, steps: impl IntoIterator<Item = Step>) {
        let (test, _) = self.transport();
        test.script.get_or_insert_with(VecDeque::new).extend(steps);
    }

    /// Changes a parameter now, as a configuration reload would.
    pub fn set_param(&mut self, name: &str, value: &str) {
        let mut config = self.node.core.config.clone();
        config.params.insert(name.to_owned(), value.to_owned());
        self.node.core.apply_config(config);
    }

    /// Activates or deactivates the module now, as the controller would (before the body
    /// runs: the body starts in that state, its `Start` or `Stop` event still queued).
    pub fn set_active(&mut self, active: bool) {
        self.node.core.set_active(active);
        self.node.core.told_active = active;
    }

    /// Every value sent on an output so far, decoded.
    pub fn sent<T: Datum>(&self, output: &str) -> Result<Vec<T>, ApiError> {
        let port = self.node.output::<T>(output)?;
        let Transport::Test(test) = &self.node.transport else {
            return Ok(Vec::new());
        };
        test.sent
            .iter()
            .filter(|(index, _)| *index == port.index())
            .map(|(_, frame)| Ok(T::decode(&frame.payload)?))
            .collect()
    }

    /// The events the module reported, in order.
    pub fn reported(&self) -> Vec<String> {
        let Transport::Test(test) = &self.node.transport else {
            return Vec::new();
        };
        test.reports
            .iter()
            .filter_map(|report| match report {
                ToSupervisor::Event { name } => Some(name.clone()),
                _ => None,
            })
            .collect()
    }

    /// The no-go areas the module reported ([`Node::report_area`]), in order.
    pub fn areas_reported(&self) -> Vec<(String, Vec<[f64; 2]>)> {
        let Transport::Test(test) = &self.node.transport else {
            return Vec::new();
        };
        test.reports
            .iter()
            .filter_map(|report| match report {
                ToSupervisor::Area { name, points_m } => Some((name.clone(), points_m.clone())),
                _ => None,
            })
            .collect()
    }
}

impl TestBench {
    /// What the module said of its behaviour, in order: each [`Node::set_applicable`] as
    /// `applicable`/`not applicable`, each [`Node::set_winner`] as `winner INPUT`/`winner none`.
    pub fn behaviour(&self) -> Vec<String> {
        let Transport::Test(test) = &self.node.transport else {
            return Vec::new();
        };
        test.reports
            .iter()
            .filter_map(|report| match report {
                ToSupervisor::Applicable { applicable: true } => Some("applicable".to_owned()),
                ToSupervisor::Applicable { applicable: false } => Some("not applicable".to_owned()),
                ToSupervisor::Winner { input } => {
                    Some(format!("winner {}", input.as_deref().unwrap_or("none")))
                }
                _ => None,
            })
            .collect()
    }
}

impl TestBench {
    /// The module as if restarted after an earlier process kept `state` ([`Node::kept`]).
    pub fn with_kept(mut self, state: &str) -> Self {
        self.node.core.kept = Some(state.to_owned());
        self
    }

    /// The states the module asked to keep ([`Node::keep`]), in order.
    pub fn kept_states(&self) -> Vec<String> {
        let Transport::Test(test) = &self.node.transport else {
            return Vec::new();
        };
        test.reports
            .iter()
            .filter_map(|report| match report {
                ToSupervisor::Keep { state } => Some(state.clone()),
                _ => None,
            })
            .collect()
    }

    /// The endpoints the module said it listens at ([`Node::set_endpoint`]), in order, each as
    /// `NAME ADDRESS`.
    pub fn endpoints(&self) -> Vec<String> {
        let Transport::Test(test) = &self.node.transport else {
            return Vec::new();
        };
        test.reports
            .iter()
            .filter_map(|report| match report {
                ToSupervisor::Endpoint { name, address } => Some(format!("{name} {address}")),
                _ => None,
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Blob;

    #[test]
    fn large_values_are_recorded_whole() {
        let spec = ModuleSpec::new("big", "sends a large blob").output::<Blob>("out", "");
        let mut bench = TestBench::new(&spec, &[]).expect("bench");
        let node = bench.node();
        let out = node.output::<Blob>("out").expect("output");
        let blob = Blob(vec![7; 3 * 1024 * 1024]);
        node.send(&out, &blob).expect("send");
        assert_eq!(bench.sent::<Blob>("out").expect("sent"), [blob]);
    }
}
