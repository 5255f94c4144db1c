//! `localiser`: where the robot is on a known map, by Monte Carlo localisation ([`mcl`]).
//!
//! The map is the plan's world (a `.world` file or a ROS map_server map, read by
//! [`armor_model::world_file::load`] as the simulator and the planner read it). Each scan moves the
//! particles by the odometry's motion since the last update, weighs them on the scan and
//! resamples them; the estimate is their mean and covariance. Between scans, the pose published
//! on `pose` is the last estimate moved by the odometry since (the map-from-odometry correction
//! applied to every odometry sample), so a follower linked to it gets a pose as often as it got
//! odometry: a drop-in replacement for it. `estimate` carries the covariance and the state at
//! each scan.
//!
//! The state is reported as events on entering it: `localised` (position standard deviation at
//! most 0.15 m on its worst axis, heading at most 0.1 rad, the scan's fit at least 0.5, one
//! cluster of particles and 90 % of the beams agreeing with the map), `lost` (position standard
//! deviation above 1 m, the fit below 0.25 or fewer than half the beams agreeing: a cloud can be
//! tight and wrong, as when the robot is carried elsewhere, and only the scan shows it),
//! `uncertain` otherwise; a step down in the beams' agreement against its history (a suspected
//! kidnap, [`mcl`]) makes it `uncertain` until the estimate is proven again, and each estimate
//! says whether it is proven (a follower does not drive on one that is not).
//! Lost, it stays lost until an operator sets the pose (`set_pose`), or, with
//! `recover`, spreads its particles over the map's free space (global mode); a place found so
//! must hold while the robot drives on before it is called `localised`. When the scans stop
//! coming ([`SCANS_LATE_SECS`]), the filter goes on on the odometry alone, its covariance
//! growing, and publishes that estimate (never becoming `localised` without a scan).
//!
//! The initial pose is the world's start (the simulator's), or `x_m`, `y_m`, `heading_deg`;
//! `global` starts in global mode. `set_pose` ("X Y HEADING_DEG", tunable live) puts the
//! particles round a pose given by hand, as rviz's "2D Pose Estimate" does.

pub mod mcl;
#[cfg(test)]
mod sweep;

use armor_module_api::types::{LaserScan, LocalisationState, Odometry, Pose2D, PoseEstimate};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;
use crate::mapper::{between, compose};
use mcl::{Filter, Map, Settings, State};

pub const TYPE: &str = "localiser";

/// A scan this late (run time since the last one; ten periods of the simulator's laser) means
/// the laser went quiet: the filter then goes on on the odometry alone
/// ([`mcl::Filter::predict_only`]), its covariance growing with the way driven, and publishes
/// that estimate at each step, as Nav2's AMCL keeps its estimate on odometry. Without it, the
/// estimate would stay as sure as at the last scan while the robot drives on.
pub const SCANS_LATE_SECS: f64 = 1.0;

/// The spread of the particles round a pose given by a parameter or by hand, and round the
/// pose a restarted localiser starts from ([`Kept`]), at the least.
const SET_POSE_SIGMA_M: f64 = 0.2;
const SET_POSE_SIGMA_RAD: f64 = 0.15;

/// How often (run time) the module asks the run to keep its correction of odometry for a
/// process restarted after it ([`Kept`]), besides whenever the state or the proof changes.
const KEEP_EVERY_SECS: f64 = 0.5;

/// What the localiser keeps for its next process, should this one die and be restarted by the
/// supervisor (a stall under load, a crash): the map-from-odometry correction, the estimate's
/// standard deviations, its state and whether it was proven. The simulator's odometry (or a
/// robot's) goes on while the localiser is down, so the correction applied to the first
/// odometry sample the new process gets is where the robot is now, give or take the
/// odometry's drift since; without it, a restarted localiser started at the world's start and
/// the follower drove on that until the kidnap detector noticed (seen under load).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kept {
    pub map_from_odom: Pose2D,
    pub sigma_m: f64,
    pub sigma_rad: f64,
    pub state: State,
    pub proven: bool,
}

