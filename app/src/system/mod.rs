//! The System view: the block diagram of a system file, whole in this folder. Its state is
//! [`SystemView`]: the document and its editor, the canvas, the file it came from, its problems.
//! The model: `diagram.rs` (blocks, links, subsystems in `diagram/groups.rs`), `editor.rs` (the
//! commands and their undo), `layout.rs` (Arrange), `validation.rs` (`armor check`'s problems
//! tied to blocks), `file.rs` (the system file read and saved); none of them knows egui. The
//! canvas: `viewer.rs` (the egui-snarl adapter), `canvas.rs` (its input: wires, drops, moves,
//! clicks, the clipboard), `overview.rs` (dragging blocks zoomed out). Panels and dialogs:
//! `palette_ui.rs` (the module types), `problems.rs`, `params.rs` (a block's parameters),
//! `search.rs` ("Find block"). The window (`app.rs`) routes frames, files and commands here and
//! shows what the view reports on its status line.

mod canvas;
pub mod diagram;
pub mod editor;
pub mod file;
pub mod layout;
mod overview;
mod palette_ui;
mod params;
mod problems;
mod search;
pub mod validation;
pub mod viewer;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use egui::{Color32, Pos2, Ui};

use crate::command::UiCommand;
use crate::common::context::ViewerContext;
use crate::common::history::Outcome;
use crate::common::palette::Catalog;
use crate::common::palette::Palette;
use crate::files::{Document, Home};
use crate::system::diagram::{BlockId, Diagram, Pin, PinSide};
use crate::system::editor::{Command, Editor};
use crate::system::validation::Problem;
use crate::system::viewer::Canvas;

pub(crate) const ERROR: Color32 = Color32::from_rgb(230, 90, 70);
pub(crate) const OK: Color32 = Color32::from_rgb(90, 200, 110);

/// The System view's state.
#[derive(Default)]
pub struct SystemView {
    pub(crate) editor: Editor,
    /// What this studio last put on the system clipboard: pasting it back pastes the editor's
    /// own clip, which lands beside the last paste rather than on it.
    copied_text: Option<String>,
    pub(crate) path: Option<PathBuf>,
    /// The document as last opened or saved: unsaved changes are differences from it.
    pub(crate) saved: Diagram,
    pub(crate) dirty: bool,
    problems: Vec<Problem>,
    problems_revision: Option<u64>,
    flagged: BTreeSet<BlockId>,
    pub(crate) canvas: Canvas,
    /// Edits queued by this frame's widgets, applied after it.
    commands: Vec<Command>,
    params: Option<params::ParamsDialog>,
    search: Option<String>,
    last_autosave: Option<Instant>,
    autosaved_revision: Option<u64>,
    /// The last save was a draft (required parameters unset), and the status line says so.
    draft_saved: bool,
    /// What the view has to say on the status line (text, is an error), taken by the window.
    messages: Vec<(String, bool)>,
    /// The last fit guessed the size of blocks not yet drawn: fit again after this many frames.
    fit_again: u8,
    /// A subsystem double-clicked this frame, to open once the frame is drawn.
    opened_group: Option<BlockId>,
    /// The canvas is drawing a level of the subsystems: the document is that level's diagram
    /// for the frame (`canvas.rs`).
    drawing_level: bool,
}

impl SystemView {
    /// What the view said on the status line since the last call, oldest first.
    pub fn take_messages(&mut self) -> Vec<(String, bool)> {
        std::mem::take(&mut self.messages)
    }

    fn set_status(&mut self, text: String, is_error: bool) {
        self.messages.push((text, is_error));
    }

    pub fn problems(&self) -> &[Problem] {
        &self.problems
    }

