//! What a team's operator station knows of its robots, in the form both ends of the station's
//! local stream share: `armor-team station --json` prints one [`StationEvent`] a line, and the
//! studio's station view reads them. The studio links this crate, never `armor_team` (and so
//! never zenoh): it starts the station program and reads its standard output.
//!
//! [`RobotStatus`] and [`RoutePoint`] also travel, sealed, from a robot's bridge to a station.

use serde::{Deserialize, Serialize};

/// A robot's state as a station shows it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RobotStatus {
    pub robot: String,
    /// The run's clock (`armor run`'s seconds, scaled).
    pub run_secs: f64,
    /// `running`, `paused`, `holding`, the mission's outcome once it ended (`complete`,
    /// `aborted`…), `no mission`, or `run unreachable` when the bridge cannot reach its run.
    pub state: String,
    /// The leg the mission is in (the marked place's leg), if any.
    pub leg: Option<String>,
    /// The marked places.
    pub places: Vec<String>,
    /// The localiser's state (`localised`, `uncertain`, `lost`), when its estimate comes.
    pub localisation: Option<String>,
    /// Seconds since the bridge last heard an operator station, if it ever did.
    pub operator_heard_secs_ago: Option<f64>,
    /// Whether the bridge told the run that its operator's link is lost.
    pub link_lost: bool,
    pub firings_total: usize,
    /// The latest firing's transition, for a station to see a response happen.
    pub last_firing: Option<String>,
}

/// A waypoint of a robot's plan in its world frame (metres), in the order the route passes
/// them.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RoutePoint {
    pub name: String,
    pub x_m: f64,
    pub y_m: f64,
}

/// One line of `armor-team station --json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StationEvent {
    /// First: the station's role (`observer` or `operator`) and its robots.
    Station { role: String, robots: Vec<String> },
    /// What the station knows of one robot, each robot about every half second.
    Robot(Box<RobotReport>),
    /// A robot's answer to a command (`ok` false: refused, or no answer).
    Answer {
        robot: String,
        command: String,
        ok: bool,
        message: String,
    },
    /// A command line the station could not take (a robot it does not know, a plan it cannot
    /// read…).
    Error { message: String },
}

/// What the station knows of one robot.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct RobotReport {
    pub robot: String,
    /// Whether the station holds a session with the robot (its role proved).
    pub session: bool,
    /// Why it has none, when a hello failed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refusal: Option<String>,
    /// Its latest status, if any came.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub status: Option<RobotStatus>,
    /// Its latest pose in its world frame: x and y in metres, heading in radians.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pose: Option<[f64; 3]>,
    /// Its plan's route, once its bridge sent it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub route: Vec<RoutePoint>,
    /// Seconds since its last report (none before the first).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub report_age_secs: Option<f64>,
    /// What its reports cost this station, in kbit/s.
    pub kbit_per_sec: f64,
    /// The link's quality over the last [`LINK_WINDOW_SECS`].
    pub link: LinkQuality,
    /// Its camera's frames over the last [`LINK_WINDOW_SECS`], when it sends one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraSeen>,
}

/// A robot's camera as a station receives it.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraSeen {
    /// The output's data name (`camera.image`).
    pub name: String,
    pub frames_per_sec: f64,
    pub kbit_per_sec: f64,
    /// The latest frame's size, in bytes as the robot's wire carries it.
    pub frame_bytes: usize,
}

/// How much of the last seconds' reports were lost on the way: every sample a bridge seals for
/// a session is numbered, so the gaps a station sees are the samples the radio lost (or the
/// bridge dropped on a congested link).
pub const LINK_WINDOW_SECS: f64 = 10.0;

#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LinkQuality {
    /// Samples received in the window.
    pub received: u64,
    /// Samples sent in the window, as their numbers tell, received or not.
    pub sent: u64,
}

impl LinkQuality {
    /// The share of the window's samples lost, from 0 to 1; none when nothing was sent.
    pub fn loss(&self) -> Option<f64> {
        (self.sent > 0).then(|| 1.0 - (self.received.min(self.sent) as f64 / self.sent as f64))
    }

    /// A word for the link, from the loss and the age of the last report: `lost` past 2 s
    /// without a report, `poor` above 20 % loss or past 1 s, `fair` above 5 %, else `good`.
    pub fn word(&self, report_age_secs: Option<f64>) -> &'static str {
        let Some(age) = report_age_secs else {
            return "none yet";
        };
        let loss = self.loss().unwrap_or(0.0);
        if age > 2.0 {
            "lost"
        } else if loss > 0.2 || age > 1.0 {
            "poor"
        } else if loss > 0.05 {
            "fair"
        } else {
            "good"
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_link_is_named_by_loss_and_age() {
        let link = |received, sent| LinkQuality { received, sent };
        assert_eq!(link(0, 0).word(None), "none yet");
        assert_eq!(link(70, 70).word(Some(0.3)), "good");
        assert_eq!(link(63, 70).word(Some(0.3)), "fair");
        assert_eq!(link(50, 70).word(Some(0.3)), "poor");
        assert_eq!(link(70, 70).word(Some(1.5)), "poor");
        assert_eq!(link(70, 70).word(Some(2.5)), "lost");
        assert_eq!(link(63, 70).loss().map(|l| (l * 100.0).round()), Some(10.0));
    }

    #[test]
    fn a_station_line_reads_back() {
        let event = StationEvent::Robot(Box::new(RobotReport {
            robot: "r1".into(),
            session: true,
            pose: Some([1.0, 2.0, 0.5]),
            route: vec![RoutePoint {
                name: "wp1".into(),
                x_m: 3.0,
                y_m: 4.0,
            }],
            report_age_secs: Some(0.2),
            ..RobotReport::default()
        }));
        let line = serde_json::to_string(&event).expect("serialises");
        assert!(
            line.starts_with(r#"{"kind":"robot","robot":"r1""#),
            "{line}"
        );
        assert_eq!(
            serde_json::from_str::<StationEvent>(&line).expect("reads"),
            event
        );
    }
}
