//! The robot modules' binaries: each describes itself, and `teleop`, run standalone, serves its
//! line protocol on TCP.

use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use armor_module_api::describe::{ModuleDescription, PortSpec};

const FOLLOWER: &str = env!("CARGO_BIN_EXE_armor-mod-follower");
const LOCALISER: &str = env!("CARGO_BIN_EXE_armor-mod-localiser");
const AVOIDER: &str = env!("CARGO_BIN_EXE_armor-mod-avoider");
const OBSERVER: &str = env!("CARGO_BIN_EXE_armor-mod-observer");
const TELEOP: &str = env!("CARGO_BIN_EXE_armor-mod-teleop");

/// How long to wait for the teleop's process before failing the test.
const PATIENCE: Duration = Duration::from_secs(30);

fn describe(binary: &str) -> ModuleDescription {
    let output = Command::new(binary)
        .arg("--describe")
        .output()
        .expect("run the module");
    assert!(output.status.success(), "{binary}: {:?}", output.status);
    let xml = String::from_utf8(output.stdout).expect("UTF-8");
    ModuleDescription::from_xml(&xml)
        .unwrap_or_else(|problems| panic!("{binary}: {problems:?}\n{xml}"))
}

fn ports(ports: &[PortSpec]) -> Vec<(&str, &str)> {
    ports
        .iter()
        .map(|port| (port.name.as_str(), port.data_type.as_str()))
        .collect()
}

/// What a module binary must declare: ports as (name, data type).
struct Expected {
    binary: &'static str,
    module_type: &'static str,
    controllable: bool,
    inputs: &'static [(&'static str, &'static str)],
    outputs: &'static [(&'static str, &'static str)],
    events: &'static [&'static str],
}

const MODULES: &[Expected] = &[
    Expected {
        binary: FOLLOWER,
        module_type: "follower",
        controllable: true,
        inputs: &[
            ("odometry", "Odometry"),
            ("estimate", "PoseEstimate"),
            ("scan", "LaserScan"),
            ("map", "OccupancyGrid"),
        ],
        outputs: &[
            ("path", "Text"),
            ("markers", "Markers"),
            ("cmd_desired", "Twist"),
        ],
        events: &["goal_reached", "blocked"],
    },
    Expected {
        binary: LOCALISER,
        module_type: "localiser",
        controllable: false,
        inputs: &[("odometry", "Odometry"), ("scan", "LaserScan")],
        outputs: &[("pose", "Odometry"), ("estimate", "PoseEstimate")],
        events: &["localised", "uncertain", "lost"],
    },
    Expected {
        binary: AVOIDER,
        module_type: "avoider",
        controllable: true,
        inputs: &[("scan", "LaserScan"), ("cmd_desired", "Twist")],
        outputs: &[("markers", "Markers"), ("cmd_vel", "Twist")],
        events: &["safety_stop"],
    },
    Expected {
        binary: OBSERVER,
        module_type: "observer",
        controllable: true,
        inputs: &[("odometry", "Odometry")],
        outputs: &[("markers", "Markers"), ("cmd_vel", "Twist")],
        events: &["observation_done"],
    },
    Expected {
        binary: TELEOP,
        module_type: "teleop",
        controllable: false,
        inputs: &[],
        outputs: &[("cmd_vel", "Twist")],
        events: &[],
    },
];

#[test]
fn every_robot_module_describes_itself() {
    for expected in MODULES {
        let description = describe(expected.binary);
        let module_type = expected.module_type;
        assert_eq!(description.module_type, module_type);
        assert_eq!(description.version, env!("CARGO_PKG_VERSION"));
        assert!(!description.doc.is_empty());
        assert_eq!(
            description.controllable, expected.controllable,
            "{module_type}"
        );
        assert_eq!(ports(&description.inputs), expected.inputs, "{module_type}");
        assert_eq!(
            ports(&description.outputs),
            expected.outputs,
            "{module_type}"
        );
        let events: Vec<&str> = description
            .events
            .iter()
            .map(|event| event.name.as_str())
            .collect();
        assert_eq!(events, expected.events, "{module_type}");
    }
}

#[test]
fn the_follower_requires_its_goal_and_defaults_the_rest() {
    let description = describe(FOLLOWER);
    for name in ["goal_x_m", "goal_y_m"] {
        let param = description.param(name).expect(name);
        assert!(param.is_required(), "{name}");
        assert_eq!(param.unit, "m");
    }
    let defaults = [
        ("tolerance_m", "0.3"),
        ("max_speed_mps", "0.6"),
        ("max_turn_radps", "1.2"),
        ("blocked_after_secs", "10"),
    ];
    for (name, default) in defaults {
        let param = description.param(name).expect(name);
        assert_eq!(param.default.as_deref(), Some(default), "{name}");
    }
}

/// Kills and reaps the process when dropped, so a failing test leaves nothing running.
struct KillOnDrop(Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Waits for a stderr line containing `marker` and returns what follows it.
fn wait_for_line(lines: &mpsc::Receiver<String>, marker: &str) -> String {
    let deadline = Instant::now() + PATIENCE;
    let mut seen = Vec::new();
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) => {
                if let Some((_, rest)) = line.split_once(marker) {
                    return rest.trim().to_owned();
                }
                seen.push(line);
            }
            Err(err) => panic!("no `{marker}` line ({err}); stderr so far: {seen:#?}"),
        }
    }
}

#[test]
fn teleop_answers_its_line_protocol_over_tcp() {
    let mut child = Command::new(TELEOP)
        .args(["--agent", "127.0.0.1:9", "--param", "listen=127.0.0.1:0"])
        .env_remove("ARMOR_SUPERVISOR")
        .env_remove("ARMOR_EPOCH_NS")
        .env_remove("ARMOR_TIME_SCALE")
        .env("ARMOR_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start the teleop");
    let stderr = child.stderr.take().expect("stderr");
    let teleop = KillOnDrop(child);
    let (sender, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines() {
            let Ok(line) = line else { break };
            if sender.send(line).is_err() {
                break;
            }
        }
    });
    let addr = wait_for_line(&lines, "teleop listening on ");
    let stream = TcpStream::connect(&addr).unwrap_or_else(|err| panic!("connect to {addr}: {err}"));
    stream
        .set_read_timeout(Some(PATIENCE))
        .expect("read timeout");
    let mut writer = stream.try_clone().expect("clone");
    let mut replies = BufReader::new(stream).lines();
    let mut ask = |line: &str| -> String {
        writer
            .write_all(format!("{line}\n").as_bytes())
            .expect("send");
        replies.next().expect("a reply").expect("read the reply")
    };
    assert_eq!(ask("v 0.2 0.1"), "ok");
    let reply = ask("fly");
    assert!(reply.starts_with("error: "), "{reply}");
    assert_eq!(ask("stop"), "ok");
    drop(teleop);
}
