//! QGroundControl plan files: `qgc::import` never panics, its problems and warnings are at
//! places in the text; what it imports is a plan the plan reader accepts, whose own export
//! reads back with the same route (exactly: the file carries doubles) and which KML can write.
#![no_main]

use armor_model::plan::{Plan, kml, qgc};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|text: &str| {
    let lines = u32::try_from(text.lines().count() + 1).unwrap_or(u32::MAX);
    let imported = match qgc::import(text, "fuzz", "system.xml", Some(1_800_000_000.0)) {
        Ok(imported) => imported,
        Err(problems) => {
            assert!(problems.iter().all(|p| (1..=lines).contains(&p.pos.line)));
            return;
        }
    };
    assert!(imported.warnings.iter().all(|w| (1..=lines).contains(&w.pos.line)));
    let plan = imported.plan;
    let plan_xml = plan.to_xml();
    Plan::parse(&plan_xml)
        .unwrap_or_else(|problems| panic!("imported plan refused: {problems:?}\n{plan_xml}"));
    let written = qgc::export(&plan).text;
    let again = qgc::import(&written, "fuzz", "system.xml", plan.start_unix_secs)
        .unwrap_or_else(|problems| panic!("own .plan refused: {problems:?}\n{written}"))
        .plan;
    assert_eq!(again.legs.len(), plan.legs.len(), "legs lost\n{written}");
    for (a, b) in plan.legs.iter().zip(&again.legs) {
        let pa = plan.waypoint(&a.to).expect("leg ends at a waypoint").position;
        let pb = again.waypoint(&b.to).expect("leg ends at a waypoint").position;
        assert_eq!(pa, pb, "{written}");
        assert_eq!(a.wait_secs, b.wait_secs, "{written}");
    }
    let _ = kml::export(&plan);
});
