//! A scripted drive with the headless [`Simulator`]: waypoints followed from the true pose, for
//! tests and benchmarks that need realistic scans and odometry without a navigation stack.

use armor_module_api::types::{Pose2D, Twist};

use super::{Simulator, StepReport};
use crate::nav::wrap_angle;

/// Waypoints of a loop through the office floor (`building.world`): east along the corridor,
/// round the middle north room, round the middle south room past the meeting table, and back
/// west along the corridor to the start.
pub const BUILDING_LOOP: &[(f64, f64)] = &[
    (14.7, 9.5),
    (14.7, 13.0),
    (12.0, 13.0),
    (12.0, 18.5),
    (18.0, 18.5),
    (18.0, 13.0),
    (14.7, 13.0),
    (14.7, 9.5),
    (19.7, 9.5),
    (19.7, 6.0),
    (17.0, 6.0),
    (17.0, 1.0),
    (23.0, 1.0),
    (23.0, 5.5),
    (19.7, 5.5),
    (19.7, 9.5),
    (2.5, 9.5),
];

/// A floor built round a ring corridor, for the mapper's loop closure: a 32 m × 24 m building
/// whose corridor, 3 m wide, runs all the way round a block of rooms, so that a drive round it
/// comes back to where it started after 100 m without having seen any of it on the way. Doorways
/// into the rooms, furniture and cabinets along the outer wall give the scan matcher something
/// to hold on to, as in a real building; the corridor's long straight stretches are where its
/// drift grows.
pub const RING_FLOOR: &str = "\
name     Ring floor
origin   48.71250 2.20420
start    4 1.5 0
boundary 0,0 32,0 32,24 0,24 0,0
wall     3,3 6,3
wall     7.4,3 29,3
wall     29,3 29,19
wall     29,20.4 29,21
wall     29,21 26,21
wall     24.6,21 3,21
wall     3,21 3,6
wall     3,4.6 3,3
rect     0,9 0.6,10
";

/// Once round [`RING_FLOOR`]'s corridor, anticlockwise from the start and back to it: 100 m.
pub const RING_LOOP: &[(f64, f64)] = &[
    (30.5, 1.5),
    (30.5, 22.5),
    (1.5, 22.5),
    (1.5, 1.5),
    (4.0, 1.5),
];

/// The warehouse round (`warehouse.world`): east along the main aisle to the cross aisle, down
/// it into the south aisle, west along it, and up to the start.
pub const WAREHOUSE_ROUND: &[(f64, f64)] = &[
    (25.5, 10.0),
    (25.5, 3.0),
    (10.0, 3.0),
    (3.0, 3.0),
    (3.0, 10.0),
];

/// A waypoint counts as reached this close.
const REACHED_M: f64 = 0.15;

/// A command towards a waypoint from the true pose: turn on the spot when far off course.
pub fn steer(truth: Pose2D, (x, y): (f64, f64)) -> Twist {
    let heading = (y - truth.y_m).atan2(x - truth.x_m);
    let error = wrap_angle(heading - truth.theta_rad);
    let angular_radps = (2.0 * error).clamp(-1.2, 1.2);
    let linear_mps = if error.abs() > 0.4 {
        0.0
    } else {
        (0.8 * (1.0 - error.abs() / 0.4)).max(0.2)
    };
    Twist {
        linear_mps,
        angular_radps,
    }
}

/// Drives a simulator through waypoints in order, one step at a time.
#[derive(Clone, Debug)]
pub struct Tour {
    waypoints: &'static [(f64, f64)],
    next: usize,
    steps: u64,
    max_steps: u64,
    travelled_m: f64,
}

impl Tour {
    /// A tour of `waypoints` that gives up after `max_steps` steps (a robot stuck at a wall).
    pub fn new(waypoints: &'static [(f64, f64)], max_steps: u64) -> Self {
        Self {
            waypoints,
            next: 0,
            steps: 0,
            max_steps,
            travelled_m: 0.0,
        }
    }

    /// Every waypoint was reached.
    pub fn finished(&self) -> bool {
        self.next == self.waypoints.len()
    }

    /// Goes on from waypoint `next` (a robot carried elsewhere on the tour's way).
    pub fn resume_at(&mut self, next: usize) {
        self.next = next.min(self.waypoints.len());
    }

    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The distance the robot truly travelled so far.
    pub fn travelled_m(&self) -> f64 {
        self.travelled_m
    }

    /// Commands and steps the simulator once; `None` when the tour is over (every waypoint
    /// reached, or `max_steps` taken).
    pub fn step(&mut self, sim: &mut Simulator) -> Option<StepReport> {
        let truth = sim.truth();
        while let Some(&goal) = self.waypoints.get(self.next) {
            if (goal.0 - truth.x_m).hypot(goal.1 - truth.y_m) >= REACHED_M {
                break;
            }
            self.next += 1;
        }
        let goal = *self.waypoints.get(self.next)?;
        if self.steps >= self.max_steps {
            return None;
        }
        // The command is finite, so the simulator takes it.
        let _ = sim.command(steer(truth, goal));
        let report = sim.step();
        self.steps += 1;
        self.travelled_m += (report.truth.x_m - truth.x_m).hypot(report.truth.y_m - truth.y_m);
        Some(report)
    }

    /// Steps until the next scan ([`Simulator::scan`]); `None` when the tour is over.
    pub fn next_scan(&mut self, sim: &mut Simulator) -> Option<StepReport> {
        loop {
            let report = self.step(sim)?;
            if report.scanned {
                return Some(report);
            }
        }
    }
}
