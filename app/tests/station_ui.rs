//! The operator station's view on its own, fed as `armor-team station --json` feeds it: every
//! robot in the table with its state, leg, localisation, report age, link and camera; a robot not heard
//! from shown with its last known state; an operator's Pause sent to the robot chosen; an
//! observer's commands greyed with the reason, and nothing sent.
#![allow(clippy::unwrap_used)]

use std::sync::mpsc::{Receiver, Sender};

use armor_protocol::team::{
    CameraSeen, LinkQuality, RobotReport, RobotStatus, RoutePoint, StationEvent,
};
use armor_studio::station::{FromStation, Link, OBSERVER_CANNOT, StationView};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};

fn report(robot: &str, state: &str, age_secs: f64, received: u64) -> RobotReport {
    RobotReport {
        robot: robot.into(),
        session: true,
        status: Some(RobotStatus {
            robot: robot.into(),
            state: state.into(),
            leg: Some("cross".into()),
            localisation: Some("localised".into()),
            ..RobotStatus::default()
        }),
        refusal: None,
        pose: Some([2.0, 3.0, 0.5]),
        route: vec![
            RoutePoint {
                name: "a".into(),
                x_m: 0.0,
                y_m: 0.0,
            },
            RoutePoint {
                name: "b".into(),
                x_m: 10.0,
                y_m: 5.0,
            },
        ],
        report_age_secs: Some(age_secs),
        kbit_per_sec: 7.9,
        link: LinkQuality { received, sent: 20 },
        camera: (robot == "r1").then(|| CameraSeen {
            name: "camera.image".into(),
            frames_per_sec: 2.0,
            kbit_per_sec: 331.4,
            frame_bytes: 20_000,
        }),
    }
}

fn station(
    role: &str,
) -> (
    Harness<'static, StationView>,
    Sender<FromStation>,
    Receiver<String>,
) {
    let (link, events, commands) = Link::pair();
    let send = |event| events.send(FromStation::Event(event)).unwrap();
    send(StationEvent::Station {
        role: role.into(),
        robots: vec!["r1".into(), "r2".into()],
    });
    send(StationEvent::Robot(Box::new(report(
        "r1", "running", 0.3, 20,
    ))));
    send(StationEvent::Robot(Box::new(report(
        "r2", "holding", 6.5, 15,
    ))));
    let mut harness = Harness::builder()
        .with_size([1280.0, 800.0])
        .build_ui_state(
            |ui, view: &mut StationView| view.ui(ui),
            StationView::new(link),
        );
    // The view asks to be drawn again every 250 ms (the ages move): a few frames, not `run`.
    for _ in 0..3 {
        harness.step();
    }
    (harness, events, commands)
}

#[test]
fn every_robot_is_listed_with_its_state_and_link() {
    let (harness, _events, _commands) = station("operator");
    harness.get_by_label("r1");
    harness.get_by_label("r2");
    harness.get_by_label("running");
    // Not heard from in 6.5 s: its last known state, and its link lost.
    harness.get_by_label("last known: holding");
    harness.get_by_label("0.3 s ago");
    harness.get_by_label("good, loss 0 %");
    harness.get_by_label("lost, loss 25 %");
    assert_eq!(harness.get_all_by_label("localised").count(), 2);
    // r1's camera at its rate; r2 has none.
    harness.get_by_label("2.0/s, 331 kbit/s");
    assert!(harness.query_by_label(OBSERVER_CANNOT).is_none());
}

#[test]
fn an_operator_pauses_the_robot_chosen() {
    let (mut harness, _events, commands) = station("operator");
    harness.get_by_label("r2").click();
    harness.step();
    harness.get_by_label("Pause").click();
    harness.step();
    assert_eq!(commands.try_recv().unwrap(), "r2 pause");
    harness.get_by_label("r2 pause: sent");
}

#[test]
fn an_observer_cannot_command_and_is_told_why() {
    let (mut harness, events, commands) = station("observer");
    harness.get_by_label(OBSERVER_CANNOT);
    for label in ["Pause", "Resume", "Abort", "Status"] {
        assert!(
            harness.get_by_label(label).accesskit_node().is_disabled(),
            "{label} is not greyed"
        );
    }
    harness.get_by_label("Pause").click();
    harness.step();
    assert!(commands.try_recv().is_err(), "an observer's click was sent");
    // A refusal the robot sent (an observer's command typed on the program's terminal) is
    // shown in words.
    events
        .send(FromStation::Event(StationEvent::Answer {
            robot: "r1".into(),
            command: "r1 resume".into(),
            ok: false,
            message: "refused: the observer role may not command this robot".into(),
        }))
        .unwrap();
    harness.step();
    harness.get_by_label("r1 resume: r1: refused: the observer role may not command this robot");
}
