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
use std::time::Instant;

use crate::clock::Clock;
use crate::module::{ModuleSpec, default_config};
use crate::node::{ApiError, Core, Event, Node, Transport};
use crate::protocol::ToSupervisor;
use crate::types::Datum;
use crate::wire::{DataFrame, Frame, FrameReader};

/// One step of a bench script, played when the module body waits and no event is queued.
#[derive(Clone, Debug)]
pub enum Step {
    /// The body's next `n` waits with a deadline time out (a wait without one skips the step).
    Timeouts(usize),
    /// A configuration reload changes a parameter.
    Param(String, String),
    /// The controller starts (`true`) or stops (`false`) the module.
    Active(bool),
    /// Run time jumps forward by this many seconds (for timeouts measured on the run clock).
    Advance(f64),
    /// An encoded value arrives on an input; see [`Step::push`].
    Push { input: String, payload: Vec<u8> },
    /// The input loses its provider and links again (see [`Sample::link`](crate::Sample::link)).
    Relink(String),
}

impl Step {
    pub fn param(name: &str, value: &str) -> Step {
        Step::Param(name.to_owned(), value.to_owned())
    }

    pub fn push<T: Datum>(input: &str, value: &T) -> Result<Step, ApiError> {
        let mut payload = Vec::new();
        value.encode(&mut payload)?;
        Ok(Step::Push {
            input: input.to_owned(),
            payload,
        })
    }
}

#[derive(Default)]
pub(crate) struct TestTransport {
    sent: Vec<(usize, DataFrame)>,
    pub reports: Vec<ToSupervisor>,
    script: Option<VecDeque<Step>>,
    next_seq: u64,
}

impl TestTransport {
    pub fn publish(&mut self, output: usize, frame: &[u8]) {
        // One read may not take a whole large frame: read until the frame is complete.
        let mut reader = FrameReader::default();
        let mut source = frame;
        loop {
            match reader.next_frame() {
                Ok(Some(Frame::Data(data))) => {
                    self.sent.push((output, data));
                    return;
                }
                Ok(None) if !source.is_empty() => {
                    if reader.fill_from(&mut source).is_err() {
                        return;
                    }
                }
                _ => return,
            }
        }
    }

    fn deliver(&mut self, core: &mut Core, input: &str, payload: Vec<u8>) -> Result<(), ApiError> {
        let index = core
            .inputs
            .iter()
            .position(|slot| slot.name == input)
            .ok_or_else(|| ApiError::UnknownPort {
                module: core.name.clone(),
                kind: "input",
                port: input.to_owned(),
            })?;
        self.next_seq += 1;
        core.inputs[index].link = core.inputs[index].link.max(1);
        let frame = DataFrame {
            seq: self.next_seq,
            stamp_ns: core.clock.now_ns(),
            payload,
        };
        core.deliver(index, frame);
        Ok(())
    }

    /// Called when the body waits and no event is queued.
    pub fn next_event(&mut self, core: &mut Core, deadline: Option<Instant>) -> Event {
        let Some(mut script) = self.script.take() else {
            return if deadline.is_some() {
                Event::Timeout
            } else {
                Event::Shutdown
            };
        };
        let event = loop {
            let Some(step) = script.pop_front() else {
                break Event::Shutdown;
            };
            match step {
                Step::Timeouts(n) if n > 0 && deadline.is_some() => {
                    script.push_front(Step::Timeouts(n - 1));
                    break Event::Timeout;
                }
                Step::Timeouts(_) => {}
                Step::Param(name, value) => {
                    let mut config = core.config.clone();
                    config.params.insert(name, value);
                    core.apply_config(config);
                }
                Step::Active(active) => core.set_active(active),
                Step::Advance(secs) => core.clock.advance(secs),
                Step::Push { input, payload } => {
                    if let Err(err) = self.deliver(core, &input, payload) {
                        tracing::error!("bench script: {err}");
                    }
                }
                Step::Relink(input) => {
                    if let Some(slot) = core.inputs.iter_mut().find(|slot| slot.name == input) {
                        slot.link = slot.link.max(1) + 1;
                    }
                }
            }
            if let Some(event) = core.take_event() {
                break event;
            }
        };
        self.script = Some(script);
        event
    }
}

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
            declared
                .param_type
                .check_value(value)
                .map_err(|reason| ApiError::BadParam {
                    name: (*param).to_owned(),
                    value: (*value).to_owned(),
                    reason,
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
