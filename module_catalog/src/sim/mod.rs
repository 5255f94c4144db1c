//! `sim`: a simulated differential-drive robot with a planar laser scanner, in a 2-D world read
//! from a `.world` file ([`world`] documents the format; `assets/worlds/` holds examples) or a
//! ROS map_server map ([`armor_model::ros_map`]).
//!
//! The simulation runs on the run clock: it steps the physics `rate_hz` times per second of run
//! time, so `armor run --time-scale 20` runs a simulated minute in three seconds. Each step takes
//! the latest velocity command, moves the robot (stopping it at walls), and publishes odometry
//! and the true pose; every `1 / laser_rate_hz` it also publishes a laser scan. The headless
//! [`Simulator`] does the same without a node, for tools and tests.

pub mod laser;
pub mod rng;
pub mod robot;
pub mod tour;
/// The world model lives in `armor_model` (plans and the studio's maps use it too).
pub use armor_model::world;

use std::path::{Path, PathBuf};

use armor_module_api::types::{Battery, LaserScan, Odometry, Pose2D, Twist};
use armor_module_api::{BodyResult, Event, ModuleSpec, Node, ParamSpec, ParamType};

use crate::BodyError;
use crate::params::float_where;
use laser::Laser;
use rng::Rng;
use robot::{OdometryNoise, Robot};
use world::World;

pub const TYPE: &str = "sim";

/// A command older than this (run time) means stop.
pub const COMMAND_TIMEOUT_SECS: f64 = 0.5;
/// Falling further than this behind the run clock (and half a second of real time), the
/// simulation skips ahead rather than running flat out to catch up. Shorter lags, from timer
/// granularity or a busy moment, are caught up step by step.
const MAX_LAG_SECS: f64 = 1.0;
const MAX_LAG_REAL_SECS: f64 = 0.5;
/// Where world files are looked for when not found as given.
pub const WORLDS_DIR: &str = "assets/worlds";

