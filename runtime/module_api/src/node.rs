//! The module author's handle on the system: typed ports, parameters, events and the event loop.
//!
//! ```no_run
//! use armor_module_api::{Event, ModuleSpec, types::Counter};
//!
//! let spec = ModuleSpec::new("doubler", "Publishes twice each value it receives.")
//!     .input::<Counter>("input", "values to double")
//!     .output::<Counter>("output", "doubled values");
//! armor_module_api::run(spec, |node| {
//!     let input = node.input::<Counter>("input")?;
//!     let output = node.output::<Counter>("output")?;
//!     loop {
//!         match node.next_event(None)? {
//!             Event::Input(port) if port == input.id() => {
//!                 if let Some(sample) = node.take(&input)? {
//!                     node.send(&output, &Counter(sample.value.0 * 2))?;
//!                 }
//!             }
//!             Event::Shutdown => return Ok(()),
//!             _ => {}
//!         }
//!     }
//! });
//! ```

use std::collections::BTreeMap;
use std::marker::PhantomData;
use std::str::FromStr;
use std::time::{Duration, Instant};

use crate::clock::Clock;
pub use crate::core::{ApiError, Event, PortId};
use crate::core::{Core, InputSlot, OutputSlot, check_param};
use crate::describe::ModuleDescription;
use crate::net::Net;
use crate::protocol::ToSupervisor;
use crate::types::Datum;
use crate::wire::{self, DataFrame, WireError};

/// A received value with its provider's sequence number and run-clock stamp.
#[derive(Clone, Debug, PartialEq)]
pub struct Sample<T> {
    pub seq: u64,
    pub stamp_ns: u64,
    /// Which link of the input brought it: 1 for the first connection to a provider, then one
    /// more each time the input is relinked (the provider restarted, or the link was lost).
    /// Sequence numbers are in order within one link.
    pub link: u64,
    pub value: T,
}

/// A typed handle on an output, from [`Node::output`].
#[derive(Debug)]
pub struct Output<T> {
    index: usize,
    _type: PhantomData<fn(T)>,
}

/// A typed handle on an input, from [`Node::input`] or [`Node::reliable_input`].
#[derive(Debug)]
pub struct Input<T> {
    index: usize,
    _type: PhantomData<fn() -> T>,
}

impl<T> Input<T> {
    pub fn id(&self) -> PortId {
        PortId(self.index)
    }
}

impl<T> Output<T> {
    pub(crate) fn index(&self) -> usize {
        self.index
    }
}

/// An input added at run time by [`Node::subscribe_raw`]: bound to a data name, of whatever type
/// its provider serves, read as bytes with [`Node::take_raw`].
#[derive(Debug)]
pub struct RawInput {
    index: usize,
}

impl RawInput {
    /// Compare with the port of an [`Event::Input`].
    pub fn id(&self) -> PortId {
        PortId(self.index)
    }
}

/// An output added at run time by [`Node::publish_raw`], written as bytes with
/// [`Node::send_raw`].
#[derive(Debug)]
pub struct RawOutput {
    index: usize,
}

/// A received sample of a [`RawInput`]: the datum's bytes as they travelled, undecoded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RawSample {
    pub seq: u64,
    pub stamp_ns: u64,
    /// As in [`Sample::link`].
    pub link: u64,
    /// The provider's data type, as the agent announced it (empty on a test bench, which has no
    /// agent).
    pub data_type: String,
    /// The encoded datum (see `docs/protocol.md`, section 3).
    pub payload: Vec<u8>,
}

/// A data name is `module.output`: refused if empty or holding whitespace or control characters.
fn check_data_name(data_name: &str) -> Result<(), ApiError> {
    if data_name.is_empty()
        || data_name
            .chars()
            .any(|c| c.is_whitespace() || c.is_control())
    {
        return Err(ApiError::BadDataName(data_name.to_owned()));
    }
    Ok(())
}

pub(crate) enum Transport {
    Net(Box<Net>),
    /// No network: see [`crate::testing`].
    Test(crate::test_transport::TestTransport),
}

/// A running module's connection to the system.
pub struct Node {
    pub(crate) core: Core,
    pub(crate) transport: Transport,
    scratch: Vec<u8>,
    /// The encoding before a large payload's own bytes (see [`Datum::split_encoding`]).
    large_head: Vec<u8>,
}

impl Node {
    pub(crate) fn from_parts(core: Core, transport: Transport) -> Self {
        Self {
            core,
            transport,
            scratch: Vec::new(),
            large_head: Vec::new(),
        }
    }

