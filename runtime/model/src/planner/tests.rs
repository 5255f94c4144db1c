use std::collections::VecDeque;

use super::costmap::distance_transform_for_tests;
use super::random::{self, RandomWorld, SplitMix64 as Rng};
use super::*;
use crate::geo::Polygon;
use crate::world::World;

fn world(body: &str) -> World {
    World::parse(
        &format!("name t\norigin 0 0\nstart 0.5 0.5 0\n{body}"),
        "t.world",
    )
    .unwrap_or_else(|err| panic!("{err}"))
}

fn planner_on(world: &World, keepouts: &[Keepout]) -> Planner {
    let costmap = Costmap::for_world(
        world,
        &Robot::default(),
        keepouts,
        &CostmapSettings::default(),
    )
    .unwrap_or_else(|err| panic!("{err}"));
    Planner::new(costmap)
}

fn square(name: &str, x0: f64, y0: f64, x1: f64, y1: f64, margin_m: f64) -> Keepout {
    Keepout::new(
        name,
        Polygon::new(vec![
            Point::new(x0, y0),
            Point::new(x1, y0),
            Point::new(x1, y1),
            Point::new(x0, y1),
        ]),
        margin_m,
    )
}

/// Every segment of `path` keeps what the robot keeps from the world and the keepouts,
/// measured on the geometry.
fn assert_clear(world: &World, keepouts: &[Keepout], path: &Path, context: &str) {
    let robot = Robot::default();
    let keep = robot.keep_m();
    for pair in path.points.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        assert!(world.is_free(a) && world.is_free(b), "{context}: {a}–{b}");
        let clearance = world.segment_clearance(a, b, keep);
        assert!(
            clearance >= keep - 1e-9,
            "{context}: {a}–{b} comes {clearance} m from a wall, keeps {keep}"
        );
        for keepout in keepouts {
            let keep = keepout.keep_m(&robot);
            assert!(
                !keepout.polygon.contains(a),
                "{context}: {a} in {}",
                keepout.name
            );
            let distance = keepout
                .polygon
                .edges()
                .map(|(c, d)| crate::world::segment_segment_distance(a, b, c, d))
                .fold(f64::INFINITY, f64::min);
            assert!(
                distance >= keep - 1e-9,
                "{context}: {a}–{b} comes {distance} m from area {}",
                keepout.name
            );
        }
    }
    let length = crate::geo::path_length(&path.points);
    assert!((length - path.length_m).abs() < 1e-9, "{context}");
}

#[test]
fn the_distance_transform_is_exact() {
    let mut rng = Rng(7);
    for round in 0..20 {
        let (width, height) = (3 + round % 7, 2 + round % 5 * 3);
        let occupied: Vec<bool> = (0..width * height)
            .map(|_| rng.uniform(0.0, 1.0) < 0.15)
            .collect();
        let fast = distance_transform_for_tests(&occupied, width, height);
        for (cell, &fast) in fast.iter().enumerate() {
            let (x, y) = ((cell % width) as f64, (cell / width) as f64);
            let brute = (0..width * height)
                .filter(|&other| occupied[other])
                .map(|other| {
                    let (ox, oy) = ((other % width) as f64, (other / width) as f64);
                    (x - ox).powi(2) + (y - oy).powi(2)
                })
                .fold(f64::INFINITY, f64::min);
            if brute.is_finite() {
                assert_eq!(f64::from(fast), brute, "round {round} cell {cell}");
            } else {
                assert!(fast > 1e9, "round {round} cell {cell}");
            }
        }
    }
}

