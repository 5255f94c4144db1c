//! Navigation, as two modules linked by a typed port so the diagram shows the data flow:
//!
//! ```text
//! odometry (or a corrected pose) ──▶ follower ──cmd_desired──▶ avoider ──cmd_vel──▶ robot
//!                                                    scan ──▶ ┘
//! ```
//!
//! - [`follower`]: go-to-goal. A proportional heading controller drives towards the goal set in
//!   its parameters (changed per leg by the mission), reports `goal_reached` once per goal and
//!   `blocked` when it makes no progress.
//! - [`avoider`]: reactive obstacle avoidance and safety stop (the virtual force field of the JDE
//!   schemas). It bends the desired command away from the close points of the laser scan, slows
//!   down before obstacles, stops forward motion when one is too close, and stops altogether
//!   without fresh scans.
//!
//! Navigation as competing behaviours (JDE's motor schemas), chosen by the
//! [`arbiter`](crate::arbiter), with the avoider still under the winner as the safety layer:
//!
//! ```text
//! follower (go-to-goal) ─┐
//! vff (obstacle avoidance) ─┼─▶ arbiter ──▶ avoider ──▶ robot
//! stop ──────────────────┘
//! ```
//!
//! - [`vff`]: applies while an obstacle is close ahead and proposes a way round it.
//! - [`stop`]: always applies, proposes zero; the lowest priority.
//!
//! The follower, the avoider and vff publish nothing while inactive, after one zero command when stopped so that the robot
//! does not keep the last motion command.

pub mod avoider;
pub mod follower;
pub(crate) mod pursuit;
pub(crate) mod replan;
pub mod stop;
pub mod vff;

use armor_module_api::types::Twist;

pub(crate) use crate::wrap_angle;

/// A finite number, or 0 for NaN and infinities.
pub(crate) fn finite_or_zero(value: f64) -> f64 {
    if value.is_finite() { value } else { 0.0 }
}

/// A command with every non-finite component replaced by 0.
pub(crate) fn sanitized(twist: Twist) -> Twist {
    Twist {
        linear_mps: finite_or_zero(twist.linear_mps),
        angular_radps: finite_or_zero(twist.angular_radps),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn angles_wrap_into_one_turn() {
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_angle(-3.0 * PI / 2.0) - PI / 2.0).abs() < 1e-12);
        assert_eq!(wrap_angle(0.25), 0.25);
        assert!(wrap_angle(f64::NAN).is_nan());
    }

    #[test]
    fn non_finite_commands_become_zero() {
        let twist = sanitized(Twist {
            linear_mps: f64::NAN,
            angular_radps: f64::NEG_INFINITY,
        });
        assert_eq!(twist, Twist::default());
    }
}