    /// How a service port of this module's own (the teleop's command port) admits clients
    /// when the run has a secret: Noise with this module's key, as its data port does
    /// ([`crate::auth::Admit::LinksTo`]: a client proves the link key for the name it
    /// claims), always encrypted. `None` without a secret.
    pub fn service_listen(&self) -> Option<crate::auth::Listen> {
        match &self.transport {
            Transport::Net(net) => net.service_listen(),
            Transport::Test(_) => None,
        }
    }

    /// This module's instance name in the system.
    pub fn name(&self) -> &str {
        &self.core.name
    }

    pub fn description(&self) -> &ModuleDescription {
        &self.core.description
    }

    pub fn clock(&self) -> &Clock {
        &self.core.clock
    }

    /// Run time in seconds, common to every module of the run.
    pub fn timestamp(&self) -> f64 {
        self.core.clock.now_secs()
    }

    /// Whether the module is active, as far as the events it has taken go: a `Start` or `Stop`
    /// still queued has not changed it yet. Non-controllable modules always are.
    pub fn is_active(&self) -> bool {
        self.core.told_active || !self.core.description.controllable
    }

    /// The unique data name of an output (`module.output`).
    pub fn data_name<T>(&self, output: &Output<T>) -> &str {
        &self.core.outputs[output.index].data_name
    }

    /// A typed handle on a declared output.
    pub fn output<T: Datum>(&self, name: &str) -> Result<Output<T>, ApiError> {
        let index = self.port_index("output", name, T::TYPE, |core| {
            core.outputs
                .iter()
                .map(|slot| (&slot.name, &slot.data_type))
                .collect()
        })?;
        Ok(Output {
            index,
            _type: PhantomData,
        })
    }

    /// A typed handle on a declared input that keeps only the newest sample: a slow module never
    /// falls behind and never queues without bound.
    pub fn input<T: Datum>(&mut self, name: &str) -> Result<Input<T>, ApiError> {
        let index = self.port_index("input", name, T::TYPE, |core| {
            // Raw inputs come after the declared ones, so indices agree.
            core.inputs
                .iter()
                .filter(|slot| !slot.raw)
                .map(|slot| (&slot.name, &slot.data_type))
                .collect()
        })?;
        Ok(Input {
            index,
            _type: PhantomData,
        })
    }

    /// Like [`Node::input`], but every sample is kept in order (up to a bounded queue, beyond
    /// which the provider is made to wait). For recorders and checkers.
    pub fn reliable_input<T: Datum>(&mut self, name: &str) -> Result<Input<T>, ApiError> {
        let input = self.input::<T>(name)?;
        let slot = &mut self.core.inputs[input.index];
        if !slot.reliable {
            slot.reliable = true;
            // A sample that arrived before the switch is kept, first in the queue.
            if let Some(sample) = slot.latest.take() {
                slot.queued_bytes += sample.1.payload.len();
                slot.queue.push_back(sample);
            }
            if let Transport::Net(net) = &mut self.transport {
                net.relink(&mut self.core, input.index);
            }
        }
        Ok(input)
    }

    /// Like [`Node::input`], in pull mode: the provider sends nothing of its own accord and
    /// answers each [`Node::pull`] with its latest sample (a request for the latest value, as
    /// zenoh's `get` on a publisher's cache). The answer comes like any sample:
    /// [`Event::Input`], then [`Node::take`]; or use [`Node::pull_latest`].
    pub fn pull_input<T: Datum>(&mut self, name: &str) -> Result<Input<T>, ApiError> {
        let input = self.input::<T>(name)?;
        let slot = &mut self.core.inputs[input.index];
        if !slot.pull {
            slot.pull = true;
            if let Transport::Net(net) = &mut self.transport {
                net.relink(&mut self.core, input.index);
            }
        }
        Ok(input)
    }

    /// Asks the input's provider for its latest sample, or the next one if it has sent none
    /// yet; the provider's node answers without waking its module, and the answer comes as
    /// [`Event::Input`]. `false` when the input has no provider linked yet: nothing was asked.
    pub fn pull<T>(&mut self, input: &Input<T>) -> Result<bool, ApiError> {
        match &mut self.transport {
            Transport::Net(net) => Ok(net.pull(input.index)),
            Transport::Test(_) => Ok(false),
        }
    }

