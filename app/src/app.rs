//! The studio window: the menu bar, the status line, the view shown (System, Mission, Run) and
//! the dialogs over it. It owns the views' states and routes to them: frames to the view
//! shown, menu entries and keys through the command table (`crate::command`) to the view they
//! act on, and what each view reports to the status line. The views queue their edits and
//! apply them after the frame; then the window keeps what derives from the documents (title,
//! dirty marker, problems, recovery copies) up to date. Its documents' files are handled in
//! `app/documents.rs`, pictures in `app/picture.rs`, the menu bar in `app/menu.rs`, and what tests
//! and the bench read of the canvas in `app/probes.rs`.

mod documents;
mod menu;
mod picture;
mod probes;

use crate::start::StartChoice;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use egui::Ui;

pub use crate::command::View;
use crate::command::{self, UiCommand};
use crate::common::context::ViewerContext;
use crate::common::palette::Palette;
use crate::dialogs::{PathDialog, PathPurpose, Replacing};
use crate::files::{Document, Home, Recovery};
use crate::mission::MissionView;
use crate::run::{RunView, Target};
use crate::system::editor::Editor;
use crate::system::validation::Problem;
use crate::system::{self, SystemView};

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
    /// Show the start page while the studio holds no document (the window does; tests that
    /// drive the canvas from the first frame do not ask for it).
    pub start_page: bool,
    /// Attach the Run view to the run whose control interface is here, from the first frame
    /// (`armor-studio --attach ADDR`).
    pub attach: Option<std::net::SocketAddr>,
}

impl Options {
    pub fn new(home: Home) -> Options {
        Options {
            home,
            module_path: armor_runtime::probe::module_path(),
            palette: None,
            file: None,
            autosave_every: Duration::from_secs(5),
            start_page: false,
            attach: None,
        }
    }
}

/// The status line: what the last action did, or why it was refused.
#[derive(Clone, Debug, Default)]
pub struct Status {
    pub text: String,
    pub is_error: bool,
}

pub struct StudioApp {
    system: SystemView,
    palette: Palette,
    home: Home,
    status: Status,
    path_dialog: Option<PathDialog>,
    help_open: bool,
    /// The start page is on offer (no document yet), with the examples found.
    start: Option<Vec<PathBuf>>,
    /// Recovery copies left by a session that did not end cleanly, offered one at a time.
    recovery: Vec<Recovery>,
    autosave_every: Duration,
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
    /// A run to attach to at the first frame (`--attach`).
    attach_at_start: Option<std::net::SocketAddr>,
    /// The editing view shown last (System or Mission): its document is the one a Run starts.
    document_view: View,
    /// F5's prompt (what runs, at what time scale), while it is open.
    run_prompt: Option<crate::run::prompt::RunPrompt>,
}

