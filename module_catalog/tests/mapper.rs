//! The mapper binary describes itself: ports, parameters and defaults.

use std::process::Command;

use armor_module_api::describe::ModuleDescription;

fn describe() -> ModuleDescription {
    let output = Command::new(env!("CARGO_BIN_EXE_armor-mod-mapper"))
        .arg("--describe")
        .output()
        .expect("run the mapper");
    assert!(output.status.success(), "{:?}", output.status);
    let xml = String::from_utf8(output.stdout).expect("UTF-8");
    ModuleDescription::from_xml(&xml).unwrap_or_else(|problems| panic!("{problems:?}\n{xml}"))
}

fn ports(ports: &[armor_module_api::describe::PortSpec]) -> Vec<(&str, &str)> {
    ports
        .iter()
        .map(|port| (port.name.as_str(), port.data_type.as_str()))
        .collect()
}

#[test]
fn the_mapper_describes_its_ports_and_params() {
    let description = describe();
    assert_eq!(description.module_type, "mapper");
    assert_eq!(description.version, env!("CARGO_PKG_VERSION"));
    assert!(
        !description.controllable,
        "the pose it publishes is needed in every state"
    );
    assert_eq!(
        ports(&description.inputs),
        [("scan", "LaserScan"), ("odometry", "Odometry")]
    );
    assert_eq!(
        ports(&description.outputs),
        [
            ("map", "OccupancyGrid"),
            ("pose", "Odometry"),
            ("pose_map", "Pose2D"),
            ("estimate", "PoseEstimate"),
            ("markers", "Markers"),
        ]
    );
    for (name, unit, default) in [
        ("resolution_m", "m", "0.1"),
        ("size_m", "m", "60"),
        ("match_search_m", "m", "0.3"),
        ("match_search_deg", "deg", "10"),
        ("max_range_m", "m", "7.5"),
        ("map_rate_hz", "Hz", "1"),
        ("keyframe_m", "m", "1"),
        ("keyframe_deg", "deg", "30"),
    ] {
        let param = description.param(name).unwrap_or_else(|| panic!("{name}"));
        assert_eq!(param.unit, unit, "{name}");
        assert_eq!(param.default.as_deref(), Some(default), "{name}");
    }
    let loop_closure = description.param("loop_closure").expect("loop_closure");
    assert_eq!(
        loop_closure.default.as_deref(),
        Some("true"),
        "on by default"
    );
}

#[test]
fn the_mapper_refuses_an_unknown_argument() {
    let output = Command::new(env!("CARGO_BIN_EXE_armor-mod-mapper"))
        .arg("--no-such-option")
        .output()
        .expect("run the mapper");
    assert_eq!(output.status.code(), Some(2));
}
