//! `avoider`: reactive obstacle avoidance and safety stop, after the virtual force field (VFF)
//! of the JDE schemas.
//!
//! The desired command is read as a direction of travel: straight ahead turned by what the
//! desired turning speed would turn in one second. Every laser point closer than `influence_m`
//! in the front half pushes the robot away from it, the more the closer it is; the direction to
//! follow is the desired direction plus `gain` times that repulsion. The avoider turns by the
//! difference between the two directions, and slows down in proportion to the clearance left in
//! the robot's path (the corridor as wide as the robot). With an obstacle closer than `stop_m`
//! in that path it commands no forward speed at all (turning is still allowed) and reports
//! `safety_stop`. Without a scan for 0.5 s of run time, or without a desired command for as long,
//! it commands zero.

use std::f64::consts::FRAC_PI_2;

use armor_module_api::types::{Frame, LaserScan, Marker, Markers, Shape, Twist};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use super::{finite_or_zero, sanitized, wrap_angle};
use crate::BodyError;
use crate::params::float_where;

pub const TYPE: &str = "avoider";

/// A scan or a desired command older than this (run time) is no longer trusted: zero command.
pub const STALE_SECS: f64 = 0.5;
/// How often, in run time, the avoider checks for stale inputs when nothing arrives.
const TICK_SECS: f64 = 0.1;
/// The desired direction is where the desired turning speed would point the robot after this
/// long (and the correction is turned into a turning speed over as long).
const LOOKAHEAD_SECS: f64 = 1.0;
/// The avoider turns no faster than this (the robot's limit), unless asked to.
const MAX_TURN_RADPS: f64 = 1.5;
/// Clearances below this count as this, so that a point at the robot's edge repels strongly
/// but finitely.
const MIN_CLEARANCE_M: f64 = 0.05;
/// Desired forward speeds below this are steered away from obstacles in proportion (turning
/// on the spot is left alone); the slow-down and the stop still guard the robot's path.
const FULL_STEERING_MPS: f64 = 0.2;
/// The resulting direction keeps at least this forward component (or the desired one, if
/// smaller): obstacles ahead on both sides slow the robot down instead of turning it round.
const MIN_FORWARD: f64 = 0.2;
/// A stop counts as released only once the way it held back is this much clearer than
/// `stop_m`. Range noise and a desired command that alternates between turning on the spot
/// and moving on would otherwise engage and release it at every scan.
pub const RELEASE_MARGIN_M: f64 = 0.1;

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Reactive obstacle avoidance and safety stop (virtual force field): bends the desired \
         command away from close laser points, slows down before obstacles in the robot's path, \
         stops forward motion when one is closer than stop_m, and stops without fresh scans.",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .input::<LaserScan>(
        "scan",
        "laser scan in the robot's frame (angle 0 straight ahead, counter-clockwise positive); \
         without one for 0.5 s of run time the avoider commands zero",
    )
    .input::<Twist>(
        "cmd_desired",
        "the command to follow when the way is free (without one for 0.5 s of run time the \
         avoider commands zero)",
    )
    .output::<Markers>(
        "markers",
        "its view, ten times a second of run time: the total repulsive force and the robot's \
         path ahead up to the nearest obstacle in it, red while the stop holds (robot frame)",
    )
    .output::<Twist>(
        "cmd_vel",
        "the safe command: one per desired command, and one zero when an input goes stale or \
         the module is stopped (never NaN)",
    )
    .param(
        ParamSpec::new(
            "influence_m",
            ParamType::Float,
            "obstacles closer than this repel the robot and slow it down (greater than stop_m)",
        )
        .above(0.0)
        .unit("m")
        .default("1.2"),
    )
    .param(
        ParamSpec::new(
            "stop_m",
            ParamType::Float,
            "an obstacle this close in the robot's path stops forward (or backward) motion; \
             turning is still allowed (greater than 0)",
        )
        .above(0.0)
        .unit("m")
        .default("0.35"),
    )
    .param(
        ParamSpec::new(
            "gain",
            ParamType::Float,
            "weight of the repulsion against the desired direction (0 or more; 0 only slows \
             down and stops)",
        )
        .min(0.0)
        .default("1.0"),
    )
    .param(
        ParamSpec::new(
            "robot_radius_m",
            ParamType::Float,
            "half the width of the robot's path, checked for obstacles (0 or more)",
        )
        .min(0.0)
        .unit("m")
        .default("0.25"),
    )
    .event(
        "safety_stop",
        "the stop engaged: an obstacle closer than stop_m in the robot's path, or scans stopped \
         coming or became unusable (once per stop: it releases when that way is 0.1 m clearer \
         than stop_m, or usable scans come again)",
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let scan_input = node.input::<LaserScan>("scan")?;
    let desired_input = node.input::<Twist>("cmd_desired")?;
    let output = node.output::<Twist>("cmd_vel")?;
    let markers = node.output::<Markers>("markers")?;
    let mut avoider = Avoider::new(Settings::read(node)?);
    let mut next_tick = node.timestamp() + TICK_SECS;
    loop {
        let event = if node.is_active() {
            let deadline = node.clock().instant_at(next_tick);
            node.next_event_until(deadline)?
        } else {
            node.next_event(None)?
        };
        match event {
            Event::Input(port) if port == scan_input.id() => {
                if let Some(sample) = node.take(&scan_input)? {
                    avoider.on_scan(sample.value, node.timestamp());
                }
            }
            Event::Input(port) if port == desired_input.id() => {
                let Some(sample) = node.take(&desired_input)? else {
                    continue;
                };
                if node.is_active() {
                    let output_now = avoider.on_desired(sample.value, node.timestamp());
                    node.send(&output, &output_now.twist)?;
                    if let Some(event) = output_now.report {
                        node.report(event)?;
                    }
                }
            }
            Event::Timeout if node.is_active() => {
                let now = node.timestamp();
                next_tick = now + TICK_SECS;
                if let Some(output_now) = avoider.on_tick(now) {
                    node.send(&output, &output_now.twist)?;
                    if let Some(event) = output_now.report {
                        node.report(event)?;
                    }
                }
                if let Some(drawn) = avoider.markers(now) {
                    node.send(&markers, &drawn)?;
                }
            }
            Event::Start => {
                tracing::info!("active");
                avoider.stops = Stops::default();
                next_tick = node.timestamp() + TICK_SECS;
            }
            Event::Stop => {
                tracing::info!("inactive: stopping");
                node.send(&output, &Twist::default())?;
            }
            Event::ParamsChanged(_) => match Settings::read(node) {
                Ok(settings) => avoider.settings = settings,
                Err(err) => tracing::error!("{err}; keeping the previous settings"),
            },
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

/// The avoider's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub influence_m: f64,
    pub stop_m: f64,
    pub gain: f64,
    pub robot_radius_m: f64,
}

impl Settings {
    fn read(node: &Node) -> Result<Self, BodyError> {
        let stop_m = node.param::<f64>("stop_m")?;
        Ok(Self {
            influence_m: float_where(
                node,
                "influence_m",
                |value| value > stop_m,
                &format!("greater than stop_m ({stop_m} m)"),
            )?,
            stop_m,
            gain: node.param::<f64>("gain")?,
            robot_radius_m: node.param::<f64>("robot_radius_m")?,
        })
    }
}

/// A command to publish, and the event to report, if any.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Output {
    twist: Twist,
    report: Option<&'static str>,
}

/// Which stops are engaged. Each is reported when it engages and releases with hysteresis
/// (see [`Stops::track`]), so that one obstacle gives one `safety_stop`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Stops {
    /// An obstacle in the robot's path ahead held forward motion back.
    ahead: bool,
    /// ... behind, backward motion.
    behind: bool,
    /// No fresh, usable scan: everything held back.
    blind: bool,
}

