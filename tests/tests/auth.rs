//! Authenticated links, as a user turns them on: `armor run --secret FILE` (and `--encrypt`).
//! Modules find each other and data flows as before; every listener — the agent, the config
//! server, the control interface and a module's data port — refuses a peer that does not prove
//! its key: one without the secret, one with another, an attacker who reflects the listener's
//! own messages or replays a recorded handshake, and a module that claims another's name. A
//! thousand idle connections cost the run little and keep no module out; with `--encrypt`, a
//! capture of a data link holds none of what it carries.
#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use armor_module_api::auth::{Dial, Dialer, Key, Secret};
use armor_module_api::protocol::{
    Advert, FromAgent, FromProvider, ToAgent, ToProvider, ToSupervisor,
};
use armor_module_api::wire::{self, HELLO, WireError, blocking};
use armor_tests::{PATIENCE, Proc, bin, children_of, field, workspace_root};

const SECRET: &str = "a shared secret of 32 bytes ....\n";

fn secret_file(dir: &Path, name: &str, text: &str, mode: u32) -> PathBuf {
    let file = dir.join(name);
    std::fs::write(&file, text).unwrap();
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(mode)).unwrap();
    file
}

fn armor_run(file: &Path, args: &[&str]) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(file)
            .args(args)
            .env("ARMOR_MODULE_PATH", armor_tests::bin_dir())
            .env_remove("ARMOR_SECRET_FILE"),
    )
}

fn connect(addr: SocketAddr) -> TcpStream {
    let stream = TcpStream::connect(addr).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    stream
}

/// The addresses `armor run` logs: the agent's, the config server's, the control interface's.
struct Addrs {
    agent: SocketAddr,
    config: SocketAddr,
    control: SocketAddr,
}

fn addrs(run: &Proc) -> Addrs {
    let addr = |what: &str, pred: &dyn Fn(&str) -> bool, name: &str| -> SocketAddr {
        let line = run.wait_for(what, PATIENCE, pred);
        field(&line, name).unwrap().parse().unwrap()
    };
    Addrs {
        agent: addr(
            "the agent's address",
            &|line| line.contains("agent started"),
            "addr",
        ),
        config: addr(
            "the config server's address",
            &|line| line.contains("run started"),
            "config_server",
        ),
        control: addr(
            "the control address",
            &|line| line.contains("control interface listening"),
            "addr",
        ),
    }
}

fn checker_in_order(line: &str) -> bool {
    line.starts_with("[checker]") && line.contains("received ") && line.ends_with("in order")
}

/// Dials `addr` as `identity` with `key` (and asks for encryption or not).
fn dial(
    addr: SocketAddr,
    key: Key,
    identity: &str,
    encrypt: bool,
) -> Result<blocking::SecureStream, WireError> {
    blocking::dial(
        connect(addr),
        Some(&Dial {
            key,
            identity: identity.into(),
            encrypt,
        }),
    )
}

