//! Hostile and broken peers: garbage, a frame announcing 4 GiB, a handshake never finished. The
//! connection is dropped and the process keeps serving everyone else.
#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::process::Command;
use std::time::Duration;

use armor_module_api::protocol::{Advert, FromAgent, ToAgent};
use armor_module_api::wire::{HELLO, blocking};
use armor_tests::{PATIENCE, Proc, bin};

fn start_agent() -> (Proc, SocketAddr) {
    let (agent, addr) = armor_tests::start_agent();
    assert!(
        addr.ip().is_loopback(),
        "listens on loopback by default: {addr}"
    );
    (agent, addr)
}

fn connect(addr: SocketAddr) -> TcpStream {
    let stream = TcpStream::connect(addr).unwrap();
    stream.set_read_timeout(Some(PATIENCE)).unwrap();
    stream
}

/// Reads until the peer closes; panics if it does not within the timeout.
fn assert_closed_by_peer(mut stream: TcpStream) {
    let mut sink = Vec::new();
    match stream.read_to_end(&mut sink) {
        Ok(_) => {}
        Err(err) if err.kind() == std::io::ErrorKind::ConnectionReset => {}
        Err(err) => panic!("peer did not close the connection: {err}"),
    }
}

fn lookup(addr: SocketAddr, data_name: &str) -> FromAgent {
    let mut stream = connect(addr);
    blocking::write_hello(&mut stream).unwrap();
    blocking::read_hello(&mut stream).unwrap();
    blocking::write_message(
        &mut stream,
        &ToAgent::Lookup {
            data_name: data_name.into(),
        },
    )
    .unwrap();
    blocking::read_message(&mut stream).unwrap()
}

fn hostile_peers(addr: SocketAddr) {
    // Not our protocol at all.
    let mut http = connect(addr);
    http.write_all(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
        .unwrap();
    assert_closed_by_peer(http);
    // A valid hello, then a frame announcing 4 GiB.
    let mut huge = connect(addr);
    huge.write_all(&HELLO).unwrap();
    huge.write_all(&u32::MAX.to_le_bytes()).unwrap();
    huge.write_all(&[1; 64]).unwrap();
    assert_closed_by_peer(huge);
    // A valid frame of JSON that is no message of ours.
    let mut nonsense = connect(addr);
    nonsense.write_all(&HELLO).unwrap();
    let body = br#"{"type":"launch_missiles"}"#;
    nonsense
        .write_all(&(body.len() as u32 + 1).to_le_bytes())
        .unwrap();
    nonsense.write_all(&[1]).unwrap();
    nonsense.write_all(body).unwrap();
    assert_closed_by_peer(nonsense);
}

#[test]
fn the_agent_drops_bad_peers_and_serves_the_others() {
    let (_agent, addr) = start_agent();
    // A silent peer holds a connection open for the whole test; it must not block anyone.
    let _silent = connect(addr);
    let mut provider = connect(addr);
    blocking::write_hello(&mut provider).unwrap();
    blocking::read_hello(&mut provider).unwrap();
    let advert = Advert {
        data_name: "sim.odometry".into(),
        data_type: "Odometry".into(),
        addr: "127.0.0.1:9".into(),
        key: None,
    };
    blocking::write_message(
        &mut provider,
        &ToAgent::Register {
            module: "sim".into(),
            outputs: vec![advert.clone()],
        },
    )
    .unwrap();
    assert_eq!(
        blocking::read_message::<FromAgent>(&mut provider).unwrap(),
        FromAgent::Registered
    );

    hostile_peers(addr);

    assert_eq!(lookup(addr, "sim.odometry"), FromAgent::Provider(advert));
    assert_eq!(
        lookup(addr, "sim.laser"),
        FromAgent::Unknown {
            data_name: "sim.laser".into()
        }
    );
    // Another module may not take over a data name; the provider's own registration dies with it.
    let mut thief = connect(addr);
    blocking::write_hello(&mut thief).unwrap();
    blocking::read_hello(&mut thief).unwrap();
    blocking::write_message(
        &mut thief,
        &ToAgent::Register {
            module: "impostor".into(),
            outputs: vec![Advert {
                data_name: "sim.odometry".into(),
                data_type: "Odometry".into(),
                addr: "127.0.0.1:1".into(),
                key: None,
            }],
        },
    )
    .unwrap();
    assert!(matches!(
        blocking::read_message::<FromAgent>(&mut thief).unwrap(),
        FromAgent::Error { .. }
    ));
    drop(provider);
    armor_tests::wait_until("the dead provider's registration is gone", PATIENCE, || {
        lookup(addr, "sim.odometry")
            == FromAgent::Unknown {
                data_name: "sim.odometry".into(),
            }
    });
}

#[test]
fn the_agent_drops_a_peer_that_never_finishes_its_handshake() {
    let (_agent, addr) = start_agent();
    let mut half = connect(addr);
    half.write_all(&HELLO[..3]).unwrap();
    let started = std::time::Instant::now();
    assert_closed_by_peer(half);
    assert!(started.elapsed() < Duration::from_secs(10));
    assert_eq!(
        lookup(addr, "x.y"),
        FromAgent::Unknown {
            data_name: "x.y".into()
        }
    );
}

#[test]
fn a_module_drops_bad_subscribers_and_keeps_publishing() {
    let (_agent, agent_addr) = start_agent();
    let agent = agent_addr.to_string();
    let _counter = Proc::start(Command::new(bin("armor-mod-counter")).args([
        "--agent",
        &agent,
        "--param",
        "period_secs=0.01",
    ]));
    let data_addr: SocketAddr = {
        let mut found = None;
        armor_tests::wait_until("the counter registers with the agent", PATIENCE, || {
            if let FromAgent::Provider(advert) = lookup(agent_addr, "counter.count") {
                found = Some(advert.addr.parse().unwrap());
            }
            found.is_some()
        });
        found.unwrap()
    };
    assert!(
        data_addr.ip().is_loopback(),
        "data listener on loopback by default: {data_addr}"
    );
    hostile_peers(data_addr);
    let mut half = connect(data_addr);
    half.write_all(&HELLO).unwrap();
    assert_closed_by_peer(half);

    // A real subscriber still gets every value in order.
    let checker = Proc::start(Command::new(bin("armor-mod-checker")).args([
        "--agent",
        &agent,
        "--bind",
        "input=counter.count",
        "--param",
        "report_every=20",
    ]));
    checker.wait_for("from the checker", PATIENCE, |line| {
        line.contains("received 40 values") && line.ends_with("in order")
    });
}
