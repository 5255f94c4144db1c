//! `qgc_import_10k_ms`: a QGroundControl plan file of 10,000 waypoints (the sweep of
//! `compile_10k_waypoints_ms` written by `armor export --qgc`'s code: 10,000 mission items,
//! every fifth with a hold, five geofence polygons, about 4 MB) read back into a plan as
//! `armor import` reads it.
//!
//! The reference is serde_json reading the same text into its `Value`, the first step of the
//! import alone: the ratio is what finding every value's position and building the plan add.

use std::hint::black_box;

use anyhow::ensure;
use armor_model::plan::{Plan, qgc};
use serde_json::Value;

use crate::Settings;
use crate::compile_plan::{plan_text, time_ms};
use armor_bench_report::{Report, median};

pub const NAME: &str = "qgc_import_10k_ms";

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let (waypoints, rounds) = if settings.quick {
        (500, 1)
    } else {
        (10_000, 9)
    };
    let plan = Plan::parse(&plan_text(waypoints))
        .map_err(|problems| anyhow::anyhow!("the bench's plan does not parse: {problems:?}"))?;
    let text = qgc::export(&plan).text;
    let import = || -> anyhow::Result<Plan> {
        let imported = qgc::import(&text, "sweep", "system.xml", None)
            .map_err(|problems| anyhow::anyhow!("import: {problems:?}"))?;
        Ok(black_box(imported.plan))
    };
    let imported = import()?;
    ensure!(
        imported.legs.len() == plan.legs.len()
            && imported.no_go_areas().count() == plan.no_go_areas().count(),
        "the import lost legs or areas"
    );
    let parse = || -> anyhow::Result<Value> { Ok(black_box(serde_json::from_str(&text)?)) };
    let mut ours = Vec::with_capacity(rounds);
    let mut reference = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        ours.push(time_ms(import)?);
        reference.push(time_ms(parse)?);
    }
    Ok(
        Report::single(NAME, "ms", median(&ours), median(&reference))
            .with("items", plan.legs.len())
            .with("bytes", text.len())
            .with(
                "reference_is",
                "serde_json::from_str::<Value> of the same text",
            ),
    )
}
