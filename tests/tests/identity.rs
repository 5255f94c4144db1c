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

/// The user the run and its attacker share in the `/proc` test when the test runs as root
/// (root reads every process; a module runs as an ordinary user).
const NOBODY: u32 = 65534;

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
    armor_tests::dial_as(agent, key, identity).unwrap()
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

/// A command run as the attacker: a process of the run's user.
fn as_sibling(program: &str) -> Command {
    if is_root() {
        let mut command = Command::new("setpriv");
        command.args([
            &format!("--reuid={NOBODY}"),
            &format!("--regid={NOBODY}"),
            "--clear-groups",
            program,
        ]);
        command
    } else {
        Command::new(program)
    }
}

/// What the attacker reads at `path`: the bytes, or why not.
fn read_as_sibling(path: &str) -> Result<Vec<u8>, String> {
    let output = as_sibling("cat").arg(path).output().unwrap();
    if output.status.success() {
        Ok(output.stdout)
    } else {
        Err(String::from_utf8_lossy(&output.stderr).trim().to_owned())
    }
}

fn is_root() -> bool {
    std::fs::read_to_string("/proc/self/status").is_ok_and(|status| {
        status
            .lines()
            .find_map(|line| line.strip_prefix("Uid:"))
            .and_then(|uids| uids.split_whitespace().next().map(|uid| uid == "0"))
            .unwrap_or(false)
    })
}

/// Attack 3. Every process of the run (`armor run`, its agent, each module) as seen by another
/// process of the same user: its environment, command line, inherited descriptors and memory
/// hold no key and no path to the secret; the secret file is read only if its path is known
/// another way.
#[test]
fn a_sibling_reads_no_key_and_no_secret_path_in_proc() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let system = write_system(dir.path(), DEMO);
    let mut command = Command::new(bin("armor"));
    let mut module_path = bin_dir();
    if is_root() {
        // The run and its attacker share one ordinary user, as modules do.
        for path in [dir.path(), &secret, &system] {
            std::os::unix::fs::chown(path, Some(NOBODY), Some(NOBODY)).unwrap();
        }
        // That user may not reach the checkout (under /root on a fresh machine, mode 0700):
        // the run's binaries go into the run's own folder.
        module_path = dir.path().join("bin");
        std::fs::create_dir(&module_path).unwrap();
        for name in ["armor", "armor-mod-counter", "armor-mod-checker"] {
            let to = module_path.join(name);
            if std::fs::hard_link(bin(name), &to).is_err() {
                std::fs::copy(bin(name), &to).unwrap();
            }
        }
        command = Command::new("setpriv");
        command.args([
            &format!("--reuid={NOBODY}"),
            &format!("--regid={NOBODY}"),
            "--clear-groups",
            module_path.join("armor").to_str().unwrap(),
        ]);
    }
    // The secret given as the docs show it, on the command line.
    let run = Proc::start(
        command
            .arg("run")
            .arg(&system)
            .arg("--no-run-folder")
            .arg("--secret")
            .arg(&secret)
            .env("ARMOR_MODULE_PATH", &module_path)
            .env("HOME", dir.path()),
    );
    let agent = agent_addr(&run);
    run.wait_for("the checker's values", PATIENCE, checker_in_order);
    let mut pids = vec![run.pid()];
    pids.extend(children_of(run.pid()));
    assert!(
        pids.len() >= 4,
        "armor run, its agent, two modules: {pids:?}"
    );

    let secret_path = secret.to_str().unwrap().as_bytes().to_vec();
    let keys = Secret::from_bytes(SECRET.trim_end().as_bytes());
    let mut stolen: Vec<String> = Vec::new();
    for pid in &pids {
        let comm = std::fs::read_to_string(format!("/proc/{pid}/comm")).unwrap_or_default();
        for what in ["environ", "cmdline"] {
            match read_as_sibling(&format!("/proc/{pid}/{what}")) {
                Ok(bytes) => {
                    for entry in bytes.split(|&b| b == 0) {
                        let text = String::from_utf8_lossy(entry);
                        if text.starts_with("ARMOR_KEY=")
                            || entry.windows(secret_path.len()).any(|w| w == secret_path)
                        {
                            stolen.push(format!("{} {what}: {text}", comm.trim()));
                        }
                    }
                }
                Err(why) => println!("{} {what}: not readable ({why})", comm.trim()),
            }
        }
        // Memory is read at the addresses `maps` gives; being let to open it is enough.
        let opened = as_sibling("sh")
            .args(["-c", "exec 3<\"$0\" && echo opened"])
            .arg(format!("/proc/{pid}/mem"))
            .output()
            .unwrap();
        if String::from_utf8_lossy(&opened.stdout).contains("opened") {
            stolen.push(format!("{} mem: opened", comm.trim()));
        }
    }
    // What was found is used as the attacker would: a module key to pass as its module at
    // the agent, a secret path to read the secret.
    for found in &stolen {
        if let Some(hex) = found.split("ARMOR_KEY=").nth(1)
            && let Some(key) = Key::from_hex(hex)
        {
            let owner = ["counter", "checker"]
                .into_iter()
                .find(|name| keys.module_key(name) == key)
                .unwrap_or("?");
            let stream = TcpStream::connect(agent).unwrap();
            let passed = blocking::dial(
                stream,
                Some(&Dial {
                    key,
                    identity: owner.into(),
                    encrypt: false,
                }),
            )
            .is_ok();
            println!("a stolen key passes at the agent as `{owner}`: {passed}");
        }
        if found.contains(&*String::from_utf8_lossy(&secret_path)) {
            let read = read_as_sibling(secret.to_str().unwrap());
            println!("the secret file, read by its path: {}", read.is_ok());
        }
    }
    assert!(
        stolen.is_empty(),
        "a sibling of the same user found: {stolen:#?}"
    );
}

