//! Regulated pure pursuit along a planned path: the follower's controller when it has a path.
//!
//! The robot steers on the arc through the point [`LOOKAHEAD_M`] ahead of it along the path
//! (pure pursuit), and slows down where that arc is tight (regulated pure pursuit, as Nav2's
//! controller: below [`REGULATE_RADIUS_M`] the speed falls with the radius) and near the goal.
//! When the carrot is more than [`TURN_IN_PLACE_RAD`] off its heading it turns on the spot
//! first. Progress is measured along the path (the length left from the robot's projection on
//! it), so a path that winds away from the goal is still progress.
//!
//! Pure: no IO, no clock; the follower calls [`Pursuit::steer`] at each pose.

use armor_model::geo;
use armor_model::world::Point;
use armor_module_api::types::{Pose2D, Twist};

use super::wrap_angle;

/// How far ahead along the path the robot aims.
pub const LOOKAHEAD_M: f64 = 0.8;
/// Arcs tighter than this radius are driven slower, in proportion to the radius.
pub const REGULATE_RADIUS_M: f64 = 0.9;
/// The carrot further off the heading than this: turn on the spot first.
pub const TURN_IN_PLACE_RAD: f64 = std::f64::consts::FRAC_PI_3;
/// Turning speed per radian of heading error while turning on the spot.
const TURN_GAIN: f64 = 2.0;
/// Closer than this to the goal (along the path), the speed drops in proportion.
const SLOW_DOWN_M: f64 = 1.0;
/// The projection searches at most this far along the path beyond the segment it was on, so
/// that a path that comes back near itself does not make the robot skip a loop.
const SEARCH_AHEAD_M: f64 = 2.0;

/// The path being followed, and how far along it the robot has come.
#[derive(Clone, Debug, PartialEq)]
pub struct Pursuit {
    points: Vec<Point>,
    /// The segment (`points[segment]`–`points[segment + 1]`) the robot was last projected on.
    segment: usize,
}

/// One step of pursuit: the command and the length of path left to the goal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Steer {
    pub twist: Twist,
    pub remaining_m: f64,
}

/// The limits the follower drives within.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Limits {
    pub max_speed_mps: f64,
    pub max_turn_radps: f64,
}

impl Pursuit {
    /// Follows `points` (at least one, the goal last); consecutive duplicates are dropped.
    pub fn new(points: Vec<Point>) -> Self {
        let mut kept: Vec<Point> = Vec::with_capacity(points.len());
        for p in points {
            if kept
                .last()
                .is_none_or(|last| geo::distance(*last, p) > 1e-6)
            {
                kept.push(p);
            }
        }
        Self {
            points: kept,
            segment: 0,
        }
    }

    pub fn points(&self) -> &[Point] {
        &self.points
    }

    pub fn goal(&self) -> Option<Point> {
        self.points.last().copied()
    }

    /// Projects `here` on the path (from the segment it was last on, up to
    /// [`SEARCH_AHEAD_M`] beyond), remembers the segment, and returns the projection's segment
    /// and its fraction along it.
    fn project(&mut self, here: Point) -> (usize, f64) {
        if self.points.len() < 2 {
            return (0, 0.0);
        }
        let mut best = (f64::INFINITY, self.segment, 0.0);
        let mut beyond_m = 0.0;
        for i in self.segment..self.points.len() - 1 {
            let (a, b) = (self.points[i], self.points[i + 1]);
            let (t, d) = project_on_segment(here, a, b);
            if d < best.0 {
                best = (d, i, t);
            }
            if i > self.segment {
                beyond_m += geo::distance(a, b);
                if beyond_m > SEARCH_AHEAD_M {
                    break;
                }
            }
        }
        self.segment = best.1;
        (best.1, best.2)
    }

    /// The path ahead of `here`: its projection on the segment it was last on, and the points
    /// after it.
    pub fn ahead(&self, here: Point) -> Vec<Point> {
        if self.points.len() < 2 {
            return self.points.clone();
        }
        let (a, b) = (self.points[self.segment], self.points[self.segment + 1]);
        let (t, _) = project_on_segment(here, a, b);
        let mut ahead = vec![lerp(a, b, t)];
        ahead.extend_from_slice(&self.points[self.segment + 1..]);
        ahead
    }

    /// The command from `pose`, or `None` when the pose is not finite or the path empty.
    pub fn steer(&mut self, pose: Pose2D, limits: Limits) -> Option<Steer> {
        let here = Point::new(pose.x_m, pose.y_m);
        let goal = self.goal()?;
        if !here.is_finite() || !pose.theta_rad.is_finite() {
            return None;
        }
        let (carrot, remaining_m) = if self.points.len() < 2 {
            (goal, geo::distance(here, goal))
        } else {
            let (segment, t) = self.project(here);
            let (a, b) = (self.points[segment], self.points[segment + 1]);
            let on_path = lerp(a, b, t);
            let rest_m = geo::distance(on_path, b) + geo::path_length(&self.points[segment + 1..]);
            // The carrot: LOOKAHEAD_M along the path from the projection.
            let mut carrot = goal;
            let mut left_m = LOOKAHEAD_M;
            let mut from = on_path;
            for next in &self.points[segment + 1..] {
                let step_m = geo::distance(from, *next);
                if step_m >= left_m {
                    carrot = lerp(from, *next, left_m / step_m);
                    break;
                }
                left_m -= step_m;
                from = *next;
            }
            // Off the path, the distance back onto it counts too.
            (carrot, rest_m + geo::distance(here, on_path))
        };
        let dx = carrot.x - here.x;
        let dy = carrot.y - here.y;
        let distance_m = dx.hypot(dy);
        if distance_m < 1e-9 {
            return Some(Steer {
                twist: Twist::default(),
                remaining_m,
            });
        }
        let alpha = wrap_angle(dy.atan2(dx) - pose.theta_rad);
        let twist = if alpha.abs() > TURN_IN_PLACE_RAD {
            Twist {
                linear_mps: 0.0,
                angular_radps: (TURN_GAIN * alpha)
                    .clamp(-limits.max_turn_radps, limits.max_turn_radps),
            }
        } else {
            // Pure pursuit: the arc through the carrot has curvature 2 sin α / d.
            let curvature = 2.0 * alpha.sin() / distance_m;
            let radius_m = 1.0 / curvature.abs().max(1e-9);
            let regulated = (radius_m / REGULATE_RADIUS_M).min(1.0);
            let near = (remaining_m / SLOW_DOWN_M).min(1.0);
            // Never so slow that the robot stops short of the goal.
            let mut linear_mps = (limits.max_speed_mps * regulated * near)
                .max(limits.max_speed_mps * 0.1)
                .min(limits.max_speed_mps);
            let mut angular_radps = linear_mps * curvature;
            if angular_radps.abs() > limits.max_turn_radps {
                angular_radps = limits.max_turn_radps.copysign(angular_radps);
                linear_mps = angular_radps / curvature;
            }
            Twist {
                linear_mps,
                angular_radps,
            }
        };
        Some(Steer { twist, remaining_m })
    }
}

