//! Monte Carlo localisation on a known map, pure: no IO, no clock, its randomness from a seeded
//! generator, so that a run is repeated exactly by the same seed, odometry and scans.
//!
//! - Motion: `sample_motion_model_odometry` (Thrun, Burgard and Fox, *Probabilistic Robotics*,
//!   table 5.6): the odometry's motion between two filter updates split into a turn, a
//!   straight line and a turn, each drawn with noise whose variance grows with the motion
//!   (`alpha`, as AMCL's `odom_alpha1..4`).
//! - Measurement: the likelihood field of the map (the mapper's [`LogOddsGrid`], built once from
//!   the map's occupied cells with a field wider than the mapper's), a mixture of a hit
//!   (Gaussian of the distance from a beam's end to the nearest wall) and a random reading, on
//!   a subset of the beams; the log-likelihoods are tempered (`effective_beams`), because
//!   neighbouring beams are not independent and a product over all of them makes every
//!   particle but one weigh nothing.
//! - Resampling: low-variance (systematic), to a count chosen by KLD sampling (Fox 2003): as
//!   many particles as keep the error of the estimated distribution under `kld_err` with
//!   probability `kld_z`, for the number of histogram bins the particles occupy, within
//!   `min_particles..=max_particles`.
//! - Confidence: the particles' covariance, how well the scan fits the map at the estimate
//!   (the mean field value at the beams' ends, smoothed over scans) and how many beams read
//!   what the map says they should from there (ranges cast in the world, the beams with no
//!   echo included) give [`State`]: a cloud can be tight and wrong (a robot carried
//!   elsewhere), which only the scan shows.
//! - Clusters: the particles are grouped by place; each group is resampled on its own, keeping
//!   its weight, and the estimate is the heaviest group's mean, so that two places alike stay
//!   two until the scans tell them apart, and a second one in the running means `uncertain`.
//! - Global mode: particles spread over the map's free space, placed by the first scan where
//!   it fits best of many proposals ([`Filter::propose`]). On a map with places alike (the
//!   warehouse's aisles of shelving) the cloud may still settle on the wrong one, so a place
//!   found by a search must prove itself ([`CONFIRM_M`]) before it is called `localised`, and
//!   recovering by itself when lost is off by default (`recover`, measured in the tests): a
//!   lost localiser stays lost until an operator sets the pose.
//! - Without scans ([`Filter::predict_only`]): the motion model alone, the covariance growing
//!   with the way driven.

use std::collections::VecDeque;

use rustc_hash::{FxHashMap, FxHashSet};

use armor_model::geo::Point;
use armor_model::world::World;
use armor_module_api::types::{LaserScan, Pose2D};

use crate::mapper::grid::LogOddsGrid;
use crate::sim::rng::Rng;
use crate::wrap_angle;

/// The likelihood field's cell, in metres.
pub const FIELD_RESOLUTION_M: f64 = 0.05;
/// Bins of the KLD histogram: position and heading.
const KLD_BIN_M: f64 = 0.5;
const KLD_BIN_RAD: f64 = 10.0 * std::f64::consts::PI / 180.0;
/// The faces of the world are sampled this often along their length for the field.
const FACE_SAMPLE_M: f64 = 0.01;
/// A face is seen from a side when a point this far from it on that side is in the open: more
/// than the width of the grid cells a thin wall is drawn in, on both sides of it.
const FACE_SIDE_M: f64 = 0.08;
/// Free space for the global mode is sampled on a lattice of this pitch.
const FREE_PITCH_M: f64 = 0.2;
/// The particles are resampled when their effective number (1 / Σ w²) falls below this
/// fraction of their number.
const RESAMPLE_BELOW: f64 = 0.5;
/// Updates made after the pose is set or the particles spread, even with the robot still.
const FORCED_UPDATES: u32 = 3;
/// A localised estimate stays localised until its standard deviations grow by this factor
/// beyond the thresholds, or its fit falls by it below.
const LEAVE_LOCALISED: f64 = 1.35;
/// Global mode scores this many poses per particle kept.
const PROPOSALS_PER_PARTICLE: usize = 20;
/// For this many updates after a spread, the scans count for this fraction of their usual
/// weight.
const SOFT_UPDATES: u32 = 60;
const SOFT_FACTOR: f64 = 0.15;
/// Lost again this many updates after spreading the particles, they are spread again (they
/// did not find the robot, or it was carried off once more).
const SPREAD_AGAIN_UPDATES: u32 = 100;
/// How fast the scan's fit is smoothed from scan to scan (weight of the newest).
const FIT_SMOOTHING: f64 = 0.3;
/// Particles are clustered on cells of this side: two particles in the same or neighbouring
/// cells are in one cluster (one hypothesis of where the robot is).
const CLUSTER_CELL_M: f64 = 0.5;
/// A cluster whose weight falls below this share is dropped at resampling: the scans have
/// ruled that place out.
const DROP_CLUSTER_WEIGHT: f64 = 1e-3;
/// A beam agrees with the map when its range is within this of the map's.
const AGREE_M: f64 = 0.3;
/// The kidnap detector takes a scan only when the beams it weighs count for at least this
/// share of its beams (see [`Agreement`]).
const MIN_JUDGED_BEAMS: f64 = 0.25;
/// Localised needs at least this share of the beams agreeing with the map (smoothed), and
/// stays so down to `STAY_LOCALISED_AGREEMENT`: at the truth it stays above 0.95, and a robot
/// carried to a look-alike place of the office's corridor read 0.64 to 0.86 there.
const LOCALISED_AGREEMENT: f64 = 0.9;
const STAY_LOCALISED_AGREEMENT: f64 = 0.85;
/// Lost when fewer than this share of the beams agree with the map: the map says walls where
/// the laser sees none, or none where it sees them, whatever the fit of the echoes.
const LOST_AGREEMENT: f64 = 0.5;
/// A second cluster holding this share of the weight or more makes the estimate uncertain,
/// however tight the best one: the robot may be at either place.
const SIGNIFICANT_CLUSTER: f64 = 0.05;
/// Each cluster kept gets at least this many particles at resampling, so that a place the
/// scans cannot yet tell from the best one keeps enough particles to follow the motion.
const MIN_CLUSTER_PARTICLES: usize = 30;
/// After a search of the map (global mode, or recovering when lost) or a wide cloud left by a
/// laser that went quiet, an estimate that meets every threshold of `localised` must still prove
/// itself before it says so: the best cluster held, each update where the odometry moved it
/// (within [`CONFIRM_JUMP_M`] and [`CONFIRM_JUMP_RAD`]), with at least [`CONFIRM_AGREEMENT`] of
/// the beams agreeing, over [`CONFIRM_M`] of travel and [`CONFIRM_UPDATES`] updates in a row.
/// A look-alike place fits from where the robot was carried to, not along the way on from
/// there. Measured on twenty seeded kidnaps (the tests): with 3 m, one of them still said
/// `localised` 44 m off, at the warehouse's other end, which is the same place turned round
/// within the laser's reach; with 5 m, none did.
const CONFIRM_M: f64 = 5.0;
const CONFIRM_UPDATES: u32 = 50;
const CONFIRM_AGREEMENT: f64 = 0.93;
const CONFIRM_JUMP_M: f64 = 0.2;
const CONFIRM_JUMP_RAD: f64 = 0.1;
/// A full turn in place proves a place too (a follower turns in place while the estimate is
/// not proven, rather than drive on it, as Nav2's spin recovery does): the same test at every
/// update over [`CONFIRM_TURN_RAD`] of turning and [`CONFIRM_TURN_UPDATES`] updates, with less
/// than [`CONFIRM_TURN_TRAVEL_M`] of travel since the turn began (more, and the turn is counted
/// again from there: turning at a drive's corners is not turning in place). Turned round in
/// place, the laser has seen everything within its reach from there, each part from the pose
/// the odometry gives.
const CONFIRM_TURN_RAD: f64 = 2.0 * std::f64::consts::PI;
const CONFIRM_TURN_UPDATES: u32 = 30;
const CONFIRM_TURN_TRAVEL_M: f64 = 0.1;
/// A turn in place proves a place only where the walls within the laser's reach pin it down in
/// every direction: the directions of the walls the beams ended on over the turn (the field's
/// gradient there), as an information matrix, must have its smaller eigenvalue at least this
/// share of the larger. Standing in a long aisle, the laser sees two parallel walls and the
/// aisle's position along itself is unknown (measured: a turn in place in a warehouse aisle
/// proved a place 0.94 m off along it).
const CONFIRM_TURN_OBSERVABLE: f64 = 0.1;
/// The kidnap detector: a step down in the beams' agreement against its recent history. The
/// agreement smoothed over scans (weight [`FIT_SMOOTHING`], about three scans) is compared with
/// its long-term average (weight [`AGREEMENT_HISTORY`], about fifty updates); when it falls more
/// than [`KIDNAP_STEP`] below it, the robot may have been carried to a place that only looks
/// like where the estimate is, and the estimate must prove itself again ([`CONFIRM_M`], or a
/// turn in place). Measured (the tests): on un-kidnapped drives (the warehouse round, the
/// office loop and the yard round, with the default noise and three times it; a laser quiet
/// for 3 s and for 25 s) the step reached at most 0.026; carried into a look-alike aisle of the
/// warehouse it was 0.052 or more within three scans, every other kidnap more. The history
/// needs [`KIDNAP_HISTORY_UPDATES`] updates of a proven estimate before the detector is armed.
/// This is augmented MCL's idea (Nav2's `recovery_alpha_fast`/`recovery_alpha_slow`, a short-
/// against a long-term average) on the agreement rather than on the particles' likelihood:
/// measured on the same drives, the likelihood's step on a carrying to a look-alike aisle
/// (0.12 per beam, in logarithms) was smaller than its swings on a plain drive with three times
/// the noise (0.54).
const AGREEMENT_HISTORY: f64 = 0.02;
const KIDNAP_STEP: f64 = 0.045;
const KIDNAP_HISTORY_UPDATES: u32 = 10;
/// The detector skips updates that turned more than this since the last (0.4 rad/s at the
/// simulator's 10 scans a second): in a running system the scan and the odometry it is paired
/// with are a few milliseconds apart, and turning fast that moves the far beams' ends by tens of
/// centimetres, which the agreement counts as disagreeing (measured: a false alarm on Nav2's
/// depot map as the follower turned in place at 1.2 rad/s, with no kidnap).
const KIDNAP_MAX_TURN_RAD: f64 = 0.04;
/// For the same reason the detector skips scans paired with odometry more than this apart (the
/// simulator's odometry comes every 20 ms; a loaded machine delays one or the other: a false
/// alarm on the depot map came with the simulator running 10 s behind), and the step must be
/// passed at [`KIDNAP_STEP_UPDATES`] updates in a row.
const KIDNAP_MAX_SKEW_SECS: f64 = 0.03;
const KIDNAP_STEP_UPDATES: u32 = 2;

