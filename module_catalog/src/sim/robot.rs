//! The simulated robot: a differential-drive disc that stops at walls, and its odometry.

use armor_module_api::types::{Pose2D, Twist};

use super::rng::Rng;
use super::world::World;

/// After a collision the robot must move this far clear of everything before another contact
/// counts as new.
pub const CONTACT_RELEASE_M: f64 = 0.05;
/// Bisection steps when looking for the point of contact (far below a micrometre).
const CONTACT_SEARCH_STEPS: usize = 40;

pub use crate::wrap_angle;

/// The pose reached after `t` seconds at linear speed `v` and turn rate `w` (exact
/// differential-drive kinematics: a straight line or an arc of a circle).
pub fn advance(pose: Pose2D, v: f64, w: f64, t: f64) -> Pose2D {
    let turn = w * t;
    let theta = pose.theta_rad;
    let (x_m, y_m) = if turn.abs() < 1e-9 {
        let heading = theta + turn / 2.0;
        (
            pose.x_m + v * t * heading.cos(),
            pose.y_m + v * t * heading.sin(),
        )
    } else {
        let radius = v / w;
        (
            pose.x_m + radius * ((theta + turn).sin() - theta.sin()),
            pose.y_m - radius * ((theta + turn).cos() - theta.cos()),
        )
    };
    Pose2D {
        x_m,
        y_m,
        theta_rad: wrap_angle(theta + turn),
    }
}

/// Where a disc of `radius` ends after moving from `pose` at (`v`, `w`) for `dt`, and whether it
/// was stopped by a contact. The motion is checked in sub-steps of at most half the radius, so
/// even a fast robot at a low rate cannot pass through a thin wall. At a contact the disc stops
/// where it touches, then finishes the step's turn on the spot (a turning disc hits nothing).
pub fn move_disc(
    world: &World,
    pose: Pose2D,
    v: f64,
    w: f64,
    dt: f64,
    radius: f64,
) -> (Pose2D, bool) {
    let distance = v.abs() * dt;
    let substeps = ((distance / (0.5 * radius)).ceil() as usize).clamp(1, 10_000);
    let sub_dt = dt / substeps as f64;
    let mut current = pose;
    for i in 0..substeps {
        let next = advance(current, v, w, sub_dt);
        if !world.collides(next.x_m, next.y_m, radius) {
            current = next;
            continue;
        }
        let (mut free, mut blocked) = (0.0, 1.0);
        for _ in 0..CONTACT_SEARCH_STEPS {
            let mid = (free + blocked) / 2.0;
            let probe = advance(current, v, w, sub_dt * mid);
            if world.collides(probe.x_m, probe.y_m, radius) {
                blocked = mid;
            } else {
                free = mid;
            }
        }
        let contact = advance(current, v, w, sub_dt * free);
        let remaining = dt - sub_dt * (i as f64 + free);
        let stopped = Pose2D {
            theta_rad: wrap_angle(contact.theta_rad + w * remaining),
            ..contact
        };
        return (stopped, true);
    }
    (current, false)
}

/// How odometry drifts. Each is the standard deviation of an error after 1 m travelled or 1 rad
/// turned; errors are a random walk, so their standard deviation grows with the square root of
/// the distance or angle, whatever the step rate (the variance of each step's error is
/// proportional to the step's motion, as in the probabilistic-robotics odometry model).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OdometryNoise {
    /// Distance error per metre travelled (m).
    pub dist: f64,
    /// Heading error per radian turned (rad).
    pub rot: f64,
    /// Heading error per metre travelled (rad).
    pub drift: f64,
}

/// What a step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepOutcome {
    /// The robot was stopped by a contact during this step.
    pub blocked: bool,
    /// ... and this contact is new (it was clear before): report it.
    pub new_contact: bool,
}

/// The robot's true pose and its odometry.
#[derive(Clone, Debug)]
pub struct Robot {
    /// True pose in the world frame.
    pub truth: Pose2D,
    /// Dead-reckoned pose in the odometry frame (which starts at the start pose).
    pub odom: Pose2D,
    /// Velocity as odometry measures it.
    pub odom_twist: Twist,
    pub radius_m: f64,
    noise: OdometryNoise,
    rng: Rng,
    in_contact: bool,
}

