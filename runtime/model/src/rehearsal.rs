//! A simulated rehearsal judged by the simulator's truth: given the robot's true poses (the
//! simulator's `pose_truth`), the arrivals the mission saw, the plan's no-go areas, the robot's
//! radius and the follower's tolerance, whether the plan was truly carried out.
//!
//! What the robot believes (its odometry, the follower's "arrived") is what a rehearsal tests,
//! never the evidence: a leg arrived truly when the true pose nearest in time to its arrival
//! event lies within the follower's tolerance plus [`ARRIVAL_SLACK_M`] of its waypoint, and a
//! no-go area was respected when the robot's true footprint (a disc of its radius round every
//! true pose of the run) never met it.
//!
//! [`Judge`] takes the poses as they come, at full rate, and keeps only what the verdict needs
//! (each area's least distance, the poses of the last [`WINDOW_SECS`]), so that a long run does
//! not grow its memory; [`judge`] is the same over whole lists. Both are pure: no clock, no IO.

use std::collections::VecDeque;

use serde::Serialize;

use crate::geo::{Point, Polygon};

/// How far beyond the follower's tolerance a true arrival may be: the odometry the follower
/// stops by and the truth differ by a little even when nothing is wrong (a physics step, the
/// last command's coasting), never by this much.
pub const ARRIVAL_SLACK_M: f64 = 0.1;

/// How long the poses before the newest are kept to find the one nearest to an arrival event in
/// time (run seconds): the event reaches the judge after the poses of its time, a fraction of a
/// second of real time later even on a loaded machine and at a high time scale.
pub const WINDOW_SECS: f64 = 300.0;

/// A true pose farther than this in time from an arrival event (run seconds) is no evidence of
/// where the robot was then: the simulator's stream had a gap.
pub const MAX_GAP_SECS: f64 = 5.0;

/// One true pose of the robot: where it was (world frame) at a run time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruePose {
    pub at_secs: f64,
    pub at: Point,
}

/// A leg's arrival event: the mission took the robot to be at `target` (its waypoint `waypoint`,
/// world frame) at run time `at_secs`.
#[derive(Clone, Debug, PartialEq)]
pub struct Arrival {
    pub leg: String,
    pub waypoint: String,
    pub target: Point,
    pub at_secs: f64,
}

/// A no-go area of the plan, in the world frame (without its margin: the margin is what the
/// planner keeps, the area is what must not be met).
#[derive(Clone, Debug, PartialEq)]
pub struct NoGoArea {
    pub name: String,
    pub polygon: Polygon,
}

/// What a rehearsal is held to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rules {
    /// The robot's radius, as the planner takes it: its footprint is this disc round each pose.
    pub radius_m: f64,
    /// The follower's own tolerance (its `tolerance_m`).
    pub tolerance_m: f64,
}

impl Rules {
    /// How far from its waypoint a true arrival may be.
    pub fn allowed_m(&self) -> f64 {
        self.tolerance_m + ARRIVAL_SLACK_M
    }
}

/// One arrival as the truth saw it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ArrivalJudgement {
    pub leg: String,
    pub waypoint: String,
    /// The arrival event's run time.
    pub arrived_secs: f64,
    /// The distance from the true pose nearest in time to the waypoint; `None` when no true pose
    /// lies within [`MAX_GAP_SECS`] of the event.
    pub true_error_m: Option<f64>,
    /// The run time of that true pose.
    pub truth_secs: Option<f64>,
    pub allowed_m: f64,
    pub ok: bool,
}

/// One no-go area as the truth saw it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AreaJudgement {
    pub area: String,
    /// The least distance between the robot's true footprint and the area over the run;
    /// negative: how far the footprint reached into it. `None` without any true pose.
    pub least_distance_m: Option<f64>,
    /// When the footprint came closest.
    pub least_secs: Option<f64>,
    /// When the footprint first met the area, if it did.
    pub first_met_secs: Option<f64>,
    /// How many true poses put the footprint on the area.
    pub poses_met: usize,
    pub ok: bool,
}

