//! The studio's rooms: each view (`system/`, `mission/`, `run/`) owns its folder, and what two
//! views share lives in `common/`. A view reaches another only through the items its room
//! exports at its root (`crate::mission::MissionView`), never into its files
//! (`crate::mission::map::…`); the System view names no other view at all; `common/` names none.
//! These tests read the sources, so that a `use` across rooms fails here, not in a review.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

const VIEWS: [&str; 4] = ["system", "mission", "run", "station"];

fn rust_files(dir: &Path) -> Vec<PathBuf> {
    let mut files = Vec::new();
    let mut dirs = vec![dir.to_path_buf()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|ext| ext == "rs") {
                files.push(path);
            }
        }
    }
    files.sort();
    files
}

/// Every place in `text` that names room `room` through a path, with what follows the path's
/// `crate::ROOM` (`::MissionView`, `::map::draw`, `;`), as `LINE: what`.
fn mentions(text: &str, room: &str) -> Vec<(usize, String)> {
    let needle = format!("crate::{room}");
    let mut found = Vec::new();
    for (number, line) in text.lines().enumerate() {
        let mut rest = line;
        while let Some(at) = rest.find(&needle) {
            let after = &rest[at + needle.len()..];
            // `crate::run` is not `crate::runtime`.
            if !after.starts_with(|c: char| c.is_alphanumeric() || c == '_') {
                found.push((number + 1, after.chars().take(40).collect()));
            }
            rest = after;
        }
    }
    found
}

/// Whether `after` (what follows `crate::ROOM`) names only items at the room's root, which
/// are types (capitalised): `::MissionView`, `::{LegRoute, MissionView}`.
fn root_items_only(after: &str) -> bool {
    let Some(path) = after.strip_prefix("::") else {
        return false;
    };
    let is_root_type = |item: &str| {
        item.starts_with(|c: char| c.is_ascii_uppercase())
            && item.chars().all(|c| c.is_alphanumeric() || c == '_')
    };
    match path.strip_prefix('{') {
        Some(list) => list
            .split('}')
            .next()
            .unwrap_or_default()
            .split(',')
            .map(str::trim)
            .filter(|item| !item.is_empty())
            .all(is_root_type),
        None => {
            let end = path
                .find(|c: char| !(c.is_alphanumeric() || c == '_'))
                .unwrap_or(path.len());
            is_root_type(&path[..end]) && !path[end..].starts_with("::")
        }
    }
}

/// The crossings of room boundaries in the sources under `src`, as `FILE:LINE: what`.
fn crossings(src: &Path) -> Vec<String> {
    let mut wrong = Vec::new();
    for room in VIEWS.iter().chain(&["common"]) {
        for file in rust_files(&src.join(room)) {
            let text = std::fs::read_to_string(&file).unwrap();
            for other in VIEWS.iter().chain(&["app"]).filter(|other| *other != room) {
                for (line, after) in mentions(&text, other) {
                    let allowed = !matches!(*room, "system" | "common")
                        && *other != "app"
                        && root_items_only(&after);
                    if !allowed {
                        wrong.push(format!(
                            "{}:{line}: crate::{other}{after}",
                            file.strip_prefix(src).unwrap_or(&file).display()
                        ));
                    }
                }
            }
        }
    }
    wrong
}

#[test]
fn no_view_reaches_into_another() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let wrong = crossings(&src);
    assert!(
        wrong.is_empty(),
        "imports across rooms:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn crossings_are_found() {
    let src = tempfile::tempdir().unwrap();
    let write = |path: &str, text: &str| {
        let path = src.path().join(path);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    };
    write(
        "system/viewer.rs",
        "use crate::run::monitor::state_colour;\n",
    );
    write(
        "system/mod.rs",
        "use crate::mission::MissionView;\nuse crate::runtime::x;\n",
    );
    write(
        "run/mod.rs",
        "use crate::mission::{LegRoute, MissionView};\n",
    );
    write(
        "run/markers.rs",
        "use crate::mission::labels::{self, Label};\n",
    );
    write(
        "mission/map.rs",
        "crate::run::video::has_focus(ui);\nuse crate::mission::map;\n",
    );
    write("common/draw.rs", "use crate::system::diagram::Diagram;\n");
    write("station/mod.rs", "use crate::run::monitor::x;\n");
    assert_eq!(
        crossings(src.path()),
        [
            "system/mod.rs:1: crate::mission::MissionView;",
            "system/viewer.rs:1: crate::run::monitor::state_colour;",
            "mission/map.rs:1: crate::run::video::has_focus(ui);",
            "run/markers.rs:1: crate::mission::labels::{self, Label};",
            "station/mod.rs:1: crate::run::monitor::x;",
            "common/draw.rs:1: crate::system::diagram::Diagram;",
        ]
    );
}