/// The widest thing the map does not hold that the kidnap detector takes a run of short beams
/// for whatever the laser saw before (a bin, a person walking by, who may stand where the laser
/// saw through a moment ago; see [`Agreement`]). A wider run is taken for a thing the map lacks
/// beam by beam, where the laser did not see through the beam's end on a scan of
/// [`SEEN_LAG_UPDATES`] before ([`Filter::seen_through`]): a thing that stands still, of any
/// size (the bundled behaviours system's box, 1 m by 2 m, seen face on). Measured: taking every
/// run of up to 2.5 m for a thing, whatever was seen, two of the twenty seeded kidnaps (carried
/// 7.5 m along the warehouse's main aisle, where the truth sees shelving the estimate expects
/// open) were noticed 42 and 61 scans late; the open floor the truth's shelving stands on had
/// been seen through just before the carrying.
const UNMAPPED_THING_M: f64 = 1.5;

/// How many updates back the scan lies that a wider run of short beams is checked against
/// ([`Filter::seen_through`]): a kidnap is noticed on the scans taken where the robot was put,
/// against one taken before the carrying, for this many updates.
const SEEN_LAG_UPDATES: usize = 10;

/// How many beams' likelihoods are multiplied before a logarithm is taken
/// ([`Filter::log_likelihood`]): each is at least `1 - z_hit` (a random reading), so that with
/// `z_hit` up to 0.999 the product stays above 1e-48, far from where an `f64` loses precision.
const PRODUCT_BEAMS: usize = 16;

/// The filter's settings (the module's parameters).
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    pub min_particles: usize,
    pub max_particles: usize,
    /// Noise of the motion model: rotation from rotation, rotation from translation,
    /// translation from translation, translation from rotation (AMCL's `alpha1..4`).
    pub alpha: [f64; 4],
    /// Beams used per scan, spread evenly over it.
    pub beams: usize,
    /// Standard deviation of a beam's end round the wall it hit.
    pub sigma_hit_m: f64,
    /// Weight of the hit in the measurement mixture (the rest is a random reading).
    pub z_hit: f64,
    /// How many independent beams a scan counts as.
    pub effective_beams: f64,
    pub kld_err: f64,
    /// Upper standard normal quantile of the KLD bound (2.326 for 0.99).
    pub kld_z: f64,
    /// The filter is updated when odometry moved this far or turned this much since the last
    /// update (a robot standing still would otherwise grow confident on the same scan).
    pub update_min_m: f64,
    pub update_min_rad: f64,
    /// The robot's radius: global mode spreads particles only where it fits.
    pub robot_radius_m: f64,
    /// Spread particles over the free space when lost (global mode), else hold the estimate.
    pub recover: bool,
    pub thresholds: Thresholds,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            min_particles: 500,
            max_particles: 3000,
            alpha: [0.05, 0.005, 0.05, 0.01],
            beams: 60,
            sigma_hit_m: 0.1,
            z_hit: 0.9,
            effective_beams: 12.0,
            kld_err: 0.05,
            kld_z: 2.326,
            update_min_m: 0.05,
            update_min_rad: 0.05,
            robot_radius_m: 0.25,
            recover: false,
            thresholds: Thresholds::default(),
        }
    }
}

/// Where [`State`] changes (documented in the module's description and docs/localisation.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thresholds {
    /// Localised: position standard deviation (largest axis) at most this ...
    pub localised_sigma_m: f64,
    /// ... heading standard deviation at most this ...
    pub localised_sigma_rad: f64,
    /// ... and the scan's fit at least this.
    pub localised_fit: f64,
    /// Lost: position standard deviation above this, or the fit below `lost_fit`.
    pub lost_sigma_m: f64,
    pub lost_fit: f64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Self {
            localised_sigma_m: 0.15,
            localised_sigma_rad: 0.1,
            localised_fit: 0.5,
            lost_sigma_m: 1.0,
            lost_fit: 0.25,
        }
    }
}

/// The phases of a filter update, in order ([`Filter::update_marked`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// The particles moved by the odometry, and the scan's beams taken.
    Motion,
    /// Each particle weighed on the scan (or, after a spread, the proposals scored).
    Weigh,
    /// Low-variance resampling, cluster by cluster, when the weights call for it.
    Resample,
    /// The particles' clusters, the heaviest one's mean and the covariance.
    Cluster,
    /// The scan checked against the map from the estimate: the beams' agreement (a ray cast
    /// in the world per beam), the things the map lacks, the fit.
    Agreement,
    /// The state, the kidnap detector, the proof and the scans kept for the detector.
    Watch,
}

impl Phase {
    pub const ALL: [Phase; 6] = [
        Phase::Motion,
        Phase::Weigh,
        Phase::Resample,
        Phase::Cluster,
        Phase::Agreement,
        Phase::Watch,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Phase::Motion => "motion",
            Phase::Weigh => "weigh",
            Phase::Resample => "resample",
            Phase::Cluster => "cluster",
            Phase::Agreement => "agreement",
            Phase::Watch => "watch",
        }
    }
}

/// How much the localiser trusts its estimate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    Localised,
    Uncertain,
    Lost,
}

impl State {
    /// The event the module reports on entering the state.
    pub fn event(self) -> &'static str {
        match self {
            State::Localised => "localised",
            State::Uncertain => "uncertain",
            State::Lost => "lost",
        }
    }
}

/// The estimate: the particles' mean, their covariance (x, y, heading; row-major 3 × 3), the
/// scan's fit, the state and the number of particles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Estimate {
    pub pose: Pose2D,
    pub covariance: [f64; 9],
    pub fit: f64,
    /// The share of the scan's beams that read what the map says they should from the
    /// estimate (a range within [`AGREE_M`] of the map's, or no echo where the map has no wall
    /// within range), smoothed over scans.
    pub agreement: f64,
    pub state: State,
    pub particles: usize,
    /// The estimate has nothing to prove: set by hand or from the plan's start, or proven by
    /// driving or turning on it after a search of the map, a cloud made wide by a laser gone
    /// quiet, or a suspected kidnap. A follower does not drive on an estimate that is not.
    pub proven: bool,
}

impl Estimate {
    /// The standard deviation of position along its largest axis.
    pub fn sigma_m(&self) -> f64 {
        let c = &self.covariance;
        let (a, b, d) = (c[0], c[1], c[4]);
        let half_trace = (a + d) / 2.0;
        let spread = (((a - d) / 2.0).powi(2) + b * b).sqrt();
        (half_trace + spread).max(0.0).sqrt()
    }

    pub fn sigma_rad(&self) -> f64 {
        self.covariance[8].max(0.0).sqrt()
    }
}

/// The map as the filter sees it: the likelihood field and where the robot fits.
#[derive(Clone, Debug)]
pub struct Map {
    field: LogOddsGrid,
    free: Vec<(f64, f64)>,
    /// The world itself, for the ranges the laser should read from the estimate.
    world: World,
}

