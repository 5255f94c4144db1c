//! `mapper`: builds an occupancy grid from laser scans and odometry, and corrects the robot's
//! pose by matching each scan against the map built so far, closing loops when it comes back to
//! a place it mapped long before (2-D graph SLAM).
//!
//! Each scan is paired with the latest odometry. The pose predicted for it is the previous
//! corrected pose moved by the odometry's increment since the previous scan; the [`matcher`]
//! searches a window around that prediction for the pose whose scan points best fit the map
//! (a coarse-to-fine correlative search on the grid's likelihood field, refined by
//! point-to-line ICP against the mean echo position kept per cell). The scan is then
//! integrated into the [`grid`] from the corrected pose (log-odds, clamped: free along each
//! beam, occupied where it ends on an echo), and the pose is published. A scan with too few
//! echoes on the mapped part of the grid, or whose best match is poor, is placed at the
//! prediction.
//!
//! Matching against the map so far holds the pose for a while, but its error grows with the
//! way travelled: back at a place mapped long before, the robot is off by that error, and the
//! map holds two copies of what it sees again. The [`closure`] keeps keyframes with their scans,
//! matches a new keyframe against earlier ones nearby with a search as wide as that error, and
//! optimises a [`graph`] of the keyframes' poses with what it found; the grid is then drawn again
//! from the keyframes at their corrected poses, and the corrected pose jumps to where the loop
//! put it. The parameter `loop_closure` turns this off (the mapper of before, for comparison).
//!
//! [`Mapper`] is the whole algorithm without a node, for tests and benchmarks: feed it scans
//! with the odometry pose of each ([`Mapper::on_scan`]), read the map
//! ([`Mapper::occupancy_grid`]) and the time it took ([`Mapper::stats`]). In release builds a
//! 360-beam scan takes about 0.35 ms (match, integration and keyframe) on the office floor of
//! `building.world`; a scan that closes a loop also waits for the graph's optimisation and the
//! grid drawn again (`armor-bench mapper_scan_ms` gave a p99 of 12 ms on a loaded machine).
//!
//! The map frame is the odometry frame at the first scan: the first corrected pose is the first
//! odometry pose, and the grid is a square centred on it. With the simulator, whose odometry
//! starts at the world's start pose, the map frame is thus the world frame, and the corrected
//! pose can stand in for odometry wherever goals are given in world coordinates.

pub mod closure;
pub mod graph;
pub mod grid;
pub mod matcher;

use std::time::Instant;

use armor_module_api::types::{
    Frame, LaserScan, LocalisationState, Marker, Markers, OccupancyGrid, Odometry, Pose2D,
    PoseEstimate, Shape,
};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;
use crate::nav::wrap_angle;
use closure::{KeyframeSpacing, LoopCloser};
use grid::LogOddsGrid;
use matcher::{Matcher, SearchWindow};

pub const TYPE: &str = "mapper";

