//! The transport-independent state of a module (its configuration, port slots and pending
//! events), what the event loop hands the module, and the API's errors: what [`crate::Node`],
//! the network transport and the test transport all share.

use std::collections::{BTreeMap, VecDeque};
use std::time::{Duration, Instant};

use crate::clock::Clock;
use crate::describe::{ModuleDescription, ParamSpec};
use crate::protocol::{ModuleConfig, NodeStats};
use crate::types::CodecError;
use crate::wire::{DataFrame, WireError};

/// A reliable input holds at most this many samples, and this many bytes of them; beyond
/// either, the provider is made to wait.
pub(crate) const RELIABLE_QUEUE_LEN: usize = 1024;
pub(crate) const RELIABLE_QUEUE_BYTES: usize = 16 * 1024 * 1024;

#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    #[error("module `{module}` declares no {kind} `{port}`")]
    UnknownPort {
        module: String,
        kind: &'static str,
        port: String,
    },
    #[error("{kind} `{port}` carries {declared}, not {requested}")]
    WrongType {
        kind: &'static str,
        port: String,
        declared: String,
        requested: &'static str,
    },
    #[error("parameter `{0}` is not declared and has no value")]
    UnknownParam(String),
    #[error("parameter `{name}`: cannot read `{value}`: {reason}")]
    BadParam {
        name: String,
        value: String,
        reason: String,
    },
    #[error("parameter `{name}` must be {allowed}, not {value}")]
    OutOfRange {
        name: String,
        value: String,
        allowed: String,
    },
    #[error("event `{0}` is not declared by this module")]
    UnknownEvent(String),
    #[error("cannot reach the supervisor at {addr} within {waited_secs:.1} s")]
    NoSupervisor { addr: String, waited_secs: f64 },
    #[error("the supervisor refused this module: {0}")]
    Refused(String),
    #[error(transparent)]
    Secret(#[from] crate::auth::SecretError),
    #[error(transparent)]
    Codec(#[from] CodecError),
    #[error(transparent)]
    Wire(#[from] WireError),
    #[error("network: {0}")]
    Io(#[from] std::io::Error),
    #[error("`{0}` is not a data name (expected `module.output`: no spaces, not empty)")]
    BadDataName(String),
    #[error("`{0}` is not a data type name")]
    BadDataType(String),
    #[error("`{data_name}` is already published as {declared}, not {requested}")]
    DataNameTaken {
        data_name: String,
        declared: String,
        requested: String,
    },
}

/// Checks a parameter's value against its declaration: its type, then its range, `nonzero` and
/// choices.
pub(crate) fn check_param(spec: &ParamSpec, value: &str) -> Result<(), ApiError> {
    spec.param_type
        .check_value(value)
        .map_err(|reason| ApiError::BadParam {
            name: spec.name.clone(),
            value: value.to_owned(),
            reason: reason.to_string(),
        })?;
    spec.check_value(value).map_err(|_| ApiError::OutOfRange {
        name: spec.name.clone(),
        value: value.trim().to_owned(),
        allowed: spec.range_text(),
    })
}

/// Identifies an input in [`Event::Input`]; compare with [`Input::id`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PortId(pub(crate) usize);

/// What the event loop hands the module.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    /// A new sample is ready on this input; read it with [`Node::take`].
    Input(PortId),
    /// These parameters have new values (live tuning from an edited configuration).
    ParamsChanged(Vec<String>),
    /// The controller activated the module.
    Start,
    /// The controller deactivated the module: it should idle, commanding nothing until
    /// [`Event::Start`]. Inputs keep the latest value they received, so a module whose output
    /// commands motion publishes one zero command first and then nothing.
    Stop,
    /// The run is ending: return from the module body.
    Shutdown,
    /// The deadline given to [`Node::next_event_until`] has passed.
    Timeout,
    /// The provider of this input failed or stalled (the run's health stream said so, before
    /// any socket closes); the input goes on from a fallback source if it has one, else from
    /// the provider once it is back.
    ProviderFailed(PortId),
}

pub(crate) struct InputSlot {
    pub name: String,
    /// For a raw input, the type of its current provider (empty until the agent names one).
    pub data_type: String,
    /// The unique data name of the output feeding this input, if linked in the configuration.
    pub source: Option<String>,
    /// Added by [`Node::subscribe_raw`]: bound to `source` for good (configurations do not
    /// rebind it), of any data type.
    pub raw: bool,
    pub reliable: bool,
    /// Samples are stored with the link that brought them.
    pub latest: Option<(u64, DataFrame)>,
    pub queue: VecDeque<(u64, DataFrame)>,
    /// Payload bytes in `queue`.
    pub queued_bytes: usize,
    /// The current link's number (see [`Sample::link`]).
    pub link: u64,
    /// An `Event::Input` for this slot is waiting in the event queue.
    pub notified: bool,
    /// Samples received since the module started.
    pub received: u64,
    /// Payload bytes received since the module started.
    pub received_bytes: u64,
    /// At most this many samples per second, asked of the provider (best-effort only).
    pub max_rate_hz: Option<f64>,
    /// Pull mode: the provider sends a sample only when asked ([`Node::pull`]).
    pub pull: bool,
}

impl InputSlot {
    /// An input fed by `source` (when linked), with nothing received yet: best-effort, pushed.
    pub fn new(
        name: String,
        data_type: String,
        source: Option<String>,
        max_rate_hz: Option<f64>,
    ) -> InputSlot {
        InputSlot {
            name,
            data_type,
            source,
            raw: false,
            reliable: false,
            latest: None,
            queue: VecDeque::new(),
            queued_bytes: 0,
            link: 0,
            notified: false,
            received: 0,
            received_bytes: 0,
            max_rate_hz,
            pull: false,
        }
    }

    pub fn has_room(&self) -> bool {
        !self.reliable
            || (self.queue.len() < RELIABLE_QUEUE_LEN && self.queued_bytes < RELIABLE_QUEUE_BYTES)
    }
}

pub(crate) struct OutputSlot {
    pub name: String,
    pub data_type: String,
    pub data_name: String,
    pub seq: u64,
}

/// The transport-independent state of a module: configuration, port slots and pending events.
pub(crate) struct Core {
    pub name: String,
    pub description: ModuleDescription,
    pub config: ModuleConfig,
    pub clock: Clock,
    /// What the supervisor wants now (a start or stop is queued when it changes).
    pub active: bool,
    /// What the module has been told: changed when it takes the `Start` or `Stop` event, so that
    /// events queued before (an input, new parameters) are still handled in the old state.
    pub told_active: bool,
    pub inputs: Vec<InputSlot>,
    pub outputs: Vec<OutputSlot>,
    pub events: VecDeque<Event>,
    /// Events taken by the module's loop, and the real time spent in its code between them.
    pub cycles: u64,
    pub busy: Duration,
    /// When the module last took an event (its code has been running since).
    pub took_event_at: Option<Instant>,
    /// A behaviour's preconditions as it last set them (`None`: it never did).
    pub applicable: Option<bool>,
    /// An arbiter's input in control as it last set it.
    pub winner: Option<String>,
    /// The module's own services and where they listen ([`crate::Node::set_endpoint`]).
    pub endpoints: BTreeMap<String, String>,
    /// What an earlier process of this module kept in this run ([`crate::Node::kept`]).
    pub kept: Option<String>,
}

impl Core {
    pub fn new(
        name: String,
        description: ModuleDescription,
        config: ModuleConfig,
        clock: Clock,
    ) -> Self {
        let inputs = description
            .inputs
            .iter()
            .map(|port| {
                InputSlot::new(
                    port.name.clone(),
                    port.data_type.clone(),
                    config.inputs.get(&port.name).cloned(),
                    config.input_rates.get(&port.name).copied(),
                )
            })
            .collect();
        let outputs = description
            .outputs
            .iter()
            .map(|port| OutputSlot {
                name: port.name.clone(),
                data_type: port.data_type.clone(),
                data_name: config
                    .outputs
                    .get(&port.name)
                    .cloned()
                    .unwrap_or_else(|| format!("{name}.{}", port.name)),
                seq: 0,
            })
            .collect();
        Self {
            active: config.active,
            told_active: config.active,
            name,
            description,
            config,
            clock,
            inputs,
            outputs,
            events: VecDeque::new(),
            cycles: 0,
            busy: Duration::ZERO,
            took_event_at: None,
            applicable: None,
            winner: None,
            kept: None,
            endpoints: BTreeMap::new(),
        }
    }

    /// What the module did so far, for its supervisor (see [`NodeStats`]).
    pub fn stats(&self) -> NodeStats {
        NodeStats {
            cycles: self.cycles,
            busy_us: u64::try_from(self.busy.as_micros()).unwrap_or(u64::MAX),
            sent: self
                .outputs
                .iter()
                .map(|slot| (slot.data_name.clone(), slot.seq))
                .collect(),
            received: self
                .inputs
                .iter()
                .map(|slot| (slot.name.clone(), slot.received))
                .collect(),
            applicable: self.applicable,
            winner: self.winner.clone(),
            received_bytes: self
                .inputs
                .iter()
                .filter(|slot| slot.received_bytes > 0)
                .map(|slot| (slot.name.clone(), slot.received_bytes))
                .collect(),
            endpoints: self.endpoints.clone(),
        }
    }

    /// Stores a received sample. Returns whether the input can take more right now.
    pub fn deliver(&mut self, index: usize, frame: DataFrame) -> bool {
        let slot = &mut self.inputs[index];
        slot.received += 1;
        slot.received_bytes += frame.payload.len() as u64;
        if slot.reliable {
            slot.queued_bytes += frame.payload.len();
            slot.queue.push_back((slot.link, frame));
        } else {
            slot.latest = Some((slot.link, frame));
        }
        if !slot.notified {
            slot.notified = true;
            self.events.push_back(Event::Input(PortId(index)));
        }
        slot.has_room()
    }

    /// Takes a new configuration. Returns the inputs whose source changed (to be relinked).
    pub fn apply_config(&mut self, config: ModuleConfig) -> Vec<usize> {
        let changed_params: Vec<String> = config
            .params
            .iter()
            .filter(|(name, value)| self.config.params.get(*name) != Some(*value))
            .map(|(name, _)| name.clone())
            .chain(
                self.config
                    .params
                    .keys()
                    .filter(|name| !config.params.contains_key(*name))
                    .cloned(),
            )
            .collect();
        let mut relink = Vec::new();
        for (index, slot) in self.inputs.iter_mut().enumerate() {
            if slot.raw {
                continue;
            }
            let source = config.inputs.get(&slot.name).cloned();
            if source != slot.source {
                slot.source = source;
                relink.push(index);
            }
        }
        self.config = config;
        if !changed_params.is_empty() {
            tracing::info!(params = ?changed_params, "new parameter values");
            self.events.push_back(Event::ParamsChanged(changed_params));
        }
        relink
    }

    /// The next queued event, as the module takes it: an input is no longer notified, and a
    /// start or stop now shows in [`Node::is_active`].
    pub fn take_event(&mut self) -> Option<Event> {
        let event = self.events.pop_front()?;
        match event {
            Event::Input(PortId(index)) => self.inputs[index].notified = false,
            Event::Start => self.told_active = true,
            Event::Stop => self.told_active = false,
            _ => {}
        }
        Some(event)
    }

    /// A report of the run's health stream: a sample for the inputs linked from it, and
    /// [`Event::ProviderFailed`] on the inputs its module feeds when it failed or stalled.
    pub fn on_health(&mut self, seq: u64, health: &crate::types::Health) {
        use crate::types::Datum as _;
        let mut payload = Vec::new();
        if let Err(err) = health.encode(&mut payload) {
            tracing::error!("health report: {err}");
            return;
        }
        let lost = matches!(health.kind.as_str(), "failed" | "stalled" | "gave_up");
        for index in 0..self.inputs.len() {
            let source = self.inputs[index].source.as_deref();
            if source == Some(crate::protocol::HEALTH) {
                let frame = DataFrame {
                    seq,
                    stamp_ns: health.at_ns,
                    payload: payload.clone(),
                };
                self.deliver(index, frame);
            } else if lost
                && source
                    .and_then(|source| source.split_once('.'))
                    .is_some_and(|(module, _)| module == health.module)
            {
                self.events.push_back(Event::ProviderFailed(PortId(index)));
            }
        }
    }

    pub fn set_active(&mut self, active: bool) {
        if self.active != active {
            self.active = active;
            self.events
                .push_back(if active { Event::Start } else { Event::Stop });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Blob;

    #[test]
    fn a_links_rate_from_the_configuration_is_asked_of_the_provider() {
        let spec = crate::ModuleSpec::new("m", "a test module")
            .input::<Blob>("scan", "rate-limited")
            .input::<Blob>("odometry", "every sample");
        let config = ModuleConfig {
            input_rates: [("scan".to_owned(), 5.0)].into(),
            ..ModuleConfig::default()
        };
        let mut core = Core::new(
            "m".to_owned(),
            spec.description().clone(),
            config,
            Clock::new(0, 1.0),
        );
        let rate = |core: &Core, name: &str| {
            core.inputs
                .iter()
                .find(|slot| slot.name == name)
                .and_then(|slot| slot.max_rate_hz)
        };
        assert_eq!(rate(&core, "scan"), Some(5.0));
        assert_eq!(rate(&core, "odometry"), None);
        // What arrives is counted in bytes too: the link's bandwidth.
        let frame = DataFrame {
            seq: 1,
            stamp_ns: 0,
            payload: vec![0; 100],
        };
        core.deliver(0, frame);
        assert_eq!(
            core.stats().received_bytes,
            [("scan".to_owned(), 100)].into()
        );
    }
}
