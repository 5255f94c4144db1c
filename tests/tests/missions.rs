//! Every example under `missions/` (systems, missions and plans) is valid: against the shipped XSDs
//! (checked by xmllint, an independent reader) and by `armor check` against the real module
//! binaries.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};
use std::process::Command;

use armor_tests::{bin, workspace_root};

/// Every example file with the given top element.
fn examples(top: &str) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut folders = vec![workspace_root().join("missions")];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                folders.push(path);
            } else if path.extension().is_some_and(|ext| ext == "xml")
                && std::fs::read_to_string(&path)
                    .unwrap()
                    .contains(&format!("<{top} "))
            {
                files.push(path);
            }
        }
    }
    assert!(!files.is_empty(), "no example {top} files found");
    files
}

fn xmllint(schema: &str, file: &Path) -> std::process::Output {
    Command::new(armor_tests::tools::program("xmllint"))
        .args(["--noout", "--schema"])
        .arg(workspace_root().join("assets/schema").join(schema))
        .arg(file)
        .output()
        .unwrap_or_else(|err| panic!("cannot run xmllint: {err}"))
}

#[test]
fn examples_validate_against_the_schema() {
    for (top, schema) in [
        ("system", "system.xsd"),
        ("mission", "mission.xsd"),
        ("plan", "plan.xsd"),
    ] {
        for file in examples(top) {
            let output = xmllint(schema, &file);
            assert!(
                output.status.success(),
                "{}: {}",
                file.display(),
                String::from_utf8_lossy(&output.stderr)
            );
        }
    }
}

#[test]
fn the_schema_refuses_what_the_loader_refuses() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [
        ("unknown-element", r#"<system name="s"><robot/></system>"#),
        (
            "bad-restart",
            r#"<system name="s"><module name="a" type="t" restart="sometimes"/></system>"#,
        ),
        (
            "bad-endpoint",
            r#"<system name="s"><link from="a" to="b.c"/></system>"#,
        ),
    ] {
        let file = dir.path().join(format!("{name}.xml"));
        std::fs::write(&file, text).unwrap();
        assert!(
            !xmllint("system.xsd", &file).status.success(),
            "{name} should fail the schema"
        );
        let check = Command::new(bin("armor"))
            .arg("check")
            .arg(&file)
            .output()
            .unwrap();
        assert_eq!(
            check.status.code(),
            Some(1),
            "{name} should fail armor check"
        );
    }
}

#[test]
fn the_plan_schema_refuses_what_the_plan_reader_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let system = workspace_root().join("missions/robot/system.xml");
    let plan = |body: &str| {
        format!(
            r#"<plan name="p" system="{}">
  <waypoint name="a" lat="43.561536" lon="1.4690496"/>
  {body}
</plan>"#,
            system.display()
        )
    };
    // The problem's line: the waypoints and leg are on line 3, the area on line 4.
    for (name, says, line, text) in [
        (
            "leg-without-to",
            "`to`",
            3,
            plan(r#"<waypoint name="b" lat="43.561536" lon="1.4691986"/><leg from="a"/>"#),
        ),
        (
            "latitude-not-a-number",
            "`north`",
            3,
            plan(r#"<waypoint name="b" lat="north" lon="1.4691986"/><leg from="a" to="b"/>"#),
        ),
        (
            "unknown-area-kind",
            "`lava`",
            4,
            plan(
                r#"<waypoint name="b" lat="43.561536" lon="1.4691986"/><leg from="a" to="b"/>
  <area name="x" kind="lava"><point lat="43.5615" lon="1.4692"/><point lat="43.5616" lon="1.4692"/><point lat="43.5616" lon="1.4693"/></area>"#,
            ),
        ),
    ] {
        let file = dir.path().join(format!("{name}.xml"));
        std::fs::write(&file, text).unwrap();
        assert!(
            !xmllint("plan.xsd", &file).status.success(),
            "{name} should fail the schema"
        );
        let check = Command::new(bin("armor"))
            .arg("check")
            .arg(&file)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir())
            .output()
            .unwrap();
        let out = String::from_utf8_lossy(&check.stdout);
        assert_eq!(
            check.status.code(),
            Some(1),
            "{name} should fail armor check: {out}"
        );
        assert!(
            out.contains(&format!("{}:{line}:", file.display())) && out.contains(says),
            "{name}: {out}"
        );
    }
}

#[test]
fn examples_pass_armor_check() {
    for file in examples("system")
        .into_iter()
        .chain(examples("mission"))
        .chain(examples("plan"))
    {
        let output = Command::new(bin("armor"))
            .arg("check")
            .arg(&file)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir())
            .output()
            .unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stdout)
        );
    }
}