    /// [`Node::pull`], then waits for the answer until `timeout`: the sample, or `None` when
    /// the input is not linked or no answer came in time. Events that come meanwhile are kept,
    /// in order, for the next [`Node::next_event`].
    pub fn pull_latest<T: Datum>(
        &mut self,
        input: &Input<T>,
        timeout: Duration,
    ) -> Result<Option<Sample<T>>, ApiError> {
        if !self.pull(input)? {
            return Ok(None);
        }
        let deadline = Instant::now() + timeout;
        let mut kept = Vec::new();
        let answer = loop {
            match self.next_queued_event(Some(deadline)) {
                Ok(Event::Input(port)) if port == input.id() => {
                    if let Some(sample) = self.take(input)? {
                        break Ok(Some(sample));
                    }
                }
                Ok(Event::Timeout) => break Ok(None),
                Ok(other) => kept.push(other),
                Err(err) => break Err(err),
            }
        };
        for event in kept.into_iter().rev() {
            if let Event::Input(PortId(index)) = event {
                self.core.inputs[index].notified = true;
            }
            self.core.events.push_front(event);
        }
        answer
    }

    fn port_index(
        &self,
        kind: &'static str,
        name: &str,
        requested: &'static str,
        ports: impl Fn(&Core) -> Vec<(&String, &String)>,
    ) -> Result<usize, ApiError> {
        let ports = ports(&self.core);
        let (index, (_, declared)) = ports
            .iter()
            .enumerate()
            .find(|(_, (port, _))| *port == name)
            .ok_or_else(|| ApiError::UnknownPort {
                module: self.core.name.clone(),
                kind,
                port: name.to_owned(),
            })?;
        if declared.as_str() != requested {
            return Err(ApiError::WrongType {
                kind,
                port: name.to_owned(),
                declared: (*declared).clone(),
                requested,
            });
        }
        Ok(index)
    }

    /// Publishes a value to every subscriber of the output. Values are written when the module
    /// next waits for an event (or calls [`Node::flush`]), so a burst of sends shares system calls
    /// without delaying anything the module waits on.
    pub fn send<T: Datum>(&mut self, output: &Output<T>, value: &T) -> Result<(), ApiError> {
        if matches!(self.transport, Transport::Net(_)) {
            let mut head = std::mem::take(&mut self.large_head);
            head.clear();
            let sent = match value.split_encoding(&mut head) {
                Some(bytes) if bytes.len() >= wire::LARGE_PAYLOAD_BYTES => {
                    Some(self.send_large(output.index, &head, bytes))
                }
                _ => None,
            };
            self.large_head = head;
            if let Some(sent) = sent {
                return sent;
            }
        }
        self.send_frame(output.index, |out| {
            value
                .encode(out)
                .map_err(|err| WireError::Io(std::io::Error::other(err)))
        })
    }

    /// Publishes an encoded datum on a raw output, as [`Node::send`] does a value.
    pub fn send_raw(&mut self, output: &RawOutput, payload: &[u8]) -> Result<(), ApiError> {
        self.send_frame(output.index, |out| {
            out.extend_from_slice(payload);
            Ok(())
        })
    }

    /// A large payload sent from the caller's bytes: the frame's header and the datum's `head`
    /// are encoded alone, and the payload is written after them, not copied behind them.
    fn send_large(&mut self, index: usize, head: &[u8], payload: &[u8]) -> Result<(), ApiError> {
        let slot = &mut self.core.outputs[index];
        slot.seq += 1;
        let seq = slot.seq;
        let stamp_ns = self.core.clock.now_ns();
        self.scratch.clear();
        wire::encode_data_header(&mut self.scratch, seq, stamp_ns, head.len() + payload.len())?;
        self.scratch.extend_from_slice(head);
        if let Transport::Net(net) = &mut self.transport {
            let parts = [self.scratch.as_slice(), payload];
            net.publish(&mut self.core, index, &parts)?;
            net.keep_latest_parts(index, &parts);
        }
        Ok(())
    }

    fn send_frame(
        &mut self,
        index: usize,
        encode: impl FnOnce(&mut Vec<u8>) -> Result<(), WireError>,
    ) -> Result<(), ApiError> {
        let slot = &mut self.core.outputs[index];
        slot.seq += 1;
        let seq = slot.seq;
        let stamp_ns = self.core.clock.now_ns();
        self.scratch.clear();
        wire::encode_data(&mut self.scratch, seq, stamp_ns, encode)?;
        match &mut self.transport {
            Transport::Net(net) => {
                net.publish(&mut self.core, index, &[self.scratch.as_slice()])?;
                // Kept for pulls: a swap, not a copy.
                net.keep_latest(index, &mut self.scratch);
            }
            Transport::Test(test) => test.publish(index, &self.scratch),
        }
        Ok(())
    }

    /// How many subscribers an output has right now. Values sent while it has none are lost,
    /// as in any publish/subscribe system: a module that must not lose its first values waits
    /// for a subscriber first.
    pub fn subscriber_count<T>(&self, output: &Output<T>) -> usize {
        self.subscribers_of(output.index)
    }

