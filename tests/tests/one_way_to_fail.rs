//! One way to fail (ARCHITECTURE.md, "Errors"): a library returns a typed error (thiserror) at
//! its boundary, a binary uses anyhow, and nothing returns `Result<_, String>`. The functions
//! that still do are counted here, file by file, and may only go: a file that gains one, or a
//! file not listed that has one, fails this test; a file that loses one fails it too, until its
//! count here is lowered, so that the list stays the truth.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use armor_tests::workspace_root;

/// The folders of the workspace's own code.
const ROOTS: &[&str] = &["app", "runtime", "module_catalog", "bench", "tests"];

/// Files left out: outside the workspace (the peers' benchmarks), or this test, which names the
/// pattern.
const LEFT_OUT: &[&str] = &[
    "bench/peers",
    "bench/experiments",
    "tests/tests/one_way_to_fail.rs",
];

/// The `Result<_, String>`s left, by file. Lower a count when one goes; never raise one.
const LEFT: &[(&str, usize)] = &[
    ("app/src/mission/inspector.rs", 5),
    ("app/src/mission/symbols.rs", 4),
    ("app/src/run/inspector.rs", 3),
    ("app/src/run/live.rs", 1),
    ("app/src/run/markers.rs", 2),
    ("app/src/run/video.rs", 3),
    ("app/src/system/diagram.rs", 6),
    ("app/src/system/diagram/groups.rs", 4),
    ("module_catalog/src/camera/mod.rs", 1),
    ("module_catalog/src/camera/render.rs", 1),
    ("module_catalog/src/localiser/mcl.rs", 1),
    ("module_catalog/src/localiser/mod.rs", 1),
    ("module_catalog/src/mapper/graph.rs", 1),
    ("module_catalog/src/mapper/grid.rs", 3),
    ("module_catalog/src/mapper/mod.rs", 5),
    ("module_catalog/src/sim/mod.rs", 3),
    ("module_catalog/src/teleop.rs", 1),
    ("module_catalog/src/webcam/device.rs", 1),
    ("module_catalog/src/webcam/mod.rs", 1),
    ("runtime/model/src/foxglove.rs", 2),
    ("runtime/model/src/geo.rs", 1),
    ("runtime/model/src/net/date.rs", 1),
    ("runtime/model/src/plan/mod.rs", 1),
    ("runtime/model/src/planner/mod.rs", 1),
    ("runtime/model/src/system/mod.rs", 2),
    ("runtime/model/src/world.rs", 1),
    ("runtime/module_api/src/module.rs", 1),
    ("runtime/module_api/src/types/image.rs", 1),
    ("runtime/module_api/src/xml.rs", 1),
    ("runtime/runtime/src/basemap.rs", 3),
    ("runtime/runtime/src/config_server.rs", 4),
    ("runtime/runtime/src/host.rs", 3),
    ("runtime/runtime/src/mission.rs", 2),
    ("runtime/runtime/src/paths.rs", 1),
    ("tests/src/tools.rs", 1),
    ("tests/tests/hosts.rs", 2),
    ("tests/tests/identity.rs", 1),
    ("tests/tests/navigation.rs", 2),
];

fn rust_files(dir: &Path, files: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries {
        let path = entry.unwrap().path();
        if path.is_dir() {
            if path.file_name().is_some_and(|name| name != "target") {
                rust_files(&path, files);
            }
        } else if path.extension().is_some_and(|ext| ext == "rs") {
            files.push(path);
        }
    }
}

/// The code of `text` without its comments (`//` to the end of the line), on one line.
fn code_of(text: &str) -> String {
    text.lines()
        .map(|line| line.split_once("//").map_or(line, |(code, _)| code))
        .collect::<Vec<_>>()
        .join(" ")
}