impl Map {
    /// The map of a world: the visible faces of its walls, obstacles and boundary, sampled
    /// every centimetre, make the likelihood field, with a standard deviation of `sigma_hit_m`
    /// reaching three of them. The field is built from the faces themselves rather than from
    /// the world's occupancy grid: that grid draws a face lying on a cell border in the cell
    /// beyond it, which put the field's ridge half a cell (2.5 cm in x and in y) off the walls
    /// the laser sees, and the estimate with it (measured on the warehouse round: a constant
    /// (+0.025, +0.025) m offset).
    pub fn new(world: &World, sigma_hit_m: f64, robot_radius_m: f64) -> Result<Self, String> {
        let grid = world.occupancy_grid(FIELD_RESOLUTION_M)?;
        let (width, height) = (grid.width as usize, grid.height as usize);
        // A point beside a face is in the open when the world's occupancy grid has it free
        // (inside the boundary, in no obstacle, on no wall): a face with the open on neither
        // side (between two cells of a ROS map's wall, or inside a solid obstacle) cannot be
        // seen, and leaving it out gives no credit to a beam that ends inside a wall. The grid
        // answers at once, where asking the world would go through every obstacle of a ROS
        // map (thousands) for every point.
        let open = |p: Point| {
            let col = ((p.x - grid.origin_x_m) / FIELD_RESOLUTION_M).floor();
            let row = ((p.y - grid.origin_y_m) / FIELD_RESOLUTION_M).floor();
            col >= 0.0
                && row >= 0.0
                && (col as usize) < width
                && (row as usize) < height
                && grid.cells[row as usize * width + col as usize] == 0
        };
        let mut echoes = Vec::new();
        for (a, b) in world.segments() {
            let length = a.distance(b);
            if !length.is_finite() {
                continue;
            }
            let samples = (length / FACE_SAMPLE_M).ceil().max(1.0) as usize;
            let (ux, uy) = if length > 0.0 {
                ((b.x - a.x) / length, (b.y - a.y) / length)
            } else {
                (1.0, 0.0)
            };
            let (nx, ny) = (-uy * FACE_SIDE_M, ux * FACE_SIDE_M);
            for i in 0..=samples {
                let t = i as f64 / samples as f64;
                let p = Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t);
                if open(Point::new(p.x + nx, p.y + ny)) || open(Point::new(p.x - nx, p.y - ny)) {
                    echoes.push((p.x, p.y));
                }
            }
        }
        let sigma_cells = (sigma_hit_m / FIELD_RESOLUTION_M) as f32;
        let reach_cells = ((3.0 * sigma_hit_m / FIELD_RESOLUTION_M).ceil() as isize).clamp(1, 64);
        // The field reaches beyond the map's edge (a boundary wall lies on it), so the grid is
        // wider by the reach on every side.
        let pad = reach_cells as usize + 1;
        let mut field = LogOddsGrid::new(
            FIELD_RESOLUTION_M,
            width + 2 * pad,
            height + 2 * pad,
            grid.origin_x_m - pad as f64 * FIELD_RESOLUTION_M,
            grid.origin_y_m - pad as f64 * FIELD_RESOLUTION_M,
        )?
        .with_field(sigma_cells, reach_cells)?;
        field.mark_echoes(echoes);
        let bounds = world.bounds();
        let mut free = Vec::new();
        let mut y = bounds.min_y + FREE_PITCH_M / 2.0;
        while y < bounds.max_y {
            let mut x = bounds.min_x + FREE_PITCH_M / 2.0;
            while x < bounds.max_x {
                if !world.collides(x, y, robot_radius_m) {
                    free.push((x, y));
                }
                x += FREE_PITCH_M;
            }
            y += FREE_PITCH_M;
        }
        if free.is_empty() {
            return Err(format!(
                "the world `{}` has no place where a robot of radius {robot_radius_m} m fits",
                world.name()
            ));
        }
        Ok(Self {
            field,
            free,
            world: world.clone(),
        })
    }

    /// The likelihood field at a point (1 on a wall, falling off as a Gaussian, 0 far off).
    pub fn field_at(&self, x_m: f64, y_m: f64) -> f64 {
        self.field.field_at(x_m, y_m)
    }
}

/// A scan's beams against the map from a pose ([`Filter::agreement_at`]).
struct Agreement {
    /// The share of the beams that read what the map says (none without beams): the state's
    /// and the proof's, where a beam cut short by something the map lacks counts against, so
    /// that a place is not called `localised`, or proven, on the beams that happen to agree
    /// (measured: counting only the others, a turn in place proved a place 5.2 m off on the
    /// office floor, whose truth had walls nearer than the place believed).
    all: Option<f64>,
    /// The kidnap detector's: the same share, less the beams that a thing the map does not
    /// hold explains. A box, a bin or a person walking by stands between the laser and the
    /// wall behind it: the beams that meet it end short of the map's wall, side by side. Such a
    /// run of short beams is left out (AMCL's beam model explains a reading short of the map's
    /// by `z_short`, something unexpected in the way) when its ends lie within the width of a
    /// thing that may move ([`UNMAPPED_THING_M`]), and, when wider, each beam whose end the
    /// laser did not see through shortly before ([`Filter::seen_through`]: a thing standing
    /// still). What no such thing explains counts against: a beam that reaches farther than
    /// the map allows, or sees nothing where the map has a wall in range (a thing the map
    /// lacks only ever shortens a beam), and a wider run of short beams ending where the laser
    /// saw open floor a moment ago (a wall nearer than the map has it, seen from a place the
    /// robot was carried to). A robot carried into a look-alike aisle sees both kinds (measured
    /// on the kidnaps of the tests, see [`KIDNAP_STEP`]). None when what is left is fewer than
    /// [`MIN_JUDGED_BEAMS`] of the beams (the scan shows too little of the map).
    kidnap: Option<f64>,
}

/// Room the filter works in, kept from update to update so that an update in steady state
/// allocates nothing (an allocation's cost depends on the allocator's state, and the goal is a
/// p99 of 2 ms).
#[derive(Clone, Debug, Default)]
struct Scratch {
    /// Each beam's end, in the robot's frame, when it ends short of the map's wall
    /// ([`Filter::agreement_at`]).
    short: Vec<Option<(f64, f64)>>,
    /// Each beam (in the scan's order) that a thing the map lacks explains: left out of the
    /// kidnap detector's agreement and of the fit ([`Filter::fit_at`]).
    explained: Vec<bool>,
    /// A run of short beams ([`Filter::explained_short`]).
    run: Vec<(usize, (f64, f64))>,
    /// The KLD histogram's occupied bins ([`Filter::resample`]).
    kld_bins: FxHashSet<(i64, i64, i64)>,
}

#[derive(Clone, Copy, Debug)]
struct Particle {
    pose: Pose2D,
    weight: f64,
}

/// The particles' clusters (particles near each other: one hypothesis each of where the robot
/// is; [`Filter::cluster`]), made in buffers kept from update to update.
#[derive(Clone, Debug, Default)]
struct Clusters {
    /// Each occupied cell and its index, each cell's parent in the union-find, and the cluster
    /// of each cell that is a root.
    cells: FxHashMap<(i64, i64), usize>,
    parent: Vec<usize>,
    cluster_of_root: Vec<usize>,
    /// Each particle's cell, then its cluster.
    cell_of: Vec<usize>,
    label: Vec<usize>,
    /// Each cluster's weight, numbered in the order their first particles come.
    weights: Vec<f64>,
    /// Each cluster's particles, in their order: `members[offsets[c]..offsets[c + 1]]`
    /// (`cursor` is room to sort them in).
    members: Vec<usize>,
    offsets: Vec<usize>,
    cursor: Vec<usize>,
    /// The clusters, heaviest first (of equal weight, the first met first).
    order: Vec<usize>,
}

impl Clusters {
    fn len(&self) -> usize {
        self.order.len()
    }

    /// The weight and the particles of the `rank`th heaviest cluster.
    fn get(&self, rank: usize) -> Option<(f64, &[usize])> {
        let c = *self.order.get(rank)?;
        Some((
            self.weights[c],
            &self.members[self.offsets[c]..self.offsets[c + 1]],
        ))
    }
}

/// The filter.
#[derive(Clone, Debug)]
pub struct Filter {
    settings: Settings,
    map: Map,
    particles: Vec<Particle>,
    spare: Vec<Particle>,
    rng: Rng,
    /// The odometry pose at the last update.
    last_odom: Option<Pose2D>,
    /// The scan's fit at the estimate, smoothed.
    fit: f64,
    estimate: Estimate,
    /// Updates since the particles were last spread over the map.
    since_spread: u32,
    /// The particles were spread and the next scan picks where they go ([`Filter::propose`]).
    spread_pending: bool,
    /// The particles were spread over the map and have not found the robot yet.
    searching: bool,
    /// Updates still to make whether the robot moves or not: after the pose is set or the
    /// particles spread, a robot standing still must still be able to find itself.
    forced_updates: u32,
    /// The estimate must prove itself before it says `localised` (see [`CONFIRM_M`]): after a
    /// search of the map, or after the laser went quiet until the cloud was lost.
    confirming: bool,
    /// The proof so far: the candidate's pose and the odometry pose at the last update, the
    /// travel and the updates it held.
    candidate: Option<(Pose2D, Pose2D)>,
    confirmed_m: f64,
    confirmed_updates: u32,
    /// The proof by a turn in place so far: the turn, its updates and the travel since it began.
    confirmed_rad: f64,
    confirmed_turn_updates: u32,
    turn_travel_m: f64,
    /// The walls' directions seen over the turn (xx, xy, yy; see [`CONFIRM_TURN_OBSERVABLE`]).
    turn_information: [f64; 3],
    /// The proof was armed by the kidnap detector (a lost estimate then stays lost without
    /// `recover`, as any other).
    suspected: bool,
    /// The beams' agreement's long-term average and the updates it holds (the kidnap
    /// detector's history, see [`KIDNAP_STEP`]); and how many kidnaps it suspected.
    agreement_history: f64,
    history_updates: u32,
    pub(crate) kidnaps_suspected: u32,
    /// The largest step the detector saw while armed (the tests report it against
    /// [`KIDNAP_STEP`]).
    pub(crate) largest_step: f64,
    /// The detector's own short-term average of the agreement (weight [`FIT_SMOOTHING`]), of
    /// the updates it does not skip only: the smoothed agreement carries a fast turn's low
    /// values into the updates after it.
    agreement_recent: f64,
    /// Updates in a row past the step, and how far apart the last scan and its odometry were.
    step_updates: u32,
    pairing_skew_secs: f64,
    /// Updates made on the odometry alone since the last scan ([`Filter::predict_only`]).
    starved: u32,
    /// Beam ends in the robot's frame for the scan being weighed (reused).
    points: Vec<(f64, f64)>,
    /// The beams used of that scan: their angle in the robot's frame and their range, None
    /// for no echo; and the laser's range.
    beams: Vec<(f64, Option<f64>)>,
    range_max_m: f64,
    /// Each beam used's index in the scan, and the scan's own ranges, angle of the first and
    /// spacing (the kidnap detector tells things apart on every beam of the scan).
    beam_indices: Vec<usize>,
    ranges: Vec<f32>,
    angle_min_rad: f64,
    angle_increment_rad: f64,
    /// The share of the beams that agree with the map from the estimate, smoothed.
    agreement: f64,
    log_weights: Vec<f64>,
    /// The particles' clusters and room to work in, kept from update to update.
    clusters: Clusters,
    scratch: Scratch,
    /// The kidnap detector's agreement of the last scan from the estimate, not smoothed (its
    /// history is made of it; see [`Agreement`]).
    raw_agreement: Option<f64>,
    /// The last [`SEEN_LAG_UPDATES`] scans of a proven estimate, not lost, each with that
    /// estimate, oldest first: what the laser saw through ([`Filter::seen_through`]).
    seen: VecDeque<SeenScan>,
}

