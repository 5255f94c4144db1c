//! Pull mode: a subscriber that asks for the latest value gets it, and nothing else; the
//! provider's node answers without its module doing anything but wait; a pull before the first
//! value is answered by that value; a push subscriber of the same output still gets every value.
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use armor_module_api::types::{Blob, Counter};
use armor_module_api::{Event, ModuleSpec, Node};
use armor_tests::{PATIENCE, start_agent, test_node};

fn asker(name: &str, agent: SocketAddr) -> Node {
    test_node(
        ModuleSpec::new(name, "asks for the count")
            .input::<Counter>("count", "the provider's count"),
        agent,
        &[("count", "provider.count")],
    )
}

#[test]
fn a_pull_gets_the_latest_value_and_nothing_is_pushed() {
    let (_agent, agent) = start_agent();
    let mut provider = test_node(
        ModuleSpec::new("provider", "counts when told").output::<Counter>("count", "the count"),
        agent,
        &[],
    );
    let output = provider.output::<Counter>("count").unwrap();
    // What the provider has sent last, and whether it should stop.
    let sent = Arc::new(Mutex::new(0_u64));
    let done = Arc::new(AtomicBool::new(false));
    let serving = {
        let (sent, done) = (sent.clone(), done.clone());
        std::thread::spawn(move || {
            // Sends 1, 2, 3, … every 20 ms once a first subscriber is linked, then only waits:
            // its module code never sees the pulls (no event is an input or a request).
            let mut events = Vec::new();
            while !done.load(Ordering::Relaxed) {
                let event = provider
                    .next_event(Some(Duration::from_millis(20)))
                    .unwrap();
                if !matches!(event, Event::Timeout | Event::Start | Event::Stop) {
                    events.push(format!("{event:?}"));
                }
                if provider.subscriber_count(&output) >= 2 {
                    let mut sent = sent.lock().unwrap();
                    *sent += 1;
                    provider.send(&output, &Counter(*sent)).unwrap();
                }
            }
            provider.flush().unwrap();
            events
        })
    };

    // A pull subscriber linked before any value: its first pull is answered by the first one.
    let mut puller = asker("puller", agent);
    let count = puller.pull_input::<Counter>("count").unwrap();
    let deadline = Instant::now() + PATIENCE;
    while !puller.is_linked(&count) {
        assert!(Instant::now() < deadline, "the pull input never linked");
        puller.next_event(Some(Duration::from_millis(10))).unwrap();
    }
    assert!(
        puller.pull(&count).unwrap(),
        "linked, so the pull was asked"
    );
    // The push subscriber comes second: the provider starts counting.
    let mut pushed = asker("pushed", agent);
    let all = pushed.reliable_input::<Counter>("count").unwrap();
    let first = loop {
        assert!(
            Instant::now() < deadline,
            "the first pull was never answered"
        );
        if let Event::Input(port) = puller.next_event(Some(Duration::from_millis(10))).unwrap()
            && port == count.id()
            && let Some(sample) = puller.take(&count).unwrap()
        {
            break sample.value.0;
        }
        let _ = pushed.next_event(Some(Duration::ZERO));
    };
    assert_eq!(first, 1, "a pull before any value gets the first one");

    // Pulls get the latest value, increasing; in between, nothing comes unasked.
    let mut answers = Vec::new();
    while answers.len() < 5 {
        assert!(Instant::now() < deadline, "pulls unanswered: {answers:?}");
        let sample = puller
            .pull_latest(&count, Duration::from_secs(2))
            .unwrap()
            .expect("an answer within 2 s");
        let latest = *sent.lock().unwrap();
        assert!(
            sample.value.0 <= latest && sample.value.0 + 2 >= latest,
            "pulled {} while the provider had sent {latest}",
            sample.value.0
        );
        answers.push(sample.value.0);
        let quiet_until = Instant::now() + Duration::from_millis(60);
        while Instant::now() < quiet_until {
            if let Event::Input(port) = puller.next_event_until(quiet_until).unwrap() {
                assert!(
                    port != count.id() || puller.take(&count).unwrap().is_none(),
                    "a value came without a pull"
                );
            }
        }
    }
    assert!(
        answers.windows(2).all(|pair| pair[0] < pair[1]),
        "each pull gets a newer value: {answers:?}"
    );

    done.store(true, Ordering::Relaxed);
    let events = serving.join().unwrap();
    assert!(events.is_empty(), "the provider's module saw {events:?}");
    // The push subscriber got every value sent, in order.
    let total = *sent.lock().unwrap();
    let mut got = Vec::new();
    let deadline = Instant::now() + PATIENCE;
    while got.len() < total as usize {
        assert!(
            Instant::now() < deadline,
            "pushed got {} of {total}",
            got.len()
        );
        if let Event::Input(_) = pushed.next_event(Some(Duration::from_millis(20))).unwrap() {
            while let Some(sample) = pushed.take(&all).unwrap() {
                got.push(sample.value.0);
            }
        }
    }
    assert_eq!(got, (1..=total).collect::<Vec<_>>());
}

#[test]
fn a_pull_of_a_large_output_gets_its_latest_sample_whole() {
    let (_agent, agent) = start_agent();
    let mut provider = test_node(
        ModuleSpec::new("big", "sends large frames").output::<Blob>("frame", "a frame"),
        agent,
        &[],
    );
    let output = provider.output::<Blob>("frame").unwrap();
    let frame = |n: usize| {
        Blob(
            (0..1024 * 1024 + n)
                .map(|i| ((i + n) % 251) as u8)
                .collect(),
        )
    };
    let done = Arc::new(AtomicBool::new(false));
    let serving = {
        let done = done.clone();
        std::thread::spawn(move || {
            // Three large frames once the puller is linked, sent from the value's bytes; then
            // only waits, its node answering the pulls.
            let mut sent = false;
            while !done.load(Ordering::Relaxed) {
                provider
                    .next_event(Some(Duration::from_millis(10)))
                    .unwrap();
                if !sent && provider.subscriber_count(&output) > 0 {
                    for n in 1..=3 {
                        provider.send(&output, &frame(n)).unwrap();
                    }
                    provider.flush().unwrap();
                    sent = true;
                }
            }
        })
    };
    let mut puller = test_node(
        ModuleSpec::new("puller", "asks for the frame").input::<Blob>("frame", "big's frame"),
        agent,
        &[("frame", "big.frame")],
    );
    let input = puller.pull_input::<Blob>("frame").unwrap();
    let deadline = Instant::now() + PATIENCE;
    let latest = loop {
        assert!(Instant::now() < deadline, "no third frame pulled");
        if !puller.is_linked(&input) {
            puller.next_event(Some(Duration::from_millis(10))).unwrap();
            continue;
        }
        if let Some(sample) = puller.pull_latest(&input, Duration::from_secs(2)).unwrap()
            && sample.seq == 3
        {
            break sample.value;
        }
    };
    done.store(true, Ordering::Relaxed);
    serving.join().unwrap();
    assert!(latest == frame(3), "the third frame, whole");
}
