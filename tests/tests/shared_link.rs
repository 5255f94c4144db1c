//! Two modules that subscribe to each other share one TCP connection, whichever starts first,
//! and keep sharing after one of them is killed and comes back; messages of megabytes go both
//! ways whole; a subscription refused on a shared connection, or given up when its input is
//! rebound, leaves the other direction flowing.
#![allow(clippy::unwrap_used)]

use std::net::{SocketAddr, TcpListener};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use armor_module_api::auth::ENV_SECRET_FILE;
use armor_module_api::protocol::{FromSupervisor, ModuleConfig, ToSupervisor};
use armor_module_api::types::{Blob, Counter};
use armor_module_api::wire::blocking;
use armor_module_api::{
    ENV_AGENT, ENV_MODULE, ENV_SUPERVISOR, Input, ModuleSpec, Node, Output, Standalone,
};
use armor_tests::{PATIENCE, Proc, bin, process_alive, start_agent, start_agent_with, test_node};

fn start_echo(agent: SocketAddr, secret: Option<&Path>) -> Proc {
    let mut command = Command::new(bin("armor-mod-echo"));
    command.args([
        "--name",
        "echo",
        "--agent",
        &agent.to_string(),
        "--bind",
        "input=tester.ping",
    ]);
    if let Some(secret) = secret {
        command.env(ENV_SECRET_FILE, secret);
    }
    Proc::start(&mut command)
}

/// This process's side of a ping-pong with `armor-mod-echo`.
struct Tester {
    node: Node,
    ping: Output<Blob>,
    pong: Input<Blob>,
    seq: u64,
}

impl Tester {
    fn start(agent: SocketAddr) -> Self {
        Self::start_with(agent, None)
    }

    /// A tester that proves `secret` on every connection, when given.
    fn start_with(agent: SocketAddr, secret: Option<&Path>) -> Self {
        let spec = ModuleSpec::new("tester", "pings the echo")
            .output::<Blob>("ping", "numbered messages")
            .input::<Blob>("pong", "the same, echoed");
        let mut node = Node::connect(
            spec,
            Standalone {
                name: Some("tester".to_owned()),
                agent: Some(agent.to_string()),
                binds: vec![("pong".to_owned(), "echo.output".to_owned())],
                secret: secret.map(Path::to_path_buf),
                ..Standalone::default()
            },
        )
        .unwrap();
        let ping = node.output::<Blob>("ping").unwrap();
        let pong = node.reliable_input::<Blob>("pong").unwrap();
        Self {
            node,
            ping,
            pong,
            seq: 0,
        }
    }

    fn send(&mut self) -> u64 {
        self.seq += 1;
        let message = Blob(self.seq.to_le_bytes().to_vec());
        self.node.send(&self.ping, &message).unwrap();
        self.seq
    }

    /// The sequence numbers echoed until `deadline` or until one equals `until`.
    fn receive(&mut self, until: u64, deadline: Instant) -> Vec<u64> {
        let mut got = Vec::new();
        while Instant::now() < deadline {
            self.node.next_event_until(deadline).unwrap();
            while let Some(sample) = self.node.take(&self.pong).unwrap() {
                got.push(u64::from_le_bytes(sample.value.0[..8].try_into().unwrap()));
            }
            if got.last() == Some(&until) {
                break;
            }
        }
        got
    }

    /// Pings until a pong comes back (before both links are up, pings are lost), then lets
    /// stale pongs arrive.
    fn link(&mut self, echo: &Proc) {
        let give_up = Instant::now() + PATIENCE;
        loop {
            let seq = self.send();
            if !self
                .receive(seq, Instant::now() + Duration::from_millis(20))
                .is_empty()
            {
                break;
            }
            assert!(
                process_alive(echo.pid()),
                "the echo exited:\n{}",
                echo.lines().join("\n")
            );
            assert!(Instant::now() < give_up, "no pong within {PATIENCE:?}");
        }
        let seq = self.send();
        let got = self.receive(seq, Instant::now() + PATIENCE);
        assert_eq!(got.last(), Some(&seq), "the last ping is echoed");
    }

    /// One message in flight at a time, each echoed back in order.
    fn ping_pong(&mut self, count: usize) {
        for _ in 0..count {
            let seq = self.send();
            assert_eq!(self.receive(seq, Instant::now() + PATIENCE), [seq]);
        }
    }
}

#[test]
fn a_module_and_its_echo_share_one_connection_whichever_starts_first() {
    let (_agent, agent) = start_agent();
    let shared = ping_pong_rounds(agent, None, 6);
    assert_eq!(shared, 6, "rounds on one connection");
}

