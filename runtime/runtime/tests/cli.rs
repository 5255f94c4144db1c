//! `armor check` and `armor probe` as a user runs them, against module binaries written as shell
//! scripts (a module can be written in any language: the describe output is the contract).
#![allow(clippy::unwrap_used)]

use std::os::unix::fs::PermissionsExt as _;
use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

const COUNTER_XML: &str = r#"<module type="counter" version="1.0" controllable="true">
  <doc>Counts.</doc>
  <output name="count" type="Counter" doc="the value"/>
  <param name="period_secs" type="float" unit="s" default="0.1" doc="period"/>
</module>"#;

const NAV_XML: &str = r#"<module type="nav" version="1.0">
  <doc>Navigates.</doc>
  <input name="scan" type="LaserScan" doc="laser"/>
  <input name="ticks" type="Counter" doc="ticks"/>
  <param name="goal_x" type="float" unit="m" required="true" doc="goal"/>
</module>"#;

fn script(dir: &Path, name: &str, body: &str) {
    let path = dir.join(name);
    std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
}

fn describing(dir: &Path, module_type: &str, xml: &str) {
    script(
        dir,
        &format!("armor-mod-{module_type}"),
        &format!("[ \"$1\" = --describe ] || exit 2\ncat <<'XML'\n{xml}\nXML"),
    );
}

