//! What travels between a robot's bridge and a station, inside the sealed samples, and the key
//! expressions it travels under. One enum per direction, as the control protocol has them.
//!
//! ```text
//! armor/team/ROBOT/hello            query: a station's Noise hello → SID and the answer
//! armor/team/ROBOT/cmd              query: SID, sealed Down::Command → sealed CommandReply
//! armor/team/ROBOT/SID/beat         put, station → robot: sealed Down::Beat
//! armor/team/ROBOT/SID/up           put, robot → station: sealed Up (status, pose, output)
//! ```
//!
//! What a stranger on the team network sees is these names (the robots' names and random
//! session numbers), the sizes and the times of the samples: never their contents.

pub use armor_protocol::team::{RobotStatus, RoutePoint};
use serde::{Deserialize, Serialize};

/// The root of every key expression of the team.
pub const ROOT: &str = "armor/team";
/// A session's number: 8 random bytes, written in hex in key expressions.
pub const SID_BYTES: usize = 8;

pub fn hello_key(robot: &str) -> String {
    format!("{ROOT}/{robot}/hello")
}

pub fn cmd_key(robot: &str) -> String {
    format!("{ROOT}/{robot}/cmd")
}

pub fn beat_key(robot: &str, sid: &str) -> String {
    format!("{ROOT}/{robot}/{sid}/beat")
}

pub fn up_key(robot: &str, sid: &str) -> String {
    format!("{ROOT}/{robot}/{sid}/up")
}

/// Whether `name` may name a robot: a short identifier, which fits a key expression's chunk
/// and the handshake's prologue.
pub fn is_robot_name(name: &str) -> bool {
    (1..=64).contains(&name.len())
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-')
}

/// From a robot's bridge to a station.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Up {
    Status(RobotStatus),
    /// Where the robot believes it is (its localiser's estimate, or odometry).
    Pose {
        x_m: f64,
        y_m: f64,
        heading_rad: f64,
    },
    /// A chosen output's latest sample, as the run's wire carries it (postcard), sent only
    /// when it changed: a map goes out once per change.
    Output {
        name: String,
        data_type: String,
        /// The sample's bytes, base64.
        base64: String,
    },
    /// A camera's frame (`--camera`), at its own rate and within its own budget.
    Camera {
        name: String,
        data_type: String,
        /// The sample's bytes, base64.
        base64: String,
    },
    /// The route of the robot's plan in its world frame, for the station's map: sent every
    /// few seconds (a station that opens a session later gets it too), a few hundred bytes.
    Plan {
        route: Vec<RoutePoint>,
    },
}

/// From a station to a robot's bridge.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Down {
    /// The station is there: an operator's beats are what `link_lost` counts.
    Beat,
    /// A request for the run's control link, forwarded as it is if the session's role allows
    /// it (`armor_protocol::allowed`).
    Command { request: armor_protocol::Request },
}

/// The answer to a command.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CommandReply {
    pub ok: bool,
    pub message: String,
}
