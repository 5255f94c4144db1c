//! A reliable subscriber notices that its provider is gone however the end reaches it, and links
//! to the provider's successor: here the end waits in the socket behind more samples than the
//! input's queue holds, so the subscriber meets it only after pausing and resuming its reads (the
//! case `messages_lost_under_kill` met under load, where the link then waited for ever).
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use armor_module_api::types::Counter;
use armor_module_api::{ModuleSpec, Node};
use armor_tests::{PATIENCE, start_agent, test_node};

/// How many values the first provider sends, in turn: each more than a reliable input queues
/// (1,024) and more bytes than one read takes (64 KiB), so the subscriber pauses its reads before
/// it reaches the end of the connection. Where the last read falls depends on the count: with
/// about 28 bytes a value, the counts from about 2,350 to 3,050 leave a short last read whose
/// values all fit in the queue, after which only the end of the connection is left unread.
const FIRST_GENERATIONS: [u64; 5] = [2_400, 2_600, 2_800, 3_000, 4_000];
/// Values of the second provider start here.
const SECOND_GENERATION: u64 = 1_000_000;

fn provider(agent: SocketAddr) -> (Node, armor_module_api::Output<Counter>) {
    let node = test_node(
        ModuleSpec::new("provider", "counts").output::<Counter>("count", "the count"),
        agent,
        &[],
    );
    let output = node.output::<Counter>("count").unwrap();
    (node, output)
}

/// A provider that sends `count` values at once to its first subscriber and ends (its
/// connections closed, as a killed process's are).
fn first_provider(agent: SocketAddr, count: u64) -> JoinHandle<()> {
    let (mut node, output) = provider(agent);
    std::thread::spawn(move || {
        let deadline = Instant::now() + PATIENCE;
        while node.subscriber_count(&output) == 0 {
            assert!(Instant::now() < deadline, "no subscriber came");
            node.next_event(Some(Duration::from_millis(10))).unwrap();
        }
        for n in 1..=count {
            node.send(&output, &Counter(n)).unwrap();
        }
        node.flush().unwrap();
    })
}

/// A provider under the same name that counts from `SECOND_GENERATION` every 5 ms until told.
fn second_provider(agent: SocketAddr, done: Arc<AtomicBool>) -> JoinHandle<()> {
    std::thread::spawn(move || {
        let (mut node, output) = provider(agent);
        let mut n = SECOND_GENERATION;
        while !done.load(Ordering::Relaxed) {
            node.next_event(Some(Duration::from_millis(5))).unwrap();
            n += 1;
            node.send(&output, &Counter(n)).unwrap();
        }
    })
}

#[test]
fn a_provider_gone_behind_a_full_queue_is_noticed_and_its_successor_linked() {
    for count in FIRST_GENERATIONS {
        relinks_after(count);
    }
}

fn relinks_after(count: u64) {
    let (_agent, agent) = start_agent();
    let first = first_provider(agent, count);
    let mut subscriber = test_node(
        ModuleSpec::new("subscriber", "takes every value")
            .input::<Counter>("count", "the provider's count"),
        agent,
        &[("count", "provider.count")],
    );
    let input = subscriber.reliable_input::<Counter>("count").unwrap();
    let deadline = Instant::now() + PATIENCE;
    while !subscriber.is_linked(&input) {
        assert!(Instant::now() < deadline, "the input never linked");
        subscriber
            .next_event(Some(Duration::from_millis(10)))
            .unwrap();
    }
    // The subscriber does not read while the first provider sends everything and ends: all of
    // it, and the end of the connection, wait in the socket.
    first.join().unwrap();
    let done = Arc::new(AtomicBool::new(false));
    let second = second_provider(agent, done.clone());

    let mut got = Vec::new();
    let deadline = Instant::now() + PATIENCE;
    while got.last().is_none_or(|&last| last <= SECOND_GENERATION) {
        if Instant::now() >= deadline {
            done.store(true, Ordering::Relaxed);
            let first_generation = got.iter().filter(|&&n| n <= count).count();
            panic!(
                "no value from the second provider in {PATIENCE:?}: the subscriber took \
                 {first_generation} of the first provider's {count} values and {}",
                if subscriber.is_linked(&input) {
                    "still thinks it is linked (the end of the connection was never read)"
                } else {
                    "did not link again"
                }
            );
        }
        subscriber
            .next_event(Some(Duration::from_millis(10)))
            .unwrap();
        while let Some(sample) = subscriber.take(&input).unwrap() {
            got.push(sample.value.0);
        }
    }
    done.store(true, Ordering::Relaxed);
    second.join().unwrap();
    let (before, after): (Vec<u64>, Vec<u64>) = got.iter().partition(|&&n| n <= count);
    assert_eq!(
        before,
        (1..=count).collect::<Vec<_>>(),
        "every value of the first provider, once, in order"
    );
    assert!(
        after.windows(2).all(|pair| pair[0] < pair[1]),
        "the second provider's values in order"
    );
}