#[test]
fn with_a_shared_secret_they_share_one_connection_too() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let secret = dir.path().join("secret");
    std::fs::write(&secret, "a secret the pair proves on every link").unwrap();
    std::fs::set_permissions(&secret, std::fs::Permissions::from_mode(0o600)).unwrap();
    let (_agent, agent) = start_agent_with(&["--secret", secret.to_str().unwrap()]);
    // The handshake's round trips come before a subscribe, so a module waits a moment for a
    // peer that has just connected to say who it is; when both open a connection within that
    // moment, they may keep both (about one round in fifty here, against one in three without
    // the wait).
    let shared = ping_pong_rounds(agent, Some(&secret), 10);
    assert!(shared >= 8, "{shared} of 10 rounds on one connection");
}

/// Starts the echo and the tester in turn, each first in half the rounds; they ping-pong.
/// Returns in how many rounds both subscriptions were on one connection.
fn ping_pong_rounds(agent: SocketAddr, secret: Option<&Path>, rounds: usize) -> usize {
    let mut shared = 0;
    for round in 0..rounds {
        // Even rounds: the echo first (it waits for `tester.ping`); odd: the tester first.
        let (mut tester, echo) = if round % 2 == 0 {
            let echo = start_echo(agent, secret);
            (Tester::start_with(agent, secret), echo)
        } else {
            let tester = Tester::start_with(agent, secret);
            (tester, start_echo(agent, secret))
        };
        tester.link(&echo);
        tester.ping_pong(200);
        // Both subscriptions on one connection: the echo opened none of its own to the tester
        // (this side would have accepted it), and this side none to the echo.
        let connections = tester.node.data_connections();
        assert!(connections <= 2, "round {round}: {connections} connections");
        shared += usize::from(connections == 1);
        drop(echo);
        drop(tester);
    }
    shared
}

#[test]
fn large_messages_go_through_the_echo_and_back_whole() {
    let (_agent, agent) = start_agent();
    let mut tester = Tester::start(agent);
    let echo = start_echo(agent, None);
    tester.link(&echo);
    // Several megabytes each, several in flight: the frames are read straight into their
    // payload buffers, across many reads, and written from the sender's buffer or its queue.
    let sizes = [3 * 1024 * 1024 + 5, 256 * 1024, 5 * 1024 * 1024, 1];
    let messages: Vec<Blob> = sizes
        .iter()
        .enumerate()
        .map(|(n, &size)| Blob((0..size).map(|i| ((i * 7 + n) % 251) as u8).collect()))
        .collect();
    for message in &messages {
        tester.node.send(&tester.ping, message).unwrap();
    }
    let mut got = Vec::new();
    let deadline = Instant::now() + PATIENCE;
    while got.len() < messages.len() {
        assert!(Instant::now() < deadline, "{} of 4 came back", got.len());
        tester.node.next_event_until(deadline).unwrap();
        while let Some(sample) = tester.node.take(&tester.pong).unwrap() {
            got.push(sample.value);
        }
    }
    assert!(got == messages, "the same bytes, in order");
}

#[test]
fn a_shared_connection_comes_back_after_the_peer_is_killed() {
    let (_agent, agent) = start_agent();
    let mut tester = Tester::start(agent);
    let echo = start_echo(agent, None);
    tester.link(&echo);
    assert_eq!(tester.node.data_connections(), 1);
    // SIGKILL: the connection closes under both subscriptions at once.
    drop(echo);
    let deadline = Instant::now() + PATIENCE;
    while tester.node.is_linked(&tester.pong) || tester.node.subscriber_count(&tester.ping) > 0 {
        assert!(Instant::now() < deadline, "the loss is not noticed");
        tester
            .node
            .next_event(Some(Duration::from_millis(10)))
            .unwrap();
    }
    assert_eq!(tester.node.data_connections(), 0);
    let echo = start_echo(agent, None);
    tester.link(&echo);
    tester.ping_pong(100);
    assert_eq!(tester.node.data_connections(), 1);
}

#[test]
fn a_refused_subscription_on_a_shared_connection_leaves_the_other_direction_flowing() {
    let (_agent, agent) = start_agent();
    // `left` serves counts and takes `right.count`; `right` asks for `left.count` as a Blob,
    // which `left` refuses on the connection `right` already uses for its own output.
    let mut left = test_node(
        ModuleSpec::new("left", "counts")
            .output::<Counter>("count", "a count")
            .input::<Counter>("theirs", "right's count"),
        agent,
        &[("theirs", "right.count")],
    );
    let left_out = left.output::<Counter>("count").unwrap();
    let theirs = left.reliable_input::<Counter>("theirs").unwrap();
    let mut right = test_node(
        ModuleSpec::new("right", "counts too")
            .output::<Counter>("count", "a count")
            .input::<Blob>("wrong", "left's count, as the wrong type"),
        agent,
        &[("wrong", "left.count")],
    );
    let right_out = right.output::<Counter>("count").unwrap();
    let wrong = right.input::<Blob>("wrong").unwrap();

    let deadline = Instant::now() + PATIENCE;
    let mut received = Vec::new();
    let mut next = 0;
    while received.len() < 50 {
        assert!(
            Instant::now() < deadline,
            "right's counts do not reach left (got {received:?})"
        );
        if right.subscriber_count(&right_out) > 0 {
            next += 1;
            right.send(&right_out, &Counter(next)).unwrap();
        }
        left.send(&left_out, &Counter(next)).unwrap();
        right.next_event(Some(Duration::from_millis(1))).unwrap();
        left.next_event(Some(Duration::from_millis(1))).unwrap();
        while let Some(sample) = left.take(&theirs).unwrap() {
            received.push(sample.value.0);
        }
    }
    let first = received[0];
    assert_eq!(
        received,
        (first..first + 50).collect::<Vec<_>>(),
        "every count in order"
    );
    assert!(!right.is_linked(&wrong), "the wrong type is refused");
    assert_eq!(left.subscriber_count(&left_out), 0);
    assert!(left.is_linked(&theirs));
    assert_eq!(left.data_connections(), 1);
}