    /// How many subscribers a raw output has right now (see [`Node::subscriber_count`]).
    pub fn raw_subscriber_count(&self, output: &RawOutput) -> usize {
        self.subscribers_of(output.index)
    }

    fn subscribers_of(&self, index: usize) -> usize {
        match &self.transport {
            Transport::Net(net) => net.subscriber_count(index),
            Transport::Test(_) => 1,
        }
    }

    /// How many data connections this node has with other modules. Each carries at most one
    /// subscription each way: two modules that subscribe to each other share one.
    pub fn data_connections(&self) -> usize {
        match &self.transport {
            Transport::Net(net) => net.data_connections(),
            Transport::Test(_) => 0,
        }
    }

    /// Writes everything sent so far without waiting for an event.
    pub fn flush(&mut self) -> Result<(), ApiError> {
        if let Transport::Net(net) = &mut self.transport {
            net.flush_all(&mut self.core);
        }
        Ok(())
    }

    /// The newest sample of a best-effort input, or the oldest queued one of a reliable input.
    pub fn take<T: Datum>(&mut self, input: &Input<T>) -> Result<Option<Sample<T>>, ApiError> {
        let Some((link, frame)) = self.pop_frame(input.index) else {
            return Ok(None);
        };
        let value = T::decode_owned(frame.payload)?;
        Ok(Some(Sample {
            seq: frame.seq,
            stamp_ns: frame.stamp_ns,
            link,
            value,
        }))
    }

    /// The next sample of a raw input (the newest, or the oldest queued if it is reliable), as
    /// bytes with the data type its provider announced.
    pub fn take_raw(&mut self, input: &RawInput) -> Option<RawSample> {
        let (link, frame) = self.pop_frame(input.index)?;
        Some(RawSample {
            seq: frame.seq,
            stamp_ns: frame.stamp_ns,
            link,
            data_type: self.core.inputs[input.index].data_type.clone(),
            payload: frame.payload,
        })
    }

    /// Whether a raw input is linked to its provider right now.
    pub fn is_raw_linked(&self, input: &RawInput) -> bool {
        match &self.transport {
            Transport::Net(net) => net.is_linked(input.index),
            Transport::Test(_) => true,
        }
    }

    /// Adds an input at run time, bound to the output `data_name` (`module.output`) whatever
    /// its type: the agent's answer names the type, which [`RawSample::data_type`] then tells.
    /// `reliable` as for [`Node::reliable_input`]. Samples arrive as [`Event::Input`] with
    /// [`RawInput::id`]; read them with [`Node::take_raw`]. Each call adds one more input (and
    /// subscription), even for a data name already subscribed.
    pub fn subscribe_raw(&mut self, data_name: &str, reliable: bool) -> Result<RawInput, ApiError> {
        self.subscribe_raw_with(data_name, reliable, None)
    }

    /// As [`Node::subscribe_raw`] best-effort, asking the provider for at most `max_rate_hz`
    /// samples per second (it skips those that come sooner): for displays and monitors, which
    /// need far fewer samples than a fast provider publishes.
    pub fn subscribe_raw_at_most(
        &mut self,
        data_name: &str,
        max_rate_hz: f64,
    ) -> Result<RawInput, ApiError> {
        self.subscribe_raw_with(data_name, false, Some(max_rate_hz))
    }

    fn subscribe_raw_with(
        &mut self,
        data_name: &str,
        reliable: bool,
        max_rate_hz: Option<f64>,
    ) -> Result<RawInput, ApiError> {
        check_data_name(data_name)?;
        let index = self.core.inputs.len();
        self.core.inputs.push(InputSlot {
            raw: true,
            reliable,
            ..InputSlot::new(
                data_name.to_owned(),
                String::new(),
                Some(data_name.to_owned()),
                max_rate_hz,
            )
        });
        if let Transport::Net(net) = &mut self.transport {
            net.add_input(&self.core, index);
        }
        Ok(RawInput { index })
    }

