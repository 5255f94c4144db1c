//! A module in another language, written from docs/protocol.md alone: tests/python/armor_module.py
//! (type `pyecho`, Python with `noiseprotocol` and `cryptography`) republishes every Counter it
//! gets. `armor probe` and `armor check` accept its description, and in `counter → pyecho →
//! checker` the checker gets every value in order through it: in clear, with a shared secret
//! (Noise handshakes with its own key at the agent and the config server, link keys at data
//! ports, both as dialer and as listener), and with `--encrypt` (records). Its keys are the ones
//! the Rust side derives, and its data port admits the agent's link key and nothing else.
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::os::unix::fs::PermissionsExt as _;
use std::path::PathBuf;
use std::process::{Command, Output};

use armor_module_api::auth::{Key, Secret};
use armor_module_api::protocol::{Advert, FromAgent, FromProvider, ToAgent, ToProvider};
use armor_module_api::wire::{self, blocking};
use armor_tests::{PATIENCE, Proc, bin, bin_dir, field, workspace_root};

const SECRET: &str = "a shared secret of 32 bytes ....\n";

const SYSTEM: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<system name="pyecho">
  <module name="counter" type="counter">
    <param name="period_secs" value="0.05"/>
  </module>
  <module name="echo" type="pyecho"/>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="echo.input"/>
  <link from="echo.output" to="checker.input"/>
</system>
"#;

fn python_module() -> PathBuf {
    workspace_root().join("tests/python/armor_module.py")
}

/// A folder with `armor-mod-pyecho` (a wrapper that runs the Python module), the system file
/// and the secret file (mode 600).
struct Setup {
    dir: tempfile::TempDir,
    /// The Python that runs the module (checked to have its Noise and HKDF packages).
    python: PathBuf,
}

impl Setup {
    fn new() -> Setup {
        // The module imports these once it is given a key (its links' handshakes and keys).
        let python =
            PathBuf::from(armor_tests::tools::python3(&["noise", "cryptography"]).get_program());
        let dir = tempfile::tempdir().unwrap();
        let wrapper = dir.path().join("armor-mod-pyecho");
        std::fs::write(
            &wrapper,
            format!(
                "#!/bin/sh\nexec '{}' '{}' \"$@\"\n",
                python.display(),
                python_module().display()
            ),
        )
        .unwrap();
        std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
        std::fs::write(dir.path().join("system.xml"), SYSTEM).unwrap();
        let secret = dir.path().join("secret");
        std::fs::write(&secret, SECRET).unwrap();
        std::fs::set_permissions(&secret, std::fs::Permissions::from_mode(0o600)).unwrap();
        Setup { dir, python }
    }

    fn path(&self, name: &str) -> PathBuf {
        self.dir.path().join(name)
    }

    /// `armor ARGS` with the wrapper's folder and the workspace's binaries on the module path.
    fn armor(&self, args: &[&str]) -> Command {
        let mut command = Command::new(bin("armor"));
        command
            .args(args)
            .env(
                "ARMOR_MODULE_PATH",
                format!("{}:{}", self.dir.path().display(), bin_dir().display()),
            )
            .env("ARMOR_PROBE_CACHE", self.path("probe-cache"))
            .env_remove("ARMOR_SECRET_FILE");
        command
    }

    /// `armor run` of the system with `args`, once the checker has had 20 values in order
    /// through the Python module (its only source), none out of order; also the agent's
    /// address.
    fn run(&self, args: &[&str]) -> (Proc, SocketAddr) {
        let system = self.path("system.xml");
        let mut all = vec!["run", system.to_str().unwrap()];
        all.extend_from_slice(args);
        let run = Proc::start(&mut self.armor(&all));
        let line = run.wait_for("with the agent's address", PATIENCE, |line| {
            line.contains("agent started")
        });
        let agent = field(&line, "addr").unwrap().parse().unwrap();
        run.wait_for("with 20 values in order at the checker", PATIENCE, |line| {
            line.starts_with("[checker]")
                && line.contains("received 20 values")
                && line.ends_with("in order")
        });
        assert!(
            !run.lines().iter().any(|line| line.contains("out of order")),
            "{}",
            run.lines().join("\n")
        );
        (run, agent)
    }
}