impl Stops {
    /// Updates the stops with one decision; `safety_stop` if one engaged.
    fn track(&mut self, settings: &Settings, decision: &Decision) -> Option<&'static str> {
        let was = *self;
        match decision.clearance_m {
            None => self.blind = decision.stopped,
            Some((ahead_m, behind_m)) => {
                let release_m = settings.stop_m + RELEASE_MARGIN_M;
                self.blind = false;
                self.ahead = decision.held_ahead || (self.ahead && ahead_m < release_m);
                self.behind = decision.held_behind || (self.behind && behind_m < release_m);
            }
        }
        let engaged = (self.ahead && !was.ahead)
            || (self.behind && !was.behind)
            || (self.blind && !was.blind);
        engaged.then_some("safety_stop")
    }
}

/// The latest inputs and the state of the stop, on run time.
#[derive(Clone, Debug)]
struct Avoider {
    settings: Settings,
    scan: Option<(LaserScan, f64)>,
    /// When the latest desired command arrived.
    desired_at: Option<f64>,
    stops: Stops,
    /// A zero command was published because an input went stale.
    stale_published: bool,
}

impl Avoider {
    fn new(settings: Settings) -> Self {
        Self {
            settings,
            scan: None,
            desired_at: None,
            stops: Stops::default(),
            stale_published: false,
        }
    }

