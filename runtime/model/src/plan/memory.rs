//! The paths a run has planned, kept so that an update plans only what it changed: a leg
//! whose ends did not move, on the same world for the same robot, keeps its path unless a
//! no-go area added since comes near it (where the area raises the costmap's costs). A plan
//! update that moves one waypoint of a hundred legs then plans two legs, on the costmap kept
//! from the last planning when the areas are the same, instead of a hundred on a new one.
//!
//! What a path depends on is the key: its two ends (to the bit), the world's geometry, the
//! robot, and the no-go areas near it. An area removed, or changed, may open a shorter way
//! anywhere, so it forgets every path; an area added forgets only the paths it comes near, since
//! costs away from it are unchanged and a way through it only costs more, so the cheapest way
//! found before is still the cheapest.

use std::collections::BTreeMap;
use std::fmt;

use crate::planner::{
    self, Costmap, CostmapError, CostmapSettings, Keepout, Path, PathError, Planner, Robot,
};
use crate::world::{Point, World};

/// Ends this close to a remembered path's are its ends: the plan's writer keeps seven decimals
/// of a degree (about a centimetre), so a plan written back and sent again moves every waypoint
/// by up to half of that, a fifth of a costmap cell. The path kept is given the new ends
/// exactly.
pub const SAME_END_M: f64 = 0.01;

/// How far beyond the robot's keep and the costs' falloff an area is taken to touch a path, at
/// least: the costmap marks cells by their centres, so a path a cell or two further off may
/// still run through a cell whose cost the area raised.
const MIN_SLACK_M: f64 = 1.0;

/// Paths planned before, and the costmap they were planned on (see the module's text).
#[derive(Clone, Default)]
pub struct PathMemory {
    /// What the remembered paths were planned for.
    basis: Option<Basis>,
    /// The paths remembered, each from its first point to its last.
    paths: Vec<Path>,
    /// The costmap of `basis` (with a world only), built when a path had to be planned.
    planner: Option<Planner>,
    /// How the last [`PathMemory::plan_pairs`] went (the last plan's legs).
    last: Reuse,
}

/// How many of the pairs asked for were planned, and how many reused.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Reuse {
    pub planned: usize,
    pub reused: usize,
    /// Whether a costmap was built for them.
    pub costmap_built: bool,
}

#[derive(Clone)]
struct Basis {
    world: Option<World>,
    robot: Robot,
    keepouts: Vec<Keepout>,
}

impl fmt::Debug for PathMemory {
    // The costmap holds millions of cells: only what the memory holds is said.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PathMemory")
            .field("paths", &self.paths.len())
            .field("costmap", &self.planner.is_some())
            .field("last", &self.last)
            .finish()
    }
}

fn key(from: Point, to: Point) -> [u64; 4] {
    [
        from.x.to_bits(),
        from.y.to_bits(),
        to.x.to_bits(),
        to.y.to_bits(),
    ]
}

/// The path of `paths` from `from` to `to` (each end within [`SAME_END_M`]), given those ends
/// exactly.
fn remembered(paths: &[Path], from: Point, to: Point) -> Option<Path> {
    let near = |a: Point, b: Point| a.distance(b) <= SAME_END_M;
    let found = paths.iter().find(|path| {
        matches!(
            (path.points.first(), path.points.last()),
            (Some(&first), Some(&last)) if near(first, from) && near(last, to)
        )
    })?;
    let mut points = found.points.clone();
    if let Some(first) = points.first_mut() {
        *first = from;
    }
    if let Some(last) = points.last_mut() {
        *last = to;
    }
    Some(Path::new(points))
}

impl PathMemory {
    /// How the last [`PathMemory::plan_pairs`] went.
    pub fn last(&self) -> Reuse {
        self.last
    }

    /// Plans the way between each pair of points for `robot` on `world` round `keepouts`, as
    /// [`super::plan_pairs`] does, reusing the paths remembered that still hold and the costmap
    /// when the world, the robot and the areas are the ones it was built for. Afterwards it
    /// remembers exactly the paths of `pairs` that were found (a plan's legs), so that it never
    /// grows past one plan's legs.
    pub fn plan_pairs(
        &mut self,
        world: Option<&World>,
        robot: &Robot,
        keepouts: &[Keepout],
        pairs: &[(Point, Point)],
    ) -> Result<Vec<Result<Path, PathError>>, CostmapError> {
        self.plan(world, robot, keepouts, pairs, true)
    }

    /// [`PathMemory::plan_pairs`] for ways that are not the plan's legs (from where the robot
    /// is, a repair's options): the costmap is reused, and the legs' paths stay remembered as
    /// they were.
    pub fn plan_others(
        &mut self,
        world: Option<&World>,
        robot: &Robot,
        keepouts: &[Keepout],
        pairs: &[(Point, Point)],
    ) -> Result<Vec<Result<Path, PathError>>, CostmapError> {
        self.plan(world, robot, keepouts, pairs, false)
    }

