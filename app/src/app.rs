//! The studio window: menu, palette, canvas, validation panel and dialogs. UI functions queue
//! [`Command`]s; [`StudioApp::ui`] applies them after the frame, then keeps what derives from
//! the document (title, dirty marker, problems, recovery copy) up to date.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use egui::{Color32, Key, KeyboardShortcut, Modifiers, Pos2, RichText, Ui};
use egui_snarl::ui::SnarlWidget;

use crate::diagram::{BlockId, Diagram, Pin, PinSide};
use crate::editor::{Command, Editor, Outcome};
use crate::files::{self, Document, Home, Recovery};
use crate::mission::MissionView;
use crate::palette::{Entry, Palette};
use crate::run::{RunView, Surroundings as RunSurroundings, Target};
use crate::validation::{self, Problem};
use crate::viewer::{self, Canvas, CanvasEvents, DiagramViewer};

const ERROR: Color32 = Color32::from_rgb(230, 90, 70);
const OK: Color32 = Color32::from_rgb(90, 200, 110);

/// The canvas's id: tests and the selection lookup name it.
const CANVAS_ID: &str = "diagram";

/// How the studio starts.
pub struct Options {
    pub home: Home,
    /// Where module binaries are looked for.
    pub module_path: Vec<PathBuf>,
    /// A palette made in advance (tests); else the module path is probed in the background.
    pub palette: Option<Palette>,
    /// A file to open at start: a system, or a plan (opened in the Mission view).
    pub file: Option<PathBuf>,
    /// How often the recovery copy is written while there are unsaved changes.
    pub autosave_every: Duration,
}

impl Options {
    pub fn new(home: Home) -> Options {
        Options {
            home,
            module_path: armor_runtime::probe::module_path(),
            palette: None,
            file: None,
            autosave_every: Duration::from_secs(5),
        }
    }
}

/// The status line: what the last action did, or why it was refused.
#[derive(Clone, Debug, Default)]
pub struct Status {
    pub text: String,
    pub is_error: bool,
}

/// The studio's views: the system's block diagram, the mission's map, the run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum View {
    System,
    Mission,
    Run,
}

/// What a path dialog is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathPurpose {
    Open,
    SaveAs,
    ExportPng,
    OpenPlan,
    SavePlanAs,
    ImportGpx,
    ExportMission,
    ExportPnml,
    ExportMapPng,
    OpenRecording,
}

struct PathDialog {
    purpose: PathPurpose,
    text: String,
}

/// The parameters dialog of one block, with what the user is typing.
struct ParamsDialog {
    block: BlockId,
    name: String,
    values: BTreeMap<String, String>,
}

/// A picture requested from the renderer: the part under `crop` (the canvas or the map) is
/// written to `path`.
#[derive(Clone, Debug)]
struct ExportRequest {
    path: PathBuf,
    crop: egui::Rect,
}

/// What replaces a document, or closes the window: held while the user is asked what to do
/// with the unsaved changes it would lose.
#[derive(Clone, Debug, PartialEq)]
enum Replacing {
    NewSystem,
    OpenSystem(PathBuf),
    NewPlan,
    OpenPlan(PathBuf),
    Quit,
}

/// The answer to "Save changes?".
#[derive(Clone, Copy, Debug, PartialEq)]
enum UnsavedChoice {
    Save,
    Discard,
    Cancel,
}

pub struct StudioApp {
    editor: Editor,
    /// What this studio last put on the system clipboard: pasting it back pastes the editor's
    /// own clip, which lands beside the last paste rather than on it.
    copied_text: Option<String>,
    palette: Palette,
    home: Home,
    path: Option<PathBuf>,
    /// The document as last opened or saved: unsaved changes are differences from it.
    saved: Diagram,
    dirty: bool,
    status: Status,
    problems: Vec<Problem>,
    problems_revision: Option<u64>,
    flagged: BTreeSet<BlockId>,
    canvas: Canvas,
    commands: Vec<Command>,
    params: Option<ParamsDialog>,
    path_dialog: Option<PathDialog>,
    search: Option<String>,
    help_open: bool,
    /// Recovery copies left by a session that did not end cleanly, offered one at a time.
    recovery: Vec<Recovery>,
    autosave_every: Duration,
    last_autosave: Option<Instant>,
    autosaved_revision: Option<u64>,
    view: View,
    /// Made at the first frame that needs it (its map draws with the window's context).
    mission: Option<MissionView>,
    /// A plan to open once the mission view exists.
    plan_to_open: Option<PathBuf>,
    last_plan_autosave: Option<Instant>,
    plan_autosaved_revision: Option<u64>,
    title: String,
    /// The revision the title and dirty marker were computed for.
    seen_revision: Option<u64>,
    /// The last frame took place at least once (the first one lays blocks out).
    started: bool,
    /// A picture to take once this many more frames are drawn.
    export_after: Option<(PathBuf, View, u32)>,
    run: RunView,
    /// Waiting for the user's answer about unsaved changes.
    unsaved_prompt: Option<Replacing>,
    /// Done once the "save as" asked for by that prompt has saved.
    after_save_as: Option<Replacing>,
    /// The window may close: its unsaved changes were saved or given up.
    quitting: bool,
    /// Given up on closing: no recovery copy is to be left.
    discard_on_exit: bool,
}

impl StudioApp {
    pub fn new(options: Options) -> StudioApp {
        let run = RunView::new(options.module_path.clone());
        let palette = options.palette.unwrap_or_else(|| {
            Palette::probe(&options.module_path, armor_runtime::probe::DEFAULT_TIMEOUT)
        });
        let recovery = [Document::System, Document::Plan]
            .into_iter()
            .filter_map(|document| options.home.recovery(document))
            .collect();
        let mut app = StudioApp {
            editor: Editor::default(),
            copied_text: None,
            palette,
            home: options.home,
            path: None,
            saved: Diagram::default(),
            dirty: false,
            status: Status::default(),
            problems: Vec::new(),
            problems_revision: None,
            flagged: BTreeSet::new(),
            canvas: Canvas::default(),
            commands: Vec::new(),
            params: None,
            path_dialog: None,
            search: None,
            help_open: false,
            recovery,
            autosave_every: options.autosave_every,
            last_autosave: None,
            autosaved_revision: None,
            view: View::System,
            mission: None,
            plan_to_open: None,
            last_plan_autosave: None,
            plan_autosaved_revision: None,
            title: String::new(),
            seen_revision: None,
            started: false,
            export_after: None,
            run,
            unsaved_prompt: None,
            after_save_as: None,
            quitting: false,
            discard_on_exit: false,
        };
        if let Some(file) = options.file {
            if is_plan(&file) {
                app.view = View::Mission;
                app.plan_to_open = Some(file);
            } else {
                app.open(&file);
            }
        }
        app
    }

    pub fn view(&self) -> View {
        self.view
    }

    pub fn set_view(&mut self, view: View) {
        self.view = view;
        self.seen_revision = None;
    }

    /// The Run view.
    pub fn run(&self) -> &RunView {
        &self.run
    }

    pub fn run_mut(&mut self) -> &mut RunView {
        &mut self.run
    }

    /// Starts a run of the plan open in the Mission view, else of the system, after saving
    /// what has unsaved changes; shows the Run view.
    pub fn start_run(&mut self, ctx: &egui::Context) {
        let target = self.run.target(&RunSurroundings {
            mission: self.mission.as_mut(),
            system_file: self.path.as_deref(),
            catalog: &self.palette.catalog,
        });
        let Some(target) = target else {
            self.set_status(
                "nothing to run: open or save a system or a plan first".to_owned(),
                true,
            );
            return;
        };
        match &target {
            Target::Plan(_) if self.mission.as_ref().is_some_and(MissionView::is_dirty) => {
                self.save_plan(None)
            }
            Target::System(_) if self.dirty => self.save(None),
            _ => {}
        }
        self.set_view(View::Run);
        let mut surroundings = RunSurroundings {
            mission: self.mission.as_mut(),
            system_file: self.path.as_deref(),
            catalog: &self.palette.catalog,
        };
        self.run.start(target, &mut surroundings, ctx);
    }

    /// Watches a run of the open system started elsewhere, through its control interface.
    pub fn attach_run(&mut self, control: std::net::SocketAddr, ctx: &egui::Context) {
        let Some(system) = self.path.clone() else {
            return;
        };
        let mut surroundings = RunSurroundings {
            mission: None,
            system_file: Some(&system),
            catalog: &self.palette.catalog,
        };
        self.run.attach(
            Target::System(system.clone()),
            control,
            &mut surroundings,
            ctx,
        );
    }

