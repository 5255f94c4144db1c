//! The window's documents (the system and the plan): opening, saving, starting anew, the
//! recovery copies written while changes are unsaved, and "Save changes?" before either is
//! replaced or the window closes. The System and Mission views hold the documents; this is
//! where the window decides what to ask and when, and acts on the answers of its dialogs (the
//! dialogs themselves are `crate::dialogs`).

use std::path::Path;
use std::time::Instant;

use egui::Ui;

use super::{StudioApp, View};
use crate::dialogs::{
    self, PathAnswer, PathDialog, PathPurpose, RecoveryChoice, Replacing, UnsavedChoice,
};
use crate::files::Document;
use crate::mission::MissionView;

impl StudioApp {
    /// Reports what a file operation of the mission view did on the status line.
    pub(super) fn report(&mut self, report: crate::mission::Report) {
        match report {
            Ok(text) => self.set_status(text, false),
            Err(err) => self.set_status(format!("{err:#}"), true),
        }
    }

    /// Runs a file operation of the mission view (which exists once its view was shown).
    pub(super) fn with_mission(
        &mut self,
        operation: impl FnOnce(&mut MissionView) -> crate::mission::Report,
    ) {
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
    pub(super) fn new_plan(&mut self) {
        let system = self.system.path.clone();
        self.with_mission(|mission| mission.new_plan(system.as_deref()));
    }

    // ----- The system's file -----

    /// Opens a system file, replacing the document (unsaved changes stay in the undo history of
    /// nobody: the caller asks first).
    pub fn open(&mut self, file: &Path) {
        self.system.open(file, &self.home);
        self.show_system_messages();
    }

    /// Saves to `file` (save as) or to the current file.
    pub fn save(&mut self, file: Option<&Path>) {
        let Some(file) = file
            .map(Path::to_path_buf)
            .or_else(|| self.system.path.clone())
        else {
            self.ask_path(PathPurpose::SaveAs, String::new());
            return;
        };
        if self.system.save(file, &self.home, &self.palette.catalog) {
            self.seen_revision = None;
        }
        self.show_system_messages();
    }

    pub(super) fn new_document(&mut self) {
        self.system.new_document();
        self.show_system_messages();
    }

    pub(super) fn autosave(&mut self, ctx: &egui::Context) {
        self.autosave_plan(ctx);
        let held = !self.recovery.is_empty();
        self.system
            .autosave(ctx, &self.home, self.autosave_every, held);
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

    pub(super) fn plan_path_text(&self) -> String {
        self.mission
            .as_ref()
            .and_then(MissionView::path)
            .map(|path| path.display().to_string())
            .unwrap_or_default()
    }

    pub(super) fn path_text(&self) -> String {
        self.system
            .path
            .as_ref()
            .map(|path| path.display().to_string())
            .unwrap_or_default()
    }

    /// What `extension` would make of the system's file name (a default for its picture).
    pub(super) fn system_path_with(&self, extension: &str) -> String {
        self.system
            .path
            .as_ref()
            .map(|path| path.with_extension(extension).display().to_string())
            .unwrap_or_default()
    }

    /// What `extension` would make of the plan's file name (a default for its exports).
    pub(super) fn plan_path_with(&self, extension: &str) -> String {
        self.mission
            .as_ref()
            .and_then(MissionView::path)
            .map(|path| path.with_extension(extension).display().to_string())
            .unwrap_or_default()
    }

    pub(super) fn ask_path(&mut self, purpose: PathPurpose, text: String) {
        self.set_status(
            format!(
                "{}: type a path, then Enter, or Browse… to pick it",
                purpose.what()
            ),
            false,
        );
        self.path_dialog =
            Some(PathDialog::new(purpose, text).for_document(self.document_file(purpose)));
    }

    /// The file of the document a path is asked for: the browser opens in its folder. A plan's
    /// for what the Mission view reads and writes, the system's for the rest, and the run's
    /// for a recording (it is in the run's folder, beside what ran).
    fn document_file(&self, purpose: PathPurpose) -> Option<std::path::PathBuf> {
        let plan = self.mission.as_ref().and_then(MissionView::path);
        let system = self.system.path.as_deref();
        let file = match purpose {
            PathPurpose::Open | PathPurpose::SaveAs | PathPurpose::ExportPng => system.or(plan),
            PathPurpose::OpenRecording => self.run.session_target().or(plan).or(system),
            _ => plan.or(system),
        };
        file.map(Path::to_path_buf)
    }

    /// Opens `file` from a list (Open recent, the examples): a plan in the Mission view, a
    /// system in the System view, as on the command line; a file that is gone is said so.
    pub(super) fn open_listed(&mut self, file: std::path::PathBuf, ctx: &egui::Context) {
        if let Some(why) = crate::files::unreadable(&file, false) {
            self.set_status(why, true);
            return;
        }
        if super::is_plan(&file) {
            self.set_view(View::Mission);
            if self.mission.is_some() {
                self.replace(Replacing::OpenPlan(file), ctx);
            } else {
                self.plan_to_open = Some(file);
            }
        } else {
            self.set_view(View::System);
            self.replace(Replacing::OpenSystem(file), ctx);
        }
    }

    // ----- Unsaved changes -----

    /// The documents `action` would lose changes of.
    pub(super) fn unsaved_for(&self, action: &Replacing) -> Vec<Document> {
        let system = self.system.editor.diagram != self.system.saved;
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
    pub(super) fn replace(&mut self, action: Replacing, ctx: &egui::Context) {
        if self.unsaved_for(&action).is_empty() {
            self.perform(action, ctx);
        } else {
            self.unsaved_prompt = Some(action);
        }
    }

    pub(super) fn perform(&mut self, action: Replacing, ctx: &egui::Context) {
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
    pub(super) fn continue_after_save_as(&mut self, ctx: &egui::Context) {
        if let Some(action) = self.after_save_as.take() {
            self.replace(action, ctx);
        }
    }

    /// Saves the documents `action` would lose changes of, then does it; a document without a
    /// file asks for one first. A failed save stops there (its error is in the status line).
    pub(super) fn save_then(&mut self, action: Replacing, ctx: &egui::Context) {
        for document in self.unsaved_for(&action) {
            let has_file = match document {
                Document::System => self.system.path.is_some(),
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

    pub(super) fn document_name(&self, document: Document) -> String {
        let path = match document {
            Document::System => self.system.path.as_deref(),
            Document::Plan => self.mission.as_ref().and_then(MissionView::path),
        };
        path.and_then(Path::file_name).map_or_else(
            || format!("the new {}", document.noun()),
            |name| format!("“{}”", name.to_string_lossy()),
        )
    }

    /// File, Open recent: the systems and plans opened last, each opened in its view.
    pub(super) fn recent_menu_ui(&mut self, ui: &mut Ui) {
        ui.menu_button("Open recent", |ui| {
            let recent = self.home.recent();
            if recent.is_empty() {
                ui.label("(none)");
            }
            for file in recent {
                if ui.button(file.display().to_string()).clicked() {
                    self.open_listed(file, ui.ctx());
                }
            }
        });
    }

    /// File, Examples: the bundled systems and plans (the start page's list), reachable
    /// whatever happened to the start page.
    pub(super) fn examples_menu_ui(&mut self, ui: &mut Ui) {
        ui.menu_button("Examples", |ui| {
            let examples = crate::start::examples();
            if examples.is_empty() {
                ui.label("(no missions/ folder found here)");
            }
            for file in examples {
                if ui
                    .button(crate::start::short_name(&file))
                    .on_hover_text(file.display().to_string())
                    .clicked()
                {
                    self.open_listed(file, ui.ctx());
                }
            }
        });
    }

    // ----- Dialogs: the window acts on the answers -----

    pub(super) fn path_ui(&mut self, ui: &mut Ui) {
        let ctx = &ui.ctx().clone();
        let Some(dialog) = &mut self.path_dialog else {
            return;
        };
        let purpose = dialog.purpose;
        match dialog.ui(ctx) {
            None => {}
            Some(PathAnswer::Cancel) => {
                self.path_dialog = None;
                self.after_save_as = None;
                // This frame was drawn with the dialog: draw the next without it, now, not at
                // the next input (the screen would show a dialog that is no longer there).
                ctx.request_repaint();
            }
            Some(PathAnswer::Submit(path)) => {
                self.path_dialog = None;
                ctx.request_repaint();
                if path.as_os_str().is_empty() {
                    self.set_status("no path given".to_owned(), true);
                    return;
                }
                // A file to read that is not there, or is a folder, said in words before any
                // reader says it with an error number.
                let reads = matches!(
                    purpose,
                    PathPurpose::Open
                        | PathPurpose::OpenPlan
                        | PathPurpose::ImportGpx
                        | PathPurpose::OpenRecording
                );
                if let Some(why) = reads
                    .then(|| crate::files::unreadable(&path, false))
                    .flatten()
                {
                    self.set_status(why, true);
                    return;
                }
                match purpose {
                    // A plan typed into the System view's Open opens in the Mission view, as
                    // on the command line, rather than failing as a system.
                    PathPurpose::Open if super::is_plan(&path) => {
                        self.set_view(View::Mission);
                        if self.mission.is_some() {
                            self.replace(Replacing::OpenPlan(path), ctx);
                        } else {
                            self.plan_to_open = Some(path);
                        }
                    }
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
                    PathPurpose::BaseMap => self.with_mission(|m| m.choose_basemap(&path)),
                }
            }
        }
    }

    /// "Save changes?" before a document is replaced or the window closes, as any editor asks.
    pub(super) fn unsaved_ui(&mut self, ui: &mut Ui) {
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
        let Some(choice) = dialogs::unsaved_ui(&ctx, &names) else {
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

    pub(super) fn recovery_ui(&mut self, ui: &mut Ui) {
        let Some(recovery) = self.recovery.first().cloned() else {
            return;
        };
        let Some(choice) = dialogs::recovery_ui(ui.ctx(), &recovery) else {
            return;
        };
        self.recovery.remove(0);
        match choice {
            RecoveryChoice::Restore if recovery.document == Document::Plan => {
                // The plan is restored into the Mission view, which exists from its first frame.
                self.set_view(View::Mission);
                let ctx = ui.ctx().clone();
                let mission = self.mission.get_or_insert_with(|| MissionView::new(&ctx));
                let report = mission.restore(recovery.original.as_deref(), &recovery.text);
                self.report(report);
            }
            RecoveryChoice::Restore => {
                self.system
                    .restore(recovery.original.as_deref(), &recovery.text);
                self.show_system_messages();
            }
            RecoveryChoice::Discard => self.home.clear_recovery(recovery.document),
        }
    }
}
