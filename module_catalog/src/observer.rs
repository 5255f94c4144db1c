//! `observer`: turns on the spot through a sector (a full circle by default), to look around,
//! then reports `observation_done` and stands still.
//!
//! The angle turned is measured on the `odometry` heading: each pose adds the (wrapped) heading
//! change in the direction of the turn, so a turn through more than half a circle is counted
//! right and a jolt backwards counts against it. One command is published per pose received.
//! Each start (activation) begins a new turn from wherever the robot is heading.
//!
//! With `sighted`, it also reports a no-go area once the sector is covered, as a unit that
//! looked round and saw a minefield would: the mission adds it to its plan as an update
//! (`docs/plans.md`, "Areas reported from outside"). What it reports is given, not recognised:
//! this is the stand-in for a sensor that would.

use armor_module_api::types::{Frame, Marker, Markers, Odometry, Shape, Twist};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;
use crate::nav::wrap_angle;

pub const TYPE: &str = "observer";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Turns on the spot through a sector (a full circle by default), measured on the odometry \
         heading, then reports observation_done and commands zero. Each activation starts a new \
         turn.",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .input::<Odometry>(
        "odometry",
        "the robot's pose: its heading tells how far the robot has turned",
    )
    .output::<Markers>(
        "markers",
        "the sector, ten times a second of run time while turning: the arc turned so far and \
         the arc left, a metre round the robot (robot frame)",
    )
    .output::<Twist>(
        "cmd_vel",
        "the turning command, one per pose received (zero once the sector is covered, and once \
         when the module is stopped)",
    )
    .param(
        ParamSpec::new(
            "sector_deg",
            ParamType::Float,
            "how far to turn (greater than 0; more than 360 turns more than once)",
        )
        .above(0.0)
        .unit("deg")
        .default("360"),
    )
    .param(
        ParamSpec::new(
            "turn_radps",
            ParamType::Float,
            "turning speed, counter-clockwise (negative: clockwise; not 0)",
        )
        .nonzero()
        .unit("rad/s")
        .default("0.6"),
    )
    .param(
        ParamSpec::new(
            "sighted",
            ParamType::String,
            "a no-go area to report once the sector is covered, `NAME X,Y X,Y X,Y…` in the world \
             frame (metres); empty: none",
        )
        .default(""),
    )
    .event(
        "observation_done",
        "the robot has turned through the whole sector (once per activation)",
    )
}