/// A scan with the estimate it was taken from ([`Filter::seen_through`]).
#[derive(Clone, Debug)]
struct SeenScan {
    pose: Pose2D,
    ranges: Vec<f32>,
    angle_min_rad: f64,
    angle_increment_rad: f64,
    range_max_m: f64,
}

impl Filter {
    /// A filter with its particles round `pose`.
    pub fn new(settings: Settings, map: Map, pose: Pose2D, seed: u64) -> Self {
        let mut filter = Self {
            settings,
            map,
            particles: Vec::new(),
            spare: Vec::new(),
            rng: Rng::new(seed, 7),
            last_odom: None,
            fit: 1.0,
            estimate: Estimate {
                pose,
                covariance: [0.0; 9],
                fit: 1.0,
                agreement: 1.0,
                state: State::Uncertain,
                particles: 0,
                proven: true,
            },
            since_spread: u32::MAX,
            spread_pending: false,
            searching: false,
            forced_updates: 0,
            confirming: false,
            candidate: None,
            confirmed_m: 0.0,
            confirmed_updates: 0,
            confirmed_rad: 0.0,
            confirmed_turn_updates: 0,
            turn_travel_m: 0.0,
            turn_information: [0.0; 3],
            suspected: false,
            agreement_history: 1.0,
            history_updates: 0,
            kidnaps_suspected: 0,
            largest_step: 0.0,
            agreement_recent: 1.0,
            step_updates: 0,
            pairing_skew_secs: 0.0,
            starved: 0,
            points: Vec::new(),
            beams: Vec::new(),
            range_max_m: 0.0,
            beam_indices: Vec::new(),
            ranges: Vec::new(),
            angle_min_rad: 0.0,
            angle_increment_rad: 0.0,
            agreement: 1.0,
            log_weights: Vec::new(),
            clusters: Clusters::default(),
            scratch: Scratch::default(),
            raw_agreement: None,
            seen: VecDeque::new(),
        };
        filter.set_pose(pose, 0.1, 0.1);
        filter
    }

    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    pub fn map(&self) -> &Map {
        &self.map
    }

    pub fn estimate(&self) -> Estimate {
        self.estimate
    }

    /// Particles drawn round `pose` with the given standard deviations (an operator's "2D pose
    /// estimate", or the plan's start).
    pub fn set_pose(&mut self, pose: Pose2D, sigma_m: f64, sigma_rad: f64) {
        let count = self
            .settings
            .max_particles
            .min(1000)
            .max(self.settings.min_particles);
        self.particles.clear();
        for _ in 0..count {
            let drawn = Pose2D {
                x_m: pose.x_m + self.rng.normal(sigma_m),
                y_m: pose.y_m + self.rng.normal(sigma_m),
                theta_rad: wrap_angle(pose.theta_rad + self.rng.normal(sigma_rad)),
            };
            self.particles.push(Particle {
                pose: drawn,
                weight: 1.0 / count as f64,
            });
        }
        self.fit = 1.0;
        self.agreement = 1.0;
        self.searching = false;
        // A pose given by hand (or the plan's start) is the operator's word: the scans need
        // not prove it.
        self.confirm(false);
        self.starved = 0;
        self.forced_updates = FORCED_UPDATES;
        self.estimate = self.summarise(true);
    }

    /// Particles drawn round `pose`, where a localiser restarted in a run believes the robot is
    /// (its previous process's correction of odometry, applied to the odometry now). What was
    /// proven is taken as proven, as the plan's start is; what was not must still be proven (a
    /// turn in place: it may have been a suspected kidnap); and lost stays lost, until an
    /// operator sets the pose, or with `recover` the map is searched.
    pub fn resume(&mut self, pose: Pose2D, sigma_m: f64, sigma_rad: f64, proven: bool, lost: bool) {
        self.set_pose(pose, sigma_m, sigma_rad);
        if lost && self.settings.recover {
            self.spread();
        } else if lost {
            self.confirm(true);
            self.suspected = true;
            self.estimate.state = State::Lost;
            self.estimate.proven = false;
        } else if !proven {
            self.confirm(true);
            self.suspected = true;
            self.estimate.proven = false;
        }
    }

    /// How far apart in time the next scan and the odometry it is given with were taken (the
    /// module's pairing; 0 in a headless drive): the kidnap detector skips scans paired with
    /// odometry more than [`KIDNAP_MAX_SKEW_SECS`] apart.
    pub fn set_pairing_skew_secs(&mut self, secs: f64) {
        self.pairing_skew_secs = secs;
    }

    /// Arms (or disarms) the proof an estimate must give before it says `localised`.
    fn confirm(&mut self, armed: bool) {
        self.confirming = armed;
        self.suspected = false;
        self.candidate = None;
        self.restart_proof();
        // A new estimate, or one proven just now: its agreement's history starts again, and
        // what the laser saw from the old one is not where it now is.
        self.history_updates = 0;
        self.seen.clear();
    }

    fn restart_proof(&mut self) {
        self.confirmed_m = 0.0;
        self.confirmed_updates = 0;
        self.confirmed_rad = 0.0;
        self.confirmed_turn_updates = 0;
        self.turn_travel_m = 0.0;
        self.turn_information = [0.0; 3];
    }

    /// Global mode: `max_particles` particles spread over the map's free space with random
    /// headings, for a robot whose place is unknown.
    pub fn spread(&mut self) {
        let count = self.settings.max_particles;
        self.particles.clear();
        let free = &self.map.free;
        for _ in 0..count {
            let pick = ((self.rng.uniform() * free.len() as f64) as usize).min(free.len() - 1);
            let (x, y) = free[pick];
            let half = FREE_PITCH_M / 2.0;
            let pose = Pose2D {
                x_m: x + (self.rng.uniform() * 2.0 - 1.0) * half,
                y_m: y + (self.rng.uniform() * 2.0 - 1.0) * half,
                theta_rad: wrap_angle((self.rng.uniform() * 2.0 - 1.0) * std::f64::consts::PI),
            };
            self.particles.push(Particle {
                pose,
                weight: 1.0 / count as f64,
            });
        }
        self.fit = 0.0;
        self.agreement = 0.0;
        self.searching = true;
        self.confirm(true);
        self.starved = 0;
        self.since_spread = 0;
        self.spread_pending = true;
        self.forced_updates = FORCED_UPDATES;
        self.estimate = self.summarise(true);
    }

    /// The odometry alone, while no scan comes (a laser gone quiet): the particles move by the
    /// odometry's motion with its noise, as they would before a scan, so the covariance grows
    /// with the way driven as the motion model says (Nav2's AMCL does the same). Made in steps
    /// of the update's distance or turn, as the scans would have, so that a curve driven
    /// without scans is followed as a curve, not one straight line from where the last scan
    /// was. Without a scan the estimate never becomes `localised`; it stays so while its
    /// covariance allows (a scan late on a busy machine is no news), then says `uncertain`, and
    /// `lost` once the position's standard deviation passes `lost_sigma_m`. Returns whether the
    /// particles moved.
    pub fn predict_only(&mut self, odom: Pose2D) -> bool {
        let Some(last) = self.last_odom else {
            return false;
        };
        let moved = (odom.x_m - last.x_m).hypot(odom.y_m - last.y_m) >= self.settings.update_min_m
            || wrap_angle(odom.theta_rad - last.theta_rad).abs() >= self.settings.update_min_rad;
        if !moved {
            return false;
        }
        self.predict(last, odom);
        self.last_odom = Some(odom);
        self.starved = self.starved.saturating_add(1);
        // When the scans come back, the first ones weigh the cloud even if the robot stands
        // still by then.
        self.forced_updates = FORCED_UPDATES;
        self.estimate = self.summarise(false);
        true
    }

    /// One scan with the odometry pose at its time. The particles move by the odometry's motion
    /// since the last update, are weighed on the scan and resampled, when the robot moved
    /// enough since the last update (or at the first scan); returns whether it did.
    pub fn update(&mut self, odom: Pose2D, scan: &LaserScan) -> bool {
        self.update_marked(odom, scan, &mut |_| {})
    }

