//! Mission plans: `Plan::parse` never panics, and what it accepts survives `to_xml`.
//!
//! The writer gives coordinates to seven decimals of a degree (about a centimetre, by design:
//! `plan/xml.rs`), so the plan read back is compared with the first one rounded the same way.
#![no_main]

use armor_model::plan::{LatLon, Plan};
use libfuzzer_sys::fuzz_target;

/// What the writer keeps of a coordinate (its `degrees` format, read back).
fn seven_decimals(value: &mut f64) {
    if let Ok(rounded) = format!("{value:.7}").parse::<f64>() {
        *value = if rounded == 0.0 { 0.0 } else { rounded };
    }
}

fn rounded(position: &mut LatLon) {
    seven_decimals(&mut position.lat_deg);
    seven_decimals(&mut position.lon_deg);
}

/// The plan with every coordinate as the writer gives it.
fn as_written(plan: &Plan) -> Plan {
    let mut plan = plan.clone();
    plan.origin.iter_mut().for_each(rounded);
    plan.waypoints
        .iter_mut()
        .for_each(|w| rounded(&mut w.position));
    plan.units.iter_mut().for_each(|u| rounded(&mut u.position));
    plan.graphics
        .iter_mut()
        .flat_map(|g| &mut g.points)
        .for_each(rounded);
    plan
}

fuzz_target!(|text: &str| {
    if let Ok(plan) = Plan::parse(text) {
        let written = plan.to_xml();
        let again = Plan::parse(&written)
            .unwrap_or_else(|problems| panic!("own output refused: {problems:?}\n{written}"));
        armor_fuzz::assert_same(&as_written(&plan), &again, &written);
    }
});
