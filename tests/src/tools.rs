//! The programs and Python modules outside the workspace that the suites run (xmllint, Xvfb,
//! tesseract, `python3` with pm4py…). A suite asks for each here before using it, so a machine
//! that lacks one fails the test with the tool's name, the package that has it and the script
//! that installs it (`scripts/test`), never silently or with an obscure error halfway through.
//! `scripts/test` installs them all; the lists below and its lists must name the same packages.

use std::collections::HashSet;
use std::path::PathBuf;
use std::process::Command;
use std::sync::{Mutex, PoisonError};

/// Each program the suites run, and the Debian package it comes from.
const PROGRAMS: &[(&str, &str)] = &[
    ("xmllint", "libxml2-utils"),
    ("Xvfb", "xvfb"),
    ("xdotool", "xdotool"),
    ("import", "imagemagick"),
    ("convert", "imagemagick"),
    ("tesseract", "tesseract-ocr"),
    ("ip", "iproute2"),
    ("tc", "iproute2"),
    ("iptables", "iptables"),
    ("kill", "procps"),
    ("script", "bsdutils"),
    ("python3", "python3"),
];

/// Each Python module the suites import, and the PyPI package it comes from (pinned in
/// tests/python/requirements.txt).
const PYTHON_MODULES: &[(&str, &str)] = &[
    ("snakes.pnml", "snakes"),
    ("gpxpy", "gpxpy"),
    ("pm4py", "pm4py"),
    ("fastkml", "fastkml"),
    ("lxml", "lxml"),
    ("noise", "noiseprotocol"),
    ("cryptography", "cryptography"),
    ("mcap", "mcap"),
];

/// What was found already in this test process (looking up Python modules takes a second).
static FOUND: Mutex<Option<HashSet<String>>> = Mutex::new(None);

fn found(key: &str) -> bool {
    FOUND
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .as_ref()
        .is_some_and(|found| found.contains(key))
}

fn remember(key: &str) {
    FOUND
        .lock()
        .unwrap_or_else(PoisonError::into_inner)
        .get_or_insert_with(HashSet::new)
        .insert(key.to_owned());
}

/// The path of `program` on PATH; panics naming it, its Debian package and `scripts/test` when
/// it is not there.
pub fn program(program: &str) -> PathBuf {
    find_program(program, std::env::var_os("PATH").as_deref()).unwrap_or_else(|why| panic!("{why}"))
}

/// `program` in the folders of `path` (PATH's format), or the message saying how to get it.
fn find_program(program: &str, path: Option<&std::ffi::OsStr>) -> Result<PathBuf, String> {
    let package = PROGRAMS
        .iter()
        .find(|(name, _)| *name == program)
        .map(|(_, package)| *package)
        .unwrap_or_else(|| panic!("`{program}` is not in tests/src/tools.rs's list of programs"));
    path.and_then(|path| {
        std::env::split_paths(path)
            .map(|dir| dir.join(program))
            .find(|candidate| is_executable(candidate))
    })
    .ok_or_else(|| {
        format!(
            "`{program}` is not installed (Debian package `{package}`): run the tests with \
             `scripts/test`, which installs what they need"
        )
    })
}

fn is_executable(path: &std::path::Path) -> bool {
    use std::os::unix::fs::PermissionsExt as _;
    std::fs::metadata(path)
        .is_ok_and(|meta| meta.is_file() && meta.permissions().mode() & 0o111 != 0)
}

/// A `python3` command, after checking that it can import every one of `modules`; panics
/// naming the missing modules, their PyPI packages and `scripts/test` otherwise.
///
/// `scripts/test` puts its virtual environment's bin/ first on PATH, so this is that
/// environment's Python, with the versions pinned in tests/python/requirements.txt.
pub fn python3(modules: &[&str]) -> Command {
    let python = program("python3");
    let missing: Vec<&str> = modules
        .iter()
        .copied()
        .filter(|module| {
            let key = format!("python:{module}");
            if found(&key) {
                return false;
            }
            let imports = Command::new(&python)
                .args(["-c", &format!("import {module}")])
                .output()
                .is_ok_and(|output| output.status.success());
            if imports {
                remember(&key);
            }
            !imports
        })
        .collect();
    if !missing.is_empty() {
        let packages: Vec<&str> = missing
            .iter()
            .map(|module| {
                PYTHON_MODULES
                    .iter()
                    .find(|(name, _)| name == module)
                    .map(|(_, package)| *package)
                    .unwrap_or_else(|| {
                        panic!("`{module}` is not in tests/src/tools.rs's list of Python modules")
                    })
            })
            .collect();
        panic!(
            "{} cannot import {} (PyPI {}): run the tests with `scripts/test`, which installs \
             them in a virtual environment at the versions of tests/python/requirements.txt",
            python.display(),
            missing.join(", "),
            packages.join(", ")
        );
    }
    Command::new(python)
}

#[cfg(test)]
mod tests {
    use super::find_program;

    #[test]
    fn a_missing_program_is_named_with_its_package_and_the_script() {
        let why = find_program("xmllint", Some("".as_ref())).expect_err("no folder, no program");
        for word in ["`xmllint`", "libxml2-utils", "`scripts/test`"] {
            assert!(why.contains(word), "{word} in {why}");
        }
        let kill = find_program("kill", Some("/nonexistent:/usr/bin:/bin".as_ref()));
        assert!(kill.is_ok_and(|path| path.ends_with("kill")));
    }
}