    fn plan(
        &mut self,
        world: Option<&World>,
        robot: &Robot,
        keepouts: &[Keepout],
        pairs: &[(Point, Point)],
        remember: bool,
    ) -> Result<Vec<Result<Path, PathError>>, CostmapError> {
        self.rebase(world, robot, keepouts);
        // Each pair is remembered, or the index of the pair to plan (the same pair asked for
        // twice is planned once).
        let mut slots: Vec<Result<Path, usize>> = Vec::with_capacity(pairs.len());
        let mut wanted: Vec<(Point, Point)> = Vec::new();
        let mut wanted_at: BTreeMap<[u64; 4], usize> = BTreeMap::new();
        for &(from, to) in pairs {
            slots.push(match remembered(&self.paths, from, to) {
                Some(path) => Ok(path),
                None => Err(*wanted_at.entry(key(from, to)).or_insert_with(|| {
                    wanted.push((from, to));
                    wanted.len() - 1
                })),
            });
        }
        let costmap_built = world.is_some() && !wanted.is_empty() && self.planner.is_none();
        let planned = match world {
            Some(_) if wanted.is_empty() => Vec::new(),
            Some(world) => {
                let planner = match &self.planner {
                    Some(planner) => planner,
                    None => self.planner.insert(Planner::new(Costmap::for_world(
                        world,
                        robot,
                        keepouts,
                        &CostmapSettings::default(),
                    )?)),
                };
                planner.plan_many(&wanted)
            }
            None => super::plan_pairs(None, robot, keepouts, &wanted)?,
        };
        let reused = slots.iter().filter(|slot| slot.is_ok()).count();
        let mut kept = Vec::new();
        let mut results = Vec::with_capacity(pairs.len());
        for (&(from, _), slot) in pairs.iter().zip(slots) {
            let result = match slot {
                Ok(path) => Ok(path),
                // Both planners answer every pair, in order.
                Err(index) => planned
                    .get(index)
                    .cloned()
                    .unwrap_or(Err(PathError::Blocked {
                        end: planner::End::Start,
                        at: from,
                        why: planner::Blocker::OutsideWorld,
                    })),
            };
            if let Ok(path) = &result {
                kept.push(path.clone());
            }
            results.push(result);
        }
        if remember {
            self.last = Reuse {
                planned: wanted.len(),
                reused,
                costmap_built,
            };
            self.paths = kept;
        }
        Ok(results)
    }

    /// Forgets what no longer holds for `world`, `robot` and `keepouts`, and takes them as the
    /// basis.
    fn rebase(&mut self, world: Option<&World>, robot: &Robot, keepouts: &[Keepout]) {
        let same_world = |basis: &Basis| match (&basis.world, world) {
            (None, None) => true,
            (Some(old), Some(new)) => old.same_geometry(new),
            _ => false,
        };
        let Some(basis) = &self.basis else {
            self.basis = Some(Basis {
                world: world.cloned(),
                robot: *robot,
                keepouts: keepouts.to_vec(),
            });
            self.paths.clear();
            self.planner = None;
            return;
        };
        if !same_world(basis) || basis.robot != *robot {
            self.basis = None;
            self.rebase(world, robot, keepouts);
            return;
        }
        if basis.keepouts == keepouts {
            return;
        }
        let removed = basis.keepouts.iter().any(|old| !keepouts.contains(old));
        if removed {
            self.paths.clear();
        } else {
            let added: Vec<Keepout> = keepouts
                .iter()
                .filter(|new| !basis.keepouts.contains(new))
                .map(|keepout| {
                    // Widened to where the area raises costs: its keep, the falloff, and a
                    // margin for the cells.
                    let slack_m = self.planner.as_ref().map_or(MIN_SLACK_M, |planner| {
                        (3.0 * planner.costmap().resolution_m()).max(MIN_SLACK_M)
                    });
                    Keepout {
                        margin_m: keepout.margin_m + planner::DEFAULT_FALLOFF_M + slack_m,
                        ..keepout.clone()
                    }
                })
                .collect();
            let clear = |a: Point, b: Point| planner::clear_of_keepouts(robot, &added, a, b);
            self.paths.retain(|path| match path.points.as_slice() {
                [point] => clear(*point, *point),
                points => points
                    .windows(2)
                    .all(|segment| clear(segment[0], segment[1])),
            });
        }
        self.planner = None;
        self.basis = Some(Basis {
            world: world.cloned(),
            robot: *robot,
            keepouts: keepouts.to_vec(),
        });
    }
}

#[cfg(test)]
mod tests;
