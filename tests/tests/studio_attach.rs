//! The studio attached to a run started elsewhere (`armor-studio --attach ADDR`, Run →
//! Attach…), driven through egui_kittest: it follows the run through its control interface,
//! pauses and resumes the mission with the same buttons as a run of its own, detaches without
//! stopping it, attaches again through the menu's prompt, and shows a lost connection.
#![allow(clippy::unwrap_used)]

use std::process::Command;
use std::time::{Duration, Instant};

use armor_runtime::control::Status;
use armor_studio::app::View;
use armor_studio::files::Home;
use armor_studio::palette::Palette;
use armor_studio::{Options, StudioApp};
use armor_tests::{PATIENCE, Proc, bin, bin_dir, ctl_status, process_alive};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT as _, Queryable as _};

/// A mission that waits for the operator: it runs until the test is done with it.
const MISSION: &str = r#"<mission name="waits" system="system.xml">
  <place name="counting" tokens="1">
    <module name="counter"/>
    <module name="checker"/>
  </place>
  <place name="done" final="true"/>
  <transition name="finish" operator="true">
    <input place="counting"/>
    <output place="done"/>
  </transition>
</mission>
"#;

const SYSTEM: &str = r#"<system name="demo">
  <module name="counter" type="counter">
    <param name="period_secs" value="0.1"/>
  </module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

/// `armor run` of the waiting mission in a terminal of its own, and its control address.
fn run_elsewhere(dir: &std::path::Path) -> (Proc, std::net::SocketAddr) {
    std::fs::write(dir.join("system.xml"), SYSTEM).unwrap();
    std::fs::write(dir.join("mission.xml"), MISSION).unwrap();
    let run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(dir.join("mission.xml"))
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let line = run.wait_for("with its control address", PATIENCE, |line| {
        line.starts_with(armor_runtime::CONTROL_READY_PREFIX)
    });
    let addr = line
        .trim_start_matches(armor_runtime::CONTROL_READY_PREFIX)
        .trim()
        .parse()
        .unwrap();
    (run, addr)
}

fn harness(dir: &std::path::Path, attach: std::net::SocketAddr) -> Harness<'static, StudioApp> {
    let mut options = Options::new(Home::new(dir.join("home")));
    options.module_path = vec![bin_dir()];
    options.palette = Some(Palette::from_descriptions(Vec::new()));
    options.attach = Some(attach);
    let app = StudioApp::new(options);
    let mut harness = Harness::builder()
        .with_size([1500.0, 950.0])
        .with_step_dt(1.0 / 60.0)
        .with_max_steps(8)
        .build_ui_state(|ui, app: &mut StudioApp| app.ui(ui), app);
    harness.run_ok();
    harness
}

fn step_until(
    harness: &mut Harness<'_, StudioApp>,
    what: &str,
    mut done: impl FnMut(&mut Harness<'_, StudioApp>) -> bool,
) {
    let deadline = Instant::now() + PATIENCE;
    loop {
        harness.step();
        if done(harness) {
            // One more frame, drawn with what the condition saw.
            harness.step();
            return;
        }
        assert!(
            Instant::now() < deadline,
            "waited {PATIENCE:?} for {what}; last status: {:#?}",
            harness.state().run().status()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn status(app: &StudioApp) -> Status {
    app.run().status().unwrap_or_default()
}

fn paused(addr: std::net::SocketAddr) -> bool {
    ctl_status(&addr.to_string())["mission"]["paused"]
        .as_bool()
        .unwrap()
}

fn has_label(harness: &Harness<'_, StudioApp>, text: &str) -> bool {
    harness.query_by_label_contains(text).is_some()
}

#[test]
fn the_studio_attaches_pauses_resumes_and_detaches_without_stopping_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let (run, addr) = run_elsewhere(dir.path());
    let mut harness = harness(dir.path(), addr);
    assert_eq!(harness.state().view(), View::Run);
    step_until(&mut harness, "the run's modules and mission", |h| {
        let status = status(h.state());
        status.mission.is_some() && status.modules.len() == 2
    });
    assert!(has_label(&harness, "attached to demo"));

    harness.get_by_label("⏸ Pause").click();
    step_until(&mut harness, "the mission paused", |h| {
        status(h.state())
            .mission
            .is_some_and(|mission| mission.paused)
    });
    assert!(paused(addr), "the run itself is paused");
    harness.get_by_label("⏵ Resume").click();
    step_until(&mut harness, "the mission resumed", |h| {
        status(h.state())
            .mission
            .is_some_and(|mission| !mission.paused)
    });
    assert!(!paused(addr));

    // Detach: the studio stops watching, the run goes on.
    harness.get_by_label("⏏ Detach").click();
    step_until(&mut harness, "the studio detached", |h| {
        !h.state().run().is_running()
    });
    assert!(process_alive(run.pid()), "detaching stopped the run");
    let after = ctl_status(&addr.to_string());
    assert_eq!(after["mission"]["outcome"], serde_json::Value::Null);

    // Run → Attach…: the prompt offers the last address; attach again.
    // The Run menu (the other "Run" is the view's tab, toggled on).
    harness
        .get_all_by_label("Run")
        .find(|node| node.accesskit_node().toggled().is_none())
        .expect("the Run menu")
        .click();
    harness.run_ok();
    harness.get_by_label("Attach…").click();
    harness.run_ok();
    assert!(has_label(&harness, "The run's control address"));
    harness.get_by_label("Attach").click();
    step_until(&mut harness, "attached again", |h| {
        h.state().run().is_running() && status(h.state()).mission.is_some()
    });

    // The run goes away: the studio says the connection is lost, and keeps asking.
    drop(run);
    step_until(&mut harness, "the lost connection shown", |h| {
        has_label(h, "connection lost")
    });
    assert!(harness.state().run().is_running(), "still trying");
}