    /// Adds an output at run time, served under exactly `data_name` and carrying `data_type`,
    /// and registers it with the agent so that subscribers find it. Publishing a data name this
    /// node already serves with the same type returns that output again; with another type it
    /// is refused. The output is also reachable by [`Node::output`] under its data name.
    pub fn publish_raw(&mut self, data_name: &str, data_type: &str) -> Result<RawOutput, ApiError> {
        check_data_name(data_name)?;
        if data_type.is_empty() || data_type.chars().any(char::is_whitespace) {
            return Err(ApiError::BadDataType(data_type.to_owned()));
        }
        if let Some(index) = self
            .core
            .outputs
            .iter()
            .position(|slot| slot.data_name == data_name)
        {
            let declared = &self.core.outputs[index].data_type;
            if declared != data_type {
                return Err(ApiError::DataNameTaken {
                    data_name: data_name.to_owned(),
                    declared: declared.clone(),
                    requested: data_type.to_owned(),
                });
            }
            return Ok(RawOutput { index });
        }
        let index = self.core.outputs.len();
        self.core.outputs.push(OutputSlot {
            name: data_name.to_owned(),
            data_type: data_type.to_owned(),
            data_name: data_name.to_owned(),
            seq: 0,
        });
        if let Transport::Net(net) = &mut self.transport {
            net.add_output(&self.core);
        }
        Ok(RawOutput { index })
    }

    /// Takes the next sample of an input: the newest of a best-effort one, the oldest queued of
    /// a reliable one.
    fn pop_frame(&mut self, index: usize) -> Option<(u64, DataFrame)> {
        let slot = &mut self.core.inputs[index];
        let frame = if slot.reliable {
            let frame = slot.queue.pop_front();
            if let Some((_, frame)) = &frame {
                slot.queued_bytes -= frame.payload.len();
            }
            frame
        } else {
            slot.latest.take()
        };
        if frame.is_some() && !slot.queue.is_empty() && !slot.notified {
            slot.notified = true;
            self.core.events.push_back(Event::Input(PortId(index)));
        }
        frame
    }

    /// Whether an input is linked to its provider right now.
    pub fn is_linked<T>(&self, input: &Input<T>) -> bool {
        match &self.transport {
            Transport::Net(net) => net.is_linked(input.index),
            Transport::Test(_) => true,
        }
    }

    /// A parameter's current value, parsed (`f64`, `i64`, `bool`, `String`, ...).
    pub fn param<T: FromStr>(&self, name: &str) -> Result<T, ApiError>
    where
        T::Err: std::fmt::Display,
    {
        let spec = self.core.description.param(name);
        let value = self
            .core
            .config
            .params
            .get(name)
            .or_else(|| spec?.default.as_ref())
            .ok_or_else(|| ApiError::UnknownParam(name.to_owned()))?;
        if let Some(spec) = spec {
            check_param(spec, value)?;
        }
        value
            .trim()
            .parse()
            .map_err(|err: T::Err| ApiError::BadParam {
                name: name.to_owned(),
                value: value.clone(),
                reason: err.to_string(),
            })
    }

    /// All parameter values as configured (defaults included).
    pub fn params(&self) -> &BTreeMap<String, String> {
        &self.core.config.params
    }

    /// Reports an event (for example `goal_reached`) to the mission controller.
    pub fn report(&mut self, event: &str) -> Result<(), ApiError> {
        if self.core.description.event(event).is_none() {
            return Err(ApiError::UnknownEvent(event.to_owned()));
        }
        tracing::info!(event, "reporting event");
        self.tell_supervisor(ToSupervisor::Event {
            name: event.to_owned(),
        });
        Ok(())
    }

    /// Reports a no-go area the module learnt of (another unit reports a minefield), its
    /// corners in the world frame, in metres: a run that plays a plan adds it to the plan as an
    /// update (`docs/plans.md`, "Areas reported from outside").
    pub fn report_area(&mut self, name: &str, points_m: &[[f64; 2]]) {
        tracing::info!(area = name, "reporting a no-go area");
        self.tell_supervisor(ToSupervisor::Area {
            name: name.to_owned(),
            points_m: points_m.to_vec(),
        });
    }

    /// Says whether this behaviour's preconditions hold now (JDE's schemas: a behaviour that is
    /// active but not applicable is `checking`; an applicable one is `ready`, or `winner` when an
    /// arbiter gives it control). Sent to the supervisor only when it changes, so it may be
    /// called at every cycle. A behaviour proposes commands only while applicable: an arbiter
    /// counts a candidate whose proposals are fresh.
    pub fn set_applicable(&mut self, applicable: bool) {
        if self.core.applicable == Some(applicable) {
            return;
        }
        self.core.applicable = Some(applicable);
        self.tell_supervisor(ToSupervisor::Applicable { applicable });
    }

    /// An arbiter says which of its inputs is in control now (`None`: none), when it changes.
    pub fn set_winner(&mut self, input: Option<&str>) {
        if self.core.winner.as_deref() == input {
            return;
        }
        self.core.winner = input.map(str::to_owned);
        self.tell_supervisor(ToSupervisor::Winner {
            input: input.map(str::to_owned),
        });
    }

