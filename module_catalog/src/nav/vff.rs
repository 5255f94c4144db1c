//! `vff`: the obstacle-avoidance behaviour that competes with go-to-goal (JDE's `vff` schema),
//! a candidate of the [`arbiter`](crate::arbiter).
//!
//! It applies while an obstacle is close in front: a laser point nearer than `enter_m` within
//! [`FRONT_RAD`] of straight ahead makes it applicable, and it stays so until every point of the
//! front half (beside the robot too, as it goes round) is farther than `leave_m` (hysteresis:
//! `leave_m` > `enter_m`). While it applies it proposes,
//! at each scan, a virtual force field command: the direction the go-to-goal behaviour wants
//! (its latest proposal on `cmd_goal`, or straight ahead without a fresh one) plus `gain` times
//! the repulsion of every point within `influence_m`, half of it pushing away and the rest turned
//! a quarter towards the attraction's side, so that the robot goes round an obstacle square
//! across its way instead of stopping where the forces cancel (the side is kept until the
//! behaviour stops applying); it turns towards the result and
//! moves at up to `max_speed_mps`, slower the farther off ahead. Its `markers` show each repulsive force
//! (an arrow per sector), the resulting direction and the front sector, in the robot's frame.
//!
//! Unlike the avoider, a safety layer that bends every command, this one only proposes: the
//! arbiter decides whether it drives.

use armor_module_api::types::{Frame, LaserScan, Marker, Markers, Shape, Twist};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use super::{sanitized, wrap_angle};
use crate::BodyError;
use crate::params::float_where;

pub const TYPE: &str = "vff";