/// Echoes closer than this are ignored (the robot's own body, or noise around zero).
pub const MIN_RANGE_M: f64 = 0.05;
/// A match whose points score less than this on average is not trusted: the scan is placed
/// at the odometry's prediction instead.
pub const MIN_MATCH_SCORE: f64 = 0.1;
/// Scans with fewer echoes than this are not matched (placed at the prediction).
pub const MIN_MATCH_POINTS: usize = 20;
/// The corrected pose's standard deviation, in position and heading: a base, plus so much per
/// metre of the way its error grew over ([`LoopCloser::way_from_origin_m`]: from the map
/// frame's origin through the keyframes, a closed loop cutting it short), plus the odometry's
/// own drift per metre driven on the prediction alone (scans not matched) since the last loop
/// correction. Measured round the office floor with the simulator's default noise (the test
/// `the_mappers_covariance_holds_its_true_error`, three seeds): the true error is within two
/// standard deviations at 95 % of the scans and within 2.5 at every one.
pub const SIGMA_BASE_M: f64 = 0.06;
pub const SIGMA_PER_M: f64 = 0.002;
pub const SIGMA_BASE_RAD: f64 = 0.01;
pub const SIGMA_RAD_PER_M: f64 = 0.001;
pub const SIGMA_UNMATCHED_PER_M: f64 = 0.05;
/// The state the estimate reports, from its position's standard deviation alone (the same
/// thresholds as the localiser's): `localised` up to this ...
pub const LOCALISED_SIGMA_M: f64 = 0.15;
/// ... `lost` above this, `uncertain` between.
pub const LOST_SIGMA_M: f64 = 1.0;

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Builds an occupancy grid from laser scans and odometry, correcting the odometry's drift \
         by matching each scan against the map built so far and closing loops (keyframes matched \
         against earlier ones, a pose graph optimised); publishes the map and the corrected pose \
         in the map frame (the odometry frame at the first scan).",
    )
    .category(armor_module_api::Category::Mapping)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .input::<LaserScan>(
        "scan",
        "laser scan in the robot's frame, from the robot's centre; each one is matched and \
         integrated with the latest odometry (latest value used)",
    )
    .input::<Odometry>(
        "odometry",
        "dead-reckoned pose, for the motion between two scans (latest value used; scans are \
         ignored until the first one arrives)",
    )
    .output::<OccupancyGrid>(
        "map",
        "the occupancy grid in the map frame, every 1 / map_rate_hz of run time once a scan has \
         been integrated: -1 unknown, 0 free … 100 occupied",
    )
    .output::<Odometry>(
        "pose",
        "the corrected pose in the map frame (and the odometry's twist), after every integrated \
         scan and at every odometry sample between (the latest scan's correction applied to \
         it): a drop-in replacement for odometry, which jumps when a loop closes",
    )
    .output::<Pose2D>("pose_map", "the same corrected pose, for display")
    .output::<PoseEstimate>(
        "estimate",
        "the corrected pose with its covariance (x, y, heading) after every integrated scan, as \
         the localiser's estimate: its standard deviation grows with the way driven since the \
         map's origin through the keyframes (a closed loop cuts it short); the fit is the last \
         match's score; the state `localised` up to 0.15 m, `lost` beyond 1 m",
    )
    .output::<Markers>(
        "markers",
        "the last scan placed, drawn from the corrected pose (the map's frame), five times a \
         second of run time",
    )
    .param(
        ParamSpec::new(
            "resolution_m",
            ParamType::Float,
            "side of a grid cell (greater than 0; taken at restart)",
        )
        .above(0.0)
        .unit("m")
        .default("0.1"),
    )
    .param(
        ParamSpec::new(
            "size_m",
            ParamType::Float,
            "side of the square grid, centred on the pose of the first scan (at least \
             resolution_m, at most 4000 cells a side; taken at restart)",
        )
        .above(0.0)
        .unit("m")
        .default("60"),
    )
    .param(
        ParamSpec::new(
            "match_search_m",
            ParamType::Float,
            "the scan matcher looks this far from the odometry's prediction, each way in x and y \
             (0 or more, at most 2; with 0, positions are only refined; tunable live)",
        )
        .min(0.0)
        .max(2.0)
        .unit("m")
        .default("0.3"),
    )
    .param(
        ParamSpec::new(
            "match_search_deg",
            ParamType::Float,
            "the scan matcher looks this far from the predicted heading, each way (0 or more, at \
             most 45; with 0, headings are only refined; tunable live)",
        )
        .min(0.0)
        .max(45.0)
        .unit("deg")
        .default("10"),
    )
    .param(
        ParamSpec::new(
            "max_range_m",
            ParamType::Float,
            "beams are used up to this range: longer echoes only clear the cells before it \
             (greater than 0, at most 100; tunable live)",
        )
        .above(0.0)
        .max(100.0)
        .unit("m")
        .default("7.5"),
    )
    .param(
        ParamSpec::new(
            "map_rate_hz",
            ParamType::Float,
            "how often the map is published, per second of run time (greater than 0, at most \
             100; tunable live)",
        )
        .above(0.0)
        .max(100.0)
        .unit("Hz")
        .default("1"),
    )
    .param(
        ParamSpec::new(
            "loop_closure",
            ParamType::Bool,
            "match keyframes against earlier ones and correct the map and pose when a loop \
             closes (tunable live: turned off, the keyframes made so far are kept for when it \
             is turned on again)",
        )
        .default("true"),
    )
    .param(
        ParamSpec::new(
            "keyframe_m",
            ParamType::Float,
            "a keyframe, kept with its scan for loop closure, is made every this many metres of \
             the corrected pose (greater than 0, at most 10; tunable live)",
        )
        .above(0.0)
        .max(10.0)
        .unit("m")
        .default("1"),
    )
    .param(
        ParamSpec::new(
            "keyframe_deg",
            ParamType::Float,
            "... or every this many degrees of turn (greater than 0, at most 180; tunable live)",
        )
        .above(0.0)
        .max(180.0)
        .unit("deg")
        .default("30"),
    )
}