pub fn spec() -> ModuleSpec {
    ModuleSpec::new(
        TYPE,
        "Simulates a differential-drive robot with a planar laser scanner in a 2-D world of walls \
         and obstacles, on the run clock: drives as commanded on cmd_vel, stops at walls, and \
         publishes drifting odometry, laser scans and the true pose.",
    )
    .category(armor_module_api::Category::Sensor)
    .version(env!("CARGO_PKG_VERSION"))
    .not_controllable()
    .input::<Twist>(
        "cmd_vel",
        "velocity command in the robot's frame (latest value used; a command older than 0.5 s of \
         run time means stop; non-finite values are refused and mean stop; speeds are clamped to \
         max_speed_mps and max_turn_radps)",
    )
    .output::<Odometry>(
        "odometry",
        "dead-reckoned pose in the odometry frame (which starts at the world's start pose) and \
         measured velocity, every physics step; drifts with distance travelled and angle turned",
    )
    .output::<LaserScan>(
        "scan",
        "laser scan from the robot's centre, angles in the robot's frame, with range noise; beams \
         with no echo within range read range_max_m",
    )
    .output::<Pose2D>(
        "pose_truth",
        "true pose in the world frame, every physics step (for evaluation and display only: a \
         real robot has no such sensor)",
    )
    .param(
        ParamSpec::new(
            "world",
            ParamType::String,
            "the world file (format in the module's docs; examples: yard.world, building.world, \
             field.world; or a ROS map_server map.yaml): armor run hands the module the file \
             found next to the system file, in the module path or under assets/worlds/; run \
             alone, tried as given, then under assets/worlds/ of the current directory, adding \
             `.world` if it has no extension",
        )
        .file("worlds"),
    )
    .param(
        ParamSpec::new(
            "rate_hz",
            ParamType::Float,
            "physics steps per second of run time; odometry and pose_truth are published at \
             every step (greater than 0, at most 1000)",
        )
        .above(0.0)
        .max(1000.0)
        .unit("Hz")
        .default("50"),
    )
    .param(
        ParamSpec::new(
            "laser_rate_hz",
            ParamType::Float,
            "laser scans per second of run time (greater than 0, at most rate_hz)",
        )
        .above(0.0)
        .unit("Hz")
        .default("10"),
    )
    .param(
        ParamSpec::new(
            "laser_beams",
            ParamType::Int,
            "beams per scan (1 to 100000)",
        )
        .min(1.0)
        .max(100_000.0)
        .default("360"),
    )
    .param(
        ParamSpec::new(
            "laser_fov_deg",
            ParamType::Float,
            "field of view, centred on the robot's heading (greater than 0, at most 360; 360 \
             spreads the beams all around with none repeated)",
        )
        .above(0.0)
        .max(360.0)
        .unit("deg")
        .default("360"),
    )
    .param(
        ParamSpec::new(
            "laser_range_m",
            ParamType::Float,
            "maximum range of the laser (greater than 0)",
        )
        .above(0.0)
        .unit("m")
        .default("8"),
    )
    .param(
        ParamSpec::new(
            "laser_noise_m",
            ParamType::Float,
            "standard deviation of the Gaussian noise added to each range (0 or more)",
        )
        .min(0.0)
        .unit("m")
        .default("0.01"),
    )
    .param(
        ParamSpec::new(
            "odom_noise_dist",
            ParamType::Float,
            "standard deviation of the odometry's distance error after travelling 1 m (a random \
             walk: it grows with the square root of the distance, whatever rate_hz; 0 or more)",
        )
        .min(0.0)
        .unit("m")
        .default("0.02"),
    )
    .param(
        ParamSpec::new(
            "odom_noise_rot",
            ParamType::Float,
            "standard deviation of the odometry's heading error after turning 1 rad (grows with \
             the square root of the angle turned; 0 or more)",
        )
        .min(0.0)
        .unit("rad")
        .default("0.02"),
    )
    .param(
        ParamSpec::new(
            "odom_noise_drift",
            ParamType::Float,
            "standard deviation of the odometry's heading error after travelling 1 m (grows with \
             the square root of the distance; 0 or more)",
        )
        .min(0.0)
        .unit("rad")
        .default("0.005"),
    )
    .param(
        ParamSpec::new(
            "seed",
            ParamType::Int,
            "seed of the noise: the same seed and the same commands give the same run",
        )
        .default("1"),
    )
    .param(
        ParamSpec::new(
            "max_speed_mps",
            ParamType::Float,
            "linear speed limit, forwards and backwards (greater than 0)",
        )
        .above(0.0)
        .unit("m/s")
        .default("1.0"),
    )
    .param(
        ParamSpec::new(
            "max_turn_radps",
            ParamType::Float,
            "turn rate limit, either way (greater than 0)",
        )
        .above(0.0)
        .unit("rad/s")
        .default("1.5"),
    )
    .param(
        ParamSpec::new(
            "robot_radius_m",
            ParamType::Float,
            "radius of the robot's disc, for collisions (greater than 0)",
        )
        .above(0.0)
        .unit("m")
        .default("0.25"),
    )
    .param(
        ParamSpec::new(
            "obstacles",
            ParamType::String,
            "obstacles in the simulated world that are not in the world file (what no map \
             shows: a pallet left in an aisle), in the world file's syntax, lines separated by \
             `;`: for example `rect 10,4 11,6; circle 5,5 0.5`",
        )
        .default(""),
    )
    .param(
        ParamSpec::new(
            "kidnap",
            ParamType::String,
            "`T X Y HEADING_DEG`: at T seconds of simulated time, carry the robot to (X, Y) \
             facing HEADING_DEG, as if someone picked it up (the odometry does not see it; for \
             testing localisation); empty: never",
        )
        .default(""),
    )
    .output::<Battery>(
        "battery",
        "what is left of the battery's charge (1 full, 0 empty), once a second of simulated \
         time: it drains by battery_drain_per_m for every metre driven and battery_drain_per_hour \
         for every hour that passes",
    )
    .param(
        ParamSpec::new(
            "battery_drain_per_m",
            ParamType::Float,
            "the charge (of 1) driving one metre uses (0 or more; the default gives 500 m on a \
             full charge)",
        )
        .min(0.0)
        .default("0.002"),
    )
    .param(
        ParamSpec::new(
            "battery_drain_per_hour",
            ParamType::Float,
            "the charge (of 1) an hour uses, driving or not (the computers, the sensors; 0 or \
             more)",
        )
        .min(0.0)
        .default("0.1"),
    )
    .param(
        ParamSpec::new(
            "battery_low",
            ParamType::Float,
            "the charge below which the event low_battery is reported (once), from 0 to 1",
        )
        .min(0.0)
        .max(1.0)
        .default("0.2"),
    )
    .param(
        ParamSpec::new(
            "battery_start",
            ParamType::Float,
            "the charge at the start, from 0 to 1",
        )
        .min(0.0)
        .max(1.0)
        .default("1"),
    )
    .event(
        "low_battery",
        "the battery's charge fell below battery_low (once)",
    )
    .event(
        "collision",
        "the robot ran into a wall, an obstacle or the boundary and stopped at the contact \
         (once per contact: again only after moving 5 cm clear)",
    )
}

/// The simulator's settings (the module's parameters other than `world`).
#[derive(Clone, Debug, PartialEq)]
pub struct SimParams {
    pub rate_hz: f64,
    pub laser_rate_hz: f64,
    pub laser_beams: usize,
    pub laser_fov_deg: f64,
    pub laser_range_m: f64,
    pub laser_noise_m: f64,
    pub odom_noise: OdometryNoise,
    pub seed: u64,
    pub max_speed_mps: f64,
    pub max_turn_radps: f64,
    pub robot_radius_m: f64,
    /// When (simulated seconds) and where the robot is carried ([`Simulator::kidnap`]).
    pub kidnap: Option<(f64, Pose2D)>,
    pub battery: BatteryModel,
}

/// How the simulated battery drains: by distance driven and by time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatteryModel {
    pub drain_per_m: f64,
    pub drain_per_hour: f64,
    /// Below this charge, `low_battery` is reported.
    pub low: f64,
    pub start: f64,
}

impl Default for BatteryModel {
    fn default() -> Self {
        Self {
            drain_per_m: 0.002,
            drain_per_hour: 0.1,
            low: 0.2,
            start: 1.0,
        }
    }
}

impl Default for SimParams {
    fn default() -> Self {
        Self {
            rate_hz: 50.0,
            laser_rate_hz: 10.0,
            laser_beams: 360,
            laser_fov_deg: 360.0,
            laser_range_m: 8.0,
            laser_noise_m: 0.01,
            odom_noise: OdometryNoise {
                dist: 0.02,
                rot: 0.02,
                drift: 0.005,
            },
            seed: 1,
            max_speed_mps: 1.0,
            max_turn_radps: 1.5,
            robot_radius_m: 0.25,
            kidnap: None,
            battery: BatteryModel::default(),
        }
    }
}

