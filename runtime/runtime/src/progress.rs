//! The live line `armor run PLAN` draws under its log on a terminal: the leg being driven and
//! the distance left on its planned path, the next time constraint and its slack, the run time.
//! It also keeps what the closing table needs beyond the controller's firings: the distance each
//! leg was driven (by the robot's odometry) and the module events during each leg.
//!
//! The robot's position comes from the output that feeds the navigation module's `odometry`
//! input, to which a node of the run's own (`armor-run`, an observer of the access lists)
//! subscribes. In a simulated run the same node follows the simulator's true pose, every
//! sample of it, into the rehearsal's judge (`armor_model::rehearsal`), which the leg's
//! arrivals are given to as they fire.

use std::collections::BTreeMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use armor_model::geo::{self, Point};
use armor_model::plan::{Compiled, Plan};
use armor_model::rehearsal::{Arrival, Judge, NoGoArea, TruePose, Verdict};
use armor_module_api::types::{Datum, Odometry, Pose2D, Text};
use armor_module_api::{Event, ModuleSpec, Node, Standalone};
use armor_protocol::LegProgress;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::console;

/// The name of the run's own node, which the access lists let subscribe as an observer.
pub const NODE_NAME: &str = "armor-run";
/// The output on which the run's node publishes every plan update and repair as it is
/// recorded in the report's timeline (a `Text` holding the entry's JSON), so that a recorder
/// that names [`UPDATES_DATA`] keeps them in the run's MCAP recording.
pub const UPDATES_OUTPUT: &str = "updates";
/// [`UPDATES_OUTPUT`]'s data name: the only data the access lists let the run's node publish.
pub const UPDATES_DATA: &str = "armor-run.updates";
/// How often the line is redrawn.
const DRAW_PERIOD: Duration = Duration::from_millis(200);
/// How long the end of a run waits, in real time, for the true poses that settle the last
/// arrivals (those at or after each arrival's time): they are in flight when the mission ends.
const SETTLE_WAIT: Duration = Duration::from_secs(2);

/// One leg as planned, in run seconds from the run's start date.
#[derive(Clone, Debug)]
pub struct LegPlan {
    pub name: String,
    pub from: String,
    pub to: String,
    /// Where `to` is, in the world frame.
    pub target: Option<Point>,
    pub route: Vec<Point>,
    /// Its appointment: not to set off before.
    pub not_before_secs: Option<f64>,
    /// Its deadline: to arrive by.
    pub deadline_secs: Option<f64>,
    /// The transitions that switch its actions to an alternative, each with what it says
    /// (`switched to `odometry`: `mapper` failed`).
    pub switches: Vec<(String, String)>,
}

/// The legs of `plan` with the routes `compiled` planned, `start_unix_secs` being the date the
/// run starts at.
pub fn leg_plans(plan: &Plan, compiled: &Compiled, start_unix_secs: f64) -> Vec<LegPlan> {
    plan.legs
        .iter()
        .enumerate()
        .map(|(index, leg)| LegPlan {
            name: leg.name.clone(),
            from: leg.from.clone(),
            to: leg.to.clone(),
            target: compiled.positions.get(&leg.to).copied(),
            route: compiled.routes.get(index).cloned().unwrap_or_default(),
            not_before_secs: leg.not_before_unix_secs.map(|at| at - start_unix_secs),
            deadline_secs: leg.arrive_by_unix_secs.map(|at| at - start_unix_secs),
            switches: compiled
                .switches
                .iter()
                .filter(|(_, switch)| switch.leg == index)
                .map(|(transition, switch)| {
                    (
                        transition.clone(),
                        format!("switched to `{}`: `{}` failed", switch.to, switch.module),
                    )
                })
                .collect(),
        })
        .collect()
}

/// Where the mission stands, from the controller's first markings and firings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stage {
    /// No leg has set off yet.
    Starting,
    /// Driving leg `index`.
    Driving(usize),
    /// Leg `index` arrived and the next has not set off.
    After(usize),
}