/// A provider's advert as the agent tells it to `identity` (with its link key).
fn lookup(agent: SocketAddr, secret: &Secret, identity: &str, data_name: &str) -> Advert {
    let mut stream = dial(agent, secret.module_key(identity), identity, false).unwrap();
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

/// What comes back on `stream` until it closes: the bytes, and whether it did close (rather
/// than go quiet for `quiet`).
fn drain(stream: &mut TcpStream, quiet: Duration) -> (Vec<u8>, bool) {
    stream.set_read_timeout(Some(quiet)).unwrap();
    let mut got = Vec::new();
    let mut buf = [0; 4096];
    loop {
        match stream.read(&mut buf) {
            Ok(0) => return (got, true),
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(err) if err.kind() == std::io::ErrorKind::ConnectionReset => return (got, true),
            Err(_) => return (got, false),
        }
    }
}

/// Whether the bytes hold a JSON message of the service (a reply to a request).
fn holds_a_reply(bytes: &[u8]) -> bool {
    let text = String::from_utf8_lossy(bytes);
    [
        "\"provider\"",
        "\"unknown\"",
        "\"subscribed\"",
        "\"config\"",
        "\"registered\"",
        "\"error\"",
    ]
    .iter()
    .any(|reply| text.contains(reply))
}

fn frame(kind: u8, body: &[u8]) -> Vec<u8> {
    let mut out = (1 + body.len() as u32).to_le_bytes().to_vec();
    out.push(kind);
    out.extend_from_slice(body);
    out
}

fn message(value: serde_json::Value) -> Vec<u8> {
    let mut out = Vec::new();
    wire::encode_message(&mut out, &value).unwrap();
    out
}

/// A TCP relay to `target` that records the bytes each way: (from the client, to it).
type Capture = Arc<Mutex<(Vec<u8>, Vec<u8>)>>;

fn relay(target: SocketAddr) -> (SocketAddr, Capture) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let capture: Capture = Arc::default();
    let recorded = Arc::clone(&capture);
    std::thread::spawn(move || {
        for client in listener.incoming().flatten() {
            let Ok(server) = TcpStream::connect(target) else {
                return;
            };
            for (mut from, mut to, upstream) in [
                (
                    client.try_clone().unwrap(),
                    server.try_clone().unwrap(),
                    true,
                ),
                (server, client, false),
            ] {
                let recorded = Arc::clone(&recorded);
                std::thread::spawn(move || {
                    let mut buf = [0; 65536];
                    while let Ok(n) = from.read(&mut buf) {
                        if n == 0 || to.write_all(&buf[..n]).is_err() {
                            break;
                        }
                        let mut capture = recorded.lock().unwrap();
                        let side = if upstream {
                            &mut capture.0
                        } else {
                            &mut capture.1
                        };
                        side.extend_from_slice(&buf[..n]);
                    }
                    let _ = to.shutdown(std::net::Shutdown::Both);
                });
            }
        }
    });
    (addr, capture)
}

/// The attacks of issue 17 on a frame listener (`request` is what the attacker wants served;
/// `dial_key` and `identity` are what a genuine peer proves there, to record a handshake).
fn attacks_fail(addr: SocketAddr, request: &[u8], dial_key: &Key, identity: &str, wrong: &Key) {
    // 1. Reflection. The listener sends nothing, not even its hello, before the dialer proves
    //    the key: there is no challenge of its own to turn against it. Whatever it sent on one
    //    connection, sent back on another with the request, gets no answer.
    let mut one = connect(addr);
    let mut two = connect(addr);
    one.write_all(&HELLO).unwrap();
    two.write_all(&HELLO).unwrap();
    let (from_one, closed) = drain(&mut one, Duration::from_millis(300));
    assert!(from_one.is_empty(), "not a byte before the dialer's proof");
    assert!(!closed);
    let (from_two, _) = drain(&mut two, Duration::from_millis(300));
    assert!(from_two.is_empty());
    two.write_all(&frame(wire::KIND_HANDSHAKE_FIRST, &from_one))
        .unwrap();
    one.write_all(request).unwrap();
    for stream in [&mut one, &mut two] {
        let (got, closed) = drain(stream, PATIENCE);
        assert!(closed, "the connection is closed");
        assert!(
            !holds_a_reply(&got),
            "no reply: {}",
            String::from_utf8_lossy(&got)
        );
    }
    // The listener's answer to a genuine first message, passed off as a first message, is
    // refused too (a responder's message is no initiator's).
    let (dialer, first) = Dialer::start(&Dial {
        key: dial_key.clone(),
        identity: identity.into(),
        encrypt: false,
    })
    .unwrap();
    let mut genuine = connect(addr);
    genuine.write_all(&HELLO).unwrap();
    genuine
        .write_all(&frame(wire::KIND_HANDSHAKE_FIRST, &first))
        .unwrap();
    let mut reply = [0; 6 + 4 + 1 + 49];
    genuine.read_exact(&mut reply).unwrap();
    assert_eq!(reply[10], wire::KIND_HANDSHAKE_ANSWER);
    let mut reflected = vec![identity.len() as u8];
    reflected.extend_from_slice(identity.as_bytes());
    reflected.extend_from_slice(&reply[11..]);
    let mut three = connect(addr);
    three.write_all(&HELLO).unwrap();
    three
        .write_all(&frame(wire::KIND_HANDSHAKE_FIRST, &reflected))
        .unwrap();
    three.write_all(request).unwrap();
    let (got, closed) = drain(&mut three, PATIENCE);
    assert!(
        closed && !holds_a_reply(&got),
        "a reflected answer is refused"
    );
    drop(dialer);

    // 2. Replay. A genuine peer's handshake and request, recorded through a relay, replayed
    //    byte for byte on a new connection: answered up to the confirmation, which belongs to
    //    the recorded session, then closed without a reply.
    let (relayed, capture) = relay(addr);
    let mut stream = blocking::dial(
        connect(relayed),
        Some(&Dial {
            key: dial_key.clone(),
            identity: identity.into(),
            encrypt: false,
        }),
    )
    .unwrap();
    stream.write_all(request).unwrap();
    let reply = blocking::read_frame(&mut stream).unwrap();
    assert!(
        matches!(reply, wire::Frame::Message(_)),
        "the genuine peer is served"
    );
    let recorded = capture.lock().unwrap().0.clone();
    let mut replay = connect(addr);
    replay.write_all(&recorded).unwrap();
    let (got, closed) = drain(&mut replay, PATIENCE);
    assert!(closed, "a replayed handshake ends the connection");
    assert!(
        got.len() <= 6 + 4 + 1 + 49 && !holds_a_reply(&got),
        "nothing is served to a replay: {got:?}"
    );

    // 3. A wrong secret.
    let refused = blocking::dial(
        connect(addr),
        Some(&Dial {
            key: wrong.clone(),
            identity: identity.into(),
            encrypt: false,
        }),
    );
    assert!(
        matches!(
            refused,
            Err(WireError::AuthFailed(_) | WireError::HandshakeRefused(_))
        ) || matches!(&refused, Err(WireError::Io(err)) if err.kind() == std::io::ErrorKind::ConnectionReset),
        "a wrong secret must be refused, got {refused:?}"
    );

    // 4. No secret at all: the request is refused unanswered.
    let mut stream = connect(addr);
    stream.write_all(&HELLO).unwrap();
    stream.write_all(request).unwrap();
    let (got, closed) = drain(&mut stream, PATIENCE);
    assert!(closed && !holds_a_reply(&got[HELLO.len().min(got.len())..]));
}