#[test]
fn a_walk_covers_the_segment_and_measures_it() {
    let world = world("boundary 0,0 10,0 10,10 0,10 0,0\n");
    let map = Costmap::for_world(
        &world,
        &Robot::default(),
        &[],
        &CostmapSettings {
            resolution_m: 0.5,
            ..CostmapSettings::default()
        },
    )
    .expect("map");
    let mut rng = Rng(11);
    let mut cases: Vec<(Point, Point)> = (0..200)
        .map(|_| {
            (
                Point::new(rng.uniform(0.0, 10.0), rng.uniform(0.0, 10.0)),
                Point::new(rng.uniform(0.0, 10.0), rng.uniform(0.0, 10.0)),
            )
        })
        .collect();
    // Through cell corners, along cell edges, and a point.
    cases.push((Point::new(0.0, 0.0), Point::new(5.0, 5.0)));
    cases.push((Point::new(1.0, 1.0), Point::new(1.0, 6.0)));
    cases.push((Point::new(3.2, 4.1), Point::new(3.2, 4.1)));
    cases.push((Point::new(7.25, 2.25), Point::new(2.25, 7.25)));
    for (a, b) in cases {
        let mut cells = Vec::new();
        let mut total = 0.0;
        assert!(map.walk(a, b, |cell, length| {
            cells.push(cell);
            total += length;
            true
        }));
        assert!((total - a.distance(b)).abs() < 1e-9, "{a}–{b}: {total}");
        let half = map.resolution_m() / 2.0 + 1e-9;
        for i in 0..=100 {
            let t = f64::from(i) / 100.0;
            let q = Point::new(a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t);
            assert!(
                cells.iter().any(|&cell| {
                    let c = map.centre(cell);
                    (q.x - c.x).abs() <= half && (q.y - c.y).abs() <= half
                }),
                "{a}–{b}: {q} is in no visited cell"
            );
        }
    }
}

/// What a plan from `start` to `goal` gives, in words to compare.
#[derive(Debug, PartialEq)]
enum Outcome {
    /// A path of this many metres, to 0.1 m.
    Length(String),
    Error(String),
}

fn outcome(world: &World, keepouts: &[Keepout], start: (f64, f64), goal: (f64, f64)) -> Outcome {
    let mut planner = planner_on(world, keepouts);
    match planner.plan(Point::new(start.0, start.1), Point::new(goal.0, goal.1)) {
        Ok(path) => {
            assert_clear(world, keepouts, &path, "case");
            Outcome::Length(format!("{:.1}", path.length_m))
        }
        Err(err) => Outcome::Error(err.to_string()),
    }
}

