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
//! When no event is queued, waiting with a deadline returns [`Event::Timeout`] at once and waiting
//! without one returns [`Event::Shutdown`], so a module body run on a bench ends by itself.

use std::time::Instant;

use crate::clock::Clock;
use crate::module::{ModuleSpec, default_config};
use crate::node::{ApiError, Core, Event, Node, Transport};
use crate::protocol::ToSupervisor;
use crate::types::Datum;
use crate::wire::{DataFrame, Frame, FrameReader};

#[derive(Default)]
pub(crate) struct TestTransport {
    sent: Vec<(usize, DataFrame)>,
    pub reports: Vec<ToSupervisor>,
}

impl TestTransport {
    pub fn publish(&mut self, output: usize, frame: &[u8]) {
        let mut reader = FrameReader::default();
        if reader.fill_from(&mut &frame[..]).is_ok()
            && let Ok(Some(Frame::Data(data))) = reader.next_frame()
        {
            self.sent.push((output, data));
        }
    }

    pub fn next_event(&mut self, _core: &mut Core, deadline: Option<Instant>) -> Event {
        if deadline.is_some() {
            Event::Timeout
        } else {
            Event::Shutdown
        }
    }
}

/// A module's node with a test transport, and the controls to feed and observe it.
pub struct TestBench {
    node: Node,
    next_seq: u64,
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
            next_seq: 0,
        })
    }

    pub fn node(&mut self) -> &mut Node {
        &mut self.node
    }

    /// Delivers a value on an input, as its provider would.
    pub fn push<T: Datum>(&mut self, input: &str, value: &T) -> Result<(), ApiError> {
        let port = self.node.input::<T>(input)?;
        let mut payload = Vec::new();
        value.encode(&mut payload)?;
        self.next_seq += 1;
        let frame = DataFrame {
            seq: self.next_seq,
            stamp_ns: self.node.clock().now_ns(),
            payload,
        };
        self.node.core.deliver(port.id().0, frame);
        Ok(())
    }

    /// Changes a parameter as a configuration reload would.
    pub fn set_param(&mut self, name: &str, value: &str) {
        let mut config = self.node.core.config.clone();
        config.params.insert(name.to_owned(), value.to_owned());
        self.node.core.apply_config(config);
    }

    /// Activates or deactivates the module as the controller would.
    pub fn set_active(&mut self, active: bool) {
        self.node.core.set_active(active);
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