/// The `kidnap` parameter: `T X Y HEADING_DEG`, or None when empty.
fn parse_kidnap(text: &str) -> Result<Option<(f64, Pose2D)>, String> {
    let words: Vec<&str> = text.split_whitespace().collect();
    if words.is_empty() {
        return Ok(None);
    }
    let numbers: Option<Vec<f64>> = words
        .iter()
        .map(|word| word.parse::<f64>().ok().filter(|v| v.is_finite()))
        .collect();
    match numbers.as_deref() {
        Some(&[t, x_m, y_m, heading_deg]) if t >= 0.0 => Ok(Some((
            t,
            Pose2D {
                x_m,
                y_m,
                theta_rad: crate::wrap_angle(heading_deg.to_radians()),
            },
        ))),
        _ => Err(format!(
            "parameter `kidnap`: `{text}` is not `T X Y HEADING_DEG` (four numbers, T 0 or more)"
        )),
    }
}

impl SimParams {
    /// Reads and checks the parameters, refusing nonsense in words.
    pub fn from_node(node: &Node) -> Result<Self, BodyError> {
        let rate_hz = node.param::<f64>("rate_hz")?;
        let laser_rate_hz = float_where(
            node,
            "laser_rate_hz",
            |value| value <= rate_hz,
            &format!("at most rate_hz ({rate_hz} Hz, scans are taken at physics steps)"),
        )?;
        let laser_beams = node.param::<usize>("laser_beams")?;
        let seed: i64 = node.param("seed")?;
        Ok(Self {
            rate_hz,
            laser_rate_hz,
            laser_beams,
            laser_fov_deg: node.param::<f64>("laser_fov_deg")?,
            laser_range_m: node.param::<f64>("laser_range_m")?,
            laser_noise_m: node.param::<f64>("laser_noise_m")?,
            odom_noise: OdometryNoise {
                dist: node.param::<f64>("odom_noise_dist")?,
                rot: node.param::<f64>("odom_noise_rot")?,
                drift: node.param::<f64>("odom_noise_drift")?,
            },
            seed: u64::from_ne_bytes(seed.to_ne_bytes()),
            max_speed_mps: node.param::<f64>("max_speed_mps")?,
            max_turn_radps: node.param::<f64>("max_turn_radps")?,
            robot_radius_m: node.param::<f64>("robot_radius_m")?,
            kidnap: parse_kidnap(&node.param::<String>("kidnap")?)?,
            battery: BatteryModel {
                drain_per_m: node.param::<f64>("battery_drain_per_m")?,
                drain_per_hour: node.param::<f64>("battery_drain_per_hour")?,
                low: node.param::<f64>("battery_low")?,
                start: node.param::<f64>("battery_start")?,
            },
        })
    }
}

/// Where the world file named `world` is: as given, else under [`WORLDS_DIR`] in the current
/// directory (with `.world` added if the name has no extension).
pub fn find_world(world: &str) -> Result<PathBuf, BodyError> {
    let given = Path::new(world);
    let mut tried = vec![given.to_path_buf()];
    if given.is_relative() {
        tried.push(Path::new(WORLDS_DIR).join(given));
        if given.extension().is_none() {
            tried.push(Path::new(WORLDS_DIR).join(format!("{world}.world")));
        }
    }
    if let Some(found) = tried.iter().find(|path| path.is_file()) {
        return Ok(found.clone());
    }
    let tried: Vec<String> = tried
        .iter()
        .map(|path| format!("`{}`", path.display()))
        .collect();
    let cwd =
        std::env::current_dir().map_or_else(|_| "?".to_owned(), |dir| dir.display().to_string());
    Err(format!(
        "world file `{world}` not found (tried {} in {cwd})",
        tried.join(", ")
    )
    .into())
}

/// What one physics step produced.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    pub odometry: Odometry,
    pub truth: Pose2D,
    /// A new scan is ready: [`Simulator::scan`].
    pub scanned: bool,
    /// The robot has just run into something.
    pub collision: bool,
    /// The battery's charge has just fallen below its low mark.
    pub low_battery: bool,
}

/// The simulation without a node: a world, a robot and its laser, advanced one fixed step at a
/// time. Entirely determined by the world, the parameters, the seed and the commands given
/// between steps.
#[derive(Clone, Debug)]
pub struct Simulator {
    world: World,
    params: SimParams,
    robot: Robot,
    laser: Laser,
    laser_rng: Rng,
    scan: LaserScan,
    steps: u64,
    scans: u64,
    collisions: u64,
    /// The command in force (within the limits) and the simulated time it arrived.
    command: Twist,
    command_time: f64,
    /// What is left of the battery (1 full).
    charge: f64,
}

impl Simulator {
    /// A robot at the world's start pose. Refuses a start pose where the robot does not fit.
    pub fn new(world: World, params: SimParams) -> Result<Self, BodyError> {
        world.check_start(params.robot_radius_m)?;
        let start_charge = params.battery.start;
        let robot = Robot::new(
            world.start(),
            params.robot_radius_m,
            params.odom_noise,
            Rng::new(params.seed, 1),
        );
        let laser = Laser::new(
            params.laser_beams,
            params.laser_fov_deg,
            params.laser_range_m,
            params.laser_noise_m,
        );
        Ok(Self {
            laser_rng: Rng::new(params.seed, 2),
            world,
            params,
            robot,
            laser,
            scan: LaserScan::default(),
            steps: 0,
            scans: 0,
            collisions: 0,
            command: Twist::default(),
            command_time: f64::NEG_INFINITY,
            charge: start_charge,
        })
    }