fn lerp(a: Point, b: Point, t: f64) -> Point {
    Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t)
}

/// Where `p` projects on `a`–`b` (as a fraction, clamped to the segment), and its distance.
pub(crate) fn project_on_segment(p: Point, a: Point, b: Point) -> (f64, f64) {
    let (abx, aby) = (b.x - a.x, b.y - a.y);
    let length2 = abx * abx + aby * aby;
    let t = if length2 <= 0.0 {
        0.0
    } else {
        (((p.x - a.x) * abx + (p.y - a.y) * aby) / length2).clamp(0.0, 1.0)
    };
    (t, geo::distance(p, lerp(a, b, t)))
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Limits = Limits {
        max_speed_mps: 0.6,
        max_turn_radps: 1.2,
    };

    fn pose(x_m: f64, y_m: f64, theta_rad: f64) -> Pose2D {
        Pose2D {
            x_m,
            y_m,
            theta_rad,
        }
    }

    fn l_path() -> Pursuit {
        // East 5 m, then north 5 m.
        Pursuit::new(vec![
            Point::new(0.0, 0.0),
            Point::new(5.0, 0.0),
            Point::new(5.0, 5.0),
        ])
    }

    #[test]
    fn straight_on_the_path_at_full_speed_and_the_length_left_along_it() {
        let mut pursuit = l_path();
        let steer = pursuit.steer(pose(1.0, 0.0, 0.0), LIMITS).expect("steer");
        assert!((steer.twist.linear_mps - 0.6).abs() < 1e-9, "{steer:?}");
        assert!(steer.twist.angular_radps.abs() < 1e-9);
        assert!((steer.remaining_m - 9.0).abs() < 1e-9, "{steer:?}");
    }

    #[test]
    fn turns_into_the_corner_before_it_and_slows_in_the_turn() {
        let mut pursuit = l_path();
        let straight = pursuit.steer(pose(3.0, 0.0, 0.0), LIMITS).expect("steer");
        let corner = pursuit.steer(pose(4.7, 0.0, 0.0), LIMITS).expect("steer");
        assert_eq!(straight.twist.angular_radps, 0.0);
        assert!(
            corner.twist.angular_radps > 0.3,
            "left, into the corner: {corner:?}"
        );
        assert!(
            corner.twist.linear_mps < straight.twist.linear_mps,
            "regulated in the turn: {corner:?}"
        );
    }

    #[test]
    fn off_the_path_it_steers_back_and_counts_the_way_back() {
        let mut pursuit = l_path();
        let steer = pursuit.steer(pose(2.0, -1.0, 0.0), LIMITS).expect("steer");
        assert!(steer.twist.angular_radps > 0.0, "back up north: {steer:?}");
        assert!((steer.remaining_m - 9.0).abs() < 1e-9, "{steer:?}");
    }

    #[test]
    fn turns_on_the_spot_when_the_path_is_behind() {
        let mut pursuit = l_path();
        let steer = pursuit
            .steer(pose(1.0, 0.0, std::f64::consts::PI), LIMITS)
            .expect("steer");
        assert_eq!(steer.twist.linear_mps, 0.0);
        assert_eq!(steer.twist.angular_radps.abs(), 1.2);
    }

    #[test]
    fn progress_never_jumps_back_along_a_path_that_comes_back_near_itself() {
        // Out east 3 m, a U-turn 0.4 m north, and back west: the return leg passes 0.4 m from
        // the outward one.
        let mut pursuit = Pursuit::new(vec![
            Point::new(0.0, 0.0),
            Point::new(3.0, 0.0),
            Point::new(3.0, 0.4),
            Point::new(-3.0, 0.4),
        ]);
        let out = pursuit.steer(pose(2.9, 0.1, 0.0), LIMITS).expect("steer");
        let back = pursuit.steer(pose(1.0, 0.35, 3.1), LIMITS).expect("steer");
        assert!((out.remaining_m - 6.5).abs() < 0.2, "{out:?}");
        assert!((back.remaining_m - 4.0).abs() < 0.1, "{back:?}");
    }

    #[test]
    fn non_finite_poses_and_empty_paths_give_nothing() {
        assert_eq!(l_path().steer(pose(f64::NAN, 0.0, 0.0), LIMITS), None);
        assert_eq!(
            Pursuit::new(Vec::new()).steer(pose(0.0, 0.0, 0.0), LIMITS),
            None
        );
    }
}
