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
