//! The documents a newcomer reads stay true to the tree: every relative link in README.md,
//! ARCHITECTURE.md and docs/*.md leads to a file that exists (and to a heading that exists, when
//! it names one), every backticked repository path names a file or folder of the repository, and
//! the `armor` subcommands the documents list are exactly those `armor --help` shows.
#![allow(clippy::unwrap_used)]

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use armor_tests::{bin, workspace_root};

/// Extensions that make a backticked word a file name worth checking.
const EXTENSIONS: &[&str] = &[
    "rs", "md", "xml", "xsd", "toml", "yaml", "world", "pgm", "png", "sh", "json", "txt", "mcap",
    "plan", "gpx", "kml", "pnml", "mbtiles",
];

/// Words the documents use as placeholders in paths (`runs/NAME-DATE/`, `PLAN.xml`).
const PLACEHOLDERS: &[&str] = &[
    "FILE", "DIR", "DATE", "NAME", "PLAN", "MISSION", "REC", "OUT", "PATH", "LEG", "FOLDER", "T",
];

/// Files that a run or the studio writes, named in the documents but never in the repository,
/// and folders that are looked in but hold nothing here.
const WRITTEN_AT_RUN_TIME: &[&str] = &[
    "log.txt",
    "report.json",
    "summary.txt",
    "recovery.xml",
    "map.yaml",
    "map.pgm",
    "yard-recon.mcap",
    // A folder the search for base maps looks in (docs/systems.md), which this repository has
    // no files for.
    "assets/maps",
];

/// README.md, ARCHITECTURE.md and every page under docs/.
fn documents() -> Vec<PathBuf> {
    let root = workspace_root();
    let mut files = vec![root.join("README.md"), root.join("ARCHITECTURE.md")];
    let mut pages: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "md"))
        .collect();
    pages.sort();
    assert!(!pages.is_empty(), "no pages under docs/");
    files.extend(pages);
    files
}

/// Every file and folder of the repository, as paths relative to its root with `/` between
/// names, leaving out build output.
fn repository_paths() -> BTreeSet<String> {
    let root = workspace_root();
    let mut paths = BTreeSet::new();
    let mut folders = vec![root.clone()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if matches!(name.as_str(), "target" | ".git" | "corpus" | "artifacts") {
                continue;
            }
            let relative = path
                .strip_prefix(&root)
                .unwrap()
                .to_string_lossy()
                .into_owned();
            if path.is_dir() {
                folders.push(path);
            }
            paths.insert(relative);
        }
    }
    paths
}

/// A document's text outside fenced code blocks, line by line with their numbers.
fn prose_lines(text: &str) -> Vec<(usize, &str)> {
    let mut fenced = false;
    let mut lines = Vec::new();
    for (index, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
        } else if !fenced {
            lines.push((index + 1, line));
        }
    }
    lines
}

/// The inline code spans of a line (`` `x` `` and ``` `` x `` ```), and the line with them
/// blanked out, so that a link is never looked for inside code.
fn code_spans(line: &str) -> (Vec<String>, String) {
    let chars: Vec<char> = line.chars().collect();
    let mut spans = Vec::new();
    let mut rest = String::new();
    let mut i = 0;
    while i < chars.len() {
        if chars[i] != '`' {
            rest.push(chars[i]);
            i += 1;
            continue;
        }
        let ticks = chars[i..].iter().take_while(|&&c| c == '`').count();
        let start = i + ticks;
        let mut j = start;
        let mut end = None;
        while j < chars.len() {
            if chars[j] == '`' {
                let run = chars[j..].iter().take_while(|&&c| c == '`').count();
                if run == ticks {
                    end = Some(j);
                    break;
                }
                j += run;
            } else {
                j += 1;
            }
        }
        match end {
            Some(end) => {
                let content: String = chars[start..end].iter().collect();
                spans.push(if ticks > 1 {
                    content.trim().to_owned()
                } else {
                    content
                });
                rest.push(' ');
                i = end + ticks;
            }
            None => {
                rest.extend(&chars[i..start]);
                i = start;
            }
        }
    }
    (spans, rest)
}

