//! Authenticated links, as a user turns them on: `armor run --secret FILE`. Modules find each
//! other and data flows as before; a peer without the secret, or with another one, is refused
//! before any data flows — at the agent, at a module's data port and at the control interface.
#![allow(clippy::unwrap_used)]

use std::net::{SocketAddr, TcpStream};
use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use armor_module_api::auth::Secret;
use armor_module_api::protocol::{Advert, FromAgent, ToAgent, ToProvider};
use armor_module_api::wire::{WireError, blocking};
use armor_tests::{PATIENCE, Proc, bin, field, workspace_root};

fn secret_file(dir: &Path, name: &str, text: &str, mode: u32) -> PathBuf {
    let file = dir.join(name);
    std::fs::write(&file, text).unwrap();
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(mode)).unwrap();
    file
}

fn armor_run(file: &str, secret: &Path) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(workspace_root().join(file))
            .arg("--secret")
            .arg(secret)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir()),
    )
}

fn connect(addr: SocketAddr) -> TcpStream {
    let stream = TcpStream::connect(addr).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    stream
}

/// The agent's address, from `armor run`'s log.
fn agent_addr(run: &Proc) -> SocketAddr {
    let line = run.wait_for("the agent's address", PATIENCE, |line| {
        line.contains("agent started")
    });
    field(&line, "addr").unwrap().parse().unwrap()
}

fn checker_in_order(line: &str) -> bool {
    line.starts_with("[checker]") && line.contains("received ") && line.ends_with("in order")
}

/// What a peer gets after its hello when it sends `message` without proving the secret: the
/// other side's challenge (which it cannot answer), then the end of the connection.
fn refused_without_secret(addr: SocketAddr, send: impl FnOnce(&mut TcpStream)) {
    let mut stream = connect(addr);
    blocking::handshake(&mut stream, None).unwrap();
    send(&mut stream);
    match blocking::read_frame(&mut stream) {
        Ok(frame) => assert!(
            matches!(
                frame.message::<serde_json::Value>(),
                Err(WireError::AuthNotConfigured)
            ),
            "expected a challenge, got {frame:?}"
        ),
        Err(err) => panic!("expected a challenge, got {err}"),
    }
    match blocking::read_frame(&mut stream) {
        Err(WireError::Closed) => {}
        Err(WireError::Io(err)) if err.kind() == std::io::ErrorKind::ConnectionReset => {}
        other => panic!("the connection should be closed, got {other:?}"),
    }
}

#[test]
fn links_flow_with_the_secret_and_strangers_are_refused_before_any_data() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(
        dir.path(),
        "secret",
        "a shared secret of 32 bytes ....\n",
        0o600,
    );
    let run = armor_run("missions/demo/system.xml", &secret);
    let agent = agent_addr(&run);
    run.wait_for(
        "the checker, with authenticated links",
        PATIENCE,
        checker_in_order,
    );

    // With the secret, the agent answers; the counter's data port is found.
    let mut stream = connect(agent);
    let known = Secret::load(&secret).unwrap();
    blocking::handshake(&mut stream, Some(&known)).unwrap();
    let lookup = ToAgent::Lookup {
        data_name: "counter.count".into(),
    };
    blocking::write_message(&mut stream, &lookup).unwrap();
    let FromAgent::Provider(advert) = blocking::read_message(&mut stream).unwrap() else {
        panic!("the counter is registered");
    };
    let provider: SocketAddr = advert.addr.parse().unwrap();

    // Without the secret: refused at the agent and at the data port, nothing served.
    refused_without_secret(agent, |stream| {
        blocking::write_message(stream, &lookup).unwrap();
    });
    let subscribe = ToProvider::Subscribe {
        data_name: "counter.count".into(),
        data_type: advert.data_type.clone(),
        subscriber: "thief.input".into(),
        reliable: false,
        max_rate_hz: None,
        pull: false,
        subscriber_addr: None,
    };
    refused_without_secret(provider, |stream| {
        blocking::write_message(stream, &subscribe).unwrap();
    });

    // With another secret: the proof does not match.
    let wrong = Secret::from_bytes(b"another secret, just as long ...");
    for addr in [agent, provider] {
        let mut stream = connect(addr);
        match blocking::handshake(&mut stream, Some(&wrong)) {
            Err(WireError::AuthFailed | WireError::Closed) => {}
            Err(WireError::Io(err)) if err.kind() == std::io::ErrorKind::ConnectionReset => {}
            other => panic!("a wrong secret must be refused, got {other:?}"),
        }
    }
    run.wait_for("the refusals in the log", PATIENCE, |line| {
        line.contains("before authenticating")
    });
    // The legitimate links are unharmed.
    let now = run.line_count();
    run.wait_for_from(now, "the checker afterwards", PATIENCE, checker_in_order);
}

