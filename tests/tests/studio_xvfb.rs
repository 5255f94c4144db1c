//! The studio in a real X window (Xvfb), driven with the mouse and keyboard through xdotool as a
//! person would: it opens a system file given on its command line, duplicates the blocks,
//! saves under a path typed into the path field, and the saved file passes the real
//! `armor check`; the Run view starts the system with F5 and stops it with Shift+F5. Needs Debian's `xvfb` and `xdotool` (installed by `.ci/run`). Xvfb is started
//! directly rather than through `xvfb-run`, so that the guard kills the server itself.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::Command;
use std::time::Duration;

use armor_tests::{PATIENCE, Proc, bin, bin_dir, wait_until};

const SYSTEM: &str = r#"<system name="demo">
  <module name="counter" type="counter">
    <param name="period_secs" value="0.1"/>
  </module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

/// Runs xdotool on the display; true if it succeeded.
fn xdotool(display: &str, args: &[&str]) -> bool {
    Command::new("xdotool")
        .args(args)
        .env("DISPLAY", display)
        .output()
        .map(|out| out.status.success())
        .unwrap_or(false)
}

fn window(display: &str) -> Option<String> {
    let out = Command::new("xdotool")
        .args(["search", "--name", "ArMoR Studio"])
        .env("DISPLAY", display)
        .output()
        .ok()?;
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines().next().map(str::to_owned)
}

/// Sends keys until the studio says (in its log) that they did what they should: the first keys
/// after a window appears can be lost while X gives it the focus.
fn keys_until(studio: &Proc, display: &str, window: &str, keys: &[&str], said: &str) {
    let before = studio.line_count();
    for _ in 0..10 {
        // A window not yet mapped cannot take the focus: try again.
        if !xdotool(display, &["windowfocus", "--sync", window]) {
            wait_until_or(Duration::from_millis(200), || false);
            continue;
        }
        for key in keys {
            assert!(xdotool(display, &["key", "--window", window, key]));
        }
        let mut seen = false;
        wait_until_or(Duration::from_secs(2), || {
            seen = studio.lines()[before..]
                .iter()
                .any(|line| line.contains(said));
            seen
        });
        if seen {
            return;
        }
    }
    panic!(
        "the studio never said `{said}`:\n{}",
        studio.lines().join("\n")
    );
}

/// Like `wait_until`, but gives up quietly at the deadline.
fn wait_until_or(timeout: Duration, mut condition: impl FnMut() -> bool) {
    let deadline = std::time::Instant::now() + timeout;
    while !condition() && std::time::Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A studio in its own X server: the server, the studio, the display and the window.
struct Session {
    _xvfb: Proc,
    studio: Proc,
    display: String,
    window: String,
}

/// Starts Xvfb and the studio on `file`, and waits for its window.
fn start(dir: &Path, file: &Path) -> Session {
    for tool in ["Xvfb", "xdotool"] {
        assert!(
            Command::new("sh")
                .args(["-c", &format!("command -v {tool}")])
                .output()
                .is_ok_and(|out| out.status.success()),
            "{tool} is not installed: run .ci/run, or apt-get install xvfb xdotool"
        );
    }
    // Xvfb picks a free display and writes its number on stdout.
    let xvfb = Proc::start(Command::new("Xvfb").args([
        "-displayfd",
        "1",
        "-screen",
        "0",
        "1280x800x24",
        "-nolisten",
        "tcp",
    ]));
    let number = xvfb.wait_for("the display number", PATIENCE, |line| {
        !line.is_empty() && line.bytes().all(|b| b.is_ascii_digit())
    });
    let display = format!(":{}", number.trim());

    let studio = Proc::start(
        Command::new(bin("armor-studio"))
            .arg(file)
            .env("DISPLAY", &display)
            .env_remove("WAYLAND_DISPLAY")
            .env("ARMOR_STUDIO_HOME", dir.join("home"))
            .env("ARMOR_MODULE_PATH", bin_dir())
            .env("RUST_LOG", "armor_studio=info"),
    );
    studio.wait_for("the first frame", Duration::from_secs(60), |line| {
        line.contains("window ready")
    });
    let mut found = None;
    wait_until("the studio's window", PATIENCE, || {
        found = window(&display);
        found.is_some()
    });
    Session {
        _xvfb: xvfb,
        studio,
        display,
        window: found.unwrap(),
    }
}

/// Save as: the path typed into the path field replaces the one it offers.
fn save_as(session: &Session, saved: &Path) {
    let Session {
        studio,
        display,
        window,
        ..
    } = session;
    keys_until(studio, display, window, &["ctrl+shift+s"], "type a path");
    assert!(xdotool(display, &["key", "--window", window, "ctrl+a"]));
    assert!(xdotool(
        display,
        &["type", "--window", window, &saved.display().to_string()]
    ));
    keys_until(studio, display, window, &["Return"], "saved ");
    wait_until("the saved file", PATIENCE, || saved.exists());
}

#[test]
fn the_studio_edits_and_saves_a_file_with_mouse_and_keyboard() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("demo.xml");
    std::fs::write(&file, SYSTEM).unwrap();
    let saved = dir.path().join("edited.xml");
    let session = start(dir.path(), &file);
    let Session {
        studio,
        display,
        window,
        ..
    } = &session;

    // A click on the empty canvas, then select all and duplicate from the keyboard.
    assert!(xdotool(
        display,
        &["mousemove", "--sync", "700", "650", "click", "1"]
    ));
    keys_until(
        studio,
        display,
        window,
        &["ctrl+a", "ctrl+d"],
        "pasted 2 blocks",
    );

    save_as(&session, &saved);

    let text = std::fs::read_to_string(&saved).unwrap();
    for expected in [
        r#"<module name="counter_2" type="counter""#,
        r#"<module name="checker_2" type="checker""#,
        r#"<link from="counter_2.count" to="checker_2.input"/>"#,
    ] {
        assert!(text.contains(expected), "{expected} not in:\n{text}");
    }
    check(&saved);
}

