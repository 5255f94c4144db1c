//! A* on the costmap, the smoothing of its path, and the bottleneck of a way that is cut.
//!
//! Costs are integers: a step is 100 (straight) or 141 (diagonal) times 1 + the cost of the
//! cell entered in percent; the octile heuristic (100 per straight step, 141 per diagonal one)
//! never overestimates and is consistent, so A* finds the cheapest grid path and the queue's
//! `f` never decreases. That allows a bucket queue (a ring of stacks indexed by `f`, which a
//! step moves forward by at most 423) in place of a binary heap; popping the newest of equal
//! `f` prefers deeper nodes, which keeps A* from widening over the many equal-cost grid paths.
//!
//! **One path per pair, however it was searched.** Many grid paths often cost the same; the
//! one taken is read back from the goal, each time to the first neighbour (in the order of
//! `STEPS`) whose cost plus the step is the cell's. That choice depends only on the true costs
//! of the cells next to the cheapest paths, provided every cell on a cheapest path has its true
//! cost when the goal is reached: the heuristic is therefore the octile distance less one
//! (still consistent, and now below the true cost everywhere but at the goal), so that every
//! such cell is closed before the goal is. The search from one place to many
//! ([`Planner::plan_from`]) keeps the same promise for each of its goals; so a path is the same
//! whether it was planned alone (`armor check`, `armor compile`) or with the others from its
//! start (`armor plan`'s table of ways), to the bit.

use std::collections::VecDeque;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use super::costmap::{Costmap, LETHAL, MAX_EXTRA};
use super::{Blocker, Bottleneck, End, Path, PathError};
use crate::geo::Polygon;
use crate::world::Point;

/// The cost of a step into a cell of `cost` (not lethal): straight or diagonal.
pub fn step_cost(cost: u8, diagonal: bool) -> u32 {
    let base = 100 + u32::from(cost);
    if diagonal {
        (base * 141 + 50) / 100
    } else {
        base
    }
}

/// The octile distance of a grid offset in step-cost units: a lower bound of the cost.
pub fn heuristic(dx: u32, dy: u32) -> u32 {
    let (lo, hi) = if dx < dy { (dx, dy) } else { (dy, dx) };
    100 * hi + 41 * lo
}

/// [`heuristic`] less one away from the goal: strictly below the true cost of every cell but
/// the goal, so that every cell of every cheapest path is closed before the goal is (the
/// module's documentation says why). Still consistent: a step costs at least the octile
/// distance it covers.
fn strict_heuristic(dx: u32, dy: u32) -> u32 {
    heuristic(dx, dy).saturating_sub(1)
}

/// From how many goals [`Planner::plan_from`] floods once rather than searching for each: on
/// the benchmark's 100 m world an A* to a far goal took about a seventh of the time of a flood
/// to every goal (23 ms against 150 ms), and goals near the start cost A* little.
const FLOOD_FROM_GOALS: usize = 5;

/// The most threads [`Planner::plan_many`] plans on.
pub const MAX_THREADS: usize = 4;

/// Ring size of the bucket queue: more than the largest rise of `f` in one step
/// (`step_cost(MAX_EXTRA, true)` + 141).
const RING: usize = 512;
const _: () = assert!((200 * 141 + 50) / 100 + 141 < RING as u32);
const _: () = assert!(MAX_EXTRA <= 100);

/// The eight neighbours: (dx, dy); the last four are diagonal.
const STEPS: [(i64, i64); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (-1, 1),
    (1, -1),
    (-1, -1),
];
impl Costmap {
    /// The cells a path can step to from the free cell `cell`, with what each step costs
    /// ([`step_cost`]): the graph the planner searches, for other searches to run on the same
    /// costs (the reference searches of the tests and the bench). The costmap's border is
    /// lethal, so a free cell is never at its edge.
    pub fn neighbours(&self, cell: usize) -> impl Iterator<Item = (usize, u32)> + '_ {
        let width = self.width() as i64;
        let (x, y) = (cell as i64 % width, cell as i64 / width);
        let costs = self.costs();
        STEPS
            .iter()
            .enumerate()
            .filter_map(move |(index, (dx, dy))| {
                let next = ((y + dy) * width + x + dx) as usize;
                let cost = costs[next];
                (cost != LETHAL).then(|| (next, step_cost(cost, index >= 4)))
            })
    }
}

