//! `xml_load_vs_roxmltree`: loading (parsing and building the model) of a large system file and
//! a large plan, against the fastest XML reader measured in the same run, roxmltree (a DOM),
//! parsing the same bytes; xml-rs (a streaming pull parser) is a side figure.
//!
//! Ours: `SystemConfig::parse` and `Plan::parse`, which read the text into our positioned element
//! tree (on quick-xml) and build the model with every check of the loader. roxmltree:
//! `Document::parse` (a whole tree, no model). xml-rs: every event of an `EventReader` (no tree,
//! no model). The headline is the sum of both files against roxmltree, the faster of the two
//! references on every run so far; `goal` is within twice its time, as ours also builds the model,
//! keeps every position and runs the loader's checks. Our save (`to_xml`) is given for information, and so is where our load's time goes:
//! our element tree alone (`armor_module_api::xml::parse`) and the quick-xml events under it.

use std::fmt::Write as _;
use std::hint::black_box;
use std::time::Instant;

use anyhow::{Context as _, ensure};
use armor_model::plan::Plan;
use armor_model::system::SystemConfig;
use serde_json::json;

use crate::Settings;
use armor_bench_report::{Report, median};

pub const NAME: &str = "xml_load_vs_roxmltree";

/// A system of `modules` modules, each with three parameters, chained by a link each.
pub fn system_text(modules: usize) -> String {
    let mut text = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<!-- generated -->\n<system name=\"big\">\n",
    );
    for i in 0..modules {
        let _ = writeln!(
            text,
            "  <module name=\"m{i}\" type=\"echo\">\n    <param name=\"period_secs\" \
             value=\"0.{i}\"/>\n    <param name=\"label\" value=\"module number {i}\"/>\n    \
             <param name=\"limit\" value=\"{i}\"/>\n  </module>"
        );
    }
    for i in 1..modules {
        let _ = writeln!(
            text,
            "  <link from=\"m{}.output\" to=\"m{i}.input\"/>",
            i - 1
        );
    }
    text.push_str("</system>\n");
    text
}

/// A plan of `waypoints` waypoints with a leg between each two; every tenth leg observes on
/// arrival.
pub fn plan_text(waypoints: usize) -> String {
    let mut text = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<plan name=\"big\" system=\"system.xml\">\n  \
         <navigation module=\"follower\" speed_mps=\"0.5\">\n    <module name=\"avoider\"/>\n  \
         </navigation>\n",
    );
    for i in 0..waypoints {
        let (row, column) = (i / 100, i % 100);
        let _ = writeln!(
            text,
            "  <waypoint name=\"w{i}\" lat=\"{:.8}\" lon=\"{:.8}\"/>",
            43.5 + row as f64 * 0.000_18,
            1.46 + column as f64 * 0.000_25
        );
    }
    for i in 1..waypoints {
        if i % 10 == 0 {
            let _ = writeln!(
                text,
                "  <leg name=\"leg{i}\" from=\"w{}\" to=\"w{i}\" wait_secs=\"2\">\n    \
                 <arrival until=\"observer.observation_done\" for_secs=\"60\">\n      \
                 <module name=\"observer\">\n        <param name=\"sector_deg\" \
                 value=\"360\"/>\n      </module>\n    </arrival>\n  </leg>",
                i - 1
            );
        } else {
            let _ = writeln!(
                text,
                "  <leg name=\"leg{i}\" from=\"w{}\" to=\"w{i}\"/>",
                i - 1
            );
        }
    }
    text.push_str("</plan>\n");
    text
}

fn ours_system(text: &str) -> anyhow::Result<usize> {
    let system = SystemConfig::parse(text).map_err(|errs| {
        anyhow::anyhow!("the generated system does not load: {:?}", errs.first())
    })?;
    Ok(system.modules.len())
}

fn ours_plan(text: &str) -> anyhow::Result<usize> {
    let plan = Plan::parse(text)
        .map_err(|errs| anyhow::anyhow!("the generated plan does not load: {:?}", errs.first()))?;
    Ok(plan.waypoints.len())
}

/// Our positioned element tree alone (`armor_module_api::xml::parse`), without the model.
fn ours_tree(text: &str) -> anyhow::Result<usize> {
    let root = armor_module_api::xml::parse(text)
        .map_err(|err| anyhow::anyhow!("tree: {}", err.message))?;
    Ok(root.children.len())
}

/// quick-xml's event reader alone, the parser under our tree, with no allocation per event.
fn quick_xml_events(text: &str) -> anyhow::Result<usize> {
    let mut reader = quick_xml::Reader::from_str(text);
    let mut events = 0;
    loop {
        match reader.read_event().context("quick-xml")? {
            quick_xml::events::Event::Eof => return Ok(events),
            event => {
                black_box(event);
                events += 1;
            }
        }
    }
}