/// The stage of a run of `legs`, given when each leg's drive place was first marked and when it
/// first arrived.
pub fn stage(legs: &[LegPlan], started: &[Option<f64>], arrived: &[Option<f64>]) -> Stage {
    let mut stage = Stage::Starting;
    for index in 0..legs.len() {
        match (
            started.get(index).copied().flatten(),
            arrived.get(index).copied().flatten(),
        ) {
            (Some(_), None) => stage = Stage::Driving(index),
            (_, Some(_)) => stage = Stage::After(index),
            (None, None) => {}
        }
    }
    stage
}

/// The length of `route` still to drive from `at`: from the point of the route nearest to it
/// on to the end.
pub fn remaining_m(route: &[Point], at: Point) -> f64 {
    let Some((&last, _)) = route.split_last() else {
        return 0.0;
    };
    if route.len() == 1 {
        return at.distance(last);
    }
    let (segment, _) = route
        .windows(2)
        .enumerate()
        .map(|(index, pair)| (index, geo::segment_distance(at, pair[0], pair[1])))
        .fold((0, f64::INFINITY), |best, candidate| {
            if candidate.1 < best.1 {
                candidate
            } else {
                best
            }
        });
    let (a, b) = (route[segment], route[segment + 1]);
    let along = b.distance(a);
    let t = if along > 0.0 {
        (((at.x - a.x) * (b.x - a.x) + (at.y - a.y) * (b.y - a.y)) / (along * along))
            .clamp(0.0, 1.0)
    } else {
        0.0
    };
    along * (1.0 - t) + geo::path_length(&route[segment + 1..])
}

/// How the leg being driven stands at run time `now_secs`, if one is: `left_m` is the
/// distance left on it when the robot's position is known; `speed_mps` is the plan's, for the
/// slack (the time left, less the time the distance left takes at that speed). The live line
/// and the run's status (`armor ctl status`, the studio's Run view) both say these numbers.
pub fn leg_progress(
    legs: &[LegPlan],
    stage: Stage,
    now_secs: f64,
    left_m: Option<f64>,
    speed_mps: f64,
) -> Option<LegProgress> {
    let Stage::Driving(index) = stage else {
        return None;
    };
    let leg = legs.get(index)?;
    let time_left_secs = leg.deadline_secs.map(|deadline| deadline - now_secs);
    Some(LegProgress {
        number: index + 1,
        legs: legs.len(),
        leg: leg.name.clone(),
        from: leg.from.clone(),
        to: leg.to.clone(),
        left_m,
        deadline_run_secs: leg.deadline_secs,
        time_left_secs,
        slack_secs: time_left_secs
            .zip(left_m)
            .map(|(time_left, left)| time_left - left / speed_mps),
    })
}

