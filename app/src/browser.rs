//! The studio's own file browser, for desktops without a file portal (a bare X server, a
//! remote session): the `egui-file-dialog` crate's window, opened in the document's folder,
//! with the bundled examples one click away, the file types of what is asked for, and the
//! folder's files listed to be picked rather than typed.

use std::path::{Path, PathBuf};

use egui_file_dialog::{DialogState, FileDialog};

/// A browser that is open.
pub struct Browser {
    dialog: FileDialog,
}

/// What the user did in the browser.
#[derive(Clone, Debug, PartialEq)]
pub enum BrowserAnswer {
    Picked(PathBuf),
    Cancelled,
}

/// What a browser is asked to show.
pub struct BrowserRequest<'a> {
    pub title: &'a str,
    /// The folder it opens in.
    pub folder: PathBuf,
    /// The folder of the document the file is for, offered beside the bundled examples.
    pub document_folder: Option<PathBuf>,
    /// The file types offered: a name and extensions (none: every file).
    pub filter: (&'static str, &'static [&'static str]),
    /// A file to save (with this name proposed), rather than one to open.
    pub save_as: Option<String>,
    /// A folder is what is asked for, not a file.
    pub folder_wanted: bool,
}

impl Browser {
    /// Opens a browser as `request` says.
    pub fn open(request: BrowserRequest<'_>) -> Browser {
        let (name, extensions) = request.filter;
        let mut dialog = FileDialog::new()
            .id(egui::Id::new("file-browser"))
            .title(request.title)
            .initial_directory(request.folder.clone())
            .default_size([760.0, 480.0])
            .show_devices(false)
            .show_removable_devices(false)
            .add_quick_access("ArMoR", |access| {
                if let Some(folder) = &request.document_folder {
                    access.add_path("The document's folder", folder.clone());
                }
                if let Some(missions) = crate::start::missions_folder() {
                    access.add_path("Bundled examples", missions);
                }
            });
        if !extensions.is_empty() {
            dialog = dialog
                .add_file_filter_extensions(name, extensions.to_vec())
                .default_file_filter(name);
        }
        if let Some(file_name) = &request.save_as {
            dialog = dialog.default_file_name(file_name);
        }
        if request.folder_wanted {
            dialog.pick_directory();
        } else if request.save_as.is_some() {
            dialog.save_file();
        } else {
            dialog.pick_file();
        }
        Browser { dialog }
    }

    /// Shows the browser; the answer once the user has given one.
    pub fn ui(&mut self, ctx: &egui::Context) -> Option<BrowserAnswer> {
        self.dialog.update(ctx);
        match self.dialog.state() {
            DialogState::Open => None,
            DialogState::Picked(_) => self.dialog.take_picked().map(BrowserAnswer::Picked),
            DialogState::PickedMultiple(paths) => paths.first().cloned().map(BrowserAnswer::Picked),
            DialogState::Closed | DialogState::Cancelled => Some(BrowserAnswer::Cancelled),
        }
    }
}

/// The folder a browser opens in: that of the path typed when it names one that exists, else
/// the document's (`document`: its file), else the current folder.
pub fn start_folder(typed: &Path, document: Option<&Path>) -> PathBuf {
    let typed_folder = if typed.is_dir() {
        Some(typed.to_path_buf())
    } else {
        typed
            .parent()
            .filter(|folder| folder.is_dir())
            .map(Path::to_path_buf)
    };
    let document_folder = document
        .and_then(Path::parent)
        .filter(|folder| folder.is_dir())
        .map(Path::to_path_buf);
    let folder = typed_folder
        .filter(|folder| !folder.as_os_str().is_empty())
        .or(document_folder)
        .unwrap_or_else(|| PathBuf::from("."));
    std::path::absolute(&folder).unwrap_or(folder)
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn a_browser_opens_where_the_typed_path_is_else_in_the_documents_folder() {
        let dir = tempfile::tempdir().unwrap();
        let docs = dir.path().join("docs");
        std::fs::create_dir(&docs).unwrap();
        let document = docs.join("system.xml");
        let other = dir.path().join("other.xml");
        assert_eq!(start_folder(&other, Some(&document)), dir.path());
        assert_eq!(start_folder(dir.path(), Some(&document)), dir.path());
        assert_eq!(start_folder(Path::new(""), Some(&document)), docs);
        assert_eq!(
            start_folder(Path::new("/no/such/folder/x.xml"), Some(&document)),
            docs
        );
    }
}