/// How far round a start or goal whose own cell is lethal a free cell is looked for.
const SNAP_CELLS: i64 = 3;
/// Slack is bucketed by this many metres when the widest way is looked for.
const SLACK_STEP_M: f64 = 0.005;

/// A costmap and the memory of its searches: plans any number of paths on the same map.
/// Planners made with [`Planner::sharing`] search the same costmap (not copied) with memory
/// of their own, so that paths can be planned on several threads.
#[derive(Clone, Debug)]
pub struct Planner {
    costmap: Arc<Costmap>,
    search: Search,
}

#[derive(Clone, Debug, Default)]
struct Search {
    /// The cost of the cheapest way found to each cell, [`UNSEEN`] before one is.
    g: Vec<u32>,
    /// One bit per cell: done with (its `g` is final).
    closed: Vec<u64>,
    /// The step that reached each cell (index in `STEPS`): only the bottleneck's flood keeps
    /// it; A* walks back down `g` instead, which saves a write per cell reached.
    step: Vec<u8>,
    /// The cells whose `g` this search set, to reset for the next one.
    touched: Vec<u32>,
    /// The bucket queue: entries `g << 32 | x << 16 | y`, so that a popped cell needs neither
    /// a division nor a read of `g`. (A costmap is at most 65 536 cells a side.)
    ring: Vec<Vec<u64>>,
}

/// A pair of places before any search.
enum Pair {
    /// Known without searching.
    Answered(Result<Path, PathError>),
    /// The free cells to search between.
    Search { from: usize, to: usize },
}

/// `g` of a cell not reached yet.
const UNSEEN: u32 = u32::MAX;

impl Search {
    /// A new search over `cells` cells: nothing reached yet.
    fn begin(&mut self, cells: usize) {
        if self.g.len() != cells {
            self.g = vec![UNSEEN; cells];
            self.closed = vec![0; cells.div_ceil(64)];
            self.touched.clear();
        }
        for &cell in &self.touched {
            self.g[cell as usize] = UNSEEN;
        }
        self.touched.clear();
        self.closed.fill(0);
        if self.ring.len() != RING {
            self.ring = vec![Vec::new(); RING];
        }
        for bucket in &mut self.ring {
            bucket.clear();
        }
    }

    /// Marks a cell reached at cost `g`.
    fn reach(&mut self, cell: usize, g: u32) {
        if self.g[cell] == UNSEEN {
            self.touched.push(cell as u32);
        }
        self.g[cell] = g;
    }

    /// Whether a cell is closed (its `g` is final).
    fn is_closed(&self, cell: usize) -> bool {
        self.closed[cell / 64] & (1_u64 << (cell % 64)) != 0
    }

    /// Closes a cell; false if it already was.
    fn close(&mut self, cell: usize) -> bool {
        let (word, bit) = (cell / 64, 1_u64 << (cell % 64));
        let open = self.closed[word] & bit == 0;
        self.closed[word] |= bit;
        open
    }
}

impl Planner {
    pub fn new(costmap: Costmap) -> Self {
        Self {
            costmap: Arc::new(costmap),
            search: Search::default(),
        }
    }

    /// Another planner on the same costmap, with its own search memory.
    pub fn sharing(&self) -> Planner {
        Self {
            costmap: Arc::clone(&self.costmap),
            search: Search::default(),
        }
    }

    pub fn costmap(&self) -> &Costmap {
        &self.costmap
    }