#[test]
fn the_control_interface_wants_the_secret_too() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(
        dir.path(),
        "secret",
        "0123456789abcdef0123456789abcdef",
        0o600,
    );
    let run = armor_run("missions/demo/mission.xml", &secret);
    let line = run.wait_for("the control address", PATIENCE, |line| {
        line.contains("control interface listening")
    });
    let addr = field(&line, "addr").unwrap().to_owned();
    let ctl = |secret: Option<&Path>| {
        let mut command = Command::new(bin("armor"));
        command
            .args(["ctl", "--addr", &addr])
            .env_remove("ARMOR_SECRET_FILE");
        if let Some(secret) = secret {
            command.arg("--secret").arg(secret);
        }
        command.arg("status").output().unwrap()
    };
    let with = ctl(Some(&secret));
    assert!(with.status.success(), "{with:?}");
    let text = String::from_utf8_lossy(&with.stdout);
    assert!(
        text.contains("mission `"),
        "the status with its mission: {text}"
    );
    let without = ctl(None);
    assert!(!without.status.success());
    assert!(
        String::from_utf8_lossy(&without.stdout).contains("requires the shared secret"),
        "{without:?}"
    );
    let other = secret_file(
        dir.path(),
        "other",
        "fedcba9876543210fedcba9876543210",
        0o600,
    );
    let wrong = ctl(Some(&other));
    assert!(!wrong.status.success());
    assert!(
        String::from_utf8_lossy(&wrong.stderr).contains("another secret"),
        "{wrong:?}"
    );
}

#[test]
fn a_secret_others_can_read_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(
        dir.path(),
        "secret",
        "0123456789abcdef0123456789abcdef",
        0o644,
    );
    let mut run = armor_run("missions/demo/system.xml", &secret);
    // The message may reach the pipe reader after the exit is seen: wait for it first.
    run.wait_for("the refusal", PATIENCE, |line| {
        line.contains("readable by its owner only")
    });
    let status = run.wait_exit(PATIENCE);
    assert!(!status.success());
}

/// The demo system with access lists: the checker may subscribe to the counter only.
const LIMITED: &str = r#"<system name="limited">
  <module name="counter" type="counter" may_publish="counter.*" may_subscribe="">
    <param name="period_secs" value="0.1"/>
  </module>
  <module name="checker" type="checker" may_subscribe="counter.count"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

/// `armor run` on [`LIMITED`] (written to `dir`) with `args`, once the checker gets its
/// values; with the agent's address.
fn run_limited(dir: &Path, args: &[&str]) -> (Proc, SocketAddr) {
    let system = dir.join("system.xml");
    std::fs::write(&system, LIMITED).unwrap();
    let run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(&system)
            .args(args)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir()),
    );
    let agent = agent_addr(&run);
    run.wait_for("the checker, within its lists", PATIENCE, checker_in_order);
    (run, agent)
}

fn agent_reply(stream: &mut TcpStream, message: &ToAgent) -> FromAgent {
    blocking::write_message(stream, message).unwrap();
    blocking::read_message(stream).unwrap()
}