    /// Says where a service of the module's own, outside the data links, listens (the teleop's
    /// command port, `name` `teleop`): the supervisor shows it in the run's status and relays
    /// the operator's commands there (`armor ctl teleop`). Sent only when it changes. An
    /// address on `0.0.0.0` or `::` is taken by the supervisor as the module's own host.
    pub fn set_endpoint(&mut self, name: &str, address: &str) {
        if self.core.endpoints.get(name).map(String::as_str) == Some(address) {
            return;
        }
        self.core
            .endpoints
            .insert(name.to_owned(), address.to_owned());
        self.tell_supervisor(ToSupervisor::Endpoint {
            name: name.to_owned(),
            address: address.to_owned(),
        });
    }

    /// Asks the run to keep `state` for this module's next process, should this one die and be
    /// restarted ([`Node::kept`]). Each call replaces what was kept; a state longer than
    /// [`crate::protocol::MAX_KEPT_BYTES`] is not kept (an error in the log says so).
    pub fn keep(&mut self, state: &str) {
        if state.len() > crate::protocol::MAX_KEPT_BYTES {
            tracing::error!(
                bytes = state.len(),
                "state to keep is longer than {} bytes: not kept",
                crate::protocol::MAX_KEPT_BYTES
            );
            return;
        }
        self.tell_supervisor(ToSupervisor::Keep {
            state: state.to_owned(),
        });
    }

    /// What an earlier process of this module kept ([`Node::keep`]) in this run: `Some` only
    /// in a module restarted after it kept something.
    pub fn kept(&self) -> Option<&str> {
        self.core.kept.as_deref()
    }

    fn tell_supervisor(&mut self, message: ToSupervisor) {
        match &mut self.transport {
            Transport::Net(net) => net.tell_supervisor(&message),
            Transport::Test(test) => test.reports.push(message),
        }
    }

    /// Waits for the next event, at most `timeout` (forever with `None`).
    pub fn next_event(&mut self, timeout: Option<Duration>) -> Result<Event, ApiError> {
        let deadline = timeout.map(|timeout| Instant::now() + timeout);
        self.wait_event(deadline)
    }

    /// Waits for the next event until a real-time deadline ([`Clock::instant_at`] converts run
    /// time), returning [`Event::Timeout`] when it passes.
    pub fn next_event_until(&mut self, deadline: Instant) -> Result<Event, ApiError> {
        self.wait_event(Some(deadline))
    }

    fn wait_event(&mut self, deadline: Option<Instant>) -> Result<Event, ApiError> {
        if let Some(took) = self.core.took_event_at.take() {
            self.core.busy += took.elapsed();
        }
        let event = self.next_queued_event(deadline);
        self.core.cycles += 1;
        self.core.took_event_at = Some(Instant::now());
        event
    }