#[test]
fn paths_and_refusals_on_small_worlds() {
    let room = "boundary 0,0 20,0 20,10 0,10 0,0\n";
    // A wall across the room at x = 10 with a doorway of the given width at y 4 to 4 + width.
    let door = |width: f64| {
        world(&format!(
            "{room}wall 10,0 10,4\nwall 10,{} 10,10\n",
            4.0 + width
        ))
    };
    let closed_room = world(&format!("{room}wall 12,2 18,2 18,8 12,8 12,2\n"));
    type Case = (
        &'static str,
        World,
        Vec<Keepout>,
        (f64, f64),
        (f64, f64),
        Outcome,
    );
    let cases: Vec<Case> = vec![
        (
            "the straight line in the open",
            world(room),
            vec![],
            (2.0, 5.0),
            (18.0, 5.0),
            Outcome::Length("16.0".into()),
        ),
        (
            "through a 1.2 m doorway",
            door(1.2),
            vec![],
            (2.0, 4.6),
            (18.0, 4.6),
            Outcome::Length("16.0".into()),
        ),
        (
            "a 0.6 m doorway is too narrow",
            door(0.6),
            vec![],
            (2.0, 4.3),
            (18.0, 4.3),
            Outcome::Error(
                "no way through: the narrowest passage is 0.6 m wide at (10, 4.3); the robot needs 0.78 m there".into(),
            ),
        ),
        (
            "a goal in a closed room",
            closed_room.clone(),
            vec![],
            (2.0, 5.0),
            (15.0, 5.0),
            Outcome::Error("no way through: the way is closed at (12.03, 1.98)".into()),
        ),
        (
            "a goal outside the world",
            world(room),
            vec![],
            (2.0, 5.0),
            (25.0, 5.0),
            Outcome::Error("the goal (25, 5) is outside the world".into()),
        ),
        (
            "a goal in a wall",
            door(1.2),
            vec![],
            (2.0, 5.0),
            (10.0, 2.0),
            Outcome::Error(
                "the goal (10, 2) is on the wall on line 5; the robot keeps 0.35 m from obstacles"
                    .into(),
            ),
        ),
        (
            "a start inside an obstacle",
            world(&format!("{room}rect 4,4 6,6\n")),
            vec![],
            (5.0, 5.0),
            (15.0, 5.0),
            Outcome::Error("the start (5, 5) is inside the obstacle on line 5".into()),
        ),
        (
            "a no-go area covering the start",
            world(room),
            vec![square("mines", 1.0, 4.0, 3.0, 6.0, 0.75)],
            (2.0, 5.0),
            (15.0, 5.0),
            Outcome::Error("the start (2, 5) is in the no-go area `mines`".into()),
        ),
        (
            "a no-go area across the room",
            world(room),
            vec![square("ditch", 9.0, -1.0, 11.0, 11.0, 0.75)],
            (2.0, 5.0),
            (15.0, 5.0),
            Outcome::Error(
                "no way through: the way is closed at (10.03, 4.98), by the no-go area `ditch`"
                    .into(),
            ),
        ),
        (
            "a no-go area that leaves a gap too narrow for its margin",
            world(room),
            vec![square("ditch", 9.0, 1.2, 11.0, 11.0, 0.75)],
            (2.0, 5.0),
            (15.0, 5.0),
            Outcome::Error(
                "no way through: the narrowest passage is 1.2 m wide at (10.02, 0.6), by the no-go area `ditch`; the robot needs 2.08 m there"
                    .into(),
            ),
        ),
    ];
    for (name, world, keepouts, start, goal, expected) in cases {
        assert_eq!(outcome(&world, &keepouts, start, goal), expected, "{name}");
    }
}

#[test]
fn a_path_goes_round_a_block_and_keeps_off_the_walls_where_there_is_room() {
    // A corridor 3 m wide, start and goal 0.5 m from its south wall: the path moves out
    // towards the middle rather than running along the wall.
    let corridor = world("boundary 0,0 30,0 30,3 0,3 0,0\n");
    let mut planner = planner_on(&corridor, &[]);
    let path = planner
        .plan(Point::new(1.0, 0.5), Point::new(29.0, 0.5))
        .expect("a path");
    assert_clear(&corridor, &[], &path, "corridor");
    let furthest = path.points.iter().map(|p| p.y).fold(0.0, f64::max);
    assert!(furthest > 0.85, "{path:?}");
    assert!(path.length_m < 30.0, "{path:?}");
    // A block in the way: round it, a little longer than straight.
    let yard = world("boundary 0,0 20,0 20,20 0,20 0,0\nrect 8,4 12,16\n");
    let mut planner = planner_on(&yard, &[]);
    let path = planner
        .plan(Point::new(2.0, 10.0), Point::new(18.0, 10.0))
        .expect("a path");
    assert_clear(&yard, &[], &path, "yard");
    assert!(
        path.length_m > 16.0 + 2.0 && path.length_m < 24.0,
        "{path:?}"
    );
    assert!(path.points.len() <= 8, "smoothed: {path:?}");
}

#[test]
fn paths_read_back_from_their_text() {
    let path = Path::new(vec![
        Point::new(1.0, 2.5),
        Point::new(-3.25, 4.0),
        Point::new(0.0, 0.0),
    ]);
    let text = path.format();
    assert_eq!(text, "1,2.5 -3.25,4 0,0");
    assert_eq!(Path::parse(&text), Ok(path));
    assert_eq!(Path::parse(""), Ok(Path::default()));
    assert_eq!(
        Path::parse("1,2 x,3"),
        Err("`x,3` is not a point `X,Y` in metres".into())
    );
    assert!(Path::parse("1,2 NaN,3").is_err());
}