pub fn body(node: &mut Node) -> BodyResult {
    let odometry = node.input::<Odometry>("odometry")?;
    let output = node.output::<Twist>("cmd_vel")?;
    let markers = node.output::<Markers>("markers")?;
    let mut settings = Settings::read(node)?;
    let mut sighted = Sighted::read(node)?;
    let mut turn = Turn::default();
    let mut markers_sent = f64::NEG_INFINITY;
    loop {
        match node.next_event(None)? {
            Event::Input(port) if port == odometry.id() => {
                let Some(sample) = node.take(&odometry)? else {
                    continue;
                };
                if node.is_active() {
                    let (twist, done) =
                        turn.on_heading(sample.value.pose_in_odom.theta_rad, &settings);
                    node.send(&output, &twist)?;
                    if done || node.timestamp() - markers_sent >= MARKERS_EVERY_SECS {
                        markers_sent = node.timestamp();
                        node.send(&markers, &turn.markers(&settings))?;
                    }
                    if done {
                        tracing::info!("turned through {} degrees", settings.sector_deg);
                        if let Some(area) = &sighted {
                            node.report_area(&area.name, &area.points_m);
                        }
                        node.report("observation_done")?;
                    }
                }
            }
            Event::Start => {
                tracing::info!("active: turning through {} degrees", settings.sector_deg);
                turn = Turn::default();
            }
            Event::Stop => {
                tracing::info!("inactive: stopping");
                node.send(&output, &Twist::default())?;
            }
            Event::ParamsChanged(_) => match (Settings::read(node), Sighted::read(node)) {
                (Ok(new), Ok(new_sighted)) => {
                    settings = new;
                    sighted = new_sighted;
                }
                (Err(err), _) | (_, Err(err)) => {
                    tracing::error!("{err}; keeping the previous settings")
                }
            },
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

/// The observer's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub sector_deg: f64,
    pub turn_radps: f64,
}

impl Settings {
    fn read(node: &Node) -> Result<Self, BodyError> {
        Ok(Self {
            sector_deg: node.param::<f64>("sector_deg")?,
            turn_radps: node.param::<f64>("turn_radps")?,
        })
    }
}

/// The no-go area the observer reports once the sector is covered (`sighted`).
#[derive(Clone, Debug, PartialEq)]
struct Sighted {
    name: String,
    points_m: Vec<[f64; 2]>,
}

impl Sighted {
    fn read(node: &Node) -> Result<Option<Self>, BodyError> {
        let text = node.param::<String>("sighted")?;
        Self::parse(&text).map_err(|why| BodyError::from(format!("parameter `sighted`: {why}")))
    }

    /// `NAME X,Y X,Y…`; nothing when `text` is blank. The run judges the area itself (its
    /// corners, its name): this only reads the numbers.
    fn parse(text: &str) -> Result<Option<Self>, BodyError> {
        let mut words = text.split_whitespace();
        let Some(name) = words.next() else {
            return Ok(None);
        };
        let points_m = words
            .map(|corner| {
                let number = |part: &str| part.parse::<f64>().ok().filter(|v| v.is_finite());
                corner
                    .split_once(',')
                    .and_then(|(x, y)| Some([number(x)?, number(y)?]))
                    .ok_or_else(|| {
                        BodyError::from(format!("`{corner}` is not a corner `X,Y` in metres"))
                    })
            })
            .collect::<Result<_, _>>()?;
        Ok(Some(Self {
            name: name.to_owned(),
            points_m,
        }))
    }
}

/// How often, in run time, the sector is drawn again while turning.
const MARKERS_EVERY_SECS: f64 = 0.1;
/// The arcs' radius round the robot.
const ARC_M: f64 = 1.0;

/// One turn through the sector.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Turn {
    last_heading: Option<f64>,
    /// Angle turned so far in the direction of the turn (radians).
    turned_rad: f64,
    done: bool,
}

impl Turn {
    /// The arc turned so far (behind the heading) and the arc left (ahead of it), in the
    /// robot's frame, with how far it has come.
    fn markers(&self, settings: &Settings) -> Markers {
        let sign = settings.turn_radps.signum();
        let sector_rad = settings.sector_deg.to_radians();
        let turned = self
            .turned_rad
            .clamp(0.0, sector_rad)
            .min(std::f64::consts::TAU);
        let left = (sector_rad - self.turned_rad).clamp(0.0, std::f64::consts::TAU);
        let arc = |from_rad: f64, to_rad: f64| {
            let steps = ((to_rad - from_rad).abs() / 0.1).ceil().max(1.0) as usize;
            (0..=steps).map(move |i| {
                let angle = from_rad + (to_rad - from_rad) * i as f64 / steps as f64;
                (ARC_M * angle.cos(), ARC_M * angle.sin())
            })
        };
        let mut done = Marker::new(
            Shape::Polyline,
            Frame::Robot,
            [40, 160, 90, 230],
            arc(-turned * sign, 0.0),
        );
        done.size_px = 4.0;
        Markers {
            markers: vec![
                done.with_text("observed"),
                Marker::new(
                    Shape::Polyline,
                    Frame::Robot,
                    [40, 160, 90, 110],
                    arc(0.0, left * sign),
                )
                .with_text("left to observe"),
                Marker::new(
                    Shape::Text,
                    Frame::Robot,
                    [40, 160, 90, 255],
                    [(ARC_M, 0.0)],
                )
                .with_text(&format!(
                    "{:.0}° of {:.0}°",
                    turned.to_degrees(),
                    settings.sector_deg
                )),
            ],
        }
    }

    /// The command for a new heading, and whether the sector was covered just now.
    fn on_heading(&mut self, heading_rad: f64, settings: &Settings) -> (Twist, bool) {
        if self.done {
            return (Twist::default(), false);
        }
        if !heading_rad.is_finite() {
            tracing::warn!("ignoring a non-finite heading");
            return (Twist::default(), false);
        }
        if let Some(last) = self.last_heading {
            self.turned_rad += wrap_angle(heading_rad - last) * settings.turn_radps.signum();
        }
        self.last_heading = Some(heading_rad);
        if self.turned_rad >= settings.sector_deg.to_radians() {
            self.done = true;
            return (Twist::default(), true);
        }
        let twist = Twist {
            linear_mps: 0.0,
            angular_radps: settings.turn_radps,
        };
        (twist, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};
    use armor_module_api::types::Pose2D;

    fn heading(theta_rad: f64) -> Step {
        let odometry = Odometry {
            pose_in_odom: Pose2D {
                x_m: 1.0,
                y_m: 2.0,
                theta_rad,
            },
            twist: Twist::default(),
        };
        Step::push("odometry", &odometry).expect("step")
    }

    fn run(params: &[(&str, &str)], steps: impl IntoIterator<Item = Step>) -> TestBench {
        let mut bench = TestBench::new(&spec(), params).expect("bench");
        bench.script(steps);
        body(bench.node()).expect("body");
        bench
    }

    fn turning(angular_radps: f64) -> Twist {
        Twist {
            linear_mps: 0.0,
            angular_radps,
        }
    }

    /// Headings 0, 1, 2, … rad, as odometry reports them (wrapped into one turn).
    fn headings(count: usize) -> Vec<Step> {
        (0..count).map(|i| heading(wrap_angle(i as f64))).collect()
    }

    #[test]
    fn turns_through_a_full_circle_then_reports_once_and_stands_still() {
        // Headings 0 … 6 rad are short of a full turn (2π ≈ 6.28); 7 rad is past it.
        let bench = run(&[], headings(10));
        let sent = bench.sent::<Twist>("cmd_vel").expect("sent");
        assert_eq!(sent[..7], [turning(0.6); 7]);
        assert_eq!(sent[7..], [Twist::default(); 3]);
        assert_eq!(bench.reported(), ["observation_done"]);
    }

    #[test]
    fn reports_the_area_it_sighted_once_the_sector_is_covered() {
        let bench = run(&[("sighted", "mines 23,5.3 25,5.3 25,8.2")], headings(10));
        assert_eq!(
            bench.areas_reported(),
            [(
                "mines".to_owned(),
                vec![[23.0, 5.3], [25.0, 5.3], [25.0, 8.2]]
            )]
        );
        assert_eq!(bench.reported(), ["observation_done"]);
        // Nothing sighted, nothing reported; a corner that is not `X,Y` is refused.
        assert!(run(&[], headings(10)).areas_reported().is_empty());
        assert_eq!(
            Sighted::parse("mines 1,1 2;2").map_err(|err| err.to_string()),
            Err("`2;2` is not a corner `X,Y` in metres".to_owned())
        );
    }

    #[test]
    fn turns_clockwise_through_a_sector() {
        let steps = [0.0, -0.5, -1.0, 0.9, -1.5, -1.55, -1.7].map(heading);
        let bench = run(&[("sector_deg", "90"), ("turn_radps", "-0.4")], steps);
        let sent = bench.sent::<Twist>("cmd_vel").expect("sent");
        // A jolt the wrong way (to 0.9) counts against the turn.
        assert_eq!(sent[..6], [turning(-0.4); 6]);
        assert_eq!(sent[6], Twist::default());
        assert_eq!(bench.reported(), ["observation_done"]);
    }

    #[test]
    fn restarts_its_turn_on_each_start_and_commands_nothing_while_stopped() {
        let mut steps = headings(8);
        steps.extend([Step::Active(false), heading(0.5), Step::Active(true)]);
        steps.extend(headings(3));
        let bench = run(&[], steps);
        let sent = bench.sent::<Twist>("cmd_vel").expect("sent");
        assert_eq!(sent.len(), 8 + 1 + 3, "{sent:?}");
        assert_eq!(sent[8], Twist::default(), "one zero when stopped");
        assert_eq!(sent[9..], [turning(0.6); 3], "a new turn");
        assert_eq!(bench.reported(), ["observation_done"]);
    }

    #[test]
    fn refuses_a_turning_speed_of_zero() {
        let mut bench = TestBench::new(&spec(), &[("turn_radps", "0")]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse");
        assert!(
            err.to_string().contains("`turn_radps` must be non-zero"),
            "{err}"
        );
    }

    #[test]
    fn a_non_finite_heading_commands_zero_and_is_skipped() {
        let bench = run(&[], [heading(0.0), heading(f64::NAN), heading(0.5)]);
        let sent = bench.sent::<Twist>("cmd_vel").expect("sent");
        assert_eq!(sent, [turning(0.6), Twist::default(), turning(0.6)]);
    }

    #[test]
    fn draws_the_arc_turned_and_the_arc_left() {
        let settings = Settings {
            sector_deg: 180.0,
            turn_radps: -0.6,
        };
        let mut turn = Turn::default();
        for heading in [0.0, -0.5, -1.0] {
            turn.on_heading(heading, &settings);
        }
        let markers = turn.markers(&settings);
        let [observed, left, text] = &markers.markers[..] else {
            panic!("{markers:?}");
        };
        // Clockwise: what was turned lies to the robot's left, what is left to its right.
        assert!(observed.points[0].y_m > 0.0, "{observed:?}");
        assert!(left.points.last().expect("points").y_m < 0.0, "{left:?}");
        assert_eq!(text.text, "57° of 180°");
    }
}
