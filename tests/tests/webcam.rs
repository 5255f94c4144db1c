//! The webcam module without a camera, as on these machines: under `armor run`, a device that
//! is not there, or a file that is no camera, is a clear error in the log and a normal end,
//! which the supervisor does not restart; the rest of the system runs on.
#![allow(clippy::unwrap_used)]

use std::process::Command;

use armor_tests::{PATIENCE, Proc, bin, bin_dir, field};

fn system(device: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="no-camera">
  <module name="front" type="webcam">
    <param name="device" value="{device}"/>
  </module>
  <module name="counter" type="counter">
    <param name="period_secs" value="0.05"/>
  </module>
  <module name="checker" type="checker">
    <param name="report_every" value="20"/>
  </module>
  <link from="counter.count" to="checker.input"/>
</system>
"#
    )
}

#[test]
fn no_camera_is_a_clear_error_and_a_normal_end_not_a_crash_loop() {
    for (device, error) in [
        (
            "/nonexistent/video7",
            "no camera at /nonexistent/video7: No such file",
        ),
        ("/dev/null", "/dev/null is not a V4L2 device"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("system.xml");
        std::fs::write(&file, system(device)).unwrap();
        let run = Proc::start(
            Command::new(bin("armor"))
                .arg("run")
                .arg(&file)
                .env("ARMOR_MODULE_PATH", bin_dir()),
        );
        let said = run.wait_for("with the webcam's error", PATIENCE, |line| {
            line.starts_with("[front]") && line.contains(error)
        });
        assert!(said.contains("not restarted"), "{said}");
        run.wait_for("saying the webcam finished", PATIENCE, |line| {
            line.contains("module finished") && field(line, "module") == Some("front")
        });
        // The rest runs on, well past the restarts a crash loop would have made by then.
        let skip = run.line_count();
        run.wait_for_from(
            skip,
            "with 40 more values at the checker",
            PATIENCE,
            |line| line.starts_with("[checker]") && line.contains("received 60 values"),
        );
        let lines = run.lines();
        let starts = lines
            .iter()
            .filter(|line| {
                line.contains("module started") && field(line, "module") == Some("front")
            })
            .count();
        assert_eq!(
            starts,
            1,
            "started once, never again:\n{}",
            lines.join("\n")
        );
        assert!(
            !lines
                .iter()
                .any(|line| line.contains("restarting") && line.contains("front")),
            "{}",
            lines.join("\n")
        );
    }
}
