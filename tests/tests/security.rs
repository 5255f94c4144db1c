//! Attacks on a run and a host daemon, each written as the attacker would try it (issue 34):
//! a stranger at a default `armor host`, and one that chooses a module's environment; an
//! on-path relay that reads and rewrites the control link; slow clients and strangers that try
//! to lock the operator out; a process without a key at the teleop port; oversized lookups;
//! and, for every socket a run under `--secret` listens on, a stranger that gets not a byte
//! and is closed within 2 s. Without a secret: strangers that say only their hello at every
//! listener, control clients that ask once and idle, peers that say a module's hello to the
//! config server again and again, and idle queries at `armor host`, none of which may cost a
//! thread each or keep the operator out; with a secret, an idle operator is never closed to
//! make room. Real processes and sockets on loopback.
#![allow(clippy::unwrap_used)]

use std::collections::HashSet;
use std::io::{Read as _, Write as _};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use armor_module_api::auth::Secret;
use armor_module_api::wire::blocking;
use armor_tests::{
    PATIENCE, Proc, bin, bin_dir, children_of, control_address, driven_system, role_key,
    secret_file, start_agent, wait_until, waiting_mission,
};

/// What the brief allows a stranger: closed within this, having received nothing.
const STRANGER_CLOSED_WITHIN: Duration = Duration::from_secs(2);

/// `armor run FILE --secret SECRET --no-run-folder`, and its control address.
fn run_with_secret(file: &Path, secret: &Path) -> (Proc, String) {
    let run = Proc::start(
        Command::new(bin("armor"))
            .arg("run")
            .arg(file)
            .arg("--secret")
            .arg(secret)
            .arg("--no-run-folder")
            .env("ARMOR_MODULE_PATH", bin_dir()),
    );
    let addr = control_address(&run);
    (run, addr)
}