/// Attack 4. A passphrase of 16 bytes (the issue's attack found one after 87 guesses) and one
/// handshake message recorded on the way to the agent; the attacker has a word list.
#[test]
fn an_offline_guesser_pays_argon2_for_every_word() {
    let passphrase = "tangerine sunset";
    let mut words: Vec<String> = (0..86).map(|i| format!("password{i:03}")).collect();
    words.push(passphrase.to_owned());
    words.extend((0..100).map(|i| format!("dragon{i:03}")));

    // A short passphrase is refused as the run's secret: too short to be one.
    let dir = tempfile::tempdir().unwrap();
    let weak = dir.path().join("weak");
    std::fs::write(&weak, passphrase).unwrap();
    std::fs::set_permissions(&weak, std::fs::Permissions::from_mode(0o600)).unwrap();
    let refused = Command::new(bin("armor"))
        .args(["secret", "derive", "--role", "observer", "-o"])
        .arg(dir.path().join("key"))
        .arg("--secret")
        .arg(&weak)
        .output()
        .unwrap();
    assert!(!refused.status.success());
    let said = String::from_utf8_lossy(&refused.stderr);
    assert!(
        said.contains("16 bytes long") && said.contains("--passphrase"),
        "{said}"
    );

    // `armor secret new --passphrase` stretches it with Argon2id and a salt it prints.
    let stretched = dir.path().join("secret");
    let mut child = Command::new(bin("armor"))
        .args(["secret", "new", "--passphrase", "-o"])
        .arg(&stretched)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write as _;
    writeln!(child.stdin.take().unwrap(), "{passphrase}").unwrap();
    let made = child.wait_with_output().unwrap();
    let printed = String::from_utf8_lossy(&made.stdout);
    assert!(made.status.success(), "{printed}");
    let salt_hex = printed
        .split_whitespace()
        .skip_while(|word| *word != "salt")
        .nth(1)
        .unwrap()
        .to_owned();
    let salt: Vec<u8> = (0..salt_hex.len() / 2)
        .map(|i| u8::from_str_radix(&salt_hex[i * 2..i * 2 + 2], 16).unwrap())
        .collect();
    let mode = std::fs::metadata(&stretched).unwrap().permissions().mode();
    assert_eq!(mode & 0o777, 0o600);
    let secret = Secret::load(&stretched).unwrap();

    // The recorded message: a module's first handshake message to the agent.
    let (_, recorded) = Dialer::start(&Dial {
        key: secret.module_key("checker"),
        identity: "checker".into(),
        encrypt: false,
    })
    .unwrap();
    let fits = |candidate: &Secret| {
        let listen = Listen {
            admit: Admit::Modules(candidate.clone()),
            encrypt: false,
        };
        Listener::accept(&listen, &recorded).is_ok()
    };

    // The guesser of the issue: each word as the secret itself.
    let started = Instant::now();
    let found = words
        .iter()
        .position(|word| fits(&Secret::from_bytes(word.as_bytes())));
    let rate = words.len() as f64 / started.elapsed().as_secs_f64();
    println!(
        "words as secrets: {} guesses at {rate:.0}/s, found: {found:?}",
        words.len()
    );
    assert_eq!(found, None, "the passphrase itself is no longer the secret");

    // A guesser who knows the scheme and the salt pays Argon2id (64 MiB) for every word.
    let started = Instant::now();
    let tried = 3;
    for word in &words[..tried] {
        let key = armor_module_api::auth::stretch_passphrase(word.as_bytes(), &salt).unwrap();
        assert!(!fits(&Secret::from_bytes(
            armor_module_api::auth::hex(&key).as_bytes()
        )));
    }
    let per_guess = started.elapsed().as_secs_f64() / tried as f64;
    println!(
        "words through Argon2id: {:.1} guesses/s on one core, so a million-word list takes {:.0} \
         hours and 64 MiB for each guess in flight",
        1.0 / per_guess,
        1e6 * per_guess / 3600.0
    );
    // The right word does open it, once stretched: the scheme is what the guesser pays for.
    let key = armor_module_api::auth::stretch_passphrase(passphrase.as_bytes(), &salt).unwrap();
    assert!(fits(&Secret::from_bytes(
        armor_module_api::auth::hex(&key).as_bytes()
    )));
}