/// The mapper's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    pub resolution_m: f64,
    pub size_m: f64,
    pub match_search_m: f64,
    pub match_search_deg: f64,
    pub max_range_m: f64,
    pub map_rate_hz: f64,
    pub loop_closure: bool,
    pub keyframe_m: f64,
    pub keyframe_deg: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            resolution_m: 0.1,
            size_m: 60.0,
            match_search_m: 0.3,
            match_search_deg: 10.0,
            max_range_m: 7.5,
            map_rate_hz: 1.0,
            loop_closure: true,
            keyframe_m: 1.0,
            keyframe_deg: 30.0,
        }
    }
}

impl Settings {
    /// Reads and checks the parameters, refusing nonsense in words.
    pub fn read(node: &Node) -> Result<Self, BodyError> {
        let settings = Self {
            resolution_m: node.param::<f64>("resolution_m")?,
            size_m: node.param::<f64>("size_m")?,
            match_search_m: node.param::<f64>("match_search_m")?,
            match_search_deg: node.param::<f64>("match_search_deg")?,
            max_range_m: node.param::<f64>("max_range_m")?,
            map_rate_hz: node.param::<f64>("map_rate_hz")?,
            loop_closure: node.param::<bool>("loop_closure")?,
            keyframe_m: node.param::<f64>("keyframe_m")?,
            keyframe_deg: node.param::<f64>("keyframe_deg")?,
        };
        settings.check_grid()?;
        Ok(settings)
    }

    fn check_grid(&self) -> Result<(), BodyError> {
        let side = (self.size_m / self.resolution_m).round();
        if (1.0..=grid::MAX_SIDE_CELLS as f64).contains(&side) {
            Ok(())
        } else {
            Err(format!(
                "parameters `size_m` and `resolution_m` give a grid of {side} cells a side (1 to \
                 {}): {} m at {} m",
                grid::MAX_SIDE_CELLS,
                self.size_m,
                self.resolution_m
            )
            .into())
        }
    }

    fn window(&self) -> SearchWindow {
        SearchWindow {
            linear_m: self.match_search_m,
            angular_rad: self.match_search_deg.to_radians(),
        }
    }

    fn keyframe_spacing(&self) -> KeyframeSpacing {
        KeyframeSpacing {
            linear_m: self.keyframe_m,
            angular_rad: self.keyframe_deg.to_radians(),
        }
    }
}

/// `a ⊕ b`: the pose `b`, given relative to `a`, in `a`'s frame.
pub fn compose(a: Pose2D, b: Pose2D) -> Pose2D {
    let (sin, cos) = a.theta_rad.sin_cos();
    Pose2D {
        x_m: a.x_m + cos * b.x_m - sin * b.y_m,
        y_m: a.y_m + sin * b.x_m + cos * b.y_m,
        theta_rad: wrap_angle(a.theta_rad + b.theta_rad),
    }
}

/// `a⁻¹ ⊕ b`: the pose `b` seen from `a` (the motion from `a` to `b`, in `a`'s frame).
pub fn between(a: Pose2D, b: Pose2D) -> Pose2D {
    let (sin, cos) = a.theta_rad.sin_cos();
    let (dx, dy) = (b.x_m - a.x_m, b.y_m - a.y_m);
    Pose2D {
        x_m: cos * dx + sin * dy,
        y_m: -sin * dx + cos * dy,
        theta_rad: wrap_angle(b.theta_rad - a.theta_rad),
    }
}

