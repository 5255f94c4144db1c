//! The editing session over a [`Diagram`]: the undo history, the selection, the clipboard and
//! the commands the user interface queues during a frame and applies after it. No egui here:
//! every rule of editing is tested without a window.

use std::collections::BTreeSet;

use armor_model::plural;

use super::diagram::{BlockId, Clip, Diagram, Link, Pin, PortRef};
use crate::common::history::{History, Outcome};
use crate::common::palette::Catalog;

/// Where pasted and duplicated blocks land, relative to their originals.
const PASTE_OFFSET: [f32; 2] = [40.0, 40.0];

/// An edit, queued by the user interface during a frame and applied after it.
#[derive(Clone, Debug)]
pub enum Command {
    AddBlock {
        module_type: String,
        pos: [f32; 2],
    },
    /// A wire dropped from one pin on another; with `fallback` (Shift held), into an input
    /// that has a source, as its next fallback source.
    Connect {
        from: Pin,
        to: Pin,
        fallback: bool,
    },
    RemoveLink(Link),
    DisconnectInput(PortRef),
    DisconnectOutput(PortRef),
    /// Blocks moved on the canvas; `before` is the document when the drag began.
    Moved {
        before: Box<Diagram>,
    },
    SetParam {
        block: BlockId,
        name: String,
        value: Option<String>,
    },
    Rename {
        block: BlockId,
        name: String,
    },
    DeleteSelection,
    /// Lays every block out in layers by data flow (File → Arrange).
    Arrange,
    Copy,
    /// Copy, then delete, in one undo step.
    Cut,
    Paste,
    /// Paste what the system clipboard holds: a system file's blocks and links.
    PasteText(String),
    Duplicate,
    SelectAll,
    Select(BTreeSet<BlockId>),
    /// Groups the selection into a subsystem (Ctrl+G).
    Group,
    /// Puts the selected subsystems' members back at their level (Ctrl+Shift+G).
    Ungroup,
    /// Shows the inside of a subsystem on the canvas (`None`: the top).
    Open(Option<BlockId>),
    Undo,
    Redo,
}

#[derive(Debug, Default)]
pub struct Editor {
    pub diagram: Diagram,
    pub history: History<Diagram>,
    pub selection: BTreeSet<BlockId>,
    pub clipboard: Clip,
    /// The subsystem whose inside the canvas shows (`None`: the top).
    pub level: Option<BlockId>,
    /// Changes with every change of the document's content, so that views rebuild what they
    /// derive from it only when needed.
    revision: u64,
}

impl Editor {
    pub fn new(diagram: Diagram) -> Editor {
        Editor {
            diagram,
            ..Editor::default()
        }
    }

    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// Replaces the whole document (open, restore): a fresh history.
    pub fn replace(&mut self, diagram: Diagram) {
        self.diagram = diagram;
        self.history = History::default();
        self.selection.clear();
        self.level = None;
        self.revision += 1;
    }

    /// Something outside the document changed what views derive from it (the catalog).
    pub fn touch(&mut self) {
        self.revision += 1;
    }

    /// Records `before` as an undo step and marks the document changed.
    fn changed(&mut self, before: Diagram) {
        self.history.record(before);
        self.revision += 1;
    }

