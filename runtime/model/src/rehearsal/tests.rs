use super::*;

/// The square no-go area of 2 m side with its lower left corner at (10, 0).
fn square() -> NoGoArea {
    NoGoArea {
        name: "spill".to_owned(),
        polygon: Polygon::new(vec![
            Point::new(10.0, 0.0),
            Point::new(12.0, 0.0),
            Point::new(12.0, 2.0),
            Point::new(10.0, 2.0),
        ]),
    }
}

const RULES: Rules = Rules {
    radius_m: 0.35,
    tolerance_m: 0.3,
};

fn pose(at_secs: f64, x: f64, y: f64) -> TruePose {
    TruePose {
        at_secs,
        at: Point::new(x, y),
    }
}

fn arrival(leg: &str, waypoint: &str, at_secs: f64, x: f64, y: f64) -> Arrival {
    Arrival {
        leg: leg.to_owned(),
        waypoint: waypoint.to_owned(),
        target: Point::new(x, y),
        at_secs,
    }
}

/// Judges `poses` and `arrivals` round the square, and checks the verdict's failures.
fn check(poses: &[TruePose], arrivals: &[Arrival], expected_failures: &[&str]) -> Verdict {
    let verdict = judge(poses, arrivals, &[square()], RULES);
    assert_eq!(verdict.failures, expected_failures, "{verdict:#?}");
    assert_eq!(verdict.passed, expected_failures.is_empty());
    verdict
}

/// A robot that drives from (0, 5) to (20, 5) in 20 s, 50 poses a second: 3 m clear of the
/// square's top side, its footprint 2.65 m clear.
fn drive() -> Vec<TruePose> {
    (0..=1000)
        .map(|step| {
            let t = f64::from(step) * 0.02;
            pose(t, t, 5.0)
        })
        .collect()
}

#[test]
fn a_true_arrival_within_the_tolerance_and_slack_passes_and_says_its_error() {
    let verdict = check(&drive(), &[arrival("out", "east", 20.0, 20.3, 5.1)], &[]);
    let error = verdict.arrivals[0].true_error_m.expect("judged");
    assert!((error - 0.3162).abs() < 1e-3, "{error}");
    assert_eq!(verdict.true_error_text("out"), "0.32 m (simulator)");
    assert_eq!(verdict.true_error_text("other"), "-");
    assert!((verdict.allowed_m - 0.4).abs() < 1e-12);
    let least = verdict.areas[0].least_distance_m.expect("judged");
    assert!((least - 2.65).abs() < 1e-9, "{least}");
    assert_eq!(
        verdict.area_lines(),
        [
            "no-go area `spill`: the footprint (radius 0.35 m) kept 2.65 m from it at least, by \
          the simulator's truth"
        ]
    );
    assert_eq!(
        verdict.headline(),
        "rehearsal passed by the simulator's truth: every arrival within 0.40 m of its waypoint, \
         no footprint met a no-go area (1001 true poses)"
    );
}

#[test]
fn an_arrival_the_truth_puts_far_from_its_waypoint_fails_in_words() {
    let verdict = check(
        &drive(),
        &[
            arrival("advance", "gate", 10.0, 10.0, 5.2),
            arrival("regroup", "rally", 20.0, 20.0, 7.59),
        ],
        &[
            "leg `regroup` arrived 2.59 m from its waypoint `rally` by the simulator's truth \
           (allowed 0.40 m)",
        ],
    );
    assert_eq!(
        verdict.true_error_text("regroup"),
        "2.59 m (simulator) FAILED"
    );
    assert!(verdict.arrivals[0].ok && !verdict.arrivals[1].ok);
    assert_eq!(
        verdict.headline(),
        "rehearsal FAILED: leg `regroup` arrived 2.59 m from its waypoint `rally` by the \
         simulator's truth (allowed 0.40 m)"
    );
}

#[test]
fn just_beyond_the_tolerance_plus_the_slack_fails_and_just_within_passes() {
    let poses = [pose(0.0, 0.0, 0.0), pose(1.0, 0.0, 0.0)];
    check(&poses, &[arrival("a", "w", 1.0, 0.399, 0.0)], &[]);
    check(
        &poses,
        &[arrival("a", "w", 1.0, 0.401, 0.0)],
        &[
            "leg `a` arrived 0.40 m from its waypoint `w` by the simulator's truth (allowed \
           0.40 m)",
        ],
    );
}