/// `armor ctl` with these arguments: whether it succeeded, its output, and how long it took.
fn ctl(args: &[&str]) -> (bool, String, Duration) {
    let started = Instant::now();
    let output = Command::new(bin("armor"))
        .arg("ctl")
        .args(args)
        .env_remove(armor_module_api::auth::ENV_SECRET_FILE)
        .output()
        .unwrap();
    (
        output.status.success(),
        format!(
            "{}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        ),
        started.elapsed(),
    )
}

/// The teleop module's command port, once the run's status shows it.
fn teleop_port(control: &str, secret: &Path) -> SocketAddr {
    let mut found = None;
    wait_until("the teleop's endpoint in the status", PATIENCE, || {
        let (ok, text, _) = ctl(&[
            "--addr",
            control,
            "--secret",
            secret.to_str().unwrap(),
            "status",
            "--json",
        ]);
        let json = text.find('{').map_or("", |start| &text[start..]);
        // The JSON is followed by the reply's message (on stderr, after stdout here).
        let status: serde_json::Value = serde_json::Deserializer::from_str(json)
            .into_iter()
            .next()
            .and_then(Result::ok)
            .unwrap_or_default();
        found = status["modules"].as_array().and_then(|modules| {
            modules
                .iter()
                .find(|module| module["name"] == "pad" && module["state"] == "running")
                .and_then(|pad| pad["endpoints"]["teleop"].as_str())
                .and_then(|addr| addr.parse().ok())
        });
        ok && found.is_some()
    });
    found.unwrap()
}

/// Reads what a peer sends until it closes or `wait` passes: the bytes, and whether (and when)
/// it closed.
fn read_until_closed(stream: &mut TcpStream, wait: Duration) -> (Vec<u8>, Option<Duration>) {
    let started = Instant::now();
    let mut got = Vec::new();
    let mut buf = [0; 4096];
    loop {
        let left = wait.saturating_sub(started.elapsed());
        if left.is_zero() {
            return (got, None);
        }
        stream.set_read_timeout(Some(left)).unwrap();
        match stream.read(&mut buf) {
            Ok(0) => return (got, Some(started.elapsed())),
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(err)
                if matches!(
                    err.kind(),
                    std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                ) =>
            {
                return (got, None);
            }
            Err(_) => return (got, Some(started.elapsed())),
        }
    }
}

#[test]
fn a_default_host_listens_on_loopback_and_refuses_the_network_without_a_secret() {
    // Defaults first, as a user would start it.
    let mut host = Proc::start(
        Command::new(bin("armor"))
            .args(["host", "--name", "robot1"])
            .env("ARMOR_MODULE_PATH", bin_dir())
            .env_remove(armor_module_api::auth::ENV_SECRET_FILE),
    );
    let line = host.wait_for("its address or why not", PATIENCE, |line| {
        line.contains("listening on") || line.contains("cannot listen on")
    });
    // Port 7410 may be taken by another test's daemon: the address is what matters.
    assert!(line.contains("127.0.0.1:7410"), "{line}");
    host.signal(9);
    host.wait_exit(PATIENCE);
    // Asked for every interface without a secret, it refuses and says why.
    let output = Command::new(bin("armor"))
        .args(["host", "--listen", "0.0.0.0:0"])
        .env_remove(armor_module_api::auth::ENV_SECRET_FILE)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(stderr.contains("without a secret"), "{stderr}");
}

/// A supervisor's spawn request (here a stranger's, at a loopback daemon without a secret)
/// cannot choose the module's environment: the daemon builds it itself.
#[test]
fn a_spawn_request_cannot_choose_the_modules_environment() {
    let (_host, addr) = loopback_host_without_secret();
    let stream = TcpStream::connect(addr).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    let mut stream = blocking::dial(stream, None).unwrap();
    let hello = serde_json::json!({"op": "hello", "run": "stranger", "orphan_ms": 3000});
    blocking::write_message(&mut stream, &hello).unwrap();
    // The environment an attacker would like (the old form of the request) and the fields the
    // daemon checks (the new one): whichever the daemon reads, LD_PRELOAD must not pass.
    let spawn = serde_json::json!({
        "op": "spawn",
        "name": "victim",
        "module_type": "counter",
        "generation": 1,
        "env": [["LD_PRELOAD", "/nonexistent/attacker.so"], ["ARMOR_MODULE", "victim"]],
        "agent": "127.0.0.1:9",
        "supervisor": "127.0.0.1:9",
        "epoch_ns": 0,
        "time_scale": 1.0
    });
    blocking::write_message(&mut stream, &spawn).unwrap();
    let deadline = Instant::now() + PATIENCE;
    let pid = loop {
        assert!(Instant::now() < deadline, "no answer to the spawn");
        let message: serde_json::Value = blocking::read_message(&mut stream).unwrap();
        match message["op"].as_str() {
            Some("started") => break message["pid"].as_u64().unwrap(),
            Some("spawn_failed") => panic!("{message}"),
            _ => {}
        }
    };
    let environ = std::fs::read(format!("/proc/{pid}/environ")).unwrap_or_default();
    let environ = String::from_utf8_lossy(&environ);
    assert!(
        !environ.contains("LD_PRELOAD"),
        "the module got LD_PRELOAD from the network: {environ}"
    );
    assert!(environ.contains("ARMOR_MODULE=victim"), "{environ}");
}

/// A relay between the operator and the run: it records both directions, and with `tamper`
/// rewrites what it can of the client's requests (a status poll into an abort in clear text;
/// a byte of the first request once the handshake is over on an encrypted link).
struct Relay {
    addr: SocketAddr,
    seen: Arc<Mutex<Vec<u8>>>,
}

fn relay(target: SocketAddr, tamper: bool) -> Relay {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let record = Arc::clone(&seen);
    std::thread::spawn(move || {
        for client in listener.incoming().flatten() {
            let Ok(server) = TcpStream::connect(target) else {
                continue;
            };
            let pump = |mut from: TcpStream, mut to: TcpStream, upstream: bool| {
                let record = Arc::clone(&record);
                std::thread::spawn(move || {
                    let mut buf = [0; 65536];
                    let mut offset = 0;
                    let mut clear_text = None;
                    while let Ok(n) = from.read(&mut buf) {
                        if n == 0 {
                            break;
                        }
                        record.lock().unwrap().extend_from_slice(&buf[..n]);
                        let chunk = &mut buf[..n];
                        if tamper && upstream {
                            let clear = *clear_text.get_or_insert(chunk[0] == b'{');
                            if clear {
                                rewrite(chunk, br#""status"}"#, br#""abort"} "#);
                            } else if (offset..offset + n).contains(&FLIP_AT) {
                                chunk[FLIP_AT - offset] ^= 1;
                            }
                        }
                        offset += n;
                        if to.write_all(chunk).is_err() {
                            break;
                        }
                    }
                    let _ = to.shutdown(std::net::Shutdown::Both);
                });
            };
            pump(
                client.try_clone().unwrap(),
                server.try_clone().unwrap(),
                true,
            );
            pump(server, client, false);
        }
    });
    Relay { addr, seen }
}

/// On the framed link: hello (6), first handshake frame (63), confirmation (21), then the first
/// request's record.
const FLIP_AT: usize = 100;

fn rewrite(chunk: &mut [u8], from: &[u8], to: &[u8]) {
    if let Some(at) = chunk.windows(from.len()).position(|window| window == from) {
        chunk[at..at + to.len()].copy_from_slice(to);
    }
}

#[test]
fn an_on_path_relay_reads_nothing_of_the_control_link_and_its_rewrites_are_detected() {
    let dir = tempfile::tempdir().unwrap();
    let secret_path = secret_file(dir.path());
    let secret = Secret::load(&secret_path).unwrap();
    let (_run, control) = run_with_secret(&driven_system(dir.path()), &secret_path);
    let control: SocketAddr = control.parse().unwrap();
    // Reading: a status through the relay, then a look at what passed.
    let reader = relay(control, false);
    let mut client = armor_protocol::Client::connect(reader.addr, Some(&secret)).unwrap();
    let reply = client.call(&armor_protocol::Request::Status).unwrap();
    assert!(reply.ok, "{reply:?}");
    let seen = reader.seen.lock().unwrap().clone();
    for clear in ["status", "command", "driven", "teleop", "sim"] {
        assert!(
            !seen
                .windows(clear.len())
                .any(|window| window == clear.as_bytes()),
            "`{clear}` passed the relay in clear text"
        );
    }
    // Rewriting: the request changed on the way is not carried out, and the client learns it.
    let tamperer = relay(control, true);
    let mut client = armor_protocol::Client::connect(tamperer.addr, Some(&secret)).unwrap();
    let answer = client.call(&armor_protocol::Request::Status);
    assert!(
        answer.is_err(),
        "a rewritten request was answered: {answer:?}"
    );
    // The run goes on, for an operator who is not on that path.
    let (ok, text, _) = ctl(&[
        "--addr",
        &control.to_string(),
        "--secret",
        secret_path.to_str().unwrap(),
        "status",
    ]);
    assert!(ok, "{text}");
}

/// Clients that keep connections open and send a byte every 4 s, reconnecting when closed,
/// until `stop`; each connection counted in `made`.
fn slow_clients(target: SocketAddr, count: usize, stop: &Arc<AtomicBool>, made: &Arc<AtomicUsize>) {
    for _ in 0..count {
        let stop = Arc::clone(stop);
        let made = Arc::clone(made);
        std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let Ok(mut stream) = TcpStream::connect(target) else {
                    continue;
                };
                made.fetch_add(1, Ordering::Relaxed);
                let mut last = Instant::now() - Duration::from_secs(4);
                while !stop.load(Ordering::Relaxed) {
                    if last.elapsed() >= Duration::from_secs(4) {
                        if stream.write_all(b"{").is_err() {
                            break;
                        }
                        last = Instant::now();
                    }
                    // A peek that ends with the run closing the connection.
                    stream
                        .set_read_timeout(Some(Duration::from_millis(200)))
                        .unwrap();
                    let mut byte = [0];
                    match stream.read(&mut byte) {
                        Ok(0) => break,
                        Ok(_) => {}
                        Err(err)
                            if matches!(
                                err.kind(),
                                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                            ) => {}
                        Err(_) => break,
                    }
                }
            }
        });
    }
}

/// Strangers that hold `count` idle connections, opening new ones as the run closes them; each
/// connection counted in `made`.
fn strangers(target: SocketAddr, count: usize, stop: &Arc<AtomicBool>, made: &Arc<AtomicUsize>) {
    let stop = Arc::clone(stop);
    let made = Arc::clone(made);
    std::thread::spawn(move || {
        let mut held: Vec<TcpStream> = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            held.retain(|stream| {
                let mut byte = [0];
                stream.set_nonblocking(true).is_ok()
                    && matches!((&*stream).read(&mut byte), Err(err) if err.kind() == std::io::ErrorKind::WouldBlock)
            });
            while held.len() < count {
                match TcpStream::connect(target) {
                    Ok(stream) => {
                        made.fetch_add(1, Ordering::Relaxed);
                        held.push(stream);
                    }
                    Err(_) => break,
                }
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    });
}

#[test]
fn slow_clients_and_strangers_do_not_lock_the_operator_out() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let mission = waiting_mission(dir.path());
    let (_run, control) = run_with_secret(&mission, &secret);
    let target: SocketAddr = control.parse().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let made = Arc::new(AtomicUsize::new(0));
    slow_clients(target, 40, &stop, &made);
    strangers(target, 500, &stop, &made);
    // The slow clients and strangers take their places first (and renew them once).
    wait_until("the attackers' connections", PATIENCE, || {
        made.load(Ordering::Relaxed) >= 1000
    });
    let secret = secret.to_str().unwrap();
    for attempt in 1..=10 {
        let command = if attempt == 10 { "abort" } else { "status" };
        let (ok, text, took) = ctl(&["--addr", &control, "--secret", secret, command]);
        assert!(ok, "attempt {attempt} ({command}): {text}");
        assert!(
            took <= STRANGER_CLOSED_WITHIN,
            "attempt {attempt} ({command}) took {took:?}: {text}"
        );
    }
    stop.store(true, Ordering::Relaxed);
}

