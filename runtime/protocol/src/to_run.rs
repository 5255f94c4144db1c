//! From a client to the run: the requests, and each one's number on the link.

use armor_module_api::auth::Role;
use serde::{Deserialize, Serialize};

/// The environment variable that gives `armor ctl` the run's control address.
pub const ENV_CONTROL: &str = "ARMOR_CONTROL";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "command", rename_all = "snake_case")]
pub enum Request {
    Status,
    Pause,
    Resume,
    Abort,
    Fire {
        transition: String,
    },
    /// Start a controllable module by hand, whatever the mission wants, until released.
    StartModule {
        module: String,
    },
    /// Stop a controllable module by hand, until released.
    StopModule {
        module: String,
    },
    /// Give a module back to the mission (or, without one, to running).
    ReleaseModule {
        module: String,
    },
    /// Drive the robot: relayed to the run's teleop module (`module`, or the only module of
    /// type `teleop`), which holds the command for its dead-man time: an operator sends it again
    /// while driving. Zero speeds are sent as `stop`.
    Teleop {
        linear: f64,
        angular: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        module: Option<String>,
    },
    /// The run's files, for a client that attaches without them: the system file, the
    /// mission's and the files the system's parameters name ([`RunFiles`]).
    Files,
    /// Tell the localiser where the robot is (rviz's "2D Pose Estimate"): its `set_pose`
    /// parameter is set to `X Y HEADING_DEG` over the system file's, for the rest of the run.
    /// `module`, or the only module of type `localiser`.
    SetPose {
        x_m: f64,
        y_m: f64,
        heading_deg: f64,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        module: Option<String>,
    },
    /// Update the running plan (`armor ctl update PLAN.xml`): the run checks `text` as `armor
    /// check` does (its relative names resolved from the running plan's folder), compiles it
    /// and moves the mission to it between two firings (`docs/plans.md`, "Updates to a running
    /// mission"), or refuses it with the reason and goes on unchanged. `file` is the name the
    /// operator gave, for the messages.
    Update {
        file: String,
        text: String,
    },
    /// Report a no-go area (`armor ctl area NAME X,Y X,Y X,Y…`: another unit reports a
    /// minefield): its corners in the world frame, in metres. The run adds it to the running
    /// plan and takes that as an update (`docs/plans.md`, "Areas reported from outside").
    Area {
        name: String,
        points_m: Vec<[f64; 2]>,
    },
    /// Apply option `option` (numbered from 1) of the repair the mission proposes
    /// ([`crate::Repair`], in the status's `mission.repair`): `armor ctl repair N`. Each option is
    /// a plan update the run takes as it takes `Update` (`docs/plans.md`, "Repair"); refused
    /// when nothing is proposed or the number is not one of the options.
    Repair {
        option: u32,
    },
    /// The team bridge (`armor-team robot`) says that the robot's link to its operator is lost
    /// (no operator's beat for a while) or found again. A plan's `link_lost` contingency
    /// answers it on the robot (`docs/team.md`); an operator's request, since a role that only
    /// reads must not make the robot hold.
    Link {
        lost: bool,
    },
}

/// The largest plan `armor ctl update` sends: a request, with its JSON escapes, must fit in
/// the 64 KiB the control interface reads of one.
pub const MAX_UPDATE_BYTES: usize = 48 * 1024;

/// A request on the control link, numbered by the client from 1: the run answers only the
/// next number, so a request replayed, reordered or dropped on the way ends the connection.
#[derive(Debug, Serialize, Deserialize)]
pub struct ToRun {
    pub seq: u64,
    pub request: Request,
}

/// Whether a role may make a request: an observer only reads.
pub fn allowed(role: Role, request: &Request) -> bool {
    role == Role::Operator || matches!(request, Request::Status | Request::Files)
}