/// Plays `armor run`'s config server for one echo: configures it, then rebinds its input.
struct Supervisor {
    stream: blocking::SecureStream,
}

impl Supervisor {
    /// Starts an echo under this supervisor, with its input bound to `source`.
    fn start_echo(agent: SocketAddr, source: &str) -> (Supervisor, Proc) {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let echo = Proc::start(
            Command::new(bin("armor-mod-echo"))
                .env(ENV_SUPERVISOR, listener.local_addr().unwrap().to_string())
                .env(ENV_AGENT, agent.to_string())
                .env(ENV_MODULE, "echo"),
        );
        listener.set_nonblocking(true).unwrap();
        let deadline = Instant::now() + PATIENCE;
        let stream = loop {
            match listener.accept() {
                Ok((stream, _)) => break stream,
                Err(err) if err.kind() == std::io::ErrorKind::WouldBlock => {
                    assert!(Instant::now() < deadline, "the echo never connects");
                    assert!(process_alive(echo.pid()), "{}", echo.lines().join("\n"));
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(err) => panic!("accept: {err}"),
            }
        };
        stream.set_nonblocking(false).unwrap();
        stream.set_read_timeout(Some(PATIENCE)).unwrap();
        let (mut stream, _) = blocking::accept(stream, None).unwrap();
        let hello: ToSupervisor = blocking::read_message(&mut stream).unwrap();
        assert!(matches!(hello, ToSupervisor::Hello { .. }), "{hello:?}");
        let mut supervisor = Supervisor { stream };
        supervisor.bind(source);
        (supervisor, echo)
    }

    /// Sends the echo a configuration with its input bound to `source`.
    fn bind(&mut self, source: &str) {
        let config = ModuleConfig {
            module_type: "echo".to_owned(),
            inputs: [("input".to_owned(), source.to_owned())].into(),
            outputs: [("output".to_owned(), "echo.output".to_owned())].into(),
            active: true,
            host: "127.0.0.1".to_owned(),
            ..ModuleConfig::default()
        };
        blocking::write_message(&mut self.stream, &FromSupervisor::Config(config)).unwrap();
    }
}

#[test]
fn rebinding_an_input_keeps_a_shared_connection_for_the_other_direction() {
    let (_agent, agent) = start_agent();
    let mut tester = Tester::start(agent);
    let (mut supervisor, echo) = Supervisor::start_echo(agent, "tester.ping");
    tester.link(&echo);
    assert_eq!(tester.node.data_connections(), 1, "shared");
    let mut other = test_node(
        ModuleSpec::new("other", "pings too").output::<Blob>("ping", "numbered messages"),
        agent,
        &[],
    );
    let other_ping = other.output::<Blob>("ping").unwrap();

    // The echo's input moves to `other`: its connection with the tester stays, and the tester's
    // subscription to the echo goes on, on its first link, now echoing `other`.
    supervisor.bind("other.ping");
    const FROM_OTHER: u64 = 1 << 40;
    let deadline = Instant::now() + PATIENCE;
    let mut links = Vec::new();
    let mut sent = FROM_OTHER;
    while !links.iter().any(|&(_, value)| value > FROM_OTHER) {
        assert!(Instant::now() < deadline, "nothing of `other` echoed");
        sent += 1;
        other
            .send(&other_ping, &Blob(sent.to_le_bytes().to_vec()))
            .unwrap();
        other.next_event(Some(Duration::from_millis(1))).unwrap();
        tester
            .node
            .next_event(Some(Duration::from_millis(1)))
            .unwrap();
        while let Some(sample) = tester.node.take(&tester.pong).unwrap() {
            let value = u64::from_le_bytes(sample.value.0[..8].try_into().unwrap());
            links.push((sample.link, value));
        }
    }
    assert!(
        links.iter().all(|&(link, _)| link == 1),
        "the tester never relinked: {links:?}"
    );
    assert_eq!(tester.node.data_connections(), 1);

    // Bound back to the tester, the echo subscribes on the same connection again.
    supervisor.bind("tester.ping");
    tester.link(&echo);
    tester.ping_pong(50);
    assert_eq!(tester.node.data_connections(), 1);
    assert!(process_alive(echo.pid()));
}
