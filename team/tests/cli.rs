//! The `armor-team` binary's command line, as a user meets it. Having an integration test also
//! makes `cargo test --workspace` build `armor-team` itself (a package's binaries are built for
//! its integration tests only), which `armor_tests`' team suite runs.

use std::process::{Command, Output};

fn armor_team(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_armor-team"))
        .args(args)
        // A shell's settings must not fill the options in for the test.
        .env_remove("ARMOR_CONTROL")
        .env_remove("ARMOR_SECRET_FILE")
        .output()
        .expect("armor-team runs")
}

fn text(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

#[test]
fn help_names_the_robot_the_station_and_the_capture() {
    let output = armor_team(&["--help"]);
    let said = text(&output);
    assert!(output.status.success(), "{said}");
    for command in ["robot", "station", "capture"] {
        assert!(
            said.lines()
                .any(|line| line.trim_start().starts_with(command)),
            "no `{command}` in:\n{said}"
        );
    }
}

#[test]
fn a_robot_with_no_secret_file_says_which_file_and_stops() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-secret");
    let missing = missing.to_str().unwrap();
    let output = armor_team(&[
        "robot",
        "--name",
        "r1",
        "--control",
        "127.0.0.1:9",
        "--secret",
        missing,
    ]);
    let said = text(&output);
    assert!(!output.status.success(), "{said}");
    assert!(said.contains(missing), "the file is not named:\n{said}");
}

#[test]
fn a_robot_name_that_cannot_be_a_key_is_refused_before_anything_opens() {
    let output = armor_team(&[
        "robot",
        "--name",
        "r1/../r2",
        "--control",
        "127.0.0.1:9",
        "--secret",
        "/nonexistent",
    ]);
    let said = text(&output);
    assert!(!output.status.success(), "{said}");
    assert!(said.contains("cannot name a robot"), "{said}");
}