/// The demo system run with a secret (written to `dir`), once the checker gets its values.
fn demo_with_secret(dir: &Path) -> (Proc, Addrs, PathBuf) {
    let file = secret_file(dir, "secret", SECRET, 0o600);
    let run = armor_run(
        &workspace_root().join("missions/demo/system.xml"),
        &["--secret", file.to_str().unwrap()],
    );
    let addrs = addrs(&run);
    run.wait_for(
        "the checker, with authenticated links",
        PATIENCE,
        checker_in_order,
    );
    (run, addrs, file)
}

#[test]
fn every_listener_refuses_reflection_replay_a_wrong_secret_and_no_secret() {
    let dir = tempfile::tempdir().unwrap();
    let (run, addrs, file) = demo_with_secret(dir.path());
    let secret = Secret::load(&file).unwrap();
    let wrong = Secret::from_bytes(b"another secret, just as long ...");

    // The agent: a lookup is what the attacker wants.
    let lookup_request = message(
        serde_json::to_value(ToAgent::Lookup {
            data_name: "counter.count".into(),
        })
        .unwrap(),
    );
    attacks_fail(
        addrs.agent,
        &lookup_request,
        &secret.module_key("tester"),
        "tester",
        &wrong.module_key("tester"),
    );
    // The config server: a configuration (the genuine peer, a tool of the operator's, names
    // no module of the system and is told so; an attacker is told nothing).
    let hello = message(
        serde_json::to_value(ToSupervisor::Hello {
            module: "tester".into(),
            pid: 1,
        })
        .unwrap(),
    );
    attacks_fail(
        addrs.config,
        &hello,
        &secret.module_key("tester"),
        "tester",
        &wrong.module_key("tester"),
    );
    // A module's data port: the counter's samples.
    let advert = lookup(addrs.agent, &secret, "tester", "counter.count");
    let ticket = Key::from_hex(advert.key.as_deref().unwrap()).unwrap();
    assert_eq!(ticket, secret.module_key("counter").link_key("tester"));
    let provider: SocketAddr = advert.addr.parse().unwrap();
    attacks_fail(
        provider,
        &message(serde_json::to_value(subscribe("counter.count", "tester.input")).unwrap()),
        &ticket,
        "tester",
        &wrong.module_key("counter").link_key("tester"),
    );
    // The control interface: a recorded exchange replayed, no secret, a wrong one.
    let ctl = |secret_file: Option<&Path>, addr: SocketAddr| {
        let mut command = Command::new(bin("armor"));
        command
            .args(["ctl", "--addr", &addr.to_string()])
            .env_remove("ARMOR_SECRET_FILE");
        if let Some(file) = secret_file {
            command.arg("--secret").arg(file);
        }
        command.arg("status").output().unwrap()
    };
    let (relayed, capture) = relay(addrs.control);
    let with = ctl(Some(&file), relayed);
    assert!(with.status.success(), "{with:?}");
    let recorded = capture.lock().unwrap().0.clone();
    let mut replay = connect(addrs.control);
    replay.write_all(&recorded).unwrap();
    let (got, _) = drain(&mut replay, PATIENCE);
    // The replayed first message gets the run's hello and handshake answer (6 + 60 bytes at
    // most), and the replayed confirmation, made for other keys, ends the connection: no reply.
    assert!(
        got.len() <= 6 + 60,
        "a replayed control exchange got {} bytes: {:?}",
        got.len(),
        String::from_utf8_lossy(&got)
    );
    let without = ctl(None, addrs.control);
    assert!(!without.status.success());
    assert!(
        String::from_utf8_lossy(&without.stderr).contains("requires the shared secret"),
        "{without:?}"
    );
    let other = secret_file(
        dir.path(),
        "other",
        "fedcba9876543210fedcba9876543210",
        0o600,
    );
    let wrong_ctl = ctl(Some(&other), addrs.control);
    assert!(!wrong_ctl.status.success());
    assert!(
        String::from_utf8_lossy(&wrong_ctl.stderr).contains("another secret"),
        "{wrong_ctl:?}"
    );

    // The legitimate links are unharmed.
    let now = run.line_count();
    run.wait_for_from(now, "the checker afterwards", PATIENCE, checker_in_order);
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
    let mut run = armor_run(
        &workspace_root().join("missions/demo/system.xml"),
        &["--secret", secret.to_str().unwrap()],
    );
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
    let agent = addrs(&run).agent;
    run.wait_for("the checker, within its lists", PATIENCE, checker_in_order);
    (run, agent)
}

