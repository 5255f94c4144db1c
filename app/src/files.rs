//! Where the studio keeps its own files (recent files, the recovery copy). Saves go through
//! `armor_runtime::fs::write_atomically`: a failed save leaves the existing file as it was. A
//! view reads and writes its own documents (`system/file.rs`, the Mission view's plans).

use std::path::{Path, PathBuf};

use anyhow::Context as _;

/// Overrides the folder of the studio's own files (tests use a temporary one).
pub const ENV_STUDIO_HOME: &str = "ARMOR_STUDIO_HOME";

/// How many files the Recent menu lists.
const RECENT_LIMIT: usize = 10;

/// The first line of a recovery file says which document it is a copy of.
const RECOVERY_TAG: &str = "<!-- armor-studio recovery of: ";

/// The studio's folder: `$ARMOR_STUDIO_HOME`, else `$XDG_CONFIG_HOME/armor-studio`, else
/// `~/.config/armor-studio`, else a folder in the temporary directory.
pub fn default_home() -> PathBuf {
    if let Some(home) = std::env::var_os(ENV_STUDIO_HOME).filter(|v| !v.is_empty()) {
        return PathBuf::from(home);
    }
    if let Some(config) = std::env::var_os("XDG_CONFIG_HOME").filter(|v| !v.is_empty()) {
        return PathBuf::from(config).join("armor-studio");
    }
    if let Some(home) = std::env::var_os("HOME").filter(|v| !v.is_empty()) {
        return PathBuf::from(home).join(".config").join("armor-studio");
    }
    std::env::temp_dir().join("armor-studio")
}

/// The studio's own files.
#[derive(Clone, Debug)]
pub struct Home {
    pub dir: PathBuf,
}

/// The kinds of document the studio edits, each with its own recovery copy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Document {
    System,
    Plan,
}

impl Document {
    fn recovery_name(self) -> &'static str {
        match self {
            Document::System => "recovery.xml",
            Document::Plan => "recovery-plan.xml",
        }
    }

    pub fn noun(self) -> &'static str {
        match self {
            Document::System => "system",
            Document::Plan => "plan",
        }
    }
}

/// What a recovery file holds.
#[derive(Clone, Debug)]
pub struct Recovery {
    pub document: Document,
    /// The document it is a copy of, if it had been saved before.
    pub original: Option<PathBuf>,
    pub text: String,
}

impl Home {
    pub fn new(dir: impl Into<PathBuf>) -> Home {
        Home { dir: dir.into() }
    }

    fn recent_file(&self) -> PathBuf {
        self.dir.join("recent.txt")
    }

    fn time_scale_file(&self) -> PathBuf {
        self.dir.join("time-scale.txt")
    }

    /// The time scale the last run was asked for; ×1 when none was, or the file is unreadable.
    pub fn time_scale(&self) -> f64 {
        std::fs::read_to_string(self.time_scale_file())
            .ok()
            .and_then(|text| text.trim().parse::<f64>().ok())
            .filter(|scale| scale.is_finite() && *scale > 0.0)
            .unwrap_or(1.0)
    }

    /// Remembers the time scale a run was started at, for the next run, in this session or a
    /// later one.
    pub fn set_time_scale(&self, scale: f64) -> anyhow::Result<()> {
        self.write(&self.time_scale_file(), format!("{scale}\n").as_bytes())
    }

    pub fn recovery_file(&self, document: Document) -> PathBuf {
        self.dir.join(document.recovery_name())
    }

    /// The recent files, newest first. A missing or unreadable list is an empty one.
    pub fn recent(&self) -> Vec<PathBuf> {
        std::fs::read_to_string(self.recent_file())
            .unwrap_or_default()
            .lines()
            .filter(|line| !line.trim().is_empty())
            .map(PathBuf::from)
            .collect()
    }

    /// Puts `file` first in the recent list.
    pub fn add_recent(&self, file: &Path) -> anyhow::Result<()> {
        let file = std::path::absolute(file).unwrap_or_else(|_| file.to_path_buf());
        let mut recent = self.recent();
        recent.retain(|other| other != &file);
        recent.insert(0, file);
        recent.truncate(RECENT_LIMIT);
        let text: String = recent
            .iter()
            .map(|path| format!("{}\n", path.display()))
            .collect();
        self.write(&self.recent_file(), text.as_bytes())
    }

    /// Writes the recovery copy of a document being edited (`text`: its XML).
    pub fn write_recovery(
        &self,
        document: Document,
        original: Option<&Path>,
        text: &str,
    ) -> anyhow::Result<()> {
        let original = original
            .map(|path| path.display().to_string())
            .unwrap_or_default();
        // `--` may not appear inside an XML comment; a path with one is not worth recording.
        let original = if original.contains("--") {
            String::new()
        } else {
            original
        };
        let text = format!("{RECOVERY_TAG}{original} -->\n{text}");
        self.write(&self.recovery_file(document), text.as_bytes())
    }