/// The whole judgement: each arrival, each area, and what failed, in words.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Verdict {
    pub passed: bool,
    /// How many true poses were judged.
    pub true_poses: usize,
    pub robot_radius_m: f64,
    pub tolerance_m: f64,
    pub allowed_m: f64,
    pub arrivals: Vec<ArrivalJudgement>,
    pub areas: Vec<AreaJudgement>,
    /// Each failure, a sentence (`leg `regroup` arrived 2.59 m from its waypoint `rally` by the
    /// simulator's truth (allowed 0.40 m)`); empty when the rehearsal passed.
    pub failures: Vec<String>,
}

impl Verdict {
    /// The verdict in one line: `rehearsal passed …` or `rehearsal FAILED: …` with every
    /// failure.
    pub fn headline(&self) -> String {
        if self.passed {
            format!(
                "rehearsal passed by the simulator's truth: every arrival within {} m of its \
                 waypoint, no footprint met a no-go area ({} true poses)",
                metres(self.allowed_m),
                self.true_poses
            )
        } else {
            format!("rehearsal FAILED: {}", self.failures.join("; "))
        }
    }

    /// The true error of `leg`'s arrival as a table cell: `0.12 m (simulator)`, `-` when it has
    /// none.
    pub fn true_error_text(&self, leg: &str) -> String {
        let Some(arrival) = self.arrivals.iter().find(|arrival| arrival.leg == leg) else {
            return "-".to_owned();
        };
        match arrival.true_error_m {
            Some(error) => format!(
                "{} m (simulator){}",
                metres(error),
                if arrival.ok { "" } else { " FAILED" }
            ),
            None => "no truth".to_owned(),
        }
    }

    /// Each no-go area's least distance to the true footprint, one line each.
    pub fn area_lines(&self) -> Vec<String> {
        self.areas
            .iter()
            .map(|area| match (area.least_distance_m, area.first_met_secs) {
                (None, _) => format!("no-go area `{}`: no true pose to judge it by", area.area),
                (Some(least), None) => format!(
                    "no-go area `{}`: the footprint (radius {} m) kept {} m from it at least, \
                     by the simulator's truth",
                    area.area,
                    metres(self.robot_radius_m),
                    metres(least)
                ),
                (Some(least), Some(first)) => format!(
                    "no-go area `{}`: the footprint (radius {} m) met it from {first:.1} s, \
                     reaching {} m into it ({} true poses), by the simulator's truth",
                    area.area,
                    metres(self.robot_radius_m),
                    metres(-least),
                    area.poses_met
                ),
            })
            .collect()
    }
}

/// Two decimals, as the summary prints distances.
fn metres(value: f64) -> String {
    format!("{value:.2}")
}

/// The least distance from a disc of `radius_m` round `centre` to the area `polygon`; negative:
/// how far the disc reaches into it.
pub fn footprint_distance_m(polygon: &Polygon, centre: Point, radius_m: f64) -> f64 {
    let outline = polygon.distance_to_outline(centre);
    let signed = if polygon.contains(centre) {
        -outline
    } else {
        outline
    };
    signed - radius_m
}

/// An area's least distance so far.
#[derive(Clone, Debug)]
struct AreaTrack {
    area: NoGoArea,
    least: Option<(f64, f64)>,
    first_met_secs: Option<f64>,
    poses_met: usize,
    /// Taken out of the plan by an update: judged up to then, no longer after.
    retired: bool,
}

impl AreaTrack {
    fn new(area: NoGoArea) -> Self {
        Self {
            area,
            least: None,
            first_met_secs: None,
            poses_met: 0,
            retired: false,
        }
    }
}