#[test]
fn a_client_without_a_key_at_the_teleop_port_drives_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let (_run, control) = run_with_secret(&driven_system(dir.path()), &secret);
    let port = teleop_port(&control, &secret);
    let mut stranger = TcpStream::connect(port).unwrap();
    stranger.write_all(b"v 0.5 0\n").unwrap();
    let (got, closed) = read_until_closed(&mut stranger, STRANGER_CLOSED_WITHIN * 2);
    assert!(
        got.is_empty(),
        "the teleop answered a client without a key: {:?}",
        String::from_utf8_lossy(&got)
    );
    assert!(closed.is_some(), "the teleop kept a client without a key");
    // The operator still drives, through the run.
    let (ok, text, _) = ctl(&[
        "--addr",
        &control,
        "--secret",
        secret.to_str().unwrap(),
        "teleop",
        "0.3",
        "0",
    ]);
    assert!(ok && text.contains("driving at 0.3 0"), "{text}");
}

#[test]
fn oversized_lookups_are_refused_by_the_agent() {
    let (_agent, addr) = start_agent();
    let stream = TcpStream::connect(addr).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    let mut stream = blocking::dial(stream, None).unwrap();
    // A name far longer than any data name: refused, the connection kept.
    let lookup = serde_json::json!({"type": "lookup", "data_name": "x".repeat(10_000)});
    blocking::write_message(&mut stream, &lookup).unwrap();
    let answer: serde_json::Value = blocking::read_message(&mut stream).unwrap();
    assert_eq!(answer["type"], "error", "{answer}");
    // A frame of megabytes is not read at all: the connection ends.
    let lookup = serde_json::json!({"type": "lookup", "data_name": "x".repeat(4 << 20)});
    let _ = blocking::write_message(&mut stream, &lookup);
    let answer = blocking::read_message::<serde_json::Value>(&mut stream);
    assert!(answer.is_err(), "{answer:?}");
}

/// The TCP ports the processes `pids` listen on (from their sockets' inodes and
/// `/proc/PID/net/tcp`).
fn listening_ports(pids: &[i32]) -> Vec<u16> {
    let mut ports = HashSet::new();
    for pid in pids {
        let Ok(fds) = std::fs::read_dir(format!("/proc/{pid}/fd")) else {
            continue;
        };
        let inodes: HashSet<String> = fds
            .filter_map(Result::ok)
            .filter_map(|fd| std::fs::read_link(fd.path()).ok())
            .filter_map(|link| {
                let link = link.to_string_lossy().into_owned();
                Some(link.strip_prefix("socket:[")?.strip_suffix(']')?.to_owned())
            })
            .collect();
        for table in ["tcp", "tcp6"] {
            let text =
                std::fs::read_to_string(format!("/proc/{pid}/net/{table}")).unwrap_or_default();
            for line in text.lines().skip(1) {
                let fields: Vec<&str> = line.split_whitespace().collect();
                if fields.len() > 9 && fields[3] == "0A" && inodes.contains(fields[9]) {
                    let port = fields[1].rsplit(':').next().unwrap_or("");
                    if let Ok(port) = u16::from_str_radix(port, 16) {
                        ports.insert(port);
                    }
                }
            }
        }
    }
    let mut ports: Vec<u16> = ports.into_iter().collect();
    ports.sort_unstable();
    ports
}

/// The process and all its descendants.
fn process_tree(pid: i32) -> Vec<i32> {
    let mut all = vec![pid];
    let mut at = 0;
    while at < all.len() {
        all.extend(children_of(all[at]));
        at += 1;
    }
    all
}

#[test]
fn every_listener_of_a_run_with_a_secret_sends_a_stranger_nothing_and_closes_it() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let (run, control) = run_with_secret(&driven_system(dir.path()), &secret);
    // Once the teleop said where it listens, every module is up.
    teleop_port(&control, &secret);
    let ports = listening_ports(&process_tree(run.pid()));
    // The agent, the config server, the control interface, two data ports and the teleop's.
    assert!(ports.len() >= 6, "{ports:?}");
    println!("the run's listening ports: {ports:?}");
    let strangers: [&[u8]; 3] = [
        b"",
        b"GET / HTTP/1.0\r\n\r\n",
        &[b'A', b'R', b'M', b'R', 1, 0],
    ];
    for port in ports {
        for said in strangers {
            let mut stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
            stream.write_all(said).unwrap();
            let (got, closed) = read_until_closed(&mut stream, STRANGER_CLOSED_WITHIN * 2);
            assert!(
                got.is_empty(),
                "port {port} sent {} bytes to a stranger who said {said:?}",
                got.len()
            );
            let closed = closed.unwrap_or_else(|| panic!("port {port} kept a stranger"));
            assert!(
                closed <= STRANGER_CLOSED_WITHIN,
                "port {port} kept a stranger who said {said:?} for {closed:?}"
            );
        }
    }
}

#[test]
fn an_observer_key_reads_the_status_and_cannot_command() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let observer = role_key(&secret, "observer");
    // The key file reveals neither the secret nor the operator key.
    let text = std::fs::read_to_string(&observer).unwrap();
    let secret_text = std::fs::read_to_string(&secret).unwrap();
    let operator = Secret::load(&secret).unwrap().operator_key().to_hex();
    assert!(
        !text.contains(secret_text.trim()) && !text.contains(&operator),
        "{text}"
    );
    let (_run, control) = run_with_secret(&driven_system(dir.path()), &secret);
    let key = observer.to_str().unwrap();
    let (ok, text, _) = ctl(&["--addr", &control, "--key", key, "status"]);
    assert!(ok && text.contains("pad (teleop)"), "{text}");
    for command in [&["abort"][..], &["teleop", "0.3", "0"], &["stop", "sim"]] {
        let mut args = vec!["--addr", control.as_str(), "--key", key];
        args.extend_from_slice(command);
        let (ok, text, _) = ctl(&args);
        assert!(!ok && text.contains("observer"), "{command:?}: {text}");
    }
}