    /// [`Filter::update`], calling `mark` as each [`Phase`] of it ends (the benchmark times
    /// them; the filter itself reads no clock).
    pub fn update_marked(
        &mut self,
        odom: Pose2D,
        scan: &LaserScan,
        mark: &mut dyn FnMut(Phase),
    ) -> bool {
        let moved = match self.last_odom {
            None => true,
            Some(last) => {
                (odom.x_m - last.x_m).hypot(odom.y_m - last.y_m) >= self.settings.update_min_m
                    || wrap_angle(odom.theta_rad - last.theta_rad).abs()
                        >= self.settings.update_min_rad
            }
        };
        if !moved && self.forced_updates == 0 {
            return false;
        }
        self.forced_updates = self.forced_updates.saturating_sub(1);
        let (mut travelled, mut turned) = (0.0, 0.0);
        if let Some(last) = self.last_odom {
            self.predict(last, odom);
            travelled = (odom.x_m - last.x_m).hypot(odom.y_m - last.y_m);
            turned = wrap_angle(odom.theta_rad - last.theta_rad).abs();
        }
        self.last_odom = Some(odom);
        self.take_points(scan);
        mark(Phase::Motion);
        if self.spread_pending {
            self.propose();
            mark(Phase::Weigh);
        } else {
            self.weigh();
            mark(Phase::Weigh);
            self.resample();
        }
        mark(Phase::Resample);
        let was_lost = self.estimate.state == State::Lost;
        // Lost for want of scans is not lost for scans that contradict the cloud: the cloud
        // grew with the odometry and still holds the robot, so the scans may tell where in it
        // it is; but a cloud that wide may hold look-alike places too, so the estimate must
        // prove itself as after a search.
        let starved = std::mem::take(&mut self.starved) > 0;
        if starved && was_lost {
            self.confirm(true);
        }
        self.estimate = self.summarise_marked(true, mark);
        // Without recovery, lost stays lost until an operator sets the pose: a cloud left
        // where the robot no longer is, moved on by the odometry, can come to fit the scans of
        // some other place by chance and would then call itself localised there.
        // A search of the whole map (global mode) is let run to its end.
        if was_lost
            && !self.settings.recover
            && !self.searching
            && (!self.confirming || self.suspected)
        {
            self.estimate.state = State::Lost;
        }
        self.watch_for_kidnap(turned);
        self.prove(odom, travelled, turned);
        self.estimate.proven = !self.confirming && self.estimate.state != State::Lost;
        if self.estimate.state == State::Localised {
            self.searching = false;
        }
        // What the laser saw is kept while the kidnap detector watches (a proven estimate, not
        // lost): a thing beside the robot can make it `uncertain` by the state's thresholds as
        // it passes (the behaviours system's box did), and a detector without those scans would
        // take the thing for a contradiction.
        if self.estimate.proven && !self.searching && self.estimate.state != State::Lost {
            // The oldest scan's room is taken for the newest: no allocation once ten are kept.
            let mut ranges = if self.seen.len() >= SEEN_LAG_UPDATES {
                self.seen
                    .pop_front()
                    .map(|old| old.ranges)
                    .unwrap_or_default()
            } else {
                Vec::with_capacity(self.ranges.len())
            };
            ranges.clear();
            ranges.extend_from_slice(&self.ranges);
            self.seen.push_back(SeenScan {
                pose: self.estimate.pose,
                ranges,
                angle_min_rad: self.angle_min_rad,
                angle_increment_rad: self.angle_increment_rad,
                range_max_m: self.range_max_m,
            });
        } else {
            self.seen.clear();
        }
        self.since_spread = self.since_spread.saturating_add(1);
        // Spread again only when nothing fits: a wide estimate whose places all fit is the
        // scans not yet telling look-alike places apart, and spreading would throw that
        // evidence away. Or when a search settled on one place that the beams contradict: the
        // echoes fit there (the depot's rows of posts, 2.6 m along from the truth), but too
        // many ranges disagree for it ever to be `localised`, let alone proven, and the place
        // that would be has died out of the cloud (measured on Nav2's depot map: two searches
        // of eight did this and stayed `uncertain` through 48 s of turning in place).
        let nothing_fits = self.estimate.state == State::Lost
            && (self.fit < self.settings.thresholds.lost_fit || self.agreement < LOST_AGREEMENT);
        let settled_wrong = self.searching
            && self.estimate.state != State::Localised
            && self.agreement < STAY_LOCALISED_AGREEMENT;
        if self.settings.recover
            && self.since_spread >= SPREAD_AGAIN_UPDATES
            && (nothing_fits || settled_wrong)
        {
            self.spread();
        }
        mark(Phase::Watch);
        true
    }

    /// While the estimate must prove itself ([`CONFIRM_M`]): a `localised` estimate counts
    /// towards the proof when it is where the last one was moved by the odometry, with the
    /// beams agreeing; anything else starts the proof again. Until it is complete the estimate
    /// says `uncertain`.
    fn prove(&mut self, odom: Pose2D, travelled: f64, turned: f64) {
        if !self.confirming {
            return;
        }
        let estimate = self.estimate;
        if estimate.state != State::Localised {
            self.candidate = None;
            self.restart_proof();
            return;
        }
        let held = self.candidate.is_none_or(|(pose, odom_then)| {
            let moved = crate::mapper::compose(pose, crate::mapper::between(odom_then, odom));
            (moved.x_m - estimate.pose.x_m).hypot(moved.y_m - estimate.pose.y_m) <= CONFIRM_JUMP_M
                && wrap_angle(moved.theta_rad - estimate.pose.theta_rad).abs() <= CONFIRM_JUMP_RAD
        });
        if held && estimate.agreement >= CONFIRM_AGREEMENT {
            self.confirmed_m += travelled;
            self.confirmed_updates += 1;
            self.turn_travel_m += travelled;
            if self.turn_travel_m > CONFIRM_TURN_TRAVEL_M {
                // Driving, not turning in place: a turn is counted again from here.
                self.confirmed_rad = 0.0;
                self.confirmed_turn_updates = 0;
                self.turn_travel_m = 0.0;
                self.turn_information = [0.0; 3];
            } else {
                self.confirmed_rad += turned;
                self.confirmed_turn_updates += 1;
                self.add_wall_directions(estimate.pose);
            }
        } else {
            self.restart_proof();
        }
        self.candidate = Some((estimate.pose, odom));
        let driven = self.confirmed_m >= CONFIRM_M && self.confirmed_updates >= CONFIRM_UPDATES;
        let turned_round = self.confirmed_rad >= CONFIRM_TURN_RAD
            && self.confirmed_turn_updates >= CONFIRM_TURN_UPDATES
            && self.turn_observable();
        // A suspected kidnap is not proven by driving on: the cloud is where the robot was
        // believed to be, and a look-alike aisle fitted for more than 5 m of driving on from
        // where the robot was put (measured: carried 7 m across the warehouse's aisles, the
        // first scans there fitting the old place with 90 % of the beams agreeing). A turn in
        // place proves it (the follower turns while the estimate is not proven); otherwise it
        // stays `uncertain` until an operator sets the pose, or the scans make it `lost` (and
        // `recover` searches the map).
        if (driven && !self.suspected) || turned_round {
            self.confirm(false);
        } else {
            self.estimate.state = State::Uncertain;
        }
    }

    /// Adds the directions of the walls the beams end on from `pose` (the likelihood field's
    /// gradient there) to the turn's information ([`CONFIRM_TURN_OBSERVABLE`]).
    fn add_wall_directions(&mut self, pose: Pose2D) {
        let h = FIELD_RESOLUTION_M;
        let (sin, cos) = pose.theta_rad.sin_cos();
        for &(lx, ly) in &self.points {
            let x = pose.x_m + cos * lx - sin * ly;
            let y = pose.y_m + sin * lx + cos * ly;
            let gx = self.map.field_at(x + h, y) - self.map.field_at(x - h, y);
            let gy = self.map.field_at(x, y + h) - self.map.field_at(x, y - h);
            let norm = gx.hypot(gy);
            if norm > 1e-6 {
                let (nx, ny) = (gx / norm, gy / norm);
                self.turn_information[0] += nx * nx;
                self.turn_information[1] += nx * ny;
                self.turn_information[2] += ny * ny;
            }
        }
    }

    /// Whether the walls seen over the turn pin the place down in every direction.
    fn turn_observable(&self) -> bool {
        let [a, b, d] = self.turn_information;
        let half_trace = (a + d) / 2.0;
        let spread = (((a - d) / 2.0).powi(2) + b * b).sqrt();
        let (large, small) = (half_trace + spread, half_trace - spread);
        large > 0.0 && small / large >= CONFIRM_TURN_OBSERVABLE
    }

    /// The kidnap detector ([`KIDNAP_STEP`]): while the estimate is proven, the beams' agreement
    /// is watched against its history; a step down arms the proof, and the estimate says
    /// `uncertain` until it is given (or `lost` when the scans show more).
    fn watch_for_kidnap(&mut self, turned: f64) {
        if self.confirming || self.searching || self.estimate.state == State::Lost {
            self.history_updates = 0;
            return;
        }
        let Some(raw_agreement) = self.raw_agreement else {
            return;
        };
        if turned > KIDNAP_MAX_TURN_RAD || self.pairing_skew_secs > KIDNAP_MAX_SKEW_SECS {
            return;
        }
        if self.history_updates == 0 {
            self.agreement_recent = raw_agreement;
        } else {
            self.agreement_recent += FIT_SMOOTHING * (raw_agreement - self.agreement_recent);
        }
        let step = self.agreement_history - self.agreement_recent;
        if self.history_updates >= KIDNAP_HISTORY_UPDATES {
            self.largest_step = self.largest_step.max(step);
        }
        if self.history_updates >= KIDNAP_HISTORY_UPDATES && step > KIDNAP_STEP {
            self.step_updates += 1;
        } else {
            self.step_updates = 0;
        }
        if self.step_updates >= KIDNAP_STEP_UPDATES {
            self.step_updates = 0;
            self.kidnaps_suspected += 1;
            self.estimate.state = State::Uncertain;
            self.confirm(true);
            self.suspected = true;
            return;
        }
        if self.history_updates == 0 {
            self.agreement_history = raw_agreement;
        } else {
            self.agreement_history += AGREEMENT_HISTORY * (raw_agreement - self.agreement_history);
        }
        self.history_updates += 1;
    }

