//! The control messages of each connection, one enum per direction (sent as JSON frames, see
//! [`crate::wire`]). A module has three kinds of connection:
//!
//! * to the **agent** (name server): [`ToAgent`] / [`FromAgent`];
//! * to the **supervisor** (the config server of `armor run`): [`ToSupervisor`] /
//!   [`FromSupervisor`], which carry configuration, control and event reports;
//! * to a **provider** of one of its inputs: [`ToProvider`] / [`FromProvider`], after which the
//!   provider sends data frames. The provider may subscribe back on the same connection, which
//!   then carries both enums and data both ways.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

/// An output a module serves: its unique data name, data type and the address to subscribe at.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Advert {
    pub data_name: String,
    pub data_type: String,
    pub addr: String,
    /// In the agent's answers of a run with a secret: the link key (hex) with which the asker
    /// proves itself at the provider's data port (`docs/protocol.md`, section 2.5).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub key: Option<String>,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ToAgent {
    /// Replaces everything this connection registered before.
    Register {
        module: String,
        outputs: Vec<Advert>,
    },
    Lookup {
        data_name: String,
    },
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum FromAgent {
    Registered,
    Provider(Advert),
    Unknown { data_name: String },
    Error { message: String },
}

/// What a module needs to know to run: its port bindings and parameter values.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ModuleConfig {
    pub module_type: String,
    /// Input name → unique data name of the output feeding it (`module.output`).
    pub inputs: BTreeMap<String, String>,
    /// Output name → its unique data name.
    pub outputs: BTreeMap<String, String>,
    /// Parameter name → value, defaults included.
    pub params: BTreeMap<String, String>,
    /// Whether the module starts active (the mission controller may start it later).
    pub active: bool,
    /// The address the module's data listener binds to.
    pub host: String,
    /// Input name → at most this many samples a second, asked of its provider (a link's
    /// `max_rate_hz` in the system file; best-effort inputs only).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub input_rates: BTreeMap<String, f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ToSupervisor {
    Hello {
        module: String,
        pid: u32,
    },
    /// The module has its configuration and is at work.
    Ready,
    Event {
        name: String,
    },
    /// A no-go area the module learnt of (another unit reports a minefield): its corners in
    /// the world frame, in metres. A run that plays a plan adds it to the plan as an update
    /// (`docs/plans.md`, "Areas reported from outside"); any other run logs and drops it.
    Area {
        name: String,
        points_m: Vec<[f64; 2]>,
    },
    /// A behaviour's preconditions hold (`true`) or not: sent when that changes. With the
    /// module's activity it makes the states a user sees (`slept`, `checking`, `ready`,
    /// `winner`; see `docs/protocol.md`, section 4.2).
    Applicable {
        applicable: bool,
    },
    /// From an arbiter: the input whose command is in control now (`None`: no candidate is),
    /// sent when that changes.
    Winner {
        #[serde(default)]
        input: Option<String>,
    },
    /// A service of the module's own, outside the data links, listens at `address` (the
    /// teleop's command port): sent once it listens, and again when the address changes. The
    /// supervisor shows it in the run's status and relays the operator's commands to it.
    Endpoint {
        name: String,
        address: String,
    },
    /// What the module wants back if its process is restarted in this run (the localiser's
    /// correction of odometry, so that a restarted localiser starts where the robot is, not at
    /// the world's start): the config server keeps the latest per module name and hands it to
    /// the next process of that name before its configuration ([`FromSupervisor::Kept`]).
    /// Text of the module's own making, at most [`MAX_KEPT_BYTES`].
    Keep {
        state: String,
    },
    /// The answer to a ping, with what the module did so far (absent from modules that do not
    /// count: `{"type":"pong"}` is a valid answer).
    Pong {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        stats: Option<NodeStats>,
    },
}

