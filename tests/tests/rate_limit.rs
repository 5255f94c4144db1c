//! A subscriber that asks for at most N samples a second gets no more than that from a fast
//! provider, while an unlimited subscriber of the same output gets them all (the time-based
//! filter of `max_rate_hz`, which the studio's Run view uses).
#![allow(clippy::unwrap_used)]

use std::time::{Duration, Instant};

use armor_module_api::types::Counter;
use armor_module_api::{Datum as _, Event, ModuleSpec};
use armor_tests::{PATIENCE, start_agent, test_node};

#[test]
fn a_rate_limited_subscriber_gets_at_most_its_rate() {
    let (_agent, agent) = start_agent();
    let mut publisher = test_node(ModuleSpec::new("fast", "a test node"), agent, &[]);
    let output = publisher.publish_raw("fast.count", "Counter").unwrap();
    let mut subscriber = test_node(ModuleSpec::new("watcher", "a test node"), agent, &[]);
    let all = subscriber.subscribe_raw("fast.count", true).unwrap();
    let limited = subscriber
        .subscribe_raw_at_most("fast.count", 20.0)
        .unwrap();

    let publishing = std::thread::spawn(move || {
        // Both subscribers linked before the count starts.
        let deadline = Instant::now() + PATIENCE;
        while publisher.raw_subscriber_count(&output) < 2 {
            assert!(Instant::now() < deadline, "the subscribers never linked");
            let _ = publisher.next_event(Some(Duration::from_millis(10)));
        }
        let start = Instant::now();
        let mut sent = 0_u64;
        while start.elapsed() < Duration::from_millis(1500) {
            sent += 1;
            let mut payload = Vec::new();
            Counter(sent).encode(&mut payload).unwrap();
            publisher.send_raw(&output, &payload).unwrap();
            // About 2,000 a second.
            let _ = publisher.next_event(Some(Duration::from_micros(500)));
        }
        publisher.flush().unwrap();
        // Keep serving until the subscriber has read everything.
        let linger = Instant::now() + Duration::from_millis(500);
        while Instant::now() < linger {
            let _ = publisher.next_event(Some(Duration::from_millis(10)));
        }
        sent
    });

    let (mut got_all, mut got_limited) = (0_u64, 0_u64);
    let mut last = 0;
    let mut first_at = None;
    let deadline = Instant::now() + PATIENCE;
    while !publishing.is_finished() && Instant::now() < deadline {
        if let Event::Input(port) = subscriber
            .next_event(Some(Duration::from_millis(20)))
            .unwrap()
        {
            first_at.get_or_insert_with(Instant::now);
            if port == all.id() {
                while let Some(sample) = subscriber.take_raw(&all) {
                    got_all += 1;
                    last = Counter::decode(&sample.payload).unwrap().0;
                }
            } else if port == limited.id() {
                while subscriber.take_raw(&limited).is_some() {
                    got_limited += 1;
                }
            }
        }
    }
    let sent = publishing.join().unwrap();
    assert!(sent > 500, "the provider sent {sent}");
    assert_eq!(got_all, sent, "the reliable subscriber got every sample");
    assert_eq!(last, sent);
    // 1.5 s at 20 a second, with one at the start and some slack for the clock.
    assert!(
        (10..=35).contains(&got_limited),
        "the limited subscriber got {got_limited} of {sent}"
    );
}