    /// Plans every pair, on as many threads as there are cores (at most [`MAX_THREADS`]), each
    /// with its own search memory on the shared costmap: the pairs from one start are planned
    /// together ([`Planner::plan_from`]: one search to all their goals), and the answers, in the
    /// order of `pairs`, are the ones [`Planner::plan`] gives one after the other.
    pub fn plan_many(&self, pairs: &[(Point, Point)]) -> Vec<Result<Path, PathError>> {
        // The pairs by start, in the order their starts first appear.
        let mut groups: Vec<(Point, Vec<usize>)> = Vec::new();
        for (index, &(start, _)) in pairs.iter().enumerate() {
            let same = |point: &Point| {
                point.x.to_bits() == start.x.to_bits() && point.y.to_bits() == start.y.to_bits()
            };
            match groups.iter_mut().find(|(point, _)| same(point)) {
                Some((_, members)) => members.push(index),
                None => groups.push((start, vec![index])),
            }
        }
        let plan_group = |planner: &mut Planner, (start, members): &(Point, Vec<usize>)| {
            let goals: Vec<Point> = members.iter().map(|&index| pairs[index].1).collect();
            members
                .iter()
                .copied()
                .zip(planner.plan_from(*start, &goals))
                .collect::<Vec<_>>()
        };
        let workers = std::thread::available_parallelism()
            .map_or(1, std::num::NonZeroUsize::get)
            .min(MAX_THREADS)
            .min(groups.len());
        let mut results: Vec<Option<Result<Path, PathError>>> = vec![None; pairs.len()];
        if workers <= 1 {
            let mut planner = self.sharing();
            for group in &groups {
                for (index, result) in plan_group(&mut planner, group) {
                    results[index] = Some(result);
                }
            }
        } else {
            // Starts are handed out one at a time, so that a long search does not hold up a
            // thread's share of the others.
            let next = AtomicUsize::new(0);
            std::thread::scope(|scope| {
                let handles: Vec<_> = (0..workers)
                    .map(|_| {
                        scope.spawn(|| {
                            let mut planner = self.sharing();
                            let mut done = Vec::new();
                            loop {
                                let index = next.fetch_add(1, Ordering::Relaxed);
                                let Some(group) = groups.get(index) else {
                                    return done;
                                };
                                done.extend(plan_group(&mut planner, group));
                            }
                        })
                    })
                    .collect();
                for handle in handles {
                    // A thread that panicked leaves its pairs to be planned again below.
                    for (index, result) in handle.join().unwrap_or_default() {
                        results[index] = Some(result);
                    }
                }
            });
        }
        let mut planner = self.sharing();
        results
            .into_iter()
            .zip(pairs)
            .map(|(result, &(a, b))| result.unwrap_or_else(|| planner.plan(a, b)))
            .collect()
    }

    /// How many cells the last search reached (a measure of its work).
    pub fn cells_reached(&self) -> usize {
        self.search.touched.len()
    }

    /// The cheapest path from `start` to `goal`, smoothed; or why there is none.
    pub fn plan(&mut self, start: Point, goal: Point) -> Result<Path, PathError> {
        match self.before_search(start, goal) {
            Pair::Answered(answer) => answer,
            Pair::Search { from, to } => match self.grid_path(from, to) {
                Some(cells) => Ok(Path::new(self.smooth(start, goal, &cells))),
                None => Err(PathError::Cut(self.bottleneck(start, goal))),
            },
        }
    }

    /// The cheapest path from `start` to each of `goals`, smoothed, or why there is none: what
    /// [`Planner::plan`] answers for each (to the bit: the module's documentation says why),
    /// from one search that stops once every goal is reached (from a few goals, A* to each).
    pub fn plan_from(&mut self, start: Point, goals: &[Point]) -> Vec<Result<Path, PathError>> {
        let pairs: Vec<Pair> = goals
            .iter()
            .map(|&goal| self.before_search(start, goal))
            .collect();
        let targets: Vec<usize> = pairs
            .iter()
            .filter_map(|pair| match pair {
                Pair::Search { to, .. } => Some(*to),
                Pair::Answered(_) => None,
            })
            .collect();
        let from = pairs.iter().find_map(|pair| match pair {
            Pair::Search { from, .. } => Some(*from),
            Pair::Answered(_) => None,
        });
        if targets.len() < FLOOD_FROM_GOALS {
            // A few searches: A* to each goal closes fewer cells than one flood to the furthest
            // (the paths are the same either way).
            return pairs
                .into_iter()
                .zip(goals)
                .map(|(pair, &goal)| match pair {
                    Pair::Answered(answer) => answer,
                    Pair::Search { .. } => self.plan(start, goal),
                })
                .collect();
        }
        if let Some(from) = from {
            self.search_to_all(from, &targets);
        }
        // Every path reached is read back before the bottleneck of any way that is cut is
        // looked for: that flood reuses the search's memory.
        let cells: Vec<Option<Vec<usize>>> = pairs
            .iter()
            .map(|pair| match pair {
                Pair::Search { from, to } if self.search.is_closed(*to) => {
                    self.walk_back(*from, *to)
                }
                _ => None,
            })
            .collect();
        pairs
            .into_iter()
            .zip(cells)
            .zip(goals)
            .map(|((pair, cells), &goal)| match (pair, cells) {
                (Pair::Answered(answer), _) => answer,
                (Pair::Search { .. }, Some(cells)) => {
                    Ok(Path::new(self.smooth(start, goal, &cells)))
                }
                (Pair::Search { .. }, None) => Err(PathError::Cut(self.bottleneck(start, goal))),
            })
            .collect()
    }

