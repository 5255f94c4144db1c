//! Each module binary describes itself with `--describe` and refuses unknown arguments.

use std::process::Command;

use armor_module_api::describe::ModuleDescription;

/// (binary, type, inputs, outputs) with ports as (name, data type).
type Expected = (
    &'static str,
    &'static str,
    &'static [(&'static str, &'static str)],
    &'static [(&'static str, &'static str)],
);

const MODULES: &[Expected] = &[
    (
        env!("CARGO_BIN_EXE_armor-mod-counter"),
        "counter",
        &[],
        &[("count", "Counter")],
    ),
    (
        env!("CARGO_BIN_EXE_armor-mod-checker"),
        "checker",
        &[("input", "Counter")],
        &[("received", "Counter")],
    ),
    (
        env!("CARGO_BIN_EXE_armor-mod-echo"),
        "echo",
        &[("input", "Blob")],
        &[("output", "Blob")],
    ),
    (
        env!("CARGO_BIN_EXE_armor-mod-sink"),
        "sink",
        &[("input", "Blob")],
        &[("count", "Counter")],
    ),
];

fn ports(ports: &[armor_module_api::describe::PortSpec]) -> Vec<(&str, &str)> {
    ports
        .iter()
        .map(|port| (port.name.as_str(), port.data_type.as_str()))
        .collect()
}

#[test]
fn every_module_describes_itself() {
    for (binary, module_type, inputs, outputs) in MODULES {
        let output = Command::new(binary)
            .arg("--describe")
            .output()
            .expect("run the module");
        assert!(output.status.success(), "{binary}: {:?}", output.status);
        let xml = String::from_utf8(output.stdout).expect("UTF-8");
        let description = ModuleDescription::from_xml(&xml)
            .unwrap_or_else(|problems| panic!("{binary}: {problems:?}\n{xml}"));
        assert_eq!(description.module_type, *module_type);
        assert_eq!(description.version, env!("CARGO_PKG_VERSION"));
        assert!(description.controllable);
        assert_eq!(ports(&description.inputs), *inputs, "{binary}");
        assert_eq!(ports(&description.outputs), *outputs, "{binary}");
    }
}

#[test]
fn the_counter_declares_its_params_and_event() {
    let output = Command::new(MODULES[0].0)
        .arg("--describe")
        .output()
        .expect("run the counter");
    let description =
        ModuleDescription::from_xml(&String::from_utf8_lossy(&output.stdout)).expect("valid");
    let period = description.param("period_secs").expect("period_secs");
    assert_eq!(period.unit, "s");
    assert_eq!(period.default.as_deref(), Some("0.1"));
    assert_eq!(
        description
            .param("limit")
            .and_then(|p| p.default.as_deref()),
        Some("0")
    );
    assert!(description.event("done").is_some());
}

#[test]
fn an_unknown_argument_is_a_usage_error() {
    for (binary, ..) in MODULES {
        let output = Command::new(binary)
            .arg("--no-such-option")
            .output()
            .expect("run the module");
        assert_eq!(output.status.code(), Some(2), "{binary}");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(stderr.contains("unknown argument"), "{binary}: {stderr}");
    }
}
