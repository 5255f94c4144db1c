//! The ArMoR runtime: the central agent ([`agent`]), the config server (`config_server`), the
//! supervisor behind `armor run` (`supervisor`), the mission controller (`controller`) and
//! its operator interface ([`control`]), module discovery and probing ([`probe`]), and loading
//! and checking system and mission files ([`load`], [`mission`]). The `armor` binary is a thin command line over
//! these. Nothing here knows egui.
//!
//! The feature `cli` (on by default) holds the command line and the run it supervises
//! (supervisor, config server, controller, hosts, console); without it a client such as the
//! studio keeps probing, loading, plan worlds, base maps, recordings and process helpers, and
//! links neither clap, indicatif, notify nor signal-hook. The control protocol's types and
//! client are `armor_protocol`'s.

pub mod agent;
pub mod autoplan;
pub mod basemap;
pub mod behaviour;
#[cfg(feature = "cli")]
pub mod config_server;
#[cfg(feature = "cli")]
pub mod console;
pub mod control;
#[cfg(feature = "cli")]
pub mod controller;
pub mod fs;
pub mod gate;
pub mod health;
#[cfg(feature = "cli")]
pub mod host;
#[cfg(feature = "cli")]
pub mod host_run;
#[cfg(feature = "cli")]
pub mod hosts;
pub mod load;
pub mod log_pump;
mod mcap_read;
pub mod mission;
pub mod paths;
pub mod probe;
pub mod process;
#[cfg(feature = "cli")]
pub mod progress;
pub mod rehearsal;
#[cfg(feature = "cli")]
pub mod repair;
pub mod replay;
pub mod restart;
pub mod ros_export;
pub mod run_dir;
#[cfg(feature = "cli")]
pub mod summary;
#[cfg(feature = "cli")]
pub mod supervisor;
#[cfg(feature = "cli")]
pub mod teleop_relay;
#[cfg(feature = "cli")]
pub mod update;

/// The agent's first line on stdout, followed by the address it listens on.
pub const AGENT_READY_PREFIX: &str = "armor agent listening on ";
/// `armor run`'s line on stdout, followed by the address of its control interface.
pub const CONTROL_READY_PREFIX: &str = "armor run control interface at ";