    /// What is known of a pair before searching: its answer when the robot cannot be at an
    /// end or the straight line will do, else the free cells to search between.
    fn before_search(&self, start: Point, goal: Point) -> Pair {
        let map = &self.costmap;
        for (end, at) in [(End::Start, start), (End::Goal, goal)] {
            if let Some(why) = map.blocker_at(at) {
                return Pair::Answered(Err(PathError::Blocked { end, at, why }));
            }
        }
        if self.straight_is_free(start, goal) {
            return Pair::Answered(Ok(Path::new(vec![start, goal])));
        }
        let Some(from) = self.snap(start) else {
            return Pair::Answered(Err(PathError::Blocked {
                end: End::Start,
                at: start,
                why: Blocker::NoRoom,
            }));
        };
        let Some(to) = self.snap(goal) else {
            return Pair::Answered(Err(PathError::Blocked {
                end: End::Goal,
                at: goal,
                why: Blocker::NoRoom,
            }));
        };
        Pair::Search { from, to }
    }

    /// One search from the free cell `from` that closes every one of `targets` it can reach,
    /// each with every cell of its cheapest paths (the module's documentation says why):
    /// Dijkstra's ([`flood`]) until the last target is closed. With no heuristic, every cell
    /// cheaper to reach than a target is closed before it. A* towards each target in turn,
    /// its open cells keyed again at every turn, closed about half as many cells on the
    /// benchmark's world, but took as long with a binary heap, and a fifth less with the
    /// bucket ring beside the sorted carried-over cells (on a loaded machine): not worth a
    /// second search to keep exact.
    fn search_to_all(&mut self, from: usize, targets: &[usize]) {
        let mut target = vec![false; self.costmap.costs().len()];
        let mut left = 0;
        for &cell in targets {
            left += usize::from(!target[cell]);
            target[cell] = true;
        }
        flood(&self.costmap, &mut self.search, from, |cell| {
            left -= usize::from(target[cell]);
            left == 0
        });
    }

    /// Whether the straight line crosses only free cells that cost nothing: then no path is
    /// cheaper (or, through the exact check at its ends, a start or goal in a lethal cell's
    /// edge but clear of the geometry).
    fn straight_is_free(&self, start: Point, goal: Point) -> bool {
        let map = &self.costmap;
        map.walk(start, goal, |cell, _| map.costs()[cell] == 0)
    }

    /// The free cell a path from or to `p` starts at: its own, or when that one is lethal
    /// (`p` is clear of the geometry, but the cells err on the safe side) the nearest free
    /// cell reached straight from `p`.
    fn snap(&self, p: Point) -> Option<usize> {
        let map = &self.costmap;
        let cell = map.cell_of(p)?;
        if map.costs()[cell] != LETHAL {
            return Some(cell);
        }
        let (width, height) = (map.width() as i64, map.height() as i64);
        let (col, row) = ((cell % map.width()) as i64, (cell / map.width()) as i64);
        let mut around: Vec<(f64, usize)> = Vec::new();
        for dy in -SNAP_CELLS..=SNAP_CELLS {
            for dx in -SNAP_CELLS..=SNAP_CELLS {
                let (c, r) = (col + dx, row + dy);
                if c < 0 || r < 0 || c >= width || r >= height {
                    continue;
                }
                let other = (r * width + c) as usize;
                if map.costs()[other] != LETHAL {
                    around.push((p.distance(map.centre(other)), other));
                }
            }
        }
        around.sort_by(|a, b| a.0.total_cmp(&b.0));
        around
            .into_iter()
            .find(|&(_, other)| map.segment_clear(p, map.centre(other)))
            .map(|(_, other)| other)
    }