    fn next_queued_event(&mut self, deadline: Option<Instant>) -> Result<Event, ApiError> {
        loop {
            if let Some(event) = self.core.take_event() {
                return Ok(event);
            }
            match &mut self.transport {
                Transport::Net(net) => {
                    if deadline.is_some_and(|deadline| Instant::now() >= deadline) {
                        // Behind schedule: look at the sockets all the same, without waiting,
                        // so that a module that is always late still reads its inputs and its
                        // supervisor's messages (pings, stops, new parameters).
                        net.poll_once(&mut self.core, Some(Instant::now()))?;
                        if let Some(event) = self.core.take_event() {
                            return Ok(event);
                        }
                        net.flush_all(&mut self.core);
                        return Ok(Event::Timeout);
                    }
                    net.poll_once(&mut self.core, deadline)?;
                }
                Transport::Test(test) => return Ok(test.next_event(&mut self.core, deadline)),
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;
    use std::net::{TcpListener, TcpStream};
    use std::sync::{Arc, Mutex};

    use super::*;
    use crate::module::{ModuleSpec, Standalone};
    use crate::protocol::{Advert, FromAgent, ToAgent};
    use crate::testing::{Step, TestBench};
    use crate::types::{Counter, Text};
    use crate::wire::blocking;

    fn bench() -> TestBench {
        let spec = ModuleSpec::new("tool", "a tool").input::<Counter>("input", "");
        TestBench::new(&spec, &[]).expect("bench")
    }

    #[test]
    fn a_raw_input_gets_every_sample_as_bytes_and_keeps_its_binding_on_reload() {
        let mut bench = bench();
        let node = bench.node();
        let raw = node.subscribe_raw("counter.count", true).expect("raw");
        assert_ne!(
            raw.id(),
            node.input::<Counter>("input").expect("typed").id()
        );
        assert!(
            node.input::<Counter>("counter.count").is_err(),
            "raw inputs are not declared ports"
        );
        bench.set_param("unused", "1");
        bench.script([
            Step::push("counter.count", &Counter(7)).expect("step"),
            Step::push("counter.count", &Counter(300)).expect("step"),
        ]);
        let node = bench.node();
        let mut samples = Vec::new();
        loop {
            match node.next_event(None).expect("event") {
                Event::Input(port) => {
                    assert_eq!(port, raw.id());
                    while let Some(sample) = node.take_raw(&raw) {
                        samples.push(sample);
                    }
                }
                Event::Shutdown => break,
                _ => {}
            }
        }
        let payloads: Vec<Vec<u8>> = samples.iter().map(|s| s.payload.clone()).collect();
        assert_eq!(payloads, [vec![7], vec![0xAC, 0x02]]);
        assert!(samples[0].seq < samples[1].seq);
        assert_eq!(samples[0].link, 1);
        assert_eq!(
            samples[0].data_type, "",
            "a bench has no agent to name the type"
        );
        let slot = &bench.node().core.inputs[raw.index];
        assert_eq!(slot.source.as_deref(), Some("counter.count"));
    }

    #[test]
    fn raw_ports_refuse_bad_names_and_type_clashes() {
        let mut bench = bench();
        let node = bench.node();
        for bad in ["", "a b", "x\n"] {
            assert!(matches!(
                node.subscribe_raw(bad, false),
                Err(ApiError::BadDataName(_))
            ));
            assert!(matches!(
                node.publish_raw(bad, "Counter"),
                Err(ApiError::BadDataName(_))
            ));
        }
        assert!(matches!(
            node.publish_raw("replay.x", ""),
            Err(ApiError::BadDataType(_))
        ));
        let first = node.publish_raw("sim.odometry", "Odometry").expect("first");
        let again = node.publish_raw("sim.odometry", "Odometry").expect("same");
        assert_eq!(first.index, again.index);
        let err = node
            .publish_raw("sim.odometry", "Pose2D")
            .expect_err("clash");
        assert!(
            err.to_string().contains("already published as Odometry"),
            "{err}"
        );
    }

    #[test]
    fn a_raw_output_sends_bytes_under_its_exact_data_name() {
        let mut bench = bench();
        let node = bench.node();
        let output = node.publish_raw("counter.count", "Counter").expect("raw");
        let text = node.publish_raw("other.text", "Text").expect("raw");
        node.send_raw(&output, &[5]).expect("send");
        node.send_raw(&output, &[0xAC, 0x02]).expect("send");
        let mut payload = Vec::new();
        Text("hi".into()).encode(&mut payload).expect("encode");
        node.send_raw(&text, &payload).expect("send");
        assert_eq!(node.raw_subscriber_count(&output), 1);
        let typed = node
            .output::<Counter>("counter.count")
            .expect("by data name");
        assert_eq!(node.data_name(&typed), "counter.count");
        assert_eq!(
            bench.sent::<Counter>("counter.count").expect("sent"),
            [Counter(5), Counter(300)]
        );
        assert_eq!(
            bench.sent::<Text>("other.text").expect("sent"),
            [Text("hi".into())]
        );
    }

    /// A minimal agent: registrations replace the connection's previous ones; lookups answer.
    fn fake_agent() -> String {
        let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
        let addr = listener.local_addr().expect("addr").to_string();
        let registry: Arc<Mutex<HashMap<String, (usize, Advert)>>> = Arc::default();
        std::thread::spawn(move || {
            for (conn, stream) in listener.incoming().enumerate() {
                let Ok(mut stream) = stream else { return };
                let registry = Arc::clone(&registry);
                std::thread::spawn(move || {
                    blocking::read_hello(&mut stream)?;
                    blocking::write_hello(&mut stream)?;
                    loop {
                        let reply = match blocking::read_message::<ToAgent>(&mut stream)? {
                            ToAgent::Register { outputs, .. } => {
                                let mut registry = registry.lock().expect("lock");
                                registry.retain(|_, (owner, _)| *owner != conn);
                                for advert in outputs {
                                    registry.insert(advert.data_name.clone(), (conn, advert));
                                }
                                FromAgent::Registered
                            }
                            ToAgent::Lookup { data_name } => {
                                match registry.lock().expect("lock").get(&data_name) {
                                    Some((_, advert)) => FromAgent::Provider(advert.clone()),
                                    None => FromAgent::Unknown { data_name },
                                }
                            }
                        };
                        blocking::write_message(&mut stream, &reply)?;
                    }
                    #[allow(unreachable_code)]
                    Ok::<(), WireError>(())
                });
            }
        });
        addr
    }

    fn connect(name: &str, agent: &str) -> Node {
        let options = Standalone {
            name: Some(name.to_owned()),
            agent: Some(agent.to_owned()),
            ..Standalone::default()
        };
        Node::connect(ModuleSpec::new(name, "test node"), options).expect("connect")
    }

    /// Frames larger than any send buffer are written from the sender's buffer as the socket
    /// drains, with small ones between them, and read one large frame at a time: all arrive
    /// whole and in order.
    #[test]
    fn frames_larger_than_the_socket_arrive_whole_and_in_order_among_small_ones() {
        let agent = fake_agent();
        TcpStream::connect(&agent).expect("agent up");
        let sizes = [20 * 1024 * 1024 + 3, 17, 300 * 1024, 12 * 1024 * 1024, 1];
        let payloads: Vec<Vec<u8>> = sizes
            .iter()
            .enumerate()
            .map(|(n, &size)| (0..size).map(|i| ((i * 7 + n) % 251) as u8).collect())
            .collect();
        let mut recorder = connect("recorder", &agent);
        let input = recorder.subscribe_raw("replay.big", true).expect("raw");
        let (done, finished) = std::sync::mpsc::channel::<()>();
        let provider = {
            let agent = agent.clone();
            let payloads = payloads.clone();
            std::thread::spawn(move || {
                let mut provider = connect("replay", &agent);
                let output = provider.publish_raw("replay.big", "Blob").expect("raw");
                let deadline = Instant::now() + Duration::from_secs(10);
                while provider.raw_subscriber_count(&output) == 0 {
                    assert!(Instant::now() < deadline, "no subscriber in time");
                    provider
                        .next_event(Some(Duration::from_millis(5)))
                        .expect("poll");
                }
                for payload in &payloads {
                    provider.send_raw(&output, payload).expect("send");
                }
                // Served until the recorder has it all (the small frames may still be queued).
                while finished.try_recv().is_err() {
                    provider
                        .next_event(Some(Duration::from_millis(5)))
                        .expect("poll");
                }
            })
        };
        let deadline = Instant::now() + Duration::from_secs(30);
        let mut got = Vec::new();
        while got.len() < payloads.len() {
            assert!(Instant::now() < deadline, "{} of 5 arrived", got.len());
            if let Event::Input(port) = recorder
                .next_event(Some(Duration::from_millis(20)))
                .expect("event")
            {
                assert_eq!(port, input.id());
                while let Some(sample) = recorder.take_raw(&input) {
                    got.push(sample.payload);
                }
            }
        }
        done.send(()).expect("provider alive");
        provider.join().expect("provider");
        assert_eq!(
            got.iter().map(Vec::len).collect::<Vec<_>>(),
            sizes,
            "every frame, in order"
        );
        assert!(got == payloads, "the same bytes");
    }

    #[test]
    fn raw_ports_link_over_the_network_taking_the_providers_type() {
        let agent = fake_agent();
        // Check that the agent is up before the nodes look for it.
        TcpStream::connect(&agent).expect("agent up");
        let mut provider = connect("replay", &agent);
        let mut recorder = connect("recorder", &agent);
        let input = recorder.subscribe_raw("counter.count", true).expect("raw");
        let output = provider
            .publish_raw("counter.count", "Counter")
            .expect("raw");
        let deadline = Instant::now() + Duration::from_secs(10);
        while provider.raw_subscriber_count(&output) == 0 {
            assert!(Instant::now() < deadline, "no subscriber in time");
            provider
                .next_event(Some(Duration::from_millis(5)))
                .expect("poll");
            recorder
                .next_event(Some(Duration::from_millis(5)))
                .expect("poll");
        }
        assert!(recorder.is_raw_linked(&input));
        for value in 1..=3u8 {
            provider.send_raw(&output, &[value]).expect("send");
        }
        provider.flush().expect("flush");
        let mut samples = Vec::new();
        while samples.len() < 3 {
            assert!(Instant::now() < deadline, "samples: {samples:?}");
            if let Event::Input(port) = recorder
                .next_event(Some(Duration::from_millis(20)))
                .expect("event")
            {
                assert_eq!(port, input.id());
                while let Some(sample) = recorder.take_raw(&input) {
                    samples.push(sample);
                }
            }
        }
        assert!(samples.iter().all(|s| s.data_type == "Counter"));
        assert_eq!(
            samples
                .iter()
                .map(|s| (s.seq, s.payload.clone()))
                .collect::<Vec<_>>(),
            [(1, vec![1]), (2, vec![2]), (3, vec![3])]
        );
    }
}