    pub fn world(&self) -> &World {
        &self.world
    }

    pub fn params(&self) -> &SimParams {
        &self.params
    }

    /// Simulated seconds since the start.
    pub fn time(&self) -> f64 {
        self.steps as f64 / self.params.rate_hz
    }

    pub fn steps(&self) -> u64 {
        self.steps
    }

    pub fn scans(&self) -> u64 {
        self.scans
    }

    pub fn collisions(&self) -> u64 {
        self.collisions
    }

    /// What is left of the battery's charge (1 full, 0 empty).
    pub fn charge(&self) -> f64 {
        self.charge
    }

    /// The true pose (world frame).
    pub fn truth(&self) -> Pose2D {
        self.robot.truth
    }

    /// Carries the robot to `pose` (a kidnapping, for testing localisation): the truth jumps,
    /// the odometry does not. Refused where the robot does not fit.
    pub fn kidnap(&mut self, pose: Pose2D) -> Result<(), String> {
        if !(pose.x_m.is_finite() && pose.y_m.is_finite() && pose.theta_rad.is_finite())
            || self
                .world
                .collides(pose.x_m, pose.y_m, self.params.robot_radius_m)
        {
            return Err(format!(
                "cannot carry the robot to ({:.2}, {:.2}): it does not fit there",
                pose.x_m, pose.y_m
            ));
        }
        self.robot.truth = Pose2D {
            theta_rad: crate::wrap_angle(pose.theta_rad),
            ..pose
        };
        Ok(())
    }

    /// The latest scan.
    pub fn scan(&self) -> &LaserScan {
        &self.scan
    }

    /// A new velocity command, in force for [`COMMAND_TIMEOUT_SECS`] of simulated time. Speeds
    /// beyond the limits are clamped; a non-finite command is refused (the error says why) and
    /// stops the robot.
    pub fn command(&mut self, cmd: Twist) -> Result<Twist, String> {
        self.command_time = self.time();
        if !(cmd.linear_mps.is_finite() && cmd.angular_radps.is_finite()) {
            self.command = Twist::default();
            return Err(format!(
                "refused the command ({} m/s, {} rad/s): not a finite number; stopping",
                cmd.linear_mps, cmd.angular_radps
            ));
        }
        let (speed, turn) = (self.params.max_speed_mps, self.params.max_turn_radps);
        self.command = Twist {
            linear_mps: cmd.linear_mps.clamp(-speed, speed),
            angular_radps: cmd.angular_radps.clamp(-turn, turn),
        };
        Ok(self.command)
    }

    /// Advances by one step of `1 / rate_hz` seconds.
    pub fn step(&mut self) -> StepReport {
        let dt = 1.0 / self.params.rate_hz;
        if let Some((at, pose)) = self.params.kidnap
            && self.time() >= at
        {
            self.params.kidnap = None;
            match self.kidnap(pose) {
                Ok(()) => tracing::warn!(
                    "kidnapped: the robot is carried to ({:.2}, {:.2})",
                    pose.x_m,
                    pose.y_m
                ),
                Err(why) => tracing::error!("parameter `kidnap`: {why}"),
            }
        }
        let age = self.time() - self.command_time;
        let cmd = if age < COMMAND_TIMEOUT_SECS - 1e-9 {
            self.command
        } else {
            Twist::default()
        };
        let before = self.robot.truth;
        let outcome = self.robot.step(&self.world, cmd, dt);
        self.steps += 1;
        let battery = self.params.battery;
        let driven_m = (self.robot.truth.x_m - before.x_m).hypot(self.robot.truth.y_m - before.y_m);
        let was = self.charge;
        self.charge =
            (self.charge - battery.drain_per_m * driven_m - battery.drain_per_hour * dt / 3600.0)
                .max(0.0);
        if outcome.new_contact {
            self.collisions += 1;
        }
        // Scan k is due at k / laser_rate_hz; the first at the first step.
        let due = (self.scans as f64 / self.params.laser_rate_hz) * self.params.rate_hz;
        let scanned = (self.steps - 1) as f64 >= due - 1e-6;
        if scanned {
            self.laser.scan(
                &self.world,
                self.robot.truth,
                &mut self.laser_rng,
                &mut self.scan,
            );
            self.scans += 1;
        }
        StepReport {
            odometry: Odometry {
                pose_in_odom: self.robot.odom,
                twist: self.robot.odom_twist,
            },
            truth: self.robot.truth,
            scanned,
            collision: outcome.new_contact,
            low_battery: was >= battery.low && self.charge < battery.low,
        }
    }
}

/// Loads the world named by the `world` parameter.
pub fn load_world(node: &Node) -> Result<World, BodyError> {
    let name: String = node.param("world").map_err(|_| {
        "parameter `world` is required: the path of a world file (for example `yard` for \
         assets/worlds/yard.world)"
    })?;
    let path = find_world(name.trim())?;
    let obstacles: String = node.param("obstacles")?;
    if obstacles.trim().is_empty() {
        return Ok(load_world_file(&path)?);
    }
    if armor_model::ros_map::is_map_yaml(&path) {
        return Ok(map_with_obstacles(load_world_file(&path)?, &obstacles)?);
    }
    // The extra shapes are read as lines after the file's own, so that the world's parser
    // checks them as it checks the file.
    let file_name = path.display().to_string();
    let mut text = std::fs::read_to_string(&path)
        .map_err(|err| format!("cannot read the world file `{file_name}`: {err}"))?;
    text.push_str("\n# The `obstacles` parameter:\n");
    for line in obstacles.split(';') {
        text.push_str(line.trim());
        text.push('\n');
    }
    World::parse(
        &text,
        &format!("{file_name} with the `obstacles` parameter"),
    )
    .map_err(|err| format!("{err}").into())
}

