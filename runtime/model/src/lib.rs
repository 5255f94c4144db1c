//! ArMoR's pure models: the system configuration (which module instances run, their parameters
//! and the links between their ports), its XML form and the checks of a configuration against
//! the module descriptions. This crate does no IO: it parses the text it is given and checks the
//! data it is given; reading files and running modules belong to the runtime.
//!
//! Missions are Petri nets ([`net`]): their XML and PNML forms, the checks of their names against
//! a system, an engine that plays them with the time given as a parameter, and a state-space
//! analysis that finds deadlocks, dead transitions and unbounded places.
//!
//! Plans ([`plan`]) are what an operator draws on a map (waypoints, legs, actions, time
//! constraints, contingencies, tactical graphics); they compile into mission nets, on a
//! [`world`] (the simulated robot's plane, which [`geo`] routes through around no-go areas);
//! [`planner`] finds each leg's path on a costmap of that world. A world may also be a ROS
//! map_server map ([`ros_map`]).
//!
//! [`foxglove`] gives camera images the JSON forms of Foxglove's image schemas, in which the
//! recorder writes them.

mod fields;
pub mod foxglove;
pub mod geo;
mod json_positions;
pub mod net;
pub mod plan;
pub mod planner;
pub mod random;
pub mod rehearsal;
pub mod ros_map;
pub mod system;
pub mod world;
pub mod world_file;

pub use net::{
    Analysis, Condition, Engine, EngineError, EventRef, Firing, Marking, MissionNet, Place,
    PlaceParam, Transition, analyse, check_names, dining_philosophers, from_pnml, to_pnml,
};
/// `1 noun` or `N nouns`, for messages.
pub fn plural(count: usize, noun: &str) -> String {
    format!("{count} {noun}{}", if count == 1 { "" } else { "s" })
}

pub use system::{
    Activation, DEFAULT_HOST, DEFAULT_HOST_PORT, Endpoint, HostDecl, Link, ModuleBindings,
    ModuleInstance, ParamValue, RestartPolicy, SystemConfig, check,
};
