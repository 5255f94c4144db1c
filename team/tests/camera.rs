//! A robot's camera at its stated rate and within its own budget, through the real bridge and
//! station over zenoh on loopback: stand-in robots (the bridge serving a run that is only a
//! clock) with 15 kB frames that do not compress, at 2 frames a second. With the default
//! camera budget (400 kbit/s) every frame goes; with 100 kbit/s the rate falls so that the
//! budget holds, rather than the radio being flooded. The robot's own budget (50 kbit/s, its
//! status and pose) does not carry the camera.
#![allow(clippy::unwrap_used)]

use std::net::TcpListener;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use armor_module_api::auth::{Role, RoleKey, Secret};
use armor_team::robot::{Budget, Shared};
use armor_team::stand_in::{StandIn, bridge};
use armor_team::station::Station;

static NEVER: AtomicBool = AtomicBool::new(false);

#[test]
fn a_camera_keeps_its_rate_within_its_own_budget() {
    let port = TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let station_side = armor_team::net::open(std::slice::from_ref(&endpoint), &[]).unwrap();
    let secret = Secret::from_bytes(&[41; 32]);
    let epoch = Instant::now();
    for (index, (name, camera_kbps)) in [("roomy", 400.0), ("tight", 100.0)].iter().enumerate() {
        let budget = Budget {
            camera_kbit_per_sec: *camera_kbps,
            ..Budget::default()
        };
        let session = armor_team::net::open(&[], std::slice::from_ref(&endpoint)).unwrap();
        let bridge = bridge(name, &secret, budget);
        let run = StandIn::new(name, index, epoch).with_camera(15_000);
        std::thread::spawn(move || {
            let shared = Arc::new(Mutex::new(Shared::default()));
            bridge
                .serve(&session, Box::new(run), shared, &NEVER)
                .unwrap();
        });
    }
    let station = Station::start(
        &station_side,
        &RoleKey {
            role: Role::Observer,
            key: secret.role_key(Role::Observer),
        },
        &["roomy".to_owned(), "tight".to_owned()],
        2.0,
        None,
    );
    // Frames for 8 s after the first came to both.
    let deadline = Instant::now() + Duration::from_secs(60);
    while !station
        .reports()
        .iter()
        .all(|report| report.camera.is_some())
    {
        assert!(Instant::now() < deadline, "no camera frame in 60 s");
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_secs(8));
    let reports = station.reports();
    let seen = |robot: &str| {
        let report = reports.iter().find(|report| report.robot == robot).unwrap();
        (report.camera.clone().unwrap(), report.kbit_per_sec)
    };
    let (roomy, roomy_kbit) = seen("roomy");
    let (tight, tight_kbit) = seen("tight");
    println!("roomy: {roomy:?}, {roomy_kbit:.1} kbit/s; tight: {tight:?}, {tight_kbit:.1} kbit/s");
    assert!(
        (1.6..=2.3).contains(&roomy.frames_per_sec),
        "the camera's 2 frames/s within 400 kbit/s: {roomy:?}"
    );
    assert!(roomy.kbit_per_sec <= 400.0, "{roomy:?}");
    assert_eq!(roomy.frame_bytes, 15_000);
    // A frame is about 160 kbit sealed: within 100 kbit/s, one every 1.6 s (the budget may
    // hold a second's worth at the start, which a window of 8 s shows as a few % more).
    assert!(
        tight.kbit_per_sec <= 110.0 && tight.frames_per_sec > 0.4 && tight.frames_per_sec < 0.9,
        "the camera's rate falls to keep 100 kbit/s: {tight:?}"
    );
    // The robot's own budget carries its status and pose only.
    for kbit in [roomy_kbit, tight_kbit] {
        assert!(kbit > 0.0 && kbit <= 50.0, "{kbit:.1} kbit/s");
    }
}
