//! Mission files: a Petri net over a system file. Loading one loads and checks its system, then
//! checks every name the net uses against it and analyses the net (deadlocks, dead transitions,
//! places never marked, unboundedness) before anything runs.

use std::path::{Path, PathBuf};

use armor_model::net::{self, MissionNet};
use armor_module_api::xml::{self, Located, Pos};

use crate::load::{Diagnostics, Loaded, load_system, read_source};

/// More reachable markings than this and the analysis says so instead of going on.
pub const ANALYSIS_LIMIT_STATES: usize = 1_000_000;

/// What kind of document a file holds, from its top element.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DocumentKind {
    System,
    Mission,
    Pnml,
}

/// Reads a file's top element to tell systems from missions. Errors are reported as for a load.
pub fn document_kind(file: &Path) -> Result<DocumentKind, Diagnostics> {
    kind_of(file, &read_source(file)?)
}

fn kind_of(file: &Path, text: &str) -> Result<DocumentKind, Diagnostics> {
    let fail = |message: String, pos: Pos| Diagnostics {
        file: file.to_path_buf(),
        problems: vec![Located::new(pos, message)],
    };
    let root = xml::parse(text).map_err(|err| fail(err.message, err.pos))?;
    match root.name.as_str() {
        "system" => Ok(DocumentKind::System),
        "mission" => Ok(DocumentKind::Mission),
        "pnml" => Ok(DocumentKind::Pnml),
        other => Err(fail(
            format!("expected <system>, <mission> or <pnml> at the top, found <{other}>"),
            root.pos,
        )),
    }
}

/// A checked mission with its checked system.
#[derive(Clone, Debug)]
pub struct LoadedMission {
    pub file: PathBuf,
    pub net: MissionNet,
    pub system_file: PathBuf,
    pub system: Loaded,
    /// Reachable markings of the untimed net.
    pub states: usize,
}

/// Reads a mission file (our XML or PNML), loads its system, and checks both.
pub fn load_mission(file: &Path, module_path: &[PathBuf]) -> Result<LoadedMission, Diagnostics> {
    let fail = |problems| Diagnostics {
        file: file.to_path_buf(),
        problems,
    };
    let text = read_source(file)?;
    let net = match kind_of(file, &text)? {
        DocumentKind::Pnml => net::from_pnml(&text),
        _ => MissionNet::parse(&text),
    }
    .map_err(fail)?;
    if net.system.is_empty() {
        return Err(fail(vec![Located::new(
            net.pos,
            "the mission names no system file (attribute `system`)",
        )]));
    }
    let system_file = file
        .parent()
        .unwrap_or_else(|| Path::new("."))
        .join(&net.system);
    if let Err(err) = std::fs::metadata(&system_file) {
        return Err(fail(vec![Located::new(
            net.pos,
            format!(
                "cannot read the mission's system file `{}` ({}): {err}",
                net.system,
                system_file.display()
            ),
        )]));
    }
    let system = load_system(&system_file, module_path)?;
    let mut problems = net::check_names(&net, &system.system, &system.descriptions);
    let analysis = net::analyse(&net, ANALYSIS_LIMIT_STATES);
    problems.extend(analysis.problems(&net));
    problems.sort_by_key(|problem| problem.pos);
    if !problems.is_empty() {
        return Err(fail(problems));
    }
    Ok(LoadedMission {
        file: file.to_path_buf(),
        net,
        system_file,
        system,
        states: analysis.states,
    })
}