fn agent_reply(stream: &mut blocking::SecureStream, message: &ToAgent) -> FromAgent {
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

    let mut stream = blocking::dial(connect(agent), None).unwrap();
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
    let mut counter = blocking::dial(connect(agent), None).unwrap();
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
    let mut watcher = blocking::dial(connect(agent), None).unwrap();
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
            key: None,
        }],
    };
    assert!(refusal(agent_reply(&mut watcher, &publishing)).contains("may not publish"));

    let mut checker = blocking::dial(connect(agent), None).unwrap();
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

#[test]
fn a_module_with_its_own_key_cannot_claim_another_name_and_the_lists_hold() {
    let dir = tempfile::tempdir().unwrap();
    let file = secret_file(dir.path(), "secret", SECRET, 0o600);
    let secret = Secret::load(&file).unwrap();
    let (run, agent) = run_limited(dir.path(), &["--secret", file.to_str().unwrap()]);
    let config = addrs(&run).config;
    let checker_key = secret.module_key("checker");

    // A real module process given the checker's key (as `armor run` gives it) but told it is
    // the counter: refused by the config server before any configuration.
    let mut impostor = Proc::start(
        Proc::with_key(&mut Command::new(bin("armor-mod-checker")), &checker_key)
            .env("ARMOR_MODULE", "counter")
            .env("ARMOR_AGENT", agent.to_string())
            .env("ARMOR_SUPERVISOR", config.to_string())
            .env_remove("ARMOR_SECRET_FILE"),
    );
    impostor.wait_for("the impostor's refusal", PATIENCE, |line| {
        line.contains("cannot start") && line.contains("key offered for `counter`")
    });
    assert!(!impostor.wait_exit(PATIENCE).success());
    run.wait_for("the refusal in the run's log", PATIENCE, |line| {
        line.contains("refused a connection") && line.contains("counter")
    });

    // At the agent: the checker's key does not pass as the counter; as itself it may not
    // register as the counter, nor look up outside its list.
    assert!(dial(agent, checker_key.clone(), "counter", false).is_err());
    let mut checker = dial(agent, checker_key.clone(), "checker", false).unwrap();
    let register = |module: &str| ToAgent::Register {
        module: module.into(),
        outputs: Vec::new(),
    };
    assert!(
        refusal(agent_reply(&mut checker, &register("counter"))).contains("proved to be `checker`")
    );
    let lookup = |data_name: &str| ToAgent::Lookup {
        data_name: data_name.into(),
    };
    assert!(
        refusal(agent_reply(&mut checker, &lookup("checker.received")))
            .contains("may not subscribe to `checker.received`")
    );
    let FromAgent::Provider(advert) = agent_reply(&mut checker, &lookup("counter.count")) else {
        panic!("the checker's own source is served");
    };
    // At the counter's data port: the checker's own key is no ticket, and the ticket the
    // agent gave the checker admits only the checker.
    let port: SocketAddr = advert.addr.parse().unwrap();
    let ticket = Key::from_hex(advert.key.as_deref().unwrap()).unwrap();
    assert!(dial(port, checker_key.clone(), "checker", false).is_err());
    assert!(dial(port, ticket.clone(), "counter", false).is_err());
    let mut linked = dial(port, ticket, "checker", false).unwrap();
    blocking::write_message(&mut linked, &subscribe("counter.count", "counter.input")).unwrap();
    let refused: FromProvider = blocking::read_message(&mut linked).unwrap();
    assert!(
        matches!(&refused, FromProvider::Refused { reason } if reason.contains("not an input of `checker`")),
        "a subscriber name of another module is refused: {refused:?}"
    );
    let mut linked = dial(
        port,
        Key::from_hex(advert.key.as_deref().unwrap()).unwrap(),
        "checker",
        false,
    )
    .unwrap();
    blocking::write_message(&mut linked, &subscribe("counter.count", "checker.spare")).unwrap();
    let answer: FromProvider = blocking::read_message(&mut linked).unwrap();
    assert_eq!(answer, FromProvider::Subscribed);
}