/// A trickle of bare connections to a module's own port (strangers that never say a word) does
/// not hold up its input's relink when its provider restarts: the module waits only on peers
/// whose first handshake message proved a key. Relinks with and without the trickle alternate in
/// one run, so that both see the same machine; the figures are printed.
#[test]
fn strangers_at_a_modules_port_do_not_delay_its_relink() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let system = armor_tests::workspace_root().join("missions/demo/system.xml");
    let (run, _control) = run_with_secret(&system, &secret);
    let line = run.wait_for("the checker's port", PATIENCE, |line| {
        line.contains("provider registered") && line.contains("checker.received")
    });
    let port: SocketAddr = armor_tests::field(&line, "addr").unwrap().parse().unwrap();
    run.wait_for("the checker linked", PATIENCE, |line| {
        line.starts_with("[checker]") && line.contains("input linked")
    });
    let mut quiet = Vec::new();
    let mut trickled = Vec::new();
    // Four rounds: the supervisor gives up on a module that crashed six times in ten seconds.
    for round in 0..4 {
        let with_trickle = round % 2 == 1;
        // 25 bare connections a second, each left open without a word.
        let stop = Arc::new(AtomicBool::new(false));
        let trickle = with_trickle.then(|| {
            let stop = Arc::clone(&stop);
            std::thread::spawn(move || {
                let mut held = Vec::new();
                while !stop.load(Ordering::Relaxed) {
                    if let Ok(stream) = TcpStream::connect(port) {
                        held.push(stream);
                    }
                    std::thread::sleep(Duration::from_millis(40));
                }
            })
        });
        let took = relink_after_killing_the_counter(&run);
        stop.store(true, Ordering::Relaxed);
        if let Some(trickle) = trickle {
            trickle.join().unwrap();
            trickled.push(took);
        } else {
            quiet.push(took);
        }
    }
    let mean = |times: &[Duration]| times.iter().sum::<Duration>() / times.len() as u32;
    let (quiet_mean, trickled_mean) = (mean(&quiet), mean(&trickled));
    println!(
        "relink after the provider restarted: quiet {quiet:?} (mean {quiet_mean:?}), \
         with 25 strangers a second {trickled:?} (mean {trickled_mean:?})"
    );
    // Waiting on strangers cost 200 ms a relink (the cap on the total wait); the margin is
    // half of that, for the noise of a shared machine.
    assert!(
        trickled_mean < quiet_mean + Duration::from_millis(100),
        "strangers delayed the relink: {trickled_mean:?} against {quiet_mean:?}"
    );
}

/// Kills the demo's counter and returns how long after it started again the checker's input
/// was linked to it.
fn relink_after_killing_the_counter(run: &Proc) -> Duration {
    let before = run.line_count();
    let counter = armor_tests::field(
        &run.lines()
            .into_iter()
            .rev()
            .find(|line| line.contains("module started") && line.contains("module=\"counter\""))
            .unwrap(),
        "pid",
    )
    .unwrap()
    .parse::<i32>()
    .unwrap();
    armor_tests::signal(counter, 9);
    run.wait_for_from(before, "the counter started again", PATIENCE, |line| {
        line.contains("module started") && line.contains("module=\"counter\"")
    });
    let restarted = Instant::now();
    run.wait_for_from(before, "the checker relinked", PATIENCE, |line| {
        line.starts_with("[checker]") && line.contains("input linked")
    });
    restarted.elapsed()
}

/// An operator behind a link with a round trip of 2 s gets in: the run's short deadline is
/// for the first handshake message only, which comes with the connect; the round trip that
/// follows it has a deadline of its own. A stranger on the same path is still closed early.
#[test]
fn an_operator_behind_a_slow_link_gets_in() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let (_run, control) = run_with_secret(&driven_system(dir.path()), &secret);
    let slow =
        armor_tests::slow_relay(control.parse().unwrap(), Duration::from_secs(1)).to_string();
    let (ok, text, took) = ctl(&[
        "--addr",
        &slow,
        "--secret",
        secret.to_str().unwrap(),
        "status",
    ]);
    println!("status over a link with a 2 s round trip took {took:?}");
    assert!(ok && text.contains("pad (teleop)"), "{text}");
    // Handshake (a round trip and a half) and the request's round trip.
    assert!(
        took >= Duration::from_secs(3),
        "{took:?}: was the relay slow?"
    );
    // A stranger behind the same link: nothing, and closed within the first message's time
    // (plus the link's delay for the close to come back).
    let mut stream = TcpStream::connect(slow).unwrap();
    let (got, closed) = read_until_closed(&mut stream, Duration::from_secs(6));
    assert!(got.is_empty(), "{} bytes to a stranger", got.len());
    let closed = closed.expect("the stranger was kept");
    assert!(
        closed <= STRANGER_CLOSED_WITHIN + Duration::from_secs(1),
        "{closed:?}"
    );
}

/// The run's status read with `armor ctl --key KEY status --json`.
fn status_with_key(control: &str, key: &Path) -> serde_json::Value {
    let (ok, text, _) = ctl(&[
        "--addr",
        control,
        "--key",
        key.to_str().unwrap(),
        "status",
        "--json",
    ]);
    assert!(ok, "{text}");
    let json = text.find('{').map_or("", |start| &text[start..]);
    serde_json::Deserializer::from_str(json)
        .into_iter()
        .next()
        .and_then(Result::ok)
        .unwrap_or_else(|| panic!("no status: {text}"))
}

/// What the agent answers `message` on a connection proving `key` as `identity`.
fn ask_agent(
    agent: SocketAddr,
    key: armor_module_api::auth::Key,
    identity: &str,
    message: &armor_module_api::protocol::ToAgent,
) -> armor_module_api::protocol::FromAgent {
    let mut stream = armor_tests::dial_as(agent, key, identity).unwrap();
    blocking::write_message(&mut stream, message).unwrap();
    blocking::read_message(&mut stream).unwrap()
}

