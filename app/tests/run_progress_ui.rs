//! The Run view's numbers, read as an operator reads them (issue 37, defect 8, and the repair
//! card of issue 39): the leg being driven with the distance left, the time to its deadline and
//! the slack, the numbers `armor run`'s live line gives, taken from the run's status; and a
//! repair whose default applies after a stated time, counted down on its card.
//!
//! The run is a stand-in on the real control interface (`armor_runtime::control::serve`, the
//! studio's real session and link) that answers every request with the status a test sets, so
//! that the test moves the run's time and numbers as it likes. The numbers themselves are made
//! by `armor_runtime::progress::leg_progress`, whose own tests check them against the live line.
#![allow(clippy::unwrap_used)]

mod common;

use std::net::SocketAddr;
use std::time::{Duration, Instant};

use armor_protocol::{LegProgress, MissionStatus, Repair, RepairKind, RepairOption, Status};
use armor_studio::StudioApp;
use armor_studio::app::View;
use common::*;
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable as _;

const PATIENCE: Duration = Duration::from_secs(30);

/// A run at `run_secs` playing the yard plan, with `mission`'s progress and repair.
fn status(run_secs: f64, mission: MissionStatus) -> Status {
    Status {
        system: "/robot/missions/system.xml".to_owned(),
        run_secs,
        time_scale: 1.0,
        mission: Some(MissionStatus {
            name: "yard-recon".to_owned(),
            marking: [("advance_drive".to_owned(), 1)].into(),
            ..mission
        }),
        ..Status::default()
    }
}

/// A studio in the Run view, attached to the run at `control` and shown its status.
fn attached(home: &std::path::Path, control: SocketAddr) -> Harness<'static, StudioApp> {
    let mut harness = harness(options(home, None));
    harness.state_mut().set_view(View::Run);
    let ctx = harness.ctx.clone();
    harness.state_mut().run_mut().attach_bare(control, &ctx);
    step_until(&mut harness, "the run's status", |harness| {
        harness.state().run().status().is_some()
    });
    harness
}

/// Steps frames until `done` holds, for at most [`PATIENCE`] (the studio polls the run every
/// 200 ms).
fn step_until(
    harness: &mut Harness<'_, StudioApp>,
    what: &str,
    done: impl Fn(&Harness<'_, StudioApp>) -> bool,
) {
    let deadline = Instant::now() + PATIENCE;
    while !done(harness) {
        assert!(Instant::now() < deadline, "waited {PATIENCE:?} for {what}");
        harness.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    harness.run();
}

/// Leg `advance` of the yard plan (home → gate, due by 60 s) with `left_m` to go at `run_secs`,
/// as the run works it out at the plan's 0.5 m/s.
fn advance(run_secs: f64, left_m: f64) -> LegProgress {
    let time_left_secs = 60.0 - run_secs;
    LegProgress {
        number: 1,
        legs: 4,
        leg: "advance".to_owned(),
        from: "home".to_owned(),
        to: "gate".to_owned(),
        left_m: Some(left_m),
        deadline_run_secs: Some(60.0),
        time_left_secs: Some(time_left_secs),
        slack_secs: Some(time_left_secs - left_m / 0.5),
    }
}

#[test]
fn the_run_view_reads_the_leg_the_distance_left_the_time_to_the_deadline_and_the_slack() {
    let dir = tempfile::tempdir().unwrap();
    let (control, run) = stand_in_run(status(
        40.0,
        MissionStatus {
            progress: Some(advance(40.0, 5.0)),
            ..MissionStatus::default()
        },
    ));
    let mut harness = attached(dir.path(), control);
    // What `armor run`'s line says then: "leg 1/4 advance (home → gate): 5.0 m left · arrive
    // at gate by 60.0 s: 20.0 s left, slack 10.0 s".
    harness.get_by_label("Leg 1/4 `advance`, from `home` to `gate`");
    harness.get_by_label("5.0 m");
    harness.get_by_label("20.0 s left (by 60.0 s)");
    harness.get_by_label("10.0 s early at the plan's speed");

    // Later, past the deadline and still 3 m away: late on both counts.
    *run.lock().unwrap() = status(
        62.5,
        MissionStatus {
            progress: Some(advance(62.5, 3.0)),
            ..MissionStatus::default()
        },
    );
    step_until(&mut harness, "the numbers of 62.5 s", |harness| {
        harness.query_by_label("2.5 s late (was 60.0 s)").is_some()
    });
    harness.get_by_label("3.0 m");
    harness.get_by_label("8.5 s late at the plan's speed");
    assert!(
        harness.query_by_label("5.0 m").is_none(),
        "the old distance is gone"
    );

    // Between legs the run gives no numbers, and the view shows none.
    *run.lock().unwrap() = status(63.0, MissionStatus::default());
    step_until(&mut harness, "no leg driven", |harness| {
        harness.query_by_label("3.0 m").is_none()
    });
    assert!(
        harness
            .query_by_label("Leg 1/4 `advance`, from `home` to `gate`")
            .is_none()
    );
}

/// Leg `advance` is late, and the plan's `<contingency on="late" do="repair" after_secs="8"/>`
/// applies option 1 at 20 s unless the operator chooses first (the words are `armor run`'s).
fn advance_late(default_at_run_secs: Option<f64>) -> Repair {
    Repair {
        run_secs: 12.0,
        leg: "advance".to_owned(),
        why: "leg `advance` is late (due by 08:00:10): its deadline passed before it arrived, \
              it holds in `advance_hold`"
            .to_owned(),
        options: vec![RepairOption {
            number: 1,
            kind: RepairKind::PushBack,
            summary: "push the deadline back to 08:00:26, when the robot is now expected at \
                      `gate` with a fifth of the drive to spare"
                .to_owned(),
            distance_m: 46.7,
            duration_secs: Some(166.0),
            ..RepairOption::default()
        }],
        default_option: Some(1),
        default_at_run_secs,
    }
}

#[test]
fn the_repair_card_counts_down_to_the_default_applied_by_itself() {
    let dir = tempfile::tempdir().unwrap();
    let repaired = |run_secs: f64| {
        status(
            run_secs,
            MissionStatus {
                repair: Some(advance_late(Some(20.0))),
                ..MissionStatus::default()
            },
        )
    };
    let (control, run) = stand_in_run(repaired(12.0));
    let mut harness = attached(dir.path(), control);
    harness.get_by_label("Leg `advance` cannot be completed");
    harness.get_by_label("Option 1 applies by itself in 8 s, unless you choose first.");

    // The run's time goes on: the card counts down with it (rounded up: 4.2 s left is "5 s").
    *run.lock().unwrap() = repaired(15.8);
    step_until(&mut harness, "the countdown at 15.8 s", |harness| {
        harness
            .query_by_label("Option 1 applies by itself in 5 s, unless you choose first.")
            .is_some()
    });
    assert!(
        harness
            .query_by_label("Option 1 applies by itself in 8 s, unless you choose first.")
            .is_none()
    );

    // Its time has come: the run is about to apply it.
    *run.lock().unwrap() = repaired(20.1);
    step_until(&mut harness, "the default's time", |harness| {
        harness
            .query_by_label("Option 1 applies by itself now.")
            .is_some()
    });

    // A default applied at once (no `after_secs`) is said as before, with no countdown.
    *run.lock().unwrap() = status(
        21.0,
        MissionStatus {
            repair: Some(advance_late(None)),
            ..MissionStatus::default()
        },
    );
    step_until(&mut harness, "a default with no time", |harness| {
        harness
            .query_by_label("The plan applies option 1 by itself.")
            .is_some()
    });
}