    /// The recovery copy left by a session that did not end cleanly, if any.
    pub fn recovery(&self, document: Document) -> Option<Recovery> {
        let text = std::fs::read_to_string(self.recovery_file(document)).ok()?;
        let first = text.lines().next().unwrap_or_default();
        let original = first
            .strip_prefix(RECOVERY_TAG)
            .and_then(|rest| rest.strip_suffix(" -->"))
            .filter(|path| !path.is_empty())
            .map(PathBuf::from);
        let text = match first.starts_with(RECOVERY_TAG) {
            true => text
                .split_once('\n')
                .map(|(_, rest)| rest.to_owned())
                .unwrap_or_default(),
            false => text,
        };
        Some(Recovery {
            document,
            original,
            text,
        })
    }

    /// Forgets the recovery copy (after a save, a clean exit, or when the user declines it).
    pub fn clear_recovery(&self, document: Document) {
        match std::fs::remove_file(self.recovery_file(document)) {
            Ok(()) => {}
            Err(err) if err.kind() == std::io::ErrorKind::NotFound => {}
            Err(err) => tracing::warn!("cannot remove the recovery file: {err}"),
        }
    }

    fn write(&self, file: &Path, bytes: &[u8]) -> anyhow::Result<()> {
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("cannot create {}", self.dir.display()))?;
        armor_runtime::fs::write_atomically(file, bytes)
            .with_context(|| format!("cannot write {}", file.display()))
    }
}

/// What the system's error texts say, in words a user reads without knowing errno: each
/// "(os error N)" the standard library appends is taken away, and the texts of the commonest
/// ones are said plainly ("No such file or directory (os error 2)" becomes "there is no such
/// file or folder"). The status line shows every message through this.
pub fn in_words(text: &str) -> String {
    const PLAIN: &[(&str, &str)] = &[
        (
            "No such file or directory (os error 2)",
            "there is no such file or folder",
        ),
        (
            "Is a directory (os error 21)",
            "that is a folder, not a file: choose a file in it",
        ),
        (
            "Not a directory (os error 20)",
            "a part of that path is a file, not a folder",
        ),
        (
            "Permission denied (os error 13)",
            "permission denied (the file's owner does not let you)",
        ),
        (
            "Read-only file system (os error 30)",
            "that disk is read-only",
        ),
        ("No space left on device (os error 28)", "the disk is full"),
    ];
    let mut text = PLAIN.iter().fold(text.to_owned(), |text, (raw, plain)| {
        text.replace(raw, plain)
    });
    // Any other: its words stay, without the number.
    while let Some(start) = text.find(" (os error ") {
        let Some(end) = text[start..].find(')') else {
            break;
        };
        text.replace_range(start..start + end + 1, "");
    }
    text
}

/// Why `path`, given to be read as a file, cannot be, in words; `None` when it can be tried.
/// `folder_ok`: a folder is what is asked for (a folder of map tiles).
pub fn unreadable(path: &Path, folder_ok: bool) -> Option<String> {
    let shown = path.display();
    let from = || {
        std::env::current_dir()
            .ok()
            .filter(|_| path.is_relative())
            .map(|dir| format!(" (a relative path starts from {})", dir.display()))
            .unwrap_or_default()
    };
    match std::fs::metadata(path) {
        Err(err) if err.kind() == std::io::ErrorKind::NotFound => {
            Some(format!("{shown}: there is no such file{}", from()))
        }
        Err(err) => Some(in_words(&format!("{shown}: {err}"))),
        Ok(meta) if meta.is_dir() && !folder_ok => Some(format!(
            "{shown} is a folder, not a file: choose a file in it (Browse… shows what it holds)"
        )),
        Ok(_) => None,
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn recent_files_and_the_recovery_copy() {
        let dir = tempfile::tempdir().unwrap();
        let home = Home::new(dir.path().join("home"));
        assert!(home.recent().is_empty() && home.recovery(Document::System).is_none());
        for name in ["a.xml", "b.xml", "a.xml"] {
            home.add_recent(&dir.path().join(name)).unwrap();
        }
        assert_eq!(
            home.recent(),
            [dir.path().join("a.xml"), dir.path().join("b.xml")]
        );
        let text = "<system name=\"s\"><module name=\"sink\" type=\"sink\"/></system>";
        home.write_recovery(Document::System, Some(&dir.path().join("a.xml")), text)
            .unwrap();
        assert!(home.recovery(Document::Plan).is_none());
        let recovery = home.recovery(Document::System).unwrap();
        assert_eq!(recovery.original, Some(dir.path().join("a.xml")));
        assert_eq!(recovery.text, text);
        home.clear_recovery(Document::System);
        assert!(home.recovery(Document::System).is_none());
    }

    #[test]
    fn errors_are_said_in_words_without_errno() {
        assert_eq!(
            in_words("cannot read a.xml: No such file or directory (os error 2)"),
            "cannot read a.xml: there is no such file or folder"
        );
        assert_eq!(
            in_words("cannot read /tmp: Is a directory (os error 21)"),
            "cannot read /tmp: that is a folder, not a file: choose a file in it"
        );
        assert_eq!(in_words("x: Broken pipe (os error 32)"), "x: Broken pipe");
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nothing.xml");
        assert!(
            unreadable(&missing, false)
                .unwrap()
                .contains("there is no such file")
        );
        assert!(
            unreadable(dir.path(), false)
                .unwrap()
                .contains("is a folder, not a file")
        );
        assert_eq!(unreadable(dir.path(), true), None);
    }
}