    pub fn apply(&mut self, command: Command, catalog: &Catalog) -> Outcome {
        let before = self.diagram.clone();
        match command {
            Command::AddBlock { module_type, pos } => {
                let id = self.diagram.add_block(&module_type, pos);
                self.diagram.put_in(self.level, &[id]);
                self.changed(before);
                self.selection = [id].into();
                let name = self.block_name(id);
                Outcome::Done(format!("added `{name}`"))
            }
            Command::Connect {
                from,
                to,
                fallback: true,
            } => match self.diagram.connect_fallback(catalog, &from, &to) {
                Ok(0) => {
                    self.changed(before);
                    Outcome::Done("linked".to_owned())
                }
                Ok(rank) => {
                    self.changed(before);
                    Outcome::Done(format!("linked as fallback {rank}"))
                }
                Err(reason) => Outcome::Refused(reason),
            },
            Command::Connect { from, to, .. } => match self.diagram.connect(catalog, &from, &to) {
                Ok(replaced) => {
                    if self.diagram == before {
                        return Outcome::Nothing;
                    }
                    self.changed(before);
                    match replaced {
                        Some(old) => Outcome::Done(format!(
                            "linked; {} had a source already, {}, which was replaced",
                            self.diagram.port_label(&old.to),
                            self.diagram.port_label(&old.from)
                        )),
                        None => Outcome::Done("linked".to_owned()),
                    }
                }
                Err(reason) => Outcome::Refused(reason),
            },
            Command::RemoveLink(link) => {
                if self.diagram.remove_link(&link) {
                    self.changed(before);
                    Outcome::Done("link removed".to_owned())
                } else {
                    Outcome::Nothing
                }
            }
            Command::DisconnectInput(port) => {
                self.removed_links(before, |diagram| diagram.disconnect_input(&port))
            }
            Command::DisconnectOutput(port) => {
                self.removed_links(before, |diagram| diagram.disconnect_output(&port))
            }
            Command::Moved { before } => {
                if *before == self.diagram {
                    return Outcome::Nothing;
                }
                self.changed(*before);
                Outcome::Nothing
            }
            Command::SetParam { block, name, value } => {
                self.diagram.set_param(block, &name, value);
                if self.diagram == before {
                    return Outcome::Nothing;
                }
                self.changed(before);
                Outcome::Nothing
            }
            Command::Rename { block, name } => match self.diagram.rename(block, &name) {
                Ok(()) if self.diagram == before => Outcome::Nothing,
                Ok(()) => {
                    self.changed(before);
                    Outcome::Done(format!("renamed to `{name}`"))
                }
                Err(reason) => Outcome::Refused(reason),
            },
            Command::DeleteSelection => {
                if self.selection.is_empty() {
                    return Outcome::Nothing;
                }
                let count = self.selection.len();
                let selection = std::mem::take(&mut self.selection);
                self.diagram.remove_blocks(&selection);
                self.changed(before);
                Outcome::Done(format!("deleted {}", plural(count, "block")))
            }
            Command::Arrange => {
                self.diagram.arrange(Some(catalog));
                if self.diagram == before {
                    return Outcome::Nothing;
                }
                self.changed(before);
                Outcome::Done("arranged by data flow".to_owned())
            }
            Command::Copy => {
                if self.selection.is_empty() {
                    return Outcome::Nothing;
                }
                self.clipboard = self.diagram.copy(&self.selection);
                Outcome::Done(format!("copied {}", plural(self.selection.len(), "block")))
            }
            Command::Cut => {
                if self.selection.is_empty() {
                    return Outcome::Nothing;
                }
                let selection = std::mem::take(&mut self.selection);
                self.clipboard = self.diagram.copy(&selection);
                self.diagram.remove_blocks(&selection);
                self.changed(before);
                Outcome::Done(format!("cut {}", plural(selection.len(), "block")))
            }
            Command::Paste => {
                if self.clipboard.is_empty() {
                    return Outcome::Nothing;
                }
                let clip = self.clipboard.clone();
                self.paste(before, &clip)
            }
            Command::PasteText(text) => match Clip::from_xml(&text) {
                Ok(clip) => self.paste(before, &clip),
                Err(reason) => Outcome::Refused(reason),
            },
            Command::Duplicate => {
                if self.selection.is_empty() {
                    return Outcome::Nothing;
                }
                let clip = self.diagram.copy(&self.selection);
                self.paste(before, &clip)
            }
            Command::SelectAll => {
                let level = self.level;
                self.selection = self
                    .diagram
                    .blocks()
                    .map(|(id, _)| id)
                    .chain(self.diagram.groups().map(|(id, _)| id))
                    .filter(|id| self.diagram.level_of(*id) == level)
                    .collect();
                Outcome::Nothing
            }
            Command::Group => match self.diagram.group_items(&self.selection, None) {
                Ok(id) => {
                    self.changed(before);
                    self.selection = [id].into();
                    let name = self.diagram.group(id).map(|g| g.name.clone());
                    Outcome::Done(format!(
                        "grouped into `{}`; double-click it to open it",
                        name.unwrap_or_default()
                    ))
                }
                Err(reason) => Outcome::Refused(reason),
            },
            Command::Ungroup => {
                let groups: Vec<BlockId> = self
                    .selection
                    .iter()
                    .copied()
                    .filter(|id| self.diagram.is_group(*id))
                    .collect();
                if groups.is_empty() {
                    return Outcome::Refused("select a subsystem to ungroup".to_owned());
                }
                let mut members = BTreeSet::new();
                for group in &groups {
                    if let Some(inner) = self.diagram.group(*group) {
                        members.extend(inner.members.iter().copied());
                    }
                    members.extend(
                        self.diagram
                            .groups()
                            .filter(|(_, inner)| inner.parent == Some(*group))
                            .map(|(id, _)| id),
                    );
                    let _ = self.diagram.ungroup(*group);
                }
                self.changed(before);
                self.selection = members;
                Outcome::Done(format!("ungrouped {}", plural(groups.len(), "subsystem")))
            }
            Command::Open(level) => {
                if level.is_some_and(|id| !self.diagram.is_group(id)) {
                    return Outcome::Nothing;
                }
                self.level = level;
                self.selection.clear();
                // The canvas shows another level: what it derived must be made again.
                self.revision += 1;
                Outcome::Nothing
            }
            Command::Select(ids) => {
                self.selection = ids;
                Outcome::Nothing
            }
            Command::Undo => {
                if self.history.undo(&mut self.diagram) {
                    self.after_history_step();
                    Outcome::Done("undone".to_owned())
                } else {
                    Outcome::Refused("nothing to undo".to_owned())
                }
            }
            Command::Redo => {
                if self.history.redo(&mut self.diagram) {
                    self.after_history_step();
                    Outcome::Done("redone".to_owned())
                } else {
                    Outcome::Refused("nothing to redo".to_owned())
                }
            }
        }
    }