#[test]
fn without_a_world_only_the_areas_are_in_the_way() {
    let keepouts = [square("pond", 4.0, -3.0, 6.0, 3.0, 0.75)];
    let path = plan_path(
        None,
        &Robot::default(),
        &keepouts,
        Point::new(0.0, 0.0),
        Point::new(10.0, 0.0),
    )
    .expect("round the pond");
    // Over the pond at y = 4 (3 m and 1 m off) is 14.1 m; the cost keeps it a little further.
    assert!(path.length_m > 14.0 && path.length_m < 15.0, "{path:?}");
    for pair in path.points.windows(2) {
        assert!(
            !keepouts[0].polygon.blocks(pair[0], pair[1], 0.99),
            "{path:?}"
        );
    }
    let clear = plan_path(
        None,
        &Robot::default(),
        &keepouts,
        Point::new(0.0, 10.0),
        Point::new(10.0, 10.0),
    )
    .expect("straight");
    assert_eq!(clear.points.len(), 2);
}

/// A flood fill over the free cells, 8-connected: which cells can be reached from `from`.
fn reachable(map: &Costmap, from: usize, to: usize) -> bool {
    let width = map.width();
    let mut seen = vec![false; map.costs().len()];
    let mut queue = VecDeque::from([from]);
    seen[from] = true;
    while let Some(cell) = queue.pop_front() {
        if cell == to {
            return true;
        }
        for offset in [
            1,
            -1,
            width as isize,
            -(width as isize),
            width as isize + 1,
            width as isize - 1,
            -(width as isize) + 1,
            -(width as isize) - 1,
        ] {
            let next = cell.wrapping_add_signed(offset);
            if !seen[next] && map.costs()[next] != LETHAL {
                seen[next] = true;
                queue.push_back(next);
            }
        }
    }
    false
}

/// A random world: 40 m × 40 m, 20 to 40 rectangles and discs.
fn random_world(rng: &mut Rng) -> World {
    RandomWorld::default().draw(rng)
}

/// A random place where the robot may be.
fn free_place(rng: &mut Rng, map: &Costmap) -> Point {
    random::free_place(rng, map, 40.0)
}

#[test]
fn random_worlds_seed_2026() {
    const SEED: u64 = 2026;
    const WORLDS: usize = 30;
    const PAIRS: usize = 8;
    let mut rng = Rng(SEED);
    let (mut connected, mut cut) = (0, 0);
    for index in 0..WORLDS {
        let world = random_world(&mut rng);
        let mut planner = planner_on(&world, &[]);
        let pairs: Vec<(Point, Point)> = (0..PAIRS)
            .map(|_| {
                (
                    free_place(&mut rng, planner.costmap()),
                    free_place(&mut rng, planner.costmap()),
                )
            })
            .collect();
        let mut answers = Vec::new();
        for (pair, &(start, goal)) in pairs.iter().enumerate() {
            let context = format!("seed {SEED}, world {index}, pair {pair}");
            let from = planner.snap_for_tests(start);
            let to = planner.snap_for_tests(goal);
            let flood = match (from, to) {
                (Some(from), Some(to)) => reachable(planner.costmap(), from, to),
                _ => false,
            };
            let answer = planner.plan(start, goal);
            answers.push(answer.clone());
            match answer {
                Ok(path) => {
                    // The straight line may be taken off the grid when the geometry allows.
                    assert!(
                        flood || path.points.len() == 2,
                        "{context}: the flood fill disagrees"
                    );
                    assert_eq!(path.points.first(), Some(&start), "{context}");
                    assert_eq!(path.points.last(), Some(&goal), "{context}");
                    assert_clear(&world, &[], &path, &context);
                    assert!(path.length_m >= start.distance(goal) - 1e-9, "{context}");
                    connected += 1;
                }
                Err(PathError::Cut(bottleneck)) => {
                    assert!(!flood, "{context}: the flood fill found a way");
                    let keep = Robot::default().keep_m();
                    assert!(
                        bottleneck.width_m < 2.0 * keep + 0.15,
                        "{context}: a passage of {} m should let the robot through",
                        bottleneck.width_m
                    );
                    assert!(world.bounds().contains(bottleneck.at), "{context}");
                    cut += 1;
                }
                Err(other) => panic!("{context}: {other}"),
            }
        }
        // On several threads, the same answers.
        assert_eq!(
            planner.plan_many(&pairs),
            answers,
            "seed {SEED}, world {index}"
        );
    }
    // Both kinds happen, so that both checks prove something.
    assert!(
        connected > 100 && cut > 5,
        "{connected} connected, {cut} cut"
    );
    eprintln!("random worlds (seed {SEED}): {connected} pairs connected, {cut} cut");
}