    /// Moves every particle by the odometry's motion from `from` to `to`, with noise.
    fn predict(&mut self, from: Pose2D, to: Pose2D) {
        let (dx, dy) = (to.x_m - from.x_m, to.y_m - from.y_m);
        let trans = dx.hypot(dy);
        // A turn on the spot has no direction of travel.
        let rot1 = if trans < 0.01 {
            0.0
        } else {
            wrap_angle(dy.atan2(dx) - from.theta_rad)
        };
        let rot2 = wrap_angle(to.theta_rad - from.theta_rad - rot1);
        // A robot reversing turns by (rot1 - π), not rot1: the noise is drawn on the smaller.
        let small = |angle: f64| {
            angle.abs().min(
                (angle - std::f64::consts::PI)
                    .abs()
                    .min((angle + std::f64::consts::PI).abs()),
            )
        };
        let [a1, a2, a3, a4] = self.settings.alpha;
        let (r1, r2) = (small(rot1), small(rot2));
        let sd_rot1 = (a1 * r1 * r1 + a2 * trans * trans).sqrt();
        let sd_trans = (a3 * trans * trans + a4 * (r1 * r1 + r2 * r2)).sqrt();
        let sd_rot2 = (a1 * r2 * r2 + a2 * trans * trans).sqrt();
        for particle in &mut self.particles {
            let rot1_hat = rot1 - self.rng.normal(sd_rot1);
            let trans_hat = trans - self.rng.normal(sd_trans);
            let rot2_hat = rot2 - self.rng.normal(sd_rot2);
            let p = &mut particle.pose;
            let heading = p.theta_rad + rot1_hat;
            p.x_m += trans_hat * heading.cos();
            p.y_m += trans_hat * heading.sin();
            p.theta_rad = wrap_angle(heading + rot2_hat);
        }
    }

    /// The ends of the beams used, in the robot's frame.
    fn take_points(&mut self, scan: &LaserScan) {
        self.points.clear();
        self.beams.clear();
        self.beam_indices.clear();
        self.range_max_m = scan.range_max_m;
        self.ranges.clear();
        self.ranges.extend_from_slice(&scan.ranges_m);
        self.angle_min_rad = scan.angle_min_rad;
        self.angle_increment_rad = scan.angle_increment_rad;
        let n = scan.ranges_m.len();
        let step = n.div_ceil(self.settings.beams.max(1)).max(1);
        for (i, &range) in scan.ranges_m.iter().enumerate().step_by(step) {
            let range = f64::from(range);
            let angle = scan.angle_min_rad + i as f64 * scan.angle_increment_rad;
            if range.is_finite() && range >= scan.range_max_m {
                self.beams.push((angle, None));
                self.beam_indices.push(i);
            }
            // No echo, or nonsense: says nothing about where the walls are.
            if !(range.is_finite() && range > 0.0 && range < scan.range_max_m) {
                continue;
            }
            self.beams.push((angle, Some(range)));
            self.beam_indices.push(i);
            self.points.push((range * angle.cos(), range * angle.sin()));
        }
    }

    /// How the beams read from `pose` against the map: the share that read what the map says
    /// they should (a range within [`AGREE_M`] of the distance to the map's first wall, or no
    /// echo where the map has none within range), and the kidnap detector's agreement, which
    /// leaves out the beams a thing the map lacks explains (see [`Agreement`]).
    fn agreement_at(&self, pose: Pose2D, scratch: &mut Scratch) -> Agreement {
        let origin = Point::new(pose.x_m, pose.y_m);
        let range_max = self.range_max_m;
        let beams = self.beams.len();
        let (mut agreeing, mut long) = (0usize, 0usize);
        // Each beam's end, in the robot's frame, when it ends short of the map's first wall.
        let short = &mut scratch.short;
        short.clear();
        for &(angle, range) in &self.beams {
            let expected = self
                .map
                .world
                .raycast(origin, pose.theta_rad + angle, range_max);
            let mut end = None;
            match range {
                Some(range) if range < expected - AGREE_M => {
                    end = Some((range * angle.cos(), range * angle.sin()));
                }
                Some(range) if range > expected + AGREE_M => long += 1,
                Some(_) => agreeing += 1,
                None if expected >= range_max - AGREE_M => agreeing += 1,
                None => long += 1,
            }
            short.push(end);
        }
        let all = (beams > 0).then(|| agreeing as f64 / beams as f64);
        self.explained_short(
            pose,
            &scratch.short,
            &mut scratch.explained,
            &mut scratch.run,
        );
        let unexplained = scratch.short.iter().flatten().count()
            - scratch.explained.iter().filter(|&&e| e).count();
        let judged = agreeing + long + unexplained;
        let kidnap = (judged > 0 && judged as f64 >= MIN_JUDGED_BEAMS * beams as f64)
            .then(|| agreeing as f64 / judged as f64);
        Agreement { all, kidnap }
    }

    /// Which of the short beams (`short`, one entry a beam in the scan's order, the end of
    /// those that end short of the map's wall, seen from `pose`) a thing the map lacks explains.
    /// Neighbouring short beams are one thing when the scan's own points between them are one
    /// surface ([`Filter::connected`]), and two otherwise (a near thing beside a far one). A
    /// thing whose ends lie within [`UNMAPPED_THING_M`] of each other explains its beams; a
    /// wider one explains those whose ends the laser did not see through on the scan of
    /// [`SEEN_LAG_UPDATES`] before (none without such a scan). A scan all round the robot
    /// wraps: its last beam neighbours its first. The answer is `explained`, one entry a beam;
    /// `run` is room to work in.
    fn explained_short(
        &self,
        pose: Pose2D,
        short: &[Option<(f64, f64)>],
        explained: &mut Vec<bool>,
        run: &mut Vec<(usize, (f64, f64))>,
    ) {
        let n = short.len();
        explained.clear();
        explained.resize(n, false);
        if n < 2 {
            // One beam: whatever it met explains it.
            for (mark, end) in explained.iter_mut().zip(short) {
                *mark = end.is_some();
            }
            return;
        }
        let spacing = (self.beams[1].0 - self.beams[0].0).abs();
        let wraps =
            self.beams[0].0 + 2.0 * std::f64::consts::PI - self.beams[n - 1].0 <= 1.5 * spacing;
        // A wrapping scan is walked from a beam that is not short, so that no run is cut in two
        // at its end.
        let begin = if wraps {
            short.iter().position(Option::is_none).unwrap_or(0)
        } else {
            0
        };
        // A run: the beams' places in `short` and their ends.
        run.clear();
        let mut close = |run: &mut Vec<(usize, (f64, f64))>| {
            let span = run
                .iter()
                .enumerate()
                .flat_map(|(i, (_, a))| {
                    run[i + 1..]
                        .iter()
                        .map(move |(_, b)| (a.0 - b.0).hypot(a.1 - b.1))
                })
                .fold(0.0, f64::max);
            if span <= UNMAPPED_THING_M {
                for &(i, _) in run.iter() {
                    explained[i] = true;
                }
            } else if let Some(reference) = self.seen.front() {
                let (sin, cos) = pose.theta_rad.sin_cos();
                for &(i, (lx, ly)) in run.iter() {
                    let end = (
                        pose.x_m + cos * lx - sin * ly,
                        pose.y_m + sin * lx + cos * ly,
                    );
                    explained[i] = !Self::seen_through(reference, end);
                }
            }
            run.clear();
        };
        for i in (begin..begin + n).map(|i| i % n) {
            let Some(end) = short[i] else {
                close(run);
                continue;
            };
            if let Some(&(last, _)) = run.last()
                && !self.connected(self.beam_indices[last], self.beam_indices[i])
            {
                close(run);
            }
            run.push((i, end));
        }
        close(run);
    }

    /// Whether the laser saw through `end` (in the map frame) on the scan `reference`: the
    /// beams towards it, the nearest and its two neighbours, all reached more than [`AGREE_M`]
    /// beyond it, or read no echo with it within range. A thing the map lacks that stands
    /// still was never seen through: the beams towards it from anywhere end on it, or on
    /// something before it, or it was out of range. A wall a robot carried elsewhere sees where
    /// the estimate believes open floor was seen through before the carrying, when the robot
    /// was where the estimate says.
    fn seen_through(reference: &SeenScan, end: (f64, f64)) -> bool {
        let n = reference.ranges.len();
        let (dx, dy) = (end.0 - reference.pose.x_m, end.1 - reference.pose.y_m);
        let distance = dx.hypot(dy);
        if n == 0 || reference.angle_increment_rad.abs() < 1e-9 || distance < AGREE_M {
            return false;
        }
        let bearing = wrap_angle(dy.atan2(dx) - reference.pose.theta_rad);
        let mut index =
            ((bearing - reference.angle_min_rad) / reference.angle_increment_rad).round();
        let wraps = (n as f64 * reference.angle_increment_rad.abs() - 2.0 * std::f64::consts::PI)
            .abs()
            <= 1.5 * reference.angle_increment_rad.abs();
        if wraps {
            index = index.rem_euclid(n as f64);
        }
        let through = |i: f64| {
            let i = if wraps { i.rem_euclid(n as f64) } else { i };
            if i < 0.0 || i >= n as f64 {
                return false;
            }
            let range = f64::from(reference.ranges[i as usize]);
            if !range.is_finite() || range <= 0.0 {
                return false;
            }
            if range >= reference.range_max_m {
                distance < reference.range_max_m - AGREE_M
            } else {
                range > distance + AGREE_M
            }
        };
        through(index - 1.0) && through(index) && through(index + 1.0)
    }