fn refusal(reply: FromAgent) -> String {
    match reply {
        FromAgent::Error { message } => message,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn access_lists_limit_what_each_module_may_publish_and_subscribe_to() {
    let dir = tempfile::tempdir().unwrap();
    let (_run, agent) = run_limited(dir.path(), &[]);

    let mut stream = connect(agent);
    blocking::handshake(&mut stream, None).unwrap();
    let lookup = |data_name: &str| ToAgent::Lookup {
        data_name: data_name.into(),
    };
    let register = |module: &str| ToAgent::Register {
        module: module.into(),
        outputs: Vec::new(),
    };
    // No identity yet, then a name the system does not know.
    assert!(refusal(agent_reply(&mut stream, &lookup("counter.count"))).contains("register"));
    assert!(refusal(agent_reply(&mut stream, &register("spy"))).contains("no module `spy`"));
    // As the checker: its own source is served, another module's output is not.
    assert_eq!(
        agent_reply(&mut stream, &register("checker")),
        FromAgent::Registered
    );
    assert!(matches!(
        agent_reply(&mut stream, &lookup("counter.count")),
        FromAgent::Provider(_)
    ));
    assert!(
        refusal(agent_reply(&mut stream, &lookup("checker.received")))
            .contains("may not subscribe to `checker.received`")
    );
    // The counter may subscribe to nothing at all.
    let mut counter = connect(agent);
    blocking::handshake(&mut counter, None).unwrap();
    assert_eq!(
        agent_reply(&mut counter, &register("counter")),
        FromAgent::Registered
    );
    assert!(refusal(agent_reply(&mut counter, &lookup("counter.count"))).contains("may not"));
}

#[test]
fn an_observer_may_subscribe_to_everything_and_publish_nothing() {
    let dir = tempfile::tempdir().unwrap();
    // `checker` is a module of the system: naming it an observer gives it nothing more.
    let (run, agent) = run_limited(
        dir.path(),
        &["--observer", "watcher", "--observer", "checker"],
    );
    run.wait_for("the warning about `checker`", PATIENCE, |line| {
        line.contains("--observer `checker` is a module of the system")
    });

    let lookup = |data_name: &str| ToAgent::Lookup {
        data_name: data_name.into(),
    };
    let mut watcher = connect(agent);
    blocking::handshake(&mut watcher, None).unwrap();
    let register = ToAgent::Register {
        module: "watcher".into(),
        outputs: Vec::new(),
    };
    assert_eq!(agent_reply(&mut watcher, &register), FromAgent::Registered);
    for data_name in ["counter.count", "checker.received"] {
        assert!(
            matches!(
                agent_reply(&mut watcher, &lookup(data_name)),
                FromAgent::Provider(advert) if advert.data_name == data_name
            ),
            "the observer is served {data_name}"
        );
    }
    let publishing = ToAgent::Register {
        module: "watcher".into(),
        outputs: vec![Advert {
            data_name: "watcher.fake".into(),
            data_type: "Counter".into(),
            addr: "127.0.0.1:9".into(),
        }],
    };
    assert!(refusal(agent_reply(&mut watcher, &publishing)).contains("may not publish"));

    let mut checker = connect(agent);
    blocking::handshake(&mut checker, None).unwrap();
    let register = ToAgent::Register {
        module: "checker".into(),
        outputs: Vec::new(),
    };
    assert_eq!(agent_reply(&mut checker, &register), FromAgent::Registered);
    assert!(
        refusal(agent_reply(&mut checker, &lookup("checker.received")))
            .contains("may not subscribe to `checker.received`")
    );
}

#[test]
fn armor_check_reports_links_and_outputs_outside_the_lists() {
    let dir = tempfile::tempdir().unwrap();
    let system = dir.path().join("system.xml");
    std::fs::write(
        &system,
        LIMITED
            .replace(
                r#"may_subscribe="counter.count""#,
                r#"may_subscribe="sim.*""#,
            )
            .replace(
                r#"may_publish="counter.*""#,
                r#"may_publish="counter.other""#,
            ),
    )
    .unwrap();
    let output = Command::new(bin("armor"))
        .arg("check")
        .arg(&system)
        .env("ARMOR_MODULE_PATH", armor_tests::bin_dir())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(!output.status.success());
    assert!(
        stdout.contains(":2:3: module `counter`: its output `counter.count` is not in may_publish"),
        "{stdout}"
    );
    assert!(
        stdout.contains(
            "module `checker` may not subscribe to `counter.count` (may_subscribe: sim.*)"
        ),
        "{stdout}"
    );
}
