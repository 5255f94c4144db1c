//! `compile_10k_waypoints_ms`: a plan of 10,000 waypoints (a lawnmower sweep of a 2 km square,
//! with five no-go areas the routes must be checked against and every fifth leg waiting) compiled
//! into a mission net and checked as `armor check` checks it: the names against the robot's
//! system and module descriptions, then the reachability analysis. Goal: under 100 ms.
//!
//! The reference is reading and checking the compiled net from its XML, the way a hand-written
//! mission of the same size is loaded: the ratio says what compiling adds to loading.

use std::collections::BTreeMap;
use std::hint::black_box;
use std::time::Instant;

use anyhow::{Context as _, ensure};
use armor_model::SystemConfig;
use armor_model::geo::LatLon;
use armor_model::net::{MissionNet, analyse, check_names};
use armor_model::plan::{self, Plan};
use armor_model::world::Point;
use armor_module_api::ModuleDescription;
use armor_runtime::mission::ANALYSIS_LIMIT_STATES;

use crate::Settings;
use armor_bench_report::{Report, median};

pub const NAME: &str = "compile_10k_waypoints_ms";

const ORIGIN: LatLon = LatLon::new(43.5615, 1.469);

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let (waypoints, rounds) = if settings.quick {
        (500, 1)
    } else {
        (10_000, 7)
    };
    let text = plan_text(waypoints);
    let system = SystemConfig::parse(SYSTEM)
        .map_err(|problems| anyhow::anyhow!("the bench's system does not parse: {problems:?}"))?;
    let descriptions = descriptions();
    let compile_and_check = || -> anyhow::Result<(Plan, plan::Compiled)> {
        let plan = Plan::parse(&text).map_err(|p| anyhow::anyhow!("plan: {p:?}"))?;
        let compiled = plan::compile(&plan, None).map_err(|p| anyhow::anyhow!("compile: {p:?}"))?;
        check(&compiled.net, &system, &descriptions)?;
        Ok((plan, compiled))
    };
    let net = compile_and_check()?.1.net;
    let net_text = net.to_xml();
    let load_and_check = || -> anyhow::Result<MissionNet> {
        let net = MissionNet::parse(&net_text).map_err(|p| anyhow::anyhow!("net: {p:?}"))?;
        check(&net, &system, &descriptions)?;
        Ok(net)
    };
    let mut ours = Vec::with_capacity(rounds);
    let mut reference = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        ours.push(time_ms(compile_and_check)?);
        reference.push(time_ms(load_and_check)?);
    }
    Ok(
        Report::single(NAME, "ms", median(&ours), median(&reference))
            .with("waypoints", waypoints)
            .with("places", net.places.len())
            .with("transitions", net.transitions.len())
            .with("goal_ms", 100),
    )
}

/// The descriptions of the bench system's modules.
pub(crate) fn descriptions() -> BTreeMap<String, ModuleDescription> {
    [
        armor_module_catalog::nav::follower::spec(),
        armor_module_catalog::nav::avoider::spec(),
    ]
    .into_iter()
    .map(|spec| {
        let description = spec.description().clone();
        (description.module_type.clone(), description)
    })
    .collect()
}

/// The checks of `armor check`: the names against the system, then the analysis.
pub(crate) fn check(
    net: &MissionNet,
    system: &SystemConfig,
    descriptions: &BTreeMap<String, ModuleDescription>,
) -> anyhow::Result<()> {
    let problems = check_names(net, system, descriptions);
    ensure!(problems.is_empty(), "names: {problems:?}");
    let analysis = analyse(net, ANALYSIS_LIMIT_STATES);
    let problems = analysis.problems(net);
    ensure!(problems.is_empty(), "analysis: {problems:?}");
    Ok(())
}

/// The time `work` takes to give its result; freeing the result afterwards is not counted
/// (tens of thousands of small strings take milliseconds to free, on both sides alike).
pub(crate) fn time_ms<T>(work: impl FnOnce() -> anyhow::Result<T>) -> anyhow::Result<f64> {
    let start = Instant::now();
    let result = work().context("one round")?;
    let elapsed = start.elapsed();
    drop(black_box(result));
    Ok(elapsed.as_secs_f64() * 1e3)
}

pub(crate) const SYSTEM: &str = r#"<system name="bench">
  <module name="follower" type="follower">
    <param name="goal_x_m" value="0"/>
    <param name="goal_y_m" value="0"/>
  </module>
  <module name="avoider" type="avoider"/>
</system>"#;

/// A lawnmower sweep: rows of 100 waypoints 20 m apart, rows 20 m apart, so no leg is longer
/// than 20 m; no-go areas sit between rows, where the legs pass beside them.
pub(crate) fn plan_text(waypoints: usize) -> String {
    let mut text = String::from(
        "<plan name=\"sweep\" system=\"system.xml\">\n<origin lat=\"43.5615\" lon=\"1.469\"/>\n\
         <navigation><module name=\"avoider\"/></navigation>\n",
    );
    let at = |x: f64, y: f64| {
        let p = LatLon::from_local(Point::new(x, y), ORIGIN);
        format!("lat=\"{:.8}\" lon=\"{:.8}\"", p.lat_deg, p.lon_deg)
    };
    for i in 0..waypoints {
        let (row, column) = (i / 100, i % 100);
        let column = if row % 2 == 0 { column } else { 99 - column };
        let (x, y) = (column as f64 * 20.0, row as f64 * 20.0);
        text.push_str(&format!("<waypoint name=\"w{i}\" {}/>\n", at(x, y)));
    }
    for i in 1..waypoints {
        let wait = if i % 5 == 0 { " wait_secs=\"2\"" } else { "" };
        text.push_str(&format!("<leg from=\"w{}\" to=\"w{i}\"{wait}/>\n", i - 1));
    }
    for k in 0..5 {
        // A 6 m × 6 m area centred between two rows, under a column of waypoints.
        let (x, y) = (100.0 + k as f64 * 300.0, 10.0 + k as f64 * 40.0);
        text.push_str(&format!(
            "<area name=\"no_go_{k}\" kind=\"no-go\"><point {}/><point {}/><point {}/><point {}/></area>\n",
            at(x + 5.0, y - 3.0),
            at(x + 11.0, y - 3.0),
            at(x + 11.0, y + 3.0),
            at(x + 5.0, y + 3.0)
        ));
    }
    text.push_str("</plan>\n");
    text
}