/// The live line: what the robot does, what it must do next by when, and the run time.
/// `left_m` and `speed_mps` are [`leg_progress`]'s.
pub fn status_line(
    legs: &[LegPlan],
    stage: Stage,
    now_secs: f64,
    left_m: Option<f64>,
    speed_mps: f64,
) -> String {
    let count = legs.len();
    let mut parts = Vec::new();
    let next_index = match stage {
        Stage::Starting => {
            parts.push("starting".to_owned());
            0
        }
        Stage::Driving(index) => {
            if let Some(progress) = leg_progress(legs, stage, now_secs, left_m, speed_mps) {
                let mut part = format!(
                    "leg {}/{count} {} ({} → {})",
                    progress.number, progress.leg, progress.from, progress.to
                );
                if let Some(left) = progress.left_m {
                    part.push_str(&format!(": {left:.1} m left"));
                }
                parts.push(part);
                if let (Some(deadline), Some(time_left)) =
                    (progress.deadline_run_secs, progress.time_left_secs)
                {
                    let mut part = format!("arrive at {} by {deadline:.1} s: ", progress.to);
                    if time_left >= 0.0 {
                        part.push_str(&format!("{time_left:.1} s left"));
                    } else {
                        part.push_str(&format!("{:.1} s late", -time_left));
                    }
                    if let Some(slack) = progress.slack_secs {
                        part.push_str(&format!(", slack {slack:.1} s"));
                    }
                    parts.push(part);
                }
            }
            index + 1
        }
        Stage::After(index) => {
            parts.push(format!(
                "at {} after leg {}/{count}",
                legs[index].to,
                index + 1
            ));
            index + 1
        }
    };
    if !matches!(stage, Stage::Driving(index) if legs[index].deadline_secs.is_some())
        && let Some(next) = legs.get(next_index)
    {
        match next.not_before_secs {
            Some(at) if at > now_secs => parts.push(format!(
                "{} sets off at {at:.1} s, in {:.1} s",
                next.name,
                at - now_secs
            )),
            _ if matches!(stage, Stage::Driving(_)) => {}
            _ => parts.push(format!("next: {}", next.name)),
        }
    }
    parts.push(format!("run {now_secs:.1} s"));
    parts.join(" · ")
}

/// Where the robot is and how far it has driven, written by the run's node.
#[derive(Clone, Copy, Debug, Default)]
struct Odometer {
    at: Option<Point>,
    travelled_m: f64,
}

/// What the closing table adds for each leg.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LegExtras {
    /// Driven while the leg was under way, by odometry; `None` without odometry.
    pub driven_m: Option<f64>,
    /// `MODULE.EVENT` names reported while it was under way, in order.
    pub events: Vec<String>,
}

/// The run's progress: the line drawn, and the extras of each leg.
pub struct Progress {
    legs: Vec<LegPlan>,
    speed_mps: f64,
    bar: ProgressBar,
    odometer: Option<Arc<Mutex<Odometer>>>,
    /// The rehearsal's judge, in a simulated run.
    judge: Option<Arc<Mutex<Judge>>>,
    stop: Arc<AtomicBool>,
    node: Option<std::thread::JoinHandle<()>>,
    /// What the node publishes on [`UPDATES_DATA`].
    records: Option<std::sync::mpsc::Sender<String>>,
    /// The odometer when each leg set off and arrived.
    odo_started: Vec<Option<f64>>,
    odo_arrived: Vec<Option<f64>>,
    started: Vec<Option<f64>>,
    arrived: Vec<Option<f64>>,
    extras: Vec<LegExtras>,
    /// The leg being driven as the latest tick found it, for the run's status.
    latest: Option<LegProgress>,
    next_draw: Instant,
}

/// What the run's node watches: the robot's odometry and, in a simulated run, its true pose
/// (data names), through the run's agent.
pub struct Watch {
    pub agent: SocketAddr,
    pub secret_file: Option<PathBuf>,
    pub odometry: Option<String>,
    /// The simulator's true pose and the judge it feeds.
    pub truth: Option<(String, Judge)>,
}