impl Kept {
    /// One line: `X_M Y_M THETA_RAD SIGMA_M SIGMA_RAD STATE PROVEN`.
    pub fn to_text(&self) -> String {
        let c = self.map_from_odom;
        format!(
            "{} {} {} {} {} {} {}",
            c.x_m,
            c.y_m,
            c.theta_rad,
            self.sigma_m,
            self.sigma_rad,
            self.state.event(),
            self.proven
        )
    }

    pub fn parse(text: &str) -> Result<Self, BadKept> {
        let words: Vec<&str> = text.split_whitespace().collect();
        let bad = || BadKept(text.to_owned());
        let [x, y, theta, sigma_m, sigma_rad, state, proven] = words[..] else {
            return Err(bad());
        };
        let number = |word: &str| word.parse::<f64>().ok().filter(|v| v.is_finite());
        let (Some(x_m), Some(y_m), Some(theta_rad), Some(sigma_m), Some(sigma_rad)) = (
            number(x),
            number(y),
            number(theta),
            number(sigma_m),
            number(sigma_rad),
        ) else {
            return Err(bad());
        };
        let state = match state {
            "localised" => State::Localised,
            "uncertain" => State::Uncertain,
            "lost" => State::Lost,
            _ => return Err(bad()),
        };
        let proven = proven.parse::<bool>().map_err(|_| bad())?;
        Ok(Self {
            map_from_odom: Pose2D {
                x_m,
                y_m,
                theta_rad,
            },
            sigma_m: sigma_m.abs(),
            sigma_rad: sigma_rad.abs(),
            state,
            proven,
        })
    }
}