#[test]
fn an_arrival_is_judged_by_the_true_pose_nearest_to_it_in_time() {
    // Given out of order; the pose 20 ms after the event is nearer than the one 100 ms before.
    let poses = [
        pose(10.02, 5.0, 5.0),
        pose(9.9, 0.0, 0.0),
        pose(12.0, 0.0, 0.0),
    ];
    let verdict = check(&poses, &[arrival("a", "w", 10.0, 5.0, 5.0)], &[]);
    assert_eq!(verdict.arrivals[0].truth_secs, Some(10.02));
    assert_eq!(verdict.arrivals[0].true_error_m, Some(0.0));
    // And the one before, when it is the nearer.
    let verdict = judge(
        &[pose(9.99, 5.0, 5.0), pose(10.5, 0.0, 0.0)],
        &[arrival("a", "w", 10.0, 5.0, 5.0)],
        &[],
        RULES,
    );
    assert_eq!(verdict.arrivals[0].truth_secs, Some(9.99));
    assert!(verdict.passed, "{verdict:#?}");
}

#[test]
fn a_footprint_that_touches_the_area_from_outside_meets_it() {
    // The centre 0.2 m left of the square, the radius 0.35 m: 0.15 m of the disc in it.
    let poses = [
        pose(0.0, 5.0, 1.0),
        pose(1.0, 9.8, 1.0),
        pose(2.0, 9.8, 1.0),
        pose(3.0, 5.0, 1.0),
    ];
    let verdict = check(
        &poses,
        &[],
        &[
            "the robot's footprint met the no-go area `spill` by the simulator's truth (from \
           1.0 s, 0.15 m into it, 2 true poses)",
        ],
    );
    let area = &verdict.areas[0];
    assert!(!area.ok);
    assert_eq!(area.poses_met, 2);
    assert!((area.least_distance_m.expect("judged") + 0.15).abs() < 1e-9);
    assert_eq!(
        verdict.area_lines(),
        [
            "no-go area `spill`: the footprint (radius 0.35 m) met it from 1.0 s, reaching 0.15 m \
          into it (2 true poses), by the simulator's truth"
        ]
    );
}

#[test]
fn the_footprint_distance_is_signed_by_the_centre_s_side_of_the_outline() {
    let square = square().polygon;
    for (centre, expected) in [
        (Point::new(9.0, 1.0), 0.65),
        (Point::new(9.65, 1.0), 0.0),
        (Point::new(11.0, 1.0), -1.35),
        (Point::new(13.0, 3.0), 2f64.sqrt() - 0.35),
    ] {
        let got = footprint_distance_m(&square, centre, 0.35);
        assert!(
            (got - expected).abs() < 1e-9,
            "{centre}: {got} ≠ {expected}"
        );
    }
}

#[test]
fn without_any_true_pose_nothing_passes() {
    let verdict = check(
        &[],
        &[arrival("a", "w", 1.0, 0.0, 0.0)],
        &["no true pose came from the simulator, so nothing could be judged"],
    );
    assert_eq!(verdict.true_error_text("a"), "no truth");
    assert_eq!(
        verdict.area_lines(),
        ["no-go area `spill`: no true pose to judge it by"]
    );
}

#[test]
fn an_arrival_with_no_true_pose_near_it_in_time_is_not_judged_and_fails() {
    check(
        &[pose(0.0, 0.0, 0.0), pose(20.0, 0.0, 0.0)],
        &[arrival("a", "w", 10.0, 0.0, 0.0)],
        &[
            "leg `a` arrived at 10.0 s with no true pose within 5 s of it, so its arrival could \
           not be judged",
        ],
    );
}

#[test]
fn poses_that_are_not_finite_are_no_evidence() {
    let poses = [pose(0.0, f64::NAN, 0.0), pose(f64::INFINITY, 0.0, 0.0)];
    let verdict = check(
        &poses,
        &[],
        &["no true pose came from the simulator, so nothing could be judged"],
    );
    assert_eq!(verdict.true_poses, 0);
}