    /// Where in `area` the robot gets first from `start`: the centre of the free cell inside it
    /// that the cheapest way from `start` reaches first (`start` itself when it is inside);
    /// `None` when the robot cannot be at `start` or can reach no free cell of the area.
    pub fn nearest_in(&mut self, start: Point, area: &Polygon) -> Option<Point> {
        let map = &self.costmap;
        if map.blocker_at(start).is_some() {
            return None;
        }
        if area.contains(start) {
            return Some(start);
        }
        let from = self.snap(start)?;
        let map = &self.costmap;
        let inside = |cell: usize| area.contains(map.centre(cell));
        // Dijkstra's (there is no one goal for a heuristic): the first free cell closed inside
        // the area is the one the cheapest way reaches first.
        flood(map, &mut self.search, from, inside).map(|cell| map.centre(cell))
    }

    /// A* from cell `from` to cell `to` (both free): the cells of the cheapest path.
    fn grid_path(&mut self, from: usize, to: usize) -> Option<Vec<usize>> {
        self.grid_search(from, to)?;
        self.walk_back(from, to)
    }

    /// The cells of the cheapest path from `from` to `to`, read back from `to` (closed by the
    /// last search, with every cell of its cheapest paths).
    fn walk_back(&self, from: usize, to: usize) -> Option<Vec<usize>> {
        let costs = self.costmap.costs();
        let width = self.costmap.width() as i64;
        let g = &self.search.g;
        // Back from the goal, each time to the first neighbour whose cost plus the step is
        // this cell's: such a neighbour is on a cheapest path, and every neighbour that is has
        // its true cost (the module's documentation says why).
        let mut cells = vec![to];
        let mut cell = to;
        while cell != from {
            let step_in = step_cost(costs[cell], false);
            let diagonal_in = step_cost(costs[cell], true);
            let previous = STEPS.iter().enumerate().find_map(|(index, &(dx, dy))| {
                let before = (cell as i64 - dx - dy * width) as usize;
                let step = if index >= 4 { diagonal_in } else { step_in };
                (g[before] != UNSEEN
                    && u64::from(g[before]) + u64::from(step) == u64::from(g[cell]))
                .then_some(before)
            })?;
            cells.push(previous);
            cell = previous;
        }
        cells.reverse();
        Some(cells)
    }

    /// The cost of the cheapest grid path from cell `from` to cell `to`, both free (the
    /// benchmark compares it with a reference A*'s).
    pub fn grid_search(&mut self, from: usize, to: usize) -> Option<u32> {
        let map = &self.costmap;
        let costs = map.costs();
        let width = map.width();
        self.search.begin(costs.len());
        let search = &mut self.search;
        let (goal_x, goal_y) = ((to % width) as i64, (to / width) as i64);
        let offsets: [isize; 8] = STEPS.map(|(dx, dy)| (dx + dy * width as i64) as isize);
        let h = |x: i64, y: i64| {
            strict_heuristic(
                (x - goal_x).unsigned_abs() as u32,
                (y - goal_y).unsigned_abs() as u32,
            )
        };
        search.reach(from, 0);
        let (from_x, from_y) = ((from % width) as u64, (from / width) as u64);
        let mut f = h(from_x as i64, from_y as i64);
        search.ring[f as usize % RING].push(from_x << 16 | from_y);
        let mut queued = 1_usize;
        // Step costs by cell cost, straight then diagonal.
        let mut steps = [[0_u32; 2]; 256];
        for (cost, pair) in steps.iter_mut().enumerate() {
            *pair = [step_cost(cost as u8, false), step_cost(cost as u8, true)];
        }
        while queued > 0 {
            let Some(entry) = search.ring[f as usize % RING].pop() else {
                f += 1;
                continue;
            };
            queued -= 1;
            let (x, y) = (((entry >> 16) & 0xFFFF) as i64, (entry & 0xFFFF) as i64);
            let cell = y as usize * width + x as usize;
            // A cell is queued again when a cheaper way to it is found, and that entry comes
            // out first (its `f` is lower): any later entry is for a closed cell.
            if !search.close(cell) {
                continue;
            }
            let g = (entry >> 32) as u32;
            if cell == to {
                return Some(g);
            }
            for (step, (&offset, &(dx, dy))) in offsets.iter().zip(&STEPS).enumerate() {
                let next = cell.wrapping_add_signed(offset);
                let cost = costs[next];
                if cost == LETHAL {
                    continue;
                }
                let through = g + steps[usize::from(cost)][usize::from(step >= 4)];
                // A closed cell's `g` is final (the heuristic is consistent): never more than
                // `through`.
                if search.g[next] <= through {
                    continue;
                }
                search.reach(next, through);
                let (nx, ny) = (x + dx, y + dy);
                let next_f = through + h(nx, ny);
                search.ring[next_f as usize % RING]
                    .push(u64::from(through) << 32 | (nx as u64) << 16 | ny as u64);
                queued += 1;
            }
        }
        None
    }