/// An observer's key (`armor secret derive --role observer`) reads the run's live data through
/// the agent and the providers' ports, as the studio attached with it does: the robot's true
/// pose and its laser scan. It publishes nothing, takes no module's name and commands
/// nothing; a stranger without a key gets not a byte from the agent.
#[test]
fn an_observer_key_reads_live_data_and_nothing_more() {
    use armor_module_api::protocol::{Advert, FromAgent, ToAgent};
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let observer = role_key(&secret, "observer");
    let (_run, control) = run_with_secret(&driven_system(dir.path()), &secret);
    let agent: SocketAddr = status_with_key(&control, &observer)["agent"]
        .as_str()
        .unwrap()
        .parse()
        .unwrap();

    // Reads: a node holding the observer's key, under the observer's reader name.
    let mut node = armor_module_api::Node::connect(
        armor_module_api::ModuleSpec::new("watcher", "Reads a run with an observer's key."),
        armor_module_api::Standalone {
            name: Some("role:observer".to_owned()),
            agent: Some(agent.to_string()),
            secret: Some(observer.clone()),
            ..armor_module_api::Standalone::default()
        },
    )
    .unwrap();
    let truth = node.subscribe_raw_at_most("sim.pose_truth", 30.0).unwrap();
    let scan = node.subscribe_raw_at_most("sim.scan", 30.0).unwrap();
    let (mut got_truth, mut got_scan) = (false, false);
    let deadline = Instant::now() + PATIENCE;
    while !(got_truth && got_scan) {
        assert!(
            Instant::now() < deadline,
            "the observer's live data within {PATIENCE:?}: pose {got_truth}, scan {got_scan}"
        );
        if let armor_module_api::Event::Input(id) =
            node.next_event(Some(Duration::from_millis(100))).unwrap()
        {
            if id == truth.id() {
                got_truth |= node.take_raw(&truth).is_some();
            } else if id == scan.id() {
                got_scan |= node.take_raw(&scan).is_some();
            }
        }
    }
    drop(node);

    // Publishes nothing, neither under its own name nor under a module's.
    let key = armor_module_api::auth::RoleKey::load(&observer)
        .unwrap()
        .key;
    let advert = |data_name: &str| Advert {
        data_name: data_name.to_owned(),
        data_type: "Twist".to_owned(),
        addr: "127.0.0.1:9".to_owned(),
        key: None,
    };
    for (module, data_name) in [("role:observer", "pad.cmd_vel"), ("pad", "pad.cmd_vel")] {
        let answer = ask_agent(
            agent,
            key.clone(),
            "role:observer",
            &ToAgent::Register {
                module: module.to_owned(),
                outputs: vec![advert(data_name)],
            },
        );
        assert!(
            matches!(answer, FromAgent::Error { .. }),
            "the observer registered {data_name} as {module}: {answer:?}"
        );
    }
    // Takes no module's name: its key proves only its reader name.
    for module in ["pad", "sim", "observer"] {
        assert!(
            armor_tests::dial_as(agent, key.clone(), module).is_err(),
            "the observer's key passed as `{module}` at the agent"
        );
    }
    // Commands nothing.
    for command in [&["abort"][..], &["teleop", "0.3", "0"]] {
        let mut args = vec![
            "--addr",
            control.as_str(),
            "--key",
            observer.to_str().unwrap(),
        ];
        args.extend_from_slice(command);
        let (ok, text, _) = ctl(&args);
        assert!(!ok && text.contains("observer"), "{command:?}: {text}");
    }
    // A stranger without a key gets nothing from the agent, not even its hello.
    let mut stranger = TcpStream::connect(agent).unwrap();
    let mut asked = blocking_hello();
    asked.extend_from_slice(b"{\"type\":\"lookup\",\"data_name\":\"sim.pose_truth\"}");
    stranger.write_all(&asked).unwrap();
    let (got, closed) = read_until_closed(&mut stranger, STRANGER_CLOSED_WITHIN * 2);
    assert!(
        got.is_empty(),
        "the agent sent a stranger {} bytes",
        got.len()
    );
    assert!(closed.is_some(), "the agent kept a stranger");
}

/// The hello every connection starts with.
fn blocking_hello() -> Vec<u8> {
    let mut hello = Vec::new();
    blocking::write_hello(&mut hello).unwrap();
    hello
}

