use super::*;
use armor_module_api::testing::{Step, TestBench};

fn twist(linear_mps: f64, angular_radps: f64) -> Twist {
    Twist {
        linear_mps,
        angular_radps,
    }
}

const GOAL: Twist = Twist {
    linear_mps: 0.5,
    angular_radps: 0.0,
};
const AVOID: Twist = Twist {
    linear_mps: 0.1,
    angular_radps: 0.8,
};

fn settings(priorities: &[i64], hold_secs: f64) -> Settings {
    let mut all = [0; CANDIDATES];
    all[..priorities.len()].copy_from_slice(priorities);
    Settings {
        priorities: all,
        fresh_secs: 0.3,
        hold_secs,
        rate_hz: 20.0,
    }
}

fn push(input: &str, value: Twist) -> Step {
    Step::push(input, &value).expect("step")
}

#[test]
fn the_highest_priority_fresh_candidate_wins_and_a_tie_goes_to_the_first() {
    let settings = settings(&[10, 30, 20], 0.0);
    let mut arbiter = Arbiter::default();
    assert_eq!(arbiter.select(0.0, &settings), None);
    arbiter.receive(0, GOAL, 0.0);
    arbiter.receive(2, twist(0.0, 0.0), 0.0);
    assert_eq!(arbiter.select(0.1, &settings), Some(2));
    arbiter.receive(1, AVOID, 0.1);
    assert_eq!(arbiter.select(0.1, &settings), Some(1));
    assert_eq!(arbiter.command(), AVOID);
    let tie = self::settings(&[5, 5], 0.0);
    let mut arbiter = Arbiter::default();
    arbiter.receive(1, AVOID, 0.0);
    arbiter.receive(0, GOAL, 0.0);
    assert_eq!(arbiter.select(0.0, &tie), Some(0));
}

#[test]
fn a_stale_candidate_gives_way_at_once_and_none_fresh_means_zero() {
    let settings = settings(&[10, 30], 1.0);
    let mut arbiter = Arbiter::default();
    arbiter.receive(0, GOAL, 0.0);
    arbiter.receive(1, AVOID, 0.0);
    assert_eq!(arbiter.select(0.0, &settings), Some(1));
    arbiter.receive(0, GOAL, 0.25);
    // The avoider's proposal is 0.35 s old: stale, so it loses control within its hold time.
    assert_eq!(arbiter.select(0.35, &settings), Some(0));
    assert!(arbiter.winner_changed);
    assert_eq!(arbiter.select(0.7, &settings), None);
    assert_eq!(arbiter.command(), Twist::default());
}

/// How many times the winner changes in 3 s when goal proposes every 0.1 s and avoid, of
/// higher priority, proposes once every 0.5 s (fresh for 0.3 s of each 0.5 s).
fn changes_with_a_flickering_avoid(hold_secs: f64) -> usize {
    let settings = settings(&[10, 30], hold_secs);
    let mut arbiter = Arbiter::default();
    let mut winners = Vec::new();
    for step in 0..30 {
        let now = f64::from(step) * 0.1;
        arbiter.receive(0, GOAL, now);
        if step % 5 == 0 {
            arbiter.receive(1, AVOID, now);
        }
        winners.push(arbiter.select(now, &settings));
    }
    winners.windows(2).filter(|w| w[0] != w[1]).count()
}

#[test]
fn hysteresis_keeps_a_fresh_winner_for_its_hold_time() {
    let (with, without) = (
        changes_with_a_flickering_avoid(0.5),
        changes_with_a_flickering_avoid(0.0),
    );
    assert!(with < without, "hold time: {with} changes, none: {without}");
    let settings = settings(&[10, 30], 0.5);
    // The goal, once it holds control, keeps it for 0.5 s even though avoid is fresh again.
    let mut arbiter = Arbiter::default();
    arbiter.receive(0, GOAL, 0.0);
    assert_eq!(arbiter.select(0.0, &settings), Some(0));
    arbiter.receive(1, AVOID, 0.2);
    assert_eq!(arbiter.select(0.2, &settings), Some(0));
    arbiter.receive(0, GOAL, 0.45);
    arbiter.receive(1, AVOID, 0.45);
    assert_eq!(arbiter.select(0.45, &settings), Some(0));
    assert_eq!(arbiter.select(0.5, &settings), Some(1));
}

#[test]
fn seeded_random_proposals_always_pick_a_fresh_candidate_no_lower_than_the_best_after_hold() {
    // A small linear congruential generator: the seed is in the test's name.
    let mut state: u64 = 20;
    let mut next = move || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 33) as f64 / f64::from(1u32 << 31)
    };
    let settings = settings(&[3, 7, 1, 7, 5, 2], 0.2);
    let mut arbiter = Arbiter::default();
    let mut held_since = 0.0;
    let mut last = None;
    for step in 0..2000 {
        let now = f64::from(step) * 0.01;
        for index in 0..CANDIDATES {
            if next() < 0.1 {
                arbiter.receive(index, twist(next(), next()), now);
            }
        }
        let winner = arbiter.select(now, &settings);
        if winner != last {
            held_since = now;
            last = winner;
        }
        let fresh: Vec<usize> = (0..CANDIDATES)
            .filter(|&i| arbiter.is_fresh(i, now, &settings))
            .collect();
        match winner {
            None => assert!(fresh.is_empty(), "at {now}: {fresh:?} fresh, no winner"),
            Some(index) => {
                assert!(fresh.contains(&index), "at {now}: a stale winner");
                let best = fresh.iter().map(|&i| settings.priorities[i]).max();
                if now - held_since >= settings.hold_secs {
                    assert_eq!(Some(settings.priorities[index]), best, "at {now}");
                }
            }
        }
    }
}

#[test]
fn forwards_the_winners_proposals_at_once_and_reports_each_change() {
    let mut bench = TestBench::new(
        &spec(),
        &[
            ("priority_1", "10"),
            ("priority_2", "30"),
            ("hold_secs", "0"),
        ],
    )
    .expect("bench");
    bench.script([
        push("candidate_1", GOAL),
        push("candidate_2", AVOID),
        push("candidate_1", GOAL),
        push("candidate_2", AVOID),
        Step::Advance(0.5),
        Step::Timeouts(1),
        push("candidate_1", GOAL),
    ]);
    body(bench.node()).expect("body");
    assert_eq!(
        bench.sent::<Twist>("cmd_vel").expect("sent"),
        [GOAL, AVOID, AVOID, Twist::default(), GOAL],
        "a losing candidate's proposal is not forwarded; zero once none is fresh"
    );
    assert_eq!(
        bench.behaviour(),
        [
            "winner candidate_1",
            "winner candidate_2",
            "winner none",
            "winner candidate_1"
        ]
    );
    assert_eq!(bench.reported().len(), 4);
}

#[test]
fn refuses_bad_settings_and_is_not_controllable() {
    for (name, value, expected) in [
        ("fresh_secs", "0", "`fresh_secs` must be greater than 0 s"),
        ("hold_secs", "-1", "`hold_secs` must be 0 s or more"),
        ("priority_3", "-1", "`priority_3` must be"),
    ] {
        let mut bench = TestBench::new(&spec(), &[(name, value)]).expect("bench");
        let err = body(bench.node()).expect_err("must refuse");
        assert!(err.to_string().contains(expected), "{err}");
    }
    assert!(!spec().description().controllable);
}