/// Our A* finds the cheapest grid path: the same cost as the `pathfinding` crate's Dijkstra
/// (no heuristic, so ours is checked too) on random worlds at 20 cm.
#[test]
fn a_star_costs_match_an_independent_dijkstra_seed_7() {
    let mut rng = Rng(7);
    let settings = CostmapSettings {
        resolution_m: 0.2,
        ..CostmapSettings::default()
    };
    let mut compared = 0;
    for index in 0..10 {
        let world = random_world(&mut rng);
        let costmap = Costmap::for_world(&world, &Robot::default(), &[], &settings)
            .unwrap_or_else(|err| panic!("{err}"));
        let mut planner = Planner::new(costmap);
        for pair in 0..5 {
            let map = planner.costmap();
            let (start, goal) = (free_place(&mut rng, map), free_place(&mut rng, map));
            let (Some(from), Some(to)) = (map.cell_of(start), map.cell_of(goal)) else {
                continue;
            };
            if map.costs()[from] == LETHAL || map.costs()[to] == LETHAL {
                continue;
            }
            let reference = pathfinding::directed::dijkstra::dijkstra(
                &from,
                |&cell| map.neighbours(cell),
                |&cell| cell == to,
            )
            .map(|(_, cost)| cost);
            assert_eq!(
                planner.grid_search(from, to),
                reference,
                "seed 7, world {index}, pair {pair}: {start} to {goal}"
            );
            compared += 1;
        }
    }
    assert!(compared > 40, "{compared}");
}

/// One search from a place to many goals gives each goal the very path it gets planned alone,
/// to the bit, with a no-go area in the way or not: the ways of `armor plan`'s table are the
/// legs `armor check` then plans. Unreachable goals get the same bottleneck too.
#[test]
fn one_search_to_many_goals_finds_the_paths_planned_alone_seed_4040() {
    let mut rng = Rng(4040);
    let (mut searched, mut cut) = (0, 0);
    for index in 0..24 {
        let world = random_world(&mut rng);
        let keepouts = if index % 2 == 0 {
            vec![square("pit", 14.0, 14.0, 22.0, 20.0, 0.5)]
        } else {
            Vec::new()
        };
        let mut planner = planner_on(&world, &keepouts);
        let start = free_place(&mut rng, planner.costmap());
        let goals: Vec<Point> = (0..12)
            .map(|_| free_place(&mut rng, planner.costmap()))
            .collect();
        let together = planner.plan_from(start, &goals);
        assert_eq!(together.len(), goals.len());
        for (pair, (goal, answer)) in goals.iter().zip(&together).enumerate() {
            let alone = planner.plan(start, *goal);
            assert_eq!(answer, &alone, "seed 4040, world {index}, goal {pair}");
            match answer {
                Ok(path) if path.points.len() > 2 => searched += 1,
                Err(PathError::Cut(_)) => cut += 1,
                _ => {}
            }
        }
        // Planned as pairs, on threads, grouped by start: the same again.
        let pairs: Vec<(Point, Point)> = goals.iter().map(|&goal| (start, goal)).collect();
        assert_eq!(
            planner.plan_many(&pairs),
            together,
            "seed 4040, world {index}"
        );
    }
    // Most ways turn round something, and some are cut, so that both are compared.
    assert!(searched > 80 && cut > 0, "{searched} searched, {cut} cut");
}