/// Strangers that hold `count` connections to `target`, each of which said its hello and
/// nothing more, opening new ones as the run closes them; each connection counted in `made`.
fn strangers_after_hello(
    target: SocketAddr,
    count: usize,
    stop: &Arc<AtomicBool>,
    made: &Arc<AtomicUsize>,
) -> std::thread::JoinHandle<()> {
    let stop = Arc::clone(stop);
    let made = Arc::clone(made);
    std::thread::spawn(move || {
        let mut held: Vec<TcpStream> = Vec::new();
        let mut buf = [0; 64];
        while !stop.load(Ordering::Relaxed) {
            // The run's hello is read; a connection the run closed is replaced.
            held.retain(|stream| {
                loop {
                    match (&*stream).read(&mut buf) {
                        Ok(0) => return false,
                        Ok(_) => {}
                        Err(err) => return err.kind() == std::io::ErrorKind::WouldBlock,
                    }
                }
            });
            while held.len() < count {
                let Ok(mut stream) = TcpStream::connect(target) else {
                    break;
                };
                if stream.write_all(&blocking_hello()).is_err()
                    || stream.set_nonblocking(true).is_err()
                {
                    continue;
                }
                made.fetch_add(1, Ordering::Relaxed);
                held.push(stream);
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    })
}

/// A process's threads (`/proc/PID/task`) and resident memory in KiB (`VmRSS`).
fn threads_and_rss_kib(pid: i32) -> (usize, u64) {
    let threads = std::fs::read_dir(format!("/proc/{pid}/task")).map_or(0, Iterator::count);
    let rss = std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|status| {
            status
                .lines()
                .find_map(|line| line.strip_prefix("VmRSS:"))
                .and_then(|value| value.split_whitespace().next()?.parse().ok())
        })
        .unwrap_or(0);
    (threads, rss)
}

/// The most threads, and resident memory, that 1,000 idle strangers at each of the agent and
/// the control interface may add to its process: a thread or two of the run's own come and
/// go, and a stranger costs a socket and a small buffer, not a thread.
const STRANGERS_THREAD_BUDGET: usize = 8;
const STRANGERS_RSS_BUDGET_KIB: u64 = 8 * 1024;

/// Asserts that strangers took the process `what` from `before` to `during` (threads, KiB)
/// within the budgets above.
fn assert_within_strangers_budget(what: &str, before: (usize, u64), during: (usize, u64)) {
    let ((threads_before, rss_before), (threads, rss)) = (before, during);
    assert!(
        threads <= threads_before + STRANGERS_THREAD_BUDGET,
        "{what} went from {threads_before} to {threads} threads"
    );
    assert!(
        rss <= rss_before + STRANGERS_RSS_BUDGET_KIB,
        "{what} went from {rss_before} to {rss} KiB"
    );
}

/// Without a secret, 1,000 strangers at the agent and 1,000 at the control interface that
/// complete the hello and say nothing more get no thread: the agent and `armor run` stay
/// within a stated budget of threads and memory, and `armor ctl abort` gets in within 2 s,
/// 10 times out of 10 (a run each: an abort ends its run).
#[test]
fn a_thousand_idle_strangers_cost_no_thread_and_the_operator_gets_in() {
    let dir = tempfile::tempdir().unwrap();
    let mission = waiting_mission(dir.path());
    for round in 1..=10 {
        let (mut run, control) = armor_tests::run_with_control(&mission);
        let status = armor_tests::ctl_status(&control);
        let agent: SocketAddr = status["agent"].as_str().unwrap().parse().unwrap();
        let agent_pid = children_of(run.pid())
            .into_iter()
            .find(|&pid| {
                std::fs::read(format!("/proc/{pid}/cmdline"))
                    .is_ok_and(|line| line.split(|&b| b == 0).nth(1) == Some(b"agent"))
            })
            .unwrap();
        let before = [
            threads_and_rss_kib(run.pid()),
            threads_and_rss_kib(agent_pid),
        ];
        let stop = Arc::new(AtomicBool::new(false));
        let at_control = Arc::new(AtomicUsize::new(0));
        let at_agent = Arc::new(AtomicUsize::new(0));
        let holders = [
            strangers_after_hello(control.parse().unwrap(), 1000, &stop, &at_control),
            strangers_after_hello(agent, 1000, &stop, &at_agent),
        ];
        wait_until("1,000 strangers at each port", PATIENCE, || {
            at_control.load(Ordering::Relaxed) >= 1000 && at_agent.load(Ordering::Relaxed) >= 1000
        });
        let during = [
            threads_and_rss_kib(run.pid()),
            threads_and_rss_kib(agent_pid),
        ];
        let (ok, text, took) = ctl(&["--addr", &control, "abort"]);
        stop.store(true, Ordering::Relaxed);
        for holder in holders {
            holder.join().unwrap();
        }
        println!(
            "round {round}: threads and KiB of [armor run, the agent] before {before:?}, \
             with the strangers {during:?}; abort took {took:?}"
        );
        assert!(ok, "round {round}: abort: {text}");
        assert!(
            took <= STRANGER_CLOSED_WITHIN,
            "round {round}: abort took {took:?}: {text}"
        );
        for (what, before, during) in [
            ("armor run", before[0], during[0]),
            ("the agent", before[1], during[1]),
        ] {
            assert_within_strangers_budget(&format!("round {round}: {what}"), before, during);
        }
        run.wait_exit(PATIENCE);
    }
}

/// `armor host` on loopback without a secret, as a user would start one beside a run, and the
/// address it listens on.
fn loopback_host_without_secret() -> (Proc, SocketAddr) {
    let host = Proc::start(
        Command::new(bin("armor"))
            .args(["host", "--name", "robot1", "--listen", "127.0.0.1:0"])
            .env("ARMOR_MODULE_PATH", bin_dir())
            .env_remove(armor_module_api::auth::ENV_SECRET_FILE),
    );
    let line = host.wait_for("its address", PATIENCE, |line| {
        line.starts_with(armor_runtime::host::HOST_READY_PREFIX)
    });
    let addr = line
        .trim_start_matches(armor_runtime::host::HOST_READY_PREFIX)
        .trim()
        .parse()
        .unwrap();
    (host, addr)
}

/// The config server's port of a run without a secret: of the two ports `armor run` itself
/// listens on, the one that is not the control interface's.
fn config_server_port(run: &Proc, control: &str) -> SocketAddr {
    let control: SocketAddr = control.parse().unwrap();
    let others: Vec<u16> = listening_ports(&[run.pid()])
        .into_iter()
        .filter(|&port| port != control.port())
        .collect();
    assert_eq!(
        others.len(),
        1,
        "armor run listens on {others:?} besides control"
    );
    SocketAddr::from(([127, 0, 0, 1], others[0]))
}

/// The pid of the module `name` when the run's status shows it running.
fn running_pid(control: &str, name: &str) -> Option<u64> {
    armor_tests::ctl_status(control)["modules"]
        .as_array()?
        .iter()
        .find(|module| module["name"] == name && module["state"] == "running")?["pid"]
        .as_u64()
}

/// Without a secret, 1,000 strangers at a run's config server that complete the hello and say
/// nothing more get no thread of `armor run`, and a module that starts meanwhile (the counter,
/// killed and started again by the run) is configured at once.
#[test]
fn a_thousand_hello_only_strangers_at_the_config_server_cost_no_thread() {
    let dir = tempfile::tempdir().unwrap();
    let mission = waiting_mission(dir.path());
    let (run, control) = armor_tests::run_with_control(&mission);
    let mut first_pid = None;
    wait_until("the counter running", PATIENCE, || {
        first_pid = running_pid(&control, "counter");
        first_pid.is_some()
    });
    let config_server = config_server_port(&run, &control);
    let stop = Arc::new(AtomicBool::new(false));
    let (before, during, holder) = thousand_strangers_at(config_server, run.pid(), &stop);
    // A module that connects now, as a restarted one does, is served among the strangers.
    armor_tests::signal(i32::try_from(first_pid.unwrap()).unwrap(), libc::SIGKILL);
    let killed = Instant::now();
    wait_until("the counter configured again", PATIENCE, || {
        running_pid(&control, "counter").is_some_and(|pid| Some(pid) != first_pid)
    });
    let back_after = killed.elapsed();
    let after = threads_and_rss_kib(run.pid());
    stop.store(true, Ordering::Relaxed);
    holder.join().unwrap();
    println!(
        "threads and KiB of armor run: before {before:?}, with 1,000 strangers at its config \
         server {during:?}, after the counter's restart among them {after:?}; the killed \
         counter was running again after {back_after:?}"
    );
    assert_within_strangers_budget("armor run", before, during);
}

/// 1,000 strangers at `target` that say their hello and nothing more (see
/// [`strangers_after_hello`]), until `stop`: the threads and KiB of the process `pid` before
/// they came and once they are there, and the thread that holds them.
fn thousand_strangers_at(
    target: SocketAddr,
    pid: i32,
    stop: &Arc<AtomicBool>,
) -> ((usize, u64), (usize, u64), std::thread::JoinHandle<()>) {
    let before = threads_and_rss_kib(pid);
    let made = Arc::new(AtomicUsize::new(0));
    let holder = strangers_after_hello(target, 1000, stop, &made);
    wait_until("1,000 strangers", PATIENCE, || {
        made.load(Ordering::Relaxed) >= 1000
    });
    (before, threads_and_rss_kib(pid), holder)
}

/// `count` connections to `target` that each said the hello and then `first`, and were
/// answered (a message whose `field` is `value`) before the next connected.
fn peers_answered(
    target: SocketAddr,
    first: &serde_json::Value,
    count: usize,
    (field, value): (&str, &str),
) -> Vec<TcpStream> {
    let mut said = blocking_hello();
    blocking::write_message(&mut said, first).unwrap();
    (0..count)
        .map(|_| {
            let mut stream = TcpStream::connect(target).unwrap();
            stream.set_read_timeout(Some(PATIENCE)).unwrap();
            stream.write_all(&said).unwrap();
            blocking::read_hello(&mut stream).unwrap();
            let answer: serde_json::Value = blocking::read_message(&mut stream).unwrap();
            assert_eq!(answer[field], value, "{answer}");
            stream
        })
        .collect()
}

/// The threads and KiB of `pid` once its threads are back within the strangers' budget over
/// `before`, or after `within`; and the most threads seen on the way.
fn threads_once_settled(pid: i32, before: (usize, u64), within: Duration) -> ((usize, u64), usize) {
    let deadline = Instant::now() + within;
    let mut most = before.0;
    loop {
        let now = threads_and_rss_kib(pid);
        most = most.max(now.0);
        if now.0 <= before.0 + STRANGERS_THREAD_BUDGET || Instant::now() >= deadline {
            return (now, most);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Without a secret, peers that say a module's `hello` to the config server (the counter's,
/// on 300 connections kept open) cost one thread for the name, not one each: a module has one
/// connection, and a newer one closes the older.
#[test]
fn peers_that_say_a_modules_hello_cost_one_thread_for_the_name() {
    let dir = tempfile::tempdir().unwrap();
    let mission = waiting_mission(dir.path());
    let (run, control) = armor_tests::run_with_control(&mission);
    wait_until("the counter running", PATIENCE, || {
        running_pid(&control, "counter").is_some()
    });
    let config_server = config_server_port(&run, &control);
    let hello = serde_json::json!({"type": "hello", "module": "counter", "pid": 1});
    let before = threads_and_rss_kib(run.pid());
    let held = peers_answered(config_server, &hello, 300, ("type", "config"));
    // Within the deadline: the older connections' threads end once the newer ones close them.
    let (now, most) = threads_once_settled(run.pid(), before, PATIENCE);
    println!(
        "threads and KiB of armor run: before {before:?}, with 300 peers that said the \
         counter's hello {now:?} (at most {most} threads on the way)"
    );
    assert!(
        now.0 <= before.0 + STRANGERS_THREAD_BUDGET,
        "300 peers that said the counter's hello hold {} threads of armor run ({} before)",
        now.0,
        before.0
    );
    drop(held);
}

/// Without a secret, 1,000 strangers at a loopback `armor host` that complete the hello and
/// say nothing more get no thread of the daemon, and a real supervisor is served at once:
/// `armor check` asks the host its module types, and `armor run` starts its module there.
#[test]
fn a_thousand_hello_only_strangers_at_a_loopback_host_cost_no_thread() {
    let dir = tempfile::tempdir().unwrap();
    let (host, addr) = loopback_host_without_secret();
    let system = dir.path().join("system.xml");
    std::fs::write(
        &system,
        format!(
            r#"<system name="hosted">
  <host name="robot1" address="127.0.0.1" port="{}"/>
  <module name="counter" type="counter" host="robot1"><param name="period_secs" value="0.1"/></module>
</system>
"#,
            addr.port()
        ),
    )
    .unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let (before, during, holder) = thousand_strangers_at(addr, host.pid(), &stop);
    // A supervisor's questions (`armor check`), then a run that places its counter there.
    let started = Instant::now();
    let check = Command::new(bin("armor"))
        .arg("check")
        .arg(&system)
        .env("ARMOR_MODULE_PATH", bin_dir())
        .env_remove(armor_module_api::auth::ENV_SECRET_FILE)
        .output()
        .unwrap();
    let check_took = started.elapsed();
    let check_said = format!(
        "{}{}",
        String::from_utf8_lossy(&check.stdout),
        String::from_utf8_lossy(&check.stderr)
    );
    let (_run, control) = armor_tests::run_with_control(&system);
    let started = Instant::now();
    wait_until("the counter running on the host", PATIENCE, || {
        running_pid(&control, "counter").is_some()
    });
    let run_took = started.elapsed();
    stop.store(true, Ordering::Relaxed);
    holder.join().unwrap();
    println!(
        "threads and KiB of armor host: before {before:?}, with 1,000 strangers {during:?}; \
         armor check took {check_took:?}; the run's counter ran there {run_took:?} after the \
         run's control interface"
    );
    assert!(
        check.status.success() && !check_said.contains("not asked"),
        "armor check among the strangers: {check_said}"
    );
    assert!(
        check_took <= STRANGER_CLOSED_WITHIN,
        "armor check took {check_took:?} among the strangers"
    );
    assert_within_strangers_budget("armor host", before, during);
}

/// Without a secret, peers that say a query's `hello` to a loopback `armor host` (as
/// `armor check` does) and then idle, on 300 connections kept open, hold no more than a few
/// threads of the daemon: it answers a few queries at once and refuses more, saying why.
#[test]
fn idle_queries_at_a_loopback_host_hold_a_few_threads() {
    let (host, addr) = loopback_host_without_secret();
    let hello =
        serde_json::json!({"op": "hello", "run": "stranger", "orphan_ms": 0, "query": true});
    let before = threads_and_rss_kib(host.pid());
    let held = peers_answered(addr, &hello, 300, ("op", "welcome"));
    // Within 2 s, well inside the 10 s after which the daemon closes a quiet query: the
    // refused queries' threads end as they are told.
    let (during, _) = threads_once_settled(host.pid(), before, STRANGER_CLOSED_WITHIN);
    // The last one was refused, and told why.
    let mut last = held.last().unwrap();
    let told = blocking::read_message::<serde_json::Value>(&mut last);
    println!(
        "threads and KiB of armor host: before {before:?}, with 300 idle queries {during:?}; \
         the last was told {told:?}"
    );
    assert!(
        during.0 <= before.0 + STRANGERS_THREAD_BUDGET,
        "300 idle queries hold {} threads of armor host ({} before)",
        during.0,
        before.0
    );
    assert!(
        told.as_ref().is_ok_and(|told| told["op"] == "refused"),
        "the last query was told {told:?}"
    );
}

/// How many control clients a run keeps open (`armor_runtime::control`'s table).
const CONTROL_CLIENTS: usize = 64;

/// A control client without a key, as an attacker on the same machine writes one: the hello
/// and a `status` request (number 1), its reply read, then nothing more. `None` when the run
/// closed it instead of answering.
fn idle_status_client(control: SocketAddr) -> Option<TcpStream> {
    use armor_protocol::{FromRun, Request, ToRun};
    let mut stream = TcpStream::connect(control).ok()?;
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    blocking::write_hello(&mut stream).ok()?;
    let status = ToRun {
        seq: 1,
        request: Request::Status,
    };
    blocking::write_message(&mut stream, &status).ok()?;
    blocking::read_hello(&mut stream).ok()?;
    let reply: FromRun = blocking::read_message(&mut stream).ok()?;
    (reply.seq == 1 && reply.reply.ok).then_some(stream)
}

/// What an idle control client got since its last reply, within `wait`: the run's messages
/// (replies it did not ask for yet), and whether the run closed the connection.
fn what_an_idle_client_got(stream: &mut TcpStream, wait: Duration) -> (Vec<String>, bool) {
    let (bytes, closed) = read_until_closed(stream, wait);
    let mut messages = Vec::new();
    let mut rest = bytes.as_slice();
    while !rest.is_empty() {
        match blocking::read_message::<armor_protocol::FromRun>(&mut rest) {
            Ok(answer) => messages.push(format!(
                "{} (ok {}): {}",
                answer.seq, answer.reply.ok, answer.reply.message
            )),
            Err(err) => {
                messages.push(format!("undecodable: {err}"));
                break;
            }
        }
    }
    (messages, closed.is_some())
}

/// Without a secret, 71 clients that each asked for the status and then idle (more than the
/// run keeps open), and 1,000 strangers that said their hello, do not keep `armor ctl abort`
/// out: it gets in within 2 s, 10 times out of 10 (a run each: an abort ends its run). The
/// clients that idled the longest make room, each told why and closed at once, not left to
/// hang (a client kept as the studio keeps one hears it as the reply to its next request);
/// the others stay open.
#[test]
fn without_a_secret_idle_control_clients_make_room_for_the_operator() {
    let dir = tempfile::tempdir().unwrap();
    let mission = waiting_mission(dir.path());
    let clients = CONTROL_CLIENTS + 6;
    for round in 1..=10 {
        let (mut run, control) = armor_tests::run_with_control(&mission);
        let target: SocketAddr = control.parse().unwrap();
        // The oldest is a client as the studio keeps one: it is told why at its next request.
        let mut kept = armor_protocol::Client::connect(target, None).unwrap();
        assert!(kept.call(&armor_protocol::Request::Status).unwrap().ok);
        let mut idle: Vec<Option<TcpStream>> =
            (0..clients).map(|_| idle_status_client(target)).collect();
        let answered = idle.iter().filter(|client| client.is_some()).count();
        // Those that did not idle the longest are still open, with nothing to read.
        let open_after_the_last = idle
            .iter()
            .skip(clients - CONTROL_CLIENTS)
            .flatten()
            .filter(|client| {
                let mut stream: &TcpStream = client;
                let mut byte = [0];
                stream.set_nonblocking(true).is_ok()
                    && matches!(stream.read(&mut byte), Err(err) if err.kind() == std::io::ErrorKind::WouldBlock)
                    && stream.set_nonblocking(false).is_ok()
            })
            .count();
        let asked = Instant::now();
        let kept_told = kept.call(&armor_protocol::Request::Status);
        let kept_told_within = asked.elapsed();
        let stop = Arc::new(AtomicBool::new(false));
        let made = Arc::new(AtomicUsize::new(0));
        let holder = strangers_after_hello(target, 1000, &stop, &made);
        wait_until("1,000 strangers at the control port", PATIENCE, || {
            made.load(Ordering::Relaxed) >= 1000
        });
        let (ok, text, took) = ctl(&["--addr", &control, "abort"]);
        stop.store(true, Ordering::Relaxed);
        holder.join().unwrap();
        // The abort took the place of one more idle client: the oldest seven made room.
        let made_room = clients + 1 - CONTROL_CLIENTS;
        let mut told = Vec::new();
        for (index, client) in idle.iter_mut().take(made_room).enumerate() {
            let Some(client) = client else { continue };
            told.push((
                index,
                what_an_idle_client_got(client, STRANGER_CLOSED_WITHIN),
            ));
        }
        println!(
            "round {round}: {answered} of {clients} idle clients answered; abort took {took:?}; \
             the studio-like client was told {kept_told:?} within {kept_told_within:?}, \
             the oldest of the others {:?}",
            told.first()
        );
        assert!(ok, "round {round}: abort: {text}");
        assert!(
            took <= STRANGER_CLOSED_WITHIN,
            "round {round}: abort took {took:?}: {text}"
        );
        assert_eq!(
            answered, clients,
            "round {round}: a client without a secret was refused while others idled"
        );
        assert_eq!(
            open_after_the_last, CONTROL_CLIENTS,
            "round {round}: of the {CONTROL_CLIENTS} newest idle clients, only \
             {open_after_the_last} were still open"
        );
        let kept_told = kept_told.map(|reply| (reply.ok, reply.message));
        assert!(
            matches!(&kept_told, Ok((false, message)) if message.contains("idle"))
                && kept_told_within <= STRANGER_CLOSED_WITHIN,
            "round {round}: the client idle the longest was told {kept_told:?} within \
             {kept_told_within:?}"
        );
        for (index, (messages, closed)) in told {
            assert!(
                closed && messages.iter().any(|message| message.contains("idle")),
                "round {round}: idle client {index} was not told why it was closed: \
                 {messages:?}, closed: {closed}"
            );
        }
        run.wait_exit(PATIENCE);
    }
}

/// With a secret an operator is never closed to make room: one who connected first and idles
/// keeps its connection while 70 observers come (those beyond the table are refused), and
/// aborts through it; a second operator arriving then closes the observer idle the longest.
#[test]
fn with_a_secret_an_idle_operator_is_not_closed_and_a_new_one_replaces_an_observer() {
    let dir = tempfile::tempdir().unwrap();
    let secret = secret_file(dir.path());
    let observer = armor_protocol::key_from_file(&role_key(&secret, "observer")).unwrap();
    let mission = waiting_mission(dir.path());
    let (_run, control) = run_with_secret(&mission, &secret);
    let target: SocketAddr = control.parse().unwrap();
    let operator_secret = Secret::load(&secret).unwrap();
    let mut operator = armor_protocol::Client::connect(target, Some(&operator_secret)).unwrap();
    assert!(operator.call(&armor_protocol::Request::Status).unwrap().ok);
    let observers: Vec<anyhow::Result<armor_protocol::Client>> = (0..CONTROL_CLIENTS + 6)
        .map(|_| {
            let mut client = armor_protocol::Client::connect_with(target, Some(&observer))?;
            let reply = client.call(&armor_protocol::Request::Status)?;
            reply
                .ok
                .then_some(client)
                .ok_or_else(|| anyhow::anyhow!(reply.message))
        })
        .collect();
    let answered = observers.iter().filter(|client| client.is_ok()).count();
    // A second operator arriving at the full table takes the place of the observer idle the
    // longest: observers' keys cannot shut an operator out.
    let latecomer = armor_protocol::Client::connect(target, Some(&operator_secret))
        .map_err(|err| format!("{err:#}"))
        .and_then(|mut client| {
            client
                .call(&armor_protocol::Request::Status)
                .map(|reply| (reply.ok, reply.message))
                .map_err(|err| format!("{err:#}"))
        });
    let abort = operator
        .call(&armor_protocol::Request::Abort)
        .map(|reply| (reply.ok, reply.message));
    println!(
        "{answered} of {} observers answered besides the idle operator; a second operator's \
         status: {latecomer:?}; the first's abort: {abort:?}",
        observers.len()
    );
    assert_eq!(answered, CONTROL_CLIENTS - 1, "observers answered");
    assert!(
        latecomer.as_ref().is_ok_and(|(ok, _)| *ok),
        "an operator arriving at a table full of observers: {latecomer:?}"
    );
    assert!(
        abort.as_ref().is_ok_and(|(ok, _)| *ok),
        "the operator's abort on its idle connection: {abort:?}"
    );
}
