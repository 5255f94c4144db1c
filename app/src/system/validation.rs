//! The validation panel's content: exactly the problems `armor check` reports for the file the
//! diagram would save, found by the same function (`armor_model::check`, after the same parse),
//! each tied to the block it is about so that a click selects it.

use armor_model::SystemConfig;
use armor_module_api::xml::Pos;

use crate::common::palette::{BrokenType, Catalog};
use crate::system::diagram::{BlockId, Diagram};

/// One problem, as `armor check` words it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    /// Where it is in the file the diagram saves.
    pub pos: Pos,
    pub message: String,
    /// The block it is about (a link's problem is its input's block).
    pub block: Option<BlockId>,
}

/// Every problem of the diagram against the catalog, sorted by position in the saved file.
pub fn validate(diagram: &Diagram, catalog: &Catalog, broken: &[BrokenType]) -> Vec<Problem> {
    let xml = diagram.to_xml();
    let system = match SystemConfig::parse(&xml) {
        Ok(system) => system,
        // The diagram cannot produce structural errors except through names and values the
        // user typed (an empty parameter value, say): show them as the parser words them.
        Err(problems) => {
            return problems
                .into_iter()
                .map(|problem| Problem {
                    block: block_at_line(diagram, None, problem.pos.line),
                    pos: problem.pos,
                    message: problem.message,
                })
                .collect();
        }
    };
    let mut problems: Vec<Problem> = armor_model::check(&system, catalog)
        .into_iter()
        .map(|problem| Problem {
            block: block_at_line(diagram, Some(&system), problem.pos.line),
            pos: problem.pos,
            message: problem.message,
        })
        .collect();
    // As `armor check` does: a binary that exists but cannot describe itself is reported where
    // its type is named.
    for broken in broken {
        for (index, module) in system.modules.iter().enumerate() {
            if module.module_type == broken.module_type {
                problems.push(Problem {
                    pos: module.type_pos,
                    message: format!(
                        "module `{}`: {}: {}",
                        module.name, broken.binary, broken.error
                    ),
                    block: diagram.blocks().nth(index).map(|(id, _)| id),
                });
            }
        }
    }
    problems.sort_by_key(|problem| problem.pos);
    problems
}

/// The block whose lines of the saved file contain `line`: modules are written in block order,
/// each from its `<module>` line to the next; a `<link>` line belongs to the link's input.
fn block_at_line(diagram: &Diagram, system: Option<&SystemConfig>, line: u32) -> Option<BlockId> {
    let system = system?;
    if let Some(link) = system.links.iter().find(|link| link.pos.line == line) {
        return diagram.block_named(&link.to.module);
    }
    let index = system
        .modules
        .iter()
        .rposition(|module| module.pos.line <= line)?;
    diagram.blocks().nth(index).map(|(id, _)| id)
}