    /// The grid path pulled straight: from each corner, on to the furthest later corner that
    /// can be reached in a straight line over free cells without costing more than the way
    /// it replaces. The ends are the exact `start` and `goal`.
    fn smooth(&self, start: Point, goal: Point, cells: &[usize]) -> Vec<Point> {
        let map = &self.costmap;
        // The cells where the grid path turns (a straight run of cells is a straight line).
        let mut points = vec![start];
        for (i, &cell) in cells.iter().enumerate() {
            let turns = match (i.checked_sub(1).map(|p| cells[p]), cells.get(i + 1)) {
                (Some(before), Some(&after)) => {
                    cell as i64 - before as i64 != after as i64 - cell as i64
                }
                _ => true,
            };
            if turns {
                points.push(map.centre(cell));
            }
        }
        points.push(goal);
        let last = points.len() - 1;
        // The cost of the way so far along the grid path, at each point.
        let mut along = vec![0.0; points.len()];
        for i in 1..points.len() {
            along[i] = along[i - 1] + self.segment_cost(points[i - 1], points[i]);
        }
        let mut path = vec![start];
        let mut anchor = 0;
        while anchor < last {
            let mut reach = anchor + 1;
            for candidate in anchor + 2..=last {
                let ends = anchor == 0 || candidate == last;
                if !self.line_of_sight(points[anchor], points[candidate], ends) {
                    break;
                }
                let cost = self.segment_cost(points[anchor], points[candidate]);
                if cost <= along[candidate] - along[anchor] + 1e-9 {
                    reach = candidate;
                }
            }
            path.push(points[reach]);
            anchor = reach;
        }
        path
    }

    /// Whether the segment crosses only free cells; a segment from the start or to the goal
    /// may instead be clear of the geometry itself (its end's cell may be lethal by the safe
    /// side's margin).
    fn line_of_sight(&self, a: Point, b: Point, exact_ends: bool) -> bool {
        let map = &self.costmap;
        map.walk(a, b, |cell, _| map.costs()[cell] != LETHAL)
            || (exact_ends && map.segment_clear(a, b))
    }

    /// The cost of driving straight from `a` to `b`, in step units (100 per cell's width).
    fn segment_cost(&self, a: Point, b: Point) -> f64 {
        let map = &self.costmap;
        let per_metre = 100.0 / map.resolution_m();
        let mut total = 0.0;
        map.walk(a, b, |cell, length_m| {
            let cost = map.costs()[cell].min(MAX_EXTRA);
            total += length_m * per_metre * (1.0 + f64::from(cost) / 100.0);
            true
        });
        total
    }