/// A kept line that is not [`Kept::to_text`]'s: the restarted process starts as configured.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("kept state `{0}` is not `X Y THETA SIGMA_M SIGMA_RAD STATE PROVEN`")]
pub struct BadKept(pub String);

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Localises the robot on a known map (a .world file or a ROS map) by Monte Carlo \
         localisation: odometry motion model, likelihood-field laser model, KLD-adaptive \
         particle count, low-variance resampling. Publishes the pose in the map frame in place \
         of odometry, and its covariance and state: `localised` (position sigma <= 0.15 m, \
         heading sigma <= 0.1 rad, scan fit >= 0.5, one cluster of particles, 90 % of the beams \
         agreeing with the map), `lost` (position sigma > 1 m, scan fit < 0.25 or under half \
         the beams agreeing), else `uncertain`. A step down in the beams' agreement against \
         its history (a suspected kidnap) makes it `uncertain` until the estimate is proven \
         again (a full turn in place; each estimate says whether it is proven). Lost, it stays \
         lost until set_pose (or, with recover, searches the whole map). Without scans for a \
         second, it goes on on the odometry alone, its uncertainty growing.",
    )
    .category(armor_module_api::Category::Navigation)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .input::<Odometry>(
        "odometry",
        "dead-reckoned pose and velocity (every sample is corrected and published on `pose`)",
    )
    .input::<LaserScan>(
        "scan",
        "laser scan from the robot's centre (each one updates the filter with the latest \
         odometry, when the robot moved 5 cm or turned 0.05 rad since the last update)",
    )
    .output::<Odometry>(
        "pose",
        "the pose in the map frame (the world's) and the odometry's twist, at every odometry \
         sample: the latest estimate moved by the odometry since; a drop-in replacement for \
         odometry",
    )
    .output::<PoseEstimate>(
        "estimate",
        "the estimate at each scan: pose in the map frame, covariance of x, y and heading, the \
         scan's fit and the state",
    )
    .param(
        ParamSpec::new(
            "world",
            ParamType::String,
            "the map: a world file or a ROS map_server map.yaml (found as the sim finds its own)",
        )
        .file("worlds"),
    )
    .param(
        ParamSpec::new(
            "x_m",
            ParamType::String,
            "initial x in the map frame (empty: the world's start)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "y_m",
            ParamType::String,
            "initial y in the map frame (empty: the world's start)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "heading_deg",
            ParamType::String,
            "initial heading, counter-clockwise from east (empty: the world's start)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "global",
            ParamType::Bool,
            "start in global mode: the robot's place is unknown, particles spread over the map's \
             free space",
        )
        .default("false"),
    )
    .param(
        ParamSpec::new(
            "set_pose",
            ParamType::String,
            "`X Y HEADING_DEG`: the robot is there, give or take 0.2 m and 0.15 rad (an \
             operator's pose estimate; tunable live: each new value is taken once)",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "recover",
            ParamType::Bool,
            "when lost, search the whole map (global mode; a place found must hold for 5 m of \
             driving before it is called localised; measured: 13 of 20 kidnapped robots found \
             themselves, none said localised at a wrong place); off: stay lost until a set_pose",
        )
        .default("false"),
    )
    .param(
        ParamSpec::new(
            "min_particles",
            ParamType::Int,
            "fewest particles (1 or more)",
        )
        .min(1.0)
        .max(100_000.0)
        .default("500"),
    )
    .param(
        ParamSpec::new(
            "max_particles",
            ParamType::Int,
            "most particles, and how many global mode spreads (at least min_particles)",
        )
        .min(1.0)
        .max(100_000.0)
        .default("3000"),
    )
    .param(
        ParamSpec::new(
            "beams",
            ParamType::Int,
            "beams of each scan weighed, spread evenly over it (1 or more)",
        )
        .min(1.0)
        .max(100_000.0)
        .default("60"),
    )
    .param(
        ParamSpec::new(
            "sigma_hit_m",
            ParamType::Float,
            "standard deviation of a beam's end round the wall it hit (greater than 0)",
        )
        .above(0.0)
        .max(1.0)
        .unit("m")
        .default("0.1"),
    )
    .param(
        ParamSpec::new(
            "alpha",
            ParamType::String,
            "noise of the motion model, four numbers: rotation from rotation, rotation from \
             translation, translation from translation, translation from rotation",
        )
        .default("0.05 0.005 0.05 0.01"),
    )
    .param(
        ParamSpec::new(
            "robot_radius_m",
            ParamType::Float,
            "the robot's radius: global mode puts particles only where it fits (greater than 0)",
        )
        .above(0.0)
        .unit("m")
        .default("0.25"),
    )
    .param(ParamSpec::new("seed", ParamType::Int, "seed of the filter's randomness").default("1"))
    .event(
        "localised",
        "the estimate became trustworthy: position sigma <= 0.15 m, heading sigma <= 0.1 rad, \
         scan fit >= 0.5, no second cluster of particles with 5 % of the weight, 90 % of the \
         beams reading what the map says from the estimate",
    )
    .event("uncertain", "the estimate is neither localised nor lost")
    .event(
        "lost",
        "position sigma > 1 m, or the scan fits the map badly at the estimate (fit < 0.25, or \
         under half the beams reading what the map says)",
    )
}

/// A number parameter given as text, empty for none.
fn optional_number(node: &Node, name: &str) -> Result<Option<f64>, BodyError> {
    let text: String = node.param(name)?;
    let text = text.trim();
    if text.is_empty() {
        return Ok(None);
    }
    match text.parse::<f64>() {
        Ok(value) if value.is_finite() => Ok(Some(value)),
        _ => Err(format!("parameter `{name}`: `{text}` is not a number").into()),
    }
}

/// `X Y HEADING_DEG`, or None when empty.
pub fn parse_pose(text: &str) -> Result<Option<Pose2D>, String> {
    let words: Vec<&str> = text.split_whitespace().collect();
    if words.is_empty() {
        return Ok(None);
    }
    let numbers: Vec<f64> = words
        .iter()
        .map(|word| word.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| format!("`{text}` is not three numbers `X Y HEADING_DEG`"))?;
    match numbers[..] {
        [x_m, y_m, heading_deg] => Ok(Some(Pose2D {
            x_m,
            y_m,
            theta_rad: crate::wrap_angle(heading_deg.to_radians()),
        })),
        _ => Err(format!("`{text}` is not three numbers `X Y HEADING_DEG`")),
    }
}