#[test]
fn the_mission_view_adds_waypoints_with_the_mouse_and_saves_the_plan() {
    let dir = tempfile::tempdir().unwrap();
    let plan = armor_tests::workspace_root().join("missions/robot/plan-yard.xml");
    let before = armor_model::plan::Plan::parse(&std::fs::read_to_string(&plan).unwrap()).unwrap();
    let saved = dir.path().join("yard-more.xml");
    // A plan opens in the Mission view, fitted to the yard (40 m × 30 m) in the map, which
    // takes the window but for the inspector on the right and the net below.
    let session = start(dir.path(), &plan);
    let Session {
        studio,
        display,
        window,
        ..
    } = &session;
    studio.wait_for("the plan", PATIENCE, |line| line.contains("opened "));
    keys_until(studio, display, window, &["w"], "waypoint tool");
    // Two clicks in the yard's open south-west: each adds a waypoint at the route's end.
    for (x, y, said) in [("380", "390", "added `wp1`"), ("300", "430", "added `wp2`")] {
        let lines = studio.line_count();
        assert!(xdotool(
            display,
            &["mousemove", "--sync", x, y, "click", "1"]
        ));
        studio.wait_for(said, PATIENCE, |line| line.contains(said));
        assert!(studio.line_count() > lines);
    }
    save_as(&session, &saved);
    let after = armor_model::plan::Plan::parse(&std::fs::read_to_string(&saved).unwrap()).unwrap();
    assert_eq!(after.waypoints.len(), before.waypoints.len() + 2);
    assert_eq!(after.legs.len(), before.legs.len() + 2);
    assert_eq!(after.legs.last().unwrap().to, "wp2");
    check(&saved);
}

#[test]
fn the_run_view_starts_and_stops_a_run_from_the_keyboard() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("demo.xml");
    std::fs::write(&file, SYSTEM).unwrap();
    let session = start(dir.path(), &file);
    let Session {
        studio,
        display,
        window,
        ..
    } = &session;
    // F5 runs the open system with `armor run`, a child of the studio, and its modules under it.
    keys_until(studio, display, window, &["F5"], "running ");
    let modules = || -> Vec<i32> {
        armor_tests::children_of(studio.pid())
            .into_iter()
            .flat_map(armor_tests::children_of)
            .filter(|pid| {
                std::fs::read_to_string(format!("/proc/{pid}/comm"))
                    .is_ok_and(|comm| comm.starts_with("armor-mod-"))
            })
            .collect()
    };
    wait_until("the run's two modules", PATIENCE, || modules().len() == 2);
    let running = modules();
    // Shift+F5 stops it: every module ends, then the run.
    keys_until(studio, display, window, &["shift+F5"], "the run ended");
    wait_until("the modules to end", PATIENCE, || {
        running.iter().all(|pid| !armor_tests::process_alive(*pid))
    });
    wait_until("the run to end", PATIENCE, || {
        armor_tests::children_of(studio.pid()).is_empty()
    });
}

/// The real `armor check` accepts the file.
fn check(file: &Path) {
    let out = Command::new(bin("armor"))
        .arg("check")
        .arg(file)
        .env("ARMOR_MODULE_PATH", bin_dir())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "armor check failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}