impl Progress {
    /// Starts the line on standard error (drawn only if it is a terminal) and, with `watch`,
    /// the node that follows the robot's odometry and true pose.
    pub fn start(legs: Vec<LegPlan>, speed_mps: f64, watch: Watch) -> Progress {
        let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::stderr_with_hz(5));
        bar.set_style(
            ProgressStyle::with_template("{spinner} {wide_msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        if !bar.is_hidden() {
            console::show_bar(Some(bar.clone()));
        }
        let stop = Arc::new(AtomicBool::new(false));
        let mut node = None;
        let mut records = None;
        let odometer = watch
            .odometry
            .as_ref()
            .map(|_| Arc::new(Mutex::new(Odometer::default())));
        let Watch {
            agent,
            secret_file,
            odometry,
            truth,
        } = watch;
        let (truth, judge) = match truth {
            Some((name, judge)) => (Some(name), Some(Arc::new(Mutex::new(judge)))),
            None => (None, None),
        };
        if odometry.is_some() || truth.is_some() {
            let shared = Shared {
                odometer: odometer.clone(),
                judge: judge.clone(),
            };
            let stop = Arc::clone(&stop);
            let names = Names { odometry, truth };
            let (sender, updates) = std::sync::mpsc::channel();
            records = Some(sender);
            node = Some(std::thread::spawn(move || {
                if let Err(err) = follow(agent, secret_file, &names, &shared, &updates, &stop) {
                    // Without the truth the judge has no pose and says so in the verdict.
                    tracing::warn!("the run's node cannot follow the robot: {err:#}");
                }
            }));
        }
        let count = legs.len();
        Progress {
            legs,
            speed_mps,
            bar,
            odometer,
            judge,
            stop,
            node,
            records,
            odo_started: vec![None; count],
            odo_arrived: vec![None; count],
            started: vec![None; count],
            arrived: vec![None; count],
            extras: vec![LegExtras::default(); count],
            latest: None,
            next_draw: Instant::now(),
        }
    }

    fn odometer(&self) -> Odometer {
        self.odometer
            .as_ref()
            .map_or_else(Odometer::default, |shared| {
                *shared.lock().unwrap_or_else(PoisonError::into_inner)
            })
    }

    /// Where the run's node publishes the records of the updates and repairs
    /// ([`UPDATES_DATA`]); none when the run has no node (nothing followed).
    pub fn records(&self) -> Option<std::sync::mpsc::Sender<String>> {
        self.records.clone()
    }

    /// Where the robot believes it is (its odometry's latest pose), if the run's node has it.
    pub fn robot_at(&self) -> Option<Point> {
        self.odometer().at
    }

    /// The plan was updated while it ran: its legs are now `legs` and its no-go areas `areas`.
    /// What each leg of the same name did so far (set off, arrived, driven, its events) is
    /// kept; a leg not arrived yet is judged, when it arrives, against its new waypoint.
    pub fn update(&mut self, legs: Vec<LegPlan>, areas: Vec<NoGoArea>) {
        let before = |index: Option<usize>, values: &[Option<f64>]| {
            index.and_then(|index| values.get(index).copied().flatten())
        };
        let old = std::mem::take(&mut self.legs);
        let position = |name: &str| old.iter().position(|leg| leg.name == name);
        let mut extras = Vec::with_capacity(legs.len());
        let (mut odo_started, mut odo_arrived, mut started, mut arrived) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for leg in &legs {
            let index = position(&leg.name);
            odo_started.push(before(index, &self.odo_started));
            odo_arrived.push(before(index, &self.odo_arrived));
            started.push(before(index, &self.started));
            arrived.push(before(index, &self.arrived));
            extras.push(
                index
                    .and_then(|index| self.extras.get(index).cloned())
                    .unwrap_or_default(),
            );
        }
        self.legs = legs;
        self.odo_started = odo_started;
        self.odo_arrived = odo_arrived;
        self.started = started;
        self.arrived = arrived;
        self.extras = extras;
        if let Some(judge) = &self.judge {
            judge
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .set_areas(areas);
        }
    }