/// Half the angle of the sector ahead whose obstacles make the behaviour apply.
pub const FRONT_RAD: f64 = 0.8;
/// A go-to-goal proposal older than this (run time) is not followed any more.
const GOAL_FRESH_SECS: f64 = 0.5;
/// The repulsion is drawn as this many arrows, one per sector of the front half.
const FORCE_SECTORS: usize = 9;
const TURN_GAIN: f64 = 1.5;
const MAX_TURN_RADPS: f64 = 1.2;
const MIN_CLEARANCE_M: f64 = 0.05;

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Obstacle avoidance as a competing behaviour: applies while an obstacle is closer than \
         enter_m ahead (until all are beyond leave_m) and then proposes a virtual force field \
         command round it; publishes its forces as markers.",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .input::<LaserScan>("scan", "the laser scan, in the robot's frame")
    .input::<Twist>(
        "cmd_goal",
        "what the go-to-goal behaviour proposes: the direction attracting the robot",
    )
    .output::<Twist>(
        "cmd_vel",
        "the proposed command, one per scan while the behaviour applies (nothing otherwise)",
    )
    .output::<Markers>(
        "markers",
        "the repulsive forces, the resulting direction and the front sector (robot frame)",
    )
    .param(
        ParamSpec::new(
            "enter_m",
            ParamType::Float,
            "an obstacle this close ahead makes the behaviour apply (greater than 0)",
        )
        .above(0.0)
        .unit("m")
        .default("0.8"),
    )
    .param(
        ParamSpec::new(
            "leave_m",
            ParamType::Float,
            "the behaviour stops applying once everything ahead is farther than this \
             (greater than enter_m)",
        )
        .above(0.0)
        .unit("m")
        .default("1.1"),
    )
    .param(
        ParamSpec::new(
            "influence_m",
            ParamType::Float,
            "points closer than this repel the robot (greater than 0)",
        )
        .above(0.0)
        .unit("m")
        .default("1.5"),
    )
    .param(
        ParamSpec::new(
            "gain",
            ParamType::Float,
            "weight of the repulsion against the attraction (0 or more)",
        )
        .min(0.0)
        .default("1.5"),
    )
    .param(
        ParamSpec::new(
            "max_speed_mps",
            ParamType::Float,
            "forward speed when the resulting direction is straight ahead (0 or more)",
        )
        .min(0.0)
        .unit("m/s")
        .default("0.25"),
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let scan_input = node.input::<LaserScan>("scan")?;
    let goal_input = node.input::<Twist>("cmd_goal")?;
    let output = node.output::<Twist>("cmd_vel")?;
    let markers = node.output::<Markers>("markers")?;
    let mut settings = Settings::read(node)?;
    let mut vff = Vff::default();
    loop {
        match node.next_event(None)? {
            Event::Input(port) if port == goal_input.id() => {
                if let Some(sample) = node.take(&goal_input)? {
                    vff.goal = Some((sanitized(sample.value), node.timestamp()));
                }
            }
            Event::Input(port) if port == scan_input.id() => {
                let Some(sample) = node.take(&scan_input)? else {
                    continue;
                };
                if !node.is_active() {
                    continue;
                }
                let proposal = vff.on_scan(&settings, &sample.value, node.timestamp());
                node.set_applicable(vff.applies);
                if let Some(twist) = proposal.twist {
                    node.send(&output, &twist)?;
                }
                node.send(&markers, &proposal.markers)?;
            }
            Event::Start => vff.applies = false,
            Event::Stop => node.send(&markers, &Markers::default())?,
            Event::ParamsChanged(_) => match Settings::read(node) {
                Ok(new) => settings = new,
                Err(err) => tracing::error!("{err}; keeping the previous settings"),
            },
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

/// The behaviour's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub enter_m: f64,
    pub leave_m: f64,
    pub influence_m: f64,
    pub gain: f64,
    pub max_speed_mps: f64,
}

impl Settings {
    fn read(node: &Node) -> Result<Self, BodyError> {
        let enter_m = node.param::<f64>("enter_m")?;
        Ok(Self {
            enter_m,
            leave_m: float_where(
                node,
                "leave_m",
                |value| value > enter_m,
                &format!("greater than enter_m ({enter_m} m)"),
            )?,
            influence_m: node.param::<f64>("influence_m")?,
            gain: node.param::<f64>("gain")?,
            max_speed_mps: node.param::<f64>("max_speed_mps")?,
        })
    }
}

/// What one scan gives: the command proposed (none when the behaviour does not apply) and the
/// markers drawn.
pub struct Proposal {
    pub twist: Option<Twist>,
    pub markers: Markers,
}

/// Whether the behaviour applies, and the go-to-goal proposal attracting it.
#[derive(Clone, Debug, Default)]
pub struct Vff {
    pub applies: bool,
    goal: Option<(Twist, f64)>,
    /// The side the robot goes round by while the behaviour applies (1 left, -1 right).
    side: Option<f64>,
}

const FORCE_RGBA: [u8; 4] = [230, 60, 40, 220];
const RESULT_RGBA: [u8; 4] = [40, 110, 230, 255];
const SECTOR_RGBA: [u8; 4] = [230, 150, 40, 90];

impl Vff {
    pub fn on_scan(&mut self, settings: &Settings, scan: &LaserScan, now: f64) -> Proposal {
        let mut closest_ahead = f64::INFINITY;
        let mut closest_in_front_half = f64::INFINITY;
        let mut sectors = [(0.0, 0.0); FORCE_SECTORS];
        let mut repulsion = (0.0, 0.0);
        for (index, &range) in scan.ranges_m.iter().enumerate() {
            let range = f64::from(range);
            let angle = wrap_angle(scan.angle_min_rad + index as f64 * scan.angle_increment_rad);
            if !range.is_finite() || range <= 0.0 || range >= scan.range_max_m {
                continue;
            }
            if angle.abs() <= FRONT_RAD {
                closest_ahead = closest_ahead.min(range);
            }
            if angle.abs() <= std::f64::consts::FRAC_PI_2 {
                closest_in_front_half = closest_in_front_half.min(range);
            }
            if range < settings.influence_m && angle.abs() <= std::f64::consts::FRAC_PI_2 {
                let push = (settings.influence_m - range)
                    / settings.influence_m
                    / range.max(MIN_CLEARANCE_M);
                let force = (-push * angle.cos(), -push * angle.sin());
                repulsion.0 += force.0;
                repulsion.1 += force.1;
                let sector = ((angle + std::f64::consts::FRAC_PI_2) / std::f64::consts::PI
                    * FORCE_SECTORS as f64) as usize;
                let sector = &mut sectors[sector.min(FORCE_SECTORS - 1)];
                sector.0 += force.0;
                sector.1 += force.1;
            }
        }
        let beams = scan.ranges_m.len().max(1) as f64;
        let scale = 30.0 / beams;
        self.applies = if self.applies {
            closest_in_front_half <= settings.leave_m
        } else {
            closest_ahead < settings.enter_m
        };
        let attraction = match self.goal {
            Some((goal, at)) if now - at <= GOAL_FRESH_SECS && goal.linear_mps > 0.0 => {
                let angle = goal.angular_radps.clamp(-1.0, 1.0);
                (angle.cos(), angle.sin())
            }
            _ => (1.0, 0.0),
        };
        // A pure field stops the robot where attraction and repulsion cancel (an obstacle
        // square across the way): the repulsion turned a quarter towards the attraction's side
        // (left on a tie) takes it round instead.
        // The side is chosen once per episode: re-chosen at every scan, it flips with the
        // noise when the obstacle is square across the way, and the robot turns to and fro.
        let side = *self.side.get_or_insert(
            if attraction.0 * -repulsion.1 + attraction.1 * repulsion.0 >= 0.0 {
                1.0
            } else {
                -1.0
            },
        );
        if !self.applies {
            self.side = None;
        }
        let tangent = (-repulsion.1 * side, repulsion.0 * side);
        let x = attraction.0 + settings.gain * (repulsion.0 * 0.5 + tangent.0) * scale;
        let y = attraction.1 + settings.gain * (repulsion.1 * 0.5 + tangent.1) * scale;
        let heading = y.atan2(x);
        let twist = Twist {
            linear_mps: settings.max_speed_mps * heading.cos().max(0.0),
            angular_radps: (TURN_GAIN * heading).clamp(-MAX_TURN_RADPS, MAX_TURN_RADPS),
        };
        let mut markers = vec![
            Marker::new(
                Shape::Polygon,
                Frame::Robot,
                SECTOR_RGBA,
                [
                    (0.0, 0.0),
                    (
                        settings.enter_m * FRONT_RAD.cos(),
                        settings.enter_m * FRONT_RAD.sin(),
                    ),
                    (settings.enter_m, 0.0),
                    (
                        settings.enter_m * FRONT_RAD.cos(),
                        -settings.enter_m * FRONT_RAD.sin(),
                    ),
                ],
            )
            .with_text("vff front"),
            Marker::new(
                Shape::Arrows,
                Frame::Robot,
                FORCE_RGBA,
                sectors
                    .iter()
                    .filter(|force| force.0 != 0.0 || force.1 != 0.0)
                    .flat_map(|force| [(0.0, 0.0), (force.0 * scale, force.1 * scale)]),
            )
            .with_text("repulsion"),
        ];
        if self.applies {
            markers.push(
                Marker::new(
                    Shape::Arrows,
                    Frame::Robot,
                    RESULT_RGBA,
                    [(0.0, 0.0), (heading.cos(), heading.sin())],
                )
                .with_text("vff"),
            );
        }
        Proposal {
            twist: self.applies.then_some(twist),
            markers: Markers { markers },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};

    /// A scan of 181 beams over the front half, everything at `far_m` but the beams within
    /// `width_rad` of `at_rad`, at `near_m`.
    fn scan(far_m: f32, at_rad: f64, width_rad: f64, near_m: f32) -> LaserScan {
        let increment = std::f64::consts::PI / 180.0;
        LaserScan {
            angle_min_rad: -std::f64::consts::FRAC_PI_2,
            angle_increment_rad: increment,
            range_max_m: 10.0,
            ranges_m: (0..181)
                .map(|i| {
                    let angle = -std::f64::consts::FRAC_PI_2 + f64::from(i) * increment;
                    if (angle - at_rad).abs() <= width_rad {
                        near_m
                    } else {
                        far_m
                    }
                })
                .collect(),
        }
    }

    #[test]
    fn applies_near_an_obstacle_ahead_with_hysteresis_and_steers_away_from_it() {
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        let steps = [
            scan(5.0, 0.0, 0.1, 3.0),  // far: does not apply
            scan(5.0, 0.2, 0.15, 0.6), // close, a little to the left: applies
            scan(5.0, 0.2, 0.15, 1.0), // between enter and leave: still applies
            scan(5.0, 0.2, 0.15, 1.3), // beyond leave: no longer
        ]
        .map(|scan| Step::push("scan", &scan).expect("step"));
        bench.script(steps);
        body(bench.node()).expect("body");
        let sent = bench.sent::<Twist>("cmd_vel").expect("sent");
        assert_eq!(sent.len(), 2, "proposes only while it applies: {sent:?}");
        assert!(
            sent[0].angular_radps < 0.0,
            "turns right, away from an obstacle on the left: {sent:?}"
        );
        assert_eq!(
            bench.behaviour(),
            ["not applicable", "applicable", "not applicable"]
        );
        let markers = bench.sent::<Markers>("markers").expect("markers");
        assert_eq!(markers.len(), 4, "markers at every scan");
        assert!(
            markers[1]
                .markers
                .iter()
                .any(|m| m.shape == Shape::Arrows && m.text == "repulsion" && !m.points.is_empty())
        );
    }

    #[test]
    fn refuses_a_leave_distance_inside_the_enter_distance() {
        let mut bench =
            TestBench::new(&spec(), &[("enter_m", "1.0"), ("leave_m", "0.9")]).expect("bench");
        let err = body(bench.node()).expect_err("refused");
        assert!(
            err.to_string().contains("greater than enter_m (1 m)"),
            "{err}"
        );
    }
}