    fn paste(&mut self, before: Diagram, clip: &Clip) -> Outcome {
        let new = self.diagram.paste(clip, PASTE_OFFSET);
        self.diagram.put_in(self.level, &new);
        // The next paste of the same clip lands beside this one, not on top of it.
        self.clipboard = self.diagram.copy(&new.iter().copied().collect());
        self.changed(before);
        let count = new.len();
        self.selection = new.into_iter().collect();
        Outcome::Done(format!("pasted {}", plural(count, "block")))
    }

    fn removed_links(
        &mut self,
        before: Diagram,
        remove: impl FnOnce(&mut Diagram) -> usize,
    ) -> Outcome {
        match remove(&mut self.diagram) {
            0 => Outcome::Nothing,
            count => {
                self.changed(before);
                Outcome::Done(format!("removed {}", plural(count, "link")))
            }
        }
    }

    fn after_history_step(&mut self) {
        self.revision += 1;
        let diagram = &self.diagram;
        self.selection
            .retain(|id| diagram.block(*id).is_some() || diagram.is_group(*id));
        if self.level.is_some_and(|id| !self.diagram.is_group(id)) {
            self.level = None;
        }
    }

    fn block_name(&self, id: BlockId) -> String {
        self.diagram
            .block(id)
            .map(|block| block.name.clone())
            .unwrap_or_default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undo_goes_back_to_empty_and_redo_forward() {
        let catalog = Catalog::new();
        let mut editor = Editor::default();
        for _ in 0..3 {
            editor.apply(
                Command::AddBlock {
                    module_type: "counter".into(),
                    pos: [0.0, 0.0],
                },
                &catalog,
            );
        }
        editor.apply(Command::SelectAll, &catalog);
        editor.apply(Command::Duplicate, &catalog);
        assert_eq!(editor.diagram.len(), 6);
        while editor.history.can_undo() {
            editor.apply(Command::Undo, &catalog);
        }
        assert!(editor.diagram.is_empty());
        assert!(editor.selection.is_empty());
        editor.apply(Command::Redo, &catalog);
        assert_eq!(editor.diagram.len(), 1);
    }

    #[test]
    fn delete_copy_paste() {
        let catalog = Catalog::new();
        let mut editor = Editor::default();
        editor.apply(
            Command::AddBlock {
                module_type: "sink".into(),
                pos: [0.0, 0.0],
            },
            &catalog,
        );
        editor.apply(Command::Copy, &catalog);
        editor.apply(Command::Paste, &catalog);
        editor.apply(Command::Paste, &catalog);
        let names: Vec<_> = editor
            .diagram
            .blocks()
            .map(|(_, b)| (b.name.clone(), b.pos))
            .collect();
        assert_eq!(
            names,
            [
                ("sink".to_owned(), [0.0, 0.0]),
                ("sink_2".to_owned(), [40.0, 40.0]),
                ("sink_3".to_owned(), [80.0, 80.0])
            ]
        );
        editor.apply(Command::DeleteSelection, &catalog);
        assert_eq!(editor.diagram.len(), 2);
    }
}