impl Robot {
    pub fn new(start: Pose2D, radius_m: f64, noise: OdometryNoise, rng: Rng) -> Self {
        Self {
            truth: start,
            odom: start,
            odom_twist: Twist::default(),
            radius_m,
            noise,
            rng,
            in_contact: false,
        }
    }

    /// Whether the robot is touching something (since its last collision it has not moved
    /// [`CONTACT_RELEASE_M`] clear).
    pub fn in_contact(&self) -> bool {
        self.in_contact
    }

    /// Drives for `dt` seconds at `cmd` (already within the limits).
    pub fn step(&mut self, world: &World, cmd: Twist, dt: f64) -> StepOutcome {
        let before = self.truth;
        let (after, blocked) = move_disc(
            world,
            before,
            cmd.linear_mps,
            cmd.angular_radps,
            dt,
            self.radius_m,
        );
        self.truth = after;
        self.update_odometry(before, after, dt);
        let new_contact = blocked && !self.in_contact;
        if blocked {
            self.in_contact = true;
        } else if self.in_contact
            && !world.collides(after.x_m, after.y_m, self.radius_m + CONTACT_RELEASE_M)
        {
            self.in_contact = false;
        }
        StepOutcome {
            blocked,
            new_contact,
        }
    }

    /// Adds the step's true motion, with noise, to the odometry pose.
    fn update_odometry(&mut self, before: Pose2D, after: Pose2D, dt: f64) {
        let (sin, cos) = before.theta_rad.sin_cos();
        let (dx, dy) = (after.x_m - before.x_m, after.y_m - before.y_m);
        // The motion in the robot's frame at the start of the step.
        let (local_x, local_y) = (cos * dx + sin * dy, -sin * dx + cos * dy);
        let turn = wrap_angle(after.theta_rad - before.theta_rad);
        let distance = local_x.hypot(local_y);
        let noise = self.noise;
        let distance_error = noise.dist * distance.sqrt() * self.rng.standard_normal();
        let heading_error = (noise.rot.powi(2) * turn.abs() + noise.drift.powi(2) * distance)
            .sqrt()
            * self.rng.standard_normal();
        let scale = if distance > 0.0 {
            (distance + distance_error) / distance
        } else {
            1.0
        };
        let (sin, cos) = (self.odom.theta_rad + heading_error / 2.0).sin_cos();
        let (mx, my) = (local_x * scale, local_y * scale);
        self.odom.x_m += cos * mx - sin * my;
        self.odom.y_m += sin * mx + cos * my;
        self.odom.theta_rad = wrap_angle(self.odom.theta_rad + turn + heading_error);
        let travelled = (distance * scale).copysign(local_x);
        self.odom_twist = if dt > 0.0 {
            Twist {
                linear_mps: travelled / dt,
                angular_radps: (turn + heading_error) / dt,
            }
        } else {
            Twist::default()
        };
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    fn room() -> World {
        World::parse(
            "name room\norigin 0 0\nstart 5 5 0\nboundary 0,0 10,0 10,10 0,10 0,0\n",
            "room.world",
        )
        .expect("valid")
    }

    fn pose(x_m: f64, y_m: f64, theta_rad: f64) -> Pose2D {
        Pose2D {
            x_m,
            y_m,
            theta_rad,
        }
    }

    fn close(a: Pose2D, b: Pose2D) -> bool {
        (a.x_m - b.x_m).abs() < 1e-9
            && (a.y_m - b.y_m).abs() < 1e-9
            && wrap_angle(a.theta_rad - b.theta_rad).abs() < 1e-9
    }

    #[test]
    fn differential_drive_kinematics() {
        let start = pose(1.0, 2.0, 0.0);
        assert!(close(advance(start, 0.5, 0.0, 2.0), pose(2.0, 2.0, 0.0)));
        assert!(close(advance(start, 0.0, 1.0, 1.5), pose(1.0, 2.0, 1.5)));
        // A quarter circle of radius 2 to the left.
        let quarter = advance(start, 1.0, 0.5, PI);
        assert!(close(quarter, pose(3.0, 4.0, PI / 2.0)), "{quarter:?}");
        // Facing north, backwards while turning clockwise: half a turn around (-1, 0).
        let half = advance(pose(0.0, 0.0, PI / 2.0), -1.0, -1.0, PI);
        assert!(close(half, pose(-2.0, 0.0, -PI / 2.0)), "{half:?}");
        assert_eq!(wrap_angle(3.0 * PI), PI);
        assert!((wrap_angle(-3.5 * PI) - PI / 2.0).abs() < 1e-12);
    }

    #[test]
    fn a_fast_robot_does_not_pass_through_a_thin_wall() {
        let world = World::parse(
            "name w\norigin 0 0\nstart 1 5 0\nboundary 0,0 10,0 10,10 0,10 0,0\nwall 3,1 3,9\n",
            "w.world",
        )
        .expect("valid");
        let (after, blocked) = move_disc(&world, pose(1.0, 5.0, 0.0), 10.0, 0.0, 1.0, 0.25);
        assert!(blocked);
        assert!((after.x_m - 2.75).abs() < 1e-6, "{after:?}");
    }

    #[test]
    fn stops_at_contact_and_can_turn_away() {
        let world = room();
        let (after, blocked) = move_disc(&world, pose(9.7, 5.0, 0.0), 1.0, 1.0, 0.1, 0.25);
        assert!(blocked);
        assert!(!world.collides(after.x_m, after.y_m, 0.25));
        assert!(world.collides(after.x_m, after.y_m, 0.2501));
        assert!(
            (after.theta_rad - 0.1).abs() < 1e-9,
            "the whole turn is done"
        );
    }

    fn drive(seed: u64, distance_m: f64) -> Robot {
        let world = World::parse(
            "name long\norigin 0 0\nstart 1 50 0\nboundary 0,0 200,0 200,100 0,100 0,0\n",
            "long.world",
        )
        .expect("valid");
        let noise = OdometryNoise {
            dist: 0.02,
            rot: 0.02,
            drift: 0.005,
        };
        let mut robot = Robot::new(world.start(), 0.25, noise, Rng::new(seed, 1));
        let cmd = Twist {
            linear_mps: 1.0,
            angular_radps: 0.0,
        };
        for _ in 0..(distance_m * 50.0).round() as usize {
            robot.step(&world, cmd, 0.02);
        }
        robot
    }

    fn position_error(robot: &Robot) -> f64 {
        (robot.odom.x_m - robot.truth.x_m).hypot(robot.odom.y_m - robot.truth.y_m)
    }

    #[test]
    fn odometry_error_grows_with_distance() {
        let mean_error = |distance: f64| {
            (1..=40)
                .map(|seed| position_error(&drive(seed, distance)))
                .sum::<f64>()
                / 40.0
        };
        let (short, long) = (mean_error(2.0), mean_error(50.0));
        assert!(short > 0.0);
        assert!(
            long > 3.0 * short,
            "{short} m after 2 m, {long} m after 50 m"
        );
        let robot = drive(3, 10.0);
        assert!((robot.truth.x_m - 11.0).abs() < 1e-9, "the truth is exact");
        assert!((robot.odom_twist.linear_mps - 1.0).abs() < 0.5);
    }

    #[test]
    fn odometry_is_exact_without_noise_and_still_when_standing() {
        let world = room();
        let mut robot = Robot::new(
            world.start(),
            0.25,
            OdometryNoise::default(),
            Rng::new(1, 1),
        );
        let cmd = Twist {
            linear_mps: 0.5,
            angular_radps: 0.3,
        };
        for _ in 0..100 {
            robot.step(&world, cmd, 0.02);
        }
        assert!(
            close(robot.odom, robot.truth),
            "{:?} {:?}",
            robot.odom,
            robot.truth
        );
        let mut noisy = Robot::new(
            world.start(),
            0.25,
            OdometryNoise {
                dist: 0.1,
                rot: 0.1,
                drift: 0.1,
            },
            Rng::new(1, 1),
        );
        for _ in 0..100 {
            noisy.step(&world, Twist::default(), 0.02);
        }
        assert_eq!(noisy.odom, world.start());
    }
}
