//! The system file of the System view: read into a diagram and written back (atomically,
//! through `armor_runtime::fs::write_atomically`: a failed save leaves the file as it was).

use std::path::Path;

use anyhow::Context as _;

use super::diagram::Diagram;
use crate::common::palette::Catalog;

/// Reads a system file into a diagram; the error lists every problem as `FILE:LINE:COL: message`.
pub fn open(file: &Path) -> anyhow::Result<Diagram> {
    let text =
        std::fs::read_to_string(file).with_context(|| format!("cannot read {}", file.display()))?;
    Diagram::from_xml(&text).map_err(|problems| {
        let lines: Vec<String> = problems
            .iter()
            .map(|problem| format!("{}:{}: {}", file.display(), problem.pos, problem.message))
            .collect();
        anyhow::anyhow!("{}", lines.join("\n"))
    })
}

/// Saves a diagram, refusing while a required parameter is unset, and naming each one.
/// Saves `diagram` to `file` (atomically: a failed save leaves the file as it was). A system
/// with required parameters unset is saved all the same, as a draft that `armor check` and
/// `armor run` refuse with the reasons: the parameters unset are returned for the warning.
pub fn save(file: &Path, diagram: &Diagram, catalog: &Catalog) -> anyhow::Result<Vec<String>> {
    armor_runtime::fs::write_atomically(file, diagram.to_xml().as_bytes())
        .with_context(|| format!("cannot save {}", file.display()))?;
    Ok(diagram.all_missing_required(catalog))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use armor_module_api::ModuleDescription;
    use armor_module_api::describe::{ParamSpec, ParamType};

    #[test]
    fn a_draft_is_saved_with_what_it_lacks_and_a_failed_save_changes_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("system.xml");
        std::fs::write(&file, "the good version").unwrap();
        let mut nav = ModuleDescription::new("nav", "drives");
        nav.params
            .push(ParamSpec::new("goal_m", ParamType::Float, "goal"));
        let catalog: Catalog = [("nav".to_owned(), nav)].into_iter().collect();
        let mut diagram = Diagram::default();
        let id = diagram.add_block("nav", [0.0, 0.0]);
        assert!(save(&dir.path().join("missing/system.xml"), &diagram, &catalog).is_err());
        assert_eq!(std::fs::read_to_string(&file).unwrap(), "the good version");
        let missing = save(&file, &diagram, &catalog).unwrap();
        assert_eq!(missing, ["nav.goal_m"]);
        assert_eq!(open(&file).unwrap(), diagram);
        diagram.set_param(id, "goal_m", Some("3".into()));
        assert!(save(&file, &diagram, &catalog).unwrap().is_empty());
        assert_eq!(open(&file).unwrap(), diagram);
    }
}