    /// The Mission view, once a frame has shown it.
    pub fn mission(&self) -> Option<&MissionView> {
        self.mission.as_ref()
    }

    pub fn mission_mut(&mut self) -> Option<&mut MissionView> {
        self.mission.as_mut()
    }

    /// Reports what a file operation of the mission view did on the status line.
    fn report(&mut self, report: crate::mission::Report) {
        match report {
            Ok(text) => self.set_status(text, false),
            Err(err) => self.set_status(format!("{err:#}"), true),
        }
    }

    /// Runs a file operation of the mission view (which exists once its view was shown).
    fn with_mission(&mut self, operation: impl FnOnce(&mut MissionView) -> crate::mission::Report) {
        let report = match self.mission.as_mut() {
            Some(mission) => operation(mission),
            None => Err(anyhow::anyhow!("open the Mission view first")),
        };
        if report.is_ok() {
            self.seen_revision = None;
        }
        self.report(report);
    }

    pub fn open_plan(&mut self, file: &Path) {
        self.with_mission(|mission| mission.open(file));
        if self.mission.as_ref().and_then(MissionView::path) == Some(file)
            && let Err(err) = self.home.add_recent(file)
        {
            tracing::warn!("{err:#}");
        }
    }

    pub fn save_plan(&mut self, file: Option<&Path>) {
        let has_path = self.mission.as_ref().and_then(MissionView::path).is_some();
        if file.is_none() && !has_path {
            self.ask_path(PathPurpose::SavePlanAs, String::new());
            return;
        }
        self.with_mission(|mission| mission.save(file));
        if self.status.is_error {
            return;
        }
        self.home.clear_recovery(Document::Plan);
        self.plan_autosaved_revision = self.mission.as_ref().map(|m| m.editor.revision());
        if let Some(path) = self
            .mission
            .as_ref()
            .and_then(MissionView::path)
            .map(Path::to_path_buf)
            && let Err(err) = self.home.add_recent(&path)
        {
            tracing::warn!("{err:#}");
        }
    }

    /// Starts a new plan on the system being edited (if it has a file).
    fn new_plan(&mut self) {
        let system = self.path.clone();
        self.with_mission(|mission| mission.new_plan(system.as_deref()));
    }

    // ----- What tests and the bench read -----

    pub fn editor(&self) -> &Editor {
        &self.editor
    }

    pub fn palette(&self) -> &Palette {
        &self.palette
    }

    pub fn status(&self) -> &Status {
        &self.status
    }

    pub fn title(&self) -> &str {
        &self.title
    }

    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    pub fn is_dirty(&self) -> bool {
        self.dirty
    }

    pub fn problems(&self) -> &[Problem] {
        &self.problems
    }

    /// Where a block's pin is on screen (as drawn last frame): `side` is input or output.
    pub fn pin_pos(&self, block: &str, port: &str, side: PinSide) -> Option<Pos2> {
        let block = self.editor.diagram.block_named(block)?;
        self.canvas.pin_screen_pos(&Pin {
            side,
            port: crate::diagram::PortRef {
                block,
                port: port.to_owned(),
            },
        })
    }

    /// Where a block is on screen (its centre, as drawn last frame).
    pub fn block_pos(&self, block: &str) -> Option<Pos2> {
        self.block_rect(block)
            .map(|rect| self.canvas.to_global * rect.center())
    }

    /// Where a block's header is on screen (where a hand grabs it to move it).
    pub fn block_header_pos(&self, block: &str) -> Option<Pos2> {
        self.block_rect(block)
            .map(|rect| self.canvas.to_global * Pos2::new(rect.center().x, rect.min.y + 10.0))
    }

    /// A block's rectangle on the canvas, if it has been laid out.
    fn block_rect(&self, block: &str) -> Option<egui::Rect> {
        let id = self.editor.diagram.block_named(block)?;
        let rect = self
            .canvas
            .rect_of(&self.editor.diagram, &self.palette.catalog, id);
        rect.is_finite().then_some(rect)
    }

    /// Whether the canvas shows the overview (zoomed out: boxes and lines, no widgets).
    pub fn is_overview(&self) -> bool {
        self.canvas.is_overview()
    }

    /// The screen rectangle of the canvas.
    /// The canvas's transform (graph to screen), as drawn last frame.
    pub fn canvas_transform(&self) -> egui::emath::TSTransform {
        self.canvas.to_global
    }

    pub fn canvas_rect(&self) -> egui::Rect {
        self.canvas.rect
    }

    // ----- Files -----

    /// Opens a system file, replacing the document (unsaved changes stay in the undo history of
    /// nobody: the caller asks first).
    pub fn open(&mut self, file: &Path) {
        match files::open(file) {
            Ok(diagram) => {
                self.saved = diagram.clone();
                self.editor.replace(diagram);
                self.path = Some(file.to_path_buf());
                self.canvas.view_request = None;
                self.zoom_to_fit();
                if let Err(err) = self.home.add_recent(file) {
                    tracing::warn!("{err:#}");
                }
                self.set_status(format!("opened {}", file.display()), false);
            }
            Err(err) => self.set_status(format!("{err:#}"), true),
        }
    }

    /// Saves to `file` (save as) or to the current file.
    pub fn save(&mut self, file: Option<&Path>) {
        let Some(file) = file.map(Path::to_path_buf).or_else(|| self.path.clone()) else {
            self.ask_path(PathPurpose::SaveAs, String::new());
            return;
        };
        match files::save(&file, &self.editor.diagram, &self.palette.catalog) {
            Ok(()) => {
                self.saved = self.editor.diagram.clone();
                self.path = Some(file.clone());
                self.seen_revision = None;
                self.home.clear_recovery(Document::System);
                self.autosaved_revision = Some(self.editor.revision());
                if let Err(err) = self.home.add_recent(&file) {
                    tracing::warn!("{err:#}");
                }
                self.set_status(format!("saved {}", file.display()), false);
            }
            Err(err) => self.set_status(format!("{err:#}"), true),
        }
    }

    fn new_document(&mut self) {
        self.editor.replace(Diagram::default());
        self.saved = Diagram::default();
        self.path = None;
        self.set_status("new system".to_owned(), false);
    }

    fn set_status(&mut self, text: String, is_error: bool) {
        // What the status line says is what a user is told: the log says it too, so that a
        // session can be followed (and driven, by the Xvfb test) from outside.
        tracing::info!("{text}");
        self.status = Status { text, is_error };
    }

    fn zoom_to_fit(&mut self) {
        self.canvas.view_request = self.canvas.bounds(&self.editor.diagram, None);
    }

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

    /// Called when the window closes: a clean document needs no recovery copy.
    pub fn on_exit(&mut self) {
        if !self.dirty || self.discard_on_exit {
            self.home.clear_recovery(Document::System);
        }
        if !self.mission.as_ref().is_some_and(MissionView::is_dirty) || self.discard_on_exit {
            self.home.clear_recovery(Document::Plan);
        }
    }

    // ----- The frame -----

    /// One frame of the whole window.
    pub fn ui(&mut self, ui: &mut Ui) {
        let ctx = ui.ctx().clone();
        if self.palette.poll() {
            self.editor.touch();
        }
        if self.palette.is_probing() {
            ctx.request_repaint_after(Duration::from_millis(50));
        }
        self.handle_screenshots(&ctx);
        self.shortcuts(&ctx);
        self.run.poll();
        for (ok, message) in std::mem::take(&mut self.run.messages) {
            self.set_status(message, !ok);
        }

        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_ui(ui));
        match self.view {
            View::Mission => self.mission_ui(ui),
            View::System => self.system_ui(ui),
            View::Run => self.run_ui(ui),
        }

        self.params_ui(ui);
        self.path_ui(ui);
        self.search_ui(ui);
        self.help_ui(ui);
        self.recovery_ui(ui);
        self.unsaved_ui(ui);