    /// Whether the scan's own points from its beam `from` to its beam `to` (onwards, round the
    /// scan's end if need be) lie on one surface: each with an echo, and each within [`AGREE_M`]
    /// of the next, or twice the beams' spacing at their range when that is more (a surface
    /// facing the laser within about 70° leaves its points that close on the simulator's scan of
    /// a beam a degree).
    fn connected(&self, from: usize, to: usize) -> bool {
        let n = self.ranges.len();
        if from >= n || to >= n {
            return false;
        }
        let point = |i: usize| {
            let range = f64::from(self.ranges[i]);
            (range.is_finite() && range > 0.0 && range < self.range_max_m).then(|| {
                let angle = self.angle_min_rad + i as f64 * self.angle_increment_rad;
                (range * angle.cos(), range * angle.sin(), range)
            })
        };
        let mut i = from;
        while i != to {
            let j = (i + 1) % n;
            let (Some(a), Some(b)) = (point(i), point(j)) else {
                return false;
            };
            let close = (2.0 * a.2.max(b.2) * self.angle_increment_rad.abs()).max(AGREE_M);
            if (a.0 - b.0).hypot(a.1 - b.1) > close {
                return false;
            }
            i = j;
        }
        true
    }

    /// The tempering of the scan's log-likelihood: how much one scan counts.
    fn temper(&self) -> f64 {
        // Just after the particles were spread, the scans are trusted less, so that the cloud
        // keeps every place that fits until the robot's motion tells them apart, rather than
        // collapsing on the first that fits well (a map with rooms alike has several).
        let effective = if self.since_spread < SOFT_UPDATES {
            self.settings.effective_beams * SOFT_FACTOR
        } else {
            self.settings.effective_beams
        };
        effective / self.points.len().max(1) as f64
    }

    /// The scan's log-likelihood from a pose: the sum of the beams' logarithms, taken as the
    /// logarithm of their product, [`PRODUCT_BEAMS`] beams at a time. A logarithm for every beam
    /// of every particle (60,000 a scan) was half of an update (perf on `armor-bench
    /// localise_ms_per_scan`); the product differs from the sum of logarithms only in rounding.
    fn log_likelihood(&self, pose: Pose2D) -> f64 {
        let z_hit = self.settings.z_hit;
        let z_rand = 1.0 - z_hit;
        let (sin, cos) = pose.theta_rad.sin_cos();
        let mut log_likelihood = 0.0;
        for chunk in self.points.chunks(PRODUCT_BEAMS) {
            let mut product = 1.0;
            for &(lx, ly) in chunk {
                let x = pose.x_m + cos * lx - sin * ly;
                let y = pose.y_m + sin * lx + cos * ly;
                product *= z_hit * self.map.field_at(x, y) + z_rand;
            }
            log_likelihood += product.ln();
        }
        log_likelihood
    }

    /// Global mode's first scan: of [`PROPOSALS_PER_PARTICLE`] times `max_particles` poses
    /// drawn over the free space, the `max_particles` where the scan fits best become the
    /// particles, weighed by the scan. Drawing only `max_particles` would leave hardly any near
    /// the robot on a large map; scoring many and keeping the best is importance sampling from
    /// a wider proposal.
    fn propose(&mut self) {
        if self.points.is_empty() {
            return;
        }
        self.spread_pending = false;
        let count = self.settings.max_particles;
        let free = &self.map.free;
        let mut candidates: Vec<(f64, Pose2D)> = Vec::with_capacity(count * PROPOSALS_PER_PARTICLE);
        for _ in 0..count * PROPOSALS_PER_PARTICLE {
            let pick = ((self.rng.uniform() * free.len() as f64) as usize).min(free.len() - 1);
            let (x, y) = free[pick];
            let half = FREE_PITCH_M / 2.0;
            let pose = Pose2D {
                x_m: x + (self.rng.uniform() * 2.0 - 1.0) * half,
                y_m: y + (self.rng.uniform() * 2.0 - 1.0) * half,
                theta_rad: wrap_angle((self.rng.uniform() * 2.0 - 1.0) * std::f64::consts::PI),
            };
            candidates.push((self.log_likelihood(pose), pose));
        }
        if candidates.len() > count {
            candidates.select_nth_unstable_by(count, |a, b| b.0.total_cmp(&a.0));
            candidates.truncate(count);
        }
        let best = candidates
            .iter()
            .map(|(l, _)| *l)
            .fold(f64::NEG_INFINITY, f64::max);
        let temper = self.temper();
        self.particles.clear();
        let mut total = 0.0;
        for (log_likelihood, pose) in candidates {
            let weight = (temper * (log_likelihood - best)).exp();
            total += weight;
            self.particles.push(Particle { pose, weight });
        }
        for particle in &mut self.particles {
            particle.weight /= total;
        }
    }

    /// Weighs every particle by how well the scan's beams fit the map from its pose.
    fn weigh(&mut self) {
        if self.points.is_empty() {
            return;
        }
        let temper = self.temper();
        let mut log_weights = std::mem::take(&mut self.log_weights);
        log_weights.clear();
        let mut best = f64::NEG_INFINITY;
        for particle in &self.particles {
            let log_weight =
                particle.weight.max(1e-300).ln() + temper * self.log_likelihood(particle.pose);
            best = best.max(log_weight);
            log_weights.push(log_weight);
        }
        let mut total = 0.0;
        for (particle, &log_weight) in self.particles.iter_mut().zip(&log_weights) {
            particle.weight = (log_weight - best).exp();
            total += particle.weight;
        }
        for particle in &mut self.particles {
            particle.weight /= total;
        }
        self.log_weights = log_weights;
    }

    /// Low-variance resampling to the KLD bound's count, when the weights say something: while
    /// they are nearly even (a corridor seen from anywhere along it looks the same), resampling
    /// would only make the cloud's mean wander (genetic drift), so the particles are kept as
    /// they are, weights and all.
    fn resample(&mut self) {
        let first = self.particles.len();
        let sum_sq: f64 = self.particles.iter().map(|p| p.weight * p.weight).sum();
        let effective = if sum_sq > 0.0 { 1.0 / sum_sq } else { 0.0 };
        if effective > RESAMPLE_BELOW * first as f64 {
            return;
        }
        let bins = &mut self.scratch.kld_bins;
        bins.clear();
        bins.extend(self.particles.iter().map(|particle| {
            let p = particle.pose;
            (
                (p.x_m / KLD_BIN_M).floor() as i64,
                (p.y_m / KLD_BIN_M).floor() as i64,
                (p.theta_rad / KLD_BIN_RAD).floor() as i64,
            )
        }));
        let wanted = kld_bound(bins.len(), self.settings.kld_err, self.settings.kld_z)
            .clamp(self.settings.min_particles, self.settings.max_particles);
        self.resample_clusters(wanted);
    }

    /// Resamples each cluster on its own, keeping its total weight: the clusters' weights are
    /// the evidence for each place, and resampling the whole cloud at once would let one of
    /// two places that fit equally well die out by chance (genetic drift), leaving a tight
    /// cloud on a place the scans never preferred, which would then call itself localised.
    /// Clusters the scans ruled out (weight under [`DROP_CLUSTER_WEIGHT`]) are dropped; every
    /// other one gets its share of `count`, at least [`MIN_CLUSTER_PARTICLES`], the heaviest
    /// first, within `max_particles`.
    fn resample_clusters(&mut self, count: usize) {
        self.cluster();
        let clusters = std::mem::take(&mut self.clusters);
        let kept = (0..clusters.len())
            .filter_map(|rank| clusters.get(rank))
            .filter(|(weight, _)| *weight >= DROP_CLUSTER_WEIGHT);
        let (kept_count, kept_weight) =
            kept.fold((0, 0.0), |(n, sum), (weight, _)| (n + 1, sum + weight));
        if kept_count == 0 || kept_weight <= 0.0 {
            self.clusters = clusters;
            return;
        }
        self.spare.clear();
        let mut budget = self.settings.max_particles.max(1);
        for (weight, members) in (0..clusters.len())
            .filter_map(|rank| clusters.get(rank))
            .filter(|(weight, _)| *weight >= DROP_CLUSTER_WEIGHT)
        {
            if budget == 0 {
                break;
            }
            let share = weight / kept_weight;
            let wanted = ((share * count as f64).round() as usize)
                .max(MIN_CLUSTER_PARTICLES)
                .min(budget);
            budget -= wanted;
            self.systematic(members, weight, wanted, share);
        }
        self.clusters = clusters;
        let total: f64 = self.spare.iter().map(|p| p.weight).sum();
        if total > 0.0 {
            for particle in &mut self.spare {
                particle.weight /= total;
            }
        }
        std::mem::swap(&mut self.particles, &mut self.spare);
    }