    /// Its view of the latest fresh scan: the total repulsion (an arrow from the robot, one
    /// metre per unit of force) and the corridor ahead up to the nearest obstacle in it.
    fn markers(&self, now: f64) -> Option<Markers> {
        let (scan, _) = self.scan.as_ref().filter(|_| self.scan_is_fresh(now))?;
        let around = survey(&self.settings, scan)?;
        let held = self.stops.ahead || self.stops.behind;
        let corridor_rgba = if held {
            [220, 40, 40, 200]
        } else {
            [120, 120, 200, 120]
        };
        let radius = self.settings.robot_radius_m;
        let length = around.clearance_ahead_m.min(self.settings.influence_m);
        let (x, y) = around.repulsion;
        Some(Markers {
            markers: vec![
                Marker::new(
                    Shape::Polygon,
                    Frame::Robot,
                    corridor_rgba,
                    [
                        (0.0, -radius),
                        (length, -radius),
                        (length, radius),
                        (0.0, radius),
                    ],
                )
                .with_text("path ahead"),
                Marker::new(
                    Shape::Arrows,
                    Frame::Robot,
                    [220, 40, 200, 230],
                    [(0.0, 0.0), (x, y)],
                )
                .with_text("repulsion"),
            ],
        })
    }

    fn on_scan(&mut self, scan: LaserScan, now: f64) {
        self.scan = Some((scan, now));
    }

    fn scan_is_fresh(&self, now: f64) -> bool {
        self.scan
            .as_ref()
            .is_some_and(|(_, at)| now - at <= STALE_SECS)
    }

    fn on_desired(&mut self, desired: Twist, now: f64) -> Output {
        self.desired_at = Some(now);
        self.stale_published = false;
        let decision = match &self.scan {
            Some((scan, _)) if self.scan_is_fresh(now) => avoid(&self.settings, scan, desired),
            Some(_) => {
                if !self.stops.blind {
                    tracing::warn!("no scan for {STALE_SECS} s: stopping");
                }
                Decision::blind()
            }
            // Waiting for a first scan is no safety event.
            None => {
                return Output {
                    twist: Twist::default(),
                    report: None,
                };
            }
        };
        Output {
            twist: decision.twist,
            report: self.stops.track(&self.settings, &decision),
        }
    }

    /// With no input for a while: one zero command when the scan or the desired command goes
    /// stale.
    fn on_tick(&mut self, now: f64) -> Option<Output> {
        let desired_fresh = self.desired_at.is_some_and(|at| now - at <= STALE_SECS);
        let scan_lost = self.scan.is_some() && !self.scan_is_fresh(now);
        if self.desired_at.is_none() || self.stale_published {
            return None;
        }
        if desired_fresh && !scan_lost {
            return None;
        }
        self.stale_published = true;
        let report = if scan_lost {
            if !self.stops.blind {
                tracing::warn!("no scan for {STALE_SECS} s: stopping");
            }
            self.stops.track(&self.settings, &Decision::blind())
        } else {
            None
        };
        Some(Output {
            twist: Twist::default(),
            report,
        })
    }
}