        self.apply_commands(&ctx);
        self.after_frame(&ctx);
        self.request_screenshot(&ctx);
        if !self.started {
            tracing::info!("window ready");
        }
        self.started = true;
    }

    /// The System view: palette, problems, canvas.
    fn system_ui(&mut self, ui: &mut Ui) {
        egui::Panel::left("palette")
            .resizable(true)
            .default_size(220.0)
            .show(ui, |ui| self.palette_ui(ui));
        egui::Panel::right("problems")
            .resizable(true)
            .default_size(300.0)
            .min_size(240.0)
            .show(ui, |ui| self.problems_ui(ui));
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| self.canvas_ui(ui));
    }

    /// The Mission view: tools, inspector, net, map.
    fn mission_ui(&mut self, ui: &mut Ui) {
        let ctx = ui.ctx().clone();
        let mission = self.mission.get_or_insert_with(|| MissionView::new(&ctx));
        mission.set_catalog(&self.palette.catalog);
        if let Some(file) = self.plan_to_open.take() {
            self.open_plan(&file);
        }
        let Some(mission) = self.mission.as_mut() else {
            return;
        };
        egui::Panel::top("mission-tools").show(ui, |ui| mission.toolbar_ui(ui));
        egui::Panel::right("mission-inspector")
            .resizable(true)
            .default_size(330.0)
            .min_size(260.0)
            .show(ui, |ui| mission.inspector_ui(ui));
        egui::Panel::bottom("mission-net")
            .resizable(true)
            .default_size(230.0)
            .min_size(150.0)
            .show(ui, |ui| mission.net_ui(ui));
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| mission.map_ui(ui));
        if let Some((text, is_error)) = mission.apply_commands() {
            self.set_status(text, is_error);
        }
    }

    /// The Run view.
    fn run_ui(&mut self, ui: &mut Ui) {
        let mut surroundings = RunSurroundings {
            mission: self.mission.as_mut(),
            system_file: self.path.as_deref(),
            catalog: &self.palette.catalog,
        };
        if self.run.ui(ui, &mut surroundings).is_some() {
            self.start_run(ui.ctx());
        }
    }

    fn apply_commands(&mut self, ctx: &egui::Context) {
        for command in std::mem::take(&mut self.commands) {
            let copies = matches!(command, Command::Copy | Command::Cut);
            match self.editor.apply(command, &self.palette.catalog) {
                Outcome::Nothing => {}
                Outcome::Done(text) => {
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

    fn after_frame(&mut self, ctx: &egui::Context) {
        // The title follows the document of the view shown.
        let revision = match (self.view, &self.mission) {
            (View::Mission, Some(mission)) => mission.editor.revision() ^ (1 << 63),
            _ => self.editor.revision(),
        };
        if self.seen_revision != Some(revision) {
            self.seen_revision = Some(revision);
            self.dirty = self.editor.diagram != self.saved;
            let (path, dirty) = match (self.view, &self.mission) {
                (View::Mission, Some(mission)) => (mission.path(), mission.is_dirty()),
                _ => (self.path.as_deref(), self.dirty),
            };
            let file = path.and_then(Path::file_name).map_or_else(
                || "untitled".to_owned(),
                |name| name.to_string_lossy().into(),
            );
            let title = format!("{}{file} — ArMoR Studio", if dirty { "*" } else { "" });
            if title != self.title {
                ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
                self.title = title;
            }
        }
        let revision = self.editor.revision();
        if self.problems_revision != Some(revision) {
            self.problems_revision = Some(revision);
            self.problems = validation::validate(
                &self.editor.diagram,
                &self.palette.catalog,
                &self.palette.broken,
            );
            self.flagged = self.problems.iter().filter_map(|p| p.block).collect();
        }
        self.autosave(ctx);
    }

    fn autosave(&mut self, ctx: &egui::Context) {
        self.autosave_plan(ctx);
        let revision = self.editor.revision();
        if !self.dirty || self.autosaved_revision == Some(revision) || !self.recovery.is_empty() {
            return;
        }
        let due = self
            .last_autosave
            .is_none_or(|last| last.elapsed() >= self.autosave_every);
        if !due {
            ctx.request_repaint_after(self.autosave_every);
            return;
        }
        self.last_autosave = Some(Instant::now());
        self.autosaved_revision = Some(revision);
        if let Err(err) = self.home.write_recovery(
            Document::System,
            self.path.as_deref(),
            &self.editor.diagram.to_xml(),
        ) {
            tracing::warn!("autosave: {err:#}");
        }
    }

    /// The plan's recovery copy, written on the same schedule as the system's.
    fn autosave_plan(&mut self, ctx: &egui::Context) {
        let Some(mission) = &self.mission else {
            return;
        };
        let revision = mission.editor.revision();
        if !mission.is_dirty()
            || self.plan_autosaved_revision == Some(revision)
            || !self.recovery.is_empty()
        {
            return;
        }
        if self
            .last_plan_autosave
            .is_some_and(|last| last.elapsed() < self.autosave_every)
        {
            ctx.request_repaint_after(self.autosave_every);
            return;
        }
        self.last_plan_autosave = Some(Instant::now());
        self.plan_autosaved_revision = Some(revision);
        if let Err(err) =
            self.home
                .write_recovery(Document::Plan, mission.path(), &mission.recovery_text())
        {
            tracing::warn!("autosave: {err:#}");
        }
    }

    fn shortcuts(&mut self, ctx: &egui::Context) {
        let command = Modifiers::COMMAND;
        let shift_command = Modifiers::COMMAND | Modifiers::SHIFT;
        let typing = ctx.egui_wants_keyboard_input();
        let pressed = |modifiers, key| {
            ctx.input_mut(|input| input.consume_shortcut(&KeyboardShortcut::new(modifiers, key)))
        };
        if pressed(Modifiers::SHIFT, Key::F5) {
            self.run.stop();
        }
        if pressed(Modifiers::NONE, Key::F5) && !self.run.is_running() {
            self.start_run(ctx);
        }
        match self.view {
            View::Mission => return self.mission_shortcuts(ctx, typing),
            View::Run => {
                if pressed(command, Key::O) {
                    self.ask_path(PathPurpose::OpenRecording, String::new());
                }
                if pressed(Modifiers::NONE, Key::F1) {
                    self.help_open = !self.help_open;
                }
                return;
            }
            View::System => {}
        }
        // File shortcuts work while typing too; the others would steal the text field's keys.
        if pressed(shift_command, Key::S) {
            self.ask_path(PathPurpose::SaveAs, self.path_text());
        }
        if pressed(command, Key::S) {
            self.save(None);
        }
        if pressed(command, Key::O) {
            self.ask_path(PathPurpose::Open, self.path_text());
        }
        if pressed(Modifiers::NONE, Key::F1) {
            self.help_open = !self.help_open;
        }
        if pressed(command, Key::F) {
            self.search = Some(String::new());
        }
        if typing {
            return;
        }
        // Ctrl+Shift+Z first: a plain Ctrl+Z shortcut would also match it.
        if pressed(shift_command, Key::Z) || pressed(command, Key::Y) {
            self.commands.push(Command::Redo);
        }
        if pressed(command, Key::Z) {
            self.commands.push(Command::Undo);
        }
        if pressed(command, Key::A) {
            self.commands.push(Command::SelectAll);
        }
        if pressed(command, Key::D) {
            self.commands.push(Command::Duplicate);
        }
        if pressed(Modifiers::NONE, Key::Delete) || pressed(Modifiers::NONE, Key::Backspace) {
            self.commands.push(Command::DeleteSelection);
        }
        if pressed(Modifiers::NONE, Key::Home) || pressed(command, Key::Num0) {
            self.zoom_to_fit();
        }
        if pressed(Modifiers::NONE, Key::Escape) {
            self.commands.push(Command::Select(BTreeSet::new()));
        }
        // The platform turns Ctrl+C / Ctrl+X / Ctrl+V into copy, cut and paste events, the
        // last with the system clipboard's text (and a headless harness sends plain keys):
        // take both.
        let shortcut = |event: &egui::Event, wanted: Key| matches!(event, egui::Event::Key { key, pressed: true, modifiers, .. } if *key == wanted && modifiers.command);
        let commands = ctx.input(|input| {
            let mut commands = Vec::new();
            for event in &input.events {
                match event {
                    egui::Event::Copy => commands.push(Command::Copy),
                    egui::Event::Cut => commands.push(Command::Cut),
                    egui::Event::Paste(text) if self.copied_text.as_ref() == Some(text) => {
                        commands.push(Command::Paste);
                    }
                    egui::Event::Paste(text) => commands.push(Command::PasteText(text.clone())),
                    event if shortcut(event, Key::C) => commands.push(Command::Copy),
                    event if shortcut(event, Key::X) => commands.push(Command::Cut),
                    event if shortcut(event, Key::V) => commands.push(Command::Paste),
                    _ => {}
                }
            }
            commands
        });
        self.commands.extend(commands);
    }

    /// The Mission view's keys: files, undo, delete, and the map's tools.
    fn mission_shortcuts(&mut self, ctx: &egui::Context, typing: bool) {
        use crate::mission::plan_edit::{PlanCommand, Selection};
        let command = Modifiers::COMMAND;
        let shift_command = Modifiers::COMMAND | Modifiers::SHIFT;
        let pressed = |modifiers, key| {
            ctx.input_mut(|input| input.consume_shortcut(&KeyboardShortcut::new(modifiers, key)))
        };
        if pressed(shift_command, Key::S) {
            self.ask_path(PathPurpose::SavePlanAs, self.plan_path_text());
        }
        if pressed(command, Key::S) {
            self.save_plan(None);
        }
        if pressed(command, Key::O) {
            self.ask_path(PathPurpose::OpenPlan, self.plan_path_text());
        }
        if pressed(Modifiers::NONE, Key::F1) {
            self.help_open = !self.help_open;
        }
        let Some(mission) = self.mission.as_mut() else {
            return;
        };
        if typing {
            return;
        }
        let mut commands = Vec::new();
        if pressed(shift_command, Key::Z) || pressed(command, Key::Y) {
            commands.push(PlanCommand::Redo);
        }
        if pressed(command, Key::Z) {
            commands.push(PlanCommand::Undo);
        }
        if pressed(Modifiers::NONE, Key::Delete) || pressed(Modifiers::NONE, Key::Backspace) {
            commands.push(PlanCommand::DeleteSelection);
        }
        if pressed(Modifiers::NONE, Key::Escape) && mission.map.pending.is_empty() {
            mission.set_tool(crate::mission::Tool::Select);
            commands.push(PlanCommand::Select(Selection::None));
        }
        let mut chosen = None;
        for (key, tool) in crate::mission::TOOL_KEYS {
            if pressed(Modifiers::NONE, *key) {
                mission.set_tool(*tool);
                chosen = Some(*tool);
            }
        }
        if pressed(Modifiers::NONE, Key::Home) || pressed(command, Key::Num0) {
            mission.map.fit_requested = true;
        }
        mission.commands.extend(commands);
        if let Some(tool) = chosen {
            self.set_status(tool.help().to_owned(), false);
        }
    }

    fn plan_path_text(&self) -> String {
        self.mission
            .as_ref()
            .and_then(MissionView::path)
            .map(|path| path.display().to_string())
            .unwrap_or_default()
    }

    fn ask_path(&mut self, purpose: PathPurpose, text: String) {
        let what = match purpose {
            PathPurpose::Open => "open",
            PathPurpose::SaveAs | PathPurpose::SavePlanAs => "save as",
            PathPurpose::ExportPng | PathPurpose::ExportMapPng => "export a picture",
            PathPurpose::OpenPlan => "open a plan",
            PathPurpose::ImportGpx => "import GPX",
            PathPurpose::ExportMission => "export the mission",
            PathPurpose::ExportPnml => "export PNML",
            PathPurpose::OpenRecording => "open a recording",
        };
        self.set_status(format!("{what}: type a path, then Enter"), false);
        self.path_dialog = Some(PathDialog { purpose, text });
    }

    fn path_text(&self) -> String {
        self.path
            .as_ref()
            .map(|path| path.display().to_string())
            .unwrap_or_default()
    }

    fn menu_ui(&mut self, ui: &mut Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            match self.view {
                View::Mission => self.mission_file_menu_ui(ui),
                View::System => self.system_menus_ui(ui),
                View::Run => self.run_menu_ui(ui),
            }
            ui.separator();
            let mut view = self.view;
            ui.selectable_value(&mut view, View::System, "System");
            ui.selectable_value(&mut view, View::Mission, "Mission");
            ui.selectable_value(&mut view, View::Run, "Run");
            if view != self.view {
                self.set_view(view);
            }
            ui.separator();
            ui.label(RichText::new(&self.title).weak());
        });
    }

    fn run_menu_ui(&mut self, ui: &mut Ui) {
        let running = self.run.is_running();
        ui.menu_button("Run", |ui| {
            if ui
                .add_enabled(!running, egui::Button::new("Run").shortcut_text("F5"))
                .clicked()
            {
                self.start_run(ui.ctx());
            }
            if ui
                .add_enabled(running, egui::Button::new("Stop").shortcut_text("Shift+F5"))
                .clicked()
            {
                self.run.stop();
            }
            ui.separator();
            if ui
                .add(egui::Button::new("Open recording…").shortcut_text("Ctrl+O"))
                .clicked()
            {
                self.ask_path(PathPurpose::OpenRecording, String::new());
            }
        });
    }

    fn mission_file_menu_ui(&mut self, ui: &mut Ui) {
        let with_extension = |this: &Self, extension: &str| {
            this.mission
                .as_ref()
                .and_then(MissionView::path)
                .map(|path| path.with_extension(extension).display().to_string())
                .unwrap_or_default()
        };
        ui.menu_button("File", |ui| {
            if ui.button("New plan").clicked() {
                self.replace(Replacing::NewPlan, ui.ctx());
            }
            if ui.button("Open plan…").clicked() {
                self.ask_path(PathPurpose::OpenPlan, self.plan_path_text());
            }
            if ui.button("Save plan").clicked() {
                self.save_plan(None);
            }
            if ui.button("Save plan as…").clicked() {
                self.ask_path(PathPurpose::SavePlanAs, self.plan_path_text());
            }
            ui.separator();
            if ui.button("Import GPX…").clicked() {
                self.ask_path(PathPurpose::ImportGpx, String::new());
            }
            if ui.button("Export mission XML…").clicked() {
                let text = with_extension(self, "mission.xml");
                self.ask_path(PathPurpose::ExportMission, text);
            }
            if ui.button("Export PNML…").clicked() {
                let text = with_extension(self, "pnml");
                self.ask_path(PathPurpose::ExportPnml, text);
            }
            if ui.button("Export map PNG…").clicked() {
                let text = with_extension(self, "png");
                self.ask_path(PathPurpose::ExportMapPng, text);
            }
            ui.separator();
            if ui.button("Quit").clicked() {
                ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
            }
        });
        ui.menu_button("Edit", |ui| {
            use crate::mission::plan_edit::PlanCommand;
            for (label, command) in [
                ("Undo", PlanCommand::Undo),
                ("Redo", PlanCommand::Redo),
                ("Delete", PlanCommand::DeleteSelection),
            ] {
                if ui.button(label).clicked()
                    && let Some(mission) = self.mission.as_mut()
                {
                    mission.commands.push(command);
                }
            }
        });
    }

    fn system_menus_ui(&mut self, ui: &mut Ui) {
        {
            ui.menu_button("File", |ui| {
                if ui.button("New").clicked() {
                    self.replace(Replacing::NewSystem, ui.ctx());
                }
                if ui.button("Open…").clicked() {
                    self.ask_path(PathPurpose::Open, self.path_text());
                }
                ui.menu_button("Open recent", |ui| {
                    let recent = self.home.recent();
                    if recent.is_empty() {
                        ui.label("(none)");
                    }
                    for file in recent {
                        if ui.button(file.display().to_string()).clicked() {
                            self.replace(Replacing::OpenSystem(file), ui.ctx());
                        }
                    }
                });
                if ui.button("Save").clicked() {
                    self.save(None);
                }
                if ui.button("Save as…").clicked() {
                    self.ask_path(PathPurpose::SaveAs, self.path_text());
                }
                if ui.button("Export PNG…").clicked() {
                    let text = self
                        .path
                        .as_ref()
                        .map(|path| path.with_extension("png").display().to_string())
                        .unwrap_or_default();
                    self.ask_path(PathPurpose::ExportPng, text);
                }
                if ui.button("Quit").clicked() {
                    ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                }
            });
            ui.menu_button("Edit", |ui| {
                let items = [
                    ("Undo", Command::Undo),
                    ("Redo", Command::Redo),
                    ("Cut", Command::Cut),
                    ("Copy", Command::Copy),
                    ("Paste", Command::Paste),
                    ("Duplicate", Command::Duplicate),
                    ("Delete", Command::DeleteSelection),
                    ("Select all", Command::SelectAll),
                ];
                for (label, command) in items {
                    if ui.button(label).clicked() {
                        self.commands.push(command);
                    }
                }
            });
            ui.menu_button("View", |ui| {
                if ui.button("Zoom to fit").clicked() {
                    self.zoom_to_fit();
                }
                if ui.button("Find block…").clicked() {
                    self.search = Some(String::new());
                }
                if ui.button("Keyboard shortcuts").clicked() {
                    self.help_open = true;
                }
            });
        }
    }

    fn status_ui(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            let colour = if self.status.is_error {
                ERROR
            } else {
                ui.visuals().text_color()
            };
            ui.colored_label(colour, &self.status.text);
        });
    }

    fn palette_ui(&mut self, ui: &mut Ui) {
        ui.heading("Modules");
        if self.palette.is_probing() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.label(format!(
                    "describing {} of {}",
                    self.palette.done, self.palette.total
                ));
            });
            ui.add(
                egui::ProgressBar::new(self.palette.done as f32 / self.palette.total.max(1) as f32)
                    .desired_height(4.0),
            );
        } else if self.palette.entries.is_empty() {
            ui.label("No module binaries (armor-mod-*) found on the module path.");
        }
        ui.label(
            RichText::new("Drag a module onto the canvas.")
                .weak()
                .small(),
        );
        egui::ScrollArea::vertical().show(ui, |ui| {
            for entry in &self.palette.entries {
                match entry {
                    Entry::Described(description) => {
                        let module_type = description.module_type.clone();
                        ui.horizontal(|ui| {
                            ui.dnd_drag_source(
                                egui::Id::new(("palette", &module_type)),
                                PaletteDrag(module_type.clone()),
                                |ui| {
                                    ui.add(
                                        egui::Label::new(RichText::new(&module_type).strong())
                                            .selectable(false),
                                    );
                                },
                            )
                            .response
                            .on_hover_text(&description.doc);
                            if ui.small_button(format!("add {module_type}")).clicked() {
                                // Cascade, so that blocks added one after the other do not hide
                                // each other.
                                let n = self.editor.diagram.len();
                                let at = self.canvas.to_canvas(self.canvas.rect.center())
                                    + egui::vec2(
                                        (n % 3) as f32 * 240.0 - 240.0,
                                        (n / 3 % 4) as f32 * 120.0 - 120.0,
                                    );
                                self.commands.push(Command::AddBlock {
                                    module_type: module_type.clone(),
                                    pos: [at.x - 80.0, at.y - 40.0],
                                });
                            }
                        });
                        ui.label(RichText::new(&description.doc).small().weak());
                        ui.add_space(4.0);
                    }
                    Entry::Broken(broken) => {
                        ui.colored_label(ERROR, format!("{} (broken)", broken.module_type));
                        ui.label(
                            RichText::new(format!("{}: {}", broken.binary, broken.error))
                                .small()
                                .color(ERROR),
                        );
                        ui.add_space(4.0);
                    }
                }
            }
        });
    }

    fn problems_ui(&mut self, ui: &mut Ui) {
        if self.problems.is_empty() {
            ui.colored_label(OK, "No problems");
            if self.palette.is_probing() {
                ui.label(RichText::new("(modules are still being described)").weak());
            }
            return;
        }
        ui.heading(crate::editor::plural(self.problems.len(), "problem"));
        ui.label(
            RichText::new("As `armor check` reports them; click one to select its block.")
                .weak()
                .small(),
        );
        let mut clicked = None;
        egui::ScrollArea::vertical().show(ui, |ui| {
            for problem in &self.problems {
                let text = format!("{}: {}", problem.pos, problem.message);
                let response = ui.add(
                    egui::Label::new(RichText::new(text).color(ERROR))
                        .sense(egui::Sense::click())
                        .wrap(),
                );
                if response.clicked()
                    && let Some(block) = problem.block
                {
                    clicked = Some(block);
                }
            }
        });
        if let Some(block) = clicked {
            self.show_block(block);
        }
    }

    /// Where the blocks moving with `grabbed` go when it moves by `delta`: itself, and the rest
    /// of the editor's selection if it is part of it.
    fn group_moved(
        &self,
        grabbed: BlockId,
        delta: [f32; 2],
    ) -> impl Iterator<Item = (BlockId, [f32; 2])> + '_ {
        let selection = &self.editor.selection;
        let group: Vec<BlockId> = if selection.contains(&grabbed) {
            selection.iter().copied().collect()
        } else {
            vec![grabbed]
        };
        group.into_iter().filter_map(move |id| {
            let pos = self.editor.diagram.block(id)?.pos;
            Some((id, [pos[0] + delta[0], pos[1] + delta[1]]))
        })
    }

    /// In the overview, the block under the pointer (or the one being dragged) takes drags, on
    /// top of the canvas's own panning: the blocks it moves this frame, with their new places.
    fn overview_drag(&mut self, ui: &mut Ui) -> Vec<(BlockId, [f32; 2])> {
        let diagram = &self.editor.diagram;
        let catalog = &self.palette.catalog;
        let under_pointer = || {
            let pointer = ui.ctx().pointer_hover_pos()?;
            self.canvas.block_at(diagram, catalog, pointer)
        };
        let Some(block) = self
            .canvas
            .overview_grab
            .filter(|block| diagram.block(*block).is_some())
            .or_else(under_pointer)
        else {
            return Vec::new();
        };
        let rect = self.canvas.to_global * self.canvas.rect_of(diagram, catalog, block);
        // Over egui-snarl's layer (a sublayer of this one, which takes drags to pan).
        let layer = egui::LayerId::new(ui.layer_id().order, egui::Id::new("overview drag"));
        ui.ctx().set_sublayer(ui.layer_id(), layer);
        let drag_ui = ui.new_child(
            egui::UiBuilder::new()
                .layer_id(layer)
                .max_rect(self.canvas.rect),
        );
        let response = drag_ui.interact(
            rect.intersect(self.canvas.rect),
            egui::Id::new(("overview block", block)),
            egui::Sense::drag(),
        );
        if response.drag_started() {
            self.canvas.overview_grab = Some(block);
        }
        if !response.dragged() {
            self.canvas.overview_grab = None;
        }
        let delta = response.drag_delta() / self.canvas.to_global.scaling;
        if delta == egui::Vec2::ZERO {
            return Vec::new();
        }
        self.group_moved(block, [delta.x, delta.y]).collect()
    }

    fn canvas_ui(&mut self, ui: &mut Ui) {
        let ctx = ui.ctx().clone();
        self.canvas.sync(
            &self.editor.diagram,
            &self.palette.catalog,
            self.editor.revision(),
        );
        self.canvas.rect = ui.available_rect_before_wrap();
        if !self.started && self.canvas.view_request.is_none() {
            self.zoom_to_fit();
        }
        let (pressed, released, press_origin, latest, double_click, modifiers) =
            ctx.input(|input| {
                (
                    input.pointer.primary_pressed(),
                    input.pointer.primary_released(),
                    input.pointer.press_origin(),
                    input.pointer.latest_pos(),
                    input
                        .pointer
                        .button_double_clicked(egui::PointerButton::Primary)
                        .then(|| input.pointer.interact_pos())
                        .flatten(),
                    input.modifiers,
                )
            });
        // The wire's origin: the pin under the pointer when the button went down.
        if pressed {
            self.canvas.wire_from = press_origin
                .filter(|pos| self.canvas.rect.contains(*pos))
                .and_then(|pos| self.canvas.pin_at(pos).cloned());
        }

        let pins = std::rc::Rc::new(std::cell::RefCell::new(Vec::new()));
        let mut events = CanvasEvents::default();
        let mut node_rects = HashMap::new();
        let mut to_global = self.canvas.to_global;
        let view_request = self.canvas.view_request.take();
        let wire_from = self.canvas.wire_from.clone();
        let live = self.run.module_states();
        // The viewer reads the canvas while egui-snarl edits the snarl: hold them apart.
        let mut canvas = std::mem::take(&mut self.canvas);
        let mut snarl = std::mem::take(&mut canvas.snarl);
        let mut viewer = DiagramViewer {
            diagram: &self.editor.diagram,
            catalog: &self.palette.catalog,
            selection: &self.editor.selection,
            flagged: &self.flagged,
            commands: &mut self.commands,
            events: &mut events,
            wire_from: wire_from.as_ref(),
            pins: pins.clone(),
            node_rects: &mut node_rects,
            to_global: &mut to_global,
            view_request,
            screen_rect: canvas.rect,
            double_click: double_click.filter(|pos| canvas.rect.contains(*pos)),
            canvas: &canvas,
            live: &live,
        };
        let widget = SnarlWidget::new().id_salt(CANVAS_ID).style(viewer::style());
        widget.show(&mut snarl, &mut viewer, ui);
        drop(viewer);
        self.canvas = canvas;
        self.canvas.snarl = snarl;
        self.canvas.node_rects.extend(node_rects);
        self.canvas.to_global = to_global;
        self.canvas.pins = pins.take();

        // In the overview, a double click zooms in on the block (its pins and parameters are
        // there).
        if self.canvas.is_overview()
            && let Some(pos) = double_click.filter(|pos| self.canvas.rect.contains(*pos))
            && let Some(block) =
                self.canvas
                    .block_at(&self.editor.diagram, &self.palette.catalog, pos)
        {
            self.show_block(block);
        }
        if let Some(block) = events.open_params {
            self.open_params(block);
        }

        // A wire dropped on a pin of the same side: egui-snarl ignores it silently; say why.
        if released {
            if let (Some(from), Some(to)) = (
                self.canvas.wire_from.take(),
                latest.and_then(|pos| self.canvas.pin_at(pos).cloned()),
            ) && from.side == to.side
                && from != to
                && let Err(reason) =
                    self.editor
                        .diagram
                        .link_between(&self.palette.catalog, &from, &to)
            {
                self.set_status(format!("refused: {reason}"), true);
            }
            self.canvas.wire_from = None;
        }

        // A module type dropped from the palette.
        if let Some(pos) = latest.filter(|pos| self.canvas.rect.contains(*pos))
            && released
            && let Some(payload) = egui::DragAndDrop::take_payload::<PaletteDrag>(&ctx)
        {
            let at = self.canvas.to_canvas(pos);
            self.commands.push(Command::AddBlock {
                module_type: payload.0.clone(),
                pos: [at.x - 60.0, at.y - 20.0],
            });
        }

        // Moves: the snarl moved its nodes; copy them into the document, one undo step a drag.
        let mut moved = self.canvas.moved_blocks(&self.editor.diagram);
        // A block of a group selected in the editor (select all, find, a paste) carries the rest
        // of the group along; egui-snarl moves only its own selection.
        if let [(grabbed, to)] = moved[..]
            && let Some(from) = self.editor.diagram.block(grabbed).map(|block| block.pos)
        {
            let delta = [to[0] - from[0], to[1] - from[1]];
            moved.extend(
                self.group_moved(grabbed, delta)
                    .filter(|(id, _)| *id != grabbed),
            );
            self.canvas.place_nodes(&moved);
        }
        // In the overview egui-snarl holds no block: the block under the pointer is dragged here.
        if self.canvas.is_overview() {
            moved.extend(self.overview_drag(ui));
        }
        if !moved.is_empty() {
            if self.canvas.move_before.is_none() {
                self.canvas.move_before = Some(self.editor.diagram.clone());
            }
            for (id, pos) in moved {
                self.editor.diagram.move_block(id, pos);
            }
        }
        let pointer_down = ctx.input(|input| input.pointer.any_down());
        if !pointer_down && let Some(before) = self.canvas.move_before.take() {
            self.commands.push(Command::Moved {
                before: Box::new(before),
            });
        }

        // Selection: a click on a block selects it (egui-snarl selects only with Shift), a click
        // on empty canvas clears it; Shift-click and rectangle selection are egui-snarl's own.
        let snarl_selected = widget.get_selected_nodes(ui);
        if let Some(selected) = self.canvas.snarl_selection_change(snarl_selected) {
            self.commands.push(Command::Select(selected));
        } else if released
            && !modifiers.shift
            && !modifiers.command
            && let Some(pos) = latest.filter(|pos| self.canvas.rect.contains(*pos))
            && !ctx.input(|input| input.pointer.is_decidedly_dragging())
            && ctx
                .layer_id_at(pos)
                .is_some_and(|layer| layer.order == egui::Order::Background)
        {
            match self
                .canvas
                .block_at(&self.editor.diagram, &self.palette.catalog, pos)
            {
                Some(block) => self.commands.push(Command::Select([block].into())),
                None => self.commands.push(Command::Select(BTreeSet::new())),
            }
        }
    }

    fn open_params(&mut self, block: BlockId) {
        let Some(found) = self.editor.diagram.block(block) else {
            return;
        };
        self.params = Some(ParamsDialog {
            block,
            name: found.name.clone(),
            values: found.params.clone(),
        });
    }

    fn params_ui(&mut self, ui: &mut Ui) {
        let ctx = &ui.ctx().clone();
        let Some(dialog) = &mut self.params else {
            return;
        };
        let Some(block) = self.editor.diagram.block(dialog.block) else {
            self.params = None;
            return;
        };
        let description = self.palette.catalog.get(&block.module_type);
        let mut open = true;
        let mut close = false;
        egui::Window::new(format!("Block {}", block.name))
            .id(egui::Id::new("params"))
            .open(&mut open)
            .collapsible(false)
            .default_width(560.0)
            .show(ctx, |ui| {
                ui.horizontal(|ui| {
                    let label = ui.label("Name");
                    let edit = ui
                        .add(egui::TextEdit::singleline(&mut dialog.name).id_salt("name"))
                        .labelled_by(label.id);
                    let taken = self
                        .editor
                        .diagram
                        .block_named(&dialog.name)
                        .is_some_and(|other| other != dialog.block);
                    let valid = armor_module_api::describe::is_identifier(&dialog.name);
                    if !valid {
                        ui.colored_label(ERROR, "letters, digits and _, starting with a letter");
                    } else if taken {
                        ui.colored_label(ERROR, "another block has this name");
                    } else if edit.changed() {
                        self.commands.push(Command::Rename {
                            block: dialog.block,
                            name: dialog.name.clone(),
                        });
                    }
                });
                ui.label(RichText::new(format!("type {}", block.module_type)).weak());
                let Some(description) = description else {
                    ui.colored_label(ERROR, "this module type is unknown: no parameters to show");
                    return;
                };
                if let Some(doc) = Some(&description.doc).filter(|doc| !doc.is_empty()) {
                    ui.label(RichText::new(doc).small());
                }
                ui.separator();
                if description.params.is_empty() {
                    ui.label("This module has no parameters.");
                }
                // One block of lines per parameter (not a grid): long docs wrap at the
                // window's width instead of widening it, and long lists scroll.
                egui::ScrollArea::vertical()
                    .max_height(460.0)
                    .show(ui, |ui| {
                        for spec in &description.params {
                            let unit = if spec.unit.is_empty() {
                                String::new()
                            } else {
                                format!(" [{}]", spec.unit)
                            };
                            let default = match &spec.default {
                                Some(default) if default.is_empty() => "default: empty".to_owned(),
                                Some(default) => format!("default {default}"),
                                None => "required".to_owned(),
                            };
                            let value = dialog.values.entry(spec.name.clone()).or_default();
                            let (edit, verdict) = ui
                                .horizontal(|ui| {
                                    let label = ui.label(RichText::new(&spec.name).strong());
                                    ui.label(format!("{}{unit}", spec.param_type.as_str()));
                                    ui.label(RichText::new(&default).weak());
                                    let edit = ui
                                        .add(
                                            egui::TextEdit::singleline(value)
                                                .id_salt(("param", &spec.name))
                                                .hint_text(&default)
                                                .desired_width(140.0),
                                        )
                                        .labelled_by(label.id);
                                    // Checked as typed: the verdict is of this frame's text.
                                    let trimmed = value.trim().to_owned();
                                    let verdict = if trimmed.is_empty() {
                                        if spec.is_required() {
                                            Err("required: set a value".to_owned())
                                        } else {
                                            Ok(None)
                                        }
                                    } else {
                                        spec.param_type
                                            .check_value(&trimmed)
                                            .map(|()| Some(trimmed))
                                    };
                                    match &verdict {
                                        Ok(_) => ui.colored_label(OK, "ok"),
                                        Err(reason) => ui.colored_label(ERROR, reason),
                                    };
                                    (edit, verdict)
                                })
                                .inner;
                            if !spec.doc.is_empty() {
                                ui.add(
                                    egui::Label::new(RichText::new(&spec.doc).small().weak())
                                        .wrap(),
                                );
                            }
                            ui.add_space(6.0);
                            // A value is written to the document only once it is valid, so the
                            // document never holds a value `armor check` would refuse; an emptied
                            // field returns the parameter to its default.
                            if edit.changed() {
                                let value = match verdict {
                                    Ok(value) => Some(value),
                                    Err(_) if value.trim().is_empty() => Some(None),
                                    Err(_) => None,
                                };
                                if let Some(value) = value {
                                    self.commands.push(Command::SetParam {
                                        block: dialog.block,
                                        name: spec.name.clone(),
                                        value,
                                    });
                                }
                            }
                        }
                    });
                ui.separator();
                if ui.button("Close").clicked() {
                    close = true;
                }
            });
        if !open || close {
            self.params = None;
        }
    }

    fn path_ui(&mut self, ui: &mut Ui) {
        let ctx = &ui.ctx().clone();
        let Some(dialog) = &mut self.path_dialog else {
            return;
        };
        let (title, action) = match dialog.purpose {
            PathPurpose::Open => ("Open a system file", "Open"),
            PathPurpose::SaveAs => ("Save the system as", "Save"),
            PathPurpose::ExportPng => ("Export a picture (PNG)", "Export"),
            PathPurpose::OpenPlan => ("Open a plan", "Open"),
            PathPurpose::SavePlanAs => ("Save the plan as", "Save"),
            PathPurpose::ImportGpx => ("Import waypoints and a route (GPX)", "Import"),
            PathPurpose::ExportMission => ("Export the mission (XML for armor run)", "Export"),
            PathPurpose::ExportPnml => ("Export the net (PNML)", "Export"),
            PathPurpose::ExportMapPng => ("Export the map (PNG)", "Export"),
            PathPurpose::OpenRecording => ("Open a recording (MCAP)", "Open"),
        };
        let mut submit = false;
        let mut cancel = false;
        egui::Window::new(title)
            .id(egui::Id::new("path-dialog"))
            .collapsible(false)
            .show(ctx, |ui| {
                let label = ui.label("Path:");
                let edit = ui
                    .add(
                        egui::TextEdit::singleline(&mut dialog.text)
                            .id_salt("path")
                            .desired_width(420.0),
                    )
                    .labelled_by(label.id);
                if !edit.has_focus() && !edit.lost_focus() {
                    edit.request_focus();
                }
                if edit.lost_focus() && ui.input(|input| input.key_pressed(Key::Enter)) {
                    submit = true;
                }
                ui.horizontal(|ui| {
                    if ui.button(action).clicked() {
                        submit = true;
                    }
                    if ui.button("Cancel").clicked() {
                        cancel = true;
                    }
                });
            });
        if cancel {
            self.path_dialog = None;
            self.after_save_as = None;
        } else if submit {
            let purpose = dialog.purpose;
            let path = PathBuf::from(dialog.text.trim());
            self.path_dialog = None;
            if path.as_os_str().is_empty() {
                self.set_status("no path given".to_owned(), true);
                return;
            }
            match purpose {
                PathPurpose::Open => self.replace(Replacing::OpenSystem(path), ctx),
                PathPurpose::SaveAs => {
                    self.save(Some(&path));
                    self.continue_after_save_as(ctx);
                }
                PathPurpose::ExportPng => self.export_png(ctx, path, View::System),
                PathPurpose::OpenPlan => self.replace(Replacing::OpenPlan(path), ctx),
                PathPurpose::SavePlanAs => {
                    self.save_plan(Some(&path));
                    self.continue_after_save_as(ctx);
                }
                PathPurpose::ImportGpx => self.with_mission(|m| m.import_gpx(&path)),
                PathPurpose::ExportMission => self.with_mission(|m| m.export_mission(&path)),
                PathPurpose::ExportPnml => self.with_mission(|m| m.export_pnml(&path)),
                PathPurpose::ExportMapPng => self.export_png(ctx, path, View::Mission),
                PathPurpose::OpenRecording => self.run.open_recording(&path),
            }
        }
    }

    fn search_ui(&mut self, ui: &mut Ui) {
        let ctx = &ui.ctx().clone();
        let Some(query) = &mut self.search else {
            return;
        };
        let mut open = true;
        let mut chosen = None;
        egui::Window::new("Find block")
            .id(egui::Id::new("search"))
            .open(&mut open)
            .collapsible(false)
            .show(ctx, |ui| {
                let label = ui.label("Find:");
                let edit = ui
                    .add(
                        egui::TextEdit::singleline(query)
                            .id_salt("find")
                            .hint_text("name or type"),
                    )
                    .labelled_by(label.id);
                if !edit.has_focus() && !edit.lost_focus() {
                    edit.request_focus();
                }
                let needle = query.to_lowercase();
                let matches: Vec<(BlockId, String)> = self
                    .editor
                    .diagram
                    .blocks()
                    .filter(|(_, block)| {
                        block.name.to_lowercase().contains(&needle)
                            || block.module_type.to_lowercase().contains(&needle)
                    })
                    .take(50)
                    .map(|(id, block)| (id, format!("{} ({})", block.name, block.module_type)))
                    .collect();
                if edit.lost_focus() && ui.input(|input| input.key_pressed(Key::Enter)) {
                    chosen = matches.first().map(|(id, _)| *id);
                }
                if matches.is_empty() {
                    ui.label("no block matches");
                }
                for (id, label) in matches {
                    if ui.button(label).clicked() {
                        chosen = Some(id);
                    }
                }
            });
        if let Some(block) = chosen {
            self.show_block(block);
            self.search = None;
        } else if !open {
            self.search = None;
        }
    }

    fn help_ui(&mut self, ui: &mut Ui) {
        let ctx = &ui.ctx().clone();
        egui::Window::new("Keyboard shortcuts")
            .id(egui::Id::new("help"))
            .open(&mut self.help_open)
            .collapsible(false)
            .show(ctx, |ui| {
                egui::Grid::new("shortcuts").striped(true).show(ui, |ui| {
                    for (keys, what) in SHORTCUTS {
                        ui.label(RichText::new(*keys).monospace());
                        ui.label(*what);
                        ui.end_row();
                    }
                });
            });
    }

    // ----- Unsaved changes -----

    /// The documents `action` would lose changes of.
    fn unsaved_for(&self, action: &Replacing) -> Vec<Document> {
        let system = self.editor.diagram != self.saved;
        let plan = self.mission.as_ref().is_some_and(MissionView::is_dirty);
        let (system_matters, plan_matters) = match action {
            Replacing::NewSystem | Replacing::OpenSystem(_) => (true, false),
            Replacing::NewPlan | Replacing::OpenPlan(_) => (false, true),
            Replacing::Quit => (true, true),
        };
        [
            (system && system_matters, Document::System),
            (plan && plan_matters, Document::Plan),
        ]
        .into_iter()
        .filter_map(|(unsaved, document)| unsaved.then_some(document))
        .collect()
    }

    /// Does `action`, or first asks what to do with the changes it would lose.
    fn replace(&mut self, action: Replacing, ctx: &egui::Context) {
        if self.unsaved_for(&action).is_empty() {
            self.perform(action, ctx);
        } else {
            self.unsaved_prompt = Some(action);
        }
    }

    fn perform(&mut self, action: Replacing, ctx: &egui::Context) {
        match action {
            Replacing::NewSystem => self.new_document(),
            Replacing::OpenSystem(file) => self.open(&file),
            Replacing::NewPlan => self.new_plan(),
            Replacing::OpenPlan(file) => self.open_plan(&file),
            Replacing::Quit => {
                self.quitting = true;
                ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
    }

    /// A "save as" asked for by the unsaved-changes prompt has run: on with what was asked.
    fn continue_after_save_as(&mut self, ctx: &egui::Context) {
        if let Some(action) = self.after_save_as.take() {
            self.replace(action, ctx);
        }
    }

    /// Saves the documents `action` would lose changes of, then does it; a document without a
    /// file asks for one first. A failed save stops there (its error is in the status line).
    fn save_then(&mut self, action: Replacing, ctx: &egui::Context) {
        for document in self.unsaved_for(&action) {
            let has_file = match document {
                Document::System => self.path.is_some(),
                Document::Plan => self.mission.as_ref().and_then(MissionView::path).is_some(),
            };
            if !has_file {
                self.after_save_as = Some(action);
                match document {
                    Document::System => self.ask_path(PathPurpose::SaveAs, String::new()),
                    Document::Plan => self.ask_path(PathPurpose::SavePlanAs, String::new()),
                }
                return;
            }
            match document {
                Document::System => self.save(None),
                Document::Plan => self.save_plan(None),
            }
            if self.status.is_error {
                return;
            }
        }
        self.replace(action, ctx);
    }

    fn document_name(&self, document: Document) -> String {
        let path = match document {
            Document::System => self.path.as_deref(),
            Document::Plan => self.mission.as_ref().and_then(MissionView::path),
        };
        path.and_then(Path::file_name).map_or_else(
            || format!("the new {}", document.noun()),
            |name| format!("“{}”", name.to_string_lossy()),
        )
    }

    /// "Save changes?" before a document is replaced or the window closes, as any editor asks.
    fn unsaved_ui(&mut self, ui: &mut Ui) {
        let ctx = ui.ctx().clone();
        // Closing the window (its close button, or Quit) asks too.
        if ctx.input(|input| input.viewport().close_requested())
            && !self.quitting
            && !self.unsaved_for(&Replacing::Quit).is_empty()
        {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.unsaved_prompt = Some(Replacing::Quit);
        }
        let Some(action) = self.unsaved_prompt.clone() else {
            return;
        };
        let documents = self.unsaved_for(&action);
        let names: Vec<String> = documents
            .iter()
            .map(|&document| self.document_name(document))
            .collect();
        let mut choice = None;
        egui::Modal::new(egui::Id::new("unsaved")).show(&ctx, |ui| {
            ui.heading("Save changes?");
            ui.label(format!(
                "{} {} unsaved changes, lost if not saved.",
                names.join(" and "),
                if names.len() == 1 { "has" } else { "have" }
            ));
            ui.horizontal(|ui| {
                for (label, answer) in [
                    ("Save", UnsavedChoice::Save),
                    ("Don't save", UnsavedChoice::Discard),
                    ("Cancel", UnsavedChoice::Cancel),
                ] {
                    if ui.button(label).clicked() {
                        choice = Some(answer);
                    }
                }
            });
        });
        let Some(choice) = choice else {
            return;
        };
        self.unsaved_prompt = None;
        match choice {
            UnsavedChoice::Save => self.save_then(action, &ctx),
            UnsavedChoice::Discard => {
                // Given up on purpose: no recovery copy is offered for them next time.
                for document in documents {
                    self.home.clear_recovery(document);
                }
                self.discard_on_exit = action == Replacing::Quit;
                self.perform(action, &ctx);
            }
            UnsavedChoice::Cancel => self.set_status("kept the unsaved changes".to_owned(), false),
        }
    }

    fn recovery_ui(&mut self, ui: &mut Ui) {
        let ctx = &ui.ctx().clone();
        let Some(recovery) = self.recovery.first().cloned() else {
            return;
        };
        let mut restore = false;
        let mut discard = false;
        egui::Modal::new(egui::Id::new("recovery")).show(ctx, |ui| {
            ui.heading("Restore unsaved work?");
            let of = recovery.original.as_ref().map_or_else(
                || format!("an unsaved {}", recovery.document.noun()),
                |path| path.display().to_string(),
            );
            ui.label(format!(
                "The studio did not close cleanly last time; a recovery copy of {of} was kept."
            ));
            ui.horizontal(|ui| {
                restore = ui.button("Restore").clicked();
                discard = ui.button("Discard").clicked();
            });
        });
        if restore && recovery.document == Document::Plan {
            // The plan is restored into the Mission view, which exists from its first frame.
            self.set_view(View::Mission);
            let ctx = ui.ctx().clone();
            let mission = self.mission.get_or_insert_with(|| MissionView::new(&ctx));
            let report = mission.restore(recovery.original.as_deref(), &recovery.text);
            self.report(report);
            self.recovery.remove(0);
        } else if restore {
            match Diagram::from_xml(&recovery.text) {
                Ok(diagram) => {
                    self.path.clone_from(&recovery.original);
                    // What is on disk (if anything) is the saved state: the restored document
                    // shows as changed until it is saved.
                    self.saved = self
                        .path
                        .as_deref()
                        .and_then(|path| files::open(path).ok())
                        .unwrap_or_default();
                    self.editor.replace(diagram);
                    self.zoom_to_fit();
                    self.set_status("restored the recovery copy".to_owned(), false);
                }
                Err(_) => self.set_status("the recovery copy cannot be read".to_owned(), true),
            }
            self.recovery.remove(0);
        } else if discard {
            self.home.clear_recovery(recovery.document);
            self.recovery.remove(0);
        }
    }

    // ----- Picture export -----

    fn export_png(&mut self, ctx: &egui::Context, path: PathBuf, view: View) {
        // Deselect and frame everything so the picture shows the whole document as drawn; the
        // screenshot waits two frames, for the new view and for the path dialog to be gone.
        if view == View::System {
            self.commands.push(Command::Select(BTreeSet::new()));
            self.zoom_to_fit();
        } else if let Some(mission) = &mut self.mission {
            mission.map.fit_requested = true;
        }
        self.export_after = Some((path, view, 2));
        self.set_status("exporting the picture…".to_owned(), false);
        ctx.request_repaint();
    }

    fn request_screenshot(&mut self, ctx: &egui::Context) {
        match self.export_after.take() {
            Some((path, view, 0)) => {
                let crop = match (view, &self.mission) {
                    (View::Mission, Some(mission)) => mission.map_rect(),
                    _ => self.canvas.rect,
                };
                ctx.send_viewport_cmd(egui::ViewportCommand::Screenshot(egui::UserData::new(
                    ExportRequest { path, crop },
                )));
                ctx.request_repaint();
            }
            Some((path, view, frames)) => {
                self.export_after = Some((path, view, frames - 1));
                ctx.request_repaint();
            }
            None => {}
        }
    }

    fn handle_screenshots(&mut self, ctx: &egui::Context) {
        let shots: Vec<(Arc<egui::ColorImage>, ExportRequest)> = ctx.input(|input| {
            input
                .events
                .iter()
                .filter_map(|event| match event {
                    egui::Event::Screenshot {
                        image, user_data, ..
                    } => {
                        let request = user_data.data.as_ref()?.downcast_ref::<ExportRequest>()?;
                        Some((image.clone(), request.clone()))
                    }
                    _ => None,
                })
                .collect()
        });
        for (image, ExportRequest { path, crop }) in shots {
            let scale = ctx.pixels_per_point();
            match crate::export::write_png(&image, crop, scale, &path) {
                Ok(()) => self.set_status(format!("exported {}", path.display()), false),
                Err(err) => self.set_status(format!("{err:#}"), true),
            }
        }
    }
}

/// What the palette hands the canvas during a drag.
#[derive(Clone, Debug)]
struct PaletteDrag(String);

/// The help sheet.
pub const SHORTCUTS: &[(&str, &str)] = &[
    ("Ctrl+S", "save"),
    ("Ctrl+Shift+S", "save as"),
    ("Ctrl+O", "open a file (type its path)"),
    ("Ctrl+Z", "undo"),
    ("Ctrl+Y, Ctrl+Shift+Z", "redo"),
    (
        "Ctrl+X / Ctrl+C / Ctrl+V",
        "cut / copy / paste the selected blocks (as system XML on the clipboard)",
    ),
    ("Ctrl+D", "duplicate the selected blocks"),
    ("Ctrl+A", "select all"),
    ("Delete", "delete the selected blocks"),
    ("Escape", "clear the selection"),
    ("Home, Ctrl+0", "zoom to fit"),
    ("Ctrl+F", "find a block"),
    ("F1", "this sheet"),
    ("Double-click a block", "its name and parameters"),
    ("Right-click a block", "parameters, duplicate, delete"),
    ("Right-click the canvas", "add a block"),
    ("Drag from a pin", "link: legal targets turn green"),
    ("Right-click a pin or wire", "remove its links"),
    ("Shift+drag", "select with a rectangle"),
    ("F5", "run the open plan, else the system (Run view)"),
    ("Shift+F5", "stop the run"),
    (
        "Arrow keys (Run view)",
        "drive the robot through teleop while held",
    ),
];

/// Whether a file is a plan (opened in the Mission view) rather than a system.
fn is_plan(file: &Path) -> bool {
    matches!(
        armor_runtime::mission::document_kind(file),
        Ok(armor_runtime::mission::DocumentKind::Plan)
    )
}