/// Resident memory of a process, in KiB.
fn rss_kib(pid: i32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|line| line.strip_prefix("VmRSS:"))
        .and_then(|value| value.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

/// The pid of the run's child that is `comm`.
fn child_named(run: &Proc, comm: &str) -> i32 {
    children_of(run.pid())
        .into_iter()
        .find(|pid| {
            std::fs::read_to_string(format!("/proc/{pid}/comm"))
                .is_ok_and(|name| name.trim() == comm)
        })
        .unwrap_or_else(|| panic!("no `{comm}` under the run"))
}

#[test]
fn a_thousand_idle_strangers_cost_little_and_keep_no_module_out() {
    let dir = tempfile::tempdir().unwrap();
    let (run, addrs, file) = demo_with_secret(dir.path());
    let secret = Secret::load(&file).unwrap();
    let port: SocketAddr = lookup(addrs.agent, &secret, "tester", "counter.count")
        .addr
        .parse()
        .unwrap();
    let agent_pid = child_named(&run, "armor");
    let counter_pid = child_named(&run, "armor-mod-count");
    let watched = [
        ("run", run.pid()),
        ("agent", agent_pid),
        ("counter", counter_pid),
    ];
    let before: Vec<u64> = watched.iter().map(|(_, pid)| rss_kib(*pid)).collect();

    // A thousand connections that never send a byte, at the agent, the config server and the
    // counter's data port, held open for the rest of the test.
    let mut idle = Vec::new();
    for i in 0..1000 {
        let target = [addrs.agent, addrs.config, port][i % 3];
        idle.push(TcpStream::connect(target).unwrap());
    }
    // A module restarted now must register, be configured and link again among them.
    let checker = child_named(&run, "armor-mod-check");
    armor_tests::signal(checker, 9);
    let now = run.line_count();
    run.wait_for_from(
        now,
        "the checker restarted during the flood",
        PATIENCE,
        |line| line.contains("module started") && line.contains("checker"),
    );
    run.wait_for_from(
        now,
        "the restarted checker's values",
        PATIENCE,
        checker_in_order,
    );
    // A newcomer of the operator's is served too.
    let advert = lookup(addrs.agent, &secret, "newcomer", "counter.count");
    assert!(advert.key.is_some());

    // Memory stays within a stated bound: at most 256 pending connections per listener, a
    // kilobyte each at most, and idle ones hold no buffer; 8 MiB leaves room for allocator
    // noise.
    for ((what, pid), before) in watched.iter().zip(before) {
        let after = rss_kib(*pid);
        assert!(
            after < before + 8 * 1024,
            "{what} grew from {before} KiB to {after} KiB with 1000 idle connections"
        );
    }
    drop(idle);
}

#[test]
fn with_encrypt_a_capture_of_a_data_link_holds_none_of_what_it_carries() {
    let dir = tempfile::tempdir().unwrap();
    let file = secret_file(dir.path(), "secret", SECRET, 0o600);
    let secret = Secret::load(&file).unwrap();
    for encrypt in [true, false] {
        let mut args = vec!["--secret", file.to_str().unwrap()];
        if encrypt {
            args.push("--encrypt");
        }
        let run = armor_run(&workspace_root().join("missions/demo/system.xml"), &args);
        let addrs = addrs(&run);
        // The modules' own links work encrypted.
        run.wait_for(
            "the checker, on encrypted links",
            PATIENCE,
            checker_in_order,
        );
        let advert = lookup(addrs.agent, &secret, "tester", "counter.count");
        let port: SocketAddr = advert.addr.parse().unwrap();
        let (relayed, capture) = relay(port);
        let ticket = Key::from_hex(advert.key.as_deref().unwrap()).unwrap();
        // This side does not ask for encryption: the counter, run with --encrypt, insists.
        let mut stream = dial(relayed, ticket, "tester", false).unwrap();
        blocking::write_message(&mut stream, &subscribe("counter.count", "tester.input")).unwrap();
        let answer: FromProvider = blocking::read_message(&mut stream).unwrap();
        assert_eq!(answer, FromProvider::Subscribed);
        let mut values = Vec::new();
        while values.len() < 3 {
            if let wire::Frame::Data(data) = blocking::read_frame(&mut stream).unwrap() {
                values.push(data.payload);
            }
        }
        let (up, down) = capture.lock().unwrap().clone();
        let holds =
            |bytes: &[u8], text: &str| bytes.windows(text.len()).any(|w| w == text.as_bytes());
        let seen = holds(&up, "counter.count") || holds(&down, "\"subscribed\"");
        assert_eq!(
            seen, !encrypt,
            "with --encrypt the capture holds no message in clear; without, it does"
        );
    }
}

#[test]
fn without_a_secret_the_protocol_is_unchanged() {
    // The hello, then frames (docs/protocol.md, section 2), as a module in another language
    // writes them by hand; the agent's answer carries no key.
    let run = armor_run(&workspace_root().join("missions/demo/system.xml"), &[]);
    let agent = addrs(&run).agent;
    run.wait_for("the checker", PATIENCE, checker_in_order);
    let mut stream = connect(agent);
    stream.write_all(&HELLO).unwrap();
    stream
        .write_all(&message(
            serde_json::to_value(ToAgent::Lookup {
                data_name: "counter.count".into(),
            })
            .unwrap(),
        ))
        .unwrap();
    let mut hello = [0; 6];
    stream.read_exact(&mut hello).unwrap();
    assert_eq!(hello, HELLO);
    let reply: FromAgent = blocking::read_message(&mut stream).unwrap();
    assert!(
        matches!(reply, FromAgent::Provider(Advert { key: None, .. })),
        "{reply:?}"
    );
}
