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
    probe_text(binary, timeout).map(|(_, description)| description)
}

/// Starts `binary --describe`. A binary just written (by a build, or a test) can be busy for a
/// moment — another process forked while its file was open for writing — so that is retried
/// within `timeout`.
fn spawn_describe(binary: &Path, timeout: Duration) -> Result<std::process::Child, ProbeError> {
    let give_up = Instant::now() + timeout;
    loop {
        match Command::new(binary)
            .arg("--describe")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
        {
            Err(err)
                if err.kind() == std::io::ErrorKind::ExecutableFileBusy
                    && Instant::now() < give_up =>
            {
                std::thread::sleep(Duration::from_millis(10));
            }
            result => return result.map_err(ProbeError::Spawn),
        }
    }
}

/// [`probe`], also returning the text the binary printed.
fn probe_text(binary: &Path, timeout: Duration) -> Result<(String, ModuleDescription), ProbeError> {
    let mut child = spawn_describe(binary, timeout)?;
    let stdout = child.stdout.take();
    // Read on a thread so that a child that fills the pipe does not block its own exit; the
    // thread says when the output ended, which is when the child exits (or closes it).
    let (ended_tx, ended) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut text = Vec::new();
        if let Some(stdout) = stdout {
            let _ = stdout.take(MAX_DESCRIBE_BYTES + 1).read_to_end(&mut text);
        }
        let _ = ended_tx.send(());
        text
    });
    let deadline = Instant::now() + timeout;
    let _ = ended.recv_timeout(timeout);
    // Then the exit itself, a moment later (or never, for a child that closed its output and
    // went on running: it is killed at the deadline).
    let status = loop {
        match child.try_wait() {
            Ok(Some(status)) => break Ok(status),
            Ok(None) if Instant::now() < deadline => {
                std::thread::sleep(Duration::from_micros(200));
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
    Ok((text, check_type(binary, description)?))
}

/// The description, if it names the type the binary's file name promises.
fn check_type(
    binary: &Path,
    description: ModuleDescription,
) -> Result<ModuleDescription, ProbeError> {
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

/// [`probe_all`] through the user's cache ([`ProbeCache::from_env`]) when there is one: what
/// `armor run`, `armor check`, `armor probe` and the studio's palette use, so that a binary is run
/// to describe itself only after it changed.
pub fn probe_all_cached(
    binaries: &[PathBuf],
    timeout: Duration,
) -> Vec<(PathBuf, Result<ModuleDescription, ProbeError>)> {
    match ProbeCache::from_env() {
        Some(cache) => cache.probe_all(binaries, timeout),
        None => probe_all(binaries, timeout),
    }
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
    for ((module_type, _), (file, result)) in binaries
        .into_iter()
        .zip(probe_all_cached(&files, DEFAULT_TIMEOUT))
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

/// Where [`ProbeCache::from_env`] keeps its files instead of the user's cache folder.
pub const ENV_PROBE_CACHE: &str = "ARMOR_PROBE_CACHE";

/// Descriptions kept on disk, one file per binary, so that a binary described once is not run
/// again until it changes. An entry holds only for the same path, size and modification time
/// (to the nanosecond); anything else runs the binary afresh and replaces the entry. Failures
/// are never cached, and a cache that cannot be read or written only costs a probe.
#[derive(Clone, Debug)]
pub struct ProbeCache {
    dir: PathBuf,
}

impl ProbeCache {
    /// A cache in `dir` (created on first write).
    pub fn new(dir: impl Into<PathBuf>) -> ProbeCache {
        ProbeCache { dir: dir.into() }
    }

    /// The cache in `$ARMOR_PROBE_CACHE`, else `$XDG_CACHE_HOME/armor/probe`, else
    /// `$HOME/.cache/armor/probe`; `None` when none of them is set.
    pub fn from_env() -> Option<ProbeCache> {
        let nonempty = |name: &str| std::env::var_os(name).filter(|value| !value.is_empty());
        let dir = nonempty(ENV_PROBE_CACHE)
            .map(PathBuf::from)
            .or_else(|| nonempty("XDG_CACHE_HOME").map(|dir| Path::new(&dir).join("armor/probe")))
            .or_else(|| nonempty("HOME").map(|dir| Path::new(&dir).join(".cache/armor/probe")))?;
        Some(ProbeCache::new(dir))
    }

    /// The folder holding the entries.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The description of `binary`: from the cache when its entry matches the file's path, size
    /// and modification time, else by [`probe`], whose answer is then stored.
    pub fn probe(&self, binary: &Path, timeout: Duration) -> Result<ModuleDescription, ProbeError> {
        let key = cache_key(binary);
        let entry = key.as_ref().map(|key| self.entry(key));
        if let (Some(key), Some(entry)) = (&key, &entry)
            && let Some(description) = read_entry(entry, key)
        {
            return check_type(binary, description);
        }
        let (text, description) = probe_text(binary, timeout)?;
        // Stored only if the file did not change while it ran.
        if let (Some(key), Some(entry)) = (&key, &entry)
            && cache_key(binary).as_ref() == Some(key)
        {
            let _ = self.write_entry(entry, key, &text);
        }
        Ok(description)
    }

    /// [`ProbeCache::probe`] of many binaries: the cached ones first, in this thread, then the
    /// others all at once, as [`probe_all`] does.
    pub fn probe_all(
        &self,
        binaries: &[PathBuf],
        timeout: Duration,
    ) -> Vec<(PathBuf, Result<ModuleDescription, ProbeError>)> {
        let cached: Vec<Option<ModuleDescription>> = binaries
            .iter()
            .map(|binary| {
                let key = cache_key(binary)?;
                read_entry(&self.entry(&key), &key)
            })
            .collect();
        std::thread::scope(|scope| {
            let handles: Vec<_> = binaries
                .iter()
                .zip(&cached)
                .map(|(binary, cached)| {
                    cached
                        .is_none()
                        .then(|| scope.spawn(move || self.probe(binary, timeout)))
                })
                .collect();
            binaries
                .iter()
                .cloned()
                .zip(handles.into_iter().zip(cached))
                .map(|(binary, (handle, cached))| {
                    let result = match (handle, cached) {
                        (_, Some(description)) => check_type(&binary, description),
                        (Some(handle), None) => handle.join().unwrap_or_else(|_| {
                            Err(ProbeError::Invalid("probe thread panicked".into()))
                        }),
                        (None, None) => Err(ProbeError::Invalid("not probed".into())),
                    };
                    (binary, result)
                })
                .collect()
        })
    }

    /// The entry file of a key: named by a hash of the path (a collision only costs a probe,
    /// since the whole key is checked on reading).
    fn entry(&self, key: &str) -> PathBuf {
        use std::hash::{Hash as _, Hasher as _};
        let path = key.split('\t').nth(1).unwrap_or(key);
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        path.hash(&mut hasher);
        self.dir.join(format!("{:016x}.entry", hasher.finish()))
    }

    fn write_entry(&self, entry: &Path, key: &str, text: &str) -> std::io::Result<()> {
        use std::io::Write as _;
        std::fs::create_dir_all(&self.dir)?;
        let mut temporary = tempfile::NamedTempFile::new_in(&self.dir)?;
        writeln!(temporary, "{key}")?;
        temporary.write_all(text.as_bytes())?;
        temporary.persist(entry).map_err(|err| err.error)?;
        Ok(())
    }
}

/// The first line of a cache entry: format, absolute path, size, modification time in
/// nanoseconds since the epoch. `None` when the file cannot be examined.
fn cache_key(binary: &Path) -> Option<String> {
    let path = std::fs::canonicalize(binary).ok()?;
    let meta = std::fs::metadata(&path).ok()?;
    let modified = meta
        .modified()
        .ok()?
        .duration_since(std::time::UNIX_EPOCH)
        .ok()?
        .as_nanos();
    let path = path.to_str()?;
    if path.contains(['\t', '\n']) {
        return None;
    }
    Some(format!(
        "armor-probe-cache-1\t{path}\t{}\t{modified}",
        meta.len()
    ))
}

fn read_entry(entry: &Path, key: &str) -> Option<ModuleDescription> {
    let text = std::fs::read_to_string(entry).ok()?;
    let (first, description) = text.split_once('\n')?;
    if first != key {
        return None;
    }
    ModuleDescription::from_xml(description).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A module binary that is a shell script: it describes itself as `fake` and appends a line
    /// to `runs` each time it is run.
    fn fake_module(dir: &Path, runs: &Path, doc: &str) -> PathBuf {
        use std::os::unix::fs::PermissionsExt as _;
        let binary = dir.join("armor-mod-fake");
        let script = format!(
            "#!/bin/sh\necho run >> '{}'\ncat <<'EOF'\n<module type=\"fake\" version=\"0.1.0\">\n  \
             <doc>{doc}</doc>\n</module>\nEOF\n",
            runs.display()
        );
        std::fs::write(&binary, script).expect("write the fake module");
        std::fs::set_permissions(&binary, std::fs::Permissions::from_mode(0o755))
            .expect("make it executable");
        binary
    }

    fn runs(file: &Path) -> usize {
        std::fs::read_to_string(file).map_or(0, |text| text.lines().count())
    }

    #[test]
    fn the_cache_serves_an_unchanged_binary_and_probes_a_changed_one() {
        let dir = tempfile::tempdir().expect("temporary folder");
        let runs_file = dir.path().join("runs");
        let cache = ProbeCache::new(dir.path().join("cache"));
        let binary = fake_module(dir.path(), &runs_file, "first");
        let first = cache.probe(&binary, DEFAULT_TIMEOUT).expect("cold probe");
        assert_eq!(first.module_type, "fake");
        assert_eq!(runs(&runs_file), 1);
        let warm = cache.probe(&binary, DEFAULT_TIMEOUT).expect("warm probe");
        assert_eq!(warm, first);
        assert_eq!(runs(&runs_file), 1, "a warm probe runs nothing");

        // A new size (and modification time) invalidates the entry.
        let binary = fake_module(dir.path(), &runs_file, "second, longer");
        let changed = cache
            .probe(&binary, DEFAULT_TIMEOUT)
            .expect("probe after a change");
        assert_ne!(changed, first);
        assert_eq!(runs(&runs_file), 2);

        // The same size with another modification time invalidates it too.
        let modified = std::fs::metadata(&binary)
            .and_then(|meta| meta.modified())
            .expect("modification time");
        std::fs::File::options()
            .write(true)
            .open(&binary)
            .and_then(|file| file.set_modified(modified + Duration::from_secs(5)))
            .expect("touch");
        cache
            .probe(&binary, DEFAULT_TIMEOUT)
            .expect("probe after touch");
        assert_eq!(runs(&runs_file), 3);
        cache.probe(&binary, DEFAULT_TIMEOUT).expect("warm again");
        assert_eq!(runs(&runs_file), 3);
        let all = cache.probe_all(&[binary.clone(), binary.clone()], DEFAULT_TIMEOUT);
        assert!(all.iter().all(|(_, result)| result.is_ok()));
        assert_eq!(runs(&runs_file), 3, "probe_all serves cached entries too");

        // A link named for another type is refused, even though its target is cached.
        let other = dir.path().join("other");
        std::fs::create_dir(&other).expect("folder");
        let link = other.join("armor-mod-counter");
        std::os::unix::fs::symlink(&binary, &link).expect("symlink");
        assert!(matches!(
            cache.probe(&link, DEFAULT_TIMEOUT),
            Err(ProbeError::WrongType { .. })
        ));
        assert!(matches!(
            cache.probe_all(std::slice::from_ref(&link), DEFAULT_TIMEOUT)[0].1,
            Err(ProbeError::WrongType { .. })
        ));
        assert_eq!(runs(&runs_file), 3);

        // A corrupt entry is only a miss.
        for entry in std::fs::read_dir(cache.dir()).expect("cache folder") {
            std::fs::write(entry.expect("entry").path(), "garbage").expect("corrupt");
        }
        let again = cache
            .probe(&binary, DEFAULT_TIMEOUT)
            .expect("probe after corruption");
        assert_eq!(again, changed);
        assert_eq!(runs(&runs_file), 4);
    }

    #[test]
    fn failures_are_not_cached() {
        use std::os::unix::fs::PermissionsExt as _;
        let dir = tempfile::tempdir().expect("temporary folder");
        let cache = ProbeCache::new(dir.path().join("cache"));
        let binary = dir.path().join("armor-mod-broken");
        std::fs::write(
            &binary,
            "#!/bin/sh\necho '<module type=\"other\" version=\"1\"/>'\n",
        )
        .expect("write");
        std::fs::set_permissions(&binary, std::fs::Permissions::from_mode(0o755)).expect("chmod");
        assert!(matches!(
            cache.probe(&binary, DEFAULT_TIMEOUT),
            Err(ProbeError::WrongType { .. })
        ));
        assert!(!cache.dir().exists() || std::fs::read_dir(cache.dir()).expect("dir").count() == 0);
    }
}
