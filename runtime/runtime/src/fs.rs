//! File writing that never leaves a half-written file behind.

use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Writes `bytes` to a temporary file beside `file`, then renames it over `file`: a reader sees
/// the old content or the new, never a mix, and a failure leaves the old file as it was.
pub fn write_atomically(file: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let folder = match file.parent() {
        Some(folder) if !folder.as_os_str().is_empty() => folder,
        _ => Path::new("."),
    };
    let mut temporary = tempfile::NamedTempFile::new_in(folder)?;
    temporary.write_all(bytes)?;
    temporary.as_file().sync_all()?;
    temporary.persist(file).map_err(|err| err.error)?;
    Ok(())
}

/// `target` as seen from the folder `from`: relative when both resolve, else absolute.
pub fn relative_path(target: &Path, from: &Path) -> PathBuf {
    let (Ok(target), Ok(from)) = (std::fs::canonicalize(target), std::fs::canonicalize(from))
    else {
        return std::path::absolute(target).unwrap_or_else(|_| target.to_path_buf());
    };
    let common = target
        .components()
        .zip(from.components())
        .take_while(|(a, b)| a == b)
        .count();
    let mut relative = PathBuf::new();
    for _ in from.components().skip(common) {
        relative.push("..");
    }
    for part in target.components().skip(common) {
        relative.push(part);
    }
    relative
}