/// What the mapper has done so far.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Scans integrated into the map.
    pub scans: u64,
    /// ... of which placed where the matcher put them (the others at the prediction).
    pub matched: u64,
    /// Time spent in [`Mapper::on_scan`], in seconds.
    pub busy_secs: f64,
    /// Keyframes made, loop edges added to their graph, and the times a loop edge moved them
    /// (and the grid was drawn again).
    pub keyframes: u64,
    pub loop_closures: u64,
    pub optimisations: u64,
}

impl Stats {
    /// The mean time per scan, in milliseconds.
    pub fn ms_per_scan(&self) -> f64 {
        if self.scans == 0 {
            0.0
        } else {
            1e3 * self.busy_secs / self.scans as f64
        }
    }
}

/// The mapping itself, without a node: feed it scans with the odometry pose of each.
#[derive(Clone, Debug)]
pub struct Mapper {
    settings: Settings,
    grid: Option<LogOddsGrid>,
    matcher: Matcher,
    closer: LoopCloser,
    /// The corrected pose of the last integrated scan, and the odometry pose it was paired with
    /// (None after [`Mapper::forget_odometry`]).
    last: Option<(Pose2D, Option<Pose2D>)>,
    stats: Stats,
    beams: Vec<(f64, f64, bool)>,
    points: Vec<(f64, f64)>,
    /// The way travelled by the corrected pose, and the part of it placed at the odometry's
    /// prediction (no match) since the last loop correction.
    travelled_m: f64,
    unmatched_m: f64,
    /// The last match's score (0 when placed at the prediction).
    match_score: f64,
}

impl Mapper {
    pub fn new(settings: Settings) -> Result<Self, BodyError> {
        settings.check_grid()?;
        Ok(Self {
            settings,
            grid: None,
            matcher: Matcher::default(),
            closer: LoopCloser::default(),
            last: None,
            stats: Stats::default(),
            beams: Vec::new(),
            points: Vec::new(),
            travelled_m: 0.0,
            unmatched_m: 0.0,
            match_score: 0.0,
        })
    }

    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Takes new settings; the grid's resolution and size only apply to a new mapper.
    pub fn retune(&mut self, settings: Settings) {
        let (resolution_m, size_m) = (self.settings.resolution_m, self.settings.size_m);
        self.settings = Settings {
            resolution_m,
            size_m,
            ..settings
        };
    }

    pub fn stats(&self) -> Stats {
        let (loop_closures, optimisations) = self.closer.closures();
        Stats {
            keyframes: self.closer.graph().poses().len() as u64,
            loop_closures,
            optimisations,
            ..self.stats
        }
    }

    /// The keyframes' poses, as the last loop closure corrected them.
    pub fn keyframe_poses(&self) -> &[Pose2D] {
        self.closer.graph().poses()
    }

    /// The corrected pose of the last integrated scan.
    pub fn pose(&self) -> Option<Pose2D> {
        self.last.map(|(pose, _)| pose)
    }

    /// The corrected pose of the last integrated scan with its covariance ([`SIGMA_PER_M`]).
    pub fn estimate(&self) -> Option<PoseEstimate> {
        let pose = self.pose()?;
        let way_m = if self.settings.loop_closure {
            self.closer.way_from_origin_m()
        } else {
            self.travelled_m
        };
        let sigma_m = SIGMA_BASE_M + SIGMA_PER_M * way_m + SIGMA_UNMATCHED_PER_M * self.unmatched_m;
        let sigma_rad = SIGMA_BASE_RAD + SIGMA_RAD_PER_M * way_m;
        let state = if sigma_m <= LOCALISED_SIGMA_M {
            LocalisationState::Localised
        } else if sigma_m <= LOST_SIGMA_M {
            LocalisationState::Uncertain
        } else {
            LocalisationState::Lost
        };
        Some(PoseEstimate {
            pose_in_map: pose,
            covariance: PoseEstimate::diagonal_covariance(sigma_m, sigma_rad),
            fit: self.match_score,
            state,
            // The mapper has no look-alike places to tell apart: its pose is where its own
            // matches put it, and its covariance says how far that may be from the truth.
            proven: true,
        })
    }