fn roxmltree(text: &str) -> anyhow::Result<usize> {
    let document = roxmltree::Document::parse(text).context("roxmltree")?;
    Ok(document.root_element().children().count())
}

fn xmlrs(bytes: &[u8]) -> anyhow::Result<usize> {
    let mut events = 0;
    for event in xml::reader::EventReader::new(bytes) {
        black_box(event.context("xml-rs")?);
        events += 1;
    }
    Ok(events)
}

/// Milliseconds of one call, the median of `rounds`.
fn time_ms(rounds: usize, mut work: impl FnMut() -> anyhow::Result<usize>) -> anyhow::Result<f64> {
    let mut times = Vec::with_capacity(rounds);
    for _ in 0..rounds {
        let start = Instant::now();
        black_box(work()?);
        times.push(start.elapsed().as_secs_f64() * 1e3);
    }
    Ok(median(&times))
}

pub fn run(settings: &Settings) -> anyhow::Result<Report> {
    let (modules, waypoints, rounds) = if settings.quick {
        (200, 200, 2)
    } else {
        (5_000, 10_000, 15)
    };
    let files = [
        ("system", system_text(modules)),
        ("plan", plan_text(waypoints)),
    ];
    let mut detail = Vec::new();
    let (mut ours_total, mut roxml_total, mut xmlrs_total) = (0.0, 0.0, 0.0);
    for (kind, text) in &files {
        let load = |text: &str| match *kind {
            "system" => ours_system(text),
            _ => ours_plan(text),
        };
        ensure!(load(text)? > 0, "the generated {kind} is empty");
        // Alternate the three, a few calls at a time, so that load changes weigh on all alike.
        let (mut ours, mut roxml, mut xml_rs) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..3 {
            ours.push(time_ms(rounds, || load(text))?);
            roxml.push(time_ms(rounds, || roxmltree(text))?);
            xml_rs.push(time_ms(rounds, || xmlrs(text.as_bytes()))?);
        }
        let (ours, roxml, xml_rs) = (median(&ours), median(&roxml), median(&xml_rs));
        // Where our time goes: the element tree, and the parser under it.
        let tree = time_ms(rounds, || ours_tree(text))?;
        let events = time_ms(rounds, || quick_xml_events(text))?;
        let save = match *kind {
            "system" => {
                let system = SystemConfig::parse(text).map_err(|_| anyhow::anyhow!("load"))?;
                time_ms(rounds, || Ok(system.to_xml().len()))?
            }
            _ => {
                let plan = Plan::parse(text).map_err(|_| anyhow::anyhow!("load"))?;
                time_ms(rounds, || Ok(plan.to_xml().len()))?
            }
        };
        detail.push(json!({
            "file": kind,
            "bytes": text.len(),
            "ours_ms": crate::round4(ours),
            "roxmltree_ms": crate::round4(roxml),
            "xmlrs_ms": crate::round4(xml_rs),
            "ours_save_ms": crate::round4(save),
            "ours_tree_only_ms": crate::round4(tree),
            "quick_xml_events_ms": crate::round4(events),
        }));
        ours_total += ours;
        roxml_total += roxml;
        xmlrs_total += xml_rs;
    }
    let fastest = if roxml_total <= xmlrs_total {
        "roxmltree"
    } else {
        "xml-rs"
    };
    Ok(Report::single(NAME, "ms", ours_total, roxml_total)
        .with("xmlrs_ms", crate::round4(xmlrs_total))
        .with("ratio_vs_xmlrs", crate::round4(ours_total / xmlrs_total))
        .with("fastest_reference_this_run", fastest)
        .with(
            "goal",
            "ratio <= 2 (our model with its checks within twice a bare DOM)",
        )
        .with(
            "reference_is",
            format!(
                "roxmltree 0.20 building its whole tree of the same bytes ({modules}-module \
                 system + {waypoints}-waypoint plan), the fastest reader measured"
            ),
        )
        .with("files", detail))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_generated_files_load_everywhere() {
        let system = system_text(20);
        assert_eq!(ours_system(&system).ok(), Some(20));
        assert!(roxmltree(&system).is_ok() && xmlrs(system.as_bytes()).is_ok());
        let plan = plan_text(30);
        assert_eq!(ours_plan(&plan).ok(), Some(30));
        assert!(roxmltree(&plan).is_ok() && xmlrs(plan.as_bytes()).is_ok());
    }
}
