//! The ArMoR runtime: the central agent ([`agent`]), the config server ([`config_server`]), the
//! supervisor behind `armor run` ([`supervisor`]), the mission controller ([`controller`]) and
//! its operator interface ([`control`]), module discovery and probing ([`probe`]), and loading
//! and checking system and mission files ([`load`], [`mission`]). The `armor` binary is a thin command line over
//! these. Nothing here knows egui.

pub mod agent;
pub mod autoplan;
pub mod basemap;
pub mod behaviour;
pub mod config_server;
pub mod console;
pub mod control;
pub mod controller;
pub mod fs;
pub mod gate;
pub mod health;
pub mod host;
pub mod host_run;
pub mod hosts;
pub mod load;
mod mcap_read;
pub mod mission;
pub mod paths;
pub mod probe;
pub mod process;
pub mod progress;
pub mod rehearsal;
pub mod replay;
pub mod restart;
pub mod ros_export;
pub mod run_dir;
pub mod summary;
pub mod supervisor;
pub mod teleop_relay;

/// The agent's first line on stdout, followed by the address it listens on.
pub const AGENT_READY_PREFIX: &str = "armor agent listening on ";
/// `armor run`'s line on stdout, followed by the address of its control interface.
pub const CONTROL_READY_PREFIX: &str = "armor run control interface at ";