    /// The grid, once a scan has been integrated.
    pub fn grid(&self) -> Option<&LogOddsGrid> {
        self.grid.as_ref()
    }

    /// The map as published, once a scan has been integrated.
    pub fn occupancy_grid(&self) -> Option<OccupancyGrid> {
        self.grid.as_ref().map(LogOddsGrid::to_occupancy_grid)
    }

    /// The odometry restarted (a new provider): the next scan is predicted at the last
    /// corrected pose, and the matcher finds the motion alone.
    pub fn forget_odometry(&mut self) {
        if let Some((_, odometry)) = &mut self.last {
            *odometry = None;
        }
        self.closer.forget_odometry();
    }

    /// Matches a scan taken at the odometry pose `odometry`, integrates it, and returns the
    /// corrected pose. Refuses a scan whose geometry is not finite.
    pub fn on_scan(&mut self, scan: &LaserScan, odometry: Pose2D) -> Result<Pose2D, String> {
        let started = Instant::now();
        check_finite(scan, odometry)?;
        self.read_beams(scan);
        let pose = match self.last {
            None => odometry,
            Some((previous, last_odometry)) => {
                let predicted = match last_odometry {
                    Some(last_odometry) => compose(previous, between(last_odometry, odometry)),
                    None => previous,
                };
                self.corrected(predicted)
            }
        };
        self.integrate_at(pose)?;
        if let Some((previous, _)) = self.last {
            let step_m = (pose.x_m - previous.x_m).hypot(pose.y_m - previous.y_m);
            self.travelled_m += step_m;
            if self.match_score <= 0.0 {
                self.unmatched_m += step_m;
            }
        }
        let corrections = self.closer.closures().1;
        let pose = if self.settings.loop_closure {
            self.close_loops(pose, odometry)?
        } else {
            pose
        };
        if self.closer.closures().1 > corrections {
            self.unmatched_m = 0.0;
        }
        self.last = Some((pose, Some(odometry)));
        self.stats.scans += 1;
        self.stats.busy_secs += started.elapsed().as_secs_f64();
        Ok(pose)
    }

    /// Integrates a scan taken at a known `pose` in the map frame, without matching: the grid
    /// update alone (a map from the true pose; the reference of `armor-bench mapper_scan_ms`).
    /// The pose and statistics of [`Mapper::on_scan`] are left alone.
    pub fn place_scan(&mut self, scan: &LaserScan, pose: Pose2D) -> Result<(), String> {
        check_finite(scan, pose)?;
        self.read_beams(scan);
        self.integrate_at(pose)
    }

    /// Hands the scan just integrated to the loop closure, and when a loop moved the keyframes,
    /// draws the grid again from them; returns the pose of the scan, corrected by the loop.
    fn close_loops(&mut self, pose: Pose2D, odometry: Pose2D) -> Result<Pose2D, String> {
        let spacing = self.settings.keyframe_spacing();
        let resolution_m = self.settings.resolution_m;
        let Some(grid) = &self.grid else {
            return Ok(pose);
        };
        let Some(closed) = self.closer.on_scan(
            grid,
            pose,
            odometry,
            &self.beams,
            &self.points,
            spacing,
            resolution_m,
        ) else {
            return Ok(pose);
        };
        // Smaller moves than half a cell would leave the grid as it is.
        if closed.largest_move_m >= resolution_m / 2.0
            && let Some(old) = &self.grid
        {
            let (origin_x_m, origin_y_m) = old.origin();
            let mut grid = LogOddsGrid::new(
                resolution_m,
                old.width(),
                old.height(),
                origin_x_m,
                origin_y_m,
            )?;
            for (at, keyframe) in self.closer.keyframes() {
                grid.integrate(at, keyframe.beams.iter().copied());
            }
            self.grid = Some(grid);
        }
        Ok(closed.pose)
    }

    /// Puts the beams read last into the grid from `pose` (making the grid, centred there, at
    /// the first scan).
    fn integrate_at(&mut self, pose: Pose2D) -> Result<(), String> {
        let grid = match &mut self.grid {
            Some(grid) => grid,
            None => self.grid.insert(LogOddsGrid::centred(
                self.settings.resolution_m,
                self.settings.size_m,
                pose.x_m,
                pose.y_m,
            )?),
        };
        grid.integrate(pose, self.beams.iter().copied());
        Ok(())
    }