    /// Where the widest way from `start` to `goal` is narrowest: a flood that always goes on
    /// from the reached cell with the most slack (a maximum spanning tree, grown from the
    /// start), then the cell of least slack on the tree's way to the goal.
    fn bottleneck(&mut self, start: Point, goal: Point) -> Bottleneck {
        let map = &self.costmap;
        let (Some(from), Some(to)) = (map.cell_of(start), map.cell_of(goal)) else {
            return Bottleneck {
                at: goal,
                width_m: 0.0,
                area: None,
                needed_m: 0.0,
            };
        };
        let (width, height) = (map.width(), map.height());
        let keep_max = map
            .keepouts()
            .iter()
            .map(|keepout| keepout.keep_m(map.robot()))
            .fold(map.robot().keep_m(), f64::max);
        // Slack above a cell's diagonal is room enough: all of it is one level.
        let top = map.half_diagonal() + map.resolution_m();
        let levels = ((keep_max + top) / SLACK_STEP_M).ceil() as usize + 2;
        let level = |cell: usize| {
            let slack = f64::from(map.slack(cell)).clamp(-keep_max, top);
            ((slack + keep_max) / SLACK_STEP_M).round() as usize
        };
        self.search.begin(width * height);
        let search = &mut self.search;
        // First in, first out within a level: the tree grows evenly from the start, so that
        // its way to the goal is a short one among the widest (and crosses a wall or an area
        // where the start is nearest to it, not anywhere along it).
        let mut buckets: Vec<VecDeque<u32>> = vec![VecDeque::new(); levels + 1];
        if search.step.len() != width * height {
            search.step = vec![0; width * height];
        }
        search.reach(from, 0);
        let mut highest = level(from);
        buckets[highest].push_back(from as u32);
        loop {
            while highest > 0 && buckets[highest].is_empty() {
                highest -= 1;
            }
            let Some(cell) = buckets[highest].pop_front() else {
                break;
            };
            let cell = cell as usize;
            if cell == to {
                break;
            }
            let (x, y) = ((cell % width) as i64, (cell / width) as i64);
            for (step, &(dx, dy)) in STEPS.iter().enumerate() {
                let (nx, ny) = (x + dx, y + dy);
                // The lethal border is outside the map: the flood stays within.
                if nx < 1 || ny < 1 || nx >= width as i64 - 1 || ny >= height as i64 - 1 {
                    continue;
                }
                let next = ny as usize * width + nx as usize;
                if search.g[next] != UNSEEN {
                    continue;
                }
                search.reach(next, 0);
                search.step[next] = step as u8;
                let next_level = level(next);
                highest = highest.max(next_level);
                buckets[next_level].push_back(next as u32);
            }
        }
        // The least slack on the tree's way from the start to the goal: the middle of the
        // first run of cells that have it (the middle of a wall or an area crossed).
        let mut way = vec![to];
        let mut cell = to;
        if search.g[to] != UNSEEN {
            while cell != from {
                let (dx, dy) = STEPS[usize::from(search.step[cell])];
                cell = (cell as i64 - dx - dy * width as i64) as usize;
                way.push(cell);
            }
        }
        way.reverse();
        let least = way
            .iter()
            .map(|&cell| map.slack(cell))
            .fold(f32::INFINITY, f32::min);
        let first = way
            .iter()
            .position(|&cell| map.slack(cell) <= least)
            .unwrap_or(0);
        let run = way[first..]
            .iter()
            .take_while(|&&cell| map.slack(cell) <= least)
            .count();
        let narrowest = way[first + run / 2];
        self.describe_bottleneck(narrowest)
    }

    /// The place and width of the passage at `cell`, measured on the geometry: from the
    /// nearest edge of an obstacle or area to the nearest one on the other side, and the point
    /// half-way between them.
    fn describe_bottleneck(&self, cell: usize) -> Bottleneck {
        let map = &self.costmap;
        let at = map.centre(cell);
        let robot = map.robot();
        // Which kind of thing makes it narrow: the one the robot has least slack from.
        let obstacle_m = match map.world() {
            Some(world) if !world.is_free(at) => 0.0,
            Some(world) => world.wall_distance(at, f64::MAX),
            None => f64::INFINITY,
        };
        let mut slack_m = obstacle_m - robot.keep_m();
        let mut area = None;
        let mut inside_area = false;
        for keepout in map.keepouts() {
            let inside = keepout.polygon.contains(at);
            let distance = if inside {
                0.0
            } else {
                keepout.polygon.distance_to_outline(at)
            };
            let slack = distance - keepout.keep_m(robot);
            if slack < slack_m {
                slack_m = slack;
                area = Some(keepout.name.clone());
                inside_area = inside;
            }
        }
        // Twice what the centre keeps from the thing that makes the passage narrow, and a cell's
        // diagonal: a cell is free only when every point of it keeps that far.
        let needed_m = 2.0
            * (area
                .as_ref()
                .and_then(|name| map.keepouts().iter().find(|k| &k.name == name))
                .map_or(robot.keep_m(), |keepout| keepout.keep_m(robot))
                + map.half_diagonal());
        let walled = map.world().is_some_and(|world| !world.is_free(at));
        // A wall's cells are occupied although their centres may be a hair's breadth off it.
        let on_wall = area.is_none() && f64::from(map.slack(cell)) <= -robot.keep_m() + 1e-6;
        if walled || inside_area || on_wall {
            return Bottleneck {
                at,
                width_m: 0.0,
                area,
                needed_m,
            };
        }
        let edges: Vec<(Point, Point)> = map
            .world()
            .into_iter()
            .flat_map(|world| world.segments())
            .chain(map.keepouts().iter().flat_map(|k| k.polygon.edges()))
            .collect();
        let Some((near, near_m)) = nearest_on(&edges, at, None) else {
            return Bottleneck {
                at,
                width_m: f64::INFINITY,
                area,
                needed_m,
            };
        };
        let away = Point::new(near.x - at.x, near.y - at.y);
        match nearest_on(&edges, at, Some(away)) {
            Some((far, far_m)) => Bottleneck {
                at: Point::new((near.x + far.x) / 2.0, (near.y + far.y) / 2.0),
                width_m: near_m + far_m,
                area,
                needed_m,
            },
            None => Bottleneck {
                at,
                width_m: 2.0 * near_m,
                area,
                needed_m,
            },
        }
    }

