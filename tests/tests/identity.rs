//! A module of the run attacking its siblings (issue 35), each attack written as the attacker
//! would try it, with only what a module of the run holds (its own key), on loopback:
//!
//! 1. it races another module's restart to register that module's data names (and a name like
//!    `mux.cmd_vel`, which would let it drive);
//! 2. as a provider, it subscribes back, on the connection its subscriber opened, to an output
//!    its `may_subscribe` does not give it;
//! 3. as another process of the same user, it reads `/proc/PID/environ`, `cmdline`, `fd` and
//!    `mem` of the run's processes for keys and the secret file's path, and uses what it finds;
//! 4. offline, it guesses a passphrase from a recorded handshake message with a word list.
#![allow(clippy::unwrap_used)]

use std::net::{SocketAddr, TcpListener, TcpStream};
use std::os::unix::fs::PermissionsExt as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use armor_module_api::auth::{Admit, Dial, Dialer, Key, Listen, Listener, Secret};
use armor_module_api::wire::blocking;
use armor_tests::{PATIENCE, Proc, bin, bin_dir, children_of, field, wait_until};
use serde_json::{Value, json};

/// A random-looking secret of 32 bytes (as `armor secret new` writes them, in hex).
const SECRET: &str = "5f0c2a9e61d4b3870e1f92ac34d7b6e05a8c1f3d92e4b7a6c0d5e8f1a2b3c4d5\n";

fn secret_file(dir: &Path) -> PathBuf {
    let file = dir.join("secret");
    std::fs::write(&file, SECRET).unwrap();
    std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
    file
}

fn write_system(dir: &Path, text: &str) -> PathBuf {
    let file = dir.join("system.xml");
    std::fs::write(&file, text).unwrap();
    file
}

fn armor_run(system: &Path, secret: &Path) -> Proc {
    Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(system)
            .arg("--no-run-folder")
            .env("ARMOR_SECRET_FILE", secret)
            .env("ARMOR_MODULE_PATH", bin_dir()),
    )
}

fn agent_addr(run: &Proc) -> SocketAddr {
    let line = run.wait_for("the agent's address", PATIENCE, |line| {
        line.contains("agent started")
    });
    field(&line, "addr").unwrap().parse().unwrap()
}

fn checker_in_order(line: &str) -> bool {
    line.starts_with("[checker]") && line.contains("received ") && line.ends_with("in order")
}

/// The pid of the run's module `comm` (its process name).
fn module_pid(run: &Proc, comm: &str) -> i32 {
    let mut found = None;
    wait_until(&format!("the process {comm}"), PATIENCE, || {
        found = children_of(run.pid()).into_iter().find(|pid| {
            std::fs::read_to_string(format!("/proc/{pid}/comm"))
                .is_ok_and(|text| text.trim() == comm)
        });
        found.is_some()
    });
    found.unwrap()
}

fn kill(pid: i32) {
    assert!(
        Command::new("kill")
            .args(["-KILL", &pid.to_string()])
            .status()
            .unwrap()
            .success()
    );
}

/// A connection to the agent as `identity`, proving `key`.
fn agent_as(agent: SocketAddr, key: Key, identity: &str) -> blocking::SecureStream {
    let stream = TcpStream::connect(agent).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    blocking::dial(
        stream,
        Some(&Dial {
            key,
            identity: identity.into(),
            encrypt: false,
        }),
    )
    .unwrap()
}

fn ask(stream: &mut blocking::SecureStream, message: &Value) -> Value {
    blocking::write_message(stream, message).unwrap();
    blocking::read_message(stream).unwrap()
}

fn register(module: &str, data_name: &str, addr: SocketAddr) -> Value {
    json!({
        "type": "register",
        "module": module,
        "outputs": [{"data_name": data_name, "data_type": "Counter", "addr": addr.to_string()}],
    })
}

const DEMO: &str = r#"<system name="demo">
  <module name="counter" type="counter"><param name="period_secs" value="0.05"/></module>
  <module name="checker" type="checker"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