    /// Systematic (low-variance) resampling of the particles `members`, of total weight
    /// `weight`, into `count` particles sharing `share` equally, pushed onto `spare`.
    fn systematic(&mut self, members: &[usize], weight: f64, count: usize, share: f64) {
        if count == 0 || members.is_empty() || weight <= 0.0 {
            return;
        }
        let step = weight / count as f64;
        let each = share / count as f64;
        let mut target = self.rng.uniform() * step;
        let mut cumulative = 0.0;
        let mut pushed = 0;
        let mut source = members.iter().map(|&i| self.particles[i]);
        let mut current = source.next();
        while pushed < count {
            let Some(particle) = current else {
                break;
            };
            if cumulative + particle.weight >= target {
                self.spare.push(Particle {
                    pose: particle.pose,
                    weight: each,
                });
                pushed += 1;
                target += step;
            } else {
                cumulative += particle.weight;
                current = source.next();
            }
        }
        // Rounding can leave the last few places: they go to the last particle.
        if let Some(&last) = members.last() {
            let pose = self.particles[last].pose;
            for _ in pushed..count {
                self.spare.push(Particle { pose, weight: each });
            }
        }
    }

    /// The particles' clusters, into `self.clusters`: connected groups of [`CLUSTER_CELL_M`]
    /// cells (eight neighbours) holding particles, each with its particles and their total
    /// weight, heaviest first.
    fn cluster(&mut self) {
        let cell = |pose: Pose2D| {
            (
                (pose.x_m / CLUSTER_CELL_M).floor() as i64,
                (pose.y_m / CLUSTER_CELL_M).floor() as i64,
            )
        };
        let k = &mut self.clusters;
        k.cells.clear();
        k.cell_of.clear();
        for particle in &self.particles {
            let next = k.cells.len();
            k.cell_of
                .push(*k.cells.entry(cell(particle.pose)).or_insert(next));
        }
        // Union-find over the occupied cells.
        k.parent.clear();
        k.parent.extend(0..k.cells.len());
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        for (&(cx, cy), &i) in &k.cells {
            for (dx, dy) in [(1, 0), (1, 1), (0, 1), (-1, 1)] {
                if let Some(&j) = k.cells.get(&(cx + dx, cy + dy)) {
                    let (a, b) = (root(&mut k.parent, i), root(&mut k.parent, j));
                    if a != b {
                        k.parent[a] = b;
                    }
                }
            }
        }
        // Clusters numbered in the order their first particles come, as the weights add up.
        k.cluster_of_root.clear();
        k.cluster_of_root.resize(k.cells.len(), usize::MAX);
        k.label.clear();
        k.weights.clear();
        for (i, particle) in self.particles.iter().enumerate() {
            let r = root(&mut k.parent, k.cell_of[i]);
            if k.cluster_of_root[r] == usize::MAX {
                k.cluster_of_root[r] = k.weights.len();
                k.weights.push(0.0);
            }
            let c = k.cluster_of_root[r];
            k.label.push(c);
            k.weights[c] += particle.weight;
        }
        // Each cluster's particles side by side, in their order (a counting sort).
        let count = k.weights.len();
        k.offsets.clear();
        k.offsets.resize(count + 1, 0);
        for &c in &k.label {
            k.offsets[c + 1] += 1;
        }
        for c in 0..count {
            k.offsets[c + 1] += k.offsets[c];
        }
        k.cursor.clear();
        k.cursor.extend_from_slice(&k.offsets[..count]);
        k.members.clear();
        k.members.resize(k.label.len(), 0);
        for (i, &c) in k.label.iter().enumerate() {
            k.members[k.cursor[c]] = i;
            k.cursor[c] += 1;
        }
        k.order.clear();
        k.order.extend(0..count);
        let weights = &k.weights;
        k.order.sort_by(|&a, &b| weights[b].total_cmp(&weights[a]));
    }

    /// The estimate: the mean of the heaviest cluster (the mean of the whole cloud would fall
    /// between two places, where the robot is not), the covariance of the whole cloud round
    /// it (so that another place still in the running makes it wide), the fit there and the
    /// state.
    fn summarise(&mut self, scanned: bool) -> Estimate {
        self.summarise_marked(scanned, &mut |_| {})
    }

    /// [`Filter::summarise`], calling `mark` when the clusters and the covariance are made
    /// ([`Phase::Cluster`]) and when the scan is checked against the map from the estimate
    /// ([`Phase::Agreement`]).
    fn summarise_marked(&mut self, scanned: bool, mark: &mut dyn FnMut(Phase)) -> Estimate {
        let total: f64 = self.particles.iter().map(|p| p.weight).sum();
        let total = if total > 0.0 { total } else { 1.0 };
        self.cluster();
        let second_weight = self
            .clusters
            .get(1)
            .map_or(0.0, |(weight, _)| weight / total);
        let (mut mx, mut my, mut ms, mut mc) = (0.0, 0.0, 0.0, 0.0);
        if let Some((best_weight, members)) =
            self.clusters.get(0).filter(|(weight, _)| *weight > 0.0)
        {
            for &i in members {
                let particle = &self.particles[i];
                let w = particle.weight / best_weight;
                mx += w * particle.pose.x_m;
                my += w * particle.pose.y_m;
                ms += w * particle.pose.theta_rad.sin();
                mc += w * particle.pose.theta_rad.cos();
            }
        }
        let mean_theta = ms.atan2(mc);
        let mut cov = [0.0; 9];
        for particle in &self.particles {
            let w = particle.weight / total;
            let d = [
                particle.pose.x_m - mx,
                particle.pose.y_m - my,
                wrap_angle(particle.pose.theta_rad - mean_theta),
            ];
            for r in 0..3 {
                for c in 0..3 {
                    cov[r * 3 + c] += w * d[r] * d[c];
                }
            }
        }
        let pose = Pose2D {
            x_m: mx,
            y_m: my,
            theta_rad: mean_theta,
        };
        mark(Phase::Cluster);
        if scanned {
            let mut scratch = std::mem::take(&mut self.scratch);
            let agreement = self.agreement_at(pose, &mut scratch);
            let fit = self.fit_at(pose, &scratch.explained);
            self.scratch = scratch;
            if let Some(fit) = fit {
                self.fit = FIT_SMOOTHING * fit + (1.0 - FIT_SMOOTHING) * self.fit;
            }
            self.raw_agreement = agreement.kidnap;
            if let Some(all) = agreement.all {
                self.agreement = FIT_SMOOTHING * all + (1.0 - FIT_SMOOTHING) * self.agreement;
            }
        }
        mark(Phase::Agreement);
        let mut estimate = Estimate {
            pose,
            covariance: cov,
            fit: self.fit,
            agreement: self.agreement,
            state: State::Uncertain,
            particles: self.particles.len(),
            proven: !self.confirming,
        };
        let t = self.settings.thresholds;
        // Once localised, the state is left only beyond a margin (hysteresis), so that an
        // estimate on the edge does not report localised and uncertain by turns.
        let slack = if self.estimate.state == State::Localised {
            LEAVE_LOCALISED
        } else {
            1.0
        };
        let agreement_needed = if self.estimate.state == State::Localised {
            STAY_LOCALISED_AGREEMENT
        } else {
            LOCALISED_AGREEMENT
        };
        estimate.state = if estimate.sigma_m() > t.lost_sigma_m
            || self.fit < t.lost_fit
            || self.agreement < LOST_AGREEMENT
        {
            State::Lost
        } else if (scanned || self.estimate.state == State::Localised)
            && second_weight < SIGNIFICANT_CLUSTER
            && self.agreement >= agreement_needed
            && estimate.sigma_m() <= t.localised_sigma_m * slack
            && estimate.sigma_rad() <= t.localised_sigma_rad * slack
            && self.fit >= t.localised_fit / slack
        {
            State::Localised
        } else {
            State::Uncertain
        };
        estimate.proven = !self.confirming && estimate.state != State::Lost;
        estimate
    }

    /// The mean field value at the ends of the beams of the last scan weighed, from `pose`,
    /// but those a thing the map lacks explains (`explained`, see [`Agreement`]): in the open,
    /// where the laser sees nothing else within range, a box beside the robot made the mean
    /// fall under the threshold of `lost` with the estimate 0.03 m from the truth (measured in
    /// the yard). None when no beam is left.
    fn fit_at(&self, pose: Pose2D, explained: &[bool]) -> Option<f64> {
        let (sin, cos) = pose.theta_rad.sin_cos();
        let (mut sum, mut count) = (0.0, 0usize);
        for (i, &(angle, range)) in self.beams.iter().enumerate() {
            let Some(range) = range else {
                continue;
            };
            if explained.get(i).copied().unwrap_or(false) {
                continue;
            }
            let (lx, ly) = (range * angle.cos(), range * angle.sin());
            sum += self.map.field_at(
                pose.x_m + cos * lx - sin * ly,
                pose.y_m + sin * lx + cos * ly,
            );
            count += 1;
        }
        (count > 0).then(|| sum / count as f64)
    }
}

/// The number of particles KLD sampling asks for when they occupy `bins` bins: the error of the
/// estimated distribution stays under `err` with the confidence whose normal quantile is `z`
/// (Fox 2003, with the Wilson–Hilferty approximation of the chi-square quantile).
pub fn kld_bound(bins: usize, err: f64, z: f64) -> usize {
    if bins <= 1 {
        return 0;
    }
    let k = (bins - 1) as f64;
    let a = 2.0 / (9.0 * k);
    let n = k / (2.0 * err) * (1.0 - a + a.sqrt() * z).powi(3);
    n.ceil() as usize
}

#[cfg(test)]
mod tests;