/// How many `Result<…, String>` types `code` names: a `Result` whose last type argument, at
/// its own depth of angle brackets, is `String`.
fn string_results(code: &str) -> usize {
    let mut count = 0;
    let mut rest = code;
    while let Some(at) = rest.find("Result<") {
        let is_name_start = at == 0
            || !rest[..at]
                .chars()
                .next_back()
                .is_some_and(|c| c.is_alphanumeric() || c == '_');
        let arguments = &rest[at + "Result<".len()..];
        rest = arguments;
        if !is_name_start {
            continue;
        }
        let mut depth = 0usize;
        let mut previous = ' ';
        let mut arguments_seen = vec![String::new()];
        for c in arguments.chars() {
            match c {
                '<' | '(' | '[' => depth += 1,
                // The arrow of a function type is no bracket.
                '>' if previous == '-' => {}
                ')' | ']' => depth = depth.saturating_sub(1),
                '>' if depth == 0 => break,
                '>' => depth -= 1,
                ',' if depth == 0 => {
                    arguments_seen.push(String::new());
                    previous = c;
                    continue;
                }
                _ => {}
            }
            if let Some(argument) = arguments_seen.last_mut() {
                argument.push(c);
            }
            previous = c;
        }
        // A trailing comma ends the list with nothing after it.
        if arguments_seen
            .last()
            .is_some_and(|argument| argument.trim().is_empty())
        {
            arguments_seen.pop();
        }
        if arguments_seen.len() == 2 && arguments_seen[1].trim() == "String" {
            count += 1;
        }
    }
    count
}

#[test]
fn no_new_result_with_a_string_error() {
    let root = workspace_root();
    let mut files = Vec::new();
    for dir in ROOTS {
        rust_files(&root.join(dir), &mut files);
    }
    let mut found = BTreeMap::new();
    for file in files {
        let name = file.strip_prefix(&root).unwrap().display().to_string();
        if LEFT_OUT.iter().any(|left_out| name.starts_with(left_out)) {
            continue;
        }
        let count = string_results(&code_of(&std::fs::read_to_string(&file).unwrap()));
        if count > 0 {
            found.insert(name, count);
        }
    }
    let left: BTreeMap<String, usize> = LEFT
        .iter()
        .map(|(file, count)| ((*file).to_owned(), *count))
        .collect();
    let mut wrong = Vec::new();
    for (file, &count) in &found {
        let allowed = left.get(file).copied().unwrap_or(0);
        if count > allowed {
            wrong.push(format!(
                "{file}: {count} `Result<_, String>` where {allowed} are left: return a typed \
                 error (thiserror) from a library, anyhow::Result from a binary"
            ));
        }
    }
    for (file, &allowed) in &left {
        let count = found.get(file).copied().unwrap_or(0);
        if count < allowed {
            wrong.push(format!(
                "{file}: {count} `Result<_, String>` left, {allowed} listed: lower its count here"
            ));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n"));
}

#[test]
fn string_errors_are_counted_wherever_they_are_written() {
    let check = |code: &str, expected: usize| {
        assert_eq!(string_results(&code_of(code)), expected, "{code}");
    };
    check("fn f() -> Result<u32, String> {", 1);
    check("fn f() -> Result<Vec<(u8, u8)>, String> {", 1);
    check(
        "fn f(\n) -> Result<\n    BTreeMap<String, u32>,\n    String,\n> {",
        1,
    );
    check("fn f() -> std::result::Result<(), String>", 1);
    check("fn f() -> Result<Box<dyn Fn() -> u8>, String> {", 1);
    check("fn f() -> Result<String, Error> {", 0);
    check("fn f() -> Result<u32, StringError> {", 0);
    check("fn f() -> anyhow::Result<String> {", 0);
    check("fn f() -> io::Result<(String, u8)> {", 0);
    check("fn f() -> TryResult<u32, String> {", 0);
    check("// returns Result<u32, String>\nfn f() {}", 0);
    check(
        "let parsed: Result<u32, String> = a(); let b: Result<u8, String> = c();",
        2,
    );
}