/// A map's world with the `obstacles` parameter's shapes added: they are read as a world
/// file's lines, in a world that is the map's rectangle, and added to the map.
fn map_with_obstacles(map: World, obstacles: &str) -> Result<World, world::WorldError> {
    let (b, start) = (map.bounds(), map.start());
    let mut text = format!(
        "name obstacles\norigin 0 0\nstart {} {} 0\nboundary {},{} {},{} {},{} {},{} {},{}\n",
        start.x_m,
        start.y_m,
        b.min_x,
        b.min_y,
        b.max_x,
        b.min_y,
        b.max_x,
        b.max_y,
        b.min_x,
        b.max_y,
        b.min_x,
        b.min_y
    );
    for line in obstacles.split(';') {
        text.push_str(line.trim());
        text.push('\n');
    }
    let extra = World::parse(&text, "the `obstacles` parameter")?;
    map.with_shapes(extra.shapes().iter().skip(1).cloned())
}

/// Reads and checks a world file (a `.world` file or a ROS map_server `map.yaml`).
pub fn load_world_file(path: &std::path::Path) -> Result<World, world::WorldError> {
    armor_model::world_file::load(path, &mut |path| std::fs::read(path))
}

pub fn body(node: &mut Node) -> BodyResult {
    let params = SimParams::from_node(node)?;
    let world = load_world(node)?;
    let cmd_vel = node.input::<Twist>("cmd_vel")?;
    let odometry = node.output::<Odometry>("odometry")?;
    let scan = node.output::<LaserScan>("scan")?;
    let pose_truth = node.output::<Pose2D>("pose_truth")?;
    let battery = node.output::<Battery>("battery")?;
    tracing::info!(
        "world `{}` ({}): {} shapes, start at ({:.2}, {:.2}); stepping at {} Hz, scanning {} beams at {} Hz",
        world.name(),
        world.file_name(),
        world.shapes().len(),
        world.start().x_m,
        world.start().y_m,
        params.rate_hz,
        params.laser_beams,
        params.laser_rate_hz
    );
    let mut sim = Simulator::new(world, params)?;
    let dt = 1.0 / sim.params().rate_hz;
    let max_lag = MAX_LAG_SECS.max(MAX_LAG_REAL_SECS * node.clock().scale());
    // The run time at which simulated time was zero.
    let mut run_time_at_zero = node.timestamp();
    loop {
        let due = run_time_at_zero + sim.time() + dt;
        let deadline = node.clock().instant_at(due);
        match node.next_event_until(deadline)? {
            Event::Timeout => {
                let report = sim.step();
                node.send(&odometry, &report.odometry)?;
                node.send(&pose_truth, &report.truth)?;
                if report.scanned {
                    node.send(&scan, sim.scan())?;
                }
                // The charge once a second of simulated time, from the first step.
                if (sim.steps() - 1) % (sim.params().rate_hz.round().max(1.0) as u64) == 0 {
                    node.send(
                        &battery,
                        &Battery {
                            charge: sim.charge(),
                        },
                    )?;
                }
                if report.low_battery {
                    tracing::warn!("low battery: {:.0} % left", sim.charge() * 100.0);
                    node.report("low_battery")?;
                }
                if report.collision {
                    let at = report.truth;
                    tracing::warn!("collision at ({:.2}, {:.2})", at.x_m, at.y_m);
                    node.report("collision")?;
                }
                let behind = node.timestamp() - (run_time_at_zero + sim.time());
                if behind > max_lag {
                    tracing::warn!(
                        "{behind:.1} s of run time behind: this computer cannot simulate this fast (lower --time-scale, rate_hz or laser_beams); skipping ahead"
                    );
                    run_time_at_zero += behind;
                }
            }
            Event::Input(port) if port == cmd_vel.id() => {
                if let Some(sample) = node.take(&cmd_vel)?
                    && let Err(why) = sim.command(sample.value)
                {
                    tracing::warn!("{why}");
                }
            }
            Event::ParamsChanged(names) => tracing::warn!(
                "new values of {} are taken when the simulator restarts",
                names.join(", ")
            ),
            Event::Shutdown => {
                tracing::info!(
                    "simulated {:.1} s: {} steps, {} scans, {} collisions",
                    sim.time(),
                    sim.steps(),
                    sim.scans(),
                    sim.collisions()
                );
                return Ok(());
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use armor_module_api::testing::{Step, TestBench};

    const ROOM: &str = "\
name Test room
origin 45.5 -73.6
start 5 5 0
boundary 0,0 10,0 10,10 0,10 0,0
";

    /// A world file that lives as long as the test.
    fn world_file(text: &str) -> tempfile::NamedTempFile {
        let file = tempfile::Builder::new()
            .suffix(".world")
            .tempfile()
            .expect("temp file");
        std::fs::write(file.path(), text).expect("write");
        file
    }

    fn bench(world: &tempfile::NamedTempFile, params: &[(&str, &str)]) -> TestBench {
        let path = world.path().display().to_string();
        let mut all = vec![("world", path.as_str())];
        all.extend_from_slice(params);
        TestBench::new(&spec(), &all).expect("bench")
    }

    fn twist(linear_mps: f64, angular_radps: f64) -> Twist {
        Twist {
            linear_mps,
            angular_radps,
        }
    }

    fn push(cmd: Twist) -> Step {
        Step::push("cmd_vel", &cmd).expect("encode")
    }

    /// Noise-free, so the odometry equals the truth.
    const EXACT: &[(&str, &str)] = &[
        ("odom_noise_dist", "0"),
        ("odom_noise_rot", "0"),
        ("odom_noise_drift", "0"),
        ("laser_noise_m", "0"),
    ];

    fn last_truth(bench: &TestBench) -> Pose2D {
        *bench
            .sent::<Pose2D>("pose_truth")
            .expect("sent")
            .last()
            .expect("a pose")
    }

    #[test]
    fn drives_straight_then_stops_when_commands_stop() {
        let world = world_file(ROOM);
        let mut bench = bench(&world, EXACT);
        // 0.5 m/s for 2 × 0.4 s, then nothing: the last command holds for 0.5 s, then stop.
        bench.script([
            push(twist(0.5, 0.0)),
            Step::Timeouts(20),
            push(twist(0.5, 0.0)),
            Step::Timeouts(50),
        ]);
        body(bench.node()).expect("body");
        let truth = bench.sent::<Pose2D>("pose_truth").expect("sent");
        assert_eq!(truth.len(), 70);
        let end = truth[69];
        assert!((end.x_m - 5.45).abs() < 1e-9, "{end:?}");
        assert!((end.y_m - 5.0).abs() < 1e-12 && end.theta_rad == 0.0);
        assert_eq!(truth[44], end, "stopped 0.5 s after the last command");
        assert!(truth[43].x_m < end.x_m);
        let odometry = bench.sent::<Odometry>("odometry").expect("sent");
        assert_eq!(odometry.len(), 70);
        assert!((odometry[10].twist.linear_mps - 0.5).abs() < 1e-9);
        assert!((odometry[69].pose_in_odom.x_m - end.x_m).abs() < 1e-9);
        assert_eq!(odometry[69].twist, Twist::default());
        // 10 Hz scans from 50 Hz steps: at steps 1, 6, 11, ... 66.
        let scans = bench.sent::<LaserScan>("scan").expect("sent");
        assert_eq!(scans.len(), 14);
        assert_eq!(scans[0].ranges_m.len(), 360);
        // Taken after the first step, 1 cm on.
        let ahead = scans[0].ranges_m[180];
        assert!(
            (ahead - 4.99).abs() < 1e-5,
            "beam 180 looks straight ahead: {ahead}"
        );
        assert!(bench.reported().is_empty());
    }

    #[test]
    fn turns_and_follows_arcs_as_commanded() {
        let world = world_file(ROOM);
        let mut bench = bench(&world, EXACT);
        bench.script([push(twist(0.0, 1.0)), Step::Timeouts(25)]);
        body(bench.node()).expect("body");
        let end = last_truth(&bench);
        assert!((end.theta_rad - 0.5).abs() < 1e-9, "{end:?}");
        assert!((end.x_m - 5.0).abs() < 1e-12 && (end.y_m - 5.0).abs() < 1e-12);

        // 0.4 m/s turning at 0.8 rad/s: an arc of radius 0.5 m, for 0.5 s.
        let mut bench = self::bench(&world, EXACT);
        bench.script([push(twist(0.4, 0.8)), Step::Timeouts(25)]);
        body(bench.node()).expect("body");
        let end = last_truth(&bench);
        assert!((end.theta_rad - 0.4).abs() < 1e-9);
        assert!(
            (end.x_m - (5.0 + 0.5 * 0.4f64.sin())).abs() < 1e-9,
            "{end:?}"
        );
        assert!(
            (end.y_m - (5.0 + 0.5 * (1.0 - 0.4f64.cos()))).abs() < 1e-9,
            "{end:?}"
        );
    }

    #[test]
    fn commands_are_clamped_to_the_limits() {
        let world = world_file(ROOM);
        let mut bench = bench(
            &world,
            &[("max_speed_mps", "0.5"), ("max_turn_radps", "0.2")],
        );
        bench.script([push(twist(-3.0, 9.0)), Step::Timeouts(25)]);
        body(bench.node()).expect("body");
        let end = last_truth(&bench);
        assert!((end.theta_rad - 0.1).abs() < 1e-9, "{end:?}");
        let travelled = (end.x_m - 5.0).hypot(end.y_m - 5.0);
        assert!((travelled - 0.25).abs() < 1e-3, "{travelled}");
        assert!(end.x_m < 5.0, "backwards");
    }

    #[test]
    fn a_nan_command_is_refused_and_stops_the_robot() {
        let world = world_file(ROOM);
        let mut bench = bench(&world, EXACT);
        bench.script([
            push(twist(f64::NAN, 0.0)),
            Step::Timeouts(10),
            push(twist(1.0, 0.0)),
            Step::Timeouts(10),
            push(twist(0.5, f64::INFINITY)),
            Step::Timeouts(10),
        ]);
        body(bench.node()).expect("body");
        let truth = bench.sent::<Pose2D>("pose_truth").expect("sent");
        assert_eq!(
            truth[9],
            Pose2D {
                x_m: 5.0,
                y_m: 5.0,
                theta_rad: 0.0
            },
            "NaN: no motion"
        );
        assert!((truth[19].x_m - 5.2).abs() < 1e-9, "{:?}", truth[19]);
        assert_eq!(truth[29], truth[19], "infinite: stop at once");
    }

    #[test]
    fn the_battery_drains_by_distance_and_time_and_says_when_it_runs_low() {
        let world = world_file(ROOM);
        // 1 % a metre, 36 % an hour (0.01 % a second), low below 95 %.
        let mut params = EXACT.to_vec();
        params.extend([
            ("battery_drain_per_m", "0.01"),
            ("battery_drain_per_hour", "0.36"),
            ("battery_low", "0.95"),
        ]);
        // 1 m/s for 4 s (pushed every 0.4 s): 4 m driven in 4 s, then 2 s standing.
        let drive = |params: &[(&str, &str)]| {
            let mut bench = bench(&world, params);
            let mut script = Vec::new();
            for _ in 0..10 {
                script.extend([push(twist(1.0, 0.0)), Step::Timeouts(20)]);
            }
            script.push(Step::Timeouts(100));
            bench.script(script);
            body(bench.node()).expect("body");
            bench
        };
        let bench = drive(&params);
        let charges: Vec<f64> = bench
            .sent::<Battery>("battery")
            .expect("sent")
            .iter()
            .map(|battery| battery.charge)
            .collect();
        // Once a second of simulated time: 300 steps at 50 Hz, from the first.
        assert_eq!(charges.len(), 6, "{charges:?}");
        let driven_m = last_truth(&bench).x_m - 5.0;
        let expected = 1.0 - 0.01 * driven_m - 0.0001 * 6.0;
        let last = *charges.last().expect("a charge");
        // The last sample is a second before the end: at most a second's drain off.
        assert!(
            (last - expected).abs() < 0.0002 && driven_m > 3.5,
            "{charges:?} after {driven_m} m, expected {expected}"
        );
        assert!(charges.windows(2).all(|pair| pair[1] <= pair[0]));
        // Above its low mark (95 %) all along: no event. The same drive with the mark at 97 %
        // falls below it once.
        assert_eq!(bench.reported(), Vec::<String>::new(), "{charges:?}");
        let mut higher = params.clone();
        higher.retain(|(name, _)| *name != "battery_low");
        higher.push(("battery_low", "0.97"));
        assert_eq!(drive(&higher).reported(), ["low_battery"]);
    }

    #[test]
    fn stops_at_a_wall_and_reports_the_collision_once() {
        let world = world_file(ROOM);
        let mut bench = bench(&world, EXACT);
        // 1 m/s towards the wall at x = 10, for 6 s (pushing every 0.4 s).
        let mut script = Vec::new();
        for _ in 0..15 {
            script.extend([push(twist(1.0, 0.0)), Step::Timeouts(20)]);
        }
        bench.script(script);
        body(bench.node()).expect("body");
        let end = last_truth(&bench);
        assert!(
            (end.x_m - 9.75).abs() < 1e-6,
            "stopped at the contact: {end:?}"
        );
        assert_eq!(bench.reported(), ["collision"]);

        // Back off 10 cm, and in again: a new contact.
        let mut bench = self::bench(&world, EXACT);
        let mut script = Vec::new();
        for _ in 0..15 {
            script.extend([push(twist(1.0, 0.0)), Step::Timeouts(20)]);
        }
        script.extend([push(twist(-0.5, 0.0)), Step::Timeouts(10)]);
        script.extend([push(twist(0.0, 1.0)), Step::Timeouts(10)]);
        script.extend([push(twist(0.5, 0.0)), Step::Timeouts(20)]);
        bench.script(script);
        body(bench.node()).expect("body");
        assert_eq!(bench.reported(), ["collision", "collision"]);
    }

    #[test]
    fn turning_at_a_wall_is_the_same_contact() {
        let world = world_file(ROOM);
        let mut bench = bench(&world, EXACT);
        let mut script = Vec::new();
        for _ in 0..15 {
            script.extend([push(twist(1.0, 0.0)), Step::Timeouts(20)]);
        }
        // Still pressing on: stuck. Then a turn on the spot to 1.6 rad, and off along the wall.
        script.extend([push(twist(1.0, 0.3)), Step::Timeouts(20)]);
        for _ in 0..4 {
            script.extend([push(twist(0.0, 1.0)), Step::Timeouts(20)]);
        }
        script.extend([push(twist(1.0, 0.0)), Step::Timeouts(20)]);
        bench.script(script);
        body(bench.node()).expect("body");
        assert_eq!(bench.reported(), ["collision"]);
        let truth = bench.sent::<Pose2D>("pose_truth").expect("sent");
        let pressing = truth[319];
        assert!((pressing.x_m - 9.75).abs() < 1e-6 && (pressing.y_m - 5.0).abs() < 1e-6);
        let end = truth[truth.len() - 1];
        assert!((end.theta_rad - 1.72).abs() < 1e-9, "{end:?}");
        assert!(
            end.y_m > 5.35,
            "moved off along the wall after turning: {end:?}"
        );
    }

    fn odometry_run(seed: &str) -> Vec<Odometry> {
        let world = world_file(ROOM);
        let mut bench = bench(&world, &[("seed", seed)]);
        let mut script = Vec::new();
        for _ in 0..5 {
            script.extend([push(twist(0.8, 0.3)), Step::Timeouts(20)]);
        }
        bench.script(script);
        body(bench.node()).expect("body");
        bench.sent::<Odometry>("odometry").expect("sent")
    }

    #[test]
    fn odometry_repeats_for_a_seed_and_differs_between_seeds() {
        let first = odometry_run("7");
        assert_eq!(first.len(), 100);
        assert_eq!(first, odometry_run("7"));
        assert_ne!(first, odometry_run("8"));
        let world = world_file(ROOM);
        let scans = |seed: &str| {
            let mut bench = bench(&world, &[("seed", seed)]);
            bench.script([Step::Timeouts(1)]);
            body(bench.node()).expect("body");
            bench.sent::<LaserScan>("scan").expect("sent")
        };
        assert_eq!(scans("3"), scans("3"));
        assert_ne!(scans("3"), scans("4"));
    }

    #[test]
    fn odometry_error_grows_with_distance_in_the_module() {
        // Straight at 1 m/s in a long corridor; the mean error over seeds after 1 m and 16 m.
        // (Kept short: the bench decodes every message sent.)
        let world =
            world_file("name long\norigin 0 0\nstart 1 5 0\nboundary 0,0 30,0 30,10 0,10 0,0\n");
        let mean_error = |metres: usize| {
            let mut total = 0.0;
            for seed in 1..=5 {
                let seed = seed.to_string();
                let mut bench = bench(&world, &[("seed", &seed), ("laser_beams", "1")]);
                let mut script = Vec::new();
                for _ in 0..metres * 5 {
                    script.extend([push(twist(1.0, 0.0)), Step::Timeouts(10)]);
                }
                bench.script(script);
                body(bench.node()).expect("body");
                let odom = bench.sent::<Odometry>("odometry").expect("sent");
                let (odom, truth) = (odom[odom.len() - 1].pose_in_odom, last_truth(&bench));
                assert!((truth.x_m - (1.0 + metres as f64)).abs() < 1e-6);
                total += (odom.x_m - truth.x_m).hypot(odom.y_m - truth.y_m);
            }
            total / 5.0
        };
        let (short, long) = (mean_error(1), mean_error(16));
        assert!(
            long > 2.0 * short,
            "{short} m after 1 m, {long} m after 16 m"
        );
    }

    #[test]
    fn refuses_bad_parameters_and_worlds() {
        let world = world_file(ROOM);
        let refusal = |params: &[(&str, &str)]| {
            let mut bench = bench(&world, params);
            body(bench.node()).expect_err("must refuse").to_string()
        };
        assert_eq!(
            refusal(&[("rate_hz", "0")]),
            "parameter `rate_hz` must be greater than 0 Hz and at most 1000 Hz, not 0"
        );
        assert_eq!(
            refusal(&[("laser_rate_hz", "60")]),
            "parameter `laser_rate_hz` must be at most rate_hz (50 Hz, scans are taken at physics steps), not 60"
        );
        assert_eq!(
            refusal(&[("laser_beams", "0")]),
            "parameter `laser_beams` must be between 1 and 100000, not 0"
        );
        assert_eq!(
            refusal(&[("odom_noise_rot", "-0.1")]),
            "parameter `odom_noise_rot` must be 0 rad or more, not -0.1"
        );
        // The `obstacles` parameter's shapes are in the world: one on the start pose is refused
        // as the file's own would be, and a broken one is refused in the world's words.
        let extra = refusal(&[("obstacles", "rect 8,8 9,9; circle 5,5.3 0.2")]);
        assert!(
            extra.contains("with the `obstacles` parameter") && extra.contains("overlaps"),
            "{extra}"
        );
        let broken = refusal(&[("obstacles", "circle 5")]);
        assert!(broken.contains("circle"), "{broken}");
        assert_eq!(
            refusal(&[("robot_radius_m", "6")]),
            format!(
                "{}:3:7: the robot (radius 6 m) at the start pose (5, 5) overlaps the boundary on line 4",
                world.path().display()
            )
        );
        let bad = world_file("name x\norigin 0 0\nstart 1 1 0\nboundary 0,0 4,0 4,4 0,4\n");
        let mut bench = bench(&bad, &[]);
        let err = body(bench.node()).expect_err("must refuse").to_string();
        assert_eq!(
            err,
            format!(
                "{}:4:22: the boundary is not closed: it starts at (0, 0) but ends at (0, 4) (repeat the first vertex at the end)",
                bad.path().display()
            )
        );
        let mut bench = TestBench::new(&spec(), &[]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse").to_string();
        assert!(err.starts_with("parameter `world` is required"), "{err}");
        let mut bench = TestBench::new(&spec(), &[("world", "no-such-world")]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse").to_string();
        assert!(
            err.starts_with("world file `no-such-world` not found (tried `no-such-world`, `assets/worlds/no-such-world`, `assets/worlds/no-such-world.world` in "),
            "{err}"
        );
    }

    #[test]
    fn bundled_worlds_are_found_by_name_from_the_workspace() {
        // Tests run in the package's folder; the worlds are in the workspace's.
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        for name in ["yard", "building", "field"] {
            let path = root.join(WORLDS_DIR).join(format!("{name}.world"));
            let world = load_world_file(&path).expect("loads");
            let mut sim = Simulator::new(world, SimParams::default()).expect("fits");
            sim.command(twist(0.5, 0.2)).expect("finite");
            for _ in 0..25 {
                sim.step();
            }
            assert_eq!((sim.scans(), sim.scan().ranges_m.len()), (5, 360));
            assert_eq!(sim.collisions(), 0, "{name}: room to move at the start");
        }
    }
}