/// The safe command, and whether the stop held it back.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Decision {
    twist: Twist,
    /// The stop held some motion back (either way, or for want of a usable scan).
    stopped: bool,
    held_ahead: bool,
    held_behind: bool,
    /// The clearance in the robot's path ahead and behind, if the scan was usable.
    clearance_m: Option<(f64, f64)>,
}

impl Decision {
    /// Nothing usable to go by: stop.
    fn blind() -> Self {
        Self {
            twist: Twist::default(),
            stopped: true,
            held_ahead: false,
            held_behind: false,
            clearance_m: None,
        }
    }
}

/// What the scan says around the robot.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Surroundings {
    /// Sum of the repulsions of the close points in the front half (robot frame).
    repulsion: (f64, f64),
    /// The nearest point in the robot's path ahead and behind (infinite if none).
    clearance_ahead_m: f64,
    clearance_behind_m: f64,
}

/// Sums up the scan's valid points: finite, positive ranges short of `range_max_m`. `None` if
/// the beams' angles are not finite numbers (the scan says nothing usable).
fn survey(settings: &Settings, scan: &LaserScan) -> Option<Surroundings> {
    let mut around = Surroundings {
        repulsion: (0.0, 0.0),
        clearance_ahead_m: f64::INFINITY,
        clearance_behind_m: f64::INFINITY,
    };
    let step = scan.angle_increment_rad;
    if !scan.angle_min_rad.is_finite() || !step.is_finite() {
        return None;
    }
    // Each point stands for the arc its beam covers, so the sum does not grow with the beam count.
    let arc = step.abs().min(std::f64::consts::TAU);
    for (index, range) in scan.ranges_m.iter().enumerate() {
        let range = f64::from(*range);
        let no_echo = scan.range_max_m.is_finite() && range >= scan.range_max_m;
        if !range.is_finite() || range <= 0.0 || no_echo {
            continue;
        }
        let angle = wrap_angle(scan.angle_min_rad + index as f64 * step);
        let (sin, cos) = angle.sin_cos();
        let (x, y) = (range * cos, range * sin);
        if y.abs() <= settings.robot_radius_m {
            if x > 0.0 {
                around.clearance_ahead_m = around.clearance_ahead_m.min(range);
            } else {
                around.clearance_behind_m = around.clearance_behind_m.min(range);
            }
        }
        if range < settings.influence_m && angle.abs() <= FRAC_PI_2 {
            let clearance = (range - settings.robot_radius_m).max(MIN_CLEARANCE_M);
            let weight = (settings.influence_m - range) / clearance * arc;
            around.repulsion.0 -= weight * cos;
            around.repulsion.1 -= weight * sin;
        }
    }
    Some(around)
}