    /// Takes in the controller's first markings and firings at run time `now_secs`, and redraws
    /// the line when it is due.
    pub fn tick(
        &mut self,
        now_secs: f64,
        first_marked: &BTreeMap<String, f64>,
        first_fired: &BTreeMap<String, f64>,
    ) {
        let odometer = self.odometer();
        let travelled = self.odometer.as_ref().map(|_| odometer.travelled_m);
        for (index, leg) in self.legs.iter().enumerate() {
            if self.started[index].is_none() {
                self.started[index] = first_marked.get(&format!("{}_drive", leg.name)).copied();
                if self.started[index].is_some() {
                    self.odo_started[index] = travelled;
                }
            }
            if self.arrived[index].is_none() {
                let arrived = format!("{}_arrived", leg.name);
                self.arrived[index] = first_fired
                    .iter()
                    .filter(|(name, _)| name.starts_with(&arrived))
                    .map(|(_, at)| *at)
                    .reduce(f64::min);
                if let Some(at_secs) = self.arrived[index] {
                    self.odo_arrived[index] = travelled;
                    if let (Some(judge), Some(target)) = (&self.judge, leg.target) {
                        judge
                            .lock()
                            .unwrap_or_else(PoisonError::into_inner)
                            .arrived(Arrival {
                                leg: leg.name.clone(),
                                waypoint: leg.to.clone(),
                                target,
                                at_secs,
                            });
                    }
                }
            }
        }
        let stage = stage(&self.legs, &self.started, &self.arrived);
        let left = match (stage, odometer.at) {
            (Stage::Driving(index), Some(at)) => Some(remaining_m(&self.legs[index].route, at)),
            _ => None,
        };
        // Worked out at every tick, terminal or not: a studio that runs `armor run` reads it
        // from the status.
        self.latest = leg_progress(&self.legs, stage, now_secs, left, self.speed_mps);
        let now = Instant::now();
        if now < self.next_draw || self.bar.is_hidden() {
            return;
        }
        self.next_draw = now + DRAW_PERIOD;
        self.bar.set_message(status_line(
            &self.legs,
            stage,
            now_secs,
            left,
            self.speed_mps,
        ));
        self.bar.tick();
    }

    /// The leg being driven, as the latest tick found it.
    pub fn leg_progress(&self) -> Option<LegProgress> {
        self.latest.clone()
    }

    /// A module reported `name` (`MODULE.EVENT`): kept with the leg under way.
    pub fn on_event(&mut self, name: &str) {
        if let Stage::Driving(index) = stage(&self.legs, &self.started, &self.arrived) {
            self.extras[index].events.push(name.to_owned());
        }
    }

    /// Clears the line and stops the node (before the agent goes); returns each leg's extras
    /// and, in a simulated run, the rehearsal's verdict.
    pub fn finish(mut self) -> (Vec<LegExtras>, Option<Verdict>) {
        if let Some(judge) = &self.judge {
            let deadline = Instant::now() + SETTLE_WAIT;
            while !judge
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .settled()
                && Instant::now() < deadline
                && self.node.as_ref().is_some_and(|node| !node.is_finished())
            {
                std::thread::sleep(Duration::from_millis(10));
            }
        }
        self.stop.store(true, Ordering::Relaxed);
        if let Some(node) = self.node.take() {
            // It looks at `stop` ten times a second; one still waiting for the agent is left.
            let deadline = Instant::now() + Duration::from_secs(1);
            while !node.is_finished() && Instant::now() < deadline {
                std::thread::sleep(Duration::from_millis(10));
            }
            if node.is_finished() {
                let _ = node.join();
            }
        }
        console::show_bar(None);
        self.bar.finish_and_clear();
        let travelled = self.odometer.as_ref().map(|_| self.odometer().travelled_m);
        for (index, extras) in self.extras.iter_mut().enumerate() {
            extras.driven_m = match (self.odo_started[index], self.odo_arrived[index]) {
                (Some(from), Some(to)) => Some(to - from),
                (Some(from), None) => travelled.map(|now| now - from),
                _ => None,
            };
        }
        let verdict = self.judge.as_ref().map(|judge| {
            judge
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .verdict()
        });
        (std::mem::take(&mut self.extras), verdict)
    }
}

/// The data names the run's node follows.
struct Names {
    odometry: Option<String>,
    truth: Option<String>,
}

/// Where the run's node writes what it follows.
struct Shared {
    odometer: Option<Arc<Mutex<Odometer>>>,
    judge: Option<Arc<Mutex<Judge>>>,
}