fn output_text(output: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    )
}

/// The lines the Python module logged when it linked its input and took the checker.
fn linked_lines(run: &Proc) -> (String, String) {
    let input = run.wait_for("the Python module's input link", PATIENCE, |line| {
        line.starts_with("[echo]") && line.contains("subscribed to counter.count")
    });
    let output = run.wait_for("the checker at the Python module", PATIENCE, |line| {
        line.starts_with("[echo]") && line.contains("checker.input subscribed to echo.output")
    });
    (input, output)
}

#[test]
fn probe_and_check_accept_the_python_module() {
    let setup = Setup::new();
    let wrapper = setup.path("armor-mod-pyecho");
    let probe = setup
        .armor(&["probe", "--no-cache", wrapper.to_str().unwrap()])
        .output()
        .unwrap();
    let text = output_text(&probe);
    assert!(probe.status.success(), "{text}");
    assert!(text.starts_with("pyecho 0.1.0 "), "{text}");
    assert!(text.contains("input input: Counter"), "{text}");
    assert!(text.contains("output output: Counter"), "{text}");
    let check = setup
        .armor(&["check", setup.path("system.xml").to_str().unwrap()])
        .output()
        .unwrap();
    let text = output_text(&check);
    assert!(check.status.success(), "{text}");
    assert!(
        text.contains("ok (system `pyecho`: 3 modules, 2 links)"),
        "{text}"
    );
}

#[test]
fn values_flow_through_the_python_module_in_clear() {
    let setup = Setup::new();
    let (run, _) = setup.run(&[]);
    let (input, output) = linked_lines(&run);
    assert!(!input.contains("authenticated"), "{input}");
    assert!(!output.contains("authenticated"), "{output}");
}

#[test]
fn values_flow_through_the_python_module_with_a_secret() {
    let setup = Setup::new();
    let secret_file = setup.path("secret");
    let (run, agent) = setup.run(&["--secret", secret_file.to_str().unwrap()]);
    let (input, output) = linked_lines(&run);
    assert!(input.ends_with("(authenticated)"), "{input}");
    assert!(output.ends_with("(authenticated)"), "{output}");

    // The Python side derives the keys the Rust side does (a module's, a link's).
    let secret = Secret::load(&secret_file).unwrap();
    let python_key = |args: &[&str]| -> String {
        let output = Command::new(&setup.python)
            .arg(python_module())
            .arg("--key")
            .arg(&secret_file)
            .args(args)
            .output()
            .unwrap();
        assert!(output.status.success(), "{}", output_text(&output));
        String::from_utf8(output.stdout).unwrap().trim().to_owned()
    };
    assert_eq!(python_key(&["echo"]), secret.module_key("echo").to_hex());
    assert_eq!(
        python_key(&["echo", "tester"]),
        secret.module_key("echo").link_key("tester").to_hex()
    );

    // The agent hands a tester the link key for the Python module's port: it is admitted with
    // it and gets values; with the key of another link it gets no answer at all.
    let advert = lookup(agent, &secret, "tester", "echo.output");
    assert_eq!(
        advert.key.as_deref(),
        Some(python_key(&["echo", "tester"]).as_str())
    );
    let port: SocketAddr = advert.addr.parse().unwrap();
    let ticket = Key::from_hex(advert.key.as_deref().unwrap()).unwrap();
    let mut stream = armor_tests::dial_as(port, ticket, "tester").unwrap();
    blocking::write_message(&mut stream, &subscribe("echo.output", "tester.input")).unwrap();
    let answer: FromProvider = blocking::read_message(&mut stream).unwrap();
    assert_eq!(answer, FromProvider::Subscribed);
    let mut frames = 0;
    while frames < 3 {
        if let wire::Frame::Data(_) = blocking::read_frame(&mut stream).unwrap() {
            frames += 1;
        }
    }
    let wrong = secret.module_key("echo").link_key("checker");
    assert!(
        armor_tests::dial_as(port, wrong, "tester").is_err(),
        "a wrong link key"
    );
    // Nor may a tester name another module's input.
    let ticket = Key::from_hex(advert.key.as_deref().unwrap()).unwrap();
    let mut stream = armor_tests::dial_as(port, ticket, "tester").unwrap();
    blocking::write_message(&mut stream, &subscribe("echo.output", "checker.input")).unwrap();
    let answer: FromProvider = blocking::read_message(&mut stream).unwrap();
    assert!(matches!(answer, FromProvider::Refused { .. }), "{answer:?}");
}