/// An arrival with the true pose nearest to it in time so far; `settled` once a pose at or after
/// its time has come, after which no later pose can be nearer.
#[derive(Clone, Debug)]
struct PendingArrival {
    arrival: Arrival,
    nearest: Option<TruePose>,
    settled: bool,
}

impl PendingArrival {
    fn consider(&mut self, pose: TruePose) {
        let gap = |pose: &TruePose| (pose.at_secs - self.arrival.at_secs).abs();
        if self.nearest.is_none_or(|best| gap(&pose) < gap(&best)) {
            self.nearest = Some(pose);
        }
        if pose.at_secs >= self.arrival.at_secs {
            self.settled = true;
        }
    }
}

/// The judge of a rehearsal in progress: true poses and arrival events go in as they come, the
/// verdict comes out at any time.
#[derive(Clone, Debug)]
pub struct Judge {
    rules: Rules,
    areas: Vec<AreaTrack>,
    arrivals: Vec<PendingArrival>,
    recent: VecDeque<TruePose>,
    /// The run time of the newest pose in.
    newest_secs: f64,
    poses: usize,
}

impl Judge {
    pub fn new(areas: Vec<NoGoArea>, rules: Rules) -> Self {
        Self {
            rules,
            areas: areas.into_iter().map(AreaTrack::new).collect(),
            arrivals: Vec::new(),
            recent: VecDeque::new(),
            newest_secs: f64::NEG_INFINITY,
            poses: 0,
        }
    }

    /// Takes in one true pose. A pose that is not finite is no evidence and is left out.
    pub fn observe(&mut self, pose: TruePose) {
        if !pose.at.is_finite() || !pose.at_secs.is_finite() {
            return;
        }
        self.poses += 1;
        for track in self.areas.iter_mut().filter(|track| !track.retired) {
            let distance = footprint_distance_m(&track.area.polygon, pose.at, self.rules.radius_m);
            if track.least.is_none_or(|(least, _)| distance < least) {
                track.least = Some((distance, pose.at_secs));
            }
            if distance <= 0.0 {
                track.poses_met += 1;
                if track
                    .first_met_secs
                    .is_none_or(|first| pose.at_secs < first)
                {
                    track.first_met_secs = Some(pose.at_secs);
                }
            }
        }
        for pending in self.arrivals.iter_mut().filter(|pending| !pending.settled) {
            pending.consider(pose);
        }
        self.recent.push_back(pose);
        self.newest_secs = self.newest_secs.max(pose.at_secs);
        while self
            .recent
            .front()
            .is_some_and(|oldest| oldest.at_secs < self.newest_secs - WINDOW_SECS)
        {
            self.recent.pop_front();
        }
    }

    /// The plan was updated while it ran: its no-go areas are now `areas`. An area the plan
    /// had before, by name and outline, goes on being judged as it was; a new one (or a new
    /// outline) is judged from now on, since the robot was not kept from it before; one the
    /// update took out keeps its judgement so far and is no longer judged.
    pub fn set_areas(&mut self, areas: Vec<NoGoArea>) {
        for track in self.areas.iter_mut().filter(|track| !track.retired) {
            track.retired = !areas.contains(&track.area);
        }
        for area in areas {
            if !self
                .areas
                .iter()
                .any(|track| !track.retired && track.area == area)
            {
                self.areas.push(AreaTrack::new(area));
            }
        }
    }

    /// Takes in an arrival event: judged by the true pose nearest to it in time, among those
    /// already in and those to come.
    pub fn arrived(&mut self, arrival: Arrival) {
        let mut pending = PendingArrival {
            arrival,
            nearest: None,
            settled: false,
        };
        for &pose in &self.recent {
            pending.consider(pose);
        }
        self.arrivals.push(pending);
    }

    /// Whether every arrival has seen a true pose at or after its time (the verdict on it can no
    /// longer change).
    pub fn settled(&self) -> bool {
        self.arrivals.iter().all(|pending| pending.settled)
    }