impl StudioApp {
    pub fn new(options: Options) -> StudioApp {
        let mut run = RunView::new(options.module_path.clone());
        run.time_scale = options.home.time_scale();
        let palette = options.palette.unwrap_or_else(|| {
            Palette::probe(&options.module_path, armor_runtime::probe::DEFAULT_TIMEOUT)
        });
        let recovery = [Document::System, Document::Plan]
            .into_iter()
            .filter_map(|document| options.home.recovery(document))
            .collect();
        let mut app = StudioApp {
            system: SystemView::default(),
            palette,
            home: options.home,
            status: Status::default(),
            path_dialog: None,
            help_open: false,
            start: (options.start_page && options.file.is_none()).then(crate::start::examples),
            recovery,
            autosave_every: options.autosave_every,
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
            attach_at_start: options.attach,
            document_view: View::System,
            run_prompt: None,
        };
        if options.attach.is_some() {
            app.start = None;
        }
        if let Some(file) = options.file {
            if is_plan(&file) {
                app.view = View::Mission;
                app.document_view = View::Mission;
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
        if view != View::Run {
            self.document_view = view;
        }
        self.seen_revision = None;
    }

    /// What a Run starts now: the document of the view shown, or in the Run view that of the
    /// editing view left last (the plan in the Mission view, the system in the System view).
    pub fn run_target(&self) -> Option<Target> {
        // A copy of an attached run's files is the run's, not a document to run again.
        let target = match self.document_view {
            View::Mission => self
                .mission
                .as_ref()
                .and_then(MissionView::path)
                .map(|plan| Target::Plan(plan.to_path_buf())),
            _ => self.system.path.clone().map(Target::System),
        };
        target.filter(|target| !self.run.is_mirror_copy(target.path()))
    }

    /// F5's prompt, while it is open: what it runs and at what time scale.
    pub fn run_prompt(&self) -> Option<&crate::run::prompt::RunPrompt> {
        self.run_prompt.as_ref()
    }

    /// The Run view.
    pub fn run(&self) -> &RunView {
        &self.run
    }

    pub fn run_mut(&mut self) -> &mut RunView {
        &mut self.run
    }

    /// Starts a run of the document of the view shown ([`Self::run_target`]) at the Run view's
    /// time scale, after saving it if it has unsaved changes; shows the Run view.
    pub fn start_run(&mut self, ctx: &egui::Context) {
        let Some(target) = self.run_target() else {
            self.nothing_to_run();
            return;
        };
        match &target {
            Target::Plan(_) if self.mission.as_ref().is_some_and(MissionView::is_dirty) => {
                self.save_plan(None)
            }
            Target::System(_) if self.system.dirty => self.save(None),
            _ => {}
        }
        self.set_view(View::Run);
        self.run
            .start(target, self.mission.as_ref(), &self.palette.catalog, ctx);
    }

    /// Says why a Run starts nothing: the view's document was never saved.
    fn nothing_to_run(&mut self) {
        let text = match self.document_view {
            View::Mission => "nothing to run: open or save a plan first (Ctrl+S)",
            _ => "nothing to run: open or save a system first (Ctrl+S)",
        };
        self.set_status(text.to_owned(), true);
    }

    /// F5 and the Run entries: asks the time scale for a run of the view's document, offering
    /// the one asked last.
    fn ask_run(&mut self) {
        if self.run.is_running() {
            return;
        }
        match self.run_target() {
            Some(target) => {
                self.run_prompt = Some(crate::run::prompt::RunPrompt::new(
                    target,
                    self.run.time_scale,
                ));
            }
            None => self.nothing_to_run(),
        }
    }

    /// Runs the view's document at `time_scale`, remembered for the next run.
    fn run_at(&mut self, time_scale: f64, ctx: &egui::Context) {
        self.run.time_scale = time_scale;
        if let Err(err) = self.home.set_time_scale(time_scale) {
            // The run goes on at the scale asked; only the next session's default is lost.
            tracing::warn!("cannot remember the time scale: {err:#}");
        }
        self.start_run(ctx);
    }

    /// F5's prompt, while it is open.
    fn run_prompt_ui(&mut self, ctx: &egui::Context) {
        let Some(prompt) = &mut self.run_prompt else {
            return;
        };
        match prompt.ui(ctx) {
            None => {}
            Some(crate::run::prompt::Answer::Cancel) => self.run_prompt = None,
            Some(crate::run::prompt::Answer::Run(time_scale)) => {
                self.run_prompt = None;
                self.run_at(time_scale, ctx);
            }
        }
    }

    /// Watches a run started elsewhere, through its control interface: with the open system's
    /// live views when a system is open, else its modules, mission and controls. Either way
    /// the run is asked for its files: the plan it plays, if it plays one, is opened in the
    /// Mission view to edit and send ([`Self::attach_with_runs_files`]).
    pub fn attach_run(&mut self, control: std::net::SocketAddr, ctx: &egui::Context) {
        self.set_view(View::Run);
        let Some(system) = self.system.path.clone() else {
            self.run.attach_bare(control, ctx);
            return;
        };
        self.run.attach(
            Target::System(system),
            control,
            (None, true),
            &self.palette.catalog,
            ctx,
        );
    }

    /// A run attached to has sent its files: writes them into a folder of their own and
    /// attaches again as with them open, with the run's module descriptions over the palette's;
    /// the run's plan, if it plays one, in the Mission view (unless it holds a plan of the
    /// user's), whose map the Run view then draws. Attached with its system file open, the
    /// studio keeps that attachment unless the run's plan is opened: then it watches the plan,
    /// as a run started from the Mission view, so that the edits to it can be sent.
    fn attach_with_runs_files(&mut self, ctx: &egui::Context) {
        let Some((control, files, system_open)) = self.run.take_runs_files() else {
            return;
        };
        let mirror = match crate::run::attach::mirror(&files) {
            Ok(mirror) => mirror,
            Err(err) => {
                self.set_status(format!("{err:#}"), true);
                return;
            }
        };
        let mut catalog = self.palette.catalog.clone();
        catalog.extend(mirror.catalog.clone());
        // The Mission view is free for the run's plan unless it holds a plan of the user's: a
        // copy of the run attached to before (a second attach) is the studio's, not the user's.
        let free = self
            .mission
            .as_ref()
            .is_none_or(|mission| match mission.path() {
                Some(path) => self.run.is_mirror_copy(path),
                None => !mission.is_dirty(),
            });
        let plan = mirror
            .mission
            .clone()
            .filter(|mission| free && is_plan(mission));
        if system_open && plan.is_none() {
            return;
        }
        if let Some(plan) = &plan {
            let mission = self.mission.get_or_insert_with(|| MissionView::new(ctx));
            mission.set_catalog(&catalog);
            // Not through `open_plan`: a copy in a temporary folder is no recent file.
            self.with_mission(|mission| mission.open(plan));
            // Compiled now: the Mission view compiles in its own frames, and the Run view
            // draws the net before the operator ever looks there.
            if let Some(mission) = self.mission.as_mut() {
                mission.recheck(true);
            }
        }
        let opened = self.mission.as_ref().and_then(MissionView::path);
        let target = match plan {
            Some(plan) if opened == Some(plan.as_path()) => Target::Plan(plan),
            _ => Target::System(mirror.system.clone()),
        };
        let mission = match target {
            Target::Plan(_) => self.mission.as_ref(),
            Target::System(_) => None,
        };
        self.run
            .attach(target, control, (mission, false), &catalog, ctx);
        self.run.keep_mirror(mirror);
        // After the attachment's own message, so that the status line says this.
        self.run.messages.push((
            true,
            format!(
                "watching the run at {control}: {} from the run",
                files
                    .mission
                    .as_ref()
                    .map_or(&files.system.path, |mission| &mission.path)
            ),
        ));
    }

    /// The Mission view, once a frame has shown it.
    pub fn mission(&self) -> Option<&MissionView> {
        self.mission.as_ref()
    }

    pub fn mission_mut(&mut self) -> Option<&mut MissionView> {
        self.mission.as_mut()
    }

    // ----- What tests and the bench read -----

    pub fn editor(&self) -> &Editor {
        &self.system.editor
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
        self.system.path.as_deref()
    }

    pub fn is_dirty(&self) -> bool {
        self.system.dirty
    }

    pub fn problems(&self) -> &[Problem] {
        self.system.problems()
    }

    fn set_status(&mut self, text: String, is_error: bool) {
        // What the status line says is what a user is told: the log says it too, so that a
        // session can be followed (and driven, by the Xvfb test) from outside.
        let text = crate::files::in_words(&text);
        tracing::info!("{text}");
        self.status = Status { text, is_error };
    }

    /// Shows on the status line what the System view said.
    fn show_system_messages(&mut self) {
        for (text, is_error) in self.system.take_messages() {
            self.set_status(text, is_error);
        }
    }

    /// Called when the window closes: a clean document needs no recovery copy.
    pub fn on_exit(&mut self) {
        if !self.system.dirty || self.discard_on_exit {
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
            self.system.editor.touch();
        }
        if self.palette.is_probing() {
            ctx.request_repaint_after(Duration::from_millis(50));
        }
        self.handle_screenshots(&ctx);
        if let Some(control) = self.attach_at_start.take() {
            self.attach_run(control, &ctx);
        }
        self.shortcuts(&ctx);
        self.run.poll();
        self.attach_with_runs_files(&ctx);
        self.run.sync_plan(self.mission.as_mut());
        for (ok, message) in std::mem::take(&mut self.run.messages) {
            self.set_status(message, !ok);
        }

        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_ui(ui));
        match self.view {
            View::Mission => self.mission_ui(ui),
            View::System => {
                let live = self.run.module_states();
                let viewer = viewer_context(&self.palette, &self.system, &live, self.started);
                self.system.ui(ui, &viewer);
                self.show_system_messages();
                self.start_ui(ui);
            }
            View::Run => self.run_ui(ui),
        }

        self.system.params_ui(ui, &self.palette.catalog);
        self.path_ui(ui);
        self.system.search_ui(ui);
        command::help_ui(ui.ctx(), &mut self.help_open);
        self.recovery_ui(ui);
        self.unsaved_ui(ui);
        self.attach_ui(&ctx);
        self.run_prompt_ui(&ctx);

        self.system.apply_commands(&ctx, &self.palette.catalog);
        self.show_system_messages();
        self.after_frame(&ctx);
        self.request_screenshot(&ctx);
        if !self.started {
            tracing::info!("window ready");
        }
        self.started = true;
    }

    /// Run → Attach…'s prompt, while it is open.
    fn attach_ui(&mut self, ctx: &egui::Context) {
        let Some(prompt) = &mut self.run.attach_prompt else {
            return;
        };
        match prompt.ui(ctx) {
            None => {}
            Some(crate::run::attach::Answer::Cancel) => self.run.attach_prompt = None,
            Some(crate::run::attach::Answer::Attach(control)) => {
                self.run.attach_prompt = None;
                self.attach_run(control, ctx);
            }
        }
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
        // While a run plays this plan: edit it here, then send it to the robot.
        if self.run.watches(mission) {
            egui::Panel::top("mission-send").show(ui, |ui| self.run.send_bar_ui(ui, mission));
        }
        egui::Panel::right("mission-inspector")
            .resizable(true)
            .default_size(330.0)
            .min_size(260.0)
            .show(ui, |ui| mission.inspector_ui(ui));
        mission.net_panel_ui(ui, "mission-net", 230.0, MissionView::net_ui);
        egui::CentralPanel::default()
            .frame(egui::Frame::NONE)
            .show(ui, |ui| mission.map_ui(ui));
        if let Some((text, is_error)) = mission.apply_commands() {
            self.set_status(text, is_error);
        }
    }

    /// The Run view.
    fn run_ui(&mut self, ui: &mut Ui) {
        let live = self.run.module_states();
        let viewer = viewer_context(&self.palette, &self.system, &live, self.started);
        let target = self.run_target();
        // The toolbar's time scale is beside its Run button: it runs at once, at that scale.
        if let Some(target) = self.run.ui(ui, &viewer, self.mission.as_mut(), target) {
            tracing::debug!("run {} from the toolbar", target.path().display());
            let time_scale = self.run.time_scale;
            self.run_at(time_scale, ui.ctx());
        }
    }

    /// The window's title: the document of the view shown, or in the Run view what runs (or
    /// ran last).
    fn window_title(&self) -> String {
        let name = |path: Option<&Path>| {
            path.and_then(Path::file_name).map_or_else(
                || "untitled".to_owned(),
                |name| name.to_string_lossy().into_owned(),
            )
        };
        if self.view == View::Run
            && let Some(target) = self.run.session_target()
        {
            let state = if self.run.is_running() {
                "running"
            } else if self.run.is_detached() {
                "detached: the run goes on"
            } else {
                "run ended"
            };
            return format!("{} ({state}) — ArMoR Studio", name(Some(target)));
        }
        if self.view == View::Run {
            // What a Run would start, as the toolbar says.
            if let Some(target) = self.run_target() {
                return format!("{} — ArMoR Studio", name(Some(target.path())));
            }
        }
        let (path, dirty) = match (self.view, &self.mission) {
            (View::Mission, Some(mission)) => (mission.path(), mission.is_dirty()),
            _ => (self.system.path.as_deref(), self.system.dirty),
        };
        format!(
            "{}{} — ArMoR Studio",
            if dirty { "*" } else { "" },
            name(path)
        )
    }

    fn after_frame(&mut self, ctx: &egui::Context) {
        // The title follows the document of the view shown.
        let revision = match (self.view, &self.mission) {
            (View::Mission, Some(mission)) => mission.editor.revision() ^ (1 << 63),
            _ => self.system.editor.revision(),
        };
        if self.seen_revision != Some(revision) {
            self.seen_revision = Some(revision);
            self.system.dirty = self.system.editor.diagram != self.system.saved;
        }
        let title = self.window_title();
        if title != self.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.title = title;
        }
        self.system.update_problems(&self.palette);
        self.autosave(ctx);
    }