    /// The scan's beams as (angle, length, ends on an echo), lengths cut to `max_range_m`, and
    /// the echoes' points for the matcher, thinned so that consecutive points are at least half
    /// a cell apart.
    fn read_beams(&mut self, scan: &LaserScan) {
        let max_range = self.settings.max_range_m;
        let min_gap = self.settings.resolution_m / 2.0;
        self.beams.clear();
        self.points.clear();
        for (i, &range) in scan.ranges_m.iter().enumerate() {
            let range = f64::from(range);
            if !range.is_finite() || range < MIN_RANGE_M {
                continue;
            }
            let angle = scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
            let echo = range < scan.range_max_m && range <= max_range;
            self.beams.push((angle, range.min(max_range), echo));
            if echo {
                let point = (range * angle.cos(), range * angle.sin());
                let far_enough = self
                    .points
                    .last()
                    .is_none_or(|&(x, y)| (point.0 - x).hypot(point.1 - y) >= min_gap);
                if far_enough {
                    self.points.push(point);
                }
            }
        }
    }

    /// The pose the matcher finds around the prediction, or the prediction when the match is
    /// not to be trusted.
    fn corrected(&mut self, predicted: Pose2D) -> Pose2D {
        self.match_score = 0.0;
        let Some(grid) = &self.grid else {
            return predicted;
        };
        if self.points.len() < MIN_MATCH_POINTS {
            return predicted;
        }
        let window = self.settings.window();
        match self
            .matcher
            .match_scan(grid, &self.points, predicted, window)
        {
            Some(found) if found.score >= MIN_MATCH_SCORE && found.points >= MIN_MATCH_POINTS => {
                self.stats.matched += 1;
                self.match_score = found.score;
                found.pose
            }
            _ => predicted,
        }
    }
}

/// Refuses a scan whose geometry, or a pose, that is not finite.
fn check_finite(scan: &LaserScan, pose: Pose2D) -> Result<(), String> {
    let finite = [
        scan.angle_min_rad,
        scan.angle_increment_rad,
        scan.range_max_m,
        pose.x_m,
        pose.y_m,
        pose.theta_rad,
    ]
    .iter()
    .all(|v| v.is_finite());
    if finite {
        Ok(())
    } else {
        Err(format!(
            "ignored a scan or odometry that is not finite (angle_min_rad {}, \
             angle_increment_rad {}, range_max_m {}, odometry {pose:?})",
            scan.angle_min_rad, scan.angle_increment_rad, scan.range_max_m
        ))
    }
}

/// How often, in run time, the last scan placed is drawn again.
const MARKERS_EVERY_SECS: f64 = 0.2;

/// The echoes of `scan` seen from `pose`, in the map's frame: where the matcher placed them.
fn placed_scan(scan: &LaserScan, pose: Pose2D) -> Markers {
    let hits = scan.ranges_m.iter().enumerate().filter_map(|(i, &range)| {
        let range = f64::from(range);
        if !range.is_finite() || range <= 0.0 || range >= scan.range_max_m {
            return None;
        }
        let angle = pose.theta_rad + scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
        Some((
            pose.x_m + range * angle.cos(),
            pose.y_m + range * angle.sin(),
        ))
    });
    let mut points = Marker::new(Shape::Points, Frame::World, [20, 170, 190, 220], hits)
        .with_text("last scan placed");
    points.size_px = 1.5;
    Markers {
        markers: vec![points],
    }
}

