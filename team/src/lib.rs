//! A team of robots and operator stations over zenoh (issue 41): `armor-team robot` runs on
//! each robot beside its `armor run`, `armor-team station` on each operator's computer.
//!
//! Inside a robot nothing changes: the bridge is a client of its run like the studio (the
//! control link, and the agent for the data), so modules, the agent and their direct links
//! know nothing of zenoh, and nothing else in the workspace links this crate. Between robots
//! and stations, zenoh carries the samples (peer to peer or through routers, with the
//! endpoints given and no scouting), and the run's Noise keys and roles protect them end to
//! end ([`seal`]): an observer's station reads, an operator's also commands, and someone
//! without a key learns nothing and commands nothing.
//!
//! [`wire`] holds the key expressions and messages, [`net`] the zenoh session, [`robot`] and
//! [`station`] the two ends; [`stand_in`] robots that are only a clock, for tests and
//! benchmarks ([`bench`]) of a station with many robots, and [`radio`] a lossy, slow radio
//! between them on one machine (network namespaces).

pub mod bench;
pub mod capture;
pub mod net;
pub mod radio;
pub mod robot;
pub mod seal;
pub mod stand_in;
pub mod station;
pub mod wire;