#[test]
fn the_judge_fed_as_a_run_goes_gives_the_verdict_of_the_whole_lists() {
    let poses = drive();
    let arrivals = [
        arrival("advance", "gate", 10.0, 10.0, 5.2),
        arrival("regroup", "rally", 20.0, 20.0, 7.59),
    ];
    let mut live = Judge::new(vec![square()], RULES);
    // Each event reaches the judge a little after the poses of its time, and the last one
    // before any pose at or after it: it stays unsettled until one comes.
    for (step, pose) in poses.iter().enumerate() {
        live.observe(*pose);
        // Half a second after the event at 10 s.
        if step == 525 {
            live.arrived(arrivals[0].clone());
            assert!(live.settled());
        }
    }
    live.arrived(arrival("late", "w", 30.0, 20.0, 5.0));
    assert!(!live.settled());
    live.observe(pose(30.0, 20.0, 5.0));
    assert!(live.settled());
    live.arrived(arrivals[1].clone());
    let mut expected = judge(
        &[poses.as_slice(), &[pose(30.0, 20.0, 5.0)]].concat(),
        &[arrivals[0].clone(), arrivals[1].clone()],
        &[square()],
        RULES,
    );
    let verdict = live.verdict();
    // The late arrival is extra in the live judge, and the order of events is the live one.
    assert_eq!(verdict.arrivals[1].leg, "late");
    assert!(verdict.arrivals[1].ok);
    expected.arrivals.insert(1, verdict.arrivals[1].clone());
    assert_eq!(verdict, expected);
}

#[test]
fn a_long_run_keeps_only_a_window_of_poses_but_every_area_meeting() {
    let mut live = Judge::new(vec![square()], RULES);
    // Met at the start, then an hour of driving far from it at 50 poses a second.
    live.observe(pose(0.0, 11.0, 1.0));
    for step in 1..=180_000 {
        live.observe(pose(f64::from(step) * 0.02, 0.0, 50.0));
    }
    assert!(
        live.recent.len() <= (WINDOW_SECS / 0.02) as usize + 1,
        "{}",
        live.recent.len()
    );
    let verdict = live.verdict();
    assert!(!verdict.passed);
    assert_eq!(verdict.areas[0].first_met_secs, Some(0.0));
    assert_eq!(verdict.true_poses, 180_001);
}

#[test]
fn an_area_added_by_an_update_is_judged_from_then_and_one_taken_out_until_then() {
    // The robot drives through the square (y = 1) from 0 s to 20 s; the square is added at
    // 5 s, before it gets there, and taken out again at 9 s, as it is about to enter.
    let through: Vec<TruePose> = (0..=1000)
        .map(|step| {
            let t = f64::from(step) * 0.02;
            pose(t, t, 1.0)
        })
        .collect();
    let mut judge = Judge::new(Vec::new(), RULES);
    let feed = |judge: &mut Judge, from: f64, to: f64| {
        for pose in through
            .iter()
            .filter(|pose| pose.at_secs >= from && pose.at_secs < to)
        {
            judge.observe(*pose);
        }
    };
    feed(&mut judge, 0.0, 5.0);
    judge.set_areas(vec![square()]);
    feed(&mut judge, 5.0, 9.0);
    judge.set_areas(Vec::new());
    feed(&mut judge, 9.0, 21.0);
    let verdict = judge.verdict();
    // Up to 9 s the footprint (radius 0.35) came to 0.65 m of the square, never in.
    assert!(verdict.passed, "{verdict:#?}");
    let least = verdict.areas[0].least_distance_m.expect("judged");
    assert!((least - 0.65).abs() < 0.03, "{least}");
    // Kept in the plan, the same drive meets it.
    let mut judge = Judge::new(Vec::new(), RULES);
    feed(&mut judge, 0.0, 5.0);
    judge.set_areas(vec![square()]);
    // The same area again changes nothing.
    judge.set_areas(vec![square()]);
    feed(&mut judge, 5.0, 21.0);
    let verdict = judge.verdict();
    assert_eq!(verdict.areas.len(), 1);
    assert!(!verdict.passed);
    assert!(
        verdict.areas[0]
            .first_met_secs
            .is_some_and(|first| first >= 9.0)
    );
}
