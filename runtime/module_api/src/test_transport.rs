//! The test transport under [`crate::testing::TestBench`]: a module's sent frames kept in
//! memory, and a script of steps played when its body waits.

use std::collections::VecDeque;
use std::time::Instant;

use crate::core::{ApiError, Core, Event};
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
    pub sent: Vec<(usize, DataFrame)>,
    pub reports: Vec<ToSupervisor>,
    pub script: Option<VecDeque<Step>>,
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
