//! Parameter ranges are part of the contract (docs/protocol.md, section 5): every bundled module
//! declares them in its `--describe` output, and `armor check` refuses a value outside them with
//! the file, line and column of the value, in a system, a mission's place and a plan's action.
//! The values tried come from each module's own description, not from a list kept here.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::process::{Command, Output};

use armor_module_api::ModuleDescription;
use armor_module_api::describe::{ParamSpec, ParamType};
use armor_tests::{bin, bin_dir, workspace_root};

fn describe(module_type: &str) -> ModuleDescription {
    let out = Command::new(bin(&format!("armor-mod-{module_type}")))
        .arg("--describe")
        .output()
        .unwrap();
    assert!(out.status.success(), "{module_type} --describe failed");
    ModuleDescription::from_xml(&String::from_utf8(out.stdout).unwrap())
        .unwrap_or_else(|problems| panic!("{module_type}: {problems:?}"))
}

/// The bundled module types: every `armor-mod-*` binary next to `armor`.
fn bundled_types() -> Vec<String> {
    let mut types: Vec<String> = std::fs::read_dir(bin_dir())
        .unwrap()
        .filter_map(|entry| {
            let name = entry.ok()?.file_name().into_string().ok()?;
            name.strip_prefix("armor-mod-")
                .filter(|rest| !rest.contains('.') && !rest.contains('-'))
                .map(str::to_owned)
        })
        .collect();
    types.sort();
    types
}

/// A value the parameter refuses, if its declaration limits it.
fn out_of_range(spec: &ParamSpec) -> Option<String> {
    let number = |value: f64| match spec.param_type {
        ParamType::Int => format!("{}", value.floor() as i64),
        _ => format!("{value}"),
    };
    let value = if let Some(low) = spec.min {
        number(if low.inclusive {
            low.value - 1.0
        } else {
            low.value
        })
    } else if let Some(high) = spec.max {
        number(if high.inclusive {
            high.value + 1.0
        } else {
            high.value
        })
    } else if spec.nonzero {
        "0".to_owned()
    } else if !spec.choices.is_empty() {
        "not-a-choice".to_owned()
    } else {
        return None;
    };
    assert!(spec.check_value(&value).is_err(), "{} {value}", spec.name);
    Some(value)
}

/// A value the parameter accepts (its default, or one inside its range).
fn in_range(spec: &ParamSpec) -> String {
    if let Some(default) = &spec.default {
        return default.clone();
    }
    let value = match spec.param_type {
        ParamType::Bool => "true".to_owned(),
        ParamType::String => spec.choices.first().cloned().unwrap_or("x".to_owned()),
        ParamType::Int | ParamType::Float => {
            let low = spec.min.map_or(0.0, |bound| bound.value);
            format!("{}", (low + 1.0).floor())
        }
    };
    assert!(spec.check_value(&value).is_ok(), "{} {value}", spec.name);
    value
}

fn armor_check(file: &Path) -> Output {
    Command::new(bin("armor"))
        .arg("check")
        .arg(file)
        .env("PATH", bin_dir())
        .current_dir(workspace_root())
        .output()
        .unwrap()
}

/// The system file of one module with one parameter set to `value`; the line of that `<param>`.
fn system_with(
    module_type: &str,
    description: &ModuleDescription,
    name: &str,
    value: &str,
) -> (String, usize) {
    let mut xml =
        format!("<system name=\"ranges\">\n  <module name=\"m\" type=\"{module_type}\">\n");
    let mut line = 0;
    for spec in &description.params {
        if spec.name == name {
            line = xml.lines().count() + 1;
            xml.push_str(&format!("    <param name=\"{name}\" value=\"{value}\"/>\n"));
        } else if spec.is_required() {
            xml.push_str(&format!(
                "    <param name=\"{}\" value=\"{}\"/>\n",
                spec.name,
                in_range(spec)
            ));
        }
    }
    xml.push_str("  </module>\n</system>\n");
    (xml, line)
}

