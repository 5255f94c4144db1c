//! GPX: `gpx::import` never panics; what it imports is a plan the plan reader accepts, and it
//! survives `gpx::export`. The export is lossy by design (coordinates to 8 decimals, the route's
//! points repeated after the waypoints come back with suffixed names), so the route is compared
//! leg by leg, to 1e-7 degrees.
#![no_main]

use armor_model::plan::{Plan, gpx};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    let Ok(plan) = gpx::import(text, "fuzz", "system.xml") else {
        return;
    };
    let plan_xml = plan.to_xml();
    Plan::parse(&plan_xml)
        .unwrap_or_else(|problems| panic!("imported plan refused: {problems:?}\n{plan_xml}"));
    let written = gpx::export(&plan);
    let again = gpx::import(&written, "fuzz", "system.xml")
        .unwrap_or_else(|problems| panic!("own GPX refused: {problems:?}\n{written}"));
    assert_eq!(again.legs.len(), plan.legs.len(), "legs lost\n{written}");
    for (a, b) in plan.legs.iter().zip(&again.legs) {
        for (name_a, name_b) in [(&a.from, &b.from), (&a.to, &b.to)] {
            let pa = plan
                .waypoint(name_a)
                .expect("leg ends at a waypoint")
                .position;
            let pb = again
                .waypoint(name_b)
                .expect("leg ends at a waypoint")
                .position;
            assert!(
                (pa.lat_deg - pb.lat_deg).abs() < 1e-7 && (pa.lon_deg - pb.lon_deg).abs() < 1e-7,
                "{name_a} {pa:?} came back as {name_b} {pb:?}\n{written}"
            );
        }
    }
});
