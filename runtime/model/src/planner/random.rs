//! Seeded random worlds for tests and benchmarks: rectangles, long thin blocks (like walls, which
//! close off pockets) and discs in a square, and random places where the robot may be. The
//! planner's own tests and the process tests of `tests/navigation.rs` draw their worlds here, so
//! that a seed names the same world in both. (`armor-bench path_plan_ms` keeps its own world,
//! drawn with the sim's generator: its published figures were measured on that one.)
//!
//! Not part of the model's interface (hidden from its documentation): only what tests and
//! benchmarks share.

use super::Costmap;
/// The generator the worlds are drawn with (its users name it here).
pub use crate::random::SplitMix64;
use crate::world::{Point, World};

/// What kind of random world to draw.
#[derive(Clone, Debug, PartialEq)]
pub struct RandomWorld {
    /// The world is the square from (0, 0) to (side_m, side_m), its boundary a wall.
    pub side_m: f64,
    /// How many obstacles, at least and at most (both included).
    pub obstacles: (usize, usize),
    /// The `origin` and `start` lines of the world file.
    pub origin: (f64, f64),
    pub start: (f64, f64, f64),
}

impl Default for RandomWorld {
    /// 40 m × 40 m with 20 to 40 obstacles: the worlds of issue 26's tests.
    fn default() -> Self {
        Self {
            side_m: 40.0,
            obstacles: (20, 40),
            origin: (0.0, 0.0),
            start: (0.2, 0.2, 0.0),
        }
    }
}

impl RandomWorld {
    /// The body of a world file: the boundary and the obstacles (no `name`, `origin` nor
    /// `start` line), drawn from `rng`.
    pub fn obstacles_text(&self, rng: &mut SplitMix64) -> String {
        let side = self.side_m;
        let mut text = format!("boundary 0,0 {side},0 {side},{side} 0,{side} 0,0\n");
        let (fewest, most) = self.obstacles;
        let count = fewest + (rng.next_u64() % (most - fewest + 1) as u64) as usize;
        for _ in 0..count {
            let (x, y) = (rng.uniform(1.0, side - 1.0), rng.uniform(1.0, side - 1.0));
            let (w, h) = match rng.next_u64() % 3 {
                // Blocks of 0.5 to 8 m a side.
                0 => (rng.uniform(0.5, 8.0), rng.uniform(0.5, 8.0)),
                1 if rng.next_u64().is_multiple_of(2) => {
                    (rng.uniform(4.0, 16.0), rng.uniform(0.2, 0.5))
                }
                1 => (rng.uniform(0.2, 0.5), rng.uniform(4.0, 16.0)),
                _ => {
                    text.push_str(&format!(
                        "circle {x:.2},{y:.2} {:.2}\n",
                        rng.uniform(0.3, 3.0)
                    ));
                    continue;
                }
            };
            text.push_str(&format!(
                "rect {x:.2},{y:.2} {:.2},{:.2}\n",
                (x + w).min(side - 0.1),
                (y + h).min(side - 0.1)
            ));
        }
        text
    }

    /// A whole world file around [`RandomWorld::obstacles_text`]'s `body`.
    pub fn file_text(&self, name: &str, body: &str) -> String {
        let (lat, lon) = self.origin;
        let (x, y, heading) = self.start;
        format!("name {name}\norigin {lat} {lon}\nstart {x} {y} {heading}\n{body}")
    }

    /// A random world drawn from `rng`.
    pub fn draw(&self, rng: &mut SplitMix64) -> World {
        let body = self.obstacles_text(rng);
        let text = self.file_text("random", &body);
        World::parse(&text, "random.world").unwrap_or_else(|err| {
            // The generator only writes what the parser reads: a failure is a bug here.
            panic!("a random world does not parse: {err}\n{text}")
        })
    }
}

/// A random place in the square from (0, 0) to (side_m, side_m) where the robot of `map` may
/// be (what `armor check` asks of a waypoint): neither outside the world nor within its keep of
/// anything.
pub fn free_place(rng: &mut SplitMix64, map: &Costmap, side_m: f64) -> Point {
    loop {
        let p = Point::new(rng.uniform(0.0, side_m), rng.uniform(0.0, side_m));
        if map.blocker_at(p).is_none() {
            return p;
        }
    }
}