fn settings(node: &Node) -> Result<Settings, BodyError> {
    let min_particles = node.param::<usize>("min_particles")?;
    let max_particles = node.param::<usize>("max_particles")?;
    if max_particles < min_particles {
        return Err(format!(
            "parameter `max_particles` ({max_particles}) must be at least min_particles \
             ({min_particles})"
        )
        .into());
    }
    let alpha_text: String = node.param("alpha")?;
    let alpha: Vec<f64> = alpha_text
        .split_whitespace()
        .map(|word| {
            word.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 0.0)
        })
        .collect::<Option<_>>()
        .unwrap_or_default();
    let [a1, a2, a3, a4] = alpha[..] else {
        return Err(
            format!("parameter `alpha`: `{alpha_text}` is not four numbers of 0 or more").into(),
        );
    };
    Ok(Settings {
        min_particles,
        max_particles,
        alpha: [a1, a2, a3, a4],
        beams: node.param::<usize>("beams")?,
        sigma_hit_m: node.param::<f64>("sigma_hit_m")?,
        robot_radius_m: node.param::<f64>("robot_radius_m")?,
        recover: node.param::<bool>("recover")?,
        ..Settings::default()
    })
}

/// The estimate as the `estimate` output carries it.
pub fn message(estimate: &mcl::Estimate) -> PoseEstimate {
    PoseEstimate {
        pose_in_map: estimate.pose,
        covariance: estimate.covariance,
        fit: estimate.fit,
        state: match estimate.state {
            State::Localised => LocalisationState::Localised,
            State::Uncertain => LocalisationState::Uncertain,
            State::Lost => LocalisationState::Lost,
        },
        proven: estimate.proven,
    }
}

/// The module without a node: the filter, and the correction it makes of odometry (the map
/// pose of the odometry frame's origin: the estimate at the last update composed with the
/// inverse of the odometry pose then).
#[derive(Clone, Debug)]
pub struct Localiser {
    pub filter: Filter,
    map_from_odom: Option<Pose2D>,
}

impl Localiser {
    pub fn new(filter: Filter) -> Self {
        Self {
            filter,
            map_from_odom: None,
        }
    }

    /// A localiser restarted with what its previous process kept: the correction is in force
    /// at once (poses are published from the first odometry sample), and the filter starts
    /// from it at that sample ([`Localiser::resume_at`]).
    pub fn resumed(filter: Filter, kept: &Kept) -> Self {
        Self {
            filter,
            map_from_odom: Some(kept.map_from_odom),
        }
    }

    /// The filter put where `kept`'s correction puts the odometry pose `odom` (the first one a
    /// restarted localiser gets), spread by the kept standard deviations, at least those of a
    /// pose set by hand; what was to prove must still be proven, and lost stays lost.
    pub fn resume_at(&mut self, kept: &Kept, odom: Pose2D) {
        let pose = compose(kept.map_from_odom, odom);
        self.filter.resume(
            pose,
            kept.sigma_m.max(SET_POSE_SIGMA_M),
            kept.sigma_rad.max(SET_POSE_SIGMA_RAD),
            kept.proven,
            kept.state == State::Lost,
        );
        self.map_from_odom = Some(kept.map_from_odom);
    }

    /// What to keep for a process restarted after this one, once there is an estimate.
    pub fn kept(&self) -> Option<Kept> {
        let estimate = self.filter.estimate();
        Some(Kept {
            map_from_odom: self.map_from_odom?,
            sigma_m: estimate.sigma_m(),
            sigma_rad: estimate.sigma_rad(),
            state: estimate.state,
            proven: estimate.proven,
        })
    }

    /// The pose in the map frame for an odometry pose (none before the first scan).
    pub fn on_odometry(&self, odom: Pose2D) -> Option<Pose2D> {
        self.map_from_odom
            .map(|correction| compose(correction, odom))
    }

    /// A scan, with the odometry pose of its time: the filter's update, and its estimate.
    pub fn on_scan(&mut self, odom: Pose2D, scan: &LaserScan) -> mcl::Estimate {
        let updated = self.filter.update(odom, scan);
        let estimate = self.filter.estimate();
        if updated || self.map_from_odom.is_none() {
            self.map_from_odom = Some(compose(estimate.pose, between(odom, Pose2D::default())));
        }
        estimate
    }

