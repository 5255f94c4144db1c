//! ArMoR's pure models: the system configuration (which module instances run, their parameters
//! and the links between their ports), its XML form and the checks of a configuration against
//! the module descriptions. This crate does no IO: it parses the text it is given and checks the
//! data it is given; reading files and running modules belong to the runtime.

pub mod system;

pub use system::{
    DEFAULT_HOST, Endpoint, Link, ModuleBindings, ModuleInstance, ParamValue, RestartPolicy,
    SystemConfig, check,
};
