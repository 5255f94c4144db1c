//! The `sim` module binary: it describes itself completely, and refuses a bad world file with
//! the file, line and column on stderr.

use std::process::{Command, Output};

use armor_module_api::describe::ModuleDescription;

const SIM: &str = env!("CARGO_BIN_EXE_armor-mod-sim");

fn describe() -> ModuleDescription {
    let output = Command::new(SIM)
        .arg("--describe")
        .output()
        .expect("run the simulator");
    assert!(output.status.success(), "{:?}", output.status);
    let xml = String::from_utf8(output.stdout).expect("UTF-8");
    ModuleDescription::from_xml(&xml).unwrap_or_else(|problems| panic!("{problems:?}\n{xml}"))
}

/// Runs the module standalone (no supervisor; the agent is looked for lazily, so the body runs).
fn run_standalone(params: &[String]) -> Output {
    let mut command = Command::new(SIM);
    command
        .env_remove("ARMOR_SUPERVISOR")
        .env("ARMOR_AGENT", "127.0.0.1:9")
        .env("ARMOR_LOG", "info");
    for param in params {
        command.arg("--param").arg(param);
    }
    command.output().expect("run the simulator")
}

#[test]
fn describes_ports_params_units_and_event() {
    let description = describe();
    assert_eq!(description.module_type, "sim");
    assert_eq!(description.version, env!("CARGO_PKG_VERSION"));
    assert!(!description.doc.is_empty());
    assert!(
        !description.controllable,
        "the world runs whatever the mission does"
    );
    let ports = |ports: &[armor_module_api::describe::PortSpec]| -> Vec<(String, String)> {
        ports
            .iter()
            .map(|port| (port.name.clone(), port.data_type.clone()))
            .collect()
    };
    assert_eq!(
        ports(&description.inputs),
        [("cmd_vel".to_owned(), "Twist".to_owned())]
    );
    assert_eq!(
        ports(&description.outputs),
        [
            ("odometry".to_owned(), "Odometry".to_owned()),
            ("scan".to_owned(), "LaserScan".to_owned()),
            ("pose_truth".to_owned(), "Pose2D".to_owned()),
            ("battery".to_owned(), "Battery".to_owned()),
        ]
    );
    let world = description.param("world").expect("world");
    assert!(world.is_required());
    let expected = [
        ("rate_hz", "Hz", "50"),
        ("laser_rate_hz", "Hz", "10"),
        ("laser_beams", "", "360"),
        ("laser_fov_deg", "deg", "360"),
        ("laser_range_m", "m", "8"),
        ("laser_noise_m", "m", "0.01"),
        ("odom_noise_dist", "m", "0.02"),
        ("odom_noise_rot", "rad", "0.02"),
        ("odom_noise_drift", "rad", "0.005"),
        ("seed", "", "1"),
        ("max_speed_mps", "m/s", "1.0"),
        ("max_turn_radps", "rad/s", "1.5"),
        ("robot_radius_m", "m", "0.25"),
        ("battery_drain_per_m", "", "0.002"),
        ("battery_drain_per_hour", "", "0.1"),
        ("battery_low", "", "0.2"),
        ("battery_start", "", "1"),
    ];
    for (name, unit, default) in expected {
        let param = description
            .param(name)
            .unwrap_or_else(|| panic!("no `{name}`"));
        assert_eq!(param.unit, unit, "{name}");
        assert_eq!(param.default.as_deref(), Some(default), "{name}");
        assert!(!param.doc.is_empty(), "{name}");
    }
    // Besides these: `world`, `obstacles` (shapes the world file does not have) and `kidnap`
    // (the robot carried elsewhere, for testing localisation; never by default).
    let obstacles = description.param("obstacles").expect("obstacles");
    assert!(!obstacles.is_required());
    let kidnap = description.param("kidnap").expect("kidnap");
    assert_eq!(kidnap.default.as_deref(), Some(""));
    assert_eq!(description.params.len(), expected.len() + 3);
    assert!(description.event("collision").is_some());
    assert!(description.event("low_battery").is_some());
}

#[test]
fn a_bad_world_file_is_refused_with_its_place() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("broken.world");
    std::fs::write(
        &path,
        "name broken\norigin 0 0\nstart 2 2 0\nboundary 0,0 10,0 10,10 0,10 0,0\nobstacle 4,4 6,6 6,4 4,6 4,4\n",
    )
    .expect("write");
    let output = run_standalone(&[format!("world={}", path.display())]);
    assert!(!output.status.success(), "{:?}", output.status);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let expected = format!(
        "{}:5:10: the obstacle crosses itself: edge (4, 4)–(6, 6) meets edge (6, 4)–(4, 6)",
        path.display()
    );
    assert!(stderr.contains(&expected), "{stderr}");
}

/// Bad worlds from the issue, each refused by the process with its place and in words: an
/// open polygon, a robot starting inside an obstacle or outside the boundary, a robot too big
/// for its start. Never a panic.
#[test]
fn bad_worlds_and_starts_are_refused_by_the_process_in_words() {
    let dir = tempfile::tempdir().expect("temp dir");
    let room = "boundary 0,0 10,0 10,10 0,10 0,0\nobstacle 4,4 6,4 6,6 4,6 4,4\n";
    for (name, text, params, expected) in [
        (
            "open",
            "name open\norigin 0 0\nstart 2 2 0\nboundary 0,0 10,0 10,10 0,10\n".to_owned(),
            vec![],
            ":4:25: the boundary is not closed: it starts at (0, 0) but ends at (0, 10)",
        ),
        (
            "inside",
            format!("name inside\norigin 0 0\nstart 5 5 0\n{room}"),
            vec![],
            ":3:7: the start pose (5, 5) is inside the obstacle on line 5",
        ),
        (
            "outside",
            format!("name outside\norigin 0 0\nstart 12 5 0\n{room}"),
            vec![],
            ":3:7: the start pose (12, 5) is outside the boundary (line 4)",
        ),
        (
            "touching",
            format!("name touching\norigin 0 0\nstart 3.8 5 0\n{room}"),
            vec!["robot_radius_m=0.5".to_owned()],
            ":3:7: the robot (radius 0.5 m) at the start pose (3.8, 5) overlaps the obstacle on line 5",
        ),
    ] {
        let path = dir.path().join(format!("{name}.world"));
        std::fs::write(&path, text).expect("write");
        let mut args = vec![format!("world={}", path.display())];
        args.extend(params);
        let output = run_standalone(&args);
        assert!(!output.status.success(), "{name}: {:?}", output.status);
        let stderr = String::from_utf8_lossy(&output.stderr);
        let expected = format!("{}{expected}", path.display());
        assert!(stderr.contains(&expected), "{name}: {stderr}");
        assert!(!stderr.contains("panicked"), "{name}: {stderr}");
    }
}

#[test]
fn a_missing_world_file_is_refused() {
    let output = run_standalone(&["world=no/such/place.world".to_owned()]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("world file `no/such/place.world` not found"),
        "{stderr}"
    );
    let output = run_standalone(&[]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(stderr.contains("parameter `world` is required"), "{stderr}");
}
