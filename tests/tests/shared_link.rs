//! Two modules that subscribe to each other share one TCP connection, whichever starts first,
//! and keep sharing after one of them is killed and comes back; messages of megabytes go both
//! ways whole; a subscription refused on a shared connection leaves the other direction
//! flowing.
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::process::Command;
use std::time::{Duration, Instant};

use armor_module_api::types::{Blob, Counter};
use armor_module_api::{Input, ModuleSpec, Node, Output};
use armor_tests::{PATIENCE, Proc, bin, process_alive, start_agent, test_node};

fn start_echo(agent: SocketAddr) -> Proc {
    Proc::start(Command::new(bin("armor-mod-echo")).args([
        "--name",
        "echo",
        "--agent",
        &agent.to_string(),
        "--bind",
        "input=tester.ping",
    ]))
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
        let spec = ModuleSpec::new("tester", "pings the echo")
            .output::<Blob>("ping", "numbered messages")
            .input::<Blob>("pong", "the same, echoed");
        let mut node = test_node(spec, agent, &[("pong", "echo.output")]);
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
    for round in 0..6 {
        // Even rounds: the echo first (it waits for `tester.ping`); odd: the tester first.
        let (mut tester, echo) = if round % 2 == 0 {
            let echo = start_echo(agent);
            (Tester::start(agent), echo)
        } else {
            let tester = Tester::start(agent);
            (tester, start_echo(agent))
        };
        tester.link(&echo);
        tester.ping_pong(200);
        // Both subscriptions on one connection: the echo opened none of its own to the tester
        // (this side would have accepted it), and this side none to the echo.
        assert_eq!(tester.node.data_connections(), 1, "round {round}");
        drop(echo);
        drop(tester);
    }
}

#[test]
fn large_messages_go_through_the_echo_and_back_whole() {
    let (_agent, agent) = start_agent();
    let mut tester = Tester::start(agent);
    let echo = start_echo(agent);
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
    let echo = start_echo(agent);
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
    let echo = start_echo(agent);
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
