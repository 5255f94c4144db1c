//! Authenticated links, as a user turns them on: `armor run --secret FILE`. Modules find each
//! other and data flows as before; a peer without the secret, or with another one, is refused
//! before any data flows — at the agent, at a module's data port and at the control interface.
#![allow(clippy::unwrap_used)]

use std::net::{SocketAddr, TcpStream};
use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use armor_module_api::auth::Secret;
use armor_module_api::protocol::{FromAgent, ToAgent, ToProvider};
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
    assert!(String::from_utf8_lossy(&with.stdout).contains("\"marking\""));
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
    let status = run.wait_exit(PATIENCE);
    assert!(!status.success());
    assert!(
        run.lines()
            .iter()
            .any(|line| line.contains("readable by its owner only")),
        "{:#?}",
        run.lines()
    );
}