    /// An odometry sample while the scans are late ([`SCANS_LATE_SECS`]): the filter on the
    /// odometry alone; its estimate when the particles moved. The correction published on
    /// `pose` stays the last scan's: the particles' mean moves as the odometry does.
    pub fn on_odometry_without_scans(&mut self, odom: Pose2D) -> Option<mcl::Estimate> {
        self.filter
            .predict_only(odom)
            .then(|| self.filter.estimate())
    }
}

/// Reports the state when it changed since the last one reported.
fn report_state(
    node: &mut Node,
    reported: &mut Option<State>,
    estimate: &mcl::Estimate,
    why: &str,
) -> Result<(), BodyError> {
    if *reported == Some(estimate.state) {
        return Ok(());
    }
    *reported = Some(estimate.state);
    let text = format!(
        "{} at ({:.2}, {:.2}): sigma {:.2} m, {:.2} rad; fit {:.2}; {} particles{why}",
        estimate.state.event(),
        estimate.pose.x_m,
        estimate.pose.y_m,
        estimate.sigma_m(),
        estimate.sigma_rad(),
        estimate.fit,
        estimate.particles
    );
    if estimate.state == State::Lost {
        tracing::warn!("{text}");
    } else {
        tracing::info!("{text}");
    }
    node.report(estimate.state.event())?;
    Ok(())
}

/// Asks the run to keep the correction for a restarted process ([`Kept`]), every
/// [`KEEP_EVERY_SECS`] and whenever the state or the proof changed.
fn keep(node: &mut Node, localiser: &Localiser, last: &mut Option<(Kept, f64)>) {
    let Some(kept) = localiser.kept() else {
        return;
    };
    let now = node.timestamp();
    let due = last.is_none_or(|(before, at)| {
        now - at >= KEEP_EVERY_SECS || before.state != kept.state || before.proven != kept.proven
    });
    if due {
        node.keep(&kept.to_text());
        *last = Some((kept, now));
    }
}

