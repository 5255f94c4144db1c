use super::*;
use crate::geo::Polygon;

/// A 30 m square with a wall across its middle, open at both ends.
fn world() -> World {
    World::parse(
        "name t\norigin 0 0\nstart 1 1 0\nboundary 0,0 30,0 30,30 0,30 0,0\n\
         rect 5,14.8 25,15.2\n",
        "t.world",
    )
    .unwrap_or_else(|err| panic!("{err}"))
}

fn area(name: &str, x0: f64, y0: f64, x1: f64, y1: f64) -> Keepout {
    Keepout::new(
        name,
        Polygon::new(vec![
            Point::new(x0, y0),
            Point::new(x1, y0),
            Point::new(x1, y1),
            Point::new(x0, y1),
        ]),
        planner::DEFAULT_AREA_MARGIN_M,
    )
}

/// Legs round the square: two below the wall, one across it, two above.
fn legs(moved: Option<Point>) -> Vec<(Point, Point)> {
    let points = [
        Point::new(3.0, 3.0),
        Point::new(15.0, 4.0),
        moved.unwrap_or(Point::new(27.0, 3.0)),
        Point::new(27.0, 27.0),
        Point::new(15.0, 26.0),
        Point::new(3.0, 27.0),
    ];
    points.windows(2).map(|pair| (pair[0], pair[1])).collect()
}

/// What planning every pair afresh gives.
fn fresh(keepouts: &[Keepout], pairs: &[(Point, Point)]) -> Vec<Result<Path, PathError>> {
    crate::plan::plan_pairs(Some(&world()), &Robot::default(), keepouts, pairs)
        .unwrap_or_else(|err| panic!("{err}"))
}

/// Plans `pairs` with `memory` and checks the paths are the ones planned afresh.
fn check(memory: &mut PathMemory, keepouts: &[Keepout], pairs: &[(Point, Point)]) -> Reuse {
    let got = memory
        .plan_pairs(Some(&world()), &Robot::default(), keepouts, pairs)
        .unwrap_or_else(|err| panic!("{err}"));
    assert_eq!(got, fresh(keepouts, pairs));
    memory.last()
}

fn reuse(planned: usize, reused: usize, costmap_built: bool) -> Reuse {
    Reuse {
        planned,
        reused,
        costmap_built,
    }
}

#[test]
fn the_same_legs_again_are_all_reused_with_no_costmap() {
    let mut memory = PathMemory::default();
    assert_eq!(check(&mut memory, &[], &legs(None)), reuse(5, 0, true));
    assert_eq!(check(&mut memory, &[], &legs(None)), reuse(0, 5, false));
}

#[test]
fn a_moved_waypoint_plans_its_two_legs_on_the_costmap_kept() {
    let mut memory = PathMemory::default();
    check(&mut memory, &[], &legs(None));
    let moved = legs(Some(Point::new(27.0, 5.0)));
    assert_eq!(check(&mut memory, &[], &moved), reuse(2, 3, false));
    // Moved back: the memory holds one plan's legs, so the two are planned again.
    assert_eq!(check(&mut memory, &[], &legs(None)), reuse(2, 3, false));
}

#[test]
fn an_area_added_plans_again_only_the_legs_it_comes_near() {
    let mut memory = PathMemory::default();
    check(&mut memory, &[], &legs(None));
    // Across the first leg's straight line, far from the others.
    let mines = [area("mines", 8.0, 2.0, 10.0, 4.5)];
    assert_eq!(check(&mut memory, &mines, &legs(None)), reuse(1, 4, true));
    let paths = memory
        .plan_pairs(Some(&world()), &Robot::default(), &mines, &legs(None))
        .unwrap_or_else(|err| panic!("{err}"));
    let first = paths[0].as_ref().unwrap_or_else(|err| panic!("{err}"));
    assert!(
        planner::clear_of_keepouts(&Robot::default(), &mines, first.points[0], first.points[1]),
        "the first leg's new path keeps off the area: {:?}",
        first.points
    );
}

#[test]
fn an_area_removed_or_another_robot_plans_every_leg_again() {
    let mut memory = PathMemory::default();
    let mines = [area("mines", 8.0, 2.0, 10.0, 4.5)];
    check(&mut memory, &mines, &legs(None));
    assert_eq!(check(&mut memory, &[], &legs(None)), reuse(5, 0, true));
    let wide = Robot {
        radius_m: 0.5,
        ..Robot::default()
    };
    let got = memory
        .plan_pairs(Some(&world()), &wide, &[], &legs(None))
        .unwrap_or_else(|err| panic!("{err}"));
    assert_eq!(memory.last(), reuse(5, 0, true));
    let expected = crate::plan::plan_pairs(Some(&world()), &wide, &[], &legs(None))
        .unwrap_or_else(|err| panic!("{err}"));
    assert_eq!(got, expected);
}

#[test]
fn another_world_plans_every_leg_again() {
    let mut memory = PathMemory::default();
    check(&mut memory, &[], &legs(None));
    let other = World::parse(
        "name t\norigin 0 0\nstart 1 1 0\nboundary 0,0 30,0 30,30 0,30 0,0\n\
         rect 5,14.8 29,15.2\n",
        "t.world",
    )
    .unwrap_or_else(|err| panic!("{err}"));
    memory
        .plan_pairs(Some(&other), &Robot::default(), &[], &legs(None))
        .unwrap_or_else(|err| panic!("{err}"));
    assert_eq!(memory.last(), reuse(5, 0, true));
}

#[test]
fn ends_moved_by_less_than_a_centimetre_keep_their_paths_with_the_new_ends() {
    // A plan written back with seven decimals of a degree moves each waypoint by up to half a
    // centimetre: the same legs.
    let mut memory = PathMemory::default();
    check(&mut memory, &[], &legs(None));
    let nudged: Vec<(Point, Point)> = legs(None)
        .iter()
        .map(|&(from, to)| {
            (
                Point::new(from.x + 0.004, from.y - 0.003),
                Point::new(to.x + 0.004, to.y - 0.003),
            )
        })
        .collect();
    let paths = memory
        .plan_pairs(Some(&world()), &Robot::default(), &[], &nudged)
        .unwrap_or_else(|err| panic!("{err}"));
    assert_eq!(memory.last(), reuse(0, 5, false));
    for (path, &(from, to)) in paths.iter().zip(&nudged) {
        let points = &path.as_ref().unwrap_or_else(|err| panic!("{err}")).points;
        assert_eq!((points[0], points[points.len() - 1]), (from, to));
    }
    // Two centimetres is another waypoint: planned again.
    let moved = legs(Some(Point::new(27.02, 3.0)));
    check(&mut memory, &[], &moved);
    assert_eq!(memory.last(), reuse(2, 3, false));
}