    /// The verdict on what came in so far.
    pub fn verdict(&self) -> Verdict {
        let allowed_m = self.rules.allowed_m();
        let mut failures = Vec::new();
        if self.poses == 0 {
            failures.push(
                "no true pose came from the simulator, so nothing could be judged".to_owned(),
            );
        }
        let arrivals: Vec<ArrivalJudgement> = self
            .arrivals
            .iter()
            .map(|pending| {
                let arrival = &pending.arrival;
                let truth = pending
                    .nearest
                    .filter(|pose| (pose.at_secs - arrival.at_secs).abs() <= MAX_GAP_SECS);
                let error = truth.map(|pose| pose.at.distance(arrival.target));
                let ok = error.is_some_and(|error| error <= allowed_m);
                match error {
                    Some(error) if !ok => failures.push(format!(
                        "leg `{}` arrived {} m from its waypoint `{}` by the simulator's truth \
                         (allowed {} m)",
                        arrival.leg,
                        metres(error),
                        arrival.waypoint,
                        metres(allowed_m)
                    )),
                    None if self.poses > 0 => failures.push(format!(
                        "leg `{}` arrived at {:.1} s with no true pose within {MAX_GAP_SECS} s \
                         of it, so its arrival could not be judged",
                        arrival.leg, arrival.at_secs
                    )),
                    _ => {}
                }
                ArrivalJudgement {
                    leg: arrival.leg.clone(),
                    waypoint: arrival.waypoint.clone(),
                    arrived_secs: arrival.at_secs,
                    true_error_m: error,
                    truth_secs: truth.map(|pose| pose.at_secs),
                    allowed_m,
                    ok,
                }
            })
            .collect();
        let areas: Vec<AreaJudgement> = self
            .areas
            .iter()
            .map(|track| {
                let ok = track.first_met_secs.is_none();
                if let (Some((least, _)), Some(first)) = (track.least, track.first_met_secs) {
                    failures.push(format!(
                        "the robot's footprint met the no-go area `{}` by the simulator's truth \
                         (from {first:.1} s, {} m into it, {} true poses)",
                        track.area.name,
                        metres(-least),
                        track.poses_met
                    ));
                }
                AreaJudgement {
                    area: track.area.name.clone(),
                    least_distance_m: track.least.map(|(least, _)| least),
                    least_secs: track.least.map(|(_, at)| at),
                    first_met_secs: track.first_met_secs,
                    poses_met: track.poses_met,
                    ok,
                }
            })
            .collect();
        Verdict {
            passed: failures.is_empty(),
            true_poses: self.poses,
            robot_radius_m: self.rules.radius_m,
            tolerance_m: self.rules.tolerance_m,
            allowed_m,
            arrivals,
            areas,
            failures,
        }
    }
}

/// The verdict on a whole run: `poses` (in any order), `arrivals`, `areas`, by `rules`. The same
/// as feeding a [`Judge`] the poses and arrivals in time order, each arrival before the poses
/// that come after it.
pub fn judge(
    poses: &[TruePose],
    arrivals: &[Arrival],
    areas: &[NoGoArea],
    rules: Rules,
) -> Verdict {
    let mut poses = poses.to_vec();
    poses.sort_by(|a, b| a.at_secs.total_cmp(&b.at_secs));
    let mut arrivals = arrivals.to_vec();
    arrivals.sort_by(|a, b| a.at_secs.total_cmp(&b.at_secs));
    let mut arrivals = arrivals.into_iter().peekable();
    let mut judge = Judge::new(areas.to_vec(), rules);
    for pose in poses {
        while let Some(arrival) = arrivals.next_if(|arrival| arrival.at_secs <= pose.at_secs) {
            judge.arrived(arrival);
        }
        judge.observe(pose);
    }
    for arrival in arrivals {
        judge.arrived(arrival);
    }
    judge.verdict()
}

#[cfg(test)]
mod tests;
