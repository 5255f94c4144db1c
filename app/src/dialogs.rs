//! The window's dialogs: the path field with its browser (open, save as, import, export), "Save
//! changes?" and "Restore unsaved work?". Each shows itself and returns the user's answer; the window
//! (`app.rs`) acts on it.

use std::path::PathBuf;

use egui::Key;

use crate::browser::{Browser, BrowserAnswer, BrowserRequest};
use crate::files::Recovery;

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
    BaseMap,
}

impl PathPurpose {
    /// What the status line says it is asking for.
    pub fn what(self) -> &'static str {
        match self {
            PathPurpose::Open => "open",
            PathPurpose::SaveAs | PathPurpose::SavePlanAs => "save as",
            PathPurpose::ExportPng | PathPurpose::ExportMapPng => "export a picture",
            PathPurpose::OpenPlan => "open a plan",
            PathPurpose::ImportGpx => "import GPX",
            PathPurpose::ExportMission => "export the mission",
            PathPurpose::ExportPnml => "export PNML",
            PathPurpose::OpenRecording => "open a recording",
            PathPurpose::BaseMap => "choose a base map",
        }
    }
}

/// A path being typed, and what for.
pub struct PathDialog {
    pub purpose: PathPurpose,
    pub text: String,
    /// The native dialog was offered (at the first frame), and the path field follows.
    native_offered: bool,
    /// The path field's text was selected, so that typing replaces it.
    selected: bool,
    /// The path field has held the keyboard focus (said once in the log: keys typed from then
    /// on go into it, while keys typed before its first frame are lost).
    focused: bool,
    /// The document the path is for (its file), whose folder the browser opens in.
    document: Option<PathBuf>,
    /// The studio's own browser, while it is open (over the path field, which it fills).
    browser: Option<Browser>,
}

/// What the user did with the path dialog.
pub enum PathAnswer {
    Submit(PathBuf),
    Cancel,
}

impl PathPurpose {
    fn saves(self) -> bool {
        !matches!(
            self,
            PathPurpose::Open
                | PathPurpose::OpenPlan
                | PathPurpose::ImportGpx
                | PathPurpose::OpenRecording
                | PathPurpose::BaseMap
        )
    }

    /// The file types offered by the native dialog: (name, extensions).
    fn filter(self) -> (&'static str, &'static [&'static str]) {
        match self {
            PathPurpose::Open | PathPurpose::SaveAs => ("System (XML)", &["xml"]),
            PathPurpose::OpenPlan | PathPurpose::SavePlanAs => ("Plan (XML)", &["xml"]),
            PathPurpose::ExportMission => ("Mission (XML)", &["xml"]),
            PathPurpose::ExportPnml => ("PNML", &["pnml", "xml"]),
            PathPurpose::ExportPng | PathPurpose::ExportMapPng => ("Picture (PNG)", &["png"]),
            PathPurpose::ImportGpx => ("GPX", &["gpx"]),
            PathPurpose::OpenRecording => ("Recording (MCAP)", &["mcap"]),
            PathPurpose::BaseMap => ("Base map (MBTiles)", &["mbtiles"]),
        }
    }
}

/// Whether the desktop can show a native file dialog: a session bus and a desktop that runs
/// the file-chooser portal. Elsewhere (a bare X server, a test) the path is typed, and
/// `ARMOR_STUDIO_TYPED_PATHS=1` asks for that everywhere.
fn native_dialogs() -> bool {
    let set = |name: &str| std::env::var_os(name).is_some_and(|value| !value.is_empty());
    set("DBUS_SESSION_BUS_ADDRESS")
        && set("XDG_CURRENT_DESKTOP")
        && !std::env::var("ARMOR_STUDIO_TYPED_PATHS").is_ok_and(|value| value == "1")
}

impl PathDialog {
    pub fn new(purpose: PathPurpose, text: String) -> PathDialog {
        PathDialog {
            purpose,
            text,
            native_offered: false,
            selected: false,
            focused: false,
            document: None,
            browser: None,
        }
    }

    /// The document the path is for: the browser opens in its folder.
    pub fn for_document(mut self, document: Option<PathBuf>) -> PathDialog {
        self.document = document;
        self
    }

    /// Whether the studio's own browser is open.
    pub fn is_browsing(&self) -> bool {
        self.browser.is_some()
    }

    /// Opens the studio's browser where the path typed is, else in the document's folder.
    pub fn browse(&mut self, title: &str) {
        let typed = PathBuf::from(self.text.trim());
        let save_as = self.purpose.saves().then(|| {
            typed
                .file_name()
                .map(|name| name.to_string_lossy().into_owned())
                .unwrap_or_default()
        });
        self.browser = Some(Browser::open(BrowserRequest {
            title,
            folder: crate::browser::start_folder(&typed, self.document.as_deref()),
            document_folder: self
                .document
                .as_deref()
                .and_then(std::path::Path::parent)
                .filter(|folder| folder.is_dir())
                .map(PathBuf::from),
            filter: self.purpose.filter(),
            save_as,
            folder_wanted: false,
        }));
    }