    // ----- Commands: keys and menus -----

    /// The keys of the command table that work in the view shown, then the System view's
    /// clipboard and the Mission view's tool keys (`mission::TOOL_KEYS`, which its toolbar
    /// shows).
    fn shortcuts(&mut self, ctx: &egui::Context) {
        // A prompt open owns the keys: its Escape is no "clear the selection" under it.
        if self.run_prompt.is_some() || self.run.attach_prompt.is_some() {
            return;
        }
        // File shortcuts work while typing too; the others would steal the text field's keys.
        let typing = ctx.egui_wants_keyboard_input();
        let held = typing || (self.view == View::Mission && self.mission.is_none());
        for command in command::triggered(ctx, self.view, held) {
            self.execute(command, ctx, false);
        }
        if held {
            return;
        }
        match self.view {
            View::System => self.system.clipboard_input(ctx),
            View::Mission => {
                let chosen = self.mission.as_mut().and_then(|m| m.tool_key_input(ctx));
                if let Some(tool) = chosen {
                    self.set_status(tool.help().to_owned(), false);
                }
            }
            View::Run => {}
        }
    }

    /// Does what `command` means in the view shown (from a menu if `from_menu`, else a key):
    /// the run's, the sheet's and the files' here, the edits in the view.
    fn execute(&mut self, command: UiCommand, ctx: &egui::Context, from_menu: bool) {
        match (self.view, command) {
            (_, UiCommand::Stop) => self.run.stop(),
            (_, UiCommand::Attach) => {
                let last = self
                    .run
                    .session
                    .as_ref()
                    .and_then(|session| session.shared().control_addr)
                    .map(|addr| addr.to_string())
                    .unwrap_or_default();
                self.run.attach_prompt = Some(crate::run::attach::AttachPrompt::new(&last));
            }
            (_, UiCommand::Run) => self.ask_run(),
            // The menu entry opens the sheet; F1 opens and closes it.
            (_, UiCommand::Help) => self.help_open = from_menu || !self.help_open,
            (_, UiCommand::Quit) => ctx.send_viewport_cmd(egui::ViewportCommand::Close),
            (View::System, UiCommand::New) => self.replace(Replacing::NewSystem, ctx),
            (View::System, UiCommand::Open) => {
                self.ask_path(PathPurpose::Open, self.path_text());
            }
            (View::System, UiCommand::Save) => self.save(None),
            (View::System, UiCommand::SaveAs) => {
                self.ask_path(PathPurpose::SaveAs, self.path_text());
            }
            (View::System, UiCommand::ExportPng) => {
                self.ask_path(PathPurpose::ExportPng, self.system_path_with("png"));
            }
            (View::System, _) => self.system.execute(command),
            (View::Mission, UiCommand::New) => self.replace(Replacing::NewPlan, ctx),
            (View::Mission, UiCommand::Open) => {
                self.ask_path(PathPurpose::OpenPlan, self.plan_path_text());
            }
            (View::Mission, UiCommand::Save) => self.save_plan(None),
            (View::Mission, UiCommand::SaveAs) => {
                self.ask_path(PathPurpose::SavePlanAs, self.plan_path_text());
            }
            (View::Mission, UiCommand::ImportGpx) => {
                self.ask_path(PathPurpose::ImportGpx, String::new());
            }
            (View::Mission, UiCommand::ExportMission) => {
                let text = self.plan_path_with("mission.xml");
                self.ask_path(PathPurpose::ExportMission, text);
            }
            (View::Mission, UiCommand::ExportPnml) => {
                self.ask_path(PathPurpose::ExportPnml, self.plan_path_with("pnml"));
            }
            (View::Mission, UiCommand::BaseMap) => {
                let current = self
                    .mission
                    .as_ref()
                    .and_then(|mission| mission.basemap_href())
                    .unwrap_or_default();
                self.ask_path(PathPurpose::BaseMap, current);
            }
            (View::Mission, UiCommand::ExportPng) => {
                self.ask_path(PathPurpose::ExportMapPng, self.plan_path_with("png"));
            }
            (View::Mission, _) => {
                if let Some(mission) = self.mission.as_mut() {
                    mission.execute(command);
                }
            }
            (View::Run, UiCommand::Open) => {
                self.ask_path(PathPurpose::OpenRecording, String::new());
            }
            (View::Run, UiCommand::ZoomToFit) => self.run.request_fit(),
            (View::Run, _) => {}
        }
    }

