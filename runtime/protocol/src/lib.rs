//! The control protocol of a run: what `armor ctl`, the studio's Run view and any other client
//! say to `armor run`'s control interface, what it answers, and a client. The run serves it
//! (`armor_runtime::control`); a client links this crate only, not the program that serves it.
//!
//! The link is the run's wire protocol (`docs/protocol.md`): hellos, then JSON messages in
//! frames, each request numbered from 1 and its reply carrying the same number:
//!
//! ```text
//! → {"seq":1,"request":{"command":"fire","transition":"leave_wp1"}}
//! ← {"seq":1,"reply":{"ok":true,"message":"fired `leave_wp1`","status":{...}}}
//! → {"seq":2,"request":{"command":"teleop","linear":0.3,"angular":0}}
//! ← {"seq":2,"reply":{"ok":true,"message":"teleop `teleop`: driving at 0.3 0","status":null}}
//! ```
//!
//! One module per direction, as dora's message crate has them: [`to_run`] (the requests),
//! [`from_run`] (the replies, the run's [`Status`] and files), [`frame`] (reading a bounded
//! frame, shared by both ends) and the [`Client`]; [`team`] holds what a team's operator
//! station shows of its robots (issue 41), which the studio reads from `armor-team station`.
//!
//! With a shared secret the client proves a role's key in the Noise handshake of the data
//! links (identity `operator` or `observer`), and the link is encrypted: nobody on the path
//! reads it, and a record changed, replayed, reordered or dropped fails to open, which ends
//! the connection. The run sends nothing to a client before its valid first handshake message.

pub mod client;
pub mod frame;
pub mod from_run;
pub mod team;
pub mod to_run;

pub use armor_module_api::auth::{Role, RoleKey};
pub use client::{Client, ClientError, key_from_file, request};
pub use from_run::{
    BehaviourChange, BehaviourState, BinaryFile, Enabled, FileText, FiringRecord, FromRun,
    LegProgress, MissionStatus, ModuleState, ModuleStatus, ParamFile, Repair, RepairKind,
    RepairOption, Reply, RunFiles, Status, TELEOP_ENDPOINT, TELEOP_TYPE, UpdateRecord,
};
pub use to_run::{ENV_CONTROL, MAX_UPDATE_BYTES, Request, ToRun, allowed};

/// How long a client waits to reach the run, and the run for its own answer to a request.
pub const REPLY_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(5);