    /// The desktop's own dialog (the `rfd` crate, through the XDG portal), where there is one:
    /// `Some` path chosen; `None` when there is none or the user closed it, and then the path
    /// is typed.
    fn native(&self, title: &str) -> Option<PathBuf> {
        let typed = PathBuf::from(self.text.trim());
        let (name, extensions) = self.purpose.filter();
        let mut dialog = rfd::FileDialog::new()
            .set_title(title)
            .add_filter(name, extensions);
        if let Some(folder) = typed.parent().filter(|folder| folder.is_dir()) {
            dialog = dialog.set_directory(folder);
        }
        if let Some(file) = typed.file_name() {
            dialog = dialog.set_file_name(file.to_string_lossy());
        }
        if self.purpose.saves() {
            dialog.save_file()
        } else {
            dialog.pick_file()
        }
    }

    /// Shows the dialog; the answer once the user has given one.
    pub fn ui(&mut self, ctx: &egui::Context) -> Option<PathAnswer> {
        let dialog = self;
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
            PathPurpose::BaseMap => (
                "Base map: an MBTiles file or a folder of {z}/{x}/{y}.png tiles (none: the world's)",
                "Show",
            ),
        };
        if !dialog.native_offered {
            dialog.native_offered = true;
            if native_dialogs()
                && let Some(path) = dialog.native(title)
            {
                return Some(PathAnswer::Submit(path));
            }
        }
        if let Some(browser) = &mut dialog.browser {
            match browser.ui(ctx) {
                None => return None,
                // Picked: done, as if typed and submitted.
                Some(BrowserAnswer::Picked(path)) => return Some(PathAnswer::Submit(path)),
                // Closed: back to the path field, as it was.
                Some(BrowserAnswer::Cancelled) => dialog.browser = None,
            }
        }
        let mut submit = false;
        let mut cancel = false;
        let mut browse = false;
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
                if edit.has_focus() && dialog.selected && !dialog.focused {
                    dialog.focused = true;
                    tracing::info!("{title}: the path field takes what is typed");
                }
                // The path offered is selected: typing replaces it, an arrow key keeps it.
                if !dialog.selected
                    && let Some(mut state) = egui::text_edit::TextEditState::load(ui.ctx(), edit.id)
                {
                    let end = dialog.text.chars().count();
                    state
                        .cursor
                        .set_char_range(Some(egui::text::CCursorRange::two(
                            egui::text::CCursor::new(0),
                            egui::text::CCursor::new(end),
                        )));
                    state.store(ui.ctx(), edit.id);
                    dialog.selected = true;
                }
                if edit.lost_focus() && ui.input(|input| input.key_pressed(Key::Enter)) {
                    submit = true;
                }
                if let Ok(dir) = std::env::current_dir() {
                    ui.weak(format!("A relative path starts from {}", dir.display()));
                }
                ui.horizontal(|ui| {
                    if ui.button(action).clicked() {
                        submit = true;
                    }
                    browse = ui
                        .button("Browse…")
                        .on_hover_text("Pick the file in a list of the folder's files")
                        .clicked();
                    if ui.button("Cancel").clicked() {
                        cancel = true;
                    }
                });
            });
        if browse {
            dialog.browse(title);
            return None;
        }
        if cancel {
            Some(PathAnswer::Cancel)
        } else if submit {
            Some(PathAnswer::Submit(PathBuf::from(dialog.text.trim())))
        } else {
            None
        }
    }
}

/// What replaces a document, or closes the window: held while the user is asked what to do
/// with the unsaved changes it would lose.
#[derive(Clone, Debug, PartialEq)]
pub enum Replacing {
    NewSystem,
    OpenSystem(PathBuf),
    NewPlan,
    OpenPlan(PathBuf),
    Quit,
}

/// The answer to "Save changes?".
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UnsavedChoice {
    Save,
    Discard,
    Cancel,
}

/// "Save changes?" for the documents `names` (as the user knows them).
pub fn unsaved_ui(ctx: &egui::Context, names: &[String]) -> Option<UnsavedChoice> {
    let mut choice = None;
    egui::Modal::new(egui::Id::new("unsaved")).show(ctx, |ui| {
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
    choice
}

/// The answer to "Restore unsaved work?".
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RecoveryChoice {
    Restore,
    Discard,
}

/// "Restore unsaved work?" for a recovery copy left by a session that did not end cleanly.
pub fn recovery_ui(ctx: &egui::Context, recovery: &Recovery) -> Option<RecoveryChoice> {
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
    if restore {
        Some(RecoveryChoice::Restore)
    } else if discard {
        Some(RecoveryChoice::Discard)
    } else {
        None
    }
}
