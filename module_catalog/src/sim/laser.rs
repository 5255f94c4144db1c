//! The simulated planar laser scanner: one ray cast per beam from the robot's centre, with
//! Gaussian range noise.

use armor_module_api::types::{LaserScan, Pose2D};

use super::rng::Rng;
use super::world::{Point, World};

/// A laser scanner's geometry and noise.
#[derive(Clone, Debug, PartialEq)]
pub struct Laser {
    pub beams: usize,
    /// Angle of the first beam in the robot's frame.
    pub angle_min_rad: f64,
    pub angle_increment_rad: f64,
    pub range_max_m: f64,
    /// Standard deviation of the range noise.
    pub noise_m: f64,
}

impl Laser {
    /// `beams` beams spread over `fov_deg` centred on the robot's heading. A full circle has no
    /// duplicate beam (the last one stops one increment short of the first); a partial field of
    /// view has a beam at each edge.
    pub fn new(beams: usize, fov_deg: f64, range_max_m: f64, noise_m: f64) -> Self {
        let fov = fov_deg.to_radians();
        let (angle_min_rad, angle_increment_rad) = if fov_deg >= 360.0 {
            (
                -std::f64::consts::PI,
                std::f64::consts::TAU / beams.max(1) as f64,
            )
        } else if beams <= 1 {
            (0.0, 0.0)
        } else {
            (-fov / 2.0, fov / (beams - 1) as f64)
        };
        Self {
            beams,
            angle_min_rad,
            angle_increment_rad,
            range_max_m,
            noise_m,
        }
    }

    /// Fills `scan` with a sweep from `pose` (world frame). Beams that hit nothing within range
    /// read exactly `range_max_m`; the others read the distance plus noise, within
    /// 0..=`range_max_m`.
    pub fn scan(&self, world: &World, pose: Pose2D, rng: &mut Rng, scan: &mut LaserScan) {
        scan.angle_min_rad = self.angle_min_rad;
        scan.angle_increment_rad = self.angle_increment_rad;
        scan.range_max_m = self.range_max_m;
        scan.ranges_m.clear();
        let origin = Point::new(pose.x_m, pose.y_m);
        let first = pose.theta_rad + self.angle_min_rad;
        scan.ranges_m.extend((0..self.beams).map(|i| {
            let angle = first + i as f64 * self.angle_increment_rad;
            let range = world.raycast(origin, angle, self.range_max_m);
            let noise = rng.normal(self.noise_m);
            if range >= self.range_max_m {
                self.range_max_m as f32
            } else {
                (range + noise).clamp(0.0, self.range_max_m) as f32
            }
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn room() -> World {
        World::parse(
            "name room\norigin 0 0\nstart 5 5 0\nboundary 0,0 10,0 10,10 0,10 0,0\n",
            "room.world",
        )
        .expect("valid")
    }

    #[test]
    fn beam_angles_cover_the_field_of_view() {
        let full = Laser::new(360, 360.0, 8.0, 0.0);
        assert_eq!(full.angle_min_rad, -std::f64::consts::PI);
        assert!((full.angle_increment_rad - 1f64.to_radians()).abs() < 1e-12);
        let front = Laser::new(181, 180.0, 8.0, 0.0);
        assert!((front.angle_min_rad + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(
            (front.angle_min_rad + 180.0 * front.angle_increment_rad - std::f64::consts::FRAC_PI_2)
                .abs()
                < 1e-12
        );
        let single = Laser::new(1, 90.0, 8.0, 0.0);
        assert_eq!(
            (single.angle_min_rad, single.angle_increment_rad),
            (0.0, 0.0)
        );
    }

    #[test]
    fn scans_are_in_the_robot_frame_with_noise_and_max_range() {
        let world = room();
        let laser = Laser::new(4, 360.0, 4.5, 0.0);
        let mut rng = Rng::new(1, 0);
        let mut scan = LaserScan::default();
        // At (3, 5) facing north: beams at -180° (south), -90° (east), 0° (north), 90° (west).
        let pose = Pose2D {
            x_m: 3.0,
            y_m: 5.0,
            theta_rad: std::f64::consts::FRAC_PI_2,
        };
        laser.scan(&world, pose, &mut rng, &mut scan);
        assert_eq!(scan.ranges_m.len(), 4);
        let expected = [4.5, 4.5, 4.5, 3.0];
        for (range, expected) in scan.ranges_m.iter().zip(expected) {
            assert!(
                (f64::from(*range) - expected).abs() < 1e-5,
                "{:?}",
                scan.ranges_m
            );
        }
        assert_eq!(scan.range_max_m, 4.5);
        let noisy = Laser::new(4, 360.0, 4.5, 0.05);
        let mut noisy_scan = LaserScan::default();
        noisy.scan(&world, pose, &mut rng, &mut noisy_scan);
        assert_eq!(
            noisy_scan.ranges_m[0], 4.5,
            "no echo reads exactly the maximum"
        );
        assert_ne!(noisy_scan.ranges_m[3], 3.0);
        assert!((noisy_scan.ranges_m[3] - 3.0).abs() < 0.3);
    }
}
