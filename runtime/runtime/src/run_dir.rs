//! Each `armor run` writes into a folder of its own, `runs/<name>-<date>/`: the log of the
//! run (`log.txt`), the mission's report (`report.json`) and the plan's table of legs
//! (`summary.txt`), and whatever its modules write under relative names (a recorder's MCAP
//! file), since they are started with `ARMOR_RUN_DIR` naming it. A folder is never reused: two
//! runs started in the same second get `…-2`, `…-3`.

use std::path::{Path, PathBuf};

/// The folder runs are written under when `--runs-dir` is not given (else `runs` in the current
/// folder).
pub const ENV_RUNS_DIR: &str = "ARMOR_RUNS_DIR";
/// Given to every module of a run: the run's folder, where relative output files go.
pub const ENV_RUN_DIR: &str = armor_module_api::ENV_RUN_DIR;

/// The run's log, as printed.
pub const LOG: &str = "log.txt";
/// The mission's timeline (every firing, start and stop), as `--report` writes it.
pub const REPORT: &str = "report.json";
/// A plan's table of legs, as printed at the end.
pub const SUMMARY: &str = "summary.txt";

/// Makes a new folder under `parent` for a run of `name` started at `unix_secs` (UTC), named
/// `NAME-YYYY-MM-DD_HH-MM-SS`, with `-2`, `-3`, … when that name is taken. Returns it as an
/// absolute path.
pub fn create(parent: &Path, name: &str, unix_secs: f64) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(parent)?;
    let parent = std::path::absolute(parent)?;
    let base = format!("{}-{}", file_name_part(name), folder_date(unix_secs));
    for attempt in 1u32.. {
        let dir = match attempt {
            1 => parent.join(&base),
            n => parent.join(format!("{base}-{n}")),
        };
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(err) if err.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(err) => return Err(err),
        }
    }
    unreachable!("u32 ran out of run folder names")
}

/// `name` with what a file name should not hold replaced by `_`.
fn file_name_part(name: &str) -> String {
    let cleaned: String = name
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || matches!(c, '-' | '_' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect();
    match cleaned.trim_matches('.') {
        "" => "run".to_owned(),
        part => part.to_owned(),
    }
}

/// `2026-11-24_17-40-02`: the date of `unix_secs` in UTC, without a colon (which some file
/// systems and tools refuse).
fn folder_date(unix_secs: f64) -> String {
    armor_model::net::format_rfc3339(unix_secs.floor())
        .trim_end_matches('Z')
        .replace('T', "_")
        .replace(':', "-")
}

/// The files of a finished run's folder, by name, for the closing line.
pub fn listing(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .map(|entry| entry.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    names
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_is_named_after_the_run_and_never_reused() {
        let parent = tempfile::tempdir().expect("test");
        let at = 1_795_542_002.7; // 2026-11-24T17:40:02Z
        let first = create(parent.path(), "yard-recon", at).expect("test");
        let second = create(parent.path(), "yard-recon", at).expect("test");
        let third = create(parent.path(), "yard-recon", at).expect("test");
        assert_eq!(
            first.file_name().expect("test"),
            "yard-recon-2026-11-24_17-40-02"
        );
        assert_eq!(
            second.file_name().expect("test"),
            "yard-recon-2026-11-24_17-40-02-2"
        );
        assert_eq!(
            third.file_name().expect("test"),
            "yard-recon-2026-11-24_17-40-02-3"
        );
        assert!(first.is_absolute() && first.is_dir());
    }

    #[test]
    fn names_are_made_safe_for_a_file_system() {
        assert_eq!(file_name_part("a/b c:d"), "a_b_c_d");
        assert_eq!(file_name_part(".."), "run");
        assert_eq!(file_name_part("robot-yard"), "robot-yard");
    }
}
