//! Finding module binaries and asking them what they are (`--describe`).

use std::collections::BTreeMap;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use armor_module_api::ModuleDescription;

pub const BINARY_PREFIX: &str = "armor-mod-";
pub const ENV_MODULE_PATH: &str = "ARMOR_MODULE_PATH";
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(5);
/// Describe output beyond this is garbage, not a description.
const MAX_DESCRIBE_BYTES: u64 = 1024 * 1024;

/// The folders searched for module binaries: `$ARMOR_MODULE_PATH` (colon-separated), else the
/// folder of the running executable, where `cargo build` puts every binary of the workspace.
pub fn module_path() -> Vec<PathBuf> {
    match std::env::var_os(ENV_MODULE_PATH) {
        Some(path) if !path.is_empty() => std::env::split_paths(&path).collect(),
        _ => std::env::current_exe()
            .ok()
            .and_then(|exe| exe.parent().map(Path::to_path_buf))
            .into_iter()
            .collect(),
    }
}

/// The binary of a module type, from the first folder of `path` that has it.
pub fn find_module(path: &[PathBuf], module_type: &str) -> Option<PathBuf> {
    path.iter()
        .map(|dir| dir.join(format!("{BINARY_PREFIX}{module_type}")))
        .find(|candidate| is_executable(candidate))
}

/// Every module binary in the given files and folders, sorted, without duplicates.
pub fn list_modules(paths: &[PathBuf]) -> Vec<PathBuf> {
    let mut found = Vec::new();
    for path in paths {
        if path.is_dir() {
            let Ok(entries) = std::fs::read_dir(path) else {
                continue;
            };
            found.extend(
                entries
                    .filter_map(Result::ok)
                    .map(|entry| entry.path())
                    .filter(|file| is_module_binary(file)),
            );
        } else {
            found.push(path.clone());
        }
    }
    found.sort();
    found.dedup();
    found
}

fn is_module_binary(file: &Path) -> bool {
    file.file_name()
        .and_then(|name| name.to_str())
        .is_some_and(|name| name.starts_with(BINARY_PREFIX) && !name.contains('.'))
        && is_executable(file)
}

fn is_executable(file: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt as _;
    file.metadata()
        .is_ok_and(|meta| meta.is_file() && meta.permissions().mode() & 0o111 != 0)
}

/// The module type a binary's file name promises (`armor-mod-counter` → `counter`).
pub fn type_from_file_name(binary: &Path) -> Option<&str> {
    binary.file_name()?.to_str()?.strip_prefix(BINARY_PREFIX)
}

#[derive(Debug, thiserror::Error)]
pub enum ProbeError {
    #[error("cannot run it: {0}")]
    Spawn(std::io::Error),
    #[error("did not answer --describe within {0:.1} s (killed)")]
    Timeout(f64),
    #[error("--describe exited with {0}")]
    Failed(std::process::ExitStatus),
    #[error("--describe printed more than {MAX_DESCRIBE_BYTES} bytes")]
    TooLarge,
    #[error("--describe printed text that is not UTF-8")]
    NotUtf8,
    #[error("--describe printed an invalid description: {0}")]
    Invalid(String),
    #[error("describes itself as type `{found}`, but its file name says `{expected}`")]
    WrongType { expected: String, found: String },
}

/// Runs one binary with `--describe`, killing it if it takes longer than `timeout`.
pub fn probe(binary: &Path, timeout: Duration) -> Result<ModuleDescription, ProbeError> {
    let mut child = Command::new(binary)
        .arg("--describe")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(ProbeError::Spawn)?;
    let stdout = child.stdout.take();
    // Read on a thread so that a child that fills the pipe does not block its own exit.
    let reader = std::thread::spawn(move || {
        let mut text = Vec::new();
        if let Some(stdout) = stdout {
            let _ = stdout.take(MAX_DESCRIBE_BYTES + 1).read_to_end(&mut text);
        }
        text
    });
    let deadline = Instant::now() + timeout;
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Ok(status),
            Ok(None) if Instant::now() < deadline => {
                std::thread::sleep(Duration::from_millis(5));
            }
            Ok(None) => {
                let _ = child.kill();
                let _ = child.wait();
                break Err(ProbeError::Timeout(timeout.as_secs_f64()));
            }
            Err(err) => break Err(ProbeError::Spawn(err)),
        }
    };
    let status = status?;
    let text = reader.join().unwrap_or_default();
    if !status.success() {
        return Err(ProbeError::Failed(status));
    }
    if text.len() as u64 > MAX_DESCRIBE_BYTES {
        return Err(ProbeError::TooLarge);
    }
    let text = String::from_utf8(text).map_err(|_| ProbeError::NotUtf8)?;
    let description = ModuleDescription::from_xml(&text).map_err(|problems| {
        ProbeError::Invalid(
            problems
                .iter()
                .map(|problem| {
                    format!(
                        "line {}:{}: {}",
                        problem.pos.line, problem.pos.col, problem.message
                    )
                })
                .collect::<Vec<_>>()
                .join("; "),
        )
    })?;
    if let Some(expected) = type_from_file_name(binary)
        && expected != description.module_type
    {
        return Err(ProbeError::WrongType {
            expected: expected.to_owned(),
            found: description.module_type,
        });
    }
    Ok(description)
}

/// Probes many binaries at once; each answers or fails on its own.
pub fn probe_all(
    binaries: &[PathBuf],
    timeout: Duration,
) -> Vec<(PathBuf, Result<ModuleDescription, ProbeError>)> {
    std::thread::scope(|scope| {
        let handles: Vec<_> = binaries
            .iter()
            .map(|binary| scope.spawn(move || probe(binary, timeout)))
            .collect();
        binaries
            .iter()
            .cloned()
            .zip(handles.into_iter().map(|handle| {
                handle
                    .join()
                    .unwrap_or_else(|_| Err(ProbeError::Invalid("probe thread panicked".into())))
            }))
            .collect()
    })
}

/// Module types that have a binary which failed to describe itself: type, binary, why.
pub type ProbeFailures = Vec<(String, PathBuf, ProbeError)>;

/// Describes the given module types from the module path. Types with no binary are absent from
/// the map; binaries that fail to describe themselves are in the error list.
pub fn describe_types<'a>(
    path: &[PathBuf],
    types: impl IntoIterator<Item = &'a str>,
) -> (BTreeMap<String, ModuleDescription>, ProbeFailures) {
    let mut binaries: Vec<(String, PathBuf)> = types
        .into_iter()
        .filter_map(|module_type| Some((module_type.to_owned(), find_module(path, module_type)?)))
        .collect();
    binaries.sort();
    binaries.dedup();
    let files: Vec<PathBuf> = binaries.iter().map(|(_, file)| file.clone()).collect();
    let mut descriptions = BTreeMap::new();
    let mut failures = Vec::new();
    for ((module_type, _), (file, result)) in
        binaries.into_iter().zip(probe_all(&files, DEFAULT_TIMEOUT))
    {
        match result {
            Ok(description) => {
                descriptions.insert(module_type, description);
            }
            Err(err) => failures.push((module_type, file, err)),
        }
    }
    (descriptions, failures)
}