pub fn body(node: &mut Node) -> BodyResult {
    let scan_input = node.input::<LaserScan>("scan")?;
    let odometry_input = node.input::<Odometry>("odometry")?;
    let map_output = node.output::<OccupancyGrid>("map")?;
    let pose_output = node.output::<Odometry>("pose")?;
    let pose_map_output = node.output::<Pose2D>("pose_map")?;
    let estimate_output = node.output::<PoseEstimate>("estimate")?;
    let markers_output = node.output::<Markers>("markers")?;
    let mut markers_sent = f64::NEG_INFINITY;
    let mut mapper = Mapper::new(Settings::read(node)?)?;
    let settings = mapper.settings();
    tracing::info!(
        "a {} m grid at {} m; matching within {} m and {}°",
        settings.size_m,
        settings.resolution_m,
        settings.match_search_m,
        settings.match_search_deg
    );
    // The latest odometry and the link that brought it.
    let mut odometry: Option<(u64, Odometry)> = None;
    // The map pose of the odometry frame's origin at the latest scan: each odometry sample
    // between scans is published corrected by it, so that a follower driving on `pose` gets
    // a pose as often as it got odometry, not one per scan a scan period old.
    let mut map_from_odom: Option<Pose2D> = None;
    let mut warned_no_odometry = false;
    let mut next_map = node.timestamp() + 1.0 / mapper.settings().map_rate_hz;
    loop {
        let deadline = node.clock().instant_at(next_map);
        match node.next_event_until(deadline)? {
            Event::Input(port) if port == odometry_input.id() => {
                if let Some(sample) = node.take(&odometry_input)? {
                    if odometry.is_some_and(|(link, _)| link != sample.link) {
                        tracing::warn!("the odometry restarted: matching the next scan alone");
                        mapper.forget_odometry();
                        map_from_odom = None;
                    }
                    odometry = Some((sample.link, sample.value));
                    if let Some(correction) = map_from_odom {
                        let corrected = Odometry {
                            pose_in_odom: compose(correction, sample.value.pose_in_odom),
                            twist: sample.value.twist,
                        };
                        node.send(&pose_output, &corrected)?;
                    }
                }
            }
            Event::Input(port) if port == scan_input.id() => {
                let Some(sample) = node.take(&scan_input)? else {
                    continue;
                };
                let Some((_, latest)) = odometry else {
                    if !warned_no_odometry {
                        tracing::warn!("no odometry yet: ignoring scans until it comes");
                        warned_no_odometry = true;
                    }
                    continue;
                };
                match mapper.on_scan(&sample.value, latest.pose_in_odom) {
                    Ok(pose) => {
                        map_from_odom = Some(compose(
                            pose,
                            between(latest.pose_in_odom, Pose2D::default()),
                        ));
                        let corrected = Odometry {
                            pose_in_odom: pose,
                            twist: latest.twist,
                        };
                        node.send(&pose_output, &corrected)?;
                        node.send(&pose_map_output, &pose)?;
                        if let Some(estimate) = mapper.estimate() {
                            node.send(&estimate_output, &estimate)?;
                        }
                        if node.timestamp() - markers_sent >= MARKERS_EVERY_SECS {
                            markers_sent = node.timestamp();
                            node.send(&markers_output, &placed_scan(&sample.value, pose))?;
                        }
                    }
                    Err(why) => tracing::warn!("{why}"),
                }
            }
            Event::Timeout => {
                if let Some(map) = mapper.occupancy_grid() {
                    node.send(&map_output, &map)?;
                }
                let now = node.timestamp();
                next_map += 1.0 / mapper.settings().map_rate_hz;
                if next_map <= now {
                    next_map = now + 1.0 / mapper.settings().map_rate_hz;
                }
            }
            Event::ParamsChanged(names) => match Settings::read(node) {
                Ok(settings) => {
                    if names
                        .iter()
                        .any(|name| name == "resolution_m" || name == "size_m")
                    {
                        tracing::warn!(
                            "new values of resolution_m and size_m are taken at restart"
                        );
                    }
                    mapper.retune(settings);
                }
                Err(err) => tracing::error!("{err}; keeping the previous settings"),
            },
            Event::Shutdown => {
                let stats = mapper.stats();
                tracing::info!(
                    "{} scans integrated, {} placed by the matcher; {:.2} ms per scan; {} \
                     keyframes, {} loop edges, {} corrections",
                    stats.scans,
                    stats.matched,
                    stats.ms_per_scan(),
                    stats.keyframes,
                    stats.loop_closures,
                    stats.optimisations
                );
                return Ok(());
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests;