/// A module's work since it started, as its node counts it: the run view's rates and cycle
/// times are differences between two of these.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeStats {
    /// Events the module's loop has taken (returns of `next_event`).
    pub cycles: u64,
    /// Real time spent in the module's own code, between taking an event and asking for the
    /// next, in microseconds.
    pub busy_us: u64,
    /// Samples published, per output (its unique data name).
    pub sent: BTreeMap<String, u64>,
    /// Samples received, per input name.
    pub received: BTreeMap<String, u64>,
    /// A behaviour's latest [`ToSupervisor::Applicable`] (absent from other modules), repeated
    /// here so that a config server that reconnects learns it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applicable: Option<bool>,
    /// An arbiter's latest [`ToSupervisor::Winner`], repeated for the same reason.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub winner: Option<String>,
    /// Payload bytes received, per input name (the link's bandwidth, over time).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub received_bytes: BTreeMap<String, u64>,
    /// The module's [`ToSupervisor::Endpoint`]s, name → address, repeated so that a config
    /// server that reconnects learns them.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub endpoints: BTreeMap<String, String>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum FromSupervisor {
    Config(ModuleConfig),
    /// What an earlier process of this module kept ([`ToSupervisor::Keep`]) in this run: sent
    /// once, just before the first `config` of a restarted module, and only to a module that
    /// kept something.
    Kept {
        state: String,
    },
    Start,
    Stop,
    Shutdown,
    Ping,
    Error {
        message: String,
    },
    /// One report of the run's health stream, sent to every module: an input linked from
    /// [`HEALTH`] receives it as a sample (`seq` its sequence number), and the inputs fed by
    /// the module it is about hear [`crate::Event::ProviderFailed`] when it failed or stalled.
    Health {
        seq: u64,
        #[serde(flatten)]
        health: crate::types::Health,
    },
}

/// The longest state a module may keep ([`ToSupervisor::Keep`]); a longer one is dropped.
pub const MAX_KEPT_BYTES: usize = 4096;

/// The data name of the run's health stream: an input of type `Health` linked from it gets
/// every report, through the module's connection to the config server.
pub const HEALTH: &str = "armor.health";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum ToProvider {
    Subscribe {
        data_name: String,
        data_type: String,
        /// `module.input`, for the provider's logs.
        subscriber: String,
        /// `false`: the subscriber wants only the newest sample and the provider may drop older
        /// ones it has not started to send. `true`: every sample, with back-pressure.
        reliable: bool,
        /// A best-effort subscriber that wants at most this many samples per second (real
        /// time): the provider skips a sample that comes sooner than `1 / max_rate_hz` after the
        /// last one it sent this subscriber, as DDS's time-based filter does. A display needs a
        /// few dozen poses a second, not the thousands a fast simulation publishes.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        max_rate_hz: Option<f64>,
        /// Pull mode: the provider sends nothing of its own accord, and answers each
        /// [`ToProvider::Pull`] with its latest sample.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        pull: bool,
        /// The subscriber's own data address (as it registered it at the agent): the provider
        /// may subscribe to the subscriber's outputs on this connection rather than open
        /// another, which it does when it has no subscription on it yet.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        subscriber_addr: Option<String>,
        /// With a secret, from a provider subscribing back on a connection its subscriber
        /// opened: the proof that it holds the link key the agent issued it for this direction,
        /// bound to this connection's handshake ([`crate::auth::reverse_proof`]). A connection
        /// serves only the direction its link key was issued for, unless the other is proven
        /// so.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        proof: Option<String>,
    },
    /// From a subscriber (in pull mode or not): send me your latest sample now, or the next one
    /// if you have sent none yet. Answered from the provider's node without waking its module.
    Pull,
    /// From a subscriber whose input is rebound, on a connection that also carries the
    /// provider's own subscription the other way: send no more samples here. Answered with
    /// [`FromProvider::Unsubscribed`] after the last frame of the subscription; the connection
    /// stays up for the other direction.
    Unsubscribe,
}

#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum FromProvider {
    Subscribed,
    Refused {
        reason: String,
    },
    /// The answer to [`ToProvider::Unsubscribe`]: no frame of the old subscription follows.
    Unsubscribed,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_subscribe_without_pull_reads_and_writes_as_before() {
        let text = r#"{"type":"subscribe","data_name":"a.b","data_type":"Counter","subscriber":"c.d","reliable":false}"#;
        let message: ToProvider = serde_json::from_str(text).expect("an older subscribe");
        assert!(matches!(
            message,
            ToProvider::Subscribe {
                pull: false,
                max_rate_hz: None,
                ..
            }
        ));
        assert_eq!(serde_json::to_string(&message).expect("encodes"), text);
        let pulling = ToProvider::Subscribe {
            data_name: "a.b".into(),
            data_type: "Counter".into(),
            subscriber: "c.d".into(),
            reliable: false,
            max_rate_hz: None,
            pull: true,
            subscriber_addr: None,
            proof: None,
        };
        assert!(
            serde_json::to_string(&pulling)
                .expect("encodes")
                .ends_with(r#""reliable":false,"pull":true}"#)
        );
        assert_eq!(
            serde_json::to_string(&ToProvider::Pull).expect("encodes"),
            r#"{"type":"pull"}"#
        );
    }
}
