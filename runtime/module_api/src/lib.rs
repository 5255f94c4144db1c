//! The ArMoR module API: everything a module process needs, and nothing of the servers.
//!
//! A module declares its ports, parameters and events in a [`ModuleSpec`] and hands its body to
//! [`run`], which answers `--describe`, connects to the supervisor (configuration, control) and
//! the agent (who serves which datum), and gives the body a [`Node`]: typed [`Output`]s and
//! [`Input`]s, parameters, event reports, the run [`Clock`], and an event loop
//! ([`Node::next_event`]). [`testing::TestBench`] runs the same body with no network.
//! Tools that handle data of any type (recorders, replay) add raw ports at run time, bound to
//! data names: [`Node::subscribe_raw`] and [`Node::publish_raw`].
//!
//! The wire format ([`wire`], [`protocol`]) and the describe format ([`describe`]) are the
//! contract for modules written in other languages; `docs/protocol.md` documents both.

pub mod auth;
pub mod clock;
mod core;
pub mod describe;
pub mod handshake_deadline;
pub mod hardening;
pub mod memory;
mod module;
mod net;
mod node;
pub mod protocol;
mod test_transport;
pub mod testing;
pub mod types;
pub mod wire;
pub mod xml;

pub use clock::Clock;
pub use describe::{Category, ModuleDescription, ParamSpec, ParamType};
pub use module::{
    BodyResult, DEFAULT_AGENT, ENV_AGENT, ENV_MODULE, ENV_RUN_DIR, ENV_SUPERVISOR, ModuleSpec,
    Standalone, init_logging, output_path, run,
};
pub use node::{
    ApiError, Event, Input, Node, Output, PortId, RawInput, RawOutput, RawSample, Sample,
};
pub use types::Datum;

/// Run time in seconds, common to every module of the run (the original API's `timestamp()`).
pub fn timestamp() -> f64 {
    static CLOCK: std::sync::OnceLock<Clock> = std::sync::OnceLock::new();
    CLOCK.get_or_init(Clock::from_env).now_secs()
}
