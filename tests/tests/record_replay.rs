//! Recording a live stream into an MCAP file with `armor-mod-recorder`, then publishing it again
//! with `armor replay` to a module that checks it, as a user would.
#![allow(clippy::unwrap_used)]

use std::process::Command;

use armor_tests::mcap::{read_mcap, recorded};
use armor_tests::{PATIENCE, Proc, bin};

/// How many values the recording should hold at least (0.01 s apart: a second or more).
const ENOUGH: u64 = 100;

fn start_agent() -> (Proc, String) {
    let (agent, addr) = armor_tests::start_agent();
    (agent, addr.to_string())
}

#[test]
fn a_recorded_stream_is_saved_on_sigterm_and_replayed_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.mcap");
    let (agent, addr) = start_agent();
    let counter = Proc::start(Command::new(bin("armor-mod-counter")).args([
        "--agent",
        &addr,
        "--param",
        "period_secs=0.01",
    ]));
    let mut recorder = Proc::start(Command::new(bin("armor-mod-recorder")).args([
        "--agent",
        &addr,
        "--param",
        "record=counter.count",
        "--param",
        &format!("file={}", file.display()),
        "--param",
        "compression=none",
        "--param",
        "report_secs=0.2",
    ]));
    recorder.wait_for("saying enough values were recorded", PATIENCE, |line| {
        recorded(line).is_some_and(|count| count >= ENOUGH)
    });

    // SIGTERM: the recorder completes the file and renames it into place.
    recorder.signal(libc::SIGTERM);
    let status = recorder.wait_exit(PATIENCE);
    assert!(status.success(), "{status}: {:#?}", recorder.lines());
    let saved = recorder.wait_for("saying the file was saved", PATIENCE, |line| {
        line.contains("saved") && line.contains("run.mcap")
    });
    assert!(file.exists(), "{saved}");
    assert!(!dir.path().join("run.mcap.partial").exists());

    let channels = read_mcap(&file);
    let messages = &channels[&("counter.count".to_owned(), "json".to_owned())];
    assert_eq!(channels.len(), 1, "{:?}", channels.keys());
    let values: Vec<u64> = messages
        .iter()
        .map(|(_, data)| {
            let json: serde_json::Value = serde_json::from_slice(data).unwrap();
            json["value"].as_u64().unwrap()
        })
        .collect();
    assert!(values.len() as u64 >= ENOUGH, "{values:?}");
    assert!(
        values.windows(2).all(|pair| pair[1] == pair[0] + 1),
        "every value, in order: {values:?}"
    );
    assert!(
        messages.windows(2).all(|pair| pair[1].0 > pair[0].0),
        "log times increase"
    );
    let span_secs = (messages[messages.len() - 1].0 - messages[0].0) as f64 / 1e9;

    // The counter goes away; the replay takes its data name over.
    let skip = agent.line_count();
    drop(counter);
    agent.wait_for_from(skip, "forgetting the counter", PATIENCE, |line| {
        line.contains("provider unregistered") && line.contains("counter.count")
    });
    let checker = Proc::start(Command::new(bin("armor-mod-checker")).args([
        "--agent",
        &addr,
        "--bind",
        "input=counter.count",
        "--param",
        "report_every=10",
    ]));
    let mut replay = Proc::start(Command::new(bin("armor")).args([
        "replay",
        file.to_str().unwrap(),
        "--agent",
        &addr,
        "--time-scale",
        "2",
        "--wait",
        "20",
    ]));
    let status = replay.wait_exit(PATIENCE);
    assert!(status.success(), "{status}: {:#?}", replay.lines());
    let done = replay.wait_for("with a summary", PATIENCE, |line| {
        line.contains("replayed") && line.contains("messages")
    });
    assert!(
        done.contains(&format!("replayed {} messages", values.len())),
        "{done}"
    );
    // The recorded timing is kept, twice as fast.
    let took: f64 = done
        .rsplit(" in ")
        .next()
        .and_then(|rest| rest.trim_end_matches(" s").parse().ok())
        .unwrap();
    assert!(took >= span_secs / 2.0 * 0.95, "{took} s for {span_secs} s");

    // The checker linked before the replay started: it got every value, in order.
    let reported = values.len() / 10 * 10;
    let last = values[reported - 1];
    checker.wait_for("with the replayed values", PATIENCE, |line| {
        line.contains(&format!(
            "received {reported} values, last {last}, in order"
        ))
    });
    assert!(
        !checker
            .lines()
            .iter()
            .any(|line| line.contains("out of order")),
        "{:#?}",
        checker.lines()
    );
}