/// The run's node: follows the odometry and the true pose named by `names` into `shared`
/// until `stop`. The odometry is only for the line and the distances driven, a few samples a
/// second are enough; the truth is evidence, so every sample is taken (a reliable input).
fn follow(
    agent: SocketAddr,
    secret_file: Option<PathBuf>,
    names: &Names,
    shared: &Shared,
    updates: &std::sync::mpsc::Receiver<String>,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let mut node = Node::connect(
        ModuleSpec::new(
            NODE_NAME,
            "`armor run`'s progress line and rehearsal judge.",
        )
        .output::<Text>(
            UPDATES_OUTPUT,
            "every plan update and repair, as the report's timeline has it (JSON)",
        ),
        Standalone {
            name: Some(NODE_NAME.to_owned()),
            agent: Some(agent.to_string()),
            secret: secret_file,
            ..Standalone::default()
        },
    )?;
    let odometry = match (&names.odometry, &shared.odometer) {
        (Some(name), Some(odometer)) => Some((node.subscribe_raw_at_most(name, 20.0)?, odometer)),
        _ => None,
    };
    let truth = match (&names.truth, &shared.judge) {
        (Some(name), Some(judge)) => Some((node.subscribe_raw(name, true)?, judge)),
        _ => None,
    };
    let records = node.output::<Text>(UPDATES_OUTPUT)?;
    let mut poses = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        while let Ok(entry) = updates.try_recv() {
            node.send(&records, &Text(entry))?;
        }
        if let Event::Input(_) = node.next_event(Some(Duration::from_millis(100)))? {
            if let Some((input, shared)) = &odometry {
                while let Some(sample) = node.take_raw(input) {
                    let Ok(odometry) = Odometry::decode(&sample.payload) else {
                        continue;
                    };
                    let pose = odometry.pose_in_odom;
                    let at = Point::new(pose.x_m, pose.y_m);
                    if !at.is_finite() {
                        continue;
                    }
                    let mut odometer = shared.lock().unwrap_or_else(PoisonError::into_inner);
                    if let Some(before) = odometer.at {
                        odometer.travelled_m += before.distance(at);
                    }
                    odometer.at = Some(at);
                }
            }
            if let Some((input, judge)) = &truth {
                // Taken off the input first, then judged under one lock.
                while let Some(sample) = node.take_raw(input) {
                    if let Ok(pose) = Pose2D::decode(&sample.payload) {
                        poses.push(TruePose {
                            at_secs: sample.stamp_ns as f64 / 1e9,
                            at: Point::new(pose.x_m, pose.y_m),
                        });
                    }
                }
                if !poses.is_empty() {
                    let mut judge = judge.lock().unwrap_or_else(PoisonError::into_inner);
                    for pose in poses.drain(..) {
                        judge.observe(pose);
                    }
                }
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn leg(
        name: &str,
        route: &[(f64, f64)],
        not_before: Option<f64>,
        deadline: Option<f64>,
    ) -> LegPlan {
        LegPlan {
            name: name.to_owned(),
            from: "a".to_owned(),
            to: format!("{name}_end"),
            target: None,
            route: route.iter().map(|&(x, y)| Point::new(x, y)).collect(),
            not_before_secs: not_before,
            deadline_secs: deadline,
            switches: Vec::new(),
        }
    }

    #[test]
    fn the_distance_left_runs_from_the_nearest_point_of_the_route() {
        let route = [
            Point::new(0.0, 0.0),
            Point::new(10.0, 0.0),
            Point::new(10.0, 10.0),
        ];
        assert!((remaining_m(&route, Point::new(0.0, 0.0)) - 20.0).abs() < 1e-9);
        assert!((remaining_m(&route, Point::new(4.0, 1.0)) - 16.0).abs() < 1e-9);
        assert!((remaining_m(&route, Point::new(11.0, 5.0)) - 5.0).abs() < 1e-9);
        assert!(remaining_m(&route, Point::new(10.0, 10.0)).abs() < 1e-9);
        assert!((remaining_m(&[Point::new(3.0, 4.0)], Point::new(0.0, 0.0)) - 5.0).abs() < 1e-9);
        assert_eq!(remaining_m(&[], Point::new(1.0, 1.0)), 0.0);
    }

    #[test]
    fn the_stage_follows_set_offs_and_arrivals() {
        let legs = [leg("a", &[], None, None), leg("b", &[], None, None)];
        assert_eq!(stage(&legs, &[None, None], &[None, None]), Stage::Starting);
        assert_eq!(
            stage(&legs, &[Some(1.0), None], &[None, None]),
            Stage::Driving(0)
        );
        assert_eq!(
            stage(&legs, &[Some(1.0), None], &[Some(9.0), None]),
            Stage::After(0)
        );
        assert_eq!(
            stage(&legs, &[Some(1.0), Some(10.0)], &[Some(9.0), None]),
            Stage::Driving(1)
        );
    }

    #[test]
    fn the_line_gives_the_leg_the_distance_left_and_the_slack() {
        let legs = [
            leg("advance", &[(0.0, 0.0), (20.0, 0.0)], None, Some(60.0)),
            leg("cross", &[(20.0, 0.0), (20.0, 10.0)], Some(65.5), None),
        ];
        let line = status_line(&legs, Stage::Driving(0), 40.0, Some(5.0), 0.5);
        assert_eq!(
            line,
            "leg 1/2 advance (a → advance_end): 5.0 m left · arrive at advance_end by 60.0 s: \
             20.0 s left, slack 10.0 s · run 40.0 s"
        );
        let late = status_line(&legs, Stage::Driving(0), 62.5, None, 0.5);
        assert!(late.contains("by 60.0 s: 2.5 s late"), "{late}");
        let waiting = status_line(&legs, Stage::After(0), 61.0, None, 0.5);
        assert_eq!(
            waiting,
            "at advance_end after leg 1/2 · cross sets off at 65.5 s, in 4.5 s · run 61.0 s"
        );
        let starting = status_line(&legs, Stage::Starting, 0.3, None, 0.5);
        assert_eq!(starting, "starting · next: advance · run 0.3 s");
    }

    #[test]
    fn the_status_carries_the_numbers_of_the_line() {
        let legs = [
            leg("advance", &[(0.0, 0.0), (20.0, 0.0)], None, Some(60.0)),
            leg("cross", &[(20.0, 0.0), (20.0, 10.0)], Some(65.5), None),
        ];
        assert_eq!(
            leg_progress(&legs, Stage::Driving(0), 40.0, Some(5.0), 0.5),
            Some(LegProgress {
                number: 1,
                legs: 2,
                leg: "advance".to_owned(),
                from: "a".to_owned(),
                to: "advance_end".to_owned(),
                left_m: Some(5.0),
                deadline_run_secs: Some(60.0),
                time_left_secs: Some(20.0),
                slack_secs: Some(10.0),
            })
        );
        let late = leg_progress(&legs, Stage::Driving(0), 62.5, Some(3.0), 0.5).unwrap();
        assert_eq!(
            (late.time_left_secs, late.slack_secs),
            (Some(-2.5), Some(-8.5))
        );
        // No deadline, no time left nor slack; no position, no distance.
        let cross = leg_progress(&legs, Stage::Driving(1), 70.0, None, 0.5).unwrap();
        assert_eq!(
            (
                cross.number,
                cross.left_m,
                cross.time_left_secs,
                cross.slack_secs
            ),
            (2, None, None, None)
        );
        assert_eq!(leg_progress(&legs, Stage::After(0), 61.0, None, 0.5), None);
        assert_eq!(leg_progress(&legs, Stage::Starting, 0.3, None, 0.5), None);
    }
}