#[test]
fn every_bundled_module_declares_ranges_that_armor_check_enforces() {
    let dir = tempfile::tempdir().unwrap();
    let types = bundled_types();
    assert!(types.len() >= 12, "bundled modules: {types:?}");
    let mut tried = 0;
    let mut limited_types = Vec::new();
    for module_type in &types {
        let description = describe(module_type);
        let limited: Vec<&ParamSpec> = description
            .params
            .iter()
            .filter(|spec| spec.is_limited())
            .collect();
        if !limited.is_empty() {
            limited_types.push(module_type.clone());
        }
        for spec in limited {
            let value = out_of_range(spec).unwrap();
            let (xml, line) = system_with(module_type, &description, &spec.name, &value);
            let file = dir.path().join(format!("{module_type}-{}.xml", spec.name));
            std::fs::write(&file, &xml).unwrap();
            let out = armor_check(&file);
            let stderr = String::from_utf8_lossy(&out.stderr);
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                !out.status.success(),
                "{module_type}.{} = {value} passed:\n{xml}",
                spec.name
            );
            let expected = format!("{}:{line}:", file.display());
            let said = format!("{stdout}{stderr}");
            assert!(
                said.lines().any(|l| l.starts_with(&expected)
                    && l.contains(&format!("parameter `{}`", spec.name))
                    && l.contains(&format!("`{value}` is not {}", spec.range_text()))),
                "{module_type}.{} = {value}: expected a problem at {expected}, got:\n{said}",
                spec.name
            );
            tried += 1;
        }
    }
    // Every module with a numeric setting declares its range (echo has no parameters; sink,
    // checker and counter count, the robot modules measure).
    for module_type in [
        "avoider", "checker", "counter", "follower", "mapper", "mux", "observer", "recorder",
        "sim", "sink", "teleop",
    ] {
        assert!(
            limited_types.iter().any(|t| t == module_type),
            "{module_type} declares no range"
        );
    }
    assert!(tried >= 40, "only {tried} limited parameters");
    eprintln!(
        "{tried} out-of-range values refused across {} module types",
        limited_types.len()
    );
}

#[test]
fn a_value_inside_the_range_passes_armor_check() {
    let dir = tempfile::tempdir().unwrap();
    let description = describe("observer");
    let (xml, _) = system_with("observer", &description, "sector_deg", "90");
    let file = dir.path().join("ok.xml");
    std::fs::write(&file, xml).unwrap();
    let out = armor_check(&file);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_place_parameter_out_of_range_fails_armor_check_in_a_mission_and_in_a_plan() {
    let dir = tempfile::tempdir().unwrap();
    let system = workspace_root().join("missions/robot/system.xml");
    let mission = dir.path().join("mission.xml");
    std::fs::write(
        &mission,
        format!(
            "<mission name=\"m\" system=\"{}\">\n  <place name=\"look\" tokens=\"1\">\n    <module name=\"observer\"/>\n    <param module=\"observer\" name=\"sector_deg\" value=\"-5\"/>\n  </place>\n  <place name=\"done\" final=\"true\"/>\n  <transition name=\"seen\" event=\"observer.observation_done\">\n    <input place=\"look\"/>\n    <output place=\"done\"/>\n  </transition>\n</mission>\n",
            system.display()
        ),
    )
    .unwrap();
    let out = armor_check(&mission);
    let said =
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "{said}");
    assert!(
        said.contains(&format!("{}:4:", mission.display()))
            && said.contains("`-5` is not greater than 0°"),
        "{said}"
    );

    // The bundled yard plan with the observer's sector made negative.
    let yard =
        std::fs::read_to_string(workspace_root().join("missions/robot/plan-yard.xml")).unwrap();
    let line = yard
        .lines()
        .position(|l| l.contains("name=\"sector_deg\""))
        .unwrap()
        + 1;
    let plan = dir.path().join("plan.xml");
    let changed = yard
        .replace(
            "system=\"system.xml\"",
            &format!("system=\"{}\"", system.display()),
        )
        .replace(
            "name=\"sector_deg\" value=\"360\"",
            "name=\"sector_deg\" value=\"-5\"",
        );
    std::fs::write(&plan, changed).unwrap();
    let out = armor_check(&plan);
    let said =
        String::from_utf8_lossy(&out.stderr).into_owned() + &String::from_utf8_lossy(&out.stdout);
    assert!(!out.status.success(), "{said}");
    assert!(
        said.contains(&format!("{}:{line}:", plan.display()))
            && said.contains("`-5` is not greater than 0°"),
        "{said}"
    );
}

#[test]
fn armor_probe_shows_the_category_and_the_ranges() {
    let out = Command::new(bin("armor"))
        .args(["probe", "--no-cache"])
        .arg(bin("armor-mod-observer"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(text.starts_with("observer 0.1.0 [navigation] "), "{text}");
    assert!(
        text.contains("param sector_deg: float [deg] = 360 (greater than 0°)"),
        "{text}"
    );
    assert!(text.contains("(non-zero)"), "{text}");
}