fn armor(module_path: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_armor"))
        .args(args)
        .env("ARMOR_MODULE_PATH", module_path)
        .output()
        .unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Runs `armor check` on `system` and compares its report line by line (`FILE` stands for the
/// file's path) and its exit status.
fn check(system: &str, expected: &[&str]) {
    let modules = tempfile::tempdir().unwrap();
    describing(modules.path(), "counter", COUNTER_XML);
    describing(modules.path(), "nav", NAV_XML);
    let file = modules.path().join("system.xml");
    std::fs::write(&file, system).unwrap();
    let output = armor(modules.path(), &["check", file.to_str().unwrap()]);
    let stdout = text(&output.stdout).replace(file.to_str().unwrap(), "FILE");
    let got: Vec<&str> = stdout.lines().collect();
    assert_eq!(got, expected, "stderr: {}", text(&output.stderr));
    assert_eq!(
        output.status.code(),
        Some(if expected[0].contains(": ok") { 0 } else { 1 })
    );
}

#[test]
fn check_accepts_a_clean_system() {
    check(
        r#"<system name="s">
  <module name="c" type="counter"><param name="period_secs" value="0.5"/></module>
  <module name="n" type="nav"><param name="goal_x" value="3"/></module>
  <link from="c.count" to="n.ticks"/>
</system>"#,
        &["FILE: ok (system `s`: 2 modules, 1 link)"],
    );
}

#[test]
fn check_reports_every_problem_with_its_place() {
    check(
        r#"<system name="s">
  <module name="c" type="counter"><param name="period_secs" value="soon"/></module>
  <module name="n" type="nav"/>
  <module name="c" type="counter"/>
  <module name="x" type="navigaton"/>
  <link from="c.count" to="n.scan"/>
  <link from="n.scan" to="n.ticks"/>
  <link from="c.count" to="n.scan"/>
</system>"#,
        &[
            "FILE:2:61: module `c`: parameter `period_secs` (float): `soon` is not a finite number",
            "FILE:3:3: module `n`: required parameter `goal_x` is not set",
            "FILE:4:3: module `c` is already defined at line 2",
            "FILE:5:20: module `x`: no module type `navigaton` on the module path (known: counter, nav)",
            "FILE:6:24: module `n`: input `scan` expects LaserScan but `c.count` is Counter",
            "FILE:7:9: link from `n.scan`: `scan` is an input of `n`; a link goes from an output to an input",
            "FILE:8:24: module `n`: input `scan` expects LaserScan but `c.count` is Counter",
            "FILE:8:24: input `n.scan` is already fed by `c.count` (line 6); another source is a fallback (fallback=\"1\", \"2\", …)",
        ],
    );
}

#[test]
fn check_reports_malformed_and_unknown_xml() {
    check(
        "<system name=\"s\">\n  <module name=\"c\" type=\"counter\">\n</system>",
        &[
            "FILE:3:1: malformed XML: ill-formed document: expected `</module>`, but `</system>` was found",
        ],
    );
    check(
        "<system name=\"s\" colour=\"red\">\n  <robot/>\n</system>",
        &[
            "FILE:1:18: unknown attribute `colour` on <system> (expected one of: name, host)",
            "FILE:2:3: unknown element <robot> inside <system> (expected one of: host, module, link, subsystem)",
        ],
    );
}

#[test]
fn check_of_a_missing_file_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let output = armor(dir.path(), &["check", "/nonexistent/system.xml"]);
    assert_eq!(output.status.code(), Some(1));
    assert!(
        text(&output.stdout).starts_with("/nonexistent/system.xml:1:1: cannot read the file:"),
        "{}",
        text(&output.stdout)
    );
}

#[test]
fn probe_isolates_broken_binaries() {
    let modules = tempfile::tempdir().unwrap();
    describing(modules.path(), "counter", COUNTER_XML);
    script(modules.path(), "armor-mod-hang", "sleep 60");
    script(modules.path(), "armor-mod-crash", "echo oops >&2; exit 3");
    script(
        modules.path(),
        "armor-mod-garbage",
        "echo 'this is not xml'",
    );
    script(
        modules.path(),
        "armor-mod-liar",
        "echo '<module type=\"somebody-else\"><doc>x</doc></module>'",
    );
    script(modules.path(), "not-a-module", "exit 0");
    let started = Instant::now();
    let output = armor(
        modules.path(),
        &[
            "probe",
            modules.path().to_str().unwrap(),
            "--timeout-secs",
            "1",
        ],
    );
    let elapsed = started.elapsed();
    assert_eq!(output.status.code(), Some(1));
    let stdout = text(&output.stdout);
    assert!(
        stdout.starts_with("counter 1.0 [other] ("),
        "the good module still answers: {stdout}"
    );
    assert!(
        stdout.contains("  output count: Counter — the value"),
        "{stdout}"
    );
    assert!(
        stdout.contains("  param period_secs: float [s] = 0.1 — period"),
        "{stdout}"
    );
    let dir = modules.path().display();
    let mut errors: Vec<String> = text(&output.stderr).lines().map(str::to_owned).collect();
    errors.sort();
    assert_eq!(
        errors,
        [
            format!("error: {dir}/armor-mod-crash: --describe exited with exit status: 3"),
            format!(
                "error: {dir}/armor-mod-garbage: --describe printed an invalid description: line 1:1: text outside the top-level element"
            ),
            format!("error: {dir}/armor-mod-hang: did not answer --describe within 1.0 s (killed)"),
            format!(
                "error: {dir}/armor-mod-liar: describes itself as type `somebody-else`, but its file name says `liar`"
            ),
        ]
    );
    // Probed in parallel: the hanging binary costs one timeout, not one per binary.
    assert!(elapsed < Duration::from_secs(4), "took {elapsed:?}");
}

#[test]
fn probe_prints_xml_that_reads_back() {
    let modules = tempfile::tempdir().unwrap();
    describing(modules.path(), "nav", NAV_XML);
    let output = armor(modules.path(), &["probe", "--xml"]);
    assert_eq!(output.status.code(), Some(0), "{}", text(&output.stderr));
    let description = armor_module_api::ModuleDescription::from_xml(&text(&output.stdout)).unwrap();
    assert_eq!(description.module_type, "nav");
    assert!(description.param("goal_x").unwrap().is_required());
}

#[test]
fn probe_check_and_run_reuse_the_cached_description_until_the_binary_changes() {
    let modules = tempfile::tempdir().unwrap();
    let cache = tempfile::tempdir().unwrap();
    let runs = modules.path().join("runs");
    let describe = |doc: &str| {
        script(
            modules.path(),
            "armor-mod-counter",
            &format!(
                "[ \"$1\" = --describe ] || exit 2\necho run >> '{}'\ncat <<'XML'\n{}\nXML",
                runs.display(),
                COUNTER_XML.replace("<doc>", &format!("<doc>{doc} "))
            ),
        );
    };
    describe("first");
    let system = modules.path().join("system.xml");
    std::fs::write(
        &system,
        r#"<system name="s"><module name="c" type="counter"/></system>"#,
    )
    .unwrap();
    let armor_cached = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_armor"))
            .args(args)
            .env("ARMOR_MODULE_PATH", modules.path())
            .env("ARMOR_PROBE_CACHE", cache.path())
            .output()
            .unwrap()
    };
    let run_count = || {
        std::fs::read_to_string(&runs)
            .unwrap_or_default()
            .lines()
            .count()
    };
    for args in [
        &["probe"][..],
        &["probe"],
        &["check", system.to_str().unwrap()],
    ] {
        let output = armor_cached(args);
        assert_eq!(output.status.code(), Some(0), "{}", text(&output.stderr));
    }
    assert_eq!(run_count(), 1, "described once, then from the cache");
    // A changed binary (another size) is run again, and its new description is the one used.
    describe("second, longer");
    let output = armor_cached(&["probe"]);
    assert!(
        text(&output.stdout).contains("second, longer"),
        "{}",
        text(&output.stdout)
    );
    assert_eq!(run_count(), 2);
    armor_cached(&["probe", "--no-cache"]);
    assert_eq!(
        run_count(),
        3,
        "--no-cache runs it whatever the cache holds"
    );
}