    /// The view: palette, problems, canvas; blocks are coloured by the state of the modules of
    /// the run the Run view watches.
    pub fn ui(&mut self, ui: &mut Ui, viewer: &ViewerContext) {
        let palette = viewer.palette;
        egui::Panel::left("palette")
            .resizable(true)
            .default_size(220.0)
            .show(ui, |ui| self.palette_ui(ui, palette));
        // The problem list takes room only when there are problems: otherwise a line above
        // the canvas says so, and the diagram has the width. (Checked before the panels are
        // laid out, so that a document fitted at its first frame is fitted in the right room.)
        self.update_problems(palette);
        if self.problems.is_empty() {
            egui::Panel::top("no-problems").show(ui, |ui| self.problems_ui(ui, palette));
        } else {
            egui::Panel::right("problems")
                .resizable(true)
                .default_size(300.0)
                .min_size(240.0)
                .show(ui, |ui| self.problems_ui(ui, palette));
        }
        if self.editor.diagram.groups().next().is_some() {
            egui::Panel::top("breadcrumb").show(ui, |ui| self.breadcrumb_ui(ui));
        }
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| {
                self.canvas_ui(
                    ui,
                    &palette.catalog,
                    !viewer.first_frame,
                    viewer.module_states,
                )
            });
    }

    /// Where the canvas is in the subsystems: `System › navigation`, each level above a link
    /// that goes up to it; inside a subsystem, the ports on its border.
    fn breadcrumb_ui(&mut self, ui: &mut Ui) {
        let diagram = &self.editor.diagram;
        let path = diagram.path_to(self.editor.level);
        let mut open = None;
        ui.horizontal_wrapped(|ui| {
            if path.is_empty() {
                ui.strong("System");
            } else if ui
                .link("System")
                .on_hover_text("up to the top (Alt+↑ goes up a level)")
                .clicked()
            {
                open = Some(None);
            }
            for (index, id) in path.iter().enumerate() {
                ui.weak("›");
                let name = diagram.group(*id).map_or("?", |group| group.name.as_str());
                if index + 1 == path.len() {
                    ui.strong(name);
                } else if ui.link(name).clicked() {
                    open = Some(Some(*id));
                }
            }
            match path.last().and_then(|id| diagram.group(*id)) {
                Some(group) => {
                    let ports: Vec<&str> =
                        group.ports.iter().map(|(name, _)| name.as_str()).collect();
                    ui.weak(format!(
                        "   ports on its border: {}",
                        if ports.is_empty() {
                            "none".to_owned()
                        } else {
                            ports.join(", ")
                        }
                    ));
                }
                None => {
                    ui.weak("   double-click a subsystem to open it · Ctrl+G groups the selection");
                }
            }
        });
        if let Some(level) = open {
            self.commands.push(Command::Open(level));
        }
    }

    /// Applies the edits queued this frame.
    pub fn apply_commands(&mut self, ctx: &egui::Context, catalog: &Catalog) {
        for command in std::mem::take(&mut self.commands) {
            let copies = matches!(command, Command::Copy | Command::Cut);
            let arranges = matches!(command, Command::Arrange);
            let opens = matches!(command, Command::Open(_));
            match self.editor.apply(command, catalog) {
                Outcome::Nothing if opens => self.zoom_to_fit(),
                Outcome::Nothing => {}
                Outcome::Done(text) => {
                    if arranges {
                        self.zoom_to_fit();
                    }
                    if copies {
                        // On the system clipboard too, as a system file of the copied blocks.
                        let xml = self.editor.clipboard.to_xml();
                        ctx.copy_text(xml.clone());
                        self.copied_text = Some(xml);
                    }
                    self.set_status(text, false);
                }
                Outcome::Refused(reason) => self.set_status(format!("refused: {reason}"), true),
            }
        }
    }

    /// Checks the document again if it changed, as `armor check` would.
    pub fn update_problems(&mut self, palette: &Palette) {
        let revision = self.editor.revision();
        if self.problems_revision != Some(revision) {
            self.problems_revision = Some(revision);
            self.problems =
                validation::validate(&self.editor.diagram, &palette.catalog, &palette.broken);
            self.flagged = self.problems.iter().filter_map(|p| p.block).collect();
            // The draft's warning goes once its cause does.
            if self.draft_saved
                && self
                    .editor
                    .diagram
                    .all_missing_required(&palette.catalog)
                    .is_empty()
            {
                self.draft_saved = false;
                self.set_status(
                    "every required parameter is set (save to make the file complete)".to_owned(),
                    false,
                );
            }
        }
    }

    // ----- Files -----

    /// Opens a system file, replacing the document (unsaved changes stay in the undo history of
    /// nobody: the caller asks first).
    pub fn open(&mut self, file: &Path, home: &Home) {
        match file::open(file) {
            Ok(diagram) => {
                self.saved = diagram.clone();
                self.editor.replace(diagram);
                self.path = Some(file.to_path_buf());
                self.canvas.view_request = None;
                self.zoom_to_fit();
                if let Err(err) = home.add_recent(file) {
                    tracing::warn!("{err:#}");
                }
                self.set_status(format!("opened {}", file.display()), false);
            }
            Err(err) => self.set_status(format!("{err:#}"), true),
        }
    }

    /// Saves to `file`; whether it was saved.
    pub fn save(&mut self, file: PathBuf, home: &Home, catalog: &Catalog) -> bool {
        match file::save(&file, &self.editor.diagram, catalog) {
            Ok(missing) => {
                self.saved = self.editor.diagram.clone();
                self.path = Some(file.clone());
                home.clear_recovery(Document::System);
                self.autosaved_revision = Some(self.editor.revision());
                if let Err(err) = home.add_recent(&file) {
                    tracing::warn!("{err:#}");
                }
                if missing.is_empty() {
                    self.set_status(format!("saved {}", file.display()), false);
                } else {
                    self.set_status(
                        format!(
                            "saved {} as a draft: required parameters unset: {} (armor check and \
                             armor run refuse it until they are set)",
                            file.display(),
                            missing.join(", ")
                        ),
                        true,
                    );
                }
                self.draft_saved = !missing.is_empty();
                true
            }
            Err(err) => {
                self.set_status(format!("{err:#}"), true);
                false
            }
        }
    }

    pub fn new_document(&mut self) {
        self.editor.replace(Diagram::default());
        self.saved = Diagram::default();
        self.path = None;
        self.set_status("new system".to_owned(), false);
    }

    /// Restores a recovery copy of the system that was at `original` (if it had a file).
    pub fn restore(&mut self, original: Option<&Path>, text: &str) {
        match Diagram::from_xml(text) {
            Ok(diagram) => {
                self.path = original.map(Path::to_path_buf);
                // What is on disk (if anything) is the saved state: the restored document
                // shows as changed until it is saved.
                self.saved = self
                    .path
                    .as_deref()
                    .and_then(|path| file::open(path).ok())
                    .unwrap_or_default();
                self.editor.replace(diagram);
                self.zoom_to_fit();
                self.set_status("restored the recovery copy".to_owned(), false);
            }
            Err(_) => self.set_status("the recovery copy cannot be read".to_owned(), true),
        }
    }

    /// Writes the recovery copy every `every` while there are unsaved changes, unless `held`
    /// (recovery copies of an earlier session are still on offer).
    pub fn autosave(&mut self, ctx: &egui::Context, home: &Home, every: Duration, held: bool) {
        let revision = self.editor.revision();
        if !self.dirty || self.autosaved_revision == Some(revision) || held {
            return;
        }
        let due = self
            .last_autosave
            .is_none_or(|last| last.elapsed() >= every);
        if !due {
            ctx.request_repaint_after(every);
            return;
        }
        self.last_autosave = Some(Instant::now());
        self.autosaved_revision = Some(revision);
        if let Err(err) = home.write_recovery(
            Document::System,
            self.path.as_deref(),
            &self.editor.diagram.to_xml(),
        ) {
            tracing::warn!("autosave: {err:#}");
        }
    }

    // ----- The view -----

    /// Does a command of the table that edits or moves about the diagram (the window does the
    /// files' and the run's).
    pub fn execute(&mut self, command: UiCommand) {
        let edit = match command {
            UiCommand::Undo => Command::Undo,
            UiCommand::Redo => Command::Redo,
            UiCommand::Cut => Command::Cut,
            UiCommand::Copy => Command::Copy,
            UiCommand::Paste => Command::Paste,
            UiCommand::Duplicate => Command::Duplicate,
            UiCommand::Delete => Command::DeleteSelection,
            UiCommand::SelectAll => Command::SelectAll,
            UiCommand::Arrange => Command::Arrange,
            UiCommand::ClearSelection => Command::Select(BTreeSet::new()),
            UiCommand::Group => Command::Group,
            UiCommand::Ungroup => Command::Ungroup,
            UiCommand::Up => {
                let level = self.editor.level;
                Command::Open(level.and_then(|level| self.editor.diagram.level_of(level)))
            }
            UiCommand::ZoomToFit => {
                self.zoom_to_fit();
                return;
            }
            UiCommand::Find => {
                self.search = Some(String::new());
                return;
            }
            _ => return,
        };
        self.commands.push(edit);
    }

    pub fn zoom_to_fit(&mut self) {
        // With subsystems, the level shown (inside the canvas's frame, the document is that
        // level's already).
        let level;
        let diagram = if self.drawing_level || self.editor.diagram.groups().next().is_none() {
            &self.editor.diagram
        } else {
            level = self
                .editor
                .diagram
                .at_level(self.editor.level, &Catalog::new())
                .0;
            &level
        };
        self.canvas.view_request = self.canvas.bounds(diagram, None);
        // Blocks not drawn yet have a guessed size: fitted again once they are (egui-snarl
        // draws the blocks in view, and the view changes with the fit: a few frames).
        let guessed = diagram
            .blocks()
            .any(|(id, _)| !self.canvas.node_rects.contains_key(&id));
        self.fit_again = if guessed { 3 } else { 0 };
    }

    /// Selects a block and brings it into view.
    fn show_block(&mut self, block: BlockId) {
        self.commands.push(Command::Select([block].into()));
        let only: BTreeSet<BlockId> = [block].into();
        if let Some(rect) = self.canvas.bounds(&self.editor.diagram, Some(&only)) {
            // Not closer than 1:1, and with some of the surroundings.
            self.canvas.view_request = Some(rect.expand(200.0));
        }
    }

    /// Shows the first blocks at about `scale` (the bench's other views).
    pub fn view_at_scale(&mut self, scale: f32) {
        if let Some((_, block)) = self.editor.diagram.blocks().next() {
            let min = Pos2::new(block.pos[0], block.pos[1]);
            // `viewer::fit` adds a margin of 40 around the view it is asked for.
            let size = self.canvas.rect.size() / scale - egui::vec2(80.0, 80.0);
            self.canvas.view_request = Some(egui::Rect::from_min_size(min, size));
        }
    }

    /// Clears the selection and frames the whole document, for a picture of it.
    pub fn frame_for_picture(&mut self) {
        self.commands.push(Command::Select(BTreeSet::new()));
        self.zoom_to_fit();
    }

    // ----- Where things are on screen (tests and the bench) -----

    /// Where a block's pin is on screen (as drawn last frame): `side` is input or output; a
    /// subsystem's border inside it is `NAME inputs` or `NAME outputs`.
    pub fn pin_pos(&self, block: &str, port: &str, side: PinSide) -> Option<Pos2> {
        let diagram = &self.editor.diagram;
        let border = |suffix: &str, outputs: bool| {
            let group = diagram.group_named(block.strip_suffix(suffix)?)?;
            Some(crate::system::diagram::border_id(group, outputs))
        };
        let block = diagram
            .block_named(block)
            .or_else(|| diagram.group_named(block))
            .or_else(|| border(" inputs", false))
            .or_else(|| border(" outputs", true))?;
        self.canvas.pin_screen_pos(&Pin {
            side,
            port: crate::system::diagram::PortRef {
                block,
                port: port.to_owned(),
            },
        })
    }

    /// The wires' ends marked last frame: the input pin (`block.port`) and where, on screen.
    pub fn wire_ends(&self) -> Vec<(String, Pos2)> {
        self.canvas
            .wire_ends
            .iter()
            .filter_map(|(port, at)| {
                let block = self.editor.diagram.block(port.block)?;
                Some((
                    format!("{}.{}", block.name, port.port),
                    self.canvas.to_global * *at,
                ))
            })
            .collect()
    }

    /// The links drawn round the blocks (those that run backwards): `from -> to` as
    /// `block.port` and the route's corners on screen, as drawn last frame.
    pub fn routes(&self, catalog: &Catalog) -> Vec<(String, Vec<Pos2>)> {
        let diagram = &self.editor.diagram;
        self.canvas
            .routes(diagram, catalog)
            .into_iter()
            .map(|(link, points)| {
                let name = |port: &crate::system::diagram::PortRef| {
                    diagram
                        .block(port.block)
                        .map_or_else(String::new, |block| format!("{}.{}", block.name, port.port))
                };
                let fallback = if link.fallback > 0 {
                    format!(" (fallback {})", link.fallback)
                } else {
                    String::new()
                };
                (
                    format!("{} -> {}{fallback}", name(&link.from), name(&link.to)),
                    points
                        .into_iter()
                        .map(|point| self.canvas.to_global * point)
                        .collect(),
                )
            })
            .collect()
    }

    /// A block's rectangle on screen (as drawn last frame).
    pub fn block_screen_rect(&self, catalog: &Catalog, block: &str) -> Option<egui::Rect> {
        self.block_rect(catalog, block)
            .map(|rect| self.canvas.to_global * rect)
    }

    /// Where a block is on screen (its centre, as drawn last frame).
    pub fn block_pos(&self, catalog: &Catalog, block: &str) -> Option<Pos2> {
        self.block_rect(catalog, block)
            .map(|rect| self.canvas.to_global * rect.center())
    }

    /// Where a block's header is on screen (where a hand grabs it to move it).
    pub fn block_header_pos(&self, catalog: &Catalog, block: &str) -> Option<Pos2> {
        self.block_rect(catalog, block)
            .map(|rect| self.canvas.to_global * Pos2::new(rect.center().x, rect.min.y + 10.0))
    }

    /// A block's rectangle on the canvas, if it has been laid out.
    fn block_rect(&self, catalog: &Catalog, block: &str) -> Option<egui::Rect> {
        let diagram = &self.editor.diagram;
        if let Some(id) = diagram.group_named(block) {
            // A subsystem's block: where its group is, as big as it was drawn.
            let group = diagram.group(id)?;
            let size = self.canvas.node_rects.get(&id)?.size();
            return Some(egui::Rect::from_min_size(
                Pos2::new(group.pos[0], group.pos[1]),
                size,
            ));
        }
        let id = diagram.block_named(block)?;
        let rect = self.canvas.rect_of(diagram, catalog, id);
        rect.is_finite().then_some(rect)
    }
}