/// The virtual force field: the desired command bent away from obstacles, slowed down before
/// them, and held back by the stop.
fn avoid(settings: &Settings, scan: &LaserScan, desired: Twist) -> Decision {
    let desired = sanitized(desired);
    let Some(around) = survey(settings, scan) else {
        return Decision::blind();
    };
    let (linear, angular) = (desired.linear_mps, desired.angular_radps);
    let twist = if linear > 0.0 {
        let desired_angle = (angular * LOOKAHEAD_SECS).clamp(-FRAC_PI_2, FRAC_PI_2);
        let (sin, cos) = desired_angle.sin_cos();
        let x = cos + settings.gain * around.repulsion.0;
        let y = sin + settings.gain * around.repulsion.1;
        // Turning on the spot is safe: the slower the desired motion, the less it is corrected.
        let authority = (linear / FULL_STEERING_MPS).min(1.0);
        let correction =
            authority * wrap_angle(y.atan2(x.max(cos.min(MIN_FORWARD))) - desired_angle);
        let angle = desired_angle + correction;
        let limit = angular.abs().max(MAX_TURN_RADPS);
        let room =
            (around.clearance_ahead_m - settings.stop_m) / (settings.influence_m - settings.stop_m);
        // Slower only when sent further off the robot's heading than desired (not when sent
        // straighter, as along a wall the desired command would turn into).
        let heading = if angle.cos() >= cos {
            1.0
        } else {
            angle.cos().max(0.0) / cos
        };
        Twist {
            linear_mps: linear * room.clamp(0.0, 1.0) * heading,
            angular_radps: (angular + correction / LOOKAHEAD_SECS).clamp(-limit, limit),
        }
    } else {
        desired
    };
    let held_ahead = linear > 0.0 && around.clearance_ahead_m < settings.stop_m;
    let held_behind = linear < 0.0 && around.clearance_behind_m < settings.stop_m;
    let stopped = held_ahead || held_behind;
    let twist = Twist {
        linear_mps: if stopped {
            0.0
        } else {
            finite_or_zero(twist.linear_mps)
        },
        angular_radps: finite_or_zero(twist.angular_radps),
    };
    Decision {
        twist,
        stopped,
        held_ahead,
        held_behind,
        clearance_m: Some((around.clearance_ahead_m, around.clearance_behind_m)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};
    use std::f64::consts::{PI, TAU};

    const BEAMS: usize = 360;

    /// A 360-beam scan with nothing in range, starting straight behind.
    fn free_scan() -> LaserScan {
        LaserScan {
            angle_min_rad: -PI,
            angle_increment_rad: TAU / BEAMS as f64,
            range_max_m: 8.0,
            ranges_m: vec![8.0; BEAMS],
        }
    }

    /// The free scan with an obstacle of `width_deg` centred at `bearing_deg`, `range_m` away.
    fn scan_with_obstacle(bearing_deg: f64, width_deg: f64, range_m: f32) -> LaserScan {
        let mut scan = free_scan();
        for (index, range) in scan.ranges_m.iter_mut().enumerate() {
            let angle_deg = -180.0 + index as f64;
            if (angle_deg - bearing_deg).abs() <= width_deg / 2.0 {
                *range = range_m;
            }
        }
        scan
    }

    fn twist(linear_mps: f64, angular_radps: f64) -> Twist {
        Twist {
            linear_mps,
            angular_radps,
        }
    }

    fn scan_step(scan: &LaserScan) -> Step {
        Step::push("scan", scan).expect("step")
    }

    fn desired(linear_mps: f64, angular_radps: f64) -> Step {
        Step::push("cmd_desired", &twist(linear_mps, angular_radps)).expect("step")
    }

    fn run(steps: impl IntoIterator<Item = Step>) -> TestBench {
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        bench.script(steps);
        body(bench.node()).expect("body");
        bench
    }

    fn sent(bench: &TestBench) -> Vec<Twist> {
        bench.sent::<Twist>("cmd_vel").expect("sent")
    }

    fn settings() -> Settings {
        Settings {
            influence_m: 1.2,
            stop_m: 0.35,
            gain: 1.0,
            robot_radius_m: 0.25,
        }
    }

    #[test]
    fn passes_the_desired_command_through_in_free_space() {
        let bench = run([
            scan_step(&free_scan()),
            desired(0.5, 0.0),
            desired(0.4, -0.8),
            desired(0.0, 1.0),
            desired(-0.2, 0.3),
        ]);
        let sent = sent(&bench);
        let expected = [
            twist(0.5, 0.0),
            twist(0.4, -0.8),
            twist(0.0, 1.0),
            twist(-0.2, 0.3),
        ];
        assert_eq!(sent.len(), expected.len());
        for (got, want) in sent.iter().zip(expected) {
            assert!((got.linear_mps - want.linear_mps).abs() < 1e-9, "{sent:?}");
            assert!(
                (got.angular_radps - want.angular_radps).abs() < 1e-9,
                "{sent:?}"
            );
        }
        assert!(bench.reported().is_empty());
    }

    #[test]
    fn turns_away_from_an_obstacle_on_either_side() {
        for (bearing_deg, away) in [(30.0, -1.0), (-30.0, 1.0)] {
            let bench = run([
                scan_step(&scan_with_obstacle(bearing_deg, 20.0, 0.6)),
                desired(0.5, 0.0),
            ]);
            let sent = sent(&bench);
            assert_eq!(sent.len(), 1);
            assert!(
                sent[0].angular_radps * away > 0.2,
                "obstacle at {bearing_deg}°: {sent:?}"
            );
            assert!(
                sent[0].linear_mps > 0.0 && sent[0].linear_mps < 0.5,
                "{sent:?}"
            );
            assert!(bench.reported().is_empty());
        }
    }

    #[test]
    fn obstacles_behind_or_beyond_the_influence_do_not_matter() {
        let settings = settings();
        for scan in [
            scan_with_obstacle(180.0, 60.0, 0.5),
            scan_with_obstacle(0.0, 60.0, 1.3),
        ] {
            let decision = avoid(&settings, &scan, twist(0.5, 0.2));
            assert!(
                (decision.twist.linear_mps - 0.5).abs() < 1e-9,
                "{decision:?}"
            );
            assert!(
                (decision.twist.angular_radps - 0.2).abs() < 1e-9,
                "{decision:?}"
            );
        }
    }

    #[test]
    fn slows_down_before_an_obstacle_in_its_path() {
        let settings = settings();
        let far = avoid(
            &settings,
            &scan_with_obstacle(0.0, 10.0, 1.0),
            twist(0.5, 0.0),
        );
        let near = avoid(
            &settings,
            &scan_with_obstacle(0.0, 10.0, 0.5),
            twist(0.5, 0.0),
        );
        assert!(far.twist.linear_mps < 0.5, "{far:?}");
        assert!(near.twist.linear_mps < far.twist.linear_mps, "{near:?}");
        assert!(!far.stopped && !near.stopped);
    }

    #[test]
    fn side_walls_of_a_corridor_neither_turn_nor_stop_it() {
        let settings = settings();
        let mut scan = free_scan();
        for (index, range) in scan.ranges_m.iter_mut().enumerate() {
            let angle = -PI + index as f64 * TAU / BEAMS as f64;
            let to_wall = 0.5 / angle.sin().abs();
            if to_wall < 8.0 {
                *range = to_wall as f32;
            }
        }
        let decision = avoid(&settings, &scan, twist(0.5, 0.0));
        assert!(decision.twist.angular_radps.abs() < 0.05, "{decision:?}");
        assert!(decision.twist.linear_mps > 0.4, "{decision:?}");
    }

    #[test]
    fn stops_forward_motion_close_to_an_obstacle_ahead_but_still_turns() {
        let blocked = scan_with_obstacle(0.0, 30.0, 0.3);
        let bench = run([
            scan_step(&blocked),
            desired(0.5, 0.4),
            desired(0.5, 0.4),
            desired(0.0, -0.5),
            desired(-0.3, 0.0),
            scan_step(&free_scan()),
            desired(0.5, 0.0),
            scan_step(&blocked),
            desired(0.5, 0.0),
        ]);
        let sent = sent(&bench);
        assert_eq!(sent[0].linear_mps, 0.0, "{sent:?}");
        assert!(
            sent[0].angular_radps.abs() > 0.1,
            "turning allowed: {sent:?}"
        );
        assert_eq!(sent[1].linear_mps, 0.0);
        assert_eq!(
            sent[2],
            twist(0.0, -0.5),
            "turning on the spot is left alone"
        );
        assert_eq!(sent[3], twist(-0.3, 0.0), "backing away is allowed");
        assert!(
            (sent[4].linear_mps - 0.5).abs() < 1e-9,
            "released: {sent:?}"
        );
        assert_eq!(sent[5].linear_mps, 0.0);
        assert_eq!(bench.reported(), ["safety_stop", "safety_stop"]);
    }

    #[test]
    fn one_safety_stop_per_stop_despite_noise_and_turns() {
        // Held in front of a wall whose range reads either side of stop_m, with the follower
        // alternating between turning on the spot and moving on: one stop, not one per scan.
        let mut script = Vec::new();
        for round in 0..50 {
            let range_m = if round % 2 == 0 { 0.34 } else { 0.37 };
            script.push(scan_step(&scan_with_obstacle(0.0, 30.0, range_m)));
            script.push(desired(0.5, 0.0));
            script.push(desired(0.0, 0.8));
        }
        // The way clears by more than the margin, then the wall is back: a second stop.
        script.push(scan_step(&scan_with_obstacle(0.0, 30.0, 0.5)));
        script.push(desired(0.5, 0.0));
        script.push(scan_step(&scan_with_obstacle(0.0, 30.0, 0.3)));
        script.push(desired(0.5, 0.0));
        let bench = run(script);
        assert_eq!(bench.reported(), ["safety_stop", "safety_stop"]);
        let sent = sent(&bench);
        assert_eq!(sent[0].linear_mps, 0.0, "{sent:?}");
        assert!(sent[sent.len() - 2].linear_mps > 0.0, "released: {sent:?}");
        assert_eq!(sent[sent.len() - 1].linear_mps, 0.0);
    }

    #[test]
    fn stops_ahead_behind_and_blind_are_each_reported_once() {
        let mut stops = Stops::default();
        let settings = settings();
        let decide = |range_deg: f64, range_m: f32, linear_mps: f64| {
            avoid(
                &settings,
                &scan_with_obstacle(range_deg, 30.0, range_m),
                twist(linear_mps, 0.0),
            )
        };
        assert_eq!(
            stops.track(&settings, &decide(0.0, 0.3, 0.5)),
            Some("safety_stop")
        );
        assert_eq!(stops.track(&settings, &decide(0.0, 0.3, 0.0)), None);
        assert_eq!(stops.track(&settings, &decide(0.0, 0.4, 0.5)), None);
        assert!(stops.ahead, "within the release margin");
        assert_eq!(
            stops.track(&settings, &decide(180.0, 0.3, -0.5)),
            Some("safety_stop"),
            "a stop behind is another stop"
        );
        assert_eq!(
            stops.track(&settings, &Decision::blind()),
            Some("safety_stop")
        );
        assert_eq!(stops.track(&settings, &Decision::blind()), None);
        assert_eq!(stops.track(&settings, &decide(0.0, 8.0, 0.5)), None);
        assert_eq!(stops, Stops::default(), "all clear");
    }

    #[test]
    fn slow_motion_keeps_most_of_its_turn_near_an_obstacle() {
        // An obstacle on the right, out of the robot's path, and a turn towards it.
        let settings = settings();
        let scan = scan_with_obstacle(-60.0, 40.0, 0.6);
        let slow = avoid(&settings, &scan, twist(0.02, -1.0));
        let fast = avoid(&settings, &scan, twist(0.5, -1.0));
        assert!(slow.twist.angular_radps < -0.8, "{slow:?}");
        assert!(fast.twist.angular_radps > -0.5, "{fast:?}");
        assert!(!slow.stopped && !fast.stopped);
    }

    #[test]
    fn stops_backing_into_an_obstacle_behind() {
        let decision = avoid(
            &settings(),
            &scan_with_obstacle(180.0, 20.0, 0.3),
            twist(-0.3, 0.2),
        );
        assert_eq!(decision.twist, twist(0.0, 0.2));
        assert!(decision.stopped);
    }

    #[test]
    fn stops_without_scans() {
        let bench = run([desired(0.5, 0.3), desired(0.5, 0.3)]);
        assert_eq!(sent(&bench), [Twist::default(); 2]);
        assert!(bench.reported().is_empty(), "waiting for a first scan");
    }

    #[test]
    fn a_stale_scan_or_desired_command_stops_once() {
        let mut avoider = Avoider::new(settings());
        avoider.on_scan(free_scan(), 10.0);
        assert_eq!(
            avoider.on_desired(twist(0.5, 0.0), 10.2).twist,
            twist(0.5, 0.0)
        );
        assert_eq!(avoider.on_tick(10.4), None, "all fresh");
        let stop = avoider.on_tick(10.6).expect("the scan went stale");
        assert_eq!(stop.twist, Twist::default());
        assert_eq!(stop.report, Some("safety_stop"));
        assert_eq!(avoider.on_tick(10.7), None, "once");
        let held = avoider.on_desired(twist(0.5, 0.0), 10.8);
        assert_eq!((held.twist, held.report), (Twist::default(), None));
        avoider.on_scan(free_scan(), 10.9);
        assert_eq!(
            avoider.on_desired(twist(0.5, 0.0), 10.9).twist,
            twist(0.5, 0.0)
        );
        avoider.on_scan(free_scan(), 11.3);
        assert_eq!(avoider.on_tick(11.3), None);
        let idle = avoider
            .on_tick(11.5)
            .expect("the desired command went stale");
        assert_eq!((idle.twist, idle.report), (Twist::default(), None));
    }

    #[test]
    fn never_outputs_nan() {
        let mut nasty = scan_with_obstacle(20.0, 40.0, f32::NAN);
        nasty.ranges_m[180] = f32::INFINITY;
        nasty.ranges_m[181] = -1.0;
        nasty.ranges_m[182] = 0.0;
        let mut broken = free_scan();
        broken.angle_increment_rad = f64::NAN;
        let mut lopsided = scan_with_obstacle(0.0, 2.0, 0.26);
        lopsided.range_max_m = f64::NAN;
        let settings = settings();
        for scan in [
            nasty,
            broken,
            lopsided,
            scan_with_obstacle(10.0, 90.0, 0.25),
        ] {
            for command in [
                twist(f64::NAN, f64::NAN),
                twist(0.5, f64::INFINITY),
                twist(f64::INFINITY, 0.0),
                twist(0.5, 0.0),
                twist(-0.5, f64::NEG_INFINITY),
            ] {
                let out = avoid(&settings, &scan, command).twist;
                assert!(
                    out.linear_mps.is_finite() && out.angular_radps.is_finite(),
                    "{scan:?} {command:?} -> {out:?}"
                );
            }
        }
        let mut broken = free_scan();
        broken.angle_min_rad = f64::INFINITY;
        let bench = run([
            scan_step(&free_scan()),
            desired(f64::NAN, f64::NAN),
            scan_step(&broken),
            desired(0.5, 0.0),
        ]);
        assert_eq!(sent(&bench), [Twist::default(); 2]);
        assert_eq!(
            bench.reported(),
            ["safety_stop"],
            "an unusable scan stops the robot"
        );
    }

    #[test]
    fn commands_nothing_while_stopped() {
        let bench = run([
            scan_step(&free_scan()),
            desired(0.5, 0.0),
            Step::Active(false),
            desired(0.5, 0.0),
            Step::Active(true),
            scan_step(&free_scan()),
            desired(0.3, 0.0),
        ]);
        let sent = sent(&bench);
        assert_eq!(sent.len(), 3, "{sent:?}");
        assert_eq!(sent[1], Twist::default(), "one zero when stopped");
        assert!((sent[2].linear_mps - 0.3).abs() < 1e-9);
    }

    #[test]
    fn refuses_an_influence_within_the_stop_distance() {
        let mut bench =
            TestBench::new(&spec(), &[("influence_m", "0.3"), ("stop_m", "0.35")]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse");
        assert!(
            err.to_string()
                .contains("`influence_m` must be greater than stop_m"),
            "{err}"
        );
    }

    #[test]
    fn draws_the_repulsion_away_from_an_obstacle_and_the_path_red_while_stopped() {
        let bench = run([
            scan_step(&scan_with_obstacle(30.0, 10.0, 0.6)),
            Step::Timeouts(1),
            scan_step(&scan_with_obstacle(0.0, 10.0, 0.2)),
            desired(0.3, 0.0),
            Step::Timeouts(1),
        ]);
        let drawn = bench.sent::<Markers>("markers").expect("markers");
        assert_eq!(drawn.len(), 2, "one per tick with a fresh scan");
        let arrow = &drawn[0].markers[1];
        assert_eq!((arrow.shape, arrow.frame), (Shape::Arrows, Frame::Robot));
        let force = arrow.points[1];
        assert!(
            force.x_m < 0.0 && force.y_m < 0.0,
            "pushed back and to the right by an obstacle ahead on the left: {force:?}"
        );
        assert_eq!(drawn[0].markers[0].rgba[0], 120, "free");
        assert_eq!(
            drawn[1].markers[0].rgba,
            [220, 40, 40, 200],
            "held by the stop"
        );
    }
}