/// The targets of the Markdown links and images of a line (its code spans blanked out).
fn link_targets(line: &str) -> Vec<String> {
    let mut targets = Vec::new();
    let mut rest = line;
    while let Some(at) = rest.find("](") {
        let after = &rest[at + 2..];
        let Some(close) = after.find(')') else { break };
        targets.push(after[..close].trim().to_owned());
        rest = &after[close..];
    }
    targets
}

/// The anchor GitHub gives a heading: lower case, punctuation dropped, spaces as hyphens.
fn anchor_of(heading: &str) -> String {
    heading
        .trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

fn anchors(file: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(file).unwrap();
    prose_lines(&text)
        .into_iter()
        .filter_map(|(_, line)| line.strip_prefix('#'))
        .map(|heading| anchor_of(heading.trim_start_matches('#')))
        .collect()
}

/// Whether a code span reads as a path in the repository (not a placeholder, an address, an
/// XML snippet or a command).
fn looks_like_repository_path(span: &str) -> bool {
    if span.is_empty()
        || span
            .chars()
            .any(|c| c.is_whitespace() || "<>=\"'*{}~:$@,;()|\\".contains(c))
        || span.starts_with('/')
        || span.starts_with('-')
    {
        return false;
    }
    let has_extension = span
        .rsplit_once('.')
        .is_some_and(|(stem, ext)| !stem.is_empty() && EXTENSIONS.contains(&ext));
    if !(span.contains('/') || has_extension) {
        return false;
    }
    !span
        .split(['/', '.', '-'])
        .any(|word| PLACEHOLDERS.contains(&word))
}

/// Whether a backticked path names something in the repository: from the root, from the
/// document's folder, or as the end of a longer path (`run/untrusted.rs`, `auth.rs`, `net/`).
fn names_something(span: &str, document_dir: &str, paths: &BTreeSet<String>) -> bool {
    let path = span.trim_start_matches("./").trim_end_matches('/');
    // Build output (`target/release/armor`) is made by cargo, never kept in the repository.
    if WRITTEN_AT_RUN_TIME.contains(&path) || path == "target" || path.starts_with("target/") {
        return true;
    }
    let from_document = normalise(&format!("{document_dir}/{path}"));
    paths.contains(path)
        || from_document.is_some_and(|joined| paths.contains(&joined))
        || paths
            .iter()
            .any(|known| known.ends_with(&format!("/{path}")))
}

/// `a/b/../c` as `a/c`; `None` when it climbs out of the repository.
fn normalise(path: &str) -> Option<String> {
    let mut parts: Vec<&str> = Vec::new();
    for part in path.split('/') {
        match part {
            "" | "." => {}
            ".." => {
                parts.pop()?;
            }
            part => parts.push(part),
        }
    }
    Some(parts.join("/"))
}

#[test]
fn every_relative_link_and_backticked_path_exists() {
    let root = workspace_root();
    let paths = repository_paths();
    let mut problems = Vec::new();
    let mut links = 0;
    let mut spans_checked = 0;
    for document in documents() {
        let name = document
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .into_owned();
        let dir = name.rsplit_once('/').map_or("", |(dir, _)| dir).to_owned();
        let text = std::fs::read_to_string(&document).unwrap();
        for (line_number, line) in prose_lines(&text) {
            let (spans, without_code) = code_spans(line);
            for target in link_targets(&without_code) {
                if target.contains("://") || target.starts_with("mailto:") {
                    continue;
                }
                links += 1;
                let (file, anchor) = target.split_once('#').unwrap_or((&target, ""));
                let linked = if file.is_empty() {
                    Some(name.clone())
                } else {
                    normalise(&format!("{dir}/{file}"))
                };
                let Some(linked) = linked.filter(|linked| paths.contains(linked.as_str())) else {
                    problems.push(format!(
                        "{name}:{line_number}: link to `{target}`: no such file"
                    ));
                    continue;
                };
                if !anchor.is_empty()
                    && linked.ends_with(".md")
                    && !anchors(&root.join(&linked)).contains(anchor)
                {
                    problems.push(format!(
                        "{name}:{line_number}: link to `{target}`: {linked} has no heading `#{anchor}`"
                    ));
                }
            }
            for span in spans {
                if looks_like_repository_path(&span) {
                    spans_checked += 1;
                    if !names_something(&span, &dir, &paths) {
                        problems.push(format!(
                            "{name}:{line_number}: `{span}` names nothing in the repository"
                        ));
                    }
                }
            }
        }
    }
    assert!(
        problems.is_empty(),
        "{} problems in the documents:\n{}",
        problems.len(),
        problems.join("\n")
    );
    // The documents link and name files in numbers: finding none would mean the parser is broken.
    assert!(links > 20, "only {links} relative links found");
    assert!(
        spans_checked > 50,
        "only {spans_checked} backticked paths found"
    );
}

/// The subcommands `armor --help` lists.
fn armor_subcommands() -> BTreeSet<String> {
    let output = Command::new(bin("armor")).arg("--help").output().unwrap();
    assert!(output.status.success(), "armor --help failed");
    let help = String::from_utf8(output.stdout).unwrap();
    let commands: BTreeSet<String> = help
        .lines()
        .skip_while(|line| !line.starts_with("Commands:"))
        .skip(1)
        .take_while(|line| !line.trim().is_empty())
        .filter_map(|line| line.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_owned)
        .collect();
    assert!(commands.len() > 5, "no commands read from:\n{help}");
    commands
}

/// The subcommand a code span such as `armor run FILE` names, if it names one.
fn subcommand_of(span: &str) -> Option<String> {
    let mut words = span.split_whitespace();
    (words.next()? == "armor").then_some(())?;
    let word = words.next()?;
    word.chars()
        .all(|c| c.is_ascii_lowercase())
        .then(|| word.to_owned())
}

/// The subcommands named in the first column of a document's first table whose rows start with
/// `armor`.
fn table_subcommands(document: &Path) -> BTreeSet<String> {
    let text = std::fs::read_to_string(document).unwrap();
    let mut found = BTreeSet::new();
    for (_, line) in prose_lines(&text) {
        let Some(first_cell) = line.strip_prefix('|').and_then(|row| row.split('|').next()) else {
            if !found.is_empty() {
                break;
            }
            continue;
        };
        found.extend(
            code_spans(first_cell)
                .0
                .iter()
                .filter_map(|s| subcommand_of(s)),
        );
    }
    found
}

#[test]
fn the_documents_list_exactly_the_subcommands_armor_has() {
    let root = workspace_root();
    let commands = armor_subcommands();
    // The two tables that list them: the README's and the command line's page.
    for page in ["README.md", "docs/cli.md"] {
        assert_eq!(
            table_subcommands(&root.join(page)),
            commands,
            "{page}'s table of commands against `armor --help`"
        );
    }
    // And no document names a subcommand that does not exist.
    for document in documents() {
        let text = std::fs::read_to_string(&document).unwrap();
        for (line_number, line) in prose_lines(&text) {
            for span in code_spans(line).0 {
                if let Some(command) = subcommand_of(&span) {
                    assert!(
                        commands.contains(&command),
                        "{}:{line_number}: `{span}`: armor has no command `{command}`",
                        document.display()
                    );
                }
            }
        }
    }
}

#[test]
fn the_parsers_read_what_the_documents_hold() {
    let (spans, rest) = code_spans("see `a/b.rs` and ``x `y` z`` then [t](docs/c.md#top)");
    assert_eq!(spans, ["a/b.rs", "x `y` z"]);
    assert_eq!(link_targets(&rest), ["docs/c.md#top"]);
    assert!(looks_like_repository_path("runtime/model/src/world.rs"));
    assert!(looks_like_repository_path("auth.rs"));
    assert!(!looks_like_repository_path("runs/NAME-DATE/"));
    assert!(!looks_like_repository_path("127.0.0.1:7400"));
    assert!(!looks_like_repository_path("1.0625"));
    assert_eq!(anchor_of(" The health stream"), "the-health-stream");
    assert_eq!(anchor_of("armor run"), "armor-run");
    assert_eq!(
        subcommand_of("armor ctl --addr ADDR status"),
        Some("ctl".into())
    );
    assert_eq!(subcommand_of("armor COMMAND --help"), None);
    assert_eq!(normalise("docs/../README.md"), Some("README.md".into()));
    assert_eq!(normalise("../x"), None);
}