    /// The cell a path from or to `p` starts at (for tests: the flood-fill cross-check).
    #[cfg(test)]
    pub(crate) fn snap_for_tests(&self, p: Point) -> Option<usize> {
        self.snap(p)
    }
}

/// Dijkstra's search over `map` from the free cell `from`, on the bucket queue A* uses: closes
/// cells cheapest first until `done` is true of one closed (returned), or none is left.
fn flood(
    map: &Costmap,
    search: &mut Search,
    from: usize,
    mut done: impl FnMut(usize) -> bool,
) -> Option<usize> {
    let costs = map.costs();
    let width = map.width();
    search.begin(costs.len());
    let offsets: [isize; 8] = STEPS.map(|(dx, dy)| (dx + dy * width as i64) as isize);
    let mut steps = [[0_u32; 2]; 256];
    for (cost, pair) in steps.iter_mut().enumerate() {
        *pair = [step_cost(cost as u8, false), step_cost(cost as u8, true)];
    }
    search.reach(from, 0);
    // Entries are cells: a cell's cheapest entry is the first out of the queue, and the others
    // find it closed or dearer than its cost.
    search.ring[0].push(from as u64);
    let mut g_now = 0_u32;
    let mut queued = 1_usize;
    while queued > 0 {
        let Some(cell) = search.ring[g_now as usize % RING].pop() else {
            g_now += 1;
            continue;
        };
        queued -= 1;
        let cell = cell as usize;
        if search.g[cell] != g_now || !search.close(cell) {
            continue;
        }
        if done(cell) {
            return Some(cell);
        }
        for (step, &offset) in offsets.iter().enumerate() {
            let next = cell.wrapping_add_signed(offset);
            let cost = costs[next];
            if cost == LETHAL {
                continue;
            }
            let through = g_now + steps[usize::from(cost)][usize::from(step >= 4)];
            if search.g[next] <= through {
                continue;
            }
            search.reach(next, through);
            search.ring[through as usize % RING].push(next as u64);
            queued += 1;
        }
    }
    None
}

/// The point of `edges` nearest to `p`, and its distance; with `away`, only among the points
/// on the other side of `p` from that direction (`(q - p) · away <= 0`).
fn nearest_on(edges: &[(Point, Point)], p: Point, away: Option<Point>) -> Option<(Point, f64)> {
    let mut best: Option<(Point, f64)> = None;
    for &(a, b) in edges {
        let (mut a, mut b) = (a, b);
        if let Some(u) = away {
            // Clip the edge to the half-plane.
            let side = |q: Point| (q.x - p.x) * u.x + (q.y - p.y) * u.y;
            let (sa, sb) = (side(a), side(b));
            if sa > 0.0 && sb > 0.0 {
                continue;
            }
            if sa > 0.0 || sb > 0.0 {
                let t = sa / (sa - sb);
                let cut = Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t);
                if sa > 0.0 {
                    a = cut;
                } else {
                    b = cut;
                }
            }
        }
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let length_sq = dx * dx + dy * dy;
        let t = if length_sq > 0.0 {
            (((p.x - a.x) * dx + (p.y - a.y) * dy) / length_sq).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = Point::new(a.x + t * dx, a.y + t * dy);
        let distance = p.distance(q);
        if best.is_none_or(|(_, d)| distance < d) {
            best = Some((q, distance));
        }
    }
    best
}