    /// The start page, over the empty canvas, until a document is made or opened: a choice
    /// that fails (a file that cannot be opened) leaves it there, so that its examples and
    /// recent files stay at hand. It gives way to the dialogs while they are open.
    fn start_ui(&mut self, ui: &mut Ui) {
        let Some(examples) = &self.start else {
            return;
        };
        let plan_opened = self.mission.as_ref().and_then(MissionView::path).is_some();
        if !self.system.editor.diagram.is_empty() || self.system.path.is_some() || plan_opened {
            self.start = None;
            return;
        }
        if self.path_dialog.is_some() || self.unsaved_prompt.is_some() || !self.recovery.is_empty()
        {
            return;
        }
        let recent = self.home.recent();
        let mut choice = None;
        egui::Window::new("Start")
            .title_bar(false)
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .fixed_size([560.0, 380.0])
            .show(ui.ctx(), |ui| {
                choice = crate::start::start_ui(ui, &recent, examples);
            });
        let Some(choice) = choice else {
            return;
        };
        let ctx = ui.ctx().clone();
        match choice {
            StartChoice::NewSystem => {
                // An empty canvas is what was asked for: the page leaves it.
                self.start = None;
                self.set_status(
                    "new system: drag modules from the palette onto the canvas".to_owned(),
                    false,
                );
            }
            StartChoice::NewPlan => {
                self.start = None;
                self.set_view(View::Mission);
                self.replace(Replacing::NewPlan, &ctx);
            }
            StartChoice::Open => self.execute(UiCommand::Open, &ctx, true),
            StartChoice::File(file) => self.open_listed(file, &ctx),
        }
    }

    fn status_ui(&mut self, ui: &mut Ui) {
        ui.horizontal(|ui| {
            let colour = if self.status.is_error {
                system::ERROR
            } else {
                ui.visuals().text_color()
            };
            ui.colored_label(colour, &self.status.text);
        });
    }
}

/// Whether a file is a plan (opened in the Mission view) rather than a system.
fn is_plan(file: &Path) -> bool {
    matches!(
        armor_runtime::mission::document_kind(file),
        Ok(armor_runtime::mission::DocumentKind::Plan)
    )
}

/// The context the views get this frame; `live` is the state of the run's modules. A function
/// of the window's parts, not of the window, so that a view can be borrowed beside it.
fn viewer_context<'a>(
    palette: &'a Palette,
    system: &SystemView,
    live: &'a std::collections::BTreeMap<String, armor_protocol::ModuleState>,
    started: bool,
) -> ViewerContext<'a> {
    ViewerContext {
        palette,
        system_file: system.path.clone(),
        module_states: live,
        first_frame: !started,
    }
}