#[test]
fn values_flow_through_the_python_module_with_a_secret_and_encryption() {
    let setup = Setup::new();
    let secret_file = setup.path("secret");
    let (run, _) = setup.run(&["--secret", secret_file.to_str().unwrap(), "--encrypt"]);
    let (input, output) = linked_lines(&run);
    assert!(input.ends_with("(authenticated, encrypted)"), "{input}");
    assert!(output.ends_with("(authenticated, encrypted)"), "{output}");
}

/// A provider's advert as the agent tells it to `identity` (with its link key).
fn lookup(agent: SocketAddr, secret: &Secret, identity: &str, data_name: &str) -> Advert {
    let mut stream = armor_tests::dial_as(agent, secret.module_key(identity), identity).unwrap();
    let lookup = ToAgent::Lookup {
        data_name: data_name.into(),
    };
    blocking::write_message(&mut stream, &lookup).unwrap();
    match blocking::read_message(&mut stream).unwrap() {
        FromAgent::Provider(advert) => advert,
        other => panic!("{data_name} is served: {other:?}"),
    }
}

fn subscribe(data_name: &str, subscriber: &str) -> ToProvider {
    ToProvider::Subscribe {
        data_name: data_name.into(),
        data_type: "Counter".into(),
        subscriber: subscriber.into(),
        reliable: false,
        max_rate_hz: None,
        pull: false,
        subscriber_addr: None,
        proof: None,
    }
}

#[test]
fn the_python_module_says_it_applies_and_its_markers_decode_as_the_protocol_says() {
    use armor_module_api::types::{Frame, Markers, Shape};
    use armor_module_api::{Event, ModuleSpec};
    use armor_protocol::{BehaviourState, Status};
    let setup = Setup::new();
    let (run, agent) = setup.run(&[]);
    let line = run.wait_for("the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();
    // A behaviour with no arbiter over it: applicable, so `ready`.
    armor_tests::wait_until("the Python module's behaviour state", PATIENCE, || {
        let output = setup
            .armor(&["ctl", "--addr", &addr, "status", "--json"])
            .output()
            .unwrap();
        let status: Status = serde_json::from_slice(&output.stdout).unwrap();
        status
            .modules
            .iter()
            .any(|m| m.name == "echo" && m.behaviour == Some(BehaviourState::Ready))
    });
    // Its markers, read by a Rust node: a point at (value, 0) and the value as text.
    let spec = ModuleSpec::new("markers_reader", "reads the Python module's markers")
        .input::<Markers>("markers", "");
    let mut node = armor_tests::test_node(spec, agent, &[("markers", "echo.markers")]);
    let input = node.input::<Markers>("markers").unwrap();
    let deadline = std::time::Instant::now() + PATIENCE;
    let markers = loop {
        assert!(std::time::Instant::now() < deadline, "no markers from echo");
        if let Event::Input(_) = node
            .next_event(Some(std::time::Duration::from_millis(200)))
            .unwrap()
            && let Some(sample) = node.take(&input).unwrap()
        {
            break sample.value;
        }
    };
    assert_eq!(markers.markers.len(), 2);
    let (point, text) = (&markers.markers[0], &markers.markers[1]);
    assert_eq!((point.shape, point.frame), (Shape::Points, Frame::World));
    assert_eq!(text.shape, Shape::Text);
    assert_eq!(point.rgba, [200, 40, 160, 255]);
    let value = point.points[0].x_m;
    assert!(value >= 1.0 && value.fract() == 0.0, "{value}");
    assert_eq!(text.text, format!("pyecho {value}"));
}