pub fn body(node: &mut Node) -> BodyResult {
    let odometry_input = node.input::<Odometry>("odometry")?;
    let scan_input = node.input::<LaserScan>("scan")?;
    let pose_output = node.output::<Odometry>("pose")?;
    let estimate_output = node.output::<PoseEstimate>("estimate")?;
    let settings = settings(node)?;
    let name: String = node.param("world").map_err(|_| {
        "parameter `world` is required: the map, a world file or a ROS map.yaml (for example \
         `warehouse.world`)"
    })?;
    let world = crate::sim::load_world_file(&crate::sim::find_world(name.trim())?)?;
    let mut start = world.start();
    if let Some(x) = optional_number(node, "x_m")? {
        start.x_m = x;
    }
    if let Some(y) = optional_number(node, "y_m")? {
        start.y_m = y;
    }
    if let Some(heading) = optional_number(node, "heading_deg")? {
        start.theta_rad = crate::wrap_angle(heading.to_radians());
    }
    let seed: i64 = node.param("seed")?;
    let map = Map::new(&world, settings.sigma_hit_m, settings.robot_radius_m)?;
    let mut filter = Filter::new(settings, map, start, u64::from_ne_bytes(seed.to_ne_bytes()));
    // Restarted in this run: where the previous process left the robot, not the start.
    let mut resume = match node.kept().map(Kept::parse) {
        Some(Ok(kept)) => Some(kept),
        Some(Err(why)) => {
            tracing::error!("{why}: starting as configured");
            None
        }
        None => None,
    };
    let mut set_pose: String = node.param("set_pose")?;
    if let Some(kept) = &resume {
        let c = kept.map_from_odom;
        tracing::info!(
            "map `{}`: restarted, resuming from the last process's correction of odometry \
             ({:.2}, {:.2}, {:.0}°), {} when it ended",
            world.name(),
            c.x_m,
            c.y_m,
            c.theta_rad.to_degrees(),
            kept.state.event()
        );
    } else if node.param::<bool>("global")? {
        filter.spread();
        tracing::info!(
            "map `{}`: global mode, the robot's place unknown",
            world.name()
        );
    } else {
        tracing::info!(
            "map `{}`: starting at ({:.2}, {:.2}), heading {:.0}°",
            world.name(),
            start.x_m,
            start.y_m,
            start.theta_rad.to_degrees()
        );
    }
    // A pose an operator set earlier in the run stays in the parameters; a restarted process
    // has a later word from its previous one and takes it as already taken.
    if resume.is_none()
        && let Some(pose) = parse_pose(&set_pose)?
    {
        filter.set_pose(pose, SET_POSE_SIGMA_M, SET_POSE_SIGMA_RAD);
    }
    let mut localiser = match &resume {
        Some(kept) => Localiser::resumed(filter, kept),
        None => Localiser::new(filter),
    };
    // What was last kept and when (run time).
    let mut kept_last: Option<(Kept, f64)> = None;
    let mut latest: Option<Odometry> = None;
    let mut latest_stamp_ns = 0u64;
    let mut reported: Option<State> = None;
    // Run time of the last scan, and whether the scans are late (said once per silence).
    let mut scanned_at: Option<f64> = None;
    let mut quiet = false;
    loop {
        match node.next_event(None)? {
            Event::Input(port) if port == odometry_input.id() => {
                let Some(sample) = node.take(&odometry_input)? else {
                    continue;
                };
                latest = Some(sample.value);
                latest_stamp_ns = sample.stamp_ns;
                if let Some(kept) = resume.take() {
                    localiser.resume_at(&kept, sample.value.pose_in_odom);
                }
                if let Some(pose) = localiser.on_odometry(sample.value.pose_in_odom) {
                    let pose = Odometry {
                        pose_in_odom: pose,
                        twist: sample.value.twist,
                    };
                    node.send(&pose_output, &pose)?;
                }
                let now = node.timestamp();
                if scanned_at.is_some_and(|at| now - at > SCANS_LATE_SECS) {
                    if !quiet {
                        quiet = true;
                        tracing::warn!(
                            "no scan for {SCANS_LATE_SECS} s: going on on the odometry alone, \
                             the uncertainty growing"
                        );
                    }
                    if let Some(estimate) =
                        localiser.on_odometry_without_scans(sample.value.pose_in_odom)
                    {
                        node.send(&estimate_output, &message(&estimate))?;
                        report_state(node, &mut reported, &estimate, " (no scans)")?;
                    }
                }
            }
            Event::Input(port) if port == scan_input.id() => {
                let Some(sample) = node.take(&scan_input)? else {
                    continue;
                };
                let Some(odometry) = latest else {
                    continue;
                };
                if quiet {
                    quiet = false;
                    tracing::info!("scans again");
                }
                scanned_at = Some(node.timestamp());
                localiser
                    .filter
                    .set_pairing_skew_secs(sample.stamp_ns.abs_diff(latest_stamp_ns) as f64 / 1e9);
                let estimate = localiser.on_scan(odometry.pose_in_odom, &sample.value);
                node.send(&estimate_output, &message(&estimate))?;
                report_state(node, &mut reported, &estimate, "")?;
                keep(node, &localiser, &mut kept_last);
            }
            Event::ParamsChanged(_) => {
                let text: String = node.param("set_pose")?;
                if text != set_pose {
                    match parse_pose(&text) {
                        Ok(Some(pose)) => {
                            tracing::info!(
                                "pose set by hand: ({:.2}, {:.2}), heading {:.0}°",
                                pose.x_m,
                                pose.y_m,
                                pose.theta_rad.to_degrees()
                            );
                            localiser
                                .filter
                                .set_pose(pose, SET_POSE_SIGMA_M, SET_POSE_SIGMA_RAD);
                        }
                        Ok(None) => {}
                        Err(why) => tracing::error!("parameter `set_pose`: {why}; ignored"),
                    }
                    set_pose = text;
                }
            }
            Event::Shutdown => return Ok(()),
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::tour::{Tour, WAREHOUSE_ROUND};
    use crate::sim::{SimParams, Simulator};
    use armor_module_api::testing::{Step, TestBench};

    fn push<T: armor_module_api::types::Datum>(input: &str, value: &T) -> Step {
        Step::push(input, value).expect("encode")
    }

    fn warehouse() -> String {
        let world = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/worlds/warehouse.world");
        world.to_str().expect("a UTF-8 path").to_owned()
    }

    /// A localiser restarted in a run, handed what its previous process kept, starts where the
    /// robot is, not at the world's start: it publishes a pose from the first odometry sample
    /// (the kept correction applied to it), its estimates are within 0.3 m of the truth from
    /// the first and proven, and it keeps its own correction in turn.
    #[test]
    fn a_restarted_localiser_starts_from_what_its_previous_process_kept() {
        let world = warehouse();
        let loaded = crate::sim::load_world_file(world.as_ref()).expect("the warehouse");
        let mut sim = Simulator::new(loaded.clone(), SimParams::default()).expect("sim");
        let mut tour = Tour::new(WAREHOUSE_ROUND, 200_000);
        // The first process: 150 scans of the round (15 s, along the main aisle).
        let map = Map::new(&loaded, 0.1, 0.25).expect("map");
        let mut first = Localiser::new(Filter::new(Settings::default(), map, loaded.start(), 1));
        for _ in 0..150 {
            let report = tour.next_scan(&mut sim).expect("the round goes on");
            first.on_scan(report.odometry.pose_in_odom, sim.scan());
        }
        let kept = first.kept().expect("an estimate to keep");
        assert_eq!(kept.state, State::Localised, "{kept:?}");
        assert_eq!(Kept::parse(&kept.to_text()), Ok(kept));
        // The robot drives on for 2 s with no localiser, then the new process starts.
        for _ in 0..20 {
            tour.next_scan(&mut sim).expect("the round goes on");
        }
        let mut script = Vec::new();
        let mut truths = Vec::new();
        for _ in 0..30 {
            let report = tour.next_scan(&mut sim).expect("the round goes on");
            script.push(Step::Advance(0.1));
            script.push(push("odometry", &report.odometry));
            script.push(push("scan", &sim.scan().clone()));
            truths.push(report.truth);
        }
        let start = loaded.start();
        let far_from_start = truths[0];
        assert!(
            (far_from_start.x_m - start.x_m).hypot(far_from_start.y_m - start.y_m) > 5.0,
            "the robot is far from the world's start"
        );
        let mut bench = TestBench::new(&spec(), &[("world", &world)])
            .expect("bench")
            .with_kept(&kept.to_text());
        bench.script(script);
        body(bench.node()).expect("body");
        let poses = bench.sent::<Odometry>("pose").expect("sent");
        let estimates = bench.sent::<PoseEstimate>("estimate").expect("sent");
        assert_eq!(poses.len(), 30, "a pose from the first odometry sample");
        let off = |at: Pose2D, truth: Pose2D| (at.x_m - truth.x_m).hypot(at.y_m - truth.y_m);
        let first_pose = off(poses[0].pose_in_odom, truths[0]);
        assert!(first_pose < 0.3, "the first pose {first_pose:.3} m off");
        assert_eq!(estimates.len(), 30);
        for (estimate, truth) in estimates.iter().zip(&truths) {
            let error = off(estimate.pose_in_map, *truth);
            assert!(error < 0.3, "{error:.3} m off: {estimate:?}");
            assert!(estimate.proven, "{estimate:?}");
            assert_ne!(estimate.state, LocalisationState::Lost, "{estimate:?}");
        }
        let last_error = off(estimates[29].pose_in_map, truths[29]);
        assert!(last_error < 0.1, "{last_error:.3} m off after 3 s");
        let kept_again = bench.kept_states();
        assert!(
            !kept_again.is_empty(),
            "the new process keeps its correction"
        );
        Kept::parse(kept_again.last().expect("one")).expect("it reads back");
    }

    /// What a previous process kept decides how a restarted filter starts: lost stays lost
    /// (without `recover`), not proven must still be proven; a kept state that does not read is
    /// refused with what it should be.
    #[test]
    fn a_restart_keeps_what_was_lost_or_unproven_so() {
        let world = warehouse();
        let loaded = crate::sim::load_world_file(world.as_ref()).expect("the warehouse");
        let start = loaded.start();
        let map = Map::new(&loaded, 0.1, 0.25).expect("map");
        let filter = Filter::new(Settings::default(), map, start, 1);
        let kept = |state, proven| Kept {
            map_from_odom: Pose2D::default(),
            sigma_m: 0.05,
            sigma_rad: 0.02,
            state,
            proven,
        };
        for (state, proven, lost, must_prove) in [
            (State::Localised, true, false, false),
            (State::Uncertain, false, false, true),
            (State::Lost, false, true, true),
        ] {
            let mut localiser = Localiser::new(filter.clone());
            localiser.resume_at(&kept(state, proven), start);
            let estimate = localiser.filter.estimate();
            assert_eq!(
                estimate.state == State::Lost,
                lost,
                "{state:?}: {estimate:?}"
            );
            assert_eq!(estimate.proven, !must_prove, "{state:?}: {estimate:?}");
            assert_eq!(localiser.on_odometry(start), Some(start));
        }
        for bad in [
            "",
            "1 2 3",
            "1 2 x 0.1 0.1 localised true",
            "1 2 3 0.1 0.1 found true",
        ] {
            let err = Kept::parse(bad).expect_err(bad).to_string();
            assert!(
                err.contains("X Y THETA SIGMA_M SIGMA_RAD STATE PROVEN"),
                "{err}"
            );
        }
    }

    /// The module with a laser that goes quiet: estimates at each scan, then, once the scans
    /// are more than a second late, at each odometry sample that moved the robot, their
    /// covariance growing; the corrected pose at every odometry sample throughout.
    #[test]
    fn without_scans_the_module_goes_on_on_odometry_its_uncertainty_growing() {
        let world = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../assets/worlds/warehouse.world");
        let world = world.to_str().expect("a UTF-8 path").to_owned();
        let mut sim = Simulator::new(
            crate::sim::load_world_file(world.as_ref()).expect("the warehouse"),
            SimParams::default(),
        )
        .expect("sim");
        let mut tour = Tour::new(WAREHOUSE_ROUND, 200_000);
        let mut script = Vec::new();
        let (scanning, quiet) = (20, 40);
        for scan in 0..scanning + quiet {
            let report = tour.next_scan(&mut sim).expect("the round goes on");
            script.push(Step::Advance(0.1));
            script.push(push("odometry", &report.odometry));
            if scan < scanning {
                script.push(push("scan", &sim.scan().clone()));
            }
        }
        let mut bench = TestBench::new(&spec(), &[("world", &world)]).expect("bench");
        bench.script(script);
        body(bench.node()).expect("body");
        let estimates = bench.sent::<PoseEstimate>("estimate").expect("sent");
        let poses = bench.sent::<Odometry>("pose").expect("sent");
        // A pose per odometry sample but the first, which came before any scan.
        assert_eq!(poses.len(), scanning + quiet - 1);
        // A scan each for the first, then one per sample that moved once the scans were a
        // second late (ten periods): thirty or so of the forty.
        let quiet_estimates = &estimates[scanning..];
        assert!(
            (25..=31).contains(&quiet_estimates.len()),
            "{} estimates without scans",
            quiet_estimates.len()
        );
        let first = estimates[scanning - 1].position_sigma_m();
        let last = quiet_estimates[quiet_estimates.len() - 1].position_sigma_m();
        assert!(last > 1.5 * first, "sigma {first:.3} m, then {last:.3} m");
        let truth = sim.truth();
        let at = quiet_estimates[quiet_estimates.len() - 1].pose_in_map;
        let error = (at.x_m - truth.x_m).hypot(at.y_m - truth.y_m);
        assert!(
            error < 3.0 * last + 0.05,
            "{error:.3} m off, sigma {last:.3} m"
        );
    }
}