/// Attack 1. `rogue`, a module of the run with its own key only, kills nothing itself: it
/// waits for the counter to restart (here: killed by the test) and registers `counter.count`
/// in the moment its registration is gone; then `mux.cmd_vel`, a name no module serves yet.
#[test]
fn a_module_cannot_take_another_modules_names_even_racing_its_restart() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let run = armor_run(&write_system(dir.path(), DEMO), &secret);
    let agent = agent_addr(&run);
    run.wait_for("the checker's values", PATIENCE, checker_in_order);
    let secret = Secret::from_bytes(SECRET.trim_end().as_bytes());
    let own_port = TcpListener::bind("127.0.0.1:0").unwrap();
    let own_addr = own_port.local_addr().unwrap();
    let mut rogue = agent_as(agent, secret.module_key("rogue"), "rogue");

    kill(module_pid(&run, "armor-mod-count"));
    // The counter is back within a second (its restart's first backoff); three cover it.
    let deadline = Instant::now() + Duration::from_secs(3);
    let mut answers = Vec::new();
    loop {
        let answer = ask(&mut rogue, &register("rogue", "counter.count", own_addr));
        let taken = answer["type"] == "registered";
        answers.push(answer);
        if taken || Instant::now() > deadline {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let last = answers.last().unwrap().clone();
    println!(
        "racing the counter's restart: {} tries, last answer {last}",
        answers.len()
    );
    assert!(
        answers.iter().all(|answer| answer["type"] == "error"),
        "the rogue module took `counter.count`: {last}"
    );
    assert!(
        answers.iter().any(|answer| answer["message"]
            .as_str()
            .is_some_and(|text| text.contains("may not publish `counter.count`"))),
        "refused as not its own name, not only as taken: {answers:?}"
    );
    let answer = ask(&mut rogue, &register("rogue", "mux.cmd_vel", own_addr));
    println!("registering mux.cmd_vel: {answer}");
    assert_eq!(
        answer["type"], "error",
        "the rogue module took `mux.cmd_vel`"
    );
    // Its own names it registers as ever.
    let answer = ask(&mut rogue, &register("rogue", "rogue.count", own_addr));
    assert_eq!(answer["type"], "registered", "{answer}");

    // The counter came back and the checker is fed by it again, in order.
    let seen = run.lines().len();
    run.wait_for_from(seen, "the checker, fed again", PATIENCE, checker_in_order);

    // Whoever registers a name, the checker's ticket to it is derived from the key of the
    // name's module: a port that holds another module's key does not pass its handshake.
    let mut checker = agent_as(agent, secret.module_key("checker"), "checker");
    let advert = ask(
        &mut checker,
        &json!({"type": "lookup", "data_name": "counter.count"}),
    );
    let ticket = Key::from_hex(advert["key"].as_str().unwrap()).unwrap();
    assert_eq!(ticket, secret.module_key("counter").link_key("checker"));
    let (_, first) = Dialer::start(&Dial {
        key: ticket,
        identity: "checker".into(),
        encrypt: false,
    })
    .unwrap();
    let rogue_port = Listen {
        admit: Admit::LinksTo(secret.module_key("rogue")),
        encrypt: false,
    };
    assert!(Listener::accept(&rogue_port, &first).is_err());
}

const LIMITED: &str = r#"<system name="limited">
  <module name="counter" type="counter" restart="never" may_subscribe="">
    <param name="period_secs" value="0.05"/>
  </module>
  <module name="checker" type="checker" may_subscribe="counter.count"/>
  <link from="counter.count" to="checker.input"/>
</system>
"#;

/// Attack 2. The counter's key in the hands of an attacker (the counter's process taken
/// over): its `may_subscribe` is empty, so the agent gives it no ticket to anything. It serves
/// `counter.count` and, on the connection the checker opens to subscribe, subscribes back to
/// `checker.received`.
#[test]
fn a_provider_cannot_subscribe_back_on_its_subscribers_connection() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let run = armor_run(&write_system(dir.path(), LIMITED), &secret);
    let agent = agent_addr(&run);
    run.wait_for("the checker's values", PATIENCE, checker_in_order);
    let secret = Secret::from_bytes(SECRET.trim_end().as_bytes());
    let counter_key = secret.module_key("counter");

    // The real counter goes (it is not restarted), the attacker serves its name.
    kill(module_pid(&run, "armor-mod-count"));
    let port = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = port.local_addr().unwrap();
    let mut counter = agent_as(agent, counter_key.clone(), "counter");
    let refused = ask(
        &mut counter,
        &json!({"type": "lookup", "data_name": "checker.received"}),
    );
    assert_eq!(
        refused["type"], "error",
        "the lists give the counter nothing"
    );
    wait_until("the counter's name free again", PATIENCE, || {
        ask(&mut counter, &register("counter", "counter.count", addr))["type"] == "registered"
    });

    let (stream, _) = port.accept().unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    let (mut link, dialer) = blocking::accept(
        stream,
        Some(Listen {
            admit: Admit::LinksTo(counter_key),
            encrypt: false,
        }),
    )
    .unwrap();
    assert_eq!(dialer.as_deref(), Some("checker"));
    let subscribe: Value = blocking::read_message(&mut link).unwrap();
    assert_eq!(subscribe["type"], "subscribe", "{subscribe}");
    blocking::write_message(&mut link, &json!({"type": "subscribed"})).unwrap();
    let back = json!({
        "type": "subscribe",
        "data_name": "checker.received",
        "data_type": "Counter",
        "subscriber": "counter.spy",
        "reliable": false,
    });
    blocking::write_message(&mut link, &back).unwrap();
    let answer: Value = blocking::read_message(&mut link).unwrap();
    println!("the checker's answer to the provider's subscription back: {answer}");
    assert_eq!(
        answer["type"], "refused",
        "the provider read checker.received back: {answer}"
    );
    assert!(
        answer["reason"]
            .as_str()
            .is_some_and(|reason| reason.contains("subscribes back")),
        "{answer}"
    );
}
